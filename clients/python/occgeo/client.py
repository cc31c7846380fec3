"""The occgeo.v1 client: one TCP connection to occgeod, varint-delimited protobuf frames.

Every message on the stream is a protobuf message preceded by its length as a base-128 varint
(protobuf's delimited format); the client sends ``ClientMessage``s and receives ``ServerMessage``s
(see docs/PROTOCOL.md). Requests carry a ``request_id`` chosen here on the ``ClientMessage``
envelope, and their replies are matched by the ``request_id`` on the ``ServerMessage`` envelope;
``Error`` replies raise :class:`ServerError`.

Frames and units: poses are ``base_link`` in the ``world`` frame (x, y in metres, theta in radians
counter-clockwise from +x); points are world-frame metres; all values are SI.
"""

import collections
import socket
import time

from occgeo.v1 import common_pb2, control_pb2, query_pb2, robot_pb2, sensors_pb2, session_pb2

#: The protocol version this client speaks (2: request_id on the ClientMessage / ServerMessage envelope).
PROTOCOL_VERSION = 3
#: Largest frame accepted from the server (whole-map replies can be large), as the C++ client.
MAX_FRAME_BYTES = 256 * 1024 * 1024

_ROLES = {
    "driver": session_pb2.ROLE_DRIVER,
    "query": session_pb2.ROLE_QUERY,
    "controller": session_pb2.ROLE_CONTROLLER,
    "observer": session_pb2.ROLE_OBSERVER,
}
_MODELS = {"grid": query_pb2.MODEL_GRID, "octomap": query_pb2.MODEL_OCTOMAP, "ptem": query_pb2.MODEL_PTEM}
_LEASE_ACTIONS = {
    "acquire": control_pb2.LeaseRequest.ACQUIRE,
    "retain": control_pb2.LeaseRequest.RETAIN,
    "return": control_pb2.LeaseRequest.RETURN,
    "take": control_pb2.LeaseRequest.TAKE,
}
#: Behaviour names a ``DriveRequest`` accepts (see docs/PROTOCOL.md, "Drive").
def _labels(enum, prefix):
    """An enum's values by their label: the name without the prefix, in lower case (BEHAVIOUR_GOTO is "goto")."""
    return {name[len(prefix):].lower(): number for name, number in enum.items() if number != 0}


_BEHAVIOUR_BY_LABEL = _labels(control_pb2.Behaviour, "BEHAVIOUR_")
_STATE_BY_LABEL = _labels(control_pb2.BehaviourState, "BEHAVIOUR_STATE_")
_BEHAVIOUR_LABELS = {number: label for label, number in _BEHAVIOUR_BY_LABEL.items()}
_STATE_LABELS = {number: label for label, number in _STATE_BY_LABEL.items()}

#: The behaviours :meth:`Client.drive` takes, by label, in the schema's order (the ``Behaviour`` enum).
BEHAVIOURS = tuple(_BEHAVIOUR_BY_LABEL)


def behaviour_label(value):
    """The label of a ``Behaviour`` value (``control_pb2.BEHAVIOUR_GOTO`` is ``"goto"``); ``""`` when unset."""
    return _BEHAVIOUR_LABELS.get(value, "" if value == 0 else str(value))


def state_label(value):
    """The label of a ``BehaviourState`` value (``BEHAVIOUR_STATE_STEER_GAP`` is ``"steer_gap"``); ``""`` when unset."""
    return _STATE_LABELS.get(value, "" if value == 0 else str(value))


def behaviour_value(behaviour):
    """A ``Behaviour`` value from its label (``"goto"``) or the value itself; raises ValueError naming the labels."""
    if isinstance(behaviour, str):
        if behaviour not in _BEHAVIOUR_BY_LABEL:
            raise ValueError("behaviour %r is not one of %s" % (behaviour, ", ".join(BEHAVIOURS)))
        return _BEHAVIOUR_BY_LABEL[behaviour]
    return int(behaviour)


class ClientError(Exception):
    """A transport problem: cannot connect, connection closed, undecodable frame."""


class Timeout(ClientError):
    """No answer within the timeout."""


class ServerError(Exception):
    """An ``Error`` from the server.

    Attributes: ``code`` (``occgeo.v1.ErrorCode`` value, e.g. ``session_pb2.ERROR_UNKNOWN_ROBOT``),
    ``code_name`` (e.g. ``"ERROR_UNKNOWN_ROBOT"``), ``field`` (path of the offending field, e.g.
    ``"collision.robot_id"``), ``message`` (text), ``request_id`` (the id of the request it answers,
    from the ``ServerMessage`` envelope; 0 otherwise),
    ``seq`` (the rejected sensor/odometry message's seq, 0 otherwise) and ``retry_after_s``
    (``ERROR_BUSY``: the server's query backlog was full and nothing was done; send the request
    again after this many seconds). ``busy`` is true for ``ERROR_BUSY``.
    """

    def __init__(self, code, field, message, request_id=0, seq=0, retry_after_s=0.0):
        self.code = int(code)
        self.field = field
        self.message = message
        self.request_id = request_id
        self.seq = seq
        self.retry_after_s = retry_after_s
        super().__init__(self.__str__())

    @property
    def busy(self):
        return self.code == session_pb2.ERROR_BUSY

    @property
    def code_name(self):
        try:
            return session_pb2.ErrorCode.Name(self.code)
        except ValueError:
            return "ERROR_%d" % self.code

    @classmethod
    def from_proto(cls, error, request_id=0):
        """From an ``Error`` and the ``request_id`` of the ``ServerMessage`` envelope that carried it."""
        return cls(error.code, error.field, error.message, request_id, error.seq, error.retry_after_s)

    @classmethod
    def from_message(cls, message):
        """From a ``ServerMessage`` whose body is an ``Error``."""
        return cls.from_proto(message.error, message.request_id)

    def __str__(self):
        text = self.code_name
        if self.field:
            text += " " + self.field
        text += ": " + self.message
        if self.busy:
            text += " (server busy: retry in %g s)" % self.retry_after_s
        return text


class LeaseRefused(Exception):
    """A ``LeaseRequest`` answered with ``granted: false``: someone else holds the lease.

    Attributes: ``reply`` (the ``LeaseReply``; ``reply.holder`` names the holder's session and client).
    """

    def __init__(self, reply, action):
        self.reply = reply
        holder = reply.holder
        who = ("session %d (%s)" % (holder.session_id, holder.client_name)) if reply.HasField("holder") else "nobody"
        super().__init__("lease %s of robot %s refused: held by %s" % (action, reply.robot_id, who))


class CertaintyWindow:
    """A rectangle of HIMM grid cells (from ``GridReply``).

    ``cells`` is ``bytes``, row-major, row 0 at ``min_iy`` (the lowest y), column 0 at ``min_ix``;
    each byte a certainty 0..``max_certainty``, or 255 for a cell never observed. Cell (ix, iy) covers
    [ix*s, (ix+1)*s) x [iy*s, (iy+1)*s) in the world frame for cell size s = ``cell_size_m`` (metres).
    Cells with certainty >= ``occupied_threshold`` are occupied. ``version`` is the world version.
    """

    UNOBSERVED = 255

    def __init__(self, world, cell_size_m, min_ix, min_iy, width, height, cells, occupied_threshold,
                 max_certainty, version):
        self.world = world
        self.cell_size_m = cell_size_m
        self.min_ix = min_ix
        self.min_iy = min_iy
        self.width = width
        self.height = height
        self.cells = cells
        self.occupied_threshold = occupied_threshold
        self.max_certainty = max_certainty
        self.version = version

    @classmethod
    def from_proto(cls, reply):
        return cls(reply.world, reply.cell_size_m, reply.min_cell.ix, reply.min_cell.iy, reply.width,
                   reply.height, bytes(reply.cells), reply.occupied_threshold, reply.max_certainty or 15,
                   reply.version)

    def rows(self):
        """The cells as a list of rows (lists of ints), row 0 at ``min_iy``."""
        w = self.width
        return [list(self.cells[r * w:(r + 1) * w]) for r in range(self.height)]

    def value(self, ix, iy):
        """Cell value at grid index (ix, iy), or None outside the window."""
        col, row = ix - self.min_ix, iy - self.min_iy
        if 0 <= col < self.width and 0 <= row < self.height:
            return self.cells[row * self.width + col]
        return None

    def is_occupied(self, ix, iy):
        v = self.value(ix, iy)
        return v is not None and v != self.UNOBSERVED and v >= self.occupied_threshold

    def occupied_cells(self):
        """Set of (ix, iy) of the occupied cells."""
        out = set()
        t = self.occupied_threshold
        for i, v in enumerate(self.cells):
            if v != self.UNOBSERVED and v >= t:
                out.add((self.min_ix + i % self.width, self.min_iy + i // self.width))
        return out

    def cell_center(self, ix, iy):
        """World-frame centre (x, y), metres, of cell (ix, iy)."""
        return ((ix + 0.5) * self.cell_size_m, (iy + 0.5) * self.cell_size_m)


def _varint(value):
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        if value:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


def _model_list(models):
    if models is None:
        return []
    if isinstance(models, str):
        models = [m for m in models.split(",") if m]
    out = []
    for m in models:
        if isinstance(m, str):
            key = m.lower().replace("model_", "")
            if key not in _MODELS:
                raise ValueError("unknown model %r (grid, octomap, ptem)" % m)
            out.append(_MODELS[key])
        else:
            out.append(int(m))
    return out


def _pose2d(x, y, theta):
    return common_pb2.Pose2D(x=float(x), y=float(y), theta=float(theta))


class Client:
    """A session with occgeod. Create it with :meth:`Client.connect`; use it as a context manager
    or call :meth:`close`.

    Not thread-safe: use one Client per thread. Messages that answer no request (``ScanAck``,
    ``MotionCommand``, errors about sensor data) received while waiting are kept in
    :attr:`scan_acks`, :attr:`motion_commands` and :attr:`errors`.
    """

    def __init__(self, sock, welcome, role, robot_id, world, timeout_s):
        self._sock = sock
        self._buffer = bytearray()
        self._replies = {}  # request_id -> ServerMessage
        self._next_request_id = 1
        self._next_seq = 1  # one increasing sequence per robot across all sensor kinds
        self._next_odometry_seq = 1
        self._last_stamp_s = 0.0
        self.welcome = welcome  #: the server's ``Welcome`` (protocol_version, server_version, session_id)
        self.role = role
        self.robot_id = robot_id
        self.world = world
        self.timeout_s = timeout_s
        self.scan_acks = collections.deque(maxlen=10000)  #: ``ScanAck``s not yet consumed
        self.motion_commands = collections.deque(maxlen=10000)  #: ``MotionCommand``s, oldest first
        self.errors = collections.deque(maxlen=10000)  #: ``Error``s naming no request (as ServerError)
        self.watch_events = collections.deque(maxlen=100000)  #: ``WatchEvent``s not yet consumed, oldest first

    # ----------------------------------------------------------------------------- connection

    @classmethod
    def connect(cls, host="127.0.0.1", port=7700, role="query", robot_id=None, world=None, timeout_s=5.0,
                client_name="occgeo-python", auth_token=""):
        """Connects to occgeod at ``host:port`` and does the hello/welcome exchange.

        ``role``: ``"query"`` (queries only), ``"driver"`` (a robot: ``robot_id`` required, 1-64
        characters of ``A-Z a-z 0-9 _ . -``; ``world`` the world it maps into, None for "default"),
        ``"controller"`` (leases, drive, e-stop, watch and queries) or ``"observer"`` (e-stop, watch and
        queries). ``auth_token``: the role's token, or the operator token (which allows lease ``take``).
        ``timeout_s`` (seconds) bounds the connect, the hello and, by default, every later call.
        Raises :class:`ServerError` when the server refuses the hello, :class:`Timeout` or
        :class:`ClientError` on transport problems.
        """
        role_value = _ROLES[role] if isinstance(role, str) else int(role)
        if role_value == session_pb2.ROLE_DRIVER and not robot_id:
            raise ValueError("a driver session needs a robot_id")
        try:
            sock = socket.create_connection((host, int(port)), timeout=timeout_s)
        except socket.timeout as e:
            raise Timeout("timed out connecting to %s:%s" % (host, port)) from e
        except OSError as e:
            raise ClientError("cannot connect to %s:%s: %s" % (host, port, e)) from e
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        client = cls(sock, None, role, robot_id, world, timeout_s)
        try:
            message = session_pb2.ClientMessage()
            hello = message.hello
            hello.protocol_version = PROTOCOL_VERSION
            hello.role = role_value
            hello.robot_id = robot_id or ""
            hello.world = world or ""
            hello.auth_token = auth_token
            hello.client_name = client_name
            client._send(message)
            deadline = time.monotonic() + timeout_s
            while True:
                reply = client._receive(deadline)
                if reply is None:
                    raise Timeout("timed out waiting for the server's welcome")
                kind = reply.WhichOneof("body")
                if kind == "welcome":
                    client.welcome = reply.welcome
                    return client
                if kind == "error":
                    raise ServerError.from_message(reply)
        except BaseException:
            client.close()
            raise

    def close(self):
        """Closes the connection (a driver's robot stays registered, offline)."""
        if self._sock is not None:
            try:
                self._sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            self._sock.close()
            self._sock = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ----------------------------------------------------------------------------- framing

    def _send(self, message):
        if self._sock is None:
            raise ClientError("the connection is closed")
        payload = message.SerializeToString()
        try:
            self._sock.sendall(_varint(len(payload)) + payload)
        except OSError as e:
            raise ClientError("send failed: %s" % e) from e

    def _decode_one(self):
        """Decodes one ServerMessage from the buffer, or returns None if incomplete."""
        length, shift, pos = 0, 0, 0
        while True:
            if pos >= len(self._buffer):
                return None
            byte = self._buffer[pos]
            pos += 1
            length |= (byte & 0x7F) << shift
            if not byte & 0x80:
                break
            shift += 7
            if shift > 63:
                raise ClientError("server sent a malformed length prefix")
        if length > MAX_FRAME_BYTES:
            raise ClientError("server sent a frame over %d bytes" % MAX_FRAME_BYTES)
        if len(self._buffer) - pos < length:
            return None
        message = session_pb2.ServerMessage()
        try:
            message.ParseFromString(bytes(self._buffer[pos:pos + length]))
        except Exception as e:  # google.protobuf.message.DecodeError
            raise ClientError("server sent an undecodable frame: %s" % e) from e
        del self._buffer[:pos + length]
        return message

    def _receive(self, deadline):
        """The next ServerMessage, or None when ``deadline`` (time.monotonic()) passes."""
        while True:
            message = self._decode_one()
            if message is not None:
                return message
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            if self._sock is None:
                raise ClientError("the connection is closed")
            self._sock.settimeout(remaining)
            try:
                chunk = self._sock.recv(1 << 16)
            except socket.timeout:
                return None
            except OSError as e:
                raise ClientError("receive failed: %s" % e) from e
            if not chunk:
                raise ClientError("server closed the connection")
            self._buffer += chunk

    def _file(self, message):
        """Files a message that is not the one being waited for."""
        kind = message.WhichOneof("body")
        if kind == "scan_ack":
            self.scan_acks.append(message.scan_ack)
        elif kind == "motion_command":
            self.motion_commands.append(message.motion_command)
        elif kind == "watch_event":
            self.watch_events.append(message.watch_event)
        elif kind == "error" and message.request_id == 0:
            self.errors.append(ServerError.from_message(message))
        elif message.request_id != 0:  # a reply, or an Error answering a request
            self._replies[message.request_id] = message

    def _wait(self, predicate, timeout_s, what):
        """Receives until ``predicate(message)`` is true for a message, which is returned (others
        are filed). Raises :class:`Timeout` after ``timeout_s`` seconds."""
        deadline = time.monotonic() + (self.timeout_s if timeout_s is None else timeout_s)
        while True:
            message = self._receive(deadline)
            if message is None:
                raise Timeout("timed out waiting for " + what)
            if predicate(message):
                return message
            self._file(message)

    def _new_request_id(self):
        request_id = self._next_request_id
        self._next_request_id += 1
        return request_id

    def _call(self, body, fill, timeout_s=None):
        """Sends a request (``ClientMessage.<body>``, its request_id on the envelope), waits for the
        reply whose envelope carries that request_id and returns the reply's body; raises
        :class:`ServerError` for an ``Error`` reply."""
        request_id = self._new_request_id()
        message = session_pb2.ClientMessage()
        message.request_id = request_id
        request = getattr(message, body)
        request.SetInParent()  # the body is sent even when fill leaves every field at its default
        fill(request)
        self._send(message)
        reply = self._replies.pop(request_id, None)
        if reply is None:
            reply = self._wait(lambda m: m.request_id == request_id, timeout_s,
                               "the reply to request %d (%s)" % (request_id, body))
        if reply.WhichOneof("body") == "error":
            raise ServerError.from_message(reply)
        return getattr(reply, reply.WhichOneof("body"))

    # ----------------------------------------------------------------------------- queries

    def status(self, detailed=False, timeout_s=None):
        """The server's ``StatusReply``: ``robots`` (id, world, pose, scans ...), ``worlds`` (name,
        cell_size_m, version, occupied_cells, PTEM and OctoMap counts), ``clients``, ``uptime_s``.
        ``detailed``: each robot also carries ``path`` (its planned path) and ``scan`` (its first
        laser's latest returns, at ``scan_stamp_s``), world frame, metres; heavier, so off by default."""

        def fill(r):
            r.detailed = bool(detailed)
        return self._call("status", fill, timeout_s)

    def collision(self, robot, x, y, theta=0.0, models=None, footprint=None, timeout_s=None):
        """Is robot ``robot``'s footprint at pose (x, y, theta) — ``base_link`` in the world frame,
        metres and radians — in collision with its world's models?

        ``models``: None or empty for all three (grid, octomap, ptem), else a list of ``"grid"``,
        ``"octomap"``, ``"ptem"`` (or ``query_pb2.MODEL_*`` values), or a comma-separated string.
        ``footprint``: an optional ``robot_pb2.Footprint`` overriding the robot's own.
        Returns the ``CollisionReply``: ``hit``, ``model`` (first model hit), ``contact`` (world,
        metres), ``cell`` / ``cell_center`` (GRID hit), ``cells_tested``.
        Raises :class:`ServerError` (e.g. ``ERROR_UNKNOWN_ROBOT`` naming ``collision.robot_id``).
        """
        model_values = _model_list(models)

        def fill(q):
            q.robot_id = robot
            q.pose.CopyFrom(_pose2d(x, y, theta))
            q.models.extend(model_values)
            if footprint is not None:
                q.footprint.CopyFrom(footprint)
        return self._call("collision", fill, timeout_s)

    def clearance(self, robot, x, y, theta=0.0, models=None, max_distance_m=0.0, footprint=None, timeout_s=None):
        """Distance (metres) from robot ``robot``'s footprint at pose (x, y, theta) — ``base_link``
        in the world frame — to the nearest obstacle of the asked models (see :meth:`collision` for
        ``models`` and ``footprint``), searching up to ``max_distance_m`` (0: the server's default,
        5 m). Returns the ``ClearanceReply``: ``found``, ``clearance_m`` (0 in collision,
        ``max_distance_m`` when not found), ``model``, ``nearest_cell``, ``nearest_point`` (world, m);
        when the PTEM is asked, ``keep_out`` and ``restricted_clearance_m``: the PTEM's restricted region,
        reported beside the clearance to matter and never counted in it.
        """
        model_values = _model_list(models)

        def fill(q):
            q.robot_id = robot
            q.pose.CopyFrom(_pose2d(x, y, theta))
            q.max_distance_m = float(max_distance_m)
            q.models.extend(model_values)
            if footprint is not None:
                q.footprint.CopyFrom(footprint)
        return self._call("clearance", fill, timeout_s)

    def collision_batch(self, robot, poses, models=None, footprint=None, timeout_s=None):
        """Collision of robot ``robot``'s footprint at many poses ``[(x, y, theta), ...]`` in one request.
        Returns the ``CollisionBatchReply``: ``results`` (one ``CollisionReply`` per pose, as
        :meth:`collision` would answer it) and ``hits``."""
        model_values = _model_list(models)

        def fill(q):
            q.robot_id = robot
            q.poses.extend(_pose2d(*p) for p in poses)
            q.models.extend(model_values)
            if footprint is not None:
                q.footprint.CopyFrom(footprint)
        return self._call("collision_batch", fill, timeout_s)

    def clearance_batch(self, robot, poses, models=None, max_distance_m=0.0, footprint=None, timeout_s=None):
        """Clearance (with gradient) at many poses in one request; ``results`` holds one ``ClearanceReply``
        per pose."""
        model_values = _model_list(models)

        def fill(q):
            q.robot_id = robot
            q.poses.extend(_pose2d(*p) for p in poses)
            q.max_distance_m = float(max_distance_m)
            q.models.extend(model_values)
            if footprint is not None:
                q.footprint.CopyFrom(footprint)
        return self._call("clearance_batch", fill, timeout_s)

    def raycast(self, rays, max_range_m, world="", models=None, height_m=0.0, timeout_s=None):
        """Planar rays ``[(x, y, theta), ...]`` (world frame): ``RaycastReply.results``, one per ray, with
        ``hit``, ``range_m``, ``model`` and ``per_model``."""
        model_values = _model_list(models)

        def fill(q):
            q.world = world
            q.rays.extend(_pose2d(*r) for r in rays)
            q.max_range_m = float(max_range_m)
            q.height_m = float(height_m)
            q.models.extend(model_values)
        return self._call("raycast", fill, timeout_s)

    def occupancy(self, points, world="", models=None, timeout_s=None):
        """Grid certainty, octree probability and PTEM threat at points ``[(x, y, z), ...]`` (world frame):
        ``OccupancyReply.samples``, one per point."""
        model_values = _model_list(models)

        def fill(q):
            q.world = world
            for x, y, z in points:
                q.points.add(x=float(x), y=float(y), z=float(z))
            q.models.extend(model_values)
        return self._call("occupancy", fill, timeout_s)

    def swept(self, robot, start, linear_mps, angular_radps, duration_s, models=None, footprint=None, timeout_s=None):
        """Does robot ``robot``'s footprint moving from ``start`` (x, y, theta) at (v, w) for ``duration_s``
        touch anything, and when first? Returns the ``SweptResult`` (``hit``, ``time_s``, ``pose``,
        ``model``, ``contact``)."""
        model_values = _model_list(models)

        def fill(q):
            q.robot_id = robot
            q.models.extend(model_values)
            if footprint is not None:
                q.footprint.CopyFrom(footprint)
            motion = q.motions.add()
            motion.start.CopyFrom(_pose2d(*start))
            motion.linear_mps = float(linear_mps)
            motion.angular_radps = float(angular_radps)
            motion.duration_s = float(duration_s)
        return self._call("swept", fill, timeout_s).results[0]

    def grid_window(self, min_x, min_y, max_x, max_y, world="", since_version=0, timeout_s=60.0):
        """A window of the grid for the box [min, max] (world frame, metres): ``GridWindowReply`` with the
        whole window in ``cells`` (``since_version`` 0) or only the blocks changed since ``since_version``
        in ``changed`` (see :class:`GridFollower`)."""
        def fill(q):
            q.world = world
            q.min_corner.x, q.min_corner.y = float(min_x), float(min_y)
            q.max_corner.x, q.max_corner.y = float(max_x), float(max_y)
            q.since_version = int(since_version)
        return self._call("grid_window", fill, timeout_s)

    def ptem(self, world, points, include_clusters=False, timeout_s=None):
        """Evaluates world ``world``'s probabilistic threat exposure map (``""``: the default world)
        at ``points``, an iterable of (x, y) world-frame positions in metres.

        Returns the ``PtemReply``: one ``PtemSample {threat (1/m²), gradient (world, 1/m³),
        restricted}`` per point in order, ``threshold_f_r``, ``cluster_count``, ``scans``,
        ``construction``, ``version`` and, with ``include_clusters``, ``clusters`` (``center`` world
        metres, ``radius_m``, ``sigma_m``, ages). Raises ``ERROR_UNKNOWN_WORLD`` for a missing world.
        """
        point_list = [common_pb2.Point2D(x=float(p[0]), y=float(p[1])) for p in points]

        def fill(q):
            q.world = world or ""
            q.points.extend(point_list)
            q.include_clusters = bool(include_clusters)
        return self._call("ptem", fill, timeout_s)

    def grid(self, world="", timeout_s=60.0):
        """World ``world``'s whole HIMM grid (its bounding box of allocated tiles) as a
        :class:`CertaintyWindow` (``cells`` bytes + geometry; ``rows()`` gives a list of rows).
        ``world`` ``""`` is the default world; a missing one raises ``ERROR_UNKNOWN_WORLD``."""
        def fill(q):
            q.world = world or ""
        return CertaintyWindow.from_proto(self._call("grid", fill, timeout_s))

    def export_map(self, world, prefix, timeout_s=60.0):
        """Writes world ``world``'s grid as a ROS map_server map, ``PREFIX.pgm`` and
        ``PREFIX.yaml``, with the same certainty → grey encoding, thresholds and bytes as
        ``occgeo map export --format pgm``. Returns the :class:`CertaintyWindow` exported.
        Raises :class:`ClientError` if the world has no observed cell yet (nothing is written)."""
        from occgeo import mapfile

        window = self.grid(world, timeout_s)
        if window.width == 0 or window.height == 0:
            raise ClientError("world '%s' has no cells observed yet; nothing written" % window.world)
        mapfile.write_map(prefix, mapfile.image_from_certainty(window))
        return window

    def octree(self, world="", timeout_s=60.0):
        """World ``world``'s OctoMap: the ``OctreeReply`` (``bt`` the .bt file's bytes,
        ``resolution_m``, ``node_count``, ``leaf_count``, ``version``)."""
        def fill(q):
            q.world = world or ""
        return self._call("octree", fill, timeout_s)

    def export_octree(self, world, path, timeout_s=60.0):
        """Writes world ``world``'s OctoMap as an OctoMap binary file (.bt) at ``path``; returns
        the ``OctreeReply`` (its ``bt`` is what was written)."""
        reply = self.octree(world, timeout_s)
        with open(path, "wb") as out:
            out.write(reply.bt)
        return reply

    def octree_window(self, min_corner, max_corner, world="", timeout_s=60.0):
        """The OctoMap's occupied leaves overlapping the box [``min_corner``, ``max_corner``] ((x, y, z), world
        frame, metres): ``OctreeWindowReply`` with ``voxels`` (``center``, ``size_m``, ``probability``),
        ``resolution_m`` and ``version``."""
        def fill(q):
            q.world = world or ""
            q.min_corner.x, q.min_corner.y, q.min_corner.z = (float(v) for v in min_corner)
            q.max_corner.x, q.max_corner.y, q.max_corner.z = (float(v) for v in max_corner)
        return self._call("octree_window", fill, timeout_s)

    # ----------------------------------------------------------------------------- watch

    def watch(self, world="", robot_id="", timeout_s=None):
        """Subscribes this session (observer or controller) to one ``WatchEvent`` per sensor message the
        server acknowledges for robot ``robot_id`` of world ``world`` (empty: every robot, every world);
        a new call replaces the filter. Events arrive in :attr:`watch_events`; read them with
        :meth:`next_watch_event`. Returns the ``WatchReply``."""
        def fill(q):
            q.world = world or ""
            q.robot_id = robot_id or ""
        return self._call("watch", fill, timeout_s)

    def next_watch_event(self, timeout_s=None):
        """The oldest ``WatchEvent`` not yet consumed (``world``, ``robot_id``, ``seq``, ``world_version``,
        ``dropped_since_last``: events the server dropped just before this one because this client read
        too slowly), waiting up to ``timeout_s``; raises :class:`Timeout` when none arrives."""
        if self.watch_events:
            return self.watch_events.popleft()
        return self._wait(lambda m: m.WhichOneof("body") == "watch_event", timeout_s, "a watch event").watch_event

    def poll(self, duration_s):
        """Reads (and files) whatever the server sends for ``duration_s`` seconds: watch events, motion
        commands, errors. Returns the number of messages received."""
        deadline = time.monotonic() + duration_s
        received = 0
        while True:
            message = self._receive(deadline)
            if message is None:
                return received
            self._file(message)
            received += 1

    # ----------------------------------------------------------------------------- control

    def lease(self, robot, action, timeout_s=0.0, call_timeout_s=None):
        """One ``LeaseRequest`` for robot ``robot`` (controller sessions): ``action`` ``"acquire"``,
        ``"retain"``, ``"return"`` or ``"take"`` (operator sessions only); ``timeout_s`` the lease's timeout
        in seconds (0: the server's ``control.lease_timeout_s``). Returns the ``LeaseReply`` (``granted``,
        ``holder``, ``expires_in_s``), whether granted or not; see :meth:`hold_lease`."""
        action_value = _LEASE_ACTIONS[action] if isinstance(action, str) else int(action)

        def fill(q):
            q.robot_id = robot
            q.action = action_value
            q.timeout_s = float(timeout_s)
        return self._call("lease", fill, call_timeout_s)

    def hold_lease(self, robot, timeout_s=2.0, take=False):
        """Acquires (``take``: takes) robot ``robot``'s lease and returns a :class:`Lease`, which keeps it
        with :meth:`Lease.keep_alive` and returns it on :meth:`Lease.release` or leaving a ``with`` block.
        Raises :class:`LeaseRefused` when someone else holds it."""
        action = "take" if take else "acquire"
        reply = self.lease(robot, action, timeout_s)
        if not reply.granted:
            raise LeaseRefused(reply, action)
        return Lease(self, robot, timeout_s, reply)

    def drive(self, robot, behaviour, linear_mps=0.0, angular_radps=0.0, goal=None, waypoints=None, escape=False,
              timeout_s=None):
        """Sets robot ``robot``'s behaviour (the session must hold its lease): one of :data:`BEHAVIOURS` or a
        ``control_pb2.Behaviour`` value.
        ``teleop`` drives at ``linear_mps`` (m/s, forward along ``base_link`` x) and ``angular_radps``
        (rad/s, counter-clockwise); ``goto`` needs ``goal`` (x, y), world frame, metres; ``waypoints`` a
        list of (x, y); ``escape`` follows a global path when the behaviour stalls. Returns the
        ``DriveReply`` (teleop velocities after clamping to the robot's limits, ``estop``). Raises
        :class:`ServerError` (``ERROR_NOT_ALLOWED`` naming ``drive.robot_id`` without the lease)."""
        def fill(q):
            q.robot_id = robot
            q.behaviour = behaviour_value(behaviour)
            q.linear_mps = float(linear_mps)
            q.angular_radps = float(angular_radps)
            if goal is not None:
                q.goal.x_m, q.goal.y_m = float(goal[0]), float(goal[1])
            for x, y in waypoints or ():
                q.waypoints.add(x_m=float(x), y_m=float(y))
            q.escape = bool(escape)
        return self._call("drive", fill, timeout_s)

    def teleop(self, robot, linear_mps, angular_radps, timeout_s=None):
        """:meth:`drive` with behaviour ``teleop``: drive robot ``robot`` at (``linear_mps``, ``angular_radps``)."""
        return self.drive(robot, "teleop", linear_mps, angular_radps, timeout_s=timeout_s)

    def estop(self, robot, engage=True, timeout_s=None):
        """Engages robot ``robot``'s e-stop (any driver, controller or observer session; it latches), or
        with ``engage=False`` releases it (only the lease holder). Returns the ``EStopReply`` (``engaged``,
        ``holder``)."""
        def fill(q):
            q.robot_id = robot
            q.engage = bool(engage)
        return self._call("estop", fill, timeout_s)

    # ----------------------------------------------------------------------------- driver

    def sync(self, timeout_s=None):
        """Round trip (a status request): when it returns, the server has handled every message
        sent before; raises the first :class:`ServerError` about them (robot spec, odometry,
        sensor data) that arrived meanwhile."""
        self.errors.clear()
        self.status(timeout_s=timeout_s)
        if self.errors:
            raise self.errors.popleft()

    def send_robot_spec(self, spec, confirm=True, timeout_s=None):
        """Sends the driver's ``robot_pb2.RobotSpec`` (once, first thing after connecting; see
        :func:`occgeo.laser_robot_spec`). With ``confirm``, waits until the server has handled it
        and raises :class:`ServerError` (e.g. ``ERROR_INVALID_ARGUMENT`` naming
        ``robot_spec.sensors[0].laser.beam_count``) if it was refused."""
        message = session_pb2.ClientMessage()
        message.robot_spec.CopyFrom(spec)
        self._send(message)
        if confirm:
            self.sync(timeout_s)

    def _stamp(self, stamp_s):
        if stamp_s is None:
            stamp_s = max(time.time(), self._last_stamp_s)
        self._last_stamp_s = max(self._last_stamp_s, stamp_s)
        return float(stamp_s)

    def send_odometry(self, x, y, theta, stamp_s=None, linear_mps=0.0, angular_radps=0.0, seq=None,
                      confirm=False, timeout_s=None):
        """Sends the robot's pose — ``base_link`` in the world frame, (x, y) metres, theta radians —
        and its body velocity (m/s, rad/s). ``stamp_s`` (seconds, driver clock, must not go
        backwards; default: wall time, never before the last stamp sent) and ``seq`` (default: the
        next one) are filled when None. No reply when accepted; ``confirm`` does a :meth:`sync`."""
        message = session_pb2.ClientMessage()
        odometry = message.odometry
        if seq is None:
            seq = self._next_odometry_seq
        self._next_odometry_seq = max(self._next_odometry_seq, seq + 1)
        odometry.seq = seq
        odometry.stamp_s = self._stamp(stamp_s)
        odometry.pose.CopyFrom(_pose2d(x, y, theta))
        odometry.linear_mps = float(linear_mps)
        odometry.angular_radps = float(angular_radps)
        self._send(message)
        if confirm:
            self.sync(timeout_s)

    def send_laser_scan(self, sensor, ranges, stamp_s=None, seq=None, timeout_s=None):
        """Sends one sweep of laser ``sensor`` (its ``SensorSpec.name``): exactly ``beam_count``
        ranges in metres (>= ``range_max_m``: no return), placed at the robot's latest pose.
        ``seq`` (default: the next of the robot's one sensor sequence) and ``stamp_s`` (seconds,
        default wall time) are filled when None; an automatic seq that the server refused is
        used again by the next message.

        Waits for and returns the ``ScanAck {seq, world_version}`` (the map holds the scan: a query
        sent afterwards sees it). Raises :class:`ServerError` if the scan is refused (e.g.
        ``ERROR_INVALID_ARGUMENT`` naming ``laser_scan.ranges[17]``). A ``MotionCommand`` answering
        the scan, if any, is appended to :attr:`motion_commands`.
        """
        message = session_pb2.ClientMessage()
        scan = message.laser_scan
        auto_seq = seq is None
        if seq is None:
            seq = self._next_seq
        self._next_seq = max(self._next_seq, seq + 1)
        scan.sensor = sensor
        scan.seq = seq
        scan.stamp_s = self._stamp(stamp_s)
        scan.ranges.extend(float(r) for r in ranges)
        self._send(message)
        try:
            return self._wait_scan_ack(seq, "laser_scan", timeout_s)
        except ServerError:
            if auto_seq and self._next_seq == seq + 1:
                self._next_seq = seq  # a rejected message's seq may be used again
            raise

    def _wait_scan_ack(self, seq, kind, timeout_s):
        for i, ack in enumerate(self.scan_acks):
            if ack.seq == seq:
                del self.scan_acks[i]
                return ack

        def matches(m):
            body = m.WhichOneof("body")
            if body == "scan_ack":
                return m.scan_ack.seq == seq
            if body == "error" and m.request_id == 0:
                return m.error.seq == seq or (m.error.seq == 0 and m.error.field.startswith(kind))
            return False
        reply = self._wait(matches, timeout_s, "the ScanAck of %s seq %d" % (kind, seq))
        if reply.WhichOneof("body") == "error":
            raise ServerError.from_message(reply)
        return reply.scan_ack


class Lease:
    """A control lease this client holds (from :meth:`Client.hold_lease`). The server lets it lapse — and
    stops the robot — unless it is retained within its timeout: call :meth:`keep_alive` often (it
    retains once a third of the timeout has passed), e.g. from the loop that watches the robot. Used as
    a context manager, the lease is returned when the block ends."""

    def __init__(self, client, robot, timeout_s, reply):
        self.client = client
        self.robot = robot
        self.timeout_s = timeout_s  #: seconds; 0 means the server's control.lease_timeout_s
        self.reply = reply  #: the latest ``LeaseReply``
        self.held = True
        self._retained_at = time.monotonic()

    def retain(self):
        """Renews the lease now; raises :class:`LeaseRefused` if it was lost (lapsed or taken)."""
        reply = self.client.lease(self.robot, "retain", self.timeout_s)
        self._retained_at = time.monotonic()
        self.reply = reply
        if not reply.granted:
            self.held = False
            raise LeaseRefused(reply, "retain")
        return reply

    def keep_alive(self):
        """Retains the lease if a third of its timeout (or of the server's, when the reply says how long)
        has passed since the last renewal; cheap to call often."""
        period = self.timeout_s or self.reply.expires_in_s or 2.0
        if time.monotonic() - self._retained_at >= period / 3.0:
            self.retain()

    def sleep(self, duration_s):
        """Waits ``duration_s`` seconds, filing what the server sends and keeping the lease alive."""
        deadline = time.monotonic() + duration_s
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return
            self.keep_alive()
            period = self.timeout_s or self.reply.expires_in_s or 2.0
            self.client.poll(min(remaining, period / 6.0))

    def release(self):
        """Returns the lease (a ``teleop`` behaviour becomes ``stop``); returns the ``LeaseReply``."""
        if not self.held:
            return self.reply
        self.held = False
        self.reply = self.client.lease(self.robot, "return")
        return self.reply

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.client._sock is not None:
            self.release()


class GridFollower:
    """Follows a window of a world's grid incrementally: :meth:`update` fetches only the blocks changed
    since the version held and writes them into :attr:`cells` (row-major bytes, row 0 at the window's
    lowest y, 255 = never observed)."""

    def __init__(self, client, min_x, min_y, max_x, max_y, world=""):
        self._client = client
        self._box = (min_x, min_y, max_x, max_y)
        self._world = world
        self.version = 0
        self.width = 0
        self.height = 0
        self.min_cell = (0, 0)
        self.cells = bytearray()

    def update(self):
        """Brings :attr:`cells` to the grid's current version; returns the number of cells received."""
        reply = self._client.grid_window(*self._box, world=self._world, since_version=self.version)
        self.width, self.height = reply.width, reply.height
        self.min_cell = (reply.min_cell.ix, reply.min_cell.iy)
        received = 0
        if reply.cells or self.version == 0:
            self.cells = bytearray(reply.cells)
            received = len(reply.cells)
        for block in reply.changed:
            for row in range(block.height):
                start = (block.min_cell.iy - reply.min_cell.iy + row) * reply.width + (block.min_cell.ix - reply.min_cell.ix)
                self.cells[start:start + block.width] = block.cells[row * block.width:(row + 1) * block.width]
            received += len(block.cells)
        self.version = reply.version
        return received

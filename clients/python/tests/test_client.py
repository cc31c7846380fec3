"""Integration tests of the Python client against a real occgeod and the C++ CLI.

Needs the environment CTest sets (clients/CMakeLists.txt): PYTHONPATH with clients/python and
<build>/clients/python (generated occgeo.v1 modules), and OCCGEO_BINARY_DIR (the build tree) or
OCCGEOD / OCCGEO_CLI (the two executables).
"""

import json
import math
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
import unittest

import occgeo
from occgeo.specs import laser_robot_spec
from google.protobuf import json_format

from occgeo.v1 import query_pb2, session_pb2

ROBOT = "py-bot"
WORLD = "pyworld"
SCANS = 6
WALL_X_M = 2.0       # a wall across the robot's path, x = 2 m in the world frame
WALL_HALF_WIDTH_M = 1.5
START_TIMEOUT_S = 15.0
STOP_TIMEOUT_S = 15.0
CLI_TIMEOUT_S = 20.0


def _executable(env_name, relative):
    path = os.environ.get(env_name)
    if not path:
        binary_dir = os.environ.get("OCCGEO_BINARY_DIR")
        if not binary_dir:
            raise unittest.SkipTest("set OCCGEO_BINARY_DIR (or %s) to run the integration tests" % env_name)
        path = os.path.join(binary_dir, relative)
    if not os.access(path, os.X_OK):
        raise AssertionError("%s is not an executable (build the occgeod and occgeo targets)" % path)
    return path


def wall_scan(spec):
    """Ranges of the spec's laser, standing at the world origin facing +x, seeing the wall."""
    laser = spec.sensors[0].laser
    ranges = []
    for k in range(laser.beam_count):
        angle = laser.angle_min_rad + k * laser.angle_increment_rad
        c = math.cos(angle)
        r = laser.range_max_m
        if c > 1e-6:
            d = WALL_X_M / c
            if abs(d * math.sin(angle)) <= WALL_HALF_WIDTH_M and d < laser.range_max_m:
                r = d
        ranges.append(r)
    return ranges


MODEL_NAMES = {query_pb2.MODEL_GRID: "grid", query_pb2.MODEL_OCTOMAP: "octomap", query_pb2.MODEL_PTEM: "ptem"}


def cli_reply(text, reply_type):
    """The reply a `occgeo ... --json` printed (protobuf's JSON mapping of it), parsed back into its message."""
    return json_format.Parse(text, reply_type())


class ServerTestCase(unittest.TestCase):
    """Each test gets its own occgeod (random port, temporary data dir), stopped when it ends."""

    def setUp(self):
        self.start_server()

    def start_server(self, extra_args=()):
        self.occgeod = _executable("OCCGEOD", os.path.join("service", "occgeod"))
        self.cli = _executable("OCCGEO_CLI", os.path.join("clients", "occgeo"))
        self.tmp = tempfile.mkdtemp(prefix="occgeo-python-test-")
        self.addCleanup(shutil.rmtree, self.tmp, True)
        port_file = os.path.join(self.tmp, "port")
        self.log = open(os.path.join(self.tmp, "occgeod.log"), "wb")
        self.addCleanup(self.log.close)
        self.server = subprocess.Popen(
            [self.occgeod, "--listen", "127.0.0.1:0", "--port-file", port_file,
             "--data-dir", os.path.join(self.tmp, "data"), "--log-level", "warn"] + list(extra_args),
            stdout=self.log, stderr=subprocess.STDOUT)
        self.addCleanup(self._stop_server)  # runs even when setUp fails below
        self.port = self._wait_for_port(port_file)
        self.addCleanup(self._close_clients)
        self.clients = []

    def tearDown(self):
        pass  # the cleanups registered in start_server close the clients and stop the server (SIGINT)

    # -------------------------------------------------------------------------------- helpers

    def _wait_for_port(self, port_file):
        deadline = time.monotonic() + START_TIMEOUT_S
        while time.monotonic() < deadline:
            if self.server.poll() is not None:
                self.fail("occgeod exited with %s: %s" % (self.server.returncode, self._server_log()))
            try:
                with open(port_file) as f:
                    text = f.read().strip()
                if text:
                    return int(text)
            except (OSError, ValueError):
                pass
            time.sleep(0.05)
        self.fail("occgeod wrote no port within %.0f s" % START_TIMEOUT_S)

    def _server_log(self):
        self.log.flush()
        with open(self.log.name, "rb") as f:
            return f.read()[-4000:].decode(errors="replace")

    def _stop_server(self):
        if self.server.poll() is None:
            self.server.send_signal(signal.SIGINT)
            try:
                self.server.wait(timeout=STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.server.kill()
                self.server.wait(timeout=STOP_TIMEOUT_S)
                raise AssertionError("occgeod did not stop on SIGINT within %.0f s" % STOP_TIMEOUT_S)

    def _close_clients(self):
        for client in self.clients:
            client.close()

    def connect(self, **kwargs):
        client = occgeo.Client.connect("127.0.0.1", self.port, timeout_s=10.0, **kwargs)
        self.clients.append(client)
        return client

    def run_cli(self, *args, check=True):
        result = subprocess.run([self.cli] + list(args) + ["--server", "127.0.0.1:%d" % self.port],
                                capture_output=True, timeout=CLI_TIMEOUT_S)
        if check:
            self.assertEqual(result.returncode, 0,
                             "occgeo %s failed: %s" % (" ".join(args), result.stderr.decode()))
        return result.stdout.decode() if check else result


class ClientTest(ServerTestCase):
    """Each test gets its own occgeod holding a world mapped by SCANS laser scans of a wall, streamed by
    this client as a driver."""

    def setUp(self):
        self.start_server()
        self.spec = laser_robot_spec(model="python-test")
        self.acks = self._stream_wall()
        self._wait_for_octree()
        self.query = self.connect()

    def _stream_wall(self):
        driver = self.connect(role="driver", robot_id=ROBOT, world=WORLD)
        driver.send_robot_spec(self.spec)
        driver.send_odometry(0.0, 0.0, 0.0, stamp_s=1.0, confirm=True)
        ranges = wall_scan(self.spec)
        acks = [driver.send_laser_scan("laser", ranges, stamp_s=1.0 + 0.1 * i) for i in range(SCANS)]
        driver.close()  # the robot stays registered, offline: queries still use its footprint
        return acks

    def _wait_for_octree(self):
        """Waits until the published octree holds every scan (it lags up to
        octomap.min_publish_interval_s), so both clients query the same snapshot."""
        client = self.connect()
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            worlds = {w.name: w for w in client.status().worlds}
            if WORLD in worlds and worlds[WORLD].octomap_version >= SCANS:
                return
            time.sleep(0.1)
        self.fail("the octree snapshot did not catch up with %d scans" % SCANS)

    # -------------------------------------------------------------------------------- tests

    def test_driver_acks_and_status(self):
        self.assertEqual([a.seq for a in self.acks], list(range(1, SCANS + 1)))
        versions = [a.world_version for a in self.acks]
        self.assertEqual(versions, sorted(versions))
        self.assertEqual(len(set(versions)), SCANS)
        status = self.query.status()
        robots = {r.id: r for r in status.robots}
        self.assertIn(ROBOT, robots)
        self.assertEqual(robots[ROBOT].world, WORLD)
        self.assertEqual(robots[ROBOT].scans_ingested, SCANS)
        self.assertFalse(robots[ROBOT].connected)
        self.assertGreater({w.name: w for w in status.worlds}[WORLD].occupied_cells, 0)

    def test_driver_errors(self):
        driver = self.connect(role="driver", robot_id="py-bot-2", world=WORLD)
        with self.assertRaises(occgeo.ServerError) as caught:
            driver.send_laser_scan("laser", [1.0] * 181, stamp_s=1.0)  # before the spec
        self.assertEqual(caught.exception.code, session_pb2.ERROR_OUT_OF_ORDER)
        bad = laser_robot_spec()
        bad.sensors[0].laser.beam_count = 0
        with self.assertRaises(occgeo.ServerError) as caught:
            driver.send_robot_spec(bad)
        self.assertEqual(caught.exception.code, session_pb2.ERROR_INVALID_ARGUMENT)
        self.assertEqual(caught.exception.field, "robot_spec.sensors[0].laser.beam_count")
        driver.send_robot_spec(self.spec)
        driver.send_odometry(0.0, 0.0, 0.0, stamp_s=1.0, confirm=True)
        with self.assertRaises(occgeo.ServerError) as caught:
            driver.send_laser_scan("laser", [1.0] * 180, stamp_s=1.0)  # one range short
        self.assertEqual(caught.exception.code, session_pb2.ERROR_INVALID_ARGUMENT)
        self.assertTrue(caught.exception.field.startswith("laser_scan.ranges"), caught.exception.field)
        self.assertEqual(driver.send_laser_scan("laser", wall_scan(self.spec), stamp_s=1.0).seq, 1)  # refused seqs are reused

    def test_hello_refused(self):
        with self.assertRaises(occgeo.ServerError) as caught:
            self.connect(role="driver", robot_id="not a valid id!", world=WORLD)
        self.assertEqual(caught.exception.code, session_pb2.ERROR_INVALID_ARGUMENT)
        self.assertEqual(caught.exception.field, "hello.robot_id")

    def test_collision_and_clearance_match_cli(self):
        poses = []
        for x in (0.0, 0.9, 1.5, 1.62, 1.75, 2.3, 3.0):
            for theta in (0.0, 0.7, -1.2):
                poses.append((x, 0.37 * (x - 1.0), theta))
        self.assertGreaterEqual(len(poses), 20)
        hits = 0
        for x, y, theta in poses:
            pose_args = ["--robot", ROBOT, "--x", repr(x), "--y", repr(y), "--theta", repr(theta), "--json"]
            collision = self.query.collision(ROBOT, x, y, theta)
            clearance = self.query.clearance(ROBOT, x, y, theta)
            hits += collision.hit
            with self.subTest(pose=(x, y, theta)):
                self.assertEqual(collision, cli_reply(self.run_cli("query", "collision", *pose_args), query_pb2.CollisionReply))
                self.assertEqual(clearance, cli_reply(self.run_cli("query", "clearance", *pose_args), query_pb2.ClearanceReply))
                if collision.hit:
                    self.assertEqual(clearance.clearance_m, 0.0)
        self.assertGreater(hits, 0, "no pose hit the wall")
        self.assertLess(hits, len(poses), "every pose hit the wall")
        # One model at a time, as the CLI's --models.
        for models in ("grid", "octomap", "ptem"):
            pose_args = ["--robot", ROBOT, "--x", "1.0", "--y", "0.2", "--theta", "0.3", "--models", models, "--json"]
            self.assertEqual(self.query.clearance(ROBOT, 1.0, 0.2, 0.3, models=[models]),
                             cli_reply(self.run_cli("query", "clearance", *pose_args), query_pb2.ClearanceReply))
            hit_args = ["--robot", ROBOT, "--x", "1.75", "--y", "0", "--theta", "0", "--models", models, "--json"]
            hit = self.query.collision(ROBOT, 1.75, 0.0, 0.0, models=models)
            self.assertTrue(hit.hit, "the footprint overlapping the wall does not hit the " + models)
            self.assertEqual(MODEL_NAMES[hit.model], models)
            self.assertEqual(hit, cli_reply(self.run_cli("query", "collision", *hit_args), query_pb2.CollisionReply))

    def test_unknown_robot_raises(self):
        for method, field in ((self.query.collision, "collision.robot_id"),
                              (self.query.clearance, "clearance.robot_id")):
            with self.assertRaises(occgeo.ServerError) as caught:
                method("no-such-robot", 0.0, 0.0, 0.0)
            error = caught.exception
            self.assertEqual(error.code, session_pb2.ERROR_UNKNOWN_ROBOT)
            self.assertEqual(error.code_name, "ERROR_UNKNOWN_ROBOT")
            self.assertEqual(error.field, field)
            self.assertIn("no-such-robot", error.message)
        # The session goes on after an error.
        self.assertTrue(self.query.collision(ROBOT, 1.75, 0.0, 0.0).hit)
        with self.assertRaises(occgeo.ServerError) as caught:
            self.query.grid("no-such-world")
        self.assertEqual(caught.exception.code, session_pb2.ERROR_UNKNOWN_WORLD)

    def test_export_map_matches_cli(self):
        os.mkdir(os.path.join(self.tmp, "py"))
        os.mkdir(os.path.join(self.tmp, "cli"))
        py_prefix = os.path.join(self.tmp, "py", "map")
        cli_prefix = os.path.join(self.tmp, "cli", "map")
        window = self.query.export_map(WORLD, py_prefix)
        self.run_cli("map", "export", "--world", WORLD, "--out", cli_prefix)
        for ext in (".pgm", ".yaml"):
            with open(py_prefix + ext, "rb") as a, open(cli_prefix + ext, "rb") as b:
                self.assertEqual(a.read(), b.read(), "%s differs from the C++ export" % ext)
        # The occupied pixels are the grid's occupied cells, and the wall is among them.
        levels = occgeo.CertaintyGreyLevels(window.max_certainty, window.occupied_threshold)
        with open(py_prefix + ".pgm", "rb") as f:
            pgm = f.read()
        header = b"P5\n%d %d\n255\n" % (window.width, window.height)
        self.assertTrue(pgm.startswith(header))
        pixels = pgm[len(header):]
        occupied = set()
        for i, grey in enumerate(pixels):
            if (255 - grey) / 255.0 > levels.occupied_thresh:
                row, col = divmod(i, window.width)
                occupied.add((window.min_ix + col, window.min_iy + window.height - 1 - row))
        self.assertEqual(occupied, window.occupied_cells())
        wall_ix = int(math.floor(WALL_X_M / window.cell_size_m))
        self.assertTrue(any(abs(ix - wall_ix) <= 1 and abs(iy) <= 2 for ix, iy in occupied))

    def test_grid_window(self):
        window = self.query.grid(WORLD)
        self.assertEqual(len(window.cells), window.width * window.height)
        rows = window.rows()
        self.assertEqual(len(rows), window.height)
        self.assertTrue(all(len(r) == window.width for r in rows))
        self.assertEqual(window.version, self.acks[-1].world_version)
        cs = window.cell_size_m
        wall = [(ix, iy) for ix, iy in window.occupied_cells() if abs((ix + 0.5) * cs - WALL_X_M) <= 2 * cs]
        self.assertGreater(len(wall), 10)
        # The robot's own cell was traced through: free, not unobserved.
        self.assertNotEqual(window.value(0, 0), window.UNOBSERVED)
        self.assertFalse(window.is_occupied(0, 0))

    def test_ptem_clusters(self):
        reply = self.query.ptem(WORLD, [(WALL_X_M, 0.0), (0.0, 0.0)], include_clusters=True)
        self.assertEqual(reply.world, WORLD)
        self.assertEqual(reply.scans, SCANS)
        self.assertGreater(reply.cluster_count, 0)
        self.assertEqual(len(reply.clusters), reply.cluster_count)
        for cluster in reply.clusters:
            self.assertAlmostEqual(cluster.center.x, WALL_X_M, delta=0.5)
            self.assertLessEqual(abs(cluster.center.y), WALL_HALF_WIDTH_M + 0.5)
        self.assertEqual(len(reply.samples), 2)
        self.assertGreater(reply.samples[0].threat, reply.samples[1].threat)
        self.assertEqual(len(self.query.ptem(WORLD, [(0.0, 0.0)]).clusters), 0)  # only when asked

    def test_export_octree(self):
        path = os.path.join(self.tmp, "world.bt")
        reply = self.query.export_octree(WORLD, path)
        with open(path, "rb") as f:
            data = f.read()
        self.assertEqual(data, reply.bt)
        self.assertTrue(data.startswith(b"# Octomap OcTree binary file"), data[:40])
        self.assertGreater(reply.leaf_count, 0)
        self.assertGreater(reply.resolution_m, 0.0)


class BusyErrorTest(unittest.TestCase):
    """ERROR_BUSY (the server's query backlog was full) reads as such, with its retry hint."""

    def test_busy_error_names_the_retry(self):
        message = session_pb2.ServerMessage(request_id=9)  # the request it answers, on the envelope
        message.error.CopyFrom(session_pb2.Error(code=session_pb2.ERROR_BUSY, field="collision_batch",
                                                 message="the server is busy", retry_after_s=0.05))
        error = occgeo.ServerError.from_message(message)
        self.assertTrue(error.busy)
        self.assertEqual(error.code_name, "ERROR_BUSY")
        self.assertEqual(error.request_id, 9)
        self.assertAlmostEqual(error.retry_after_s, 0.05)
        self.assertIn("ERROR_BUSY collision_batch", str(error))
        self.assertIn("retry in 0.05 s", str(error))
        self.assertEqual(occgeo.ServerError.from_proto(message.error, 9).request_id, 9)
        self.assertEqual(occgeo.ServerError.from_proto(message.error).request_id, 0)
        self.assertFalse(occgeo.ServerError(session_pb2.ERROR_UNKNOWN_ROBOT, "collision.robot_id", "no").busy)


def _frame(message):
    """``message`` as a frame: its length as a base-128 varint, then the message."""
    payload = message.SerializeToString()
    length, prefix = len(payload), bytearray()
    while length >= 0x80:
        prefix.append((length & 0x7F) | 0x80)
        length >>= 7
    prefix.append(length)
    return bytes(prefix) + payload


def _read_frame(sock):
    """One ClientMessage frame read from ``sock``."""
    length, shift = 0, 0
    while True:
        byte = sock.recv(1)[0]
        length |= (byte & 0x7F) << shift
        if not byte & 0x80:
            break
        shift += 7
    payload = b""
    while len(payload) < length:
        payload += sock.recv(length - len(payload))
    message = session_pb2.ClientMessage()
    message.ParseFromString(payload)
    return message


class EnvelopeTest(unittest.TestCase):
    """Since protocol version 2, a request's request_id is on the ClientMessage envelope, and its reply (or Error) is the
    ServerMessage whose envelope carries the same id. No server: the test writes the server's side of a socket pair."""

    def setUp(self):
        self.ours, self.theirs = socket.socketpair()
        self.client = occgeo.Client(self.ours, None, "query", None, None, 5.0)

    def tearDown(self):
        self.client.close()
        self.theirs.close()

    def test_the_client_speaks_version_3(self):
        self.assertEqual(occgeo.client.PROTOCOL_VERSION, 3)

    def test_request_id_travels_on_the_envelopes(self):
        # Answers queued before the requests (the client numbers them 1, 2, ...): a reply to a request never sent,
        # a watch event, the status reply to request 1, then an Error answering request 2.
        stray = session_pb2.ServerMessage(request_id=77)
        stray.status.server_version = "stray"
        event = session_pb2.ServerMessage()
        event.watch_event.seq = 3
        status = session_pb2.ServerMessage(request_id=1)
        status.status.server_version = "answer to 1"
        error = session_pb2.ServerMessage(request_id=2)
        error.error.code = session_pb2.ERROR_UNKNOWN_ROBOT
        error.error.field = "collision.robot_id"
        self.theirs.sendall(_frame(stray) + _frame(event) + _frame(status) + _frame(error))

        self.assertEqual(self.client.status().server_version, "answer to 1")
        request = _read_frame(self.theirs)
        self.assertEqual(request.request_id, 1)
        self.assertEqual(request.WhichOneof("body"), "status")  # sent even with every field at its default
        self.assertEqual(len(self.client.watch_events), 1)

        with self.assertRaises(occgeo.ServerError) as caught:
            self.client.collision("ghost", 0.0, 0.0)
        self.assertEqual(caught.exception.code, session_pb2.ERROR_UNKNOWN_ROBOT)
        self.assertEqual(caught.exception.request_id, 2)
        request = _read_frame(self.theirs)
        self.assertEqual(request.request_id, 2)
        self.assertEqual(request.collision.robot_id, "ghost")
        self.assertEqual(len(self.client.errors), 0, "an Error answering a request is not filed as unsolicited")

    def test_an_error_answering_no_request_is_filed(self):
        unsolicited = session_pb2.ServerMessage()
        unsolicited.error.code = session_pb2.ERROR_INVALID_ARGUMENT
        unsolicited.error.field = "laser_scan.ranges[17]"
        unsolicited.error.seq = 4
        self.client._file(unsolicited)
        self.assertEqual(len(self.client.errors), 1)
        self.assertEqual(self.client.errors[0].request_id, 0)
        self.assertEqual(self.client.errors[0].seq, 4)


if __name__ == "__main__":
    unittest.main()

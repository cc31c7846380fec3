"""occgeo: a pure-Python client for the occgeod occupancy/geometry server (protocol occgeo.v1).

The protocol's protobuf modules (``occgeo.v1.*_pb2``) are generated when the package is installed
(``pip install ./clients/python``, see setup.py), or, in a build tree, by the CMake target ``occgeo_python``
into ``<build>/clients/python/occgeo/v1`` (then put ``clients/python`` and ``<build>/clients/python`` on
``PYTHONPATH``). See clients/python/README.md and docs/PROTOCOL.md.

Units are SI throughout (metres, radians, seconds); poses are ``base_link`` in the ``world`` frame.
"""

# Used from a checkout, the package spans two directories: this source tree (client code) and the build tree
# (generated occgeo/v1/*_pb2.py). Extending __path__ lets `occgeo.v1` be found in the build tree. Installed, both
# are in one place.
import pkgutil as _pkgutil

__path__ = _pkgutil.extend_path(__path__, __name__)  # noqa: F821 (set by the import system)

try:
    from occgeo.v1 import session_pb2 as _session_pb2  # noqa: F401
except ImportError as _error:  # pragma: no cover - a setup problem, explained to the user
    raise ImportError(
        "occgeo: the generated protobuf modules occgeo.v1.*_pb2 were not found; install the package "
        "(pip install ./clients/python in a venv made with --system-site-packages from /usr/bin/python3), or build "
        "the CMake target 'occgeo_python' and add <build>/clients/python to PYTHONPATH: " + str(_error)
    ) from _error

from occgeo.client import (  # noqa: E402
    BEHAVIOURS,
    CertaintyWindow,
    Client,
    ClientError,
    GridFollower,
    Lease,
    LeaseRefused,
    ServerError,
    Timeout,
    behaviour_label,
    behaviour_value,
    state_label,
)
from occgeo.mapfile import (  # noqa: E402
    CertaintyGreyLevels,
    image_from_certainty,
    write_map,
)
from occgeo.specs import (  # noqa: E402
    box_footprint,
    cylinder_footprint,
    laser_robot_spec,
    polygon_footprint,
)

__all__ = [
    "BEHAVIOURS",
    "CertaintyGreyLevels",
    "CertaintyWindow",
    "Client",
    "ClientError",
    "GridFollower",
    "Lease",
    "LeaseRefused",
    "Timeout",
    "ServerError",
    "behaviour_label",
    "behaviour_value",
    "state_label",
    "box_footprint",
    "cylinder_footprint",
    "image_from_certainty",
    "laser_robot_spec",
    "polygon_footprint",
    "write_map",
]

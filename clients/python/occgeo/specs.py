"""Helpers that build ``RobotSpec`` messages (``occgeo.v1.robot_pb2``)."""

import math

from occgeo.v1 import robot_pb2


def laser_robot_spec(model="python-robot", sensor="laser", beam_count=181, angle_min_rad=-math.pi / 2,
                     angle_increment_rad=math.pi / 180, range_min_m=0.05, range_max_m=8.0, scan_period_s=0.1,
                     mount_x_m=0.0, mount_y_m=0.0, mount_z_m=0.3, mount_yaw_rad=0.0,
                     footprint_length_m=0.6, footprint_width_m=0.5, footprint_height_m=0.5,
                     footprint_center_x_m=0.0, wheel_separation_m=0.5, wheel_radius_m=0.1,
                     max_wheel_speed_mps=1.0, command_timeout_s=0.6, footprint=None):
    """A differential-drive robot with a box footprint and one planar laser.

    The footprint is a box in ``base_link`` centred at (``footprint_center_x_m``, 0), ``length``
    along x, ``width`` along y, ``height`` from the ground (metres), unless ``footprint`` (a
    ``robot_pb2.Footprint``, e.g. from ``polygon_footprint``) is given. The laser ``sensor`` is mounted
    level at (``mount_x_m``, ``mount_y_m``, ``mount_z_m``) in ``base_link`` with heading
    ``mount_yaw_rad``; beam k points at ``angle_min_rad + k * angle_increment_rad`` in its frame.
    """
    spec = robot_pb2.RobotSpec()
    spec.model = model
    diff = spec.kinematics.differential
    diff.wheel_separation_m = wheel_separation_m
    diff.wheel_radius_m = wheel_radius_m
    diff.max_wheel_speed_mps = max_wheel_speed_mps
    if footprint is not None:
        spec.footprint.CopyFrom(footprint)
    else:
        spec.footprint.CopyFrom(box_footprint(footprint_length_m, footprint_width_m, footprint_height_m,
                                              footprint_center_x_m))
    s = spec.sensors.add()
    s.name = sensor
    s.mount.position.x = mount_x_m
    s.mount.position.y = mount_y_m
    s.mount.position.z = mount_z_m
    s.mount.yaw = mount_yaw_rad
    laser = s.laser
    laser.angle_min_rad = angle_min_rad
    laser.angle_increment_rad = angle_increment_rad
    laser.beam_count = beam_count
    laser.range_min_m = range_min_m
    laser.range_max_m = range_max_m
    laser.scan_period_s = scan_period_s
    spec.command_timeout_s = command_timeout_s
    return spec


def box_footprint(length_m, width_m, height_m, center_x_m=0.0):
    """A box footprint in ``base_link``: centred at (``center_x_m``, 0), ``length_m`` along x,
    ``width_m`` along y, from the ground up to ``height_m`` (metres)."""
    footprint = robot_pb2.Footprint()
    footprint.box.length_m = length_m
    footprint.box.width_m = width_m
    footprint.box.height_m = height_m
    footprint.box.center_x_m = center_x_m
    return footprint


def cylinder_footprint(radius_m, height_m):
    """A vertical cylinder footprint centred on the ``base_link`` origin (metres)."""
    footprint = robot_pb2.Footprint()
    footprint.cylinder.radius_m = radius_m
    footprint.cylinder.height_m = height_m
    return footprint


def polygon_footprint(vertices, height_m):
    """A convex polygon footprint: ``vertices`` ``[(x, y), ...]`` in ``base_link`` (metres, 3 to 64
    of them, counter-clockwise or clockwise, the first not repeated) extruded from the ground up to
    ``height_m``. The server rejects a non-convex or degenerate outline, naming the vertex."""
    footprint = robot_pb2.Footprint()
    footprint.polygon.height_m = height_m
    for x, y in vertices:
        vertex = footprint.polygon.vertices.add()
        vertex.x = x
        vertex.y = y
    return footprint


def wall_ranges(distance_m, beam_count=181, angle_min_rad=-math.pi / 2, angle_increment_rad=math.pi / 180,
                range_max_m=8.0):
    """Ranges (metres) a laser at the origin of its frame reads facing a straight wall
    perpendicular to its x axis at ``distance_m``; beams that miss it read ``range_max_m``."""
    ranges = []
    for k in range(beam_count):
        angle = angle_min_rad + k * angle_increment_rad
        c = math.cos(angle)
        r = distance_m / c if c > 1e-9 else math.inf
        ranges.append(r if r < range_max_m else range_max_m)
    return ranges

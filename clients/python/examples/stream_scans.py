#!/usr/bin/env python3
"""Streams a few synthetic laser scans of a wall 2 m ahead as a driver, then exports the map.

usage: stream_scans.py [HOST:PORT] [PREFIX]   (defaults 127.0.0.1:7700, ./python-demo-map)

Writes PREFIX.pgm + PREFIX.yaml (ROS map_server) and PREFIX.bt (OctoMap) of world "python-demo".
"""
import math
import sys

import occgeo
from occgeo.specs import laser_robot_spec

address = sys.argv[1] if len(sys.argv) > 1 else "127.0.0.1:7700"
prefix = sys.argv[2] if len(sys.argv) > 2 else "python-demo-map"
host, port = address.rsplit(":", 1)
world = "python-demo"

spec = laser_robot_spec(model="python-demo", beam_count=181, angle_min_rad=-math.pi / 2,
                        angle_increment_rad=math.pi / 180, range_max_m=8.0)
laser = spec.sensors[0].laser


def scan_of_wall(robot_x_m, wall_x_m=2.0, half_width_m=1.5):
    """Ranges (m) seen from (robot_x_m, 0) facing +x, of a wall at x = wall_x_m, |y| <= half_width_m."""
    ranges = []
    for k in range(laser.beam_count):
        angle = laser.angle_min_rad + k * laser.angle_increment_rad
        c = math.cos(angle)
        r = laser.range_max_m
        if c > 1e-6:
            d = (wall_x_m - robot_x_m) / c
            if abs(d * math.sin(angle)) <= half_width_m:
                r = min(d, laser.range_max_m)
        ranges.append(r)
    return ranges


with occgeo.Client.connect(host, int(port), role="driver", robot_id="python-demo-1", world=world) as driver:
    driver.send_robot_spec(spec)
    for i in range(5):
        x = 0.1 * i  # the robot creeps towards the wall along +x
        driver.send_odometry(x, 0.0, 0.0, stamp_s=0.1 * i, linear_mps=1.0)
        ack = driver.send_laser_scan("laser", scan_of_wall(x), stamp_s=0.1 * i)
        print("scan %d: world version %d" % (ack.seq, ack.world_version))
    for command in driver.motion_commands:
        print("motion command for scan %d: %s/%s, %.2f m/s" % (command.answers_scan_seq,
                                                                occgeo.behaviour_label(command.behaviour),
                                                                occgeo.state_label(command.state), command.linear_mps))

with occgeo.Client.connect(host, int(port)) as client:
    window = client.export_map(world, prefix)
    print("wrote %s.pgm and %s.yaml (%d x %d cells of %g m, %d occupied)"
          % (prefix, prefix, window.width, window.height, window.cell_size_m, len(window.occupied_cells())))
    octree = client.export_octree(world, prefix + ".bt")
    print("wrote %s.bt (%d leaves of %g m)" % (prefix, octree.leaf_count, octree.resolution_m))

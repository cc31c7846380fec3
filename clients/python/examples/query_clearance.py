#!/usr/bin/env python3
"""Asks occgeod whether robot ROBOT (default bearcat-1) at pose (x, y, theta) = (1, 0, 0) in the world frame collides, and how far it is from obstacles."""
import sys

import occgeo

robot = sys.argv[1] if len(sys.argv) > 1 else "bearcat-1"
with occgeo.Client.connect("127.0.0.1", 7700) as client:
    hit = client.collision(robot, x=1.0, y=0.0, theta=0.0)
    clearance = client.clearance(robot, x=1.0, y=0.0, theta=0.0)
    print("collision:", hit.hit, "clearance: %.3f m" % clearance.clearance_m, "found:", clearance.found)

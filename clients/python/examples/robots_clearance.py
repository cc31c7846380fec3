#!/usr/bin/env python3
"""Every robot occgeod knows: where it is, what it is doing and how much room it has; then its world's map size."""
import sys

import occgeo

host, port = (sys.argv[1] if len(sys.argv) > 1 else "127.0.0.1:7700").rsplit(":", 1)
with occgeo.Client.connect(host, int(port)) as client:
    for robot in client.status().robots:
        p = robot.pose
        room = client.clearance(robot.id, x=p.x, y=p.y, theta=p.theta)
        behaviour = occgeo.behaviour_label(robot.behaviour)
        print("%s at (%.2f, %.2f, %.2f) %s: clearance %.3f m, keep-out %.3f m"
              % (robot.id, p.x, p.y, p.theta, behaviour, room.clearance_m, room.restricted_clearance_m))
        print("  world %s: %d occupied cells" % (robot.world, len(client.grid(robot.world).occupied_cells())))

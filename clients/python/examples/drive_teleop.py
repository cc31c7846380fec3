#!/usr/bin/env python3
"""Drives a robot by hand for a while: takes its lease as a controller, sets teleop velocities, watches its sensor
messages arrive, then stops it and gives the lease back.

usage: drive_teleop.py [HOST:PORT] [ROBOT] [LINEAR_MPS] [ANGULAR_RADPS] [SECONDS]
       (defaults 127.0.0.1:7700, bearcat-1, 0.2 m/s, 0.0 rad/s, 3 s)

Run it against a server with a robot that has a laser (e.g. `occgeo-sim --world clients/sim/worlds/open_field.yaml`):
the server turns the velocities into wheel commands, through the safety guard, at each of the robot's scans.
"""
import sys

import occgeo

address = sys.argv[1] if len(sys.argv) > 1 else "127.0.0.1:7700"
robot = sys.argv[2] if len(sys.argv) > 2 else "bearcat-1"
linear_mps = float(sys.argv[3]) if len(sys.argv) > 3 else 0.2
angular_radps = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0
seconds = float(sys.argv[5]) if len(sys.argv) > 5 else 3.0
host, port = address.rsplit(":", 1)


def pose_of(client, robot_id):
    for r in client.status().robots:
        if r.id == robot_id:
            return r.pose
    raise SystemExit("no robot %s on the server" % robot_id)


with occgeo.Client.connect(host, int(port), role="controller", client_name="drive_teleop.py") as client:
    start = pose_of(client, robot)
    client.watch(robot_id=robot)
    try:
        lease = client.hold_lease(robot, timeout_s=2.0)
    except occgeo.LeaseRefused as refused:
        raise SystemExit(str(refused))
    with lease:  # returned at the end of the block; the server then stops the robot
        reply = client.teleop(robot, linear_mps, angular_radps)
        print("teleop %.3f m/s, %.3f rad/s (after the robot's limits)%s"
              % (reply.linear_mps, reply.angular_radps, "; e-stop engaged: the robot stays still" if reply.estop else ""))
        lease.sleep(seconds)  # keeps the lease alive while the watch events arrive
        client.drive(robot, "stop")
    events = list(client.watch_events)
    end = pose_of(client, robot)
    print("%d sensor messages from %s in %.1f s (%d dropped)"
          % (len(events), robot, seconds, sum(e.dropped_since_last for e in events)))
    print("moved from (%.3f, %.3f, %.3f) to (%.3f, %.3f, %.3f)"
          % (start.x, start.y, start.theta, end.x, end.y, end.theta))

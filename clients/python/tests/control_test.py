"""Watch, lease, drive and e-stop from the Python client against a real occgeod and a real simulated Bearcat
(occgeo-sim in real time on the open field): the watch stream follows the robot's scans, the lease excludes a
rival (as the C++ CLI sees it too), teleop turns the robot, the e-stop latches until the holder releases it, and
the drive example script moves the robot.

Needs the environment CTest sets (tests/clients/CMakeLists.txt, test python_control): PYTHONPATH, and
OCCGEO_BINARY_DIR or OCCGEOD / OCCGEO_CLI / OCCGEO_SIM.
"""

import math
import os
import subprocess
import sys
import time

import occgeo
import test_client
from google.protobuf import json_format

from occgeo.v1 import control_pb2, session_pb2

ROBOT = "bearcat-py"
SIM_SECONDS = 60  # longer than the test; the simulator is stopped when the test ends
EXAMPLE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples", "drive_teleop.py")


def angle_between(a, b):
    return abs(math.atan2(math.sin(a - b), math.cos(a - b)))


class ControlWithSimulator(test_client.ServerTestCase):

    def setUp(self):
        self.start_server()
        sim = test_client._executable("OCCGEO_SIM", os.path.join("clients", "sim", "occgeo-sim"))
        world = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "sim", "worlds", "open_field.yaml")
        self.sim_log = open(os.path.join(self.tmp, "sim.log"), "wb")
        self.addCleanup(self.sim_log.close)
        self.sim = subprocess.Popen([sim, "--world", world, "--server", "127.0.0.1:%d" % self.port, "--id", ROBOT,
                                     "--duration", str(SIM_SECONDS)], stdout=self.sim_log, stderr=subprocess.STDOUT)
        self.addCleanup(self._stop_sim)
        self.query = self.connect()
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            robot = self.robot_status()
            if robot is not None and robot.scans_ingested >= 3:
                return
            time.sleep(0.05)
        self.fail("the simulator's robot sent no scans within 10 s")

    def _stop_sim(self):
        if self.sim.poll() is None:
            self.sim.terminate()
            try:
                self.sim.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.sim.kill()
                self.sim.wait(timeout=10)

    def robot_status(self):
        for robot in self.query.status().robots:
            if robot.id == ROBOT:
                return robot
        return None

    def test_watch_lease_teleop_and_estop(self):
        observer = self.connect(role="observer", client_name="py-observer")
        observer.watch(robot_id=ROBOT)
        events = [observer.next_watch_event(timeout_s=5.0) for _ in range(5)]
        self.assertTrue(all(e.robot_id == ROBOT and e.world == "default" for e in events), events)
        seqs = [e.seq for e in events]
        self.assertEqual(seqs, sorted(set(seqs)), "watch events out of order")
        versions = [e.world_version for e in events]
        self.assertEqual(versions, sorted(versions))

        controller = self.connect(role="controller", client_name="py-controller")
        lease = controller.hold_lease(ROBOT, timeout_s=3.0)
        self.assertTrue(lease.reply.granted)
        session_id = controller.welcome.session_id
        self.assertEqual(lease.reply.holder.session_id, session_id)
        # A rival controller, and the C++ CLI, are refused and told who holds it.
        rival = self.connect(role="controller", client_name="py-rival")
        with self.assertRaises(occgeo.LeaseRefused) as refused:
            rival.hold_lease(ROBOT)
        self.assertEqual(refused.exception.reply.holder.session_id, session_id)
        with self.assertRaises(occgeo.ServerError) as caught:
            rival.teleop(ROBOT, 0.3, 0.0)
        self.assertEqual(caught.exception.code, session_pb2.ERROR_NOT_ALLOWED)
        self.assertEqual(caught.exception.field, "drive.robot_id")
        cli = self.run_cli("lease", "acquire", "--robot", ROBOT, "--json", check=False)
        self.assertEqual(cli.returncode, 1, cli.stderr.decode())
        refused = json_format.Parse(cli.stdout.decode(), control_pb2.LeaseReply())
        self.assertFalse(refused.granted)
        self.assertEqual((refused.holder.session_id, refused.holder.client_name), (session_id, "py-controller"))

        # Teleop: turn in place (nothing near the start of the open field to stop it) for two seconds.
        before = self.robot_status().pose
        reply = controller.teleop(ROBOT, 0.0, 0.5)
        self.assertEqual(occgeo.behaviour_label(reply.behaviour), "teleop")
        self.assertAlmostEqual(reply.angular_radps, 0.5)
        self.assertFalse(reply.estop)
        lease.sleep(2.0)
        status = self.robot_status()
        self.assertEqual(occgeo.behaviour_label(status.behaviour), "teleop")
        self.assertEqual(occgeo.state_label(status.behaviour_state), "teleop")
        self.assertEqual(status.lease_holder.session_id, session_id)
        turned = angle_between(status.pose.theta, before.theta)
        self.assertGreater(turned, 0.3, "teleop at 0.5 rad/s for 2 s turned the robot only %.3f rad" % turned)

        # The observer engages the e-stop: the robot stands still, and only the holder may release it.
        engaged = observer.estop(ROBOT)
        self.assertTrue(engaged.engaged)
        self.assertEqual(engaged.holder.session_id, session_id)
        lease.sleep(0.5)  # the stop reaches the simulator
        held = self.robot_status().pose
        lease.sleep(1.0)
        still = self.robot_status()
        self.assertTrue(still.estop)
        self.assertLess(angle_between(still.pose.theta, held.theta), 0.01, "the robot turned under the e-stop")
        self.assertTrue(controller.teleop(ROBOT, 0.0, 0.5).estop)  # the behaviour changes, the latch stays
        with self.assertRaises(occgeo.ServerError) as caught:
            rival.estop(ROBOT, engage=False)
        self.assertEqual(caught.exception.code, session_pb2.ERROR_NOT_ALLOWED)
        self.assertEqual(caught.exception.field, "estop.engage")
        self.assertFalse(controller.estop(ROBOT, engage=False).engaged)
        lease.sleep(1.5)
        moving = self.robot_status()
        self.assertFalse(moving.estop)
        self.assertGreater(angle_between(moving.pose.theta, still.pose.theta), 0.2, "teleop did not resume")

        # Giving the lease back: teleop becomes stop, nobody holds it, and the rival may take it.
        lease.release()
        after = self.robot_status()
        self.assertFalse(after.HasField("lease_holder"))
        self.assertEqual(occgeo.behaviour_label(after.behaviour), "stop")
        self.assertTrue(rival.lease(ROBOT, "acquire").granted)

        # Meanwhile the watch stream kept up with every scan the robot sent (no drops at this rate).
        observer.poll(0.3)
        watched = list(observer.watch_events)
        self.assertGreater(len(watched), 20)
        self.assertEqual(sum(e.dropped_since_last for e in watched), 0)
        all_seqs = seqs + [e.seq for e in watched]
        self.assertEqual(all_seqs, sorted(set(all_seqs)))

    def test_behaviours_are_named_by_the_schemas_labels(self):
        self.assertEqual(occgeo.BEHAVIOURS, ("bearcat", "bearcat_seed", "stop", "teleop", "wander", "goto", "waypoints"))
        with self.assertRaises(ValueError) as caught:
            occgeo.behaviour_value("dance")
        self.assertIn("goto", str(caught.exception))
        self.assertEqual(occgeo.state_label(0), "")

    def test_drive_example_turns_the_robot(self):
        before = self.robot_status().pose
        result = subprocess.run([sys.executable, EXAMPLE, "127.0.0.1:%d" % self.port, ROBOT, "0", "0.5", "2"],
                                capture_output=True, timeout=test_client.CLI_TIMEOUT_S, env=os.environ)
        self.assertEqual(result.returncode, 0, result.stderr.decode())
        out = result.stdout.decode()
        self.assertIn("teleop 0.000 m/s, 0.500 rad/s", out)
        count = int(out.split(" sensor messages")[0].split("\n")[-1])
        self.assertGreater(count, 5, out)  # the LMS200 scans at 10 Hz
        after = self.robot_status()
        self.assertGreater(angle_between(after.pose.theta, before.theta), 0.3, out)
        self.assertFalse(after.HasField("lease_holder"))
        self.assertEqual(occgeo.behaviour_label(after.behaviour), "stop")

"""Every query call of the Python client against a real occgeod, compared with what the C++ CLI answers
(``occgeo query ... --json``, ``occgeo map export --format bt``) on the same server and map: the wall of
test_client.py, mapped by SCANS laser scans from the origin. Batch forms must answer each entry exactly as
the single form does.

Needs the environment CTest sets (tests/clients/CMakeLists.txt, test python_queries): PYTHONPATH, and
OCCGEO_BINARY_DIR or OCCGEOD / OCCGEO_CLI.
"""

import json
import math
import os

import occgeo
import test_client
from occgeo.v1 import query_pb2
from test_client import MODEL_NAMES, ROBOT, WALL_X_M, WORLD, cli_reply


def model_name(model):
    """A model's label: "" for MODEL_UNSPECIFIED."""
    return MODEL_NAMES.get(model, "")


def number_args(**values):
    """--name value pairs, numbers written so they read back exactly."""
    out = []
    for name, value in values.items():
        out += ["--" + name.replace("_", "-"), repr(float(value))]
    return out


class QueriesMatchCli(test_client.ClientTest):
    """A server holding the wall per test (ClientTest.setUp); ClientTest's own tests run from test_client.py."""

    def cli_json(self, *args):
        """What `occgeo ARGS --json` printed, as JSON (the grid window prints its cells as numbers)."""
        return json.loads(self.run_cli(*args, "--json"))

    def printed(self, reply_type, *args):
        """What `occgeo ARGS --json` printed, parsed back into the reply it printed."""
        return cli_reply(self.run_cli(*args, "--json"), reply_type)

    def test_raycast_single_and_batch_match_cli(self):
        rays = [(0.0, 0.0, theta) for theta in (0.0, 0.3, -0.5, 1.2, math.pi)] + [(1.0, 0.4, 0.1), (2.5, 0.0, math.pi)]
        batch = self.query.raycast(rays, 5.0, world=WORLD)
        self.assertEqual(len(batch.results), len(rays))
        hits = 0
        for (x, y, theta), result in zip(rays, batch.results):
            with self.subTest(ray=(x, y, theta)):
                single = self.query.raycast([(x, y, theta)], 5.0, world=WORLD).results[0]
                self.assertEqual(single, result)
                cli = self.printed(query_pb2.RaycastReply, "query", "raycast", "--world", WORLD,
                               *number_args(x=x, y=y, theta=theta, max_range=5.0))
                self.assertEqual(result, cli.results[0])
                self.assertEqual(batch.version, cli.version)
                hits += result.hit
        self.assertGreater(hits, 0, "no ray hit the wall")
        self.assertLess(hits, len(rays), "every ray hit something")
        # Straight at the wall from the origin: the grid's hit is where the ray enters the wall's cells (the PTEM's
        # restricted region, one circle around the wall's returns, reaches farther out).
        grid_hit = [h for h in batch.results[0].per_model if model_name(h.model) == "grid"][0]
        self.assertTrue(grid_hit.hit)
        self.assertAlmostEqual(grid_hit.range_m, WALL_X_M, delta=0.15)
        # One model at a time, as the CLI's --models.
        for models in ("grid", "octomap", "ptem"):
            result = self.query.raycast([(0.0, 0.0, 0.0)], 5.0, world=WORLD, models=models).results[0]
            self.assertEqual([model_name(h.model) for h in result.per_model], [models])
            cli = self.printed(query_pb2.RaycastReply, "query", "raycast", "--world", WORLD, "--models", models,
                           *number_args(x=0, y=0, theta=0, max_range=5))
            self.assertEqual(result, cli.results[0])

    def test_occupancy_matches_cli(self):
        points = [(WALL_X_M + 0.05, 0.0, 0.3), (1.0, 0.0, 0.3), (-6.0, 6.0, 0.3), (WALL_X_M + 0.05, 0.5, 0.1)]
        reply = self.query.occupancy(points, world=WORLD)
        self.assertEqual(len(reply.samples), len(points))
        for (x, y, z), sample in zip(points, reply.samples):
            with self.subTest(point=(x, y, z)):
                cli = self.printed(query_pb2.OccupancyReply, "query", "occupancy", "--world", WORLD,
                               *number_args(x=x, y=y, z=z))
                self.assertEqual(sample, cli.samples[0])
                self.assertEqual(reply.version, cli.version)
        wall, free, unknown = reply.samples[0], reply.samples[1], reply.samples[2]
        self.assertTrue(wall.occupied)
        self.assertTrue(free.observed)
        self.assertFalse(free.occupied)
        self.assertFalse(unknown.observed)

    def test_swept_matches_cli(self):
        motions = [((0.0, 0.0, 0.0), 0.5, 0.0, 6.0),      # straight into the wall
                   ((0.0, 0.0, math.pi), 0.5, 0.0, 4.0),  # away from it
                   ((0.0, 0.0, 0.0), 0.4, 0.3, 5.0)]      # an arc
        results = []
        for start, v, w, duration in motions:
            with self.subTest(start=start, v=v, w=w):
                result = self.query.swept(ROBOT, start, v, w, duration)
                cli = self.printed(query_pb2.SweptReply, "query", "swept", "--robot", ROBOT,
                               *number_args(x=start[0], y=start[1], theta=start[2], v=v, w=w, duration=duration))
                self.assertEqual(result, cli.results[0])
                results.append(result)
        self.assertTrue(results[0].hit)
        self.assertFalse(results[1].hit)
        self.assertAlmostEqual(results[1].time_s, 4.0)
        # On the grid alone, the front of the 0.6 m footprint (0.3 m ahead of base_link) meets the wall after about
        # 1.7 m at 0.5 m/s (the PTEM's circle around the wall is met sooner).
        into = self.query.swept(ROBOT, (0.0, 0.0, 0.0), 0.5, 0.0, 6.0, models="grid")
        self.assertEqual(into, self.printed(query_pb2.SweptReply, "query", "swept", "--robot", ROBOT, "--models", "grid",
                                        *number_args(x=0, y=0, theta=0, v=0.5, w=0, duration=6)).results[0])
        self.assertTrue(into.hit)
        self.assertAlmostEqual(into.time_s, (WALL_X_M - 0.3) / 0.5, delta=0.3)

    def test_collision_and_clearance_batches_answer_as_single_queries_and_the_cli(self):
        poses = [(x, 0.2 * y, theta) for x in (0.0, 1.2, 1.65, 1.8, 2.4) for y in (-1, 0, 2) for theta in (0.0, 0.8)]
        collisions = self.query.collision_batch(ROBOT, poses)
        clearances = self.query.clearance_batch(ROBOT, poses)
        self.assertEqual(len(collisions.results), len(poses))
        self.assertEqual(len(clearances.results), len(poses))
        self.assertEqual(collisions.hits, sum(r.hit for r in collisions.results))
        self.assertGreater(collisions.hits, 0)
        self.assertLess(collisions.hits, len(poses))
        for i, (x, y, theta) in enumerate(poses):
            with self.subTest(pose=(x, y, theta)):
                self.assertEqual(collisions.results[i], self.query.collision(ROBOT, x, y, theta))
                self.assertEqual(clearances.results[i], self.query.clearance(ROBOT, x, y, theta))
                if i % 3 == 0:  # the CLI for a third of them: each call is a process
                    pose_args = ["--robot", ROBOT] + number_args(x=x, y=y, theta=theta)
                    self.assertEqual(collisions.results[i],
                                     self.printed(query_pb2.CollisionReply, "query", "collision", *pose_args))
                    self.assertEqual(clearances.results[i],
                                     self.printed(query_pb2.ClearanceReply, "query", "clearance", *pose_args))
        # A model subset, as the CLI's --models.
        grid_only = self.query.clearance_batch(ROBOT, poses[:4], models="grid")
        for (x, y, theta), result in zip(poses[:4], grid_only.results):
            self.assertEqual(result, self.printed(query_pb2.ClearanceReply, "query", "clearance", "--robot", ROBOT,
                                              "--models", "grid", *number_args(x=x, y=y, theta=theta)))

    def test_grid_window_and_its_changes_match_cli(self):
        box = dict(min_x=-1.0, min_y=-2.0, max_x=3.0, max_y=2.0)
        reply = self.query.grid_window(box["min_x"], box["min_y"], box["max_x"], box["max_y"], world=WORLD)
        cli = self.cli_json("query", "window", "--world", WORLD, *number_args(**box))
        self.assertEqual(reply.version, cli["version"])
        self.assertEqual((reply.min_cell.ix, reply.min_cell.iy), (cli["min_cell"]["ix"], cli["min_cell"]["iy"]))
        self.assertEqual((reply.width, reply.height), (cli["width"], cli["height"]))
        self.assertEqual(list(reply.cells), cli["cells"])
        self.assertTrue(any(c != 255 and c >= 3 for c in reply.cells), "no occupied cell in the window")

        follower = occgeo.GridFollower(self.query, box["min_x"], box["min_y"], box["max_x"], box["max_y"], world=WORLD)
        self.assertEqual(follower.update(), reply.width * reply.height)
        old_version = follower.version
        # A second robot scans the wall from farther up: only the blocks it wrote come back.
        driver = self.connect(role="driver", robot_id="py-bot-3", world=WORLD)
        driver.send_robot_spec(self.spec)
        driver.send_odometry(0.0, 1.0, 0.0, stamp_s=1.0, confirm=True)
        driver.send_laser_scan("laser", test_client.wall_scan(self.spec), stamp_s=1.0)
        changes = self.query.grid_window(box["min_x"], box["min_y"], box["max_x"], box["max_y"], world=WORLD,
                                         since_version=old_version)
        cli_changes = self.cli_json("query", "window", "--world", WORLD, "--since", str(old_version), *number_args(**box))
        self.assertEqual(changes.version, cli_changes["version"])
        self.assertEqual(len(changes.changed), cli_changes["changed_blocks"])
        self.assertEqual(sum(len(b.cells) for b in changes.changed), cli_changes["changed_cells"])
        self.assertGreater(len(changes.changed), 0)
        self.assertLess(sum(len(b.cells) for b in changes.changed), reply.width * reply.height + 1)
        follower.update()
        self.assertEqual(bytes(follower.cells), list_bytes(self.cli_json("query", "window", "--world", WORLD,
                                                                         *number_args(**box))["cells"]))

    def test_octree_and_its_window_match_cli(self):
        path = os.path.join(self.tmp, "py.bt")
        reply = self.query.export_octree(WORLD, path)
        cli_prefix = os.path.join(self.tmp, "cli")
        self.run_cli("map", "export", "--format", "bt", "--world", WORLD, "--out", cli_prefix)
        with open(path, "rb") as a, open(cli_prefix + ".bt", "rb") as b:
            self.assertEqual(a.read(), b.read(), "the .bt differs from the C++ export")
        self.assertGreater(reply.leaf_count, 0)

        window = self.query.octree_window((WALL_X_M - 0.5, -0.5, 0.0), (WALL_X_M + 0.5, 0.5, 1.0), world=WORLD)
        self.assertEqual(window.resolution_m, reply.resolution_m)
        self.assertGreater(len(window.voxels), 0, "no occupied voxel at the wall")
        # Each voxel is occupied where the CLI's occupancy query looks (the laser's plane at 0.3 m).
        for voxel in list(window.voxels)[:6]:
            c = voxel.center
            with self.subTest(voxel=(c.x, c.y, c.z)):
                self.assertAlmostEqual(c.x, WALL_X_M, delta=0.2)
                cli = self.printed(query_pb2.OccupancyReply, "query", "occupancy", "--world", WORLD, "--models", "octomap",
                               *number_args(x=c.x, y=c.y, z=c.z)).samples[0]
                self.assertTrue(cli.octree_known)
                self.assertAlmostEqual(voxel.probability, cli.octree_probability, places=6)

    def test_ptem_matches_cli(self):
        for x, y in ((WALL_X_M, 0.0), (1.0, 0.3), (-3.0, 2.0)):
            with self.subTest(point=(x, y)):
                reply = self.query.ptem(WORLD, [(x, y)])
                self.assertEqual(reply, self.printed(query_pb2.PtemReply, "query", "ptem", "--world", WORLD,
                                                 *number_args(x=x, y=y)))


def list_bytes(values):
    return bytes(bytearray(values))


# Only the tests above run here; ClientTest's own tests run from test_client.py.
for _name in dir(test_client.ClientTest):
    if _name.startswith("test_") and _name not in QueriesMatchCli.__dict__:
        setattr(QueriesMatchCli, _name, None)

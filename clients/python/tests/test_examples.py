"""The README's Python example (examples/robots_clearance.py) run against a real occgeod, after the same wall
scans as test_client.py: what it prints must be what the C++ CLI answers for that robot and pose.

Needs the environment CTest sets (see test_client.py): PYTHONPATH, and OCCGEO_BINARY_DIR or OCCGEOD / OCCGEO_CLI.
"""

import json
import os
import re
import subprocess
import sys

import test_client

EXAMPLE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples", "robots_clearance.py")


class ReadmeExampleTest(test_client.ClientTest):
    """Reuses ClientTest's server and wall (setUp), not its tests."""

    def test_example_prints_what_the_cli_answers(self):
        result = subprocess.run([sys.executable, EXAMPLE, "127.0.0.1:%d" % self.port], capture_output=True,
                                timeout=test_client.CLI_TIMEOUT_S, env=os.environ)
        self.assertEqual(result.returncode, 0, result.stderr.decode())
        out = result.stdout.decode()
        match = re.search(r"^%s at \(([-0-9.]+), ([-0-9.]+), ([-0-9.]+)\) (\S+): clearance ([-0-9.]+) m, keep-out ([-0-9.]+) m$"
                          % re.escape(test_client.ROBOT), out, re.MULTILINE)
        self.assertIsNotNone(match, out)
        x, y, theta = (float(v) for v in match.group(1, 2, 3))
        cli = json.loads(self.run_cli("query", "clearance", "--robot", test_client.ROBOT, "--x", "%.17g" % x,
                                      "--y", "%.17g" % y, "--theta", "%.17g" % theta, "--json"))
        # The robot stands at (0, 0, 0), so the printed pose is exact; the clearance is printed to 1 mm.
        self.assertAlmostEqual(float(match.group(5)), cli["clearance_m"], delta=0.0005)
        self.assertAlmostEqual(float(match.group(6)), cli.get("restricted_clearance_m", 0.0), delta=0.0005)
        # The robot stands in the open, 2 m short of the wall: the default models answer against matter, as the grid
        # alone does (to a cell), not 0 inside the PTEM's keep-out.
        grid = self.query.clearance(test_client.ROBOT, x, y, theta, models=["grid"])
        self.assertTrue(grid.found)
        self.assertGreater(grid.clearance_m, 1.0)
        self.assertAlmostEqual(float(match.group(5)), grid.clearance_m, delta=0.1)
        cells = re.search(r"world %s: (\d+) occupied cells" % test_client.WORLD, out)
        self.assertIsNotNone(cells, out)
        self.assertEqual(int(cells.group(1)), len(self.query.grid(test_client.WORLD).occupied_cells()))
        self.assertGreater(int(cells.group(1)), 0)


# Only the test above runs here; ClientTest's own tests run from test_client.py.
for _name in dir(test_client.ClientTest):
    if _name.startswith("test_"):
        setattr(ReadmeExampleTest, _name, None)

"""The client installs as a package with no package index and no build tree, and works from the install.

Does what the README says a user does: `python3 -m venv --system-site-packages V && V/bin/pip install
./clients/python` (Debian's interpreter, with python3-protobuf and protobuf-compiler installed), with pip told
there is no index. The checkout is copied to a temporary folder first so the install's build files are not
written into the source tree. Then, with no PYTHONPATH, the venv's interpreter imports occgeo (whose occgeo.v1
modules the install generated) and runs examples/stream_scans.py against a real occgeod.
"""

import os
import shutil
import subprocess
import tempfile
import unittest

from test_client import ServerTestCase

SOURCE_DIR = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", ".."))
DEBIAN_PYTHON = "/usr/bin/python3"
INSTALL_TIMEOUT_S = 240.0
RUN_TIMEOUT_S = 60.0


def _clean_env(tmp):
    env = {key: value for key, value in os.environ.items() if not key.startswith(("PYTHON", "PIP_", "VIRTUAL_ENV"))}
    env.update({"PIP_NO_INDEX": "1", "PIP_DISABLE_PIP_VERSION_CHECK": "1", "PIP_NO_CACHE_DIR": "1",
                "HOME": tmp, "PYTHONDONTWRITEBYTECODE": "1"})
    return env


class InstallTest(ServerTestCase):
    def setUp(self):
        if not os.access(DEBIAN_PYTHON, os.X_OK):
            raise unittest.SkipTest("Debian's python3 is not at %s" % DEBIAN_PYTHON)
        super().setUp()
        self.work = tempfile.mkdtemp(prefix="occgeo-python-install-")
        self.addCleanup(shutil.rmtree, self.work, True)
        # The package's build reads the schema at ../../proto beside clients/python, as in the checkout.
        checkout = os.path.join(self.work, "checkout")
        shutil.copytree(os.path.join(SOURCE_DIR, "clients", "python"), os.path.join(checkout, "clients", "python"),
                        ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
        shutil.copytree(os.path.join(SOURCE_DIR, "proto", "occgeo"), os.path.join(checkout, "proto", "occgeo"))
        self.checkout = checkout
        self.env = _clean_env(self.work)

    def run_checked(self, args, timeout_s, cwd=None):
        result = subprocess.run(args, env=self.env, cwd=cwd or self.work, capture_output=True, timeout=timeout_s)
        self.assertEqual(result.returncode, 0, "%s failed:\n%s\n%s" % (
            " ".join(args), result.stdout.decode(errors="replace")[-3000:], result.stderr.decode(errors="replace")[-3000:]))
        return result.stdout.decode()

    def test_pip_install_without_an_index_gives_a_working_client(self):
        venv = os.path.join(self.work, "venv")
        self.run_checked([DEBIAN_PYTHON, "-m", "venv", "--system-site-packages", venv], INSTALL_TIMEOUT_S)
        python = os.path.join(venv, "bin", "python")
        self.run_checked([os.path.join(venv, "bin", "pip"), "install", "./clients/python"], INSTALL_TIMEOUT_S,
                         cwd=self.checkout)

        where = self.run_checked(
            [python, "-c", "import occgeo, occgeo.v1.session_pb2 as s; print(occgeo.__file__); print(s.__file__)"],
            RUN_TIMEOUT_S).split()
        for path in where:
            self.assertTrue(path.startswith(venv), "%s was not imported from the install in %s" % (path, venv))

        prefix = os.path.join(self.work, "map")
        out = self.run_checked([python, os.path.join(SOURCE_DIR, "clients", "python", "examples", "stream_scans.py"),
                                "127.0.0.1:%d" % self.port, prefix], RUN_TIMEOUT_S)
        self.assertIn("scan 4: world version", out)
        for suffix in (".pgm", ".yaml", ".bt"):
            self.assertGreater(os.path.getsize(prefix + suffix), 0, "stream_scans.py wrote no " + suffix)


if __name__ == "__main__":
    unittest.main()

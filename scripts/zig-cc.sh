#!/usr/bin/env bash
# The linker the test command and scripts/wheel.sh give cargo for x86_64 Linux
# (CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_LINKER): `zig cc` against glibc 2.28's symbol versions,
# through cargo-zigbuild's wrapper (it drops the flags zig does not take), both from PyPI in
# target/zig (scripts/test-tools.sh). A library linked on a new system otherwise asks for the
# newest versions of `hypot` (GLIBC_2.35) and `pthread_*` (GLIBC_2.34), and pip refuses its wheel
# on Ubuntu 20.04/22.04, RHEL 8/9 and Amazon Linux 2023; linked here it runs on glibc 2.28 and
# later (manylinux_2_28). The code is the same: only the symbol versions asked for differ.
#
# Only the shipped library is linked so: the build scripts, proc macros, tests, examples and
# benchmarks are linked by this machine's `cc` with rustc's own arguments (rustc's bundled lld),
# which saves a Python and a zig start on each of the run's few hundred links. The linker path
# cargo sees, and so every fingerprint, is this script either way.
set -euo pipefail
# zig reads `--strip-debug` (what cargo passes for a profile without debug info) as "strip
# everything", symbol table included, and then profilers and valgrind's suppressions see no
# function names. So its link keeps it all, and the debug sections alone are stripped after.
args=() strip_debug= out= next_is_out=
for arg in "$@"; do
    if [ -n "$next_is_out" ]; then out=$arg next_is_out=; fi
    case "$arg" in
        -Wl,--strip-debug | -Wl,-S) strip_debug=1; continue ;;
        -o) next_is_out=1 ;;
    esac
    args+=("$arg")
done
case "$(basename -- "$out")" in
    libtroupe.so | libtroupe-*.so) ;;
    *) exec cc "$@" ;;
esac
zig_env="$(cd "$(dirname "$0")/.." && pwd)/target/zig"
[ -x "$zig_env/bin/cargo-zigbuild" ] || {
    echo "zig-cc.sh: $zig_env/bin/cargo-zigbuild is missing (scripts/test-tools.sh zig)" >&2
    exit 1
}
# zig builds glibc 2.28's stubs and its runtime libraries on first use and caches them; the cache
# lives beside zig, in the project's target folder, which is writable wherever the build is
# (a CI runner's home may not be).
export ZIG_GLOBAL_CACHE_DIR="${ZIG_GLOBAL_CACHE_DIR:-$zig_env/cache}"
export ZIG_LOCAL_CACHE_DIR="${ZIG_LOCAL_CACHE_DIR:-$zig_env/cache}"
export CARGO_ZIGBUILD_ZIG_COMMAND="$zig_env/bin/python3"
export CARGO_ZIGBUILD_ZIG_COMMAND_ARGS="-m ziglang"
"$zig_env/bin/cargo-zigbuild" zig cc -- -g -fno-sanitize=all -target x86_64-linux-gnu.2.28 "${args[@]}"
if [ -n "$strip_debug" ] && [ -n "$out" ]; then
    objcopy --strip-debug "$out"
fi

#!/usr/bin/env bash
# Runs a program built for another target on this Linux x86-64 machine: Windows x64 programs
# under Wine, Linux arm64 programs under qemu-user. Cargo calls it as the targets' runner
# (.cargo/config.toml); the cross tests (tests/platforms.rs) call it for C programs too.
#
#   scripts/platform-run.sh TRIPLE PROGRAM [ARGUMENTS...]
#
# Environment: TROUPE_WINE (the Wine loader; found on PATH or in /usr/lib/wine otherwise),
# WINEPREFIX (default: target/wine, created on first use), WINEPATH (folders searched for
# DLLs, e.g. the one holding troupe.dll), QEMU_LD_PREFIX (default: /usr/aarch64-linux-gnu,
# Debian's arm64 C library for cross builds), QEMU_CPU (default: neoverse-n1, below).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
triple="$1"
shift
case "$triple" in
x86_64-pc-windows-gnu)
    wine="${TROUPE_WINE:-}"
    if [ -z "$wine" ]; then
        for candidate in wine64 wine /usr/lib/wine/wine64; do
            if command -v "$candidate" >/dev/null 2>&1; then
                wine="$candidate"
                break
            fi
        done
    fi
    if [ -z "$wine" ]; then
        echo "platform-run: Wine is not installed (apt-get install wine64)" >&2
        exit 127
    fi
    export WINEPREFIX="${WINEPREFIX:-${CARGO_TARGET_DIR:-$root/target}/wine}"
    # Wine's own diagnostics (fixme:, err:) are not the program's output.
    export WINEDEBUG="${WINEDEBUG:--all}"
    # No Mono or Gecko installers, no desktop integration when the prefix is created.
    export WINEDLLOVERRIDES="${WINEDLLOVERRIDES:-mscoree,mshtml,winemenubuilder.exe=}"
    # Wine 8 has no bcryptprimitives.dll, from which Rust's standard library draws its random
    # seeds: a shim (scripts/wine/bcryptprimitives.c) goes into the prefix's system folder.
    # Tests run in parallel: the first to get the lock makes the prefix, the others wait for it.
    shim="$WINEPREFIX/drive_c/windows/system32/bcryptprimitives.dll"
    if [ ! -f "$shim" ]; then
        (
            flock 9
            if [ ! -f "$shim" ]; then
                "$wine" cmd /c exit >/dev/null 2>&1 || true # creates the prefix
                x86_64-w64-mingw32-gcc -O2 -shared -o "$shim.$$.tmp" \
                    "$root/scripts/wine/bcryptprimitives.c" -ladvapi32
                mv "$shim.$$.tmp" "$shim"
            fi
        ) 9>"$WINEPREFIX.lock"
    fi
    exec "$wine" "$@"
    ;;
aarch64-unknown-linux-gnu)
    if ! command -v qemu-aarch64 >/dev/null 2>&1; then
        echo "platform-run: qemu-user is not installed (apt-get install qemu-user)" >&2
        exit 127
    fi
    export QEMU_LD_PREFIX="${QEMU_LD_PREFIX:-/usr/aarch64-linux-gnu}"
    # An Arm Neoverse N1 (AWS Graviton2, Ampere Altra; the Cortex-A76 of phones is its sibling):
    # NEON, no SVE. Under qemu's default CPU, `max`, tract sees SVE2 and adds its SVE kernels
    # (sve_mmm_f32_8x8, sve_mmv_f32_64x1) to those it may choose, and the C clip test took over
    # 10 minutes on a 2-core Xeon VM: 60 s as an N1.
    export QEMU_CPU="${QEMU_CPU:-neoverse-n1}"
    exec qemu-aarch64 "$@"
    ;;
*)
    echo "platform-run: no way to run $triple programs here" >&2
    exit 2
    ;;
esac

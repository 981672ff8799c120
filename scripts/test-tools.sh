#!/usr/bin/env bash
# Installs what the test suite needs beyond the Rust toolchain, a C compiler and a bare python3,
# each thing once: a second run finds it and installs nothing. scripts/test.sh runs it (in the
# background, while the first builds compile: it is mostly downloads); it can run alone.
#
#   target/venv       a project-local virtual environment with tests/requirements.txt (numpy,
#                     pytest, the wheel tools, bvhio, CLIP's tokenizer, Ray and websockets),
#                     refreshed when that file changes; never the system's site-packages
#   Debian packages   in one `apt-get install --no-install-recommends` (as root or through
#                     `sudo -n`), only those whose tool is missing: chromium (the picture tests),
#                     valgrind (the C memory check), cmake (the installed package's consumer),
#                     Mono (the C# binding), the MinGW-w64 and aarch64 cross toolchains with Wine
#                     and qemu-user (docs/PLATFORMS.md), Node.js, and the X and GL libraries
#                     Blender's module links
#   Rust targets      x86_64-pc-windows-gnu, aarch64-unknown-linux-gnu, aarch64-linux-android
#                     and wasm32-unknown-unknown, with rustfmt and clippy (rustup)
#   target/zig        the linker of the x86_64 Linux builds (scripts/zig-cc.sh): cargo-zigbuild
#                     and zig from PyPI, pinned, so the library asks for glibc 2.28 at most
#   target/npm        Khronos' gltf-validator, three.js and playwright-core, pinned
#   target/blender    Blender as PyPI's `bpy` (a build for Python 3.11, about 1 GB) in its own
#                     environment: its numpy pin differs from the suite's
#
#   scripts/test-tools.sh [all|rust|zig|packages]   everything (default), the Rust targets,
#                                                   components and linker, the linker alone
#                                                   (scripts/wheel.sh), or all but those
#
# (scripts/test.sh adds the Rust parts first, in the foreground: rustup must not run twice at
# once, and scripts/web.sh may add a target of its own.)
#
# A tool that cannot be installed is reported; under CI the tests that need it then fail, and
# elsewhere they record a counted skip (tests/common/mod.rs). Only a missing Python environment
# or Chromium stops the run here.
set -euo pipefail
cd "$(dirname "$0")/.."
# Its steps' wall times join the test command's table when it runs under it.
declare -F phase >/dev/null || phase() { echo "== $1"; }

what="${1:-all}"
case "$what" in
all | rust | zig | packages) ;;
*) echo "test-tools.sh: unknown argument $what (all, rust, zig or packages)" >&2; exit 2 ;;
esac
venv=target/venv
requirements=tests/requirements.txt

# Debian packages, as root or through `sudo -n`; `apt-get update` once, before the first install.
apt_updated=
apt_install() {
    local apt_get=(env DEBIAN_FRONTEND=noninteractive apt-get)
    [ "$(id -u)" -eq 0 ] || apt_get=(sudo -n "${apt_get[@]}")
    if [ -z "$apt_updated" ]; then
        "${apt_get[@]}" update -qq || true
        apt_updated=1
    fi
    "${apt_get[@]}" install -y -qq --no-install-recommends "$@" || true
}

# A virtual environment at $1 (Debian's python3 keeps venv in a separate package).
make_venv() {
    [ -x "$1/bin/python3" ] && return 0
    echo "== python: creating $1"
    python3 -m venv "$1" 2>/dev/null && return 0
    rm -rf "$1"
    apt_install python3-venv
    python3 -m venv "$1"
}

# 1. The Rust targets the cross-platform checks and the web page build for, and the lint tools.
if { [ "$what" = all ] || [ "$what" = rust ]; } && command -v rustup >/dev/null 2>&1; then
    phase "install: rust targets and components"
    targets="x86_64-pc-windows-gnu aarch64-unknown-linux-gnu aarch64-linux-android wasm32-unknown-unknown"
    installed=$(rustup target list --installed 2>/dev/null || true)
    wanted=
    for target in $targets; do
        grep -qx "$target" <<<"$installed" || wanted="$wanted $target"
    done
    if [ -n "$wanted" ]; then
        echo "== rustup target add$wanted"
        # shellcheck disable=SC2086  (the targets are a list)
        rustup target add $wanted >/dev/null 2>&1 ||
            echo "rustup target add$wanted failed: the cross and web checks fail under CI" >&2
    fi
    rustup component add rustfmt clippy >/dev/null 2>&1 || true
fi

# The linker (scripts/zig-cc.sh) goes with the Rust parts: the first build needs it. Pinned: the
# wrapper's flags and zig's glibc stubs are what the wheel's manylinux_2_28 tag rests on.
zig_requirement="cargo-zigbuild==0.24.1 ziglang==0.17.1"
zig_env=target/zig
if [ "$what" != packages ] && [ "$(uname -sm)" = "Linux x86_64" ] &&
    [ "$(cat "$zig_env/.installed" 2>/dev/null)" != "$zig_requirement" ]; then
    phase "install: the linker (zig, cargo-zigbuild)"
    rm -rf "$zig_env"
    # shellcheck disable=SC2086  (the requirement is a list)
    if make_venv "$zig_env" &&
        "$zig_env/bin/python3" -m pip install --quiet --disable-pip-version-check $zig_requirement; then
        echo "$zig_requirement" >"$zig_env/.installed"
    else
        echo "pip install $zig_requirement failed: the library links against this machine's glibc" \
            "and the wheel's tag check fails under CI" >&2
    fi
fi

[ "$what" != rust ] && [ "$what" != zig ] || return 0 2>/dev/null || exit 0

# 2. Python: the suite's virtual environment.
phase "install: python environment"
make_venv "$venv"
stamp="$venv/.requirements"
if ! cmp -s "$requirements" "$stamp"; then
    echo "== python: installing $requirements"
    "$venv/bin/python3" -m pip install --quiet --disable-pip-version-check -r "$requirements"
    cp "$requirements" "$stamp"
fi

# 3. Debian's packages, one install for all that are missing. Each line: the command that
#    shows the package is there, the packages, and what needs them.
phase "install: debian packages"
tools=(
    "chromium|chromium|the picture tests (viewer, demo, web)"
    "valgrind|valgrind|the C tests under valgrind (tests/c_abi.rs)"
    "cmake|cmake|the installed package's CMake consumer (tests/install.rs)"
    "mcs|mono-mcs mono-runtime|the C# binding's test under Mono (tests/csharp.rs)"
    "x86_64-w64-mingw32-g++|gcc-mingw-w64-x86-64 g++-mingw-w64-x86-64|the Windows x64 build (tests/platforms.rs)"
    "wine|wine wine64|the Windows x64 tests under Wine (tests/platforms.rs)"
    "aarch64-linux-gnu-g++|gcc-aarch64-linux-gnu g++-aarch64-linux-gnu libc6-dev-arm64-cross|the Linux arm64 build (tests/platforms.rs)"
    "qemu-aarch64|qemu-user|the Linux arm64 tests under qemu (tests/platforms.rs)"
    "node|nodejs npm|the glTF validator, three.js and web page tests (tests/rigs.rs, tests/web.rs)"
)
# The libraries bpy links (libX11, libGL, ...), each checked with dpkg-query where there is one.
blender_libraries="libx11-6 libxrender1 libxfixes3 libxi6 libxkbcommon0 libxext6 libsm6 libice6 libgl1 libvulkan1 libxxf86vm1"
missing=()
for line in "${tools[@]}"; do
    IFS='|' read -r command packages _ <<<"$line"
    if [ "$command" = chromium ] && [ -n "${TROUPE_CHROMIUM:-}" ]; then
        continue
    fi
    if ! command -v "$command" >/dev/null 2>&1; then
        read -ra more <<<"$packages"
        missing+=("${more[@]}")
    fi
done
if command -v dpkg-query >/dev/null 2>&1; then
    for package in $blender_libraries; do
        dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "ok installed" ||
            missing+=("$package")
    done
fi
if [ "${#missing[@]}" -gt 0 ]; then
    echo "== debian: installing ${missing[*]}"
    apt_install "${missing[@]}"
fi
for line in "${tools[@]}"; do
    IFS='|' read -r command packages needs <<<"$line"
    if [ "$command" = chromium ]; then
        if [ -z "${TROUPE_CHROMIUM:-}" ] && ! command -v chromium >/dev/null 2>&1; then
            echo "chromium is missing and could not be installed; the picture tests need it" \
                "(apt-get install chromium, or set TROUPE_CHROMIUM to a Chromium binary)" >&2
            exit 1
        fi
    elif ! command -v "$command" >/dev/null 2>&1; then
        echo "$command is missing and could not be installed (apt-get install $packages):" \
            "$needs fails under CI and is skipped elsewhere" >&2
    fi
done

# 4. The clients the rig, glTF and web tests run: npm's, pinned, in target/npm.
phase "install: npm packages"
npm_packages="gltf-validator@2.0.0-dev.3.10 three@0.187.0 playwright-core@1.65.1"
npm_dir=target/npm
if command -v npm >/dev/null 2>&1 && [ "$(cat "$npm_dir/.installed" 2>/dev/null)" != "$npm_packages" ]; then
    echo "== npm: installing $npm_packages into $npm_dir"
    mkdir -p "$npm_dir"
    [ -f "$npm_dir/package.json" ] || echo '{"private": true}' >"$npm_dir/package.json"
    # shellcheck disable=SC2086  (the packages are a list)
    if (cd "$npm_dir" && npm install --no-audit --no-fund --silent $npm_packages); then
        echo "$npm_packages" >"$npm_dir/.installed"
    else
        echo "npm install $npm_packages failed: tests/rigs.rs fails" >&2
    fi
fi

# 5. Blender's module, in its own environment.
phase "install: blender (bpy)"
blender_requirement="bpy==4.5.15"
blender=target/blender
if [ "$(cat "$blender/.installed" 2>/dev/null)" != "$blender_requirement" ]; then
    echo "== blender: installing $blender_requirement into $blender"
    rm -rf "$blender"
    if python3 -m venv "$blender" &&
        "$blender/bin/python3" -m pip install --quiet --disable-pip-version-check "$blender_requirement"; then
        echo "$blender_requirement" >"$blender/.installed"
    else
        echo "pip install $blender_requirement failed: the Blender test fails under CI" >&2
    fi
fi
if [ -x "$blender/bin/python3" ] && ! "$blender/bin/python3" -c "import bpy" >/dev/null 2>&1; then
    echo "bpy does not import (the libraries it links: $blender_libraries):" \
        "the Blender test fails under CI" >&2
fi

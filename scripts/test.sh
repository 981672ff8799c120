#!/usr/bin/env bash
# The project's test command: on a machine with only the Rust toolchain, a C compiler and a bare
# python3, it installs what the suite needs (a project-local virtual environment for the Python
# tests, Ray and websockets for the serving tests among them; Debian's chromium for the picture
# tests, valgrind for the C memory check, cmake for the installed package's consumer, Mono for
# the C# binding, the Windows and arm64 cross toolchains with Wine and qemu-user, Node.js with
# gltf-validator and three.js, Blender's bpy, the wasm32 target with wasm-bindgen-cli for the web
# page) and runs every
# check CI runs. It ends with the count of checks the tests skipped, and why (torch-dependent
# ones are optional; see tests/common/mod.rs, `skip`).
#
#   scripts/test.sh              format, lint, every test, the demo and benchmark smoke runs
#   TROUPE_SLOW_TESTS=1 ...      also the long forms (training reproduction, soak, long fuzz)
#
# Extra arguments go to `cargo test` (e.g. `scripts/test.sh --test streaming`), which then runs
# alone, without the format, lint and smoke steps.
set -euo pipefail
cd "$(dirname "$0")/.."

# A one-off build (CI) gains nothing from incremental compilation and its ~0.8 GB of state, nor
# from line tables (~15 MB in each of the ~45 test and example binaries): a CI machine's disk is
# not always large (one ran out in the cross-platform step).
if [ -n "${CI:-}" ]; then
    export CARGO_INCREMENTAL=0
    export CARGO_PROFILE_DEV_DEBUG=false
fi
# Under CI, a step's build folders and tools are deleted once no later step needs them.
ci_discard() {
    [ -n "${CI:-}" ] || return 0
    local path
    for path in "$@"; do
        [ -e "$path" ] || continue
        echo "== CI: freeing $(du -sh "$path" | cut -f1) ($path, no later step uses it)"
        rm -rf "$path"
    done
}

# Every step's wall time, printed when the script ends (scripts/phases.sh).
. scripts/phases.sh
trap phase_summary EXIT

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

# 1. Python: a virtual environment under target/ (never the system's site-packages), refreshed
#    when tests/requirements.txt changes.
phase "install: python environment"
if [ ! -x "$venv/bin/python3" ]; then
    echo "== python: creating $venv"
    if ! python3 -m venv "$venv" 2>/dev/null; then
        # Debian's python3 keeps venv in a separate package.
        rm -rf "$venv"
        apt_install python3-venv
        python3 -m venv "$venv"
    fi
fi
stamp="$venv/.requirements"
if ! cmp -s "$requirements" "$stamp"; then
    echo "== python: installing $requirements"
    "$venv/bin/python3" -m pip install --quiet --disable-pip-version-check -r "$requirements"
    cp "$requirements" "$stamp"
fi
# The tests run `python3`: the environment's comes first on PATH.
PATH="$PWD/$venv/bin:$PATH"
export PATH

# 2. Chromium: the viewer and demo tests screenshot the HTML player.
phase "install: chromium"
if [ -z "${TROUPE_CHROMIUM:-}" ] && ! command -v chromium >/dev/null 2>&1; then
    echo "== chromium: installing Debian's package"
    apt_install chromium
    if ! command -v chromium >/dev/null 2>&1; then
        echo "chromium is missing and could not be installed; the picture tests need it" \
            "(apt-get install chromium, or set TROUPE_CHROMIUM to a Chromium binary)" >&2
        exit 1
    fi
fi

# 3. Tools tests need, each a Debian package. Under CI a test whose tool is missing fails;
#    elsewhere it records a counted skip.
#    ensure_tool COMMAND "PACKAGES" "WHAT NEEDS IT"
ensure_tool() {
    command -v "$1" >/dev/null 2>&1 && return
    echo "== $1: installing Debian's $2"
    # shellcheck disable=SC2086  (the packages are a list)
    apt_install $2
    if ! command -v "$1" >/dev/null 2>&1; then
        echo "$1 is missing and could not be installed (apt-get install $2): $3 fails under CI" \
            "and is skipped elsewhere" >&2
    fi
}
phase "install: debian tools"
ensure_tool valgrind valgrind "the C tests under valgrind (tests/c_abi.rs)"
ensure_tool cmake cmake "the installed package's CMake consumer (tests/install.rs)"
ensure_tool mcs "mono-mcs mono-runtime" "the C# binding's test under Mono (tests/csharp.rs)"

# 4. The other platforms (docs/PLATFORMS.md): Windows x64 cross-built with MinGW-w64 and run under
#    Wine, Linux arm64 cross-built and run under qemu-user; the Rust standard library for each.
cross_targets="x86_64-pc-windows-gnu aarch64-unknown-linux-gnu"
android=aarch64-linux-android
ensure_tool x86_64-w64-mingw32-g++ "gcc-mingw-w64-x86-64 g++-mingw-w64-x86-64" \
    "the Windows x64 build (tests/platforms.rs)"
ensure_tool wine "wine wine64" "the Windows x64 tests under Wine (tests/platforms.rs)"
ensure_tool aarch64-linux-gnu-g++ "gcc-aarch64-linux-gnu g++-aarch64-linux-gnu libc6-dev-arm64-cross" \
    "the Linux arm64 build (tests/platforms.rs)"
ensure_tool qemu-aarch64 qemu-user "the Linux arm64 tests under qemu (tests/platforms.rs)"
phase "install: rust cross targets"
if command -v rustup >/dev/null 2>&1; then
    # shellcheck disable=SC2086  (the targets are a list)
    rustup target add $cross_targets $android >/dev/null 2>&1 ||
        echo "rustup target add $cross_targets $android failed: the cross tests fail under CI" >&2
fi

# 5. The clients the rig and glTF tests run (tests/rigs.rs): Node.js with Khronos' gltf-validator
#    and three.js from npm, pinned, in target/npm (with playwright-core, which drives Chromium for
#    the web page's tests, tests/web.rs); Blender as PyPI's `bpy` (a build for this
#    Python, 3.11) in its own environment, target/blender (about 1 GB; its numpy pin differs
#    from the suite's), with the X and GL libraries its module links.
phase "install: node and npm packages"
ensure_tool node "nodejs npm" "the glTF validator, three.js and web page tests (tests/rigs.rs, tests/web.rs)"
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
    echo "== blender: installing the libraries bpy links"
    apt_install libx11-6 libxrender1 libxfixes3 libxi6 libxkbcommon0 libxext6 libsm6 libice6 \
        libgl1 libvulkan1 libxxf86vm1
fi

# 6. The web page (docs/WEB.md, tests/web.rs): troupe-web built for wasm32 into web/pkg by
#    scripts/web.sh, which installs the wasm32 target and the pinned wasm-bindgen-cli itself.
phase "web: building the page (scripts/web.sh)"
if ! scripts/web.sh; then
    [ -z "${CI:-}" ] || exit 1
    echo "scripts/web.sh failed: tests/web.rs runs on an older web/pkg or skips" >&2
fi

# Tests that cannot run their check append `<test binary>::<test><TAB><reason>` here
# (tests/common/mod.rs, `skip`); emptied before the tests, summed up when the script ends,
# whether it passes or fails.
skips="${CARGO_TARGET_DIR:-target}/test-skips.txt"
skip_summary() {
    local n=0
    [ -f "$skips" ] && n=$(wc -l <"$skips")
    echo "== skipped checks: $n"
    if [ "$n" -gt 0 ]; then
        sort "$skips" | sed 's/\t/: /; s/^/   /'
    fi
}
start_tests() {
    mkdir -p "$(dirname "$skips")"
    : >"$skips"
    trap 'phase_summary; skip_summary' EXIT
}

if [ "$#" -gt 0 ]; then
    start_tests
    phase "cargo test $*"
    cargo_test_timed "$@"
    exit
fi

if command -v rustup >/dev/null 2>&1; then
    rustup component add rustfmt clippy >/dev/null 2>&1 || true
fi

phase "format"
cargo fmt --check

phase "lint: clippy (host, all targets)"
cargo clippy --all-targets -- -D warnings
phase "lint: clippy (web, wasm32)"
# The web bindings, for the only target they are built for (bindings/web/.cargo/config.toml).
(cd bindings/web && cargo fmt --check &&
    CARGO_TARGET_DIR=../../target/web-build cargo clippy --locked -- -D warnings)
ci_discard target/web-build
phase "lint: clippy (windows)"
if [ -d "$(rustc --print sysroot)/lib/rustlib/x86_64-pc-windows-gnu" ]; then
    # The code only Windows compiles (src/shared/paths.rs, the bundle loader's file checks).
    cargo clippy --lib --target x86_64-pc-windows-gnu -- -D warnings
fi

start_tests
phase "tests: build (cargo test --no-run)"
cargo test --no-run
phase "tests: run (cargo test)"
cargo_test_timed
ci_discard "$blender" target/release

echo "== other platforms: the unit and golden parity tests under Wine and qemu (docs/PLATFORMS.md)"
phase_end
sysroot="$(rustc --print sysroot)"
for triple in $cross_targets; do
    runner_tool=wine
    [ "$triple" = aarch64-unknown-linux-gnu ] && runner_tool=qemu-aarch64
    phase "other platforms: cargo test --target $triple"
    if [ -d "$sysroot/lib/rustlib/$triple" ] && command -v "$runner_tool" >/dev/null 2>&1; then
        # Optimised: emulated unoptimised code is slow. The same build as tests/platforms.rs'.
        cargo test --release --target "$triple" --features testing --lib --test golden
        ci_discard "target/$triple"
    elif [ -n "${CI:-}" ]; then
        echo "the Rust target $triple or $runner_tool is missing and CI is set" >&2
        exit 1
    else
        printf 'scripts/test.sh::cargo test --target %s\t%s\n' "$triple" \
            "the Rust target or $runner_tool is not installed" >>"$skips"
    fi
done
ci_discard target/wine
# Android: no NDK can be had from the registries, so the library is not linked; every crate is
# type-checked for it, tract's NEON assembly assembled by the Linux arm64 GNU assembler.
phase "other platforms: cargo check --target $android"
if [ -d "$sysroot/lib/rustlib/$android" ] && command -v aarch64-linux-gnu-gcc >/dev/null 2>&1; then
    CC_aarch64_linux_android=aarch64-linux-gnu-gcc AR_aarch64_linux_android=aarch64-linux-gnu-ar \
        cargo check --lib --target "$android"
    ci_discard "target/$android"
elif [ -n "${CI:-}" ]; then
    echo "the Rust target $android or aarch64-linux-gnu-gcc is missing and CI is set" >&2
    exit 1
else
    printf 'scripts/test.sh::cargo check --target %s\t%s\n' "$android" \
        "the Rust target or aarch64-linux-gnu-gcc is not installed" >>"$skips"
fi

phase "smoke: streaming and magnet demos"
cargo run --example stream -- --frames 120 --tick 3 --out target/ci-reactor.npy --gltf target/ci-reactor.glb
cargo run --example magnet -- --steps 2 --samples 1 --seq-len 64 --no-x0-guidance --out target/ci-magnet.npy

phase "smoke: benchmarks (each once, tiny bundle; speed is not checked here)"
# `cargo test` runs a criterion benchmark once, in the test profile the suite already built
# (`cargo bench` would build everything again, optimised, for no check it adds).
cargo test --bench step
cargo test --bench graph_rows

#!/usr/bin/env bash
# The project's test command: on a machine with only the Rust toolchain, a C compiler and a bare
# python3, it installs what the suite needs (scripts/test-tools.sh: a project-local virtual
# environment for the Python tests, Debian's chromium, valgrind, cmake, Mono, the Windows and
# arm64 cross toolchains with Wine and qemu-user, Node.js with gltf-validator, three.js and
# playwright-core, Blender's bpy, the Rust targets; scripts/web.sh: wasm-bindgen-cli for the web
# page) and runs every check CI runs. It ends with the wall time of each phase
# (scripts/phases.sh) and the count of checks the tests skipped, and why (torch-dependent ones
# are optional; see tests/common/mod.rs, `skip`).
#
#   scripts/test.sh              format, lint, every test, the demo and benchmark smoke runs
#   TROUPE_SLOW_TESTS=1 ...      also the long forms (training reproduction, soak, long fuzz)
#
# Extra arguments go to `cargo test` (e.g. `scripts/test.sh --test streaming`), which then runs
# after the installs and the web page's build, without the format, lint, cross-platform and
# smoke steps.
#
# Each build is made once (docs/TESTING.md): clippy lints the workspace's crates while they are
# compiled for the tests (clippy-driver as cargo's workspace wrapper), so the lint is not a
# second build of every dependency; the library is built with the `testing` feature that the C
# tests' build asks for, so theirs finds it built; the Windows and arm64 libraries the platform
# tests load are the ones their unit and golden tests were built with, both targets in one
# cargo run; the tool installs download while the host build compiles; the web page and the
# cross builds compile in the background, at a low CPU priority, while the host's tests run
# (which leave part of the two cores idle, waiting on browsers, Ray, compilers and emulators).
set -euo pipefail
cd "$(dirname "$0")/.."

# Every step's wall time, printed when the script ends (scripts/phases.sh).
. scripts/phases.sh
# Background jobs (bg_start, bg_wait): their output goes to a log, printed when they are
# waited for; one that failed ends the run there. A step that fails ends the run, and the jobs
# still running end with it (the EXIT trap).
kill_tree() {
    local child
    for child in $(cat "/proc/$1/task/$1/children" 2>/dev/null); do
        kill_tree "$child"
    done
    kill "$1" 2>/dev/null || true
}
stop_background() {
    local job
    for job in $(jobs -p); do
        kill_tree "$job"
    done
}
trap 'stop_background; phase_summary' EXIT
declare -A bg_pids=() bg_logs=()
# bg_start NAME NICENESS COMMAND...: COMMAND in the background as phase NAME, at that niceness.
bg_start() {
    local name=$1 niceness=$2
    shift 2
    bg_logs[$name]="${CARGO_TARGET_DIR:-target}/background-$((${#bg_logs[@]} + 1))-$(echo "$name" |
        tr -c 'a-zA-Z0-9\n' '-' | cut -c1-40).log"
    (
        trap - EXIT
        renice -n "$niceness" -p "$BASHPID" >/dev/null || true
        phase_name='' phase_prefix="background: "
        phase "$name"
        "$@"
        phase_end
    ) >"${bg_logs[$name]}" 2>&1 &
    bg_pids[$name]=$!
}
# bg_wait NAME: waits for the job, prints its output, and stops the run if it failed.
bg_wait() {
    local name=$1 status=0
    [ -n "${bg_pids[$name]:-}" ] || return 0
    phase "waiting for: $name"
    wait "${bg_pids[$name]}" || status=$?
    unset "bg_pids[$name]"
    sed 's/^/   | /' "${bg_logs[$name]}"
    [ "$status" -eq 0 ] || { echo "background step failed ($status): $name" >&2; exit "$status"; }
}

# A one-off build (CI) gains nothing from incremental compilation and its ~0.8 GB of state, nor
# from line tables (~15 MB in each of the ~45 test and example binaries): a CI machine's disk is
# not always large (one ran out in the cross-platform step).
if [ -n "${CI:-}" ]; then
    export CARGO_INCREMENTAL=0
    export CARGO_PROFILE_DEV_DEBUG=false
fi
# Under CI, a step's build folders and tools are deleted once no later step needs them if the
# disk is short of room (under 10 GiB free; all of them together take about 4 GiB); with room
# to spare they stay, and a second run finds them built.
ci_discard() {
    [ -n "${CI:-}" ] || return 0
    local path free_kib
    free_kib=$(df -Pk . | awk 'NR == 2 { print $4 }')
    if [ "${free_kib:-0}" -ge $((10 * 1024 * 1024)) ]; then
        echo "== CI: keeping $* ($((free_kib / 1024 / 1024)) GiB free)"
        return 0
    fi
    for path in "$@"; do
        [ -e "$path" ] || continue
        echo "== CI: freeing $(du -sh "$path" | cut -f1) ($path, no later step uses it)"
        rm -rf "$path"
    done
}

# The tests run `python3`: the suite's environment (scripts/test-tools.sh makes it) comes first.
PATH="$PWD/target/venv/bin:$PATH"
export PATH

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
    trap 'stop_background; phase_summary; skip_summary' EXIT
}

# x86_64 Linux builds link through zig against glibc 2.28's symbol versions (scripts/zig-cc.sh,
# installed by scripts/test-tools.sh into target/zig), so the library the tests load is the one
# the wheel ships, and its manylinux_2_28 tag is checked (tests/python_bindings.rs). Set for
# every build of the run: cargo rebuilds whatever a different linker built.
use_glibc_228_linker() {
    [ "$(uname -sm)" = "Linux x86_64" ] || return 0
    if [ -x target/zig/bin/cargo-zigbuild ]; then
        export CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_LINKER="$PWD/scripts/zig-cc.sh"
    elif [ -n "${CI:-}" ]; then
        echo "target/zig (cargo-zigbuild and zig) is missing and CI is set" >&2
        exit 1
    else
        echo "target/zig is missing: the library links against this machine's glibc" >&2
    fi
}

if [ "$#" -gt 0 ]; then
    . scripts/test-tools.sh all
    use_glibc_228_linker
    phase "web: building the page (scripts/web.sh)"
    scripts/web.sh || echo "scripts/web.sh failed: tests/web.rs runs on an older web/pkg or skips" >&2
    start_tests
    phase "cargo test $*"
    cargo_test_timed "$@"
    exit
fi

# 1. The installs: the Rust targets and components first (rustup must not run twice at once),
#    then the rest in the background: mostly downloads, which the host build overlaps. Their
#    output is printed when they are waited for.
. scripts/test-tools.sh rust
use_glibc_228_linker
install_packages() {
    . scripts/test-tools.sh packages
}
bg_start "installs (scripts/test-tools.sh)" 0 install_packages

phase "format"
cargo fmt --check
(cd bindings/web && cargo fmt --check)

# 2. Lint while building: every cargo build from here on compiles the workspace's own crates
#    with clippy-driver (what `cargo clippy` runs, but producing the binaries too) and denies
#    its warnings; dependencies are compiled by rustc as always and shared with plain builds.
#    The wrapped builds keep artefacts of their own beside plain `cargo test`'s, so neither
#    invalidates the other.
clippy_driver=$(command -v clippy-driver || true)
if [ -z "$clippy_driver" ]; then
    echo "clippy-driver is missing (rustup component add clippy): the lint cannot run" >&2
    exit 1
fi
export RUSTC_WORKSPACE_WRAPPER="$clippy_driver"
# `cargo clippy -- -D warnings` passes its arguments to the driver this way.
export CLIPPY_ARGS="-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__"
# That convention is clippy's own: should a release change it, the builds would lint without
# denying. So first, a lint warning must stop a compilation through the wrapper.
lint_probe=$(mktemp -d)
printf 'pub fn f(x: &Vec<i32>) -> usize {\n    x.len()\n}\n' >"$lint_probe/lib.rs"
if "$clippy_driver" rustc --edition 2021 --crate-type lib --emit=metadata \
    --out-dir "$lint_probe" "$lint_probe/lib.rs" >"$lint_probe/out" 2>&1 ||
    ! grep -q 'implied by `-D warnings`' "$lint_probe/out"; then
    cat "$lint_probe/out" >&2
    echo "clippy-driver with CLIPPY_ARGS=$CLIPPY_ARGS does not deny a warning: the lint would" \
        "pass anything" >&2
    exit 1
fi
rm -rf "$lint_probe"

start_tests
phase "build: host, every target, linted (cargo test --no-run; --benches)"
# Not `--all-targets`: that also builds each example a second time, as a test harness nothing
# runs (about 50 MB and a link apiece). The default set builds the examples as `cargo run
# --example` does; the benchmarks are built as the smoke phase runs them.
cargo test --features testing --no-run
cargo test --features testing --no-run --benches

# The joins below need the installs: the cross linkers, Wine and qemu, the browsers.
bg_wait "installs (scripts/test-tools.sh)"

# 3. In the background, at low CPU priority, while the host's tests run in front: the web
#    page and the other platforms' builds. Neither shares a cargo lock with the host's builds
#    (the web page has its own target folder; the cross builds are `release`, the host's `dev`).
#
#    The web page (docs/WEB.md, tests/web.rs): troupe-web built for wasm32 into web/pkg (linted
#    as it compiles), with the pinned wasm-bindgen-cli, which scripts/web.sh installs once.
build_web() {
    scripts/web.sh
    ci_discard target/web-build
}
bg_start "build: web page (scripts/web.sh)" 10 build_web

#    The other platforms (docs/PLATFORMS.md): Windows x64 cross-built with MinGW-w64 and run
#    under Wine, Linux arm64 cross-built and run under qemu-user. Optimised, because emulated
#    unoptimised code is slow, but at opt-level 1: tract's kernels are assembly either way, and
#    the two targets compile in about four fifths of the time for a few seconds more under the
#    emulators (docs/TESTING.md). The unit and golden tests and the library tests/platforms.rs
#    loads, both targets in one cargo run (linted: the code only Windows compiles,
#    src/shared/paths.rs and the bundle loader's file checks, is checked here). Built with
#    `--cfg troupe_emulated_tests`, which leaves out the dev-dependencies those tests do not use
#    (Cargo.toml); the flags are the targets' own (not the release profile's, which the web
#    page's build reads) and exported for the whole run, so the platform tests' own builds find
#    the library built.
cross_targets="x86_64-pc-windows-gnu aarch64-unknown-linux-gnu"
android=aarch64-linux-android
sysroot="$(rustc --print sysroot)"
cross_ready=()
for triple in $cross_targets; do
    runner_tool=wine
    [ "$triple" = aarch64-unknown-linux-gnu ] && runner_tool=qemu-aarch64
    if [ -d "$sysroot/lib/rustlib/$triple" ] && command -v "$runner_tool" >/dev/null 2>&1; then
        cross_ready+=("$triple")
        export "CARGO_TARGET_$(echo "$triple" | tr 'a-z-' 'A-Z_')_RUSTFLAGS=--cfg troupe_emulated_tests -C opt-level=1"
    elif [ -n "${CI:-}" ]; then
        echo "the Rust target $triple or $runner_tool is missing and CI is set" >&2
        exit 1
    else
        printf 'scripts/test.sh::cargo test --target %s\t%s\n' "$triple" \
            "the Rust target or $runner_tool is not installed" >>"$skips"
    fi
done
cross_build=""
if [ "${#cross_ready[@]}" -gt 0 ]; then
    cross_build="build: ${cross_ready[*]} (release, linted)"
    bg_start "$cross_build" 19 \
        cargo test --release --features testing "${cross_ready[@]/#/--target=}" --lib --test golden --no-run
fi

# 4. In front: the Android check, the API docs, then the host's tests.
#    Android: no NDK can be had from the registries, so the library is not linked; every crate is
#    type-checked for it, tract's NEON assembly assembled by the Linux arm64 GNU assembler.
phase "build: cargo check --target $android"
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

#    The API docs: every intra-doc link resolves and no public item's docs point at a private one.
phase "docs: cargo doc, warnings denied"
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --features testing

#    Every test binary but the two that need a background build (tests/web.rs and
#    tests/platforms.rs, run once it is done), then the documentation's code samples.
host_tests=()
for file in tests/*.rs; do
    name=$(basename "$file" .rs)
    case "$name" in web | platforms) ;; *) host_tests+=("--test=$name") ;; esac
done
phase "tests: run (cargo test), but for the web page's and the other platforms'"
cargo_test_timed --features testing --lib "${host_tests[@]}"
phase "tests: documentation samples (cargo test --doc)"
cargo_test_timed --features testing --doc
ci_discard target/blender

phase "smoke: streaming and magnet demos"
cargo run --features testing --example stream -- --frames 120 --tick 3 --out target/ci-reactor.npy --gltf target/ci-reactor.glb
cargo run --features testing --example magnet -- --steps 2 --samples 1 --seq-len 64 --no-x0-guidance --out target/ci-magnet.npy

phase "smoke: benchmarks (each once, tiny bundle; speed is not checked here)"
# `cargo test` runs a criterion benchmark once, in the test profile the suite already built
# (`cargo bench` would build everything again, optimised, for no check it adds).
cargo test --features testing --bench step
cargo test --features testing --bench graph_rows

# 5. The tests that waited for a background build.
bg_wait "build: web page (scripts/web.sh)"
phase "tests: the web page (cargo test --test web)"
cargo_test_timed --features testing --test web

if [ -n "$cross_build" ]; then
    bg_wait "$cross_build"
    # The three emulated runs at once: each waits on Wine or qemu more than it computes, and
    # they share nothing but the Wine prefix, whose creation scripts/platform-run.sh locks. The
    # unit and golden parity tests under Wine and qemu (docs/PLATFORMS.md) in the background,
    # the C programs and installs tests/platforms.rs runs against the same libraries in front.
    emulated=()
    for triple in "${cross_ready[@]}"; do
        emulated+=("tests: cargo test --target $triple (Wine or qemu)")
        bg_start "${emulated[-1]}" 0 cargo test --release --target "$triple" --features testing --lib --test golden
    done
    phase "tests: the other platforms' libraries (cargo test --test platforms)"
    cargo_test_timed --features testing --test platforms
    for job in "${emulated[@]}"; do
        bg_wait "$job"
    done
    for triple in "${cross_ready[@]}"; do
        ci_discard "target/$triple"
    done
    ci_discard target/wine
fi

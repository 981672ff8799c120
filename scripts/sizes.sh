#!/usr/bin/env bash
# Measures what a build of each profile leaves: the shared library, the static library and the
# wheel (scripts/wheel.sh around that library), and the demo model the packages carry. Prints a
# Markdown table; with --update-docs, writes it into docs/INSTALL.md between its
# `<!-- sizes:begin -->` and `<!-- sizes:end -->` markers, stamped with the commit, the date, the
# compiler and the machine, so the document's sizes are this script's and say when they were
# taken (tests/install.rs checks the stamp and the sizes it can recompute cheaply).
#
#   scripts/sizes.sh                          # release and dist (dist: a long, link-time optimised build)
#   scripts/sizes.sh --profiles release       # one profile
#   scripts/sizes.sh --update-docs
#
# Builds as scripts/wheel.sh does (on x86_64 Linux linked through zig against glibc 2.28).
set -euo pipefail
cd "$(dirname "$0")/.."
profiles="release dist" update=
while [ "$#" -gt 0 ]; do
    case "$1" in
        --profiles) [ -n "${2:-}" ] || { echo "sizes.sh: --profiles needs a value" >&2; exit 2; }; profiles=$2; shift 2 ;;
        --update-docs) update=1; shift ;;
        -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
        *) echo "sizes.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
    esac
done
if [ "$(uname -sm)" = "Linux x86_64" ]; then
    scripts/test-tools.sh zig >&2
    export CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_LINKER="$PWD/scripts/zig-cc.sh"
fi
# Megabytes (10^6 bytes), one decimal, as the document gives them.
mb() { awk -v b="$(wc -c <"$1")" 'BEGIN { printf "%.1f MB", b / 1e6 }'; }
what_release="what the examples and benchmarks use; symbols kept, so profiles name functions"
what_dist="release with link-time optimisation across crates, one codegen unit, symbols stripped: what a package should ship"

wheels=$(mktemp -d)
trap 'rm -rf "$wheels"' EXIT
rows=()
for profile in $profiles; do
    echo "== cargo build --profile $profile --lib" >&2
    cargo build --profile "$profile" --lib >&2
    dir=${CARGO_TARGET_DIR:-target}/$profile
    scripts/wheel.sh --profile "$profile" --no-build --out "$wheels/$profile" >&2
    what=what_$profile
    rows+=("| \`$profile\` | ${!what:-} | $(mb "$dir/libtroupe.so") | $(mb "$dir/libtroupe.a") | $(mb "$wheels/$profile"/troupe-*.whl) |")
done
model_bytes=$(find onnx/bundles/armflow-demo -maxdepth 1 -type f -printf '%s\n' | awk '{ s += $1 } END { print s }')
table=$(
    echo "| profile | what | \`libtroupe.so\` | \`libtroupe.a\` | wheel |"
    echo "|---|---|---|---|---|"
    printf '%s\n' "${rows[@]}"
    echo
    echo "The demo model the packages carry: $(awk -v b="$model_bytes" 'BEGIN { printf "%.1f MB", b / 1e6 }')" \
        "(\`onnx/bundles/armflow-demo\`). Measured by \`scripts/sizes.sh --update-docs\` at commit" \
        "$(git rev-parse --short=12 HEAD)$(git diff --quiet HEAD -- src Cargo.toml Cargo.lock build.rs || echo ' with uncommitted changes')" \
        "on $(date -u +%Y-%m-%d), $(rustc --version | cut -d' ' -f1-2), $(uname -sm)."
)
echo "$table"
if [ -n "$update" ]; then
    doc=docs/INSTALL.md
    grep -q '^<!-- sizes:begin -->$' "$doc" && grep -q '^<!-- sizes:end -->$' "$doc" ||
        { echo "sizes.sh: $doc lacks the sizes markers" >&2; exit 1; }
    TABLE="$table" awk '
        /^<!-- sizes:begin -->$/ { print; print ENVIRON["TABLE"]; skip = 1; next }
        /^<!-- sizes:end -->$/ { skip = 0 }
        !skip' "$doc" >"$doc.tmp"
    mv "$doc.tmp" "$doc"
    echo "== wrote the sizes into $doc" >&2
fi

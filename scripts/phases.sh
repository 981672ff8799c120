# Phase timings for scripts/test.sh (sourced, not run): the wall time of every step the test
# command takes (tool installs, builds, each test binary, the cross-platform and smoke runs),
# printed when the script ends, pass or fail, so the next slow step shows in every CI log.
#
#   phase NAME            ends the running phase (if any) and starts NAME
#   phase_end             ends the running phase
#   cargo_test_timed ARGS `cargo test ARGS`, recording each test binary's own time as well
#   phase_summary         prints the table (the EXIT trap calls it)
#
# The table is also written to target/test-timings.tsv (phase, seconds), one run's worth.

phase_dir="${CARGO_TARGET_DIR:-target}"
phase_file="$phase_dir/test-timings.tsv"
phase_binaries="$phase_dir/test-binaries.tsv"
phase_name=
phase_started=
# Prepended to the names of the phases that follow: a background job's ("background: ").
phase_prefix=
phase_run_started=$(date +%s)
mkdir -p "$phase_dir"
: >"$phase_file"
: >"$phase_binaries"

phase_end() {
    [ -n "$phase_name" ] || return 0
    printf '%s\t%s\n' "$phase_name" "$(($(date +%s) - phase_started))" >>"$phase_file"
    phase_name=
}

phase() {
    phase_end
    phase_name="$phase_prefix$1"
    phase_started=$(date +%s)
    echo "== $1"
}

# `cargo test ARGS` with its output also kept, to read each binary's "finished in" line.
cargo_test_timed() {
    local log="$phase_dir/test-output.log" status=0
    cargo test "$@" 2>&1 | tee "$log" || status=$?
    # "Running tests/abi.rs (target/...)" or "Running unittests src/lib.rs (...)", "Doc-tests
    # troupe", then the binary's "test result: ... finished in 1.23s".
    awk '
        /^ +Running / { name = ($2 == "unittests") ? $3 : $2 }
        /^ +Doc-tests / { name = "doc-tests " $2 }
        /^test result:/ && name != "" {
            if (match($0, /finished in [0-9.]+s/)) {
                s = substr($0, RSTART + 12, RLENGTH - 13)
                printf "%s\t%s\n", name, s
            }
            name = ""
        }' "$log" >>"$phase_binaries"
    return "$status"
}

phase_summary() {
    phase_end
    [ -s "$phase_file" ] || return 0
    local total=$(($(date +%s) - phase_run_started))
    echo "== phase timings (wall seconds; $total in all; $phase_file)"
    awk -F'\t' '{ printf "   %6d s  %5.1f min  %s\n", $2, $2 / 60, $1 }' "$phase_file"
    if [ -s "$phase_binaries" ]; then
        echo "== test binaries, slowest first (their own run time, without the build)"
        sort -t"$(printf '\t')" -k2 -g -r "$phase_binaries" | head -15 |
            awk -F'\t' '{ printf "   %8.1f s  %s\n", $2, $1 }'
    fi
}

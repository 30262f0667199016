#!/usr/bin/env bash
# Bounded fuzzing run of the parser targets (cargo-fuzz, libFuzzer).
#
#   fuzz/run.sh                     # every target, 60 s each
#   SECONDS_PER_TARGET=300 fuzz/run.sh csv_stream mcap_recording
#   EXTRA_ARGS="-fork=1 -ignore_ooms=1" fuzz/run.sh mcap_recording  # go on past OOMs
#
# Needs the nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz --locked`).
# New inputs go to fuzz/scratch/<target>/ (git-ignored); the committed seeds in
# fuzz/corpus/<target>/ are read, never written. A crash, timeout or
# out-of-memory input lands in fuzz/artifacts/<target>/; the log of each run is
# fuzz/logs/<target>.log. Exit status 1 when any target found something.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cd "$here"

seconds="${SECONDS_PER_TARGET:-60}"
all_targets=(csv_stream mcap_recording vehicle_toml estimate_json wire_estimate state_files)
if (($# > 0)); then targets=("$@"); else targets=("${all_targets[@]}"); fi

max_len_of() {
    case "$1" in
        mcap_recording) echo 32768 ;;  # seeds are recordings of a few KB
        wire_estimate) echo 512 ;;     # the struct is 416 bytes
        *) echo 8192 ;;
    esac
}

mkdir -p logs
# Build every target first, so that the time limit is all fuzzing.
for t in "${targets[@]}"; do cargo +nightly fuzz build "$t"; done

failed=0
summary=()
for t in "${targets[@]}"; do
    mkdir -p "scratch/$t" "artifacts/$t"
    log="logs/$t.log"
    rc=0
    cargo +nightly fuzz run "$t" "scratch/$t" "corpus/$t" -- \
        -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
        -max_len="$(max_len_of "$t")" -print_final_stats=1 \
        -artifact_prefix="artifacts/$t/" ${EXTRA_ARGS:-} >"$log" 2>&1 || rc=$?
    execs="$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || true)"
    last="$(grep -E '^#[0-9]+' "$log" | tail -n 1 || true)"
    # Fork mode prints no final stats: take the last status line's count.
    execs="${execs:-$(grep -oE '^#[0-9]+' <<<"$last" | tr -d '#' || true)}"
    cov="$(grep -o 'cov: [0-9]*' <<<"$last" | grep -o '[0-9]*' || true)"
    ft="$(grep -o 'ft: [0-9]*' <<<"$last" | grep -o '[0-9]*' || true)"
    corp="$(grep -oE 'corp: [0-9]+(/[0-9]+[a-zA-Z]*)?' <<<"$last" | cut -d' ' -f2 || true)"
    found="none"
    if ((rc != 0)); then
        failed=1
        artifact="$(ls -t "artifacts/$t" 2>/dev/null | head -n 1 || true)"
        found="YES (exit $rc, artifacts/$t/${artifact:-?}, see $log)"
    fi
    line="$t: ${seconds}s, executions ${execs:-?}, cov ${cov:-?}, ft ${ft:-?}, corpus ${corp:-?} (units/bytes), crash: $found"
    echo "$line"
    summary+=("$line")
done

echo
echo "Summary (${seconds} s per target):"
printf '  %s\n' "${summary[@]}"
exit "$failed"

#!/usr/bin/env bash
# Repeats the fuzz campaign: seeds the corpora (seed.sh), builds the targets, then runs each
# target alone, as one libFuzzer process, for a fixed number of executions, and prints per
# target the executions, the wall seconds and the findings (files libFuzzer wrote to
# fuzz/artifacts/<target>/). libFuzzer stops a target at its first finding.
#
# Exits 1 when any target had a finding.
# Usage: fuzz/campaign.sh [--smoke] [--no-seed] [--no-build] [TARGET...]
#   --smoke     about 20 s per target (-max_total_time) instead of the execution counts
#   --no-seed   keep fuzz/corpus as it is (e.g. to go on from a previous campaign's corpus)
#   --no-build  use the binaries already built
# Environment: RUNS (default 1000000) and RUNS_DECODE (default 10000000) executions;
# CARGO_TARGET_DIR_FUZZ, the fuzz builds' target folder (default ~/.cache/pwgs/fuzz-target);
# PWENC, PWDEC, BUILD_LOCK as seed.sh reads them (BUILD_LOCK also serializes the fuzz build).
# Needs nightly Rust and cargo-fuzz 0.13.2.
set -euo pipefail

fuzz_dir=$(cd "$(dirname "$0")" && pwd)
all_targets=(container entropy octree camera_json ply colmap_bin transforms splat_file sog decode)
smoke=false seed=true build=true targets=()
for arg in "$@"; do
    case "$arg" in
        --smoke) smoke=true ;;
        --no-seed) seed=false ;;
        --no-build) build=false ;;
        -*) echo "unknown option $arg" >&2; exit 2 ;;
        *) targets+=("$arg") ;;
    esac
done
[[ ${#targets[@]} -gt 0 ]] || targets=("${all_targets[@]}")

cd "$fuzz_dir"
if $seed; then
    ./seed.sh # builds pwenc and pwdec in the workspace's usual target folder
fi
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR_FUZZ:-$HOME/.cache/pwgs/fuzz-target}"
if $build; then
    if [[ -n "${BUILD_LOCK:-}" ]]; then
        flock "$BUILD_LOCK" cargo +nightly fuzz build
    else
        cargo +nightly fuzz build
    fi
fi
bin="$CARGO_TARGET_DIR/x86_64-unknown-linux-gnu/release"

# Extra libFuzzer flags per target: dictionaries, and a length cap for decode so that the
# mutator works on small streams (executions per second fall with the stream's size).
flags_of() {
    case "$1" in
        container) echo "-dict=dict/decode.dict" ;;
        decode) echo "-dict=dict/decode.dict -max_len=16384" ;;
        ply) echo "-dict=dict/ply.dict" ;;
        camera_json | transforms | sog) echo "-dict=dict/json.dict" ;;
    esac
}

summary=()
total_findings=0
for target in "${targets[@]}"; do
    mkdir -p "artifacts/$target" "corpus/$target"
    if $smoke; then
        budget=(-max_total_time=20)
    elif [[ $target == decode ]]; then
        budget=(-runs="${RUNS_DECODE:-10000000}")
    else
        budget=(-runs="${RUNS:-1000000}")
    fi
    log="artifacts/$target/campaign.log"
    before=$(ls "artifacts/$target" | grep -cE '^(crash|timeout|oom|leak|slow-unit)-' || true)
    start=$(date +%s.%N)
    # One Rayon worker: the decoder's parallel parts leave the machine's other core alone.
    set +e
    # shellcheck disable=SC2046
    RAYON_NUM_THREADS=1 "$bin/$target" "${budget[@]}" -timeout=1 -rss_limit_mb=1024 -malloc_limit_mb=1024 \
        -print_final_stats=1 -artifact_prefix="artifacts/$target/" $(flags_of "$target") "corpus/$target" \
        > "$log" 2>&1
    status=$?
    set -e
    seconds=$(echo "$(date +%s.%N) - $start" | bc)
    executions=$(grep -oE '^stat::number_of_executed_units: *[0-9]+' "$log" | grep -oE '[0-9]+$' || true)
    [[ -n $executions ]] || executions=$(grep -oE '^#[0-9]+' "$log" | tail -1 | tr -d '#')
    after=$(ls "artifacts/$target" | grep -cE '^(crash|timeout|oom|leak|slow-unit)-' || true)
    findings=$((after - before))
    total_findings=$((total_findings + findings))
    line=$(printf '%-12s %10s execs %8.1f s %8.0f exec/s  findings: %d  (exit %d, log %s)' \
        "$target" "${executions:-0}" "$seconds" "$(echo "${executions:-0} / $seconds" | bc -l)" "$findings" "$status" "$log")
    echo "$line"
    summary+=("$line")
    if [[ $findings -gt 0 ]]; then
        grep -m1 -A3 -E "panicked at|ERROR: libFuzzer|==ERROR" "$log" | sed 's/^/    /'
    fi
    rm -rf /dev/shm/pwgs-fuzz-"$target"-*
done

echo
echo "campaign summary:"
printf '%s\n' "${summary[@]}"
# A finding fails the campaign, so that scripts (and CI) can stop on it.
[[ $total_findings -eq 0 ]] || { echo "$total_findings finding(s): see fuzz/artifacts/" >&2; exit 1; }

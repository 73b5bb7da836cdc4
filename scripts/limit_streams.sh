#!/usr/bin/env bash
# Times pwdec on the 1 MB streams at SPEC.md section 9's per-byte limits (written by the
# conformance crate's `limit-streams`): per stream, decoding alone (`--hash`), then a render at
# each view size, with pwdec's own timings, the whole command's wall time and its peak memory,
# as a Markdown table (docs/results/bounded-inputs.md).
#
# Usage: scripts/limit_streams.sh [--release] DIR    (DIR receives the streams and cameras)
set -euo pipefail

profile=debug
flags=()
if [[ "${1:-}" == --release ]]; then
    profile=release
    flags=(--release)
    shift
fi
dir=${1:?usage: scripts/limit_streams.sh [--release] DIR}
bin="${CARGO_TARGET_DIR:-target}/$profile"

cargo build "${flags[@]}" -q -p pwgs-pwdec -p pwgs-conformance --bin pwdec --bin limit-streams
"$bin/limit-streams" "$dir" >/dev/null

# Runs pwdec with the given arguments; prints its reported times (or its error, shortened),
# then wall seconds and peak MB.
measure() {
    local log time
    log=$(mktemp)
    time=$(mktemp)
    /usr/bin/time -o "$time" -f "%e %M" "$bin/pwdec" "$@" >"$log" 2>&1 || true
    local said
    said=$(grep -oE "(decoded|wrote) [^;]* in [0-9.]+ s|needs more than [0-9]+ units of blend work" "$log" |
        sed -E "s/^(decoded|wrote) .* in /\\1 in /" | paste -sd ';' -)
    read -r wall kb < <(tail -n 1 "$time")
    printf '%s | %s s | %d MB' "${said:-$(head -c 120 "$log")}" "$wall" $((kb / 1024))
    rm -f "$log" "$time"
}

echo "| stream | command | pwdec says | wall | peak |"
echo "|---|---|---|---|---|"
for stream in "$dir"/*.pwb; do
    name=$(basename "$stream" .pwb)
    echo "| $name | --hash | $(measure "$stream" --hash) |"
    for view in 1920x1080 320x240 64x48; do
        echo "| $name | $view | $(measure "$stream" --view "$dir/view-$view.json" -o "$dir/$name-$view.png") |"
    done
done

#!/usr/bin/env bash
# Where a training step's GPU time goes: runs the `training_device` bench on the GPU alone with
# CubeCL's per-kernel profiling (each kernel timed on the device, so the run is slower than
# the bench's own figures), then lists the kernels by total time, with their launch counts.
# First steps compile kernels: give enough steps that the steady state dominates.
#
#   scripts/profile_kernels.sh [bench options...]
#   scripts/profile_kernels.sh --cases anchor --scene ../shared/scenes/fern --downscale 4 --gpu-steps 20
#
# With --trace first, it times each step instead and counts the kernels CubeCL compiled during
# it, naming them: whether steps after the first still compile (new shapes, autotuning) shows
# here, not in the per-kernel profile. The same count for a whole `pwenc` run (its rate term
# and growth included, which the bench leaves out): `PWGS_TRACE_STEPS=1 CUBECL_DEBUG_LOG=stderr
# pwenc SCENE --device gpu ... 2>LOG`, then `scripts/profile_kernels.sh --count LOG`. With
# `BURN_FUSION_LOG=full` in the run's environment too, it also counts the segments Burn's fusion
# explored anew in each step (host work; none in a steady state whose operations repeat).
#
#   scripts/profile_kernels.sh --trace --cases anchor --scene ../shared/scenes/fern --downscale 4 --gpu-steps 20
#
# BENCH names the bench binary (default: the newest `training_device` test-profile build in
# $CARGO_TARGET_DIR or target/; build it with
# `cargo test -p pwgs-encoder --features gpu --bench training_device --no-run`). LOG keeps
# CubeCL's log (default: a temporary file); TOP kernels are listed (default 25).
set -euo pipefail
# Steps and the kernels compiled during each, from a log of CubeCL's compilations
# ("[START_KERNEL_COMPILATION]", then "name: Kernel...") and the steps' "[STEP] k ms" lines,
# and fusion's explorations ("[plan] exploration completed") where the log has them.
count_per_step() {
    awk '
        /^\[plan\] exploration completed/ { explored++; next }
        /^\[START_KERNEL_COMPILATION\]/ { compiled++; want = 1; next }
        want && /^name: / { n = $2; sub(/<.*/, "", n); sub(/.*::/, "", n); names[n]++; want = 0; next }
        /^\[STEP\]/ {
            list = ""
            for (k in names) list = list " " k "x" names[k]
            printf "step %4d %10.1f ms %4d explored %5d compiled%s\n", $2, $3, explored, compiled, list
            compiled = 0; explored = 0; delete names
        }' "$1"
}
if [ "${1:-}" = --count ]; then
    count_per_step "$2"
    exit 0
fi
target=${CARGO_TARGET_DIR:-target}/debug/deps
bench=${BENCH:-$(ls -t "$target"/training_device-* 2>/dev/null | grep -v '\.d$' | head -1)}
[ -x "$bench" ] || { echo "no training_device bench binary (set BENCH, or build it: see the header)" >&2; exit 2; }
log=${LOG:-$(mktemp)}
if [ "${1:-}" = --trace ]; then
    shift
    PWGS_TRACE_STEPS=1 CUBECL_DEBUG_LOG=stderr "$bench" --gpu-only "$@" 2>"$log"
    count_per_step "$log"
    exit 0
fi
CUBECL_DEBUG_OPTION=profile CUBECL_DEBUG_LOG=$log "$bench" --gpu-only "$@"
# CubeCL's profile lines read "| 1.68ms | KernelName_hash | ...".
grep -E '^\| [0-9.]+(ns|µs|ms|s) +\|' "$log" | awk -F'|' -v top="${TOP:-25}" '
    {
        t = $2; gsub(/ /, "", t); v = t + 0
        if (t ~ /ns$/) v /= 1e6; else if (t ~ /µs$/) v /= 1e3; else if (t !~ /ms$/) v *= 1e3
        name = $3; gsub(/^ +| +$/, "", name); sub(/_[0-9a-f]+$/, "", name)
        total[name] += v; count[name]++; all += v
    }
    END {
        printf "%12s %8s %7s  %s\n", "ms", "share", "calls", "kernel"
        for (k in total) printf "%12.1f %7.1f%% %7d  %s\n", total[k], 100 * total[k] / all, count[k], k | "sort -rn | head -" top
        close("sort -rn | head -" top)
        printf "%12.1f %7s %7s  all kernels\n", all, "", ""
    }'

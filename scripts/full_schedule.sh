#!/usr/bin/env bash
# The method's own schedule on one scene, on a GPU: 15,000 iterations of stage 1 (the anchor
# base with its rate term, the default), then 15,000 steps of stage 2 with the wrapper; the
# decoded stream scored on the test views (PSNR, SSIM, LPIPS, DISTS) with the stream's size and
# the timings in DIR/report.json.
#
#   scripts/full_schedule.sh SCENE DIR [pwenc options...]
#   scripts/full_schedule.sh ../shared/scenes/fern runs/fern --downscale 4   # 1008x756
#
# PWENC names the binary (default: a dev build with the gpu feature in $CARGO_TARGET_DIR or
# target/; build it with `cargo build -p pwgs-pwenc --features gpu --bin pwenc`). Extra options
# go to pwenc (for example --lambda, or --iters 2000 for a shorter stage 1 when time is short:
# --wrapper-min-steps sets stage 2's length).
set -euo pipefail
[ $# -ge 2 ] || { sed -n 2,12p "$0" >&2; exit 2; }
scene=$1
dir=$2
shift 2
pwenc=${PWENC:-${CARGO_TARGET_DIR:-target}/debug/pwenc}
mkdir -p "$dir"
# One crop per training view and at least 15,000 steps: stage 2 runs 15,000 steps on any scene
# with fewer than 15,000 training views.
"$pwenc" "$scene" --device gpu --iters 15000 --wrapper-crops-per-view 1 --wrapper-min-steps 15000 \
    --eval "$dir/eval" --eval-metrics lpips,dists -o "$dir/scene.pwb" --report "$dir/report.json" "$@" \
    2>&1 | tee "$dir/log.txt"

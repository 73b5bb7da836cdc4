#!/usr/bin/env bash
# The stage-2 rows of docs/results/wrapper.md, one change at a time from the defaults, on a shared stage-1 model.
#
#   scripts/stage2_ablation.sh stage1 fern|fox DIR      # once per scene: DIR/SCENE_s1.ply
#   scripts/stage2_ablation.sh row NAME fern|fox DIR [pwenc options...]
#                                                       # DIR/NAME.{pwb,json,log}, DIR/NAME_eval
#
# Stage 1 is the first 1,000 iterations of a default wrapper run, exactly: densification and
# SH bands as there, and the position rate decaying over those iterations as it does in the
# whole run (fern: 1,000 + 1,000 stage-2 steps, so 1.6e-4 -> 1.6e-5; fox: 1,000 + 1,856, so
# 1.6e-4 -> 3.19036e-5); a row continues the schedule to 1.6e-6 over stage 2 alone
# (`--init-ply ... --iters 0`). Rows compare with the row of the defaults (no options), made
# the same way. Run from the repository root with ../shared beside it; PWENC names the binary
# (default: the release build in $CARGO_TARGET_DIR or target/).
set -euo pipefail
mode=$1
shift
pwenc=${PWENC:-${CARGO_TARGET_DIR:-target}/release/pwenc}
weights=(--eval-metrics lpips,dists,wd --eval-wd-log2-sigma 3 --weights ../shared/weights)
scene_args() {
    case $1 in
        fern) echo "../shared/scenes/fern --base 3dgs --downscale 8 --max-gaussians 33500" ;;
        fox) echo "../shared/scenes/fox --base 3dgs --downscale 2 --max-gaussians 40000" ;;
        *) echo "unknown scene $1 (fern or fox)" >&2; exit 2 ;;
    esac
}
split_rate() { case $1 in fern) echo 1.6e-5 ;; fox) echo 3.19036e-5 ;; esac; }
target() { case $1 in fern) echo 303002 ;; fox) echo 300000 ;; esac; }
case $mode in
    stage1)
        scene=$1 dir=$2
        mkdir -p "$dir"
        # shellcheck disable=SC2046
        "$pwenc" $(scene_args "$scene") --no-wrapper --iters 1000 --position-lr "1.6e-4,$(split_rate "$scene")" \
            --export-ply "$dir/${scene}_s1.ply" -o "$dir/${scene}_s1.pwb" > "$dir/${scene}_s1.log" 2>&1
        ;;
    row)
        name=$1 scene=$2 dir=$3
        shift 3
        start=$(date +%s)
        # shellcheck disable=SC2046
        "$pwenc" $(scene_args "$scene") --init-ply "$dir/${scene}_s1.ply" --iters 0 \
            --position-lr "$(split_rate "$scene"),1.6e-6" --target-bytes "$(target "$scene")" "$@" \
            -o "$dir/$name.pwb" --eval "$dir/${name}_eval" --report "$dir/$name.json" "${weights[@]}" \
            > "$dir/$name.log" 2>&1
        echo "wall $(( $(date +%s) - start )) s" >> "$dir/$name.log"
        ;;
    *) echo "usage: $0 stage1 SCENE DIR | row NAME SCENE DIR [options]" >&2; exit 2 ;;
esac

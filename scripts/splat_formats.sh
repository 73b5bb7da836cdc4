#!/usr/bin/env bash
# The comparison with the formats splat viewers ship (a benchmark, not a test): writes
# SPZ, SOG and compressed PLY of one 3DGS PLY with PlayCanvas's splat-transform (installed
# from npm into DIR/npm), converts each back to PLY with it, compresses the input with pwenc at
# several qualities, and scores every one of them with `pwenc compare` against the input's own
# renders on an orbit (the same cameras for all). Then `pwbench` writes DIR/report/report.md:
# each format's size and scores, our curve, and each format against our curve at equal score.
#
#   scripts/splat_formats.sh INPUT.ply DIR [QUALITY ...]     (default qualities: 2 4 6 8 10)
#
# Environment: PWENC and PWBENCH name the binaries (default: the release builds in
# $CARGO_TARGET_DIR or target/); ORBIT views (8), SIZE pixels (512), UP (0,-1,0), METRICS for
# `pwenc compare --metrics` (dists; empty for PSNR and SSIM only), WEIGHTS a weights folder,
# PWENC_OPTIONS more options for our streams (e.g. "--importance-classes --prune-faint
# --search-steps --refit-colours", the README's figures).
# SOG is written on the CPU (`-g cpu`), as no GPU is assumed.
set -euo pipefail
[ $# -ge 2 ] || { sed -n '2,16p' "$0" >&2; exit 2; }
input=$1
dir=$2
shift 2
if [ $# -ge 1 ]; then qualities=("$@"); else qualities=(2 4 6 8 10); fi
[ -f "$input" ] || { echo "no such file: $input" >&2; exit 2; }
target=${CARGO_TARGET_DIR:-target}/release
pwenc=${PWENC:-$target/pwenc}
pwbench=${PWBENCH:-$target/pwbench}
metrics=${METRICS-dists}
compare_options=(--orbit "${ORBIT:-8}" --orbit-size "${SIZE:-512}" --up "${UP:-0,-1,0}")
[ -n "$metrics" ] && compare_options+=(--metrics "$metrics")
[ -n "${WEIGHTS:-}" ] && compare_options+=(--weights "$WEIGHTS")
mkdir -p "$dir"/{formats,ours,reports,renders}
name=$(basename "${input%.*}")

transform=$dir/npm/node_modules/.bin/splat-transform
if [ ! -x "$transform" ]; then
    npm install --prefix "$dir/npm" --no-audit --no-fund @playcanvas/splat-transform@3.7.0 >"$dir/npm.log" 2>&1 ||
        npm install --prefix "$dir/npm" --no-audit --no-fund @playcanvas/splat-transform@3.7.0 >"$dir/npm.log" 2>&1 ||
        { echo "npm could not install @playcanvas/splat-transform (see $dir/npm.log)" >&2; exit 1; }
fi
"$transform" --version

# Each format, and its conversion back to PLY (what `pwenc compare` renders).
declare -A written
for format in spz sog compressed.ply; do
    file=$dir/formats/$name.$format
    options=(-q -w)
    [ "$format" = sog ] && options+=(-g cpu)
    "$transform" "${options[@]}" "$input" "$file"
    "$transform" -q -w "$file" "$file.ply"
    written[$format]=$file
done

# Our readers against splat-transform's: its conversion back to PLY is the reference, our
# reading of its file the candidate (identical renders give PSNR inf). Its SPZ files store
# the PLY's axes unmarked, hence --spz-axes rdf (ignored for the other formats).
for format in spz sog compressed.ply; do
    label=reader-${format//./-}
    "$pwenc" compare "${written[$format]}.ply" "${written[$format]}" --spz-axes rdf --orbit 4 --orbit-size 256 \
        --up "${UP:-0,-1,0}" -o "$dir/renders/$label" >"$dir/reports/$label.log"
    echo "our $format reader against splat-transform's: $(grep -m1 'mean over' "$dir/reports/$label.log")"
done

compare() { # NAME CANDIDATE [SIZE_OF]
    local size_of=()
    [ $# -ge 3 ] && size_of=(--size-of "$3")
    "$pwenc" compare "$input" "$2" -o "$dir/renders/$1" --report "$dir/reports/$1.json" \
        "${compare_options[@]}" "${size_of[@]}" >"$dir/reports/$1.log"
    echo "$1: $(grep -m1 'mean over' "$dir/reports/$1.log")"
}
curves=()
for format in spz sog compressed.ply; do
    label=${format//./-}
    compare "$label" "${written[$format]}.ply" "${written[$format]}"
    curves+=("$label=$dir/reports/$label.json")
done
ours=()
for q in "${qualities[@]}"; do
    # shellcheck disable=SC2086 # PWENC_OPTIONS is a list of options
    "$pwenc" --from "$input" --quality "$q" ${PWENC_OPTIONS:-} -o "$dir/ours/q$q.pwb" >"$dir/ours/q$q.log"
    compare "pwgs-q$q" "$dir/ours/q$q.pwb"
    ours+=("$dir/reports/pwgs-q$q.json")
done
"$pwbench" "pwgs=$(IFS=,; echo "${ours[*]}")" "${curves[@]}" -o "$dir/report" \
    --title "$name: pwgs against SPZ, SOG and compressed PLY (orbit renders against the input's)"

#!/usr/bin/env bash
# The comparison with the formats splat viewers ship (a benchmark, not a test): writes
# SPZ, SOG and compressed PLY of one 3DGS PLY with PlayCanvas's splat-transform (installed
# from npm into DIR/npm), converts each back to PLY with it, compresses the input with pwenc at
# several qualities (timing the encode and the decode), and scores every one of them with
# `pwenc compare` against the input's own renders on three sets of views (the same cameras for
# all): the orbit, an orbit from below and one closer in. Then `pwbench` writes
# DIR/report-SET/report.md for each set: each format's size and scores, our curve, and each
# format against our curve at equal score.
#
#   scripts/splat_formats.sh INPUT.ply DIR [QUALITY ...]     (default qualities: 2 4 6 8 10)
#
# Environment: PWENC, PWDEC and PWBENCH name the binaries (default: the release builds in
# $CARGO_TARGET_DIR or target/); ORBIT views (8), SIZE pixels (512), UP (0,-1,0), METRICS for
# `pwenc compare --metrics` (dists; empty for PSNR and SSIM only), WEIGHTS a weights folder,
# PWENC_OPTIONS more options for our streams (e.g. "--effort 7"; without it, the default
# effort), FORMATS the formats to write (default "spz sog compressed.ply": SOG of a model with SH
# bands takes splat-transform hours on 2 cores, so "spz compressed.ply" leaves it out),
# SOG_ITERATIONS the SOG writer's k-means iterations on the SH bands (`-i`; default its own, 10).
# SOG is written on the CPU (`-g cpu`), as no GPU is assumed.
set -euo pipefail
[ $# -ge 2 ] || { sed -n '2,20p' "$0" >&2; exit 2; }
input=$1
dir=$2
shift 2
if [ $# -ge 1 ]; then qualities=("$@"); else qualities=(2 4 6 8 10); fi
[ -f "$input" ] || { echo "no such file: $input" >&2; exit 2; }
target=${CARGO_TARGET_DIR:-target}/release
pwenc=${PWENC:-$target/pwenc}
pwbench=${PWBENCH:-$target/pwbench}
pwdec=${PWDEC:-$target/pwdec}
metrics=${METRICS-dists}
compare_options=(--orbit "${ORBIT:-8}" --orbit-size "${SIZE:-512}" --up "${UP:-0,-1,0}")
[ -n "$metrics" ] && compare_options+=(--metrics "$metrics")
[ -n "${WEIGHTS:-}" ] && compare_options+=(--weights "$WEIGHTS")
mkdir -p "$dir"/{formats,ours,reports,renders}
rm -f "$dir/ours/times.txt" "$dir/formats/times.txt"
name=$(basename "${input%.*}")

transform=$dir/npm/node_modules/.bin/splat-transform
if [ ! -x "$transform" ]; then
    npm install --prefix "$dir/npm" --no-audit --no-fund @playcanvas/splat-transform@3.7.0 >"$dir/npm.log" 2>&1 ||
        npm install --prefix "$dir/npm" --no-audit --no-fund @playcanvas/splat-transform@3.7.0 >"$dir/npm.log" 2>&1 ||
        { echo "npm could not install @playcanvas/splat-transform (see $dir/npm.log)" >&2; exit 1; }
fi
"$transform" --version

# Each format, and its conversion back to PLY (what `pwenc compare` renders).
read -r -a formats <<<"${FORMATS:-spz sog compressed.ply}"
# Each file's encode and decode time (splat-transform's writing and its reading back to PLY for
# the formats), which the reports carry.
declare -A written encode_seconds decode_seconds
for format in "${formats[@]}"; do
    file=$dir/formats/$name.$format
    options=(-q -w)
    [ "$format" = sog ] && options+=(-g cpu ${SOG_ITERATIONS:+-i "$SOG_ITERATIONS"})
    start=$(date +%s.%N)
    "$transform" "${options[@]}" "$input" "$file"
    middle=$(date +%s.%N)
    "$transform" -q -w "$file" "$file.ply"
    end=$(date +%s.%N)
    encode_seconds[$format]=$(echo "$middle - $start" | bc)
    decode_seconds[$format]=$(echo "$end - $middle" | bc)
    echo "$format: $(stat -c %s "$file") bytes, splat-transform writes it in ${encode_seconds[$format]} s, reads it back to PLY in ${decode_seconds[$format]} s" |
        tee -a "$dir/formats/times.txt"
    written[$format]=$file
done

# Our readers against splat-transform's: its conversion back to PLY is the reference, our
# reading of its file the candidate (identical renders give PSNR inf). Its SPZ files store
# the PLY's axes unmarked, hence --spz-axes rdf (ignored for the other formats).
for format in "${formats[@]}"; do
    label=reader-${format//./-}
    "$pwenc" compare "${written[$format]}.ply" "${written[$format]}" --spz-axes rdf --orbit 4 --orbit-size 256 \
        --up "${UP:-0,-1,0}" -o "$dir/renders/$label" >"$dir/reports/$label.log"
    echo "our $format reader against splat-transform's: $(grep -m1 'mean over' "$dir/reports/$label.log")"
done

# Our streams, timed (encode, and decode with `pwdec --hash`, which rebuilds every Gaussian).
for q in "${qualities[@]}"; do
    start=$(date +%s.%N)
    # shellcheck disable=SC2086 # PWENC_OPTIONS is a list of options
    "$pwenc" --from "$input" --quality "$q" ${PWENC_OPTIONS:-} -o "$dir/ours/q$q.pwb" >"$dir/ours/q$q.log"
    middle=$(date +%s.%N)
    "$pwdec" "$dir/ours/q$q.pwb" --hash >/dev/null
    end=$(date +%s.%N)
    encode_seconds[q$q]=$(echo "$middle - $start" | bc)
    decode_seconds[q$q]=$(echo "$end - $middle" | bc)
    echo "q$q: $(stat -c %s "$dir/ours/q$q.pwb") bytes, encode ${encode_seconds[q$q]} s, decode ${decode_seconds[q$q]} s" |
        tee -a "$dir/ours/times.txt"
done

# Every file scored on the orbit, and on two sets of views unlike the importance views the
# encoder measures on: an orbit from below, and one closer in with narrower views.
view_sets=("orbit:" "below:--orbit-elevation -35" "close:--orbit-distance 0.5 --orbit-fov 40")
for set in "${view_sets[@]}"; do
    label=${set%%:*}
    read -r -a set_options <<<"${set#*:}"
    reports=$dir/reports/$label
    mkdir -p "$reports"
    compare() { # NAME CANDIDATE TIMES_KEY [SIZE_OF]
        local more=(--encode-seconds "${encode_seconds[$3]}" --decode-seconds "${decode_seconds[$3]}")
        [ $# -ge 4 ] && more+=(--size-of "$4")
        "$pwenc" compare "$input" "$2" -o "$dir/renders/$label/$1" --report "$reports/$1.json" \
            "${compare_options[@]}" "${set_options[@]}" "${more[@]}" >"$reports/$1.log"
        echo "$label, $1: $(grep -m1 'mean over' "$reports/$1.log")"
    }
    curves=()
    for format in "${formats[@]}"; do
        compare "${format//./-}" "${written[$format]}.ply" "$format" "${written[$format]}"
        curves+=("${format//./-}=$reports/${format//./-}.json")
    done
    ours=()
    for q in "${qualities[@]}"; do
        compare "pwgs-q$q" "$dir/ours/q$q.pwb" "q$q"
        ours+=("$reports/pwgs-q$q.json")
    done
    "$pwbench" "pwgs=$(IFS=,; echo "${ours[*]}")" "${curves[@]}" -o "$dir/report-$label" \
        --title "$name: pwgs against SPZ, SOG and compressed PLY ($label views: renders against the input's)"
done

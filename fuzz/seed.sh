#!/usr/bin/env bash
# Fills fuzz/corpus/<target>/ with seed inputs, from the conformance vectors and from small
# files the project's own tools write. The corpus is rebuilt from scratch (it is not
# committed), so the same checkout always gives the same seeds.
#
# Needs python3 and the workspace's pwenc and pwdec, which it builds (dev profile) unless
# PWENC and PWDEC name existing binaries. BUILD_LOCK, when set, names a file that every cargo
# command is run under (flock), for machines where builds must not overlap.
set -euo pipefail

fuzz_dir=$(cd "$(dirname "$0")" && pwd)
repo=$(dirname "$fuzz_dir")
corpus="$fuzz_dir/corpus"
vectors="$repo/conformance/vectors"
invalid="$repo/conformance/invalid"

run_cargo() {
    if [[ -n "${BUILD_LOCK:-}" ]]; then flock "$BUILD_LOCK" cargo "$@"; else cargo "$@"; fi
}

if [[ -z "${PWENC:-}" || -z "${PWDEC:-}" ]]; then
    (cd "$repo" && run_cargo build -q -p pwgs-pwenc --bin pwenc -p pwgs-pwdec --bin pwdec)
    bin="${CARGO_TARGET_DIR:-$repo/target}/debug"
    PWENC="$bin/pwenc"
    PWDEC="$bin/pwdec"
fi

rm -rf "$corpus"
mkdir -p "$corpus"/{container,entropy,octree,decode,camera_json,ply,colmap_bin,transforms,splat_file,sog}
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT

# Streams: every conformance vector and every invalid stream (named after its folder or file).
for stream in "$vectors"/*/stream.pwb; do
    name=$(basename "$(dirname "$stream")")
    cp "$stream" "$corpus/container/$name"
    cp "$stream" "$corpus/decode/$name"
done
for stream in "$invalid"/*.pwb; do
    cp "$stream" "$corpus/container/invalid-$(basename "$stream" .pwb)"
    cp "$stream" "$corpus/decode/invalid-$(basename "$stream" .pwb)"
done

# Camera files: the vectors' views and the invalid camera files.
for camera in "$vectors"/*/view_*.json; do
    cp "$camera" "$corpus/camera_json/$(basename "$(dirname "$camera")")-$(basename "$camera")"
done
cp "$invalid"/camera-*.json "$corpus/camera_json/"

# PLY: a few decoded vectors exported by pwdec (SH degrees 0 to 3), the generated scene's
# point cloud, and a small ASCII file with a face element.
for name in single-sh0 sh1 sh2 sh3 empty; do
    "$PWDEC" "$vectors/$name/stream.pwb" --export-ply "$corpus/ply/$name.ply" > /dev/null 2>&1
done
"$PWENC" generate-scene "$scratch/scene" --width 8 --height 6 --views 3 > /dev/null
cp "$scratch/scene/points3d.ply" "$corpus/ply/generated-points.ply"
printf 'ply\nformat ascii 1.0\ncomment seed\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 1 2 255 0 0\n-1 0.5 3e2 0 128 255\n3 0 1 1\n' \
    > "$corpus/ply/ascii-points.ply"

# transforms.json: the generated scene's (3 views of 8x6, the names the harness provides),
# and Blender- and OpenCV-distortion variants of it.
cp "$scratch/scene/transforms.json" "$corpus/transforms/generated.json"

# The rest is carved or written byte by byte.
python3 - "$corpus" "$vectors" "$scratch/scene/transforms.json" <<'PY'
import glob, json, os, struct, sys

corpus, vectors, transforms = sys.argv[1:4]

def write(target, name, data):
    with open(os.path.join(corpus, target, name), "wb") as f:
        f.write(data)

def varint(v):
    out = bytearray()
    while True:
        byte, v = v & 0x7F, v >> 7
        if v == 0:
            out.append(byte)
            return bytes(out)
        out.append(byte | 0x80)

def sections(stream):
    """Section payloads by tag (the container was verified by the conformance suite)."""
    at, found = 12, {}
    while at + 8 <= len(stream):
        tag, length = stream[at:at + 4], struct.unpack_from("<I", stream, at + 4)[0]
        found[tag] = stream[at + 8:at + 8 + length]
        at += 12 + length
    return found

# entropy: each attribute block minus its steps; octree: each POSN minus origin and cell.
for path in sorted(glob.glob(os.path.join(vectors, "*", "stream.pwb"))):
    name = os.path.basename(os.path.dirname(path))
    found = sections(open(path, "rb").read())
    count, degree = struct.unpack_from("<IB", found[b"HEAD"], 1)
    rest = ((degree + 1) ** 2 - 1) * 3
    for tag, steps, channels in [(b"SCAL", 1, 3), (b"ROTN", 1, 4), (b"OPAC", 1, 1), (b"COLR", 1, 3), (b"SHRS", degree, rest)]:
        if tag in found and 1 <= channels <= 4:
            seed = bytes([channels - 1, 0]) + varint(count * channels) + found[tag][4 * steps:]
            write("entropy", f"{name}-{tag.decode().strip()}", seed)
    # Anchor streams (base 1) hold APOS and Gaussian-model blocks: the decode target covers them.
    if b"POSN" in found and count <= 4096:
        posn = found[b"POSN"]
        write("octree", name, bytes([posn[16]]) + struct.pack("<H", count) + posn[17:])

# transforms variants
scene = json.load(open(transforms))
blender = {"camera_angle_x": 1.0, "frames": [{"file_path": "images/view_00%d" % i, "transform_matrix": f["transform_matrix"]} for i, f in enumerate(scene["frames"])]}
write("transforms", "blender.json", json.dumps(blender).encode())
opencv = dict(scene, camera_model="OPENCV", k1=0.01, k2=-0.002, p1=0.001, p2=0.0)
del opencv["ply_file_path"]
opencv["frames"] = [dict(f, fl_x=7.0, w=8, h=6) for f in scene["frames"]]
write("transforms", "opencv.json", json.dumps(opencv).encode())

# colmap_bin: u32 length + cameras.bin, u32 length + images.bin, then points3D.bin.
def colmap(cameras, images, points):
    cams = struct.pack("<Q", len(cameras))
    for cam_id, model, w, h, params in cameras:
        cams += struct.pack("<IiQQ", cam_id, model, w, h) + struct.pack(f"<{len(params)}d", *params)
    imgs = struct.pack("<Q", len(images))
    for img_id, qvec, tvec, cam_id, name, points2d in images:
        imgs += struct.pack("<I7dI", img_id, *qvec, *tvec, cam_id) + name + b"\0"
        imgs += struct.pack("<Q", len(points2d)) + b"".join(struct.pack("<2dq", x, y, p) for x, y, p in points2d)
    pts = struct.pack("<Q", len(points))
    for pt_id, xyz, rgb, error, track in points:
        pts += struct.pack("<Q3d3Bd", pt_id, *xyz, *rgb, error) + struct.pack("<Q", len(track))
        pts += b"".join(struct.pack("<II", image, idx) for image, idx in track)
    return struct.pack("<I", len(cams)) + cams + struct.pack("<I", len(imgs)) + imgs + pts

write("colmap_bin", "empty", colmap([], [], []))
cameras = [
    (1, 1, 8, 6, [7.0, 7.5, 4.0, 3.0]),                            # PINHOLE
    (2, 2, 16, 12, [14.0, 8.0, 6.0, 0.01]),                        # SIMPLE_RADIAL
    (3, 4, 8, 6, [7.0, 7.0, 4.0, 3.0, 0.01, -0.002, 0.001, 0.0]),  # OPENCV
    (4, 5, 8, 6, [7.0, 7.0, 4.0, 3.0, 0.01, 0.0, 0.0, 0.0]),       # OPENCV_FISHEYE
]
images = [
    (1, [1, 0, 0, 0], [0, 0, 3], 1, b"view_000.png", [(1.5, 2.5, 1), (3.0, 4.0, -1)]),
    (2, [0.9, 0.1, 0.3, 0.2], [0.5, -1, 4], 3, b"view_001.png", [(0.5, 0.5, 2)]),
]
points = [
    (1, [0.1, 0.2, 0.3], [255, 0, 128], 0.5, [(1, 0)]),
    (2, [-1.0, 2.0, 5.0], [10, 20, 30], 1.25, [(1, 1), (2, 0)]),
    (7, [0.0, 0.0, 0.0], [0, 0, 0], 0.0, []),
]
write("colmap_bin", "model", colmap(cameras, images, points))
write("colmap_bin", "cameras-only", colmap(cameras, [], []))

# splat_file: a selector byte (even: .splat, odd: .spz), then the file. Two .splat records;
# SPZ versions 2 and 3 with two points of degree 0 and of degree 1 (attributes stored one
# after the other: positions as 24-bit fixed point, alphas, colors, scales, rotations, SH).
import gzip
records = struct.pack("<3f3f4B4B", 0.1, -0.2, 1.5, 0.01, 0.02, 0.03, 200, 100, 50, 180, 200, 128, 128, 128)
records += struct.pack("<3f3f4B4B", -1.0, 0.5, 2.0, 0.1, 0.1, 0.1, 10, 250, 30, 90, 128, 200, 60, 128)
write("splat_file", "two-records", b"\x00" + records)
def spz(version, degree):
    n, rotation = 2, 3 if version == 2 else 4
    coeffs = ((degree + 1) ** 2 - 1) * 3
    header = struct.pack("<IIIBBBB", 0x5053474E, version, n, degree, 12, 0, 0)
    body = bytes(range(9 * n)) + bytes([200, 40]) + bytes([128, 64, 200] * n) + bytes([100, 120, 140] * n)
    body += bytes([128, 140, 100, 90][:rotation] * n) + bytes([128 + i % 7 for i in range(coeffs * n)])
    return b"\x01" + gzip.compress(header + body, mtime=0)
for version in (2, 3):
    for degree in (0, 1):
        write("splat_file", f"spz-v{version}-sh{degree}", spz(version, degree))
PY

# The hostile splat files (conformance/hostile/, made by the conformance generator): .splat and
# .spz files as splat_file inputs behind their selector byte (0: .splat, 1: .spz), SOG archives
# as they are. Among them are decompression bombs (SPZ headers claiming 53 million points, SOG
# images declaring 16383 x 16383 pixels, zip entries overlapping one deflated payload) and a
# valid SOG laid out as PlayCanvas's writer lays it out.
hostile="$repo/conformance/hostile"
for file in "$hostile"/*.splat "$hostile"/*.spz; do
    [[ -e $file ]] || continue
    case "$file" in *.splat) selector='\000' ;; *) selector='\001' ;; esac
    { printf "$selector"; cat "$file"; } > "$corpus/splat_file/hostile-$(basename "$file")"
done
for file in "$hostile"/*.sog; do
    [[ -e $file ]] || continue
    cp "$file" "$corpus/sog/hostile-$(basename "$file")"
done
# And the hostile streams (at the per-byte limits of SPEC.md sections 9 and 12) for decode.
for file in "$hostile"/*.pwb; do
    cp "$file" "$corpus/decode/hostile-$(basename "$file" .pwb)"
done

echo "seeded $corpus:"
for dir in "$corpus"/*/; do
    printf '  %-12s %3d files\n' "$(basename "$dir")" "$(ls "$dir" | wc -l)"
done

#!/usr/bin/env python3
"""How much of a splat model's rotation precision its shapes can use (issue 16).

Usage: splat_anisotropy.py MODEL.ply   (INRIA layout, binary little-endian)

Turning a Gaussian by a small angle d about its principal axis k changes its covariance by
d (s_i^2 - s_j^2) in the plane of the other two axes i, j. Against the Gaussian's size s_max^2,
the angle about the largest axis (a needle's roll) matters in proportion to
(s_mid^2 - s_min^2) / s_max^2, about the smallest axis (a disk's spin) in proportion to
(s_max^2 - s_mid^2) / s_max^2. The script prints the quantiles of each ratio and the mean of
-log2 of it (capped at 8 bits): the bits a coder could save on that angle if its step grew in
inverse proportion. Standard library only.
"""
import math
import struct
import sys


def read_ply(path):
    with open(path, "rb") as f:
        header = []
        while True:
            line = f.readline()
            if not line:
                sys.exit(f"{path}: no end_header")
            header.append(line.decode("ascii", "replace").strip())
            if header[-1] == "end_header":
                break
        if "format binary_little_endian 1.0" not in header:
            sys.exit(f"{path}: only binary little-endian PLY is read")
        count = next(int(h.split()[-1]) for h in header if h.startswith("element vertex"))
        props = [h.split()[-1] for h in header if h.startswith("property")]
        if any(h.startswith("property") and h.split()[1] != "float" for h in header):
            sys.exit(f"{path}: only float properties are read (INRIA layout)")
        data = f.read(4 * len(props) * count)
    if len(data) != 4 * len(props) * count:
        sys.exit(f"{path}: truncated")
    return props, count, struct.iter_unpack(f"<{len(props)}f", data)


def quantiles(values, qs=(0.1, 0.25, 0.5, 0.75, 0.9)):
    s = sorted(values)
    return " ".join(f"{s[min(len(s) - 1, int(q * len(s)))]:.3g}" for q in qs)


def main():
    props, count, rows = read_ply(sys.argv[1])
    at = [props.index(f"scale_{k}") for k in range(3)]
    roll, spin = [], []
    for row in rows:
        s_min, s_mid, s_max = sorted(math.exp(row[i]) for i in at)
        if not s_max > 0 or math.isinf(s_max):
            continue
        roll.append((s_mid**2 - s_min**2) / s_max**2)
        spin.append((s_max**2 - s_mid**2) / s_max**2)
    print(f"{sys.argv[1]}: {count} Gaussians")
    print("ratio quantiles at 10 / 25 / 50 / 75 / 90%, and the mean bits an angle step growing as 1/ratio saves")
    for name, ratio in (("roll about the largest axis", roll), ("spin about the smallest axis", spin)):
        bits = sum(min(8.0, -math.log2(max(r, 2**-8))) for r in ratio) / len(ratio)
        print(f"  {name}: {quantiles(ratio)}; {bits:.2f} bits")


if __name__ == "__main__":
    main()

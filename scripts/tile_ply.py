#!/usr/bin/env python3
"""Writes a large 3DGS model made of copies of a smaller one, side by side on a grid: a test
model for imports of a million Gaussians and more (memory, time, progress) whose attributes are
those of a real model.

    scripts/tile_ply.py INPUT.ply OUTPUT.ply COPIES

INPUT is a binary little-endian PLY whose vertex properties are all float (an INRIA 3DGS PLY).
The copies sit on a cube of k x k x k cells (k the smallest with k^3 >= COPIES), filled x first,
each cell 1.1 times the input's bounding box, so that no two copies overlap.
"""
import array
import sys


def read_header(f):
    lines = []
    while True:
        line = f.readline()
        if not line:
            sys.exit("no end_header: not a PLY file")
        lines.append(line.decode("ascii", "replace").rstrip("\n"))
        if lines[-1].strip() == "end_header":
            return lines


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    source, target, copies = sys.argv[1], sys.argv[2], int(sys.argv[3])
    if copies < 1:
        sys.exit("COPIES must be at least 1")
    with open(source, "rb") as f:
        header = read_header(f)
        if "format binary_little_endian 1.0" not in header:
            sys.exit("only binary little-endian PLY files")
        count, names, element = 0, [], None
        for line in header:
            words = line.split()
            if words[:1] == ["element"]:
                element = words[1]
                if element == "vertex":
                    count = int(words[2])
                elif int(words[2]) > 0:
                    sys.exit(f"element {element}: only vertices are copied")
            elif words[:1] == ["property"] and element == "vertex":
                if words[1] != "float":
                    sys.exit(f"property {words[-1]} is {words[1]}: only float properties")
                names.append(words[2])
        stride = len(names)
        values = array.array("f")
        values.frombytes(f.read(count * stride * 4))
    if sys.byteorder != "little":
        values.byteswap()
    axes = [names.index(a) for a in "xyz"]
    lows = [min(values[a::stride]) for a in axes]
    sizes = [1.1 * (max(values[a::stride]) - lo) for a, lo in zip(axes, lows)]
    k = 1
    while k**3 < copies:
        k += 1
    out_header = [
        f"element vertex {count * copies}" if line.startswith("element vertex") else line for line in header
    ]
    with open(target, "wb") as out:
        out.write(("\n".join(out_header) + "\n").encode("ascii"))
        for c in range(copies):
            cell = (c % k, c // k % k, c // (k * k))
            moved = array.array("f", values)
            for a, offset in zip(axes, (cell[i] * sizes[i] for i in range(3))):
                moved[a::stride] = array.array("f", (v + offset for v in values[a::stride]))
            if sys.byteorder != "little":
                moved.byteswap()
            out.write(moved.tobytes())
    print(f"{target}: {count * copies} Gaussians ({copies} copies of {count})")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""A centre-weighted log2-sigma map for `pwenc --wd-log2-sigma-map` (issue 19's sigma-map row).

Usage: radial_sigma_map.py WIDTH HEIGHT OUT.png

The simplest saliency prior, centre bias: log2 sigma = 3 + 2 (r / r_max)^2, i.e. WD pools over
8 pixels at the centre and 32 in the corners (3.67 on average, against the constant default 4).
The grayscale PNG stores gray = 255 * log2sigma / 5, as pwenc reads it. Standard library only.
"""
import struct
import sys
import zlib


def main():
    width, height, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
    rows = bytearray()
    for y in range(height):
        rows.append(0)  # PNG filter type 0 for the row
        for x in range(width):
            dx, dy = (x + 0.5) / width - 0.5, (y + 0.5) / height - 0.5
            r2 = (dx * dx + dy * dy) / 0.5
            rows.append(round(255 * (3 + 2 * r2) / 5))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(bytes(rows))) + chunk(b"IEND", b"")
    with open(out, "wb") as f:
        f.write(png)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Prints a markdown table of pwenc reports (--report, with --eval and --eval-metrics): one row
per report, with the stream's size, the training time and the test views' mean scores.

Usage: scripts/report_table.py [LABEL=]report.json ...
A path without LABEL= is labelled with its file stem.
"""
import json
import sys
from pathlib import Path


def row(label, path):
    r = json.loads(Path(path).read_text())
    mean = r.get("mean") or {}
    stream = r.get("stream") or {}
    # A plain-base report nests its training figures; an anchor-base report (`--base anchor`)
    # has them at the top level.
    training = r.get("training") or {"iterations": r["iterations"], "seconds": r["training_seconds"]}
    cells = [
        label,
        f"{stream['bytes']:,}" if stream else "-",
        f"{training['iterations']:,}",
        f"{training['seconds']:.0f}",
    ]
    for key, fmt in [("dists", "{:.4f}"), ("lpips", "{:.4f}"), ("wd", "{:.3f}"), ("psnr", "{:.2f}"), ("ssim", "{:.4f}")]:
        cells.append(fmt.format(mean[key]) if key in mean else "-")
    return "| " + " | ".join(cells) + " |"


def main(args):
    if not args or args[0] in ("-h", "--help"):
        print(__doc__.strip())
        return 0 if args else 2
    print("| run | bytes | iterations | training s | DISTS | LPIPS | WD | PSNR | SSIM |")
    print("|---|---|---|---|---|---|---|---|---|")
    for arg in args:
        label, _, path = arg.partition("=") if "=" in arg else (Path(arg).stem, "", arg)
        print(row(label, path))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

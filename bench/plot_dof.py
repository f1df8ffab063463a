#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Plots bench/results/bench_dof.csv (bench_dof): for each scene, PSNR against the thin-lens
ray-traced reference versus the mean CoC (left) and versus ms/frame (right: accuracy against cost,
one point per method and CoC). Usage: plot_dof.py [CSV] [PNG]."""
import csv
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else "bench/results/bench_dof.csv"
    out = sys.argv[2] if len(sys.argv) > 2 else "bench/results/bench_dof.png"
    rows = [r for r in csv.DictReader(open(path)) if not r["method"].startswith("reference-")]
    scenes = sorted({r["scene"] for r in rows})
    fig, axes = plt.subplots(len(scenes), 2, figsize=(12, 4 * len(scenes)), squeeze=False)
    for i, scene in enumerate(scenes):
        by_method = defaultdict(list)
        for r in rows:
            if r["scene"] == scene:
                by_method[r["method"]].append((float(r["mean_coc_px"]), float(r["psnr_db"]), float(r["ms_per_frame"])))
        left, right = axes[i][0], axes[i][1]
        for method, pts in sorted(by_method.items()):
            pts.sort()
            left.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=method)
            right.scatter([p[2] for p in pts], [p[1] for p in pts], label=method)
        left.set_xscale("log", base=2)
        left.set_xlabel("mean CoC (px)")
        left.set_ylabel("PSNR vs ray-traced reference (dB)")
        left.set_title(scene)
        left.grid(True, alpha=0.3)
        right.set_xscale("log")
        right.set_xlabel("ms/frame (2 cores)")
        right.set_ylabel("PSNR (dB)")
        right.set_title(scene + ": accuracy against cost")
        right.grid(True, alpha=0.3)
        if i == 0:
            left.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    print("wrote", out)


if __name__ == "__main__":
    main()

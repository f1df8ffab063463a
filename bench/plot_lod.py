#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Plots bench/results/bench_lod.csv (bench_lod). Top row: ms/frame against visible objects per
condition (Lee 2009 Fig. 7.4/7.5), one panel per model and backend. Bottom row: at the largest count,
image error against time (PSNR inside the attended objects and in the periphery against ms/frame),
what each condition's accuracy costs. Usage: plot_lod.py [CSV] [PNG]."""
import csv
import math
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else "bench/results/bench_lod.csv"
    out = sys.argv[2] if len(sys.argv) > 2 else "bench/results/bench_lod.png"
    rows = [r for r in csv.DictReader(open(path)) if r["condition"] != "floor-only"]
    panels = sorted({(r["model"], r["backend"]) for r in rows})
    fig, axes = plt.subplots(2, len(panels), figsize=(5 * len(panels), 8.4), squeeze=False)
    for col, (model, backend) in enumerate(panels):
        ax = axes[0][col]
        mine = [r for r in rows if r["model"] == model and r["backend"] == backend]
        series = defaultdict(list)
        for r in mine:
            series[r["condition"]].append((int(r["objects"]), float(r["ms_per_frame"])))
        for cond, pts in sorted(series.items()):
            pts.sort()
            style = "-" if cond.startswith(("NOLOD", "ULOD")) else "--"
            ax.plot([p[0] for p in pts], [p[1] for p in pts], style, marker="o", label=cond)
        ax.set_yscale("log")
        ax.set_xlabel("visible objects")
        ax.set_ylabel("ms/frame (2 cores)")
        ax.set_title(f"{model}, {backend}")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
        ax = axes[1][col]
        most = max(int(r["objects"]) for r in mine)
        for r in mine:
            if int(r["objects"]) != most or r["condition"] == "NOLOD":
                continue
            ms = float(r["ms_per_frame"])
            # 99 dB marks an image identical to full detail (brown without frame stress): shown at 60.
            att, per = min(float(r["psnr_attended_db"]), 60.0), min(float(r["psnr_periphery_db"]), 60.0)
            if math.isnan(att) or math.isnan(per):
                continue
            ax.plot([ms, ms], [per, att], "-", color="0.7")
            ax.plot(ms, att, "o", color="C0")
            ax.plot(ms, per, "s", color="C1")
            ax.annotate(r["condition"], (ms, att), fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.plot([], [], "o", color="C0", label="attended objects")
        ax.plot([], [], "s", color="C1", label="periphery")
        ax.set_xscale("log")
        ax.set_xlabel(f"ms/frame at {most} objects")
        ax.set_ylabel("PSNR against full detail (dB)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    print("wrote", out)


if __name__ == "__main__":
    main()

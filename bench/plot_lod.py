#!/usr/bin/python3
"""Plots bench/results/bench_lod.csv (bench_lod): ms/frame against visible objects per condition (Lee
2009 Fig. 7.4/7.5), one panel per model and backend. Usage: plot_lod.py [CSV] [PNG]."""
import csv
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else "bench/results/bench_lod.csv"
    out = sys.argv[2] if len(sys.argv) > 2 else "bench/results/bench_lod.png"
    rows = list(csv.DictReader(open(path)))
    panels = sorted({(r["model"], r["backend"]) for r in rows})
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4.2), squeeze=False)
    for ax, (model, backend) in zip(axes[0], panels):
        series = defaultdict(list)
        for r in rows:
            if r["model"] == model and r["backend"] == backend:
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
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    print("wrote", out)


if __name__ == "__main__":
    main()

#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Plots bench_gi's CSVs (bench/results/gi/): relative RMSE in the gaze area against ms/frame per
strategy and estimate (left: accuracy against cost, one point per photon count), and photons in the
gaze area per scene and gaze-area size (right). Usage: plot_gi.py [CSV_DIR] [PNG]."""
import csv
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    folder = sys.argv[1] if len(sys.argv) > 1 else "bench/results/gi"
    out = sys.argv[2] if len(sys.argv) > 2 else os.path.join(folder, "bench_gi.png")
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 4.8))
    accuracy = os.path.join(folder, "gi_accuracy.csv")
    if os.path.exists(accuracy):
        series = defaultdict(list)
        for r in csv.DictReader(open(accuracy)):
            series[(r["strategy"], r["estimate"])].append(
                (float(r["ms_per_frame"]), float(r["relative_rmse"]), int(r["photons"])))
        for (strategy, estimate), pts in sorted(series.items()):
            pts.sort(key=lambda p: p[2])
            style = "-" if estimate == "nearest" else "--"
            left.plot([p[0] for p in pts], [p[1] for p in pts], style, marker="o", label=f"{strategy}, {estimate}")
            for ms, e, n in pts:
                left.annotate(f"{n // 1000}k", (ms, e), fontsize=6, alpha=0.6)
        left.set_xscale("log")
        left.set_yscale("log")
        left.set_xlabel("ms/frame (photons + index + estimate + render, 2 cores)")
        left.set_ylabel("relative RMSE in the 20 deg gaze area")
        left.set_title("640x480 cornell: accuracy against cost")
        left.grid(True, alpha=0.3)
        left.legend(fontsize=7)
    density = os.path.join(folder, "gi_density.csv")
    if os.path.exists(density):
        rows = list(csv.DictReader(open(density)))
        scenes = sorted({r["scene"] for r in rows})
        strategies = ["traditional", "gaze-directed", "importon"]
        labels, width = [], 0.27
        groups = sorted({(r["scene"], float(r["area_deg"])) for r in rows})
        for k, st in enumerate(strategies):
            values = []
            for scene, deg in groups:
                v = [int(r["area_photons"]) for r in rows if r["scene"] == scene and float(r["area_deg"]) == deg and r["strategy"] == st]
                values.append(v[0] if v else 0)
            right.bar([i + (k - 1) * width for i in range(len(groups))], values, width, label=st)
        labels = [f"{s}\n{d:.0f} deg" for s, d in groups]
        right.set_xticks(range(len(groups)))
        right.set_xticklabels(labels, fontsize=7)
        right.set_ylabel("indirect photons visible in the gaze area")
        right.set_yscale("log")
        right.set_title("photons in the gaze area (same number stored)")
        right.legend(fontsize=7)
        right.grid(True, axis="y", alpha=0.3)
        del scenes
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    print("wrote", out)


if __name__ == "__main__":
    main()

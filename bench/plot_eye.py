#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Plots bench_eye's CSV: pupil-centre accuracy against ms/frame per detector variant.

usage: bench/plot_eye.py bench_eye.csv out.png
Left: clean images (median error). Middle: the hard set (95th-percentile error). Right: the
low-contrast set (dark irises, weak light, lashes, off-axis views: share of frames answered within
2 px), where issue 44's options (no-inside, no-edges, no-contour) differ. One colour per variant,
one marker shape per resolution; detection rates are in the CSV and bench/RESULTS.md.
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main() -> int:
    if len(sys.argv) != 3:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    rows = list(csv.DictReader(open(sys.argv[1], newline="")))
    if not rows:
        print(f"{sys.argv[1]}: no rows", file=sys.stderr)
        return 1
    sizes = sorted({r["resolution"] for r in rows}, key=lambda s: int(s.split("x")[0]))
    markers = dict(zip(sizes, "o^sDv"))
    variants = list(dict.fromkeys(r["variant"] for r in rows))
    palette = plt.cm.tab10.colors + plt.cm.Dark2.colors  # more variants than tab10 has colours
    colours = {v: palette[i % len(palette)] for i, v in enumerate(variants)}
    panels = [("clean", "median_px", "pupil-centre error, median (px)", True),
              ("hard", "p95_px", "pupil-centre error, 95th percentile (px)", True),
              ("low-contrast", "within2_pct", "frames answered within 2 px (%)", False)]
    panels = [p for p in panels if any(r["set"] == p[0] and r.get(p[1]) for r in rows)]
    fig, axes = plt.subplots(1, len(panels), figsize=(6.5 * len(panels), 5.5), squeeze=False)
    axes = axes[0]
    for ax, (set_name, column, label, log_y) in zip(axes, panels):
        for r in rows:
            if r["set"] != set_name or not r.get(column):
                continue
            ax.scatter(float(r["ms_per_frame"]), float(r[column]), marker=markers[r["resolution"]],
                       color=colours[r["variant"]], s=45)
        ax.set_xscale("log")
        if log_y:
            ax.set_yscale("log")
        ax.set_xlabel("ms per frame (one core)")
        ax.set_ylabel(label)
        ax.set_title(f"{set_name} set")
        ax.grid(True, which="both", alpha=0.3)
    handles = [plt.Line2D([], [], color=colours[v], marker="o", linestyle="", label=v) for v in variants]
    handles += [plt.Line2D([], [], color="grey", marker=markers[s], linestyle="", label=s) for s in sizes]
    axes[-1].legend(handles=handles, fontsize=7, loc="best")
    fig.suptitle("fovea pupil detector: accuracy versus time (bench_eye)")
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())

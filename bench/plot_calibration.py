#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Plots bench/results/bench_calibration.csv (bench_calibration) as calibration error versus the
number of calibration points, one line per model; panels: input (pupil-glint vector / the tracker's
factory-calibrated screen gaze) x head offset (0 / the bench's offset). Solid: normal imaging,
dashed: hard. Each point is the mean over viewers of the mean validation error (deg).

/usr/bin/python3 because the pyenv python lacks matplotlib:
    /usr/bin/python3 bench/plot_calibration.py [CSV] [PNG]
"""
import csv
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

src = sys.argv[1] if len(sys.argv) > 1 else "bench/results/bench_calibration.csv"
dst = sys.argv[2] if len(sys.argv) > 2 else "bench/results/bench_calibration.png"

with open(src) as f:
    lines = [line for line in f if not line.startswith("#")]
rows = list(csv.DictReader(lines))
cells = defaultdict(list)  # (input, offset, imaging, model, points) -> mean errors
for r in rows:
    if r["status"] != "ok":
        continue
    cells[(r["input"], r["offset_mm"], r["imaging"], r["model"], int(r["points"]))].append(float(r["mean_err_deg"]))

inputs = ["pupil-glint", "screen"]
offsets = sorted({r["offset_mm"] for r in rows}, key=lambda o: (o != "0", o))
imagings = [i for i in ("normal", "hard") if any(r["imaging"] == i for r in rows)]
models = ["none", "affine", "homography", "poly2", "bilinear-grid", "poly2+bilinear-grid",
          "affine@fick", "homography@fick", "poly2@fick"]
colours = {"none": "0.5", "affine": "C0", "homography": "C1", "poly2": "C2", "bilinear-grid": "C3",
           "poly2+bilinear-grid": "C4", "affine@fick": "C0", "homography@fick": "C1", "poly2@fick": "C2"}
points = sorted({int(r["points"]) for r in rows})

fig, axes = plt.subplots(len(inputs), len(offsets), figsize=(6 * len(offsets), 4.3 * len(inputs)), squeeze=False,
                         sharey=True)
for i, inp in enumerate(inputs):
    for j, off in enumerate(offsets):
        ax = axes[i][j]
        for model in models:
            for imaging in imagings:
                xs, ys = [], []
                for p in points:
                    v = cells.get((inp, off, imaging, model, p))
                    if v:
                        xs.append(p)
                        ys.append(sum(v) / len(v))
                if not xs:
                    continue
                label = model.replace("@fick", " (Fick angles)") + ("" if imaging == "normal" else " (hard)")
                style = ":s" if "@fick" in model else ("-o" if imaging == "normal" else "--x")
                ax.plot(xs, ys, style, color=colours[model], label=label,
                        alpha=1.0 if imaging == "normal" else 0.6, markersize=4)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(points)
        ax.set_xticklabels([str(p) for p in points])
        ax.grid(True, which="both", alpha=0.3)
        title_off = "no head offset" if off == "0" else "head offset " + off.replace(";", ", ") + " mm"
        ax.set_title(f"input {inp}, {title_off}", fontsize=10)
        ax.set_xlabel("calibration points")
        if j == 0:
            ax.set_ylabel("mean validation error (deg)")
axes[0][-1].legend(fontsize=7, loc="upper right")
axes[1][-1].legend(fontsize=7, loc="upper right")
fig.suptitle("Calibration error vs points and model (synthetic eye, 9 validation targets; mean over viewers)",
             fontsize=11)
fig.tight_layout()
fig.savefig(dst, dpi=110)
print("wrote", dst)

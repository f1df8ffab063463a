#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Builds the governor's accuracy-versus-time fronts (renderer/governor/fronts.json) from the
benchmarks' checked-in CSVs: every option is a set of render settings with the time it took and the
accuracy it reached against the effect's reference, and only the Pareto-optimal ones are kept (no
other option is both at least as fast and at least as accurate).

Usage: make_fronts.py [RESULTS_DIR] [OUT_JSON]   (defaults bench/results, renderer/governor/fronts.json)
"""
import csv
import glob
import json
import os
import re
import sys
from collections import defaultdict


def pareto(options, higher_better):
    key = (lambda o: o["accuracy"]) if higher_better else (lambda o: -o["accuracy"])
    kept = []
    for o in sorted(options, key=lambda o: (o["ms"], -key(o))):
        if not kept or key(o) > key(kept[-1]):
            kept.append(o)
    return kept


def dof_front(path):
    # bench_dof: mean over its three scenes at a mean CoC of 16 px (1024x768).
    settings = {
        "lee-mipmap": {"dof.method": "lee-mipmap", "dof.sigma_per_coc": "0.5"},
        "lee-mipmap sigma=C/4": {"dof.method": "lee-mipmap", "dof.sigma_per_coc": "0.25"},
        "lee-splat": {"dof.method": "lee-splat", "dof.hidden": "true"},
        "lee-splat no hidden": {"dof.method": "lee-splat", "dof.hidden": "false"},
        "schedl-layered M=3": {"dof.method": "schedl-layered", "dof.layers": "3"},
        "schedl-layered M=1": {"dof.method": "schedl-layered", "dof.layers": "1"},
        "accum (embree 16 views)": {"dof.method": "accum", "dof.samples": "16"},
    }
    acc, ms = defaultdict(list), defaultdict(list)
    for r in csv.DictReader(open(path)):
        if r["mean_coc_px"] == "16" and r["method"] in settings:
            acc[r["method"]].append(float(r["psnr_db"]))
            ms[r["method"]].append(float(r["ms_per_frame"]))
    options = [{"label": m, "settings": settings[m], "ms": sum(ms[m]) / len(ms[m]), "accuracy": sum(acc[m]) / len(acc[m])}
               for m in acc]
    return {"effect": "dof", "passes": ["dof"], "metric": "PSNR dB", "higher_better": True,
            "reference": "64-sample thin-lens ray tracing, mean CoC 16 px, bench_dof's three scenes",
            "pixels": 1024 * 768, "scales_with_pixels": True, "source": "bench/results/bench_dof.csv",
            "options": pareto(options, True)}


def device_token(renderer):
    """The part of an OpenGL renderer's description a front is matched by (FramePipeline::device()
    contains it): "OpenGL 4.5 (llvmpipe (LLVM 15.0.6, 256 bits))" -> "llvmpipe",
    "OpenGL 4.6 (NVIDIA H200/PCIe/SSE2)" -> "NVIDIA H200/PCIe/SSE2"."""
    m = re.match(r"OpenGL [\d.]+ \((.*)\)$", renderer)
    name = m.group(1) if m else renderer
    return name.split(" (")[0]


def dof_device_fronts(results):
    """The dof fronts of the OpenGL backend on the devices bench_dof's GL rows ran on: every
    bench_dof_gl.csv under RESULTS (this machine's, and any copied from another machine's run of
    bench_dof --methods "lee-mipmap,lee-mipmap sigma=C/4,lee-mipmap gl", and of
    --methods "lee-splat,schedl-layered M=3,schedl-layered gl M=3" with the same size and reference). Options:
    the CPU methods (dof.device=cpu: read back, filtered, uploaded) at their wall time (lee-splat's and
    schedl-layered's with their peeled renders), and the GL implementations (dof.device=gpu) at their GPU
    time, the pass's cost in a GPU-resident frame (without gpu.peel), each implementation a point of
    its own (frame.effect_passes=fragment, or compute for the "gl compute" rows where the run had
    them); one reference for all."""
    cpu = {"lee-mipmap": {"dof.method": "lee-mipmap", "dof.sigma_per_coc": "0.5"},
           "lee-mipmap sigma=C/4": {"dof.method": "lee-mipmap", "dof.sigma_per_coc": "0.25"},
           "lee-splat": {"dof.method": "lee-splat"},
           "schedl-layered M=3": {"dof.method": "schedl-layered", "dof.layers": "3"}}
    gpu = {"lee-mipmap gl": cpu["lee-mipmap"], "lee-mipmap gl sigma=C/4": cpu["lee-mipmap sigma=C/4"],
           "lee-splat gl": cpu["lee-splat"], "schedl-layered gl M=3": cpu["schedl-layered M=3"]}
    # The passes with a compute implementation: the fragment rows say so, the compute rows are points too.
    for m in ("lee-mipmap gl", "lee-mipmap gl sigma=C/4", "schedl-layered gl M=3", "lee-splat gl"):
        gpu[m] = dict(gpu[m], **{"frame.effect_passes": "fragment"})
    gpu["lee-mipmap gl compute"] = dict(gpu["lee-mipmap gl"], **{"frame.effect_passes": "compute"})
    gpu["lee-mipmap gl compute sigma=C/4"] = dict(gpu["lee-mipmap gl sigma=C/4"], **{"frame.effect_passes": "compute"})
    gpu["schedl-layered gl compute M=3"] = dict(gpu["schedl-layered gl M=3"], **{"frame.effect_passes": "compute"})
    gpu["lee-splat gl compute"] = dict(gpu["lee-splat gl"], **{"frame.effect_passes": "compute"})
    fronts = []
    for path in sorted(glob.glob(os.path.join(results, "**", "bench_dof_gl.csv"), recursive=True)):
        rows = [r for r in csv.DictReader(open(path)) if r["mean_coc_px"] == "16"]
        devices = {r["device"] for r in rows if r["method"] in gpu}
        if len(devices) != 1:
            sys.exit(f"make_fronts: {path}: expected the GL rows of one device, found {sorted(devices) or 'none'}")
        device = devices.pop()
        acc, ms = defaultdict(list), defaultdict(list)
        for r in rows:
            if r["method"] in cpu:
                ms[r["method"]].append(float(r["ms_per_frame"]))
            elif r["method"] in gpu:
                ms[r["method"]].append(float(r["gpu_ms"]))
            else:
                continue
            acc[r["method"]].append(float(r["psnr_db"]))
        options = []
        for m in acc:
            settings = dict(cpu.get(m) or gpu[m])
            settings["dof.device"] = "gpu" if m in gpu else "cpu"
            options.append({"label": m, "settings": settings, "ms": sum(ms[m]) / len(ms[m]),
                            "accuracy": sum(acc[m]) / len(acc[m])})
        samples = rows[0]["reference_samples"]
        fronts.append({"effect": "dof", "backend": "gl", "device": device_token(device), "passes": ["dof", "gpu.dof"],
                       "metric": "PSNR dB", "higher_better": True,
                       "reference": f"{samples}-sample thin-lens ray tracing, mean CoC 16 px, bench_dof's three scenes; "
                                    f"GL rows on {device}",
                       "pixels": 1024 * 768, "scales_with_pixels": True, "source": os.path.relpath(path),
                       "options": pareto(options, True)})
    return fronts


def gi_front(results):
    # The gaze area's size traded against photons (bench_gi --sections radius): the hybrid image
    # against a full-screen reference with errors weighted by the eye's resolution at each pixel's
    # eccentricity. Without that run, the photons alone in a 20 deg area (--sections accuracy).
    radius = os.path.join(results, "gi", "gi_radius.csv")
    if os.path.exists(radius):
        options = []
        for r in csv.DictReader(open(radius)):
            deg = float(r["area_deg"])
            settings = {"gi.strategy": r["strategy"], "gi.estimate": r["estimate"], "gi.photons": r["photons"],
                        "gi.area": "gaze" if deg > 0 else "full"}
            if deg > 0:
                settings["gi.gaze_area_deg"] = f"{deg:g}"
            options.append({"label": f'{r["strategy"]} {r["estimate"]} {int(r["photons"]) // 1000}k, '
                                     + (f"{deg:g} deg" if deg > 0 else "full screen"),
                            "settings": settings, "ms": float(r["ms_per_frame"]),
                            "accuracy": float(r["csf_weighted_rmse"])})
        return {"effect": "gi", "passes": ["gi"], "metric": "CSF-weighted relative RMSE over the image", "higher_better": False,
                "reference": "a full-screen traditional map (bench_gi --reference-photons), errors weighted by the "
                             "Geisler-Perry cutoff frequency at each pixel's eccentricity from the gaze (cornell.json)",
                "pixels": 640 * 480, "scales_with_pixels": True, "source": "bench/results/gi/gi_radius.csv",
                "options": pareto(options, False)}
    options = []
    for r in csv.DictReader(open(os.path.join(results, "gi", "gi_accuracy.csv"))):
        options.append({"label": f'{r["strategy"]} {r["estimate"]} {int(r["photons"]) // 1000}k',
                        "settings": {"gi.strategy": r["strategy"], "gi.estimate": r["estimate"], "gi.photons": r["photons"]},
                        "ms": float(r["ms_per_frame"]), "accuracy": float(r["relative_rmse"])})
    return {"effect": "gi", "passes": ["gi"], "metric": "relative RMSE", "higher_better": False,
            "reference": "a 2M-photon traditional map, radiance in a 20 deg gaze area (cornell.json)",
            "pixels": 640 * 480, "scales_with_pixels": True, "source": "bench/results/gi/gi_accuracy.csv",
            "options": pareto(options, False)}


def attention_device_fronts(results):
    """The attention fronts of the OpenGL backend on the devices bench_attention's GL rows ran on: every
    bench_attention_gl.csv under RESULTS (this machine's, and any copied from another machine's run of
    bench_attention). Options per map size: the CPU's pixel stage (attention.device=cpu) at its wall time
    and the GL one (attention.device=gpu) at its GPU time, on the largest G-buffer of the run; accuracy
    A1 from eval_attention.csv (the same maps on both: the GL map is the CPU's to 2e-6)."""
    a1 = {r["map"]: float(r["A1"]) for r in csv.DictReader(open(os.path.join(results, "eval_attention.csv")))
          if r["section"] == "map_size" and r["method"] == "fovea"}
    fronts = []
    for path in sorted(glob.glob(os.path.join(results, "**", "bench_attention_gl.csv"), recursive=True)):
        rows = list(csv.DictReader(open(path)))
        gl_rows = [r for r in rows if r["method"] == "fovea gl (GPU pixel stage)"]
        devices = {r["device"] for r in gl_rows}
        if len(devices) != 1:
            sys.exit(f"make_fronts: {path}: expected the GL rows of one device, found {sorted(devices) or 'none'}")
        device = devices.pop()
        size = max({r["input"].split()[-1] for r in gl_rows}, key=lambda s: int(s.split("x")[0]) * int(s.split("x")[1]))
        w, h = (int(v) for v in size.split("x"))
        options = []
        for r in rows:
            if not r["input"].endswith(" " + size) or r["map"] not in a1:
                continue
            # Each GL implementation a point of its own (frame.effect_passes), where the run had it.
            where, passes = {"fovea (Lee 2009)": ("cpu", None), "fovea gl (GPU pixel stage)": ("gpu", "fragment"),
                             "fovea gl compute (GPU pixel stage)": ("gpu", "compute")}.get(r["method"], (None, None))
            if where is None:
                continue
            settings = {"attention.map_size": r["map"], "attention.resample": "box", "attention.device": where}
            if passes:
                settings["frame.effect_passes"] = passes
            options.append({"label": f'{r["map"]}x{r["map"]} box, {where}' + (" compute" if passes == "compute" else ""),
                            "settings": settings, "ms": float(r["total_median_ms"]), "accuracy": a1[r["map"]]})
        fronts.append({"effect": "attention", "backend": "gl", "device": device_token(device),
                       "passes": ["attention", "gpu.attention"],
                       "metric": "A1 (share of frames the most attended object is the gazed one)", "higher_better": True,
                       "reference": "a synthetic viewer's gaze on renderer/scenes/attention.json (fovea-eval-attention); "
                                    f"times of {size} G-buffers, GL rows on {device}",
                       "pixels": w * h, "scales_with_pixels": False, "source": os.path.relpath(path),
                       "options": pareto(options, True)})
    return fronts


def attention_front(path):
    options = []
    for r in csv.DictReader(open(path)):
        if r["section"] != "map_size":
            continue
        resample = "nearest" if r["method"].endswith("nearest") else "box"
        options.append({"label": f'{r["map"]}x{r["map"]} {resample}',
                        "settings": {"attention.map_size": r["map"], "attention.resample": resample},
                        "ms": float(r["ms_per_frame"]), "accuracy": float(r["A1"])})
    return {"effect": "attention", "passes": ["attention"], "metric": "A1 (share of frames the most attended object is the gazed one)",
            "higher_better": True, "reference": "a synthetic viewer's gaze on renderer/scenes/attention.json (fovea-eval-attention)",
            "pixels": 0, "scales_with_pixels": False, "source": "bench/results/eval_attention.csv",
            "options": pareto(options, True)}


def lod_fronts(path):
    fronts = []
    rows = list(csv.DictReader(open(path)))
    for backend in sorted({r["backend"] for r in rows}):
        mine = [r for r in rows if r["backend"] == backend and r["model"] == "dragon"]
        most = max(int(r["objects"]) for r in mine)
        policy = {"NOLOD": "none", "ULOD5": "ulod", "distance": "distance", "screen-size": "screen-size",
                  "brown": "brown", "gaze": "gaze"}
        options = []
        for r in mine:
            if int(r["objects"]) != most or r["condition"] not in policy:
                continue
            db = float(r["psnr_periphery_db"])
            options.append({"label": policy[r["condition"]], "settings": {"lod.policy": policy[r["condition"]]},
                            "ms": float(r["ms_per_frame"]), "accuracy": min(db, 60.0) if db == db else 60.0})
        fronts.append({"effect": "lod", "backend": backend, "passes": ["gbuffer", "attention.proxy", "lod-select"],
                       "metric": "PSNR dB (periphery)", "higher_better": True,
                       "reference": f"full detail, {most} dragon-like objects (bench_lod)", "pixels": 1024 * 768,
                       "scales_with_pixels": False, "source": "bench/results/bench_lod.csv",
                       "options": pareto(options, True)})
    return fronts


def main():
    results = sys.argv[1] if len(sys.argv) > 1 else "bench/results"
    out = sys.argv[2] if len(sys.argv) > 2 else "renderer/governor/fronts.json"
    # Device fronts first: the governor takes the first front of an effect that matches.
    fronts = dof_device_fronts(results) + attention_device_fronts(results)
    fronts += [dof_front(os.path.join(results, "bench_dof.csv")),
              gi_front(results),
              attention_front(os.path.join(results, "eval_attention.csv"))]
    fronts += lod_fronts(os.path.join(results, "bench_lod.csv"))
    for f in fronts:
        for o in f["options"]:
            o["ms"] = round(o["ms"], 3)
            o["accuracy"] = round(o["accuracy"], 5)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    with open(out, "w") as fh:
        json.dump({"machine": "the project's 2-core Debian 12 machine (see bench/RESULTS.md)", "fronts": fronts}, fh, indent=1)
        fh.write("\n")
    for f in fronts:
        print(f["effect"], f.get("backend", ""), [(o["label"], o["ms"], o["accuracy"]) for o in f["options"]])
    print("wrote", out)


if __name__ == "__main__":
    main()

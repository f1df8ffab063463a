#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Agreement of fovea's classifiers with GazeCom's expert labels: fixation, saccade and smooth
pursuit in free viewing of natural videos (issue 43).

GazeCom (../shared/data/gazecom, see its README): 826 EyeLink II recordings at 250 Hz of 18 videos,
labelled by Agtzidis, Startsev & Dorr 2016 / Startsev, Agtzidis & Dorr 2019 (Behav Res Meth
51:556-572). Each recording is given to `fovea-ctl classify` exactly as a user would (screen pixels,
a lost sample as nan: x = y = 0 or confidence 0 is track loss, as the README says), and its labels
are scored against `handlabeller_final`:

- sample level: F1 and Cohen's kappa of each class against the rest, over all samples of all
  recordings pooled (as Startsev et al. 2019 report GazeCom). fovea's `pso` counts as fixation
  (GazeCom has no PSO class); its blink, lost and unknown labels and GazeCom's noise are "other";
- event level: F1 with a hit where a detected and a coder event of the class overlap with
  intersection over union >= 0.5 (Startsev et al. 2019), counts pooled over recordings;
- leave-one-video-out: each video's recordings scored with what was fitted on the other 17. The
  rule-based methods have no parameters fitted to GazeCom, so their held-out score is the pooled one;
  the learned `gbt` is scored with --lovo DIR, each video by the model bench/train_classifier.py
  --lovo fitted without it (the built-in model has seen every video: its pooled score is not a
  held-out one); the per-video table shows how much the videos differ;
- the final labels' latency: final_ms - t_ms per sample (`--final-times`), p50 / p99 per class;
- the student coders against the expert, on the recordings that have their labels: the ceiling.

Usage: bench/eval_classify_gazecom.py FOVEA_CTL [--data DIR_OR_TAR] [--every N] [--limit N]
       [--methods ivvt,gbt,gbt+offline,...] [--lovo DIR] [--extra-args "..."] [--json OUT.json] [--per-video]
"""
import argparse
import concurrent.futures
import json
import os
import subprocess
import sys
import tarfile
import tempfile

import numpy as np

from classify_scoring import confusion, event_counts, events_of, f1_of, kappa_of, method_args

CLASSES = ("fixation", "saccade", "pursuit")
CODER = {1: "fixation", 2: "saccade", 3: "pursuit", 4: "noise"}
FOVEA = {"fixation": "fixation", "pso": "fixation", "saccade": "saccade", "pursuit": "pursuit"}
RATE_HZ = 250


def unpacked(data):
    """The ground_truth directory: `data` itself, or its tar.xz unpacked once into the user's cache."""
    if os.path.isdir(os.path.join(data, "ground_truth")):
        return os.path.join(data, "ground_truth")
    if os.path.isdir(data) and os.path.exists(os.path.join(data, "gazecom-ground-truth.tar.xz")):
        data = os.path.join(data, "gazecom-ground-truth.tar.xz")
    if not os.path.isfile(data):
        sys.exit(f"eval_classify_gazecom: no GazeCom at {data} (a ground_truth/ directory or the .tar.xz)")
    cache = os.path.join(os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")), "fovea", "gazecom")
    target = os.path.join(cache, "ground_truth")
    stamp = os.path.join(cache, "unpacked-from")
    key = f"{os.path.abspath(data)} {os.path.getsize(data)} {int(os.path.getmtime(data))}"
    if not (os.path.isdir(target) and os.path.exists(stamp) and open(stamp).read() == key):
        os.makedirs(cache, exist_ok=True)
        with tarfile.open(data) as tar:
            members = [m for m in tar.getmembers() if m.isfile() and m.name.startswith("ground_truth/")
                       and ".." not in m.name.split("/")]
            tar.extractall(cache, members=members)
        with open(stamp, "w") as f:
            f.write(key)
    return target


def read_arff(path):
    """(geometry, t_us, x, y, confidence, final labels, coder 1, coder 2) of one recording."""
    meta, rows, in_data = {}, [], False
    with open(path) as f:
        for line in f:
            line = line.strip()
            if line.startswith("%@METADATA"):
                _, key, value = line.split()
                meta[key] = float(value)
            elif line.upper() == "@DATA":
                in_data = True
            elif in_data and line and not line.startswith("%"):
                rows.append(line.split(","))
    if not rows:
        raise ValueError(f"{path}: no data rows")
    geometry = (int(meta["width_px"]), int(meta["height_px"]), meta["width_mm"], meta["height_mm"], meta["distance_mm"])
    col = lambda i, conv: [conv(r[i]) for r in rows]
    label = lambda v: -1 if v == "?" else int(v)
    return (geometry, np.array(col(0, int), dtype=np.int64), np.array(col(1, float)), np.array(col(2, float)),
            np.array(col(3, float)), col(6, label), col(4, label), col(5, label))


def write_input(t_us, x, y, conf, path):
    lost = ((x == 0) & (y == 0)) | (conf <= 0) | ~np.isfinite(x) | ~np.isfinite(y)
    with open(path, "w") as f:
        f.write("t_ms,x_px,y_px\n")
        for t, xi, yi, gone in zip(t_us / 1000.0, x, y, lost):
            f.write("%.3f,nan,nan\n" % t if gone else "%.3f,%.2f,%.2f\n" % (t, xi, yi))


def classify(ctl, in_path, out_path, geometry, method, extra):
    w_px, h_px, w_mm, h_mm, dist_mm = geometry
    cmd = [ctl, "classify", in_path, out_path, str(RATE_HZ), str(w_px), str(h_px), "%g" % w_mm, "%g" % h_mm,
           "%g" % dist_mm, "--method", method, "--force", "--final-times"] + extra
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    labels, final_ms, raw = [], [], []
    with open(out_path) as f:
        next(f)
        for line in f:
            fields = line.rstrip("\n").split(",")
            raw.append(fields[1])
            labels.append(FOVEA.get(fields[1], "other"))
            final_ms.append(float(fields[2]))
    return labels, np.array(final_ms), raw


def speed_deg_s(geometry, t_us, x, y, conf):
    """Gaze speed per sample, central differences of the per-axis angles (nan at track loss)."""
    w_px, h_px, w_mm, h_mm, dist_mm = geometry
    lost = ((x == 0) & (y == 0)) | (conf <= 0)
    xd = np.degrees(np.arctan((x / w_px - 0.5) * w_mm / dist_mm))
    yd = np.degrees(np.arctan((y / h_px - 0.5) * h_mm / dist_mm))
    xd[lost] = yd[lost] = np.nan
    t = t_us / 1e6
    return np.hypot(np.gradient(xd, t), np.gradient(yd, t))


def saccade_edge_speeds(truth, predicted, speed):
    """For each expert saccade that one detected saccade overlaps (no loss inside): the speed at the
    expert's first and last sample and at the detected event's."""
    out = {"expert_onset": [], "expert_offset": [], "method_onset": [], "method_offset": []}
    found = events_of(predicted, "saccade")
    j = 0
    for a, b in events_of(truth, "saccade"):
        while j < len(found) and found[j][1] <= a:
            j += 1
        overlap = [e for e in found[j:] if e[0] < b]
        if len(overlap) != 1 or not np.isfinite(speed[min(a, overlap[0][0]):max(b, overlap[0][1])]).all():
            continue
        fs, fe = overlap[0]
        for key, i in (("expert_onset", a), ("expert_offset", b - 1), ("method_onset", fs), ("method_offset", fe - 1)):
            out[key].append(float(speed[i]))
    return out


def where_wrong(truth, predicted, raw, c):
    """Where class c's sample errors lie: the expert's c samples missed before the detected event
    starts, after it ends, or in events missed whole (with fovea's own labels there), and false c
    samples before the expert's onset, after its offset, or in events the expert has none of (with the
    expert's labels there)."""
    out = {"missed_start": 0, "missed_end": 0, "missed_whole": 0, "false_start": 0, "false_end": 0,
           "false_whole": 0, "fovea_in_missed_end": {}, "expert_in_false_whole": {}}
    te, pe = events_of(truth, c), events_of(predicted, c)
    for events, other, kind in ((te, pe, "missed"), (pe, te, "false")):
        j = 0
        for a, b in events:
            while j < len(other) and other[j][1] <= a:
                j += 1
            overlap = [e for e in other[j:] if e[0] < b]
            if not overlap:
                out[kind + "_whole"] += b - a
                if kind == "false":
                    for i in range(a, b):
                        out["expert_in_false_whole"][truth[i]] = out["expert_in_false_whole"].get(truth[i], 0) + 1
                continue
            out[kind + "_start"] += max(0, overlap[0][0] - a)
            out[kind + "_end"] += max(0, b - overlap[-1][1])
            if kind == "missed":
                for i in range(max(a, overlap[-1][1]), b):
                    out["fovea_in_missed_end"][raw[i]] = out["fovea_in_missed_end"].get(raw[i], 0) + 1
    return out


def score(truth, predicted):
    """Counts per class: sample confusion (tp, fp, fn, tn) and event (hits, fp, fn)."""
    return {c: {"sample": confusion(truth, predicted, c), "event": event_counts(truth, predicted, c)} for c in CLASSES}


def add(total, counts):
    for c in CLASSES:
        for level in ("sample", "event"):
            total[c][level] = tuple(a + b for a, b in zip(total[c][level], counts[c][level]))


def empty():
    return {c: {"sample": (0, 0, 0, 0), "event": (0, 0, 0)} for c in CLASSES}


def figures(total):
    return {c: {"f1": f1_of(*total[c]["sample"][:3]), "kappa": kappa_of(*total[c]["sample"]),
                "event_f1": f1_of(*total[c]["event"])} for c in CLASSES}


def run_recording(args, path, tmp):
    geometry, t_us, x, y, conf, final, coder1, coder2 = read_arff(path)
    truth = [CODER.get(v, "other") for v in final]
    base = os.path.join(tmp, os.path.basename(path))
    write_input(t_us, x, y, conf, base + ".in.csv")
    out = {"video": os.path.basename(os.path.dirname(path)), "methods": {}, "latency": {}}
    t_ms = t_us / 1000.0
    for m in args.methods:
        method, flags = method_args(m)  # gbt+offline+pso=none: ... --method gbt --offline --pso none
        extra = list(args.extra) + flags
        if args.lovo and method == "gbt":  # the model fitted without this recording's video
            extra += ["--model", os.path.join(args.lovo, out["video"] + ".trees")]
        labels, final_ms, raw = classify(args.ctl, base + ".in.csv", base + ".out.csv", geometry, method, extra)
        out["methods"][m] = score(truth, labels)
        if args.diagnose and m == args.methods[0]:
            out["diagnosis"] = {c: where_wrong(truth, labels, raw, c) for c in CLASSES}
            out["edges"] = saccade_edge_speeds(truth, labels, speed_deg_s(geometry, t_us, x, y, conf))
        late = final_ms - t_ms
        out["latency"][m] = {c: late[[l == c for l in labels]].tolist() for c in CLASSES}
    # The student coders against the expert, on the rows that have their labels (most recordings
    # lack them for the first rows; recordings where they cover less than 90 % are left out).
    for name, coder in (("coder 1", coder1), ("coder 2", coder2)):
        rows = [i for i, v in enumerate(coder) if v >= 0]
        if len(rows) >= 0.9 * len(coder):
            out["methods"][name] = score([truth[i] for i in rows], [CODER.get(coder[i], "other") for i in rows])
    return out


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("ctl", help="the fovea-ctl binary")
    ap.add_argument("--data", default=os.path.join(here, "..", "..", "shared", "data", "gazecom"))
    ap.add_argument("--every", type=int, default=1, help="every N-th recording (sorted by video, observer)")
    ap.add_argument("--limit", type=int, default=0, help="at most N recordings (0: all)")
    ap.add_argument("--methods", default="ivvt", help="comma-separated fovea-ctl classify methods; METHOD+FLAG "
                    "adds --FLAG, METHOD+FLAG=V --FLAG V (gbt+offline: the offline second stage beside the "
                    "online one; gbt+pso=none: without a PSO class; gbt+pso=onset: the PSO from its onset)")
    ap.add_argument("--extra-args", default="", help="more fovea-ctl classify arguments, e.g. --offline")
    ap.add_argument("--lovo", help="DIR of bench/train_classifier.py --lovo: method gbt labels each recording "
                    "with DIR/<its video>.trees, fitted on the other videos")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--json", help="write the figures here")
    ap.add_argument("--per-video", action="store_true", help="also print each held-out video's figures")
    ap.add_argument("--pso-as", choices=("fixation", "saccade"), default="fixation",
                    help="the class fovea's pso counts as (GazeCom has none; default fixation, as the issue scores)")
    ap.add_argument("--diagnose", action="store_true", help="where the first method's errors lie, per class")
    args = ap.parse_args()
    FOVEA["pso"] = args.pso_as
    args.methods = [m for m in args.methods.split(",") if m]
    args.extra = args.extra_args.split()
    root = unpacked(args.data)
    files = sorted(os.path.join(root, v, f) for v in os.listdir(root) for f in os.listdir(os.path.join(root, v))
                   if f.endswith(".arff"))
    files = files[::args.every]
    if args.limit:
        files = files[:args.limit]
    if not files:
        sys.exit(f"eval_classify_gazecom: no .arff recordings under {root}")
    with tempfile.TemporaryDirectory() as tmp, concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        results = list(pool.map(lambda p: run_recording(args, p, tmp), files))
    report(args, results, len(files))


def report(args, results, n_files):
    names = args.methods + ["coder 1", "coder 2"]
    pooled = {m: empty() for m in names}
    per_video = {}
    have = {m: 0 for m in names}
    for r in results:
        for m, counts in r["methods"].items():
            add(pooled[m], counts)
            have[m] += 1
            add(per_video.setdefault(r["video"], {}).setdefault(m, empty()), counts)
    videos = sorted(per_video)
    print(f"{n_files} GazeCom recordings of {len(videos)} videos{' (fovea-ctl classify ' + ' '.join(args.extra) + ')' if args.extra else ''}, "
          f"scored against the expert's labels (PSO as {args.pso_as})\n")
    print("| labels | recordings | F1 fixation | F1 saccade | F1 pursuit | kappa fixation | kappa saccade | kappa pursuit "
          "| event F1 fixation | event F1 saccade | event F1 pursuit |")
    print("|---|---:|" + "---:|" * 9)
    summary = {"recordings": n_files, "videos": len(videos), "pooled": {}, "per_video": {}, "latency_ms": {}}
    for m in names:
        if have[m] == 0:
            continue
        f = figures(pooled[m])
        summary["pooled"][m] = f
        cells = [f[c]["f1"] for c in CLASSES] + [f[c]["kappa"] for c in CLASSES] + [f[c]["event_f1"] for c in CLASSES]
        print(f"| {m} | {have[m]} | " + " | ".join(f"{v:.3f}" for v in cells) + " |")
    for m in args.methods:
        lat = {c: np.concatenate([np.array(r["latency"][m][c]) for r in results]) for c in CLASSES}
        summary["latency_ms"][m] = {c: {"p50": float(np.percentile(v, 50)) if len(v) else None,
                                        "p99": float(np.percentile(v, 99)) if len(v) else None} for c, v in lat.items()}
    print("\nFinal labels' latency (final_ms - t_ms, ms; p50 / p99):\n")
    print("| method | fixation | saccade | pursuit |")
    print("|---|---:|---:|---:|")
    for m in args.methods:
        lat = summary["latency_ms"][m]
        print(f"| {m} | " + " | ".join("%.0f / %.0f" % (lat[c]["p50"], lat[c]["p99"]) if lat[c]["p50"] is not None
                                      else "-" for c in CLASSES) + " |")
    for v in videos:
        summary["per_video"][v] = {m: figures(per_video[v][m]) for m in per_video[v]}
    if args.per_video:
        print("\nEach video held out (sample F1 fixation / saccade / pursuit):\n")
        print("| video | " + " | ".join(args.methods) + " |")
        print("|---|" + "---:|" * len(args.methods))
        for v in videos:
            print(f"| {v} | " + " | ".join(
                " / ".join(f"{summary['per_video'][v][m][c]['f1']:.2f}" for c in CLASSES) for m in args.methods) + " |")
    if args.diagnose:
        summary["diagnosis"] = diagnose(args.methods[0], results)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(summary, f, indent=1)


def diagnose(method, results):
    """Sums where_wrong over the recordings and prints it."""
    total = {}
    for r in results:
        for c, d in r["diagnosis"].items():
            t = total.setdefault(c, {})
            for k, v in d.items():
                if isinstance(v, dict):
                    into = t.setdefault(k, {})
                    for label, n in v.items():
                        into[label] = into.get(label, 0) + n
                else:
                    t[k] = t.get(k, 0) + v
    edges = {k: np.concatenate([np.array(r["edges"][k]) for r in results]) for k in results[0]["edges"]}
    total["saccade_edge_speed_p50"] = {k: float(np.median(v)) if len(v) else None for k, v in edges.items()}
    quartiles = lambda k: " / ".join("%.0f" % q for q in np.percentile(edges[k], [25, 50, 75])) if len(edges[k]) else "-"
    print(f"\nSpeed at the saccade's edges, °/s (p25 / p50 / p75, {len(edges['expert_onset'])} expert saccades that one "
          f"detected saccade overlaps): expert onset {quartiles('expert_onset')}, {method}'s onset "
          f"{quartiles('method_onset')}; expert offset {quartiles('expert_offset')}, {method}'s offset "
          f"{quartiles('method_offset')}")
    print(f"\nWhere {method}'s sample errors lie (samples; the expert's events against the detected ones):\n")
    print("| class | missed before onset | missed after offset | missed whole events | false before onset "
          "| false after offset | false whole events | fovea's labels in the missed ends | the expert's in false events |")
    print("|---|---:|---:|---:|---:|---:|---:|---|---|")
    fmt = lambda d: ", ".join(f"{k} {v}" for k, v in sorted(d.items(), key=lambda kv: -kv[1]))
    for c in CLASSES:
        t = total[c]
        print(f"| {c} | {t['missed_start']} | {t['missed_end']} | {t['missed_whole']} | {t['false_start']} | "
              f"{t['false_end']} | {t['false_whole']} | {fmt(t.get('fovea_in_missed_end', {}))} | "
              f"{fmt(t.get('expert_in_false_whole', {}))} |")
    return total


if __name__ == "__main__":
    main()

#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Agreement of fovea's classifiers with the Lund coders: fixation, saccade, PSO and pursuit in
recordings of moving dots, videos and still images (issue 43).

The data are not in this repository: Andersson, Larsson, Holmqvist, Stridh & Nystrom 2017, "One
algorithm to rule them all? An evaluation and discussion of ten eye movement event-detection
algorithms", Behav Res Meth 49:616-637; their repository EyeMovementDetectorEvaluation holds the
annotated recordings (SMI HiSpeed 1250 at 500 Hz) as MATLAB files, one per recording and coder:
`annotated_data/data used in the article/{dots,img,video}/<name>_labelled_<coder>.mat` (coders MN
and RA). Each holds a struct ETdata: `pos` (one row per sample; columns 4 and 5 the gaze in screen
pixels, (0, 0) where the tracker lost the eye, column 6 the coder's label: 1 fixation, 2 saccade,
3 PSO, 4 pursuit, 5 blink, 6 undefined, 0 not labelled), `screenRes` (pixels), `screenDim` and
`viewDist` (metres), `sampFreq` (Hz). Each recording is given to `fovea-ctl classify` as a user
would (screen pixels, a lost sample as nan, sample i at i / sampFreq) and scored as Andersson et
al. score (their callKappa6.m):

- per stimulus kind and class, Cohen's kappa of the class against the rest, over all samples of
  all recordings of the kind pooled; against each coder, and against all (every recording each
  coder labelled, pooled). The issue's summary: the mean of fixation and saccade kappa per kind,
  and the mean of those six numbers (issue 43 asks each kind at or above REMoDNaV, mean >= 0.70);
- event-level F1 per class (intersection over union >= 0.5, Startsev et al. 2019), pooled;
- the two coders against each other, on the recordings both labelled: the ceiling (Andersson et
  al.'s figures: kappa fixation / saccade dots 0.72 / 0.82, videos 0.65 / 0.87, images 0.81 /
  0.90; a loader that reads the files as they did should reproduce them: not checked here, where
  the files are not).

fovea's `pso` is its own class here (the Lund coders label PSO); its lost and unknown labels and
the coders' undefined and unlabelled samples are "other", a class neither side is scored on.

Usage: bench/eval_classify_lund.py FOVEA_CTL DATA_DIR [--methods gbt,ivvt,...] [--json OUT.json]
       [--jobs N] [--model FILE]
DATA_DIR: the repository's root, its annotated_data/, or any directory holding dots/, img/ and
video/ (images/, videos/ too) with *_labelled_<coder>.mat files.
"""
import argparse
import concurrent.futures
import json
import math
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

from classify_scoring import confusion, event_counts, f1_of, kappa_of, method_args

KINDS = {"dots": "dots", "video": "videos", "videos": "videos", "img": "images", "images": "images"}
KIND_ORDER = ("dots", "videos", "images")
LUND = {1: "fixation", 2: "saccade", 3: "pso", 4: "pursuit", 5: "blink"}  # 6 undefined, 0 unlabelled
CLASSES = ("fixation", "saccade", "pso", "pursuit", "blink")
METHODS = ("gbt", "gbt+offline", "ivvt")
FILE_NAME = re.compile(r"^(?P<recording>.+)_labelled_(?P<coder>[A-Za-z0-9]+)\.mat$")


class LundError(Exception):
    """A file that is not a Lund recording as Andersson et al. wrote them: the message names it."""


def recordings_root(data):
    """The directory whose dots/, img/, video/ hold the recordings the article used."""
    for sub in (os.path.join("annotated_data", "data used in the article"), "data used in the article", ""):
        root = os.path.join(data, sub)
        if os.path.isdir(root) and any(os.path.isdir(os.path.join(root, k)) for k in KINDS):
            return root
    sys.exit(f"eval_classify_lund: no dots/, img/ or video/ directory of Lund recordings under {data} "
             "(the EyeMovementDetectorEvaluation repository, its annotated_data/, or such a directory)")


def find_files(root):
    """(kind, recording, coder, path) of every *_labelled_<coder>.mat, sorted."""
    found = []
    for sub in sorted(os.listdir(root)):
        if sub not in KINDS or not os.path.isdir(os.path.join(root, sub)):
            continue
        for name in sorted(os.listdir(os.path.join(root, sub))):
            m = FILE_NAME.match(name)
            if m:
                found.append((KINDS[sub], m["recording"], m["coder"], os.path.join(root, sub, name)))
    if not found:
        sys.exit(f"eval_classify_lund: no *_labelled_<coder>.mat files in the kind directories of {root}")
    return found


def field(et, name, path):
    if not hasattr(et, name):
        raise LundError(f"{path}: ETdata has no field '{name}'")
    return np.atleast_1d(np.asarray(getattr(et, name), dtype=np.float64))


def load(path):
    """A Lund recording: rate (Hz), geometry (w_px, h_px, w_mm, h_mm, dist_mm), x, y (pixels, nan where
    lost) and the coder's labels (class names, "other" where undefined)."""
    import scipy.io  # Debian's python3-scipy (with python3-sklearn); only this script needs it
    try:
        mat = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)
    except NotImplementedError as e:  # MATLAB 7.3 files are HDF5
        raise LundError(f"{path}: a MATLAB file scipy cannot read ({e}); save it as -v7") from None
    except Exception as e:  # scipy's parser raises what the bytes lead it to: all mean "damaged"
        raise LundError(f"{path}: not a MATLAB file scipy can read ({type(e).__name__}: {e})") from None
    if "ETdata" not in mat:
        raise LundError(f"{path}: no ETdata struct (holds {', '.join(k for k in mat if not k.startswith('__'))})")
    et = mat["ETdata"]
    try:
        pos = np.asarray(et.pos, dtype=np.float64)
    except (AttributeError, TypeError, ValueError):
        raise LundError(f"{path}: ETdata.pos is missing or not a numeric matrix") from None
    if pos.ndim != 2 or pos.shape[1] < 6 or len(pos) < 2:
        raise LundError(f"{path}: ETdata.pos is {pos.shape}, not samples x (at least) 6 columns")
    rate = field(et, "sampFreq", path)[0]
    res = field(et, "screenRes", path)
    dim = field(et, "screenDim", path)
    dist = field(et, "viewDist", path)[0]
    if not (math.isfinite(rate) and 1 <= rate <= 10000):
        raise LundError(f"{path}: sampFreq {rate} is not a sampling rate in Hz")
    if len(res) < 2 or len(dim) < 2 or not all(np.isfinite(np.r_[res[:2], dim[:2], dist])) or \
            min(res[0], res[1], dim[0], dim[1], dist) <= 0:
        raise LundError(f"{path}: screenRes {res.tolist()}, screenDim {dim.tolist()}, viewDist {dist}: "
                        "not a screen's pixels, its size and the eye's distance")
    x, y = pos[:, 3].copy(), pos[:, 4].copy()
    lost = ~np.isfinite(x) | ~np.isfinite(y) | ((x == 0) & (y == 0))
    x[lost], y[lost] = np.nan, np.nan
    codes = pos[:, 5]
    labels = [LUND.get(int(c), "other") if math.isfinite(c) else "other" for c in codes]
    # screenDim and viewDist in metres as the annotator writes them; fovea-ctl takes millimetres
    geometry = (int(round(res[0])), int(round(res[1])), dim[0] * 1000.0, dim[1] * 1000.0, dist * 1000.0)
    return rate, geometry, x, y, labels


def write_input(rec, tmp):
    """The recording as fovea-ctl classify's input (t_ms,x_px,y_px; nan where lost), once for every
    method: its path."""
    rate, _, x, y, _ = rec["data"]
    path = os.path.join(tmp, f"{rec['id']}.in.csv")
    with open(path, "w") as f:
        f.write("t_ms,x_px,y_px\n")
        for i, (a, b) in enumerate(zip(x, y)):
            t = i * 1000.0 / rate
            f.write(f"{t:.3f},nan,nan\n" if math.isnan(a) else f"{t:.3f},{a:.3f},{b:.3f}\n")
    return path


def classify(ctl, rec, in_path, method, model, tmp):
    """fovea's labels of one recording (class names; lost and unknown as "other")."""
    rate, (w_px, h_px, w_mm, h_mm, dist_mm), x, _, _ = rec["data"]
    out_path = os.path.join(tmp, f"{rec['id']}-{method.replace('+', '_').replace('=', '-')}.out.csv")
    name, flags = method_args(method)
    cmd = [ctl, "classify", in_path, out_path, "%g" % rate, str(w_px), str(h_px),
           "%g" % w_mm, "%g" % h_mm, "%g" % dist_mm, "--method", name, "--force"] + flags
    if name == "gbt" and model:
        cmd += ["--model", model]
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        raise LundError(f"{rec['path']}: fovea-ctl classify --method {method} failed: {run.stderr.strip()}")
    with open(out_path) as f:
        next(f)
        labels = [line.rstrip("\n").split(",", 2)[1] for line in f]
    if len(labels) != len(x):
        raise LundError(f"{rec['path']}: fovea-ctl gave {len(labels)} labels for {len(x)} samples")
    return [l if l in CLASSES else "other" for l in labels]


class Pool:
    """Confusion and event counts per class, summed over recordings (Andersson et al. pool samples)."""

    def __init__(self):
        self.samples = {c: np.zeros(4, dtype=np.int64) for c in CLASSES}
        self.events = {c: np.zeros(3, dtype=np.int64) for c in CLASSES}
        self.recordings = 0

    def add(self, truth, predicted):
        for c in CLASSES:
            self.samples[c] += confusion(truth, predicted, c)
            self.events[c] += event_counts(truth, predicted, c)
        self.recordings += 1

    def kappa(self, c):
        return kappa_of(*(int(v) for v in self.samples[c]))

    def event_f1(self, c):
        return f1_of(*(int(v) for v in self.events[c]))

    def as_dict(self):
        return {"recordings": self.recordings,
                **{c: {"kappa": self.kappa(c), "event_f1": self.event_f1(c),
                       "samples": int(self.samples[c][0] + self.samples[c][2])} for c in CLASSES}}


def fix_sacc(pool):
    return (pool.kappa("fixation") + pool.kappa("saccade")) / 2


def print_table(title, pools):
    """One row per kind: kappa per class, the fixation+saccade mean; the issue's mean of the six."""
    print(f"\n{title}\n")
    print("| stimuli | recordings | kappa fixation | kappa saccade | kappa PSO | kappa pursuit | kappa blink "
          "| **mean fix+sacc** | event F1 fixation | event F1 saccade | event F1 pursuit |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    means = []
    for kind in KIND_ORDER:
        p = pools.get(kind)
        if p is None or p.recordings == 0:
            continue
        means.append(fix_sacc(p))
        print(f"| {kind} | {p.recordings} | " + " | ".join(f"{p.kappa(c):.2f}" for c in CLASSES) +
              f" | **{means[-1]:.2f}** | " + " | ".join(f"{p.event_f1(c):.2f}" for c in ("fixation", "saccade", "pursuit")) + " |")
    overall = float(np.mean(means)) if means else float("nan")
    print(f"\nmean of fixation and saccade kappa over the kinds: **{overall:.3f}**")
    return overall


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("ctl", help="the fovea-ctl binary")
    ap.add_argument("data", help="the EyeMovementDetectorEvaluation repository's root, its annotated_data/, or a "
                                 "directory whose dots/, img/, video/ hold *_labelled_<coder>.mat files")
    ap.add_argument("--methods", default=",".join(METHODS),
                    help="comma-separated fovea-ctl classify methods; METHOD+FLAG adds --FLAG, METHOD+FLAG=V "
                         "--FLAG V (default: %(default)s)")
    ap.add_argument("--model", help="gbt's model (default: the built-in one)")
    ap.add_argument("--json", help="write the figures here")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="fovea-ctl runs at once")
    args = ap.parse_args()
    methods = args.methods.split(",")
    files = find_files(recordings_root(args.data))
    recs = []
    try:
        for i, (kind, recording, coder, path) in enumerate(files):
            recs.append({"id": i, "kind": kind, "recording": recording, "coder": coder, "path": path,
                         "data": load(path)})
    except LundError as e:
        sys.exit(f"eval_classify_lund: {e}")
    coders = sorted({r["coder"] for r in recs})
    pools = {(m, c): {} for m in methods for c in coders + ["all"]}
    with tempfile.TemporaryDirectory() as tmp, concurrent.futures.ThreadPoolExecutor(args.jobs) as ex:
        inputs = {r["id"]: write_input(r, tmp) for r in recs}
        jobs = {(r["id"], m): ex.submit(classify, args.ctl, r, inputs[r["id"]], m, args.model, tmp)
                for r in recs for m in methods}
        try:
            for r in recs:
                truth = r["data"][4]
                for m in methods:
                    predicted = jobs[(r["id"], m)].result()
                    for c in (r["coder"], "all"):
                        pools[(m, c)].setdefault(r["kind"], Pool()).add(truth, predicted)
        except LundError as e:
            for j in jobs.values():
                j.cancel()
            sys.exit(f"eval_classify_lund: {e}")
    summary = {"recordings": len(recs), "coders": coders, "methods": {}, "coders_agreement": {}}
    counts = ", ".join("%d by %s" % (sum(r["coder"] == c for r in recs), c) for c in coders)
    kinds = len({(r["kind"], r["recording"]) for r in recs})
    print(f"{len(recs)} coded recordings ({counts}) of {kinds} Lund recordings, scored as Andersson et al. 2017")
    for m in methods:
        summary["methods"][m] = {}
        for c in ["all"] + coders:
            who = "all coders" if c == "all" else f"coder {c}"
            overall = print_table(f"### {m} against {who}", pools[(m, c)])
            summary["methods"][m][c] = {"mean_kappa_fixation_saccade": overall,
                                        **{k: p.as_dict() for k, p in pools[(m, c)].items()}}
    human = coders_against_each_other(recs, coders)
    for (a, b), (pool, truncated) in human.items():
        overall = print_table(f"### coder {b} against coder {a} (the recordings both labelled"
                              f"{f'; {truncated} cut to the shorter labelling' if truncated else ''})", pool)
        summary["coders_agreement"][f"{a}-{b}"] = {"mean_kappa_fixation_saccade": overall,
                                                   **{k: p.as_dict() for k, p in pool.items()}}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(summary, f, indent=1)


def coders_against_each_other(recs, coders):
    """Each pair of coders on the recordings both labelled (the longer labelling cut to the shorter,
    as Dar et al. 2021 do where the files differ in length)."""
    by = {(r["kind"], r["recording"], r["coder"]): r["data"][4] for r in recs}
    out = {}
    for i, a in enumerate(coders):
        for b in coders[i + 1:]:
            pools, truncated = {}, 0
            for kind, recording, coder in sorted(by):
                if coder != a or (kind, recording, b) not in by:
                    continue
                ta, tb = by[(kind, recording, a)], by[(kind, recording, b)]
                n = min(len(ta), len(tb))
                truncated += len(ta) != len(tb)
                pools.setdefault(kind, Pool()).add(ta[:n], tb[:n])
            if pools:
                out[(a, b)] = (pools, truncated)
    return out


if __name__ == "__main__":
    main()

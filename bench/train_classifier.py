#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Trains the `gbt` classifier's tree model on GazeCom's expert labels (issue 43).

Features come from fovea-ctl itself (`classify --method gbt --features-out`), so training and the
daemon see exactly the same numbers; scikit-learn's HistGradientBoostingClassifier (Debian's
python3-sklearn) fits the trees, and they are written in fovea's own text format
(trackerd/classify/trees.h), which the C++ evaluates without scikit-learn. After writing a model the
script checks that fovea-ctl with it gives scikit-learn's own predictions on held-back recordings.

  --out FILE                 one model on every recording given (the built-in model:
                             trackerd/classify/models/gazecom.trees)
  --lovo DIR                 leave-one-video-out: DIR/<video>.trees fitted on the other 17 videos,
                             for bench/eval_classify_gazecom.py --lovo DIR

GazeCom (../shared/data/gazecom, see its README): Dorr et al. 2010 (recordings), Agtzidis, Startsev
& Dorr 2016 and Startsev, Agtzidis & Dorr 2019 (labels). The copy here states no licence of its
own; a model trained on it carries the data's terms (trackerd/classify/models/README.md).

Usage: bench/train_classifier.py FOVEA_CTL (--out FILE | --lovo DIR) [--data DIR_OR_TAR] [--every N]
       [--stride-ms MS] [--augment N] [--iterations N] [--leaves N] [--jobs N]
"""
import argparse
import concurrent.futures
import hashlib
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from eval_classify_gazecom import RATE_HZ, read_arff, unpacked, write_input  # noqa: E402

CLASS_NAMES = {1: "fixation", 2: "saccade", 3: "pursuit", 4: "noise"}
NOISE_NEAR_LOSS_S = 0.100  # trees_core.h, kNoiseNearLossS


def classify(ctl, tmp, gaze, geometry, rate, extra):
    """fovea-ctl classify on one recording (t_us, x, y, conf) in directory tmp: its labels."""
    write_input(*gaze, os.path.join(tmp, "in.csv"))
    w_px, h_px, w_mm, h_mm, dist_mm = geometry
    subprocess.run([ctl, "classify", os.path.join(tmp, "in.csv"), os.path.join(tmp, "out.csv"), "%g" % rate,
                    str(w_px), str(h_px), "%g" % w_mm, "%g" % h_mm, "%g" % dist_mm] + extra,
                   check=True, capture_output=True)
    return [line.split(",")[1] for line in open(os.path.join(tmp, "out.csv")).read().splitlines()[1:]]


def as_other_tracker(t_us, x, y, conf, final, geometry, rng):
    """The recording as another tracker might have recorded the same eye movements: at another rate
    (62.5 or 125 Hz by keeping every 4th or 2nd sample; 500 or 1000 Hz by linear interpolation), with
    white noise of 0.02-0.35 deg RMS per axis (log-uniform) and 0-2 drop-outs a second (exponential
    length, mean 20 ms, at most 200 ms, as sim/synthetic_gaze's). The labels go with the movement:
    each new sample takes the label of the original sample nearest in time. GazeCom alone is one
    tracker at one rate and one noise level; trees fitted to it alone fall apart on others."""
    w_px, h_px, w_mm, h_mm, dist_mm = geometry
    lost = ((x == 0) & (y == 0)) | (conf <= 0) | ~np.isfinite(x) | ~np.isfinite(y)
    xd = np.degrees(np.arctan((x / w_px - 0.5) * w_mm / dist_mm))
    yd = np.degrees(np.arctan((y / h_px - 0.5) * h_mm / dist_mm))
    t = t_us / 1e6
    rate = float(rng.choice([62.5, 125.0, 250.0, 500.0, 1000.0]))
    if rate < RATE_HZ:
        keep = np.arange(0, len(t), int(round(RATE_HZ / rate)))
        nt, nx, ny, nlost, nlab = t[keep], xd[keep], yd[keep], lost[keep], np.asarray(final)[keep]
    else:
        nt = np.arange(t[0], t[-1], 1.0 / rate) if rate > RATE_HZ else t
        j = np.clip(np.searchsorted(t, nt, side="right") - 1, 0, len(t) - 2)
        w = np.clip((nt - t[j]) / np.maximum(t[j + 1] - t[j], 1e-9), 0, 1)
        nx = xd[j] + w * (xd[j + 1] - xd[j])
        ny = yd[j] + w * (yd[j + 1] - yd[j])
        nlost = lost[j] | (lost[j + 1] & (w > 0))
        nlab = np.asarray(final)[np.where(w < 0.5, j, j + 1)]
    sigma = float(np.exp(rng.uniform(np.log(0.02), np.log(0.35))))
    nx = nx + sigma * rng.standard_normal(len(nt))
    ny = ny + sigma * rng.standard_normal(len(nt))
    drops_per_s = rng.uniform(0, 2)
    nlost = nlost.copy()
    for start in rng.uniform(nt[0], nt[-1], rng.poisson(drops_per_s * (nt[-1] - nt[0]))):
        nlost[(nt >= start) & (nt < start + min(0.2, rng.exponential(0.02)))] = True
    px = (np.tan(np.radians(nx)) * dist_mm / w_mm + 0.5) * w_px
    py = (np.tan(np.radians(ny)) * dist_mm / h_mm + 0.5) * h_px
    return np.round(nt * 1e6).astype(np.int64), px, py, np.where(nlost, 0.0, 1.0), list(nlab), rate


def features_of(ctl, path, copy, cache):
    """(features float32 rows x F, expert labels int, rate) of a recording (copy 0) or of its copy
    as another tracker would have recorded it (copy >= 1, seeded by name and copy), cached per
    fovea-ctl build."""
    stem = os.path.join(cache, os.path.basename(path) + ("" if copy == 0 else ".copy%d" % copy))
    npy, lab, hz = stem + ".npy", stem + ".labels.npy", stem + ".rate"
    if not (os.path.exists(npy) and os.path.exists(lab) and os.path.exists(hz)):
        geometry, t_us, x, y, conf, final, _, _ = read_arff(path)
        rate = RATE_HZ
        if copy:
            seed = int.from_bytes(hashlib.sha256(f"{os.path.basename(path)} {copy}".encode()).digest()[:8], "little")
            t_us, x, y, conf, final, rate = as_other_tracker(t_us, x, y, conf, final, geometry,
                                                            np.random.default_rng(seed))
        with tempfile.TemporaryDirectory() as tmp:
            classify(ctl, tmp, (t_us, x, y, conf), geometry, rate, ["--features-out", os.path.join(tmp, "f.npy")])
            np.save(lab, np.array(final, dtype=np.int8))
            with open(hz, "w") as f:
                f.write("%g" % rate)
            os.replace(os.path.join(tmp, "f.npy"), npy)
            os.replace(os.path.join(tmp, "f.npy.names"), os.path.join(cache, "names"))
    return np.load(npy), np.load(lab), float(open(hz).read())


def build_key(ctl):
    """The cache directory's key: the fovea-ctl binary's content (its features may have changed)."""
    h = hashlib.sha256()
    with open(ctl, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()[:16]


def load_all(args, files):
    """Every recording (copy 0) and args.augment copies of each: a list of (recording index,
    features, labels, rate)."""
    cache = os.path.join(os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")), "fovea",
                         "gazecom-features", build_key(args.ctl))
    os.makedirs(cache, exist_ok=True)
    units = [(i, c) for c in range(args.augment + 1) for i in range(len(files))]
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        data = list(pool.map(lambda u: (u[0],) + features_of(args.ctl, files[u[0]], u[1], cache), units))
    names = open(os.path.join(cache, "names")).read().split()
    return data, names


def fit(x, y, args):
    from sklearn.ensemble import HistGradientBoostingClassifier
    clf = HistGradientBoostingClassifier(max_iter=args.iterations, max_leaf_nodes=args.leaves, learning_rate=0.1,
                                         l2_regularization=1.0, early_stopping=False, random_state=0)
    clf.fit(x, y)
    return clf


def training_rows(data, keep, stride_ms):
    """A labelled sample with gaze features every stride_ms of the recordings (and copies) whose
    recording index is in keep."""
    xs, ys = [], []
    for i, f, lab, rate in data:
        if i not in keep:
            continue
        rows = np.arange(0, len(lab), max(1, int(round(stride_ms * rate / 1000.0))))
        rows = rows[(lab[rows] > 0) & ~np.isnan(f[rows, -1])]
        xs.append(f[rows])
        ys.append(lab[rows])
    return np.concatenate(xs), np.concatenate(ys)


def write_model(clf, names, path, note):
    """The fitted trees in trackerd/classify/trees.h's format."""
    classes = [CLASS_NAMES[int(c)] for c in clf.classes_]
    baseline = np.asarray(clf._baseline_prediction).reshape(-1)
    if len(classes) == 2:
        sys.exit("train_classifier: two classes give one tree per iteration; the format needs one per class")
    lines = ["# fovea gbt model: " + note, "fovea-trees 1", f"features {len(names)} " + " ".join(names),
             f"classes {len(classes)} " + " ".join(classes), "baseline " + " ".join("%.17g" % b for b in baseline)]
    trees = [(k, p) for iteration in clf._predictors for k, p in enumerate(iteration)]
    lines.append(f"trees {len(trees)}")
    for k, p in trees:
        nodes = p.nodes
        lines.append(f"tree {k} {len(nodes)}")
        for n in nodes:
            if n["is_leaf"]:
                lines.append("-1 0 0 0 0 %.9g" % n["value"])
            else:
                lines.append("%d %.17g %d %d %d 0" % (n["feature_idx"], n["num_threshold"], n["missing_go_to_left"],
                                                     n["left"], n["right"]))
    with open(path + ".partial", "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(path + ".partial", path)


def labels(clf, f, names):
    """The classes the C++ gives (trees_core.h, TreesModel::label): the coders' noise only within
    NOISE_NEAR_LOSS_S of a loss or off the display, elsewhere the best other class."""
    p = clf.predict_proba(f)
    near = (np.minimum(f[:, names.index("loss_before_s")], f[:, names.index("loss_after_s")]).astype(np.float64)
            < NOISE_NEAR_LOSS_S) | (f[:, names.index("offscreen_deg")] > 0)
    best = p.argmax(axis=1)
    if 4 not in clf.classes_:
        return clf.classes_[best]
    noise = list(clf.classes_).index(4)
    movement = np.where(np.arange(p.shape[1]) == noise, -np.inf, p).argmax(axis=1)
    return clf.classes_[np.where((best == noise) & ~near, movement, best)]


def check_model(args, clf, path, data, files, which, names):
    """fovea-ctl with the written model must label the held-back recordings as scikit-learn does
    (the C++ adds nothing after the trees but what it does to samples without gaze)."""
    mismatched, total = 0, 0
    for i in which:
        f = next(u[1] for u in data if u[0] == i)
        geometry, t_us, x, y, conf, _, _, _ = read_arff(files[i])
        with tempfile.TemporaryDirectory() as tmp:
            got = classify(args.ctl, tmp, (t_us, x, y, conf), geometry, RATE_HZ,
                           ["--method", "gbt", "--model", path, "--trees-only"])
        gaze = ~np.isnan(f[:, -1])
        want = np.array([CLASS_NAMES[int(c)] for c in labels(clf, f[gaze], names)])
        got = np.array(got)[gaze]
        got = np.where(got == "blink", "noise", got)
        mismatched += int((want != got).sum())
        total += len(want)
    print(f"train_classifier: fovea-ctl and scikit-learn disagree on {mismatched} of {total} samples")
    if mismatched:
        sys.exit(f"train_classifier: {path} does not reproduce scikit-learn's predictions in fovea-ctl")


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("ctl", help="the fovea-ctl binary")
    ap.add_argument("--data", default=os.path.join(here, "..", "..", "shared", "data", "gazecom"))
    out = ap.add_mutually_exclusive_group(required=True)
    out.add_argument("--out", help="write one model fitted on every recording here")
    out.add_argument("--lovo", help="write DIR/<video>.trees, each fitted without that video")
    ap.add_argument("--every", type=int, default=1, help="every N-th recording (sorted by video, observer)")
    ap.add_argument("--stride-ms", type=float, default=16, help="train on a sample every this many ms")
    ap.add_argument("--augment", type=int, default=1,
                    help="copies of each recording as other trackers would record it (as_other_tracker)")
    ap.add_argument("--iterations", type=int, default=60, help="boosting iterations (trees per class)")
    ap.add_argument("--leaves", type=int, default=31, help="leaves per tree at most")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args()
    root = unpacked(args.data)
    files = sorted(os.path.join(root, v, f) for v in os.listdir(root) for f in os.listdir(os.path.join(root, v))
                   if f.endswith(".arff"))[::args.every]
    videos = [os.path.basename(os.path.dirname(p)) for p in files]
    start = time.time()
    data, names = load_all(args, files)
    print(f"train_classifier: features of {len(files)} recordings and {args.augment} copies of each "
          f"({sum(len(u[2]) for u in data)} samples, {len(names)} features) in {time.time() - start:.0f} s")
    settings = (f"iterations {args.iterations}, leaves {args.leaves}, a sample every {args.stride_ms:g} ms, "
                f"{args.augment} copies as other trackers")
    if args.out:
        x, y = training_rows(data, set(range(len(files))), args.stride_ms)
        clf = fit(x, y, args)
        write_model(clf, names, args.out, f"{len(files)} GazeCom recordings, {len(x)} samples; {settings}")
        check_model(args, clf, args.out, data, files, range(0, len(files), max(1, len(files) // 4)), names)
        print(f"train_classifier: wrote {args.out} ({len(x)} samples) in {time.time() - start:.0f} s")
        return
    os.makedirs(args.lovo, exist_ok=True)
    for v in sorted(set(videos)):
        x, y = training_rows(data, {i for i, w in enumerate(videos) if w != v}, args.stride_ms)
        clf = fit(x, y, args)
        path = os.path.join(args.lovo, v + ".trees")
        write_model(clf, names, path, f"GazeCom without {v}: {len(x)} samples; {settings}")
        held = [i for i, w in enumerate(videos) if w == v]
        check_model(args, clf, path, data, files, held[:1], names)
        print(f"train_classifier: {path} ({len(x)} samples) at {time.time() - start:.0f} s", flush=True)


if __name__ == "__main__":
    main()

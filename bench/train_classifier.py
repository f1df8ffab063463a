#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Trains the `gbt` classifier's tree models on GazeCom's expert labels (issue 43).

Features come from fovea-ctl itself (`classify --method gbt --features-out / --context-out`), so
training and the daemon see exactly the same numbers; scikit-learn's HistGradientBoostingClassifier
(Debian's python3-sklearn) fits the trees, and they are written in fovea's own text format
(trackerd/classify/trees.h and trees_core.h), which the C++ evaluates without scikit-learn. After
writing a model the script checks that fovea-ctl with it gives scikit-learn's own predictions on
held-back recordings.

Two stages (trees_core.h, GbtModel): the first over each sample's features (features.h), the second
over the first's probabilities around the sample (context.h), once with the daemon's look-ahead
(online) and once with the whole reach (offline). With --online-reach the online chain has a first
stage of its own, over features that look less far ahead (the daemon's labels are final sooner);
its second stage then learns from that first stage's probabilities. The second stage must learn from first-stage
probabilities on recordings that stage did not see (stacking), so its rows come from each video's
leave-one-video-out first stage: --lovo's DIR/<video>.frame.trees (fitted when missing, reused when
present with the same settings).

  --lovo DIR                 leave-one-video-out: DIR/<video>.trees fitted on the other 17 videos,
                             for bench/eval_classify_gazecom.py --lovo DIR
  --online-reach S           the online chain's first stage over features reaching S ahead
  --out FILE --lovo DIR      also one model on every recording (the built-in one:
                             trackerd/classify/models/gazecom.trees), written first
  --nested V1,V2 --lovo DIR  also DIR/nested/<video>.trees: that video's second stages fitted on rows
                             from first stages that never saw it (nested cross-validation; the plain
                             bundles' rows come from first stages that saw it), ~20 min a video
  --no-weights               give the chains no pursuit-onset hold (by default
                             bench/fit_class_weights.py fits it, or none, for the online and the
                             offline chain on held-out videos once the bundles are written, ~20 min;
                             the pursuit weight stays 1)

On GazeCom with the defaults and --online-reach 0.064, 2 cores (2026-12-03, the built-in model's
run): the features 1.5 min, the 36 first stages (offline and online) 40 min (once: reused), the
second stages' features 8 min, the full model 5 min, the 18 leave-one-video-out bundles 29 min; the
chains' pursuit-onset holds 20 min more. The
features are cached (XDG_CACHE_HOME/fovea/gazecom-features/KEY) and the first stages reused under
a key that hashes the features fovea-ctl computes for one recording and its copy: a build that
changed nothing in them reuses both.

GazeCom (../shared/data/gazecom, see its README): Dorr et al. 2010 (recordings), Agtzidis, Startsev
& Dorr 2016 and Startsev, Agtzidis & Dorr 2019 (labels). The copy here states no licence of its
own; a model trained on it carries the data's terms (trackerd/classify/models/README.md).

Usage: bench/train_classifier.py FOVEA_CTL [--out FILE] --lovo DIR [--data DIR_OR_TAR] [--every N]
       [--stride-ms MS] [--augment N] [--iterations N] [--leaves N] [--context-stride-ms MS]
       [--offline-context-stride-ms MS] [--context-iterations N]
       [--offline-context-iterations N] [--frame-only] [--nested VIDEOS] [--online-reach S] [--no-weights] [--jobs N]
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
import fit_class_weights  # noqa: E402
from eval_classify_gazecom import RATE_HZ, read_arff, unpacked, write_input  # noqa: E402

CLASS_NAMES = {1: "fixation", 2: "saccade", 3: "pursuit", 4: "noise"}
ONLINE_LOOKAHEAD_S = 0.032  # trees_core.h, kOnlineLookaheadS
FULL_REACH_S = 0.256  # features.h, kFeatureReachS
OFFLINE_LOOKAHEAD_S = 0.512  # context.h, kContextReachS


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


def recording(path, copy):
    """(gaze (t_us, x, y, conf), geometry, expert labels, rate) of a recording (copy 0) or of its copy
    as another tracker would have recorded it (copy >= 1, seeded by name and copy)."""
    geometry, t_us, x, y, conf, final, _, _ = read_arff(path)
    rate = RATE_HZ
    if copy:
        seed = int.from_bytes(hashlib.sha256(f"{os.path.basename(path)} {copy}".encode()).digest()[:8], "little")
        t_us, x, y, conf, final, rate = as_other_tracker(t_us, x, y, conf, final, geometry,
                                                        np.random.default_rng(seed))
    return (t_us, x, y, conf), geometry, final, rate


def matrix_out(ctl, rec, option, extra=()):
    """fovea-ctl's --features-out or --context-out matrix of a recording or copy (recording()'s
    tuple), and its names."""
    gaze, geometry, _, rate = rec
    with tempfile.TemporaryDirectory() as tmp:
        classify(ctl, tmp, gaze, geometry, rate, list(extra) + [option, os.path.join(tmp, "f.npy")])
        return np.load(os.path.join(tmp, "f.npy")), open(os.path.join(tmp, "f.npy.names")).read().split()


def reach_args(reach):
    """fovea-ctl's arguments for features reaching `reach` seconds ahead (features.h)."""
    return [] if reach >= FULL_REACH_S else ["--features-reach", "%g" % reach]


def features_of(ctl, path, copy, cache, reach):
    """(features float32 rows x F, expert labels int, rate) of a recording or copy, cached per
    features_key."""
    stem = os.path.join(cache, os.path.basename(path) + ("" if copy == 0 else ".copy%d" % copy))
    npy, lab, hz = stem + ".npy", stem + ".labels.npy", stem + ".rate"
    if not (os.path.exists(npy) and os.path.exists(lab) and os.path.exists(hz)):
        rec = recording(path, copy)
        _, _, final, rate = rec
        m, names = matrix_out(ctl, rec, "--features-out", reach_args(reach))
        np.save(lab, np.array(final, dtype=np.int8))
        with open(hz, "w") as f:
            f.write("%g" % rate)
        with open(os.path.join(cache, "names"), "w") as f:
            f.write("\n".join(names) + "\n")
        np.save(npy + ".partial.npy", m)
        os.replace(npy + ".partial.npy", npy)
    return np.load(npy), np.load(lab), float(open(hz).read())


def features_key(ctl, files, reach):
    """The cache's and the first stages' key: a hash of the features this fovea-ctl computes at this
    reach for the first recording and its first copy (another rate, noise and drop-outs), so a build
    whose features changed fits anew and one that only changed elsewhere reuses what was fitted."""
    h = hashlib.sha256()
    for copy in (0, 1):
        m, names = matrix_out(ctl, recording(files[0], copy), "--features-out", reach_args(reach))
        h.update(" ".join(names).encode())
        h.update(np.ascontiguousarray(m).tobytes())
    return h.hexdigest()[:16]


def load_all(args, files, reach):
    """Every recording (copy 0) and args.augment copies of each, with features reaching `reach`
    ahead: a list of (recording index, features, labels, rate), the feature names and the features'
    key."""
    key = features_key(args.ctl, files, reach)
    cache = os.path.join(os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache")), "fovea",
                         "gazecom-features", key)
    os.makedirs(cache, exist_ok=True)
    units = [(i, c) for c in range(args.augment + 1) for i in range(len(files))]
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        data = list(pool.map(lambda u: (u[0],) + features_of(args.ctl, files[u[0]], u[1], cache, reach), units))
    names = open(os.path.join(cache, "names")).read().split()
    return data, names, key


def fit(x, y, iterations, leaves, learning_rate):
    from sklearn.ensemble import HistGradientBoostingClassifier
    clf = HistGradientBoostingClassifier(max_iter=iterations, max_leaf_nodes=leaves, learning_rate=learning_rate,
                                         l2_regularization=1.0, early_stopping=False, random_state=0)
    clf.fit(x, y)
    return clf


def training_rows(data, names, keep, stride_ms):
    """A labelled sample with gaze every stride_ms of the recordings (and copies) whose recording
    index is in keep. offscreen_deg is NaN exactly where a sample has no gaze (other features are
    NaN too where their windows leave the gaze's run: those rows are kept)."""
    xs, ys = [], []
    gaze_column = names.index("offscreen_deg")
    for i, f, lab, rate in data:
        if i not in keep:
            continue
        rows = np.arange(0, len(lab), max(1, int(round(stride_ms * rate / 1000.0))))
        rows = rows[(lab[rows] > 0) & ~np.isnan(f[rows, gaze_column])]
        xs.append(f[rows])
        ys.append(lab[rows])
    return np.concatenate(xs), np.concatenate(ys)


def num(x):
    """A double as the shortest text that reads back as exactly it (Python's repr): the model's
    scores are then scikit-learn's bit for bit, in about half the text of %.17g."""
    return repr(float(x))


def write_model(clf, names, path, note):
    """The fitted trees in trackerd/classify/trees.h's format."""
    classes = [CLASS_NAMES[int(c)] for c in clf.classes_]
    baseline = np.asarray(clf._baseline_prediction).reshape(-1)
    if len(classes) == 2:
        sys.exit("train_classifier: two classes give one tree per iteration; the format needs one per class")
    lines = ["# fovea gbt model: " + note, "fovea-trees 1", f"features {len(names)} " + " ".join(names),
             f"classes {len(classes)} " + " ".join(classes), "baseline " + " ".join(num(b) for b in baseline)]
    trees = [(k, p) for iteration in clf._predictors for k, p in enumerate(iteration)]
    lines.append(f"trees {len(trees)}")
    for k, p in trees:
        nodes = p.nodes
        lines.append(f"tree {k} {len(nodes)}")
        for n in nodes:
            if n["is_leaf"]:
                lines.append("-1 0 0 0 0 " + num(n["value"]))
            else:
                lines.append("%d %s %d %d %d 0" % (n["feature_idx"], num(n["num_threshold"]), n["missing_go_to_left"],
                                                     n["left"], n["right"]))
    with open(path + ".partial", "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(path + ".partial", path)


def labels(clf, f):
    """The classes scikit-learn predicts. The C++ (trees_core.h, TreesModel::label) names the coders'
    noise `blink` near a loss or off the display and `unknown` elsewhere: both are noise here."""
    return clf.predict(f)


def check_model(args, clf, path, files, which, extra=(), stage1=None, reach=None):
    """fovea-ctl with the written model `path` (whose chain, online or with --offline in extra, ends
    in clf) must label the held-back recordings as scikit-learn does (the C++ adds nothing after the
    trees but what it does to samples without gaze). stage1: the model whose chain's first stage
    gives the probabilities the second-stage model clf reads (None: clf is a first stage, over
    features reaching `reach` ahead)."""
    mismatched, total = 0, 0
    offline = "--offline" in extra
    for i in which:
        rec = recording(files[i], 0)
        if stage1 is None:
            f, names = matrix_out(args.ctl, rec, "--features-out", reach_args(reach or FULL_REACH_S))
        else:
            f, names = matrix_out(args.ctl, rec, "--context-out", ["--model", stage1] + (["--offline"] if offline else []))
            if not offline:
                f = online_columns(f, names)
        gaze_t, geometry, _, rate = rec
        with tempfile.TemporaryDirectory() as tmp:
            got = classify(args.ctl, tmp, gaze_t, geometry, rate, ["--method", "gbt", "--model", path, "--trees-only"] + list(extra))
        gaze = ~np.isnan(f[:, names.index("offscreen_deg")])
        want = np.array([CLASS_NAMES[int(c)] for c in labels(clf, f[gaze])])
        got = np.array(got)[gaze]
        got = np.where((got == "blink") | (got == "unknown"), "noise", got)
        mismatched += int((want != got).sum())
        total += len(want)
    print(f"train_classifier: fovea-ctl and scikit-learn disagree on {mismatched} of {total} samples ({os.path.basename(path)} {' '.join(extra)})")
    if mismatched:
        sys.exit(f"train_classifier: {path} does not reproduce scikit-learn's predictions in fovea-ctl")


def reach_s(name):
    """How far ahead of its sample a context feature looks (context.h, context_feature_reach_s)."""
    tail = name.rsplit("_p", 1)
    if len(tail) == 2 and tail[1].endswith("ms") and tail[1][:-2].isdigit():
        return int(tail[1][:-2]) / 1000.0
    return 0.0


def online_columns(f, names, lookahead=ONLINE_LOOKAHEAD_S):
    """The context features as the daemon computes them: NaN where a feature looks further ahead."""
    f = f.copy()
    f[:, [k for k, n in enumerate(names) if reach_s(n) > lookahead + 1e-9]] = np.nan
    return f


def frame_lovo(args, data, names, files, videos, settings, start, reach=None):
    """DIR/<video>.frame.trees for every video, fitted without it (reused where present with these
    settings); with a reach, DIR/<video>.frame-online.trees over features reaching that far ahead and
    the online chain DIR/<video>.chain.trees (chain_path)."""
    os.makedirs(args.lovo, exist_ok=True)
    for v in sorted(set(videos)):
        path = os.path.join(args.lovo, v + (".frame-online.trees" if reach else ".frame.trees"))
        if os.path.exists(path) and open(path).readline().rstrip().endswith(settings):
            if reach:
                write_chain(args, v, reach)
            continue
        x, y = training_rows(data, names, {i for i, w in enumerate(videos) if w != v}, args.stride_ms)
        clf = fit(x, y, args.iterations, args.leaves, args.learning_rate)
        write_model(clf, names, path, f"GazeCom without {v}: {len(x)} samples; {settings}")
        held = [i for i, w in enumerate(videos) if w == v][:1]
        if reach:
            check_model(args, clf, write_chain(args, v, reach), files, held, reach=reach)
        else:
            check_model(args, clf, path, files, held)
        print(f"train_classifier: {path} ({len(x)} samples) at {time.time() - start:.0f} s", flush=True)


def chain_path(args, v):
    """The model whose online chain's first stage is the one fitted without video v: its bundle of
    both first stages (--online-reach) or its plain first stage."""
    chain = os.path.join(args.lovo, v + ".chain.trees")
    return chain if args.online_reach < FULL_REACH_S else os.path.join(args.lovo, v + ".frame.trees")


def write_chain(args, v, reach):
    """DIR/<v>.chain.trees: the first stages fitted without video v, the offline one and the online
    one over features reaching `reach` ahead, as one bundle."""
    path = os.path.join(args.lovo, v + ".chain.trees")
    write_bundle(path, os.path.join(args.lovo, v + ".frame.trees"), note=f"GazeCom without {v}: first stages",
                 frame_online=(os.path.join(args.lovo, v + ".frame-online.trees"), reach))
    return path


def context_unit(args, files, i, copy, model, offline):
    """One recording's (or copy's) second-stage rows, a sample every --context-stride-ms, from the
    first stage of `model`'s online or offline chain: ((recording index, features, labels), feature
    names)."""
    rec = recording(files[i], copy)
    f, names = matrix_out(args.ctl, rec, "--context-out", ["--model", model] + (["--offline"] if offline else []))
    _, _, final, rate = rec
    lab = np.array(final, dtype=np.int8)
    stride_ms = args.offline_context_stride_ms if offline else args.context_stride_ms
    rows = np.arange(0, len(lab), max(1, int(round(stride_ms * rate / 1000.0))))
    rows = rows[(lab[rows] > 0) & ~np.isnan(f[rows, names.index("offscreen_deg")])]
    return (i, f[rows], lab[rows]), names


def context_rows(args, files, videos, start, offline):
    """Every recording's (and copy's) second-stage rows from the first stage of the online or offline
    chain fitted without its video: a list of (recording index, features, labels); and the feature
    names."""
    units = [(i, c) for c in range(args.augment + 1) for i in range(len(files))]
    model = (lambda v: os.path.join(args.lovo, v + ".frame.trees")) if offline else (lambda v: chain_path(args, v))
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        out = list(pool.map(lambda u: context_unit(args, files, u[0], u[1], model(videos[u[0]]), offline), units))
    print(f"train_classifier: {'offline' if offline else 'online'} second-stage features of {len(units)} recordings "
          f"and copies at {time.time() - start:.0f} s", flush=True)
    return [o[0] for o in out], out[0][1]


def nested_lovo(args, data, names, files, videos, settings2, start):
    """--nested: for each named held-out video V, second stages fitted on rows that no first stage
    fitted with V produced (each other video U's from a first stage fitted without U and V: 17 fits),
    bundled with V's own first stage into LOVO/nested/V.trees. The plain --lovo bundles' second stages
    read rows from first stages that saw V; these show whether that leaks."""
    out_dir = os.path.join(args.lovo, "nested")
    os.makedirs(out_dir, exist_ok=True)
    for v in args.nested.split(","):
        rows, context_names = [], None
        for u in sorted(set(videos) - {v}):
            x, y = training_rows(data, names, {i for i, w in enumerate(videos) if w not in (u, v)}, args.stride_ms)
            model = os.path.join(out_dir, f"{v}.without.{u}.frame.trees")
            write_model(fit(x, y, args.iterations, args.leaves, args.learning_rate), names, model,
                        f"GazeCom without {v} and {u}")
            units = [(i, c) for c in range(args.augment + 1) for i, w in enumerate(videos) if w == u]
            with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
                got = list(pool.map(lambda t: context_unit(args, files, t[0], t[1], model, True), units))
            rows += [g[0] for g in got]
            context_names = got[0][1]
            os.remove(model)
        online, offline, n2 = fit_context(args, rows, rows, context_names, {i for i, w in enumerate(videos) if w != v})
        path = os.path.join(out_dir, v + ".trees")
        write_bundle(path, os.path.join(args.lovo, v + ".frame.trees"), context_names, online, offline,
                     f"GazeCom without {v}, nested (no first stage behind its rows saw {v}): {n2} samples; {settings2}")
        print(f"train_classifier: {path} ({n2} samples) at {time.time() - start:.0f} s", flush=True)


def fit_context(args, rows_online, rows_offline, names, keep):
    """The online and the offline second stage on the rows of the recordings in keep, each from its
    chain's first stage (the same rows where both chains share it)."""
    def xy(rows):
        return (np.concatenate([f for i, f, _ in rows if i in keep]),
                np.concatenate([lab for i, _, lab in rows if i in keep]))
    x, y = xy(rows_offline)
    offline = fit(x, y, args.offline_context_iterations, args.context_leaves, args.learning_rate)
    if rows_online is not rows_offline:
        x, y = xy(rows_online)
    online = fit(online_columns(x, names), y, args.context_iterations, args.context_leaves, args.learning_rate)
    return online, offline, len(x)


def write_bundle(path, frame_path, context_names=None, online=None, offline=None, note="", frame_online=None):
    """A fovea-gbt model (trees_core.h): the first stage's text, the online chain's own first stage
    (frame_online: (its file, its reach) or None), then the two second stages (or none)."""
    lines = ["# fovea gbt model: " + note, "fovea-gbt 1", "stage frame", open(frame_path).read().rstrip("\n")]
    if frame_online:
        lines += ["stage frame-online %g" % frame_online[1], open(frame_online[0]).read().rstrip("\n")]
    with tempfile.TemporaryDirectory() as tmp:
        for name, clf, lookahead in (("online", online, ONLINE_LOOKAHEAD_S), ("offline", offline, OFFLINE_LOOKAHEAD_S)):
            if clf is not None:
                write_model(clf, context_names, os.path.join(tmp, name), note)
                lines += ["stage %s %g" % (name, lookahead), open(os.path.join(tmp, name)).read().rstrip("\n")]
    with open(path + ".partial", "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(path + ".partial", path)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("ctl", help="the fovea-ctl binary")
    ap.add_argument("--data", default=os.path.join(here, "..", "..", "shared", "data", "gazecom"))
    ap.add_argument("--out", help="write one model fitted on every recording here")
    ap.add_argument("--lovo", required=True, help="DIR/<video>.trees, each fitted without that video")
    ap.add_argument("--every", type=int, default=1, help="every N-th recording (sorted by video, observer)")
    ap.add_argument("--stride-ms", type=float, default=16, help="train the first stage on a sample every this many ms")
    ap.add_argument("--augment", type=int, default=1,
                    help="copies of each recording as other trackers would record it (as_other_tracker)")
    # Fewer, larger trees cost less per sample for the same fit (trackerd/CLASSIFY.md, cost): on 12
    # videos, scored on the other 6, the first stage alone gives sample F1 0.931 / 0.883 / 0.534
    # (fixation / saccade / pursuit) with 60 iterations of 31 leaves at a rate of 0.1 (240 trees) and
    # 0.932 / 0.885 / 0.542 with 20 of 127 at 0.2 (80 trees).
    ap.add_argument("--iterations", type=int, default=20, help="boosting iterations (trees per class)")
    ap.add_argument("--leaves", type=int, default=127, help="leaves per tree at most")
    ap.add_argument("--learning-rate", type=float, default=0.2, help="both stages' boosting learning rate")
    ap.add_argument("--context-stride-ms", type=float, default=32,
                    help="the second stage's sample spacing (default 32; 128 before 2026-12-03)")
    ap.add_argument("--offline-context-stride-ms", type=float,
                    help="the offline chain's second stage's sample spacing (default: --context-stride-ms)")
    ap.add_argument("--context-iterations", type=int, default=10, help="the second stage's boosting iterations")
    ap.add_argument("--offline-context-iterations", type=int,
                    help="the offline chain's second stage's boosting iterations (default: --context-iterations); "
                    "the offline chain does not bind the daemon's cost per sample")
    ap.add_argument("--context-leaves", type=int, default=127, help="the second stage's leaves per tree at most")
    ap.add_argument("--frame-only", action="store_true", help="no second stage (the first stage's model alone)")
    ap.add_argument("--nested", help="comma-separated videos: also LOVO/nested/<video>.trees, second stages on "
                    "rows from first stages that never saw the video (17 first-stage fits a video)")
    ap.add_argument("--online-reach", type=float, default=FULL_REACH_S,
                    help="the online chain's own first stage, over features reaching this many seconds ahead "
                    "(features.h; shorter: the daemon's labels are final sooner); %g: the offline one" % FULL_REACH_S)
    ap.add_argument("--no-weights", action="store_true",
                    help="do not fit the chains' pursuit-onset holds (bench/fit_class_weights.py) after the bundles")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args()
    if not 0 < args.online_reach <= FULL_REACH_S:
        sys.exit(f"train_classifier: --online-reach must be in (0, {FULL_REACH_S:g}] s")
    if args.offline_context_iterations is not None and args.offline_context_iterations < 1:
        sys.exit("train_classifier: --offline-context-iterations must be at least 1")
    if args.offline_context_stride_ms is not None and not args.offline_context_stride_ms > 0:
        sys.exit("train_classifier: --offline-context-stride-ms must be a positive number of ms")
    offline_own_iterations = args.offline_context_iterations not in (None, args.context_iterations)
    offline_own_rows = args.offline_context_stride_ms not in (None, args.context_stride_ms)
    if args.offline_context_iterations is None:
        args.offline_context_iterations = args.context_iterations
    if args.offline_context_stride_ms is None:
        args.offline_context_stride_ms = args.context_stride_ms
    if args.nested and args.online_reach < FULL_REACH_S:
        sys.exit("train_classifier: --nested is for the offline chain's rows only (drop --online-reach)")
    if args.nested and args.frame_only:
        sys.exit("train_classifier: --nested needs the second stage (drop --frame-only)")
    root = unpacked(args.data)
    files = sorted(os.path.join(root, v, f) for v in os.listdir(root) for f in os.listdir(os.path.join(root, v))
                   if f.endswith(".arff"))[::args.every]
    videos = [os.path.basename(os.path.dirname(p)) for p in files]
    for v in (args.nested.split(",") if args.nested else []):  # before hours of fitting, not after
        if v not in videos:
            sys.exit(f"train_classifier: --nested: no video '{v}' (videos: {', '.join(sorted(set(videos)))})")
    start = time.time()
    data, names, key = load_all(args, files, FULL_REACH_S)
    print(f"train_classifier: features of {len(files)} recordings and {args.augment} copies of each "
          f"({sum(len(u[2]) for u in data)} samples, {len(names)} features) in {time.time() - start:.0f} s")
    # The features (their key) are part of the settings: a first stage fitted on other features is
    # not reused.
    settings = (f"iterations {args.iterations}, leaves {args.leaves}, learning rate {args.learning_rate:g}, a sample "
                f"every {args.stride_ms:g} ms, {args.augment} copies as other trackers, features {key}")
    frame_lovo(args, data, names, files, videos, settings, start)
    data_online = settings_online = None
    if args.online_reach < FULL_REACH_S:
        data_online, _, key_online = load_all(args, files, args.online_reach)
        settings_online = settings.replace(key, f"{key_online} ({args.online_reach:g} s ahead)")
        frame_lovo(args, data_online, names, files, videos, settings_online, start, args.online_reach)
    rows_online = rows_offline = context_names = settings2 = None
    if not args.frame_only:
        rows_offline, context_names = context_rows(args, files, videos, start, True)
        # The chains share their rows only where they share the first stage and the spacing.
        separate_rows = data_online is not None or offline_own_rows
        rows_online = context_rows(args, files, videos, start, False)[0] if separate_rows else rows_offline
        settings2 = (settings_online or settings) + (
            f"; second stage: iterations {args.context_iterations}"
            + (f" ({args.offline_context_iterations} offline)" if offline_own_iterations else "") + ", leaves "
            f"{args.context_leaves}, a sample every {args.context_stride_ms:g} ms"
            + (f" ({args.offline_context_stride_ms:g} offline)" if offline_own_rows else ""))
    if args.out:
        write_full_model(args, (data, data_online), names, files, settings2 or settings_online or settings,
                         (rows_online, rows_offline), context_names, start)
    if args.frame_only:
        return
    for k, v in enumerate(sorted(set(videos))):
        keep = {i for i, w in enumerate(videos) if w != v}
        online, offline, n2 = fit_context(args, rows_online, rows_offline, context_names, keep)
        path = os.path.join(args.lovo, v + ".trees")
        frame_path = os.path.join(args.lovo, v + ".frame.trees")
        frame_online = (os.path.join(args.lovo, v + ".frame-online.trees"), args.online_reach) if data_online else None
        write_bundle(path, frame_path, context_names, online, offline, f"GazeCom without {v}: {n2} samples; {settings2}",
                     frame_online)
        if k == 0:  # the same code writes every bundle: one exactness check is enough
            held = [i for i, w in enumerate(videos) if w == v][:1]
            check_model(args, online, path, files, held, (), chain_path(args, v))
            check_model(args, offline, path, files, held, ("--offline",), frame_path)
        print(f"train_classifier: {path} ({n2} samples) at {time.time() - start:.0f} s", flush=True)
    if not args.no_weights:  # on every 2nd recording (the script's own default) unless --every thinned them
        fit_class_weights.fit(args.ctl, args.lovo, files if args.every > 1 else files[::2], args.out, jobs=args.jobs,
                              weights=fit_class_weights.TRAINING_WEIGHTS, holds=fit_class_weights.TRAINING_HOLDS,
                              chains=fit_class_weights.CHAINS)
        print(f"train_classifier: pursuit weights and holds fitted at {time.time() - start:.0f} s", flush=True)
    if args.nested:
        nested_lovo(args, data, names, files, videos, settings2, start)


def write_full_model(args, data, names, files, settings, rows, context_names, start):
    """--out: the first stage (and with --online-reach the online chain's own) on every recording
    and, unless --frame-only, both second stages on every recording's out-of-fold rows (rows: the
    online and the offline chain's); checked against scikit-learn."""
    x, y = training_rows(data[0], names, set(range(len(files))), args.stride_ms)
    clf = fit(x, y, args.iterations, args.leaves, args.learning_rate)
    note = f"{len(files)} GazeCom recordings, {len(x)} samples; {settings}"
    check_at = range(0, len(files), max(1, len(files) // 4))
    frame_path, online_path, chain = args.out + ".frame", args.out + ".frame-online", args.out + ".chain"
    write_model(clf, names, frame_path, note)
    frame_online = None
    if data[1] is not None:
        xo, yo = training_rows(data[1], names, set(range(len(files))), args.stride_ms)
        clf_online = fit(xo, yo, args.iterations, args.leaves, args.learning_rate)
        write_model(clf_online, names, online_path, note)
        frame_online = (online_path, args.online_reach)
        write_bundle(chain, frame_path, note=note, frame_online=frame_online)
        check_model(args, clf_online, chain, files, check_at, reach=args.online_reach)
    if rows[0] is None and frame_online is None:
        os.replace(frame_path, args.out)
        check_model(args, clf, args.out, files, check_at)
    elif rows[0] is None:
        os.replace(chain, args.out)
        check_model(args, clf, args.out, files, check_at, ("--offline",))
    else:
        online, offline, n2 = fit_context(args, rows[0], rows[1], context_names, set(range(len(files))))
        write_bundle(args.out, frame_path, context_names, online, offline,
                     f"{len(files)} GazeCom recordings, {len(x)} samples ({n2} in the second stage); {settings}",
                     frame_online)
        check_model(args, online, args.out, files, check_at, (), chain if frame_online else frame_path)
        check_model(args, offline, args.out, files, check_at, ("--offline",), frame_path)
    for p in (frame_path, online_path, chain):
        if os.path.exists(p):
            os.remove(p)
    print(f"train_classifier: wrote {args.out} ({len(x)} samples) at {time.time() - start:.0f} s", flush=True)


if __name__ == "__main__":
    main()

# SPDX-License-Identifier: Apache-2.0
"""Agreement of eye-movement labels with a human coder's: the measures both evaluation scripts use
(bench/eval_classify_human.py on the EyeLink set, bench/eval_classify_gazecom.py on GazeCom).

Labels are sequences of class names, one per sample. Sample-level measures count samples; event-
level ones count runs of a class ("events"). Counts are returned alongside the figures so that
several recordings can be pooled (sum the counts, then compute), as Startsev et al. 2019 pool
GazeCom's recordings.
"""
import numpy as np


def method_args(spec):
    """A method as the scripts name it, METHOD[+FLAG[=V]...], as (METHOD, fovea-ctl classify arguments):
    gbt+offline+pso=none -> ("gbt", ["--offline", "--pso", "none"])."""
    method, *flags = spec.split("+")
    return method, [a for f in flags for a in ["--" + f.split("=")[0]] + f.split("=")[1:2]]


def kappa(truth, predicted, c):
    """Cohen's kappa of class c against the rest; nan when undefined."""
    t = np.asarray(truth) == c
    p = np.asarray(predicted) == c
    n = len(t)
    po = np.mean(t == p)
    pe = (t.sum() * p.sum() + (n - t.sum()) * (n - p.sum())) / (n * n)
    return float("nan") if pe >= 1.0 else float((po - pe) / (1 - pe))


def confusion(truth, predicted, c):
    """(TP, FP, FN, TN) of class c against the rest, sample by sample."""
    t = np.asarray(truth) == c
    p = np.asarray(predicted) == c
    tp = int(np.sum(t & p))
    fp = int(np.sum(~t & p))
    fn = int(np.sum(t & ~p))
    return tp, fp, fn, len(t) - tp - fp - fn


def f1_of(tp, fp, fn):
    """F1 from counts; nan when there is nothing of the class on either side."""
    return float("nan") if tp + fp + fn == 0 else 2 * tp / (2 * tp + fp + fn)


def kappa_of(tp, fp, fn, tn):
    """Cohen's kappa from a 2x2 confusion (class against the rest); nan when undefined."""
    n = tp + fp + fn + tn
    if n == 0:
        return float("nan")
    po = (tp + tn) / n
    pe = ((tp + fn) * (tp + fp) + (fp + tn) * (fn + tn)) / (n * n)
    return float("nan") if pe >= 1.0 else (po - pe) / (1 - pe)


def events_of(labels, c):
    """Runs of class c as half-open [start, end) sample intervals."""
    out, start = [], None
    for i, label in enumerate(labels):
        if label == c and start is None:
            start = i
        elif label != c and start is not None:
            out.append((start, i))
            start = None
    if start is not None:
        out.append((start, len(labels)))
    return out


def event_counts(truth, predicted, c, min_iou=0.5):
    """(hits, false positives, false negatives) of class c's events: Startsev, Agtzidis & Dorr 2019
    (Behav Res Meth 51:556-572, "Event-level evaluation"): a hit is a pair of same-class events with
    intersection over union >= min_iou, each event used once."""
    true_events, found = events_of(truth, c), events_of(predicted, c)
    hits, j = 0, 0
    used = set()
    for ts, te in true_events:
        while j < len(found) and found[j][1] <= ts:
            j += 1
        k = j
        while k < len(found) and found[k][0] < te:
            fs, fe = found[k]
            inter = min(te, fe) - max(ts, fs)
            union = max(te, fe) - min(ts, fs)
            if k not in used and inter / union >= min_iou:
                used.add(k)
                hits += 1
                break
            k += 1
    return hits, len(found) - hits, len(true_events) - hits


def event_f1(truth, predicted, c, min_iou=0.5):
    """Event-level F1 of class c (event_counts), nan when neither side has an event of it."""
    hits, fp, fn = event_counts(truth, predicted, c, min_iou)
    return f1_of(hits, fp, fn)

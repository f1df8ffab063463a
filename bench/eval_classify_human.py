#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Agreement of fovea's classifiers with a human coder, on real recordings (issue 25).

Reads the human-coded IRF lookAtPoint_EL sessions (EyeLink 1000 Plus, 1000 Hz; ../shared/data, see
its README), runs every `fovea-ctl classify` method on each session exactly as a user would (the
gaze in screen pixels, lost samples as nan), and scores the labels against the coder's:

- sample level: Cohen's kappa of each class against the rest, and the mean over fixation and
  saccade (the issue's summary figure);
- event level: F1 of each class, an algorithm event matching a coder event of the same class when
  their intersection over union is at least 0.5 (Startsev, Agtzidis & Dorr 2019, "1D CNN with
  BLSTM for automated classification of fixations, saccades, and smooth pursuits", Behav Res Meth
  51:556-572, section "Event-level evaluation"; each coder event matches at most one);
- onset latency: for each coder fixation and saccade, the algorithm's event of that class that
  overlaps it, and when the label of its first sample became final (`--final-times`: the classifier
  runs online, one sample at a time) minus the coder's onset; p50 and p99 over all sessions.
- provisional events (`--provisional`, the daemon's events before the final labels): for each coder
  saccade, the first provisional saccade start whose onset lies from 20 ms before it to its end;
  for each coder saccade followed by PSO or fixation (its landing: the saccade's end), the first
  provisional fixation start from 20 ms before to 50 ms after the landing; latency = the time of
  the sample that made the event known minus the coder's time. And how many provisional events
  the default method's final labels retracted (fovea-ctl classify reports it).

Coder classes: 1 fixation, 2 saccade, 3 PSO, 4 pursuit, 5 blink, 0 undefined (scored as "other":
a label the algorithm never gives). fovea's lost and unknown labels are "other" too.

- `--robustness`: the same sessions as other trackers would have recorded them, scored against the
  same coder: decimated to 500, 250 and 62.5 Hz (every 2nd, 4th, 16th sample and its label), and
  with white noise added (seeded, per axis): the mean kappa over fixation and saccade per method.
  A decimated EyeLink signal keeps EyeLink's filter and is no real 250 Hz tracker; it shows how the
  methods' rules hold when samples are fewer and noisier, not what another tracker's coder would say.

Usage: bench/eval_classify_human.py FOVEA_CTL [DATA_DIR] [--json OUT.json] [--robustness] [--model FILE]
(DATA_DIR defaults to ../shared/data/irf-lookAtPoint_EL beside the checkout.)
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

from classify_scoring import event_f1, events_of, kappa, method_args

CODER = {1: "fixation", 2: "saccade", 3: "pso", 4: "pursuit", 5: "blink"}
CLASSES = ("fixation", "saccade", "pso", "blink")  # the classes this data set holds
# METHOD+FLAG: fovea-ctl classify --FLAG; METHOD+FLAG=V: --FLAG V
METHODS = ("ivvt", "gbt", "gbt+offline", "gbt+pso=onset", "gbt+pso=none", "ivt", "idt", "lee2009")


def load_geometry(data_dir):
    with open(os.path.join(data_dir, "db_config.json")) as f:
        g = json.load(f)["geom"]
    return (int(g["display_width_pix"]), int(g["display_height_pix"]), g["screen_width"], g["screen_height"],
            g["eye_distance"])


def write_input(session, geometry, path):
    """The session as fovea-ctl classify's input: t_ms,x_px,y_px, nan where the tracker lost the eye."""
    w_px, h_px, w_mm, h_mm, dist_mm = geometry
    x_px = np.tan(np.radians(session["x"].astype(np.float64))) * dist_mm / w_mm * w_px + w_px / 2
    y_px = np.tan(np.radians(session["y"].astype(np.float64))) * dist_mm / h_mm * h_px + h_px / 2
    lost = ~session["status"] | ~np.isfinite(x_px) | ~np.isfinite(y_px)
    with open(path, "w") as f:
        f.write("t_ms,x_px,y_px\n")
        for t, x, y, gone in zip(session["t"] * 1000.0, x_px, y_px, lost):
            f.write("%.3f,nan,nan\n" % t if gone else "%.3f,%.3f,%.3f\n" % (t, x, y))


def coder_labels(session):
    """The coder's class of every sample, by name ("other" for undefined)."""
    return [CODER.get(int(e), "other") for e in session["evt"]]


def scored(raw):
    """fovea's labels as scored: lost and unknown are "other" (a class the coder never gives)."""
    return [l if l in CLASSES or l == "pursuit" else "other" for l in raw]


MODEL = []  # --model FILE: fovea-ctl classify's arguments for gbt's model (the built-in one without)


def classify(ctl, in_path, out_path, rate_hz, geometry, method, provisional=None):
    """Labels and final times; with `provisional` (a dict) also the provisional events, as
    (kind_phase, event time ms, row index that made it known), and the confirmed/retracted counts."""
    w_px, h_px, w_mm, h_mm, dist_mm = geometry
    method, flags = method_args(method)
    cmd = [ctl, "classify", in_path, out_path, "%g" % rate_hz, str(w_px), str(h_px), "%g" % w_mm, "%g" % h_mm,
           "%g" % dist_mm, "--method", method, "--force", "--final-times"] + flags
    if method == "gbt":
        cmd += MODEL
    if provisional is not None:
        cmd.append("--provisional")
    run = subprocess.run(cmd, check=True, capture_output=True, text=True)
    labels, final_ms, found = [], [], []
    with open(out_path) as f:
        next(f)
        for row, line in enumerate(f):
            fields = line.rstrip("\n").split(",")
            labels.append(fields[1])
            final_ms.append(float(fields[2]))
            if provisional is not None and fields[3]:
                for cell in fields[3].split(";"):
                    kind, at = cell.split("@")
                    found.append((kind, float(at), row))
    if provisional is not None:
        provisional["events"] = found
        for line in run.stderr.splitlines():
            if "provisional events" in line:
                words = line.split()
                provisional["counts"] = (int(words[2]), int(words[5]), int(words[8]))
    return labels, final_ms


def provisional_latencies(truth, t_ms, events):
    """Coder saccade onsets and landings -> the row time that made the provisional event known."""
    starts = [(at, row) for kind, at, row in events if kind == "saccade_start"]
    fixes = [(at, row) for kind, at, row in events if kind == "fixation_start"]
    out = {"saccade": [], "fixation": []}
    missed = {"saccade": 0, "fixation": 0}
    for a, b in events_of(truth, "saccade"):
        onset, end = t_ms[a], t_ms[b - 1]
        hit = next((row for at, row in starts if onset - 20 <= at <= end), None)
        if hit is None:
            missed["saccade"] += 1
        else:
            out["saccade"].append(t_ms[hit] - onset)
        if b < len(truth) and truth[b] in ("pso", "fixation"):
            landing = t_ms[b]
            hit = next((row for at, row in fixes if landing - 20 <= at <= landing + 50), None)
            if hit is None:
                missed["fixation"] += 1
            else:
                out["fixation"].append(t_ms[hit] - landing)
    return out, missed


def onset_latencies(truth, predicted, final_ms, t_ms, c):
    """Coder onset of each event of class c -> when the overlapping detected event's first label was final."""
    out, missed = [], 0
    for a, b in events_of(truth, c):
        k = next((i for i in range(a, b) if predicted[i] == c), None)
        if k is None:
            missed += 1
            continue
        while k > 0 and predicted[k - 1] == c:
            k -= 1
        out.append(final_ms[k] - t_ms[a])
    return out, missed


VARIANTS = (  # (name, decimation step, added noise deg RMS per axis)
    ("1000 Hz as recorded", 1, 0.0),
    ("500 Hz", 2, 0.0),
    ("250 Hz", 4, 0.0),
    ("62.5 Hz", 16, 0.0),
    ("1000 Hz + 0.05 deg noise", 1, 0.05),
    ("250 Hz + 0.1 deg noise", 4, 0.1),
    ("62.5 Hz + 0.3 deg noise", 16, 0.3),
)


def robustness(ctl, data, geometry, sessions):
    """Mean kappa over fixation and saccade for each method on each variant of the sessions."""
    rng = np.random.default_rng(25)
    print("\nThe same sessions decimated and with added noise (mean kappa fixation+saccade; fixation / saccade):\n")
    print("| variant | " + " | ".join(METHODS) + " |")
    print("|---|" + "---:|" * len(METHODS))
    with tempfile.TemporaryDirectory() as tmp:
        for name, step, noise in VARIANTS:
            k = {m: {"fixation": [], "saccade": []} for m in METHODS}
            for session in sessions:
                s = np.load(os.path.join(data, session))[::step].copy()
                if noise > 0:
                    for axis in ("x", "y"):
                        s[axis] = s[axis] + rng.normal(0.0, noise, len(s)).astype(s[axis].dtype)
                rate = 1.0 / float(np.median(np.diff(s["t"])))
                truth = coder_labels(s)
                in_path, out_path = os.path.join(tmp, "in.csv"), os.path.join(tmp, "out.csv")
                write_input(s, geometry, in_path)
                for m in METHODS:
                    raw, _ = classify(ctl, in_path, out_path, rate, geometry, m)
                    labels = scored(raw)
                    for c in ("fixation", "saccade"):
                        k[m][c].append(kappa(truth, labels, c))
            cells = []
            for m in METHODS:
                f, sac = float(np.nanmean(k[m]["fixation"])), float(np.nanmean(k[m]["saccade"]))
                cells.append(f"**{(f + sac) / 2:.2f}** ({f:.2f} / {sac:.2f})")
            print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


def main():
    global METHODS
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("ctl", help="the fovea-ctl binary")
    ap.add_argument("data", nargs="?", default=os.path.join(here, "..", "..", "shared", "data", "irf-lookAtPoint_EL"))
    ap.add_argument("--json", help="write the scores here")
    ap.add_argument("--robustness", action="store_true", help="also score decimated and noisier versions")
    ap.add_argument("--model", help="gbt's model: a file of bench/train_classifier.py (default: the built-in one)")
    ap.add_argument("--methods", default=",".join(METHODS),
                    help="comma-separated fovea-ctl classify methods, the first the reference of the latency "
                         "tables; METHOD+FLAG adds --FLAG, METHOD+FLAG=V --FLAG V (default: %(default)s)")
    args = ap.parse_args()
    if args.model:
        MODEL[:] = ["--model", args.model]
    METHODS = tuple(args.methods.split(","))
    geometry = load_geometry(args.data)
    sessions = sorted(f for f in os.listdir(args.data) if f.endswith(".npy"))
    if not sessions:
        sys.exit(f"no .npy sessions in {args.data}")
    scores = {m: {"kappa": {c: [] for c in CLASSES}, "f1": {c: [] for c in CLASSES},
                  "onset_ms": {"fixation": [], "saccade": []}, "missed": {"fixation": 0, "saccade": 0}} for m in METHODS}
    prov = {"onset_ms": {"fixation": [], "saccade": []}, "missed": {"fixation": 0, "saccade": 0}, "counts": [0, 0, 0]}
    with tempfile.TemporaryDirectory() as tmp:
        for name in sessions:
            s = np.load(os.path.join(args.data, name))
            rate = 1.0 / float(np.median(np.diff(s["t"])))
            truth = coder_labels(s)
            in_path, out_path = os.path.join(tmp, "in.csv"), os.path.join(tmp, "out.csv")
            write_input(s, geometry, in_path)
            t_ms = s["t"] * 1000.0
            for m in METHODS:
                p = {} if m == METHODS[0] else None
                raw, final_ms = classify(args.ctl, in_path, out_path, rate, geometry, m, p)
                if p is not None:
                    found, missed = provisional_latencies(truth, t_ms, p["events"])
                    for c in ("fixation", "saccade"):
                        prov["onset_ms"][c] += found[c]
                        prov["missed"][c] += missed[c]
                    prov["counts"] = [x + y for x, y in zip(prov["counts"], p["counts"])]
                labels = scored(raw)
                for c in CLASSES:
                    scores[m]["kappa"][c].append(kappa(truth, labels, c))
                    scores[m]["f1"][c].append(event_f1(truth, labels, c))
                for c in ("fixation", "saccade"):
                    found, missed = onset_latencies(truth, labels, final_ms, t_ms, c)
                    scores[m]["onset_ms"][c] += found
                    scores[m]["missed"][c] += missed
    mean = lambda v: float(np.nanmean(v)) if not all(math.isnan(x) for x in v) else float("nan")
    print(f"{len(sessions)} sessions of {os.path.basename(os.path.normpath(args.data))}, one human coder\n")
    print("| method | kappa fixation | kappa saccade | kappa PSO | kappa blink | **mean kappa fix+sacc** "
          "| F1 fixation | F1 saccade | F1 PSO | F1 blink |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    summary = {}
    for m in METHODS:
        k = {c: mean(scores[m]["kappa"][c]) for c in CLASSES}
        f = {c: mean(scores[m]["f1"][c]) for c in CLASSES}
        fs = (k["fixation"] + k["saccade"]) / 2
        summary[m] = {"kappa": k, "f1": f, "mean_kappa_fixation_saccade": fs,
                      "per_session": {"kappa": scores[m]["kappa"], "f1": scores[m]["f1"]}}
        print(f"| {m} | " + " | ".join(f"{k[c]:.2f}" for c in CLASSES) + f" | **{fs:.2f}** | " +
              " | ".join(f"{f[c]:.2f}" for c in CLASSES) + " |")
    print("\nOnset latency of final labels (ms from the coder's onset to the final label of the detected "
          "event's first sample; missed: coder events no detected event of the class overlaps):\n")
    print("| method | fixation onset p50 | p99 | missed | saccade onset p50 | p99 | missed |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for m in METHODS:
        row = []
        for c in ("fixation", "saccade"):
            v = np.array(scores[m]["onset_ms"][c])
            n = len(v) + scores[m]["missed"][c]
            row += ["%.0f" % np.percentile(v, 50) if len(v) else "-", "%.0f" % np.percentile(v, 99) if len(v) else "-",
                    "%d of %d" % (scores[m]["missed"][c], n)]
            summary[m]["onset_p50_ms_" + c] = float(np.percentile(v, 50)) if len(v) else None
            summary[m]["onset_p99_ms_" + c] = float(np.percentile(v, 99)) if len(v) else None
        print(f"| {m} | " + " | ".join(row) + " |")
    emitted, confirmed, retracted = prov["counts"]
    print(f"\nProvisional events (ms from the coder's saccade onset / landing to the sample that made the provisional "
          f"saccade start / fixation start known); {emitted} sent, {confirmed} confirmed and {retracted} retracted "
          f"({100.0 * retracted / max(1, emitted):.1f} %) by {METHODS[0]}'s final labels:\n")
    print("| event | p50 | p99 | missed |")
    print("|---|---:|---:|---:|")
    for c, what in (("saccade", "saccade onset"), ("fixation", "fixation onset (landing)")):
        v = np.array(prov["onset_ms"][c])
        n = len(v) + prov["missed"][c]
        print(f"| {what} | " + ("%.0f | %.0f" % (np.percentile(v, 50), np.percentile(v, 99)) if len(v) else "- | -") +
              " | %d of %d |" % (prov["missed"][c], n))
        summary.setdefault("provisional", {})[c] = {
            "p50_ms": float(np.percentile(v, 50)) if len(v) else None,
            "p99_ms": float(np.percentile(v, 99)) if len(v) else None, "missed": prov["missed"][c], "of": n}
    summary["provisional"]["sent"], summary["provisional"]["retracted"] = emitted, retracted
    if args.json:
        with open(args.json, "w") as f:
            json.dump(summary, f, indent=1)
    if args.robustness:
        robustness(args.ctl, args.data, geometry, sessions)


if __name__ == "__main__":
    main()

#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Does the focus follow an object the eye pursues? (issue 43, "the renderer follows pursuit")

On renderer/scenes/attention.json's moving objects (red_ball: left-right, ~14 deg/s on the display;
approaching_ball: 9 m -> 3 m and back), a scripted eye fixates a still object, makes a saccade onto a
moving one and pursues it, and so on. Where each object is on every frame comes from the renderer
itself (`fovea-render --headless --log-objects`, objects.csv), so the eye looks at what is drawn.

The gaze (500 Hz, 0.05 deg noise, main-sequence saccades, pursuit at a gain of 0.9 with catch-up
saccades) is labelled by `fovea-ctl classify` with
each method, and the renderer replays it (`--gaze file:`) knowing each label only once it is final
(`--final-times`: the state column of the replayed CSV is, at every sample, the newest label already
final then), as a renderer subscribed to the daemon without provisional events would; METHOD+provisional
adds the provisional saccade and fixation onsets (`--provisional`) at the sample that made each known,
as the daemon sends them live; `truth` replays the script's own labels at once (the best any
classifier could do). Each is rendered with
focus.refocus_on_pursuit on and off, focus.mode=gaze, and scored from focus.csv:

  pursued    share of the pursuit frames whose focused object is the pursued one
  delay      ms from each pursuit's start until the focus is on its object (median over pursuits)
  still      share of the fixation frames focused on the fixated object
  depth err  median |focal depth - the pursued object's depth| over the pursuit frames, m
  LOD full   share of red_ball's pursuit frames drawn at its full level, and of the frames while the
             eye fixates elsewhere (red_ball is given a chain of simplified levels, LOD_CHAIN, and
             lod.policy=gaze picks levels by eccentricity from the gaze point)

Usage: bench/bench_pursuit_focus.py FOVEA_RENDER FOVEA_CTL [--methods ivvt,gbt] [--fps 30] [--width 320]
       [--seed 1] [--keep DIR]
"""
import argparse
import csv
import json
import math
import os
import random
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "..", "renderer", "scenes", "attention.json")
RATE_HZ = 500
NOISE_DEG = 0.05
PURSUIT_GAIN = 0.9
CATCH_UP_DEG = 1.0
LOD_OBJECT, LOD_CHAIN = "red_ball", "[0.5,0.25,0.1]"
# (what the eye does, on which object, for how long in s): fixations on still objects at other
# depths than the pursued ones, so a focus left behind shows.
SCRIPT = [("fixation", "mirror_ball", 1.0), ("pursuit", "red_ball", 2.5), ("fixation", "mirror_ball", 1.0),
          ("pursuit", "approaching_ball", 3.0), ("fixation", "blob", 1.0), ("pursuit", "red_ball", 2.5),
          ("fixation", "far_sphere", 1.0)]


class Display:
    """The scene's display: normalised screen coordinates <-> degrees from its centre (x right, y
    down), as protocol/display_geometry.h."""

    def __init__(self, d):
        self.w_px, self.h_px = d["width_px"], d["height_px"]
        self.w_mm, self.h_mm, self.dist_mm = d["width_mm"], d["height_mm"], d["viewing_distance_mm"]

    def to_deg(self, x, y):
        return (math.degrees(math.atan((x - 0.5) * self.w_mm / self.dist_mm)),
                math.degrees(math.atan((y - 0.5) * self.h_mm / self.dist_mm)))

    def to_norm(self, xd, yd):
        return (math.tan(math.radians(xd)) * self.dist_mm / self.w_mm + 0.5,
                math.tan(math.radians(yd)) * self.dist_mm / self.h_mm + 0.5)


def render(ctl_render, out, fps, frames, width, extra):
    cmd = [ctl_render, "--scene", SCENE, "--headless", "--frames", str(frames), "--fps", str(fps), "--no-images",
           "--backend", "embree", "--scene-set", f"camera.width={width}",
           "--scene-set", f"camera.height={width * 9 // 16}", "--out", out] + extra
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"bench_pursuit_focus: {' '.join(cmd)} failed:\n{r.stderr[-2000:]}")


def object_tracks(path):
    """name -> {frame: (x, y, depth)} and name -> object id, from objects.csv."""
    tracks, ids = {}, {}
    with open(path) as f:
        for r in csv.DictReader(f):
            tracks.setdefault(r["name"], {})[int(r["frame"])] = (float(r["x"]), float(r["y"]),
                                                                 float(r["median_depth_m"]))
            ids[r["name"]] = int(r["object"])
    return tracks, ids


def where(track, t, fps):
    """The object's screen point at time t, between the frames around it."""
    f = t * fps
    a = int(math.floor(f))
    pa, pb = track.get(a), track.get(a + 1)
    if pa is None or pb is None:
        p = pa or pb or track[min(track, key=lambda k: abs(k - f))]
        return p[0], p[1]
    w = f - a
    return pa[0] + w * (pb[0] - pa[0]), pa[1] + w * (pb[1] - pa[1])


def saccade(t, eye, target, samples):
    """A main-sequence saccade (duration 2.2 ms/deg + 21 ms, minimum-jerk profile) from eye to target,
    appended to samples; returns the time after it."""
    amp = math.hypot(target[0] - eye[0], target[1] - eye[1])
    n = max(1, int(round((0.021 + 0.0022 * amp) * RATE_HZ)))
    for k in range(1, n + 1):
        s = k / n
        f = 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5
        samples.append((t, eye[0] + f * (target[0] - eye[0]), eye[1] + f * (target[1] - eye[1]), "saccade"))
        t += 1.0 / RATE_HZ
    return t


def gaze_script(tracks, fps, display, rng):
    """The eye's samples: (t_s, x_deg, y_deg, true label) at RATE_HZ, and the script's segments
    (kind, object, start s, end s). Saccades land where the object will be; pursuit runs at a gain
    of PURSUIT_GAIN of the object's speed, with a catch-up saccade whenever the eye falls more than
    CATCH_UP_DEG behind (de Brouwer et al. 2002), as human pursuit does."""
    samples, segments, t = [], [], 0.0
    eye = None
    for kind, name, duration in SCRIPT:
        start = t
        if eye is not None:
            t = saccade(t, eye, display.to_deg(*where(tracks[name], t + 0.05, fps)), samples)
        segments.append((kind, name, t, start + duration))
        eye = display.to_deg(*where(tracks[name], t, fps))
        dt = 1.0 / RATE_HZ
        while t < start + duration:
            obj = display.to_deg(*where(tracks[name], t, fps))
            if kind == "pursuit":
                ahead = display.to_deg(*where(tracks[name], t + dt, fps))
                eye = (eye[0] + PURSUIT_GAIN * (ahead[0] - obj[0]), eye[1] + PURSUIT_GAIN * (ahead[1] - obj[1]))
                if math.hypot(obj[0] - eye[0], obj[1] - eye[1]) > CATCH_UP_DEG:
                    t = saccade(t, eye, display.to_deg(*where(tracks[name], t + 0.03, fps)), samples)
                    eye = display.to_deg(*where(tracks[name], t, fps))
                    continue
            else:
                eye = obj
            samples.append((t, eye[0] + rng.gauss(0, NOISE_DEG), eye[1] + rng.gauss(0, NOISE_DEG), kind))
            t += dt
        eye = samples[-1][1:3]
    return samples, segments


def classify(ctl, samples, display, method, tmp):
    """fovea-ctl classify's labels, when each became final (s), and the provisional events each row
    made known: a list per row of (kind_phase, event time s)."""
    src, out = os.path.join(tmp, "trace.csv"), os.path.join(tmp, f"{method}.labels.csv")
    with open(src, "w") as f:
        f.write("t_ms,x_px,y_px\n")
        for t, xd, yd, _ in samples:
            x, y = display.to_norm(xd, yd)
            f.write("%.3f,%.3f,%.3f\n" % (t * 1000, x * display.w_px, y * display.h_px))
    subprocess.run([ctl, "classify", src, out, str(RATE_HZ), str(display.w_px), str(display.h_px), "%g" % display.w_mm,
                    "%g" % display.h_mm, "%g" % display.dist_mm, "--method", method, "--final-times", "--provisional",
                    "--force"], check=True, capture_output=True)
    labels, final, provisional = [], [], []
    with open(out) as f:
        for r in csv.DictReader(f):
            labels.append(r["label"])
            final.append(float(r["final_ms"]) / 1000.0)
            provisional.append([(e.split("@")[0], float(e.split("@")[1]) / 1000.0) for e in r["provisional"].split(";") if e])
    return labels, final, provisional


# fovea-ctl's labels as the protocol's states (PROTOCOL.md: no PSO there; the daemon sends it as fixation).
STATES = {"fixation": "fixation", "pso": "fixation", "saccade": "saccade", "pursuit": "pursuit", "blink": "blink"}


def replay_csv(path, samples, known, display):
    """A protocol CSV (fovea-ctl convert's format) of the samples with `known[i]` as their state."""
    cols = ["sequence", "tracker_time_ns", "x", "y", "x_deg", "y_deg", "angular_velocity_deg_s", "confidence", "state",
            "gaze_valid", "left_flags", "left_pupil_x_px", "left_pupil_y_px", "left_pupil_diameter_mm",
            "left_pupil_glint_x_px", "left_pupil_glint_y_px", "right_flags", "right_pupil_x_px", "right_pupil_y_px",
            "right_pupil_diameter_mm", "right_pupil_glint_x_px", "right_pupil_glint_y_px", "host_receive_ns"]
    with open(path, "w") as f:
        f.write("# fovea gaze samples v1\n# device: bench_pursuit_focus\n")
        f.write(f"# display: {display.w_px}x{display.h_px}@{display.w_mm:g}x{display.h_mm:g}mm,{display.dist_mm:g}mm\n")
        f.write(f"# sample_rate_hz: {RATE_HZ}\n" + ",".join(cols) + "\n")
        for i, ((t, xd, yd, _), state) in enumerate(zip(samples, known)):
            x, y = display.to_norm(xd, yd)
            f.write(f"{i},{int(round(t * 1e9))},{x:.6f},{y:.6f},{xd:.4f},{yd:.4f},0,1,{STATES.get(state, 'unknown')},1,"
                    "0,0,0,0,0,0,0,0,0,0,0,0,\n")


def known_at_each_sample(samples, labels, final, provisional=None):
    """At each sample's time, the newest label already final (what a renderer knows then); with the
    provisional events, where the newest of them is about a later time than that label, what it says
    (in a saccade from its start, in a fixation from its landing), as the renderer's udp input takes
    them (renderer/gaze/gaze_events.h)."""
    order = sorted(range(len(labels)), key=lambda i: final[i])
    known, newest, k, said = [], -1, 0, None
    for i, (t, *_) in enumerate(samples):
        while k < len(order) and final[order[k]] <= t + 1e-9:
            newest = max(newest, order[k])
            k += 1
        for kind, at in (provisional[i] if provisional else []):
            said = ("saccade" if kind == "saccade_start" else "fixation", at)
        state = labels[newest] if newest >= 0 else "unknown"
        if said is not None and (newest < 0 or said[1] > samples[newest][0]):
            state = said[0]
        known.append(state)
    return known


def lod_levels(lod_csv, object_id):
    """frame -> the level drawn of object_id (lod.csv's "id:level ..." cells)."""
    levels = {}
    with open(lod_csv) as f:
        for r in csv.DictReader(f):
            for cell in r["levels"].split():
                oid, level = cell.split(":")
                if int(oid) == object_id:
                    levels[int(r["frame"])] = int(level)
    return levels


def lod_full(levels, segments, fps, pursued):
    """The share of frames LOD_OBJECT is drawn at its full level (0): while pursued, and not."""
    counts = {True: [0, 0], False: [0, 0]}
    for kind, name, a, b in segments:
        on = kind == "pursuit" and name == LOD_OBJECT
        if on != pursued:
            continue
        for i in range(int(math.ceil(a * fps)), int(b * fps)):
            if i in levels:
                counts[on][0] += levels[i] == 0
                counts[on][1] += 1
    n, d = counts[pursued]
    return n / max(1, d)


def score(focus_csv, tracks, ids, segments, fps):
    """The figures of one run (the module's docstring) from its focus.csv and lod.csv."""
    with open(focus_csv) as f:
        rows = {int(r["frame"]): r for r in csv.DictReader(f)}
    pursued = [0, 0]
    still = [0, 0]
    delays, depth_err = [], []
    for kind, name, a, b in segments:
        frames = [i for i in range(int(math.ceil(a * fps)), int(b * fps)) if i in rows]
        on = [int(rows[i]["object"]) == ids[name] for i in frames]
        if kind == "pursuit":
            pursued[0] += sum(on)
            pursued[1] += len(on)
            first = next((i for i, o in zip(frames, on) if o), None)
            delays.append((first / fps - a) * 1000 if first is not None else (b - a) * 1000)
            depth_err += [abs(float(rows[i]["focal_depth_m"]) - tracks[name][i][2]) for i in frames if i in tracks[name]]
        else:
            still[0] += sum(on)
            still[1] += len(on)
    levels = lod_levels(os.path.join(os.path.dirname(focus_csv), "lod.csv"), ids[LOD_OBJECT])
    return {"pursued": pursued[0] / max(1, pursued[1]), "delay_ms": statistics.median(delays),
            "still": still[0] / max(1, still[1]), "depth_err_m": statistics.median(depth_err) if depth_err else float("nan"),
            "lod_pursued": lod_full(levels, segments, fps, True), "lod_else": lod_full(levels, segments, fps, False)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("render", help="the fovea-render binary")
    ap.add_argument("ctl", help="the fovea-ctl binary")
    ap.add_argument("--methods", default="ivvt,gbt")
    ap.add_argument("--fps", type=int, default=30)
    ap.add_argument("--width", type=int, default=320, help="render width (height: 9/16 of it)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--keep", help="keep the runs' files here")
    args = ap.parse_args()
    scene = json.load(open(SCENE))
    display = Display(scene["display"])
    lod_index = [o["name"] for o in scene["objects"]].index(LOD_OBJECT)
    duration = sum(d for _, _, d in SCRIPT) + 1
    frames = int(duration * args.fps)
    tmp_obj = tempfile.TemporaryDirectory()
    tmp = args.keep or tmp_obj.name
    os.makedirs(tmp, exist_ok=True)
    truth_dir = os.path.join(tmp, "objects")
    render(args.render, truth_dir, args.fps, frames, args.width, ["--gaze", "none", "--log-objects"])
    tracks, ids = object_tracks(os.path.join(truth_dir, "objects.csv"))
    samples, segments = gaze_script(tracks, args.fps, display, random.Random(args.seed))
    runs = [("truth", [s[3] for s in samples])]
    for m in [m for m in args.methods.split(",") if m]:
        labels, final, provisional = classify(args.ctl, samples, display, m, tmp)
        runs.append((m, known_at_each_sample(samples, labels, final)))
        runs.append((m + "+provisional", known_at_each_sample(samples, labels, final, provisional)))
    print(f"{len(samples)} gaze samples at {RATE_HZ} Hz over {samples[-1][0]:.1f} s; {frames} frames at {args.fps} fps "
          f"of attention.json at {args.width} px; focus.mode=gaze\n")
    print("| labels | refocus_on_pursuit | pursued | delay ms | still | depth err m | LOD full: pursued / not |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for name, known in runs:
        rec = os.path.join(tmp, f"{name}.replay.csv")
        replay_csv(rec, samples, known, display)
        for on in ("true", "false"):
            out = os.path.join(tmp, f"{name}-{on}")
            render(args.render, out, args.fps, frames, args.width,
                   ["--gaze", "file:" + rec, "--set", "focus.mode=gaze", "--set", "overlay.focus=true",
                    "--set", f"focus.refocus_on_pursuit={on}", "--set", "lod.policy=gaze",
                    "--scene-set", f"objects.{lod_index}.lod.simplify={LOD_CHAIN}"])
            s = score(os.path.join(out, "focus.csv"), tracks, ids, segments, args.fps)
            print(f"| {name} | {on} | {s['pursued']:.2f} | {s['delay_ms']:.0f} | {s['still']:.2f} | {s['depth_err_m']:.2f} "
                  f"| {s['lod_pursued']:.2f} / {s['lod_else']:.2f} |", flush=True)


if __name__ == "__main__":
    main()

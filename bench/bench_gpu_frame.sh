#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The frame kept on the GPU against the readback path, side by side in one run: fovea-render headless
# with the OpenGL backend through EGL (no X), each configuration rendered by both paths one after the
# other (frame.gpu=false: the G-buffer read back and every pass on the CPU; frame.gpu=true: G-buffer,
# tone map and overlay on the GPU, only the planes the CPU passes read come back). No frame images
# are written (--no-images), so the display image never leaves the GPU, as on a screen.
#
# Reports per configuration, from each run's timings.csv (first WARMUP frames dropped: shader
# compilation, first-touch allocations): the whole frame's p50/p99 in ms, the gaze age at completion
# p50/p99 (the overlay's gaze sample's age when the GPU's fence signalled, or the CPU image was done),
# and readback/gpu, the ratio of the frame p50s. A "+fragment" / "+compute" suffix forces the effect
# passes' implementation (frame.effect_passes), "+forward" the forward G-buffer and depth peel
# (frame.gbuffer_pass=forward: the baseline of the visibility buffer's), "+stereo" both eyes. PATHS="true" runs the GPU path alone (the readback
# columns then read "-"): what a device sweep with little time takes.
#
# Effects: "base" = G-buffer, tone map, gaze overlay only (dof, LOD and so attention and focus off);
# "scene" = the scene's own effects (attention.json: attention, focus, LOD selection and DOF on the
# CPU from a readback of colour, depth and ids); "base-allplanes" = base with every G-buffer plane
# written on the GPU path too (debug.gbuffer_planes=all: what culling the unread planes saves);
# "base-forward" / "base-visibility" = base with the G-buffer shaded in the raster pass / by the
# visibility buffer's compute pass (frame.gbuffer_pass); "base-noprepass" = base-forward shading
# every surface drawn (frame.depth_prepass=false: what the depth pre-pass saves);
# "gi" = base with the hybrid renderer (20k photons traced by Embree on the CPU, the inset
# composited on the GPU; gi.device=auto: gathered on a GPU, on the CPU under llvmpipe); "gi-gpu" /
# "gi-cpu" = the same radius gather forced onto the GPU / the CPU (gi.device, gi.estimate=radius);
# "gi-nearest" = the CPU's k-nearest estimate (Table 8.3's nNN = 240: the thesis's); "dof" = base with the scene's lens and lee-mipmap focused at the lens's own
# distance (focus.mode=fixed: the DOF alone; on the GPU path it runs on the GPU, nothing is read
# back); "dof-cpu" = dof with dof.device=cpu (the GPU path reads colour and depth back for the CPU's
# lee-mipmap and uploads its colour: what running it on the GPU saves). The scene's own effects
# ("scene") run lee-mipmap on the GPU path's GPU too. "dof-fN" = dof with the lens at f-number N
# (attention.json: 2.8; 0.7 blurs 4x as much, 11.2 a quarter as much): the DOF's cost against its CoC.
# "dof-schedl" = dof with schedl-layered, M = 3 (its two layers peeled on the GPU path's GPU);
# "dof-splat" = dof with lee-splat (its hidden image peeled there).
# "attention" = base with the attention pass, focus.mode=attention and its outline (overlay.focus),
# attention.device=gpu (on the GPU path attention's pixel stage runs on the GPU and the focus pass
# reads only the pixels it looks at: nothing is read back whole); "attention-cpu" = the same with
# attention.device=cpu (colour, depth and ids read back for the CPU's attention). "ulod" = the
# scene's effects with lod.policy=ulod (its blend of levels on the GPU path's GPU, gpu.ulod; the
# next levels' render before it, gpu.ulod_render).
# Any of these with "+fragment" or "+compute" appended sets frame.effect_passes (the tone map,
# lee-mipmap and ULOD's blend as fragment or compute passes; without: auto, compute on a GPU).
# "+stereo" (last) renders both eyes (--stereo), each at the size given: the frame is then both
# eyes' renders (frame + right.frame) and the gaze age the older eye's.
#
# Usage: bench/bench_gpu_frame.sh [RENDER] [FRAMES] [SIZES] [SCENES] [EFFECTS]
#   RENDER   fovea-render binary (default build/default/renderer/fovea-render)
#   FRAMES   frames per run (default 30; WARMUP=3 of them dropped)
#   SIZES    default "640x480 1280x720 1920x1080"
#   SCENES   default "attention cornell" (renderer/scenes/NAME.json)
#   EFFECTS  default "base scene"
# OUT=DIR keeps the runs' folders (default: a temporary folder, removed). EMBREE=1 also renders each
# configuration with the Embree backend (no GPU: the frame on the CPU alone) in a second table.
set -euo pipefail
cd "$(dirname "$0")/.."
RENDER=${1:-build/default/renderer/fovea-render}
FRAMES=${2:-30}
SIZES=${3:-640x480 1280x720 1920x1080}
SCENES=${4:-attention cornell}
EFFECTS=${5:-base scene}
WARMUP=${WARMUP:-3}
PATHS=${PATHS:-false true}
EMBREE=${EMBREE:-0}
GAZE=file:tests/data/recordings/synthetic-250hz-62s.fgr
if [ -n "${OUT:-}" ]; then RUNS=$OUT/runs; mkdir -p "$RUNS"; else RUNS=$(mktemp -d); trap 'rm -rf "$RUNS"' EXIT; fi
[ -x "$RENDER" ] || { echo "bench_gpu_frame: $RENDER is not an executable (build first)" >&2; exit 2; }

echo "# bench/bench_gpu_frame.sh $RENDER $FRAMES \"$SIZES\" \"$SCENES\" \"$EFFECTS\"  ($(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores)"
for scene in $SCENES; do
  for size in $SIZES; do
    w=${size%x*} h=${size#*x}
    for effects in $EFFECTS; do
      extra=()
      what=${effects%+stereo}
      [ "$what" != "$effects" ] && extra=(--stereo)
      case $what in
        *+fragment) extra+=(--set frame.effect_passes=fragment) ;;
        *+compute) extra+=(--set frame.effect_passes=compute) ;;
        *+forward) extra+=(--set frame.gbuffer_pass=forward) ;;
      esac
      what=${what%+fragment}
      what=${what%+compute}
      what=${what%+forward}
      case $what in
        base) extra+=(--set dof.enabled=false --set lod.enabled=false --set gi.enabled=false) ;;
        base-allplanes) extra+=(--set dof.enabled=false --set lod.enabled=false --set gi.enabled=false
                               --set debug.gbuffer_planes=all) ;;
        base-noprepass) extra+=(--set dof.enabled=false --set lod.enabled=false --set gi.enabled=false
                               --set frame.gbuffer_pass=forward --set frame.depth_prepass=false) ;;
        base-forward) extra+=(--set dof.enabled=false --set lod.enabled=false --set gi.enabled=false
                             --set frame.gbuffer_pass=forward) ;;
        base-visibility) extra+=(--set dof.enabled=false --set lod.enabled=false --set gi.enabled=false
                                --set frame.gbuffer_pass=visibility) ;;
        dof) extra+=(--set lod.enabled=false --set gi.enabled=false --set focus.mode=fixed) ;;
        dof-f*) extra+=(--set lod.enabled=false --set gi.enabled=false --set focus.mode=fixed
                       --scene-set camera.lens.f_number="${what#dof-f}") ;;
        dof-cpu) extra+=(--set lod.enabled=false --set gi.enabled=false --set focus.mode=fixed --set dof.device=cpu) ;;
        dof-schedl) extra+=(--set lod.enabled=false --set gi.enabled=false --set focus.mode=fixed
                           --set dof.method=schedl-layered) ;;
        dof-splat) extra+=(--set lod.enabled=false --set gi.enabled=false --set focus.mode=fixed
                          --set dof.method=lee-splat) ;;
        attention) extra+=(--set dof.enabled=false --set lod.enabled=false --set gi.enabled=false
                          --set focus.mode=attention --set overlay.focus=true --set attention.device=gpu) ;;
        attention-cpu) extra+=(--set dof.enabled=false --set lod.enabled=false --set gi.enabled=false
                              --set focus.mode=attention --set overlay.focus=true --set attention.device=cpu) ;;
        ulod) extra+=(--set gi.enabled=false --set lod.policy=ulod) ;;
        gi*) extra+=(--set dof.enabled=false --set lod.enabled=false --set gi.enabled=true --set gi.photons=20000
                    --set gi.caustic_photons=0)
             case $what in
               gi-gpu) extra+=(--set gi.device=gpu) ;;
               gi-cpu) extra+=(--set gi.device=cpu --set gi.estimate=radius) ;;
               gi-nearest) extra+=(--set gi.device=cpu --set gi.estimate=nearest) ;;
             esac ;;
      esac
      for gpu in $PATHS; do
        dir=$RUNS/$scene-$size-$effects-$([ $gpu = true ] && echo gpu || echo readback)
        env -u DISPLAY "$RENDER" --scene "renderer/scenes/$scene.json" --backend gl --headless --no-images \
          --frames "$FRAMES" --gaze "$GAZE" --scene-set camera.width="$w" --scene-set camera.height="$h" \
          --set frame.gpu=$gpu "${extra[@]}" --out "$dir" >/dev/null 2>"$dir.log" ||
          { echo "bench_gpu_frame: $dir failed:" >&2; cat "$dir.log" >&2; exit 1; }
      done
      if [ "$EMBREE" = 1 ]; then  # the ray-tracing backend, the same frame on the CPU alone
        dir=$RUNS/$scene-$size-$effects-embree
        "$RENDER" --scene "renderer/scenes/$scene.json" --backend embree --headless --no-images \
          --frames "$FRAMES" --gaze "$GAZE" --scene-set camera.width="$w" --scene-set camera.height="$h" \
          "${extra[@]}" --out "$dir" >/dev/null 2>"$dir.log" ||
          { echo "bench_gpu_frame: $dir failed:" >&2; cat "$dir.log" >&2; exit 1; }
      fi
    done
  done
done

python3 - "$RUNS" "$WARMUP" <<'PY'
import csv, glob, os, re, statistics, sys
runs, warmup = sys.argv[1], int(sys.argv[2])

def pct(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, max(0, round(q / 100 * (len(v) - 1))))]

def load(path):
    by, frames = {}, {}
    for r in csv.DictReader(open(os.path.join(path, "timings.csv"))):
        if int(r["frame"]) >= warmup:
            by.setdefault(r["pass"], []).append(float(r["ms"]))
            frames.setdefault(int(r["frame"]), {})[r["pass"]] = float(r["ms"])
    if "right.frame" in by:  # stereo: the frame is both eyes' renders, its gaze age the older eye's
        by["frame"] = [f["frame"] + f["right.frame"] for f in frames.values() if "right.frame" in f]
        by["gaze-age"] = [max(f["gaze-age"], f["right.gaze-age"]) for f in frames.values() if "right.gaze-age" in f]
    return by

renderer = ""
for d in sorted(glob.glob(os.path.join(runs, "*-gpu"))):
    for line in open(os.path.join(d, "plan.txt")):
        if "where gpu" in line:
            renderer = line.split("gpu", 1)[1].split(":")[0].strip()
print(f"device: {renderer or 'no GPU path ran'}")
print()
print("| scene | size | effects | readback frame p50/p99 ms | gpu frame p50/p99 ms | readback/gpu | "
      "gaze age readback p50/p99 ms | gaze age gpu p50/p99 ms | gpu-side ms per pass (p50) |")
print("|---|---|---|---|---|---|---|---|---|")
def p50_p99(v):
    return f"{pct(v, 50):.2f} / {pct(v, 99):.2f}" if v else "-"

for d in sorted(glob.glob(os.path.join(runs, "*-gpu"))):
    if not os.path.isdir(d):
        continue
    name = os.path.basename(d)[: -len("-gpu")]
    scene, size, effects = re.match(r"(.+)-(\d+x\d+)-([\w.+-]+)$", name).groups()
    readback = os.path.join(runs, name + "-readback")
    a, b = (load(readback) if os.path.isdir(readback) else {}), load(d)
    fa, fb = a.get("frame", []), b["frame"]
    ga, gb = a.get("gaze-age", []), b["gaze-age"]
    gpu_side = ", ".join(f'{p[4:]} {statistics.median(b[p]):.2f}' for p in ("gpu.gbuffer", "gpu.attention", "gpu.ulod_render", "gpu.ulod", "gpu.peel", "gpu.dof", "gpu.gi", "gpu.tonemap", "gpu.overlay") if p in b)
    ratio = f"{pct(fa, 50) / pct(fb, 50):.2f}" if fa else "-"
    print(f"| {scene} | {size} | {effects} | {p50_p99(fa)} | {p50_p99(fb)} | "
          f"{ratio} | {p50_p99(ga)} | {p50_p99(gb)} | {gpu_side} |")
gi_runs = [d for d in sorted(glob.glob(os.path.join(runs, "*-gi*-gpu"))) if os.path.isdir(d)]
if gi_runs:
    # The GI pass's own stages on the GPU path, CPU ms p50: photons traced (or waited for, with
    # gi.overlap), kd-trees, the area's ids read back, the CPU's pixels, the gather handed over; and
    # the GPU's gather.
    stages = ("gi.photons", "gi.photons_overlapped", "gi.index", "gi.ids", "gi.render", "gi.gather", "gi", "gpu.gi", "gpu.upload")
    print()
    print("| run | " + " | ".join(stages) + " |")
    print("|---|" + "---|" * len(stages))
    for d in gi_runs:
        b = load(d)
        cells = [f"{statistics.median(b[p]):.2f}" if p in b else "-" for p in stages]
        print(f"| {os.path.basename(d)[: -len('-gpu')]} | " + " | ".join(cells) + " |")
stereo = [d for d in sorted(glob.glob(os.path.join(runs, "*+stereo-*"))) if os.path.isdir(d)]
if stereo:
    # Each eye's own render in one process, frame after frame: what the right eye saves by reusing
    # the left eye's attention, focus and photon maps (the passes it skipped, timed in the left eye).
    print()
    print("| run | left eye p50 ms | right eye p50 ms | right/left | done once, left eye p50 ms |")
    print("|---|---|---|---|---|")
    for d in stereo:
        e = {}
        for r in csv.DictReader(open(os.path.join(d, "timings.csv"))):
            if int(r["frame"]) >= warmup:
                e.setdefault(r["pass"], []).append(float(r["ms"]))
        once = ", ".join(f"{p} {statistics.median(e[p]):.2f}" for p in ("attention", "focus", "lod-select", "gi.photons", "gi.index")
                         if p in e and "right." + p not in e)
        left, right = statistics.median(e["frame"]), statistics.median(e["right.frame"])
        print(f"| {os.path.basename(d)} | {left:.2f} | {right:.2f} | {right / left:.2f} | {once or 'nothing'} |")
embree = sorted(glob.glob(os.path.join(runs, "*-embree")))
if embree:
    print()
    print("| scene | size | effects | embree frame p50/p99 ms | gaze age embree p50/p99 ms |")
    print("|---|---|---|---|---|")
    for d in embree:
        scene, size, effects = re.match(r"(.+)-(\d+x\d+)-([\w.+-]+)$", os.path.basename(d)[: -len("-embree")]).groups()
        e = load(d)
        print(f"| {scene} | {size} | {effects} | {pct(e['frame'], 50):.2f} / {pct(e['frame'], 99):.2f} | "
              f"{pct(e['gaze-age'], 50):.2f} / {pct(e['gaze-age'], 99):.2f} |")
PY

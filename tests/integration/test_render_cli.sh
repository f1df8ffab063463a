#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Whole-process test of fovea-render as a user runs it: explain, headless frames with each backend,
# deterministic replays, clear errors, the viewer under Xvfb, and two render clients on one daemon.
set -u
RENDER=$1 TRACKERD=$2 CTL=$3 SOURCE_DIR=$4
SCENES=$SOURCE_DIR/renderer/scenes
REC=$SOURCE_DIR/tests/data/recordings/synthetic-250hz-62s.fgr
WORK=$(mktemp -d)
PIDS=()
cleanup() { for p in "${PIDS[@]}"; do kill -9 "$p" 2>/dev/null; done; rm -rf "$WORK"; }
trap cleanup EXIT
fail() { echo "FAIL: $*"; exit 1; }
# Under ASan, LeakSanitizer's exit-time scan of a process with Mesa llvmpipe's worker threads can
# itself crash ("Tracer caught signal 11"), failing a run that did its work. GL processes here run
# without leak detection; test_gl_backend keeps it on for the GL code itself.
XVFB=(env "ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0" "$SOURCE_DIR/deploy/with-xvfb.sh")
# Headless OpenGL needs no X server (EGL): those runs go with DISPLAY unset; only the viewer gets Xvfb.
HEADLESS_GL=(env -u DISPLAY "ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0")
SMALL=(--scene-set camera.width=160 --scene-set camera.height=120)

echo "== --explain on every bundled scene"
for s in "$SCENES"/*.json; do
  out=$("$RENDER" --scene "$s" --explain --gaze none 2>&1) || fail "explain $s: $out"
  grep -qE "run +gbuffer" <<<"$out" || fail "plan of $s lacks the gbuffer pass: $out"
done
out=$("$RENDER" --scene "$SCENES/cornell.json" --explain --gaze none)
grep -qE "skip +dof .*pinhole" <<<"$out" || fail "cornell (pinhole) should skip dof: $out"

echo "== clear errors"
out=$("$RENDER" --scene /nonexistent.json --explain 2>&1) && fail "missing scene accepted"
grep -q "/nonexistent.json" <<<"$out" || fail "missing scene message: $out"
out=$("$RENDER" --scene "$SCENES/cornell.json" --set gi.enable=true --explain 2>&1) && fail "bad setting accepted"
grep -q 'unknown setting "gi.enable"' <<<"$out" || fail "bad setting message: $out"
out=$("$RENDER" --scene "$SCENES/cornell.json" --gaze bogus --explain 2>&1) && fail "bad gaze accepted"
grep -q 'expected udp://' <<<"$out" || fail "bad gaze message: $out"
mkdir -p "$WORK/full" && touch "$WORK/full/keep.png"
out=$("$RENDER" --scene "$SCENES/cornell.json" --headless --frames 1 --out "$WORK/full" --gaze none 2>&1) \
  && fail "non-empty output directory accepted"
grep -q "not empty" <<<"$out" || fail "non-empty dir message: $out"
[ -f "$WORK/full/keep.png" ] || fail "existing file was removed"

echo "== headless embree, gaze from a recording on the frame clock, twice: identical frames"
for run in a b; do
  "$RENDER" --scene "$SCENES/attention.json" "${SMALL[@]}" --headless --frames 4 --fps 10 --exr \
    --gaze "file:$REC" --out "$WORK/embree-$run" >/dev/null 2>"$WORK/embree-$run.err" \
    || fail "headless embree: $(cat "$WORK/embree-$run.err")"
done
[ "$(ls "$WORK/embree-a"/frame-*.png | wc -l)" -eq 4 ] || fail "expected 4 PNG frames"
[ "$(ls "$WORK/embree-a"/frame-*.exr | wc -l)" -eq 4 ] || fail "expected 4 EXR frames"
for f in "$WORK/embree-a"/frame-*.png; do
  cmp -s "$f" "$WORK/embree-b/$(basename "$f")" || fail "frame $(basename "$f") differs between identical runs"
done
head -1 "$WORK/embree-a/timings.csv" | grep -q "^frame,scene_time_s,pass,ms$" || fail "timings.csv header"
for pass in gbuffer tonemap overlay write frame; do
  [ "$(grep -c ",$pass," "$WORK/embree-a/timings.csv")" -eq 4 ] || fail "timings.csv lacks 4 rows of $pass"
done
grep -qE "run +gbuffer" "$WORK/embree-a/plan.txt" || fail "plan.txt"

echo "== headless gl through EGL, DISPLAY unset"
"${HEADLESS_GL[@]}" "$RENDER" --scene "$SCENES/cornell.json" "${SMALL[@]}" --backend gl --headless --frames 3 --gaze none \
  --out "$WORK/gl" >/dev/null 2>"$WORK/gl.err" || fail "headless gl: $(cat "$WORK/gl.err")"
[ "$(ls "$WORK/gl"/frame-*.png | wc -l)" -eq 3 ] || fail "expected 3 GL frames"
echo "== the visibility buffer asked of a context without compute shaders: forward, one log line, the plan says why"
"${HEADLESS_GL[@]}" env MESA_GL_VERSION_OVERRIDE=3.3 "$RENDER" --scene "$SCENES/cornell.json" "${SMALL[@]}" --backend gl \
  --headless --frames 3 --gaze none --set frame.gbuffer_pass=visibility --out "$WORK/gl33" >/dev/null 2>"$WORK/gl33.err" \
  || fail "gl 3.3: $(cat "$WORK/gl33.err")"
[ "$(grep -c 'visibility buffer off (no compute shaders (OpenGL 3.3' "$WORK/gl33.err")" -eq 1 ] \
  || fail "expected one line saying why the visibility buffer is off: $(cat "$WORK/gl33.err")"
grep -q "forward raster shading: no compute shaders" "$WORK/gl33/plan.txt" || fail "gl 3.3 plan: $(cat "$WORK/gl33/plan.txt")"
[ "$(ls "$WORK/gl33"/frame-*.png | wc -l)" -eq 3 ] || fail "expected 3 GL 3.3 frames"
out=$(env -u DISPLAY "$RENDER" --scene "$SCENES/cornell.json" "${SMALL[@]}" --backend gl --frames 1 --gaze none 2>&1) \
  && fail "the viewer without a display succeeded"
grep -q "no X display" <<<"$out" || fail "the viewer's no-display message: $out"

echo "== viewer under Xvfb, mouse gaze, 5 frames"
"${XVFB[@]}" "$RENDER" --scene "$SCENES/cornell.json" "${SMALL[@]}" --backend gl --gaze mouse --frames 5 \
  >"$WORK/viewer.out" 2>&1 || fail "viewer: $(cat "$WORK/viewer.out")"
grep -q "^frame " "$WORK/viewer.out" || fail "viewer printed no timing summary"
for backend in gl embree; do  # stereo: both eyes side by side in the window, from the GPU or uploaded
  "${XVFB[@]}" "$RENDER" --scene "$SCENES/attention.json" "${SMALL[@]}" --backend $backend --gaze mouse --stereo \
    --frames 4 >"$WORK/viewer-stereo.out" 2>&1 || fail "stereo viewer ($backend): $(cat "$WORK/viewer-stereo.out")"
  grep -q "^right.frame " "$WORK/viewer-stereo.out" || fail "stereo viewer ($backend) drew no right eye"
  grep -q "^stereo  *two views of 160x120" "$WORK/viewer-stereo.out" || fail "stereo viewer ($backend) plan"
done

echo "== the focus follows the recorded gaze (focus.csv), and only runs when something shows it"
"$RENDER" --scene "$SCENES/attention.json" "${SMALL[@]}" --headless --frames 12 --fps 10 --gaze "file:$REC" \
  --set overlay.focus=true --out "$WORK/focus" >"$WORK/focus.log" 2>&1 || fail "focus run: $(tail -5 "$WORK/focus.log")"
head -1 "$WORK/focus/focus.csv" | grep -qx "frame,focal_depth_m,target_depth_m,object,in_transition,why" \
  || fail "focus.csv header: $(head -1 "$WORK/focus/focus.csv")"
[ "$(wc -l <"$WORK/focus/focus.csv")" -eq 13 ] || fail "focus.csv rows: $(cat "$WORK/focus/focus.csv")"
grep -q "gaze+attention: " "$WORK/focus/focus.csv" || fail "focus.csv why: $(cat "$WORK/focus/focus.csv")"
grep -q "run   attention" "$WORK/focus/plan.txt" || fail "attention did not run for the focus: $(cat "$WORK/focus/plan.txt")"
[ -e "$WORK/full/focus.csv" ] && fail "focus ran although nothing consumes it"

echo "== --log-objects: where each object shows each frame (objects.csv), the moving ones moving"
"$RENDER" --scene "$SCENES/attention.json" "${SMALL[@]}" --headless --frames 10 --fps 5 --gaze none --no-images \
  --log-objects --out "$WORK/objects" >"$WORK/objects.log" 2>&1 || fail "objects run: $(tail -5 "$WORK/objects.log")"
head -1 "$WORK/objects/objects.csv" | grep -qx "frame,object,name,pixels,x,y,median_depth_m" \
  || fail "objects.csv header: $(head -1 "$WORK/objects/objects.csv")"
/usr/bin/python3 - "$WORK/objects/objects.csv" <<'PY' || fail "objects.csv: $(head -20 "$WORK/objects/objects.csv")"
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
track = lambda name, key: [float(r[key]) for r in rows if r["name"] == name]
assert len({r["frame"] for r in rows}) == 10, "a row set per frame"
assert max(track("red_ball", "x")) - min(track("red_ball", "x")) > 0.1, "red_ball moves left-right"
assert max(track("approaching_ball", "median_depth_m")) - min(track("approaching_ball", "median_depth_m")) > 2, "approaching_ball comes closer"
assert max(track("blob", "x")) - min(track("blob", "x")) < 1e-3, "blob stays"
assert all(0 <= float(r["x"]) <= 1 and 0 <= float(r["y"]) <= 1 and int(r["pixels"]) > 0 for r in rows)
PY

echo "== depth of field: every method headless, the CoC overlay, the raster backend's reference"
# f/0.5: CoCs of several pixels even at 160x120.
DOF=(--scene "$SCENES/attention.json" "${SMALL[@]}" --scene-set camera.lens.f_number=0.5 --headless --frames 2 --fps 10
     --gaze none --set focus.mode=fixed)
"$RENDER" "${DOF[@]}" --set dof.enabled=false --out "$WORK/dof-off" >/dev/null 2>&1 || fail "dof off run"
grep -qE "skip +dof +dof.enabled=false" "$WORK/dof-off/plan.txt" || fail "dof off plan: $(cat "$WORK/dof-off/plan.txt")"
for m in lee-mipmap lee-splat schedl-layered accum reference; do
  "$RENDER" "${DOF[@]}" --set dof.method=$m --set dof.samples=4 --out "$WORK/dof-$m" >"$WORK/dof-$m.log" 2>&1 \
    || fail "dof.method=$m: $(tail -5 "$WORK/dof-$m.log")"
  grep -qE "run +dof .*method $m" "$WORK/dof-$m/plan.txt" || fail "$m plan: $(cat "$WORK/dof-$m/plan.txt")"
  [ "$(grep -c ",dof," "$WORK/dof-$m/timings.csv")" -eq 2 ] || fail "$m: timings.csv lacks 2 dof rows"
  cmp -s "$WORK/dof-$m/frame-000001.png" "$WORK/dof-off/frame-000001.png" && fail "$m left the frame unblurred"
done
"$RENDER" "${DOF[@]}" --set overlay.map=coc --out "$WORK/dof-coc" >/dev/null 2>&1 || fail "coc overlay run"
cmp -s "$WORK/dof-coc/frame-000001.png" "$WORK/dof-lee-mipmap/frame-000001.png" && fail "the CoC overlay drew nothing"
out=$("${HEADLESS_GL[@]}" "$RENDER" --scene "$SCENES/attention.json" "${SMALL[@]}" --backend gl --explain --gaze none \
  --set dof.method=reference 2>&1) || fail "gl explain: $out"
grep -qE "later +dof .*--backend embree" <<<"$out" || fail "gl + reference should say to use embree: $out"
"${HEADLESS_GL[@]}" "$RENDER" "${DOF[@]}" --backend gl --set dof.method=accum --set dof.samples=4 --out "$WORK/dof-gl" \
  >"$WORK/dof-gl.log" 2>&1 || fail "gl accum: $(tail -5 "$WORK/dof-gl.log")"
grep -qE "run +dof .*method accum" "$WORK/dof-gl/plan.txt" || fail "gl accum plan: $(cat "$WORK/dof-gl/plan.txt")"

echo "== gaze-directed hybrid GI (photon mapping)"
out=$("$RENDER" --scene "$SCENES/cornell.json" --explain --gaze none --set gi.enabled=true) || fail "gi explain: $out"
grep -qE "run +gi .*caustic map: no .*most attended object" <<<"$out" || fail "gi plan without gaze: $out"
grep -qE "run +attention .*consumed by gi" <<<"$out" || fail "gi without gaze should plan attention: $out"
out=$("$RENDER" --scene "$SCENES/cornell.json" --explain --gaze none --set gi.enabled=true \
  --scene-set objects.6.material=glass) || fail "gi glass explain: $out"
grep -qE "run +gi .*caustic map: yes" <<<"$out" || fail "glass sphere should plan a caustic map: $out"
GI=(--scene "$SCENES/cornell.json" "${SMALL[@]}" --headless --frames 3 --fps 2 --gaze "file:$REC" --set gi.photons=5000)
"$RENDER" "${GI[@]}" --out "$WORK/gi-off" >/dev/null 2>&1 || fail "gi off run"
for e in nearest precomputed; do
  "$RENDER" "${GI[@]}" --set gi.enabled=true --set gi.estimate=$e --out "$WORK/gi-$e" >"$WORK/gi-$e.log" 2>&1 \
    || fail "gi.estimate=$e: $(tail -5 "$WORK/gi-$e.log")"
  [ "$(grep -c ",gi," "$WORK/gi-$e/timings.csv")" -eq 3 ] || fail "gi $e: timings.csv lacks 3 gi rows"
  [ "$(grep -c ",gaze," "$WORK/gi-$e/gi.csv")" -eq 3 ] || fail "gi $e: the area should follow the gaze: $(cat "$WORK/gi-$e/gi.csv")"
  cmp -s "$WORK/gi-$e/frame-000002.png" "$WORK/gi-off/frame-000002.png" && fail "gi $e changed nothing"
done
for st in gaze-directed importon; do
  "$RENDER" "${GI[@]}" --set gi.enabled=true --set gi.strategy=$st --out "$WORK/gi-$st" >"$WORK/gi-$st.log" 2>&1 \
    || fail "gi.strategy=$st: $(tail -5 "$WORK/gi-$st.log")"
  [ "$(grep -c ",$st,gaze," "$WORK/gi-$st/gi.csv")" -eq 3 ] || fail "gi $st: gi.csv: $(cat "$WORK/gi-$st/gi.csv")"
done
# From the second frame on, the gaze-directed map has an emission map (column 13) from the first frame's labels.
[ "$(sed -n 3p "$WORK/gi-gaze-directed/gi.csv" | cut -d, -f13)" -gt 0 ] || fail "no emission map: $(cat "$WORK/gi-gaze-directed/gi.csv")"
[ "$(sed -n 2p "$WORK/gi-importon/gi.csv" | cut -d, -f15)" -gt 0 ] || fail "no importons: $(cat "$WORK/gi-importon/gi.csv")"
# Murphy's CSF-driven periphery: fewer rays than pixels, reported per frame (at 640x480: on cornell's
# 474 mm display a 160x120 image's pixels are so coarse that the eye resolves every one).
"$RENDER" --scene "$SCENES/cornell.json" --headless --frames 1 --gaze "file:$REC" --set gi.photons=5000 \
  --set gi.estimate=precomputed --set gi.enabled=true --set gi.periphery=csf --out "$WORK/gi-csf" >"$WORK/gi-csf.log" 2>&1 \
  || fail "gi.periphery=csf: $(tail -5 "$WORK/gi-csf.log")"
grep -qE "run +gi .*CSF-driven ray casting" "$WORK/gi-csf/plan.txt" || fail "csf plan: $(cat "$WORK/gi-csf/plan.txt")"
line=$(sed -n 2p "$WORK/gi-csf/gi.csv")
rays=$(cut -d, -f16 <<<"$line") full=$(cut -d, -f17 <<<"$line")
[ "$rays" -gt 0 ] && [ "$rays" -lt "$full" ] || fail "csf periphery rays $rays of $full: $line"
# The area moves with the recorded gaze (frames 0.5 s apart).
[ "$(cut -d, -f3,4 "$WORK/gi-nearest/gi.csv" | sort -u | wc -l)" -ge 3 ] || fail "gi area did not move: $(cat "$WORK/gi-nearest/gi.csv")"
"${HEADLESS_GL[@]}" "$RENDER" "${GI[@]}" --backend gl --set gi.enabled=true --out "$WORK/gi-gl" >"$WORK/gi-gl.log" 2>&1 \
  || fail "gi over the raster backend: $(tail -5 "$WORK/gi-gl.log")"
grep -qE "run +gi" "$WORK/gi-gl/plan.txt" || fail "gi gl plan: $(cat "$WORK/gi-gl/plan.txt")"
out=$("$RENDER" "${GI[@]}" --set gi.enabled=true --set gi.filter=square --out "$WORK/gi-bad" 2>&1) && fail "a bad gi.filter was accepted"
grep -q "gi.filter" <<<"$out" || fail "the error should name gi.filter: $out"

echo "== level of detail: every policy headless, levels in lod.csv"
for pol in distance screen-size brown ulod gaze; do
  "$RENDER" --scene "$SCENES/attention.json" "${SMALL[@]}" --headless --frames 2 --fps 10 --gaze "file:$REC" \
    --set lod.policy=$pol --out "$WORK/lod-$pol" >"$WORK/lod-$pol.log" 2>&1 || fail "lod.policy=$pol: $(tail -5 "$WORK/lod-$pol.log")"
  grep -qE "run +lod-select .*lod.policy=$pol" "$WORK/lod-$pol/plan.txt" || fail "lod plan: $(cat "$WORK/lod-$pol/plan.txt")"
  line=$(sed -n 2p "$WORK/lod-$pol/lod.csv")
  [ "$(cut -d, -f2 <<<"$line")" = "$pol" ] || fail "lod.csv policy: $line"
  [ "$(cut -d, -f4 <<<"$line")" -le "$(cut -d, -f5 <<<"$line")" ] || fail "more triangles than full detail: $line"
done
grep -qE "run +attention .*lod-select" "$WORK/lod-ulod/plan.txt" || fail "ulod should plan attention: $(cat "$WORK/lod-ulod/plan.txt")"
# Lee §7.2: with ULOD the attention pass runs on the coarsest-level proxy, before lod-select.
[ "$(grep -c ",attention.proxy," "$WORK/lod-ulod/timings.csv")" -eq 2 ] || fail "ulod: no attention proxy in timings.csv"
grep -q ",attention.proxy," "$WORK/lod-distance/timings.csv" && fail "the distance policy should not render an attention proxy"
"${HEADLESS_GL[@]}" "$RENDER" --scene "$SCENES/attention.json" "${SMALL[@]}" --backend gl --headless --frames 2 --fps 10 \
  --gaze "file:$REC" --set lod.policy=distance --set lod.distance_ref_m=0.5 --out "$WORK/lod-gl" >"$WORK/lod-gl.log" 2>&1 \
  || fail "lod with the raster backend: $(tail -5 "$WORK/lod-gl.log")"
grep -qE '"[0-9]+:[1-9]' "$WORK/lod-gl/lod.csv" || fail "the raster backend should draw a coarser level: $(cat "$WORK/lod-gl/lod.csv")"
out=$("$RENDER" --scene "$SCENES/attention.json" --explain --gaze none --set lod.policy=fastest 2>&1) && fail "bad lod.policy accepted"
grep -q "lod.policy" <<<"$out" || fail "the error should name lod.policy: $out"

echo "== the governor: --budget-ms headless and in the viewer, a budget it cannot meet, bad fronts"
GOV=(--scene "$SCENES/cornell.json" "${SMALL[@]}" --gaze "file:$REC" --set gi.enabled=true --set gi.photons=5000)
"$RENDER" "${GOV[@]}" --headless --frames 6 --fps 10 --budget-ms 500 --out "$WORK/gov" >"$WORK/gov.log" 2>&1 \
  || fail "governor: $(tail -5 "$WORK/gov.log")"
[ "$(wc -l <"$WORK/gov/governor.csv")" -eq 7 ] || fail "governor.csv should have 6 frames: $(cat "$WORK/gov/governor.csv")"
grep -q '"gi=' "$WORK/gov/governor.csv" || fail "the governor should choose gi settings: $(cat "$WORK/gov/governor.csv")"
[ "$(tail -1 "$WORK/gov/governor.csv" | cut -d, -f6)" = 0 ] || fail "500 ms should be met: $(tail -1 "$WORK/gov/governor.csv")"
grep -q "^governor: budget 500.0 ms" "$WORK/gov.log" || fail "no governor summary: $(tail -3 "$WORK/gov.log")"
"$RENDER" "${GOV[@]}" --headless --frames 3 --fps 10 --budget-ms 0.5 --out "$WORK/gov-tight" >"$WORK/gov-tight.log" 2>&1 \
  || fail "governor, tight budget: $(tail -5 "$WORK/gov-tight.log")"
[ "$(tail -1 "$WORK/gov-tight/governor.csv" | cut -d, -f6)" = 1 ] || fail "0.5 ms cannot be met: $(cat "$WORK/gov-tight/governor.csv")"
grep -q "cannot meet" "$WORK/gov-tight.log" || fail "the summary should say the budget cannot be met"
echo '{"fronts": [{"effect": "gi", "passes": ["gi"], "metric": "m", "reference": "r", "higher_better": true,
  "scales_with_pixels": false, "pixels": 0, "options": [{"label": "x", "settings": {"gi.photons": "-5"}, "ms": 1, "accuracy": 1}]}]}' \
  >"$WORK/bad-fronts.json"
out=$("$RENDER" "${GOV[@]}" --headless --frames 1 --budget-ms 50 --fronts "$WORK/bad-fronts.json" --out "$WORK/gov-bad" 2>&1) \
  && fail "bad fronts accepted"
grep -q "bad-fronts.json.fronts\[0\].options\[0\].settings" <<<"$out" || fail "the error should name the option: $out"
[ -e "$WORK/gov-bad" ] && fail "refused fronts should leave no output directory behind"
out=$("$RENDER" "${GOV[@]}" --headless --frames 1 --budget-ms 0 --out "$WORK/gov-zero" 2>&1) && fail "--budget-ms 0 accepted"
"${XVFB[@]}" "$RENDER" "${GOV[@]}" --frames 5 --budget-ms 500 >"$WORK/viewer-gov.out" 2>&1 \
  || fail "viewer with the governor: $(tail -5 "$WORK/viewer-gov.out")"
grep -q "^governor: budget 500.0 ms" "$WORK/viewer-gov.out" || fail "the viewer should report the governor: $(tail -3 "$WORK/viewer-gov.out")"

echo "== glTF scenes: --list-objects and a headless frame of a .glb"
# Two quads (red left, green right), each its own mesh node, and a camera node; written as .gltf
# (data: URI) and .glb.
python3 - "$WORK" <<'PY' || fail "could not write the glTF assets"
import base64, json, struct, sys
pos = struct.pack("<12f", -.5, -.5, 0, .5, -.5, 0, .5, .5, 0, -.5, .5, 0)
nrm = struct.pack("<12f", *([0, 0, 1] * 4))
idx = struct.pack("<6H", 0, 1, 2, 0, 2, 3)
binary = pos + nrm + idx
doc = {"asset": {"version": "2.0"},
       "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 48},
                       {"buffer": 0, "byteOffset": 96, "byteLength": 12}],
       "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-.5, -.5, 0], "max": [.5, .5, 0]},
                     {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
                     {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}],
       "materials": [{"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1], "metallicFactor": 0}},
                     {"name": "green", "pbrMetallicRoughness": {"baseColorFactor": [0, 1, 0, 1], "metallicFactor": 0}}],
       "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0}]},
                  {"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 1}]}],
       "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 20}}],
       "nodes": [{"name": "left", "mesh": 0, "translation": [-.6, 0, 0]}, {"name": "right", "mesh": 1, "translation": [.6, 0, 0]},
                 {"name": "eye", "camera": 0, "translation": [0, 0, 3]}],
       "scenes": [{"nodes": [0, 1, 2]}], "scene": 0}
gltf = dict(doc, buffers=[{"byteLength": len(binary), "uri": "data:application/octet-stream;base64," + base64.b64encode(binary).decode()}])
open(sys.argv[1] + "/quads.gltf", "w").write(json.dumps(gltf))
text = json.dumps(dict(doc, buffers=[{"byteLength": len(binary)}])).encode()
text += b" " * (-len(text) % 4)
glb = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(binary), b"BIN\0") + binary
open(sys.argv[1] + "/quads.glb", "wb").write(b"glTF" + struct.pack("<II", 2, 12 + len(glb)) + glb)
PY
out=$("$RENDER" --scene "$WORK/quads.gltf" --list-objects 2>&1) || fail "--list-objects on a .gltf: $out"
expected=$(printf '1\tleft\t2 triangles\tred (metallic-roughness)\n2\tright\t2 triangles\tgreen (metallic-roughness)')
[ "$out" = "$expected" ] || fail "--list-objects on a .gltf printed: $out"
out=$("$RENDER" --scene "$SCENES/cornell.json" --list-objects 2>&1) || fail "--list-objects on a JSON scene: $out"
grep -qE "^1	[^	]+	[0-9]+ triangles	.+ \((lambertian|blinn-phong|mirror|glass|emissive)\)$" <<<"$out" \
  || fail "--list-objects on a JSON scene printed: $out"
out=$("$RENDER" --scene "$WORK/quads.gltf" --camera top --list-objects 2>&1) && fail "an unknown --camera was accepted"
grep -q 'no perspective camera node named "top" (camera nodes: "eye")' <<<"$out" || fail "unknown --camera message: $out"
"$RENDER" --scene "$WORK/quads.glb" --camera eye "${SMALL[@]}" --headless --frames 1 --gaze none --out "$WORK/glb" \
  --verbose >/dev/null 2>"$WORK/glb.err" || fail "headless .glb: $(cat "$WORK/glb.err")"
[ "$(ls "$WORK/glb"/frame-*.png | wc -l)" -eq 1 ] || fail "expected 1 frame of the .glb"
# --verbose: what loading cost, phase by phase; the same phases in timings.csv.
grep -qE "^fovea-render: load [0-9]+ ms: parse [0-9]+ ms \(4 triangles in 2 meshes\), textures [0-9]+ ms \(0 textures, 0 MiB\), lod [0-9]+ ms \([0-9]+ levels\), backend [0-9]+ ms \(Embree BVH build\)$" \
  "$WORK/glb.err" || fail "--verbose load line: $(cat "$WORK/glb.err")"
for phase in parse textures lod backend; do
  grep -qE "^0,0.000000,load\.$phase,[0-9.]+$" "$WORK/glb/timings.csv" || fail "timings.csv lacks load.$phase"
done
out=$("$RENDER" --scene "$WORK/quads.glb" --scene-set lights.0.power=1 --list-objects 2>&1) \
  && fail "a glTF override other than the image size was accepted"
grep -q "a glTF scene takes only camera.width, camera.height, camera.stereo and camera.ipd_m" <<<"$out" || fail "glTF override message: $out"

echo "== --stereo: both eyes side by side, each eye's gaze, the shared passes once"
# The PNG's width and height from its IHDR chunk (bytes 16-23, big-endian).
png_size() { od -An -tu1 -j16 -N8 "$1" | awk '{print $1*16777216+$2*65536+$3*256+$4 "x" $5*16777216+$6*65536+$7*256+$8}'; }
for backend in embree gl; do
  runner=(); [ $backend = gl ] && runner=("${HEADLESS_GL[@]}")
  "${runner[@]}" "$RENDER" --scene "$SCENES/attention.json" "${SMALL[@]}" --backend $backend --stereo --headless \
    --frames 3 --gaze none --out "$WORK/stereo-$backend" >"$WORK/stereo-$backend.log" 2>&1 \
    || fail "--stereo with $backend: $(tail -5 "$WORK/stereo-$backend.log")"
  [ "$(png_size "$WORK/stereo-$backend/frame-000002.png")" = 320x120 ] \
    || fail "$backend stereo frame is $(png_size "$WORK/stereo-$backend/frame-000002.png"), not 320x120"
  [ "$(wc -l <"$WORK/stereo-$backend/stereo.csv")" -eq 4 ] || fail "$backend stereo.csv: $(cat "$WORK/stereo-$backend/stereo.csv")"
  # Frame 2 converges at the focus pass's depth: the left eye's gaze right of the right eye's.
  awk -F, 'NR==4 && !($3 > 0 && $4 > $5 && $7 > 0 && $8 < 0) {exit 1}' "$WORK/stereo-$backend/stereo.csv" \
    || fail "$backend stereo.csv gaze points: $(tail -1 "$WORK/stereo-$backend/stereo.csv")"
  grep -q ",right.gbuffer," "$WORK/stereo-$backend/timings.csv" || fail "$backend: no right.gbuffer timing"
  ! grep -q ",right.attention," "$WORK/stereo-$backend/timings.csv" || fail "$backend: attention ran for the right eye"
  grep -q "^stereo  *two views of 160x120, the eyes 63.0 mm apart" "$WORK/stereo-$backend/plan.txt" \
    || fail "$backend plan.txt lacks the stereo line: $(tail -2 "$WORK/stereo-$backend/plan.txt")"
done
out=$("$RENDER" --scene "$SCENES/attention.json" --stereo --explain --gaze none 2>&1) || fail "--stereo --explain: $out"
grep -q "once per frame (left eye): attention, focus" <<<"$out" || fail "--stereo --explain: $out"
# The governor budgets both eyes: governor.csv's frame time is the left eye's frame plus the right eye's.
"$RENDER" --scene "$SCENES/attention.json" "${SMALL[@]}" --stereo --budget-ms 500 --headless --frames 3 --gaze none \
  --out "$WORK/stereo-budget" >"$WORK/stereo-budget.log" 2>&1 || fail "--stereo --budget-ms: $(tail -3 "$WORK/stereo-budget.log")"
[ "$(wc -l <"$WORK/stereo-budget/governor.csv")" -eq 4 ] || fail "stereo governor.csv: $(cat "$WORK/stereo-budget/governor.csv")"
awk -F, '$3 == "frame" || $3 == "right.frame" {sum[$1] += $4} END {for (f in sum) printf "%s,%.4f\n", f, sum[f]}' \
  "$WORK/stereo-budget/timings.csv" | sort -n >"$WORK/stereo-budget/both.txt"
while IFS=, read -r f ms; do
  both=$(grep "^$f," "$WORK/stereo-budget/both.txt" | cut -d, -f2)
  awk -v a="$ms" -v b="$both" 'BEGIN {exit !(a - b < 0.01 && b - a < 0.01)}' \
    || fail "governor.csv frame $f: $ms ms, both eyes' renders $both ms"
done < <(awk -F, 'NR > 1 {print $1 "," $3}' "$WORK/stereo-budget/governor.csv")
out=$("$RENDER" --scene "$SCENES/attention.json" --scene-set camera.ipd_m=0 --stereo --explain 2>&1) \
  && fail "camera.ipd_m=0 accepted"
grep -q 'camera.ipd_m = 0' <<<"$out" || fail "camera.ipd_m=0 message: $out"
"$RENDER" --scene "$WORK/quads.gltf" --stereo --scene-set camera.ipd_m=0.07 "${SMALL[@]}" --headless --frames 1 \
  --gaze none --out "$WORK/stereo-gltf" >"$WORK/stereo-gltf.log" 2>&1 || fail "--stereo on a glTF: $(tail -3 "$WORK/stereo-gltf.log")"
grep -q "^0,0.0700," "$WORK/stereo-gltf/stereo.csv" || fail "glTF stereo.csv: $(cat "$WORK/stereo-gltf/stereo.csv")"

echo "== two render clients against one daemon"
. "$(dirname "${BASH_SOURCE[0]}")/ports.sh"
PORT=$(free_udp_port)
"$TRACKERD" --source "replay:$REC" --loop --port $PORT >"$WORK/daemon.log" 2>&1 &
PIDS+=($!)
for _ in $(seq 1 50); do "$CTL" --server 127.0.0.1:$PORT status >/dev/null 2>&1 && break; sleep 0.1; done
"$RENDER" --scene "$SCENES/attention.json" "${SMALL[@]}" --headless --frames 10 --fps 10 \
  --gaze udp://127.0.0.1:$PORT --out "$WORK/live-embree" >"$WORK/live-embree.log" 2>&1 &
R1=$!
"${HEADLESS_GL[@]}" "$RENDER" --scene "$SCENES/attention.json" "${SMALL[@]}" --backend gl --headless --frames 10 --fps 10 \
  --gaze udp://127.0.0.1:$PORT --out "$WORK/live-gl" >"$WORK/live-gl.log" 2>&1 &
R2=$!
wait $R1 || fail "live embree client failed: $(tail -20 "$WORK/live-embree.log")"
wait $R2 || fail "live gl client failed: $(tail -20 "$WORK/live-gl.log")"
for d in live-embree live-gl; do
  last=$(tail -1 "$WORK/$d/gaze.csv")
  received=$(cut -d, -f8 <<<"$last")
  [ "$received" -gt 100 ] || fail "$d received only $received gaze samples: $last"
done

echo "== --stereo on a binocular daemon: each eye sees its own measured gaze point"
BPORT=$(free_udp_port)
"$TRACKERD" --source synthetic:binocular --port $BPORT >"$WORK/daemon-bino.log" 2>&1 &
PIDS+=($!)
for _ in $(seq 1 50); do "$CTL" --server 127.0.0.1:$BPORT status >/dev/null 2>&1 && break; sleep 0.1; done
"$RENDER" --scene "$SCENES/attention.json" "${SMALL[@]}" --stereo --headless --frames 8 --fps 10 --no-images \
  --gaze udp://127.0.0.1:$BPORT --out "$WORK/stereo-bino" >"$WORK/stereo-bino.log" 2>&1 \
  || fail "--stereo with binocular gaze: $(tail -5 "$WORK/stereo-bino.log")"
# Once samples flow, each eye's point is the tracker's (columns 11, 12), and the eyes differ: each
# eye's own noise (the synthetic viewer's), not a shift by the vergence.
awk -F, 'NR > 4 && $11 == "tracker" && $12 == "tracker" && ($4 != $5 || $6 != $13) {n++} END {exit !(n >= 3)}' \
  "$WORK/stereo-bino/stereo.csv" || fail "binocular stereo.csv: $(cat "$WORK/stereo-bino/stereo.csv")"
echo "PASS"

#!/bin/bash
# SPDX-License-Identifier: Apache-2.0
# fovea-bench report --only: the re-measured effect is replaced, every other effect of the report
# stays (from DIR/report.json when DIR holds only a report, as bench/results/report does).
# Runs against a fake build directory whose benchmarks print fixed tables, so it takes a second.
# Usage: test_fovea_bench_only.sh SOURCE_DIR
set -euo pipefail
src=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/build/bench" "$work/out"
fake_classify() {  # bench_classify's first table, with ivvt's kappa $1
  cat > "$work/build/bench/bench_classify" <<SCRIPT
#!/bin/sh
echo "| rate Hz | condition | method | fixation | saccade | pursuit | blink | all | pso % | unknown % | ns/sample | latency ms |"
echo "|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
echo "| 250 | clean (0.03 deg) | ivvt | 0.9 | 0.9 | 0.9 | 1.0 | $1 | 0.0 | 0.0 | 500 | 385 |"
echo "| 250 | clean (0.03 deg) | ivt | 0.5 | 0.9 | 0.0 | 1.0 | 0.45 | 0.0 | 0.0 | 100 | 280 |"
SCRIPT
  chmod +x "$work/build/bench/bench_classify"
}
printf '#!/bin/sh\nexit 0\n' > "$work/build/bench/bench_dof"
chmod +x "$work/build/bench/bench_dof"
# A report as committed: a classification step and another effect, no state.json, no step folders.
cat > "$work/out/report.json" <<'JSON'
{"generated": "2026-01-01T00:00:00", "quick": false, "machine": {},
 "steps": [
  {"name": "eye", "title": "Pupil detection", "metric": "median pupil-centre error (px)", "baseline": true,
   "higher_better": false, "reference": "r", "time_unit": "ms per image", "seconds": 1, "command": "c",
   "status": "ok", "points": [{"label": "kept-eye", "ms": 1.0, "accuracy": 0.5}],
   "front": [{"label": "kept-eye", "ms": 1.0, "accuracy": 0.5}]},
  {"name": "classify", "title": "Eye-movement classification", "metric": "Cohen's kappa over all labels",
   "baseline": true, "higher_better": true, "reference": "r", "time_unit": "ms per sample", "seconds": 1,
   "command": "c", "status": "ok", "points": [{"label": "ivvt", "ms": 0.001, "accuracy": 0.1}],
   "front": [{"label": "ivvt", "ms": 0.001, "accuracy": 0.1}]}]}
JSON
fake_classify 0.77
/usr/bin/python3 "$src/bench/fovea-bench" report --out "$work/out" --build "$work/build" --only classify --force > "$work/log" 2>&1 \
  || { cat "$work/log"; exit 1; }
/usr/bin/python3 - "$work/out" <<'PY'
import csv, json, sys
out = sys.argv[1]
steps = {s["name"]: s for s in json.load(open(f"{out}/report.json"))["steps"]}
assert set(steps) == {"eye", "classify"}, f"steps in the report: {sorted(steps)}"
assert steps["eye"]["points"][0]["label"] == "kept-eye", "the other effect was not kept as it was"
ivvt = next(p for p in steps["classify"]["points"] if p["label"] == "ivvt")
assert abs(ivvt["accuracy"] - 0.77) < 1e-9, f"classify was not re-measured: {ivvt}"
rows = list(csv.DictReader(open(f"{out}/points.csv")))
assert {r["effect"] for r in rows} == {"eye", "classify"}, "points.csv lost an effect"
html = open(f"{out}/report.html").read()
assert "Pupil detection" in html and "Eye-movement classification" in html, "report.html lost an effect"
PY
# Again, from the run just made (state.json and the classify folder now exist): still both.
fake_classify 0.78
/usr/bin/python3 "$src/bench/fovea-bench" report --out "$work/out" --build "$work/build" --only classify --force > "$work/log" 2>&1 \
  || { cat "$work/log"; exit 1; }
/usr/bin/python3 - "$work/out" <<'PY'
import json, sys
steps = {s["name"]: s for s in json.load(open(f"{sys.argv[1]}/report.json"))["steps"]}
assert set(steps) == {"eye", "classify"}, f"second run: steps {sorted(steps)}"
assert abs(next(p for p in steps["classify"]["points"] if p["label"] == "ivvt")["accuracy"] - 0.78) < 1e-9
PY
echo "PASS: --only replaced classify and kept the other effect, twice"

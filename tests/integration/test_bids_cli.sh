#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# fovea-ctl convert --format bids as a user runs it (issue 26 item 6): the dataset is read back by an
# independent reader (Python's gzip, csv and json) and checked against BIDS 1.10's eye-tracking rules
# and the recording's known counts; existing files and bad labels are refused; a damaged recording
# exports its intact records and says what it skipped.
# Usage: test_bids_cli.sh FOVEA_CTL DATA_DIR [PYTHON]
set -u
CTL=$1 DATA=$2 PY=${3:-/usr/bin/python3}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
REC=$DATA/recordings/synthetic-250hz-62s.fgr
DS=$WORK/ds

echo "== export"
"$CTL" convert "$REC" "$DS" --format bids --subject 01 --task freeview --session 1 2>"$WORK/err" ||
  fail "export failed: $(cat "$WORK/err")"
grep -q '15500 samples (15021 with valid gaze) at 250 Hz, 342 eye-movement events, 0 markers' "$WORK/err" ||
  fail "unclear summary: $(cat "$WORK/err")"

echo "== read back (Python: gzip, csv, json)"
"$PY" - "$DS" <<'EOF' || fail "read-back check failed"
import csv, gzip, io, json, os, sys
root = sys.argv[1]
beh = os.path.join(root, "sub-01", "ses-1", "beh")
stem = os.path.join(beh, "sub-01_ses-1_task-freeview_recording-eye1")
def load(p):
    with open(p, encoding="utf-8") as f:
        return json.load(f)
def rows(p, gz):
    data = gzip.open(p, "rt", encoding="utf-8", newline="").read() if gz else open(p, encoding="utf-8", newline="").read()
    assert "\r" not in data
    return list(csv.reader(io.StringIO(data), delimiter="\t", quoting=csv.QUOTE_NONE))
desc = load(os.path.join(root, "dataset_description.json"))
assert desc["Name"] and desc["BIDSVersion"] == "1.10.0", desc
j = load(stem + "_physio.json")
required = ["SamplingFrequency", "StartTime", "Columns", "PhysioType", "RecordedEye", "SampleCoordinateSystem"]
missing = [k for k in required if k not in j]
assert not missing, missing
assert j["SamplingFrequency"] == 250, j["SamplingFrequency"]
assert j["PhysioType"] == "eyetrack" and j["SampleCoordinateSystem"] == "gaze-on-screen"
assert j["RecordedEye"] in ("left", "right", "cyclopean")
cols = j["Columns"]
assert cols[:3] == ["timestamp", "x_coordinate", "y_coordinate"], cols
assert len(set(cols)) == len(cols)
for c in cols:
    assert c in j, "column %s not described" % c
assert j["x_coordinate"]["Units"] == "pixel" and j["y_coordinate"]["Units"] == "pixel"
sp = j["StimulusPresentation"]
assert sp["ScreenResolution"] == [1920, 1080] and abs(sp["ScreenDistance"] - 0.65) < 1e-9, sp
data = rows(stem + "_physio.tsv.gz", True)
assert len(data) == 15500, len(data)
assert all(len(r) == len(cols) for r in data), "a row's cell count differs from Columns"
assert data[0][0] != "timestamp", "the physio file must not have a header line"
valid = [r for r in data if r[1] != "n/a"]
assert len(valid) == 15021, len(valid)
assert all(r[2] == "n/a" for r in data if r[1] == "n/a")
t = [float(r[0]) for r in data]
assert all(b >= a for a, b in zip(t, t[1:])), "timestamps go backwards"
assert 61.9 < t[-1] - t[0] < 62.1, t[-1] - t[0]
for r in valid:
    float(r[1]); float(r[2])
ej = load(stem + "_physioevents.json")
assert ej["OnsetSource"] == "timestamp" and ej["Columns"][:2] == ["onset", "duration"], ej
ev = rows(stem + "_physioevents.tsv.gz", True)
assert all(len(r) == len(ej["Columns"]) for r in ev)
kinds = {}
for r in ev:
    kinds[r[2]] = kinds.get(r[2], 0) + 1
    assert t[0] - 1 <= float(r[0]) <= t[-1] + 1, r
assert kinds == {"blink": 9, "fixation": 171, "pursuit": 11, "saccade": 151}, kinds
tev = rows(os.path.join(beh, "sub-01_ses-1_task-freeview_events.tsv"), False)
assert tev[0] == ["onset", "duration", "trial_type"], tev[0]
tj = load(os.path.join(beh, "sub-01_ses-1_task-freeview_events.json"))
for k in ("ScreenDistance", "ScreenOrigin", "ScreenResolution", "ScreenSize"):
    assert k in tj["StimulusPresentation"], k
scans = rows(os.path.join(root, "sub-01", "ses-1", "sub-01_ses-1_scans.tsv"), False)
assert scans[0] == ["filename", "acq_time"] and scans[1][0] == "beh/sub-01_ses-1_task-freeview_recording-eye1_physio.tsv.gz", scans
print("read back: 15500 rows, 342 events, required fields present")
EOF

echo "== never replaces a file"
before=$(md5sum "$DS"/sub-01/ses-1/beh/* | md5sum)
out=$("$CTL" convert "$REC" "$DS" --format bids --subject 01 --task freeview --session 1 2>&1) && fail "second export succeeded"
grep -q 'sub-01_ses-1_task-freeview_recording-eye1_physio.tsv.gz already exists' <<<"$out" || fail "unclear: $out"
[ "$(md5sum "$DS"/sub-01/ses-1/beh/* | md5sum)" = "$before" ] || fail "existing files changed"
out=$("$CTL" convert "$REC" "$DS" --format bids --subject 01 --task freeview --force 2>&1) && fail "--force accepted"
grep -q -- '--force does not apply' <<<"$out" || fail "unclear: $out"
echo '{"Name": "mine", "BIDSVersion": "1.9.0"}' >"$WORK/desc"
cp "$WORK/desc" "$DS/dataset_description.json"
"$CTL" convert "$REC" "$DS" --format bids --subject 02 --task freeview 2>/dev/null || fail "export of subject 02 failed"
cmp -s "$WORK/desc" "$DS/dataset_description.json" || fail "dataset_description.json was replaced"
touch "$WORK/file"
out=$("$CTL" convert "$REC" "$WORK/file" --format bids --subject 01 --task x 2>&1) && fail "file as dataset accepted"
grep -q 'is not a directory' <<<"$out" || fail "unclear: $out"

echo "== bad labels and missing options"
for args in "--subject 0-1 --task x" "--subject 01 --task free_view" "--subject 01 --task x --session a.b" \
            "--subject 01 --task x --recording eye-1" "--subject 01 --task x --run 1a"; do
  # shellcheck disable=SC2086
  out=$("$CTL" convert "$REC" "$WORK/bad" --format bids $args 2>&1) && fail "accepted: $args"
  grep -qE 'not a BIDS (label|index)' <<<"$out" || fail "unclear for $args: $out"
done
out=$("$CTL" convert "$REC" "$WORK/bad" --format bids --subject 01 2>&1) && fail "missing --task accepted"
grep -q 'needs --subject and --task' <<<"$out" || fail "unclear: $out"
out=$("$CTL" convert "$REC" "$WORK/x.csv" --subject 01 2>&1) && fail "--subject without --format bids accepted"
grep -q 'need --format bids' <<<"$out" || fail "unclear: $out"
[ ! -e "$WORK/bad" ] || fail "a refused export left $WORK/bad"

echo "== a damaged recording exports its intact records"
cp "$REC" "$WORK/damaged.fgr"
size=$(stat -c %s "$WORK/damaged.fgr")
printf '\xff\xff\xff\xff' | dd of="$WORK/damaged.fgr" bs=1 seek=$((size / 2)) conv=notrunc status=none
out=$("$CTL" convert "$WORK/damaged.fgr" "$WORK/dmg" --format bids --subject 01 --task x 2>&1) || fail "damaged export failed: $out"
grep -q 'skipped [0-9]* bytes in 1 damaged region' <<<"$out" || fail "skip not reported: $out"
n=$("$PY" -c 'import gzip,sys; print(sum(1 for _ in gzip.open(sys.argv[1], "rt")))' \
      "$WORK/dmg/sub-01/beh/sub-01_task-x_recording-eye1_physio.tsv.gz")
[ "$n" -ge 15499 ] && [ "$n" -le 15500 ] || fail "damaged export holds $n rows"
grep -q "$n samples" <<<"$out" || fail "summary does not match the $n rows: $out"

echo "PASS"

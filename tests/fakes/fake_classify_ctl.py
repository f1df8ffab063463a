#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""A stand-in for `fovea-ctl classify IN OUT ...` whose labels the harness tests know: every sample
fixation, a lost one (nan) lost, each final 100 ms after it (t_ms,label,final_ms)."""
import sys

rows = open(sys.argv[2]).read().splitlines()[1:]
with open(sys.argv[3], "w") as f:
    f.write("t_ms,label,final_ms\n")
    for r in rows:
        t, x, y = r.split(",")
        f.write(f"{t},{'lost' if x == 'nan' else 'fixation'},{float(t) + 100}\n")

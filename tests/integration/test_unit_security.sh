#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The service unit's exposure as systemd rates it (issue 23: keep `systemd-analyze security` at or
# below 1.6), analysed offline on the file in the tree. Skipped (77) where systemd-analyze is absent.
set -u
UNIT=$1
command -v systemd-analyze >/dev/null || { echo "SKIP: no systemd-analyze here"; exit 77; }
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
cp "$UNIT" "$WORK/fovea-trackerd.service"
out=$(timeout 120 systemd-analyze security --offline=true --no-pager "$WORK/fovea-trackerd.service" 2>&1) \
  || { echo "SKIP: systemd-analyze security --offline failed here: $(tail -n 2 <<<"$out")"; exit 77; }
level=$(sed -n 's/.*Overall exposure level for fovea-trackerd.service: \([0-9.]*\).*/\1/p' <<<"$out")
[ -n "$level" ] || { echo "FAIL: no exposure level in: $(tail -n 3 <<<"$out")"; exit 1; }
echo "exposure $level"
awk -v l="$level" 'BEGIN { exit !(l <= 1.6) }' || { echo "FAIL: exposure $level > 1.6"; exit 1; }
for want in 'ProcSubset=' 'IPAddressDeny=' 'RestrictAddressFamilies='; do
  grep -q "✓ $want\|✗ $want" <<<"$out" || { echo "FAIL: $want not assessed"; exit 1; }
done
echo PASS

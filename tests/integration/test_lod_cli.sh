#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# fovea-lod as a user runs it: build a chain from a bundled mesh in both formats, read it back,
# refuse to overwrite, name a missing mesh and a bad option.
set -u
LOD=$1 SOURCE_DIR=$2
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
MESH=$SOURCE_DIR/renderer/scenes/meshes/blob.obj

out=$("$LOD" build "$MESH" --out "$WORK/obj" 2>&1) || fail "build: $out"
grep -qE "^0 +320 " <<<"$out" || fail "level 0 should list the 320 input triangles: $out"
for l in 0 1 2 3 4; do [ -s "$WORK/obj/level$l.obj" ] || fail "level$l.obj missing"; done
grep -q '"target_ratio": 0.25' "$WORK/obj/manifest.json" || fail "manifest lacks level 1's ratio 4^-1: $(cat "$WORK/obj/manifest.json")"
out=$("$LOD" build "$MESH" --levels 3 --base 2 --format ply --attributes weld --out "$WORK/ply" 2>&1) || fail "ply build: $out"
[ -s "$WORK/ply/level2.ply" ] && [ ! -e "$WORK/ply/level3.ply" ] || fail "3 levels expected: $(ls "$WORK/ply")"
out=$("$LOD" info "$WORK/ply" 2>&1) || fail "info: $out"
grep -qE "^2 +[0-9]+ +0\.250000" <<<"$out" || fail "info should show level 2 at ratio 2^-2: $out"
out=$("$LOD" build "$MESH" --out "$WORK/obj" 2>&1) && fail "overwrote a non-empty directory"
grep -q "not empty" <<<"$out" || fail "the refusal should say why: $out"
out=$("$LOD" build "$WORK/none.obj" --out "$WORK/x" 2>&1) && fail "a missing mesh was accepted"
grep -q "none.obj" <<<"$out" || fail "the error should name the file: $out"
out=$("$LOD" build "$MESH" --base 0.5 --out "$WORK/y" 2>&1) && fail "base 0.5 was accepted"
grep -q "base" <<<"$out" || fail "the error should name --base: $out"
echo "PASS"

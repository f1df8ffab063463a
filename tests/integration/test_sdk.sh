#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The client SDK as a user gets it (issue 26 item 1): `cmake --install --component sdk` into a fresh
# prefix holds libfovea-client (shared with its SONAME, and static), the public headers and nothing
# of the server side, the CMake package and the pkg-config file; examples/ builds against that
# prefix with find_package(fovea) (shared and static) and with pkg-config, and each build talks
# to a running fovea-trackerd.
# Usage: test_sdk.sh BUILD_DIR SOURCE_DIR TRACKERD CXX
set -u
BUILD=$1 SRC=$2 TRACKERD=$3 CXX=$4
WORK=$(mktemp -d)
DPID=""
trap 'kill $DPID 2>/dev/null; rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*"; exit 1; }
P=$WORK/prefix

echo "== cmake --install --component sdk"
cmake --install "$BUILD" --prefix "$P" --component sdk >"$WORK/install.log" 2>&1 || fail "install: $(tail -5 "$WORK/install.log")"
so=$(find "$P" -name 'libfovea-client.so.0' | head -1)
[ -n "$so" ] || fail "no libfovea-client.so.0 under $P: $(find "$P" -type f | head -20)"
readelf -d "$so" | grep -q 'SONAME.*\[libfovea-client.so.0\]' || fail "libfovea-client's SONAME: $(readelf -d "$so" | grep SONAME)"
[ -n "$(find "$P" -name 'libfovea-client.a')" ] || fail "no static libfovea-client.a"
for h in client.h codec.h messages.h recording.h csv.h clock.h; do
  [ -f "$P/include/fovea/protocol/$h" ] || fail "header $h not installed"
done
for h in server.h cookie.h control_socket.h wire.h; do
  [ -e "$P/include/fovea/protocol/$h" ] && fail "server-side header $h installed"
done
nm -D --defined-only "$so" | grep -q GazeServer && fail "the SDK exports the server"
pc=$(find "$P" -name fovea-client.pc | head -1)
[ -n "$pc" ] || fail "no fovea-client.pc"
[ -n "$(find "$P" -name foveaConfig.cmake)" ] || fail "no foveaConfig.cmake"

echo "== examples/ with find_package(fovea CONFIG REQUIRED)"
cmake -S "$SRC/examples" -B "$WORK/ex" -DCMAKE_PREFIX_PATH="$P" -DCMAKE_CXX_COMPILER="$CXX" >"$WORK/ex.log" 2>&1 \
  || fail "configure: $(tail -5 "$WORK/ex.log")"
cmake --build "$WORK/ex" >>"$WORK/ex.log" 2>&1 || fail "build: $(tail -10 "$WORK/ex.log")"
ldd "$WORK/ex/fovea-example-client" | grep -q "libfovea-client.so.0 => $(dirname "$so")" \
  || fail "the shared example does not load the installed library: $(ldd "$WORK/ex/fovea-example-client" | grep fovea)"
ldd "$WORK/ex/fovea-example-client-static" | grep -q libfovea-client && fail "the static example loads libfovea-client.so"

echo "== examples/client.cpp with pkg-config"
# shellcheck disable=SC2046
"$CXX" -o "$WORK/ex-pc" "$SRC/examples/client.cpp" $(PKG_CONFIG_PATH=$(dirname "$pc") pkg-config --cflags --libs fovea-client) \
  >"$WORK/pc.log" 2>&1 || fail "pkg-config build: $(tail -10 "$WORK/pc.log")"

echo "== each build against a running daemon"
. "$(dirname "${BASH_SOURCE[0]}")/ports.sh"
PORT=$(free_udp_port)
"$TRACKERD" --port "$PORT" --control-socket none --duration 20 --log-level warn >"$WORK/d.log" 2>&1 &
DPID=$!
sleep 0.5
for ex in "$WORK/ex/fovea-example-client" "$WORK/ex/fovea-example-client-static" "$WORK/ex-pc"; do
  LD_LIBRARY_PATH=$(dirname "$so") "$ex" "127.0.0.1:$PORT" 2 >"$WORK/out" 2>&1 || fail "$(basename "$ex"): $(cat "$WORK/out")"
  grep -q '^gaze (' "$WORK/out" || fail "$(basename "$ex") printed no gaze: $(cat "$WORK/out")"
  n=$(sed -n 's/^\([0-9]*\) samples, .*/\1/p' "$WORK/out")
  [ "${n:-0}" -gt 200 ] || fail "$(basename "$ex") received ${n:-0} samples in 2 s"
  echo "   $(basename "$ex"): $(tail -1 "$WORK/out")"
done
echo "PASS"

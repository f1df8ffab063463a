#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Builds fovea's Debian packages and checks what they hold (issue 26 item 4; README "Install"):
#   deploy/build-packages.sh [--out DIR] [--check-only DIR] [--tests] [--quick]
# Copies the tree (tracked and untracked, not ignored) to build/package-work, runs
# `dpkg-buildpackage -us -uc -b` there (with DEB_BUILD_OPTIONS=nocheck unless --tests: deploy/test.sh
# runs the test suite on its own), copies the .deb files to DIR (default build/packages), then checks
# them: each package's file list, every program's --version from the extracted files, the unit with
# `systemd-analyze verify` (when present), the C++ example built against the extracted -dev package
# with CMake and pkg-config, `import fovea` from python3-fovea, and lintian (its findings printed;
# errors fail). --check-only DIR checks .deb files already built. --quick builds unoptimised
# (DEB_BUILD_OPTIONS=noopt) with line tables only (-g1): the same files and checks in about half
# the time, for deploy/test.sh; such packages are for checking, not for installing. Needs dpkg-buildpackage (dpkg-dev) and
# debhelper: deploy/install-deps.sh installs them.
set -euo pipefail
SRC=$(cd "$(dirname "$0")/.." && pwd)
OUT=$SRC/build/packages
CHECK_ONLY=""
NOCHECK=nocheck
NOOPT=""
GLEVEL=""
while [ $# -gt 0 ]; do
  case $1 in
    --out) OUT=$2; shift ;;
    --check-only) CHECK_ONLY=$2; shift ;;
    --tests) NOCHECK="" ;;
    --quick) NOOPT=noopt; GLEVEL=-g1 ;;
    -h|--help) sed -n '2,14p' "$0"; exit 0 ;;
    *) echo "build-packages: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
  shift
done
for tool in dpkg-buildpackage dh dpkg-deb; do
  command -v "$tool" >/dev/null || { echo "build-packages: $tool not found (run deploy/install-deps.sh)" >&2; exit 3; }
done
# A fixed scratch directory (inside the ignored build/): the compiler flags name it
# (-ffile-prefix-map), so with deploy/test.sh's compiler cache a rebuild of unchanged files hits.
WORK=$SRC/build/package-work
rm -rf "$WORK"
mkdir -p "$WORK"
trap 'rm -rf "$WORK"' EXIT
fail() { echo "build-packages: FAIL: $*" >&2; exit 1; }

version=$(dpkg-parsechangelog -l "$SRC/debian/changelog" -S Version)
arch=$(dpkg-architecture -qDEB_HOST_ARCH)
multiarch=$(dpkg-architecture -qDEB_HOST_MULTIARCH)

build() {
  local tree=$WORK/fovea-$version
  mkdir -p "$tree"
  (cd "$SRC" && git ls-files -z --cached --others --exclude-standard | xargs -0 cp --parents -t "$tree" 2>/dev/null) ||
    (cd "$SRC" && git ls-files -z --cached --others --exclude-standard | while IFS= read -r -d '' f; do
       [ -e "$f" ] && cp --parents -P -t "$tree" "$f"; done)
  local options="$NOCHECK $NOOPT parallel=$(nproc)"
  echo "build-packages: dpkg-buildpackage -us -uc -b in $tree (DEB_BUILD_OPTIONS=$options)"
  local start=$SECONDS
  # Debian's own interpreters and tools only: a python3 from pyenv or a venv earlier in PATH would
  # build the Python package for itself.
  (cd "$tree" && env -u CMAKE_PREFIX_PATH PATH=/usr/sbin:/usr/bin:/sbin:/bin DEB_BUILD_OPTIONS="$options" DEB_CXXFLAGS_APPEND="$GLEVEL" DEB_CFLAGS_APPEND="$GLEVEL" \
     dpkg-buildpackage -us -uc -b >"$WORK/build.log" 2>&1) ||
    { tail -n 40 "$WORK/build.log" >&2; fail "dpkg-buildpackage failed (log above)"; }
  echo "build-packages: built in $((SECONDS - start)) s"
  mkdir -p "$OUT"
  rm -f "$OUT"/*.deb
  cp "$WORK"/*.deb "$OUT/"
  cp "$WORK"/*.changes "$OUT/" 2>/dev/null || true
}

# PACKAGE PATH... : the package holds each path.
expect() {
  local pkg=$1; shift
  local deb=$DEBS/${pkg}_${version}_$( [ "$pkg" = python3-fovea ] && echo all || echo "$arch").deb
  [ -f "$deb" ] || fail "no $deb"
  dpkg-deb -c "$deb" | awk '{print $6}' | sed 's#^\./#/#; s#/$##' >"$WORK/$pkg.list"
  for p in "$@"; do grep -qx -- "$p" "$WORK/$pkg.list" || fail "$pkg lacks $p (has: $(grep -v '/$' "$WORK/$pkg.list" | tr '\n' ' '))"; done
  dpkg-deb -x "$deb" "$WORK/root"
}

# The packaged daemon with the packaged configuration (its port moved off the default), answered by
# the packaged fovea-ctl and by the packaged Python client: the service's start without systemd.
run_packaged_daemon() {  # ROOT
  local R=$1 port=$(( 47900 + RANDOM % 500 ))
  "$R/usr/bin/fovea-trackerd" --config "$R/etc/fovea/trackerd.toml" --port "$port" --duration 5 >"$WORK/daemon.log" 2>&1 &
  local pid=$!
  for _ in $(seq 1 100); do "$R/usr/bin/fovea-ctl" --server "127.0.0.1:$port" status >/dev/null 2>&1 && break; sleep 0.05; done
  "$R/usr/bin/fovea-ctl" --server "127.0.0.1:$port" status >"$WORK/status.txt" 2>&1 ||
    { kill "$pid" 2>/dev/null; fail "the packaged daemon does not answer: $(tail -n 5 "$WORK/daemon.log")"; }
  PYTHONPATH=$R/usr/lib/python3/dist-packages /usr/bin/python3 -c '
import sys, fovea
with fovea.GazeClient("127.0.0.1", int(sys.argv[1])) as c:
    assert c.wait_subscribed(3.0), "no subscription"
    import time; time.sleep(0.3)
    assert c.latest() is not None, "no sample"' "$port" || { kill "$pid" 2>/dev/null; fail "the packaged Python client got no gaze"; }
  kill "$pid" 2>/dev/null; wait "$pid" 2>/dev/null || true
  echo "build-packages: the packaged daemon runs its packaged configuration; fovea-ctl and the Python client get its gaze"
}

check() {
  DEBS=$1
  rm -rf "$WORK/root"; mkdir -p "$WORK/root"
  expect fovea-trackerd /usr/bin/fovea-trackerd /lib/systemd/system/fovea-trackerd.service \
    /lib/udev/rules.d/70-fovea-trackers.rules /usr/lib/sysusers.d/fovea.conf /usr/lib/tmpfiles.d/fovea.conf \
    /etc/fovea/trackerd.toml /usr/share/man/man8/fovea-trackerd.8.gz /usr/share/man/man5/trackerd.toml.5.gz
  dpkg-deb -e "$DEBS/fovea-trackerd_${version}_$arch.deb" "$WORK/control"
  grep -qx /etc/fovea/trackerd.toml "$WORK/control/conffiles" || fail "/etc/fovea/trackerd.toml is not a conffile"
  grep -q systemd-sysusers "$WORK/control/postinst" || fail "postinst does not create the fovea user (systemd-sysusers)"
  expect fovea-tools /usr/bin/fovea-ctl /usr/bin/fovea-calibrate /usr/bin/fovea-lod /usr/bin/fovea-monitor /usr/share/man/man1/fovea-ctl.1.gz /usr/share/man/man1/fovea-monitor.1.gz
  expect fovea-render /usr/bin/fovea-render /usr/share/fovea/scenes/attention.json /usr/share/man/man1/fovea-render.1.gz
  expect libfovea-client0 "/usr/lib/$multiarch/libfovea-client.so.0"
  expect libfovea-client-dev /usr/include/fovea/protocol/client.h "/usr/lib/$multiarch/libfovea-client.so" \
    "/usr/lib/$multiarch/cmake/fovea/foveaConfig.cmake" "/usr/lib/$multiarch/pkgconfig/fovea-client.pc"
  expect python3-fovea /usr/lib/python3/dist-packages/fovea/__init__.py
  local R=$WORK/root
  echo "build-packages: packages ($version):"
  for d in "$DEBS"/*.deb; do printf '  %-44s %8s bytes, installed %6s KiB\n' "$(basename "$d")" "$(stat -c %s "$d")" "$(dpkg-deb -f "$d" Installed-Size)"; done

  for b in fovea-trackerd fovea-ctl fovea-calibrate fovea-lod fovea-monitor fovea-render; do
    v=$("$R/usr/bin/$b" --version 2>&1) || fail "$b --version: $v"
    [ "$v" = "$b ${version%%-*}" ] || fail "$b --version says '$v', the package is $version"
  done
  echo "build-packages: every program runs from the package (--version matches $version)"
  out=$("$R/usr/bin/fovea-trackerd" --check-config --config "$R/etc/fovea/trackerd.toml" 2>&1) || fail "the packaged configuration is refused: $out"
  if command -v systemd-analyze >/dev/null; then
    # The unit as packaged, its ExecStart pointed at the extracted binary (verify wants it to exist).
    mkdir -p "$WORK/unit"
    sed "s#^ExecStart=/usr/bin/fovea-trackerd #ExecStart=$R/usr/bin/fovea-trackerd #" \
      "$R/lib/systemd/system/fovea-trackerd.service" >"$WORK/unit/fovea-trackerd.service"
    grep -q "^ExecStart=$R/usr/bin/fovea-trackerd --config /etc/fovea/trackerd.toml" "$WORK/unit/fovea-trackerd.service" ||
      fail "the packaged unit's ExecStart: $(grep ExecStart= "$R/lib/systemd/system/fovea-trackerd.service")"
    out=$(systemd-analyze verify "$WORK/unit/fovea-trackerd.service" 2>&1) || fail "systemd-analyze verify: $out"
    echo "build-packages: systemd-analyze verify: the unit is valid${out:+ ($out)}"
  else
    echo "build-packages: systemd-analyze not here: the unit is not verified"
  fi
  PYTHONPATH=$R/usr/lib/python3/dist-packages /usr/bin/python3 -c 'import fovea, sys; assert fovea.__file__.startswith(sys.argv[1]), fovea.__file__' "$R" ||
    fail "import fovea from python3-fovea"
  run_packaged_daemon "$R"
  "$R/usr/bin/fovea-ctl" convert "$SRC/tests/data/recordings/synthetic-250hz-62s.fgr" "$WORK/bids" --format bids \
    --subject 01 --task check >"$WORK/bids.log" 2>&1 || fail "BIDS export with the packaged fovea-ctl: $(tail -n 5 "$WORK/bids.log")"
  echo "build-packages: the packaged fovea-ctl exports a recording to BIDS"
  cmake -S "$SRC/examples" -B "$WORK/ex" -DCMAKE_PREFIX_PATH="$R/usr" >"$WORK/ex.log" 2>&1 && cmake --build "$WORK/ex" >>"$WORK/ex.log" 2>&1 ||
    fail "the example against libfovea-client-dev (CMake): $(tail -n 8 "$WORK/ex.log")"
  PKG_CONFIG_PATH=$R/usr/lib/$multiarch/pkgconfig c++ -std=c++20 "$SRC/examples/client.cpp" -o "$WORK/ex-pc" \
    $(PKG_CONFIG_PATH=$R/usr/lib/$multiarch/pkgconfig pkg-config --cflags --libs fovea-client) 2>"$WORK/pc.log" ||
    fail "the example against libfovea-client-dev (pkg-config): $(tail -n 8 "$WORK/pc.log")"
  echo "build-packages: examples/client.cpp builds against the packaged SDK (CMake and pkg-config)"
  if command -v lintian >/dev/null; then
    lintian --tag-display-limit 0 --info "$DEBS"/*.deb >"$WORK/lintian.txt" 2>&1 || true
    echo "build-packages: lintian ($(grep -c '^[EWIP]:' "$WORK/lintian.txt" || true) findings):"
    sed 's/^/  /' "$WORK/lintian.txt"
    ! grep -q '^E:' "$WORK/lintian.txt" || fail "lintian reports errors (above)"
  else
    echo "build-packages: lintian not here: not run"
  fi
}

if [ -n "$CHECK_ONLY" ]; then check "$(cd "$CHECK_ONLY" && pwd)"; else build; check "$OUT"; fi
echo "build-packages: ok ($OUT)"

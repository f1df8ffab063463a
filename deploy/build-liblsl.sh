#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Builds liblsl (the Lab Streaming Layer library, which Debian does not package) from the source kept
# in ../shared/third_party into a cached prefix, for this project's own CI and tests (issue 27). Users
# install upstream's release .deb instead (README, "Lab Streaming Layer").
#   deploy/build-liblsl.sh            prints the prefix (building it first when missing), exit 0
#   exit 3 (and a message): no liblsl source here; the LSL parts are then not built
# The prefix: $FOVEA_LSL_PREFIX, default ~/.cache/fovea/liblsl-1.16.2. A prefix holding
# LSLConfig.cmake is reused as is (about 3-5 minutes to build on 2 cores otherwise).
set -euo pipefail
SRC=$(cd "$(dirname "$0")/.." && pwd)
VERSION=1.16.2
TARBALL=${FOVEA_LSL_SOURCE:-$SRC/../shared/third_party/liblsl-$VERSION.tar.gz}
PREFIX=${FOVEA_LSL_PREFIX:-${XDG_CACHE_HOME:-$HOME/.cache}/fovea/liblsl-$VERSION}

# Installed (upstream's .deb puts it under /usr): nothing to build; CMake finds it by itself.
for sys in /usr /usr/local; do
  if [ -n "$(find "$sys/lib" "$sys/share" -maxdepth 4 -name LSLConfig.cmake 2>/dev/null | head -n 1)" ]; then echo "$sys"; exit 0; fi
done
config=$(find "$PREFIX" -name LSLConfig.cmake 2>/dev/null | head -n 1 || true)
if [ -n "$config" ]; then echo "$PREFIX"; exit 0; fi
if [ ! -f "$TARBALL" ]; then
  echo "build-liblsl: no liblsl source at $TARBALL: the LSL parts are not built" >&2
  exit 3
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "build-liblsl: building liblsl $VERSION into $PREFIX" >&2
tar xzf "$TARBALL" -C "$work"
cmake -S "$work/liblsl-$VERSION" -B "$work/build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DLSL_UNIXFOLDERS=ON \
  -DCMAKE_INSTALL_PREFIX="$PREFIX" >"$work/configure.log" 2>&1 || { tail -n 20 "$work/configure.log" >&2; exit 1; }
cmake --build "$work/build" -j "${FOVEA_JOBS:-$(nproc)}" >"$work/build.log" 2>&1 || { tail -n 20 "$work/build.log" >&2; exit 1; }
cmake --install "$work/build" >"$work/install.log" 2>&1 || { tail -n 20 "$work/install.log" >&2; exit 1; }
echo "$PREFIX"

#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Packs fovea-render (and make_gltf_standin, bench_gl, bench_dof and bench_attention, where built) and the shared libraries they need (from ldd)
# into .gpu-bundle/bundle.tar.xz, for
# the GPU machine, which has no package registry: bench/device/gpu-frame.sh unpacks and runs it there.
# Left out: glibc (the machine's own is newer), libstdc++/libgcc_s (likewise), and the OpenGL/EGL
# dispatch libraries (libglvnd), which must be the machine's so that its NVIDIA driver is found. For
# a machine without libglvnd, its Debian packages travel beside the tarball (.gpu-bundle/glvnd/) and
# gpu-frame.sh unpacks them only where libEGL.so.1 is missing.
# Usage: bench/device/make-bundle.sh [BUILD_DIR]   (default build/default)
set -euo pipefail
cd "$(dirname "$0")/../.."
BUILD=${1:-build/default}
BIN=$BUILD/renderer/fovea-render
DEST=.gpu-bundle
[ -x "$BIN" ] || { echo "make-bundle: $BIN not built" >&2; exit 2; }
grep -qx '/.gpu-bundle/' .git/info/exclude 2>/dev/null || echo '/.gpu-bundle/' >>.git/info/exclude
rm -rf "$DEST" && mkdir -p "$DEST/glvnd"
stage=$(mktemp -d)
trap 'rm -rf "$stage"' EXIT
mkdir -p "$stage/lib"
strip --strip-debug -o "$stage/fovea-render.bin" "$BIN"
# The glTF stand-in's generator (bench/device/gpu-gltf.sh makes the scene there: 28 MB of data stays here).
# bench_gl: the effect passes alone, fragment against compute (gpu-effects.sh).
# bench_dof, bench_attention: the DOF's and attention's accuracy against time there, the governor's
# device fronts (gpu-fronts.sh).
EXTRA=()
for tool in make_gltf_standin bench_gl bench_dof bench_attention; do
  if [ -x "$BUILD/bench/$tool" ]; then
    strip --strip-debug -o "$stage/$tool.bin" "$BUILD/bench/$tool"
    EXTRA+=("$BUILD/bench/$tool")
  fi
done
# GDAL: OpenCV's imgcodecs links it (for GIS rasters, which fovea never reads) and with it some 40
# libraries (PROJ, HDF5, Poppler, x265, ICU data...), 136 MB that would push the bundle over the 64 MiB
# the device tool carries. The bundle gets a stand-in libgdal.so.32 instead, defining the functions
# imgcodecs imports (it is linked BIND_NOW, so each must exist): registering does nothing, opening
# opens nothing, and any other function aborts with a message.
standin_gdal() {
  local gdal imgcodecs
  # awk reads all of ldconfig's list (no exit at the first match): ldconfig's SIGPIPE failed the
  # assignment under pipefail whenever awk quit before ldconfig had written everything.
  gdal=$(ldconfig -p | awk '$1 == "libgdal.so.32" && !n++ {print $NF}')
  imgcodecs=$(ldconfig -p | awk '$1 == "libopencv_imgcodecs.so.406" && !n++ {print $NF}')
  [ -n "$gdal" ] && [ -n "$imgcodecs" ] || return 0
  mkdir -p "$stage/standin"
  nm -D --defined-only "$gdal" | awk '{print $3}' | sort -u >"$stage/standin/defined"
  {
    echo '#include <stdio.h>'
    echo '#include <stdlib.h>'
    echo 'static void gone(const char *s) { fprintf(stderr, "fovea device bundle: %s called, but libgdal is a stand-in here (bench/device/make-bundle.sh)\n", s); abort(); }'
    nm -D --undefined-only "$imgcodecs" | awk '{print $2}' | sort -u | comm -12 - "$stage/standin/defined" |
      grep -vxE 'GDALAllRegister|GDALOpen' | while read -r sym; do echo "void $sym(void) { gone(\"$sym\"); }"; done
    # imgcodecs registers its GDAL decoder on first use (GDALAllRegister: nothing to register here);
    # GDALOpen, reached only with IMREAD_LOAD_GDAL, opens nothing.
    echo 'void GDALAllRegister(void) {}'
    echo 'void *GDALOpen(const char *path, int access) { (void)path; (void)access; return NULL; }'
  } >"$stage/standin/gdal.c"
  cc -shared -fPIC -O1 -o "$stage/standin/libgdal.so.32" -Wl,-soname,libgdal.so.32 "$stage/standin/gdal.c"
}
standin_gdal
for bin in "$BIN" "${EXTRA[@]}"; do LD_LIBRARY_PATH="$stage/standin" ldd "$bin"; done | awk '$3 ~ /^\// {print $3}' | sort -u |
  grep -vE '/(libc|libm|libpthread|libdl|librt|libresolv|ld-linux-x86-64|libstdc\+\+|libgcc_s|libGL|libEGL|libGLX|libGLdispatch|libOpenGL)[.-]' |
  while read -r lib; do cp -L "$lib" "$stage/lib/"; done
rm -rf "$stage/standin"
cat >"$stage/fovea-render" <<'W'
#!/bin/sh
# The carried fovea-render with its carried libraries (only for this process: the machine's own
# programs keep theirs).
here=$(dirname "$(readlink -f "$0")")
LD_LIBRARY_PATH="$here/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" exec "$here/fovea-render.bin" "$@"
W
chmod +x "$stage/fovea-render"
for tool in make_gltf_standin bench_gl bench_dof bench_attention; do
  if [ -f "$stage/$tool.bin" ]; then
    sed "s/fovea-render\.bin/$tool.bin/" "$stage/fovea-render" >"$stage/$tool"
    chmod +x "$stage/$tool"
  fi
done
tar -C "$stage" -cf - . | xz -T0 -6 >"$DEST/bundle.tar.xz"
(cd "$DEST/glvnd" && apt-get download libegl1 libglvnd0 libopengl0 libgl1 libglx0 >/dev/null 2>&1) ||
  echo "make-bundle: could not download libglvnd's packages (apt-get update first?); the machine's own must do" >&2
du -sh "$DEST"/* | sed 's/^/make-bundle: /'

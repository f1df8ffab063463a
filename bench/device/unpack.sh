# SPDX-License-Identifier: Apache-2.0
# Sourced by the device scripts (gpu-frame.sh, gpu-effects.sh): unpacks the bundle that
# bench/device/make-bundle.sh made here (.gpu-bundle, carried) into $run, makes EGL find the NVIDIA
# driver, and says which card and driver the figures come from.
[ -f .gpu-bundle/bundle.tar.xz ] || { echo "device: .gpu-bundle/bundle.tar.xz missing: run bench/device/make-bundle.sh here and carry .gpu-bundle" >&2; exit 2; }
run=$(mktemp -d)
tar -C "$run" -xJf .gpu-bundle/bundle.tar.xz

# EGL through libglvnd: the machine's own, else the carried Debian packages.
if ! ldconfig -p | grep -q 'libEGL.so.1 '; then
  echo "device: no libEGL.so.1 here: unpacking the carried libglvnd"
  for f in .gpu-bundle/glvnd/*.deb; do dpkg -x "$f" /; done
  ldconfig
fi
for json in /usr/share/glvnd/egl_vendor.d/10_nvidia.json /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json; do
  if [ -f "$json" ]; then export __EGL_VENDOR_LIBRARY_FILENAMES=$json; break; fi
done
echo "device: $(nvidia-smi -L 2>/dev/null || echo 'nvidia-smi: none'); driver $(nvidia-smi --query-gpu=driver_version --format=csv,noheader 2>/dev/null || echo '?'); EGL vendor ${__EGL_VENDOR_LIBRARY_FILENAMES:-default}"
echo "device: $(nproc) CPU cores"

#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Installs every Debian 12 package fovea needs to build, test, benchmark and run.
# This file is the only place package names are listed. Idempotent: packages
# already present are not reinstalled, and nothing happens when all are there.
set -euo pipefail

PACKAGES=(
  # toolchain
  build-essential g++ cmake ninja-build pkg-config git
  universal-ctags                     # dev/long-functions (function lengths)
  scdoc                               # the man pages (man/*.scd -> roff, at build time)
  clang libclang-rt-14-dev            # libFuzzer target and its sanitizer runtimes
  ccache                              # deploy/test.sh: a rerun on a fresh clone recompiles only what changed
  # protocol, daemon and CLI
  libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev libtomlplusplus-dev
  libsystemd-dev
  libboost-dev                        # fovea-monitor: Boost.Beast (HTTP and WebSocket, header-only)
  libsodium-dev                       # the subscription cookies' MAC and key (no hand-written cryptography)
  zlib1g-dev                          # gzip of the BIDS export's .tsv.gz files (fovea-ctl convert --format bids)
  # tracker hardware
  libhidapi-dev libusb-1.0-0-dev libv4l-dev
  libzmq3-dev cppzmq-dev libmsgpack-cxx-dev  # Pupil Core's network API (ZeroMQ, msgpack)
  libx11-dev                          # the mouse source (the X11 pointer as gaze)
  # vision
  libopencv-dev libopencv-contrib-dev
  # renderer
  libembree-dev libtbb-dev libglfw3-dev libgl-dev libgl1-mesa-dri libglm-dev
  libassimp-dev libmeshoptimizer-dev libnanoflann-dev libopenexr-dev
  libpng-dev                          # the renderer's PNG frames
  libepoxy-dev                        # OpenGL function loading for the core profile
  libegl-dev libegl1 libegl-mesa0     # headless OpenGL through EGL (Mesa's surfaceless platform, llvmpipe)
  xvfb xauth                          # an X server for the tests of the GLFW window (the viewer)
  # tests, benchmarks, report plots
  libgtest-dev libgmock-dev googletest libbenchmark-dev python3 python3-matplotlib
  python3-zmq python3-msgpack         # the fake Pupil Capture of the tests (tests/fakes/)
  python3-sklearn                     # bench/train_classifier.py: fits the gbt classifier's trees
  chromium                            # fovea-monitor's page tested in a real browser (headless; tests only)
  # packaging: the Python package (python/), the Debian packages (debian/)
  python3-setuptools python3-pip python3-wheel
  debhelper dh-python fakeroot lintian python3-all pybuild-plugin-pyproject python3-build python3-installer
)

# Node.js and npm run the browser test (tests/browser: puppeteer-core). A machine that has them
# (any source) keeps its own; otherwise Debian's are installed.
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  PACKAGES+=(nodejs npm)
fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "install-deps: need root or sudo to install: ${missing[*]}" >&2; exit 1
  fi
fi

echo "install-deps: installing ${#missing[@]} package(s): ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done"

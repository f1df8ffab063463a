#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Runs a command with its own Xvfb server, for what opens an X window (fovea-render's viewer,
# fovea-calibrate's target window): Mesa llvmpipe OpenGL, no GPU or real display needed. Headless
# OpenGL (fovea-render --headless, the GL tests and benchmarks) needs no X server: it uses EGL.
# Unlike `xvfb-run -a`, the server picks a free display number itself (-displayfd), so several of
# these can start at the same moment (parallel tests) without racing.
# Usage: deploy/with-xvfb.sh COMMAND [ARGS...]
set -u
if ! command -v Xvfb >/dev/null 2>&1; then
  echo "with-xvfb: Xvfb not found (package xvfb; run deploy/install-deps.sh)" >&2
  exit 127
fi
fifo_dir=$(mktemp -d)
mkfifo "$fifo_dir/displayfd"
Xvfb -displayfd 3 -screen 0 1280x1024x24 -nolisten tcp -noreset 3>"$fifo_dir/displayfd" >"$fifo_dir/xvfb.log" 2>&1 &
xvfb_pid=$!
display=""
read -r -t 20 display <"$fifo_dir/displayfd" || true
if [ -z "$display" ]; then
  echo "with-xvfb: Xvfb did not start: $(tail -n 5 "$fifo_dir/xvfb.log")" >&2
  kill "$xvfb_pid" 2>/dev/null
  rm -rf "$fifo_dir"
  exit 1
fi
cleanup() { kill "$xvfb_pid" 2>/dev/null; wait "$xvfb_pid" 2>/dev/null; rm -rf "$fifo_dir"; }
trap cleanup EXIT
trap 'exit 143' TERM
trap 'exit 130' INT
DISPLAY=":$display" "$@"

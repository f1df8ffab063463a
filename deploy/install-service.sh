#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Installs fovea-trackerd as a systemd service. Idempotent: run it again after a rebuild to update
# the binaries, the unit and the udev rules; an existing /etc/fovea/trackerd.toml is never touched.
#
#   deploy/install-service.sh [--enable] [--build-dir DIR] [--prefix DIR]
#   deploy/install-service.sh --uninstall        # keeps /etc/fovea, /var/lib/fovea and the fovea user
#   deploy/install-service.sh --root DIR ...     # stage into DIR (no users, systemctl or udevadm; for testing)
#
# Build first (release): cmake --preset default && cmake --build --preset default
# What it does (as root, via sudo when needed):
#   1. creates the system group and user "fovea" (no login, home /var/lib/fovea)
#   2. cmake --install BUILD --prefix /usr/local   (fovea-trackerd, fovea-ctl, ...)
#   3. /etc/fovea/trackerd.toml from deploy/trackerd.toml, only if absent; then --check-config
#   4. /etc/systemd/system/fovea-trackerd.service, /etc/udev/rules.d/70-fovea-trackers.rules
#   5. systemctl daemon-reload; udevadm control --reload; udevadm trigger for hidraw/video4linux/usb
#   6. with --enable: systemctl enable --now fovea-trackerd (or reload it when it already runs)
set -euo pipefail

HERE=$(cd "$(dirname "$0")" && pwd)
SRC=$(cd "$HERE/.." && pwd)
BUILD=$SRC/build/default
PREFIX=/usr/local
ROOT=""
ENABLE=0
UNINSTALL=0
while [ $# -gt 0 ]; do
  case $1 in
    --enable) ENABLE=1 ;;
    --uninstall) UNINSTALL=1 ;;
    --build-dir) BUILD=$(cd "$2" && pwd); shift ;;
    --prefix) PREFIX=$2; shift ;;
    --root) ROOT=$(mkdir -p "$2" && cd "$2" && pwd); shift ;;
    -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
    *) echo "install-service: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
  shift
done

SUDO=""
if [ -z "$ROOT" ] && [ "$(id -u)" -ne 0 ]; then SUDO=sudo; fi
run() { echo "+ $*"; $SUDO "$@"; }
CONF_DIR=$ROOT/etc/fovea
UNIT=$ROOT/etc/systemd/system/fovea-trackerd.service
RULES=$ROOT/etc/udev/rules.d/70-fovea-trackers.rules
# systemd and udev only when they run here and we are not staging.
have_systemd() { [ -z "$ROOT" ] && [ -d /run/systemd/system ] && command -v systemctl >/dev/null; }
have_udev() { [ -z "$ROOT" ] && command -v udevadm >/dev/null && [ -d /run/udev ]; }

if [ $UNINSTALL -eq 1 ]; then
  if have_systemd; then
    run systemctl disable --now fovea-trackerd.service 2>/dev/null || true
  fi
  run rm -f "$UNIT" "$RULES"
  if [ -f "$BUILD/install_manifest.txt" ] && [ -z "$ROOT" ]; then
    # Only what cmake --install put there.
    while IFS= read -r f; do [ -n "$f" ] && run rm -f "$f"; done <"$BUILD/install_manifest.txt"
  else
    run rm -f "$ROOT$PREFIX/bin/fovea-trackerd" "$ROOT$PREFIX/bin/fovea-ctl"
  fi
  if have_systemd; then run systemctl daemon-reload; fi
  if have_udev; then run udevadm control --reload; fi
  echo "install-service: uninstalled; kept $CONF_DIR (configuration), $ROOT/var/lib/fovea (recordings)"
  echo "  and the fovea user and group (remove with: userdel fovea; groupdel fovea)"
  exit 0
fi

if [ ! -x "$BUILD/trackerd/fovea-trackerd" ]; then
  echo "install-service: $BUILD/trackerd/fovea-trackerd not found; build first:" >&2
  echo "  cmake --preset default && cmake --build --preset default" >&2
  exit 1
fi

# 1. user and group (the udev rules name the group, so it must exist before they are loaded)
if [ -z "$ROOT" ]; then
  getent group fovea >/dev/null || run groupadd --system fovea
  getent passwd fovea >/dev/null ||
    run useradd --system --gid fovea --home-dir /var/lib/fovea --no-create-home \
      --shell /usr/sbin/nologin --comment "fovea eye-tracking daemon" fovea
fi

# 2. binaries
if [ -n "$ROOT" ]; then
  DESTDIR=$ROOT run cmake --install "$BUILD" --prefix "$PREFIX"
else
  run cmake --install "$BUILD" --prefix "$PREFIX"
fi

# 3. configuration: never overwrite an existing one
run install -d -m 0755 "$CONF_DIR"
if [ -e "$CONF_DIR/trackerd.toml" ]; then
  echo "install-service: keeping existing $CONF_DIR/trackerd.toml (example: $SRC/deploy/trackerd.toml)"
else
  run install -m 0644 "$SRC/deploy/trackerd.toml" "$CONF_DIR/trackerd.toml"
fi
if ! $SUDO "$ROOT$PREFIX/bin/fovea-trackerd" --check-config --config "$CONF_DIR/trackerd.toml" >/dev/null; then
  echo "install-service: $CONF_DIR/trackerd.toml is invalid (see above); fix it before starting the service" >&2
  exit 1
fi

# 4. unit and udev rules (the unit names the binary's installed path)
run install -d -m 0755 "$(dirname "$UNIT")" "$(dirname "$RULES")"
sed "s#/usr/local/bin/fovea-trackerd#$PREFIX/bin/fovea-trackerd#" "$SRC/deploy/fovea-trackerd.service" |
  $SUDO tee "$UNIT.tmp" >/dev/null
run chmod 0644 "$UNIT.tmp"
run mv -f "$UNIT.tmp" "$UNIT"
run install -m 0644 "$SRC/deploy/70-fovea-trackers.rules" "$RULES"

# 5. tell systemd and udev
if have_systemd; then run systemctl daemon-reload; else echo "install-service: systemd not running here; skipped daemon-reload"; fi
if have_udev; then
  run udevadm control --reload
  run udevadm trigger --action=change --subsystem-match=hidraw --subsystem-match=video4linux --subsystem-match=usb
else
  echo "install-service: udev not running here; skipped udevadm reload/trigger"
fi

# 6. enable
if [ $ENABLE -eq 1 ] && have_systemd; then
  if systemctl is-active --quiet fovea-trackerd; then
    run systemctl restart fovea-trackerd   # new binary
  else
    run systemctl enable --now fovea-trackerd
  fi
  systemctl --no-pager status fovea-trackerd | head -n 5 || true
else
  echo "install-service: installed. Start it now and at boot with: sudo systemctl enable --now fovea-trackerd"
fi

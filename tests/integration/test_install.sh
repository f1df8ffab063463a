#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# `cmake --install` installs everything a package needs (issue 26 item 5), to the GNUInstallDirs
# places: every binary, the systemd unit naming the installed binary and configuration, the udev
# rules, sysusers.d/tmpfiles.d entries, the example configuration (never replacing an edited one),
# the man pages, the bundled scenes, the client SDK. Checked for a private prefix (configuration under
# PREFIX/etc) and for a staged /usr install (DESTDIR; configuration in /etc, as GNUInstallDirs says).
# Usage: test_install.sh BUILD_DIR
set -u
BUILD=$1
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

expect_files() {  # ROOT PATH...
  local root=$1; shift
  for f in "$@"; do [ -e "$root/$f" ] || fail "not installed: $f (under $root; have: $(cd "$root" && find . -type f | sort | head -40 | tr '\n' ' '))"; done
}
COMMON=(bin/fovea-trackerd bin/fovea-ctl bin/fovea-render bin/fovea-calibrate bin/fovea-lod
        lib/systemd/system/fovea-trackerd.service lib/udev/rules.d/70-fovea-trackers.rules
        lib/sysusers.d/fovea.conf lib/tmpfiles.d/fovea.conf
        share/man/man8/fovea-trackerd.8 share/man/man1/fovea-ctl.1 share/man/man1/fovea-render.1
        share/man/man1/fovea-calibrate.1 share/man/man1/fovea-lod.1 share/man/man5/trackerd.toml.5
        share/fovea/scenes/attention.json share/fovea/scenes/meshes/blob.obj
        include/fovea/protocol/client.h lib/cmake/fovea/foveaConfig.cmake lib/pkgconfig/fovea-client.pc)

echo "== cmake --install --prefix P"
P=$WORK/prefix
cmake --install "$BUILD" --prefix "$P" >"$WORK/install.log" 2>&1 || fail "install: $(tail -5 "$WORK/install.log")"
expect_files "$P" "${COMMON[@]}" etc/fovea/trackerd.toml
[ -z "$(find "$P" -name '*.py')" ] || fail "a build script was installed: $(find "$P" -name '*.py')"
unit=$P/lib/systemd/system/fovea-trackerd.service
grep -qx "ExecStart=$P/bin/fovea-trackerd --config $P/etc/fovea/trackerd.toml" "$unit" \
  || fail "the unit does not name the installed binary and configuration: $(grep ExecStart "$unit")"
for b in fovea-trackerd fovea-ctl fovea-render fovea-calibrate fovea-lod; do
  "$P/bin/$b" --version >/dev/null 2>&1 || fail "$P/bin/$b --version"
done
"$P/bin/fovea-trackerd" --check-config --config "$P/etc/fovea/trackerd.toml" >/dev/null 2>&1 \
  || fail "the installed example configuration is refused: $("$P/bin/fovea-trackerd" --check-config --config "$P/etc/fovea/trackerd.toml" 2>&1 | tail -3)"
if command -v systemd-analyze >/dev/null; then
  out=$(systemd-analyze verify "$unit" 2>&1) || fail "systemd-analyze verify: $out"
  echo "systemd-analyze verify: ok"
else
  echo "systemd-analyze: not here; the unit is not verified"
fi

echo "== a reinstall keeps an edited configuration"
echo "# edited by the administrator" >>"$P/etc/fovea/trackerd.toml"
cmake --install "$BUILD" --prefix "$P" >"$WORK/install2.log" 2>&1 || fail "reinstall: $(tail -5 "$WORK/install2.log")"
tail -n 1 "$P/etc/fovea/trackerd.toml" | grep -q "edited by the administrator" || fail "the reinstall replaced the edited configuration"
grep -q "Keeping: $P/etc/fovea/trackerd.toml" "$WORK/install2.log" || fail "the reinstall did not say it kept the configuration"

echo "== DESTDIR=D cmake --install --prefix /usr"
D=$WORK/stage
DESTDIR=$D cmake --install "$BUILD" --prefix /usr >"$WORK/install3.log" 2>&1 || fail "staged install: $(tail -5 "$WORK/install3.log")"
expect_files "$D/usr" "${COMMON[@]}"
expect_files "$D" etc/fovea/trackerd.toml
[ -e "$D/usr/etc" ] && fail "the configuration went to /usr/etc, not /etc"
grep -qx "ExecStart=/usr/bin/fovea-trackerd --config /etc/fovea/trackerd.toml" "$D/usr/lib/systemd/system/fovea-trackerd.service" \
  || fail "staged unit: $(grep ExecStart "$D/usr/lib/systemd/system/fovea-trackerd.service")"
echo "PASS"

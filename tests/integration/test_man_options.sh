#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The man pages keep up with the programs (issue 26 item 3): every long option and subcommand that a
# program's --help lists (its subcommands' --help too) is in its page's source (man/*.scd), every
# section and key of the example configuration (deploy/trackerd.toml) is in trackerd.toml(5), and
# each page was built (scdoc) when scdoc is installed.
# Usage: test_man_options.sh SOURCE_DIR BUILD_DIR PAGE=BINARY...
set -u
SRC=$1 BUILD=$2
shift 2
missing=0
say() { echo "MISSING: $*"; missing=$((missing + 1)); }

options_of() { grep -o -- '--[a-zA-Z][a-zA-Z0-9-]*' | sort -u; }
# The option as a whole token (--time-ns is not in a page that says only --time-nsec).
has() { grep -qE -- "(^|[^a-zA-Z0-9-])$1([^a-zA-Z0-9-]|\$)" "$2"; }
subcommands_of() { sed -n '/^Subcommands:/,$p' | sed -n 's/^  \([a-z][a-z0-9-]*\)  .*/\1/p'; }

for pair in "$@"; do
  page=${pair%%=*} bin=${pair#*=}
  scd=$SRC/man/$page.scd
  [ -f "$scd" ] || { say "$page: no man/$page.scd"; continue; }
  help=$("$bin" --help 2>&1) || { say "$page: $bin --help failed"; continue; }
  for opt in $(options_of <<<"$help"); do
    has "$opt" "$scd" || say "$page: $opt (from $(basename "$bin") --help)"
  done
  for sub in $(subcommands_of <<<"$help"); do
    grep -qw -- "$sub" "$scd" || say "$page: subcommand $sub"
    for opt in $("$bin" "$sub" --help 2>&1 | options_of); do
      has "$opt" "$scd" || say "$page: $opt (from $(basename "$bin") $sub --help)"
    done
  done
  if command -v scdoc >/dev/null; then
    [ -s "$BUILD/man/$page" ] || say "$page: not built into $BUILD/man/$page"
  fi
done

conf=$SRC/man/trackerd.toml.5.scd
if [ -f "$conf" ]; then
  for section in $(sed -n 's/^#* *\[\([a-z_]*\)\].*/\1/p' "$SRC/deploy/trackerd.toml" | sort -u); do
    grep -qF "[$section]" "$conf" || say "trackerd.toml.5: section [$section]"
  done
  for key in $(sed -n 's/^#* *\([a-z_][a-z0-9_]*\) *=.*/\1/p' "$SRC/deploy/trackerd.toml" | sort -u); do
    grep -qw -- "$key" "$conf" || say "trackerd.toml.5: key $key (deploy/trackerd.toml)"
  done
fi
[ "$missing" -eq 0 ] || { echo "FAIL: $missing missing from the man pages"; exit 1; }
echo "PASS: every option, subcommand and configuration key is in its man page"

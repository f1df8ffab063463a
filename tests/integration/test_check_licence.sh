#!/bin/bash
# SPDX-License-Identifier: Apache-2.0
# The licence check CI relies on: the checkout passes, and a source file without the SPDX line
# (C++, Python, shell, an extensionless script) fails it by name until --fix adds the line.
# Usage: test_check_licence.sh SOURCE_DIR
set -euo pipefail
src=$1
python3 "$src/dev/check-licence" "$src"

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
git -C "$work" init -q
printf '#pragma once\nint f();\n' > "$work/a.h"
printf '#!/bin/sh\necho hi\n' > "$work/tool"
printf '"""doc"""\n' > "$work/m.py"
printf '// SPDX-License-Identifier: Apache-2.0\nint g();\n' > "$work/ok.cpp"
mkdir -p "$work/tests/data" && printf 'x\n' > "$work/tests/data/blob.sh"
git -C "$work" add -A
if out=$(python3 "$src/dev/check-licence" "$work" 2>&1); then
  echo "FAIL: files without the licence line passed"; exit 1
fi
for f in a.h tool m.py; do
  grep -q "^$f: no 'SPDX-License-Identifier: Apache-2.0'" <<<"$out" || { echo "FAIL: $f not named: $out"; exit 1; }
done
if grep -q -e ok.cpp -e blob.sh <<<"$out"; then echo "FAIL: a good file or test data named: $out"; exit 1; fi
python3 "$src/dev/check-licence" --fix "$work" >/dev/null
[ "$(sed -n 2p "$work/tool")" = "# SPDX-License-Identifier: Apache-2.0" ] || { echo "FAIL: shebang not kept first"; exit 1; }
[ "$(head -n 1 "$work/a.h")" = "// SPDX-License-Identifier: Apache-2.0" ] || { echo "FAIL: C++ line"; exit 1; }
python3 "$src/dev/check-licence" "$work" >/dev/null
echo "check-licence: passes the tree, names files without the line, --fix adds it"

#!/usr/bin/env bash
# The Blender add-on, headless (Debian's `blender`): installed with apt when missing and root,
# else skipped with a notice. Needs the venv of scripts/python-tests (the installed wheel).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../../.."
VENV=target/python-venv

if ! command -v blender >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        echo "==> installing blender (Debian package)"
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq blender >/dev/null 2>&1 || true
    fi
fi
if ! command -v blender >/dev/null 2>&1; then
    echo "notice: skipped the Blender add-on test: blender is not installed and cannot be installed here"
    exit 0
fi
# Blender's Python must match the wheel's ABI (abi3, CPython >= 3.9): only the relief package
# is put on its path (Blender keeps its own numpy).
site=$("$VENV/bin/python" -c 'import relief, os; print(os.path.dirname(os.path.dirname(relief.__file__)))')
pkg=$(mktemp -d)
trap 'rm -rf "$pkg"' EXIT
cp -r "$site/relief" "$pkg/"
dem="$pkg/dem.tif"
"$VENV/bin/python" - "$dem" <<'PY'
import sys, relief
r = relief.read("fixtures/grandcanyon.tif")
relief.write(sys.argv[1], relief.Raster(r.array[100:148, 200:260].copy(), r.transform, r.crs, r.cell_size))
PY
out=$(blender -b --factory-startup --python crates/python/blender/test_blender.py -- "$pkg" "$dem" "$PWD/fixtures/grandcanyon.tif" 2>&1) || {
    echo "$out" | tail -30
    echo "error: the Blender add-on test failed" >&2
    exit 1
}
echo "$out" | grep "blender add-on: ok"

#!/usr/bin/env bash
# The bundle in Blender (issue 20): a small `can` capture is reconstructed and its object.glb
# imported by Blender's own glTF importer (tools/blender-import.py), which checks: one mesh object
# with the mesh's triangles, the atlas's vertices (at most 1.3 times the input mesh's), and at most
# one connected part per atlas chart, not one loose triangle each.
# Skips (exit 77) when Blender is not installed (tools/install-deps.sh installs Debian's).
# usage: blender_check.sh SPECULA_BINARY SOURCE_DIR
set -euo pipefail
specula=$1
src=$2
if ! command -v blender >/dev/null 2>&1; then echo "SKIP: no Blender (tools/install-deps.sh installs it)"; exit 77; fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$specula" synth --preset can --size 96 --views 6 --lights 3 --out "$work/capture" >/dev/null
"$specula" reconstruct "$work/capture" -o "$work/result" --no-html >/dev/null 2>"$work/reconstruct.log" ||
  { cat "$work/reconstruct.log"; exit 1; }
set +e
blender -b --factory-startup --python-exit-code 2 --python "$src/tools/blender-import.py" -- \
  "$work/result/object.glb" --expect "$work/result/report.json" >"$work/blender.log" 2>&1
rc=$?
set -e
grep "^blender-import" "$work/blender.log" || true
if [ "$rc" -ne 0 ]; then
  echo "FAIL: Blender's import (exit $rc):"
  tail -n 30 "$work/blender.log"
  exit 1
fi

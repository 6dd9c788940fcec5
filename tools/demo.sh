#!/usr/bin/env bash
# The main job on the bundled demo capture: installs dependencies, builds, makes
# the demo capture (the `can` preset, 20 views x 6 lights + test frames, 512x512)
# under out/demo/capture, validates it, and reconstructs it into out/demo/result
# (report.html, object.glb, albedo.exr/png, sheets/, evaluation.json, report.json).
# With --sweep, also the error-against-run-time sweep into out/demo/sweep
# (sweep.svg, sweep.csv, sweep.json; a few minutes on lavapipe).
set -euo pipefail
sweep=0
for arg in "$@"; do
  case "$arg" in
    --sweep) sweep=1 ;;
    -h|--help) sed -n '2,7p' "$0"; exit 0 ;;
    *) echo "demo.sh: unknown argument '$arg' (only --sweep)" >&2; exit 2 ;;
  esac
done
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$root/tools/install-deps.sh"
"$root/tools/build.sh"
specula="$root/build/tools/specula/specula"
out="$root/out/demo"
mkdir -p "$out"
"$specula" synth --preset can --out "$out/capture" --force
"$specula" validate "$out/capture"
"$specula" reconstruct "$out/capture" -o "$out/result"
echo "demo: capture in $out/capture, reconstruction in $out/result"
echo "demo: open $out/result/report.html (self-contained: quality, planner decisions, times, lobe, sheets)"
if [ "$sweep" = 1 ]; then
  "$specula" bench sweep "$out/capture" -o "$out/sweep"
  echo "demo: error against run time in $out/sweep/sweep.svg (table: sweep.csv, sweep.json)"
fi

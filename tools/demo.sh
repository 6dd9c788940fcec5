#!/usr/bin/env bash
# The main job on the bundled demo capture: installs dependencies, builds, makes
# the demo capture (the `can` preset, 20 views x 6 lights + test frames, 512x512)
# under out/demo/capture, validates it, and reconstructs it into out/demo/result
# (albedo.exr, albedo.png, report.json).
set -euo pipefail
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

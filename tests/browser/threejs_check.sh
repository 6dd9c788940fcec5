#!/usr/bin/env bash
# The bundle in a real browser (issue 20): a small `can` capture (128 px) is reconstructed, its
# object.glb rendered by three.js (GLTFLoader, the material it makes) in headless Chromium under
# the capture's cameras and lights (tools/threejs-render.mjs), and the renders scored against the
# captured images by `specula evaluate --renders`. Asserts, on 4 train and 4 test frames:
#   - three.js draws what Specula's own render of the core material draws (`--specular core`,
#     shared/gltf_core.h): masked display PSNR within 0.5 dB per split without shadows, and within
#     0.75 dB with them (each its own shadow map: three.js's PCF edges against Specula's offset,
#     frustum-fitted map). Measured on the train frames with shadows: 0.46 dB with the albedo of
#     back-projection, 0.52-0.62 dB with the pixel fit's sharper one, whose renders are 1.5 dB
#     nearer the captures, while the squared error between the two renderers' figures shrank
#     (1.94e-4 -> 1.80e-4): the same shadow edges beside a smaller total error;
#   - three.js is within 2 dB of Specula's own renderer (the bundle's full model) per split;
#   - `--report` puts three.js's picture of the test sheet's frame into report.html: a PNG of the
#     capture's size with the object drawn (not an empty frame: read by oiiotool), linked from the
#     placeholder.
# Skips (exit 77) with the reason when Node.js, three.js, puppeteer-core, Chromium or WebGL is
# missing (tools/install-deps.sh installs them).
# usage: threejs_check.sh SPECULA_BINARY SOURCE_DIR
set -euo pipefail
specula=$1
src=$2
if ! command -v node >/dev/null 2>&1; then echo "SKIP: no Node.js"; exit 77; fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$specula" synth --preset can --size 128 --out "$work/capture" >/dev/null
"$specula" reconstruct "$work/capture" -o "$work/result" >/dev/null 2>"$work/reconstruct.log" ||
  { cat "$work/reconstruct.log"; exit 1; }
for shadows in on off; do
  flag=(); [ "$shadows" = off ] && flag=(--no-shadows)
  set +e
  node "$src/tools/threejs-render.mjs" --bundle "$work/result/object.glb" --capture "$work/capture" \
    --out "$work/threejs_$shadows" --max-per-split 4 "${flag[@]}" >"$work/threejs.log" 2>&1
  rc=$?
  set -e
  grep -v "^threejs-render: frame" "$work/threejs.log" || true
  if [ "$rc" -eq 3 ]; then echo "SKIP: $(grep -m1 unavailable "$work/threejs.log")"; exit 77; fi
  [ "$rc" -eq 0 ] || { cat "$work/threejs.log"; exit 1; }
done
for what in threejs threejs_off core core_off own; do
  case $what in
    threejs) extra=(--renders "$work/threejs_on") ;;
    threejs_off) extra=(--renders "$work/threejs_off" --no-shadows) ;;
    core) extra=(--specular core) ;;
    core_off) extra=(--specular core --no-shadows) ;;
    own) extra=() ;;
  esac
  "$specula" evaluate "$work/result/object.glb" "$work/capture" --frames 4 --metrics cpu --no-hausdorff \
    --json "$work/$what.json" "${extra[@]}" >/dev/null 2>&1
done
set +e
node "$src/tools/threejs-render.mjs" --report "$work/result" --capture "$work/capture" >"$work/report.log" 2>&1
rc=$?
set -e
cat "$work/report.log"
[ "$rc" -eq 0 ] || exit 1
node - "$work" <<'JS'
const fs = require('fs');
const dir = process.argv[2];
{
  // The picture in the report: a PNG of the capture's size, with the object in it.
  const html = fs.readFileSync(`${dir}/result/report.html`, 'utf8');
  const m = /<img alt="three.js"[^>]* src="([^"]+)">/.exec(html);
  if (!m) { console.log('FAIL: report.html has no three.js picture'); process.exit(1); }
  // Read by OpenImageIO (oiiotool, installed with it): its size, and its mean code over the frame.
  const stats = require('child_process').execFileSync('oiiotool', ['--stats', `${dir}/result/${m[1]}`], { encoding: 'utf8' });
  const size = /:\s*(\d+)\s*x\s*(\d+)/.exec(stats), avg = /Stats Avg:\s*([\d.]+)\s+([\d.]+)\s+([\d.]+)/.exec(stats);
  if (!size || !avg) { console.log(`FAIL: oiiotool could not read the picture:\n${stats}`); process.exit(1); }
  const cap = JSON.parse(fs.readFileSync(`${dir}/capture/capture.json`, 'utf8'));
  const w = Number(size[1]), h = Number(size[2]), mean = (Number(avg[1]) + Number(avg[2]) + Number(avg[3])) / 3;
  if (w !== cap.w || h !== cap.h) { console.log(`FAIL: the picture is ${w}x${h}, the capture ${cap.w}x${cap.h}`); process.exit(1); }
  console.log(`three.js picture: ${m[1]}, ${w}x${h}, mean code ${mean.toFixed(1)} of 255`);
  // The object on black covers about a third of the frame (mean about 25); an empty frame is 0.
  if (mean < 3) { console.log('FAIL: the three.js picture is (nearly) empty'); process.exit(1); }
}
const read = w => JSON.parse(fs.readFileSync(`${dir}/${w}.json`, 'utf8'));
const t = read('threejs'), tn = read('threejs_off'), c = read('core'), cn = read('core_off'), o = read('own');
let ok = true;
for (const split of ['train', 'test']) {
  const p = j => j[split].masked.psnr_display;
  console.log(`${split}: three.js ${p(t).toFixed(2)} dB, Specula's core render ${p(c).toFixed(2)} dB, Specula's own ` +
              `${p(o).toFixed(2)} dB; without shadows: three.js ${p(tn).toFixed(2)} dB, the core render ${p(cn).toFixed(2)} dB ` +
              `(masked display PSNR, ${t[split].masked.frames} frames)`);
  for (const j of [t, tn])
    if (j[split].masked.frames !== 4) { console.log(`FAIL: ${split}: three.js rendered ${j[split].masked.frames} of 4 frames`); ok = false; }
  if (Math.abs(p(t) - p(c)) > 0.75) { console.log(`FAIL: ${split}: three.js and the core render differ by more than 0.75 dB`); ok = false; }
  if (Math.abs(p(tn) - p(cn)) > 0.5) { console.log(`FAIL: ${split}: without shadows, three.js and the core render differ by more than 0.5 dB`); ok = false; }
  if (p(t) < p(o) - 2.0) { console.log(`FAIL: ${split}: three.js is more than 2 dB below Specula's own renderer`); ok = false; }
}
process.exit(ok ? 0 : 1);
JS

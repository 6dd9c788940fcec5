#!/usr/bin/env node
// Renders capture frames of a bundle with three.js as an ordinary viewer shows it: the glb loaded
// by three.js's GLTFLoader with the material it makes (the core glTF material and its KHR
// extensions; three.js ignores SPECULA_lafortune), in headless Chromium (WebGL), under each
// frame's camera and point light. Writes one linear float image per frame, OUT/<image stem>.pfm,
// which `specula evaluate BUNDLE CAPTURE --renders OUT` scores against the captured images.
//
//   node tools/threejs-render.mjs --bundle R/object.glb --capture CAP --out DIR
//        [--frames 0,5,9 | --max-per-split N] [--no-shadows] [--screenshot FILE.png]
//        [--chromium PATH]
//   node tools/threejs-render.mjs --report R --capture CAP
//
// With --report (a `specula reconstruct` output folder): renders the frame of the report's test
// sheet (else its first sheet) from R/object.glb, writes the picture as three.js shows it to
// R/viewer/threejs_<image stem>.png (sRGB 8-bit, the canvas), and puts it into R/report.html's
// "What ordinary viewers show" beside that sheet's photograph and Specula's render (each file
// written whole, then renamed into place).
//
// The light: three.js's PointLight (and a SpotLight inside its cone, used here for its shadow
// map) with decay 2 gives L = BRDF * intensity * cos / d^2 and BRDF_Lambert = color / pi, the
// capture format's radiometry (docs/capture-format.md), so the capture's intensity goes in
// unchanged. The camera: the frame's transform_matrix (OpenGL axes, as
// three.js) and a projection matrix made from fl_x, fl_y, cx, cy (pixel centres at +0.5, as
// WebGL rasterizes). No tone mapping; the render target is float, so the image is linear.
// Needs Node.js, Debian's chromium and npm's three and puppeteer-core (tools/install-deps.sh).
// Exit status: 0 done, 2 usage, 3 Chromium or WebGL unavailable (the message says why), 1 other.
import { execSync } from 'node:child_process';
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { createRequire } from 'node:module';

const kPinnedThree = '0.187.0';
// report.html's placeholder for three.js's picture (engine/report/report_html.cpp viewer_section).
const kPlaceholder = '<div id="threejs-picture">';

function usage(message) {
    if (message) console.error(`threejs-render: ${message}`);
    console.error('usage: node tools/threejs-render.mjs --bundle FILE.glb --capture DIR --out DIR ' +
                  '[--frames i,j,... | --max-per-split N] [--no-shadows] [--screenshot FILE.png] [--chromium PATH]\n' +
                  '       node tools/threejs-render.mjs --report RECONSTRUCT_OUT --capture DIR [--chromium PATH]');
    process.exit(2);
}

function parseArgs(argv) {
    const a = { frames: null, maxPerSplit: 4, shadows: true, screenshot: null, chromium: null, report: null };
    for (let i = 0; i < argv.length; ++i) {
        const k = argv[i];
        const next = () => { if (i + 1 >= argv.length) usage(`${k} needs a value`); return argv[++i]; };
        if (k === '--bundle') a.bundle = next();
        else if (k === '--capture') a.capture = next();
        else if (k === '--out') a.out = next();
        else if (k === '--frames') a.frames = next().split(',').map(s => {
            const n = Number(s);
            if (!Number.isInteger(n) || n < 0) usage(`--frames: '${s}' is not a frame index`);
            return n;
        });
        else if (k === '--max-per-split') {
            a.maxPerSplit = Number(next());
            if (!Number.isInteger(a.maxPerSplit) || a.maxPerSplit < 1) usage('--max-per-split must be a positive integer');
        }
        else if (k === '--no-shadows') a.shadows = false;
        else if (k === '--screenshot') a.screenshot = next();
        else if (k === '--chromium') a.chromium = next();
        else if (k === '--report') a.report = next();
        else if (k === '-h' || k === '--help') usage();
        else usage(`unknown argument '${k}'`);
    }
    if (a.report) {
        if (a.bundle || a.out || a.frames || a.screenshot) usage('--report takes the bundle, the frame and the outputs from the report folder');
        if (!a.capture) usage('--report needs --capture');
        a.bundle = path.join(a.report, 'object.glb');
        a.out = path.join(a.report, 'viewer');
        return a;
    }
    if (!a.bundle || !a.capture || !a.out) usage('--bundle, --capture and --out are required');
    return a;
}

// Frames evenly spaced over each split (at most n per split), in capture order.
function chooseFrames(frames, n) {
    const chosen = [];
    for (const split of ['train', 'test']) {
        const idx = frames.map((f, i) => [f, i]).filter(([f]) => (f.split ?? 'train') === split).map(([, i]) => i);
        const k = Math.min(n, idx.length);
        for (let j = 0; j < k; ++j) chosen.push(idx[Math.floor((j * idx.length) / k)]);
    }
    return chosen.sort((x, y) => x - y);
}

function globalModules() {
    try { return execSync('npm root -g', { encoding: 'utf8' }).trim(); } catch { return null; }
}

function findThree() {
    const roots = [process.env.SPECULA_NODE_MODULES, globalModules(), path.resolve('node_modules')].filter(Boolean);
    for (const r of roots) {
        const p = path.join(r, 'three', 'package.json');
        if (fs.existsSync(p)) return { dir: path.dirname(p), root: r, version: JSON.parse(fs.readFileSync(p, 'utf8')).version };
    }
    return null;
}

function unavailable(message) {
    console.error(`threejs-render: unavailable: ${message}`);
    process.exit(3);
}

const args = parseArgs(process.argv.slice(2));
const three = findThree();
if (!three) unavailable(`npm's three is not installed (tools/install-deps.sh installs three@${kPinnedThree})`);
let puppeteer;
try {
    puppeteer = createRequire(path.join(three.root, 'noop.js'))('puppeteer-core');
} catch (e) {
    unavailable(`npm's puppeteer-core is not installed (tools/install-deps.sh installs it): ${e.message}`);
}
const chromium = args.chromium ?? ['/usr/bin/chromium', '/usr/bin/chromium-browser'].find(p => fs.existsSync(p));
if (!chromium) unavailable("no Chromium (Debian's chromium package; or --chromium PATH)");

const capturePath = path.join(args.capture, 'capture.json');
let capture;
try { capture = JSON.parse(fs.readFileSync(capturePath, 'utf8')); } catch (e) { usage(`${capturePath}: ${e.message}`); }
if (!Array.isArray(capture.frames) || capture.frames.length === 0) usage(`${capturePath}: frames: no frame`);
// --report: the frame of the report's test sheet (else its first), from the sheet's file name
// (evaluate's sheet_<frame>_<split>_view<v>.png).
let reportSheet = null;
if (args.report) {
    const reportJson = path.join(args.report, 'report.json');
    let report;
    try { report = JSON.parse(fs.readFileSync(reportJson, 'utf8')); } catch (e) { usage(`${reportJson}: ${e.message}`); }
    const sheets = (report.evaluation?.sheets ?? []).map(s => ({ file: s, m: /sheet_(\d+)_(train|test)_/.exec(path.basename(s)) }))
        .filter(s => s.m);
    if (sheets.length === 0) usage(`${reportJson}: evaluation.sheets: no sheet to put three.js's picture beside`);
    reportSheet = sheets.find(s => s.m[2] === 'test') ?? sheets[0];
    args.frames = [Number(reportSheet.m[1])];
    const htmlPath = path.join(args.report, 'report.html');
    if (!fs.existsSync(htmlPath)) usage(`${args.report}: no report.html (reconstruct without --no-html)`);
    if (!fs.readFileSync(htmlPath, 'utf8').includes(kPlaceholder))
        usage(`${htmlPath}: no ${kPlaceholder} placeholder (a report from an older Specula, or one that has the picture already)`);
}
const frames = args.frames ?? chooseFrames(capture.frames, args.maxPerSplit);
for (const i of frames) if (i >= capture.frames.length) usage(`--frames: ${i} is past the last frame (${capture.frames.length - 1})`);
if (!fs.existsSync(args.bundle)) usage(`${args.bundle}: no such file`);
fs.mkdirSync(args.out, { recursive: true });

const page_html = `<!doctype html><html><head><meta charset="utf-8">
<script type="importmap">{"imports": {"three": "/three/build/three.module.js", "three/addons/": "/three/examples/jsm/"}}</script>
</head><body style="margin:0;background:#000"><canvas id="c"></canvas>
<script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
window.setup = async (p) => {
  const canvas = document.getElementById('c');
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(p.w, p.h, false);
  renderer.toneMapping = THREE.NoToneMapping;
  renderer.shadowMap.enabled = p.shadows;
  renderer.shadowMap.type = THREE.PCFShadowMap;
  const gltf = await new GLTFLoader().loadAsync('/bundle.glb');
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0, 0, 0);
  scene.add(gltf.scene);
  const box = new THREE.Box3().setFromObject(gltf.scene);
  const sphere = box.getBoundingSphere(new THREE.Sphere());
  gltf.scene.traverse(o => { if (o.isMesh) { o.castShadow = p.shadows; o.receiveShadow = p.shadows; } });
  // A spot light aimed at the object, its cone just covering the bounding sphere: inside the cone
  // (penumbra 0) three.js lights exactly as a point light does, and its shadow map spends all its
  // texels on the object (a point light's cube map spreads them over the whole sphere of directions
  // and loses the can's thin rim shadows).
  const light = new THREE.SpotLight(0xffffff, 1, 0, Math.PI / 4, 0, 2);
  light.castShadow = p.shadows;
  scene.add(light.target);
  light.shadow.mapSize.set(2048, 2048);
  light.shadow.bias = -1e-4;
  light.shadow.normalBias = sphere.radius * 2e-3;
  scene.add(light);
  const camera = new THREE.PerspectiveCamera();
  camera.matrixAutoUpdate = false;
  const target = new THREE.WebGLRenderTarget(p.w, p.h, { type: THREE.FloatType, depthBuffer: true });
  const materials = [];
  gltf.scene.traverse(o => { if (o.isMesh) materials.push(o.material.type); });
  window.state = { renderer, scene, light, camera, target, sphere, p };
  return { materials, three: THREE.REVISION };
};
window.renderFrame = (f) => {
  const { renderer, scene, light, camera, target, sphere, p } = window.state;
  const t = f.transform_matrix;
  camera.matrix.set(t[0][0], t[0][1], t[0][2], t[0][3], t[1][0], t[1][1], t[1][2], t[1][3],
                    t[2][0], t[2][1], t[2][2], t[2][3], 0, 0, 0, 1);
  camera.matrixWorldNeedsUpdate = true;
  camera.updateMatrixWorld(true);
  const eye = new THREE.Vector3(t[0][3], t[1][3], t[2][3]);
  const d = eye.distanceTo(sphere.center);
  const near = Math.max(d - sphere.radius * 1.05, d * 1e-3), far = d + sphere.radius * 1.05;
  const w = p.w, h = p.h;
  camera.projectionMatrix.set(2 * p.fx / w, 0, (w - 2 * p.cx) / w, 0,
                              0, 2 * p.fy / h, (2 * p.cy - h) / h, 0,
                              0, 0, -(far + near) / (far - near), -2 * far * near / (far - near),
                              0, 0, -1, 0);
  camera.projectionMatrixInverse.copy(camera.projectionMatrix).invert();
  const I = f.light.intensity;
  const peak = Math.max(I[0], I[1], I[2], 1e-30);
  light.color.setRGB(I[0] / peak, I[1] / peak, I[2] / peak, THREE.LinearSRGBColorSpace);
  light.intensity = peak;
  light.position.set(f.light.position[0], f.light.position[1], f.light.position[2]);
  // The shadow map's depth range around the object only (three.js packs depth into 8-bit RGBA:
  // a wide range would leave no precision).
  const ld = light.position.distanceTo(sphere.center);
  if (ld <= sphere.radius * 1.05) throw new Error('the light is inside the bounding sphere: no spot cone covers the object');
  light.target.position.copy(sphere.center);
  light.target.updateMatrixWorld();
  light.angle = Math.min(Math.asin(sphere.radius / ld) * 1.05, Math.PI / 2 - 1e-3);
  light.shadow.camera.near = Math.max(ld - sphere.radius * 1.05, ld * 1e-3);
  light.shadow.camera.far = ld + sphere.radius * 1.05;
  light.shadow.camera.updateProjectionMatrix();
  light.shadow.needsUpdate = true;
  renderer.setRenderTarget(target);
  renderer.render(scene, camera);
  const px = new Float32Array(w * h * 4);
  renderer.readRenderTargetPixels(target, 0, 0, w, h, px);
  renderer.setRenderTarget(null);
  renderer.render(scene, camera);  // the canvas too, for a screenshot
  const rgb = new Float32Array(w * h * 3);
  for (let i = 0; i < w * h; ++i) { rgb[3 * i] = px[4 * i]; rgb[3 * i + 1] = px[4 * i + 1]; rgb[3 * i + 2] = px[4 * i + 2]; }
  const bytes = new Uint8Array(rgb.buffer);
  let s = '';
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
  return btoa(s);
};
window.ready = true;
</script></body></html>`;

// Replaces report.html's placeholder (<div id="threejs-picture">...</div>, written by
// `specula reconstruct`) with the sheet of `frame` (photograph | Specula's render | difference)
// and three.js's picture of it, side by side; the page is written whole, then renamed into place.
function putIntoReport(dir, sheet, picture, frame, split, revision) {
    const htmlPath = path.join(dir, 'report.html');
    const html = fs.readFileSync(htmlPath, 'utf8');
    const start = html.indexOf(kPlaceholder);
    const end = start < 0 ? -1 : html.indexOf('</div>', start);
    if (end < 0) throw new Error(`${htmlPath}: no ${kPlaceholder} placeholder`);
    const esc = s => s.replace(/&/g, '&amp;').replace(/</g, '&lt;').replace(/"/g, '&quot;');
    const figure = `<div id="threejs-picture-shown"><p>Frame ${frame} (${split}) as three.js r${revision} shows the bundle (GLTFLoader, the material ` +
        `it makes, the frame's camera and point light, shadows), beside the photograph and Specula's own render of that ` +
        `frame (<code>node tools/threejs-render.mjs --report</code>):</p>` +
        // One row, the images at one height: the sheet is three frames wide.
        `<div style="display:flex;gap:4px;align-items:flex-start">` +
        `<figure style="flex:3 1 0;margin:0"><img alt="sheet" style="width:100%" src="${esc(sheet.file)}">` +
        `<figcaption>photograph | Specula | difference</figcaption></figure>` +
        `<figure style="flex:1 1 0;margin:0"><img alt="three.js" style="width:100%" ` +
        `src="${esc(picture.split(path.sep).join('/'))}"><figcaption>three.js</figcaption></figure>` +
        `</div></div>`;
    const out = html.slice(0, start) + figure + html.slice(end + '</div>'.length);
    fs.writeFileSync(`${htmlPath}.partial`, out);
    fs.renameSync(`${htmlPath}.partial`, htmlPath);
}

const files = { '/bundle.glb': path.resolve(args.bundle) };
const types = { '.js': 'text/javascript', '.glb': 'model/gltf-binary' };
const server = http.createServer((req, res) => {
    const url = decodeURIComponent(new URL(req.url, 'http://x').pathname);
    let file = files[url];
    if (url === '/' || url === '/page.html') {
        res.writeHead(200, { 'content-type': 'text/html' });
        res.end(page_html);
        return;
    }
    if (!file && url.startsWith('/three/')) {
        file = path.join(three.dir, path.normalize(url.slice('/three/'.length)));
        if (!file.startsWith(three.dir)) file = null;
    }
    if (!file || !fs.existsSync(file)) { res.writeHead(404); res.end(); return; }
    res.writeHead(200, { 'content-type': types[path.extname(file)] ?? 'application/octet-stream' });
    fs.createReadStream(file).pipe(res);
});
await new Promise(r => server.listen(0, '127.0.0.1', r));
const base = `http://127.0.0.1:${server.address().port}`;

let browser;
try {
    browser = await puppeteer.launch({
        executablePath: chromium, headless: true,
        args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
               `--window-size=${capture.w},${capture.h}`],
    });
} catch (e) {
    server.close();
    unavailable(`Chromium (${chromium}) did not start: ${e.message.split('\n')[0]}`);
}
let status = 0;
try {
    const page = await browser.newPage();
    const logs = [];
    page.on('console', m => logs.push(m.text()));
    page.on('pageerror', e => logs.push(String(e)));
    await page.setViewport({ width: capture.w, height: capture.h });
    await page.goto(`${base}/page.html`);
    await page.waitForFunction('window.ready === true', { timeout: 30000 });
    let info;
    try {
        info = await page.evaluate(p => window.setup(p), {
            w: capture.w, h: capture.h, fx: capture.fl_x, fy: capture.fl_y, cx: capture.cx, cy: capture.cy, shadows: args.shadows });
    } catch (e) {
        const why = `${e.message.split('\n')[0]} ${logs.join(' | ')}`;
        if (/WebGL/i.test(why)) { await browser.close(); server.close(); unavailable(`no WebGL in ${chromium}: ${why}`); }
        throw e;
    }
    if (three.version !== kPinnedThree)
        console.error(`threejs-render: note: three ${three.version}, not the pinned ${kPinnedThree}`);
    console.log(`threejs-render: three r${info.three}, materials: ${info.materials.join(', ')}, ${frames.length} frames, shadows ${args.shadows ? 'on' : 'off'}`);
    for (const i of frames) {
        const f = capture.frames[i];
        const b64 = await page.evaluate(fr => window.renderFrame(fr), f);
        const data = Buffer.from(b64, 'base64');
        const stem = path.basename(f.file_path).replace(/\.[^.]*$/, '');
        // PFM: rows bottom to top, as WebGL reads them back.
        const header = Buffer.from(`PF\n${capture.w} ${capture.h}\n-1.0\n`, 'ascii');
        const file = path.join(args.out, `${stem}.pfm`);
        fs.writeFileSync(`${file}.partial`, Buffer.concat([header, data]));
        fs.renameSync(`${file}.partial`, file);
        console.log(`threejs-render: frame ${i} (${f.split ?? 'train'}) -> ${file}`);
        if (reportSheet) {
            const picture = path.join(args.out, `threejs_${stem}.png`);
            await page.screenshot({ path: `${picture}.partial.png`, clip: { x: 0, y: 0, width: capture.w, height: capture.h } });
            fs.renameSync(`${picture}.partial.png`, picture);
            fs.rmSync(file); // the float image is for `specula evaluate --renders`; the report needs the picture
            putIntoReport(args.report, reportSheet, path.relative(args.report, picture), i, f.split ?? 'train', info.three);
            console.log(`threejs-render: frame ${i} as three.js shows it -> ${picture}, in ${path.join(args.report, 'report.html')}`);
        }
        if (args.screenshot && i === frames[frames.length - 1]) {
            await page.screenshot({ path: args.screenshot, clip: { x: 0, y: 0, width: capture.w, height: capture.h } });
            console.log(`threejs-render: screenshot of frame ${i} -> ${args.screenshot}`);
        }
    }
    const errors = logs.filter(l => /error/i.test(l));
    if (errors.length) console.error(`threejs-render: the page logged: ${errors.join(' | ')}`);
} catch (e) {
    console.error(`threejs-render: ${e.message}`);
    status = 1;
} finally {
    await browser.close();
    server.close();
}
process.exit(status);

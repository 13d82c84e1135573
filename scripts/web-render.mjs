// Render a glTF/GLB in a stock browser viewer (three.js or Babylon.js) through one of the
// file's own glTF cameras and write the frame as a PNG.
//
// Usage: node scripts/web-render.mjs three|babylon FILE OUT.png [--camera N] [--size WxH] [--time T]
//
// `--camera` also takes a list (`0,1,2`): the file is loaded once and OUT must contain
// `{camera}`, replaced by each index (the measurement scripts use this to save start-ups).
//
// `--time T` (three.js) plays the file's animations to T seconds the way a three.js app does:
// every clip of `gltf.animations` played by one `AnimationMixer` on the loaded scene, then
// `mixer.setTime(T)` (which updates the animated nodes) before rendering. It also takes a list
// (`0.4,1.4`): one load, OUT must contain `{time}`, replaced by each time as given. Without
// it the scene is drawn as loaded (the glTF's node transforms, no animation applied).
//
// Headless Debian `chromium` (software GL: ANGLE on SwiftShader) is driven by puppeteer-core;
// the page loads the stock loaders (three's `GLTFLoader`, Babylon's glTF loader with its
// `KHR_gaussian_splatting` extension) from the npm cache folder through a tiny local HTTP
// server, since browsers refuse ES modules over file://. Viewer settings are the defaults a
// user gets, except what makes a frame comparable with `splatbridge render`: black
// background, no tone mapping, no anti-aliasing, pixel ratio 1, sRGB output.
//
// Camera N is the N-th entry of the file's `cameras` array (the order `splatbridge convert`
// writes them), found through the node that references it. The size defaults to the
// camera's `extras.opencv` size, else 640×480.
//
// Exit status: 0 written, 1 failed, 3 the client is not available (chromium or the npm
// packages missing; the reason is printed). Environment: SPLATBRIDGE_WEB_DIR (npm cache
// folder, default ~/.cache/splatbridge-web), CHROMIUM (browser binary).

import fs from "node:fs";
import http from "node:http";
import os from "node:os";
import path from "node:path";

const NOT_AVAILABLE = 3;

function fail(msg, code = 1) {
  console.error(`web-render: ${msg}`);
  process.exit(code);
}

function parseArgs(argv) {
  const pos = [];
  const o = { cameras: [0], size: null, times: null };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === "--camera") {
      o.cameras = String(argv[++i] ?? "").split(",").map(Number);
      if (!o.cameras.every((c) => Number.isInteger(c) && c >= 0)) fail("--camera: expected indices ≥ 0", 2);
    } else if (a === "--size") {
      const m = /^(\d+)x(\d+)$/.exec(argv[++i] ?? "");
      if (!m) fail("--size: expected WxH", 2);
      o.size = [Number(m[1]), Number(m[2])];
      if (!(o.size[0] >= 1 && o.size[1] >= 1 && o.size[0] <= 4096 && o.size[1] <= 4096))
        fail("--size: sides must be in 1..=4096", 2);
    } else if (a === "--time") {
      const list = String(argv[++i] ?? "").split(",");
      if (!list.every((t) => /^[0-9]+([.][0-9]+)?$/.test(t))) fail("--time: expected seconds ≥ 0 (or a list: 0.4,1.4)", 2);
      o.times = list;
    } else pos.push(a);
  }
  if (pos.length !== 3 || !["three", "babylon"].includes(pos[0]))
    fail("usage: web-render.mjs three|babylon FILE OUT.png [--camera N] [--size WxH] [--time T]", 2);
  [o.client, o.file, o.out] = pos;
  if (o.cameras.length > 1 && !o.out.includes("{camera}")) fail("a camera list needs {camera} in OUT", 2);
  if (o.times && o.client !== "three") fail("--time: only the three client plays animations", 2);
  if (o.times && o.times.length > 1 && !o.out.includes("{time}")) fail("a time list needs {time} in OUT", 2);
  return o;
}

// The glTF JSON of a GLB or .gltf, for the camera's size (no other parsing: the viewer loads it).
function gltfJson(file) {
  const buf = fs.readFileSync(file);
  if (buf.length >= 20 && buf.toString("latin1", 0, 4) === "glTF") {
    const len = buf.readUInt32LE(12);
    if (20 + len > buf.length) throw new Error("GLB JSON chunk runs past the end of the file");
    return JSON.parse(buf.toString("utf8", 20, 20 + len));
  }
  return JSON.parse(buf.toString("utf8"));
}

const opts = parseArgs(process.argv.slice(2));
const webDir = process.env.SPLATBRIDGE_WEB_DIR ?? path.join(os.homedir(), ".cache/splatbridge-web");
const modules = path.join(webDir, "node_modules");
const chromium = process.env.CHROMIUM ?? "/usr/bin/chromium";
if (!fs.existsSync(chromium)) fail(`${chromium} not found (run scripts/setup.sh)`, NOT_AVAILABLE);
for (const p of ["three", "@babylonjs/core", "@babylonjs/loaders", "puppeteer-core"]) {
  if (!fs.existsSync(path.join(modules, p, "package.json")))
    fail(`npm package ${p} not found in ${modules} (run scripts/setup.sh)`, NOT_AVAILABLE);
}
let stat;
try {
  stat = fs.statSync(opts.file);
} catch (e) {
  fail(`${opts.file}: ${e.message}`, 2);
}
if (!stat.isFile()) fail(`${opts.file}: not a regular file`, 2);
let doc;
try {
  doc = gltfJson(opts.file);
} catch (e) {
  fail(`${opts.file}: ${e.message}`, 2);
}
for (const c of opts.cameras) {
  if (!(doc.cameras ?? [])[c]) fail(`${opts.file}: no camera ${c} (the file has ${(doc.cameras ?? []).length})`, 2);
}
const camDef = doc.cameras[opts.cameras[0]];
const cv = camDef.extras?.opencv;
const [width, height] = opts.size ?? (cv ? [cv.width, cv.height] : [640, 480]);

const { default: puppeteer } = await import(path.join(modules, "puppeteer-core/lib/puppeteer/puppeteer-core.js"));

const fileDir = path.dirname(path.resolve(opts.file));
const fileName = path.basename(opts.file);
const types = { ".js": "text/javascript", ".mjs": "text/javascript", ".json": "application/json", ".html": "text/html", ".glb": "model/gltf-binary", ".gltf": "model/gltf+json", ".bin": "application/octet-stream", ".png": "image/png", ".wasm": "application/wasm" };

const page3 = `
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
export async function render(url, camList, w, h, times) {
  const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(w, h);
  renderer.toneMapping = THREE.NoToneMapping;
  renderer.outputColorSpace = THREE.SRGBColorSpace;
  renderer.setClearColor(0x000000, 1);
  document.body.appendChild(renderer.domElement);
  const gltf = await new GLTFLoader().loadAsync(url);
  const scene = gltf.scene;
  scene.background = new THREE.Color(0x000000);
  // The animations as an app plays them: one mixer, every clip playing from the start.
  const mixer = new THREE.AnimationMixer(scene);
  for (const clip of gltf.animations) mixer.clipAction(clip).play();
  const shots = [];
  for (const t of times ?? [null]) {
    if (t !== null) mixer.setTime(t);
    for (const camIndex of camList) {
      let cam = null;
      scene.traverse((o) => {
        const a = gltf.parser.associations.get(o);
        if (!cam && o.isCamera && a && a.nodes !== undefined && gltf.parser.json.nodes[a.nodes].camera === camIndex) cam = o;
      });
      if (!cam) throw new Error("camera " + camIndex + " is not referenced by a node");
      cam.aspect = w / h;
      cam.updateProjectionMatrix();
      scene.updateMatrixWorld(true);
      renderer.render(scene, cam);
      shots.push(renderer.domElement.toDataURL("image/png"));
    }
  }
  return shots;
}`;

const pageBabylon = `
import { Engine } from "@babylonjs/core/Engines/engine.js";
import { Scene } from "@babylonjs/core/scene.js";
import { Color4 } from "@babylonjs/core/Maths/math.color.js";
import { AppendSceneAsync } from "@babylonjs/core/Loading/sceneLoader.js";
import "@babylonjs/core/Loading/loadingScreen.js";
// Without this side-effect import Babylon draws one splat of a Gaussian splatting mesh and
// reports nothing.
import "@babylonjs/core/Meshes/thinInstanceMesh.js";
import "@babylonjs/loaders/glTF/index.js";
export async function render(url, camList, w, h) {
  const canvas = document.createElement("canvas");
  canvas.width = w;
  canvas.height = h;
  canvas.style.width = w + "px";
  canvas.style.height = h + "px";
  document.body.appendChild(canvas);
  const engine = new Engine(canvas, false, { preserveDrawingBuffer: true, stencil: true, premultipliedAlpha: false }, false);
  engine.setHardwareScalingLevel(1);
  const scene = new Scene(engine);
  scene.clearColor = new Color4(0, 0, 0, 1);
  await AppendSceneAsync(url, scene);
  const shots = [];
  for (const camIndex of camList) {
    const want = "/cameras/" + camIndex;
    const cam = scene.cameras.find((c) => (c._internalMetadata?.gltf?.pointers ?? []).includes(want));
    if (!cam) throw new Error("camera " + camIndex + " not loaded");
    scene.activeCamera = cam;
    await scene.whenReadyAsync();
    // Gaussian splats are sorted on a worker after the first frames: render until the sort
    // settles.
    for (let i = 0; i < 10; i++) {
      scene.render();
      await new Promise((r) => setTimeout(r, 100));
    }
    scene.render();
    shots.push(canvas.toDataURL("image/png"));
  }
  return shots;
}`;

const html = `<!doctype html><html><head><meta charset="utf-8">
<style>html,body{margin:0;padding:0;background:#000;overflow:hidden}</style>
<script type="importmap">{"imports": {
  "three": "/node_modules/three/build/three.module.js",
  "three/addons/": "/node_modules/three/examples/jsm/",
  "@babylonjs/core/": "/node_modules/@babylonjs/core/",
  "@babylonjs/loaders/": "/node_modules/@babylonjs/loaders/",
  "babylonjs-gltf2interface": "/node_modules/babylonjs-gltf2interface/babylon.glTF2Interface.js"
}}</script></head><body></body></html>`;

const server = http.createServer((req, res) => {
  const url = decodeURIComponent(new URL(req.url, "http://x").pathname);
  let p = null;
  if (url === "/" || url === "/index.html") {
    res.writeHead(200, { "content-type": "text/html" });
    return res.end(html);
  }
  if (url === "/render.js") {
    res.writeHead(200, { "content-type": "text/javascript" });
    return res.end(opts.client === "three" ? page3 : pageBabylon);
  }
  if (url.startsWith("/node_modules/")) p = path.join(modules, url.slice("/node_modules/".length));
  else if (url.startsWith("/file/")) p = path.join(fileDir, url.slice("/file/".length));
  const root = url.startsWith("/file/") ? fileDir : modules;
  if (!p || !path.resolve(p).startsWith(root + path.sep) || !fs.existsSync(p) || !fs.statSync(p).isFile()) {
    res.writeHead(404);
    return res.end();
  }
  res.writeHead(200, { "content-type": types[path.extname(p)] ?? "application/octet-stream" });
  fs.createReadStream(p).pipe(res);
});
await new Promise((r) => server.listen(0, "127.0.0.1", r));
const base = `http://127.0.0.1:${server.address().port}`;

let browser;
let code = 0;
try {
  browser = await puppeteer.launch({
    executablePath: chromium,
    headless: true,
    // Software GL is slow on big files: no protocol deadline (the caller bounds the run).
    protocolTimeout: 0,
    args: ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--disable-dev-shm-usage", `--window-size=${width},${height}`],
  });
  const page = await browser.newPage();
  await page.setViewport({ width, height, deviceScaleFactor: 1 });
  const logs = [];
  page.on("console", (m) => logs.push(`${m.type()}: ${m.text()}`));
  page.on("pageerror", (e) => logs.push(`pageerror: ${e.message}`));
  page.setDefaultTimeout(0);
  await page.goto(`${base}/`);
  const shots = await page.evaluate(
    async (u, n, w, h, t) => (await import("/render.js")).render(u, n, w, h, t),
    `${base}/file/${encodeURIComponent(fileName)}`, opts.cameras, width, height, opts.times?.map(Number) ?? null,
  );
  const nc = opts.cameras.length;
  shots.forEach((dataUrl, k) => {
    const png = Buffer.from(dataUrl.slice(dataUrl.indexOf(",") + 1), "base64");
    let out = opts.out.replaceAll("{camera}", String(opts.cameras[k % nc]));
    if (opts.times) out = out.replaceAll("{time}", opts.times[Math.floor(k / nc)]);
    const tmp = `${out}.tmp${process.pid}`;
    fs.writeFileSync(tmp, png);
    fs.renameSync(tmp, out);
  });
  if (process.env.SPLATBRIDGE_WEB_LOG) for (const l of logs) console.error(l);
} catch (e) {
  console.error(`web-render: ${opts.client}: ${opts.file}: ${e.message ?? e}`);
  code = 1;
} finally {
  if (browser) await browser.close();
  server.close();
}
process.exit(code);

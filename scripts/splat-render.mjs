// Render a Gaussian splat file in a stock browser splat renderer (three.js's own
// `GaussianSplat`, or Spark) through a glTF camera and write the frame as a PNG.
//
// Usage: node scripts/splat-render.mjs CLIENT FILE OUT.png [--camera N] [--size WxH]
//                                      [--cameras CAMS.glb] [--set KEY=VALUE]...
//   CLIENT three-splats        three.js 0.187 `WebGPURenderer` + `GaussianSplat` (WebGPU on
//                              SwiftShader; `--set backend=webgl` for its WebGL 2 fallback)
//          three-splats-linear the same with a linear output colour space (`--set output=linear`):
//                              the fix for three.js's loaders, which ignore `colorSpace` and
//                              store display colours, that its sRGB output then encodes again
//          spark               Spark 2.2 (`SparkRenderer` + `SplatMesh`, three.js `WebGLRenderer`)
//          spark-native        Spark with native 3DGS numerics: `blurAmount=0 preBlurAmount=0.3
//                              maxStdDev=3 minAlpha=0.00392156862745098 sortRadial=false`
//   FILE   three-splats: `.glb`/`.gltf` (KHR_gaussian_splatting, `GLTFGaussianSplatLoaderExtension`),
//          `.spz` (`SPZLoader`), `.splat` (`SPLATLoader`), `.ksplat` (`KSPLATLoader`);
//          spark: `.spz`, `.splat`, `.ksplat`, `.ply` (its own readers).
//   --cameras CAMS.glb  where camera N comes from when FILE holds none (`.spz` …): a glTF
//          written by `splatbridge convert … --camera SPEC`, whose cameras sit under the root
//          node in the capture frame (3DGS RDF). `.spz` is read in its own RUB axes (y and z
//          flipped, as splatbridge writes it), `.splat`/`.ksplat`/`.ply` in the capture frame.
//   --set KEY=VALUE  a renderer setting: three-splats `output=srgb|linear`, `backend=webgpu|webgl`;
//          spark any numeric or boolean `SparkRenderer` option (`maxStdDev=3`, `sortRadial=false`).
//
// Black background, pixel ratio 1, no tone mapping; everything else is the viewer's default.
// Headless Debian `chromium` (WebGPU through `--enable-unsafe-webgpu
// --use-webgpu-adapter=swiftshader`, WebGL on ANGLE/SwiftShader) is driven by puppeteer-core;
// files and modules are served from a local HTTP server (WebGPU and ES modules need an http
// page). The renderers sort on the GPU (three.js) or in a worker (Spark): frames are drawn
// until the sort has run for the final view.
//
// Exit status: 0 written, 1 failed, 2 bad arguments, 3 the client is not available (chromium or
// the npm packages missing; the reason is printed). Environment: SPLATBRIDGE_WEB_DIR (npm cache
// folder, default ~/.cache/splatbridge-web), CHROMIUM (browser binary), SPLATBRIDGE_WEB_LOG
// (print the page's console).

import fs from "node:fs";
import http from "node:http";
import os from "node:os";
import path from "node:path";

const NOT_AVAILABLE = 3;
const CLIENTS = ["three-splats", "three-splats-linear", "spark", "spark-native"];
// Native 3DGS: +0.3 px² low-pass without opacity compensation, the 3σ square, α ≥ 1/255, sorted
// by view depth (diff-gaussian-rasterization, forward.cu `preprocessCUDA`/`renderCUDA`).
const PRESETS = {
  "three-splats-linear": { output: "linear" },
  "spark-native": { blurAmount: 0, preBlurAmount: 0.3, maxStdDev: 3, minAlpha: 1 / 255, sortRadial: false },
};

function fail(msg, code = 1) {
  console.error(`splat-render: ${msg}`);
  process.exit(code);
}

function parseArgs(argv) {
  const pos = [];
  const o = { camera: 0, size: null, cameras: null, set: {} };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === "--camera") {
      o.camera = Number(argv[++i]);
      if (!Number.isInteger(o.camera) || o.camera < 0) fail("--camera: expected an index ≥ 0", 2);
    } else if (a === "--size") {
      const m = /^(\d+)x(\d+)$/.exec(argv[++i] ?? "");
      if (!m) fail("--size: expected WxH", 2);
      o.size = [Number(m[1]), Number(m[2])];
      if (!(o.size[0] >= 1 && o.size[1] >= 1 && o.size[0] <= 4096 && o.size[1] <= 4096))
        fail("--size: sides must be in 1..=4096", 2);
    } else if (a === "--cameras") {
      o.cameras = argv[++i];
      if (!o.cameras) fail("--cameras: expected a glTF file", 2);
    } else if (a === "--set") {
      const m = /^([A-Za-z][A-Za-z0-9]*)=(.+)$/.exec(argv[++i] ?? "");
      if (!m) fail("--set: expected KEY=VALUE", 2);
      const v = m[2];
      o.set[m[1]] = v === "true" ? true : v === "false" ? false : Number.isFinite(Number(v)) ? Number(v) : v;
    } else pos.push(a);
  }
  if (pos.length !== 3 || !CLIENTS.includes(pos[0]))
    fail(`usage: splat-render.mjs ${CLIENTS.join("|")} FILE OUT.png [--camera N] [--size WxH] [--cameras CAMS.glb] [--set KEY=VALUE]`, 2);
  [o.client, o.file, o.out] = pos;
  o.set = { ...(PRESETS[o.client] ?? {}), ...o.set };
  o.viewer = o.client.startsWith("spark") ? "spark" : "three";
  return o;
}

// The glTF JSON of a GLB or .gltf (for its cameras; the viewer loads the file itself).
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
const ext = path.extname(opts.file).toLowerCase();
const kinds = opts.viewer === "three" ? [".glb", ".gltf", ".spz", ".splat", ".ksplat"] : [".spz", ".splat", ".ksplat", ".ply"];
if (!kinds.includes(ext)) fail(`${opts.file}: ${opts.client} reads ${kinds.join(", ")}`, 2);
const isGltf = ext === ".glb" || ext === ".gltf";
if (opts.viewer === "three" && !["srgb", "linear", undefined].includes(opts.set.output)) fail("--set output: srgb or linear", 2);
if (opts.viewer === "three" && !["webgpu", "webgl", undefined].includes(opts.set.backend)) fail("--set backend: webgpu or webgl", 2);
const webDir = process.env.SPLATBRIDGE_WEB_DIR ?? path.join(os.homedir(), ".cache/splatbridge-web");
const modules = path.join(webDir, "node_modules");
const chromium = process.env.CHROMIUM ?? "/usr/bin/chromium";
if (!fs.existsSync(chromium)) fail(`${chromium} not found (run scripts/setup.sh)`, NOT_AVAILABLE);
for (const p of ["three", "puppeteer-core", ...(opts.viewer === "spark" ? ["@sparkjsdev/spark"] : [])]) {
  if (!fs.existsSync(path.join(modules, p, "package.json")))
    fail(`npm package ${p} not found in ${modules} (run scripts/setup.sh)`, NOT_AVAILABLE);
}
for (const f of [opts.file, opts.cameras ?? opts.file]) {
  let st;
  try {
    st = fs.statSync(f);
  } catch (e) {
    fail(`${f}: ${e.message}`, 2);
  }
  if (!st.isFile()) fail(`${f}: not a regular file`, 2);
}
const camFile = opts.cameras ?? (isGltf ? opts.file : fail(`${opts.file}: holds no cameras: give --cameras CAMS.glb`, 2));

const { Matrix4, Quaternion, Vector3 } = await import(path.join(modules, "three/build/three.core.js"));

// Camera N of `camFile`: its world matrix in the frame FILE is loaded in, and its lens.
function camera(doc, n) {
  const cam = (doc.cameras ?? [])[n];
  if (!cam) throw new Error(`no camera ${n} (the file has ${(doc.cameras ?? []).length})`);
  if (cam.type !== "perspective") throw new Error(`camera ${n} is ${cam.type}, not perspective`);
  const nodes = doc.nodes ?? [];
  const parent = new Map();
  nodes.forEach((nd, i) => (nd.children ?? []).forEach((c) => parent.set(c, i)));
  const local = (nd) => {
    const m = new Matrix4();
    if (nd.matrix) return m.fromArray(nd.matrix);
    const [tx, ty, tz] = nd.translation ?? [0, 0, 0];
    const [qx, qy, qz, qw] = nd.rotation ?? [0, 0, 0, 1];
    const [sx, sy, sz] = nd.scale ?? [1, 1, 1];
    return m.compose(new Vector3(tx, ty, tz), new Quaternion(qx, qy, qz, qw), new Vector3(sx, sy, sz));
  };
  const node = nodes.findIndex((nd) => nd.camera === n);
  if (node < 0) throw new Error(`camera ${n} is not referenced by a node`);
  // World (glTF) matrix, and the matrix below the root node (the capture frame).
  const world = new Matrix4();
  let below = null;
  for (let i = node; i !== undefined; i = parent.get(i)) {
    if (parent.get(i) === undefined) below = world.clone();
    world.premultiply(local(nodes[i]));
  }
  let m = world;
  if (!isGltf) {
    m = below;
    // SPZ's RUB axes against the capture frame's RDF: a half turn about x.
    if (ext === ".spz") m.premultiply(new Matrix4().makeScale(1, -1, -1));
  }
  const p = cam.perspective;
  return { matrix: m.toArray(), yfov: p.yfov, near: p.znear, far: p.zfar ?? 1e4, opencv: cam.extras?.opencv };
}

let view;
try {
  view = camera(gltfJson(camFile), opts.camera);
} catch (e) {
  fail(`${camFile}: ${e.message}`, 2);
}
const [width, height] = opts.size ?? (view.opencv ? [view.opencv.width, view.opencv.height] : [640, 480]);

const { default: puppeteer } = await import(path.join(modules, "puppeteer-core/lib/puppeteer/puppeteer-core.js"));

const fileDir = path.dirname(path.resolve(opts.file));
const fileName = path.basename(opts.file);
const types = { ".js": "text/javascript", ".mjs": "text/javascript", ".json": "application/json", ".html": "text/html", ".glb": "model/gltf-binary", ".wasm": "application/wasm" };

// Shared by both pages: the camera from the glTF's matrix and vertical field of view.
const cameraCode = `
function makeCamera(THREE, view, w, h) {
  const cam = new THREE.PerspectiveCamera(view.yfov * 180 / Math.PI, w / h, view.near, view.far);
  cam.matrixAutoUpdate = false;
  cam.matrix.fromArray(view.matrix);
  cam.matrixWorld.fromArray(view.matrix);
  cam.matrixWorldInverse.copy(cam.matrixWorld).invert();
  cam.updateProjectionMatrix();
  return cam;
}
const settle = (ms) => new Promise((r) => setTimeout(r, ms));`;

const pageThree = `
import * as THREE from "three/webgpu";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { GLTFGaussianSplatLoaderExtension } from "three/addons/loaders/GLTFGaussianSplatLoaderExtension.js";
import { SPZLoader } from "three/addons/loaders/SPZLoader.js";
import { SPLATLoader } from "three/addons/loaders/SPLATLoader.js";
import { KSPLATLoader } from "three/addons/loaders/KSPLATLoader.js";
import { GaussianSplat } from "three/addons/objects/GaussianSplat.js";
${cameraCode}
export async function render(url, ext, view, w, h, set) {
  // The adapter and device three.js would request (WebGPUBackend.init), made here so that the
  // page keeps the adapter alive: on chromium's SwiftShader adapter, buffer reads fail ("A valid
  // external Instance reference no longer exists") once the adapter has been collected.
  let device;
  if (set.backend !== "webgl" && navigator.gpu) {
    window.keepAdapter = await navigator.gpu.requestAdapter({ featureLevel: "compatibility" });
    if (window.keepAdapter) {
      const features = [...window.keepAdapter.features];
      device = await window.keepAdapter.requestDevice({ requiredFeatures: features });
      device.lost.then((i) => console.error("device lost: " + i.reason + " " + i.message));
      device.addEventListener("uncapturederror", (e) => console.error("gpu error: " + e.error.message));
    }
  }
  const renderer = new THREE.WebGPURenderer({ antialias: false, forceWebGL: set.backend === "webgl", device });
  renderer.setPixelRatio(1);
  renderer.setSize(w, h);
  renderer.toneMapping = THREE.NoToneMapping;
  renderer.outputColorSpace = set.output === "linear" ? THREE.LinearSRGBColorSpace : THREE.SRGBColorSpace;
  renderer.setClearColor(0x000000, 1);
  document.body.appendChild(renderer.domElement);
  await renderer.init();
  const scene = new THREE.Scene();
  if (ext === ".glb" || ext === ".gltf") {
    const loader = new GLTFLoader();
    loader.register((parser) => new GLTFGaussianSplatLoaderExtension(parser));
    scene.add((await loader.loadAsync(url)).scene);
  } else {
    const Loader = { ".spz": SPZLoader, ".splat": SPLATLoader, ".ksplat": KSPLATLoader }[ext];
    scene.add(new GaussianSplat(await new Loader().loadAsync(url)));
  }
  let splats = 0;
  scene.traverse((o) => { if (o.isGaussianSplat) splats += o.splatGeometry.getAttribute("position").count; });
  if (splats === 0) throw new Error("no Gaussian splats loaded");
  scene.updateMatrixWorld(true);
  const cam = makeCamera(THREE, view, w, h);
  // The sort runs in onBeforeRender: the first frame sorts for this camera and draws.
  // Frames go, output pass included, to an 8-bit output target that is read back: headless
  // chromium has no WebGPU swap chain on SwiftShader (drawing to the canvas loses the device),
  // and a presented WebGPU canvas is not readable.
  const target = new THREE.RenderTarget(w, h, { type: THREE.UnsignedByteType, depthBuffer: true });
  renderer.setOutputRenderTarget(target);
  for (let i = 0; i < 3; i++) {
    renderer.render(scene, cam);
    await settle(50);
  }
  const px = await renderer.readRenderTargetPixelsAsync(target, 0, 0, w, h);
  const webgpu = renderer.backend.isWebGPUBackend === true;
  const out = new ImageData(w, h);
  for (let y = 0; y < h; y++) {
    // WebGPU textures start at the top row, WebGL's at the bottom one.
    const src = (webgpu ? y : h - 1 - y) * w * 4;
    out.data.set(px.subarray(src, src + w * 4), y * w * 4);
  }
  for (let i = 3; i < out.data.length; i += 4) out.data[i] = 255;
  const c2 = document.createElement("canvas");
  c2.width = w;
  c2.height = h;
  c2.getContext("2d").putImageData(out, 0, 0);
  return { png: c2.toDataURL("image/png"), splats, backend: webgpu ? "webgpu" : "webgl" };
}`;

const pageSpark = `
import * as THREE from "three";
import { SparkRenderer, SplatMesh } from "@sparkjsdev/spark";
${cameraCode}
export async function render(url, ext, view, w, h, set) {
  const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(w, h);
  renderer.toneMapping = THREE.NoToneMapping;
  renderer.setClearColor(0x000000, 1);
  document.body.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  const spark = new SparkRenderer({ renderer, ...set });
  scene.add(spark);
  const mesh = new SplatMesh({ url, fileName: "scene" + ext });
  await mesh.initialized;
  scene.add(mesh);
  const splats = mesh.packedSplats?.numSplats ?? mesh.numSplats ?? 0;
  const cam = makeCamera(THREE, view, w, h);
  scene.add(cam);
  // Spark sorts in a worker after a frame has been generated for the view: draw until a
  // sort has finished for this camera and nothing is pending.
  for (let i = 0; i < 60; i++) {
    renderer.render(scene, cam);
    await settle(50);
    if (i >= 6 && !spark.sorting && !spark.sortDirty && !spark.dirty) break;
  }
  renderer.render(scene, cam);
  return { png: renderer.domElement.toDataURL("image/png"), splats, backend: "webgl" };
}`;

const html = `<!doctype html><html><head><meta charset="utf-8">
<style>html,body{margin:0;padding:0;background:#000;overflow:hidden}</style>
<script type="importmap">{"imports": {
  "three": "/node_modules/three/build/three.module.js",
  "three/webgpu": "/node_modules/three/build/three.webgpu.js",
  "three/tsl": "/node_modules/three/build/three.tsl.js",
  "three/addons/": "/node_modules/three/examples/jsm/",
  "@sparkjsdev/spark": "/node_modules/@sparkjsdev/spark/dist/spark.module.js"
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
    return res.end(opts.viewer === "three" ? pageThree : pageSpark);
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
const logs = [];
try {
  browser = await puppeteer.launch({
    executablePath: chromium,
    headless: true,
    protocolTimeout: 0,
    args: [
      "--no-sandbox",
      "--use-angle=swiftshader",
      "--enable-unsafe-swiftshader",
      "--enable-unsafe-webgpu",
      "--use-webgpu-adapter=swiftshader",
      "--ignore-gpu-blocklist",
      "--disable-dev-shm-usage",
      "--force-color-profile=srgb",
      `--window-size=${width},${height}`,
    ],
  });
  const page = await browser.newPage();
  await page.setViewport({ width, height, deviceScaleFactor: 1 });
  page.on("console", (m) => logs.push(`${m.type()}: ${m.text()}`));
  page.on("pageerror", (e) => logs.push(`pageerror: ${e.message}`));
  page.setDefaultTimeout(0);
  await page.goto(`${base}/`);
  const shot = await page.evaluate(
    async (u, e, v, w, h, s) => (await import("/render.js")).render(u, e, v, w, h, s),
    `${base}/file/${encodeURIComponent(fileName)}`, ext, view, width, height, opts.set,
  );
  if (opts.viewer === "three" && opts.set.backend !== "webgl" && shot.backend !== "webgpu")
    throw new Error("WebGPU is not available in this chromium (the renderer fell back to WebGL 2)");
  const png = Buffer.from(shot.png.slice(shot.png.indexOf(",") + 1), "base64");
  const tmp = `${opts.out}.tmp${process.pid}`;
  fs.writeFileSync(tmp, png);
  fs.renameSync(tmp, opts.out);
  console.error(`splat-render: ${opts.client} (${shot.backend}): ${shot.splats} splats`);
} catch (e) {
  console.error(`splat-render: ${opts.client}: ${opts.file}: ${e.message ?? e}`);
  code = 1;
} finally {
  if (process.env.SPLATBRIDGE_WEB_LOG || code) for (const l of logs.slice(-20)) console.error(l);
  if (browser) await browser.close();
  server.close();
}
process.exit(code);

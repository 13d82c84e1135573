// Render a 3D Tiles tileset in a stock browser client (CesiumJS, or 3d-tiles-renderer on
// three.js) through a stated camera and write the frame as a PNG.
//
// Usage: node scripts/tiles-render.mjs cesium|3d-tiles-renderer TILESET.json OUT.png
//          --eye X,Y,Z --target X,Y,Z --up X,Y,Z [--fov DEG] [--size WxH] [--sse PX]
//
// The camera is given in the tileset's frame (after the root transform: ECEF for a
// geolocated tileset, the capture's Z-up frame for an identity root transform); --fov is the
// vertical field of view (default 50), --sse the client's maximum screen-space error in
// pixels (default 16, both clients' default; 0 loads every leaf). `splatbridge convert
// --tiles` writes tileset frames; the test maps its native camera into it.
//
// Headless Debian `chromium` (software GL) through puppeteer-core, packages from the npm
// cache folder (scripts/package.json: `cesium`, `3d-tiles-renderer`, `three`). CesiumJS runs
// without Ion, imagery, terrain or globe (black background, no sky, no FXAA, no HDR);
// 3d-tiles-renderer uses three's GLTFLoader with no tone mapping and sRGB output. The frame
// is taken once every requested tile is loaded and a few more frames have run (CesiumJS
// sorts splats on a worker).
//
// Exit status: 0 written, 1 failed, 2 bad arguments, 3 the client is not available.
// Environment: SPLATBRIDGE_WEB_DIR (default ~/.cache/splatbridge-web), CHROMIUM,
// SPLATBRIDGE_WEB_LOG (print the page's console).

import fs from "node:fs";
import http from "node:http";
import os from "node:os";
import path from "node:path";

const NOT_AVAILABLE = 3;
const CLIENTS = ["cesium", "3d-tiles-renderer"];

function fail(msg, code = 1) {
  console.error(`tiles-render: ${msg}`);
  process.exit(code);
}

function vec3(flag, s) {
  const v = String(s ?? "").split(",").map(Number);
  if (v.length !== 3 || !v.every(Number.isFinite)) fail(`${flag}: expected X,Y,Z`, 2);
  return v;
}

function parseArgs(argv) {
  const pos = [];
  const o = { fov: 50, size: [640, 480], sse: 16 };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === "--eye" || a === "--target" || a === "--up") o[a.slice(2)] = vec3(a, argv[++i]);
    else if (a === "--fov") {
      o.fov = Number(argv[++i]);
      if (!(o.fov > 0 && o.fov < 180)) fail("--fov: expected degrees in (0, 180)", 2);
    } else if (a === "--sse") {
      o.sse = Number(argv[++i]);
      if (!(o.sse >= 0 && o.sse <= 1e6)) fail("--sse: expected pixels ≥ 0", 2);
    } else if (a === "--size") {
      const m = /^(\d+)x(\d+)$/.exec(argv[++i] ?? "");
      if (!m) fail("--size: expected WxH", 2);
      o.size = [Number(m[1]), Number(m[2])];
      if (!(o.size[0] >= 1 && o.size[1] >= 1 && o.size[0] <= 4096 && o.size[1] <= 4096))
        fail("--size: sides must be in 1..=4096", 2);
    } else pos.push(a);
  }
  if (pos.length !== 3 || !CLIENTS.includes(pos[0]) || !o.eye || !o.target || !o.up)
    fail("usage: tiles-render.mjs cesium|3d-tiles-renderer TILESET.json OUT.png --eye X,Y,Z --target X,Y,Z --up X,Y,Z [--fov DEG] [--size WxH] [--sse PX]", 2);
  [o.client, o.file, o.out] = pos;
  return o;
}

const opts = parseArgs(process.argv.slice(2));
const webDir = process.env.SPLATBRIDGE_WEB_DIR ?? path.join(os.homedir(), ".cache/splatbridge-web");
const modules = path.join(webDir, "node_modules");
const chromium = process.env.CHROMIUM ?? "/usr/bin/chromium";
if (!fs.existsSync(chromium)) fail(`${chromium} not found (run scripts/setup.sh)`, NOT_AVAILABLE);
const need = opts.client === "cesium" ? ["cesium", "puppeteer-core"] : ["three", "3d-tiles-renderer", "puppeteer-core"];
for (const p of need) {
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
const [width, height] = opts.size;

const { default: puppeteer } = await import(path.join(modules, "puppeteer-core/lib/puppeteer/puppeteer-core.js"));
const fileDir = path.dirname(path.resolve(opts.file));
const fileName = path.basename(opts.file);
const types = { ".js": "text/javascript", ".mjs": "text/javascript", ".json": "application/json", ".html": "text/html", ".glb": "model/gltf-binary", ".gltf": "model/gltf+json", ".bin": "application/octet-stream", ".png": "image/png", ".wasm": "application/wasm", ".css": "text/css" };

// Both pages: load, then render until every requested tile is in and `settle` more frames ran.
const pageCesium = `
export async function render(url, o) {
  const C = window.Cesium;
  const div = document.createElement("div");
  div.style.width = o.width + "px";
  div.style.height = o.height + "px";
  document.body.appendChild(div);
  const widget = new C.CesiumWidget(div, {
    globe: false, skyBox: false, skyAtmosphere: false, baseLayer: false,
    useDefaultRenderLoop: false, requestRenderMode: false, scene3DOnly: true,
    contextOptions: { webgl: { preserveDrawingBuffer: true, antialias: false } },
    msaaSamples: 1,
  });
  widget.resolutionScale = 1;
  widget.useBrowserRecommendedResolution = false;
  // Without Cesium's widget CSS the canvas keeps the browser's default 300×150 CSS size, and
  // the widget sizes its drawing buffer from that: give the canvas the requested size.
  widget.canvas.style.width = o.width + "px";
  widget.canvas.style.height = o.height + "px";
  widget.resize();
  const scene = widget.scene;
  scene.backgroundColor = C.Color.BLACK;
  scene.highDynamicRange = false;
  scene.postProcessStages.fxaa.enabled = false;
  if (scene.sun) scene.sun.show = false;
  if (scene.moon) scene.moon.show = false;
  // Load what the screen-space error asks for everywhere in the view: foveated loading
  // (on by default) defers tiles away from the centre of the screen until the camera has
  // rested, and dynamic screen-space error relaxes tiles towards a street-level horizon;
  // either leaves parents in place of leaves at --sse 0.
  const tileset = await C.Cesium3DTileset.fromUrl(url, {
    maximumScreenSpaceError: o.sse,
    foveatedScreenSpaceError: false,
    dynamicScreenSpaceError: false,
    cullRequestsWhileMoving: false,
  });
  scene.primitives.add(tileset);
  const cam = scene.camera;
  const eye = C.Cartesian3.fromArray(o.eye), target = C.Cartesian3.fromArray(o.target);
  const dir = C.Cartesian3.normalize(C.Cartesian3.subtract(target, eye, new C.Cartesian3()), new C.Cartesian3());
  const upIn = C.Cartesian3.fromArray(o.up);
  const right = C.Cartesian3.normalize(C.Cartesian3.cross(dir, upIn, new C.Cartesian3()), new C.Cartesian3());
  const up = C.Cartesian3.cross(right, dir, new C.Cartesian3());
  cam.setView({ destination: eye, orientation: { direction: dir, up } });
  // Cesium's fov is the horizontal one when the image is wider than tall.
  const tanY = Math.tan((o.fov * Math.PI) / 360);
  cam.frustum.fov = o.width > o.height ? 2 * Math.atan((tanY * o.width) / o.height) : (o.fov * Math.PI) / 180;
  cam.frustum.aspectRatio = o.width / o.height;
  cam.frustum.near = o.near;
  cam.frustum.far = o.far;
  let settled = 0;
  for (let i = 0; i < 600 && settled < 20; i++) {
    widget.resize();
    widget.render();
    await new Promise((r) => setTimeout(r, 50));
    // The splat primitive rebuilds its combined snapshot of the selected tiles only once
    // the selection has been stable for a few frames, then sorts on a worker: wait for
    // that too (private fields of CesiumJS 1.145's GaussianSplatPrimitive; absent for
    // mesh content).
    const p = tileset.gaussianSplatPrimitive;
    const splatsBusy = p !== undefined && (p._dirty || p._needsSnapshotRebuild || p._pendingSnapshot !== undefined || p._pendingSortPromise !== undefined || p._drawCommand === undefined);
    settled = tileset.tilesLoaded && !splatsBusy ? settled + 1 : 0;
  }
  if (!tileset.tilesLoaded) throw new Error("tiles did not finish loading");
  const st = tileset.statistics;
  console.log("cesium: " + st.selected + " tiles selected, " + st.numberOfTilesWithContentReady + " with content ready, " + st.visited + " visited");
  widget.render();
  return widget.canvas.toDataURL("image/png");
}`;

const pageThree = `
import * as THREE from "three";
import { TilesRenderer } from "3d-tiles-renderer";
export async function render(url, o) {
  const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(o.width, o.height);
  renderer.toneMapping = THREE.NoToneMapping;
  renderer.outputColorSpace = THREE.SRGBColorSpace;
  renderer.setClearColor(0x000000, 1);
  document.body.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x000000);
  const camera = new THREE.PerspectiveCamera(o.fov, o.width / o.height, o.near, o.far);
  camera.position.fromArray(o.eye);
  camera.up.fromArray(o.up);
  camera.lookAt(new THREE.Vector3().fromArray(o.target));
  camera.updateMatrixWorld(true);
  const tiles = new TilesRenderer(url);
  tiles.errorTarget = o.sse;
  tiles.setCamera(camera);
  tiles.setResolutionFromRenderer(camera, renderer);
  scene.add(tiles.group);
  let settled = 0;
  for (let i = 0; i < 600 && settled < 10; i++) {
    tiles.update();
    renderer.render(scene, camera);
    await new Promise((r) => setTimeout(r, 50));
    const s = tiles.stats;
    const busy = (s.queued ?? 0) + (s.downloading ?? 0) + (s.parsing ?? 0);
    settled = busy === 0 && tiles.root ? settled + 1 : 0;
  }
  tiles.update();
  renderer.render(scene, camera);
  return renderer.domElement.toDataURL("image/png");
}`;

const html = `<!doctype html><html><head><meta charset="utf-8">
<style>html,body{margin:0;padding:0;background:#000;overflow:hidden}</style>
${opts.client === "cesium"
    ? `<script>window.CESIUM_BASE_URL = "/node_modules/cesium/Build/Cesium/";</script>
<script src="/node_modules/cesium/Build/Cesium/Cesium.js"></script>`
    : `<script type="importmap">{"imports": {
  "three": "/node_modules/three/build/three.module.js",
  "three/addons/": "/node_modules/three/examples/jsm/",
  "3d-tiles-renderer": "/node_modules/3d-tiles-renderer/build/index.js"
}}</script>`}
</head><body></body></html>`;

const server = http.createServer((req, res) => {
  const url = decodeURIComponent(new URL(req.url, "http://x").pathname);
  let p = null;
  if (url === "/" || url === "/index.html") {
    res.writeHead(200, { "content-type": "text/html" });
    return res.end(html);
  }
  if (url === "/render.js") {
    res.writeHead(200, { "content-type": "text/javascript" });
    return res.end(opts.client === "cesium" ? pageCesium : pageThree);
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

// Near and far planes from the camera's distance to the target: the scene is framed there.
const dist = Math.hypot(...opts.eye.map((e, k) => e - opts.target[k]));
const near = Math.max(dist * 1e-3, 1e-4);
const far = dist * 1e3 + 1;

let browser;
let code = 0;
const logs = [];
try {
  browser = await puppeteer.launch({
    executablePath: chromium,
    headless: true,
    protocolTimeout: 0,
    args: ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist", "--disable-dev-shm-usage", `--window-size=${width},${height}`],
  });
  const page = await browser.newPage();
  await page.setViewport({ width, height, deviceScaleFactor: 1 });
  page.on("console", (m) => logs.push(`${m.type()}: ${m.text()}`));
  page.on("pageerror", (e) => logs.push(`pageerror: ${e.message}`));
  page.setDefaultTimeout(0);
  await page.goto(`${base}/`);
  const shot = await page.evaluate(
    async (u, o) => (await import("/render.js")).render(u, o),
    `${base}/file/${encodeURIComponent(fileName)}`,
    { eye: opts.eye, target: opts.target, up: opts.up, fov: opts.fov, sse: opts.sse, width, height, near, far },
  );
  const png = Buffer.from(shot.slice(shot.indexOf(",") + 1), "base64");
  const tmp = `${opts.out}.tmp${process.pid}`;
  fs.writeFileSync(tmp, png);
  fs.renameSync(tmp, opts.out);
} catch (e) {
  console.error(`tiles-render: ${opts.client}: ${opts.file}: ${e.message ?? e}`);
  code = 1;
} finally {
  if (process.env.SPLATBRIDGE_WEB_LOG) for (const l of logs) console.error(l);
  if (browser) await browser.close();
  server.close();
}
process.exit(code);

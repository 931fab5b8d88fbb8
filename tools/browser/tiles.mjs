// Loads a 3D Tiles tileset with 3DTilesRendererJS (three.js) in headless
// chromium for one fixed camera, waits until every tile the view needs is
// loaded, and prints what it draws as JSON on stdout.
//
// node tiles.mjs '{"origin": "http://127.0.0.1:PORT", "tileset": URL,
//   "camera": {"position": [..], "target": [..], "up": [..], "fov": deg,
//   "near": n, "far": f}, "viewport": {"width": w, "height": h},
//   "errorTarget": pixels, "files": DIR?}'
//
// The page is served at ORIGIN/__tiles-test/ (so that the tileset on ORIGIN
// is same-origin), its ES modules from tools/node_modules through an import
// map, and ORIGIN/__tiles-files/* from DIR when `files` is given (a tileset
// written to disk). Everything else goes to the real server.
import { readFile } from "node:fs/promises";
import path from "node:path";
import { fileURLToPath } from "node:url";
import { launch } from "./launch.mjs";

const MODULES = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "../node_modules");
const TYPES = { ".js": "text/javascript", ".mjs": "text/javascript", ".json": "application/json", ".glb": "model/gltf-binary" };

const PAGE = `<!doctype html>
<html><head><meta charset="utf-8">
<script type="importmap">{"imports": {
  "three": "/__tiles-test/modules/three/build/three.module.js",
  "three/addons/": "/__tiles-test/modules/three/examples/jsm/",
  "3d-tiles-renderer": "/__tiles-test/modules/3d-tiles-renderer/build/index.js"
}}</script></head>
<body style="margin:0"><script type="module">
import * as THREE from "three";
import { TilesRenderer } from "3d-tiles-renderer";

window.runTiles = async (cfg) => {
  const { width, height } = cfg.viewport;
  const renderer = new THREE.WebGLRenderer({ antialias: false });
  renderer.setPixelRatio(1);
  renderer.setSize(width, height);
  document.body.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  const c = cfg.camera;
  const camera = new THREE.PerspectiveCamera(c.fov, width / height, c.near, c.far);
  // 3D Tiles is z-up: the camera is given in the tileset's frame.
  camera.up.set(...c.up);
  camera.position.set(...c.position);
  camera.lookAt(...c.target);
  camera.updateMatrixWorld();
  scene.add(camera);

  const tiles = new TilesRenderer(cfg.tileset);
  tiles.errorTarget = cfg.errorTarget;
  tiles.setCamera(camera);
  tiles.setResolution(camera, width, height);
  scene.add(tiles.group);
  const errors = [];
  tiles.addEventListener("load-error", (e) => errors.push(String(e.error && e.error.message || e.error) + " " + e.url));

  let stable = 0;
  let last = "";
  const start = performance.now();
  while (performance.now() - start < cfg.timeoutMs) {
    tiles.update();
    renderer.render(scene, camera);
    const s = tiles.stats;
    const key = [s.visible, s.used, s.inFrustum].join("/");
    const idle = tiles.root && !tiles.isLoading && s.queued === 0 && s.downloading === 0 && s.parsing === 0;
    stable = idle && key === last ? stable + 1 : 0;
    last = key;
    if (stable >= 5) break;
    await new Promise((r) => setTimeout(r, 30));
  }
  tiles.update();
  renderer.render(scene, camera);
  const drawn = renderer.info.render.triangles;
  let meshTriangles = 0;
  tiles.group.traverse((o) => {
    if (o.isMesh && o.visible) {
      const g = o.geometry;
      meshTriangles += (g.index ? g.index.count : g.attributes.position.count) / 3;
    }
  });
  const clusters = [];
  for (const tile of tiles.visibleTiles) {
    if (tile.extras && tile.extras.cluster !== undefined) clusters.push(tile.extras.cluster);
  }
  clusters.sort((a, b) => a - b);
  return {
    settled: stable >= 5,
    ms: performance.now() - start,
    triangles: drawn,
    meshTriangles,
    clusters,
    stats: { ...tiles.stats },
    errors,
  };
};
window.tilesReady = true;
</script></body></html>`;

function inside(root, rel) {
  const file = path.resolve(root, rel);
  return file.startsWith(root + path.sep) ? file : null;
}

async function main() {
  const cfg = JSON.parse(process.argv[2]);
  cfg.timeoutMs ??= 60000;
  const browser = await launch();
  try {
    const page = await browser.newPage({ viewport: cfg.viewport, deviceScaleFactor: 1 });
    const pageErrors = [];
    page.on("pageerror", (e) => pageErrors.push(String(e)));
    await page.route(`${cfg.origin}/__tiles-test/**`, async (route) => {
      const rel = decodeURIComponent(new URL(route.request().url()).pathname.slice("/__tiles-test/".length));
      if (rel === "index.html") {
        return route.fulfill({ status: 200, contentType: "text/html", body: PAGE });
      }
      const file = rel.startsWith("modules/") ? inside(MODULES, rel.slice("modules/".length)) : null;
      if (!file) return route.fulfill({ status: 404, body: "" });
      try {
        const body = await readFile(file);
        return route.fulfill({ status: 200, contentType: TYPES[path.extname(file)] || "application/octet-stream", body });
      } catch {
        return route.fulfill({ status: 404, body: "" });
      }
    });
    if (cfg.files) {
      const root = path.resolve(cfg.files);
      await page.route(`${cfg.origin}/__tiles-files/**`, async (route) => {
        const rel = decodeURIComponent(new URL(route.request().url()).pathname.slice("/__tiles-files/".length));
        const file = inside(root, rel);
        try {
          const body = await readFile(file);
          return route.fulfill({ status: 200, contentType: TYPES[path.extname(file)] || "application/octet-stream", body });
        } catch {
          return route.fulfill({ status: 404, body: "" });
        }
      });
    }
    await page.goto(`${cfg.origin}/__tiles-test/index.html`);
    await page.waitForFunction(() => window.tilesReady === true, null, { timeout: 30000 });
    const result = await page.evaluate((c) => window.runTiles(c), cfg);
    result.pageErrors = pageErrors;
    process.stdout.write(JSON.stringify(result) + "\n");
  } finally {
    await browser.close();
  }
}

main().catch((e) => {
  process.stderr.write(`${e.stack || e}\n`);
  process.exit(2);
});

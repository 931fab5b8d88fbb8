// CesiumJS (the npm `cesium` package) in headless chromium against a real
// hdlod server: the page follows the viewer's clock through the scene's
// slices with the recipe of docs/tiles.md (docs/examples/cesium-clock.js),
// and this prints as JSON what it drew at each time, a picked feature and
// every request it made.
//
// node cesium.mjs '{"server": "http://127.0.0.1:PORT", "scene": NAME,
//   "camera": {"position": ECEF, "direction": [..], "up": [..]},
//   "viewport": {"width": w, "height": h}, "maximumScreenSpaceError": px,
//   "step": seconds, "times": [seconds, ...], "pickAt": index into times}'
//
// The page, CesiumJS and the recipe are served from an origin of their own
// (a loopback port of this process), so every tileset and content request
// to the server is cross-origin. No request is routed through playwright:
// routing turns the browser's HTTP cache off, which the clock's reuse of
// content needs. The server's /metrics, read before and after each time,
// count the content GLBs that reached it.
import { createServer } from "node:http";
import { readFile } from "node:fs/promises";
import path from "node:path";
import { fileURLToPath } from "node:url";
import { launch } from "./launch.mjs";

const HERE = path.dirname(fileURLToPath(import.meta.url));
const ROOTS = {
  "/cesium/": path.resolve(HERE, "../node_modules/cesium/Build/Cesium"),
  "/examples/": path.resolve(HERE, "../../docs/examples"),
};
const TYPES = {
  ".html": "text/html",
  ".js": "text/javascript",
  ".css": "text/css",
  ".json": "application/json",
  ".png": "image/png",
  ".jpg": "image/jpeg",
  ".svg": "image/svg+xml",
  ".wasm": "application/wasm",
  ".xml": "application/xml",
};

const PAGE = `<!doctype html>
<html><head><meta charset="utf-8">
<link rel="stylesheet" href="/cesium/Widgets/widgets.css">
<script>window.CESIUM_BASE_URL = "/cesium/";</script>
<script type="importmap">{"imports": {"cesium": "/cesium/index.js"}}</script>
<style>html, body, #viewer { margin: 0; width: 100%; height: 100%; overflow: hidden; }</style>
</head><body><div id="viewer"></div>
<script type="module" src="/page.js"></script>
</body></html>`;

function file(urlPath) {
  if (urlPath === "/page.js") return path.join(HERE, "cesium-page.js");
  for (const [prefix, root] of Object.entries(ROOTS)) {
    if (!urlPath.startsWith(prefix)) continue;
    const f = path.resolve(root, decodeURIComponent(urlPath.slice(prefix.length)));
    return f.startsWith(root + path.sep) ? f : null;
  }
  return null;
}

// The page's origin: a static server on a loopback port of its own.
function servePage() {
  const server = createServer(async (req, res) => {
    const urlPath = new URL(req.url, "http://x").pathname;
    if (urlPath === "/") {
      res.writeHead(200, { "content-type": "text/html" });
      return res.end(PAGE);
    }
    if (urlPath === "/favicon.ico") {
      res.writeHead(204);
      return res.end();
    }
    const f = file(urlPath);
    try {
      if (!f) throw new Error("outside");
      const body = await readFile(f);
      res.writeHead(200, { "content-type": TYPES[path.extname(f)] || "application/octet-stream" });
      res.end(body);
    } catch {
      res.writeHead(404);
      res.end();
    }
  });
  return new Promise((resolve) => server.listen(0, "127.0.0.1", () => resolve(server)));
}

// Requests of the content route that reached the server, by status.
async function contentHits(server) {
  const text = await (await fetch(`${server}/metrics`)).text();
  let hits = 0;
  for (const line of text.split("\n")) {
    const m = line.match(/^hdlod_http_requests_total\{route="([^"]*)",status="(\d+)"\} (\d+)$/);
    if (m && m[1].includes("/tiles/content/")) hits += Number(m[3]);
  }
  return hits;
}

async function main() {
  const cfg = JSON.parse(process.argv[2]);
  const timeoutMs = cfg.timeoutMs ?? 90000;
  const began = Date.now();
  const pageServer = await servePage();
  const origin = `http://127.0.0.1:${pageServer.address().port}`;
  const browser = await launch();
  try {
    const context = await browser.newContext({ viewport: cfg.viewport, deviceScaleFactor: 1 });
    const page = await context.newPage();
    const pageErrors = [];
    const consoleErrors = [];
    page.on("pageerror", (e) => pageErrors.push(String(e)));
    page.on("console", (m) => m.type() === "error" && consoleErrors.push(m.text()));
    // Every request the page made, to find any that leaves the two
    // origins; from the DevTools protocol, each with the phase it was made
    // in and whether the browser's cache answered it.
    let phase = "load";
    const requests = [];
    const byId = new Map();
    page.on("request", (r) => requests.push(r.url()));
    const cdp = await context.newCDPSession(page);
    await cdp.send("Network.enable");
    cdp.on("Network.requestWillBeSent", (e) => byId.set(e.requestId, { url: e.request.url, phase, cached: false }));
    cdp.on("Network.requestServedFromCache", (e) => byId.has(e.requestId) && (byId.get(e.requestId).cached = true));
    cdp.on("Network.responseReceived", (e) => {
      const r = byId.get(e.requestId);
      if (!r) return;
      r.status = e.response.status;
      r.cached ||= Boolean(e.response.fromDiskCache || e.response.fromPrefetchCache);
      r.allowOrigin = e.response.headers["access-control-allow-origin"] ?? e.response.headers["Access-Control-Allow-Origin"];
    });

    await page.goto(`${origin}/`);
    await page.waitForFunction(() => window.cesiumTestReady === true, null, { timeout: 30000 });
    const init = await page.evaluate(
      (c) => window.cesiumTest.init(c),
      { ...cfg, api: `${cfg.server}/api/v1` },
    );
    const states = [];
    let pick = null;
    for (const [i, seconds] of cfg.times.entries()) {
      phase = `time ${i}`;
      const before = await contentHits(cfg.server);
      const left = Math.max(1000, timeoutMs - (Date.now() - began));
      const state = await page.evaluate(([s, ms]) => window.cesiumTest.showTime(s, ms), [seconds, left]);
      state.serverContentHits = (await contentHits(cfg.server)) - before;
      states.push(state);
      if (i === cfg.pickAt) pick = await page.evaluate(() => window.cesiumTest.pick());
    }
    const result = {
      origin,
      init,
      states,
      pick,
      requests: [...byId.values()],
      foreign: requests.filter((url) => !url.startsWith(origin) && !url.startsWith(cfg.server) && !/^(data|blob):/.test(url)),
      pageErrors,
      consoleErrors,
      ms: Date.now() - began,
    };
    process.stdout.write(JSON.stringify(result) + "\n");
  } finally {
    await browser.close();
    pageServer.close();
  }
}

main().catch((e) => {
  process.stderr.write(`${e.stack || e}\n`);
  process.exit(2);
});

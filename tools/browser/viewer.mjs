// Drives the web viewer in headless chromium for server/tests/viewer_browser.rs:
//   node tools/browser/viewer.mjs BASE_URL SCENE SCREENSHOT_DIR
// and prints one JSON object of measurements on stdout; the Rust test
// asserts on it. The viewer is driven through its test hook
// (window.hdlodViewer, docs/viewer.md), the canvas checked on screenshots.
import { mkdirSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { launch } from "./launch.mjs";
import { canvasShot as canvasPng, compare as comparePng, hook as pageHook, settle as settlePage } from "./page.mjs";

const [base, scene, outDir] = process.argv.slice(2);
if (!base || !scene || !outDir) {
  console.error("usage: node viewer.mjs BASE_URL SCENE SCREENSHOT_DIR");
  process.exit(2);
}
mkdirSync(outDir, { recursive: true });
const WIDTH = 960;
const HEIGHT = 600;
const out = { errors: [], screenshots: [] };

async function padCoverage() {
  const p = await browser.newPage({ viewport: { width: WIDTH, height: HEIGHT } });
  try {
    await p.goto(`${base}/?scene=${encodeURIComponent(scene)}`);
    await settlePage(p);
    const found = await p.evaluate(async (name) => {
      const r = await fetch(`/api/v1/scenes/${encodeURIComponent(name)}/objects?q=SITE-GROUND&limit=1`);
      return (await r.json()).items;
    }, scene);
    if (found.length === 0) return null;
    const pad = found[0].index;
    const res = {};
    for (const [factor, pe] of [[2, 0.02], [2, 1], [4, 0.02], [4, 1]]) {
      await pageHook(p, (v, [factor, pe]) => {
        v.setDistanceFactor(factor);
        v.setPixelError(pe);
      }, [factor, pe]);
      await settlePage(p);
      const shown = await pageHook(p, (v) => v.featureCoverage());
      await pageHook(p, (v) => v.search("GROUND-", "hide"));
      await settlePage(p);
      const alone = await pageHook(p, (v) => v.featureCoverage());
      await pageHook(p, (v) => v.search("", "highlight"));
      res[`${factor}x ${pe}`] = { shown: shown[pad] || 0, alone: alone[pad] || 0 };
    }
    return res;
  } finally {
    await p.close();
  }
}

async function encodings(t) {
  const res = {};
  const shots = {};
  for (const encoding of ["compact", "plain"]) {
    const p = await browser.newPage({ viewport: { width: WIDTH, height: HEIGHT } });
    try {
      p.on("pageerror", (e) => out.errors.push(`page error (${encoding}): ${e.message}`));
      const query = encoding === "plain" ? "&encoding=plain" : "";
      await p.goto(`${base}/?scene=${encodeURIComponent(scene)}&time=${t}&pixel_error=0.5${query}`);
      const st = await settlePage(p);
      shots[encoding] = await canvasPng(p);
      res[encoding] = { glbFiles: st.glbFiles, glbBytes: st.glbBytes, glbRequests: st.glbRequests, clusters: st.clusters, ids: st.ids };
      if (encoding === "plain") res.pixels = await comparePng(p, outDir, "encodings", shots.compact, shots.plain, { x: 0, y: 0, width: WIDTH, height: HEIGHT });
    } finally {
      await p.close();
    }
  }
  return res;
}

const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: WIDTH, height: HEIGHT } });
  // The last checks provoke failed requests on purpose; errors count until then.
  let faults = false;
  page.on("pageerror", (e) => out.errors.push(`page error: ${e.message}`));
  page.on("console", (m) => {
    if (m.type() === "error" && !faults) out.errors.push(`console: ${m.text()}`);
  });

  const settle = () => settlePage(page);
  // The server's own cut for the request the viewer's drawn cut answers.
  const serverCut = (request) =>
    page.evaluate(async ([sceneName, body]) => {
      const r = await fetch(`/api/v1/scenes/${encodeURIComponent(sceneName)}/cut`, {
        method: "POST",
        headers: { "content-type": "application/json" },
        body: JSON.stringify(body),
      });
      return r.json();
    }, [scene, request]);
  // Pixel statistics of a screenshot, decoded by the page's own image decoder;
  // the region under the toolbar and left of the stats panel is the canvas.
  const shoot = async (name) => {
    const png = await page.screenshot();
    const file = join(outDir, `${name}.png`);
    writeFileSync(file, png);
    out.screenshots.push(file);
    return page.evaluate(async (data) => {
      const img = await createImageBitmap(await (await fetch(`data:image/png;base64,${data}`)).blob());
      const c = new OffscreenCanvas(img.width, img.height);
      const g = c.getContext("2d");
      g.drawImage(img, 0, 0);
      const [x0, y0, x1, y1] = [0, 60, img.width - 280, img.height - 40];
      const px = g.getImageData(x0, y0, x1 - x0, y1 - y0).data;
      const bg = [219, 227, 237];
      let other = 0;
      const colours = new Map();
      for (let i = 0; i < px.length; i += 4) {
        const d = Math.abs(px[i] - bg[0]) + Math.abs(px[i + 1] - bg[1]) + Math.abs(px[i + 2] - bg[2]);
        if (d > 12) other++;
        const key = ((px[i] >> 4) << 8) | ((px[i + 1] >> 4) << 4) | (px[i + 2] >> 4);
        colours.set(key, (colours.get(key) || 0) + 1);
      }
      const n = px.length / 4;
      return {
        pixels: n,
        nonBackgroundShare: other / n,
        // Colours (4 bits a channel) covering at least 0.05% of the region.
        distinctColours: [...colours.values()].filter((k) => k >= n * 0.0005).length,
      };
    }, png.toString("base64"));
  };
  const hook = (f, arg) => pageHook(page, f, arg);
  const api = (p, path) => p.evaluate(async (u) => (await fetch(u)).json(), path);
  const sceneApi = `/api/v1/scenes/${encodeURIComponent(scene)}`;
  // The RGB of one CSS pixel of the page as shown.
  const pixel = async (p, x, y) => {
    const png = await p.screenshot({ clip: { x, y, width: 1, height: 1 } });
    return p.evaluate(async (data) => {
      const img = await createImageBitmap(await (await fetch(`data:image/png;base64,${data}`)).blob());
      const c = new OffscreenCanvas(1, 1);
      const g = c.getContext("2d");
      g.drawImage(img, 0, 0);
      return [...g.getImageData(0, 0, 1, 1).data.slice(0, 3)];
    }, png.toString("base64"));
  };
  // Two screenshots of the canvas compared: pixels that differ, and the
  // pixels off the background in each.
  const compare = (name, a, b) => comparePng(page, outDir, name, a, b, { x: 0, y: 0, width: WIDTH, height: HEIGHT });
  // The canvas alone: the overlays (toolbar, panel, stats) hidden for the shot.
  const canvasShot = (p = page) => canvasPng(p);
  const coverage = () => hook((v) => v.featureCoverage());

  async function identity() {
    const presence = (await api(page, `${sceneApi}/presence`)).presence;
    const presentAt = (i, t) => presence[i].some(([a, b]) => (a === null || a <= t) && (b === null || t < b));
    out.objects = presence.length;

    // (a) A click on the site at the end of the period: a pixel in the
    // middle of some object (its neighbours pick the same), clicked with
    // the mouse; the panel names it and the pixel takes the selection tint.
    await hook((v) => { v.setDistanceFactor(1); v.setPixelError(1); v.setColourMode("vertex"); v.setTime(v.state().span); });
    await settle();
    let target = null;
    for (let dy = 0; dy < 200 && !target; dy += 6) {
      for (const sy of [1, -1]) {
        const [x, y] = [Math.round(WIDTH / 2) - 100, Math.round(HEIGHT / 2) + sy * dy];
        const ids = await hook((v, [x, y]) => [[0, 0], [3, 0], [-3, 0], [0, 3], [0, -3]].map(([a, b]) => v.pickAt(x + a, y + b)), [x, y]);
        if (ids[0] !== null && ids.every((i) => i === ids[0])) {
          target = { x, y, index: ids[0] };
          break;
        }
      }
    }
    out.pick = { target };
    if (!target) return;
    const before = await pixel(page, target.x, target.y);
    const picksBefore = (await hook((v) => v.state())).picks;
    await page.mouse.click(target.x, target.y);
    let s = await settle();
    const field = (name) => page.evaluate((n) => document.querySelector(`#panel [data-field="${n}"]`)?.textContent ?? null, name);
    out.pick = {
      ...out.pick,
      time: s.time,
      selection: s.selection,
      picks: s.picks - picksBefore,
      panel: { id: await field("id"), name: await field("name"), class: await field("class"), storey: await field("storey"), present: await field("present") },
      tasks: await page.evaluate(() => [...document.querySelectorAll("#panel [data-task]")].map((e) => e.dataset.task)),
      before,
      after: await pixel(page, target.x, target.y),
    };
    // The panel follows the time: at the start of the period.
    await hook((v) => v.setTime(0));
    s = await settle();
    out.pick.atStart = { time: s.time, panel: s.panel, present: await field("present") };
    await hook((v) => v.setTime(v.state().span));
    await settle();

    // (b) Exact presence: a time and pixel error where the cut draws a
    // cluster holding an object absent then; with the state texture off the
    // absent object shows, with it on it does not.
    await hook((v) => v.select(null));
    const span = out.span;
    let found = null;
    for (const pe of [16, 4]) {
      for (let i = 0; i < 24 && !found; i++) {
        const t = (span * (i + 0.5)) / 24;
        await hook((v, [t, pe]) => { v.setTime(t); v.setPixelError(pe); v.setFeatureState(false); }, [t, pe]);
        await settle();
        const off = await coverage();
        const absent = Object.keys(off).map(Number).filter((id) => !presentAt(id, t));
        if (absent.length) found = { t, pixelError: pe, absent, offShot: await canvasShot(), off };
      }
      if (found) break;
    }
    if (found) {
      await hook((v) => v.setFeatureState(true));
      s = await settle();
      const on = await coverage();
      const onShot = await canvasShot();
      out.presence = {
        time: found.t,
        pixelError: found.pixelError,
        clusters: s.ids,
        absentShownWithoutState: found.absent.slice(0, 50),
        absentPixelsWithoutState: found.absent.reduce((n, id) => n + found.off[id], 0),
        shownWithState: Object.keys(on).map(Number).slice(0, 200),
        absentShownWithState: Object.keys(on).map(Number).filter((id) => !presentAt(id, found.t)),
        pixels: await compare("presence", found.offShot, onShot),
        stateUploads: s.stateUploads,
      };
      // Nothing changes, nothing is uploaded again.
      await page.waitForTimeout(200);
      out.presence.stateUploadsLater = (await hook((v) => v.state())).stateUploads;
    }
    await hook((v) => { v.setFeatureState(true); v.setPixelError(1); v.setTime(v.state().span); });

    // (c) Search by the picked object's storey (or class), then isolate,
    // hide, clear: what is drawn and pickable follows the matches.
    const q = [out.pick.panel.storey, out.pick.panel.class].find((x) => x && x !== "-");
    const plainShot = (await settle(), await canvasShot());
    const run = async (mode) => {
      await hook((v, [q, mode]) => v.search(q, mode), [q, mode]);
      const st = await settle();
      return { state: st.search, shot: await canvasShot(), coverage: Object.keys(await coverage()).map(Number) };
    };
    const highlight = await run("highlight");
    const matches = await hook((v) => v.matches());
    const isolate = await run("isolate");
    const hide = await run("hide");
    await hook((v) => v.search("", "highlight"));
    await settle();
    const clearedShot = await canvasShot();
    const matchSet = new Set(matches);
    out.search = {
      q,
      matches: matches.length,
      state: isolate.state,
      highlight: await compare("highlight", plainShot, highlight.shot),
      isolate: await compare("isolate", plainShot, isolate.shot),
      hide: await compare("hide", plainShot, hide.shot),
      cleared: await compare("cleared", plainShot, clearedShot),
      isolatedPickable: isolate.coverage.length,
      isolatedOutsideMatches: isolate.coverage.filter((i) => !matchSet.has(i)).length,
      hiddenPickable: hide.coverage.filter((i) => matchSet.has(i)).length,
      plainMatchesPickable: highlight.coverage.filter((i) => matchSet.has(i)).length,
    };
  }

  // (d) The link: a camera, a selection and an isolation set, the address
  // opened in a second page, which shows the same.
  async function roundTrip() {
    if (!out.pick || !out.pick.target || !out.search) return;
    await hook((v, [index, q]) => {
      v.setTime(v.state().span);
      v.setPixelError(1);
      v.setCamera({ azimuth: 0.9, elevation: 0.45 });
      v.setDistanceFactor(1.1);
      v.select(index);
      v.search(q, "isolate");
    }, [out.pick.target.index, out.search.q]);
    const a = await settle();
    await page.waitForTimeout(700);
    const url = await page.evaluate(() => location.href);
    const shotA = await canvasShot();
    const second = await browser.newPage({ viewport: { width: WIDTH, height: HEIGHT } });
    second.on("pageerror", (e) => out.errors.push(`second page error: ${e.message}`));
    await second.goto(url);
    await second.waitForFunction(() => window.hdlodViewer && window.hdlodViewer.state().search.matches > 0, null, { timeout: 20000 });
    const b = await settlePage(second);
    const shotB = await canvasShot(second);
    const pick = (st) => ({ time: st.time, eye: st.eye, target: st.target, selection: st.selection, search: st.search, distance: st.distance });
    out.roundTrip = { url, a: pick(a), b: pick(b), pixels: await compare("link", shotA, shotB) };
    await second.close();
  }

  // The same view drawn with the clusters batched a page at a time and
  // with a draw call each: the draw calls, the pictures and the pick
  // pass's feature ids compared.
  async function batching() {
    const on = await settle();
    const shotOn = await canvasShot();
    const idsOn = await coverage();
    await hook((v) => v.setBatching(false));
    const off = await settle();
    const shotOff = await canvasShot();
    const idsOff = await coverage();
    await hook((v) => v.setBatching(true));
    await settle();
    let idsDiffer = 0;
    for (const id of new Set([...Object.keys(idsOn), ...Object.keys(idsOff)])) idsDiffer += Math.abs((idsOn[id] || 0) - (idsOff[id] || 0));
    return {
      clusters: on.clusters,
      drawCalls: on.drawCalls,
      aloneDrawCalls: off.drawCalls,
      aloneClusters: off.clusters,
      pixels: await compare("batching", shotOn, shotOff),
      idsDiffer,
      idsPixels: Object.values(idsOn).reduce((a, b) => a + b, 0),
    };
  }

  // The page allocator on a WebGL2 context of its own: ranges placed
  // first-fit, given back and joined, a mesh larger than a page on one of
  // its own, an emptied page deleted; then a page's clusters drawn with
  // one call, read back pixel by pixel.
  async function pageAllocator() {
    return page.evaluate(async () => {
      const { Pages, PAGE_VERTICES } = await import("/viewer/pages.js");
      const canvas = new OffscreenCanvas(4, 1);
      const gl = canvas.getContext("webgl2", { antialias: false });
      const pages = new Pages(gl);
      // n vertices, the first three a triangle covering pixel `px` of the 4 x 1 canvas.
      const mesh = (n, px = 0) => {
        const positions = new Float32Array(3 * n);
        const x0 = -1 + px / 2;
        positions.set([x0, -1, 0, x0 + 0.5, -1, 0, x0 + 0.25, 3, 0]);
        return { positions, normals: null, colors: null, features: new Float32Array(n).fill(px), indices: new Uint32Array([0, 1, 2, 1, 2, 2]) };
      };
      const log = {};
      const a = pages.place(mesh(1000));
      const b = pages.place(mesh(2000));
      const c = pages.place(mesh(3000));
      log.firsts = [a.first, b.first, c.first];
      pages.release(b);
      const d = pages.place(mesh(1500));
      const e = pages.place(mesh(600));
      log.refill = [d.first, e.first];
      log.rebased = [d.indices[0], d.indices[1], e.indices[2]];
      pages.release(a);
      pages.release(d);
      log.joined = c.page.free.map((r) => [...r]);
      const big = pages.place(mesh(PAGE_VERTICES + 1));
      log.bigOwnPage = big.page !== c.page && big.page.capacity === PAGE_VERTICES + 1;
      pages.release(big);
      log.pagesAfterBig = pages.pages.length;

      // Four one-pixel triangles in the shared page, their feature ids as
      // colours; two drawn with one call, then the other two.
      const vs = `#version 300 es
        layout(location = 0) in vec3 p;
        layout(location = 3) in float f;
        flat out float vf;
        void main() { vf = f; gl_Position = vec4(p, 1.0); }`;
      const fs = `#version 300 es
        precision highp float;
        flat in float vf;
        out vec4 o;
        void main() { o = vec4((vf + 1.0) * 40.0 / 255.0, 0.0, 0.0, 1.0); }`;
      const program = gl.createProgram();
      for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
        const sh = gl.createShader(type);
        gl.shaderSource(sh, src);
        gl.compileShader(sh);
        gl.attachShader(program, sh);
      }
      gl.linkProgram(program);
      gl.useProgram(program);
      const tris = [0, 1, 2, 3].map((px) => pages.place(mesh(3, px)));
      const drawn = (slots) => {
        gl.clearColor(0, 0, 0, 1);
        gl.clear(gl.COLOR_BUFFER_BIT);
        const count = pages.bindDrawn(slots[0].page, slots);
        gl.drawElements(gl.TRIANGLES, count, gl.UNSIGNED_INT, 0);
        const px = new Uint8Array(16);
        gl.readPixels(0, 0, 4, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
        // Feature id + 1 in steps of 40: a byte off in the rounding reads the same.
        return [0, 1, 2, 3].map((i) => Math.round(px[4 * i] / 40));
      };
      log.drawnFirst = drawn([tris[0], tris[2]]);
      log.drawnThen = drawn([tris[1], tris[3]]);
      for (const s of [c, e, ...tris]) pages.release(s);
      log.pagesAtEnd = pages.pages.length;
      return log;
    });
  }

  // A baked cover (a texture's alpha) drawn over a whole canvas by the
  // viewer's renderer: the share of the pixels' samples it takes, from
  // the picture against the same quad uncovered and fully covered.
  async function bakedCover() {
    return page.evaluate(async () => {
      const { Renderer } = await import("/viewer/renderer.js");
      const side = 64;
      const r = new Renderer(new OffscreenCanvas(side, side));
      const quad = {
        positions: new Float32Array([-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0]),
        normals: null, colors: null, features: null,
        uvs: new Float32Array([0, 0, 1, 0, 1, 1, 0, 1]),
        indices: new Uint32Array([0, 1, 2, 0, 2, 3]),
      };
      const camera = { viewProj: new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]), eye: new Float32Array([0, 0, 5]) };
      const mean = async (byte) => {
        const data = new Uint8ClampedArray(4 * 16).fill(255);
        for (let i = 3; i < data.length; i += 4) data[i] = byte;
        const image = await createImageBitmap(new ImageData(data, 4, 4), { premultiplyAlpha: "none", colorSpaceConversion: "none" });
        const gpu = r.upload(quad, image);
        r.draw([{ gpu, transform: null, joints: null, tint: null, feature: null }], camera, side, side, false, false);
        const px = new Uint8Array(4 * side * side);
        r.gl.readPixels(0, 0, side, side, r.gl.RGBA, r.gl.UNSIGNED_BYTE, px);
        r.free(gpu);
        let sum = 0;
        for (let i = 0; i < px.length; i += 4) sum += px[i + 2];
        return sum / (side * side);
      };
      const [bare, full] = [await mean(0), await mean(255)];
      const covers = [];
      for (const byte of [13, 26, 51, 77, 128, 179, 230]) covers.push({ alpha: byte / 255, cover: ((await mean(byte)) - bare) / (full - bare) });
      return { samples: r.cover.samples, levels: [...r.cover.levels], bare, full, covers };
    });
  }

  const summary = (s) => ({ time: s.time, clusters: s.clusters, triangles: s.triangles, baseline: s.baseline, ids: s.ids });

  const started = Date.now();
  await page.goto(`${base}/?scene=${encodeURIComponent(scene)}&time=0`);
  let s = await settle();
  out.loadMillis = Date.now() - started;
  out.span = s.span;
  out.hasStats = await page.evaluate(() => document.getElementById("stats").textContent.includes("triangles drawn"));

  // Start and end of the period, each against the server's cut of the same view.
  out.start = summary(s);
  out.start.serverIds = (await serverCut(await page.evaluate(() => window.hdlodViewer.lastRequest()))).clusters.map((c) => c.id).sort((a, b) => a - b);
  out.start.pixels = await shoot("start");
  // A jump in time waits for its own cut (up to holdMs) instead of first
  // drawing the old one at the new time; moving the camera draws at once.
  const before = s;
  await page.evaluate((t) => window.hdlodViewer.setTime(t), s.span);
  s = await settle();
  out.hold = {
    holdMs: s.holdMs,
    readyMs: s.readyMs,
    frames: s.frames - before.frames,
    staleFrames: s.staleFrames - before.staleFrames,
  };
  out.end = summary(s);
  const endCut = await serverCut(await page.evaluate(() => window.hdlodViewer.lastRequest()));
  out.end.serverIds = endCut.clusters.map((c) => c.id).sort((a, b) => a - b);
  out.end.serverTriangles = endCut.stats.triangles;
  out.end.pixels = await shoot("end");
  out.batching = await batching();
  out.pages = await pageAllocator();
  out.cover = await bakedCover();
  out.glbBytes = s.glbBytes;
  out.glbFiles = s.glbFiles;
  out.latencyMs = s.latencyMs;

  for (const mode of ["class", "level"]) {
    await page.evaluate((m) => window.hdlodViewer.setColourMode(m), mode);
    await settle();
    out[`${mode}Pixels`] = await shoot(`end-${mode}`);
  }
  await page.evaluate(() => window.hdlodViewer.setColourMode("vertex"));

  // Zooming out with the mouse wheel from the distance that frames the
  // scene: each step doubles it (the viewer zooms by exp(deltaY * 0.0015)).
  out.zoom = [];
  await page.evaluate(() => window.hdlodViewer.setDistanceFactor(1));
  await page.mouse.move(WIDTH / 2, HEIGHT / 2);
  for (let step = 0; step < 3; step++) {
    const stale = s.staleFrames;
    if (step > 0) await page.mouse.wheel(0, Math.log(2) / 0.0015);
    s = await settle();
    out.zoom.push({ distance: s.distance, triangles: s.triangles, clusters: s.clusters, staleFrames: s.staleFrames - stale });
  }
  await shoot("far");
  await page.evaluate(() => window.hdlodViewer.setDistanceFactor(1));

  // Fly mode: F, then W held moves the eye forward.
  const eyeBefore = (await settle()).eye;
  await page.click("#view");
  await page.keyboard.press("f");
  await page.keyboard.down("w");
  await page.waitForTimeout(400);
  await page.keyboard.up("w");
  s = await settle();
  out.fly = { mode: s.mode, before: eyeBefore, after: s.eye };
  await page.keyboard.press("f");
  await page.evaluate(() => window.hdlodViewer.setDistanceFactor(1));

  // A moment when some dynamic cluster in view moves within the next hour,
  // found with the server's cut; then play from there at one hour a second.
  const HOUR = 3600;
  let moving = null;
  const request = await page.evaluate(() => window.hdlodViewer.lastRequest());
  for (let i = 0; i < 120 && !moving; i++) {
    const t = (s.span * (i + 0.5)) / 120;
    const a = await serverCut({ ...request, time: t });
    const b = await serverCut({ ...request, time: t + HOUR });
    for (const c of a.clusters) {
      const d = c.transform && b.clusters.find((x) => x.id === c.id && x.transform);
      if (d && c.transform.some((v, k) => Math.abs(v - d.transform[k]) > 1e-3)) {
        moving = { t, id: c.id };
        break;
      }
    }
  }
  out.moving = moving;
  if (moving) {
    await page.evaluate((t) => window.hdlodViewer.setTime(t), moving.t);
    const before = await settle();
    await page.evaluate(() => window.hdlodViewer.play(1 / 24));
    await page.waitForTimeout(1500);
    await page.evaluate(() => window.hdlodViewer.pause());
    const after = await settle();
    const at = (st) => st.dynamicScreenPositions.find((p) => p.id === moving.id) || null;
    out.dynamic = { before: at(before), after: at(after), timeBefore: before.time, timeAfter: after.time };
  }

  // Object identity: picking, the panel, exact presence, search, the link.
  await identity();

  const last = await page.evaluate(() => window.hdlodViewer.state());
  out.finalGlbFiles = last.glbFiles;
  out.finalGlbRequests = last.glbRequests;
  await page.waitForTimeout(600);
  out.address = await page.evaluate(() => location.search);
  out.finalGlbBytes = last.glbBytes;
  // The server's counters before a second page loads the link's view.
  out.metrics = await page.evaluate(async () => (await fetch("/metrics")).text());
  await roundTrip();

  // Thin surfaces on the ground at a distance: the site pad (25 cm thick)
  // over the ground tiles, two and four times as far as the framing view, at full detail
  // (its leaf) and at 1 px (its parent, a quad), with and without the
  // ground: the pad must not lose pixels to the ground behind it.
  out.pad = await padCoverage();

  // The same view from the compact GLBs (what the tree stores, decoded by
  // meshoptimizer's decoder) and from the plain ones (`encoding=plain`):
  // the same picture.
  out.encodings = await encodings(last.span * 0.9);

  // Readable messages: an unknown scene, then a server that is not there.
  faults = true;
  await page.goto(`${base}/?scene=no-such-scene`);
  await page.waitForFunction(() => window.hdlodViewer && window.hdlodViewer.state().error, null, { timeout: 10000 });
  out.missingSceneMessage = await page.evaluate(() => document.getElementById("message").textContent);
  await page.route("**/api/v1/scenes", (route) => route.abort("connectionrefused"));
  await page.goto(`${base}/?scene=${encodeURIComponent(scene)}`);
  await page.waitForFunction(() => window.hdlodViewer && window.hdlodViewer.state().error, null, { timeout: 10000 });
  out.unreachableMessage = await page.evaluate(() => document.getElementById("message").textContent);
} catch (e) {
  out.errors.push(`driver: ${e.stack || e}`);
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));

// Drives the web viewer in headless chromium for server/tests/viewer_browser.rs:
//   node tools/browser/viewer.mjs BASE_URL SCENE SCREENSHOT_DIR
// and prints one JSON object of measurements on stdout; the Rust test
// asserts on it. The viewer is driven through its test hook
// (window.hdlodViewer, docs/viewer.md), the canvas checked on screenshots.
import { mkdirSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { launch } from "./launch.mjs";

const [base, scene, outDir] = process.argv.slice(2);
if (!base || !scene || !outDir) {
  console.error("usage: node viewer.mjs BASE_URL SCENE SCREENSHOT_DIR");
  process.exit(2);
}
mkdirSync(outDir, { recursive: true });
const WIDTH = 960;
const HEIGHT = 600;
const out = { errors: [], screenshots: [] };

const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: WIDTH, height: HEIGHT } });
  // The last checks provoke failed requests on purpose; errors count until then.
  let faults = false;
  page.on("pageerror", (e) => out.errors.push(`page error: ${e.message}`));
  page.on("console", (m) => {
    if (m.type() === "error" && !faults) out.errors.push(`console: ${m.text()}`);
  });

  const settle = async () => {
    await page.waitForFunction(() => window.hdlodViewer && window.hdlodViewer.settled(), null, {
      timeout: 20000,
      polling: 50,
    });
    // One more frame so the canvas shows what the state says.
    await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
    return page.evaluate(() => window.hdlodViewer.state());
  };
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
  await page.evaluate((t) => window.hdlodViewer.setTime(t), s.span);
  s = await settle();
  out.end = summary(s);
  const endCut = await serverCut(await page.evaluate(() => window.hdlodViewer.lastRequest()));
  out.end.serverIds = endCut.clusters.map((c) => c.id).sort((a, b) => a - b);
  out.end.serverTriangles = endCut.stats.triangles;
  out.end.pixels = await shoot("end");
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
    if (step > 0) await page.mouse.wheel(0, Math.log(2) / 0.0015);
    s = await settle();
    out.zoom.push({ distance: s.distance, triangles: s.triangles, clusters: s.clusters });
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

  const last = await page.evaluate(() => window.hdlodViewer.state());
  out.finalGlbFiles = last.glbFiles;
  await page.waitForTimeout(600);
  out.address = await page.evaluate(() => location.search);
  out.finalGlbBytes = last.glbBytes;

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

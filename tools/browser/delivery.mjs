// How fast the web viewer shows a site, for `hdlod bench viewer`
// (server/src/cmd/bench_viewer.rs):
//   node tools/browser/delivery.mjs BASE_URL SCENE WIDTH HEIGHT FRAMES
// in headless chromium (software GL through SwiftShader here):
// - first frame: a fresh browser (empty cache) navigates to the scene at
//   2/3 of its period, at table 2's nearest camera (the one that frames
//   the scene) and at its farthest (4 times as far), with the geometry as
//   stored and in the plain form (`encoding=plain`); the time from
//   navigation until the complete cut is drawn, the geometry requests and
//   their bytes, on the wire (`encodedBodySize`) and decoded;
// - one-week steps from the nearest first frame, STEPS in a row, each
//   bringing new geometry: the time until each new cut is complete (the
//   median and each), the frames drawn meanwhile with the old cut, and
//   what the first step fetched;
// - frame time: each cell of table 2 drawn FRAMES times with the cut and
//   without levels of detail (`lod=none`: every present leaf), the median
//   milliseconds of a frame (drawn and read back) and its draw calls, with
//   the clusters batched (as the viewer draws) and with a call each.
// Prints one JSON object.
import { launch } from "./launch.mjs";
import { hook } from "./page.mjs";

const [base, scene, width, height, frames] = process.argv.slice(2);
if (!frames) {
  console.error("usage: node delivery.mjs BASE_URL SCENE WIDTH HEIGHT FRAMES");
  process.exit(2);
}
const viewport = { width: Number(width), height: Number(height) };
const FRAMES = Math.max(1, Number(frames));
const WEEK = 7 * 86400;
const STEPS = 5;
// The full-detail cuts of the paper scene load thousands of files in
// software GL: minutes, not seconds.
const SETTLE_MS = 600000;
const SCREENS = [["1/1", 1], ["1/4", 2], ["1/16", 4]];
const TIMES = [["start", 0], ["1/3", 1 / 3], ["2/3", 2 / 3], ["end", 1]];
const out = { width: viewport.width, height: viewport.height, frames: FRAMES, open: [], step: null, cells: [], errors: [] };

const median = (xs) => {
  const s = [...xs].sort((a, b) => a - b);
  return s.length % 2 ? s[(s.length - 1) / 2] : (s[s.length / 2 - 1] + s[s.length / 2]) / 2;
};

// Resolves with performance.now() of the first animation frame after the
// viewer's drawn cut answers its view with nothing loading.
function settledAt(page) {
  return page
    .waitForFunction(() => window.hdlodViewer && window.hdlodViewer.settled(), null, { timeout: SETTLE_MS, polling: "raf" })
    .then(() => page.evaluate(() => new Promise((r) => requestAnimationFrame(() => r(performance.now())))));
}

// The geometry requests since `since` (ms after navigation): count, bytes
// on the wire and decoded.
function geometryFetched(page, since) {
  return page.evaluate((since) => {
    const entries = performance.getEntriesByType("resource").filter((e) => e.startTime >= since && e.name.includes("/geometry"));
    return {
      requests: entries.length,
      wireBytes: entries.reduce((n, e) => n + e.encodedBodySize, 0),
      decodedBytes: entries.reduce((n, e) => n + e.decodedBodySize, 0),
    };
  }, since);
}

async function freshPage(browser) {
  const context = await browser.newContext({ viewport });
  const page = await context.newPage();
  // The default buffer keeps 250 entries; a cut asks for more.
  await page.addInitScript(() => performance.setResourceTimingBufferSize(1000000));
  page.on("pageerror", (e) => out.errors.push(`page error: ${e.message}`));
  page.on("console", (m) => {
    if (m.type() === "error") out.errors.push(`console: ${m.text()}`);
  });
  return { context, page };
}

const browser = await launch();
try {
  // The views: the period and the farthest camera, from a first page.
  const setup = await freshPage(browser);
  await setup.page.goto(`${base}/?scene=${encodeURIComponent(scene)}`);
  await settledAt(setup.page);
  const span = await hook(setup.page, (v) => v.state().span);
  const views = {};
  for (const [screen, factor] of SCREENS) {
    views[screen] = await hook(setup.page, (v, f) => {
      v.setDistanceFactor(f);
      const s = v.state();
      return { position: s.eye, target: s.target };
    }, factor);
  }
  await setup.context.close();
  const t = Math.round((2 / 3) * span);

  for (const screen of ["1/1", "1/16"]) {
    for (const encoding of ["compact", "plain"]) {
      const { context, page } = await freshPage(browser);
      const { position, target } = views[screen];
      const url =
        `${base}/?scene=${encodeURIComponent(scene)}&time=${t}&position=${position.join(",")}&target=${target.join(",")}` +
        (encoding === "plain" ? "&encoding=plain" : "");
      await page.goto(url);
      const ms = await settledAt(page);
      const state = await hook(page, (v) => v.state());
      out.open.push({ screen, encoding, ms, clusters: state.clusters, triangles: state.triangles, ...(await geometryFetched(page, 0)) });
      if (screen === "1/1" && encoding === "compact") {
        const all = [];
        const stale = (await hook(page, (v) => v.state())).staleFrames;
        for (let i = 0; i < STEPS; i++) {
          const since = await page.evaluate(() => performance.now());
          await hook(page, (v, dt) => v.setTime(v.state().time + dt), WEEK);
          all.push((await settledAt(page)) - since);
          if (i === 0) {
            const after = await hook(page, (v) => v.state());
            out.step = { days: 7, clusters: after.clusters, triangles: after.triangles, ...(await geometryFetched(page, since)) };
          }
        }
        const staleFrames = (await hook(page, (v) => v.state())).staleFrames - stale;
        out.step = { ...out.step, ms: median(all), all, staleFrames };
      }
      await context.close();
    }
  }

  // Frame time per cell, with and without levels of detail, in one page.
  const { context, page } = await freshPage(browser);
  await page.goto(`${base}/?scene=${encodeURIComponent(scene)}`);
  await settledAt(page);
  const measure = async (lod) => {
    await hook(page, (v, l) => v.setLod(l), lod);
    await settledAt(page);
    const s = await hook(page, (v) => v.state());
    const ms = await hook(page, (v, k) => v.timeFrames(k), FRAMES);
    const drawCalls = await hook(page, (v) => v.state().drawCalls);
    await hook(page, (v) => v.setBatching(false));
    const alone = await hook(page, (v, k) => v.timeFrames(k), FRAMES);
    const aloneDrawCalls = await hook(page, (v) => v.state().drawCalls);
    await hook(page, (v) => v.setBatching(true));
    return {
      clusters: s.clusters, triangles: s.triangles, baseline: s.baseline, ms: median(ms), all: ms, drawCalls,
      aloneMs: median(alone), aloneDrawCalls,
    };
  };
  for (const [screen, factor] of SCREENS) {
    for (const [time, fraction] of TIMES) {
      await hook(page, (v, [f, t]) => {
        v.setDistanceFactor(f);
        v.setTime(t);
      }, [factor, span * fraction]);
      const hdlod = await measure("hdlod");
      const none = await measure("none");
      out.cells.push({ time, screen, hdlod, none });
    }
  }
  await context.close();
} catch (e) {
  out.errors.push(`driver: ${e.stack || e}`);
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));

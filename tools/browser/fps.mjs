// Playback frames per second of the web viewer in headless chromium
// (software GL through SwiftShader):
//   node tools/browser/fps.mjs BASE_URL SCENE [SECONDS] [MODES]
// plays the whole period in SECONDS (default 20) once per colour mode
// (default vertex,appearance,appearance+gantt: the model's colours, the
// task appearance, and the same with the Gantt chart open) and prints one
// JSON object: per mode the median frames per second over one-second
// windows, the median frame interval, the viewer's CPU time per frame and
// what it drew. scripts/viewer-fps runs it on the small site.
import { launch } from "./launch.mjs";
import { hook, settle } from "./page.mjs";

const [base, scene, seconds = "20", modes = "vertex,appearance,appearance+gantt"] = process.argv.slice(2);
if (!base || !scene) {
  console.error("usage: node fps.mjs BASE_URL SCENE [SECONDS] [MODES]");
  process.exit(2);
}
const SECONDS = Number(seconds);
const out = { scene, seconds: SECONDS, viewport: [1280, 720], modes: {}, errors: [] };

const median = (xs) => {
  const s = [...xs].sort((a, b) => a - b);
  return s.length ? (s.length % 2 ? s[(s.length - 1) / 2] : (s[s.length / 2 - 1] + s[s.length / 2]) / 2) : null;
};

const browser = await launch();
try {
  for (const name of modes.split(",")) {
    const [mode, extra] = name.split("+");
    const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
    page.on("pageerror", (e) => out.errors.push(`${name}: ${e.message}`));
    await page.goto(`${base}/?scene=${encodeURIComponent(scene)}&time=0&pixel_error=1&colour=${mode}${extra === "gantt" ? "&gantt=1" : ""}`);
    const s = await settle(page);
    // The whole period in SECONDS.
    const daysPerSecond = s.span / 86400 / SECONDS;
    const run = await page.evaluate(async ([dps, ms]) => {
      const v = window.hdlodViewer;
      const stamps = [];
      const cpu = [];
      let triangles = 0;
      let clusters = 0;
      v.play(dps);
      const start = performance.now();
      await new Promise((done) => {
        const tick = (now) => {
          stamps.push(now);
          const st = v.state();
          cpu.push(st.frameMs);
          triangles = Math.max(triangles, st.triangles);
          clusters = Math.max(clusters, st.clusters);
          if (now - start < ms) requestAnimationFrame(tick);
          else done();
        };
        requestAnimationFrame(tick);
      });
      v.pause();
      return { stamps, cpu, triangles, clusters, lookUploads: v.state().review.lookUploads, time: v.state().time };
    }, [daysPerSecond, SECONDS * 1000]);
    const windows = [];
    const t0 = run.stamps[0];
    for (const t of run.stamps) {
      const w = Math.floor((t - t0) / 1000);
      windows[w] = (windows[w] || 0) + 1;
    }
    // The last window is partial.
    const full = windows.slice(0, Math.floor((run.stamps[run.stamps.length - 1] - t0) / 1000));
    const intervals = run.stamps.slice(1).map((t, i) => t - run.stamps[i]);
    out.modes[name] = {
      medianFps: median(full),
      minFps: Math.min(...full),
      maxFps: Math.max(...full),
      frames: run.stamps.length,
      medianFrameMs: median(intervals),
      medianCpuMs: median(run.cpu),
      maxTriangles: run.triangles,
      maxClusters: run.clusters,
      lookUploads: run.lookUploads,
      reachedTime: run.time,
      span: s.span,
    };
    await hook(page, (h) => h.pause());
    await page.close();
  }
} catch (e) {
  out.errors.push(`driver: ${e.stack || e}`);
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));

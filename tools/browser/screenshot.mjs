// The documentation's screenshots of the 4D review (docs/viewer-review.png,
// docs/schependomlaan-review.png):
//   node tools/browser/screenshot.mjs BASE_URL SCENE OUT.png [whole]
// The planned against actual mode with the Gantt chart open, near the
// tower (or, with `whole`, the viewer's own framing of the whole scene),
// at the time (of 120 through the period) when late objects cover the most
// pixels while others are at work on time or early, or, where nothing is
// ever late, when early objects cover the most; the chart scrolled to the
// task of the object drawn late (else early) over most pixels.
// scripts/viewer-screenshots runs it.
import { launch } from "./launch.mjs";
import { hook, settle } from "./page.mjs";

const [base, scene, file, framing] = process.argv.slice(2);
if (!base || !scene || !file) {
  console.error("usage: node screenshot.mjs BASE_URL SCENE OUT.png");
  process.exit(2);
}
const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 800 } });
  const errors = [];
  page.on("pageerror", (e) => errors.push(e.message));
  await page.goto(`${base}/?scene=${encodeURIComponent(scene)}&time=0&colour=deviation&gantt=1`);
  let s = await settle(page);
  if (framing !== "whole") {
    await hook(page, (v) => v.setCamera({ target: [0, 10, 0], distance: 55, azimuth: 0.75, elevation: 0.42 }));
  }
  const LATE = "217,48,37";
  const EARLY = "47,179,68";
  const ON_TIME = "59,130,246";
  let best = null;
  for (let i = 1; i < 120; i++) {
    const t = (s.span * i) / 120;
    await hook(page, (v, t) => v.setTime(t), t);
    await settle(page);
    const counts = await hook(page, (v) => {
      const cover = v.featureCoverage();
      const by = {};
      for (const [id, n] of Object.entries(cover)) {
        const l = v.lookOf(Number(id));
        if (!l || l[3] < 2) continue;
        const key = l.slice(0, 3).join(",");
        by[key] = (by[key] || 0) + n;
        if (key === "217,48,37" && (!by.top || n > by.top[1])) by.top = [Number(id), n];
        if (key === "47,179,68" && (!by.topEarly || n > by.topEarly[1])) by.topEarly = [Number(id), n];
      }
      return by;
    });
    const others = (counts[EARLY] || 0) + (counts[ON_TIME] || 0);
    const score = others > 0 ? counts[LATE] || 0 : 0;
    const early = counts[EARLY] || 0;
    if (!best || score > best.score || (score === best.score && early > best.early)) {
      best = { t, score, early, top: counts.top || counts.topEarly };
    }
  }
  await hook(page, (v, [t, top]) => {
    v.setTime(t);
    if (top) v.ganttBar(v.tasksOf(top[0])[0]);
  }, [best.t, best.top]);
  s = await settle(page);
  await page.waitForTimeout(300);
  await page.screenshot({ path: file });
  console.log(JSON.stringify({ file, time: s.time, date: s.date, late: best.top, rows: s.gantt.visible, errors }));
  if (errors.length) process.exitCode = 1;
} finally {
  await browser.close();
}

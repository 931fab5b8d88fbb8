// Drives the viewer's 4D review in headless chromium for
// server/tests/viewer_browser.rs:
//   node tools/browser/review.mjs BASE_URL SCENE SCREENSHOT_DIR
// and prints one JSON object of measurements on stdout; the Rust test
// asserts on it against the server's own answers. Colours are read from
// screenshots at pixels the pick pass says show the objects in question.
import { mkdirSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { launch } from "./launch.mjs";
import { canvasShot, compare, hook, pixelsAt, settle } from "./page.mjs";

const [base, scene, outDir] = process.argv.slice(2);
if (!base || !scene || !outDir) {
  console.error("usage: node review.mjs BASE_URL SCENE SCREENSHOT_DIR");
  process.exit(2);
}
mkdirSync(outDir, { recursive: true });
const WIDTH = 960;
const HEIGHT = 640;
const GANTT_TASKS = 5000;
const out = { errors: [] };

const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: WIDTH, height: HEIGHT } });
  page.on("pageerror", (e) => out.errors.push(`page error: ${e.message}`));
  let faults = false; // a bad profile is loaded on purpose at the end
  page.on("console", (m) => {
    if (m.type() === "error" && !faults) out.errors.push(`console: ${m.text()}`);
  });
  const v = (f, arg) => hook(page, f, arg);
  const sceneApi = `/api/v1/scenes/${encodeURIComponent(scene)}`;
  const api = (path) => page.evaluate(async (u) => (await fetch(u)).json(), path);
  const shot = async (name) => {
    const png = await canvasShot(page);
    writeFileSync(join(outDir, `${name}.png`), png);
    return png;
  };

  await page.goto(`${base}/?scene=${encodeURIComponent(scene)}&time=0&colour=appearance`);
  let s = await settle(page);
  const schedule = await api(`${sceneApi}/schedule`);
  const presence = (await api(`${sceneApi}/presence`)).presence;
  const presentAt = (i, t) => presence[i].some(([a, b]) => (a === null || a <= t) && (b === null || t < b));
  out.span = s.span;
  out.tasks = schedule.tasks.length;
  out.loaded = s.review;

  // The page's status of tasks of every kind of record (late, early, on
  // time, not recorded, still running) at the times around their dates;
  // the test asks the server the same.
  const recorded = (t) => t.actual_start !== undefined;
  const kinds = [
    (t) => recorded(t) && t.actual_start > t.start,
    (t) => recorded(t) && t.actual_finish !== undefined && t.actual_finish > t.finish,
    (t) => recorded(t) && t.actual_start < t.start,
    (t) => recorded(t) && t.actual_finish !== undefined && t.actual_finish < t.finish,
    (t) => recorded(t) && t.actual_start === t.start && t.actual_finish === t.finish,
    (t) => recorded(t) && t.actual_finish === undefined,
    (t) => !recorded(t),
  ];
  const chosen = new Set();
  for (const kind of kinds) {
    schedule.tasks.map((t, k) => [t, k]).filter(([t]) => kind(t)).slice(0, 3).forEach(([, k]) => chosen.add(k));
  }
  const probes = [];
  for (const k of chosen) {
    const t = schedule.tasks[k];
    const marks = [t.start, t.finish, t.actual_start, t.actual_finish].filter((x) => x !== undefined);
    const times = new Set([(t.start + t.finish) / 2]);
    for (const m of marks) for (const d of [-1, 0, 1]) times.add(m + d);
    for (const time of times) if (time >= 0 && time <= s.span) probes.push({ k, time });
  }
  out.status = await page.evaluate(async ([tasks, dates, probes]) => {
    const a = await import("/viewer/appearance.js");
    return probes.map(({ k, time }) => {
      const d = a.deviation(tasks[k], time);
      return { index: k, id: tasks[k].id, time, state: a.PROGRESS_NAMES[a.progress(tasks[k], time, dates)], deviation: d === null ? null : a.DEVIATION_NAMES[d] };
    });
  }, [schedule.tasks, schedule.dates, probes]);

  // The rules on hand-made cases, the library's own unit cases among them
  // (scene::status, scene::appearance, the governing task).
  out.rules = await page.evaluate(async () => {
    const a = await import("/viewer/appearance.js");
    const task = (start, finish, actualStart, actualFinish, type = "construct") => {
      const t = { type, start, finish };
      if (actualStart !== null) t.actual_start = actualStart;
      if (actualFinish !== null) t.actual_finish = actualFinish;
      return t;
    };
    const name = (d) => (d === null ? null : a.DEVIATION_NAMES[d]);
    const late = task(10, 20, 15, 30);
    const progress = [[late, 12, "planned"], [late, 12, "actual"], [late, 25, "planned"], [late, 25, "actual"],
      [task(10, 20, null, null), 1e9, "actual"], [task(10, 20, 5, null), 1e9, "actual"]]
      .map(([t, time, dates]) => a.PROGRESS_NAMES[a.progress(t, time, dates)]);
    const deviation = [
      ...[5, 12, 17, 25, 30].map((t) => name(a.deviation(late, t))),
      ...[7, 11, 15].map((t) => name(a.deviation(task(10, 20, 5, 12), t))),
      ...[7, 25].map((t) => name(a.deviation(task(10, 20, 5, null), t))),
      name(a.deviation(task(10, 20, null, null), 15)),
    ];
    // Four tasks on one object: 0 [0, 10) never recorded, 1 [5, 20)
    // recorded from 8 and still running, 2 [30, 40) never recorded, 3
    // [5, 15) recorded as planned.
    const tasks = [task(0, 10, null, null), task(5, 20, 8, null), task(30, 40, null, null), task(5, 15, 5, 15)];
    const governing = (list, t, dates) => {
      const idx = Int32Array.from(list);
      return a.governing(idx, 0, idx.length, a.standings(tasks, t, dates));
    };
    const governed = {
      planned: [-1, 2, 6, 17, 25, 35].map((t) => governing([0, 1, 2], t, "planned")),
      tie: governing([0, 1, 2, 3], 6, "planned"),
      actual: [6, 9, 27].map((t) => governing([0, 1, 2], t, "actual")),
      none: governing([], 6, "planned"),
    };
    const parse = (json) => {
      try {
        return { profile: a.parseProfile(JSON.parse(json), "p.json: ") };
      } catch (e) {
        return { error: e.message };
      }
    };
    const lateRed = parse('{"format": "hdlod-appearance/1", "name": "late red", "types": {"installation": {"active": {"color": "#00ffff"}}, "construct": {"active": {"color": "#0000ff", "transparency": 0.25}, "late": {"color": "#ff0000"}}, "demolish": {}}}').profile;
    const looks = {
      late: a.look(lateRed, 0, a.IN_PROGRESS, a.LATE),
      onTime: a.look(lateRed, 0, a.IN_PROGRESS, a.ON_TIME),
      before: a.look(lateRed, 0, a.NOT_STARTED, null),
      demolishAfter: a.look(lateRed, 1, a.FINISHED, null),
      defaultActive: a.look(a.DEFAULT_PROFILE, 0, a.IN_PROGRESS, null),
      temporaryAfter: a.look(a.DEFAULT_PROFILE, 2, a.FINISHED, null),
      installation: a.look(lateRed, 0, a.IN_PROGRESS, null, "INSTALLATION"),
      installationLate: a.look(lateRed, 0, a.IN_PROGRESS, a.LATE, "INSTALLATION"),
      construction: a.look(lateRed, 0, a.IN_PROGRESS, null, "CONSTRUCTION"),
    };
    const errors = [
      '{"format": "hdlod-appearance/1", "types": {"paint": {}}}',
      '{"format": "hdlod-appearance/1", "types": {"construct": {"after": "gone"}}}',
      '{"format": "hdlod-appearance/1", "types": {"construct": {"active": {"color": "green"}}}}',
      '{"format": "hdlod-appearance/1", "types": {"INSTALLATION": {}, "installation": {}}}',
      '{"format": "hdlod-appearance/2"}',
    ].map((j) => parse(j).error || null);
    return { progress, deviation, governed, looks, errors, name: lateRed.name };
  });

  // Pixels inside the present objects of `objects` whose look is `want`
  // (the look texture's bytes); up to `n` per object.
  const pixelsOf = async (objects, t, want, n) => {
    const looks = await v((h, ids) => ids.map((i) => h.lookOf(i)), objects);
    const ok = objects.filter((i, j) => presentAt(i, t) && looks[j] && want(looks[j]));
    const byId = await v((h, [ids, n]) => h.featurePixels(ids, n), [ok, n]);
    return { objects: ok, points: ok.flatMap((i) => (byId[i] || []).map((p) => ({ id: i, p }))) };
  };
  const running = (t) => (schedule.dates === "actual" ? [t.actual_start ?? Infinity, t.actual_finish ?? Infinity] : [t.start, t.finish]);
  const sameRgb = (hex) => (l) => l[0] === parseInt(hex.slice(1, 3), 16) && l[1] === parseInt(hex.slice(3, 5), 16) && l[2] === parseInt(hex.slice(5, 7), 16) && l[3] > 1;

  // Cameras: the tower (at the site's centre) from nearby, and the whole
  // site as the viewer frames it.
  const NEAR = { target: [0, 8, 0], distance: 45 };
  const cameras = [NEAR, { factor: 1 }];
  const view = (camera, t) => v((h, [c, t]) => {
    if (c.factor) h.setDistanceFactor(c.factor);
    else h.setCamera(c);
    h.setTime(t);
  }, [camera, t]);

  // (a) Task appearance: a construct task in progress; where its objects
  // are drawn the default profile's active green shows, blended; in the
  // model's colours it does not.
  await v((h) => { h.setPixelError(1); h.setColourMode("appearance"); });
  const construct = schedule.tasks.map((t, k) => [t, k]).filter(([t]) => t.type === "construct" && t.objects.length)
    .sort((a, b) => b[0].objects.length - a[0].objects.length);
  let active = null;
  for (const camera of cameras) {
    for (const [task, k] of construct) {
      const [a, b] = running(task);
      if (!Number.isFinite(a) || !Number.isFinite(b)) continue;
      const t = (a + b) / 2;
      await view(camera, t);
      await settle(page);
      const found = await pixelsOf(task.objects, t, sameRgb("#2fb344"), 12);
      if (found.points.length >= 20) {
        active = { k, id: task.id, time: t, camera, ...found };
        break;
      }
    }
    if (active) break;
  }
  if (active) {
    s = await settle(page);
    const look = await v((h, i) => h.lookOf(i), active.objects[0]);
    const appearance = await pixelsAt(page, await shot("appearance"), active.points.map((x) => x.p));
    await v((h) => h.setColourMode("vertex"));
    s = await settle(page);
    const model = await pixelsAt(page, await shot("appearance-model"), active.points.map((x) => x.p));
    out.active = { id: active.id, index: active.k, time: active.time, objects: active.objects, look, appearance, model, eye: s.eye, target: s.target };
  }

  // (b) Planned against actual: a task late at some time (before its late
  // start or past its planned finish) whose objects are drawn then, red;
  // one whose objects are not red in their own colours (formwork is).
  const red = ([r, g, b]) => r > g + 60 && r > b + 60;
  await v((h) => h.setColourMode("deviation"));
  const windows = [];
  schedule.tasks.forEach((task, k) => {
    if (task.actual_start === undefined) return;
    if (task.actual_start > task.start) windows.push([k, task.start, task.actual_start]);
    const finished = task.actual_finish ?? Infinity;
    if (finished > task.finish) windows.push([k, task.finish, Math.min(finished, s.span)]);
  });
  let late = null;
  for (const camera of cameras) {
    for (const [k, a, b] of windows) {
      if (!(b > a)) continue;
      const t = (a + b) / 2;
      await view(camera, t);
      await settle(page);
      const found = await pixelsOf(schedule.tasks[k].objects, t, sameRgb("#d93025"), 10);
      if (found.points.length < 15) continue;
      const points = found.points.map((x) => x.p);
      const deviation = await pixelsAt(page, await shot("deviation"), points);
      await v((h) => h.setColourMode("vertex"));
      await settle(page);
      const model = await pixelsAt(page, await shot("deviation-model"), points);
      await v((h) => h.setColourMode("deviation"));
      if (model.filter(red).length < 0.2 * model.length) {
        late = { id: schedule.tasks[k].id, index: k, time: t, objects: found.objects, deviation, model };
        break;
      }
    }
    if (late) break;
  }
  out.late = late;

  // (c) The Gantt chart: a click on a task's bar isolates its objects (the
  // rest faint, not pickable), a second click ends it, and from outside the
  // task the time moves to its start. Picking an object marks its tasks.
  if (active) {
    await v((h) => { h.showGantt(true); h.setColourMode("vertex"); });
    await view(active.camera, active.time);
    s = await settle(page);
    const others = await v((h, [n]) => h.featurePixels(Object.keys(h.featureCoverage()).map(Number), n), [3]);
    const taskObjects = new Set(schedule.tasks[active.k].objects);
    const otherPoints = Object.entries(others).filter(([id]) => !taskObjects.has(Number(id))).flatMap(([, ps]) => ps).slice(0, 80);
    const before = await shot("gantt-plain");
    const bar = await v((h, k) => h.ganttBar(k), active.k);
    await page.mouse.click(bar.x + Math.min(bar.w / 2, 20), bar.y + bar.h / 2);
    s = await settle(page);
    const isolated = { search: s.search, selected: s.gantt.selected, time: s.time, coverage: Object.keys(await v((h) => h.featureCoverage())).map(Number) };
    const after = await shot("gantt-isolated");
    await page.screenshot({ path: join(outDir, "gantt-page.png") });
    isolated.pixels = await compare(page, outDir, "gantt-isolate", before, after, { x: 0, y: 0, width: WIDTH, height: HEIGHT - 241 });
    isolated.othersBefore = await pixelsAt(page, before, otherPoints);
    isolated.othersAfter = await pixelsAt(page, after, otherPoints);
    const again = await v((h, k) => h.ganttBar(k), active.k);
    await page.mouse.click(again.x + Math.min(again.w / 2, 20), again.y + again.h / 2);
    s = await settle(page);
    isolated.ended = s.search;
    await v((h) => h.setTime(0));
    await settle(page);
    const third = await v((h, k) => h.ganttBar(k), active.k);
    await page.mouse.click(third.x + Math.min(third.w / 2, 20), third.y + third.h / 2);
    s = await settle(page);
    isolated.jump = { time: s.time, task: s.search.task };
    await v((h) => h.search("", "highlight"));
    out.ganttIsolate = isolated;

    // Picking: the chart scrolled to its top, an object whose tasks are all
    // below the rows in view; the click marks them and scrolls to them.
    await v((h, t) => { h.setTime(t); h.ganttBar(0); }, active.time);
    s = await settle(page);
    const rowsInView = s.gantt.last;
    const deep = schedule.tasks.map((t, k) => [t, k]).filter(([, k]) => k > rowsInView + 2);
    let target = null;
    for (const [task] of deep) {
      const ids = task.objects.filter((i) => presentAt(i, s.time));
      if (!ids.length) continue;
      const byId = await v((h, ids) => h.featurePixels(ids, 1), ids);
      const hit = ids.find((i) => byId[i] && byId[i].length);
      if (hit === undefined) continue;
      const tasks = await v((h, i) => h.tasksOf(i), hit);
      if (tasks.every((k) => k > rowsInView + 2)) {
        target = { index: hit, at: byId[hit][0] };
        break;
      }
    }
    if (target) {
      const visibleBefore = s.gantt.visible;
      await page.mouse.click(target.at[0], target.at[1]);
      s = await settle(page);
      out.ganttPick = { target, selection: s.selection, highlighted: s.gantt.highlighted, visible: s.gantt.visible, visibleBefore };
    }
    await v((h) => { h.select(null); h.showGantt(false); });
  }

  // (d) Each mode's legend, and a picture that differs from the model's.
  await v((h, t) => { h.setDistanceFactor(1); h.setTime(t); h.setColourMode("vertex"); }, (active ? active.time : s.span / 2));
  await settle(page);
  const plain = await shot("legend-vertex");
  out.legends = {};
  for (const mode of ["appearance", "deviation", "ifc_class", "storey", "class", "level"]) {
    await v((h, m) => h.setColourMode(m), mode);
    s = await settle(page);
    out.legends[mode] = {
      colours: s.review.legend,
      text: s.review.legendText,
      error: s.review.error,
      pixels: await compare(page, outDir, `mode-${mode}`, plain, await shot(`legend-${mode}`), { x: 0, y: 0, width: WIDTH, height: HEIGHT }),
    };
  }

  // (e) Another profile: from a data: URL in the link, then from a file;
  // a broken file is refused with the field named.
  if (active) {
    const profile = (name, hex) => JSON.stringify({ format: "hdlod-appearance/1", name, types: { construct: { active: { color: hex } } } });
    const coords = (x) => x.map((c) => String(Number(c.toPrecision(9)))).join(",");
    const link = `${base}/?scene=${encodeURIComponent(scene)}&colour=appearance&pixel_error=1&time=${active.time}`
      + `&position=${coords(out.active.eye)}&target=${coords(out.active.target)}`
      + `&gantt=1&task=${encodeURIComponent(active.id)}`
      + `&appearance=${encodeURIComponent(`data:application/json,${encodeURIComponent(profile("blue work", "#1f3fff"))}`)}`;
    await page.goto(link);
    s = await settle(page);
    // The chart takes the bottom of the window: the objects' pixels again.
    const byId = await v((h, ids) => h.featurePixels(ids, 12), active.objects);
    const points = Object.values(byId).flat();
    out.profileUrl = {
      profile: s.review.profile, source: s.review.profileSource, colours: await pixelsAt(page, await shot("profile-url"), points), legend: s.review.legend,
      colourMode: s.colourMode, gantt: s.gantt.open, gantt_selected: s.gantt.selected, search: s.search,
    };
    await page.setInputFiles("#profile-file", { name: "magenta.json", mimeType: "application/json", buffer: Buffer.from(profile("magenta work", "#e000e0")) });
    await page.waitForFunction(() => window.hdlodViewer.state().review.profile === "magenta work", null, { timeout: 10000 });
    s = await settle(page);
    await page.waitForTimeout(700);
    out.profileFile = {
      profile: s.review.profile,
      colours: await pixelsAt(page, await shot("profile-file"), points),
      legend: s.review.legend,
      address: await page.evaluate(() => location.search),
    };
    faults = true;
    await page.setInputFiles("#profile-file", { name: "broken.json", mimeType: "application/json", buffer: Buffer.from('{"format": "hdlod-appearance/1", "types": {"construct": {"after": "gone"}}}') });
    await page.waitForFunction(() => window.hdlodViewer.state().error, null, { timeout: 10000 });
    s = await settle(page);
    out.profileBroken = { error: s.error, profile: s.review.profile };
    faults = false;
  }

  // The Gantt chart alone with a synthetic schedule of 5,000 tasks (250
  // summary tasks of 19 tasks each, baselines, actual dates on most):
  // the time to draw a frame while scrolling and zooming, the canvas
  // flushed each frame so the drawing is counted, not just recorded.
  out.ganttBench = await page.evaluate(async (n) => {
    const { Gantt } = await import("/viewer/gantt.js");
    const canvas = document.createElement("canvas");
    canvas.style.cssText = "position: fixed; left: 0; top: 0; width: 1280px; height: 600px; z-index: 10";
    document.body.appendChild(canvas);
    const DAY = 86400;
    const span = 3 * 365 * DAY;
    const types = ["construct", "temporary", "demolish", "maintain"];
    const tasks = [];
    let seed = 1;
    const random = () => ((seed = (seed * 16807) % 2147483647) / 2147483647);
    for (let p = 0; tasks.length < n; p++) {
      const summary = tasks.length;
      const start = random() * span * 0.8;
      tasks.push({ id: `S${p}`, name: `Phase ${p}`, type: "construct", start, finish: start + 60 * DAY, objects: [] });
      for (let c = 0; c < 19 && tasks.length < n; c++) {
        const a = start + random() * 50 * DAY;
        const task = { id: `T${tasks.length}`, name: `Phase ${p} task ${c}`, type: types[c % 4], start: a, finish: a + (1 + random() * 9) * DAY, parent: summary, objects: [tasks.length] };
        task.baseline_start = a - random() * 5 * DAY;
        task.baseline_finish = task.finish - random() * 3 * DAY;
        if (random() < 0.7) {
          task.actual_start = a + (random() - 0.5) * 4 * DAY;
          if (random() < 0.8) task.actual_finish = task.finish + (random() - 0.3) * 4 * DAY;
        }
        tasks.push(task);
      }
    }
    const g = new Gantt(canvas, () => {});
    const layoutStart = performance.now();
    g.setSchedule({ start: "2024-01-01T00:00:00Z", seconds: span, dates: "planned", tasks });
    g.layout();
    const layoutMs = performance.now() - layoutStart;
    const ctx = canvas.getContext("2d");
    const times = [];
    for (let f = 0; f < 300; f++) {
      g.setTime((span * f) / 300);
      g.scrollRows(f % 100 < 50 ? 173 : -173);
      if (f % 20 === 10) g.zoomAt(640, f % 40 === 10 ? 1.6 : 1 / 1.6);
      const a = performance.now();
      g.draw();
      ctx.getImageData(0, 0, 1, 1);
      times.push(performance.now() - a);
    }
    g.highlight([4321]);
    g.draw();
    const state = g.state();
    times.sort((a, b) => a - b);
    const at = (q) => times[Math.min(times.length - 1, Math.floor(q * times.length))];
    return { tasks: tasks.length, frames: times.length, layoutMs, medianMs: at(0.5), p95Ms: at(0.95), maxMs: times[times.length - 1], rowsDrawn: state.last - state.first, revealed: state.visible.includes("T4321") };
  }, GANTT_TASKS);
  await page.screenshot({ path: join(outDir, "gantt-5000.png"), clip: { x: 0, y: 0, width: 1280 > WIDTH ? WIDTH : 1280, height: 600 } });
} catch (e) {
  out.errors.push(`driver: ${e.stack || e}`);
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));

// The hdlod web viewer: a 4D construction site at any date. The cut (which
// clusters to draw) comes from the server's stream for the current time,
// camera and pixel error; this page fetches the clusters' GLBs once, draws
// them, moves dynamic ones to their transforms and shows what it costs
// against drawing every present object (docs/viewer.md). A click picks the
// scene object under the cursor (its properties and tasks in a panel); a
// search highlights, isolates or hides objects; objects absent at the
// current time are hidden even inside a drawn cluster. For a 4D review the
// colour modes colour each object by its task's appearance, by its
// execution against the plan, by class or storey, and a Gantt chart of the
// schedule follows the time (docs/viewer.md).

import { Camera, FOV_Y_DEG } from "./camera.js";
import { Renderer, classColour, levelColour } from "./renderer.js";
import { CutConnection, GeometryCache } from "./stream.js";
import { multiply, project } from "./mat4.js";
import { FeatureState } from "./featurestate.js";
import { ObjectPanel, objectField, searchObjects } from "./objects.js";
import { PHASES, TASK_TYPES, running, parseProfile } from "./appearance.js";
import { FeatureColours, MODES as FEATURE_MODES, naturalOrder } from "./colours.js";
import { Gantt } from "./gantt.js";

const $ = (id) => document.getElementById(id);
const DAY = 86400;

const ui = {
  canvas: $("view"), scene: $("scene"), play: $("play"), speed: $("speed"), time: $("time"),
  date: $("date"), pixelError: $("pixel-error"), pixelErrorValue: $("pixel-error-value"),
  colour: $("colour"), mode: $("mode"), stats: $("stats"), legend: $("legend"), message: $("message"),
  panel: $("panel"), search: $("search"), query: $("query"), searchMode: $("search-mode"),
  isolate: $("isolate"), hide: $("hide"), clear: $("clear"), matches: $("matches"),
  profile: $("profile"), profileFile: $("profile-file"), ganttToggle: $("gantt-toggle"),
  gantt: $("gantt"), ganttCanvas: $("gantt-canvas"),
};

// A press that moves less than this (CSS pixels) is a click, not a drag.
const CLICK_SLOP = 4;
const MODES = ["highlight", "isolate", "hide"];
const COLOUR_MODES = ["vertex", "class", "level", ...FEATURE_MODES];

const viewer = {
  ready: false,
  scene: null, // the scene's metadata (GET /api/v1/scenes/{scene})
  sceneUrl: null, // that path, the base of the scene's routes
  t: 0,
  pixelError: 1,
  // "none" draws every present leaf at full detail, in view or not (the
  // paper's comparison, `lod=none` in the address); null: the cut.
  lod: null,
  colourMode: "vertex",
  playing: false,
  clusters: new Map(), // id -> {info (cut cluster), gpu, transform, joints (a skinned cluster's)}
  missing: new Map(), // id -> {info, transform, joints}: in the cut, geometry not loaded yet
  missingTimer: null,
  stats: null, // the last answer's stats
  latency: 0,
  frameMs: 0,
  lastRequest: null, // the request of the cut that is drawn
  seq: 0,
  answers: 0, // cut answers drawn, over every connection
  viewKey: "",
  viewRequest: null, // the request of the current view, as sent
  viewSince: 0, // when the view last changed (performance.now())
  holdUntil: 0, // a time jump's frame waits for its cut until then (HOLD_MS)
  readyMs: null, // from the last view change until its cut was drawable
  frames: 0,
  staleFrames: 0, // frames drawn before the view's own cut was drawable
  needsDraw: true,
  matrices: null,
  error: null,
  features: new FeatureState(),
  panel: null, // ObjectPanel
  objectsError: null, // why the scene has no object table, if it has none
  selection: null, // {index, id}
  search: { q: "", mode: "highlight", matches: [], pending: false, task: null },
  picks: 0,
  colours: new FeatureColours(), // the per-feature colours of the review modes
  schedule: null, // GET .../schedule
  profileSource: null, // where the profile came from: null (the scene's), a URL or a data: URL
  review: { pending: true, error: null, categories: {} }, // categories: mode -> {pending, error}
  gantt: null, // Gantt
};

let renderer;
let camera;
let cache;
let connection;

function showMessage(text) {
  viewer.error = text;
  ui.message.textContent = text || "";
  ui.message.hidden = !text;
}

async function getJson(url) {
  let response;
  try {
    response = await fetch(url);
  } catch (e) {
    throw new Error(`Cannot reach the hdlod server at ${location.origin} (${e.message}). Is \`hdlod serve\` running?`);
  }
  let body = null;
  try {
    body = await response.json();
  } catch {
    // A non-JSON answer is reported by its status below.
  }
  if (!response.ok) {
    const m = body && body.error ? body.error.message : response.statusText;
    const e = new Error(`${url}: ${response.status} ${m}`);
    e.status = response.status;
    throw e;
  }
  return body;
}

function formatDate(t) {
  const start = Date.parse(viewer.scene.time.start);
  return new Date(start + t * 1000).toISOString().replace("T", " ").slice(0, 16);
}

function parseTime(text) {
  if (text === null || text === "") return null;
  const n = Number(text);
  if (Number.isFinite(n)) return n;
  const ms = Date.parse(text);
  return Number.isFinite(ms) ? (ms - Date.parse(viewer.scene.time.start)) / 1000 : null;
}

function span() {
  return viewer.scene.time.seconds;
}

function setTime(t) {
  viewer.t = Math.max(0, Math.min(span(), t));
  ui.time.value = String(Math.round((viewer.t / Math.max(span(), 1e-9)) * 10000));
  ui.date.textContent = formatDate(viewer.t);
  viewer.features.setTime(viewer.t);
  viewer.colours.setTime(viewer.t);
  if (viewer.gantt) viewer.gantt.setTime(viewer.t);
  if (viewer.panel) viewer.panel.setTime(viewer.t);
  viewer.needsDraw = true;
}

function sliderToPixelError(v) {
  return 0.5 * 2 ** (v / 10);
}

function setPixelError(p) {
  viewer.pixelError = p;
  ui.pixelError.value = String(Math.round(10 * Math.log2(p / 0.5)));
  ui.pixelErrorValue.textContent = p < 10 ? p.toFixed(1) : p.toFixed(0);
}

function setColourMode(mode) {
  if (!COLOUR_MODES.includes(mode)) mode = "vertex";
  viewer.colourMode = mode;
  urlDirty = true;
  ui.colour.value = mode;
  ui.profile.hidden = mode !== "appearance";
  viewer.colours.setMode(mode);
  if (mode === "ifc_class" || mode === "storey") loadCategories(mode);
  renderLegend();
  viewer.needsDraw = true;
}

function hex(rgb) {
  return `#${rgb.map((c) => Math.round(c * 255).toString(16).padStart(2, "0")).join("")}`;
}

function escapeHtml(text) {
  return String(text).replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" })[c]);
}

// One legend entry: a swatch of `colour` ("#rrggbb"; null: the objects'
// own colours) and its words. Swatches carry their colour as data-colour.
function entry(colour, label, opacity = 1) {
  const swatch = colour
    ? `<span class="swatch" data-colour="${colour}" style="background: ${colour}; opacity: ${Math.max(opacity, 0.15)}"></span>`
    : `<span class="swatch own" data-colour="model"></span>`;
  return `<span class="entry">${swatch}${escapeHtml(label)}</span>`;
}

// The look of a phase in the appearance legend.
function lookEntry(phase, l) {
  if (l.kind === "hidden") return `<span class="entry"><span class="note">${phase}:</span> hidden</span>`;
  if (l.kind === "model") return entry(null, `${phase}`);
  const transparency = l.transparency > 0 ? ` (${Math.round(l.transparency * 100)}% transparent)` : "";
  return entry(l.hex, `${phase}${transparency}`, 1 - l.transparency);
}

// The legend of the colour mode (the `legend` aside).
function renderLegend() {
  const mode = viewer.colourMode;
  const review = viewer.review;
  let html = "";
  if (mode === "class") {
    html = ["static", "pseudo_dynamic", "dynamic"].map((c) => entry(hex(classColour(c)), c.replace("_", "-"))).join("") + ' <span class="note">(visibility class)</span>';
  } else if (mode === "level") {
    html = [0, 1, 2, 3, 4, 5, 6].map((l) => entry(hex(levelColour(l)), l === 6 ? "6+" : String(l))).join("") + ' <span class="note">(HDLOD level; 0: original objects)</span>';
  } else if (mode === "appearance") {
    const profile = viewer.colours.profile;
    // A row per type the schedule uses; an IFC type the profile gives
    // looks of its own gets its own row.
    const tasks = viewer.schedule ? viewer.schedule.tasks : TASK_TYPES.map((type) => ({ type }));
    const used = new Set(tasks.map((t) => (t.ifc_type && profile.ifc[t.ifc_type] ? t.ifc_type : t.type)));
    const names = [...TASK_TYPES, ...Object.keys(profile.ifc).sort()];
    const rows = names.filter((name) => used.has(name)).map((name) => {
      const looks = profile.ifc[name] || profile.types[TASK_TYPES.indexOf(name)];
      const phases = PHASES.filter((p) => looks[p]).map((p) => lookEntry(p, looks[p])).join("");
      return `<div data-type="${name}"><span class="type">${name}</span>${phases}</div>`;
    }).join("");
    const from = viewer.profileSource ? (viewer.profileSource.startsWith("data:") ? " (loaded)" : ` (${escapeHtml(viewer.profileSource)})`) : "";
    html = `<div class="note">appearance profile <b data-field="profile">${escapeHtml(profile.name)}</b>${from}; ${entry(null, "own colour")}</div>${rows}`;
  } else if (mode === "deviation" || mode === "ifc_class" || mode === "storey") {
    const c = review.categories[mode];
    const entries = viewer.colours.legend().map((e) => entry(e.colour, e.note ? `${e.label} (${e.note})` : e.label)).join("");
    const title = { deviation: "planned against actual", ifc_class: "IFC class", storey: "storey" }[mode];
    html = `<div class="note">${title}</div>${entries}`;
    if (c && c.pending) html += ` <span class="note">loading&hellip;</span>`;
    if (c && c.error) html += ` <span class="error">${escapeHtml(c.error)}</span>`;
  }
  if (mode === "appearance" || mode === "deviation") {
    if (review.pending) html += ' <span class="note">loading the schedule&hellip;</span>';
    if (review.error) html += ` <span class="error">${escapeHtml(review.error)}</span>`;
  }
  ui.legend.innerHTML = html;
}

// The distinct values of every object's class or storey, once per scene,
// when their mode is first chosen.
async function loadCategories(mode) {
  const state = viewer.review.categories;
  if (state[mode] || viewer.features.count === 0) return;
  const c = { pending: true, error: null };
  state[mode] = c;
  const count = viewer.features.count;
  try {
    const values = await objectField(viewer.sceneUrl, count, mode === "ifc_class" ? "class" : "storey", getJson);
    const names = [...new Set(values.filter((v) => v !== null))].sort(naturalOrder);
    const index = new Map(names.map((n, i) => [n, i]));
    viewer.colours.setCategories(mode, names, Int32Array.from(values, (v) => (v === null ? -1 : index.get(v))));
  } catch (e) {
    c.error = e.message;
  } finally {
    c.pending = false;
    if (viewer.colourMode === mode) renderLegend();
  }
}

function setPlaying(on) {
  viewer.playing = on && viewer.t < span();
  if (on && !viewer.playing) {
    setTime(0);
    viewer.playing = true;
  }
  ui.play.innerHTML = viewer.playing ? "&#10074;&#10074;" : "&#9654;";
}

function setMode(mode) {
  camera.mode = mode;
  ui.mode.textContent = mode;
}

function viewportSize() {
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(ui.canvas.clientWidth * dpr));
  const h = Math.max(1, Math.round(ui.canvas.clientHeight * dpr));
  if (ui.canvas.width !== w || ui.canvas.height !== h) {
    ui.canvas.width = w;
    ui.canvas.height = h;
    viewer.needsDraw = true;
  }
  return [w, h];
}

function cutRequest(width, height) {
  const m = camera.matrices(width / height);
  viewer.matrices = m;
  return {
    time: viewer.t,
    camera: {
      position: m.eye,
      target: camera.target,
      up: camera.u,
      fov_y_deg: FOV_Y_DEG,
      aspect: width / height,
      near: m.near,
      far: m.far,
    },
    viewport: { width, height },
    pixel_error: viewer.pixelError,
    // Once the objects' presence is known the state texture hides absent
    // objects inside any cluster, so the partly present clusters the
    // paper's rule leaves out can be drawn too: nothing present is missing.
    presence: viewer.features.count > 0 ? "exact" : "paper",
    ...(viewer.lod ? { lod: viewer.lod } : {}),
  };
}

async function onMessage(msg, request, millis) {
  if (msg.error) {
    showMessage(`The server refused the view: ${msg.error.field ? msg.error.field + ": " : ""}${msg.error.message}`);
    return;
  }
  const loads = await Promise.allSettled(msg.add.map((c) => cache.get(c.geometry)));
  const failed = loads.filter((l) => l.status === "rejected").map((l) => l.reason.message);
  if (msg.reset) {
    viewer.clusters.clear();
    viewer.missing.clear();
  }
  for (const id of msg.remove) {
    viewer.clusters.delete(id);
    viewer.missing.delete(id);
  }
  msg.add.forEach((c, i) => {
    const transform = c.transform && new Float32Array(c.transform);
    const joints = c.joints ? new Float32Array(c.joints.flat()) : null;
    if (loads[i].status === "fulfilled") viewer.clusters.set(c.id, { info: c, gpu: loads[i].value, transform, joints });
    else viewer.missing.set(c.id, { info: c, transform, joints });
  });
  for (const u of msg.update) {
    const held = viewer.clusters.get(u.id) || viewer.missing.get(u.id);
    if (!held) continue;
    held.transform = u.transform && new Float32Array(u.transform);
    // A skinned cluster's new pose.
    if (u.joints) held.joints = new Float32Array(u.joints.flat());
  }
  if (viewer.missing.size > 0) retryMissingLater();
  cache.evict(new Set([...viewer.clusters.values(), ...viewer.missing.values()].map((c) => c.info.geometry)));
  viewer.stats = msg.stats;
  viewer.latency = millis;
  viewer.seq = msg.seq;
  viewer.answers += 1;
  viewer.lastRequest = request;
  if (request === viewer.viewRequest) viewer.readyMs = performance.now() - viewer.viewSince;
  viewer.needsDraw = true;
  updateStats();
  if (failed.length) showMessage(`Could not load ${failed.length} cluster(s): ${failed[0]}; trying again.`);
  else if (viewer.missing.size === 0 && viewer.error && viewer.error.startsWith("Could not load")) showMessage(null);
}

// The server counts a cluster it sent as held, so the page itself asks
// again for the geometry it could not load, every few seconds while the
// cluster stays in the cut, without waiting for the view to change.
const MISSING_RETRY_MS = 3000;

function retryMissingLater() {
  if (viewer.missingTimer === null) viewer.missingTimer = setTimeout(retryMissing, MISSING_RETRY_MS);
}

async function retryMissing() {
  const wanted = [...viewer.missing.entries()];
  const loads = await Promise.allSettled(wanted.map(([, m]) => cache.get(m.info.geometry)));
  viewer.missingTimer = null;
  let failed = null;
  wanted.forEach(([id, m], i) => {
    // Only if the cut still holds it as it was.
    if (viewer.missing.get(id) !== m) return;
    if (loads[i].status === "rejected") {
      failed = failed || loads[i].reason.message;
      return;
    }
    viewer.missing.delete(id);
    viewer.clusters.set(id, { info: m.info, gpu: loads[i].value, transform: m.transform, joints: m.joints });
    viewer.needsDraw = true;
  });
  updateStats();
  if (viewer.missing.size > 0) {
    showMessage(`Could not load ${viewer.missing.size} cluster(s): ${failed || "still loading"}; trying again.`);
    retryMissingLater();
  } else if (viewer.error && viewer.error.startsWith("Could not load")) {
    showMessage(null);
  }
}

function tint(c) {
  if (viewer.colourMode === "class") return classColour(c.info.class);
  if (viewer.colourMode === "level") return levelColour(c.info.level);
  return null;
}

function drawItems() {
  const items = [];
  for (const c of viewer.clusters.values()) {
    // A dynamic cluster's GLB (shared by the model's instances) has no
    // feature ids; the answer names its object.
    items.push({ gpu: c.gpu, transform: c.transform, joints: c.joints, tint: tint(c), feature: c.info.object ?? null });
  }
  return items;
}

// The state texture follows the time and the flags, the looks the time,
// the colour mode and the profile: each uploaded only when one of them
// changed since its last upload.
function uploadFeatureState() {
  const f = viewer.features;
  if (f.dirty) {
    f.dirty = false;
    renderer.setState(f.bytes(renderer.stateRowBytes()), f.count);
  }
  const c = viewer.colours;
  if (c.dirty) {
    c.dirty = false;
    const bytes = c.bytes(renderer.stateRowBytes());
    renderer.setLooks(bytes, c.count);
    if (!bytes) c.translucent = 0;
  }
}

function draw(width, height, matrices = viewer.matrices) {
  const start = performance.now();
  viewer.frames += 1;
  if (viewer.lastRequest !== viewer.viewRequest) viewer.staleFrames += 1;
  uploadFeatureState();
  renderer.draw(drawItems(), matrices, width, height, viewer.features.isolating(), viewer.colours.translucent > 0);
  const ms = performance.now() - start;
  viewer.frameMs = viewer.frameMs ? viewer.frameMs * 0.8 + ms * 0.2 : ms;
}

function drawnTriangles() {
  let n = 0;
  for (const c of viewer.clusters.values()) n += c.info.triangles;
  return n;
}

function number(n) {
  return Math.round(n).toLocaleString("en-US");
}

function updateStats() {
  const s = viewer.stats;
  if (!s) return;
  const tri = drawnTriangles();
  const ratio = tri > 0 ? (s.baseline_triangles / tri).toFixed(1) + "x" : "-";
  const lines = [
    ...(viewer.lod === "none" ? ["no LOD           every present object"] : []),
    `clusters drawn   ${number(viewer.clusters.size)}`,
    ...(viewer.missing.size > 0 ? [`clusters loading ${number(viewer.missing.size)} (retrying)`] : []),
    `triangles drawn  ${number(tri)}`,
    `baseline         ${number(s.baseline_triangles)} tris`,
    `                 ${number(s.baseline_objects)} objects`,
    `saving           ${ratio}`,
    `GLB loaded       ${(cache.bytes / 1048576).toFixed(2)} MB, ${cache.files} files`,
    `cut latency      ${viewer.latency.toFixed(1)} ms (server ${(s.micros / 1000).toFixed(2)} ms)`,
    `frame (CPU)      ${viewer.frameMs.toFixed(1)} ms, ${number(renderer.drawCalls)} draw calls`,
  ];
  ui.stats.textContent = lines.join("\n");
}

// The address follows the view (at most twice a second) so it can be shared.
let lastUrlUpdate = -Infinity;
let urlDirty = false;
function updateUrl(now) {
  if (!urlDirty || now - lastUrlUpdate < 500) return;
  lastUrlUpdate = now;
  urlDirty = false;
  const params = new URLSearchParams(location.search);
  params.set("scene", viewer.scene.name);
  params.set("time", formatDate(viewer.t).replace(" ", "T") + "Z");
  params.set("pixel_error", String(viewer.pixelError));
  params.set("colour", viewer.colourMode);
  const coords = (v) => v.map((x) => String(Number(x.toPrecision(9)))).join(",");
  params.set("position", coords(camera.eye()));
  params.set("target", coords(camera.target));
  const set = (name, value) => (value ? params.set(name, value) : params.delete(name));
  set("selected", viewer.selection && viewer.selection.id);
  set("q", viewer.search.q);
  set("mode", viewer.search.q && viewer.search.mode !== "highlight" ? viewer.search.mode : null);
  set("task", viewer.search.task);
  set("gantt", ui.gantt.hidden ? null : "1");
  set("appearance", viewer.profileSource);
  set("lod", viewer.lod);
  history.replaceState(null, "", `?${params}`);
}

// A jump in time (a step, the slider, a task's start) holds its frame
// until its own cut is drawable, for at most HOLD_MS: the old cut at the
// new time would lack the objects that appeared in clusters it does not
// hold, and in a software rasteriser that frame costs as much as the right
// one and delays it (the page waits for a frame to be drawn before it
// handles the cut's answer). Moving the camera and playing draw at once.
const HOLD_MS = 200;

function sameButTime(a, b) {
  return JSON.stringify({ ...a, time: 0 }) === JSON.stringify({ ...b, time: 0 });
}

let lastFrame = performance.now();
let lastStats = 0;
const keys = new Set();

function frame(now) {
  const dt = Math.min((now - lastFrame) / 1000, 0.25);
  lastFrame = now;
  if (viewer.playing) {
    setTime(viewer.t + dt * Number(ui.speed.value) * DAY);
    if (viewer.t >= span()) setPlaying(false);
  }
  if (camera.mode === "fly" && keys.size) {
    const k = (a, b) => (keys.has(a) ? 1 : 0) - (keys.has(b) ? 1 : 0);
    const step = dt * camera.sceneRadius * 0.4 * (keys.has("Shift") ? 3 : 1);
    camera.move(k("w", "s"), k("d", "a"), k("e", "q"), step);
  }
  const [width, height] = viewportSize();
  const request = cutRequest(width, height);
  const key = JSON.stringify(request);
  if (key !== viewer.viewKey) {
    const jump = !viewer.playing && viewer.viewRequest && sameButTime(request, viewer.viewRequest);
    viewer.viewKey = key;
    viewer.viewRequest = request;
    viewer.viewSince = performance.now();
    viewer.holdUntil = jump ? viewer.viewSince + HOLD_MS : 0;
    viewer.readyMs = null;
    connection.request(request);
    viewer.needsDraw = true;
    urlDirty = true;
  }
  updateUrl(now);
  if (viewer.features.dirty || viewer.colours.dirty) viewer.needsDraw = true;
  if (viewer.needsDraw && (viewer.lastRequest === viewer.viewRequest || performance.now() >= viewer.holdUntil)) {
    viewer.needsDraw = false;
    draw(width, height);
  }
  if (!ui.gantt.hidden) viewer.gantt.frame();
  if (now - lastStats > 250) {
    lastStats = now;
    updateStats();
  }
  requestAnimationFrame(frame);
}

function bindInput() {
  let drag = null;
  ui.canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  ui.canvas.addEventListener("pointerdown", (e) => {
    ui.canvas.focus();
    ui.canvas.setPointerCapture(e.pointerId);
    drag = { x: e.clientX, y: e.clientY, x0: e.clientX, y0: e.clientY, button: e.button, pan: e.button === 2 || e.shiftKey || e.button === 1 };
  });
  ui.canvas.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x;
    const dy = e.clientY - drag.y;
    drag.x = e.clientX;
    drag.y = e.clientY;
    if (drag.pan) camera.pan(dx, dy, ui.canvas.clientHeight);
    else camera.rotate(dx, dy);
  });
  ui.canvas.addEventListener("pointerup", (e) => {
    const click = drag && drag.button === 0 && Math.hypot(e.clientX - drag.x0, e.clientY - drag.y0) < CLICK_SLOP;
    drag = null;
    if (click) selectAt(e.clientX, e.clientY);
  });
  ui.canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    camera.zoom(Math.exp(e.deltaY * 0.0015));
  }, { passive: false });
  window.addEventListener("keydown", (e) => {
    if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement) return;
    if (e.key === " ") {
      e.preventDefault();
      setPlaying(!viewer.playing);
    } else if (e.key === "f" || e.key === "F") {
      setMode(camera.mode === "fly" ? "orbit" : "fly");
    } else {
      keys.add(e.key.length === 1 ? e.key.toLowerCase() : e.key);
    }
  });
  window.addEventListener("keyup", (e) => keys.delete(e.key.length === 1 ? e.key.toLowerCase() : e.key));
  window.addEventListener("blur", () => keys.clear());
  ui.time.addEventListener("input", () => setTime((Number(ui.time.value) / 10000) * span()));
  ui.play.addEventListener("click", () => setPlaying(!viewer.playing));
  ui.pixelError.addEventListener("input", () => setPixelError(sliderToPixelError(Number(ui.pixelError.value))));
  ui.colour.addEventListener("change", () => setColourMode(ui.colour.value));
  ui.profile.addEventListener("click", () => ui.profileFile.click());
  ui.profileFile.addEventListener("change", async () => {
    const file = ui.profileFile.files[0];
    ui.profileFile.value = "";
    if (file && (await loadProfileText(await file.text(), file.name))) setColourMode("appearance");
  });
  ui.ganttToggle.addEventListener("click", () => showGantt(ui.gantt.hidden));
  ui.mode.addEventListener("click", () => setMode(camera.mode === "fly" ? "orbit" : "fly"));
  ui.search.addEventListener("submit", (e) => {
    e.preventDefault();
    search(ui.query.value.trim(), viewer.search.mode);
  });
  ui.isolate.addEventListener("click", () => search(ui.query.value.trim(), "isolate"));
  ui.hide.addEventListener("click", () => search(ui.query.value.trim(), "hide"));
  ui.clear.addEventListener("click", () => search("", "highlight"));
  ui.panel.addEventListener("click", (e) => {
    if (e.target.closest(".close")) select(null);
  });
  ui.scene.addEventListener("change", () => {
    const params = new URLSearchParams({ scene: ui.scene.value });
    location.search = `?${params}`;
  });
}

// The feature under the CSS pixel (x, y) of the canvas: one pick pass,
// scissored to that pixel, of the view on screen.
function pickAt(x, y) {
  if (!viewer.matrices) return null;
  const r = ui.canvas.getBoundingClientRect();
  const dpr = ui.canvas.width / Math.max(r.width, 1);
  const [width, height] = [ui.canvas.width, ui.canvas.height];
  uploadFeatureState();
  viewer.picks++;
  return renderer.pick(drawItems(), viewer.matrices, width, height, Math.floor((x - r.left) * dpr), Math.floor((y - r.top) * dpr));
}

function selectAt(x, y) {
  const index = pickAt(x, y);
  select(index === null ? null : { index, id: null });
}

// selection: {index, id (null until the panel knows it)} or null. Its
// tasks are marked in the Gantt chart.
function select(selection) {
  viewer.selection = selection;
  viewer.features.select(selection && selection.index);
  viewer.panel.show(selection && selection.index, viewer.t);
  if (viewer.schedule) viewer.gantt.highlight(selection ? viewer.colours.tasksOf(selection.index) : []);
  urlDirty = true;
  viewer.needsDraw = true;
}

// Task k and the tasks under it in the WBS.
function taskTree(k) {
  const tasks = viewer.schedule.tasks;
  const under = new Set([k]);
  // Parents come in any order: sweep until no task joins.
  for (let grew = true; grew;) {
    grew = false;
    tasks.forEach((t, j) => {
      if (!under.has(j) && t.parent !== undefined && under.has(t.parent)) {
        under.add(j);
        grew = true;
      }
    });
  }
  return [...under];
}

// Isolates the objects of task k (and of the tasks under it), as a search
// does; a planner looks at a task while it runs, so the time moves to its
// start unless it is already within it. The same task again ends it.
function isolateTask(k) {
  const task = viewer.schedule.tasks[k];
  if (viewer.search.task === task.id) {
    search("", "highlight");
    return;
  }
  const objects = new Set();
  for (const j of taskTree(k)) for (const i of viewer.schedule.tasks[j].objects) objects.add(i);
  const matches = [...objects].sort((a, b) => a - b);
  const s = viewer.search;
  Object.assign(s, { q: "", mode: "isolate", matches, pending: false, task: task.id });
  ui.query.value = "";
  ui.searchMode.textContent = "isolate";
  ui.matches.textContent = `task ${task.id}: ${matches.length} objects`;
  viewer.features.setMatches(matches, "isolate");
  viewer.gantt.setSelected(k);
  const [start, finish] = running(task, viewer.schedule.dates);
  if (!(viewer.t >= start && viewer.t < finish)) setTime(Number.isFinite(start) ? start : task.start);
  urlDirty = true;
}

// q: the text (empty clears); mode: what the matches do.
async function search(q, mode) {
  const s = viewer.search;
  s.q = q;
  s.mode = MODES.includes(mode) ? mode : "highlight";
  s.task = null;
  if (viewer.gantt) viewer.gantt.setSelected(null);
  ui.query.value = q;
  ui.searchMode.textContent = q && s.mode !== "highlight" ? s.mode : "";
  urlDirty = true;
  if (!q) {
    s.matches = [];
    ui.matches.textContent = "";
    viewer.features.setMatches([], s.mode);
    return;
  }
  s.pending = true;
  try {
    const matches = await searchObjects(viewer.sceneUrl, q, getJson);
    if (s.q !== q) return;
    s.matches = matches;
    ui.matches.textContent = `${matches.length} found`;
    viewer.features.setMatches(matches, s.mode);
  } catch (e) {
    if (s.q === q) ui.matches.textContent = e.message;
  } finally {
    if (s.q === q) s.pending = false;
  }
}

function cutBytes() {
  const drawn = new Map();
  for (const c of viewer.clusters.values()) drawn.set(c.info.geometry, c.gpu);
  let bytes = 0;
  let textureBytes = 0;
  for (const gpu of drawn.values()) {
    bytes += gpu.fileBytes || 0;
    textureBytes += gpu.textureFileBytes || 0;
  }
  return { cutBytes: bytes, cutTextureBytes: textureBytes };
}

// The read-only test hook (docs/viewer.md): the browser tests drive the
// viewer through it instead of hunting pixels.
function testHook() {
  return {
    state() {
      const m = viewer.matrices;
      const w = ui.canvas.clientWidth;
      const h = ui.canvas.clientHeight;
      const dynamicScreenPositions = [];
      for (const c of viewer.clusters.values()) {
        if (!c.transform || !m) continue;
        const [x, y, , cw] = project(m.viewProj, [c.transform[12], c.transform[13], c.transform[14]]);
        if (cw <= 0) continue;
        dynamicScreenPositions.push({ id: c.info.id, x: ((x / cw + 1) / 2) * w, y: ((1 - y / cw) / 2) * h });
      }
      return {
        ready: viewer.ready,
        error: viewer.error,
        scene: viewer.scene && viewer.scene.name,
        time: viewer.t,
        date: viewer.scene && formatDate(viewer.t),
        span: viewer.scene && span(),
        playing: viewer.playing,
        pixelError: viewer.pixelError,
        lod: viewer.lod || "hdlod",
        colourMode: viewer.colourMode,
        mode: camera && camera.mode,
        distance: camera && camera.distance,
        eye: camera && camera.eye(),
        clusters: viewer.clusters.size,
        // Drawn clusters that are leaves (original objects, level 0).
        leafClusters: [...viewer.clusters.values()].filter((c) => c.info.level === 0).length,
        triangles: drawnTriangles(),
        ids: [...viewer.clusters.keys()].sort((a, b) => a - b),
        serverStats: viewer.stats,
        baseline: viewer.stats ? viewer.stats.baseline_triangles : null,
        baselineObjects: viewer.stats ? viewer.stats.baseline_objects : null,
        glbBytes: cache ? cache.bytes : 0,
        // The GLB bytes of the distinct geometry drawn, and of its textures.
        ...cutBytes(),
        gpuFreed: cache ? cache.freed : 0,
        glbFiles: cache ? cache.files : 0,
        loading: cache ? cache.loading : 0,
        missing: viewer.missing.size,
        loadsPeak: cache ? cache.peak : 0,
        loadRetries: cache ? cache.retries : 0,
        // Geometry requests made: a batch of GLBs counts once.
        glbRequests: cache ? cache.requests : 0,
        latencyMs: viewer.latency,
        frameMs: viewer.frameMs,
        // Draw calls of the last frame (a page of batched clusters is one).
        drawCalls: renderer ? renderer.drawCalls : 0,
        // Frames drawn, and of them those drawn before the view's own cut
        // could be (a time jump waits for it up to holdMs).
        frames: viewer.frames,
        staleFrames: viewer.staleFrames,
        readyMs: viewer.readyMs,
        holdMs: HOLD_MS,
        batching: renderer ? renderer.batching : true,
        seq: viewer.seq,
        answers: viewer.answers,
        settled: this.settled(),
        dynamicScreenPositions,
        target: camera && camera.target.slice(),
        selection: viewer.selection && { ...viewer.selection },
        panel: viewer.panel && viewer.panel.shown && {
          index: viewer.panel.shown.index, id: viewer.panel.shown.id, time: viewer.panel.shownTime, present: viewer.panel.shown.present,
        },
        search: { q: viewer.search.q, mode: viewer.search.mode, matches: viewer.search.matches.length, pending: viewer.search.pending, task: viewer.search.task },
        objects: viewer.features.count,
        objectsError: viewer.objectsError,
        stateUploads: renderer ? renderer.stateUploads : 0,
        picks: viewer.picks,
        review: {
          tasks: viewer.schedule ? viewer.schedule.tasks.length : 0,
          dates: viewer.schedule && viewer.schedule.dates,
          pending: viewer.review.pending,
          error: viewer.review.error,
          profile: viewer.colours.profile.name,
          profileSource: viewer.profileSource,
          coloured: viewer.colours.ready(),
          translucent: viewer.colours.translucent,
          lookUploads: renderer ? renderer.lookUploads : 0,
          legend: [...ui.legend.querySelectorAll(".swatch")].map((e) => e.dataset.colour),
          legendText: ui.legend.textContent,
        },
        gantt: viewer.gantt && { open: !ui.gantt.hidden, ...viewer.gantt.state() },
      };
    },
    // True when the drawn cut answers the current view, nothing loads and
    // the colour mode has what it needs.
    settled() {
      if (!viewer.ready || connection.busy() || cache.loading > 0 || viewer.missing.size > 0 || !viewer.lastRequest) return false;
      if (viewer.review.pending) return false;
      const c = viewer.review.categories[viewer.colourMode];
      if (c && c.pending) return false;
      const [width, height] = viewportSize();
      return JSON.stringify(viewer.lastRequest) === JSON.stringify(cutRequest(width, height));
    },
    // The panel shows the selection at the current time, and no search is pending.
    panelSettled: () => !!viewer.panel && viewer.panel.settled() && !viewer.search.pending,
    lastRequest: () => viewer.lastRequest,
    pickAt: (x, y) => pickAt(x, y),
    matches: () => viewer.search.matches.slice(),
    select: (index) => select(index === null ? null : { index, id: null }),
    search: (q, mode) => search(q, mode),
    // Off draws every feature of the drawn clusters (no presence, no flags):
    // what the cut alone shows, for the tests' pixel comparisons.
    setFeatureState: (on) => viewer.features.setEnabled(on),
    // Test only: off draws every cluster with a call of its own, as before
    // batching, for the tests' pixel comparisons.
    setBatching: (on) => {
      renderer.batching = !!on;
      viewer.needsDraw = true;
    },
    // Test only: the feature id of every device pixel of the canvas (-1 none),
    // as counts by id; a click reads one pixel of the same pass.
    featureCoverage: () => {
      const [width, height] = viewportSize();
      uploadFeatureState();
      const ids = renderer.pickRect(drawItems(), viewer.matrices, width, height, 0, 0, width, height);
      const counts = {};
      for (const id of ids) if (id >= 0) counts[id] = (counts[id] || 0) + 1;
      return counts;
    },
    setTime: (t) => setTime(t),
    setPixelError: (p) => setPixelError(p),
    setLod: (lod) => {
      viewer.lod = lod === "none" ? "none" : null;
      urlDirty = true;
    },
    // The time of each of k frames of the drawn cut, in milliseconds, each
    // drawn and then read back (one pixel), which waits for the GPU to
    // finish it: what a frame costs, not only the calls that queue it.
    timeFrames: (k) => {
      const [width, height] = viewportSize();
      const gl = renderer.gl;
      const px = new Uint8Array(4);
      const ms = [];
      for (let i = 0; i < k; i++) {
        const start = performance.now();
        draw(width, height);
        gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
        ms.push(performance.now() - start);
      }
      return ms;
    },
    // Test only: the canvas averaged over frames drawn with the projection
    // moved by each of `offsets` ([dx, dy], device pixels), as a PNG in
    // base64, rows from the top like a screenshot. More samples a pixel
    // than multisampling gives, for the image benchmark's pictures of
    // sub-pixel detail (at most 257 frames: the sums are 16-bit).
    accumulate: async (offsets) => {
      const [width, height] = viewportSize();
      const gl = renderer.gl;
      const m = viewer.matrices;
      const frame = new Uint8Array(4 * width * height);
      const sum = new Uint16Array(4 * width * height);
      for (const [dx, dy] of offsets) {
        const shift = new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, (2 * dx) / width, (2 * dy) / height, 0, 1]);
        draw(width, height, { ...m, viewProj: multiply(shift, m.viewProj) });
        gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, frame);
        for (let i = 0; i < frame.length; i++) sum[i] += frame[i];
      }
      viewer.needsDraw = true;
      const image = new ImageData(width, height);
      const n = offsets.length;
      for (let y = 0; y < height; y++) {
        // readPixels' rows run from the bottom.
        const from = 4 * (height - 1 - y) * width;
        const to = 4 * y * width;
        for (let i = 0; i < 4 * width; i++) image.data[to + i] = (i & 3) === 3 ? 255 : Math.round(sum[from + i] / n);
      }
      const canvas = new OffscreenCanvas(width, height);
      canvas.getContext("2d").putImageData(image, 0, 0);
      const png = new Uint8Array(await (await canvas.convertToBlob({ type: "image/png" })).arrayBuffer());
      let text = "";
      for (let i = 0; i < png.length; i += 0x8000) text += String.fromCharCode(...png.subarray(i, i + 0x8000));
      return btoa(text);
    },
    setColourMode: (m) => setColourMode(m),
    // The tasks of feature i, by index into the schedule.
    tasksOf: (i) => viewer.colours.tasksOf(i),
    // The look bytes of feature i as last uploaded ([r, g, b, a]; a: 0 own colour, 1 hidden).
    lookOf: (i) => (viewer.colours.out && viewer.colours.ready() ? Array.from(viewer.colours.out.subarray(4 * i, 4 * i + 4)) : null),
    // Device-pixel centres (as CSS pixels) of up to `n` pixels inside each
    // of `ids` (the pick pass's pixel and its four neighbours show it).
    featurePixels: (ids, n) => {
      const [width, height] = viewportSize();
      uploadFeatureState();
      const px = renderer.pickRect(drawItems(), viewer.matrices, width, height, 0, 0, width, height);
      const want = new Map(ids.map((id) => [id, []]));
      const dpr = width / ui.canvas.clientWidth;
      const step = Math.max(1, Math.round(3 * dpr));
      for (let y = step; y < height - step; y += step) {
        for (let x = step; x < width - step; x += step) {
          // pickRect's rows run from the bottom.
          const at = (xx, yy) => px[(height - 1 - yy) * width + xx];
          const id = at(x, y);
          const list = want.get(id);
          if (!list || list.length >= n) continue;
          if ([[step, 0], [-step, 0], [0, step], [0, -step]].every(([a, b]) => at(x + a, y + b) === id)) {
            list.push([(x + 0.5) / dpr, (y + 0.5) / dpr]);
          }
        }
      }
      return Object.fromEntries(want);
    },
    showGantt: (on) => showGantt(on),
    // Task k's planned bar in page CSS pixels {x, y, w, h}, scrolled into view.
    ganttBar: (k) => {
      viewer.gantt.reveal(k);
      viewer.gantt.frame();
      const b = viewer.gantt.barOf(k);
      const r = ui.ganttCanvas.getBoundingClientRect();
      return b && { x: b.x + r.left, y: b.y + r.top, w: b.w, h: b.h };
    },
    isolateTask: (k) => isolateTask(k),
    loadProfile: (text, name) => loadProfileText(text, name),
    // The distance as a multiple of the one where the whole scene fills the view.
    setDistanceFactor: (f) => camera.zoom((camera.home * f) / camera.distance),
    setCamera: ({ target, distance, azimuth, elevation }) => {
      if (target) camera.target = target.slice();
      if (distance) camera.distance = distance;
      if (azimuth !== undefined) camera.azimuth = azimuth;
      if (elevation !== undefined) camera.elevation = elevation;
    },
    play: (daysPerSecond) => {
      if (daysPerSecond) {
        const option = [...ui.speed.options].find((o) => Number(o.value) === daysPerSecond);
        if (!option) ui.speed.add(new Option(`${daysPerSecond} days/s`, String(daysPerSecond)));
        ui.speed.value = String(daysPerSecond);
      }
      setPlaying(true);
    },
    pause: () => setPlaying(false),
  };
}

function coordinates(text) {
  const v = (text || "").split(",").map(Number);
  return v.length === 3 && v.every(Number.isFinite) ? v : null;
}

// Every object's presence, once per scene, then the link's selection and
// search. A tree without an object table still draws: nothing is pickable
// by name then, and nothing is hidden by time beyond the cut.
async function loadObjects(params) {
  try {
    viewer.features.setPresence((await getJson(`${viewer.sceneUrl}/presence`)).presence);
    viewer.features.setTime(viewer.t);
    viewer.colours.setCount(viewer.features.count);
  } catch (e) {
    viewer.objectsError = e.message;
    ui.search.hidden = true;
    viewer.review = { pending: false, error: `no schedule: ${e.message}`, categories: {} };
    renderLegend();
    return;
  }
  await loadReview(params);
  const id = params.get("selected");
  if (id) {
    try {
      const o = await getJson(`${viewer.sceneUrl}/objects/${encodeURIComponent(id)}`);
      select({ index: o.index, id: o.id });
    } catch (e) {
      showMessage(`The link's selection: ${e.message}`);
    }
  }
  const q = params.get("q");
  if (q) search(q, params.get("mode") || "highlight");
  const task = params.get("task");
  if (task && viewer.schedule) {
    const k = viewer.schedule.tasks.findIndex((t) => t.id === task);
    if (k >= 0) isolateTask(k);
    else showMessage(`The link's task: no task ${task} in this scene.`);
  }
}

// The schedule and the scene's appearance profile, once per scene (the
// browser revalidates them by ETag), or the profile the link names.
async function loadReview(params) {
  const review = viewer.review;
  try {
    const [schedule, profile] = await Promise.all([
      getJson(`${viewer.sceneUrl}/schedule`),
      getJson(`${viewer.sceneUrl}/appearance`),
    ]);
    viewer.schedule = schedule;
    viewer.colours.setSchedule(schedule);
    viewer.colours.setProfile(parseProfile(profile, `${viewer.sceneUrl}/appearance: `));
    viewer.gantt.setSchedule(schedule);
    viewer.gantt.setTime(viewer.t);
    if (viewer.selection) viewer.gantt.highlight(viewer.colours.tasksOf(viewer.selection.index));
  } catch (e) {
    review.error = `The schedule: ${e.message}`;
  }
  const url = params.get("appearance");
  if (url) await loadProfileUrl(url);
  review.pending = false;
  renderLegend();
  // A link's class or storey mode waited for the object count.
  if (viewer.colourMode === "ifc_class" || viewer.colourMode === "storey") loadCategories(viewer.colourMode);
}

// A profile from a URL (the link's `appearance`, a data: URL for one
// loaded from a file).
async function loadProfileUrl(url) {
  let text;
  try {
    const response = await fetch(url);
    if (!response.ok) throw new Error(`HTTP ${response.status}`);
    text = await response.text();
  } catch (e) {
    showMessage(`Cannot load the appearance profile ${url.startsWith("data:") ? "of the link" : url}: ${e.message}`);
    return;
  }
  await loadProfileText(text, url.startsWith("data:") ? "the link's profile" : url, url);
}

// A profile file's text: checked, then drawn; the link keeps it as a
// data: URL (or the URL it came from), so it reproduces the colours.
async function loadProfileText(text, name, url = null) {
  let profile;
  try {
    profile = parseProfile(JSON.parse(text), `${name}: `);
  } catch (e) {
    showMessage(`The appearance profile ${e instanceof SyntaxError ? `${name}: ${e.message}` : e.message}`);
    return false;
  }
  viewer.colours.setProfile(profile);
  viewer.profileSource = url || `data:application/json,${encodeURIComponent(JSON.stringify(JSON.parse(text)))}`;
  if (viewer.error && viewer.error.startsWith("The appearance profile")) showMessage(null);
  renderLegend();
  urlDirty = true;
  viewer.needsDraw = true;
  return true;
}

// The Gantt chart docked at the bottom; the 3D view shrinks above it.
function showGantt(on) {
  ui.gantt.hidden = !on;
  document.body.classList.toggle("gantt-open", on);
  ui.ganttToggle.classList.toggle("on", on);
  urlDirty = true;
  if (on && viewer.gantt.highlighted.size) viewer.gantt.highlight([...viewer.gantt.highlighted]);
  else if (on) viewer.gantt.dirty = true;
}

async function start() {
  const params = new URLSearchParams(location.search);
  window.hdlodViewer = testHook();
  try {
    renderer = new Renderer(ui.canvas);
  } catch (e) {
    showMessage(`Cannot draw here: ${e.message}`);
    return;
  }
  let list;
  try {
    list = (await getJson("/api/v1/scenes")).scenes;
  } catch (e) {
    showMessage(e.message);
    return;
  }
  if (!list.length) {
    showMessage("The server has no scene. Start it with a tree: hdlod serve TREE");
    return;
  }
  const wanted = params.get("scene");
  const chosen = wanted === null ? list[0] : list.find((s) => s.name === wanted);
  for (const s of list) ui.scene.add(new Option(s.name, s.name, false, s === chosen));
  ui.scene.hidden = list.length < 2 && !!chosen;
  if (!chosen) {
    ui.scene.add(new Option("choose a scene", "", true, true));
    ui.scene.hidden = false;
    showMessage(`No scene named "${wanted}" on this server. Available: ${list.map((s) => s.name).join(", ")}.`);
    return;
  }
  try {
    viewer.scene = await getJson(chosen.url);
    viewer.sceneUrl = chosen.url;
  } catch (e) {
    showMessage(e.status === 404 ? `The scene "${chosen.name}" is gone from the server.` : e.message);
    return;
  }
  document.title = `${viewer.scene.name} - hdlod viewer`;
  camera = new Camera(viewer.scene.up);
  camera.frame(viewer.scene.bounds);
  // `encoding=plain` asks for the plain GLBs (docs/api.md, "Geometry"):
  // the tests compare the pictures of both forms.
  cache = new GeometryCache(renderer, params.get("encoding") === "plain" ? "plain" : null);
  const t = parseTime(params.get("time"));
  setTime(t === null ? 0 : t);
  const p = Number(params.get("pixel_error"));
  setPixelError(p > 0 ? p : 1);
  viewer.lod = params.get("lod") === "none" ? "none" : null;
  setColourMode(params.get("colour") || "vertex");
  setMode("orbit");
  const position = coordinates(params.get("position"));
  const target = coordinates(params.get("target"));
  if (position && target) camera.lookFrom(position, target);
  viewer.gantt = new Gantt(ui.ganttCanvas, (k) => isolateTask(k));
  viewer.gantt.setTime(viewer.t);
  showGantt(params.get("gantt") === "1");
  viewer.panel = new ObjectPanel(ui.panel, viewer.sceneUrl, getJson, formatDate, (o) => {
    if (viewer.selection && viewer.selection.index === o.index && viewer.selection.id !== o.id) {
      viewer.selection.id = o.id;
      urlDirty = true;
    }
  });
  await loadObjects(params);
  bindInput();
  const wsUrl = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}${viewer.scene.stream}`;
  connection = new CutConnection(wsUrl, {
    message: onMessage,
    status: (text) => {
      if (text) showMessage(text);
      else if (viewer.error && viewer.error.startsWith("Lost the connection")) showMessage(null);
    },
  });
  connection.open();
  viewer.ready = true;
  requestAnimationFrame(frame);
}

start();

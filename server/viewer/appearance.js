// Task status and appearance profiles in the page, the same rules as the
// library's hdlod/src/scene/status.rs (where a task stands at a time, and
// its execution against its plan) and hdlod/src/scene/appearance.rs (the
// hdlod-appearance/1 profiles, after Navisworks TimeLiner's appearance
// definitions). The browser tests hold these functions to the server's
// task answers (GET .../tasks/{id}?time=T), so the two cannot drift.
//
// Pure functions and plain data: no DOM, no requests. A task is as the
// schedule answer gives it (GET .../schedule): {type, start, finish,
// actual_start?, actual_finish?}, times in seconds since the scene's start.

export const TASK_TYPES = ["construct", "demolish", "temporary", "maintain"];

// Where a task stands, as the API names it (`state`).
export const NOT_STARTED = 0;
export const IN_PROGRESS = 1;
export const FINISHED = 2;
export const PROGRESS_NAMES = ["not_started", "in_progress", "finished"];

// A task's execution against its plan (`deviation`); null without actual dates.
export const EARLY = 0;
export const ON_TIME = 1;
export const LATE = 2;
export const DEVIATION_NAMES = ["early", "on_time", "late"];

export const PHASES = ["before", "active", "after", "early", "late"];

// The IFC task types (IfcTaskTypeEnum) that name one of ours, as in
// hdlod/src/scene/schedule.rs: name -> index into TASK_TYPES.
export const IFC_TASK_TYPES = {
  CONSTRUCTION: 0, INSTALLATION: 0,
  DEMOLITION: 1, DISMANTLE: 1, DISPOSAL: 1, REMOVAL: 1,
  MAINTENANCE: 3, OPERATION: 3, ATTENDANCE: 3, LOGISTIC: 3, MOVE: 3,
};

// NamedType::parse: our names or the IFC ones, any case, as {kind, ifc}
// (ifc the upper-case IFC name, or null); null for neither.
export function namedType(name) {
  const upper = String(name).toUpperCase();
  const ours = TASK_TYPES.indexOf(upper.toLowerCase());
  if (ours >= 0) return { kind: ours, ifc: null };
  const kind = IFC_TASK_TYPES[upper];
  return kind === undefined ? null : { kind, ifc: upper };
}

function has(x) {
  return x !== undefined && x !== null;
}

// [start, finish) the task runs over on `dates` ("planned" or "actual"):
// on actual dates the finish is infinite while a recorded task still runs,
// and both are for a task the record has not started (it never acts).
export function running(task, dates) {
  if (dates !== "actual") return [task.start, task.finish];
  if (!has(task.actual_start)) return [Infinity, Infinity];
  return [task.actual_start, has(task.actual_finish) ? task.actual_finish : Infinity];
}

// Not started before the start, in progress until the finish, finished
// from it on (a task of no duration is finished from its start).
export function progress(task, t, dates) {
  const [start, finish] = running(task, dates);
  if (t < start) return NOT_STARTED;
  if (t < finish) return IN_PROGRESS;
  return FINISHED;
}

// Against the plan at t, for a task with a recorded start (null otherwise):
// late while it should have started or finished and has not, early while
// it has before the plan says, lateness winning; on time otherwise.
export function deviation(task, t) {
  if (!has(task.actual_start)) return null;
  const started = task.actual_start;
  const finished = has(task.actual_finish) ? task.actual_finish : Infinity;
  const late = (t >= task.start && t < started) || (t >= task.finish && t < finished);
  if (late) return LATE;
  const early = (t >= started && t < task.start) || (t >= finished && t < task.finish);
  return early ? EARLY : ON_TIME;
}

// Looks: {kind: "model"} (the element's own colour), {kind: "hidden"}, or
// {kind: "colour", hex: "#rrggbb", rgb: [r, g, b] bytes, transparency 0..1}.
export const MODEL = Object.freeze({ kind: "model" });
export const HIDDEN = Object.freeze({ kind: "hidden" });

export function colourLook(hex, transparency = 0) {
  const n = parseInt(hex.slice(1), 16);
  return Object.freeze({ kind: "colour", hex: hex.toLowerCase(), rgb: [(n >> 16) & 255, (n >> 8) & 255, n & 255], transparency });
}

function typeLooks(active, after) {
  return { before: MODEL, active, after, early: null, late: null };
}

// Profile::default: work under construction green and half transparent,
// then its own colour; demolition red, then gone; temporary works yellow,
// then gone; maintenance as modelled.
export const DEFAULT_PROFILE = Object.freeze({
  name: "default",
  types: [
    typeLooks(colourLook("#2fb344", 0.5), MODEL),
    typeLooks(colourLook("#d93025"), HIDDEN),
    typeLooks(colourLook("#f2c21b"), HIDDEN),
    typeLooks(MODEL, MODEL),
  ],
  ifc: {},
});

function isObject(v) {
  return v !== null && typeof v === "object" && !Array.isArray(v);
}

function parseLook(value, field, at) {
  if (value === "model") return MODEL;
  if (value === "hidden") return HIDDEN;
  if (typeof value === "string") {
    throw new Error(`${at}${field}: ${JSON.stringify(value)} is not a look; use "model", "hidden" or {"color": "#rrggbb", "transparency": 0..1}`);
  }
  if (!isObject(value)) throw new Error(`${at}${field}: a look is "model", "hidden" or {"color": "#rrggbb", "transparency": 0..1}`);
  for (const key of Object.keys(value)) {
    if (key !== "color" && key !== "transparency") throw new Error(`${at}${field}.${key}: unknown field`);
  }
  const { color, transparency = 0 } = value;
  if (typeof color !== "string" || !/^#[0-9a-fA-F]{6}$/.test(color)) {
    throw new Error(`${at}${field}: color ${JSON.stringify(color)} is not of the form "#rrggbb"`);
  }
  if (typeof transparency !== "number" || !(transparency >= 0 && transparency <= 1)) {
    throw new Error(`${at}${field}: transparency ${JSON.stringify(transparency)} is not within 0..1`);
  }
  return colourLook(color, transparency);
}

// Profile::from_file: a parsed hdlod-appearance/1 file checked, errors
// naming the field (prefixed by `at`, e.g. the file's name and a colon).
// One of our types left out, or given as {}, keeps the defaults; a phase
// left out of one of our types is "model", of an IFC type its type's;
// early and late left out keep the phase's look. `ifc` holds the IFC
// types named apart (INSTALLATION beside CONSTRUCTION).
export function parseProfile(file, at = "") {
  if (!isObject(file)) throw new Error(`${at}an appearance profile is a JSON object`);
  for (const key of Object.keys(file)) {
    if (!["format", "name", "types"].includes(key)) throw new Error(`${at}${key}: unknown field`);
  }
  if (file.format !== "hdlod-appearance/1") {
    throw new Error(`${at}format: ${JSON.stringify(file.format)} is not supported (expected "hdlod-appearance/1")`);
  }
  if (has(file.name) && typeof file.name !== "string") throw new Error(`${at}name: not a string`);
  const entries = has(file.types) ? file.types : {};
  if (!isObject(entries)) throw new Error(`${at}types: not an object`);
  const keys = [];
  const given = new Map();
  for (const [key, entry] of Object.entries(entries)) {
    const named = namedType(key);
    if (!named) throw new Error(`${at}types.${key}: ${JSON.stringify(key)} is not a task type; use ${TASK_TYPES.join(", ")} (or an IFC task type name)`);
    const canonical = named.ifc || TASK_TYPES[named.kind];
    if (given.has(canonical)) throw new Error(`${at}types.${key}: names the same task type as types.${given.get(canonical)}`);
    given.set(canonical, key);
    if (!isObject(entry)) throw new Error(`${at}types.${key}: not an object`);
    for (const phase of Object.keys(entry)) {
      if (!PHASES.includes(phase)) throw new Error(`${at}types.${key}.${phase}: unknown field`);
    }
    keys.push({ key, entry, named });
  }
  // Our types first: an IFC type's phases left out are its type's.
  keys.sort((a, b) => (a.named.ifc ? 1 : 0) - (b.named.ifc ? 1 : 0));
  const types = DEFAULT_PROFILE.types.map((t) => ({ ...t }));
  const ifc = {};
  for (const { key, entry, named } of keys) {
    const phase = (p, fallback) => (has(entry[p]) ? parseLook(entry[p], `types.${key}.${p}`, at) : fallback);
    const own = types[named.kind];
    if (named.ifc) {
      ifc[named.ifc] = Object.fromEntries(PHASES.map((p) => [p, phase(p, own[p])]));
    } else if (PHASES.some((p) => has(entry[p]))) {
      types[named.kind] = {
        before: phase("before", MODEL),
        active: phase("active", MODEL),
        after: phase("after", MODEL),
        early: phase("early", null),
        late: phase("late", null),
      };
    }
  }
  return { name: has(file.name) ? file.name : "unnamed", types, ifc };
}

// Profile::look: the look of an element under a task of type `kind` (an
// index into TASK_TYPES; `ifc` the IFC type its schedule named, or null)
// at `prog`, `dev` the task's deviation (null without actual dates). Early
// and late looks, when given, override the phase's while the task deviates.
export function look(profile, kind, prog, dev, ifc = null) {
  const looks = (ifc && profile.ifc && profile.ifc[ifc]) || profile.types[kind];
  const special = dev === EARLY ? looks.early : dev === LATE ? looks.late : null;
  if (special) return special;
  return prog === NOT_STARTED ? looks.before : prog === IN_PROGRESS ? looks.active : looks.after;
}

// Every task's standing at t, worked out once per time for all the
// features it acts on: its progress on the tree's `dates`, its deviation
// (-1 without actual dates), whether it is in progress on its planned or
// its actual dates, and its claim on its features (below).
export function standings(tasks, t, dates) {
  const n = tasks.length;
  const s = {
    progress: new Uint8Array(n), deviation: new Int8Array(n), working: new Uint8Array(n),
    rank: new Uint8Array(n), key: new Float64Array(n),
  };
  for (let k = 0; k < n; k++) {
    const task = tasks[k];
    const [start, finish] = running(task, dates);
    const p = t < start ? NOT_STARTED : t < finish ? IN_PROGRESS : FINISHED;
    s.progress[k] = p;
    const d = deviation(task, t);
    s.deviation[k] = d === null ? -1 : d;
    s.working[k] = progress(task, t, "planned") === IN_PROGRESS || progress(task, t, "actual") === IN_PROGRESS ? 1 : 0;
    // In progress beats finished beats not started; then the latest
    // start, the latest finish, the earliest start.
    s.rank[k] = p === IN_PROGRESS ? 2 : p === FINISHED ? 1 : 0;
    s.key[k] = p === IN_PROGRESS ? start : p === FINISHED ? finish : -start;
  }
  return s;
}

// The task that governs a feature's look at t, among its tasks
// list[from .. to] (indices, increasing): the one in progress that started
// last; else the finished one that finished last; else the not started one
// that starts first; ties go to the higher index. -1 for a feature with no
// task (it keeps its own colour). `s`: standings() at t.
export function governing(list, from, to, s) {
  let best = -1;
  for (let j = from; j < to; j++) {
    const k = list[j];
    if (best < 0 || s.rank[k] > s.rank[best] || (s.rank[k] === s.rank[best] && s.key[k] >= s.key[best])) best = k;
  }
  return best;
}

// Planned against actual for a feature over its tasks list[from .. to]
// with actual dates: late if any is late at t, else early if any is
// early, else on time if any is in progress on its planned or its actual
// dates; null otherwise (the feature keeps its own colour).
export function featureDeviation(list, from, to, s) {
  let early = false;
  let onTime = false;
  for (let j = from; j < to; j++) {
    const k = list[j];
    const d = s.deviation[k];
    if (d === LATE) return LATE;
    if (d === EARLY) early = true;
    else if (d === ON_TIME && s.working[k]) onTime = true;
  }
  return early ? EARLY : onTime ? ON_TIME : null;
}

// The colours of the planned against actual mode, and the legend's words.
export const DEVIATION_COLOURS = [
  { deviation: EARLY, look: colourLook("#2fb344"), label: "early" },
  { deviation: ON_TIME, look: colourLook("#3b82f6"), label: "on time (in progress)" },
  { deviation: LATE, look: colourLook("#d93025"), label: "late" },
];

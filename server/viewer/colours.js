// The colour modes that colour each scene object (feature) on its own, as
// the RGBA bytes of the renderer's second per-feature texture, feature id
// -> texel (the state texture's layout, featurestate.js):
//
// - `appearance`: the look of the task that governs the feature at the
//   current time under the appearance profile (appearance.js);
// - `deviation`: planned against actual, late red, early green, on time blue;
// - `ifc_class` and `storey`: one colour per distinct class or storey.
//
// Byte `a` says what to draw: 0 the feature's own colour (vertex colours,
// or the cluster's tint), 1 hidden, 2..255 `rgb` with opacity (a - 2) / 253.
// The schedule comes once per scene (GET .../schedule); a new time only
// re-evaluates the tasks here, with no request, and the bytes are rebuilt
// (and uploaded) only when the time, the mode or the profile changed.

import {
  DEFAULT_PROFILE, DEVIATION_COLOURS, TASK_TYPES, featureDeviation, governing, look, standings,
} from "./appearance.js";

const OWN = 0;
const HIDE = 1;

// The texture's bytes of a look: [r, g, b, a].
function lookBytes(l) {
  if (l.kind === "model") return [0, 0, 0, OWN];
  if (l.kind === "hidden" || l.transparency >= 1) return [0, 0, 0, HIDE];
  return [...l.rgb, 2 + Math.round((1 - l.transparency) * 253)];
}

// Categorical colours for classes (Tableau 10, then hues a golden angle apart).
const PALETTE = ["#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1", "#ff9da7", "#9c755f", "#bab0ac"];

function hslHex(h, s, l) {
  const f = (n) => {
    const k = (n + h / 30) % 12;
    const c = l - s * Math.min(l, 1 - l) * Math.max(-1, Math.min(k - 3, 9 - k, 1));
    return Math.round(c * 255).toString(16).padStart(2, "0");
  };
  return `#${f(0)}${f(8)}${f(4)}`;
}

function categoryColour(i) {
  return i < PALETTE.length ? PALETTE[i] : hslHex((i * 137.508) % 360, 0.55, 0.55);
}

// Storeys bottom to top along a ramp from blue through green to red.
function rampColour(i, n) {
  const x = n > 1 ? i / (n - 1) : 0;
  return hslHex(240 * (1 - x), 0.6, 0.5);
}

// Names in natural order ("Level 2" before "Level 10").
export const naturalOrder = new Intl.Collator("en", { numeric: true, sensitivity: "base" }).compare;

export const MODES = ["appearance", "deviation", "ifc_class", "storey"];

export class FeatureColours {
  constructor() {
    this.count = 0; // features (the presence table's length)
    this.schedule = null; // the GET .../schedule answer
    this.tasks = [];
    this.dates = "planned";
    this.offsets = null; // feature i's tasks are taskOf[offsets[i] .. offsets[i + 1]]
    this.taskOf = null;
    this.profile = DEFAULT_PROFILE;
    this.mode = null; // one of MODES, or null: every feature its own colour
    this.categories = { ifc_class: null, storey: null }; // {values: [names], of: Int32Array per feature}
    this.t = null;
    this.out = null;
    this.translucent = 0; // features drawn with some transparency at the last build
    this.dirty = true;
  }

  setCount(n) {
    this.count = n;
    this.dirty = true;
  }

  // The schedule answer: every task with its objects' feature indices.
  setSchedule(schedule) {
    this.schedule = schedule;
    this.tasks = schedule.tasks;
    this.dates = schedule.dates;
    let n = this.count;
    for (const task of schedule.tasks) for (const i of task.objects) n = Math.max(n, i + 1);
    this.count = n;
    const counts = new Uint32Array(n + 1);
    for (const task of schedule.tasks) for (const i of task.objects) counts[i + 1]++;
    for (let i = 0; i < n; i++) counts[i + 1] += counts[i];
    this.offsets = counts.slice();
    this.taskOf = new Uint32Array(counts[n]);
    const fill = counts.slice(0, n);
    schedule.tasks.forEach((task, k) => {
      for (const i of task.objects) this.taskOf[fill[i]++] = k;
    });
    this.dirty = true;
  }

  // The tasks acting on feature i, by index, increasing.
  tasksOf(i) {
    if (!this.offsets || i >= this.count) return [];
    return Array.from(this.taskOf.subarray(this.offsets[i], this.offsets[i + 1]));
  }

  setProfile(profile) {
    this.profile = profile;
    this.dirty = true;
  }

  setMode(mode) {
    if (mode !== this.mode) {
      this.mode = MODES.includes(mode) ? mode : null;
      this.dirty = true;
    }
  }

  // values: the distinct names, in legend order; of[i]: feature i's index
  // into them, -1 for none.
  setCategories(which, values, of) {
    this.categories[which] = { values, of };
    if (this.mode === which) this.dirty = true;
  }

  setTime(t) {
    if (t !== this.t) {
      this.t = t;
      if (this.mode === "appearance" || this.mode === "deviation") this.dirty = true;
    }
  }

  // Ready to draw: the mode's data has come.
  ready() {
    if (this.mode === "appearance" || this.mode === "deviation") return !!this.offsets;
    if (this.mode) return !!this.categories[this.mode];
    return false;
  }

  // The texture's bytes (rows of rowBytes), or null when no mode colours
  // features (or its data has not come yet): every feature its own colour.
  bytes(rowBytes) {
    if (!this.ready() || !this.count) return null;
    const rows = Math.max(1, Math.ceil((4 * this.count) / rowBytes));
    if (!this.out || this.out.length !== rows * rowBytes) this.out = new Uint8Array(rows * rowBytes);
    const out = this.out;
    out.fill(0);
    this.translucent = 0;
    if (this.mode === "appearance") this.fillAppearance(out);
    else if (this.mode === "deviation") this.fillDeviation(out);
    else this.fillCategories(out, this.categories[this.mode]);
    for (let i = 0; i < this.count; i++) {
      const a = out[4 * i + 3];
      if (a > HIDE && a < 255) this.translucent++;
    }
    return out;
  }

  // Each task's standing and look at t, worked out once; then each
  // feature takes its governing task's look.
  fillAppearance(out) {
    const s = standings(this.tasks, this.t, this.dates);
    const looks = this.tasks.map((task, k) =>
      lookBytes(look(this.profile, TASK_TYPES.indexOf(task.type), s.progress[k], s.deviation[k] < 0 ? null : s.deviation[k], task.ifc_type)));
    for (let i = 0; i < this.count; i++) {
      const k = governing(this.taskOf, this.offsets[i], this.offsets[i + 1], s);
      if (k >= 0) out.set(looks[k], 4 * i);
    }
  }

  fillDeviation(out) {
    const s = standings(this.tasks, this.t, this.dates);
    const colours = [];
    for (const c of DEVIATION_COLOURS) colours[c.deviation] = lookBytes(c.look);
    for (let i = 0; i < this.count; i++) {
      const d = featureDeviation(this.taskOf, this.offsets[i], this.offsets[i + 1], s);
      if (d !== null) out.set(colours[d], 4 * i);
    }
  }

  fillCategories(out, { values, of }) {
    const colours = values.map((_, c) => {
      const hex = this.mode === "storey" ? rampColour(c, values.length) : categoryColour(c);
      const n = parseInt(hex.slice(1), 16);
      return [(n >> 16) & 255, (n >> 8) & 255, n & 255, 255];
    });
    const n = Math.min(this.count, of.length);
    for (let i = 0; i < n; i++) if (of[i] >= 0) out.set(colours[of[i]], 4 * i);
  }

  // The legend of the mode: [{label, colour ("#rrggbb" or null), note}].
  legend() {
    if (this.mode === "deviation") {
      return [...DEVIATION_COLOURS].reverse().map((c) => ({ label: c.label, colour: c.look.hex }))
        .concat([{ label: "no recorded task at work", colour: null, note: "own colour" }]);
    }
    if (this.mode === "ifc_class" || this.mode === "storey") {
      const c = this.categories[this.mode];
      if (!c) return [];
      const colour = (i) => (this.mode === "storey" ? rampColour(i, c.values.length) : categoryColour(i));
      return c.values.map((v, i) => ({ label: v, colour: colour(i) }))
        .concat([{ label: this.mode === "storey" ? "no storey" : "no class", colour: null, note: "own colour" }]);
    }
    return [];
  }
}

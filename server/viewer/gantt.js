// The Gantt chart of the schedule, drawn on a 2D canvas: one row per task
// in WBS order (summary tasks above their tasks, indented), the planned
// bar, the actual bar below it (thinner; a task still running reaches the
// current time), the baseline as a thin outline, the current time as a
// vertical line. Rows in progress at the current time are tinted, the
// tasks of the picked object marked, the isolated task outlined.
//
// Only the rows in view are drawn, so a frame costs the same with ten
// tasks or ten thousand. The wheel zooms the time axis about the pointer
// (over the names, or with shift, it scrolls the rows); a drag pans both;
// a click on a row selects its task.

import { IN_PROGRESS, TASK_TYPES, progress } from "./appearance.js";

const ROW = 20; // CSS pixels
const HEADER = 24;
const NAMES = 230;
const CLICK_SLOP = 4;
const HOUR = 3600;
const DAY = 86400;

const TYPE_COLOURS = ["#7aa6d8", "#e39087", "#e5c65c", "#a9b1bc"];
const ACTUAL = "#c2410c";
const BASELINE = "#4b5563";
const NOW = "#d93025";

export class Gantt {
  // canvas: the chart's <canvas>; select(taskIndex): a row was clicked.
  constructor(canvas, select) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.select = select;
    this.tasks = [];
    this.dates = "planned";
    this.startMs = 0; // the scene's start date
    this.span = 1;
    this.order = new Int32Array(0); // task index of each row
    this.depth = new Uint16Array(0); // WBS depth of each row
    this.rowOf = new Int32Array(0); // row of each task
    this.summary = new Uint8Array(0); // task has tasks under it
    this.t = 0;
    this.t0 = 0; // time at the chart's left edge
    this.scale = 1; // CSS pixels per second
    this.scrollY = 0;
    this.highlighted = new Set();
    this.selected = null;
    this.hovered = -1;
    this.needsFit = true; // the whole period across the chart, once it has a width
    this.width = 0; // CSS pixels
    this.height = 0;
    this.dirty = true;
    this.draws = 0;
    this.frameMs = 0;
    this.bind();
  }

  // The schedule answer (GET .../schedule): rows in WBS order, the whole
  // period in view.
  setSchedule(schedule) {
    const tasks = schedule.tasks;
    const n = tasks.length;
    this.tasks = tasks;
    this.dates = schedule.dates;
    this.startMs = Date.parse(schedule.start);
    this.span = Math.max(schedule.seconds, 1);
    const children = Array.from({ length: n }, () => []);
    const roots = [];
    tasks.forEach((task, k) => {
      const p = task.parent;
      if (p !== undefined && p !== null && p >= 0 && p < n && p !== k) children[p].push(k);
      else roots.push(k);
    });
    this.summary = new Uint8Array(n);
    children.forEach((c, k) => (this.summary[k] = c.length ? 1 : 0));
    this.order = new Int32Array(n);
    this.depth = new Uint16Array(n);
    this.rowOf = new Int32Array(n).fill(-1);
    let row = 0;
    // Depth first without recursion (deep WBS trees); a task in a parent
    // cycle is reached from no root and gets a row of its own at the end.
    const walk = (root) => {
      const stack = [[root, 0]];
      while (stack.length) {
        const [k, d] = stack.pop();
        if (this.rowOf[k] >= 0) continue;
        this.rowOf[k] = row;
        this.order[row] = k;
        this.depth[row] = d;
        row++;
        for (let c = children[k].length - 1; c >= 0; c--) stack.push([children[k][c], d + 1]);
      }
    };
    for (const r of roots) walk(r);
    for (let k = 0; k < n; k++) if (this.rowOf[k] < 0) walk(k);
    this.scrollY = 0;
    this.needsFit = true;
    this.dirty = true;
  }

  setTime(t) {
    if (t !== this.t) {
      this.t = t;
      this.dirty = true;
    }
  }

  setSelected(k) {
    if (k !== this.selected) {
      this.selected = k;
      this.dirty = true;
    }
  }

  // The tasks of the picked object, marked and the first brought into view.
  highlight(indices) {
    this.highlighted = new Set(indices);
    this.dirty = true;
    if (indices.length && this.canvas.clientHeight > 0) this.reveal(indices.reduce((a, k) => (this.rowOf[k] < this.rowOf[a] ? k : a), indices[0]));
  }

  // Scrolls task k's row, and its planned bar, into view when they are not.
  reveal(k) {
    this.layout();
    const row = this.rowOf[k];
    if (row < 0) return;
    const view = this.height - HEADER;
    if (row * ROW < this.scrollY || (row + 1) * ROW > this.scrollY + view) {
      this.scrollY = Math.max(0, row * ROW - view / 2 + ROW / 2);
      this.clampScroll();
    }
    const task = this.tasks[k];
    const chart = this.width - NAMES;
    const [a, b] = [this.x(task.start), this.x(task.finish)];
    if (b < NAMES || a > NAMES + chart) this.t0 = task.start - (chart * 0.1) / this.scale;
    this.dirty = true;
  }

  x(t) {
    return NAMES + (t - this.t0) * this.scale;
  }

  clampScroll() {
    const max = Math.max(0, this.order.length * ROW - (this.height - HEADER));
    this.scrollY = Math.min(Math.max(this.scrollY, 0), max);
  }

  // Matches the backing store to the canvas's CSS size; true if it changed.
  layout() {
    const dpr = window.devicePixelRatio || 1;
    const w = this.canvas.clientWidth;
    const h = this.canvas.clientHeight;
    if (w !== this.width || h !== this.height || this.canvas.width !== Math.max(1, Math.round(w * dpr))) {
      this.width = w;
      this.height = h;
      this.canvas.width = Math.max(1, Math.round(w * dpr));
      this.canvas.height = Math.max(1, Math.round(h * dpr));
      this.clampScroll();
      this.dirty = true;
    }
    if (this.needsFit && w > NAMES) {
      this.needsFit = false;
      this.scale = ((w - NAMES) * 0.96) / this.span;
      this.t0 = -this.span * 0.02;
      this.dirty = true;
    }
  }

  // The first and one past the last row in view.
  visibleRows() {
    const first = Math.max(0, Math.floor(this.scrollY / ROW));
    const last = Math.min(this.order.length, Math.ceil((this.scrollY + this.height - HEADER) / ROW));
    return [first, last];
  }

  // The task under CSS pixel (x, y) of the canvas, or -1.
  taskAt(x, y) {
    if (y < HEADER || x < 0 || x > this.width) return -1;
    const row = Math.floor((y - HEADER + this.scrollY) / ROW);
    return row >= 0 && row < this.order.length ? this.order[row] : -1;
  }

  // Task k's planned bar in CSS pixels of the canvas, {x, y, w, h}, or
  // null when its row is out of view.
  barOf(k) {
    const row = this.rowOf[k];
    const y = HEADER + row * ROW - this.scrollY;
    if (row < 0 || y < HEADER || y + ROW > this.height) return null;
    const task = this.tasks[k];
    const a = Math.max(this.x(task.start), NAMES);
    const b = Math.min(this.x(task.finish), this.width);
    return { x: a, y: y + 3, w: Math.max(b - a, 0), h: 9 };
  }

  // Draws if something changed since the last frame.
  frame() {
    this.layout();
    if (!this.dirty || !this.width || !this.height) return;
    this.draw();
  }

  draw() {
    const start = performance.now();
    this.dirty = false;
    const g = this.ctx;
    const dpr = this.canvas.width / Math.max(this.width, 1);
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.fillStyle = "#ffffff";
    g.fillRect(0, 0, this.width, this.height);
    g.font = "12px system-ui, sans-serif";
    g.textBaseline = "middle";
    const [first, last] = this.visibleRows();
    const right = this.width;
    for (let row = first; row < last; row++) this.drawRow(g, row, right);
    this.drawHeader(g, right);
    // The current time across the rows.
    const xt = this.x(this.t);
    if (xt >= NAMES && xt <= right) {
      g.fillStyle = NOW;
      g.fillRect(Math.round(xt) - 1, HEADER - 6, 2, this.height - HEADER + 6);
    }
    g.fillStyle = "#c9d2dd";
    g.fillRect(NAMES - 1, 0, 1, this.height);
    this.draws++;
    const ms = performance.now() - start;
    this.frameMs = this.frameMs ? this.frameMs * 0.8 + ms * 0.2 : ms;
  }

  drawRow(g, row, right) {
    const k = this.order[row];
    const task = this.tasks[k];
    const y = HEADER + row * ROW - this.scrollY;
    const active = progress(task, this.t, this.dates) === IN_PROGRESS;
    let background = row % 2 ? "#f6f8fb" : "#ffffff";
    if (active) background = "#fff3d1";
    if (this.highlighted.has(k)) background = "#ffd9b8";
    if (this.selected === k) background = "#d6eaff";
    g.fillStyle = background;
    g.fillRect(0, y, right, ROW);
    if (this.highlighted.has(k)) {
      g.fillStyle = "#ff7300";
      g.fillRect(0, y, 4, ROW);
    }
    // The name, indented by its WBS depth.
    g.save();
    g.beginPath();
    g.rect(0, y, NAMES - 4, ROW);
    g.clip();
    g.fillStyle = "#1d2733";
    g.font = this.summary[k] ? "600 12px system-ui, sans-serif" : "12px system-ui, sans-serif";
    g.fillText(task.name || task.id, 8 + 12 * this.depth[row], y + ROW / 2);
    g.restore();
    g.save();
    g.beginPath();
    g.rect(NAMES, y, right - NAMES, ROW);
    g.clip();
    const xs = this.x(task.start);
    const xf = Math.max(this.x(task.finish), xs + 1);
    if (task.baseline_start !== undefined && task.baseline_finish !== undefined) {
      const b0 = this.x(task.baseline_start);
      const b1 = Math.max(this.x(task.baseline_finish), b0 + 1);
      g.strokeStyle = BASELINE;
      g.lineWidth = 1;
      g.strokeRect(Math.round(b0) + 0.5, y + 1.5, Math.round(b1 - b0), 12);
    }
    if (this.summary[k]) {
      // A summary task: a bracket over its tasks' span.
      g.fillStyle = "#374151";
      g.fillRect(xs, y + 4, xf - xs, 5);
      g.fillRect(xs, y + 4, 3, 9);
      g.fillRect(xf - 3, y + 4, 3, 9);
    } else {
      g.fillStyle = TYPE_COLOURS[Math.max(0, TASK_TYPES.indexOf(task.type))];
      g.fillRect(xs, y + 3, xf - xs, 9);
      if (active) {
        g.strokeStyle = "#1d2733";
        g.lineWidth = 1.5;
        g.strokeRect(xs, y + 3, xf - xs, 9);
      }
    }
    if (task.actual_start !== undefined) {
      // Still running: up to the current time, if it has started by then.
      const end = task.actual_finish !== undefined ? task.actual_finish : Math.max(this.t, task.actual_start);
      const a0 = this.x(task.actual_start);
      g.fillStyle = ACTUAL;
      g.fillRect(a0, y + 14, Math.max(this.x(end) - a0, 1), 4);
    }
    if (this.selected === k) {
      g.strokeStyle = "#1f6feb";
      g.lineWidth = 2;
      g.strokeRect(1, y + 1, right - 2, ROW - 2);
    }
    g.restore();
  }

  // Date ticks: the coarsest step at least 70 pixels apart.
  drawHeader(g, right) {
    g.fillStyle = "#eef2f7";
    g.fillRect(0, 0, right, HEADER);
    g.fillStyle = "#c9d2dd";
    g.fillRect(0, HEADER - 1, right, 1);
    g.fillStyle = "#44505e";
    g.fillText(`${this.order.length.toLocaleString("en-US")} tasks`, 8, HEADER / 2);
    const steps = [HOUR, 6 * HOUR, DAY, 7 * DAY, 30 * DAY, 91 * DAY, 365 * DAY];
    const step = steps.find((s) => s * this.scale >= 70) || steps[steps.length - 1];
    const months = step >= 30 * DAY ? Math.round(step / (30 * DAY)) : 0;
    const tLeft = this.t0;
    const tRight = this.t0 + (right - NAMES) / this.scale;
    const ticks = [];
    if (months) {
      const d = new Date(this.startMs + tLeft * 1000);
      let m = new Date(Date.UTC(d.getUTCFullYear(), d.getUTCMonth() - (d.getUTCMonth() % months), 1));
      for (;;) {
        const t = (m.getTime() - this.startMs) / 1000;
        if (t > tRight) break;
        ticks.push([t, m.toISOString().slice(0, 7)]);
        m = new Date(Date.UTC(m.getUTCFullYear(), m.getUTCMonth() + months, 1));
      }
    } else {
      // Whole days (or hours) since the epoch, so ticks fall on midnights.
      const epoch = this.startMs / 1000;
      for (let a = Math.ceil((epoch + tLeft) / step) * step; a - epoch <= tRight; a += step) {
        const iso = new Date(a * 1000).toISOString();
        ticks.push([a - epoch, step < DAY ? iso.slice(5, 16).replace("T", " ") : iso.slice(0, 10)]);
      }
    }
    g.save();
    g.beginPath();
    g.rect(NAMES, 0, right - NAMES, this.height);
    g.clip();
    for (const [t, label] of ticks) {
      const x = Math.round(this.x(t)) + 0.5;
      g.fillStyle = "#c9d2dd";
      g.fillRect(x, HEADER - 6, 1, 6);
      g.fillStyle = "#44505e";
      g.fillText(label, x + 3, HEADER / 2 - 1);
    }
    g.restore();
  }

  // Rows scrolled by dy CSS pixels.
  scrollRows(dy) {
    this.scrollY += dy;
    this.clampScroll();
    this.dirty = true;
  }

  // The time axis moved by dx CSS pixels.
  pan(dx) {
    this.t0 += dx / this.scale;
    this.dirty = true;
  }

  // The time axis zoomed by f about CSS pixel x of the canvas: from the
  // whole period in a fiftieth of the chart to an hour in 200 pixels.
  zoomAt(x, f) {
    const at = this.t0 + (x - NAMES) / this.scale;
    this.scale = Math.min(Math.max(this.scale * f, (0.02 * this.width) / this.span), 200 / HOUR);
    this.t0 = at - (x - NAMES) / this.scale;
    this.dirty = true;
  }

  bind() {
    const c = this.canvas;
    let drag = null;
    c.addEventListener("wheel", (e) => {
      e.preventDefault();
      const r = c.getBoundingClientRect();
      const x = e.clientX - r.left;
      if (e.shiftKey || x < NAMES) {
        this.scrollRows(e.deltaY || e.deltaX);
      } else {
        this.zoomAt(x, Math.exp(-e.deltaY * 0.0015));
        this.pan(e.deltaX);
      }
    }, { passive: false });
    c.addEventListener("pointerdown", (e) => {
      c.setPointerCapture(e.pointerId);
      drag = { x: e.clientX, y: e.clientY, x0: e.clientX, y0: e.clientY };
    });
    c.addEventListener("pointermove", (e) => {
      const r = c.getBoundingClientRect();
      if (!drag) {
        this.hover(e.clientX - r.left, e.clientY - r.top);
        return;
      }
      this.pan(drag.x - e.clientX);
      this.scrollRows(drag.y - e.clientY);
      drag.x = e.clientX;
      drag.y = e.clientY;
    });
    c.addEventListener("pointerup", (e) => {
      const click = drag && Math.hypot(e.clientX - drag.x0, e.clientY - drag.y0) < CLICK_SLOP;
      drag = null;
      if (!click) return;
      const r = c.getBoundingClientRect();
      const k = this.taskAt(e.clientX - r.left, e.clientY - r.top);
      if (k >= 0) this.select(k);
    });
  }

  // The task under the pointer as the canvas's tooltip.
  hover(x, y) {
    const k = this.taskAt(x, y);
    if (k === this.hovered) return;
    this.hovered = k;
    if (k < 0) {
      this.canvas.title = "";
      return;
    }
    const task = this.tasks[k];
    const day = (t) => new Date(this.startMs + t * 1000).toISOString().slice(0, 16).replace("T", " ");
    const lines = [`${task.id} ${task.name || ""} (${task.type})`, `planned ${day(task.start)} to ${day(task.finish)}`];
    if (task.actual_start !== undefined) {
      lines.push(`actual ${day(task.actual_start)} to ${task.actual_finish !== undefined ? day(task.actual_finish) : "(running)"}`);
    }
    if (task.baseline_start !== undefined) lines.push(`baseline ${day(task.baseline_start)} to ${day(task.baseline_finish)}`);
    lines.push(`${task.objects.length} objects; click to isolate them`);
    this.canvas.title = lines.join("\n");
  }

  // For the test hook: what the chart shows.
  state() {
    const [first, last] = this.visibleRows();
    const id = (k) => this.tasks[k].id;
    return {
      rows: this.order.length,
      first,
      last,
      visible: Array.from(this.order.subarray(first, last), id),
      highlighted: [...this.highlighted].map(id),
      selected: this.selected === null ? null : id(this.selected),
      scrollY: this.scrollY,
      scale: this.scale,
      t0: this.t0,
      draws: this.draws,
      frameMs: this.frameMs,
    };
  }
}

// What each scene object (feature) looks like at the current time, as the
// RGBA bytes of the renderer's state texture, feature id -> texel:
// r present (and not hidden), g ghosted (isolation), b selected, a matched.
//
// Presence comes once per scene from GET .../presence (every object's
// intervals); from then on a new time only re-evaluates the intervals here,
// with no request: the cut draws a cluster while its visibility is at least
// a half, and this hides the objects in it that are absent at that time.
// The bytes are rebuilt, and uploaded, only when the time or a flag changed.

export class FeatureState {
  constructor() {
    this.count = 0;
    this.starts = null; // interval starts, all objects one after another
    this.ends = null;
    this.offsets = null; // object i's intervals are offsets[i] .. offsets[i + 1]
    this.t = null;
    this.selected = null;
    this.matches = [];
    this.mode = "highlight"; // what the matches do: highlight, isolate or hide
    this.enabled = true;
    this.dirty = true;
  }

  // presence[i]: object i's [start|null, end|null] intervals, sorted.
  setPresence(presence) {
    const n = presence.reduce((s, p) => s + p.length, 0);
    this.count = presence.length;
    this.starts = new Float64Array(n);
    this.ends = new Float64Array(n);
    this.offsets = new Uint32Array(presence.length + 1);
    let k = 0;
    presence.forEach((intervals, i) => {
      for (const [a, b] of intervals) {
        this.starts[k] = a === null ? -Infinity : a;
        this.ends[k] = b === null ? Infinity : b;
        k++;
      }
      this.offsets[i + 1] = k;
    });
    this.dirty = true;
  }

  present(i, t) {
    for (let k = this.offsets[i]; k < this.offsets[i + 1]; k++) {
      if (t < this.starts[k]) return false;
      if (t < this.ends[k]) return true;
    }
    return false;
  }

  setTime(t) {
    if (t !== this.t) {
      this.t = t;
      this.dirty = true;
    }
  }

  select(index) {
    if (index !== this.selected) {
      this.selected = index;
      this.dirty = true;
    }
  }

  setMatches(indices, mode) {
    this.matches = indices;
    this.mode = mode;
    this.dirty = true;
  }

  setEnabled(on) {
    this.enabled = on;
    this.dirty = true;
  }

  isolating() {
    return this.enabled && this.count > 0 && this.mode === "isolate" && this.matches.length > 0;
  }

  // The texture's bytes (rows of rowBytes), or null to draw every feature
  // plainly (no presence known, or the state turned off by the test hook).
  bytes(rowBytes) {
    if (!this.enabled || !this.count) return null;
    const rows = Math.max(1, Math.ceil((4 * this.count) / rowBytes));
    const out = new Uint8Array(rows * rowBytes);
    const isolating = this.isolating();
    for (let i = 0; i < this.count; i++) {
      out[4 * i] = this.present(i, this.t) ? 255 : 0;
      if (isolating) out[4 * i + 1] = 255;
    }
    for (const i of this.matches) {
      if (i >= this.count) continue;
      if (this.mode === "hide") out[4 * i] = 0;
      else if (isolating) out[4 * i + 1] = 0;
      else out[4 * i + 3] = 255;
    }
    if (this.selected !== null && this.selected < this.count) out[4 * this.selected + 2] = 255;
    return out;
  }
}

// Orbit / pan / zoom around a target, and a fly mode (WASD, drag to look).
// Both keep the same state: a target, a distance and the direction from the
// target to the eye as azimuth and elevation in the scene's ground plane, so
// switching modes never jumps. The up axis is the scene's (`y` or `z`).

import { lookAt, perspective, multiply, cross, normalize } from "./mat4.js";

export const FOV_Y_DEG = 60;

export class Camera {
  constructor(up) {
    this.setUp(up);
    this.target = [0, 0, 0];
    this.distance = 100;
    this.azimuth = Math.PI / 4;
    this.elevation = Math.PI / 6;
    this.mode = "orbit";
    this.sceneRadius = 100;
    this.sceneCentre = [0, 0, 0];
  }

  setUp(up) {
    this.upName = up === "z" ? "z" : "y";
    // Horizontal axes e1, e2 and the up axis u (as in the paper's bench camera).
    if (this.upName === "z") {
      [this.e1, this.e2, this.u] = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
    } else {
      [this.e1, this.e2, this.u] = [[1, 0, 0], [0, 0, 1], [0, 1, 0]];
    }
  }

  // Unit vector from the target to the eye.
  direction() {
    const ce = Math.cos(this.elevation);
    const a = ce * Math.cos(this.azimuth);
    const b = ce * Math.sin(this.azimuth);
    const c = Math.sin(this.elevation);
    return [0, 1, 2].map((i) => a * this.e1[i] + b * this.e2[i] + c * this.u[i]);
  }

  eye() {
    const d = this.direction();
    return this.target.map((x, i) => x + d[i] * this.distance);
  }

  // The whole scene in view, as the paper's bench frames it (az 45, el 30).
  frame(bounds) {
    const c = bounds.min.map((x, i) => (x + bounds.max[i]) / 2);
    const r = Math.max(1e-3, Math.hypot(...bounds.max.map((x, i) => x - bounds.min[i])) / 2);
    this.target = c;
    this.sceneCentre = c.slice();
    this.sceneRadius = r;
    this.sceneBox = [bounds.min.slice(), bounds.max.slice()];
    this.azimuth = Math.PI / 4;
    this.elevation = Math.PI / 6;
    this.distance = r / Math.sin((FOV_Y_DEG * Math.PI) / 360);
    this.home = this.distance;
  }

  // The eye at `position` looking at `target` (a shared link's view).
  lookFrom(position, target) {
    const v = position.map((x, i) => x - target[i]);
    const d = Math.hypot(...v);
    if (!(d > 0)) return;
    const dot = (a) => (v[0] * a[0] + v[1] * a[1] + v[2] * a[2]) / d;
    this.target = target.slice();
    this.distance = d;
    this.elevation = Math.asin(Math.max(-1, Math.min(1, dot(this.u))));
    this.azimuth = Math.atan2(dot(this.e2), dot(this.e1));
    this.clampElevation();
  }

  nearFar() {
    // The far plane holds the whole scene from wherever the eye is. The
    // near plane is as far out as nothing of the scene is nearer: from
    // outside the scene's box, most of the way to it; inside, a fixed share
    // of the far plane. Depth precision falls with the square of the
    // distance over the near plane's, and surfaces a few centimetres apart
    // (a site pad on the ground) fight at a distance when it is small.
    const e = this.eye();
    const toCentre = Math.hypot(...e.map((x, i) => x - this.sceneCentre[i]));
    const far = toCentre + 2 * this.sceneRadius;
    let toBox = 0;
    if (this.sceneBox) {
      const [lo, hi] = this.sceneBox;
      toBox = Math.hypot(...e.map((x, i) => Math.max(lo[i] - x, 0, x - hi[i])));
    }
    return [Math.max(far * 1e-4, 0.05, 0.9 * toBox), far];
  }

  matrices(aspect) {
    const eye = this.eye();
    const [near, far] = this.nearFar();
    const view = lookAt(eye, this.target, this.u);
    const proj = perspective((FOV_Y_DEG * Math.PI) / 180, aspect, near, far);
    return { eye, near, far, view, proj, viewProj: multiply(proj, view) };
  }

  clampElevation() {
    const lim = Math.PI / 2 - 1e-3;
    this.elevation = Math.max(-lim, Math.min(lim, this.elevation));
  }

  // Drag: orbit turns the eye around the target; fly turns the view around
  // the eye (the target moves).
  rotate(dx, dy) {
    if (this.mode === "fly") {
      const eye = this.eye();
      this.azimuth -= dx * 0.004;
      this.elevation -= dy * 0.004;
      this.clampElevation();
      const d = this.direction();
      this.target = eye.map((x, i) => x - d[i] * this.distance);
    } else {
      this.azimuth -= dx * 0.006;
      this.elevation += dy * 0.006;
      this.clampElevation();
    }
  }

  // Screen-space pan: the target slides in the view plane, scaled so the
  // point under the cursor roughly follows it.
  pan(dx, dy, viewportHeight) {
    const d = this.direction();
    const right = normalize(cross(this.u, d));
    const up = cross(d, right);
    const k = (2 * this.distance * Math.tan((FOV_Y_DEG * Math.PI) / 360)) / viewportHeight;
    this.target = this.target.map((x, i) => x - right[i] * dx * k + up[i] * dy * k);
  }

  zoom(factor) {
    this.distance = Math.max(0.5, Math.min(this.distance * factor, this.sceneRadius * 50));
  }

  // Fly: forward/back along the view, strafe sideways, rise and sink along up.
  move(forward, right, rise, step) {
    const d = this.direction();
    const r = normalize(cross(this.u, d));
    for (let i = 0; i < 3; i++) {
      this.target[i] += (-d[i] * forward + r[i] * right + this.u[i] * rise) * step;
    }
  }
}

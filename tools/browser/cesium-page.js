// The page of tools/browser/cesium.mjs: a CesiumJS viewer, offline (no
// Cesium ion, no imagery, no terrain, no globe), that follows its clock
// through the scene's slices with the recipe of docs/tiles.md
// (docs/examples/cesium-clock.js) and reports what it draws.
import * as Cesium from "cesium";
import { followClock } from "/examples/cesium-clock.js";

let viewer;
let slices;
let start;
// The clusters of the tiles drawn in the last frame (tileVisible).
let drawn = new Set();

const frame = () => new Promise((r) => setTimeout(r, 0));
const cartesian = (p) => new Cesium.Cartesian3(...p);

async function init(cfg) {
  viewer = new Cesium.Viewer("viewer", {
    baseLayer: false,
    baseLayerPicker: false,
    geocoder: false,
    homeButton: false,
    sceneModePicker: false,
    navigationHelpButton: false,
    fullscreenButton: false,
    infoBox: false,
    selectionIndicator: false,
    animation: false,
    timeline: true,
    globe: false,
    skyBox: false,
    skyAtmosphere: false,
    // Frames are drawn by the test, one at a time.
    useDefaultRenderLoop: false,
    useBrowserRecommendedResolution: false,
  });
  viewer.clock.shouldAnimate = false;
  const c = cfg.camera;
  viewer.camera.setView({
    destination: cartesian(c.position),
    orientation: { direction: cartesian(c.direction), up: cartesian(c.up) },
  });
  slices = await followClock(viewer, cfg.api, cfg.scene, {
    step: cfg.step,
    tileset: {
      maximumScreenSpaceError: cfg.maximumScreenSpaceError,
      dynamicScreenSpaceError: false,
      foveatedScreenSpaceError: false,
    },
  });
  slices.swapped.addEventListener((tileset) => {
    tileset.tileVisible.addEventListener((tile) => drawn.add(tile.extras.cluster));
  });
  start = viewer.clock.startTime;
  const gl = viewer.scene.context._gl;
  const debug = gl.getExtension("WEBGL_debug_renderer_info");
  return {
    webgl2: viewer.scene.context.webgl2,
    renderer: debug ? gl.getParameter(debug.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER),
    clock: {
      start: Cesium.JulianDate.toIso8601(viewer.clock.startTime),
      stop: Cesium.JulianDate.toIso8601(viewer.clock.stopTime),
      clamped: viewer.clock.clockRange === Cesium.ClockRange.CLAMPED,
    },
  };
}

// Sets the clock to `seconds` into the period (a multiple of the step) and
// draws frames until the recipe shows that slice, every tile of the view is loaded and the
// drawn set has held for a few frames.
async function showTime(seconds, timeoutMs) {
  viewer.clock.currentTime = Cesium.JulianDate.addSeconds(start, seconds, new Cesium.JulianDate());
  const began = performance.now();
  let last = "";
  let stable = 0;
  let frames = 0;
  while (performance.now() - began < timeoutMs && stable < 5) {
    drawn = new Set();
    viewer.render();
    frames += 1;
    const key = [...drawn].sort((a, b) => a - b).join(",");
    const done = slices.seconds === seconds && slices.shown.tilesLoaded && key === last;
    stable = done ? stable + 1 : 0;
    last = key;
    await frame();
  }
  const tileset = slices.shown;
  const camera = viewer.camera;
  // Clip from the scene's own frame: the frustum's projection, the view
  // (ECEF to eye), the root's transform (tileset frame to ECEF) and the
  // turn CesiumJS gives y-up glTF content (scene to tileset frame).
  const m = new Cesium.Matrix4();
  Cesium.Matrix4.multiply(camera.frustum.projectionMatrix, camera.viewMatrix, m);
  Cesium.Matrix4.multiply(m, tileset.root.computedTransform, m);
  Cesium.Matrix4.multiply(m, Cesium.Axis.Y_UP_TO_Z_UP, m);
  const ctx = viewer.scene.context;
  return {
    settled: stable >= 5,
    ms: performance.now() - began,
    frames,
    seconds: slices.seconds,
    clusters: [...drawn].sort((a, b) => a - b),
    viewProjection: Cesium.Matrix4.toArray(m),
    drawingBuffer: { width: ctx.drawingBufferWidth, height: ctx.drawingBufferHeight },
    pixelRatio: viewer.scene.pixelRatio,
    maximumScreenSpaceError: tileset.maximumScreenSpaceError,
    modelMatrix: Cesium.Matrix4.toArray(tileset.modelMatrix),
    rootTransform: Cesium.Matrix4.toArray(tileset.root.computedTransform),
    boundingSphere: {
      center: Cesium.Cartesian3.pack(tileset.boundingSphere.center, []),
      radius: tileset.boundingSphere.radius,
    },
    primitives: viewer.scene.primitives.length,
  };
}

// The first feature built by a task (whose task columns have something to
// check) at pixels spiralling out from the canvas's centre, and its
// properties; else the first feature found.
function pick() {
  let first = null;
  const canvas = viewer.scene.canvas;
  const cx = Math.floor(canvas.clientWidth / 2);
  const cy = Math.floor(canvas.clientHeight / 2);
  for (let ring = 0; ring < 12; ring++) {
    const r = ring * 15;
    const steps = Math.max(1, ring * 8);
    for (let i = 0; i < steps; i++) {
      const a = (2 * Math.PI * i) / steps;
      const x = cx + Math.round(r * Math.cos(a));
      const y = cy + Math.round(r * Math.sin(a));
      const picked = viewer.scene.pick(new Cesium.Cartesian2(x, y));
      if (picked instanceof Cesium.Cesium3DTileFeature) {
        const properties = {};
        for (const name of picked.getPropertyIds()) properties[name] = picked.getProperty(name);
        const found = { x, y, cluster: picked.content.tile.extras.cluster, properties };
        if (properties.task) return found;
        first ??= found;
      }
    }
  }
  return first;
}

window.cesiumTest = { init, showTime, pick };
window.cesiumTestReady = true;

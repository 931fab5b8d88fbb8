// WebGL2 drawing: a headlight Lambert over vertex colours times the
// cluster's baked colour texture when it has one (or a colour per class or
// level). The texture's texels are sRGB, as glTF's base colour: an
// SRGB8_ALPHA8 texture gives them back linear, as the vertex colours are.
// Dynamic clusters get their cut transform as the model matrix; a skinned
// cluster's vertices are placed by its joint matrices at the cut's time
// instead (linear blend skinning, glTF 2.0 section 3.7.3), at most
// MAX_JOINTS of them: uniforms, which every WebGL2 device has room for
// (256 vertex vectors at the least). The clusters that need nothing of
// their own (no transform, joints, tint or texture) share vertex buffers
// and are drawn a page at a time, one call each (pages.js); the others
// have a vertex array each and are drawn one by one. Picking is
// one more pass of the same clusters into an offscreen framebuffer with
// feature ids as colours, scissored to the pixel under the cursor, read
// back as that one pixel.

// Each vertex carries its scene object (the feature id, -1 for none). The
// per-feature state texture (featurestate.js: present, ghosted, selected,
// matched) is read by feature id: a feature that is absent or hidden has
// its vertices moved outside the clip volume, so its triangles (whose three
// corners share the id) are dropped before rasterisation. A second
// per-feature texture, the looks (colours.js), gives a colour mode's
// colour and opacity per feature, or hides it: opaque looks are drawn in
// the first pass, translucent ones blended in the second with the ghosts.

import { DEFAULT_COLOUR, Pages, PAGE_VERTEX_BYTES } from "./pages.js";

// The most joints a skinned cluster is drawn posed with; one with more is
// drawn in its bind pose.
const MAX_JOINTS = 32;
// The most samples a pixel whose alpha to coverage is calibrated; a
// canvas with more draws baked covers with the device's own mapping.
const MAX_SAMPLES = 8;

const VERTEX = `#version 300 es
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 aColor;
layout(location = 3) in float aFeature;
layout(location = 4) in vec2 aUv;
layout(location = 5) in vec4 aJoints;
layout(location = 6) in vec4 aWeights;
uniform mat4 uViewProj;
uniform mat4 uModel;
uniform bool uSkinned;
uniform mat4 uJoints[${MAX_JOINTS}];
uniform sampler2D uState;
uniform bool uHasState;
uniform int uStateWidth;
uniform int uStateCount;
uniform bool uIsolating;
uniform sampler2D uLooks;
uniform int uLookCount;
// 0: opaque, 1: ghosts and translucent looks, 2: feature ids (picking)
uniform int uPass;
out vec3 vWorld;
out vec3 vNormal;
out vec4 vColor;
out vec2 vUv;
flat out float vFeature;
flat out vec4 vState;
flat out vec4 vLook;
void main() {
  // r present, g ghosted, b selected, a matched
  vec4 state = vec4(1.0, 0.0, 0.0, 0.0);
  bool hasFeature = aFeature >= 0.0;
  int id = int(aFeature + 0.5);
  ivec2 texel = ivec2(id % uStateWidth, id / uStateWidth);
  if (hasFeature && uHasState && id < uStateCount) {
    state = texelFetch(uState, texel, 0);
  } else if (uIsolating) {
    state.g = 1.0;
  }
  // a: 0 own colour, 1 hidden, 2..255 rgb at opacity (a - 2) / 253
  vec4 look = vec4(0.0);
  if (hasFeature && id < uLookCount) look = texelFetch(uLooks, texel, 0);
  int lookA = int(look.a * 255.0 + 0.5);
  bool ghost = state.g > 0.5;
  bool translucent = !ghost && lookA > 1 && lookA < 255;
  bool keep = state.r > 0.5 && lookA != 1 && (uPass == 2 ? !ghost && hasFeature : (uPass == 1) == (ghost || translucent));
  if (!keep) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    return;
  }
  mat4 model = uModel;
  if (uSkinned) {
    model = aWeights.x * uJoints[int(aJoints.x)] + aWeights.y * uJoints[int(aJoints.y)]
      + aWeights.z * uJoints[int(aJoints.z)] + aWeights.w * uJoints[int(aJoints.w)];
  }
  vec4 world = model * vec4(aPosition, 1.0);
  vWorld = world.xyz;
  vNormal = mat3(model) * aNormal;
  vColor = aColor;
  vUv = aUv;
  vFeature = aFeature;
  vState = state;
  vLook = vec4(look.rgb, lookA > 1 ? float(lookA - 2) / 253.0 : -1.0);
  gl_Position = uViewProj * world;
}`;

const FRAGMENT = `#version 300 es
precision highp float;
precision highp int;
in vec3 vWorld;
in vec3 vNormal;
in vec4 vColor;
in vec2 vUv;
flat in float vFeature;
flat in vec4 vState;
flat in vec4 vLook;
uniform vec3 uEye;
uniform sampler2D uColour;
uniform bool uHasTexture;
uniform vec4 uTint;
uniform bool uHasNormals;
uniform int uPass;
// Alpha to coverage as measured on this device (calibrateCover): an alpha
// that writes exactly k of the uCoverSamples samples is uCoverLevels[k];
// no samples (0) when it was not a step function of alpha.
uniform int uCoverSamples;
uniform float uCoverLevels[${MAX_SAMPLES + 1}];
out vec4 outColor;
void main() {
  if (uPass == 2) {
    // The feature id plus one in 24 bits of colour; 0 is nothing.
    uint v = uint(vFeature + 0.5) + 1u;
    outColor = vec4(float(v & 255u), float((v >> 8) & 255u), float((v >> 16) & 255u), 255.0) / 255.0;
    return;
  }
  // Polygon soup may lack or flip normals: the face normal from screen
  // derivatives stands in (a zero normal in a shared page is a mesh
  // without normals), and both sides are lit. The derivatives are taken
  // outside the choice: they are undefined in non-uniform control flow.
  vec3 face = normalize(cross(dFdx(vWorld), dFdy(vWorld)));
  vec3 n = uHasNormals && dot(vNormal, vNormal) > 0.0 ? normalize(vNormal) : face;
  vec3 l = normalize(uEye - vWorld);
  float lambert = abs(dot(n, l));
  // A look (task colour) or a tint stands for the whole feature, texture
  // and all, as it does for vertex colours.
  vec4 texel = uHasTexture ? texture(uColour, vUv) : vec4(1.0);
  vec3 own = vColor.rgb * texel.rgb;
  vec3 base = vLook.a >= 0.0 ? vLook.rgb : uTint.a > 0.0 ? uTint.rgb : own;
  if (vState.a > 0.5) base = mix(base, vec3(0.1, 0.75, 0.95), 0.6);
  if (vState.b > 0.5) base = mix(base, vec3(1.0, 0.45, 0.0), 0.75);
  vec3 lit = base * (0.3 + 0.7 * lambert);
  if (uPass == 1 && vState.g > 0.5) {
    float grey = dot(lit, vec3(0.3, 0.59, 0.11));
    outColor = vec4(vec3(grey), 0.12);
  } else if (uPass == 1) {
    outColor = vec4(lit, vLook.a);
  } else {
    // A baked texel's alpha is how much of it the part covers (a crane's
    // lattice drawn as a box): it becomes the share of the pixel's samples
    // written (alpha to coverage). A pixel can only take whole samples, so
    // the share a * n is rounded down or up to k samples by a threshold
    // that moves from pixel to pixel (interleaved gradient noise: Jimenez,
    // "Next Generation Post Processing in Call of Duty: Advanced Warfare",
    // SIGGRAPH 2014), which keeps the mean over pixels; then written with
    // the alpha that this device turns into k samples. How a device maps
    // alpha to samples is its own (SwiftShader writes floor(5 a) of 4, so
    // a cover under a fifth vanished); where it is not a step function
    // the alpha goes as it is, moved by up to an eighth.
    float a = texel.a;
    if (a < 1.0) {
      float noise = fract(52.9829189 * fract(dot(gl_FragCoord.xy, vec2(0.06711056, 0.00583715))));
      if (uCoverSamples > 0) {
        int k = min(int(floor(a * float(uCoverSamples) + noise)), uCoverSamples);
        if (k == 0) discard;
        a = uCoverLevels[k];
      } else {
        a = clamp(a + (noise - 0.5) * 0.25, 0.0, 1.0);
      }
    }
    outColor = vec4(lit, a);
  }
}`;

export const BACKGROUND = [0.86, 0.89, 0.93];

const CLASS_COLOURS = {
  static: [0.55, 0.6, 0.68],
  pseudo_dynamic: [0.95, 0.62, 0.2],
  dynamic: [0.2, 0.7, 0.35],
};

// Level 0 (the original objects) blue, rising through green to red.
export function levelColour(level) {
  const ramp = [
    [0.2, 0.4, 0.9], [0.2, 0.75, 0.85], [0.3, 0.8, 0.35], [0.85, 0.85, 0.2],
    [0.95, 0.55, 0.15], [0.9, 0.2, 0.2], [0.7, 0.2, 0.7],
  ];
  return ramp[Math.min(level, ramp.length - 1)];
}

export function classColour(cls) {
  return CLASS_COLOURS[cls] || [0.7, 0.7, 0.7];
}

function compile(gl, type, source) {
  const s = gl.createShader(type);
  gl.shaderSource(s, source);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}

// How this device's alpha to coverage turns alpha into samples of the
// canvas's pixels, measured once: a triangle over a few pixels drawn at
// each of 64 alphas and read back. {samples, levels}: for k samples the
// middle of the alphas that write exactly k (levels[k]), or samples 0
// when some share of samples is written by no alpha (a device that
// dithers of its own) or the canvas has no samples to share.
function calibrateCover(gl) {
  const none = { samples: 0, levels: new Float32Array(MAX_SAMPLES + 1) };
  const samples = gl.getParameter(gl.SAMPLES);
  if (samples < 2 || samples > MAX_SAMPLES) return none;
  const program = gl.createProgram();
  const vs = "#version 300 es\nlayout(location = 0) in vec2 p;\nvoid main() { gl_Position = vec4(p, 0.0, 1.0); }";
  const fs = "#version 300 es\nprecision highp float;\nuniform float a;\nout vec4 o;\nvoid main() { o = vec4(1.0, 1.0, 1.0, a); }";
  gl.attachShader(program, compile(gl, gl.VERTEX_SHADER, vs));
  gl.attachShader(program, compile(gl, gl.FRAGMENT_SHADER, fs));
  gl.linkProgram(program);
  gl.useProgram(program);
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const buffer = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 3, -1, -1, 3]), gl.STATIC_DRAW);
  gl.enableVertexAttribArray(0);
  gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
  const side = 4;
  gl.viewport(0, 0, side, side);
  gl.enable(gl.SAMPLE_ALPHA_TO_COVERAGE);
  const px = new Uint8Array(4 * side * side);
  const alpha = gl.getUniformLocation(program, "a");
  const runs = new Map();
  const STEPS = 64;
  for (let i = 0; i < STEPS; i++) {
    const a = (i + 0.5) / STEPS;
    gl.clearColor(0, 0, 0, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.uniform1f(alpha, a);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    gl.readPixels(0, 0, side, side, gl.RGBA, gl.UNSIGNED_BYTE, px);
    let sum = 0;
    for (let k = 0; k < px.length; k += 4) sum += px[k];
    const written = (sum / (255 * side * side)) * samples;
    const k = Math.round(written);
    if (Math.abs(written - k) > 0.1) {
      runs.clear();
      break;
    }
    const run = runs.get(k);
    if (run) run[1] = a;
    else runs.set(k, [a, a]);
  }
  gl.disable(gl.SAMPLE_ALPHA_TO_COVERAGE);
  gl.bindVertexArray(null);
  gl.deleteVertexArray(vao);
  gl.deleteBuffer(buffer);
  gl.deleteProgram(program);
  const levels = new Float32Array(MAX_SAMPLES + 1);
  for (let k = 1; k <= samples; k++) {
    const run = runs.get(k);
    if (!run) return none;
    levels[k] = (run[0] + run[1]) / 2;
  }
  return { samples, levels };
}

const IDENTITY = new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);

export class Renderer {
  constructor(canvas) {
    const gl = canvas.getContext("webgl2", { antialias: true });
    if (!gl) throw new Error("this browser has no WebGL2");
    this.gl = gl;
    const program = gl.createProgram();
    gl.attachShader(program, compile(gl, gl.VERTEX_SHADER, VERTEX));
    gl.attachShader(program, compile(gl, gl.FRAGMENT_SHADER, FRAGMENT));
    gl.linkProgram(program);
    if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
    this.program = program;
    this.u = {};
    for (const name of ["uViewProj", "uModel", "uEye", "uTint", "uHasNormals", "uState", "uHasState", "uStateWidth", "uStateCount", "uIsolating", "uLooks", "uLookCount", "uPass", "uColour", "uHasTexture", "uSkinned", "uJoints", "uCoverSamples", "uCoverLevels"]) {
      this.u[name] = gl.getUniformLocation(program, name);
    }
    gl.enable(gl.DEPTH_TEST);
    this.stateTexture = gl.createTexture();
    this.stateWidth = Math.min(4096, gl.getParameter(gl.MAX_TEXTURE_SIZE));
    this.stateHeight = 0;
    this.stateCount = 0;
    this.stateUploads = 0;
    this.looksTexture = gl.createTexture();
    // One empty row until a colour mode fills it, so the sampler is never
    // bound to an incomplete texture.
    this.looksHeight = this.fill(this.looksTexture, 0, new Uint8Array(4 * this.stateWidth));
    this.lookCount = 0;
    this.lookUploads = 0;
    this.pickTarget = null;
    this.pages = new Pages(gl);
    this.cover = calibrateCover(gl);
    // Off draws every cluster alone, as the tests compare.
    this.batching = true;
    // Draw calls of the last draw(), both passes.
    this.drawCalls = 0;
  }

  // The per-feature state, RGBA bytes of feature i at 4 * i (the length a
  // multiple of stateRowBytes()); null draws every feature plainly.
  setState(bytes, count) {
    this.stateCount = bytes ? count : 0;
    if (!bytes) return;
    this.stateHeight = this.fill(this.stateTexture, this.stateHeight, bytes);
    this.stateUploads++;
  }

  // The per-feature looks (colours.js), in the state's layout; null: every
  // feature its own colour.
  setLooks(bytes, count) {
    this.lookCount = bytes ? count : 0;
    if (!bytes) return;
    this.looksHeight = this.fill(this.looksTexture, this.looksHeight, bytes);
    this.lookUploads++;
  }

  // Uploads rows of RGBA bytes into a texture of the state's width that
  // is `height` rows high now; returns its new height.
  fill(texture, height, bytes) {
    const gl = this.gl;
    const rows = bytes.length / (4 * this.stateWidth);
    gl.bindTexture(gl.TEXTURE_2D, texture);
    if (rows !== height) {
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, this.stateWidth, rows, 0, gl.RGBA, gl.UNSIGNED_BYTE, bytes);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    } else {
      gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, this.stateWidth, rows, gl.RGBA, gl.UNSIGNED_BYTE, bytes);
    }
    return rows;
  }

  stateRowBytes() {
    return 4 * this.stateWidth;
  }

  // GPU buffers of a parsed GLB and its decoded colour texture (an
  // ImageBitmap, or null): {slot (its range in a shared page) or vao and
  // buffers (its own), texture, count, bytes (on the GPU), hasNormals, ...}.
  // A mesh with feature ids and no joints or texture goes to a page.
  upload(mesh, image) {
    const gl = this.gl;
    if (mesh.features && !mesh.joints && !(mesh.uvs && image)) {
      const slot = this.pages.place(mesh);
      return {
        slot, texture: null, count: mesh.indices.length, bytes: slot.count * PAGE_VERTEX_BYTES + mesh.indices.byteLength,
        hasNormals: true, hasColors: true, hasFeatures: true, hasSkin: false,
      };
    }
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const buffers = [];
    const attribute = (location, data, size) => {
      const b = gl.createBuffer();
      buffers.push(b);
      gl.bindBuffer(gl.ARRAY_BUFFER, b);
      gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(location);
      gl.vertexAttribPointer(location, size, gl.FLOAT, false, 0, 0);
    };
    attribute(0, mesh.positions, 3);
    if (mesh.normals) attribute(1, mesh.normals, 3);
    if (mesh.colors) attribute(2, mesh.colors, 4);
    if (mesh.features) attribute(3, mesh.features, 1);
    if (mesh.joints) {
      attribute(5, mesh.joints, 4);
      attribute(6, mesh.weights, 4);
    }
    let texture = null;
    if (mesh.uvs && image) {
      attribute(4, mesh.uvs, 2);
      texture = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, texture);
      gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.SRGB8_ALPHA8, gl.RGBA, gl.UNSIGNED_BYTE, image);
      // Trilinear, clamped, as the GLB's sampler says: a baked texel is a
      // pixel or less where the cut draws the cluster, and where it is
      // less the mipmaps average it as full detail's samples would.
      gl.generateMipmap(gl.TEXTURE_2D);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR_MIPMAP_LINEAR);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
      gl.bindTexture(gl.TEXTURE_2D, null);
    }
    const ib = gl.createBuffer();
    buffers.push(ib);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, mesh.indices, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    const attributes = [mesh.positions, mesh.normals, mesh.colors, mesh.features, mesh.joints, mesh.weights, texture && mesh.uvs, mesh.indices];
    const bytes = attributes.reduce((s, a) => s + (a ? a.byteLength : 0), 0) + (texture ? Math.ceil((4 * 4 * image.width * image.height) / 3) : 0); // with its mipmaps
    return {
      vao, buffers, texture, bytes, count: mesh.indices.length,
      hasNormals: !!mesh.normals, hasColors: !!mesh.colors, hasFeatures: !!mesh.features, hasSkin: !!mesh.joints,
    };
  }

  // Frees what upload() made.
  free(gpu) {
    const gl = this.gl;
    if (gpu.slot) {
      this.pages.release(gpu.slot);
      return;
    }
    gl.deleteVertexArray(gpu.vao);
    for (const b of gpu.buffers) gl.deleteBuffer(b);
    if (gpu.texture) gl.deleteTexture(gpu.texture);
  }

  // items: [{gpu, transform (Float32Array|null), joints (Float32Array of
  // 16 per joint, column-major, or null), tint ([r,g,b]|null), feature (the
  // whole item's feature id where its GLB has none, or null)}];
  // isolating: features not flagged as isolated are drawn as ghosts;
  // translucent: some looks have a transparency, drawn blended.
  draw(items, camera, width, height, isolating, translucent) {
    const gl = this.gl;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, width, height);
    gl.clearColor(...BACKGROUND, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    // Opaque, but a baked texel's cover (its alpha) decides how many of a
    // pixel's samples it takes; the canvas's own alpha stays 1.
    gl.enable(gl.SAMPLE_ALPHA_TO_COVERAGE);
    gl.colorMask(true, true, true, false);
    this.drawCalls = 0;
    this.pass(items, camera, 0, isolating);
    gl.colorMask(true, true, true, true);
    gl.disable(gl.SAMPLE_ALPHA_TO_COVERAGE);
    if (isolating || translucent) {
      // Ghosts faint and translucent looks behind nothing: blended over the
      // opaque picture without writing depth, so what is behind them
      // shows through.
      gl.enable(gl.BLEND);
      gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA);
      gl.depthMask(false);
      this.pass(items, camera, 1, isolating);
      gl.depthMask(true);
      gl.disable(gl.BLEND);
    }
  }

  pass(items, camera, which, isolating) {
    const gl = this.gl;
    gl.useProgram(this.program);
    gl.uniformMatrix4fv(this.u.uViewProj, false, camera.viewProj);
    gl.uniform3fv(this.u.uEye, camera.eye);
    gl.uniform1i(this.u.uPass, which);
    gl.uniform1i(this.u.uCoverSamples, this.cover.samples);
    gl.uniform1fv(this.u.uCoverLevels, this.cover.levels);
    gl.uniform1i(this.u.uIsolating, isolating ? 1 : 0);
    gl.uniform1i(this.u.uHasState, this.stateCount > 0 ? 1 : 0);
    gl.uniform1i(this.u.uStateWidth, this.stateWidth);
    gl.uniform1i(this.u.uStateCount, this.stateCount);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, this.stateTexture);
    gl.uniform1i(this.u.uState, 0);
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, this.looksTexture);
    gl.uniform1i(this.u.uLooks, 1);
    gl.uniform1i(this.u.uLookCount, this.lookCount);
    gl.uniform1i(this.u.uColour, 2);
    gl.activeTexture(gl.TEXTURE2);
    const alone = [];
    const byPage = new Map();
    const batched = new Set();
    for (const item of items) {
      const g = item.gpu;
      if (this.batching && g.slot && !item.transform && !item.tint) {
        // An instance drawn twice in place would only draw it again.
        if (batched.has(g)) continue;
        batched.add(g);
        const list = byPage.get(g.slot.page);
        if (list) list.push(g.slot);
        else byPage.set(g.slot.page, [g.slot]);
      } else {
        alone.push(item);
      }
    }
    if (byPage.size > 0) {
      gl.uniformMatrix4fv(this.u.uModel, false, IDENTITY);
      gl.uniform1i(this.u.uSkinned, 0);
      gl.uniform4f(this.u.uTint, 0, 0, 0, 0);
      gl.uniform1i(this.u.uHasNormals, 1);
      gl.uniform1i(this.u.uHasTexture, 0);
      gl.bindTexture(gl.TEXTURE_2D, this.looksTexture);
      for (const [page, slots] of byPage) {
        const count = this.pages.bindDrawn(page, slots);
        gl.drawElements(gl.TRIANGLES, count, gl.UNSIGNED_INT, 0);
        if (which !== 2) this.drawCalls++;
      }
    }
    for (const item of alone) {
      const g = item.gpu;
      if (which === 2 && !g.hasFeatures && item.feature == null) continue;
      gl.uniformMatrix4fv(this.u.uModel, false, item.transform || IDENTITY);
      const skinned = g.hasSkin && item.joints && item.joints.length <= 16 * MAX_JOINTS;
      gl.uniform1i(this.u.uSkinned, skinned ? 1 : 0);
      if (skinned) gl.uniformMatrix4fv(this.u.uJoints, false, item.joints);
      gl.uniform4f(this.u.uTint, ...(item.tint || [0, 0, 0]), item.tint ? 1 : 0);
      gl.uniform1i(this.u.uHasNormals, g.hasNormals ? 1 : 0);
      gl.uniform1i(this.u.uHasTexture, g.texture ? 1 : 0);
      // Unit 2 always holds a complete texture: the looks' when the item
      // has none (never read then).
      gl.bindTexture(gl.TEXTURE_2D, g.texture || this.looksTexture);
      if (g.slot) this.pages.bindOne(g.slot);
      else gl.bindVertexArray(g.vao);
      // Constant attributes are context state, not the vertex array's.
      if (!g.hasColors) gl.vertexAttrib4fv(2, DEFAULT_COLOUR);
      if (!g.hasFeatures) gl.vertexAttrib1f(3, item.feature ?? -1);
      gl.drawElements(gl.TRIANGLES, g.count, gl.UNSIGNED_INT, 0);
      if (which !== 2) this.drawCalls++;
    }
    gl.bindVertexArray(null);
    gl.bindTexture(gl.TEXTURE_2D, null);
    gl.activeTexture(gl.TEXTURE0);
  }

  // Feature ids of the drawn items in the device-pixel rectangle
  // (x, y from the top left, w x h), row by row from the bottom: -1 where
  // no feature is. A click reads one pixel.
  pickRect(items, camera, width, height, x, y, w, h) {
    const gl = this.gl;
    const t = this.pickTarget;
    if (!t || t.width !== width || t.height !== height) {
      if (t) {
        gl.deleteFramebuffer(t.fb);
        gl.deleteRenderbuffer(t.colour);
        gl.deleteRenderbuffer(t.depth);
      }
      const fb = gl.createFramebuffer();
      const colour = gl.createRenderbuffer();
      const depth = gl.createRenderbuffer();
      gl.bindRenderbuffer(gl.RENDERBUFFER, colour);
      gl.renderbufferStorage(gl.RENDERBUFFER, gl.RGBA8, width, height);
      gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
      gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, width, height);
      gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
      gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.RENDERBUFFER, colour);
      gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
      this.pickTarget = { fb, colour, depth, width, height };
    }
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.pickTarget.fb);
    gl.viewport(0, 0, width, height);
    const y0 = height - y - h;
    gl.enable(gl.SCISSOR_TEST);
    gl.scissor(x, y0, w, h);
    gl.clearColor(0, 0, 0, 0);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    this.pass(items, camera, 2, false);
    const px = new Uint8Array(4 * w * h);
    gl.readPixels(x, y0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    gl.disable(gl.SCISSOR_TEST);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    const ids = new Int32Array(w * h);
    for (let i = 0; i < ids.length; i++) ids[i] = (px[4 * i] | (px[4 * i + 1] << 8) | (px[4 * i + 2] << 16)) - 1;
    return ids;
  }

  // The feature under device pixel (x, y) from the top left, or null.
  pick(items, camera, width, height, x, y) {
    if (x < 0 || y < 0 || x >= width || y >= height) return null;
    const id = this.pickRect(items, camera, width, height, x, y, 1, 1)[0];
    return id >= 0 ? id : null;
  }
}

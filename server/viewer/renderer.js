// WebGL2 drawing: one vertex array and one draw call per cluster, a
// headlight Lambert over vertex colours (or a colour per class or level).
// Dynamic clusters get their cut transform as the model matrix.

const VERTEX = `#version 300 es
layout(location = 0) in vec3 aPosition;
layout(location = 1) in vec3 aNormal;
layout(location = 2) in vec4 aColor;
uniform mat4 uViewProj;
uniform mat4 uModel;
out vec3 vWorld;
out vec3 vNormal;
out vec4 vColor;
void main() {
  vec4 world = uModel * vec4(aPosition, 1.0);
  vWorld = world.xyz;
  vNormal = mat3(uModel) * aNormal;
  vColor = aColor;
  gl_Position = uViewProj * world;
}`;

const FRAGMENT = `#version 300 es
precision highp float;
in vec3 vWorld;
in vec3 vNormal;
in vec4 vColor;
uniform vec3 uEye;
uniform vec4 uTint;
uniform bool uHasNormals;
out vec4 outColor;
void main() {
  // Polygon soup may lack or flip normals: the face normal from screen
  // derivatives stands in, and both sides are lit.
  vec3 n = uHasNormals ? normalize(vNormal) : normalize(cross(dFdx(vWorld), dFdy(vWorld)));
  vec3 l = normalize(uEye - vWorld);
  float lambert = abs(dot(n, l));
  vec3 base = uTint.a > 0.0 ? uTint.rgb : vColor.rgb;
  outColor = vec4(base * (0.3 + 0.7 * lambert), 1.0);
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
    for (const name of ["uViewProj", "uModel", "uEye", "uTint", "uHasNormals"]) {
      this.u[name] = gl.getUniformLocation(program, name);
    }
    gl.enable(gl.DEPTH_TEST);
  }

  // GPU buffers of a parsed GLB: {vao, count, hasNormals}.
  upload(mesh) {
    const gl = this.gl;
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
    else gl.vertexAttrib4f(2, 0.75, 0.75, 0.75, 1);
    const ib = gl.createBuffer();
    buffers.push(ib);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, mesh.indices, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    return { vao, buffers, count: mesh.indices.length, hasNormals: !!mesh.normals, hasColors: !!mesh.colors };
  }

  // items: [{gpu, transform (Float32Array|null), tint ([r,g,b]|null)}]
  draw(items, camera, width, height) {
    const gl = this.gl;
    gl.viewport(0, 0, width, height);
    gl.clearColor(...BACKGROUND, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.useProgram(this.program);
    gl.uniformMatrix4fv(this.u.uViewProj, false, camera.viewProj);
    gl.uniform3fv(this.u.uEye, camera.eye);
    for (const item of items) {
      const g = item.gpu;
      gl.uniformMatrix4fv(this.u.uModel, false, item.transform || IDENTITY);
      gl.uniform4f(this.u.uTint, ...(item.tint || [0, 0, 0]), item.tint ? 1 : 0);
      gl.uniform1i(this.u.uHasNormals, g.hasNormals ? 1 : 0);
      gl.bindVertexArray(g.vao);
      if (!g.hasColors) gl.vertexAttrib4f(2, 0.75, 0.75, 0.75, 1);
      gl.drawElements(gl.TRIANGLES, g.count, gl.UNSIGNED_INT, 0);
    }
    gl.bindVertexArray(null);
  }
}

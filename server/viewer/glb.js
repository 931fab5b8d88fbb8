// A minimal GLB reader for what the server's tree writer emits
// (hdlod/src/io/glb.rs, hdlod/src/io/compact.rs): one mesh of triangle
// primitives with POSITION, NORMAL and COLOR_0 (optional), the scene object
// of each vertex as `_FEATURE_ID_0` (EXT_mesh_features; optional), indices,
// and the baked colour of a reduced cluster (optional): TEXCOORD_0 and the
// material's baseColorTexture, a PNG in the binary chunk, which COLOR_0
// multiplies. The tree's compact form quantizes the attributes
// (KHR_mesh_quantization: normalized integers, read as floats here) and
// compresses the views (EXT_meshopt_compression, decoded by meshoptimizer's
// own decoder, `meshopt_decoder.js`); the plain form has neither. Written
// here rather than bundling a glTF library: the viewer has no build step
// and this subset is about two hundred lines. A node's `translation` and
// uniform `scale` place its mesh (the writer keeps positions small, or
// quantized to the mesh's extent); they are applied here. Other node
// transforms are not used: cluster GLBs hold their mesh in the cluster's
// frame, and the cut's `transform` places dynamic ones.

import { MeshoptDecoder } from "./meshopt_decoder.js";

// The extensions a file may require: the compact form's two and the
// feature ids'.
const KNOWN = new Set(["EXT_meshopt_compression", "KHR_mesh_quantization", "EXT_mesh_features", "EXT_structural_metadata"]);

// Resolves once the meshopt decoder (WebAssembly) can decode: parseGlb
// must not run before.
export const glbReady = MeshoptDecoder.ready;

const MAGIC = 0x46546c67; // "glTF"
const JSON_CHUNK = 0x4e4f534a;
const BIN_CHUNK = 0x004e4942;
const COMPONENTS = { SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4 };
const TYPES = {
  5120: [Int8Array, 127],
  5121: [Uint8Array, 255],
  5122: [Int16Array, 32767],
  5123: [Uint16Array, 65535],
  5125: [Uint32Array, 0],
  5126: [Float32Array, 0],
};

const UTF8 = new TextDecoder();

export class GlbError extends Error {}

// The bytes of buffer view `index`: a slice of the binary chunk, or the
// view decompressed (EXT_meshopt_compression) once per parse.
function viewBytes(gltf, bin, decoded, index, what) {
  const view = gltf.bufferViews?.[index];
  if (!view) throw new GlbError(`${what}: no buffer view ${index}`);
  const meshopt = view.extensions?.EXT_meshopt_compression;
  if (!meshopt) {
    if ((view.byteOffset || 0) + view.byteLength > bin.byteLength) throw new GlbError(`${what}: buffer view ${index} runs past the binary chunk`);
    return { bytes: new Uint8Array(bin.buffer, bin.byteOffset + (view.byteOffset || 0), view.byteLength), stride: view.byteStride };
  }
  if (!decoded.has(index)) {
    const start = meshopt.byteOffset || 0;
    if ((meshopt.buffer || 0) !== 0 || start + meshopt.byteLength > bin.byteLength) throw new GlbError(`${what}: compressed view ${index} is not in the binary chunk`);
    const source = new Uint8Array(bin.buffer, bin.byteOffset + start, meshopt.byteLength);
    const target = new Uint8Array(meshopt.count * meshopt.byteStride);
    try {
      MeshoptDecoder.decodeGltfBuffer(target, meshopt.count, meshopt.byteStride, source, meshopt.mode, meshopt.filter);
    } catch (e) {
      throw new GlbError(`${what}: compressed view ${index}: ${e.message}`);
    }
    decoded.set(index, target);
  }
  return { bytes: decoded.get(index), stride: view.byteStride };
}

function readAccessor(gltf, bin, decoded, index, what) {
  const accessor = gltf.accessors?.[index];
  if (!accessor) throw new GlbError(`${what}: no accessor ${index}`);
  if (accessor.bufferView === undefined) throw new GlbError(`${what}: accessor ${index} has no buffer view`);
  const view = viewBytes(gltf, bin, decoded, accessor.bufferView, what);
  const [Type, max] = TYPES[accessor.componentType] || [];
  const n = COMPONENTS[accessor.type];
  if (!Type || !n) throw new GlbError(`${what}: unsupported accessor type ${accessor.type}/${accessor.componentType}`);
  const data = view.bytes;
  const offset = data.byteOffset + (accessor.byteOffset || 0);
  const size = Type.BYTES_PER_ELEMENT;
  const stride = view.stride || n * size;
  const count = accessor.count;
  if ((accessor.byteOffset || 0) + (count - 1) * stride + n * size > data.byteLength) {
    throw new GlbError(`${what}: accessor ${index} runs past its buffer view`);
  }
  let out;
  if (stride === n * size && offset % size === 0) {
    out = new Type(data.buffer, offset, count * n);
  } else if (count > 0 && offset % size === 0 && stride % size === 0) {
    // A strided view (quantized attributes are padded to 4 bytes a
    // vertex) read through a typed array over it: a DataView call per
    // component took most of a cut's parse time.
    const step = stride / size;
    const src = new Type(data.buffer, offset, (count - 1) * step + n);
    out = new Type(count * n);
    for (let i = 0, o = 0; i < count; i++) {
      for (let k = 0; k < n; k++) out[o++] = src[i * step + k];
    }
  } else {
    out = new Type(count * n);
    const dv = new DataView(data.buffer);
    const get = {
      1: (o) => (Type === Int8Array ? dv.getInt8(o) : dv.getUint8(o)),
      2: (o) => (Type === Int16Array ? dv.getInt16(o, true) : dv.getUint16(o, true)),
      4: (o) => (Type === Float32Array ? dv.getFloat32(o, true) : dv.getUint32(o, true)),
    }[size];
    for (let i = 0; i < count; i++) {
      for (let k = 0; k < n; k++) out[i * n + k] = get(offset + i * stride + k * size);
    }
  }
  // Normalised integers become floats in [0, 1] (signed: [-1, 1]).
  if (accessor.normalized && max) {
    const floats = new Float32Array(out.length);
    for (let i = 0; i < out.length; i++) floats[i] = Math.max(out[i] / max, -1);
    out = floats;
  }
  return { data: out, components: n, count };
}

// Feature ids as floats (exact up to 2^24, the writer's limit): FLOAT as our
// writer stores them, or unsigned integers as other writers may.
function readFeatureIds(gltf, bin, decoded, index, what) {
  const type = gltf.accessors?.[index]?.componentType;
  if (![5121, 5123, 5125, 5126].includes(type)) throw new GlbError(`${what}: component type ${type} is not FLOAT or unsigned`);
  const { data, components } = readAccessor(gltf, bin, decoded, index, what);
  if (components !== 1) throw new GlbError(`${what}: not SCALAR`);
  return data instanceof Float32Array ? data : Float32Array.from(data);
}

// A skinned primitive's JOINTS_0 (unsigned bytes or shorts) and WEIGHTS_0
// (floats, or normalized unsigned bytes or shorts), four a vertex, as
// floats: {joints, weights}. The joints index the matrices the cut answer
// gives the cluster.
function readSkin(gltf, bin, decoded, a, count, what) {
  const j = readAccessor(gltf, bin, decoded, a.JOINTS_0, `${what} JOINTS_0`);
  const w = readAccessor(gltf, bin, decoded, a.WEIGHTS_0, `${what} WEIGHTS_0`);
  for (const [name, x] of [["JOINTS_0", j], ["WEIGHTS_0", w]]) {
    if (x.components !== 4 || x.count !== count) throw new GlbError(`${what}: ${name} is not one VEC4 per vertex`);
  }
  return { joints: Float32Array.from(j.data), weights: w.data instanceof Float32Array ? w.data : Float32Array.from(w.data) };
}

// The PNG (or other image) bytes of a primitive's base colour texture when
// they are in the binary chunk: {bytes, type}, or null.
function readImage(gltf, bin, decoded, prim, what) {
  const info = gltf.materials?.[prim.material]?.pbrMetallicRoughness?.baseColorTexture;
  if (!info) return null;
  const image = gltf.images?.[gltf.textures?.[info.index]?.source];
  if (!image) throw new GlbError(`${what}: base colour texture ${info.index} has no image`);
  if (image.bufferView === undefined) return null;
  const { bytes } = viewBytes(gltf, bin, decoded, image.bufferView, `${what} image`);
  return { bytes, type: image.mimeType || "image/png", texCoord: info.texCoord || 0 };
}

// -> {positions, normals|null, colors|null (RGBA), features|null (one per
// vertex, -1 for none), joints|null and weights|null (four per vertex, a
// skinned cluster's), uvs|null (texture coordinates), image|null (the
// bytes and MIME type of the colour texture), indices (Uint32Array),
// triangles}
export function parseGlb(buffer) {
  const dv = new DataView(buffer);
  if (buffer.byteLength < 20 || dv.getUint32(0, true) !== MAGIC) throw new GlbError("not a GLB file");
  if (dv.getUint32(4, true) !== 2) throw new GlbError(`GLB version ${dv.getUint32(4, true)}, expected 2`);
  let gltf = null;
  let bin = null;
  for (let at = 12; at + 8 <= buffer.byteLength; ) {
    const length = dv.getUint32(at, true);
    const type = dv.getUint32(at + 4, true);
    const body = new Uint8Array(buffer, at + 8, Math.min(length, buffer.byteLength - at - 8));
    if (type === JSON_CHUNK) gltf = JSON.parse(UTF8.decode(body));
    else if (type === BIN_CHUNK) bin = body;
    at += 8 + length;
  }
  if (!gltf) throw new GlbError("no JSON chunk");
  if (!bin) throw new GlbError("no binary chunk");
  for (const name of gltf.extensionsRequired || []) {
    if (!KNOWN.has(name)) throw new GlbError(`requires ${name}, which this reader does not know`);
  }
  const decoded = new Map();
  // Each mesh's local frame: the translation and uniform scale of the node
  // that holds it.
  const origins = new Map();
  for (const node of gltf.nodes || []) {
    if (node.mesh !== undefined && (node.translation || node.scale)) {
      origins.set(node.mesh, { t: node.translation || [0, 0, 0], s: node.scale ? node.scale[0] : 1 });
    }
  }
  const parts = [];
  for (const [m, mesh] of (gltf.meshes || []).entries()) {
    for (const [p, prim] of mesh.primitives.entries()) {
      if ((prim.mode ?? 4) !== 4) continue;
      const what = `mesh ${m} primitive ${p}`;
      const a = prim.attributes || {};
      if (a.POSITION === undefined) throw new GlbError(`${what}: no POSITION`);
      const pos = readAccessor(gltf, bin, decoded, a.POSITION, `${what} POSITION`);
      const nor = a.NORMAL !== undefined ? readAccessor(gltf, bin, decoded, a.NORMAL, `${what} NORMAL`) : null;
      const col = a.COLOR_0 !== undefined ? readAccessor(gltf, bin, decoded, a.COLOR_0, `${what} COLOR_0`) : null;
      const fid = a._FEATURE_ID_0 !== undefined ? readFeatureIds(gltf, bin, decoded, a._FEATURE_ID_0, `${what} _FEATURE_ID_0`) : null;
      const skin = a.JOINTS_0 !== undefined && a.WEIGHTS_0 !== undefined ? readSkin(gltf, bin, decoded, a, pos.count, what) : null;
      const image = readImage(gltf, bin, decoded, prim, what);
      const uvName = image && `TEXCOORD_${image.texCoord}`;
      const uv = image && a[uvName] !== undefined ? readAccessor(gltf, bin, decoded, a[uvName], `${what} ${uvName}`) : null;
      if (uv && (uv.components !== 2 || uv.count !== pos.count)) throw new GlbError(`${what}: ${uvName} is not one VEC2 per vertex`);
      const idx = prim.indices !== undefined
        ? readAccessor(gltf, bin, decoded, prim.indices, `${what} indices`).data
        : Uint32Array.from({ length: pos.count }, (_, i) => i);
      if (fid && fid.length !== pos.count) throw new GlbError(`${what}: ${fid.length} feature ids for ${pos.count} vertices`);
      parts.push({ pos, nor, col, fid, skin, idx, uv, image: uv ? image : null, origin: origins.get(m) });
    }
  }
  if (!parts.length) throw new GlbError("no triangle primitive");
  // One draw call per cluster: the primitives are concatenated.
  const vertices = parts.reduce((s, p) => s + p.pos.count, 0);
  const indexCount = parts.reduce((s, p) => s + p.idx.length, 0);
  const positions = new Float32Array(vertices * 3);
  const hasNormals = parts.every((p) => p.nor);
  const normals = hasNormals ? new Float32Array(vertices * 3) : null;
  const hasColors = parts.some((p) => p.col);
  const colors = hasColors ? new Float32Array(vertices * 4).fill(1) : null;
  // A primitive without feature ids is not pickable: -1 marks its vertices.
  const features = parts.some((p) => p.fid) ? new Float32Array(vertices).fill(-1) : null;
  // One texture per cluster: the first primitive's; the others' vertices
  // read its corner (our writer makes one primitive).
  const textured = parts.find((p) => p.uv);
  const uvs = textured ? new Float32Array(vertices * 2) : null;
  // Skinned when every primitive is: the joints place all its vertices.
  const skinned = parts.every((p) => p.skin);
  const joints = skinned ? new Float32Array(vertices * 4) : null;
  const weights = skinned ? new Float32Array(vertices * 4) : null;
  const indices = new Uint32Array(indexCount);
  let v = 0;
  let i = 0;
  for (const p of parts) {
    positions.set(p.pos.data, v * 3);
    if (p.origin) {
      const { t, s } = p.origin;
      const [tx, ty, tz] = t;
      for (let k = v * 3, end = (v + p.pos.count) * 3; k < end; k += 3) {
        positions[k] = positions[k] * s + tx;
        positions[k + 1] = positions[k + 1] * s + ty;
        positions[k + 2] = positions[k + 2] * s + tz;
      }
    }
    if (normals) normals.set(p.nor.data, v * 3);
    if (features && p.fid) features.set(p.fid, v);
    if (skinned) {
      joints.set(p.skin.joints, v * 4);
      weights.set(p.skin.weights, v * 4);
    }
    if (p === textured) uvs.set(p.uv.data, v * 2);
    if (colors && p.col) {
      const { data, components, count } = p.col;
      if (components === 4) colors.set(data, v * 4);
      else {
        for (let k = 0; k < count; k++) {
          for (let c = 0; c < components; c++) colors[(v + k) * 4 + c] = data[k * components + c];
        }
      }
    }
    const { idx } = p;
    const n = p.pos.count;
    for (let k = 0; k < idx.length; k++) {
      if (idx[k] >= n) throw new GlbError(`index ${idx[k]} past ${n} vertices`);
      indices[i + k] = idx[k] + v;
    }
    v += n;
    i += idx.length;
  }
  return { positions, normals, colors, features, joints, weights, uvs, image: textured ? textured.image : null, indices, triangles: indexCount / 3 };
}

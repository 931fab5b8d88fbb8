//! The compact form of a cluster GLB, the one a tree stores: attributes
//! quantized after `KHR_mesh_quantization`
//! (<https://github.com/KhronosGroup/glTF/tree/main/extensions/2.0/Khronos/KHR_mesh_quantization>)
//! and every vertex and index view compressed by meshoptimizer's codecs
//! after `EXT_meshopt_compression`
//! (<https://github.com/KhronosGroup/glTF/tree/main/extensions/2.0/Vendor/EXT_meshopt_compression>),
//! and the way back to the plain form for readers without either.
//!
//! Quantization: positions are normalized `SHORT` of the mesh's largest
//! coordinate `s` (the node's uniform `scale`) when that moves no vertex by
//! more than the caller's allowance, and stay exact `FLOAT` otherwise (a
//! leaf's allowance is 0); the largest move is measured and answered, and
//! the build adds it to the cluster's `eps`, so every stored `eps` stays a
//! bound of the geometry as stored. Normals normalized `BYTE`, and left
//! out where they are the triangles' own (flat), which a reader computes
//! where a primitive has none; colours
//! normalized `UNSIGNED_BYTE`,
//! texture coordinates normalized `UNSIGNED_SHORT`. Feature ids stay `FLOAT`
//! (exact, and a run of equal ids costs the vertex codec almost nothing),
//! indices `UNSIGNED_SHORT` below 65,536 vertices. The attributes are
//! interleaved in one view, each 4-byte aligned, as both extensions ask.
//! Vertices whose stored values are the same bytes are stored once: with
//! flat normals left out, a box's faces share their corners.
//!
//! Compression: the compressed streams are the GLB's binary chunk (buffer
//! 0); the views point into buffer 1, a fallback buffer without data, so
//! the file requires the extension. Vertex streams use the `ATTRIBUTES`
//! mode (codec version 0, the one `EXT_meshopt_compression` names),
//! indices the `TRIANGLES` mode. Both codecs are lossless, except that the
//! index codec may rotate a triangle's corners (keeping its winding and
//! the triangles' order): the plain form ([`plain`]) holds exactly the
//! stored values, as `f32`, a welded vertex copied once for each flat
//! normal it takes.
//!
//! A skinned cluster's file (a mesh, its skin and its joints' animation)
//! has every view compressed the same way but nothing quantized
//! (`GlbBuilder::compress_views`); its plain form is the views
//! decompressed, the glTF otherwise as written.

use std::borrow::Cow;

use glam::{Vec2, Vec3};
use gltf::json::{self, validation::Checked::Valid, validation::USize64};
use serde_json::Value;

use super::glb::{Encoding, GlbBuilder, MeshAccessors, glb_at, unit_normals, write_container};
use super::texture::Texture;
use crate::geometry::Mesh;

const MESHOPT: &str = "EXT_meshopt_compression";
const QUANTIZATION: &str = "KHR_mesh_quantization";

/// The largest value of a normalized signed short.
const SHORT: f32 = 32767.0;

impl GlbBuilder {
    /// [`GlbBuilder::add_mesh`] quantized and compressed, with the texture
    /// coordinates `uvs` (in `[0, 1]`, as the baker's are) when given, its
    /// positions moved by at most `allowance`; the scale of the positions
    /// (the node's) and how far a vertex moved at most. The attributes are
    /// interleaved in one view: one compressed stream and one extension
    /// object per file, where a view per attribute would cost more JSON
    /// than the compressed data of a small cluster.
    pub(super) fn add_compact_mesh(
        &mut self,
        mesh: &Mesh,
        uvs: Option<&[Vec2]>,
        allowance: f32,
    ) -> (MeshAccessors, f32, f32) {
        let n = mesh.positions.len();
        self.quantized = true;
        let quantized = quantized(&mesh.positions, allowance);
        let (scale, moved) = quantized
            .as_ref()
            .map_or((1.0, 0.0), |q| (q.scale, q.moved));
        // The layout: each attribute's offset in the vertex, 4-byte aligned.
        let mut stride = if quantized.is_some() { 8 } else { 12 };
        let mut field = |present: bool| {
            present.then(|| {
                stride += 4;
                stride - 4
            })
        };
        // A primitive without normals is drawn with flat ones (glTF 2.0,
        // "Meshes"), and a small cluster's file is mostly JSON: the normals'
        // accessor is left out where they are the triangles' own, as the
        // boxes and quads of most clusters have them.
        let stored: &[Vec3] = quantized.as_ref().map_or(&mesh.positions, |q| &q.values);
        let flat = is_flat(stored, &mesh.normals, &mesh.indices);
        let normals = field(!mesh.normals.is_empty() && !flat);
        let colors = field(!mesh.colors.is_empty());
        let texcoords = field(uvs.is_some());
        let features = field(!mesh.features.is_empty());
        let mut raw = vec![0u8; n * stride];
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for (i, vertex) in raw.chunks_exact_mut(stride).enumerate() {
            match &quantized {
                Some(q) => {
                    let v = q.values[i];
                    lo = lo.min(v);
                    hi = hi.max(v);
                    for (k, x) in v.to_array().into_iter().enumerate() {
                        vertex[2 * k..2 * k + 2].copy_from_slice(&(x as i16).to_le_bytes());
                    }
                }
                None => {
                    let p = mesh.positions[i];
                    lo = lo.min(p);
                    hi = hi.max(p);
                    for (k, v) in p.to_array().into_iter().enumerate() {
                        vertex[4 * k..4 * k + 4].copy_from_slice(&v.to_le_bytes());
                    }
                }
            }
            if let Some(at) = normals {
                let v = byte_grid(mesh.normals[i]);
                vertex[at..at + 3].copy_from_slice(&[
                    v.x as i8 as u8,
                    v.y as i8 as u8,
                    v.z as i8 as u8,
                ]);
            }
            if let Some(at) = colors {
                let c = mesh.colors[i].map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8);
                vertex[at..at + 4].copy_from_slice(&c);
            }
            if let (Some(at), Some(uvs)) = (texcoords, uvs) {
                for (k, v) in uvs[i].to_array().into_iter().enumerate() {
                    let q = (v.clamp(0.0, 1.0) * 65535.0).round() as u16;
                    vertex[at + 2 * k..at + 2 * k + 2].copy_from_slice(&q.to_le_bytes());
                }
            }
            if let Some(at) = features {
                vertex[at..at + 4].copy_from_slice(&(mesh.features[i] as f32).to_le_bytes());
            }
        }
        let (raw, indices) = welded(&raw, stride, &mesh.indices);
        let n = raw.len() / stride;
        let encoded = encode_vertices(&raw, stride);
        let view = self.compressed_view(raw.len(), &encoded, Some(stride), n, "ATTRIBUTES");
        use json::accessor::{ComponentType as C, Type as T};
        let positions = self.view_accessor(
            view,
            0,
            n,
            T::Vec3,
            if quantized.is_some() { C::I16 } else { C::F32 },
            Some((lo.to_array().to_vec(), hi.to_array().to_vec())),
        );
        let normals = normals.map(|at| self.view_accessor(view, at, n, T::Vec3, C::I8, None));
        let colors = colors.map(|at| self.view_accessor(view, at, n, T::Vec4, C::U8, None));
        let uvs = texcoords.map(|at| self.view_accessor(view, at, n, T::Vec2, C::U16, None));
        let features = features.map(|at| {
            let mut distinct = mesh.features.clone();
            distinct.sort_unstable();
            distinct.dedup();
            (
                self.view_accessor(view, at, n, T::Scalar, C::F32, None),
                distinct.len(),
            )
        });
        let indices = self.compressed_indices(&indices, n);
        let accessors = MeshAccessors {
            positions,
            normals,
            colors,
            uvs,
            features,
            influences: None,
            indices,
        };
        (accessors, scale, moved)
    }

    /// An accessor of `count` elements at `offset` in each vertex of the
    /// interleaved `view`; integer components normalized.
    fn view_accessor(
        &mut self,
        view: json::Index<json::buffer::View>,
        offset: usize,
        count: usize,
        kind: json::accessor::Type,
        component: json::accessor::ComponentType,
        min_max: Option<(Vec<f32>, Vec<f32>)>,
    ) -> json::Index<json::Accessor> {
        // Quantized bounds are whole numbers, written as such: `32767`,
        // not `32767.0`.
        let number = |v: &f32| match v.fract() == 0.0 && v.abs() <= SHORT {
            true => json::Value::from(*v as i64),
            false => json::Value::from(*v),
        };
        let numbers = |vs: Vec<f32>| json::Value::from(vs.iter().map(number).collect::<Vec<_>>());
        let (min, max) = match min_max {
            Some((lo, hi)) => (Some(numbers(lo)), Some(numbers(hi))),
            None => (None, None),
        };
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: (offset > 0).then(|| USize64::from(offset)),
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: None,
            type_: Valid(kind),
            min,
            max,
            name: None,
            normalized: component != json::accessor::ComponentType::F32,
            sparse: None,
        })
    }

    /// The index accessor, `u16` when the vertices allow, compressed.
    fn compressed_indices(
        &mut self,
        indices: &[u32],
        vertices: usize,
    ) -> json::Index<json::Accessor> {
        let encoded =
            meshopt::encode_index_buffer(indices, vertices).expect("the indices are triangles");
        let (size, component) = if vertices <= usize::from(u16::MAX) {
            (2, json::accessor::ComponentType::U16)
        } else {
            (4, json::accessor::ComponentType::U32)
        };
        let view = self.compressed_view(
            indices.len() * size,
            &encoded,
            None,
            indices.len(),
            "TRIANGLES",
        );
        // The extension's stride of an index view is the index size.
        let last = self.compressed.last_mut().expect("just pushed");
        last.1["byteStride"] = size.into();
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(indices.len()),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: None,
            type_: Valid(json::accessor::Type::Scalar),
            min: None,
            max: None,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// A view of `length` bytes in the fallback buffer whose data is
    /// `encoded`, appended to the binary chunk.
    fn compressed_view(
        &mut self,
        length: usize,
        encoded: &[u8],
        stride: Option<usize>,
        count: usize,
        mode: &str,
    ) -> json::Index<json::buffer::View> {
        let at = self.fallback;
        self.fallback = (at + length).next_multiple_of(4);
        let view = self.root.push(json::buffer::View {
            // Buffer 1, the fallback; the buffer count is fixed at the end.
            buffer: json::Index::new(1),
            byte_length: USize64::from(length),
            // 0 is the default, and unwritten: a small cluster's file is
            // mostly its JSON.
            byte_offset: (at > 0).then(|| USize64::from(at)),
            byte_stride: stride.map(json::buffer::Stride),
            name: None,
            // The target is a hint, optional, which loaders infer from
            // the accessors' use: left out, as the other defaults.
            target: None,
            extensions: None,
            extras: None,
        });
        self.push_compressed(view.value(), encoded, stride, count, mode);
        view
    }

    /// Appends `encoded`, the data of view `view`, to the binary chunk and
    /// records the view's `EXT_meshopt_compression` object.
    fn push_compressed(
        &mut self,
        view: usize,
        encoded: &[u8],
        stride: Option<usize>,
        count: usize,
        mode: &str,
    ) {
        let offset = self.bin.len();
        self.bin.extend_from_slice(encoded);
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let mut extension = serde_json::json!({
            "buffer": 0,
            "byteLength": encoded.len(),
            "count": count,
            "mode": mode,
        });
        if offset > 0 {
            extension["byteOffset"] = offset.into();
        }
        if let Some(stride) = stride {
            extension["byteStride"] = stride.into();
        }
        self.compressed.push((view, extension));
    }

    /// Every view written so far compressed after `EXT_meshopt_compression`,
    /// losslessly, without quantizing anything: a skinned cluster's file,
    /// whose joints' keyframes in `f32` are most of its bytes (a walker's
    /// 2,045 keyframes of five joints, 450 kB plain). Triangle indices in
    /// the `TRIANGLES` mode, a view of elements of 4 to 32 bytes in the
    /// `ATTRIBUTES` mode; any other view (the inverse binds' matrices)
    /// stays as it is.
    pub(super) fn compress_views(&mut self) {
        let plain = std::mem::take(&mut self.bin);
        let views = self.root.buffer_views.len();
        // Each view's element size, if its accessors agree on one.
        let mut element: Vec<Option<Option<usize>>> = vec![None; views];
        for a in &self.root.accessors {
            let (Some(view), Valid(kind), Valid(component)) =
                (a.buffer_view, &a.type_, &a.component_type)
            else {
                continue;
            };
            let size = kind.multiplicity() * component.0.size();
            let slot = &mut element[view.value()];
            *slot = match *slot {
                None => Some(Some(size)),
                Some(Some(s)) if s == size => Some(Some(s)),
                _ => Some(None),
            };
        }
        let mut indices = vec![false; views];
        for primitive in self.root.meshes.iter().flat_map(|m| &m.primitives) {
            let view = primitive
                .indices
                .and_then(|i| self.root.accessors[i.value()].buffer_view);
            if let Some(view) = view {
                indices[view.value()] = true;
            }
        }
        for v in 0..views {
            let view = &self.root.buffer_views[v];
            let start = view.byte_offset.map_or(0, |o| o.0 as usize);
            let bytes = &plain[start..start + view.byte_length.0 as usize];
            let size = match element[v] {
                Some(Some(size))
                    if view.byte_stride.is_none() && bytes.len().is_multiple_of(size) =>
                {
                    size
                }
                _ => 0,
            };
            let count = bytes.len() / size.max(1);
            let (encoded, mode) = match size {
                4 if indices[v] && count.is_multiple_of(3) => {
                    let indices: &[u32] = bytemuck::cast_slice(bytes);
                    let vertices = indices.iter().max().map_or(0, |&m| m as usize + 1);
                    let encoded = meshopt::encode_index_buffer(indices, vertices)
                        .expect("the indices are triangles");
                    (encoded, "TRIANGLES")
                }
                4 | 8 | 12 | 16 | 20 | 24 | 28 | 32 => (encode_vertices(bytes, size), "ATTRIBUTES"),
                _ => {
                    // Left as it is, in the binary chunk.
                    self.root.buffer_views[v].byte_offset =
                        (!self.bin.is_empty()).then(|| USize64::from(self.bin.len()));
                    self.bin.extend_from_slice(bytes);
                    self.bin.resize(self.bin.len().next_multiple_of(4), 0);
                    continue;
                }
            };
            self.push_compressed(v, &encoded, Some(size), count, mode);
            // The fallback buffer keeps the plain layout.
            self.root.buffer_views[v].buffer = json::Index::new(1);
        }
        self.fallback = plain.len().next_multiple_of(4);
    }
}

/// Unit normal `n` as a normalized `BYTE` stores it: its components times
/// 127, rounded.
fn byte_grid(n: Vec3) -> Vec3 {
    (n * 127.0)
        .round()
        .clamp(Vec3::splat(-127.0), Vec3::splat(127.0))
}

/// Whether `normals` are those of the triangles at each vertex of
/// `positions` (as stored), within the angle of an 8-bit normal's rounding
/// (0.6 degrees): what a reader computes where a primitive has none. Not
/// where a triangle is degenerate or a vertex on none.
fn is_flat(positions: &[Vec3], normals: &[Vec3], indices: &[u32]) -> bool {
    const COS: f32 = 0.99995;
    if normals.len() != positions.len() || positions.is_empty() {
        return false;
    }
    let mut used = vec![false; positions.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
        let Some(face) = (b - a).cross(c - a).try_normalize() else {
            return false;
        };
        for &i in t {
            if normals[i as usize].normalize_or_zero().dot(face) < COS {
                return false;
            }
            used[i as usize] = true;
        }
    }
    used.into_iter().all(|u| u)
}

/// The extensions' part of the JSON of a GLB with `compressed` views (none
/// for a plain GLB): each view's `EXT_meshopt_compression` object, the
/// fallback buffer of `fallback` bytes, and both extensions used and
/// required.
pub(super) fn declare(
    json: &mut Value,
    compressed: &[(usize, Value)],
    fallback: usize,
    quantized: bool,
) {
    if compressed.is_empty() {
        return;
    }
    for (view, extension) in compressed {
        json["bufferViews"][*view]["extensions"] = serde_json::json!({ MESHOPT: extension });
    }
    // The materials' default values, which the gltf crate writes out: in
    // a small cluster's file they weigh as much as its triangles.
    for material in json["materials"].as_array_mut().into_iter().flatten() {
        let Some(m) = material.as_object_mut() else {
            continue;
        };
        m.retain(|k, v| !is_default(k, v));
        if let Some(pbr) = m
            .get_mut("pbrMetallicRoughness")
            .and_then(Value::as_object_mut)
        {
            pbr.retain(|k, v| !is_default(k, v));
        }
    }
    // A node's translation and scale are `f32`, which the JSON value holds
    // as `f64`: written as the shortest decimal that reads back as the same
    // `f32` rather than the `f64` expansion, they take half the characters.
    for node in json["nodes"].as_array_mut().into_iter().flatten() {
        for key in ["translation", "scale"] {
            for v in node
                .get_mut(key)
                .and_then(Value::as_array_mut)
                .into_iter()
                .flatten()
            {
                if let Some(x) = v.as_f64().filter(|x| f64::from(*x as f32) == *x) {
                    *v = serde_json::from_str(&(x as f32).to_string()).unwrap_or(x.into());
                }
            }
        }
    }
    // Optional, and in every one of 120,000 files.
    if let Some(asset) = json["asset"].as_object_mut() {
        asset.remove("generator");
    }
    let buffers = json["buffers"]
        .as_array_mut()
        .expect("a compressed GLB has its binary chunk's buffer");
    buffers.push(serde_json::json!({
        "byteLength": fallback,
        "extensions": { MESHOPT: { "fallback": true } }
    }));
    for key in ["extensionsUsed", "extensionsRequired"] {
        let mut list = json[key]
            .as_array_mut()
            .map(std::mem::take)
            .unwrap_or_default();
        let names: &[&str] = if quantized {
            &[MESHOPT, QUANTIZATION]
        } else {
            &[MESHOPT]
        };
        for &name in names {
            if !list.iter().any(|v| v == name) {
                list.push(name.into());
            }
        }
        json[key] = Value::Array(list);
    }
}

/// Whether a material's (or its `pbrMetallicRoughness`'s) `key` holds its
/// default value.
fn is_default(key: &str, value: &Value) -> bool {
    match key {
        "alphaMode" => value == "OPAQUE",
        "emissiveFactor" => *value == serde_json::json!([0.0, 0.0, 0.0]),
        "roughnessFactor" => *value == 1.0,
        "baseColorFactor" => *value == serde_json::json!([1.0, 1.0, 1.0, 1.0]),
        _ => false,
    }
}

/// Positions as normalized shorts of the node's uniform `scale`.
struct Quantized {
    /// Each position's three shorts, as `f32` (whole numbers).
    values: Vec<Vec3>,
    scale: f32,
    /// The farthest a position moved, a little over: as a reader computes
    /// it in `f32`, `scale * q / 32767`.
    moved: f32,
}

/// `positions` quantized to normalized shorts of their largest coordinate,
/// if that moves none of them by more than `allowance`; `None` keeps them
/// exact.
fn quantized(positions: &[Vec3], allowance: f32) -> Option<Quantized> {
    if allowance <= 0.0 || positions.is_empty() {
        return None;
    }
    let scale = positions
        .iter()
        .fold(0.0f32, |m, p| m.max(p.abs().max_element()));
    if scale <= 0.0 || !scale.is_finite() {
        return None;
    }
    let values: Vec<Vec3> = positions
        .iter()
        .map(|p| {
            (*p / scale * SHORT)
                .round()
                .clamp(Vec3::splat(-SHORT), Vec3::splat(SHORT))
        })
        .collect();
    let moved = positions
        .iter()
        .zip(&values)
        .map(|(p, q)| (q.as_dvec3() / f64::from(SHORT) * f64::from(scale) - p.as_dvec3()).length())
        .fold(0.0f64, f64::max);
    // A reader's `f32` arithmetic rounds the decoded value by a few units
    // in the last place of `scale`.
    let moved = (moved + f64::from(scale) * 4.0 * f64::from(f32::EPSILON)) as f32;
    (moved <= allowance).then_some(Quantized {
        values,
        scale,
        moved,
    })
}

/// The distinct vertices of `raw` (records of `stride` bytes, as stored)
/// in the order of their first use, and `indices` into them. A box's
/// faces each have their own four corners only for their normals: with
/// the normals left out (`is_flat`), the corners the faces share are one
/// vertex, a third of them. meshoptimizer's remap compares the records
/// byte for byte, so no stored value changes; a vertex no triangle uses
/// goes. Without triangles the records stay as they are.
fn welded(raw: &[u8], stride: usize, indices: &[u32]) -> (Vec<u8>, Vec<u32>) {
    fn with<T: bytemuck::Pod>(raw: &[u8], indices: &[u32]) -> (Vec<u8>, Vec<u32>) {
        let records = bytemuck::cast_slice::<u8, T>(raw);
        let (count, remap) = meshopt::generate_vertex_remap(records, Some(indices));
        let mut distinct = vec![T::zeroed(); count];
        for (old, &new) in remap.iter().enumerate() {
            // A vertex no triangle uses maps to `u32::MAX`.
            if let Some(to) = distinct.get_mut(new as usize) {
                *to = records[old];
            }
        }
        let indices = meshopt::remap_index_buffer(Some(indices), count, &remap);
        (bytemuck::cast_vec(distinct), indices)
    }
    if indices.is_empty() {
        return (raw.to_vec(), Vec::new());
    }
    match stride {
        8 => with::<[u8; 8]>(raw, indices),
        12 => with::<[u8; 12]>(raw, indices),
        16 => with::<[u8; 16]>(raw, indices),
        20 => with::<[u8; 20]>(raw, indices),
        24 => with::<[u8; 24]>(raw, indices),
        28 => with::<[u8; 28]>(raw, indices),
        other => unreachable!("no vertex stream of {other} bytes is written"),
    }
}

/// Encodes `raw`, elements of `stride` bytes, with the vertex codec at the
/// version `EXT_meshopt_compression` decoders read.
fn encode_vertices(raw: &[u8], stride: usize) -> Vec<u8> {
    fn with<T>(elements: &[T]) -> Vec<u8> {
        meshopt::encode_vertex_buffer_level(elements, 2, Some(0)).expect("a vertex stream encodes")
    }
    match stride {
        4 => with(bytemuck::cast_slice::<u8, [u8; 4]>(raw)),
        8 => with(bytemuck::cast_slice::<u8, [u8; 8]>(raw)),
        12 => with(bytemuck::cast_slice::<u8, [u8; 12]>(raw)),
        16 => with(bytemuck::cast_slice::<u8, [u8; 16]>(raw)),
        20 => with(bytemuck::cast_slice::<u8, [u8; 20]>(raw)),
        24 => with(bytemuck::cast_slice::<u8, [u8; 24]>(raw)),
        28 => with(bytemuck::cast_slice::<u8, [u8; 28]>(raw)),
        32 => with(bytemuck::cast_slice::<u8, [u8; 32]>(raw)),
        other => unreachable!("no vertex stream of {other} bytes is written"),
    }
}

/// Whether a GLB uses either extension of the compact form, judged by its
/// JSON's `extensionsUsed` (a file that is no GLB is not).
pub fn is_compact(glb: &[u8]) -> bool {
    compact_json(glb).is_some()
}

/// The JSON of a GLB that uses either extension of the compact form.
fn compact_json(glb: &[u8]) -> Option<Value> {
    let json = gltf::binary::Glb::from_slice(glb)
        .ok()
        .and_then(|g| serde_json::from_slice::<Value>(&g.json).ok())?;
    let used = json.get("extensionsUsed").and_then(Value::as_array)?;
    used.iter()
        .any(|u| u == MESHOPT || u == QUANTIZATION)
        .then_some(json)
}

/// The plain form of a GLB: a compact one decoded and written again with
/// `f32` attributes and `u32` indices at the same translation, its texture
/// as it is; any other GLB unchanged. Deterministic: the plain form of one
/// compact file is always the same bytes. An error says what of the file
/// could not be read.
pub fn plain(glb: &[u8]) -> Result<Cow<'_, [u8]>, String> {
    let Some(json) = compact_json(glb) else {
        return Ok(Cow::Borrowed(glb));
    };
    if json.get("skins").is_some() {
        return inflated(glb).map(Cow::Owned);
    }
    let decoded = decode(glb)?.drawn();
    let mesh = unit_normals(&decoded.mesh);
    Ok(Cow::Owned(glb_at(
        &mesh,
        decoded.translation,
        decoded.texture.as_ref(),
        None,
        Encoding::Plain,
    )))
}

/// A GLB whose views are compressed but nothing quantized (a skinned
/// cluster's, [`GlbBuilder::compress_views`]) with every view decompressed
/// into the binary chunk and the extension gone: the same glTF as it was
/// written before compression, but for the views' offsets.
fn inflated(glb: &[u8]) -> Result<Vec<u8>, String> {
    let container = gltf::binary::Glb::from_slice(glb).map_err(|e| format!("not a GLB: {e}"))?;
    let mut json: Value =
        serde_json::from_slice(&container.json).map_err(|e| format!("JSON chunk: {e}"))?;
    let bin: &[u8] = container.bin.as_deref().unwrap_or(&[]);
    let views = json["bufferViews"].as_array().map_or(0, Vec::len);
    let mut out = Vec::new();
    let mut placed = Vec::with_capacity(views);
    {
        let file = File { json: &json, bin };
        for v in 0..views {
            let (bytes, _) = file.view(v)?;
            placed.push((out.len(), bytes.len()));
            out.extend_from_slice(&bytes);
            out.resize(out.len().next_multiple_of(4), 0);
        }
    }
    for (v, (offset, length)) in placed.into_iter().enumerate() {
        let Some(view) = json["bufferViews"][v].as_object_mut() else {
            continue;
        };
        view.insert("buffer".into(), 0.into());
        view.insert("byteLength".into(), length.into());
        // 0 is the default, and unwritten.
        match offset {
            0 => view.remove("byteOffset"),
            at => view.insert("byteOffset".into(), at.into()),
        };
        view.remove("extensions");
    }
    json["buffers"] = serde_json::json!([{ "byteLength": out.len() }]);
    for key in ["extensionsUsed", "extensionsRequired"] {
        if let Some(list) = json[key].as_array_mut() {
            list.retain(|name| name != MESHOPT);
            if list.is_empty() {
                json.as_object_mut().map(|o| o.remove(key));
            }
        }
    }
    let json_bytes = serde_json::to_vec(&json).map_err(|e| e.to_string())?;
    let mut bytes = Vec::with_capacity(json_bytes.len() + out.len() + 40);
    write_container(&mut bytes, &json_bytes, &out).map_err(|e| e.to_string())?;
    Ok(bytes)
}

/// A compact GLB's one mesh in its node's frame (scaled, not translated),
/// the node's translation and the texture.
#[derive(Debug, Clone)]
pub struct Decoded {
    pub mesh: Mesh,
    pub translation: Vec3,
    pub texture: Option<Texture>,
}

impl Decoded {
    /// The mesh as glTF draws it: where the file stores no normals, each
    /// triangle's own, rounded as a stored 8-bit normal reads back, so
    /// that the plain form holds the values it held when the normals were
    /// stored (and compresses as well on the wire). A vertex that
    /// triangles of different normals share (a box's corner, welded when
    /// stored) is copied, with its texture coordinate, once for each
    /// normal after the first.
    pub fn drawn(mut self) -> Self {
        if self.mesh.normals.is_empty() {
            flat_normals(&mut self.mesh, self.texture.as_mut().map(|t| &mut t.uvs));
        }
        self
    }
}

/// Reads the mesh of a GLB as this module writes it: one node with one
/// triangle primitive, views compressed or not, attributes quantized or
/// not. The mesh is as the file stores it, its vertices welded, without
/// normals where the file has none ([`Decoded::drawn`] gives them).
pub fn decode(glb: &[u8]) -> Result<Decoded, String> {
    let container = gltf::binary::Glb::from_slice(glb).map_err(|e| format!("not a GLB: {e}"))?;
    let json: Value =
        serde_json::from_slice(&container.json).map_err(|e| format!("JSON chunk: {e}"))?;
    let bin: &[u8] = container.bin.as_deref().unwrap_or(&[]);
    let file = File { json: &json, bin };
    let Some((index, node)) = json["nodes"]
        .as_array()
        .into_iter()
        .flatten()
        .enumerate()
        .find(|(_, n)| n.get("mesh").is_some())
    else {
        return Ok(Decoded {
            mesh: Mesh::default(),
            translation: Vec3::ZERO,
            texture: None,
        });
    };
    let vec3 = |key: &str, default: f32| -> Result<Vec3, String> {
        match node.get(key) {
            None => Ok(Vec3::splat(default)),
            Some(v) => serde_json::from_value::<[f32; 3]>(v.clone())
                .map(Vec3::from)
                .map_err(|e| format!("nodes[{index}].{key}: {e}")),
        }
    };
    let translation = vec3("translation", 0.0)?;
    let scale = vec3("scale", 1.0)?;
    let m = node["mesh"].as_u64().unwrap_or(0) as usize;
    let primitive = &json["meshes"][m]["primitives"][0];
    let attributes = &primitive["attributes"];
    let attribute = |name: &str| -> Result<Option<(Vec<f32>, usize)>, String> {
        attributes
            .get(name)
            .and_then(Value::as_u64)
            .map(|a| file.accessor(a as usize))
            .transpose()
    };
    let (positions, k) = attribute("POSITION")?.ok_or("the primitive has no POSITION")?;
    let n = positions.len() / k.max(1);
    let mut mesh = Mesh {
        positions: positions
            .chunks_exact(3)
            .map(|p| Vec3::from_slice(p) * scale)
            .collect(),
        ..Mesh::default()
    };
    let normals = attribute("NORMAL")?;
    if let Some((normals, 3)) = &normals {
        mesh.normals = normals.chunks_exact(3).map(Vec3::from_slice).collect();
    }
    match attribute("COLOR_0")? {
        Some((colors, 4)) => {
            mesh.colors = colors
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect();
        }
        Some((colors, 3)) => {
            mesh.colors = colors
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2], 1.0])
                .collect();
        }
        _ => {}
    }
    if let Some((features, 1)) = attribute("_FEATURE_ID_0")? {
        mesh.features = features.iter().map(|&f| f as u32).collect();
    }
    mesh.indices = match primitive.get("indices").and_then(Value::as_u64) {
        Some(a) => file
            .accessor(a as usize)?
            .0
            .into_iter()
            .map(|i| i as u32)
            .collect(),
        None => (0..n as u32).collect(),
    };
    let texture = match attribute("TEXCOORD_0")? {
        Some((uvs, 2)) => file.base_color_png(primitive)?.map(|png| Texture {
            uvs: uvs.chunks_exact(2).map(Vec2::from_slice).collect(),
            png,
        }),
        _ => None,
    };
    for (what, len) in [
        ("NORMAL", mesh.normals.len()),
        ("COLOR_0", mesh.colors.len()),
        ("_FEATURE_ID_0", mesh.features.len()),
    ] {
        if len != 0 && len != n {
            return Err(format!("{what} has {len} elements for {n} vertices"));
        }
    }
    Ok(Decoded {
        mesh,
        translation,
        texture,
    })
}

/// [`Decoded::drawn`]'s normals: `mesh`'s triangles' own, a vertex copied
/// where they differ.
fn flat_normals(mesh: &mut Mesh, mut uvs: Option<&mut Vec<Vec2>>) {
    let n = mesh.positions.len();
    let mut normals: Vec<Option<Vec3>> = vec![None; n];
    let mut copies: rustc_hash::FxHashMap<(u32, [u32; 3]), u32> = Default::default();
    for t in 0..mesh.indices.len() / 3 {
        let corners = [0, 1, 2].map(|k| mesh.indices[3 * t + k]);
        let [a, b, c] = corners.map(|i| mesh.positions[i as usize]);
        // A degenerate triangle has no normal of its own and takes its
        // vertices' as they come.
        let Some(face) = (b - a).cross(c - a).try_normalize() else {
            continue;
        };
        let face = byte_grid(face) / 127.0;
        for (k, i) in corners.into_iter().enumerate() {
            let at = i as usize;
            match normals[at] {
                None => normals[at] = Some(face),
                Some(v) if v == face => {}
                Some(_) => {
                    let copy = *copies
                        .entry((i, face.to_array().map(f32::to_bits)))
                        .or_insert_with(|| {
                            normals.push(Some(face));
                            mesh.positions.push(mesh.positions[at]);
                            if !mesh.colors.is_empty() {
                                mesh.colors.push(mesh.colors[at]);
                            }
                            if !mesh.features.is_empty() {
                                mesh.features.push(mesh.features[at]);
                            }
                            if let Some(uvs) = uvs.as_deref_mut() {
                                uvs.push(uvs[at]);
                            }
                            (normals.len() - 1) as u32
                        });
                    mesh.indices[3 * t + k] = copy;
                }
            }
        }
    }
    mesh.normals = normals
        .into_iter()
        .map(|v| v.unwrap_or(byte_grid(Vec3::Z) / 127.0))
        .collect();
}

/// A GLB's JSON and binary chunk.
struct File<'a> {
    json: &'a Value,
    bin: &'a [u8],
}

impl File<'_> {
    /// The bytes of view `v` as the accessors see them: decompressed when
    /// the view is compressed.
    fn view(&self, v: usize) -> Result<(Cow<'_, [u8]>, Option<usize>), String> {
        let view = &self.json["bufferViews"][v];
        let at =
            |value: &Value, key: &str| value.get(key).and_then(Value::as_u64).unwrap_or(0) as usize;
        let slice = |offset: usize, length: usize| {
            offset
                .checked_add(length)
                .and_then(|end| self.bin.get(offset..end))
                .ok_or_else(|| format!("bufferViews[{v}] runs past the binary chunk"))
        };
        let stride = view
            .get("byteStride")
            .and_then(Value::as_u64)
            .map(|s| s as usize);
        let Some(ext) = view.get("extensions").and_then(|e| e.get(MESHOPT)) else {
            if at(view, "buffer") != 0 {
                return Err(format!("bufferViews[{v}] is not in the binary chunk"));
            }
            return Ok((
                Cow::Borrowed(slice(at(view, "byteOffset"), at(view, "byteLength"))?),
                stride,
            ));
        };
        if at(ext, "buffer") != 0 {
            return Err(format!(
                "bufferViews[{v}]: compressed data not in the binary chunk"
            ));
        }
        let data = slice(at(ext, "byteOffset"), at(ext, "byteLength"))?;
        let count = at(ext, "count");
        let size = at(ext, "byteStride");
        if ext.get("filter").is_some_and(|f| f != "NONE") {
            return Err(format!("bufferViews[{v}]: meshopt filters are not read"));
        }
        let bad = |e: meshopt::Error| format!("bufferViews[{v}]: not meshopt data: {e:?}");
        if count.checked_mul(size) != Some(at(view, "byteLength")) {
            return Err(format!(
                "bufferViews[{v}]: {count} elements of {size} bytes are not its byteLength"
            ));
        }
        let unknown = || {
            format!(
                "bufferViews[{v}]: meshopt mode {} with stride {size} is not read",
                ext["mode"]
            )
        };
        let bytes = match ext["mode"].as_str() {
            Some("ATTRIBUTES") => decode_vertices(data, count, size)
                .ok_or_else(unknown)?
                .map_err(bad)?,
            Some("TRIANGLES") if size == 2 => bytemuck::cast_slice(
                &meshopt::decode_index_buffer::<u16>(data, count).map_err(bad)?,
            )
            .to_vec(),
            Some("TRIANGLES") if size == 4 => bytemuck::cast_slice(
                &meshopt::decode_index_buffer::<u32>(data, count).map_err(bad)?,
            )
            .to_vec(),
            _ => return Err(unknown()),
        };
        Ok((Cow::Owned(bytes), stride))
    }

    /// Accessor `a` as `f32` components (integers normalized when the
    /// accessor says so) and the number of components per element.
    fn accessor(&self, a: usize) -> Result<(Vec<f32>, usize), String> {
        let accessor = &self.json["accessors"][a];
        let field = |key: &str| accessor.get(key).and_then(Value::as_u64);
        let view = field("bufferView").ok_or(format!("accessors[{a}] has no bufferView"))?;
        let (bytes, stride) = self.view(view as usize)?;
        let components = match accessor["type"].as_str() {
            Some("SCALAR") => 1,
            Some("VEC2") => 2,
            Some("VEC3") => 3,
            Some("VEC4") => 4,
            other => return Err(format!("accessors[{a}]: type {other:?} is not read")),
        };
        let normalized = accessor["normalized"].as_bool().unwrap_or(false);
        let kind = field("componentType").unwrap_or(0);
        let size = match kind {
            5120 | 5121 => 1,
            5122 | 5123 => 2,
            5125 | 5126 => 4,
            other => return Err(format!("accessors[{a}]: componentType {other} is not read")),
        };
        let count = field("count").unwrap_or(0) as usize;
        let offset = field("byteOffset").unwrap_or(0) as usize;
        let stride = stride.unwrap_or(components * size);
        let end = count
            .saturating_sub(1)
            .saturating_mul(stride)
            .saturating_add(offset)
            .saturating_add(components * size);
        if count > 0 && end > bytes.len() {
            return Err(format!("accessors[{a}] runs past its view"));
        }
        let mut out = Vec::with_capacity(count * components);
        for i in 0..count {
            for c in 0..components {
                let at = offset + i * stride + c * size;
                let b = &bytes[at..at + size];
                let value = match kind {
                    5120 => norm(f32::from(b[0] as i8), 127.0, normalized),
                    5121 => norm(f32::from(b[0]), 255.0, normalized),
                    5122 => norm(
                        f32::from(i16::from_le_bytes([b[0], b[1]])),
                        SHORT,
                        normalized,
                    ),
                    5123 => norm(
                        f32::from(u16::from_le_bytes([b[0], b[1]])),
                        65535.0,
                        normalized,
                    ),
                    5125 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
                    _ => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
                };
                out.push(value);
            }
        }
        Ok((out, components))
    }

    /// The PNG of the primitive's base colour texture, when its image is
    /// in the binary chunk.
    fn base_color_png(&self, primitive: &Value) -> Result<Option<Vec<u8>>, String> {
        let Some(material) = primitive.get("material").and_then(Value::as_u64) else {
            return Ok(None);
        };
        let info =
            &self.json["materials"][material as usize]["pbrMetallicRoughness"]["baseColorTexture"];
        let Some(texture) = info.get("index").and_then(Value::as_u64) else {
            return Ok(None);
        };
        let source = self.json["textures"][texture as usize]["source"].as_u64();
        let view = source.and_then(|s| self.json["images"][s as usize]["bufferView"].as_u64());
        match view {
            Some(v) => Ok(Some(self.view(v as usize)?.0.into_owned())),
            None => Ok(None),
        }
    }
}

/// A normalized integer's value as glTF defines it (`max(c / max, -1)`).
fn norm(value: f32, max: f32, normalized: bool) -> f32 {
    if normalized {
        (value / max).max(-1.0)
    } else {
        value
    }
}

/// `count` elements of `size` bytes decoded by the vertex codec, `None`
/// for a size this reader does not decode.
fn decode_vertices(data: &[u8], count: usize, size: usize) -> Option<meshopt::Result<Vec<u8>>> {
    let bytes = match size {
        4 => meshopt::decode_vertex_buffer::<[u8; 4]>(data, count).map(|v| v.concat()),
        8 => meshopt::decode_vertex_buffer::<[u8; 8]>(data, count).map(|v| v.concat()),
        12 => meshopt::decode_vertex_buffer::<[u8; 12]>(data, count).map(|v| v.concat()),
        16 => meshopt::decode_vertex_buffer::<[u8; 16]>(data, count).map(|v| v.concat()),
        20 => meshopt::decode_vertex_buffer::<[u8; 20]>(data, count).map(|v| v.concat()),
        24 => meshopt::decode_vertex_buffer::<[u8; 24]>(data, count).map(|v| v.concat()),
        28 => meshopt::decode_vertex_buffer::<[u8; 28]>(data, count).map(|v| v.concat()),
        32 => meshopt::decode_vertex_buffer::<[u8; 32]>(data, count).map(|v| v.concat()),
        _ => return None,
    };
    Some(bytes)
}

//! GLB (binary glTF 2.0) writer, after the Khronos glTF 2.0 specification
//! (<https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html>). The JSON
//! types and the GLB container are the `gltf` crate's; this file lays out
//! the binary buffer and the objects that point into it.
//!
//! Attributes are written as tightly packed little-endian `f32` (positions,
//! normals, RGBA colours) and `u32` indices, copied in bulk from the mesh's
//! own vectors (`bytemuck`), so that writing a scene of millions of triangles
//! costs little more than a memcpy. A mesh written once can be placed by any
//! number of nodes and coloured by any number of materials: its accessors
//! are shared, which is how a scene keeps its instancing in the file.

use std::collections::HashMap;
use std::io::Write;
use std::path::Path;

use glam::{Mat4, Vec3};
use gltf::json::{self, validation::Checked::Valid, validation::USize64};

use crate::error::{Error, Result};
use crate::geometry::Mesh;
use crate::geometry::skin::Skin;
use crate::io::texture::Texture;
use crate::scene::{Joint, ObjectSkin};

// The bulk copies below write the in-memory representation; glTF is
// little-endian.
#[cfg(target_endian = "big")]
compile_error!("the GLB writer copies memory as little-endian bytes");

/// One mesh as a GLB: positions, normals and `COLOR_0` when the mesh has
/// them, its feature ids as `_FEATURE_ID_0` with `EXT_mesh_features` when it
/// has them, and indices; one node and one white, non-metallic,
/// double-sided material (vertex colours tint it). Double-sided because a coarse cluster
/// stands a thin element in by one flat quad (`geometry::reduce_parts`),
/// which must show from both sides, and because BIM triangle soup does not
/// wind its faces consistently. The bytes depend only on the mesh, so they
/// can be hashed for content addressing.
/// Positions are stored relative to the centre of the mesh's bounds, the
/// node's `translation`: at map coordinates (hundreds of kilometres) `f32`
/// positions alone would fall on a grid of centimetres, while offsets from
/// a centre within the mesh keep a small mesh's vertices to well under a
/// millimetre, and a 3D Tiles client composes the translation in `f64`.
/// The mesh should pass [`Mesh::validate`]; an empty mesh gives a GLB with
/// an empty scene.
pub fn mesh_to_glb(mesh: &Mesh) -> Vec<u8> {
    glb_with_features(mesh, None, None, Encoding::Plain)
}

/// How a GLB stores its vertex data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Encoding {
    /// `f32` attributes and `u32` indices: any glTF 2.0 reader.
    Plain,
    /// Quantized attributes (`KHR_mesh_quantization`) compressed by
    /// meshoptimizer's codecs (`EXT_meshopt_compression`); what a tree
    /// stores ([`super::compact`]).
    #[default]
    Compact,
}

/// [`textured_mesh_to_glb`] in the given encoding.
pub fn encoded_mesh_to_glb(mesh: &Mesh, texture: Option<&Texture>, encoding: Encoding) -> Vec<u8> {
    glb_with_features(mesh, texture, None, encoding)
}

/// The compact GLB of `mesh` (with its texture), its positions quantized
/// when that moves none by more than `allowance` (world units), exact
/// otherwise ([`super::compact`]); and the farthest a vertex moved, 0 when
/// exact, which a stored error bound must add.
pub fn compact_mesh_to_glb(
    mesh: &Mesh,
    texture: Option<&Texture>,
    allowance: f32,
) -> (Vec<u8>, f32) {
    let mesh = &*unit_normals(mesh);
    let (local, centre) = centred(mesh);
    glb_within(&local, centre, texture, None, Encoding::Compact, allowance)
}

/// [`mesh_to_glb`] with a colour texture: `TEXCOORD_0` from its
/// coordinates (one per vertex) and its PNG as the material's
/// `baseColorTexture`, which `COLOR_0` multiplies (glTF 2.0, section
/// 3.9.2), sampled linearly and clamped at the edges.
pub fn textured_mesh_to_glb(mesh: &Mesh, texture: Option<&Texture>) -> Vec<u8> {
    glb_with_features(mesh, texture, None, Encoding::Plain)
}

/// The GLB of a skinned `mesh` in its bind pose: `JOINTS_0` and
/// `WEIGHTS_0` from `skin.vertices` (one per vertex of `mesh`), the
/// skin's joints at their world transforms and an animation `name` of
/// those that move ([`GlbBuilder::add_skin`]). Plain `f32` data: its
/// positions are not quantized, as the joints' matrices, not a node's
/// scale, place them.
pub fn skinned_mesh_to_glb(mesh: &Mesh, skin: &ObjectSkin, name: &str) -> Vec<u8> {
    let mesh = &*unit_normals(mesh);
    let mut glb = GlbBuilder::new();
    let accessors = glb.add_mesh(mesh);
    let skinned = glb.with_influences(&accessors, &skin.vertices);
    let material = glb.material([1.0; 4]);
    let primitive = glb.add_primitive(&skinned, Some(material));
    let node = glb.add_node(primitive, &Mat4::IDENTITY, None);
    let (index, skeleton) = glb.add_skin(name, skin, &skin.times());
    glb.set_skin(node, index);
    glb.compress_views();
    glb.finish(vec![node, skeleton])
}

/// [`textured_mesh_to_glb`] with a property table (`EXT_structural_metadata`) whose
/// rows are the mesh's feature ids: feature `i` of the mesh is row `i`, so
/// the ids must run over `0..table.count`.
pub fn mesh_to_glb_with_table(
    mesh: &Mesh,
    texture: Option<&Texture>,
    table: &PropertyTable,
    encoding: Encoding,
) -> Vec<u8> {
    glb_with_features(mesh, texture, Some(table), encoding)
}

fn glb_with_features(
    mesh: &Mesh,
    texture: Option<&Texture>,
    table: Option<&PropertyTable>,
    encoding: Encoding,
) -> Vec<u8> {
    let mesh = &*unit_normals(mesh);
    let (local, centre) = centred(mesh);
    glb_at(&local, centre, texture, table, encoding)
}

/// The GLB of `local`, a mesh placed at `centre` (its node's translation).
pub(crate) fn glb_at(
    local: &Mesh,
    centre: Vec3,
    texture: Option<&Texture>,
    table: Option<&PropertyTable>,
    encoding: Encoding,
) -> Vec<u8> {
    glb_within(local, centre, texture, table, encoding, 0.0).0
}

/// [`glb_at`] whose compact positions may move by up to `allowance`; the
/// farthest one moved.
fn glb_within(
    local: &Mesh,
    centre: Vec3,
    texture: Option<&Texture>,
    table: Option<&PropertyTable>,
    encoding: Encoding,
    allowance: f32,
) -> (Vec<u8>, f32) {
    let mut glb = GlbBuilder::new();
    let mut nodes = Vec::new();
    let mut features = None;
    let mut moved = 0.0;
    if !local.is_empty() {
        let (mut accessors, scale) = match encoding {
            Encoding::Plain => (glb.add_mesh(local), 1.0),
            Encoding::Compact => {
                let (accessors, scale, m) =
                    glb.add_compact_mesh(local, texture.map(|t| &t.uvs[..]), allowance);
                moved = m;
                (accessors, scale)
            }
        };
        let texture = texture.map(|t| {
            if encoding == Encoding::Plain {
                accessors.uvs = Some(glb.add_uvs(&t.uvs));
            }
            (glb.add_texture(&t.png), t.translucent())
        });
        let material = glb.double_sided_material(texture);
        let m = glb.add_primitive(&accessors, Some(material));
        features = accessors.features.map(|(_, count)| (m.value(), count));
        nodes.push(glb.add_node_at(m, centre, scale));
    }
    let Some((m, count)) = features else {
        return (glb.finish(nodes), moved);
    };
    let metadata = table.map(|t| t.write(&mut glb));
    // EXT_mesh_features and EXT_structural_metadata (3D Tiles 1.1): the
    // gltf crate models neither.
    let bytes = glb.finish_with(nodes, |json| {
        let mut ids = serde_json::json!({ "featureCount": count, "attribute": 0 });
        let mut used = vec![MESH_FEATURES];
        if let Some(metadata) = metadata {
            ids["propertyTable"] = 0.into();
            json["extensions"] = serde_json::json!({ STRUCTURAL_METADATA: metadata });
            used.push(STRUCTURAL_METADATA);
        }
        json["extensionsUsed"] = serde_json::json!(used);
        json["meshes"][m]["primitives"][0]["extensions"] = serde_json::json!({
            MESH_FEATURES: { "featureIds": [ids] }
        });
    });
    (bytes, moved)
}

/// <https://github.com/CesiumGS/glTF/tree/3d-tiles-next/extensions/2.0/Vendor/EXT_structural_metadata>.
const STRUCTURAL_METADATA: &str = "EXT_structural_metadata";

/// One class of features and its values, a column per property, a row per
/// feature: what [`mesh_to_glb_with_table`] writes.
#[derive(Debug, Clone, PartialEq)]
pub struct PropertyTable {
    /// The class's name in the schema (and the schema's id).
    pub class: String,
    pub count: usize,
    pub columns: Vec<(String, Column)>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum Column {
    Strings(Vec<String>),
    U32(Vec<u32>),
    F32(Vec<f32>),
    Bool(Vec<bool>),
}

impl PropertyTable {
    /// Appends the values to the buffer (each view 8-byte aligned, as the
    /// extension asks) and gives the extension's JSON.
    fn write(&self, glb: &mut GlbBuilder) -> serde_json::Value {
        let mut classes = serde_json::Map::new();
        let mut values = serde_json::Map::new();
        for (name, column) in &self.columns {
            let (kind, value) = match column {
                Column::Strings(strings) => {
                    let mut offsets = Vec::with_capacity(strings.len() + 1);
                    let mut bytes = Vec::new();
                    offsets.push(0u32);
                    for s in strings {
                        bytes.extend_from_slice(s.as_bytes());
                        offsets.push(bytes.len() as u32);
                    }
                    let v = glb.raw_view(&bytes);
                    let o = glb.raw_view(bytemuck::cast_slice(&offsets));
                    (
                        serde_json::json!({ "type": "STRING" }),
                        serde_json::json!({ "values": v, "stringOffsets": o, "stringOffsetType": "UINT32" }),
                    )
                }
                Column::U32(v) => (
                    serde_json::json!({ "type": "SCALAR", "componentType": "UINT32" }),
                    serde_json::json!({ "values": glb.raw_view(bytemuck::cast_slice(v)) }),
                ),
                Column::F32(v) => (
                    serde_json::json!({ "type": "SCALAR", "componentType": "FLOAT32" }),
                    serde_json::json!({ "values": glb.raw_view(bytemuck::cast_slice(v)) }),
                ),
                Column::Bool(v) => {
                    // A bitstream, least significant bit first.
                    let mut bits = vec![0u8; v.len().div_ceil(8)];
                    for (i, _) in v.iter().enumerate().filter(|(_, b)| **b) {
                        bits[i / 8] |= 1 << (i % 8);
                    }
                    (
                        serde_json::json!({ "type": "BOOLEAN" }),
                        serde_json::json!({ "values": glb.raw_view(&bits) }),
                    )
                }
            };
            classes.insert(name.clone(), kind);
            values.insert(name.clone(), value);
        }
        serde_json::json!({
            "schema": {
                "id": self.class,
                "classes": { self.class.clone(): { "properties": classes } }
            },
            "propertyTables": [{
                "class": self.class,
                "count": self.count,
                "properties": values
            }]
        })
    }
}

/// <https://github.com/CesiumGS/glTF/tree/3d-tiles-next/extensions/2.0/Vendor/EXT_mesh_features>:
/// per-vertex feature ids in `_FEATURE_ID_0`, `featureCount` the number of
/// distinct ids in the primitive.
const MESH_FEATURES: &str = "EXT_mesh_features";

/// Feature ids are written as `FLOAT`, exact up to this (2^24): glTF has no
/// 32-bit integer vertex attributes, and asks every vertex attribute element
/// to start 4-byte aligned, so a `UNSIGNED_SHORT` would take 4 bytes too.
pub const MAX_FEATURE_ID: u32 = 1 << 24;

/// Writes [`mesh_to_glb`] to `path`, after checking the mesh.
pub fn write_mesh(mesh: &Mesh, path: &Path) -> Result<()> {
    mesh.validate()
        .map_err(|m| Error::invalid(path, "mesh", m.to_string()))?;
    std::fs::write(path, mesh_to_glb(mesh)).map_err(|e| Error::io(path, e))
}

/// A discrete LOD chain as one GLB, after the MSFT_lod extension
/// (<https://github.com/KhronosGroup/glTF/tree/main/extensions/2.0/Vendor/MSFT_lod>):
/// one node per level, the scene's root being the first (most detailed)
/// with `extensions.MSFT_lod.ids` listing the others from finer to coarser
/// and `extras.MSFT_screencoverage` the least screen coverage (0 to 1) at
/// which each level is drawn, one per level. Viewers that do not know the
/// extension draw the root, the full detail. [`write_lod`] checks what
/// this needs: `levels` and `coverage` of the same, non-zero length, and
/// every level a valid mesh with a triangle.
fn lod_to_glb(levels: &[Mesh], coverage: &[f32]) -> Vec<u8> {
    let mut glb = GlbBuilder::new();
    let nodes: Vec<_> = levels
        .iter()
        .map(|mesh| {
            let (local, centre) = centred(mesh);
            let accessors = glb.add_mesh(&local);
            let m = glb.add_primitive(&accessors, None);
            glb.add_node_at(m, centre, 1.0)
        })
        .collect();
    let lower: Vec<usize> = nodes[1..].iter().map(|n| n.value()).collect();
    let root = nodes[0].value();
    glb.finish_with(vec![nodes[0]], |json| {
        if lower.is_empty() {
            return;
        }
        json["extensionsUsed"] = serde_json::json!(["MSFT_lod"]);
        let node = &mut json["nodes"][root];
        node["extensions"] = serde_json::json!({ "MSFT_lod": { "ids": lower } });
        node["extras"] = serde_json::json!({ "MSFT_screencoverage": coverage });
    })
}

/// Writes [`lod_to_glb`] to `path`, after checking each level.
pub fn write_lod(levels: &[Mesh], coverage: &[f32], path: &Path) -> Result<()> {
    if levels.is_empty() || levels.len() != coverage.len() {
        return Err(Error::invalid(
            path,
            "levels",
            format!(
                "{} levels and {} screen coverages: need one coverage per level, at least one level",
                levels.len(),
                coverage.len()
            ),
        ));
    }
    for (i, mesh) in levels.iter().enumerate() {
        mesh.validate()
            .and_then(|()| {
                (!mesh.is_empty())
                    .then_some(())
                    .ok_or_else(|| Error::value("no triangles"))
            })
            .map_err(|m| Error::invalid(path, format!("level {i}"), m.to_string()))?;
    }
    let levels: Vec<Mesh> = levels
        .iter()
        .map(|m| unit_normals(m).into_owned())
        .collect();
    std::fs::write(path, lod_to_glb(&levels, coverage)).map_err(|e| Error::io(path, e))
}

/// The mesh moved so that its bounds' centre is the origin, and that
/// centre. The offsets are taken in `f64`, so the only rounding is that of
/// the small result.
fn centred(mesh: &Mesh) -> (std::borrow::Cow<'_, Mesh>, Vec3) {
    let (lo, hi) = mesh.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let centre = ((lo.as_dvec3() + hi.as_dvec3()) / 2.0).as_vec3();
    if centre == Vec3::ZERO || !centre.is_finite() {
        return (std::borrow::Cow::Borrowed(mesh), Vec3::ZERO);
    }
    let c = centre.as_dvec3();
    let positions = mesh
        .positions
        .iter()
        .map(|p| (p.as_dvec3() - c).as_vec3())
        .collect();
    (
        std::borrow::Cow::Owned(Mesh {
            positions,
            ..mesh.clone()
        }),
        centre,
    )
}

/// glTF requires unit normals, and neither mesh files (horse.ply's are not
/// unit length) nor reductions (a vertex only on degenerate triangles has
/// none) always have them: they are normalised, and a normal of zero
/// length becomes the normal of a triangle at its vertex (+z if none has
/// one).
pub(crate) fn unit_normals(mesh: &Mesh) -> std::borrow::Cow<'_, Mesh> {
    let unit = |n: &Vec3| (n.length() - 1.0).abs() <= 1e-4;
    if mesh.normals.iter().all(unit) {
        return std::borrow::Cow::Borrowed(mesh);
    }
    let mut normals: Vec<Option<Vec3>> = mesh.normals.iter().map(|n| n.try_normalize()).collect();
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
        if let Some(face) = (b - a).cross(c - a).try_normalize() {
            for &i in t {
                normals[i as usize].get_or_insert(face);
            }
        }
    }
    std::borrow::Cow::Owned(Mesh {
        normals: normals.into_iter().map(|n| n.unwrap_or(Vec3::Z)).collect(),
        ..mesh.clone()
    })
}

/// The accessors of one mesh written into the buffer.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MeshAccessors {
    pub(super) positions: json::Index<json::Accessor>,
    pub(super) normals: Option<json::Index<json::Accessor>>,
    pub(super) colors: Option<json::Index<json::Accessor>>,
    /// Texture coordinates, set by the caller that adds a texture.
    pub(super) uvs: Option<json::Index<json::Accessor>>,
    /// The feature ids and how many distinct ones there are.
    pub(super) features: Option<(json::Index<json::Accessor>, usize)>,
    /// `JOINTS_0` and `WEIGHTS_0`, set by the caller that skins the mesh.
    pub(super) influences: Option<[json::Index<json::Accessor>; 2]>,
    pub(super) indices: json::Index<json::Accessor>,
}

/// Builds one GLB: meshes into the binary chunk, then primitives, materials
/// and nodes that refer to them.
pub(crate) struct GlbBuilder {
    pub(super) root: json::Root,
    pub(super) bin: Vec<u8>,
    materials: HashMap<[u32; 4], json::Index<json::Material>>,
    /// The compressed views' `EXT_meshopt_compression` objects, by view.
    pub(super) compressed: Vec<(usize, serde_json::Value)>,
    /// The byte length of the fallback buffer, the views decompressed.
    pub(super) fallback: usize,
    /// Whether an attribute is quantized (`KHR_mesh_quantization`).
    pub(super) quantized: bool,
}

impl GlbBuilder {
    pub(crate) fn new() -> Self {
        let mut root = json::Root::default();
        root.asset.generator = Some(format!("hdlod {}", env!("CARGO_PKG_VERSION")));
        GlbBuilder {
            root,
            bin: Vec::new(),
            materials: HashMap::new(),
            compressed: Vec::new(),
            fallback: 0,
            quantized: false,
        }
    }

    /// Appends the mesh's attributes to the buffer. The mesh must have at
    /// least one triangle (glTF accessors cannot be empty).
    pub(crate) fn add_mesh(&mut self, mesh: &Mesh) -> MeshAccessors {
        let n = mesh.positions.len();
        let (lo, hi) = mesh.positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let positions = self.accessor(
            bytemuck::cast_slice(&mesh.positions),
            n,
            json::accessor::Type::Vec3,
            json::accessor::ComponentType::F32,
            json::buffer::Target::ArrayBuffer,
            Some((lo.to_array().to_vec(), hi.to_array().to_vec())),
        );
        let normals = (!mesh.normals.is_empty()).then(|| {
            self.accessor(
                bytemuck::cast_slice(&mesh.normals),
                n,
                json::accessor::Type::Vec3,
                json::accessor::ComponentType::F32,
                json::buffer::Target::ArrayBuffer,
                None,
            )
        });
        let colors = (!mesh.colors.is_empty()).then(|| {
            self.accessor(
                bytemuck::cast_slice(&mesh.colors),
                n,
                json::accessor::Type::Vec4,
                json::accessor::ComponentType::F32,
                json::buffer::Target::ArrayBuffer,
                None,
            )
        });
        let features = (!mesh.features.is_empty()).then(|| {
            let mut distinct = mesh.features.clone();
            distinct.sort_unstable();
            distinct.dedup();
            let float: Vec<f32> = mesh.features.iter().map(|&f| f as f32).collect();
            let accessor = self.accessor(
                bytemuck::cast_slice(&float),
                n,
                json::accessor::Type::Scalar,
                json::accessor::ComponentType::F32,
                json::buffer::Target::ArrayBuffer,
                None,
            );
            (accessor, distinct.len())
        });
        let indices = self.accessor(
            bytemuck::cast_slice(&mesh.indices),
            mesh.indices.len(),
            json::accessor::Type::Scalar,
            json::accessor::ComponentType::U32,
            json::buffer::Target::ElementArrayBuffer,
            None,
        );
        MeshAccessors {
            positions,
            normals,
            colors,
            uvs: None,
            features,
            influences: None,
            indices,
        }
    }

    /// `accessors` with each vertex's joints (`u16`) and weights (`f32`)
    /// of `skin` appended to the buffer, for a skinned primitive.
    pub(crate) fn with_influences(
        &mut self,
        accessors: &MeshAccessors,
        skin: &Skin,
    ) -> MeshAccessors {
        let n = skin.joints.len();
        let attribute = |glb: &mut Self, bytes: &[u8], component| {
            glb.accessor(
                bytes,
                n,
                json::accessor::Type::Vec4,
                component,
                json::buffer::Target::ArrayBuffer,
                None,
            )
        };
        // Four u16 are 8 bytes: the buffer stays 4-byte aligned.
        let joints = attribute(
            self,
            bytemuck::cast_slice(&skin.joints),
            json::accessor::ComponentType::U16,
        );
        let weights = attribute(
            self,
            bytemuck::cast_slice(&skin.weights),
            json::accessor::ComponentType::F32,
        );
        MeshAccessors {
            influences: Some([joints, weights]),
            ..*accessors
        }
    }

    /// The skin of `skin`'s joints: a skeleton node, which places nothing,
    /// with each joint a child of it at its world transform (glTF asks the
    /// joints of a skin for a common root), and, when a joint moves, an
    /// animation named `name` of the moving joints' keyframes, whose clip
    /// time at `times[k]` is `k`. `times` holds every keyframe's time,
    /// sorted and distinct. Clip times are `f32` in glTF: scene seconds
    /// over months would round to seconds, while whole keyframe indices
    /// stay exact, and linear between two of them is linear between the
    /// keyframes. Returns the skin and the skeleton node, a root of the
    /// scene.
    pub(crate) fn add_skin(
        &mut self,
        name: &str,
        skin: &ObjectSkin,
        times: &[f64],
    ) -> (json::Index<json::Skin>, json::Index<json::Node>) {
        let joints: Vec<json::Index<json::Node>> =
            skin.joints.iter().map(|j| self.add_joint(j)).collect();
        let mut channels = Vec::new();
        let mut samplers = Vec::new();
        // The joints of a skeleton are sampled at the same times, as a
        // rule: one input accessor for all of them.
        let mut inputs: Vec<(Vec<f32>, json::Index<json::Accessor>)> = Vec::new();
        for (joint, node) in skin.joints.iter().zip(&joints) {
            let Some(motion) = &joint.motion else {
                continue;
            };
            let keys = motion.keyframes();
            let clip_times: Vec<f32> = keys
                .iter()
                .map(|k| times.partition_point(|&t| t < k.t) as f32)
                .collect();
            let (first, last) = (clip_times[0], clip_times[clip_times.len() - 1]);
            let input = match inputs.iter().find(|(t, _)| *t == clip_times) {
                Some(&(_, input)) => input,
                None => {
                    let input = self.data_accessor(
                        bytemuck::cast_slice(&clip_times),
                        keys.len(),
                        json::accessor::Type::Scalar,
                        Some((vec![first], vec![last])),
                    );
                    inputs.push((clip_times, input));
                    input
                }
            };
            let translations: Vec<Vec3> = keys.iter().map(|k| k.translation).collect();
            let rotations: Vec<glam::Quat> = keys
                .iter()
                .map(|k| crate::scene::unit(k.rotation))
                .collect();
            let scales: Vec<Vec3> = keys.iter().map(|k| k.scale).collect();
            use json::accessor::Type::{Vec3 as V3, Vec4 as V4};
            use json::animation::Property;
            for (bytes, kind, path) in [
                (
                    bytemuck::cast_slice(&translations),
                    V3,
                    Property::Translation,
                ),
                (bytemuck::cast_slice(&rotations), V4, Property::Rotation),
                (bytemuck::cast_slice(&scales), V3, Property::Scale),
            ] {
                let output = self.data_accessor(bytes, keys.len(), kind, None);
                channels.push(json::animation::Channel {
                    sampler: json::Index::new(samplers.len() as u32),
                    target: json::animation::Target {
                        extensions: None,
                        extras: None,
                        node: *node,
                        path: Valid(path),
                    },
                    extensions: None,
                    extras: None,
                });
                samplers.push(json::animation::Sampler {
                    extensions: None,
                    extras: None,
                    input,
                    interpolation: Valid(json::animation::Interpolation::Linear),
                    output,
                });
            }
        }
        if !channels.is_empty() {
            self.root.push(json::Animation {
                extensions: None,
                extras: None,
                channels,
                name: Some(name.to_owned()),
                samplers,
            });
        }
        let skeleton = self.root.push(json::Node {
            children: Some(joints.clone()),
            ..Default::default()
        });
        let inverse_bind = self.data_accessor(
            bytemuck::cast_slice(&skin.inverse_bind),
            skin.inverse_bind.len(),
            json::accessor::Type::Mat4,
            None,
        );
        let index = self.root.push(json::Skin {
            extensions: None,
            extras: None,
            inverse_bind_matrices: Some(inverse_bind),
            joints,
            name: None,
            skeleton: Some(skeleton),
        });
        (index, skeleton)
    }

    /// A joint's node at its world transform: a matrix when it stays, else
    /// (glTF animates translation, rotation and scale, not a matrix) the
    /// same decomposed.
    fn add_joint(&mut self, joint: &Joint) -> json::Index<json::Node> {
        let m = joint.transform;
        let mut node = json::Node {
            name: joint.name.clone(),
            ..Default::default()
        };
        if joint.motion.is_none() {
            node.matrix = (m != Mat4::IDENTITY).then(|| m.to_cols_array());
        } else {
            let (scale, rotation, translation) = m.to_scale_rotation_translation();
            node.translation = Some(translation.to_array());
            node.rotation = Some(json::scene::UnitQuaternion(rotation.normalize().to_array()));
            node.scale = Some(scale.to_array());
        }
        self.root.push(node)
    }

    /// An `f32` accessor of `count` elements in a view of its own that
    /// no vertex attribute shares: animation keys and inverse bind
    /// matrices (glTF gives such views no target).
    fn data_accessor(
        &mut self,
        bytes: &[u8],
        count: usize,
        kind: json::accessor::Type,
        min_max: Option<(Vec<f32>, Vec<f32>)>,
    ) -> json::Index<json::Accessor> {
        let view = self.push_view(bytes, None);
        let f32 = json::accessor::ComponentType::F32;
        self.accessor_on(view, count, kind, f32, min_max)
    }

    /// Gives `node` the skin `skin`.
    pub(crate) fn set_skin(
        &mut self,
        node: json::Index<json::Node>,
        skin: json::Index<json::Skin>,
    ) {
        self.root.nodes[node.value()].skin = Some(skin);
    }

    /// Appends texture coordinates (one per vertex) to the buffer.
    fn add_uvs(&mut self, uvs: &[glam::Vec2]) -> json::Index<json::Accessor> {
        self.accessor(
            bytemuck::cast_slice(uvs),
            uvs.len(),
            json::accessor::Type::Vec2,
            json::accessor::ComponentType::F32,
            json::buffer::Target::ArrayBuffer,
            None,
        )
    }

    /// A texture of the PNG `png` (its bytes in the buffer), sampled
    /// linearly without mipmaps (a baked texel is about a pixel where the
    /// cluster is drawn) and clamped at the edges.
    fn add_texture(&mut self, png: &[u8]) -> json::Index<json::Texture> {
        let view = self.push_view(png, None);
        // Later attributes start 4-byte aligned again.
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let image = self.root.push(json::Image {
            buffer_view: Some(view),
            mime_type: Some(json::image::MimeType("image/png".into())),
            name: None,
            uri: None,
            extensions: None,
            extras: None,
        });
        let sampler = self.root.push(json::texture::Sampler {
            mag_filter: Some(Valid(json::texture::MagFilter::Linear)),
            // Mipmapped: where a baked texel is under a pixel the texture
            // is averaged, not sampled at one texel (the atlas's gutters
            // keep the first level clean of neighbouring charts).
            min_filter: Some(Valid(json::texture::MinFilter::LinearMipmapLinear)),
            name: None,
            wrap_s: Valid(json::texture::WrappingMode::ClampToEdge),
            wrap_t: Valid(json::texture::WrappingMode::ClampToEdge),
            extensions: None,
            extras: None,
        });
        self.root.push(json::Texture {
            name: None,
            sampler: Some(sampler),
            source: image,
            extensions: None,
            extras: None,
        })
    }

    pub(super) fn accessor(
        &mut self,
        bytes: &[u8],
        count: usize,
        kind: json::accessor::Type,
        component: json::accessor::ComponentType,
        target: json::buffer::Target,
        min_max: Option<(Vec<f32>, Vec<f32>)>,
    ) -> json::Index<json::Accessor> {
        // Every attribute is 4-byte components, so the buffer stays aligned.
        let view = self.push_view(bytes, Some(Valid(target)));
        self.accessor_on(view, count, kind, component, min_max)
    }

    /// An accessor of `count` elements from the start of `view`.
    fn accessor_on(
        &mut self,
        view: json::Index<json::buffer::View>,
        count: usize,
        kind: json::accessor::Type,
        component: json::accessor::ComponentType,
        min_max: Option<(Vec<f32>, Vec<f32>)>,
    ) -> json::Index<json::Accessor> {
        let (min, max) = match min_max {
            Some((lo, hi)) => (Some(json::Value::from(lo)), Some(json::Value::from(hi))),
            None => (None, None),
        };
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: None,
            type_: Valid(kind),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// A glTF mesh of one triangle primitive over the given accessors.
    pub(crate) fn add_primitive(
        &mut self,
        accessors: &MeshAccessors,
        material: Option<json::Index<json::Material>>,
    ) -> json::Index<json::Mesh> {
        let mut attributes = std::collections::BTreeMap::new();
        attributes.insert(Valid(json::mesh::Semantic::Positions), accessors.positions);
        if let Some(a) = accessors.normals {
            attributes.insert(Valid(json::mesh::Semantic::Normals), a);
        }
        if let Some(a) = accessors.colors {
            attributes.insert(Valid(json::mesh::Semantic::Colors(0)), a);
        }
        if let Some(a) = accessors.uvs {
            attributes.insert(Valid(json::mesh::Semantic::TexCoords(0)), a);
        }
        if let Some((a, _)) = accessors.features {
            attributes.insert(
                Valid(json::mesh::Semantic::Extras("FEATURE_ID_0".into())),
                a,
            );
        }
        if let Some([joints, weights]) = accessors.influences {
            attributes.insert(Valid(json::mesh::Semantic::Joints(0)), joints);
            attributes.insert(Valid(json::mesh::Semantic::Weights(0)), weights);
        }
        self.root.push(json::Mesh {
            extensions: None,
            extras: None,
            name: None,
            primitives: vec![json::mesh::Primitive {
                attributes,
                extensions: None,
                extras: None,
                indices: Some(accessors.indices),
                material,
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
            }],
            weights: None,
        })
    }

    /// Appends `bytes` to the buffer where it ends now, as a buffer view.
    pub(super) fn push_view(
        &mut self,
        bytes: &[u8],
        target: Option<json::validation::Checked<json::buffer::Target>>,
    ) -> json::Index<json::buffer::View> {
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target,
            extensions: None,
            extras: None,
        })
    }

    /// A buffer view of raw bytes (no accessor, no target), starting 8-byte
    /// aligned; its index.
    fn raw_view(&mut self, bytes: &[u8]) -> usize {
        // A view has at least one byte: an all-empty string column has one
        // unused one.
        let bytes = if bytes.is_empty() { &[0u8][..] } else { bytes };
        self.bin.resize(self.bin.len().next_multiple_of(8), 0);
        let view = self.push_view(bytes, None);
        // Later attributes start 4-byte aligned again.
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        view.value()
    }

    /// The material of a linear RGBA base colour (components in `[0, 1]`),
    /// one per distinct colour.
    pub(crate) fn material(&mut self, color: [f32; 4]) -> json::Index<json::Material> {
        let key = color.map(f32::to_bits);
        if let Some(&m) = self.materials.get(&key) {
            return m;
        }
        let material = json::Material {
            alpha_mode: Valid(if color[3] < 1.0 {
                json::material::AlphaMode::Blend
            } else {
                json::material::AlphaMode::Opaque
            }),
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor(color),
                metallic_factor: json::material::StrengthFactor(0.0),
                ..Default::default()
            },
            ..Default::default()
        };
        let m = self.root.push(material);
        self.materials.insert(key, m);
        m
    }

    /// A white, non-metallic material seen from both sides, with `texture`
    /// as its base colour when given, blended when the texture is
    /// translucent (its alpha a chart's cover).
    fn double_sided_material(
        &mut self,
        texture: Option<(json::Index<json::Texture>, bool)>,
    ) -> json::Index<json::Material> {
        let blend = texture.is_some_and(|(_, translucent)| translucent);
        let texture = texture.map(|(index, _)| index);
        self.root.push(json::Material {
            alpha_mode: Valid(if blend {
                json::material::AlphaMode::Blend
            } else {
                json::material::AlphaMode::Opaque
            }),
            double_sided: true,
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                metallic_factor: json::material::StrengthFactor(0.0),
                base_color_texture: texture.map(|index| json::texture::Info {
                    index,
                    tex_coord: 0,
                    extensions: None,
                    extras: None,
                }),
                ..Default::default()
            },
            ..Default::default()
        })
    }

    /// A node placing `mesh` by `transform`, with `extras: {"id": id}`.
    pub(crate) fn add_node(
        &mut self,
        mesh: json::Index<json::Mesh>,
        transform: &Mat4,
        id: Option<&str>,
    ) -> json::Index<json::Node> {
        let extras = id.map(|id| {
            let text = serde_json::json!({ "id": id }).to_string();
            serde_json::value::RawValue::from_string(text).expect("serde_json writes valid JSON")
        });
        self.root.push(json::Node {
            mesh: Some(mesh),
            matrix: (*transform != Mat4::IDENTITY).then(|| transform.to_cols_array()),
            extras,
            ..Default::default()
        })
    }

    /// A node placing `mesh` at `translation` (its local origin), none
    /// when that is zero, scaled by `scale` (the quantization's), none when
    /// that is one.
    fn add_node_at(
        &mut self,
        mesh: json::Index<json::Mesh>,
        translation: Vec3,
        scale: f32,
    ) -> json::Index<json::Node> {
        self.root.push(json::Node {
            mesh: Some(mesh),
            translation: (translation != Vec3::ZERO).then(|| translation.to_array()),
            scale: (scale != 1.0).then_some([scale; 3]),
            ..Default::default()
        })
    }

    /// The GLB bytes, with `nodes` as the roots of the one scene, after
    /// `edit` has changed the glTF JSON (for extensions the `gltf` types do
    /// not model).
    pub(crate) fn finish_with(
        mut self,
        nodes: Vec<json::Index<json::Node>>,
        edit: impl FnOnce(&mut serde_json::Value),
    ) -> Vec<u8> {
        self.close(nodes);
        let mut value = serde_json::to_value(&self.root).expect("glTF JSON serialises");
        edit(&mut value);
        super::compact::declare(&mut value, &self.compressed, self.fallback, self.quantized);
        let json_bytes = serde_json::to_vec(&value).expect("JSON serialises");
        let mut out = Vec::with_capacity(json_bytes.len() + self.bin.len() + 40);
        write_container(&mut out, &json_bytes, &self.bin).expect("writing to a Vec cannot fail");
        out
    }

    /// The buffer and the one scene, the last objects of every GLB.
    fn close(&mut self, nodes: Vec<json::Index<json::Node>>) {
        if !self.bin.is_empty() {
            self.root.push(json::Buffer {
                byte_length: USize64::from(self.bin.len()),
                name: None,
                uri: None,
                extensions: None,
                extras: None,
            });
        }
        let scene = self.root.push(json::Scene {
            extensions: None,
            extras: None,
            name: None,
            nodes,
        });
        self.root.scene = Some(scene);
    }

    /// The GLB bytes, with `nodes` as the roots of the one scene.
    pub(crate) fn finish(mut self, nodes: Vec<json::Index<json::Node>>) -> Vec<u8> {
        if !self.compressed.is_empty() {
            return self.finish_with(nodes, |_| {});
        }
        self.close(nodes);
        let json_bytes = json::serialize::to_vec(&self.root).expect("glTF JSON serialises");
        let mut out = Vec::with_capacity(json_bytes.len() + self.bin.len() + 40);
        write_container(&mut out, &json_bytes, &self.bin).expect("writing to a Vec cannot fail");
        out
    }

    /// The byte size of the binary chunk so far.
    pub(crate) fn bin_len(&self) -> usize {
        self.bin.len()
    }
}

pub(super) fn write_container(
    out: &mut impl Write,
    json_bytes: &[u8],
    bin: &[u8],
) -> std::io::Result<()> {
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            // Recomputed by the writer.
            length: 0,
        },
        json: json_bytes.into(),
        bin: (!bin.is_empty()).then_some(bin.into()),
    };
    glb.to_writer(out).map_err(std::io::Error::other)
}

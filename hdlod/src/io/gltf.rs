//! glTF 2.0 / GLB reader on top of the `gltf` crate (Khronos glTF 2.0
//! specification, <https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html>).
//!
//! Every node with a mesh is read with its world transform (the parent
//! chain). The node's mesh becomes one [`Mesh`]: its primitives merged, and
//! when their materials differ, the material colours baked into vertex
//! colours. Meshes are shared by key of the accessors they read (and of the
//! baked colours), not by glTF mesh index: a writer that gives each
//! (mesh, material) pair its own glTF mesh over the same accessors, as ours
//! does, still reads back as one shared mesh.
//!
//! A node with a skin keeps its mesh in its bind pose with each vertex's
//! joints and weights (`JOINTS_0`, `WEIGHTS_0`), and the skin's joints and
//! inverse bind matrices: the scene poses it (`scene::ObjectSkin`).

use std::collections::HashMap;
use std::path::Path;

use glam::{Mat4, Vec3};
use gltf::mesh::Mode;

use crate::error::{Error, Result};
use crate::geometry::Mesh;
use crate::geometry::skin::Skin;
use crate::io::texture::Texture;
use crate::scene::rig::{Channel, Clip, Interpolation, Rig, Trs, Values};
use crate::scene::{Joint, ObjectSkin};

/// The meshes of a glTF file and the nodes that place them.
#[derive(Debug, Clone, Default)]
pub(crate) struct Model {
    pub meshes: Vec<Mesh>,
    /// Each mesh's colour texture, when it has one ([`read_textured_mesh`]).
    pub textures: Vec<Option<Texture>>,
    pub nodes: Vec<ModelNode>,
    /// The node hierarchy and the animations.
    pub rig: Rig,
}

/// A node with a mesh.
#[derive(Debug, Clone)]
pub(crate) struct ModelNode {
    /// Index of the node in the file, for error messages.
    pub index: usize,
    /// `extras.id` if present, else the node name.
    pub id: Option<String>,
    /// Index into [`Model::meshes`].
    pub mesh: usize,
    /// World transform (the parent chain).
    pub transform: Mat4,
    /// The material's base colour (linear RGBA), white when the primitives'
    /// materials differ (their colours are then vertex colours).
    pub color: [f32; 4],
    /// The node's skin, when it has one.
    pub skin: Option<ModelSkin>,
}

/// A skinned node's skin: what the scene keeps, and the joints' nodes,
/// which the clips move.
#[derive(Debug, Clone)]
pub(crate) struct ModelSkin {
    /// The joints' node indices, in the skin's order.
    pub nodes: Vec<usize>,
    /// The joints at rest (no motion yet).
    pub skin: ObjectSkin,
}

/// A glTF skin as the file gives it.
struct FileSkin {
    joints: Vec<usize>,
    names: Vec<Option<String>>,
    inverse_bind: Vec<Mat4>,
}

impl ModelNode {
    /// `node 3 "C-12"` or `node 3`, for error messages.
    pub fn describe(&self) -> String {
        match &self.id {
            Some(id) => format!("node {} {id:?}", self.index),
            None => format!("node {}", self.index),
        }
    }
}

/// Every mesh node of a .gltf/.glb flattened with its world transform into
/// one mesh. Vertex colours are kept when any node has them or the nodes'
/// colours differ (node colours then fill in); normals and feature ids
/// (`_FEATURE_ID_0`) when every node has them.
pub fn read_mesh(path: &Path) -> Result<Mesh> {
    Ok(flatten(&read_model(path)?))
}

/// [`read_mesh`] and, for a file of one mesh node whose primitive has
/// texture coordinates and an embedded PNG as its base colour texture (a
/// tree's cluster GLB with baked colour), that texture, as it is.
pub fn read_textured_mesh(path: &Path) -> Result<(Mesh, Option<Texture>)> {
    let model = read_model(path)?;
    let texture = match &model.nodes[..] {
        [node] => model.textures[node.mesh].clone(),
        _ => None,
    };
    Ok((flatten(&model), texture))
}

/// A tree's skinned cluster GLB (docs/formats.md, "Skinned clusters"):
/// its one mesh node's mesh in the bind pose and each vertex's joints and
/// weights, which must name joints among the skeleton's `joint_count`.
/// The tree says the cluster is skinned (`skins.json`), so a mesh without
/// `JOINTS_0` and `WEIGHTS_0` is an error naming the file and attribute.
pub fn read_skinned_mesh(path: &Path, joint_count: usize) -> Result<(Mesh, Skin)> {
    let model = read_model(path)?;
    let [node] = &model.nodes[..] else {
        return Err(Error::invalid(
            path,
            "nodes",
            format!(
                "{} mesh nodes: a skinned cluster's GLB has one",
                model.nodes.len()
            ),
        ));
    };
    let Some(skin) = &node.skin else {
        return Err(Error::invalid(
            path,
            format!("{} JOINTS_0", node.describe()),
            "the cluster is skinned (skins.json) but its mesh has no skin: no JOINTS_0 and \
             WEIGHTS_0 to pose it by",
        ));
    };
    // The joints place a skinned mesh, not its node (glTF 2.0 section
    // 3.7.3.1): its node's transform is not applied.
    let mesh = model.meshes[node.mesh].clone();
    let vertices = skin.skin.vertices.clone();
    if let Some(problem) = vertices.problem(&mesh, joint_count) {
        return Err(Error::invalid(
            path,
            format!("{} JOINTS_0", node.describe()),
            format!("against the {joint_count} joints of skins.json: {problem}"),
        ));
    }
    Ok((mesh, vertices))
}

fn flatten(model: &Model) -> Mesh {
    let used = |node: &ModelNode| &model.meshes[node.mesh];
    let first_color = model.nodes.first().map(|n| n.color);
    let want_colors = model
        .nodes
        .iter()
        .any(|n| !used(n).colors.is_empty() || Some(n.color) != first_color);
    let want_normals = model.nodes.iter().all(|n| !used(n).normals.is_empty());
    let want_features = model.nodes.iter().all(|n| !used(n).features.is_empty());
    let mut out = Mesh::default();
    for node in &model.nodes {
        let part = used(node).transformed(&node.transform);
        let offset = out.positions.len() as u32;
        if want_colors {
            if part.colors.is_empty() {
                out.colors
                    .extend(std::iter::repeat_n(node.color, part.positions.len()));
            } else {
                out.colors.extend(
                    part.colors
                        .iter()
                        .map(|c| std::array::from_fn(|k| c[k] * node.color[k])),
                );
            }
        }
        if want_normals {
            out.normals.extend_from_slice(&part.normals);
        }
        if want_features {
            out.features.extend_from_slice(&part.features);
        }
        out.positions.extend_from_slice(&part.positions);
        out.indices.extend(part.indices.iter().map(|i| i + offset));
    }
    out
}

/// What makes two glTF meshes the same scene mesh: the accessors each
/// primitive reads, the colours baked into it when the materials differ,
/// and the skin whose joints its `JOINTS_0` names.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
struct MeshKey {
    primitives: Vec<[Option<usize>; 7]>,
    baked_colors: Option<Vec<[u32; 4]>>,
    skin: Option<usize>,
}

pub(crate) fn read_model(path: &Path) -> Result<Model> {
    let bytes = crate::input::read(path)?;
    let invalid =
        |e: gltf::Error| Error::invalid(path, "glTF", format!("not a valid glTF/GLB file: {e}"));
    glb_length_fits(&bytes).map_err(|m| Error::invalid(path, "GLB header", m))?;
    // The compact form (a tree's cluster GLBs) is read as its plain form:
    // the gltf crate decodes neither of its extensions.
    let bytes = match crate::io::compact::plain(&bytes) {
        Ok(std::borrow::Cow::Owned(plain)) => plain,
        Ok(std::borrow::Cow::Borrowed(_)) => bytes,
        Err(m) => return Err(Error::invalid(path, "EXT_meshopt_compression", m)),
    };
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(&bytes).map_err(invalid)?;
    drop(bytes);
    positions_exist(document.as_json()).map_err(|(at, m)| Error::invalid(path, at, m))?;
    let document = gltf::Document::from_json(document.into_json()).map_err(invalid)?;
    check_buffer_uris(path, &document)?;
    let buffers = gltf::import_buffers(&document, path.parent(), blob)
        .map_err(|e| Error::invalid(path, "buffers", e.to_string()))?;
    let rig = read_rig(&document, &buffers).map_err(|(at, m)| Error::invalid(path, at, m))?;
    let worlds = world_transforms(&rig).map_err(|(at, m)| Error::invalid(path, at, m))?;
    let skins = read_skins(&document, &buffers).map_err(|(at, m)| Error::invalid(path, at, m))?;

    let mut model = Model {
        rig,
        ..Model::default()
    };
    let mut shared: HashMap<MeshKey, usize> = HashMap::new();
    // Each mesh's joints and weights, when a skinned node reads it.
    let mut influences: Vec<Option<Skin>> = Vec::new();
    for node in document.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let id = node_id(&node)
            .map_err(|m| Error::invalid(path, format!("node {}", node.index()), m))?;
        let mut placed = ModelNode {
            index: node.index(),
            id,
            mesh: 0,
            transform: worlds[node.index()],
            color: [1.0; 4],
            skin: None,
        };
        let at = |m: &gltf::Mesh| {
            let name = m.name().map(|n| format!(" {n:?}")).unwrap_or_default();
            format!("{} mesh {}{name}", placed.describe(), m.index())
        };
        let skin = node.skin().map(|s| (s.index(), &skins[s.index()]));
        let key = mesh_key(&mesh, skin.map(|(k, _)| k))
            .map_err(|m| Error::invalid(path, at(&mesh), m))?;
        placed.mesh = match shared.get(&key) {
            Some(&found) => found,
            None => {
                let joints = skin.map(|(k, s)| (k, s.joints.len()));
                let (m, vertices) = read_node_mesh(&mesh, &buffers, joints)
                    .map_err(|m| Error::invalid(path, at(&mesh), m))?;
                let texture = read_texture(&mesh, &buffers, m.positions.len())
                    .map_err(|m| Error::invalid(path, at(&mesh), m))?;
                model.meshes.push(m);
                model.textures.push(texture);
                influences.push(vertices);
                shared.insert(key.clone(), model.meshes.len() - 1);
                model.meshes.len() - 1
            }
        };
        if let Some((_, s)) = skin {
            let joints = s
                .joints
                .iter()
                .zip(&s.names)
                .map(|(&n, name)| Joint {
                    name: name.clone(),
                    transform: worlds[n],
                    motion: None,
                })
                .collect();
            placed.skin = Some(ModelSkin {
                nodes: s.joints.clone(),
                skin: ObjectSkin {
                    vertices: influences[placed.mesh]
                        .clone()
                        .expect("a skin's key reads its influences"),
                    inverse_bind: s.inverse_bind.clone(),
                    joints,
                },
            });
        }
        // Instances share the mesh but each has its own material.
        if key.baked_colors.is_none() {
            placed.color = mesh
                .primitives()
                .next()
                .map_or([1.0; 4], |p| base_color(&p));
        }
        model.nodes.push(placed);
    }
    Ok(model)
}

/// A GLB's declared length covers at least its 12-byte header: gltf 1.4
/// subtracts the header from it unchecked (an overflow the `mesh` fuzz
/// target found).
fn glb_length_fits(bytes: &[u8]) -> std::result::Result<(), String> {
    if let Some(length) = bytes
        .strip_prefix(b"glTF")
        .and_then(|rest| rest.get(4..8))
        .map(|l| u32::from_le_bytes(l.try_into().expect("4 bytes")))
        && length < 12
    {
        return Err(format!("length {length} is shorter than the header"));
    }
    Ok(())
}

/// Every primitive's `POSITION` names an existing accessor. gltf-json 1.4
/// validates a primitive by indexing its position accessor before it
/// checks the index, so a file naming a missing one would panic there
/// (found by the `mesh` fuzz target, docs/fuzzing.md).
fn positions_exist(json: &gltf::json::Root) -> std::result::Result<(), (String, String)> {
    use gltf::json::validation::Checked;
    let position = Checked::Valid(gltf::json::mesh::Semantic::Positions);
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(index) = primitive.attributes.get(&position)
                && index.value() >= json.accessors.len()
            {
                return Err((
                    format!("meshes[{m}].primitives[{p}].attributes.POSITION"),
                    format!(
                        "accessor {} does not exist ({} accessors)",
                        index.value(),
                        json.accessors.len()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// A `.gltf` file's external buffers obey the rules of every input
/// (`crate::input`): inside the file's directory, regular files within the
/// cap. `gltf::import_buffers` would read any path or `file:` URI whole.
fn check_buffer_uris(path: &Path, document: &gltf::Document) -> Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    for buffer in document.buffers() {
        let gltf::buffer::Source::Uri(uri) = buffer.source() else {
            continue;
        };
        if uri.starts_with("data:") {
            continue;
        }
        let at = format!("buffers[{}]", buffer.index());
        if uri.contains(':') {
            return Err(Error::invalid(
                path,
                at,
                format!(
                    "{}: only relative paths and data URIs are read",
                    crate::input::quote(uri)
                ),
            ));
        }
        // The path as `gltf::import_buffers` will read it: percent-decoded.
        let file = crate::input::inside(dir, &percent_decoded(uri))
            .map_err(|m| Error::invalid(path, &at, m))?;
        crate::input::open(&file)?;
    }
    Ok(())
}

/// `%XX` escapes decoded (an invalid one kept as it is).
fn percent_decoded(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = bytes
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok())
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (bytes[i], hex) {
            (b'%', Some(b)) => {
                out.push(b);
                i += 3;
            }
            (b, _) => {
                out.push(b);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The node's id: `extras.id` (a string) if present, else its name.
fn node_id(node: &gltf::Node) -> Result<Option<String>, String> {
    if let Some(raw) = node.extras() {
        let extras: serde_json::Value =
            serde_json::from_str(raw.get()).map_err(|e| format!("extras: {e}"))?;
        match extras.get("id") {
            Some(serde_json::Value::String(id)) => return Ok(Some(id.clone())),
            Some(other) => return Err(format!("extras.id must be a string, not {other}")),
            None => {}
        }
    }
    Ok(node.name().map(str::to_owned))
}

/// The node hierarchy (a node with two parents is an error; a cycle is
/// found by [`world_transforms`]) and the animations: each channel's keys
/// and values, checked against each other. Morph-target weights are not
/// animated here (the scene has no morph targets) and are left out.
fn read_rig(
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
) -> Result<Rig, (String, String)> {
    let n = document.nodes().len();
    let mut rig = Rig {
        parent: vec![None; n],
        ..Rig::default()
    };
    for node in document.nodes() {
        for child in node.children() {
            if let Some(other) = rig.parent[child.index()].replace(node.index()) {
                return Err((
                    format!("node {}", child.index()),
                    format!("is a child of both node {other} and node {}", node.index()),
                ));
            }
        }
        rig.rest
            .push(Mat4::from_cols_array_2d(&node.transform().matrix()));
        let (t, r, s) = node.transform().decomposed();
        rig.rest_trs.push(Trs {
            translation: Vec3::from(t),
            rotation: glam::Quat::from_array(r),
            scale: Vec3::from(s),
        });
    }
    for animation in document.animations() {
        let mut clip = Clip {
            name: animation.name().map(str::to_owned),
            channels: Vec::new(),
        };
        for channel in animation.channels() {
            let at = format!(
                "animations[{}].channels[{}]",
                animation.index(),
                channel.index()
            );
            let reader = channel.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
            let times: Vec<f64> = reader
                .read_inputs()
                .ok_or_else(|| (at.clone(), "its sampler's input cannot be read".to_owned()))?
                .map(f64::from)
                .collect();
            if times.is_empty() {
                return Err((at, "its sampler has no keys".into()));
            }
            if !times.iter().all(|t| t.is_finite()) {
                return Err((at, "a key time is not finite".into()));
            }
            if let Some(k) = (1..times.len()).find(|&k| times[k] <= times[k - 1]) {
                return Err((
                    at,
                    format!(
                        "key {k} at {} s is not after key {} at {} s",
                        times[k],
                        k - 1,
                        times[k - 1]
                    ),
                ));
            }
            let interpolation = match channel.sampler().interpolation() {
                gltf::animation::Interpolation::Linear => Interpolation::Linear,
                gltf::animation::Interpolation::Step => Interpolation::Step,
                gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
            };
            use gltf::animation::util::ReadOutputs;
            let values = match reader.read_outputs() {
                Some(ReadOutputs::Translations(v)) => {
                    Values::Translation(v.map(Vec3::from).collect())
                }
                Some(ReadOutputs::Scales(v)) => Values::Scale(v.map(Vec3::from).collect()),
                Some(ReadOutputs::Rotations(v)) => {
                    Values::Rotation(v.into_f32().map(glam::Quat::from_array).collect())
                }
                Some(ReadOutputs::MorphTargetWeights(_)) => continue,
                None => return Err((at, "its sampler's output cannot be read".into())),
            };
            let (count, finite) = match &values {
                Values::Translation(v) | Values::Scale(v) => {
                    (v.len(), v.iter().all(|x| x.is_finite()))
                }
                Values::Rotation(v) => (v.len(), v.iter().all(|x| x.is_finite())),
            };
            let per_key = if interpolation == Interpolation::CubicSpline {
                3
            } else {
                1
            };
            if count != per_key * times.len() {
                return Err((
                    at,
                    format!(
                        "{count} output values for {} keys (expected {})",
                        times.len(),
                        per_key * times.len()
                    ),
                ));
            }
            if !finite {
                return Err((at, "an output value is not finite".into()));
            }
            if let Values::Rotation(v) = &values
                && v.iter().any(|q| q.length_squared() < 1e-12)
            {
                return Err((at, "a rotation is a zero quaternion".into()));
            }
            clip.channels.push(Channel {
                node: channel.target().node().index(),
                interpolation,
                times,
                values,
            });
        }
        rig.clips.push(clip);
    }
    Ok(rig)
}

/// Each skin's joints (node indices, with their names) and inverse bind
/// matrices (identity without an accessor, glTF's default).
fn read_skins(
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
) -> Result<Vec<FileSkin>, (String, String)> {
    let mut out = Vec::new();
    for skin in document.skins() {
        let at = format!("skins[{}]", skin.index());
        let (joints, names): (Vec<usize>, Vec<Option<String>>) = skin
            .joints()
            .map(|n| (n.index(), n.name().map(str::to_owned)))
            .unzip();
        if joints.is_empty() {
            return Err((at, "has no joints".into()));
        }
        // JOINTS_0 is at most UNSIGNED_SHORT.
        if joints.len() > usize::from(u16::MAX) + 1 {
            return Err((
                at,
                format!("has {} joints; JOINTS_0 names at most 65536", joints.len()),
            ));
        }
        let inverse_bind = match skin.inverse_bind_matrices() {
            None => vec![Mat4::IDENTITY; joints.len()],
            Some(acc) => {
                let index = acc.index();
                check_accessor(
                    &acc,
                    "inverseBindMatrices",
                    &[gltf::accessor::Dimensions::Mat4],
                    true,
                )
                .map_err(|m| (at.clone(), m))?;
                let matrices: Vec<Mat4> = skin
                    .reader(|b| buffers.get(b.index()).map(|d| &d.0[..]))
                    .read_inverse_bind_matrices()
                    .ok_or_else(|| {
                        (
                            at.clone(),
                            format!("inverseBindMatrices accessor {index} lies outside its buffer"),
                        )
                    })?
                    .map(|m| Mat4::from_cols_array_2d(&m))
                    .collect();
                if matrices.len() != joints.len() {
                    return Err((
                        at,
                        format!(
                            "{} inverse bind matrices for {} joints",
                            matrices.len(),
                            joints.len()
                        ),
                    ));
                }
                if let Some(k) = matrices.iter().position(|m| !m.is_finite()) {
                    return Err((at, format!("inverse bind matrix {k} is not finite")));
                }
                matrices
            }
        };
        out.push(FileSkin {
            joints,
            names,
            inverse_bind,
        });
    }
    Ok(out)
}

/// World transform of every node at rest: its local transform after its
/// parents'; an error where the parent chain is a cycle.
fn world_transforms(rig: &Rig) -> Result<Vec<Mat4>, (String, String)> {
    let (parent, local) = (&rig.parent, &rig.rest);
    let n = parent.len();
    let mut world: Vec<Option<Mat4>> = vec![None; n];
    for start in 0..n {
        // Walk up to the first node whose world transform is known; a chain
        // longer than the node count is a cycle.
        let mut chain = vec![start];
        while let Some(p) = parent[*chain.last().expect("not empty")] {
            if world[p].is_some() {
                break;
            }
            if chain.len() > n {
                return Err((
                    format!("node {start}"),
                    "its parent chain is a cycle".into(),
                ));
            }
            chain.push(p);
        }
        for &i in chain.iter().rev() {
            let above = parent[i].and_then(|p| world[p]).unwrap_or(Mat4::IDENTITY);
            world[i] = Some(above * local[i]);
        }
    }
    Ok(world
        .into_iter()
        .map(|m| m.expect("every node visited"))
        .collect())
}

fn base_color(primitive: &gltf::Primitive) -> [f32; 4] {
    primitive
        .material()
        .pbr_metallic_roughness()
        .base_color_factor()
}

fn mesh_key(mesh: &gltf::Mesh, skin: Option<usize>) -> Result<MeshKey, String> {
    let mut primitives = Vec::new();
    for p in mesh.primitives() {
        if p.mode() != Mode::Triangles {
            return Err(format!(
                "primitive {}: mode {:?} is not supported (only TRIANGLES)",
                p.index(),
                p.mode()
            ));
        }
        let attr = |s: gltf::Semantic| p.get(&s).map(|a| a.index());
        primitives.push([
            attr(gltf::Semantic::Positions),
            attr(gltf::Semantic::Normals),
            attr(gltf::Semantic::Colors(0)),
            attr(feature_ids()),
            p.indices().map(|a| a.index()),
            attr(gltf::Semantic::Joints(0)),
            attr(gltf::Semantic::Weights(0)),
        ]);
    }
    let colors: Vec<[f32; 4]> = mesh.primitives().map(|p| base_color(&p)).collect();
    let uniform = colors.windows(2).all(|w| w[0] == w[1]);
    Ok(MeshKey {
        primitives,
        baked_colors: (!uniform).then(|| colors.iter().map(|c| c.map(f32::to_bits)).collect()),
        skin,
    })
}

/// Checks what the `gltf` crate's reader takes on trust: a non-empty
/// accessor of the expected type (it would misread or panic otherwise).
fn check_accessor(
    accessor: &gltf::Accessor,
    what: &str,
    dimensions: &[gltf::accessor::Dimensions],
    float_only: bool,
) -> Result<(), String> {
    if accessor.count() == 0 {
        return Err(format!("{what} accessor {} is empty", accessor.index()));
    }
    if !dimensions.contains(&accessor.dimensions())
        || (float_only && accessor.data_type() != gltf::accessor::DataType::F32)
        || (float_only && accessor.normalized())
    {
        return Err(format!(
            "{what} accessor {} has unsupported type {:?} {:?}",
            accessor.index(),
            accessor.dimensions(),
            accessor.data_type()
        ));
    }
    Ok(())
}

/// The attribute of EXT_mesh_features' first feature id set.
fn feature_ids() -> gltf::Semantic {
    gltf::Semantic::Extras("FEATURE_ID_0".into())
}

/// A `_FEATURE_ID_0` accessor's values: unsigned integers, or whole floats
/// (glTF has no 32-bit integer vertex attributes).
fn read_feature_ids(
    accessor: gltf::Accessor,
    buffers: &[gltf::buffer::Data],
) -> Result<Vec<u32>, String> {
    use gltf::accessor::{DataType, Iter};
    let index = accessor.index();
    let get = |b: gltf::Buffer| buffers.get(b.index()).map(|d| &d.0[..]);
    let outside = || format!("_FEATURE_ID_0 accessor {index} lies outside its buffer");
    let ids: Vec<u32> = match accessor.data_type() {
        DataType::U8 => Iter::<u8>::new(accessor, get)
            .ok_or_else(outside)?
            .map(u32::from)
            .collect(),
        DataType::U16 => Iter::<u16>::new(accessor, get)
            .ok_or_else(outside)?
            .map(u32::from)
            .collect(),
        DataType::F32 => {
            let floats: Vec<f32> = Iter::<f32>::new(accessor, get)
                .ok_or_else(outside)?
                .collect();
            if let Some(f) = floats.iter().find(|f| {
                !(f.fract() == 0.0 && (0.0..=crate::io::glb::MAX_FEATURE_ID as f32).contains(*f))
            }) {
                return Err(format!(
                    "_FEATURE_ID_0 accessor {index} holds {f}, not a feature id"
                ));
            }
            floats.into_iter().map(|f| f as u32).collect()
        }
        other => {
            return Err(format!(
                "_FEATURE_ID_0 accessor {index} has component type {other:?} (UNSIGNED_BYTE, UNSIGNED_SHORT or FLOAT)"
            ));
        }
    };
    Ok(ids)
}

/// The colour texture of a mesh of one primitive with `TEXCOORD_0` (as
/// `FLOAT`) and a base colour texture whose image is a PNG in the buffer;
/// `None` for any other mesh.
fn read_texture(
    mesh: &gltf::Mesh,
    buffers: &[gltf::buffer::Data],
    vertices: usize,
) -> Result<Option<Texture>, String> {
    let mut primitives = mesh.primitives();
    let (Some(p), None) = (primitives.next(), primitives.next()) else {
        return Ok(None);
    };
    let Some(info) = p.material().pbr_metallic_roughness().base_color_texture() else {
        return Ok(None);
    };
    let Some(acc) = p.get(&gltf::Semantic::TexCoords(info.tex_coord())) else {
        return Ok(None);
    };
    let gltf::image::Source::View { view, mime_type } = info.texture().source().source() else {
        return Ok(None);
    };
    if mime_type != "image/png" {
        return Ok(None);
    }
    let at = |m: String| format!("primitive {}: {m}", p.index());
    check_accessor(&acc, "TEXCOORD", &[gltf::accessor::Dimensions::Vec2], true).map_err(at)?;
    let reader = p.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    let uvs: Vec<glam::Vec2> = reader
        .read_tex_coords(info.tex_coord())
        .ok_or_else(|| {
            at(format!(
                "TEXCOORD accessor {} lies outside its buffer",
                acc.index()
            ))
        })?
        .into_f32()
        .map(glam::Vec2::from)
        .collect();
    if uvs.len() != vertices {
        return Err(at("TEXCOORD and POSITION counts differ".into()));
    }
    if let Some(i) = uvs.iter().position(|uv| !uv.is_finite()) {
        return Err(at(format!("texture coordinate {i} is not finite")));
    }
    let png = buffers
        .get(view.buffer().index())
        .and_then(|b| b.0.get(view.offset()..view.offset() + view.length()))
        .ok_or_else(|| {
            at(format!(
                "image buffer view {} lies outside its buffer",
                view.index()
            ))
        })?;
    Ok(Some(Texture {
        uvs,
        png: png.to_vec(),
    }))
}

/// One glTF mesh as one scene mesh, its primitives merged; for a node
/// whose skin (`skin`: its index and joint count) deforms it, each
/// vertex's joints and weights too.
fn read_node_mesh(
    mesh: &gltf::Mesh,
    buffers: &[gltf::buffer::Data],
    skin: Option<(usize, usize)>,
) -> Result<(Mesh, Option<Skin>), String> {
    use gltf::accessor::Dimensions::{Scalar, Vec3 as D3, Vec4 as D4};
    let prims: Vec<gltf::Primitive> = mesh.primitives().collect();
    if prims.is_empty() {
        return Err("has no primitives".into());
    }
    let colors: Vec<[f32; 4]> = prims.iter().map(base_color).collect();
    let uniform = colors.windows(2).all(|w| w[0] == w[1]);
    let has = |s: gltf::Semantic| prims.iter().map(move |p| p.get(&s).is_some());
    let want_colors = !uniform || has(gltf::Semantic::Colors(0)).any(|b| b);
    let want_normals = has(gltf::Semantic::Normals).all(|b| b);
    let want_features = has(feature_ids()).all(|b| b);
    if let Some((k, _)) = skin
        && !has(gltf::Semantic::Joints(0)).any(|b| b)
    {
        return Err(format!(
            "has no JOINTS_0, which the node's skins[{k}] needs"
        ));
    }

    let mut out = Mesh::default();
    let mut influences = Skin {
        joints: Vec::new(),
        weights: Vec::new(),
    };
    for (p, material_color) in prims.iter().zip(&colors) {
        let at = |m: String| format!("primitive {}: {m}", p.index());
        let reader = p.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let unreadable = |what: &str, a: Option<gltf::Accessor>| {
            at(format!(
                "{what} accessor {} lies outside its buffer",
                a.map_or(0, |a| a.index())
            ))
        };
        let positions_acc = p
            .get(&gltf::Semantic::Positions)
            .ok_or_else(|| at("has no POSITION attribute".into()))?;
        check_accessor(&positions_acc, "POSITION", &[D3], true).map_err(at)?;
        let offset = out.positions.len();
        out.positions.extend(
            reader
                .read_positions()
                .ok_or_else(|| unreadable("POSITION", Some(positions_acc.clone())))?
                .map(Vec3::from),
        );
        let count = out.positions.len() - offset;
        if want_normals {
            let acc = p.get(&gltf::Semantic::Normals).expect("checked above");
            check_accessor(&acc, "NORMAL", &[D3], true).map_err(at)?;
            let before = out.normals.len();
            out.normals.extend(
                reader
                    .read_normals()
                    .ok_or_else(|| unreadable("NORMAL", Some(acc)))?
                    .map(Vec3::from),
            );
            if out.normals.len() - before != count {
                return Err(at("NORMAL and POSITION counts differ".into()));
            }
        }
        if want_colors {
            let tint = if uniform { [1.0; 4] } else { *material_color };
            let before = out.colors.len();
            match p.get(&gltf::Semantic::Colors(0)) {
                Some(acc) => {
                    check_accessor(&acc, "COLOR_0", &[D3, D4], false).map_err(at)?;
                    out.colors.extend(
                        reader
                            .read_colors(0)
                            .ok_or_else(|| unreadable("COLOR_0", Some(acc)))?
                            .into_rgba_f32()
                            .map(|c| std::array::from_fn(|k| c[k] * tint[k])),
                    );
                }
                None => out.colors.extend(std::iter::repeat_n(tint, count)),
            }
            if out.colors.len() - before != count {
                return Err(at("COLOR_0 and POSITION counts differ".into()));
            }
        }
        if want_features {
            let acc = p.get(&feature_ids()).expect("checked above");
            check_accessor(&acc, "_FEATURE_ID_0", &[Scalar], false).map_err(at)?;
            let ids = read_feature_ids(acc, buffers).map_err(at)?;
            if ids.len() != count {
                return Err(at("_FEATURE_ID_0 and POSITION counts differ".into()));
            }
            out.features.extend(ids);
        }
        if let Some((_, joint_count)) = skin {
            if p.get(&gltf::Semantic::Joints(0)).is_none() {
                let skinned = prims
                    .iter()
                    .find(|q| q.get(&gltf::Semantic::Joints(0)).is_some())
                    .map_or(0, |q| q.index());
                return Err(at(format!(
                    "has no JOINTS_0 while primitive {skinned} has: a skinned primitive \
                     cannot be merged with an unskinned one"
                )));
            }
            let read = read_influences(p, buffers, count, joint_count).map_err(at)?;
            influences.joints.extend(read.joints);
            influences.weights.extend(read.weights);
        }
        let base = offset as u32;
        match p.indices() {
            Some(acc) => {
                check_accessor(&acc, "indices", &[Scalar], false).map_err(at)?;
                let indices = reader
                    .read_indices()
                    .ok_or_else(|| unreadable("indices", Some(acc)))?
                    .into_u32();
                let before = out.indices.len();
                out.indices.extend(indices.map(|i| i.saturating_add(base)));
                if let Some(i) = out.indices[before..]
                    .iter()
                    .find(|&&i| (i - base) as usize >= count)
                {
                    return Err(at(format!(
                        "index {} is out of range ({count} vertices)",
                        i - base
                    )));
                }
            }
            None => out.indices.extend(base..base + count as u32),
        }
        if !(out.indices.len()).is_multiple_of(3) {
            return Err(at("the indices are not a whole number of triangles".into()));
        }
    }
    out.validate().map_err(|e| e.to_string())?;
    if let Some(i) = out.normals.iter().position(|n| !n.is_finite()) {
        return Err(format!("normal {i} is not finite"));
    }
    if let Some(i) = out
        .colors
        .iter()
        .position(|c| c.iter().any(|x| !x.is_finite()))
    {
        return Err(format!("colour {i} is not finite"));
    }
    Ok((out, skin.map(|_| influences)))
}

/// A skinned primitive's `JOINTS_0` and `WEIGHTS_0` for its `count`
/// vertices: four joints, each one of the skin's `joint_count`, and four
/// weights, scaled to sum to 1 (8- and 16-bit weights rarely sum to 1
/// exactly).
fn read_influences(
    p: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    count: usize,
    joint_count: usize,
) -> Result<Skin, String> {
    use gltf::accessor::{DataType, Dimensions::Vec4};
    let joints_acc = p.get(&gltf::Semantic::Joints(0)).ok_or("has no JOINTS_0")?;
    let weights_acc = p
        .get(&gltf::Semantic::Weights(0))
        .ok_or("has JOINTS_0 but no WEIGHTS_0")?;
    if p.get(&gltf::Semantic::Joints(1)).is_some() || p.get(&gltf::Semantic::Weights(1)).is_some() {
        return Err(
            "has JOINTS_1 or WEIGHTS_1: more than four joints per vertex are not read".into(),
        );
    }
    check_accessor(&joints_acc, "JOINTS_0", &[Vec4], false)?;
    if !matches!(joints_acc.data_type(), DataType::U8 | DataType::U16) || joints_acc.normalized() {
        return Err(format!(
            "JOINTS_0 accessor {} has component type {:?}{} (UNSIGNED_BYTE or UNSIGNED_SHORT)",
            joints_acc.index(),
            joints_acc.data_type(),
            if joints_acc.normalized() {
                ", normalized"
            } else {
                ""
            }
        ));
    }
    check_accessor(&weights_acc, "WEIGHTS_0", &[Vec4], false)?;
    match (weights_acc.data_type(), weights_acc.normalized()) {
        (DataType::F32, false) | (DataType::U8 | DataType::U16, true) => {}
        (other, normalized) => {
            return Err(format!(
                "WEIGHTS_0 accessor {} has component type {other:?}{} (FLOAT, or normalized \
                 UNSIGNED_BYTE or UNSIGNED_SHORT)",
                weights_acc.index(),
                if normalized { ", normalized" } else { "" }
            ));
        }
    }
    let reader = p.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    let outside = |what: &str, a: &gltf::Accessor| {
        format!("{what} accessor {} lies outside its buffer", a.index())
    };
    let joints: Vec<[u16; 4]> = reader
        .read_joints(0)
        .ok_or_else(|| outside("JOINTS_0", &joints_acc))?
        .into_u16()
        .collect();
    let mut weights: Vec<[f32; 4]> = reader
        .read_weights(0)
        .ok_or_else(|| outside("WEIGHTS_0", &weights_acc))?
        .into_f32()
        .collect();
    if joints.len() != count {
        return Err("JOINTS_0 and POSITION counts differ".into());
    }
    if weights.len() != count {
        return Err("WEIGHTS_0 and POSITION counts differ".into());
    }
    for (v, (j, w)) in joints.iter().zip(&mut weights).enumerate() {
        if let Some(&k) = j.iter().find(|&&k| usize::from(k) >= joint_count) {
            return Err(format!(
                "JOINTS_0 names joint {k} at vertex {v}, but the skin has {joint_count} joints"
            ));
        }
        if !w.iter().all(|x| x.is_finite() && *x >= 0.0) {
            return Err(format!(
                "WEIGHTS_0 at vertex {v} are not all finite and >= 0: {w:?}"
            ));
        }
        // In f64, where four f32 cannot overflow, and divided there: the
        // f32 results then sum to 1 within their own rounding, which
        // glTF's check on written weights allows.
        let sum = w.iter().map(|&x| f64::from(x)).sum::<f64>();
        if sum <= 0.0 {
            return Err(format!("WEIGHTS_0 at vertex {v} are all 0"));
        }
        *w = w.map(|x| (f64::from(x) / sum) as f32);
    }
    Ok(Skin { joints, weights })
}

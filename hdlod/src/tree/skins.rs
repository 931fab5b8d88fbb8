//! The skins of a tree's skinned objects (`skins.json`, optional;
//! `schemas/tree-skins.schema.json`): per object, the joints that pose its
//! chain of clusters at any time and their inverse bind matrices. One
//! record per object, named by its id, rather than a copy per cluster of
//! its chain: the chain's levels share it, as they share the object's
//! keyframes, and the object's id survives an update that renumbers the
//! clusters. A tree without the file has no skinned clusters, so older
//! trees load as they did and the cluster table keeps its format.

use std::path::Path;

use glam::Mat4;
use serde::{Deserialize, Serialize};

use super::format::KeyframeRecord;
use super::{ClusterClass, Tree};
use crate::error::{Error, Result};
use crate::scene::{Joint, Keyframe, ObjectSkin, joint_matrices_into};

/// What the cut needs to pose a skinned cluster: the joints' world
/// transforms over time and their inverse bind matrices (glTF 2.0 section
/// 3.7.3). The joints' order is that of `JOINTS_0` in the chain's GLBs.
#[derive(Debug, Clone, PartialEq)]
pub struct Skeleton {
    pub inverse_bind: Vec<Mat4>,
    pub joints: Vec<Joint>,
}

impl Skeleton {
    /// The skeleton of an object's skin.
    pub fn of(skin: &ObjectSkin) -> Skeleton {
        Skeleton {
            inverse_bind: skin.inverse_bind.clone(),
            joints: skin.joints.clone(),
        }
    }

    /// Appends the joint matrices at `t` to `out`: each joint's world
    /// transform after its inverse bind matrix, as
    /// [`ObjectSkin::matrices`] makes them.
    pub fn matrices_into(&self, t: f64, out: &mut Vec<Mat4>) {
        joint_matrices_into(&self.joints, &self.inverse_bind, t, out);
    }
}

/// The skeletons of a tree's skinned objects, by object id.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Skins {
    /// Sorted by object id, one each.
    by_object: Vec<(String, Skeleton)>,
}

impl Skins {
    /// The skins of `skeletons`; a later one of the same object replaces
    /// an earlier.
    pub fn new(skeletons: impl IntoIterator<Item = (String, Skeleton)>) -> Skins {
        let mut by_object: Vec<(String, Skeleton)> = skeletons.into_iter().collect();
        by_object.reverse();
        by_object.sort_by(|a, b| a.0.cmp(&b.0));
        by_object.dedup_by(|a, b| a.0 == b.0);
        Skins { by_object }
    }

    pub fn len(&self) -> usize {
        self.by_object.len()
    }

    pub fn is_empty(&self) -> bool {
        self.by_object.is_empty()
    }

    /// The position of `object`'s skeleton, if it has one.
    pub(crate) fn position(&self, object: &str) -> Option<usize> {
        self.by_object
            .binary_search_by(|(o, _)| o.as_str().cmp(object))
            .ok()
    }

    pub fn get(&self, object: &str) -> Option<&Skeleton> {
        self.position(object).map(|k| &self.by_object[k].1)
    }

    pub(crate) fn at(&self, k: usize) -> &Skeleton {
        &self.by_object[k].1
    }

    pub fn iter(&self) -> impl Iterator<Item = (&str, &Skeleton)> {
        self.by_object.iter().map(|(o, s)| (o.as_str(), s))
    }

    /// An error naming `file` unless every skin is that of the object of a
    /// dynamic leaf of `tree`, has as many inverse bind matrices as
    /// joints, at least one, and finite matrices.
    pub fn validate(&self, tree: &Tree, file: &Path) -> Result<()> {
        let mut leaves = vec![false; self.len()];
        for id in 0..tree.cluster_count() as u32 {
            if tree.class_of(id) == ClusterClass::Dynamic && tree.children_of(id).is_empty() {
                for object in tree.objects_of(id) {
                    if let Some(k) = self.position(object) {
                        leaves[k] = true;
                    }
                }
            }
        }
        for (k, (object, s)) in self.by_object.iter().enumerate() {
            let bad = |field: &str, message: String| {
                Error::invalid(file, format!("skins[{k}].{field}"), message)
            };
            if !leaves[k] {
                return Err(bad(
                    "object",
                    format!("{object:?} is the object of no dynamic leaf cluster"),
                ));
            }
            let n = s.joints.len();
            if n == 0 || n > usize::from(u16::MAX) + 1 {
                return Err(bad("joints", format!("{n} joints (1 to 65536)")));
            }
            if s.inverse_bind.len() != n {
                return Err(bad(
                    "inverse_bind",
                    format!("{} matrices for {n} joints", s.inverse_bind.len()),
                ));
            }
            if let Some(j) = s.inverse_bind.iter().position(|m| !m.is_finite()) {
                return Err(bad(&format!("inverse_bind[{j}]"), "is not finite".into()));
            }
            if let Some(j) = s.joints.iter().position(|j| !j.transform.is_finite()) {
                return Err(bad(
                    &format!("joints[{j}].transform"),
                    "is not finite".into(),
                ));
            }
        }
        Ok(())
    }

    pub(crate) fn to_record(&self) -> SkinsRecord {
        SkinsRecord {
            skins: self
                .by_object
                .iter()
                .map(|(object, s)| SkinRecord {
                    object: object.clone(),
                    inverse_bind: s.inverse_bind.iter().map(Mat4::to_cols_array).collect(),
                    joints: s
                        .joints
                        .iter()
                        .map(|j| JointRecord {
                            name: j.name.clone(),
                            transform: j.transform.to_cols_array(),
                            motion: j
                                .motion
                                .as_ref()
                                .map(|m| m.keyframes().iter().map(keyframe_record).collect()),
                        })
                        .collect(),
                })
                .collect(),
        }
    }

    /// The skins of a record read from `file`: errors name the record and
    /// field.
    pub(crate) fn from_record(record: SkinsRecord, file: &Path) -> Result<Skins> {
        let mut out = Vec::with_capacity(record.skins.len());
        let mut seen = std::collections::BTreeSet::new();
        for (k, r) in record.skins.into_iter().enumerate() {
            if !seen.insert(r.object.clone()) {
                return Err(Error::invalid(
                    file,
                    format!("skins[{k}].object"),
                    format!("{:?} has a skin already", r.object),
                ));
            }
            let mut joints = Vec::with_capacity(r.joints.len());
            for (j, joint) in r.joints.into_iter().enumerate() {
                let motion = match joint.motion {
                    None => None,
                    Some(keys) => Some(super::motion_of(&keys).map_err(|m| {
                        Error::invalid(file, format!("skins[{k}].joints[{j}].motion"), m)
                    })?),
                };
                joints.push(Joint {
                    name: joint.name,
                    transform: Mat4::from_cols_array(&joint.transform),
                    motion,
                });
            }
            let inverse_bind = r.inverse_bind.iter().map(Mat4::from_cols_array).collect();
            out.push((
                r.object,
                Skeleton {
                    inverse_bind,
                    joints,
                },
            ));
        }
        Ok(Skins::new(out))
    }
}

fn keyframe_record(k: &Keyframe) -> KeyframeRecord {
    KeyframeRecord {
        t: k.t,
        translation: k.translation.to_array(),
        rotation: k.rotation.to_array(),
        scale: k.scale.to_array(),
    }
}

/// `skins.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkinsRecord {
    pub skins: Vec<SkinRecord>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkinRecord {
    /// The skinned object's id: its chain is the dynamic chain whose leaf
    /// names it.
    pub object: String,
    /// Per joint, column-major.
    pub inverse_bind: Vec<[f32; 16]>,
    pub joints: Vec<JointRecord>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointRecord {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// World transform when the joint has no motion, column-major.
    pub transform: [f32; 16],
    /// Keyframed world transform, as a cluster's `motion`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<Vec<KeyframeRecord>>,
}

//! Position `p_s(t) -> 4x4 matrix` of a moving object, stored as keyframes:
//! translation and scale interpolate linearly, rotation by slerp; before the
//! first keyframe and after the last the pose is held (clamped).

use glam::{Mat4, Quat, Vec3};

use crate::error::{Error, Result};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keyframe {
    /// Seconds since the scene's start.
    pub t: f64,
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

impl Keyframe {
    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }
}

/// Keyframes sorted by time, at least one.
#[derive(Debug, Clone, PartialEq)]
pub struct Motion {
    keys: Vec<Keyframe>,
}

impl Motion {
    /// Sorts the keyframes by time. Errors on an empty list, on two
    /// keyframes at the same time and on non-finite values.
    pub fn new(mut keys: Vec<Keyframe>) -> Result<Self> {
        if keys.is_empty() {
            return Err(Error::value("a motion needs at least one keyframe"));
        }
        for (i, k) in keys.iter().enumerate() {
            if !k.t.is_finite()
                || !k.translation.is_finite()
                || !k.rotation.is_finite()
                || !k.scale.is_finite()
            {
                return Err(Error::value(format!("keyframe {i} has a non-finite value")));
            }
            if k.rotation.length_squared() < 1e-12 {
                return Err(Error::value(format!(
                    "keyframe {i} has a zero rotation quaternion"
                )));
            }
        }
        keys.sort_by(|a, b| a.t.total_cmp(&b.t));
        if let Some(w) = keys.windows(2).find(|w| w[0].t == w[1].t) {
            return Err(Error::value(format!("two keyframes at t = {}", w[0].t)));
        }
        for k in &mut keys {
            k.rotation = k.rotation.normalize();
        }
        Ok(Motion { keys })
    }

    pub fn keyframes(&self) -> &[Keyframe] {
        &self.keys
    }

    /// True when the pose changes at some time (more than one distinct pose).
    pub fn moves(&self) -> bool {
        let first = self.keys[0];
        self.keys.iter().any(|k| {
            !k.translation.abs_diff_eq(first.translation, 1e-6)
                || !k.scale.abs_diff_eq(first.scale, 1e-6)
                || k.rotation.dot(first.rotation).abs() < 1.0 - 1e-9
        })
    }

    /// The interpolated keyframe at `t`.
    pub fn sample(&self, t: f64) -> Keyframe {
        let i = self.keys.partition_point(|k| k.t <= t);
        if i == 0 {
            return self.keys[0];
        }
        if i == self.keys.len() {
            return self.keys[i - 1];
        }
        Motion::between(self.keys[i - 1], self.keys[i], t)
    }

    /// The keyframe at `t` between keyframes `a` and `b` (`a.t <= t < b.t`).
    pub(crate) fn between(a: Keyframe, b: Keyframe, t: f64) -> Keyframe {
        let s = ((t - a.t) / (b.t - a.t)) as f32;
        Keyframe {
            t,
            translation: a.translation.lerp(b.translation, s),
            rotation: a.rotation.slerp(b.rotation, s),
            scale: a.scale.lerp(b.scale, s),
        }
    }

    pub fn at(&self, t: f64) -> Mat4 {
        self.sample(t).matrix()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(t: f64, x: f32, angle: f32) -> Keyframe {
        Keyframe {
            t,
            translation: Vec3::new(x, 0.0, 0.0),
            rotation: Quat::from_rotation_z(angle),
            scale: Vec3::ONE,
        }
    }

    #[test]
    fn interpolates_and_clamps() {
        let m = Motion::new(vec![key(10.0, 10.0, 1.0), key(0.0, 0.0, 0.0)]).unwrap();
        assert!(m.moves());
        let mid = m.sample(5.0);
        assert!(mid.translation.abs_diff_eq(Vec3::new(5.0, 0.0, 0.0), 1e-5));
        assert!((mid.rotation.angle_between(Quat::IDENTITY) - 0.5).abs() < 1e-5);
        assert_eq!(m.sample(-1.0).translation.x, 0.0);
        assert_eq!(m.sample(99.0).translation.x, 10.0);
    }

    #[test]
    fn rejects_bad_keyframes() {
        assert!(Motion::new(vec![]).is_err());
        assert!(Motion::new(vec![key(1.0, 0.0, 0.0), key(1.0, 2.0, 0.0)]).is_err());
        assert!(Motion::new(vec![key(f64::NAN, 0.0, 0.0)]).is_err());
        assert!(
            !Motion::new(vec![key(1.0, 3.0, 0.0), key(2.0, 3.0, 0.0)])
                .unwrap()
                .moves()
        );
    }
}

//! Rigid motion of an object: keyframes of translation, rotation and uniform
//! scale, interpolated linearly (slerp for rotation) and held constant before
//! the first and after the last key.

use glam::{Affine3A, Quat, Vec3};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keyframe {
    pub time: f32,
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: f32,
}

impl Keyframe {
    pub fn transform(&self) -> Affine3A {
        Affine3A::from_scale_rotation_translation(
            Vec3::splat(self.scale),
            self.rotation,
            self.translation,
        )
    }
}

/// Keyframes in strictly increasing time; empty means the identity pose.
///
/// Rotation and scale act about `pivot` (object space), so a key list that
/// only turns an object spins it in place even between keys.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Motion {
    keys: Vec<Keyframe>,
    pivot: Vec3,
}

impl Motion {
    /// Keys must be sorted by strictly increasing time (the loader checks).
    pub fn new(keys: Vec<Keyframe>) -> Self {
        Self::with_pivot(keys, Vec3::ZERO)
    }

    pub fn with_pivot(keys: Vec<Keyframe>, pivot: Vec3) -> Self {
        debug_assert!(keys.windows(2).all(|w| w[0].time < w[1].time));
        Self { keys, pivot }
    }

    pub fn keys(&self) -> &[Keyframe] {
        &self.keys
    }

    /// Whether the pose is the same at every time.
    pub fn is_static(&self) -> bool {
        self.keys.windows(2).all(|w| {
            w[0].translation == w[1].translation
                && w[0].rotation == w[1].rotation
                && w[0].scale == w[1].scale
        })
    }

    /// Object-to-world transform at time `t`.
    pub fn pose(&self, t: f32) -> Affine3A {
        let (first, last) = match (self.keys.first(), self.keys.last()) {
            (Some(f), Some(l)) => (f, l),
            _ => return Affine3A::IDENTITY,
        };
        let key = if t <= first.time {
            *first
        } else if t >= last.time {
            *last
        } else {
            let i = self.keys.partition_point(|k| k.time <= t);
            let (a, b) = (&self.keys[i - 1], &self.keys[i]);
            let s = (t - a.time) / (b.time - a.time);
            Keyframe {
                time: t,
                translation: a.translation.lerp(b.translation, s),
                rotation: a.rotation.slerp(b.rotation, s),
                scale: a.scale + (b.scale - a.scale) * s,
            }
        };
        Affine3A::from_translation(self.pivot)
            * key.transform()
            * Affine3A::from_translation(-self.pivot)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(time: f32, x: f32, deg: f32, scale: f32) -> Keyframe {
        Keyframe {
            time,
            translation: Vec3::new(x, 0.0, 0.0),
            rotation: Quat::from_rotation_y(deg.to_radians()),
            scale,
        }
    }

    #[test]
    fn interpolates_and_holds_outside_keys() {
        let m = Motion::new(vec![key(0.0, 0.0, 0.0, 1.0), key(2.0, 10.0, 90.0, 3.0)]);
        let p = m.pose(1.0).transform_point3(Vec3::X);
        // Half way: rotated 45°, scaled 2, moved 5.
        let expect = Vec3::new(
            5.0 + 2.0 * 45f32.to_radians().cos(),
            0.0,
            -2.0 * 45f32.to_radians().sin(),
        );
        assert!((p - expect).length() < 1e-4, "{p} vs {expect}");
        assert_eq!(m.pose(-5.0), m.pose(0.0));
        assert_eq!(m.pose(7.0), m.pose(2.0));
        assert!(!m.is_static());
    }

    #[test]
    fn rotation_about_pivot_keeps_the_pivot_fixed_between_keys() {
        let pivot = Vec3::new(368.5, 0.0, 351.25);
        let m = Motion::with_pivot(
            vec![key(0.0, 0.0, 0.0, 1.0), key(1.0, 0.0, 30.0, 1.0)],
            pivot,
        );
        for t in [0.0, 0.25, 0.5, 1.0] {
            let p = m.pose(t).transform_point3(pivot + Vec3::Y * 100.0);
            assert!(
                (p - (pivot + Vec3::Y * 100.0)).length() < 1e-3,
                "t={t}: {p}"
            );
        }
        let corner = pivot + Vec3::X * 10.0;
        let moved = m.pose(0.5).transform_point3(corner) - pivot;
        let expect = Quat::from_rotation_y(15f32.to_radians()) * (Vec3::X * 10.0);
        assert!((moved - expect).length() < 1e-3, "{moved} vs {expect}");
    }

    #[test]
    fn no_keys_is_identity_and_static() {
        let m = Motion::default();
        assert_eq!(m.pose(3.0), Affine3A::IDENTITY);
        assert!(m.is_static());
    }
}

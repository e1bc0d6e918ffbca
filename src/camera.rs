//! Cameras: pinhole perspective, 180° angular fisheye and a full-sphere
//! equal-area octahedral mapping. Each maps a continuous pixel position to a
//! ray and a world point back to a pixel position, since reprojection of base
//! range images needs the inverse.
//!
//! Pixel coordinates are continuous: pixel `(i, j)` covers `[i, i+1) x [j, j+1)`,
//! `x` grows to the right and `y` grows downwards in the image.
//!
//! A camera may hold only a [`Window`] of its projection's pixels (a
//! partial base image: the rest sees nothing a frame needs). Its `width`
//! and `height` are then the window's, and its pixel coordinates count
//! from the window's corner; the projection itself keeps the full size, so
//! a pixel covers the same directions whether or not the image is cropped.

use anyhow::{ensure, Result};
use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::ray::Ray;

/// How directions around the camera are laid out on the image.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Projection {
    /// Pinhole with a vertical field of view in degrees; square pixels.
    Perspective { vfov_deg: f32 },
    /// 180° hemispherical fisheye, angular (equidistant) like Radiance's
    /// `-vta`: the angle from the view direction grows linearly with the
    /// distance from the image centre; the image circle touches the shorter
    /// image side.
    Fisheye,
    /// Every direction, laid out with the octahedral equal-area mapping
    /// (Clarberg 2008): each pixel covers the same solid angle, with no
    /// crowding at the poles. The view direction maps to the image centre.
    Sphere,
}

impl Projection {
    pub fn name(&self) -> &'static str {
        match self {
            Projection::Perspective { .. } => "perspective",
            Projection::Fisheye => "fisheye",
            Projection::Sphere => "sphere",
        }
    }
}

/// A posed camera with an image size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub position: Vec3,
    /// Orthonormal frame: `forward` is the view direction, `up` the image's
    /// upward direction, `right = forward x up` the image's rightward one.
    pub forward: Vec3,
    pub up: Vec3,
    pub right: Vec3,
    pub projection: Projection,
    /// The image's size: the window's where there is one.
    pub width: u32,
    pub height: u32,
    /// The rectangle of the projection's pixels the image holds; `None`:
    /// all of them.
    pub window: Option<Window>,
}

/// A rectangle of a projection's pixels: the image's pixel `(0, 0)` is the
/// projection's `(x, y)`, and the projection is `full_width` by
/// `full_height` pixels (the image's `width` by `height` lie inside it).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Window {
    pub x: u32,
    pub y: u32,
    pub full_width: u32,
    pub full_height: u32,
}

impl Window {
    /// Checks that a `width` x `height` window at `(x, y)` lies inside a
    /// `full_width` x `full_height` projection and holds a pixel; the
    /// error names which bound fails.
    pub fn check(&self, width: u32, height: u32) -> Result<()> {
        let (x, y, fw, fh) = (self.x, self.y, self.full_width, self.full_height);
        ensure!(
            width > 0 && height > 0,
            "window {width}x{height} at ({x}, {y}) holds no pixel"
        );
        ensure!(
            u64::from(x) + u64::from(width) <= u64::from(fw)
                && u64::from(y) + u64::from(height) <= u64::from(fh),
            "window {width}x{height} at ({x}, {y}) reaches outside the {fw}x{fh} projection"
        );
        Ok(())
    }
}

impl Camera {
    /// A camera at `position` looking towards `target`, `up_hint` giving the
    /// image's upward direction.
    pub fn look_at(
        position: Vec3,
        target: Vec3,
        up_hint: Vec3,
        projection: Projection,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        Self::looking(
            position,
            target - position,
            up_hint,
            projection,
            width,
            height,
        )
    }

    /// A camera at `position` looking along `direction`.
    pub fn looking(
        position: Vec3,
        direction: Vec3,
        up_hint: Vec3,
        projection: Projection,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        ensure!(
            width > 0 && height > 0,
            "image size {width}x{height} has no pixels"
        );
        ensure!(
            position.is_finite(),
            "camera position {position} is not finite"
        );
        let forward = direction.normalize_or_zero();
        ensure!(
            forward != Vec3::ZERO && forward.is_finite(),
            "camera view direction {direction} has no length"
        );
        let right = forward.cross(up_hint).normalize_or_zero();
        ensure!(
            right != Vec3::ZERO && right.is_finite(),
            "camera up vector {up_hint} is parallel to the view direction {forward}"
        );
        let up = right.cross(forward);
        if let Projection::Perspective { vfov_deg } = projection {
            ensure!(
                vfov_deg > 0.0 && vfov_deg < 180.0,
                "perspective field of view {vfov_deg}° must lie strictly between 0° and 180°"
            );
        }
        Ok(Self {
            position,
            forward,
            up,
            right,
            projection,
            width,
            height,
            window: None,
        })
    }

    /// This camera holding only the `width` x `height` pixels of its
    /// projection from `(x, y)` on (in the full projection's pixels);
    /// the whole projection gives a camera without a window.
    pub fn cropped(&self, x: u32, y: u32, width: u32, height: u32) -> Result<Camera> {
        let (fw, fh) = self.full_size();
        let (ox, oy) = self.window.map_or((0, 0), |w| (w.x, w.y));
        let window = Window {
            x: ox + x,
            y: oy + y,
            full_width: fw,
            full_height: fh,
        };
        window.check(width, height)?;
        let whole = (window.x, window.y, width, height) == (0, 0, fw, fh);
        Ok(Camera {
            width,
            height,
            window: (!whole).then_some(window),
            ..*self
        })
    }

    /// The size of the whole projection, window or not.
    pub fn full_size(&self) -> (u32, u32) {
        self.window
            .map_or((self.width, self.height), |w| (w.full_width, w.full_height))
    }

    /// The window's corner in the projection's pixels (`(0, 0)` without one).
    pub fn origin(&self) -> (u32, u32) {
        self.window.map_or((0, 0), |w| (w.x, w.y))
    }

    /// The index of image pixel `(x, y)` among all the projection's pixels,
    /// row by row: what a pixel's random numbers are drawn from, so that
    /// a pixel gets the same samples whether or not its image is cropped.
    pub fn pixel_index(&self, x: u32, y: u32) -> u64 {
        let (ox, oy) = self.origin();
        let fw = u64::from(self.full_size().0);
        (u64::from(y) + u64::from(oy)) * fw + u64::from(x) + u64::from(ox)
    }

    fn local_to_world(&self, local: Vec3) -> Vec3 {
        self.right * local.x + self.up * local.y + self.forward * local.z
    }

    fn world_to_local(&self, world: Vec3) -> Vec3 {
        Vec3::new(
            world.dot(self.right),
            world.dot(self.up),
            world.dot(self.forward),
        )
    }

    /// The ray through continuous pixel position `(x, y)`, with a unit
    /// direction (so hit distances are ray parameters). `None` where the
    /// projection covers no direction (outside a fisheye's image circle).
    pub fn ray(&self, x: f32, y: f32) -> Option<Ray> {
        let (ox, oy) = self.origin();
        if (ox, oy) == (0, 0) {
            return self.full_ray(x, y);
        }
        self.full_ray(x + ox as f32, y + oy as f32)
    }

    /// The ray through the point `(dx, dy)` (each in `[0, 1)`) of pixel
    /// `(x, y)`: the same ray, bit for bit, whether or not the image is
    /// cropped to a window (the offset is added to the whole pixel index,
    /// not to the rounded continuous position).
    pub fn pixel_ray(&self, x: u32, y: u32, dx: f32, dy: f32) -> Option<Ray> {
        let (ox, oy) = self.origin();
        self.full_ray((x + ox) as f32 + dx, (y + oy) as f32 + dy)
    }

    /// [`Camera::ray`] at a position in the whole projection's pixels.
    fn full_ray(&self, x: f32, y: f32) -> Option<Ray> {
        let (w, h) = self.full_size();
        let (w, h) = (w as f32, h as f32);
        let local = match self.projection {
            Projection::Perspective { vfov_deg } => {
                let tan = (vfov_deg.to_radians() * 0.5).tan();
                let sx = (2.0 * x / w - 1.0) * tan * (w / h);
                let sy = (1.0 - 2.0 * y / h) * tan;
                Vec3::new(sx, sy, 1.0).normalize()
            }
            Projection::Fisheye => {
                let s = w.min(h);
                let n = Vec2::new((2.0 * x - w) / s, (h - 2.0 * y) / s);
                let r = n.length();
                if r > 1.0 {
                    return None;
                }
                let theta = r * std::f32::consts::FRAC_PI_2;
                let (sin_t, cos_t) = theta.sin_cos();
                let (cos_p, sin_p) = if r > 0.0 {
                    (n.x / r, n.y / r)
                } else {
                    (1.0, 0.0)
                };
                Vec3::new(sin_t * cos_p, sin_t * sin_p, cos_t)
            }
            Projection::Sphere => {
                let p = Vec2::new(x / w, 1.0 - y / h);
                octahedral_square_to_sphere(p)
            }
        };
        Some(Ray::new(self.position, self.local_to_world(local)))
    }

    /// Continuous pixel position of world point `p`, or `None` where the
    /// projection does not see it (behind a pinhole, outside the fisheye's
    /// hemisphere or the image, or its window).
    pub fn project(&self, p: Vec3) -> Option<Vec2> {
        let d = self.world_to_local(p - self.position);
        let (w, h) = self.full_size();
        let (w, h) = (w as f32, h as f32);
        let px = match self.projection {
            Projection::Perspective { vfov_deg } => {
                if d.z <= 0.0 {
                    return None;
                }
                let tan = (vfov_deg.to_radians() * 0.5).tan();
                let sx = d.x / d.z / (tan * (w / h));
                let sy = d.y / d.z / tan;
                Vec2::new((sx + 1.0) * 0.5 * w, (1.0 - sy) * 0.5 * h)
            }
            Projection::Fisheye => {
                let len = d.length();
                if len == 0.0 {
                    return None;
                }
                let dn = d / len;
                let theta = dn.z.clamp(-1.0, 1.0).acos();
                if theta > std::f32::consts::FRAC_PI_2 {
                    return None;
                }
                let r = theta / std::f32::consts::FRAC_PI_2;
                let rho = Vec2::new(dn.x, dn.y).length();
                let (c, s) = if rho > 0.0 {
                    (dn.x / rho, dn.y / rho)
                } else {
                    (1.0, 0.0)
                };
                let side = w.min(h);
                Vec2::new((r * c * side + w) * 0.5, (h - r * s * side) * 0.5)
            }
            Projection::Sphere => {
                let dn = d.normalize_or_zero();
                if dn == Vec3::ZERO {
                    return None;
                }
                let uv = octahedral_sphere_to_square(dn);
                Vec2::new(uv.x * w, (1.0 - uv.y) * h)
            }
        };
        if self.window.is_none() {
            return (px.x >= 0.0 && px.x <= w && px.y >= 0.0 && px.y <= h).then_some(px);
        }
        let (ox, oy) = self.origin();
        let px = px - Vec2::new(ox as f32, oy as f32);
        let (w, h) = (self.width as f32, self.height as f32);
        (px.x >= 0.0 && px.x <= w && px.y >= 0.0 && px.y <= h).then_some(px)
    }

    /// Solid angle seen by the pixel `(i, j)`, for weighting pixels of
    /// wide-angle images (exact for the sphere mapping, approximate otherwise).
    pub fn pixel_solid_angle(&self, i: u32, j: u32) -> f32 {
        match self.projection {
            Projection::Sphere => {
                let (w, h) = self.full_size();
                4.0 * std::f32::consts::PI / (w as f32 * h as f32)
            }
            _ => {
                let c = |x: f32, y: f32| self.ray(x, y).map(|r| r.dir);
                let (x, y) = (i as f32, j as f32);
                match (
                    c(x + 0.5, y + 0.5),
                    c(x + 1.0, y + 0.5),
                    c(x + 0.5, y + 1.0),
                ) {
                    (Some(d), Some(dx), Some(dy)) => 4.0 * (dx - d).cross(dy - d).length(),
                    _ => 0.0,
                }
            }
        }
    }
}

/// Clarberg's equal-area mapping from the unit square to the unit sphere,
/// with `(0.5, 0.5)` at `+z` and the square's corners at `-z`.
pub fn octahedral_square_to_sphere(p: Vec2) -> Vec3 {
    let u = 2.0 * p.x - 1.0;
    let v = 2.0 * p.y - 1.0;
    let (up, vp) = (u.abs(), v.abs());
    let signed_distance = 1.0 - (up + vp);
    let r = 1.0 - signed_distance.abs();
    let phi = if r == 0.0 { 1.0 } else { (vp - up) / r + 1.0 } * std::f32::consts::FRAC_PI_4;
    let z = (1.0 - r * r).copysign(signed_distance);
    let cos_phi = phi.cos().copysign(u);
    let sin_phi = phi.sin().copysign(v);
    let s = r * (2.0 - r * r).max(0.0).sqrt();
    Vec3::new(cos_phi * s, sin_phi * s, z).normalize()
}

/// Inverse of [`octahedral_square_to_sphere`] for a unit direction.
pub fn octahedral_sphere_to_square(d: Vec3) -> Vec2 {
    let (x, y, z) = (d.x.abs(), d.y.abs(), d.z.abs());
    let r = (1.0 - z).max(0.0).sqrt();
    let a = x.max(y);
    let b = if a == 0.0 { 0.0 } else { x.min(y) / a };
    let mut phi = b.atan() * std::f32::consts::FRAC_2_PI;
    if x < y {
        phi = 1.0 - phi;
    }
    let mut v = phi * r;
    let mut u = r - v;
    if d.z < 0.0 {
        std::mem::swap(&mut u, &mut v);
        u = 1.0 - u;
        v = 1.0 - v;
    }
    let u = u.copysign(d.x);
    let v = v.copysign(d.y);
    Vec2::new(0.5 * (u + 1.0), 0.5 * (v + 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn cam(projection: Projection, w: u32, h: u32) -> Camera {
        Camera::look_at(
            Vec3::new(278.0, 273.0, -800.0),
            Vec3::new(278.0, 273.0, 0.0),
            Vec3::Y,
            projection,
            w,
            h,
        )
        .unwrap()
    }

    fn round_trip(c: &Camera, x: f32, y: f32, tol: f32) {
        let Some(ray) = c.ray(x, y) else { return };
        assert!((ray.dir.length() - 1.0).abs() < 1e-5, "direction not unit");
        let p = ray.at(37.5);
        let back = c
            .project(p)
            .unwrap_or_else(|| panic!("({x}, {y}) -> {p} not projected back"));
        assert!(
            (back - Vec2::new(x, y)).length() < tol,
            "{:?}: ({x}, {y}) -> {back}",
            c.projection
        );
    }

    /// Uniform `f32` in `[lo, hi)` drawn through integers: proptest's own float
    /// range sampler can trip an internal assertion on some seeds.
    fn real(lo: f32, hi: f32) -> impl Strategy<Value = f32> {
        (0u32..1 << 24).prop_map(move |k| lo + (hi - lo) * (k as f32 / (1u32 << 24) as f32))
    }

    proptest! {
        #[test]
        fn perspective_round_trip(x in real(0.0, 640.0), y in real(0.0, 480.0)) {
            round_trip(&cam(Projection::Perspective { vfov_deg: 39.3077 }, 640, 480), x, y, 2e-3);
        }

        #[test]
        fn fisheye_round_trip(x in real(0.0, 512.0), y in real(0.0, 512.0)) {
            round_trip(&cam(Projection::Fisheye, 512, 512), x, y, 2e-2);
        }

        #[test]
        fn sphere_round_trip(x in real(0.0, 256.0), y in real(0.0, 256.0)) {
            round_trip(&cam(Projection::Sphere, 256, 256), x, y, 2e-2);
        }

        #[test]
        fn sphere_covers_every_direction(x in real(-1.0, 1.0), y in real(-1.0, 1.0), z in real(-1.0, 1.0)) {
            let d = Vec3::new(x, y, z);
            prop_assume!(d.length() > 1e-3);
            let d = d.normalize();
            let uv = octahedral_sphere_to_square(d);
            prop_assert!((0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y));
            let back = octahedral_square_to_sphere(uv);
            prop_assert!((back - d).length() < 1e-3, "{d} -> {uv} -> {back}");
        }
    }

    #[test]
    fn cornell_red_wall_is_on_the_left() {
        let c = cam(Projection::Perspective { vfov_deg: 39.3077 }, 256, 256);
        let red = c.project(Vec3::new(550.0, 273.0, 300.0)).unwrap();
        let green = c.project(Vec3::new(5.0, 273.0, 300.0)).unwrap();
        assert!(
            red.x < 128.0 && green.x > 128.0,
            "red at {red}, green at {green}"
        );
        let ceiling = c.project(Vec3::new(278.0, 548.0, 300.0)).unwrap();
        assert!(
            ceiling.y < 128.0,
            "ceiling at {ceiling} is not in the upper half"
        );
    }

    #[test]
    fn perspective_centre_ray_is_forward() {
        let c = cam(Projection::Perspective { vfov_deg: 60.0 }, 100, 50);
        let r = c.ray(50.0, 25.0).unwrap();
        assert!((r.dir - Vec3::Z).length() < 1e-6);
        // The top edge of the image is at half the vertical field of view.
        let top = c.ray(50.0, 0.0).unwrap();
        assert!((top.dir.dot(Vec3::Z).acos().to_degrees() - 30.0).abs() < 1e-3);
    }

    #[test]
    fn fisheye_edge_is_ninety_degrees_and_outside_has_no_ray() {
        let c = cam(Projection::Fisheye, 200, 200);
        let edge = c.ray(200.0, 100.0).unwrap();
        assert!(edge.dir.dot(Vec3::Z).abs() < 1e-5);
        assert!(
            c.ray(1.0, 1.0).is_none(),
            "corner lies outside the image circle"
        );
        assert!(
            c.project(Vec3::new(278.0, 273.0, -900.0)).is_none(),
            "point behind"
        );
    }

    #[test]
    fn sphere_pixels_cover_equal_solid_angle() {
        // Monte Carlo: uniform directions land uniformly over the square.
        let mut counts = [0u32; 16];
        let n = 64_000;
        let mut s = 0x2545F491u32;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32
        };
        for _ in 0..n {
            let z = 1.0 - 2.0 * rnd();
            let phi = 2.0 * std::f32::consts::PI * rnd();
            let r = (1.0 - z * z).max(0.0).sqrt();
            let uv = octahedral_sphere_to_square(Vec3::new(r * phi.cos(), r * phi.sin(), z));
            let i = ((uv.x * 4.0) as usize).min(3) + 4 * ((uv.y * 4.0) as usize).min(3);
            counts[i] += 1;
        }
        let expect = n as f32 / 16.0;
        for c in counts {
            assert!(
                (c as f32 - expect).abs() < 0.05 * expect,
                "cells {counts:?}"
            );
        }
    }

    #[test]
    fn degenerate_cameras_are_rejected() {
        let p = Projection::Perspective { vfov_deg: 40.0 };
        assert!(Camera::look_at(Vec3::ZERO, Vec3::ZERO, Vec3::Y, p, 8, 8).is_err());
        assert!(Camera::look_at(Vec3::ZERO, Vec3::Y, Vec3::Y, p, 8, 8).is_err());
        assert!(Camera::look_at(Vec3::ZERO, Vec3::Z, Vec3::Y, p, 0, 8).is_err());
        let wide = Projection::Perspective { vfov_deg: 180.0 };
        assert!(Camera::look_at(Vec3::ZERO, Vec3::Z, Vec3::Y, wide, 8, 8).is_err());
    }
}

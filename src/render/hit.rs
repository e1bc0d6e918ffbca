//! What every integrator first makes of a ray's hit, written once so that
//! the path tracer and the multipass renderer see the same surface: the
//! world point, the side it is seen from, its material and its lobes.

use glam::{Affine3A, Vec2, Vec3};

use crate::accel::Hit;
use crate::bsdf::{Frame, Lobes};
use crate::ray::Ray;
use crate::scene::{Material, Object, Scene};

pub(super) struct SurfaceHit<'s> {
    pub hit: Hit,
    pub object: &'s Object,
    pub material: &'s Material,
    /// The point in the object's own space.
    pub local: Vec3,
    /// World point, from the triangle's vertices and the barycentrics, not
    /// from `origin + t dir`: its rounding error then scales with the
    /// triangle's coordinates, which `offset_origin` accounts for, instead
    /// of with the ray origin's (a far camera looking at a point near the
    /// world origin would otherwise start shadow rays behind the surface).
    pub p: Vec3,
    /// Geometric normal, by the triangle's winding.
    pub ng: Vec3,
    /// Unit direction back along the ray.
    pub wo: Vec3,
    pub cos_o: f32,
}

impl<'s> SurfaceHit<'s> {
    /// `None` where the hit cannot be shaded (a non-finite point or normal,
    /// or a ray exactly in the surface's plane): the path ends there.
    pub fn new(scene: &'s Scene, poses: &[Affine3A], ray: &Ray, hit: &Hit) -> Option<Self> {
        let object = &scene.objects[hit.object as usize];
        let [a, b, c] = object.mesh.triangles[hit.primitive as usize];
        let pos = &object.mesh.positions;
        let local = pos[a as usize] * (1.0 - hit.u - hit.v)
            + pos[b as usize] * hit.u
            + pos[c as usize] * hit.v;
        let p = poses[hit.object as usize].transform_point3(local);
        let ng = hit.normal;
        let wo = -ray.dir.normalize();
        let cos_o = ng.dot(wo);
        if !(p.is_finite() && ng.is_finite() && cos_o.is_finite()) || cos_o == 0.0 {
            return None;
        }
        Some(Self {
            hit: *hit,
            object,
            material: &scene.materials[object.material],
            local,
            p,
            ng,
            wo,
            cos_o,
        })
    }

    /// Radiance the surface emits towards the ray's origin, if it emits to
    /// that side.
    pub fn emitted(&self) -> Option<Vec3> {
        self.material
            .emission
            .filter(|em| em.two_sided || self.cos_o > 0.0)
            .map(|em| em.radiance)
    }

    /// Whether the ray arrived on the side the winding's normal points to.
    pub fn front(&self) -> bool {
        self.cos_o > 0.0
    }

    /// The shading frame about the normal turned towards the viewer, and
    /// the reflection lobes at the hit (textured where the mesh has
    /// coordinates).
    pub fn lobes(&self) -> (Frame, Lobes) {
        let n = if self.front() { self.ng } else { -self.ng };
        let hit = &self.hit;
        let uv = self.object.mesh.uvs.as_ref().map(|uvs| {
            let [a, b, c] = self.object.mesh.triangles[hit.primitive as usize];
            let w0 = 1.0 - hit.u - hit.v;
            uvs[a as usize] * w0 + uvs[b as usize] * hit.u + uvs[c as usize] * hit.v
        });
        (
            Frame::new(n),
            Lobes::at(&self.material.bsdf, uv.filter(|uv: &Vec2| uv.is_finite())),
        )
    }

    /// The normal in the object's own space by the triangle's winding,
    /// turned towards the viewer as the shading frame's is.
    pub fn local_normal(&self) -> Vec3 {
        let [a, b, c] = self.object.mesh.triangles[self.hit.primitive as usize];
        let pos = &self.object.mesh.positions;
        let (a, b, c) = (pos[a as usize], pos[b as usize], pos[c as usize]);
        let n = (b - a).cross(c - a).normalize_or_zero();
        if self.front() {
            n
        } else {
            -n
        }
    }
}

//! Id-images (the object seen at each pixel) and their fitness (paper §4.1).
//!
//! The paper drew polygons in false colour on graphics hardware; here one
//! batch of primary rays per image goes through the ray engine, so both
//! engines answer the same question and the id of a pixel is the object of
//! the first hit through its centre.

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::RayEngine;
use crate::camera::Camera;
use crate::image::NO_HIT;
use crate::ray::Ray;

/// Rows traced per batch: enough rays for the engines' batch paths to pay,
/// few enough that both cores get work at the small sizes planning uses.
const ROWS_PER_BATCH: usize = 4;

/// Object ids per pixel, row-major, top row first; [`NO_HIT`] where the ray
/// leaves the scene or where the projection has no ray (outside a fisheye's
/// image circle).
#[derive(Clone, Debug, PartialEq)]
pub struct IdImage {
    pub width: u32,
    pub height: u32,
    pub ids: Vec<u32>,
    /// Pixels the projection covers no direction for; they are the same in
    /// every image of one projection and left out of the fitness.
    pub outside: usize,
}

impl IdImage {
    /// Whether any pixel sees one of `objects` (flags indexed by object id).
    pub fn sees_any(&self, objects: &[bool]) -> bool {
        self.ids
            .iter()
            .any(|&id| id != NO_HIT && objects.get(id as usize).copied().unwrap_or(false))
    }
}

/// An orthographic view along a direction, framing a bounding sphere: how
/// the sun, infinitely far, sees the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Parallel {
    /// Direction the rays travel (away from the sun).
    pub direction: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    /// Centre and radius of the sphere the image frames.
    pub center: Vec3,
    pub radius: f32,
    pub size: u32,
}

impl Parallel {
    /// Rays along `direction` over a square of side `2 radius` around
    /// `center`, starting outside the sphere.
    pub fn new(direction: Vec3, center: Vec3, radius: f32, size: u32) -> Self {
        let direction = direction.normalize();
        let (right, up) = direction.any_orthonormal_pair();
        Self {
            direction,
            right,
            up,
            center,
            radius,
            size,
        }
    }

    fn ray(&self, x: f32, y: f32) -> Ray {
        let s = self.size as f32;
        let (u, v) = (2.0 * x / s - 1.0, 1.0 - 2.0 * y / s);
        let origin = self.center + (self.right * u + self.up * v) * self.radius
            - self.direction * (2.0 * self.radius);
        Ray::new(origin, self.direction)
    }
}

/// Anything an id-image can be taken with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum IdView {
    Camera(Camera),
    Parallel(Parallel),
}

impl IdView {
    pub fn size(&self) -> (u32, u32) {
        match self {
            IdView::Camera(c) => (c.width, c.height),
            IdView::Parallel(p) => (p.size, p.size),
        }
    }

    fn ray(&self, x: f32, y: f32) -> Option<Ray> {
        match self {
            IdView::Camera(c) => c.ray(x, y),
            IdView::Parallel(p) => Some(p.ray(x, y)),
        }
    }
}

/// Traces one ray through every pixel centre of `view`.
pub fn render(engine: &dyn RayEngine, view: &IdView) -> IdImage {
    let (width, height) = view.size();
    let w = width as usize;
    let mut ids = vec![NO_HIT; w * height as usize];
    let outside: usize = ids
        .par_chunks_mut(w * ROWS_PER_BATCH)
        .enumerate()
        .map(|(chunk, out)| {
            let first = chunk * ROWS_PER_BATCH * w;
            let mut rays = Vec::with_capacity(out.len());
            let mut slots = Vec::with_capacity(out.len());
            for k in 0..out.len() {
                let (i, j) = ((first + k) % w, (first + k) / w);
                if let Some(r) = view.ray(i as f32 + 0.5, j as f32 + 0.5) {
                    rays.push(r);
                    slots.push(k);
                }
            }
            let mut hits = vec![None; rays.len()];
            engine.intersect_batch(&rays, &mut hits);
            for (k, h) in slots.iter().zip(hits) {
                out[*k] = h.map_or(NO_HIT, |h| h.object);
            }
            out.len() - rays.len()
        })
        .sum();
    IdImage {
        width,
        height,
        ids,
        outside,
    }
}

/// The paper's fitness `f = N / PQ` of images taken with one projection and
/// orientation: the fraction of pixels whose id is the same in all of them.
/// A pixel that sees nothing in every image agrees; pixels the projection
/// does not cover (a fisheye's corners) are not counted at all, so a
/// fisheye's fitness is comparable with a sphere's. One image, or none, is
/// perfectly fit.
///
/// Panics if the images differ in size or coverage: they must come from
/// the same projection for the comparison to mean anything.
pub fn fitness(images: &[&IdImage]) -> f32 {
    let Some((first, rest)) = images.split_first() else {
        return 1.0;
    };
    for im in rest {
        assert!(
            (im.width, im.height, im.outside) == (first.width, first.height, first.outside),
            "fitness of id-images of different projections ({}x{}, {} outside vs {}x{}, {} outside)",
            im.width,
            im.height,
            im.outside,
            first.width,
            first.height,
            first.outside
        );
    }
    let covered = first.ids.len() - first.outside;
    if covered == 0 {
        return 1.0;
    }
    let agree = (0..first.ids.len())
        .filter(|&p| rest.iter().all(|im| im.ids[p] == first.ids[p]))
        .count();
    // Uncovered pixels are NO_HIT in every image and so among `agree`.
    (agree - first.outside) as f32 / covered as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(ids: &[u32], outside: usize) -> IdImage {
        IdImage {
            width: ids.len() as u32,
            height: 1,
            ids: ids.to_vec(),
            outside,
        }
    }

    #[test]
    fn identical_images_are_fit() {
        let a = img(&[0, 1, 2, NO_HIT], 0);
        assert_eq!(fitness(&[&a, &a.clone(), &a.clone()]), 1.0);
        assert_eq!(fitness(&[&a]), 1.0);
        assert_eq!(fitness(&[]), 1.0);
    }

    #[test]
    fn counts_pixels_agreeing_in_every_image() {
        let a = img(&[0, 1, 2, NO_HIT], 0);
        let b = img(&[0, 1, 3, NO_HIT], 0);
        let c = img(&[0, 5, 2, NO_HIT], 0);
        assert_eq!(fitness(&[&a, &b]), 0.75);
        // Pixel 1 and 2 each disagree in one of the three.
        assert_eq!(fitness(&[&a, &b, &c]), 0.5);
        let none = img(&[NO_HIT; 4], 0);
        assert_eq!(fitness(&[&a, &none]), 0.25);
    }

    #[test]
    fn uncovered_pixels_are_not_counted() {
        // Two pixels outside the projection (NO_HIT in both), one of the
        // two covered ones agrees.
        let a = img(&[NO_HIT, 7, 8, NO_HIT], 2);
        let b = img(&[NO_HIT, 7, 9, NO_HIT], 2);
        assert_eq!(fitness(&[&a, &b]), 0.5);
    }

    #[test]
    #[should_panic(expected = "different projections")]
    fn different_sizes_are_refused() {
        fitness(&[&img(&[0, 1], 0), &img(&[0, 1, 2], 0)]);
    }
}

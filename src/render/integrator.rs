//! The path-tracing estimator of one pixel sample: next-event estimation
//! with multiple importance sampling (power heuristic) against BSDF
//! sampling, and Russian roulette.
//!
//! Path length is counted as Mitsuba's `max_depth` counts it: the number of
//! segments from the camera to the emitter. `max_depth = 1` shows emitters
//! seen directly, `2` adds direct lighting, and so on; `None` is unlimited.

use glam::{Affine3A, Vec3};

use super::hit::SurfaceHit;
use super::lights::Lights;
use crate::accel::RayEngine;
use crate::ray::{offset_origin, Ray};
use crate::rng::Pcg32;
use crate::scene::Scene;

/// Segments after which Russian roulette may end a path.
const ROULETTE_AFTER: u32 = 3;
/// Upper bound on the survival probability, so that a path of (nearly)
/// lossless bounces still ends.
const MAX_SURVIVAL: f32 = 0.995;

pub struct Integrator<'a> {
    pub scene: &'a Scene,
    pub engine: &'a dyn RayEngine,
    pub lights: Lights,
    /// Each object's pose at the rendered time.
    pub poses: Vec<Affine3A>,
    /// Longest path in segments (`u32::MAX` for none).
    pub max_depth: u32,
}

/// Power heuristic weight of a strategy with density `a` against one with `b`,
/// written to stay finite for huge densities.
pub(super) fn power_heuristic(a: f32, b: f32) -> f32 {
    if a <= 0.0 || a.is_nan() {
        return 0.0;
    }
    if b <= 0.0 || a.is_infinite() {
        return 1.0;
    }
    let r = b / a;
    1.0 / (1.0 + r * r)
}

impl Integrator<'_> {
    /// Radiance arriving along `ray` (one sample); `rays` counts every ray
    /// traced.
    pub fn radiance(&self, ray: Ray, rng: &mut Pcg32, rays: &mut u64) -> Vec3 {
        self.trace(ray, rng, rays, self.max_depth, false)
    }

    /// Radiance arriving along `ray` except what its first hit emits (or the
    /// sun, where it hits nothing), in at most `max_depth` segments: the
    /// indirect light a diffuse bounce brings to a point whose direct light
    /// was sampled from the lights.
    pub fn radiance_reflected(
        &self,
        ray: Ray,
        rng: &mut Pcg32,
        rays: &mut u64,
        max_depth: u32,
    ) -> Vec3 {
        self.trace(ray, rng, rays, max_depth.min(self.max_depth), true)
    }

    fn trace(
        &self,
        mut ray: Ray,
        rng: &mut Pcg32,
        rays: &mut u64,
        max_depth: u32,
        skip_first_emission: bool,
    ) -> Vec3 {
        let mut l = Vec3::ZERO;
        let mut beta = Vec3::ONE;
        // Density of the direction of `ray` by BSDF sampling; `None` when no
        // other strategy could have produced it (camera ray, delta lobe).
        let mut prev_pdf: Option<f32> = None;
        let mut prev_p = ray.origin;
        let mut segments = 1u32;
        if max_depth == 0 {
            return l;
        }
        loop {
            *rays += 1;
            let emission_counts = !(skip_first_emission && segments == 1);
            let Some(hit) = self.engine.intersect(&ray) else {
                let dir = ray.dir.normalize();
                if let Some((le, pdf_light)) =
                    self.lights.sun_along(dir).filter(|_| emission_counts)
                {
                    let w = prev_pdf.map_or(1.0, |p| power_heuristic(p, pdf_light));
                    l += beta * le * w;
                }
                break;
            };
            let Some(surface) = SurfaceHit::new(self.scene, &self.poses, &ray, &hit) else {
                break;
            };
            let (p, ng) = (surface.p, surface.ng);
            if let Some(le) = surface.emitted().filter(|_| emission_counts) {
                let w = prev_pdf.map_or(1.0, |pb| {
                    let pl = self
                        .lights
                        .triangle_pdf(hit.object, hit.primitive, prev_p, p);
                    power_heuristic(pb, pl)
                });
                l += beta * le * w;
            }
            if segments >= max_depth {
                break;
            }
            let (frame, lobes) = surface.lobes();
            let wo_l = frame.to_local(surface.wo);

            if !lobes.is_delta() && !self.lights.is_empty() {
                let (u, u1, u2) = (rng.next_f64(), rng.next_f32(), rng.next_f32());
                if let Some(ls) = self.lights.sample(p, ng, u, u1, u2) {
                    let wi_l = frame.to_local(ls.wi);
                    let f = lobes.eval(wo_l, wi_l);
                    if wi_l.z > 0.0 && f != Vec3::ZERO {
                        *rays += 1;
                        if !self.engine.occluded(&ls.shadow) {
                            let w = if ls.delta {
                                1.0
                            } else {
                                power_heuristic(ls.pdf, lobes.pdf(wo_l, wi_l))
                            };
                            let c = beta * f * ls.radiance * (wi_l.z * w / ls.pdf);
                            if c.is_finite() {
                                l += c;
                            }
                        }
                    }
                }
            }

            let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
            let Some(s) = lobes.sample(wo_l, u) else {
                break;
            };
            beta *= s.weight;
            if beta == Vec3::ZERO || !beta.is_finite() {
                break;
            }
            let wi = frame.to_world(s.wi);
            prev_pdf = (!s.delta).then_some(s.pdf);
            prev_p = p;
            segments += 1;
            if segments > ROULETTE_AFTER {
                let survive = beta.max_element().min(MAX_SURVIVAL);
                if rng.next_f32() >= survive {
                    break;
                }
                beta /= survive;
            }
            ray = Ray::new(offset_origin(p, ng, wi), wi);
        }
        l
    }
}

#[cfg(test)]
mod tests {
    use super::power_heuristic;

    #[test]
    fn power_heuristic_is_finite_and_complementary() {
        for (a, b) in [(1.0, 1.0), (3.0, 0.5), (1e30, 1e29), (1e-30, 1e-31)] {
            let s = power_heuristic(a, b) + power_heuristic(b, a);
            assert!((s - 1.0).abs() < 1e-6, "{a} {b}: {s}");
        }
        assert_eq!(power_heuristic(f32::INFINITY, 1.0), 1.0);
        assert_eq!(power_heuristic(0.0, 1.0), 0.0);
        assert_eq!(power_heuristic(1.0, 0.0), 1.0);
    }
}

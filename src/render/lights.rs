//! Light sampling for next-event estimation: emissive triangles in world
//! space at one scene time, point lights and the sun, picked in proportion to
//! an estimate of their power (the sun: half of the picks beside other
//! lights), plus the densities that multiple importance sampling needs when
//! a BSDF-sampled ray reaches a light by itself.

use std::f32::consts::PI;

use glam::Vec3;

use crate::ray::{offset_origin, Ray};
use crate::scene::{Light, PointArrival, Scene};

enum Entry {
    Triangle {
        p0: Vec3,
        e1: Vec3,
        e2: Vec3,
        /// Unit winding normal, the emitting side of a one-sided emitter.
        normal: Vec3,
        area: f32,
        radiance: Vec3,
        two_sided: bool,
    },
    Point {
        position: Vec3,
        intensity: Vec3,
    },
    Sun(Sun),
}

/// A distant disk of uniform radiance seen within `1 - cos θ ≤ one_minus_cos`
/// of `direction`. Angles are handled through `1 - cos θ = |d - s|² / 2`,
/// which keeps full precision for the sun's tiny cone where `cos θ` rounds.
#[derive(Clone, Copy, Debug)]
pub struct Sun {
    direction: Vec3,
    radiance: Vec3,
    one_minus_cos: f32,
    solid_angle: f32,
}

impl Sun {
    pub fn new(direction: Vec3, radiance: Vec3, angular_diameter_deg: f32) -> Self {
        Self {
            direction: direction.normalize(),
            radiance,
            one_minus_cos: Light::sun_one_minus_cos(angular_diameter_deg),
            solid_angle: Light::sun_solid_angle(angular_diameter_deg),
        }
    }

    /// Whether the unit direction `d` points into the disk.
    fn contains(&self, d: Vec3) -> bool {
        0.5 * (d - self.direction).length_squared() <= self.one_minus_cos
    }

    /// A direction uniformly distributed over the disk's cone.
    fn sample(&self, u1: f32, u2: f32) -> Vec3 {
        let z = u1 * self.one_minus_cos; // 1 - cos θ
        let cos_t = 1.0 - z;
        let sin_t = (z * (2.0 - z)).max(0.0).sqrt();
        let (sp, cp) = (2.0 * PI * u2).sin_cos();
        let f = crate::bsdf::Frame::new(self.direction);
        f.to_world(Vec3::new(sin_t * cp, sin_t * sp, cos_t))
            .normalize()
    }
}

/// One light sample as seen from a shading point.
pub struct LightSample {
    /// Unit direction towards the light.
    pub wi: Vec3,
    /// The segment that must be free for the light to be seen.
    pub shadow: Ray,
    /// Radiance arriving along `wi` (for a point light: intensity / d²).
    pub radiance: Vec3,
    /// Solid-angle density including the light's selection probability;
    /// for a point light, only the selection probability.
    pub pdf: f32,
    pub delta: bool,
}

pub struct Lights {
    entries: Vec<Entry>,
    /// Selection probability of each entry, and their running sum.
    prob: Vec<f64>,
    cdf: Vec<f64>,
    /// First entry of each object's triangles, for objects that emit.
    first_triangle: Vec<Option<usize>>,
    sun: Option<usize>,
}

impl Lights {
    /// The scene's lights at time `t`.
    pub fn new(scene: &Scene, t: f32) -> Self {
        let mut entries = Vec::new();
        let mut weights = Vec::new();
        let mut first_triangle = vec![None; scene.objects.len()];
        for ((k, obj), xf) in scene.objects.iter().enumerate().zip(scene.at(t)) {
            let Some(em) = scene.materials[obj.material].emission else {
                continue;
            };
            first_triangle[k] = Some(entries.len());
            for &[a, b, c] in &obj.mesh.triangles {
                let p = |i: u32| xf.transform_point3(obj.mesh.positions[i as usize]);
                let (p0, p1, p2) = (p(a), p(b), p(c));
                let (e1, e2) = (p1 - p0, p2 - p0);
                let cross = e1.cross(e2);
                let area = 0.5 * cross.length();
                let sides = if em.two_sided { 2.0 } else { 1.0 };
                weights.push(area as f64 * PI as f64 * sides * em.radiance.element_sum() as f64);
                entries.push(Entry::Triangle {
                    p0,
                    e1,
                    e2,
                    normal: cross.normalize_or_zero(),
                    area,
                    radiance: em.radiance,
                    two_sided: em.two_sided,
                });
            }
        }
        let (lo, hi) = scene.bounds(t);
        let radius = if lo.is_finite() && hi.is_finite() {
            0.5 * (hi - lo).length()
        } else {
            0.0
        };
        let mut sun = None;
        for light in &scene.lights {
            match *light {
                Light::Point {
                    position,
                    intensity,
                } => {
                    weights.push(4.0 * PI as f64 * intensity.element_sum() as f64);
                    entries.push(Entry::Point {
                        position,
                        intensity,
                    });
                }
                Light::Sun {
                    direction,
                    radiance,
                    angular_diameter_deg,
                } => {
                    let s = Sun::new(direction, radiance, angular_diameter_deg);
                    if s.solid_angle <= 0.0 || !s.direction.is_finite() {
                        continue;
                    }
                    // Power through a disk of the scene's size, at normal
                    // incidence: radiance x projected solid angle x area.
                    // Reset below if the scene has local lights too.
                    let oc = s.one_minus_cos as f64;
                    let proj = PI as f64 * oc * (2.0 - oc);
                    let r = radius as f64;
                    weights.push(radiance.element_sum() as f64 * proj * PI as f64 * r * r);
                    sun = Some(entries.len());
                    entries.push(Entry::Sun(s));
                }
            }
        }
        // The sun's power through the scene's whole cross-section is what
        // it delivers to an open scene; inside a room it lands mostly on the
        // outside of the walls, and a power-proportional pick would spend
        // nearly every light sample of a lamp-lit interior on a sun the
        // shading point cannot see (nine in ten in the soda shop). As
        // pbrt-v4's light samplers do for infinite lights, the sun takes
        // half of the picks when local lights share the rest by power.
        if let Some(k) = sun {
            let local: f64 = weights
                .iter()
                .enumerate()
                .filter(|&(i, _)| i != k)
                .map(|(_, w)| w)
                .sum();
            if weights[k] > 0.0 && local > 0.0 {
                weights[k] = local;
            }
        }
        let total: f64 = weights.iter().sum();
        let prob: Vec<f64> = if total > 0.0 && total.is_finite() {
            weights.iter().map(|w| w / total).collect()
        } else {
            vec![0.0; weights.len()]
        };
        let mut acc = 0.0;
        let cdf = prob
            .iter()
            .map(|p| {
                acc += p;
                acc
            })
            .collect();
        Self {
            entries,
            prob,
            cdf,
            first_triangle,
            sun,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.prob.iter().all(|&p| p == 0.0)
    }

    /// Picks a light (with the probabilities set in [`Lights::new`]) and a
    /// point (or direction) on it, as seen from `p` with geometric normal `ng`.
    pub fn sample(&self, p: Vec3, ng: Vec3, u: f64, u1: f32, u2: f32) -> Option<LightSample> {
        let i = self
            .cdf
            .partition_point(|&c| c <= u)
            .min(self.cdf.len() - 1);
        let sel = self.prob[i] as f32;
        if sel <= 0.0 {
            return None;
        }
        match self.entries[i] {
            Entry::Triangle {
                p0,
                e1,
                e2,
                normal,
                area,
                radiance,
                two_sided,
            } => {
                let s = u1.sqrt();
                let q = p0 + e1 * (s * (1.0 - u2)) + e2 * (s * u2);
                let d = q - p;
                let dist2 = d.length_squared();
                let wi = d / dist2.sqrt();
                let cos_l = -normal.dot(wi);
                if !(two_sided || cos_l > 0.0) || cos_l == 0.0 {
                    return None;
                }
                let pdf = sel * (dist2 / area) / cos_l.abs();
                let origin = offset_origin(p, ng, wi);
                let end = offset_origin(q, normal, -wi);
                Some(LightSample {
                    wi,
                    shadow: Ray::segment(origin, end - origin, 1.0),
                    radiance,
                    pdf,
                    delta: false,
                })
                .filter(|l| l.pdf.is_finite() && l.pdf > 0.0 && l.wi.is_finite())
            }
            Entry::Point {
                position,
                intensity,
            } => PointArrival::new(position, intensity, p, ng).map(|a| LightSample {
                wi: a.wi,
                shadow: a.shadow,
                radiance: a.irradiance,
                pdf: sel,
                delta: true,
            }),
            Entry::Sun(sun) => {
                let wi = sun.sample(u1, u2);
                Some(LightSample {
                    wi,
                    shadow: Ray::new(offset_origin(p, ng, wi), wi),
                    radiance: sun.radiance,
                    pdf: sel / sun.solid_angle,
                    delta: false,
                })
            }
        }
    }

    /// Solid-angle density with which [`Lights::sample`] would have chosen
    /// the point `q` of triangle `primitive` of `object`, seen from `p`.
    pub fn triangle_pdf(&self, object: u32, primitive: u32, p: Vec3, q: Vec3) -> f32 {
        let Some(first) = self.first_triangle[object as usize] else {
            return 0.0;
        };
        let i = first + primitive as usize;
        let Entry::Triangle { normal, area, .. } = self.entries[i] else {
            return 0.0;
        };
        let d = q - p;
        let dist2 = d.length_squared();
        let cos_l = normal.dot(d).abs() / dist2.sqrt();
        let pdf = self.prob[i] as f32 * (dist2 / area) / cos_l;
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    /// Radiance and density of the sun along an escaping unit direction.
    pub fn sun_along(&self, dir: Vec3) -> Option<(Vec3, f32)> {
        let i = self.sun?;
        let Entry::Sun(sun) = self.entries[i] else {
            return None;
        };
        sun.contains(dir)
            .then(|| (sun.radiance, self.prob[i] as f32 / sun.solid_angle))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    #[test]
    fn sun_samples_lie_in_its_cone_and_cover_it() {
        let s = Sun::new(Vec3::new(0.3, 1.0, -0.2), Vec3::ONE, 0.53);
        let mut rng = Pcg32::for_sample(0, 0, 0);
        let half = (0.53f32 * 0.5).to_radians();
        let mut max_angle = 0.0f32;
        for _ in 0..10_000 {
            let d = s.sample(rng.next_f32(), rng.next_f32());
            assert!(s.contains(d), "{d} outside the sun");
            max_angle = max_angle.max(d.cross(s.direction).length().asin());
        }
        assert!(max_angle > 0.97 * half && max_angle <= 1.001 * half);
        // Solid angle of a 0.53° disk: π (0.265°)² to first order.
        let expect = PI * half * half;
        assert!((s.solid_angle - expect).abs() < 1e-4 * expect);
    }

    /// The sun's share of the light picks, read back from the density a ray
    /// into its disk is given.
    fn sun_share(scene: &Scene) -> f32 {
        let Some(Light::Sun {
            direction,
            angular_diameter_deg,
            ..
        }) = scene
            .lights
            .iter()
            .find(|l| matches!(l, Light::Sun { .. }))
            .copied()
        else {
            panic!("{} has no sun", scene.source.display());
        };
        let (_, pdf) = Lights::new(scene, 0.0)
            .sun_along(direction.normalize())
            .expect("the sun's own direction is in its disk");
        pdf * Light::sun_solid_angle(angular_diameter_deg)
    }

    #[test]
    fn the_sun_takes_half_the_picks_beside_local_lights_and_all_alone() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        // Sun and a point light; picks in proportion to power gave the sun
        // 90% of them.
        let both = Scene::load(dir.join("glossy-sun/scene.toml")).unwrap();
        assert!(
            (sun_share(&both) - 0.5).abs() < 1e-6,
            "{}",
            sun_share(&both)
        );
        let mut alone = both;
        alone.lights.retain(|l| matches!(l, Light::Sun { .. }));
        assert!(
            (sun_share(&alone) - 1.0).abs() < 1e-6,
            "{}",
            sun_share(&alone)
        );
    }
}

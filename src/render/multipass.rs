//! The multipass renderer (paper §4.4): direct light ray traced, specular
//! and glossy reflection traced, diffuse indirect light looked up from the
//! radiosity records instead of traced.
//!
//! At every surface a path reaches (the camera's first hit and the hits of
//! traced specular chains) the estimate is
//!
//! * emission, where an emitter is seen directly or through a mirror, or
//!   reached by a glossy sample (weighted against light sampling by the
//!   power heuristic);
//! * direct light by next-event estimation: one light sample per hit,
//!   stratified over the pixel's samples at the first hit. The diffuse
//!   part takes it with weight one; the glossy part shares it with the
//!   sampled glossy ray by multiple importance sampling;
//! * diffuse indirect light `ρ/π · E`, with `E` the records' irradiance at
//!   the hit's object-space point and normal (`IrradianceCache`), or, with
//!   [`Indirect::Gathered`], gathered at surfaces seen directly or in
//!   mirrors through one traced bounce whose hit reflects its direct light
//!   and its records' irradiance (the final gather of Chen et al. 1991,
//!   the paper's [8]): records hold an element's mean light, so where a
//!   surface meets another (a room's corners, a box on the floor) they
//!   miss the darkening that the bounce's geometry finds;
//! * a traced reflection: mirrors exactly, glossy lobes by sampling their
//!   specular part only (their diffuse part is covered by the records).
//!
//! Path length is counted in segments as the path tracer counts it (see
//! `RenderSettings::max_depth`): direct light at a hit needs one segment
//! more, looked-up indirect light two. Without a bound, chains of specular
//! bounces stop after [`UNBOUNDED_DEPTH`] segments. A scene without glossy
//! or mirror surfaces traces camera and shadow rays only.

use std::f32::consts::FRAC_1_PI;
use std::time::Instant;

use anyhow::{ensure, Result};
use glam::{Affine3A, Vec3};

use super::hit::SurfaceHit;
use super::integrator::{power_heuristic, Integrator};
use super::lights::Lights;
use super::noise::NoiseTarget;
use super::{first_hits, shade_tiles, Coverage, Progress, RenderSettings, RenderStats, Sampled};
use crate::accel::RayEngine;
use crate::bsdf::{Frame, Lobes};
use crate::camera::Camera;
use crate::image::{RangeImage, RangeMeta, NO_HIT};
use crate::radiosity::lookup::IrradianceCache;
use crate::ray::{offset_origin, Ray};
use crate::rng::Pcg32;
use crate::scene::Scene;

/// Longest path (in segments) when `RenderSettings::max_depth` is `None`:
/// a chain of mirrors facing each other must still end.
pub const UNBOUNDED_DEPTH: u32 = 16;

/// Where diffuse indirect light comes from.
#[derive(Clone, Copy)]
pub enum Indirect<'a> {
    /// Radiosity records interpolated to the rendered time (the paper's
    /// multipass renderer).
    Records(&'a IrradianceCache),
    /// The records seen through one cosine-sampled bounce per sample at
    /// surfaces seen directly or in mirrors (looked up elsewhere).
    Gathered(&'a IrradianceCache),
    /// One cosine-sampled bounce per sample, continued by the path tracer:
    /// unbiased, for base images where no radiosity bake is wanted.
    Traced,
}

/// A render split as base images store it.
pub struct Layers {
    /// The whole radiance, with first hits (distance, ids, normals).
    pub image: RangeImage,
    /// The part of each pixel's radiance that is diffuse indirect light at
    /// the surfaces seen, directly or in mirrors; the rest (emission, direct
    /// light, traced specular and glossy reflection) is `image.radiance`
    /// minus this.
    pub indirect: Vec<Vec3>,
    /// The part that is direct light (from light samples) reflected by the
    /// diffuse lobe of the surface the camera ray meets first: what moves
    /// when a shadow moves, and what synthesis re-shades.
    pub diffuse_direct: Vec<Vec3>,
    pub stats: RenderStats,
    pub sampling: Sampled,
}

/// Renders `camera`'s view at `time`; `engine` holds the scene posed at
/// `time` and `indirect` the records interpolated to `time`.
/// `settings.max_depth` bounds the chain of specular bounces.
pub fn render(
    scene: &Scene,
    engine: &dyn RayEngine,
    camera: &Camera,
    time: f32,
    settings: &RenderSettings,
    indirect: &IrradianceCache,
) -> Result<(RangeImage, RenderStats)> {
    let out = render_layers(
        scene,
        engine,
        camera,
        time,
        settings,
        Indirect::Records(indirect),
        None,
        Progress::Tiles,
    )?;
    Ok((out.image, out.stats))
}

/// [`render`] with the diffuse indirect part kept apart, indirect light
/// from either source, pixels sampled to a noise `target` if one is given
/// (`settings.spp` is then the least a pixel takes), and progress reported
/// where the caller says.
#[allow(clippy::too_many_arguments)]
pub fn render_layers(
    scene: &Scene,
    engine: &dyn RayEngine,
    camera: &Camera,
    time: f32,
    settings: &RenderSettings,
    indirect: Indirect,
    target: Option<NoiseTarget>,
    progress: Progress,
) -> Result<Layers> {
    let view = (camera, time);
    layers(
        scene,
        engine,
        view,
        settings,
        indirect,
        target,
        Coverage::Pixel,
        progress,
    )
}

/// [`render_layers`] for a base image: each pixel averages only the samples
/// that meet its centre ray's object ([`Coverage::CentreObject`]).
#[allow(clippy::too_many_arguments)]
pub fn render_base(
    scene: &Scene,
    engine: &dyn RayEngine,
    camera: &Camera,
    time: f32,
    settings: &RenderSettings,
    indirect: Indirect,
    target: Option<NoiseTarget>,
    progress: Progress,
) -> Result<Layers> {
    let view = (camera, time);
    let coverage = Coverage::CentreObject;
    layers(
        scene, engine, view, settings, indirect, target, coverage, progress,
    )
}

#[allow(clippy::too_many_arguments)]
fn layers(
    scene: &Scene,
    engine: &dyn RayEngine,
    (camera, time): (&Camera, f32),
    settings: &RenderSettings,
    indirect: Indirect,
    target: Option<NoiseTarget>,
    coverage: Coverage,
    progress: Progress,
) -> Result<Layers> {
    ensure!(settings.spp > 0, "multipass render: spp must be at least 1");
    if let Some(t) = &target {
        ensure!(
            t.relative.is_finite() && t.relative > 0.0,
            "multipass render: noise target {} is not a positive relative error",
            t.relative
        );
        ensure!(
            t.max_spp >= settings.spp,
            "multipass render: sample limit {} is below the minimum spp {}",
            t.max_spp,
            settings.spp
        );
    }
    ensure!(
        scene.objects.len() < u32::MAX as usize,
        "multipass render: too many objects"
    );
    let start = Instant::now();
    let shader = Multipass {
        scene,
        engine,
        lights: Lights::new(scene, time),
        poses: scene.at(time),
        indirect: match indirect {
            Indirect::Records(cache) => Source::Records(cache),
            Indirect::Gathered(cache) => Source::Gathered(cache),
            Indirect::Traced => Source::Traced(Integrator {
                scene,
                engine,
                lights: Lights::new(scene, time),
                poses: scene.at(time),
                max_depth: settings.max_depth.unwrap_or(u32::MAX),
            }),
        },
        max_depth: settings.max_depth.unwrap_or(UNBOUNDED_DEPTH),
        traced_depth: settings.max_depth.unwrap_or(u32::MAX),
        strata: (settings.spp as f32).sqrt().floor() as u32,
    };
    let meta = RangeMeta {
        camera: *camera,
        time,
        scene: format!(
            "{} t={time} multipass ({}, indirect {}) spp={}{} max_depth={} seed={}",
            scene.source.display(),
            engine.name(),
            match indirect {
                Indirect::Records(_) => "from radiosity records",
                Indirect::Gathered(_) => "radiosity records gathered",
                Indirect::Traced => "traced",
            },
            settings.spp,
            target.map_or(String::new(), |t| format!(
                " noise={} max_spp={}",
                t.relative, t.max_spp
            )),
            shader.max_depth,
            settings.seed
        ),
    };
    let mut image = RangeImage::empty(meta);
    let mut rays = first_hits(engine, camera, &mut image);
    let (traced, parts, sampling) = shade_tiles(
        camera,
        settings,
        target.as_ref(),
        coverage,
        &mut image,
        &|ray, s, rng, rays| shader.radiance(ray, s, rng, rays),
        progress,
    );
    rays += traced;
    let stats = RenderStats {
        seconds: start.elapsed().as_secs_f64(),
        samples: sampling.samples.iter().map(|&n| n as u64).sum(),
        rays,
    };
    let (indirect, diffuse_direct) = parts.into_iter().map(|[i, d]| (i, d)).unzip();
    Ok(Layers {
        image,
        indirect,
        diffuse_direct,
        stats,
        sampling,
    })
}

enum Source<'a> {
    Records(&'a IrradianceCache),
    Gathered(&'a IrradianceCache),
    Traced(Integrator<'a>),
}

struct Multipass<'a> {
    scene: &'a Scene,
    engine: &'a dyn RayEngine,
    lights: Lights,
    poses: Vec<Affine3A>,
    indirect: Source<'a>,
    max_depth: u32,
    /// Longest path when indirect light is traced (unbounded unless the
    /// settings bound it).
    traced_depth: u32,
    /// Light samples at the first hit are stratified on a
    /// `strata x strata` grid over the pixel's samples.
    strata: u32,
}

/// How the ray that reached a surface was chosen, for weighting the
/// emission it finds there.
#[derive(Clone, Copy)]
enum Came {
    /// Camera ray or mirror: no other strategy could have found it.
    Only,
    /// Sampled from a glossy lobe with this density, at this point.
    Glossy { pdf: f32, from: Vec3 },
}

impl Multipass<'_> {
    /// One sample's radiance, the diffuse indirect part of it seen directly
    /// or in mirrors, and the first hit's diffuse-lobe direct light.
    /// The sample's radiance and its parts, and the object its camera ray
    /// meets (`NO_HIT` for none).
    fn radiance(
        &self,
        mut ray: Ray,
        sample: u32,
        rng: &mut Pcg32,
        rays: &mut u64,
    ) -> ([Vec3; 3], u32) {
        let mut first = NO_HIT;
        let mut l = Vec3::ZERO;
        let mut l_indirect = Vec3::ZERO;
        let mut l_diffuse_direct = Vec3::ZERO;
        let mut beta = Vec3::ONE;
        let mut came = Came::Only;
        // No glossy bounce yet: what is found is seen directly or in mirrors.
        let mut sharp = true;
        let mut segments = 1u32;
        if self.max_depth == 0 {
            return ([l, l_indirect, l_diffuse_direct], first);
        }
        loop {
            *rays += 1;
            let hit = self.engine.intersect(&ray);
            if segments == 1 {
                first = hit.as_ref().map_or(NO_HIT, |h| h.object);
            }
            let Some(hit) = hit else {
                if let Some((le, pdf_light)) = self.lights.sun_along(ray.dir.normalize()) {
                    let w = match came {
                        Came::Only => 1.0,
                        Came::Glossy { pdf, .. } => power_heuristic(pdf, pdf_light),
                    };
                    l += beta * le * w;
                }
                break;
            };
            let Some(surface) = SurfaceHit::new(self.scene, &self.poses, &ray, &hit) else {
                break;
            };
            let (p, ng) = (surface.p, surface.ng);
            if let Some(le) = surface.emitted() {
                let w = match came {
                    Came::Only => 1.0,
                    Came::Glossy { pdf, from } => {
                        let pl = self.lights.triangle_pdf(hit.object, hit.primitive, from, p);
                        power_heuristic(pdf, pl)
                    }
                };
                l += beta * le * w;
            }
            if segments >= self.max_depth {
                break;
            }
            let (frame, lobes) = surface.lobes();
            let wo_l = frame.to_local(surface.wo);
            let (diffuse, specular) = split(lobes);

            let lit = diffuse.is_some() || specular.is_some_and(|s| !s.is_delta());
            if lit && !self.lights.is_empty() {
                let u = self.light_numbers(segments, sample, rng);
                let [d, s] = self.direct(p, ng, frame, wo_l, diffuse, specular, u, rays);
                l += beta * (d + s);
                if segments == 1 {
                    l_diffuse_direct += d;
                }
            }
            if let Some(Lobes::Diffuse { albedo }) = diffuse {
                if albedo != Vec3::ZERO {
                    let li = match &self.indirect {
                        Source::Gathered(cache) if sharp && segments + 3 <= self.max_depth => {
                            beta * self.gather(cache, p, ng, frame, wo_l, albedo, rng, rays)
                        }
                        Source::Records(cache) | Source::Gathered(cache)
                            if segments + 2 <= self.max_depth =>
                        {
                            beta * albedo * FRAC_1_PI * recorded(cache, &surface, hit.object)
                        }
                        Source::Traced(integrator) if segments + 2 <= self.traced_depth => {
                            let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
                            match (Lobes::Diffuse { albedo }).sample(wo_l, u) {
                                Some(s) => {
                                    let wi = frame.to_world(s.wi);
                                    let bounce = Ray::new(offset_origin(p, ng, wi), wi);
                                    let depth = self.traced_depth - segments;
                                    let li =
                                        integrator.radiance_reflected(bounce, rng, rays, depth);
                                    beta * s.weight * li
                                }
                                None => Vec3::ZERO,
                            }
                        }
                        _ => Vec3::ZERO,
                    };
                    if li.is_finite() {
                        l += li;
                        if sharp {
                            l_indirect += li;
                        }
                    }
                }
            }

            // Continue along the specular or glossy reflection, if any.
            let Some(spec) = specular else { break };
            let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
            let Some(s) = spec.sample(wo_l, u) else { break };
            beta *= s.weight;
            if beta == Vec3::ZERO || !beta.is_finite() {
                break;
            }
            sharp &= s.delta;
            came = if s.delta {
                Came::Only
            } else {
                Came::Glossy {
                    pdf: s.pdf,
                    from: p,
                }
            };
            segments += 1;
            let wi = frame.to_world(s.wi);
            ray = Ray::new(offset_origin(p, ng, wi), wi);
        }
        ([l, l_indirect, l_diffuse_direct], first)
    }

    /// Uniform numbers for a light sample; at the camera's first hit the
    /// point on the light is stratified over the pixel's samples.
    fn light_numbers(&self, segments: u32, sample: u32, rng: &mut Pcg32) -> (f64, f32, f32) {
        let (u, mut u1, mut u2) = (rng.next_f64(), rng.next_f32(), rng.next_f32());
        let n = self.strata;
        if segments == 1 && n > 1 && sample < n * n {
            let inv = 1.0 / n as f32;
            u1 = ((sample % n) as f32 + u1) * inv;
            u2 = ((sample / n) as f32 + u2) * inv;
            // Stay below one where rounding would reach it.
            u1 = u1.min(1.0 - f32::EPSILON);
            u2 = u2.min(1.0 - f32::EPSILON);
        }
        (u, u1, u2)
    }

    /// Diffuse indirect light at `p` by one cosine-sampled bounce: what its
    /// hit reflects of one light sample and of its records' irradiance.
    /// Emission met there is direct light, which light samples at `p`
    /// count; a mirror met there reflects only its direct light.
    #[allow(clippy::too_many_arguments)]
    fn gather(
        &self,
        cache: &IrradianceCache,
        p: Vec3,
        ng: Vec3,
        frame: Frame,
        wo_l: Vec3,
        albedo: Vec3,
        rng: &mut Pcg32,
        rays: &mut u64,
    ) -> Vec3 {
        let u = [rng.next_f32(), rng.next_f32(), rng.next_f32()];
        let Some(s) = (Lobes::Diffuse { albedo }).sample(wo_l, u) else {
            return Vec3::ZERO;
        };
        let wi = frame.to_world(s.wi);
        let ray = Ray::new(offset_origin(p, ng, wi), wi);
        *rays += 1;
        let Some(hit) = self.engine.intersect(&ray) else {
            return Vec3::ZERO;
        };
        let Some(y) = SurfaceHit::new(self.scene, &self.poses, &ray, &hit) else {
            return Vec3::ZERO;
        };
        let (frame_y, lobes) = y.lobes();
        let wo_y = frame_y.to_local(y.wo);
        let (diffuse, specular) = split(lobes);
        let mut l = Vec3::ZERO;
        let lit = diffuse.is_some() || specular.is_some_and(|s| !s.is_delta());
        if lit && !self.lights.is_empty() {
            let u = (rng.next_f64(), rng.next_f32(), rng.next_f32());
            let [d, sp] = self.direct(y.p, y.ng, frame_y, wo_y, diffuse, specular, u, rays);
            l += d + sp;
        }
        if let Some(Lobes::Diffuse { albedo }) = diffuse {
            l += albedo * FRAC_1_PI * recorded(cache, &y, hit.object);
        }
        s.weight * l
    }

    /// Direct light by one light sample, reflected by the diffuse lobe (with
    /// weight one) and by the glossy lobe (weighted against its own
    /// sampling).
    #[allow(clippy::too_many_arguments)]
    fn direct(
        &self,
        p: Vec3,
        ng: Vec3,
        frame: Frame,
        wo_l: Vec3,
        diffuse: Option<Lobes>,
        specular: Option<Lobes>,
        (u, u1, u2): (f64, f32, f32),
        rays: &mut u64,
    ) -> [Vec3; 2] {
        const NONE: [Vec3; 2] = [Vec3::ZERO; 2];
        let Some(ls) = self.lights.sample(p, ng, u, u1, u2) else {
            return NONE;
        };
        let wi_l = frame.to_local(ls.wi);
        if wi_l.z <= 0.0 {
            return NONE;
        }
        let fd = diffuse.map_or(Vec3::ZERO, |d| d.eval(wo_l, wi_l));
        let mut fs = Vec3::ZERO;
        if let Some(s) = specular.filter(|s| !s.is_delta()) {
            let w = if ls.delta {
                1.0
            } else {
                power_heuristic(ls.pdf, s.pdf(wo_l, wi_l))
            };
            fs = s.eval(wo_l, wi_l) * w;
        }
        if fd == Vec3::ZERO && fs == Vec3::ZERO {
            return NONE;
        }
        *rays += 1;
        if self.engine.occluded(&ls.shadow) {
            return NONE;
        }
        let scale = ls.radiance * (wi_l.z / ls.pdf);
        let (d, s) = (fd * scale, fs * scale);
        if d.is_finite() && s.is_finite() {
            [d, s]
        } else {
            NONE
        }
    }
}

/// The records' irradiance at `surface`, a point of `object`.
fn recorded(cache: &IrradianceCache, surface: &SurfaceHit, object: u32) -> Vec3 {
    cache.irradiance(
        object,
        surface.front(),
        surface.local,
        surface.local_normal(),
    )
}

/// The diffuse part (lit by light samples and the records) and the
/// specular part (traced) of a reflection model.
fn split(lobes: Lobes) -> (Option<Lobes>, Option<Lobes>) {
    match lobes {
        Lobes::Diffuse { albedo } => (Some(Lobes::Diffuse { albedo }), None),
        Lobes::Glossy {
            diffuse,
            specular,
            alpha,
            model,
        } => (
            (diffuse != Vec3::ZERO).then_some(Lobes::Diffuse { albedo: diffuse }),
            (specular != Vec3::ZERO).then_some(Lobes::Glossy {
                diffuse: Vec3::ZERO,
                specular,
                alpha,
                model,
            }),
        ),
        Lobes::Mirror { reflectance } => (
            None,
            (reflectance != Vec3::ZERO).then_some(Lobes::Mirror { reflectance }),
        ),
    }
}

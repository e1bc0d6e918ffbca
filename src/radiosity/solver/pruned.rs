//! Shadow rays through the geometry the simplification left out.
//!
//! A left-out object or pruned part has no patches, so it reflects nothing
//! in the solve; if it only blocked the links' rays, every watt it
//! intercepts would vanish (the studio's left-out books took 2.3% of its
//! indirect light at q = 0.3). Instead a ray it blocks carries on with the
//! share its surface reflects: the light reaches the far side rather than
//! coming back, but the scene keeps the power that geometry reflects, and
//! surfaces the solve does stand for still block as before.

use anyhow::{Context, Result};
use glam::Affine3A;

use crate::accel::{self, Backend, InstancedEngine, RayEngine};
use crate::radiosity::{transport_albedo, Simplified};
use crate::ray::Ray;
use crate::scene::{MeshGeometry, Scene};

/// How the links' shadow rays are traced.
pub struct Pruned {
    /// `None` when nothing was left out: the solve's own engine answers.
    split: Option<Split>,
}

/// The scene's triangles in two engines, posed as the solve's: a ray
/// blocked by `kept` is blocked; one `alone` blocks keeps the share of
/// the first left-out surface it meets. One occlusion query and, for the
/// few rays that cross left-out geometry, one closest hit: walking every
/// blocked ray's hits in the whole scene instead doubled the studio's
/// solve at q = 0.6 (a third of its rays cross a chair leg or a book).
struct Split {
    kept: Box<dyn InstancedEngine>,
    alone: Box<dyn InstancedEngine>,
    /// Per mesh of `alone`: the share of light its surface reflects (the
    /// mean of the transport albedo's channels).
    share: Vec<f32>,
    /// The scene object of each mesh of `kept` and of `alone`, to pose
    /// them again at another time.
    objects: [Vec<usize>; 2],
}

impl Pruned {
    /// `backend` and `poses`: those of the solve's ray engine.
    pub fn new(
        scene: &Scene,
        simplified: &Simplified,
        backend: Backend,
        poses: &[Affine3A],
    ) -> Result<Self> {
        if simplified.pruned.is_empty() {
            return Ok(Self { split: None });
        }
        let mut left_out = vec![Vec::new(); scene.objects.len()];
        for &(o, t) in &simplified.pruned {
            left_out[o as usize].push(t as usize);
        }
        let mut kept = (Vec::new(), Vec::new());
        let mut alone = (Vec::new(), Vec::new());
        let mut share = Vec::new();
        let mut objects = [Vec::new(), Vec::new()];
        for (k, ((o, out), &pose)) in scene.objects.iter().zip(&left_out).zip(poses).enumerate() {
            let mut mine = out.iter().peekable();
            let (mut inside, mut outside) = (Vec::new(), Vec::new());
            for (i, &t) in o.mesh.triangles.iter().enumerate() {
                if mine.next_if_eq(&&i).is_some() {
                    outside.push(t);
                } else {
                    inside.push(t);
                }
            }
            for ((triangles, (meshes, placed)), objects) in
                [(inside, &mut kept), (outside, &mut alone)]
                    .into_iter()
                    .zip(&mut objects)
            {
                if !triangles.is_empty() {
                    objects.push(k);
                    meshes.push(MeshGeometry {
                        positions: o.mesh.positions.clone(),
                        triangles,
                    });
                    placed.push(pose);
                }
            }
            if !out.is_empty() {
                // Integrated over the lobe, once an object.
                let albedo = transport_albedo(&scene.materials[o.material].bsdf);
                share.push(albedo.element_sum() / 3.0);
            }
        }
        let build = |(meshes, placed): (Vec<MeshGeometry>, Vec<Affine3A>), what: &str| {
            accel::build(backend, &meshes, &placed)
                .with_context(|| format!("building a ray engine over the {what} triangles"))
        };
        Ok(Self {
            split: Some(Split {
                kept: build(kept, "kept")?,
                alone: build(alone, "left-out")?,
                share,
                objects,
            }),
        })
    }

    /// The same engines posed at another time of the same scene (`poses`,
    /// one per object): a temporal decomposition's solves re-pose them
    /// instead of building them again.
    pub fn pose(&mut self, poses: &[Affine3A]) -> Result<()> {
        if let Some(split) = &mut self.split {
            for (engine, objects) in [&mut split.kept, &mut split.alone]
                .into_iter()
                .zip(&split.objects)
            {
                let placed: Vec<Affine3A> = objects.iter().map(|&o| poses[o]).collect();
                engine.set_transforms(&placed)?;
            }
        }
        Ok(())
    }

    /// The share of each ray's light that gets past its blockers, in
    /// 255ths: 0 when a surface the solve stands for blocks it, else the
    /// share the first left-out surface along it reflects (255 when none
    /// does). Only that first one counts: it is where the light would be
    /// reflected, and the surfaces behind it (the far side of a closed
    /// book, the next book) would see none of it.
    pub fn pass_batch(&self, engine: &dyn RayEngine, rays: &[Ray], out: &mut [u8]) {
        let mut blocked = vec![false; rays.len()];
        let Some(split) = &self.split else {
            engine.occluded_batch(rays, &mut blocked);
            for (o, b) in out.iter_mut().zip(blocked) {
                *o = if b { 0 } else { u8::MAX };
            }
            return;
        };
        split.kept.occluded_batch(rays, &mut blocked);
        for ((o, b), ray) in out.iter_mut().zip(blocked).zip(rays) {
            *o = if b {
                0
            } else {
                match split.alone.intersect(ray) {
                    None => u8::MAX,
                    Some(hit) => (split.share[hit.object as usize] * 255.0).round() as u8,
                }
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    /// The unit cube of `scenes/furnace` stretched over `lo..hi`, its
    /// vertices numbered from `first` (OBJ counts from 1).
    fn cuboid(name: &str, lo: Vec3, hi: Vec3, first: usize) -> String {
        let cube = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/furnace/cube.obj"),
        )
        .unwrap();
        let mut s = format!("o {name}\n");
        for line in cube.lines() {
            let mut words = line.split_whitespace();
            let numbers = words.clone().skip(1);
            match words.next() {
                Some("v") => {
                    let v: Vec<f32> = numbers.map(|x| x.parse().unwrap()).collect();
                    let p = lo + (hi - lo) * Vec3::from_slice(&v);
                    s += &format!("v {} {} {}\n", p.x, p.y, p.z);
                }
                Some("f") => {
                    s.push('f');
                    for i in numbers {
                        s += &format!(" {}", i.parse::<usize>().unwrap() + first - 1);
                    }
                    s.push('\n');
                }
                _ => {}
            }
        }
        s
    }

    /// Two closed boxes on the x axis, then a wall: `near` (albedo 0.4 on
    /// average) at x in [1, 1.5], `far` (0.8) at [2, 2.5], `wall` at [3, 3.1].
    fn row() -> (tempfile::TempDir, Scene) {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let h = Vec3::new(0.0, -1.0, -1.0);
        let obj = cuboid("near", Vec3::X + h, Vec3::new(1.5, 1.0, 1.0), 1)
            + &cuboid("far", 2.0 * Vec3::X + h, Vec3::new(2.5, 1.0, 1.0), 9)
            + &cuboid("wall", 3.0 * Vec3::X + h, Vec3::new(3.1, 1.0, 1.0), 17);
        std::fs::write(dir.join("row.obj"), obj).unwrap();
        let mut toml = String::new();
        for (name, rho) in [("near", "[0.2, 0.4, 0.6]"), ("far", "[0.8, 0.8, 0.8]")] {
            toml += &format!(
                "[[materials]]\nname = \"{name}\"\ntype = \"diffuse\"\nreflectance = {rho}\n\n"
            );
        }
        for (name, material) in [("near", "near"), ("far", "far"), ("wall", "far")] {
            toml += &format!(
                "[[objects]]\nname = \"{name}\"\nmesh = \"row.obj\"\ngroup = \"{name}\"\nmaterial = \"{material}\"\n\n"
            );
        }
        std::fs::write(dir.join("scene.toml"), toml).unwrap();
        let scene = Scene::load(dir.join("scene.toml")).unwrap();
        (tmp, scene)
    }

    #[test]
    fn rays_keep_the_first_left_out_surfaces_share_and_stop_at_kept_ones() {
        let (_dir, scene) = row();
        let poses = scene.at(0.0);
        let engine = accel::build(Backend::Bvh, &scene.geometry(), &poses).unwrap();
        let mut s = Simplified::whole(&scene);
        let ends = [0.9, 1.2, 1.8, 2.8, 3.5];
        let passes = |s: &Simplified| {
            let pruned = Pruned::new(&scene, s, Backend::Bvh, &poses).unwrap();
            let rays = ends.map(|x| Ray::segment(Vec3::new(0.0, 0.1, 0.2), x * Vec3::X, 1.0));
            let mut out = [7; 5];
            pruned.pass_batch(engine.as_ref(), &rays, &mut out);
            out
        };
        let near = (0.4f32 * 255.0).round() as u8;
        // Nothing left out: every box blocks.
        assert_eq!(passes(&s), [255, 0, 0, 0, 0]);

        s.pruned = (0..2u32)
            .flat_map(|o| (0..12).map(move |t| (o, t)))
            .collect();
        // Into and through the near box, its albedo once: the far box sees
        // none of what the near one reflects. The wall has patches: it
        // blocks whatever stands before it.
        assert_eq!(passes(&s), [255, near, near, near, 0]);

        // Only part of an object left out: the near box's face towards the
        // origin (x = 1), so a ray through the box still meets its kept far
        // face.
        let mesh = &scene.objects[0].mesh;
        s.pruned = (0..mesh.triangles.len() as u32)
            .filter(|&t| {
                mesh.triangles[t as usize]
                    .iter()
                    .all(|&v| mesh.positions[v as usize].x == 1.0)
            })
            .map(|t| (0, t))
            .collect();
        assert_eq!(s.pruned.len(), 2);
        assert_eq!(passes(&s), [255, near, 0, 0, 0]);
    }

    /// Engines built at one time and posed at another answer as engines
    /// built there (and not as they did before).
    #[test]
    fn re_posed_engines_answer_as_engines_built_at_that_pose() {
        let (_dir, scene) = row();
        let mut s = Simplified::whole(&scene);
        // The near box and half the far one left out.
        s.pruned = (0..12u32)
            .map(|t| (0, t))
            .chain((0..6u32).map(|t| (1, t)))
            .collect();
        let still = scene.at(0.0);
        let mut moved = still.clone();
        moved[0] = Affine3A::from_translation(Vec3::new(0.0, 5.0, 0.0)) * moved[0];
        moved[1] = Affine3A::from_translation(Vec3::new(-0.7, 0.0, 0.0)) * moved[1];
        let engine = accel::build(Backend::Bvh, &scene.geometry(), &moved).unwrap();
        let rays: Vec<Ray> = (0..40)
            .map(|k| {
                let x = 0.5 + 0.08 * k as f32;
                Ray::segment(Vec3::new(0.0, 0.1, 0.2), x * Vec3::X + 0.01 * Vec3::Y, 1.0)
            })
            .collect();
        let passes = |pruned: &Pruned| {
            let mut out = vec![7; rays.len()];
            pruned.pass_batch(engine.as_ref(), &rays, &mut out);
            out
        };
        let built = Pruned::new(&scene, &s, Backend::Bvh, &moved).unwrap();
        let mut posed = Pruned::new(&scene, &s, Backend::Bvh, &still).unwrap();
        let before = passes(&posed);
        posed.pose(&moved).unwrap();
        assert_eq!(passes(&posed), passes(&built));
        assert_ne!(
            before,
            passes(&built),
            "the poses must change what the rays meet"
        );
    }
}

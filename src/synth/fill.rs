//! Background fill of the pixels no sample reached, as `pinterp -fb`: a
//! hole takes the farther of its candidates, so that the background, not
//! the foreground, spreads into what the bases did not see. Before it, the
//! holes whose own ray leaves the scene are given the sky.

use rayon::prelude::*;

use super::base::SKY;
use super::warp::{Accum, SKY_Z};
use crate::accel::RayEngine;
use crate::camera::Camera;

/// Gives each hole of `camera`'s frame whose centre ray meets nothing in
/// `engine` the radiance `sky` gives its direction, as a sample of the sky.
/// Through an opening (a window, past a roof's edge) the frame sees sky in
/// directions no base saw through it, and a background fill would spread
/// the wall beside the opening over them: their ray alone tells what is
/// there. Returns the number of such holes.
pub fn sky(
    engine: &dyn RayEngine,
    sky: &(dyn Fn(glam::Vec3) -> glam::Vec3 + Sync),
    camera: &Camera,
    buffer: &mut [Accum],
) -> usize {
    let w = camera.width as usize;
    buffer
        .par_iter_mut()
        .enumerate()
        .filter(|(_, a)| a.is_empty())
        .map(|(k, a)| {
            let Some(ray) = camera.ray((k % w) as f32 + 0.5, (k / w) as f32 + 0.5) else {
                return 0;
            };
            if engine.intersect(&ray).is_some() {
                return 0;
            }
            let dir = ray.dir.normalize();
            *a = Accum {
                z: SKY_Z,
                w: 1.0,
                radiance: sky(dir),
                alpha: 0.0,
                point: dir,
                object: SKY,
                primitive: SKY,
                reach: 0,
            };
            1
        })
        .sum()
}

/// Fills holes in scan order. A hole's vertical candidate is the farther of
/// the pixel above (possibly filled just before) and the first filled pixel
/// below; its horizontal one the farther of the pixel to the left and the
/// first filled pixel to the right; it takes the farther of the two. A
/// value travels at most `bound` pixels from a projected sample; holes
/// beyond stay empty. Returns the number of pixels filled.
pub fn background(buffer: &mut [Accum], width: u32, height: u32, bound: u16) -> usize {
    let (w, h) = (width as usize, height as usize);
    // Rows before the first hole have nothing to fill: finding it on every
    // core costs less than scanning them on one.
    let Some(first) = buffer
        .par_chunks(w.max(1))
        .position_first(|row| row.iter().any(Accum::is_empty))
    else {
        return 0;
    };
    let mut filled = 0;
    for y in first..h {
        for x in 0..w {
            let k = y * w + x;
            if !buffer[k].is_empty() {
                continue;
            }
            let mut best: Option<(Accum, u16)> = None;
            let mut offer = |c: Accum, reach: u16| {
                if c.is_empty() || reach > bound {
                    return;
                }
                if best.is_none_or(|(b, _)| c.z > b.z) {
                    best = Some((c, reach));
                }
            };
            if y > 0 {
                let c = buffer[k - w];
                offer(c, c.reach.saturating_add(1));
            }
            if x > 0 {
                let c = buffer[k - 1];
                offer(c, c.reach.saturating_add(1));
            }
            for d in 1..=(bound as usize).min(h - 1 - y) {
                let c = buffer[k + d * w];
                if !c.is_empty() {
                    offer(c, c.reach.saturating_add(d as u16));
                    break;
                }
            }
            for d in 1..=(bound as usize).min(w - 1 - x) {
                let c = buffer[k + d];
                if !c.is_empty() {
                    offer(c, c.reach.saturating_add(d as u16));
                    break;
                }
            }
            if let Some((c, reach)) = best {
                buffer[k] = Accum { reach, ..c };
                filled += 1;
            }
        }
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(z: f32) -> Accum {
        Accum {
            z,
            w: 1.0,
            radiance: glam::Vec3::splat(z),
            ..Accum::default()
        }
    }

    /// Looking up at the sun over the glossy-sun scene's wall: holes whose
    /// ray leaves the scene take the sky (the sun's disk at the centre),
    /// the others stay holes, and pixels that hold samples keep them.
    #[test]
    fn holes_open_to_the_sky_take_its_radiance_and_no_others_change() {
        use crate::accel::{self, Backend};
        use crate::camera::Projection;
        use crate::scene::{Light, Scene};
        use glam::Vec3;

        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/glossy-sun/scene.toml");
        let scene = Scene::load(std::path::Path::new(path)).unwrap();
        let Some(&Light::Sun {
            direction,
            radiance: sun,
            ..
        }) = scene.lights.iter().find(|l| matches!(l, Light::Sun { .. }))
        else {
            panic!("the glossy-sun scene has a sun");
        };
        let engine = accel::build(Backend::Bvh, &scene.geometry(), &scene.at(0.0)).unwrap();
        let (w, h) = (33, 33);
        let camera = Camera::looking(
            Vec3::new(0.0, 0.5, -1.0),
            direction,
            Vec3::Y,
            Projection::Perspective { vfov_deg: 150.0 },
            w,
            h,
        )
        .unwrap();
        let held = Accum {
            z: 2.0,
            w: 1.0,
            radiance: Vec3::ONE,
            ..Accum::default()
        };
        let mut buffer: Vec<Accum> = (0..w * h)
            .map(|k| if k % 5 == 0 { held } else { Accum::default() })
            .collect();
        let sky_of = crate::render::sky(&scene, 0.0);
        let opened = sky(&*engine, &sky_of, &camera, &mut buffer);
        let (mut open, mut closed) = (0, 0);
        for (k, a) in buffer.iter().enumerate() {
            if k % 5 == 0 {
                assert_eq!(*a, held, "pixel {k} held a sample");
                continue;
            }
            let ray = camera
                .ray((k as u32 % w) as f32 + 0.5, (k as u32 / w) as f32 + 0.5)
                .unwrap();
            if engine.intersect(&ray).is_some() {
                assert!(a.is_empty(), "pixel {k} sees a surface: {a:?}");
                closed += 1;
            } else {
                let dir = ray.dir.normalize();
                assert_eq!((a.z, a.object, a.point), (SKY_Z, SKY, dir), "pixel {k}");
                assert_eq!(a.radiance, sky_of(dir));
                open += 1;
            }
        }
        assert_eq!(opened, open);
        assert!(open > 100 && closed > 100, "{open} open, {closed} closed");
        // The centre pixel looks at the middle of the sun's disk.
        let centre = buffer[(h / 2 * w + w / 2) as usize];
        assert_eq!(centre.radiance, sun);
        assert_eq!(buffer[0].radiance, Vec3::ONE);
    }

    #[test]
    fn the_farther_neighbour_fills_a_hole_and_the_bound_holds() {
        // A row: near | hole | far. The hole takes the far value.
        let mut row = vec![at(1.0), Accum::default(), at(5.0)];
        assert_eq!(background(&mut row, 3, 1, 4), 1);
        assert_eq!(row[1].z, 5.0);
        // A hole 3 pixels from anything, with a bound of 2: stays empty
        // in the middle, the two ends are reached.
        let mut row = vec![
            at(1.0),
            Accum::default(),
            Accum::default(),
            Accum::default(),
        ];
        let mut row2 = row.clone();
        assert_eq!(background(&mut row, 4, 1, 2), 2);
        assert!(row[3].is_empty());
        assert_eq!(background(&mut row2, 4, 1, 3), 3);
        assert_eq!(row2[3].reach, 3);
    }
}

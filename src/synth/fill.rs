//! Background fill of the pixels no sample reached, as `pinterp -fb`: a
//! hole takes the farther of its candidates, so that the background, not
//! the foreground, spreads into what the bases did not see. Before it, each
//! hole's own ray is traced: a hole whose ray leaves the scene is given the
//! sky, and one whose ray meets an object takes a candidate of that object
//! where it has one (a face the bases saw only at a grazing angle, its
//! samples too sparse to cover it, is not filled with the wall behind).

use rayon::prelude::*;

use super::base::SKY;
use super::warp::{Accum, SKY_Z};
use crate::accel::RayEngine;
use crate::camera::Camera;

/// What a hole's centre ray met: the object and its distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seen {
    pub pixel: usize,
    pub object: u32,
    pub z: f32,
}

/// Traces the centre ray of each hole of `camera`'s frame in `engine`.
/// A hole whose ray meets nothing is given the radiance `sky` gives its
/// direction, as a sample of the sky: through an opening (a window, past a
/// roof's edge) the frame sees sky in directions no base saw through it,
/// and a background fill would spread the wall beside the opening over
/// them. Returns the number of such holes, and what the others' rays met
/// (in pixel order) for [`background`].
pub fn sky(
    engine: &dyn RayEngine,
    sky: &(dyn Fn(glam::Vec3) -> glam::Vec3 + Sync),
    camera: &Camera,
    buffer: &mut [Accum],
) -> (usize, Vec<Seen>) {
    let w = camera.width as usize;
    // Per hole: `None` where its ray left the scene (the hole is sky now).
    let traced: Vec<Option<Seen>> = buffer
        .par_iter_mut()
        .enumerate()
        .filter(|(_, a)| a.is_empty())
        .filter_map(|(k, a)| {
            let ray = camera.ray((k % w) as f32 + 0.5, (k / w) as f32 + 0.5)?;
            if let Some(hit) = engine.intersect(&ray) {
                return Some(Some(Seen {
                    pixel: k,
                    object: hit.object,
                    z: hit.t * ray.dir.length(),
                }));
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
            Some(None)
        })
        .collect();
    let open = traced.iter().filter(|t| t.is_none()).count();
    (open, traced.into_iter().flatten().collect())
}

/// Finds the cracks in surfaces. Where the footprints of a surface's
/// samples leave a pixel's centre uncovered (a face the bases saw at a
/// grazing angle, the seam between two bases' samples), a sample of what
/// lies behind covers it and decides it: a dot of the wall on a box. A
/// pixel whose two neighbours on one axis (or the pixels past a second one
/// like it) show one other object, nearer than it by more than the
/// `tolerance`, may be such a crack: returns each with the nearer of those two neighbours, for
/// [`repair_cracks`] to confirm.
pub fn cracks(buffer: &[Accum], width: u32, height: u32, tolerance: f32) -> Vec<(usize, usize)> {
    let (w, h) = (width as usize, height as usize);
    let cracked = |k: usize, a: usize, b: usize| -> Option<usize> {
        let (p, n1, n2) = (&buffer[k], &buffer[a], &buffer[b]);
        let before = |n: &Accum| !n.is_empty() && n.z < p.z * (1.0 - tolerance);
        (!p.is_empty()
            && n1.object == n2.object
            && n1.object != p.object
            && n1.object != SKY
            && before(n1)
            && before(n2))
        .then_some(if n1.z <= n2.z { a } else { b })
    };
    // The neighbours `step` apart on either side, or past a second pixel
    // like this one (a crack two pixels wide).
    let sides = |k: usize, step: usize, before: usize, after: usize| -> Option<(usize, usize)> {
        let reach = |room: usize, at: &dyn Fn(usize) -> usize| {
            (room >= 1).then(|| {
                let near = at(1);
                if room >= 2 && buffer[near].object == buffer[k].object {
                    at(2)
                } else {
                    near
                }
            })
        };
        let a = reach(before, &|d| k - d * step)?;
        let b = reach(after, &|d| k + d * step)?;
        Some((a, b))
    };
    (0..w * h)
        .into_par_iter()
        .filter_map(|k| {
            let (x, y) = (k % w, k / w);
            let across = || sides(k, 1, x, w - 1 - x).and_then(|(a, b)| cracked(k, a, b));
            let along = || sides(k, w, y, h - 1 - y).and_then(|(a, b)| cracked(k, a, b));
            Some((k, across().or_else(along)?))
        })
        .collect()
}

/// Gives each crack [`cracks`] found the neighbour it was found with where
/// the pixel's own ray in `engine` meets that neighbour's object. All are
/// judged on the buffer as warped: a repair makes or hides no other.
/// Returns the number repaired.
pub fn repair_cracks(
    engine: &dyn RayEngine,
    camera: &Camera,
    buffer: &mut [Accum],
    found: &[(usize, usize)],
) -> usize {
    let w = camera.width as usize;
    let confirmed: Vec<(usize, usize)> = found
        .par_iter()
        .copied()
        .filter(|&(k, from)| {
            camera
                .ray((k % w) as f32 + 0.5, (k / w) as f32 + 0.5)
                .and_then(|ray| engine.intersect(&ray))
                .is_some_and(|hit| hit.object == buffer[from].object)
        })
        .collect();
    for &(k, from) in &confirmed {
        buffer[k] = buffer[from];
    }
    confirmed.len()
}

/// Fills holes in scan order. A hole's candidates are the pixel above
/// (possibly filled just before), the first filled pixel below, the pixel
/// to the left and the first filled pixel to the right. Where its ray met
/// an object (`seen`, in pixel order) it takes the candidate of that object
/// nearest that depth; otherwise the farthest candidate. A value travels at
/// most `bound` pixels from a projected sample; holes beyond stay empty.
/// Returns the number of pixels filled.
pub fn background(
    buffer: &mut [Accum],
    width: u32,
    height: u32,
    bound: u16,
    seen: &[Seen],
) -> usize {
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
    let mut seen = seen.iter().peekable();
    for y in first..h {
        for x in 0..w {
            let k = y * w + x;
            if !buffer[k].is_empty() {
                continue;
            }
            while seen.next_if(|s| s.pixel < k).is_some() {}
            let met = seen.next_if(|s| s.pixel == k);
            // Better candidates rank higher: of the object the ray met,
            // then nearer that depth; else farther.
            let rank = |c: &Accum| match met {
                Some(m) if c.object == m.object => (1, -(c.z - m.z).abs()),
                _ => (0, c.z),
            };
            let mut best: Option<(Accum, u16)> = None;
            let mut offer = |c: Accum, reach: u16| {
                if c.is_empty() || reach > bound {
                    return;
                }
                if best.is_none_or(|(b, _)| rank(&c) > rank(&b)) {
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
        let (opened, seen) = sky(&*engine, &sky_of, &camera, &mut buffer);
        let (mut open, mut closed) = (0, 0);
        for (k, a) in buffer.iter().enumerate() {
            if k % 5 == 0 {
                assert_eq!(*a, held, "pixel {k} held a sample");
                continue;
            }
            let ray = camera
                .ray((k as u32 % w) as f32 + 0.5, (k as u32 / w) as f32 + 0.5)
                .unwrap();
            if let Some(hit) = engine.intersect(&ray) {
                assert!(a.is_empty(), "pixel {k} sees a surface: {a:?}");
                let met = seen.iter().find(|s| s.pixel == k);
                assert_eq!(
                    met.map(|s| s.object),
                    Some(hit.object),
                    "pixel {k}: what its ray met"
                );
                closed += 1;
            } else {
                let dir = ray.dir.normalize();
                assert_eq!((a.z, a.object, a.point), (SKY_Z, SKY, dir), "pixel {k}");
                assert_eq!(a.radiance, sky_of(dir));
                open += 1;
            }
        }
        assert_eq!(opened, open);
        assert_eq!(seen.len(), closed);
        assert!(seen.windows(2).all(|p| p[0].pixel < p[1].pixel));
        assert!(open > 100 && closed > 100, "{open} open, {closed} closed");
        // The centre pixel looks at the middle of the sun's disk.
        let centre = buffer[(h / 2 * w + w / 2) as usize];
        assert_eq!(centre.radiance, sun);
        assert_eq!(buffer[0].radiance, Vec3::ONE);
    }

    /// A crack in a face seen at a grazing angle: its ray meets the face,
    /// so it takes the face's neighbour, not the wall behind; a hole whose
    /// ray met an object no candidate shows takes the farther one.
    #[test]
    fn a_hole_takes_the_object_its_ray_met() {
        let face = Accum {
            object: 3,
            ..at(1.0)
        };
        let wall = Accum {
            object: 7,
            ..at(5.0)
        };
        let seen = |object| {
            [Seen {
                pixel: 1,
                object,
                z: 1.1,
            }]
        };
        let mut row = vec![face, Accum::default(), wall];
        assert_eq!(background(&mut row, 3, 1, 4, &seen(3)), 1);
        assert_eq!(row[1].object, 3);
        let mut row = vec![face, Accum::default(), wall];
        assert_eq!(background(&mut row, 3, 1, 4, &seen(9)), 1);
        assert_eq!(row[1].object, 7);
    }

    #[test]
    fn the_farther_neighbour_fills_a_hole_and_the_bound_holds() {
        // A row: near | hole | far. The hole takes the far value.
        let mut row = vec![at(1.0), Accum::default(), at(5.0)];
        assert_eq!(background(&mut row, 3, 1, 4, &[]), 1);
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
        assert_eq!(background(&mut row, 4, 1, 2, &[]), 2);
        assert!(row[3].is_empty());
        assert_eq!(background(&mut row2, 4, 1, 3, &[]), 3);
        assert_eq!(row2[3].reach, 3);
    }
}

//! A frame's range image from its z-buffer: subpixels averaged into
//! pixels, two times' frames blended per pixel, and each pixel's surface
//! (distance, ids, normal) as a render would report it.

use anyhow::Result;
use glam::{Affine3A, Vec3};
use rayon::prelude::*;

use super::lights;
use super::warp::{Accum, SKY_Z};
use crate::alloc;
use crate::camera::Camera;
use crate::image::{RangeImage, RangeMeta, NO_HIT};
use crate::scene::Scene;

/// A frame of `camera` (with `meta`) from its synthesis at `k` × `k`
/// subpixels a pixel: subpixel `j` was reached by some sample (`seen`),
/// holds `radiance(j)` and shows object `object(j)`, whose surface is
/// `surface(j)` (distance, object, primitive, normal). A pixel's radiance is the mean of its seen
/// subpixels; its surface that of the seen subpixel nearest its centre,
/// with the distance where its centre ray meets that surface's triangle
/// (at `poses`), as a render's would be; a pixel none reached is a hole. A
/// pixel part of which shows a light takes the light's surface, so that
/// tracing lights' rims ([`lights`]) finds it. Written into `spare`'s
/// planes where given. Returns the frame, its holes, and which pixels'
/// subpixels show more than one object (their values mix surfaces:
/// [`lights::trace`] mends them).
#[allow(clippy::too_many_arguments)]
pub(super) fn downsample(
    scene: &Scene,
    poses: &[Affine3A],
    spare: Option<RangeImage>,
    (camera, k, meta): (&Camera, u32, &RangeMeta),
    seen: impl Fn(usize) -> bool + Sync,
    radiance: impl Fn(usize) -> Vec3 + Sync,
    object: impl Fn(usize) -> u32 + Sync,
    surface: impl Fn(usize) -> (f32, u32, u32, Vec3) + Sync,
) -> Result<(RangeImage, usize, Vec<bool>)> {
    let mut image = blank(
        spare,
        RangeMeta {
            camera: *camera,
            ..meta.clone()
        },
    )?;
    let (w, k) = (camera.width as usize, k as usize);
    let fw = w * k;
    let emissive = lights::emissive(scene);
    let emits = |id: u32| emissive.get(id as usize).copied().unwrap_or(false);
    // Subpixel offsets, nearest the pixel's centre first.
    let mut order: Vec<(usize, usize)> = (0..k * k).map(|i| (i % k, i / k)).collect();
    let centre = (k as f32 - 1.0) * 0.5;
    order.sort_by(|a, b| {
        let d = |p: &(usize, usize)| (p.0 as f32 - centre).powi(2) + (p.1 as f32 - centre).powi(2);
        d(a).total_cmp(&d(b))
    });
    let mut mixed = Vec::new();
    alloc::resize(&mut mixed, image.len(), false, || {
        format!("which of {} pixels mix surfaces", image.len())
    })?;
    let holes = image
        .radiance
        .par_iter_mut()
        .zip(mixed.par_iter_mut())
        .zip(image.distance.par_iter_mut())
        .zip(image.object_id.par_iter_mut())
        .zip(image.primitive_id.par_iter_mut())
        .zip(image.normal.par_iter_mut())
        .enumerate()
        .map(
            |(i, (((((pixel, mixed), distance), shown_object), primitive), normal))| {
                let (x, y) = (i % w, i / w);
                let at = |(dx, dy): (usize, usize)| (y * k + dy) * fw + x * k + dx;
                let (mut sum, mut n, mut shown, mut light) = (Vec3::ZERO, 0u32, None, None);
                for &o in &order {
                    let j = at(o);
                    if !seen(j) {
                        continue;
                    }
                    sum += radiance(j);
                    n += 1;
                    *mixed |= shown.is_some_and(|s| object(s) != object(j));
                    shown.get_or_insert(j);
                    if light.is_none() && emits(object(j)) {
                        light = Some(j);
                    }
                }
                let Some(j) = light.or(shown) else {
                    // Written, as every pixel: the image may be recycled.
                    *pixel = Vec3::ZERO;
                    (*distance, *shown_object, *primitive, *normal) =
                        (0.0, NO_HIT, NO_HIT, Vec3::ZERO);
                    return 1;
                };
                *pixel = sum / n as f32;
                (*distance, *shown_object, *primitive, *normal) = surface(j);
                if let Some(d) =
                    centre_distance(scene, poses, camera, x, y, *shown_object, *primitive)
                {
                    *distance = d;
                }
                0
            },
        )
        .sum();
    Ok((image, holes, mixed))
}

/// Distance along pixel `(x, y)`'s centre ray to the plane of `object`'s
/// triangle `primitive` posed at `poses`; `None` for sky or where the ray
/// runs along the plane or meets it behind the camera.
fn centre_distance(
    scene: &Scene,
    poses: &[Affine3A],
    camera: &Camera,
    x: usize,
    y: usize,
    object: u32,
    primitive: u32,
) -> Option<f32> {
    let mesh = &scene.objects.get(object as usize)?.mesh;
    let &[i, j, l] = mesh.triangles.get(primitive as usize)?;
    let pose = poses[object as usize];
    let p = &mesh.positions;
    let a = pose.transform_point3(p[i as usize]);
    let n =
        (pose.transform_point3(p[j as usize]) - a).cross(pose.transform_point3(p[l as usize]) - a);
    let ray = camera.ray(x as f32 + 0.5, y as f32 + 0.5)?;
    let along = ray.dir.dot(n);
    let d = (a - ray.origin).dot(n) / along;
    (along.abs() > 1e-12 * n.length() && d > 0.0 && d.is_finite()).then_some(d)
}

/// `pcomb -s (1−α) A -s α B`, where `α` is the time fraction of the views
/// that reached the pixel; a pixel only one time reached takes that time.
pub(super) fn blend_linear(a: &Accum, b: &Accum) -> Accum {
    match (a.is_empty(), b.is_empty()) {
        (true, true) => *a,
        (false, true) => *a,
        (true, false) => *b,
        (false, false) => {
            // Mean fraction of the later views; the earlier ones carry 0.
            let alpha = (b.alpha / b.w).clamp(0.0, 1.0);
            let (ca, cb) = (a.radiance / a.w, b.radiance / b.w);
            let nearer = if alpha <= 0.5 { a } else { b };
            Accum {
                w: 1.0,
                radiance: ca * (1.0 - alpha) + cb * alpha,
                ..*nearer
            }
        }
    }
}

/// An image with `meta`, `spare`'s planes where given (stale: the caller
/// writes every pixel); an error saying what it needs where memory is
/// short.
pub(super) fn blank(spare: Option<RangeImage>, meta: RangeMeta) -> Result<RangeImage> {
    match spare {
        Some(image) => Ok(RangeImage { meta, ..image }),
        None => RangeImage::try_empty(meta),
    }
}

/// The frame's pixels from what they gathered, every one of them written
/// (an image may come from [`Synthesizer::recycle`]).
pub(super) fn write_pixels(
    scene: &Scene,
    poses: &[Affine3A],
    pixels: &[Accum],
    image: &mut RangeImage,
) {
    let cam = image.meta.camera.position;
    let row = image.width.max(1) as usize;
    image
        .radiance
        .par_chunks_mut(row)
        .zip(image.distance.par_chunks_mut(row))
        .zip(image.object_id.par_chunks_mut(row))
        .zip(image.primitive_id.par_chunks_mut(row))
        .zip(image.normal.par_chunks_mut(row))
        .zip(pixels.par_chunks(row))
        .for_each(
            |(((((radiance, distance), object), primitive), normal), a)| {
                // Neighbouring pixels mostly show one triangle: its normal is
                // worked out once for the run.
                let mut last: Option<((u32, u32), Option<Vec3>)> = None;
                for (j, a) in a.iter().enumerate() {
                    if a.is_empty() {
                        radiance[j] = Vec3::ZERO;
                        (distance[j], object[j], primitive[j], normal[j]) = shown(cam, a, None);
                        continue;
                    }
                    radiance[j] = a.radiance / a.w;
                    let key = (a.object, a.primitive);
                    let n = match last {
                        Some((k, n)) if k == key => n,
                        _ => {
                            let n = triangle_normal(scene, poses, a);
                            last = Some((key, n));
                            n
                        }
                    };
                    (distance[j], object[j], primitive[j], normal[j]) = shown(cam, a, n);
                }
            },
        );
}

/// The surface a pixel that gathered `a` shows: its distance, object and
/// primitive ids and the normal of its triangle at `poses`, turned towards
/// the camera at `cam`; distance 0, no ids and a zero normal for sky.
pub(super) fn surface(
    scene: &Scene,
    poses: &[Affine3A],
    cam: Vec3,
    a: &Accum,
) -> (f32, u32, u32, Vec3) {
    shown(cam, a, triangle_normal(scene, poses, a))
}

/// The unit normal at `poses` of the triangle `a` shows, unturned; `None`
/// for sky and for a primitive its mesh does not hold.
fn triangle_normal(scene: &Scene, poses: &[Affine3A], a: &Accum) -> Option<Vec3> {
    if a.is_empty() || a.z >= SKY_Z {
        return None;
    }
    let mesh = &scene.objects[a.object as usize].mesh;
    let &[i, j, l] = mesh.triangles.get(a.primitive as usize)?;
    let p = &mesh.positions;
    let e = (p[j as usize] - p[i as usize]).cross(p[l as usize] - p[i as usize]);
    Some(
        poses[a.object as usize]
            .transform_vector3(e)
            .normalize_or_zero(),
    )
}

/// [`surface`] from the triangle's normal `n` ([`triangle_normal`]).
fn shown(cam: Vec3, a: &Accum, n: Option<Vec3>) -> (f32, u32, u32, Vec3) {
    if a.is_empty() || a.z >= SKY_Z {
        return (0.0, NO_HIT, NO_HIT, Vec3::ZERO);
    }
    let Some(n) = n else {
        return (a.z, a.object, a.primitive, Vec3::ZERO);
    };
    let n = if n.dot(cam - a.point) < 0.0 { -n } else { n };
    (a.z, a.object, a.primitive, n)
}

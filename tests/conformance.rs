//! One conformance suite for every ray engine in the build.
//!
//! Each check runs for every backend in `Backend::available()` and compares
//! the engine with a brute-force reference written here: a loop over every
//! world-space triangle with Möller–Trumbore in `f64`. Where the reference
//! itself cannot tell the answer apart from rounding (a ray within a hair of
//! an edge, a grazing ray, two surfaces at the same distance), any answer that
//! is right for one of the candidates is accepted, but such cases must stay
//! rare so a sloppy engine cannot hide behind them.

use glam::{Affine3A, DVec3, Quat, Vec3};
use proptest::prelude::*;
use rangewalk::accel::{self, Backend, Hit, InstancedEngine};
use rangewalk::ray::{offset_origin, Ray};
use rangewalk::rng::SplitMix64;
use rangewalk::scene::MeshGeometry;

// ---------------------------------------------------------------------------
// Helpers: a seeded generator, approximate assertions, engines per backend.

/// Fixed-seed inputs from the library's SplitMix64.
struct Rng(SplitMix64);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(SplitMix64::new(seed))
    }
    fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }
    /// Uniform in `[0, 1)`.
    fn f32(&mut self) -> f32 {
        self.0.next_f32()
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    fn in_box(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        Vec3::new(
            self.range(lo.x, hi.x),
            self.range(lo.y, hi.y),
            self.range(lo.z, hi.z),
        )
    }
    fn direction(&mut self) -> Vec3 {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f32::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

macro_rules! assert_close {
    ($a:expr, $b:expr, $tol:expr, $($ctx:tt)+) => {{
        let (a, b, tol) = ($a as f64, $b as f64, $tol as f64);
        assert!(
            (a - b).abs() <= tol,
            "{}: {} = {a}, {} = {b}, difference {} > {tol}",
            format!($($ctx)+),
            stringify!($a),
            stringify!($b),
            (a - b).abs()
        );
    }};
}

fn engine(
    backend: Backend,
    meshes: &[MeshGeometry],
    transforms: &[Affine3A],
) -> Box<dyn InstancedEngine> {
    accel::build(backend, meshes, transforms)
        .unwrap_or_else(|e| panic!("building the {backend} engine failed: {e:#}"))
}

// ---------------------------------------------------------------------------
// Geometry generators.

/// An axis-aligned box of 12 triangles over 8 shared corners. Face `f =
/// 2 * axis + side` (side 1 at `hi`) is triangles `2f` and `2f + 1`.
/// `outward` picks the winding: normals pointing out of or into the box.
fn box_mesh(lo: Vec3, hi: Vec3, outward: bool) -> MeshGeometry {
    let positions = (0..8)
        .map(|c| {
            Vec3::new(
                if c & 1 == 0 { lo.x } else { hi.x },
                if c & 2 == 0 { lo.y } else { hi.y },
                if c & 4 == 0 { lo.z } else { hi.z },
            )
        })
        .collect();
    let mut triangles = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in 0..2u32 {
            let corner = |i: u32, j: u32| (side << axis) | (i << u) | (j << v);
            let (c00, c10, c11, c01) = (corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1));
            // e_u x e_v = e_axis, so (c00, c10, c11) faces +axis.
            let faces_plus = (side == 1) == outward;
            if faces_plus {
                triangles.push([c00, c10, c11]);
                triangles.push([c00, c11, c01]);
            } else {
                triangles.push([c00, c11, c10]);
                triangles.push([c00, c01, c11]);
            }
        }
    }
    MeshGeometry {
        positions,
        triangles,
    }
}

fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> MeshGeometry {
    MeshGeometry {
        positions: vec![a, b, c, d],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// Random triangles of widely varying size and shape in `[-1, 1]^3`, with a
/// few degenerate ones (a repeated vertex) that must never be hit.
fn soup(rng: &mut Rng, n: usize) -> MeshGeometry {
    let mut mesh = MeshGeometry::default();
    for i in 0..n {
        let centre = rng.in_box(Vec3::splat(-1.0), Vec3::splat(1.0));
        let size = 10f32.powf(rng.range(-2.0, -0.3));
        let base = mesh.positions.len() as u32;
        let p0 = centre + rng.direction() * size;
        let p1 = centre + rng.direction() * size;
        let p2 = if i % 97 == 0 {
            p0
        } else {
            centre + rng.direction() * size
        };
        mesh.positions.extend([p0, p1, p2]);
        mesh.triangles.push([base, base + 1, base + 2]);
    }
    mesh
}

/// Rigid motion of one instance: spin about an object-space axis, then the
/// base placement, then a drift in world space.
#[derive(Clone, Copy)]
struct Motion {
    base: Affine3A,
    axis: Vec3,
    spin: f32,
    drift: Vec3,
}

impl Motion {
    fn still(base: Affine3A) -> Self {
        Self {
            base,
            axis: Vec3::Y,
            spin: 0.0,
            drift: Vec3::ZERO,
        }
    }
    fn at(&self, t: f32) -> Affine3A {
        Affine3A::from_translation(self.drift * t)
            * self.base
            * Affine3A::from_axis_angle(self.axis.normalize(), self.spin * t)
    }
}

struct TestScene {
    name: &'static str,
    meshes: Vec<MeshGeometry>,
    motion: Vec<Motion>,
    /// Where ray origins are drawn from.
    lo: Vec3,
    hi: Vec3,
}

impl TestScene {
    fn at(&self, t: f32) -> Vec<Affine3A> {
        self.motion.iter().map(|m| m.at(t)).collect()
    }
}

/// A closed room with a spinning box, a mirrored (negative determinant) box
/// that drifts, a mesh without triangles and a small box near a corner.
fn box_rooms() -> TestScene {
    let unit = box_mesh(Vec3::splat(-0.5), Vec3::splat(0.5), true);
    let meshes = vec![
        box_mesh(Vec3::ZERO, Vec3::splat(10.0), false),
        unit.clone(),
        unit.clone(),
        MeshGeometry::default(),
        box_mesh(Vec3::new(0.2, 0.2, 0.2), Vec3::new(0.9, 1.4, 0.6), true),
    ];
    let motion = vec![
        Motion::still(Affine3A::IDENTITY),
        Motion {
            base: Affine3A::from_scale_rotation_translation(
                Vec3::new(2.0, 1.0, 1.5),
                Quat::from_rotation_y(0.4),
                Vec3::new(3.0, 2.0, 4.0),
            ),
            axis: Vec3::new(0.3, 1.0, 0.1),
            spin: 1.3,
            drift: Vec3::new(0.5, 0.0, 1.0),
        },
        Motion {
            base: Affine3A::from_scale_rotation_translation(
                Vec3::new(-1.5, 1.0, 1.0),
                Quat::from_rotation_x(0.7),
                Vec3::new(7.0, 3.0, 6.0),
            ),
            axis: Vec3::Z,
            spin: -0.8,
            drift: Vec3::new(-1.0, 2.0, 0.0),
        },
        Motion::still(Affine3A::from_translation(Vec3::splat(5.0))),
        Motion::still(Affine3A::IDENTITY),
    ];
    TestScene {
        name: "box rooms",
        meshes,
        motion,
        lo: Vec3::splat(0.1),
        hi: Vec3::splat(9.9),
    }
}

/// Two soups, one of them instanced twice, moving through each other.
fn soups() -> TestScene {
    let mut rng = Rng::new(7);
    let big = soup(&mut rng, 1500);
    let small = soup(&mut rng, 400);
    TestScene {
        name: "triangle soups",
        meshes: vec![big, small.clone(), small],
        motion: vec![
            Motion::still(Affine3A::IDENTITY),
            Motion {
                base: Affine3A::from_scale_rotation_translation(
                    Vec3::splat(0.7),
                    Quat::from_rotation_z(0.3),
                    Vec3::new(0.5, 0.0, 0.0),
                ),
                axis: Vec3::X,
                spin: 2.0,
                drift: Vec3::new(-1.0, 0.2, 0.0),
            },
            Motion {
                base: Affine3A::from_scale_rotation_translation(
                    Vec3::new(1.0, 0.5, 2.0),
                    Quat::from_rotation_x(-1.0),
                    Vec3::new(0.0, -0.5, 0.3),
                ),
                axis: Vec3::Y,
                spin: 0.5,
                drift: Vec3::new(0.0, 0.0, -0.8),
            },
        ],
        lo: Vec3::splat(-2.0),
        hi: Vec3::splat(2.0),
    }
}

// ---------------------------------------------------------------------------
// The reference: every triangle in world space, Möller–Trumbore in f64.

struct WorldTriangle {
    object: u32,
    primitive: u32,
    p: [DVec3; 3],
}

fn world_triangles(meshes: &[MeshGeometry], transforms: &[Affine3A]) -> Vec<WorldTriangle> {
    let mut out = Vec::new();
    for (object, (mesh, m)) in meshes.iter().zip(transforms).enumerate() {
        let m = m.as_daffine3();
        for (primitive, tri) in mesh.triangles.iter().enumerate() {
            out.push(WorldTriangle {
                object: object as u32,
                primitive: primitive as u32,
                p: tri.map(|i| m.transform_point3(mesh.positions[i as usize].as_dvec3())),
            });
        }
    }
    out
}

/// A triangle the reference ray passes through or close to.
#[derive(Clone, Copy, Debug)]
struct Candidate {
    object: u32,
    primitive: u32,
    t: f64,
    u: f64,
    v: f64,
    normal: DVec3,
    corners: [DVec3; 3],
    /// Whether rounding could decide otherwise: the ray passes within a hair
    /// of an edge or grazes the plane.
    marginal: bool,
    /// How far an f32 engine's `t` may lie from `t`: 1e-4 relative, widened
    /// at grazing angles by what one ulp of the coordinates moves the hit
    /// along a ray that nearly parallels the plane.
    t_tol: f64,
}

/// Barycentric margin below which a hit is too close to an edge to call.
const EDGE_MARGIN: f64 = 1e-4;
/// `|cos|` between ray and plane below which a hit is grazing: rounding of
/// the origin grows by `1 / |cos|` along the ray, beyond the tolerances.
const GRAZING: f64 = 1e-2;

fn candidates(tris: &[WorldTriangle], ray: &Ray) -> Vec<Candidate> {
    let o = ray.origin.as_dvec3();
    let d = ray.dir.as_dvec3();
    let (tmin, tmax) = (ray.tmin as f64, ray.tmax as f64);
    let mut out = Vec::new();
    for tri in tris {
        let [p0, p1, p2] = tri.p;
        let (e1, e2) = (p1 - p0, p2 - p0);
        let n = e1.cross(e2);
        if n.length_squared() == 0.0 {
            continue;
        }
        let pvec = d.cross(e2);
        let det = e1.dot(pvec);
        if det == 0.0 {
            continue;
        }
        let inv = 1.0 / det;
        let s = o - p0;
        let u = s.dot(pvec) * inv;
        let q = s.cross(e1);
        let v = d.dot(q) * inv;
        let t = e2.dot(q) * inv;
        let margin = u.min(v).min(1.0 - u - v);
        let cos = n.normalize().dot(d.normalize()).abs();
        let mut t_tol = t_tolerance(t);
        if cos < GRAZING {
            let scale = tri
                .p
                .iter()
                .fold(o.abs().max_element(), |m, p| m.max(p.abs().max_element()));
            t_tol += 4.0 * f32::EPSILON as f64 * scale / (d.length() * cos.max(1e-12));
        }
        if margin < -EDGE_MARGIN || t < tmin - t_tol || t > tmax + t_tol {
            continue;
        }
        out.push(Candidate {
            object: tri.object,
            primitive: tri.primitive,
            t,
            u,
            v,
            normal: n.normalize(),
            corners: tri.p,
            marginal: margin <= EDGE_MARGIN
                || cos < GRAZING
                || t < tmin + t_tol
                || t > tmax - t_tol,
            t_tol,
        });
    }
    out.sort_by(|a, b| a.t.total_cmp(&b.t));
    out
}

/// `t` agreement demanded: 1e-4 relative, as between the two engines.
fn t_tolerance(t: f64) -> f64 {
    1e-4 * t.abs().max(1e-3)
}

/// How a batch of engine answers compared with the reference.
#[derive(Default, Debug)]
struct Tally {
    rays: usize,
    /// The engine named the reference's closest triangle (or both missed).
    exact: usize,
}

/// Checks one closest-hit answer; panics with the ray when it is wrong.
fn check_hit(label: &str, ray: &Ray, got: Option<Hit>, cands: &[Candidate], tally: &mut Tally) {
    tally.rays += 1;
    let first_clear = cands.iter().find(|c| !c.marginal);
    match got {
        None => {
            assert!(
                first_clear.is_none(),
                "{label}: missed, but the reference hits {first_clear:?}; {ray:?}"
            );
            tally.exact += usize::from(cands.is_empty());
        }
        Some(h) => {
            let Some(c) = cands
                .iter()
                .find(|c| c.object == h.object && c.primitive == h.primitive)
            else {
                panic!("{label}: hit {h:?}, a triangle the reference does not hit; candidates {cands:?}; {ray:?}")
            };
            assert_close!(h.t, c.t, c.t_tol, "{label}: t of {h:?}; {ray:?}");
            if let Some(f) = first_clear {
                assert!(
                    h.t as f64 <= f.t + t_tolerance(f.t),
                    "{label}: hit {h:?} lies behind the reference's {f:?}; {ray:?}"
                );
            }
            if !c.marginal {
                // Barycentrics of slivers are ill-conditioned; the point they
                // name is not, so compare that with the reference hit point.
                let [p0, p1, p2] = c.corners;
                let (u, v) = (h.u as f64, h.v as f64);
                let named = p0 * (1.0 - u - v) + p1 * u + p2 * v;
                let exact = ray.origin.as_dvec3() + ray.dir.as_dvec3() * c.t;
                let scale = c.t * ray.dir.as_dvec3().length() + exact.abs().max_element();
                let off = (named - exact).length();
                assert!(
                    off <= 2e-5 * scale,
                    "{label}: barycentrics of {h:?} name a point {off} away from the hit (reference u {}, v {}); {ray:?}",
                    c.u,
                    c.v
                );
                assert_close!(h.normal.length(), 1.0, 1e-4, "{label}: |normal| of {h:?}");
                let agree = h.normal.as_dvec3().dot(c.normal);
                assert!(
                    agree > 0.9999,
                    "{label}: normal {} vs reference {}; {ray:?}",
                    h.normal,
                    c.normal
                );
            }
            let closest = &cands[0];
            tally.exact +=
                usize::from(closest.object == h.object && closest.primitive == h.primitive);
        }
    }
}

fn check_occluded(label: &str, ray: &Ray, got: bool, cands: &[Candidate]) {
    if cands.iter().any(|c| !c.marginal) {
        assert!(
            got,
            "{label}: not occluded, but the reference hits {cands:?}; {ray:?}"
        );
    } else if cands.is_empty() {
        assert!(
            !got,
            "{label}: occluded, but the reference hits nothing; {ray:?}"
        );
    }
}

/// Random rays for a scene: half aimed at a point of a random triangle, half
/// in random directions; direction lengths vary (t is in units of `dir`) and
/// a third are segments with a positive `tmin` and a finite `tmax`.
fn random_rays(
    rng: &mut Rng,
    (lo, hi): (Vec3, Vec3),
    tris: &[WorldTriangle],
    n: usize,
) -> Vec<Ray> {
    (0..n)
        .map(|i| {
            let origin = rng.in_box(lo, hi);
            let aim = if i % 2 == 0 && !tris.is_empty() {
                let tri = &tris[rng.below(tris.len())];
                let (a, b) = (rng.f32() as f64, rng.f32() as f64);
                let (a, b) = if a + b > 1.0 {
                    (1.0 - a, 1.0 - b)
                } else {
                    (a, b)
                };
                let target = tri.p[0] + (tri.p[1] - tri.p[0]) * a + (tri.p[2] - tri.p[0]) * b;
                (target.as_vec3() - origin).normalize_or(Vec3::X)
            } else {
                rng.direction()
            };
            let dir = aim * 10f32.powf(rng.range(-1.0, 1.0));
            if i % 3 == 0 {
                let extent = (hi - lo).length() / dir.length();
                let tmin = rng.range(0.0, 0.1) * extent;
                Ray {
                    origin,
                    dir,
                    tmin,
                    tmax: tmin + rng.range(0.0, 1.0) * extent,
                }
            } else {
                Ray::new(origin, dir)
            }
        })
        .collect()
}

// ---------------------------------------------------------------------------
// Conformance against the reference.

/// Every backend against the brute-force reference on one scene at several
/// times, the engine moved between times with `set_transforms`.
fn agree_with_reference(
    name: &str,
    meshes: &[MeshGeometry],
    at: &dyn Fn(f32) -> Vec<Affine3A>,
    bounds: (Vec3, Vec3),
    times: &[f32],
    rays_per_time: usize,
) {
    for &backend in Backend::available() {
        let mut eng = engine(backend, meshes, &at(times[0]));
        let mut rng = Rng::new(0x5EED);
        let mut tally = Tally::default();
        for &time in times {
            let transforms = at(time);
            eng.set_transforms(&transforms)
                .unwrap_or_else(|e| panic!("{backend}: set_transforms: {e:#}"));
            let tris = world_triangles(meshes, &transforms);
            let rays = random_rays(&mut rng, bounds, &tris, rays_per_time);
            let mut hits = vec![None; rays.len()];
            eng.intersect_batch(&rays, &mut hits);
            let mut blocked = vec![false; rays.len()];
            eng.occluded_batch(&rays, &mut blocked);
            let label = format!("{backend} on {name} at t={time}");
            for (i, ray) in rays.iter().enumerate() {
                let cands = candidates(&tris, ray);
                check_hit(&label, ray, hits[i], &cands, &mut tally);
                check_occluded(&label, ray, blocked[i], &cands);
                if i % 5 == 0 {
                    // Single-ray calls answer like the batches.
                    let mut single = Tally::default();
                    check_hit(&label, ray, eng.intersect(ray), &cands, &mut single);
                    check_occluded(&label, ray, eng.occluded(ray), &cands);
                }
            }
        }
        assert!(
            tally.exact as f64 >= 0.995 * tally.rays as f64,
            "{backend} on {name}: only {} of {} rays found the reference's closest triangle",
            tally.exact,
            tally.rays
        );
    }
}

#[test]
fn engines_agree_with_the_reference_on_generated_scenes() {
    for scene in [box_rooms(), soups()] {
        let at = |t: f32| scene.at(t);
        agree_with_reference(
            scene.name,
            &scene.meshes,
            &at,
            (scene.lo, scene.hi),
            &[0.0, 0.5, 1.0],
            3000,
        );
    }
}

#[test]
fn engines_agree_with_the_reference_on_every_bundled_scene() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path().join("scene.toml");
        let scene = rangewalk::scene::Scene::load(&path).unwrap_or_else(|e| panic!("{e:#}"));
        let a = scene.animation;
        let times: Vec<f32> = (0..4)
            .map(|k| a.start + (a.end - a.start) * k as f32 / 3.0)
            .collect();
        // Origins inside and around the scene, from its bounds at the start.
        let (lo, hi) = scene.bounds(a.start);
        let pad = (hi - lo) * 0.1;
        let at = |t: f32| scene.at(t);
        agree_with_reference(
            &path.display().to_string(),
            &scene.geometry(),
            &at,
            (lo - pad, hi + pad),
            &times,
            600,
        );
        n += 1;
    }
    assert!(n >= 5, "found only {n} bundled scenes in {}", dir.display());
}

#[test]
fn empty_scenes_miss_everything() {
    let no_triangles = vec![
        MeshGeometry::default(),
        MeshGeometry {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            triangles: vec![],
        },
    ];
    for &backend in Backend::available() {
        for meshes in [vec![], no_triangles.clone()] {
            let transforms = vec![Affine3A::IDENTITY; meshes.len()];
            let eng = engine(backend, &meshes, &transforms);
            let mut rng = Rng::new(3);
            for _ in 0..100 {
                let ray = Ray::new(
                    rng.in_box(Vec3::splat(-1.0), Vec3::splat(1.0)),
                    rng.direction(),
                );
                assert_eq!(
                    eng.intersect(&ray),
                    None,
                    "{backend}: {} meshes",
                    meshes.len()
                );
                assert!(!eng.occluded(&ray), "{backend}: {} meshes", meshes.len());
            }
        }
    }
}

#[test]
fn bad_input_is_an_error_naming_the_mesh() {
    let good = quad(Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y);
    let bad = MeshGeometry {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    };
    for &backend in Backend::available() {
        let meshes = [good.clone(), bad.clone()];
        let err = accel::build(backend, &meshes, &[Affine3A::IDENTITY; 2])
            .err()
            .unwrap_or_else(|| panic!("{backend}: vertex index 3 of a 3-vertex mesh was accepted"));
        assert!(
            format!("{err:#}").contains("mesh 1"),
            "{backend}: error `{err:#}` does not name mesh 1"
        );
        assert!(
            accel::build(backend, &meshes[..1], &[]).is_err(),
            "{backend}: one mesh with no transform was accepted"
        );
    }
}

// ---------------------------------------------------------------------------
// Triangle and box truths.

/// A transform drawn from proptest: rotation, non-uniform scale (possibly
/// mirroring) and translation.
/// Uniform `f32` in `[lo, hi)` drawn through integers: proptest's own float
/// range sampler can trip an internal assertion on some seeds.
fn real(lo: f32, hi: f32) -> impl Strategy<Value = f32> {
    (0u32..1 << 24).prop_map(move |k| lo + (hi - lo) * (k as f32 / (1u32 << 24) as f32))
}

fn any_transform() -> impl Strategy<Value = Affine3A> {
    (
        prop::array::uniform3(real(-1.0, 1.0)),
        real(0.0, 6.2),
        prop::array::uniform3(real(0.3, 3.0)),
        prop::array::uniform3(any::<bool>()),
        prop::array::uniform3(real(-5.0, 5.0)),
    )
        .prop_map(|(axis, angle, scale, mirror, shift)| {
            let axis = Vec3::from(axis).normalize_or(Vec3::Y);
            let s = Vec3::from(scale) * Vec3::from(mirror.map(|m| if m { -1.0 } else { 1.0 }));
            Affine3A::from_scale_rotation_translation(
                s,
                Quat::from_axis_angle(axis, angle),
                Vec3::from(shift),
            )
        })
}

fn any_point() -> impl Strategy<Value = Vec3> {
    prop::array::uniform3(real(-2.0, 2.0)).prop_map(Vec3::from)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// A ray aimed at an interior point hits it at the expected `t` with the
    /// point's barycentrics and the winding normal; aimed outside, it misses.
    #[test]
    fn rays_find_triangle_points(
        corners in prop::array::uniform3(any_point()),
        m in any_transform(),
        (a, b) in (real(0.02, 0.96), real(0.02, 0.96)).prop_filter("inside", |(a, b)| a + b < 0.98),
        outside in (real(0.02, 0.5), 0usize..3),
        from in any_point(),
        length in real(0.1, 10.0),
    ) {
        let [p0, p1, p2] = corners;
        let n_obj = (p1 - p0).cross(p2 - p0);
        prop_assume!(n_obj.length() > 0.05 * (p1 - p0).length() * (p2 - p0).length().max(1e-3));
        let mesh = MeshGeometry { positions: corners.to_vec(), triangles: vec![[0, 1, 2]] };
        let w = corners.map(|p| m.transform_point3(p));
        let normal = (w[1] - w[0]).cross(w[2] - w[0]).normalize();
        let origin = m.transform_point3(from) + normal * 0.5;
        let target = w[0] * (1.0 - a - b) + w[1] * a + w[2] * b;
        let dir = (target - origin) * (1.0 / length);
        prop_assume!(dir.normalize().dot(normal).abs() > 0.05);
        // A point beyond one edge by `outside.0` in barycentric terms.
        let mut bary = [1.0 - a - b, a, b];
        let k = outside.1;
        let push = bary[k] + outside.0;
        bary[k] -= push;
        bary[(k + 1) % 3] += push;
        let beyond = w[0] * bary[0] + w[1] * bary[1] + w[2] * bary[2];
        for &backend in Backend::available() {
            let eng = engine(backend, std::slice::from_ref(&mesh), &[m]);
            let h = eng.intersect(&Ray::new(origin, dir));
            let h = h.unwrap_or_else(|| panic!("{backend}: missed the interior point {target}"));
            prop_assert_eq!((h.object, h.primitive), (0, 0));
            assert_close!(h.t, length, 1e-4 * length, "{backend}: t");
            assert_close!(h.u, a, 1e-3, "{backend}: u");
            assert_close!(h.v, b, 1e-3, "{backend}: v");
            prop_assert!(h.normal.dot(normal) > 0.9999, "{}: normal {} vs {}", backend, h.normal, normal);
            prop_assert!(eng.occluded(&Ray::segment(origin, dir, length * 1.001)));
            prop_assert!(!eng.occluded(&Ray::segment(origin, dir, length * 0.999)));
            let miss = Ray::new(origin, beyond - origin);
            prop_assert_eq!(eng.intersect(&miss), None, "{} hit a point outside", backend);
            prop_assert!(!eng.occluded(&miss));
        }
    }

    /// From inside a closed box every ray hits exactly the face the analytic
    /// exit distance names; from outside, a ray aimed at a face point hits
    /// that face at the analytic distance.
    #[test]
    fn rays_meet_box_faces(
        lo in prop::array::uniform3(real(-3.0, 0.0)).prop_map(Vec3::from),
        size in prop::array::uniform3(real(0.2, 4.0)).prop_map(Vec3::from),
        inside in prop::array::uniform3(real(0.01, 0.99)).prop_map(Vec3::from),
        dir in prop::array::uniform3(real(-1.0, 1.0)).prop_map(Vec3::from),
        face in 0usize..6,
        on_face in prop::array::uniform2(real(0.01, 0.99)),
        distance in real(0.1, 5.0),
        slant in prop::array::uniform2(real(-0.8, 0.8)),
        outward in any::<bool>(),
    ) {
        prop_assume!(dir.length() > 0.1);
        let hi = lo + size;
        let mesh = box_mesh(lo, hi, outward);
        let origin = lo + size * inside;
        let exit = |axis: usize| {
            let bound = if dir[axis] > 0.0 { hi[axis] } else { lo[axis] };
            (bound - origin[axis]) / dir[axis]
        };
        let t_exit = (0..3).map(exit).fold(f32::INFINITY, f32::min);

        let (axis, side) = (face / 2, face % 2);
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut target = Vec3::ZERO;
        target[axis] = if side == 1 { hi[axis] } else { lo[axis] };
        target[u] = lo[u] + size[u] * on_face[0];
        target[v] = lo[v] + size[v] * on_face[1];
        let out_normal = if side == 1 { 1.0 } else { -1.0 };
        let mut from = target;
        from[axis] += out_normal * distance;
        from[u] += slant[0] * distance;
        from[v] += slant[1] * distance;

        for &backend in Backend::available() {
            let eng = engine(backend, std::slice::from_ref(&mesh), &[Affine3A::IDENTITY]);
            let h = eng.intersect(&Ray::new(origin, dir));
            let h = h.unwrap_or_else(|| panic!("{backend}: escaped the box from {origin} along {dir}"));
            let hit_axis = h.primitive as usize / 4;
            assert_close!(exit(hit_axis), t_exit, 1e-4 * t_exit, "{}: face {} is not the exit face", backend, h.primitive / 2);
            assert_close!(h.t, t_exit, 1e-4 * t_exit.max(1e-3), "{backend}: exit t");
            let p = origin + dir * h.t;
            assert_close!(p[hit_axis], if dir[hit_axis] > 0.0 { hi[hit_axis] } else { lo[hit_axis] }, 1e-4, "{backend}: hit point on the face plane");

            let ray = Ray::new(from, target - from);
            let h = eng.intersect(&ray);
            let h = h.unwrap_or_else(|| panic!("{backend}: missed face {face} at {target} from {from}"));
            prop_assert_eq!(h.primitive as usize / 2, face, "{} hit the wrong face", backend);
            assert_close!(h.t, 1.0, 1e-4, "{backend}: t to the face point");
            let expected = out_normal * if outward { 1.0 } else { -1.0 };
            assert_close!(h.normal[axis], expected, 1e-5, "{backend}: face normal");
        }
    }
}

// ---------------------------------------------------------------------------
// Self-intersection at every scale, and moving instances.

/// A room with two boxes, at `scale`: the room's vertices are scaled, the
/// boxes are unit meshes placed by scaled transforms, so both the per-mesh
/// hierarchy and the instance path meet the scale.
fn scaled_box_scene(scale: f32) -> (Vec<MeshGeometry>, Vec<Affine3A>) {
    let shift = Vec3::new(3.0, 1.0, -2.0) * scale;
    let room = box_mesh(shift, shift + Vec3::splat(10.0 * scale), false);
    let unit = box_mesh(Vec3::splat(-0.5), Vec3::splat(0.5), true);
    let place = |s: Vec3, angle: f32, at: Vec3| {
        Affine3A::from_scale_rotation_translation(
            s * scale,
            Quat::from_rotation_y(angle),
            shift + at * scale,
        )
    };
    (
        vec![room, unit.clone(), unit],
        vec![
            Affine3A::IDENTITY,
            place(Vec3::new(3.0, 3.0, 3.0), 0.3, Vec3::new(3.0, 1.5, 3.0)),
            place(Vec3::new(3.0, 6.0, 3.0), -0.3, Vec3::new(7.0, 3.0, 6.5)),
        ],
    )
}

#[test]
fn offset_rays_do_not_hit_their_own_surface_at_any_scale() {
    for scale in [1e-4f32, 1e-2, 1.0, 1e2, 1e4] {
        let (meshes, transforms) = scaled_box_scene(scale);
        let shift = Vec3::new(3.0, 1.0, -2.0) * scale;
        for &backend in Backend::available() {
            let eng = engine(backend, &meshes, &transforms);
            let mut rng = Rng::new(11);
            for path in 0..300 {
                let mut ray = Ray::new(
                    shift + rng.in_box(Vec3::splat(0.5), Vec3::splat(9.5)) * scale,
                    rng.direction(),
                );
                let label = format!("{backend} at scale {scale}, path {path}");
                for bounce in 0..4 {
                    let h = eng.intersect(&ray).unwrap_or_else(|| {
                        panic!("{label}, bounce {bounce}: left the closed room; {ray:?}")
                    });
                    let p = ray.at(h.t);
                    // A direction into the hemisphere the ray arrived from.
                    let facing = if h.normal.dot(ray.dir) < 0.0 {
                        h.normal
                    } else {
                        -h.normal
                    };
                    let mut dir = rng.direction();
                    if dir.dot(facing) < 0.0 {
                        dir = -dir;
                    }
                    let next = Ray::new(offset_origin(p, h.normal, dir), dir);
                    let h2 = eng.intersect(&next).unwrap_or_else(|| {
                        panic!("{label}, bounce {bounce}: left the closed room; {next:?}")
                    });
                    assert!(
                        !(h2.object == h.object && h2.primitive / 2 == h.primitive / 2),
                        "{label}, bounce {bounce}: hit its own face again at t = {} ({h:?} then {h2:?})",
                        h2.t
                    );
                    assert!(
                        !eng.occluded(&Ray::segment(next.origin, next.dir, h2.t * 0.999)),
                        "{label}, bounce {bounce}: occluded before its first hit; {next:?}"
                    );
                    ray = next;
                }
            }
        }
    }
}

#[test]
fn moving_an_instance_moves_its_hits() {
    let cube = box_mesh(Vec3::splat(-0.5), Vec3::splat(0.5), true);
    let floor = quad(
        Vec3::new(-50.0, -50.0, 20.0),
        Vec3::new(50.0, -50.0, 20.0),
        Vec3::new(50.0, 50.0, 20.0),
        Vec3::new(-50.0, 50.0, 20.0),
    );
    let meshes = [floor, cube];
    let at = |p: Vec3| [Affine3A::IDENTITY, Affine3A::from_translation(p)];
    let ray = Ray::new(Vec3::ZERO, Vec3::Z * 2.0);
    for &backend in Backend::available() {
        let mut eng = engine(backend, &meshes, &at(Vec3::new(0.0, 0.0, 5.0)));
        let h = eng.intersect(&ray).expect("cube ahead");
        assert_eq!(h.object, 1, "{backend}");
        assert_close!(h.t, 2.25, 1e-5, "{backend}: cube at z = 5");
        assert!(
            (h.normal - Vec3::NEG_Z).length() < 1e-5,
            "{backend}: normal {}",
            h.normal
        );

        eng.set_transforms(&at(Vec3::new(0.0, 0.0, 9.0))).unwrap();
        let h = eng.intersect(&ray).expect("cube further ahead");
        assert_eq!(h.object, 1, "{backend}");
        assert_close!(h.t, 4.25, 1e-5, "{backend}: cube moved to z = 9");
        assert!(
            eng.occluded(&Ray::segment(ray.origin, ray.dir, 4.3)),
            "{backend}"
        );
        assert!(
            !eng.occluded(&Ray::segment(ray.origin, ray.dir, 4.2)),
            "{backend}"
        );

        eng.set_transforms(&at(Vec3::new(3.0, 0.0, 9.0))).unwrap();
        let h = eng.intersect(&ray).expect("floor behind");
        assert_eq!(
            h.object, 0,
            "{backend}: the cube moved aside, the floor remains"
        );
        assert_close!(h.t, 10.0, 1e-5, "{backend}: floor at z = 20");
        let aside = Ray::new(Vec3::new(3.0, 0.0, 0.0), Vec3::Z);
        assert_close!(
            eng.intersect(&aside).expect("cube aside").t,
            8.5,
            1e-5,
            "{backend}"
        );

        assert!(
            eng.set_transforms(&[Affine3A::IDENTITY]).is_err(),
            "{backend}: too few transforms accepted"
        );
    }
}

/// Rays from inside a closed box aimed exactly at its edges and corners, the
/// places where rounding in node or triangle tests lets rays escape.
#[test]
fn rays_into_edges_and_corners_never_escape() {
    let mut rng = Rng::new(23);
    for scale in [1e-4f32, 1.0, 1e4] {
        let lo = Vec3::new(-1.3, 0.2, 2.0) * scale;
        let hi = lo + Vec3::new(2.0, 0.7, 3.1) * scale;
        let transforms = [Affine3A::IDENTITY, Affine3A::from_scale(Vec3::splat(scale))];
        let unit_room = box_mesh(lo / scale, hi / scale, false);
        for &backend in Backend::available() {
            // The same room once in scaled vertices, once by a scaled instance;
            // only one of them is placed so they never overlap.
            for (which, mesh) in [box_mesh(lo, hi, false), unit_room.clone()]
                .into_iter()
                .enumerate()
            {
                let eng = engine(
                    backend,
                    std::slice::from_ref(&mesh),
                    &transforms[which..=which],
                );
                for i in 0..2000 {
                    let mut target = rng.in_box(lo, hi);
                    // Pin two coordinates (an edge) or all three (a corner).
                    let pinned = if i % 4 == 0 { 3 } else { 2 };
                    let free = rng.below(3);
                    for k in (0..3).filter(|&k| pinned == 3 || k != free) {
                        target[k] = if rng.f32() < 0.5 { lo[k] } else { hi[k] };
                    }
                    let origin = lo + (hi - lo) * rng.in_box(Vec3::splat(0.05), Vec3::splat(0.95));
                    let ray = Ray::new(origin, target - origin);
                    let h = eng.intersect(&ray);
                    assert!(
                        h.is_some(),
                        "{backend} at scale {scale} (room {which}): escaped through {target}; {ray:?}"
                    );
                    assert_close!(
                        h.unwrap().t,
                        1.0,
                        1e-4,
                        "{backend}: t to the edge point {target}"
                    );
                    assert!(
                        eng.occluded(&ray),
                        "{backend} at scale {scale}: not occluded; {ray:?}"
                    );
                }
            }
        }
    }
}

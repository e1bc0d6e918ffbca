//! Radiosity with thin boxes against the walls: a chair rail must cost the
//! records no more light than it costs a traced bounce.

use std::path::Path;

use rangewalk::accel::{self, Backend};
use rangewalk::eval::metrics::luminance;
use rangewalk::quality::Quality;
use rangewalk::radiosity::lookup::IrradianceCache;
use rangewalk::radiosity::{solve, Simplified};
use rangewalk::render::{self, multipass, RenderSettings};
use rangewalk::scene::Scene;

type Quad = [[f32; 3]; 4];

/// `nu × nv` quads over the parallelogram from `o` along `u` and `v`.
fn grid(o: [f32; 3], u: [f32; 3], v: [f32; 3], nu: usize, nv: usize) -> Vec<Quad> {
    let at = |a: usize, b: usize| {
        [0, 1, 2].map(|k| o[k] + u[k] * a as f32 / nu as f32 + v[k] * b as f32 / nv as f32)
    };
    (0..nu)
        .flat_map(|i| (0..nv).map(move |j| (i, j)))
        .map(|(i, j)| [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)])
        .collect()
}

/// A 6 × 3 × 4 m room of white walls and ceiling on a darker floor,
/// tessellated at 0.5 m, lit by a point light; with `rails`, white chair
/// rails 6 cm tall and 3.5 cm deep (front, top and bottom faces, each one
/// long sliver as in the soda shop) touching the north and west walls at
/// 1 m. Written to `dir`.
fn room(dir: &Path, rails: bool) -> Scene {
    let (x, y, z) = (6.0, 3.0, 4.0);
    let mut objects = vec![
        (
            "floor",
            "floor",
            grid([0.0; 3], [0.0, 0.0, z], [x, 0.0, 0.0], 8, 12),
        ),
        (
            "ceiling",
            "white",
            grid([0.0, y, 0.0], [x, 0.0, 0.0], [0.0, 0.0, z], 12, 8),
        ),
        (
            "walls",
            "white",
            [
                grid([0.0; 3], [x, 0.0, 0.0], [0.0, y, 0.0], 12, 6),
                grid([0.0, 0.0, z], [0.0, y, 0.0], [x, 0.0, 0.0], 6, 12),
                grid([0.0; 3], [0.0, y, 0.0], [0.0, 0.0, z], 6, 8),
                grid([x, 0.0, 0.0], [0.0, 0.0, z], [0.0, y, 0.0], 8, 6),
            ]
            .concat(),
        ),
    ];
    if rails {
        let (y0, y1, d) = (0.97, 1.03, 0.035);
        let quads = vec![
            [
                [0.0, y0, z - d],
                [x, y0, z - d],
                [x, y1, z - d],
                [0.0, y1, z - d],
            ],
            [[0.0, y1, z - d], [x, y1, z - d], [x, y1, z], [0.0, y1, z]],
            [[0.0, y0, z], [x, y0, z], [x, y0, z - d], [0.0, y0, z - d]],
            [[d, y0, 0.0], [d, y1, 0.0], [d, y1, z], [d, y0, z]],
            [[d, y1, 0.0], [0.0, y1, 0.0], [0.0, y1, z], [d, y1, z]],
            [[0.0, y0, 0.0], [d, y0, 0.0], [d, y0, z], [0.0, y0, z]],
        ];
        objects.push(("rails", "white", quads));
    }
    let (mut obj, mut toml, mut n) = (String::new(), String::new(), 0);
    toml.push_str(
        "[[materials]]\nname = \"white\"\ntype = \"diffuse\"\nreflectance = [0.8, 0.8, 0.8]\n\n\
         [[materials]]\nname = \"floor\"\ntype = \"diffuse\"\nreflectance = [0.5, 0.45, 0.4]\n\n",
    );
    for (name, material, quads) in &objects {
        obj.push_str(&format!("o {name}\n"));
        for q in quads {
            for v in q {
                obj.push_str(&format!("v {} {} {}\n", v[0], v[1], v[2]));
            }
            obj.push_str(&format!(
                "f {} {} {}\nf {} {} {}\n",
                n + 1,
                n + 2,
                n + 3,
                n + 1,
                n + 3,
                n + 4
            ));
            n += 4;
        }
        toml.push_str(&format!(
            "[[objects]]\nname = \"{name}\"\nmesh = \"room.obj\"\ngroup = \"{name}\"\nmaterial = \"{material}\"\n\n"
        ));
    }
    toml.push_str(
        "[[lights]]\ntype = \"point\"\nposition = [3, 2.6, 2]\nintensity = [10, 10, 10]\n\n\
         [[cameras]]\nname = \"main\"\nposition = [4.5, 1.5, 0.6]\nlook_at = [2, 1.0, 4]\nvfov = 60\n",
    );
    std::fs::write(dir.join("room.obj"), obj).unwrap();
    std::fs::write(dir.join("scene.toml"), toml).unwrap();
    Scene::load(dir.join("scene.toml")).unwrap()
}

/// The mean luminance of the indirect layer (records or one traced
/// bounce) over two seeds, and its standard error.
fn indirect_mean(scene: &Scene, records: Option<&IrradianceCache>) -> (f64, f64) {
    let engine = accel::build(
        Backend::default_available(),
        &scene.geometry(),
        &scene.at(0.0),
    )
    .unwrap();
    let cam = scene.camera("main").unwrap().perspective(32, 32).unwrap();
    let indirect = match records {
        Some(cache) => multipass::Indirect::Records(cache),
        None => multipass::Indirect::Traced,
    };
    let [a, b] = [1, 2].map(|seed| {
        let settings = RenderSettings {
            spp: 128,
            max_depth: None,
            seed,
        };
        multipass::render_layers(
            scene,
            engine.as_ref(),
            &cam,
            0.0,
            &settings,
            indirect,
            None,
            render::Progress::Tiles,
        )
        .unwrap()
        .indirect
    });
    let n = a.len() as f64;
    let mean = a.iter().chain(&b).map(|&v| luminance(v)).sum::<f64>() / (2.0 * n);
    // Var(a_i - b_i) = 2 Var(a_i): the variance of the two images' mean is
    // Σ (a_i - b_i)² / 4 / n².
    let sq: f64 = a
        .iter()
        .zip(&b)
        .map(|(&x, &y)| (luminance(x) - luminance(y)).powi(2))
        .sum();
    (mean, sq.sqrt() / (2.0 * n))
}

/// The records' indirect light and a traced bounce's, with standard errors.
fn records_and_traced(scene: &Scene) -> [(f64, f64); 2] {
    let s = Simplified::whole(scene);
    let engine = accel::build(
        Backend::default_available(),
        &scene.geometry(),
        &scene.at(0.0),
    )
    .unwrap();
    let solution = solve(scene, &s, engine.as_ref(), 0.0, Quality::new(0.3).unwrap()).unwrap();
    let cache = IrradianceCache::new(&s, &solution.indirect).unwrap();
    [
        indirect_mean(scene, Some(&cache)),
        indirect_mean(scene, None),
    ]
}

/// The rails shadow almost nothing in a traced bounce (they are as white
/// as the walls), but the solver's elements are far larger than the rails:
/// when the wall behind a rail counted dark twice (in an element's average
/// and again by the shadow rays blocked there), the records' indirect
/// light fell 4.7% with the rails where the traced bounce's fell 0.3%.
/// The goal is issue 47's 2% on the rails' cost, plus three standard
/// errors of the four means.
#[test]
fn chair_rails_cost_the_records_what_they_cost_a_traced_bounce() {
    let dir = tempfile::tempdir().unwrap();
    let [bare, rails] = [false, true].map(|with| {
        let sub = dir.path().join(if with { "rails" } else { "bare" });
        std::fs::create_dir_all(&sub).unwrap();
        records_and_traced(&room(&sub, with))
    });
    let ratio = |a: (f64, f64), b: (f64, f64)| a.0 / b.0;
    let rel = |v: (f64, f64)| v.1 / v.0;
    let records = ratio(rails[0], bare[0]);
    let traced = ratio(rails[1], bare[1]);
    let sigma = [bare[0], bare[1], rails[0], rails[1]]
        .iter()
        .map(|&v| rel(v).powi(2))
        .sum::<f64>()
        .sqrt();
    println!(
        "records against traced: bare {:+.2}%, rails {:+.2}%",
        100.0 * ratio(bare[0], bare[1]) - 100.0,
        100.0 * ratio(rails[0], rails[1]) - 100.0
    );
    println!(
        "with rails / without: records {records:.4}, traced bounce {traced:.4} (relative standard error {sigma:.4})"
    );
    assert!(
        (records / traced - 1.0).abs() <= 0.02 + 3.0 * sigma,
        "the rails cost the records {:+.2}% and a traced bounce {:+.2}% (± {:.2}%)",
        100.0 * (records - 1.0),
        100.0 * (traced - 1.0),
        100.0 * sigma
    );
}

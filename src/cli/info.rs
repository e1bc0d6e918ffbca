//! `rangewalk info`: what a scene holds and which stages it needs.

use std::path::PathBuf;

use anyhow::Result;
use rangewalk::scene::{Bsdf, Light, Scene};

use super::load;

/// `rangewalk info`.
#[derive(clap::Args)]
pub struct InfoArgs {
    scene: PathBuf,
}

pub fn run(args: InfoArgs) -> Result<()> {
    describe(&load(&args.scene)?);
    Ok(())
}

fn describe(s: &Scene) {
    let tris: usize = s.objects.iter().map(|o| o.mesh.triangles.len()).sum();
    println!("{}", s.source.display());
    println!(
        "  {} objects, {} triangles, {} materials",
        s.objects.len(),
        tris,
        s.materials.len()
    );
    for o in &s.objects {
        let m = &s.materials[o.material];
        let kind = match m.bsdf {
            Bsdf::Diffuse { .. } => "diffuse",
            Bsdf::Glossy { .. } => "glossy",
            Bsdf::Mirror { .. } => "mirror",
        };
        println!(
            "  {:<12} {:>7} triangles  {:<10} {}{}",
            o.name,
            o.mesh.triangles.len(),
            m.name,
            kind,
            match (m.emission.is_some(), o.motion.is_static()) {
                (true, true) => ", emits",
                (true, false) => ", emits, moves",
                (false, false) => ", moves",
                (false, true) => "",
            }
        );
    }
    for l in &s.lights {
        match l {
            Light::Point {
                position,
                intensity,
            } => println!("  point light at {position}, intensity {intensity}"),
            Light::Sun {
                direction,
                radiance,
                angular_diameter_deg,
            } => {
                println!("  sun towards {direction}, radiance {radiance}, {angular_diameter_deg}°")
            }
        }
    }
    let cams: Vec<&str> = s.cameras.iter().map(|c| c.name.as_str()).collect();
    println!("  cameras: {}", cams.join(", "));
    if let Some(v) = s.view_space {
        println!("  view space: {}D", v.dimensions());
    }
    for p in &s.paths {
        println!("  path `{}`: {} keys", p.name, p.keys.len());
    }
    if s.is_static() {
        println!("  static scene: one time sample, no temporal decomposition");
    } else {
        let a = s.animation;
        println!(
            "  animated over [{}, {}] s at {} frames/s",
            a.start, a.end, a.fps
        );
    }
    if !s.has_specular() {
        println!("  no glossy or mirror surfaces: no specular rays are traced");
    }
}

//! The settings of a bake besides its scene, quality and directory, shared
//! by `bake` and `slurm` (which passes them on to the jobs).

use anyhow::Result;
use rangewalk::accel::Backend;
use rangewalk::bake::{self, BaseProjection, IndirectSource};
use rangewalk::image;
use rangewalk::plan::ViewFitness;
use rangewalk::quality::Quality;
use rangewalk::scene::Scene;

use super::{choice, flag};

/// `--noise`: a target, or none (`off`). Named apart from `Option` so that
/// clap takes it as the value of an argument that always has one.
type NoiseOption = Option<f32>;

/// The settings of a bake besides its scene, quality and directory, shared
/// by `bake` and `slurm` (which passes them on to the jobs).
#[derive(clap::Args)]
pub struct BakeOptions {
    /// Side of the square base images (default: from --frame-size and the
    /// scene's narrowest field of view).
    #[arg(long)]
    size: Option<u32>,
    /// Size of the frames that will be synthesized, `<W>x<H>`: sets the
    /// default --size so that no base pixel is coarser than a frame pixel.
    #[arg(long, default_value = bake::DEFAULT_FRAME_SIZE, value_parser = image::parse_size)]
    frame_size: (u32, u32),
    /// Samples per base-image pixel; with --noise, the least a pixel takes.
    #[arg(long, default_value_t = bake::DEFAULT_SPP)]
    spp: u32,
    /// Relative standard error of a base pixel's mean luminance at which it
    /// stops taking samples (0.02: 2 %), or `off`: every pixel takes --spp
    /// [default: 0.02].
    #[arg(long, value_name = "REL|off", value_parser = bake::sampling::parse_noise, allow_negative_numbers = true)]
    noise: Option<NoiseOption>,
    /// Most samples a base pixel takes with --noise (default: 16 × --spp).
    #[arg(long)]
    max_spp: Option<u32>,
    #[arg(long, value_parser = choice::<BaseProjection>(), default_value_t = BaseProjection::Sphere)]
    projection: BaseProjection,
    /// Diffuse indirect light: radiosity records (the paper's multipass
    /// renderer), gathered through one traced bounce, or traced.
    #[arg(long, value_parser = choice::<IndirectSource>(), default_value_t = IndirectSource::default())]
    indirect: IndirectSource,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    #[arg(long, value_parser = choice::<Backend>(), default_value_t = Backend::default_available())]
    backend: Backend,
    /// Longest path, counted as Mitsuba's `max_depth`; unlimited by default.
    #[arg(long)]
    max_depth: Option<u32>,
    /// Side of the planner's id-images (default from the quality).
    #[arg(long)]
    pub resolution: Option<u32>,
    /// One master time list for every view (the paper's choice).
    #[arg(long)]
    pub master_list: bool,
    /// What a view-space cell's fitness measures.
    #[arg(long, value_parser = choice::<ViewFitness>(), default_value_t = ViewFitness::Ids)]
    pub view_fitness: ViewFitness,
    /// Keep every pixel of each base's projection, not only the window
    /// that may see the scene (the rest sees only sky, which frames trace).
    #[arg(long)]
    whole_bases: bool,
}

impl BakeOptions {
    /// The settings these options give for `s`, and a line saying how the
    /// image size was chosen.
    pub fn settings(
        &self,
        s: &Scene,
        quality: Quality,
    ) -> Result<(bake::Settings, bake::Sampling, String)> {
        let (size, why) =
            bake::size::resolve(s, self.size, self.projection, self.frame_size, &flag)?;
        let settings = bake::Settings {
            quality,
            size,
            spp: self.spp,
            projection: self.projection,
            indirect: self.indirect,
            seed: self.seed,
            backend: self.backend,
            max_depth: self.max_depth,
            planning: bake::Planning {
                resolution: self.resolution,
                master_list: self.master_list,
                view_fitness: self.view_fitness,
                whole: self.whole_bases,
            },
        };
        let sampling = bake::Sampling {
            noise: self.noise.unwrap_or(Some(bake::sampling::DEFAULT_NOISE)),
            max_spp: self.max_spp,
        };
        sampling.check(self.spp, &flag)?;
        Ok((settings, sampling, why))
    }

    /// The same options as `rangewalk bake` arguments, every one spelled
    /// out so that the jobs do not depend on defaults.
    pub fn words(&self) -> Vec<String> {
        let mut w: Vec<String> = Vec::new();
        let mut push = |k: &str, v: String| {
            w.push(k.into());
            w.push(v);
        };
        if let Some(n) = self.size {
            push("--size", n.to_string());
        }
        push(
            "--frame-size",
            format!("{}x{}", self.frame_size.0, self.frame_size.1),
        );
        push("--spp", self.spp.to_string());
        let noise = self.noise.unwrap_or(Some(bake::sampling::DEFAULT_NOISE));
        push("--noise", noise.map_or("off".into(), |n| n.to_string()));
        if let Some(m) = self.max_spp {
            push("--max-spp", m.to_string());
        }
        push("--projection", self.projection.to_string());
        push("--indirect", self.indirect.to_string());
        push("--seed", self.seed.to_string());
        push("--backend", self.backend.to_string());
        if let Some(d) = self.max_depth {
            push("--max-depth", d.to_string());
        }
        if let Some(r) = self.resolution {
            push("--resolution", r.to_string());
        }
        push("--view-fitness", self.view_fitness.to_string());
        if self.master_list {
            w.push("--master-list".into());
        }
        if self.whole_bases {
            w.push("--whole-bases".into());
        }
        w
    }
}

//! `rangewalk walk`: every frame of a walk path synthesized from a bake,
//! written as range images and previews with an animated preview of the
//! whole walk and a summary of its speed, memory and holes.

use std::fs;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{ensure, Context, Result};

use super::{view_space_warning, FrameStats, Options, Synthesizer};
use crate::camera::Camera;
use crate::image::{self, RangeImage};
use crate::output::{numbered, Contents, Folder};
use crate::progress::{ProgressBar, ProgressStyle};

/// What a walk writes and how.
#[derive(Clone, Debug)]
pub struct WalkSettings {
    pub path: String,
    pub width: u32,
    pub height: u32,
    /// Frames per second of scene time; `None`: the scene's.
    pub fps: Option<f32>,
    pub options: Options,
    pub exposure: f32,
}

/// What a walk measures of some of its frames besides writing them. The
/// evaluation implements it with path-traced references
/// (`eval::walkcheck`), so that synthesis needs nothing of evaluation.
pub trait FrameChecker {
    /// Whether frame `i` of `n` is measured.
    fn wants(&self, i: usize, n: usize) -> bool;
    /// Measures frame `i`, made for `camera` at time `t`; what it writes
    /// goes in `dir`, the walk's unfinished output folder.
    fn check(
        &mut self,
        synth: &mut Synthesizer,
        i: usize,
        t: f32,
        camera: &Camera,
        frame: &RangeImage,
        dir: &Path,
    ) -> Result<FrameCheck>;
    /// After the last frame, before the walk's folder is complete.
    fn finish(&mut self, dir: &Path, exposure: f32) -> Result<()>;
}

/// One frame checked against its path-traced reference.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FrameCheck {
    pub frame: usize,
    pub time: f32,
    /// Relative luminance RMS error and bias of the synthesized frame.
    pub lrms: f64,
    pub bias: f64,
    /// The luminance error of its 8×8 blocks: their RMS, which per-pixel
    /// noise leaves alone, and their 99th percentile, which a local
    /// artifact raises while the means hide it.
    pub block_lrms: f64,
    pub block_p99: f64,
    /// Mean HDR-FLIP, what a viewer would notice; `None` when left out.
    pub flip: Option<f64>,
    pub reference_spp: u32,
    pub reference_seconds: f64,
}

/// What a walk did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct WalkSummary {
    pub path: String,
    pub frames: usize,
    pub times: Vec<f32>,
    pub frame_seconds: Vec<f64>,
    pub holes: Vec<usize>,
    /// Wall time of synthesis alone (base loading excluded) and of the
    /// whole walk (loading and writing included).
    pub synthesis_seconds: f64,
    pub load_seconds: f64,
    pub total_seconds: f64,
    /// Frames per second of synthesis, base loading excluded.
    pub frames_per_second: f64,
    pub base_loads: usize,
    pub bytes_per_base_pixel: usize,
    /// Peak resident memory of the process (bytes), where the system says.
    pub peak_resident_bytes: Option<u64>,
    pub warnings: Vec<String>,
    /// Frames checked against path-traced references (`contact.png` shows
    /// them: synthesized, path-traced and, with FLIP, FLIP's error map).
    pub checks: Vec<FrameCheck>,
    pub out: PathBuf,
}

/// The most frames one walk writes. Each is a range image and a preview
/// named `frame-NNNN` (four digits, so that they sort in order) and its
/// preview is kept for the animated `walk.png`; 10,000 frames is over five
/// minutes at 30 frames/s. `--fps 1e6` set out to write two million.
pub const MAX_WALK_FRAMES: usize = 10_000;

/// The frame times of a walk over `span` at `fps` ([`frame_times`]),
/// refusing a rate that is not a positive number or that makes more than
/// [`MAX_WALK_FRAMES`] frames, before any is made. `given` says whether
/// `fps` came from `--fps` (else it is the scene's).
pub fn walk_times(span: (f32, f32), fps: f32, given: bool) -> Result<Vec<f32>> {
    let source = if given {
        format!("--fps {fps}")
    } else {
        format!("the scene's frame rate {fps} (animation.fps; --fps overrides it)")
    };
    ensure!(
        fps.is_finite() && fps > 0.0,
        "{source} must be a positive number"
    );
    let frames = (f64::from(span.1) - f64::from(span.0)) * f64::from(fps);
    let frames = frames.round().max(0.0) + 1.0;
    ensure!(
        frames <= MAX_WALK_FRAMES as f64,
        "{source} over the path's {} s makes {frames} frames, more than the {MAX_WALK_FRAMES} a walk \
         writes (frame-0000 to frame-9999); give a lower --fps or a shorter path",
        span.1 - span.0
    );
    Ok(frame_times(span, fps))
}

/// Frame times of a path at `fps`: from its first key to its last.
pub fn frame_times(span: (f32, f32), fps: f32) -> Vec<f32> {
    let n = ((span.1 - span.0) * fps).round().max(0.0) as usize + 1;
    (0..n)
        .map(|i| (span.0 + i as f32 / fps).min(span.1))
        .collect()
}

/// Synthesizes every frame of the path into `out` (written as
/// `<out>.partial` and renamed when complete), measuring the frames
/// `checker` wants.
pub fn walk(
    synth: &mut Synthesizer,
    settings: &WalkSettings,
    out: &Path,
    mut checker: Option<&mut dyn FrameChecker>,
) -> Result<WalkSummary> {
    let scene = synth.scene;
    let path = scene.path(&settings.path)?.clone();
    let fps = settings.fps.unwrap_or(scene.animation.fps);
    let times = walk_times(path.span(), fps, settings.fps.is_some())
        .with_context(|| format!("walking path `{}`", path.name))?;
    let mut warnings = Vec::new();
    for k in &path.keys {
        if let Some(w) = view_space_warning(
            scene,
            &format!("path `{}` key t = {}", path.name, k.time),
            k.position,
        ) {
            eprintln!("{w}");
            warnings.push(w);
        }
    }
    let folder = Folder::begin(out, CONTENTS)?;
    let staging = folder.path().to_path_buf();
    let bar = ProgressBar::new(times.len() as u64).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames, {elapsed} ({eta} left) {msg}")
            .expect("progress template is valid"),
    );
    let start = Instant::now();
    let mut stats: Vec<FrameStats> = Vec::with_capacity(times.len());
    let mut animation = Animation::start(
        &staging.join("walk.png"),
        (settings.width, settings.height),
        fps,
        times.len(),
    )?;
    let mut checks = Vec::new();
    for (i, &t) in times.iter().enumerate() {
        let desc = path.at(t);
        let camera = desc
            .perspective(settings.width, settings.height)
            .with_context(|| format!("path `{}` at t = {t}", path.name))?;
        let (frame, s) = synth
            .frame(&camera, t, &settings.options)
            .with_context(|| format!("frame {i} (t = {t})"))?;
        let name = format!("frame-{i:04}");
        image::write_exr(staging.join(format!("{name}.exr")), &frame)?;
        image::write_png_preview(
            staging.join(format!("{name}.png")),
            frame.width,
            frame.height,
            &frame.radiance,
            settings.exposure,
        )?;
        animation.push(&image::tonemap_srgb8(&frame.radiance, settings.exposure))?;
        if let Some(c) = checker.as_mut().filter(|c| c.wants(i, times.len())) {
            bar.set_message(format!("checking frame {i}"));
            checks.push(c.check(synth, i, t, &camera, &frame, &staging)?);
        }
        bar.set_message(format!(
            "{:.1} ms/frame",
            1e3 * (s.seconds - s.load_seconds)
        ));
        bar.inc(1);
        stats.push(s);
        synth.recycle(frame);
    }
    bar.finish_and_clear();
    animation.finish()?;
    if let Some(c) = checker {
        c.finish(&staging, settings.exposure)?;
    }
    let synthesis_seconds: f64 = stats.iter().map(|s| s.seconds - s.load_seconds).sum();
    let load_seconds: f64 = stats.iter().map(|s| s.load_seconds).sum();
    let mut summary = WalkSummary {
        path: path.name.clone(),
        frames: times.len(),
        frame_seconds: stats.iter().map(|s| s.seconds - s.load_seconds).collect(),
        holes: stats.iter().map(|s| s.holes).collect(),
        times,
        synthesis_seconds,
        load_seconds,
        total_seconds: start.elapsed().as_secs_f64(),
        frames_per_second: stats.len() as f64 / synthesis_seconds.max(1e-9),
        base_loads: synth.cache().loads,
        bytes_per_base_pixel: super::BYTES_PER_PIXEL,
        peak_resident_bytes: peak_resident_bytes(),
        warnings,
        checks,
        out: out.to_path_buf(),
    };
    let text = serde_json::to_string_pretty(&summary).context("encoding the walk summary")?;
    fs::write(staging.join("summary.json"), text)
        .with_context(|| format!("writing {}", staging.join("summary.json").display()))?;
    summary.out = folder.finish()?;
    Ok(summary)
}

/// What a walk writes into its folder: frames, their references,
/// `walk.png`, `contact.png` and `summary.json`.
pub const CONTENTS: Contents = Contents {
    what: "a walk",
    owns: |name, is_dir| {
        !is_dir
            && (matches!(name, "walk.png" | "contact.png" | "summary.json")
                || numbered(name, "frame-", &["exr", "png"])
                || numbered(name, "reference-", &["exr"]))
    },
};

/// The animated PNG of a walk's previews, written frame by frame as they
/// are made: a long walk holds none of them in memory.
struct Animation {
    path: PathBuf,
    writer: png::Writer<BufWriter<fs::File>>,
}

impl Animation {
    /// Starts `path` for `frames` frames of `size`, playing at `fps`.
    fn start(path: &Path, size: (u32, u32), fps: f32, frames: usize) -> Result<Animation> {
        let start = || -> Result<png::Writer<BufWriter<fs::File>>> {
            let file = fs::File::create(path)?;
            let mut enc = png::Encoder::new(BufWriter::new(file), size.0, size.1);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            enc.set_animated(u32::try_from(frames.max(1))?, 0)?;
            // Delay as a fraction: 1000 / (fps * 1000) s.
            enc.set_frame_delay(1000, (fps * 1000.0).round().clamp(1.0, 65535.0) as u16)?;
            Ok(enc.write_header()?)
        };
        Ok(Animation {
            path: path.to_path_buf(),
            writer: start().with_context(|| format!("writing {}", path.display()))?,
        })
    }

    /// Appends one frame's 8-bit RGB pixels.
    fn push(&mut self, rgb: &[u8]) -> Result<()> {
        self.writer
            .write_image_data(rgb)
            .with_context(|| format!("writing {}", self.path.display()))
    }

    fn finish(self) -> Result<()> {
        self.writer
            .finish()
            .with_context(|| format!("writing {}", self.path.display()))
    }
}

/// The process's peak resident set size (Linux: `VmHWM`).
pub fn peak_resident_bytes() -> Option<u64> {
    let status = fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_times_cover_the_path_at_the_rate() {
        assert_eq!(frame_times((0.0, 1.0), 4.0), [0.0, 0.25, 0.5, 0.75, 1.0]);
        assert_eq!(frame_times((2.0, 2.0), 30.0), [2.0]);
        assert_eq!(frame_times((0.0, 1.0), 30.0).len(), 31);
    }

    #[test]
    fn a_walk_of_too_many_frames_is_refused_before_any() {
        assert_eq!(walk_times((0.0, 1.0), 4.0, true).unwrap().len(), 5);
        // 9,999 s at 1 frame/s is the most: frames 0 to 9,999.
        assert_eq!(walk_times((0.0, 9999.0), 1.0, true).unwrap().len(), 10_000);
        let msg = walk_times((0.0, 10_000.0), 1.0, true)
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains("--fps 1 ") && msg.contains("10001 frames"),
            "{msg}"
        );
        let msg = walk_times((0.0, 2.0), 1e6, false).unwrap_err().to_string();
        assert!(
            msg.contains("scene's frame rate 1000000") && msg.contains("2000001 frames"),
            "{msg}"
        );
        for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert!(walk_times((0.0, 1.0), bad, true).is_err(), "{bad}");
        }
        // A rate whose frame count overflows any integer.
        assert!(walk_times((0.0, 1.0), f32::MAX, true).is_err());
    }
}

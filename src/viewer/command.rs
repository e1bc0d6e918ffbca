//! `rangewalk view`: the window's loop. Interactive, each pass reads the
//! keys, moves the viewer by the time that passed and asks for a new frame
//! when the last one is shown; scripted (`--path`, `--input` or
//! `--frames`), every frame is the one for its step, one scene frame
//! (1/fps) after the last, so a run can be replayed and compared.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, ensure, Context, Result};

use super::overlay;
use super::render::{Rendered, Renderer, Request};
use super::script::Script;
use super::walker::{Input, Walker};
use super::window::{self, Window};
use crate::image::png_io;
use crate::output::{numbered, Contents, Folder};
use crate::scene::{CameraDesc, Scene, WalkPath};
use crate::synth::walk::frame_times;
use crate::synth::{Blend, Filter, Options};

/// How the viewer makes frames while the view or the time changes.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[strum(serialize_all = "lowercase")]
pub enum Moving {
    /// Drafts while moving: no subpixels, only the pixels a sample covers,
    /// the nearest base's sample first, at most 4 × 4 rays a pixel of a
    /// light's rim (synth's `--supersample 1 --filter cover --blend nearest
    /// --light-rays 4`), about three times as fast; a view that stays
    /// still is made again with the options given.
    #[default]
    Draft,
    /// Every frame with the options given.
    Full,
}

impl Moving {
    /// The options of a frame whose view or time differs from the last
    /// one's (`moved`), from those given.
    pub fn options(self, given: Options, moved: bool) -> Options {
        match (self, moved) {
            (Moving::Draft, true) => Options {
                supersample: 1,
                filter: Filter::Cover,
                blend: Blend::Nearest,
                light_rays: given.light_rays.min(4),
                // Re-shading's first few samples a pixel only; where they
                // find the light changed, the still frame takes the rest.
                reshade_samples: given.reshade_samples.min(4),
                ..given
            },
            _ => given,
        }
    }
}

/// What `rangewalk view` is asked to do (the command line's `--` options).
#[derive(Clone, Debug)]
pub struct ViewSettings {
    /// A complete bake directory.
    pub bake: PathBuf,
    /// The scene the bake was made from [`None`: the one its manifest names].
    pub scene: Option<PathBuf>,
    /// Window size at the start; frames follow the window's size.
    pub size: (u32, u32),
    /// Named camera to start at [`None`: the scene's first].
    pub camera: Option<String>,
    /// Scene time to start at [`None`: the animation's start].
    pub time: Option<f32>,
    /// A walk path to play, looping.
    pub path: Option<String>,
    /// Scripted input ([`Script`]).
    pub input: Option<PathBuf>,
    /// Frames to stop after.
    pub frames: Option<usize>,
    /// Where the last frame shown is saved as PNG.
    pub screenshot: Option<PathBuf>,
    /// Where every frame shown is saved.
    pub record: Option<PathBuf>,
    /// Moving speed in scene units per second [`None`: a quarter of the view
    /// space's longest side per second].
    pub speed: Option<f32>,
    /// Scene frames per second of a scripted run [`None`: the scene's].
    pub fps: Option<f32>,
    pub options: Options,
    pub moving: Moving,
    /// Memory for bases held between frames.
    pub base_memory_bytes: usize,
    /// Exposure of the frames shown, in stops.
    pub exposure: f32,
}

/// What a run showed.
#[derive(Clone, Debug)]
pub struct ViewSummary {
    pub frames: usize,
    /// Of which drafts ([`Moving::Draft`]).
    pub drafts: usize,
    /// Frames per second of synthesis, reading bases excluded.
    pub synthesis_fps: f64,
    /// Frames per second shown, from the first frame shown to the last,
    /// reading bases excluded.
    pub shown_fps: f64,
    pub load_seconds: f64,
    pub last: Option<Rendered>,
    /// Whether the last frame's step was stopped at the view space's edge.
    pub at_edge: bool,
}

/// Frames shown in the last second.
#[derive(Default)]
struct Meter(VecDeque<Instant>);

impl Meter {
    fn tick(&mut self, now: Instant) -> f64 {
        self.0.push_back(now);
        while self
            .0
            .front()
            .is_some_and(|&t| now - t > Duration::from_secs(1))
        {
            self.0.pop_front();
        }
        let span = (now - self.0[0]).as_secs_f64();
        if self.0.len() < 2 || span == 0.0 {
            0.0
        } else {
            (self.0.len() - 1) as f64 / span
        }
    }
}

/// Where the walk-through goes: a path, a script, or the keyboard.
enum Drive {
    Path { path: WalkPath, times: Vec<f32> },
    Script(Script),
    Keys,
}

/// Opens the window and runs until the frames are done or it is closed.
pub fn run(args: &ViewSettings) -> Result<ViewSummary> {
    let options = args.options;
    if let Some(p) = &args.screenshot {
        crate::image::check_output("--screenshot", p, crate::image::OutputKind::Png)?;
    }
    if let Some(dir) = &args.record {
        crate::image::check_output_dir("--record", dir)?;
        crate::output::check_only(dir, &RECORDING)?;
    }
    let (scene, bake) = crate::synth::open(&args.bake, args.scene.as_deref())?;
    let scene = Arc::new(scene);
    let fps = args.fps.unwrap_or(scene.animation.fps);
    ensure!(
        fps.is_finite() && fps > 0.0,
        "--fps {fps} must be a positive number"
    );
    let drive = match (&args.path, &args.input) {
        (Some(name), _) => {
            let path = scene.path(name)?.clone();
            let times = frame_times(path.span(), fps);
            Drive::Path { path, times }
        }
        (None, Some(file)) => Drive::Script(Script::read(file)?),
        (None, None) => Drive::Keys,
    };
    let scripted = !matches!(drive, Drive::Keys) || args.frames.is_some();
    let total = match (&drive, args.frames) {
        (_, Some(0)) => bail!("--frames 0: give at least 1 frame"),
        (_, Some(n)) => Some(n),
        (Drive::Path { times, .. }, None) => Some(times.len()),
        (Drive::Script(s), None) if s.frames.is_empty() => bail!(
            "input script {} holds no steps",
            args.input.as_ref().expect("a script").display()
        ),
        (Drive::Script(s), None) => Some(s.frames.len()),
        (Drive::Keys, None) => None,
    };
    let start = start_pose(&scene, args.camera.as_deref())?;
    let speed = match args.speed {
        Some(v) => v,
        None => default_speed(&scene),
    };
    let walker = Walker::new(
        &start,
        args.time.unwrap_or(scene.animation.start),
        scene.view_space,
        scene.animation,
        speed,
        options.fill,
        options.time_interp,
    )?;
    let record = args
        .record
        .as_deref()
        .map(|dir| Folder::begin(dir, RECORDING))
        .transpose()?;
    let title = format!("rangewalk view {}: {}", args.bake.display(), window::KEYS);
    let window = Window::open(&title, args.size.0, args.size.1)?;
    let renderer = Renderer::start(
        Arc::clone(&scene),
        bake,
        args.base_memory_bytes,
        args.exposure,
    )?;
    let mut screen = Screen::new(
        window,
        args.size,
        record.as_ref().map(|f| f.path().to_path_buf()),
    );
    let mut session = Session {
        renderer,
        walker,
        options,
        moving: args.moving,
        asked: None,
    };
    match total.filter(|_| scripted) {
        Some(n) => session.scripted(&mut screen, &drive, n, fps)?,
        None => session.interactive(&mut screen)?,
    }
    if let (Some(p), Some(_)) = (&args.screenshot, &screen.shown) {
        png_io::write(
            p,
            screen.size.0,
            screen.size.1,
            &overlay::unpack(&screen.on_screen),
        )?;
    }
    if let Some(folder) = record {
        folder.finish()?;
    }
    let shown_fps = match screen.first_shown {
        Some(first) if screen.count > 1 => {
            let reading = screen.load_seconds - screen.first_load_seconds;
            let span = (screen.last_shown - first).as_secs_f64() - reading;
            (screen.count - 1) as f64 / span.max(1e-9)
        }
        _ => 0.0,
    };
    Ok(ViewSummary {
        frames: screen.count,
        drafts: screen.drafts,
        synthesis_fps: screen.count as f64 / screen.synthesis_seconds.max(1e-9),
        shown_fps,
        load_seconds: screen.load_seconds,
        at_edge: screen.shown.as_ref().is_some_and(|(_, f)| f.at_edge),
        last: screen.shown.map(|(r, _)| r),
    })
}

/// The viewer's state when a frame was asked for, which its status shows.
#[derive(Clone, Copy, Debug, Default)]
struct Flags {
    at_edge: bool,
    playing: bool,
    /// Made with the draft's options rather than those given.
    draft: bool,
}

/// The window and what it shows: the last frame, its status, the counts.
struct Screen {
    window: Window,
    size: (u32, u32),
    /// The last frame, packed, without status.
    pixels: Vec<u32>,
    /// What the window shows: `pixels` with the status drawn over.
    on_screen: Vec<u32>,
    shown: Option<(Rendered, Flags)>,
    record: Option<PathBuf>,
    meter: Meter,
    frames_per_second: f64,
    count: usize,
    drafts: usize,
    synthesis_seconds: f64,
    load_seconds: f64,
    first_shown: Option<Instant>,
    /// Seconds the first frame spent reading bases.
    first_load_seconds: f64,
    last_shown: Instant,
}

impl Screen {
    fn new(window: Window, (w, h): (u32, u32), record: Option<PathBuf>) -> Screen {
        Screen {
            window,
            size: (w, h),
            pixels: vec![0; (w * h) as usize],
            on_screen: Vec::new(),
            shown: None,
            record,
            meter: Meter::default(),
            frames_per_second: 0.0,
            count: 0,
            drafts: 0,
            synthesis_seconds: 0.0,
            load_seconds: 0.0,
            first_shown: None,
            first_load_seconds: 0.0,
            last_shown: Instant::now(),
        }
    }

    /// Takes a new frame: counted, shown and recorded.
    fn take(&mut self, r: Rendered, flags: Flags) -> Result<()> {
        let now = Instant::now();
        self.count += 1;
        self.drafts += flags.draft as usize;
        self.synthesis_seconds += r.stats.seconds - r.stats.load_seconds;
        self.load_seconds += r.stats.load_seconds;
        self.frames_per_second = self.meter.tick(now);
        if self.first_shown.is_none() {
            self.first_shown = Some(now);
            self.first_load_seconds = r.stats.load_seconds;
        }
        self.last_shown = now;
        self.size = (r.request.camera.width, r.request.camera.height);
        self.pixels = overlay::pack(&r.rgb);
        self.shown = Some((r, flags));
        self.redraw()?;
        if let Some(dir) = &self.record {
            let file = dir.join(format!("frame-{:04}.png", self.count - 1));
            png_io::write(
                file,
                self.size.0,
                self.size.1,
                &overlay::unpack(&self.on_screen),
            )?;
        }
        Ok(())
    }

    /// Shows the last frame again with its status (or the status alone).
    fn redraw(&mut self) -> Result<()> {
        let (w, h) = self.size;
        self.on_screen.clone_from(&self.pixels);
        let lines = match &self.shown {
            Some((r, flags)) => status(r, *flags, self.frames_per_second),
            None => vec!["reading the bases...".into(), String::new()],
        };
        overlay::draw(&mut self.on_screen, w as usize, h as usize, &lines);
        self.window.show(&self.on_screen, w, h)
    }
}

/// The viewer and the thread making its frames.
struct Session {
    renderer: Renderer,
    walker: Walker,
    options: Options,
    moving: Moving,
    /// The frame asked for last.
    asked: Option<Request>,
}

impl Session {
    /// The walker's frame at `size`: a draft where its view or time
    /// differs from the frame asked for last.
    fn wanted(&self, size: (u32, u32)) -> Result<Request> {
        let mut r = request(&self.walker, size, self.options)?;
        let moved = self
            .asked
            .as_ref()
            .is_none_or(|a| a.camera != r.camera || a.time != r.time);
        r.options = self.moving.options(r.options, moved);
        Ok(r)
    }

    fn send(&mut self, request: Request) -> Result<()> {
        self.asked = Some(request.clone());
        self.renderer.request(request)
    }

    /// Asks for the walker's frame at `size`; the flags it was asked with.
    fn ask(&mut self, size: (u32, u32)) -> Result<Flags> {
        let request = self.wanted(size)?;
        self.send(request)?;
        Ok(self.flags())
    }

    fn flags(&self) -> Flags {
        Flags {
            at_edge: self.walker.at_edge,
            playing: self.walker.playing,
            draft: self
                .asked
                .as_ref()
                .is_some_and(|a| a.options != request_options(&self.walker, self.options)),
        }
    }

    /// Moves the walker to step `i` of a scripted run.
    fn advance(&mut self, drive: &Drive, i: usize, fps: f32) {
        match drive {
            Drive::Path { path, times } => {
                let t = times[i % times.len()];
                self.walker.follow(&path.at(t), t);
            }
            Drive::Script(s) => {
                let input = s.frames.get(i).cloned().unwrap_or_default();
                self.walker.step(&input, 1.0 / fps);
            }
            Drive::Keys => self.walker.step(&Input::default(), 1.0 / fps),
        }
    }

    /// `n` frames, each of its step; the next is made while one is shown.
    fn scripted(&mut self, screen: &mut Screen, drive: &Drive, n: usize, fps: f32) -> Result<()> {
        self.advance(drive, 0, fps);
        let mut flags = self.ask(screen.window.size())?;
        for i in 0..n {
            let made = loop {
                if let Some(r) = self.renderer.poll(Duration::from_millis(30))? {
                    break r;
                }
                screen.window.pump();
                if !screen.window.is_open() {
                    bail!("the window was closed after {i} of {n} frames");
                }
            };
            let shown_flags = flags;
            if i + 1 < n {
                self.advance(drive, i + 1, fps);
                flags = self.ask(screen.window.size())?;
            }
            screen.take(made, shown_flags)?;
        }
        Ok(())
    }

    /// Until the window closes: keys move the walker by the time that
    /// passed; a new frame is asked for when the last is in and the view
    /// changed, or (a draft) when it stays still.
    fn interactive(&mut self, screen: &mut Screen) -> Result<()> {
        let mut last_step = Instant::now();
        let mut flags = self.flags();
        while screen.window.is_open() {
            let now = Instant::now();
            let input = screen.window.input();
            self.walker.step(&input, (now - last_step).as_secs_f32());
            last_step = now;
            if !self.renderer.busy() {
                let wanted = self.wanted(screen.window.size())?;
                if screen
                    .shown
                    .as_ref()
                    .is_none_or(|(s, _)| s.request != wanted)
                {
                    self.send(wanted)?;
                    flags = self.flags();
                }
            }
            match self.renderer.poll(Duration::ZERO)? {
                Some(r) => screen.take(r, flags)?,
                None => screen.redraw()?,
            }
        }
        Ok(())
    }
}

fn request(walker: &Walker, (w, h): (u32, u32), base: Options) -> Result<Request> {
    Ok(Request {
        camera: walker.camera(w, h)?,
        time: walker.time,
        options: request_options(walker, base),
    })
}

/// The options given, with the fill and time interpolation the keys chose.
fn request_options(walker: &Walker, base: Options) -> Options {
    Options {
        fill: walker.fill,
        time_interp: walker.time_interp,
        ..base
    }
}

/// The two status lines of a frame shown.
fn status(r: &Rendered, flags: Flags, frames_per_second: f64) -> Vec<String> {
    let p = r.request.camera.position;
    let o = &r.request.options;
    vec![
        format!(
            "x {:.1} y {:.1} z {:.1}{}  t {:.3} s {}  {:.1} frames/s",
            p.x,
            p.y,
            p.z,
            if flags.at_edge { " (edge)" } else { "" },
            r.request.time,
            if flags.playing { "playing" } else { "paused" },
            frames_per_second
        ),
        format!(
            "bases {} ({} images)  fill {}  time {}  {}{:.0} ms",
            list(&r.views),
            r.stats.images.len(),
            format!("{:?}", o.fill).to_lowercase(),
            format!("{:?}", o.time_interp).to_lowercase(),
            if flags.draft { "draft " } else { "" },
            1e3 * (r.stats.seconds - r.stats.load_seconds)
        ),
    ]
}

/// Base views' indices as the status line and the run's summary show them.
pub fn list(v: &[usize]) -> String {
    v.iter()
        .map(|i| i.to_string())
        .collect::<Vec<_>>()
        .join(",")
}

/// The named camera, or the scene's first, or a view of the bake's plan.
fn start_pose(scene: &Scene, name: Option<&str>) -> Result<CameraDesc> {
    match name {
        Some(n) => Ok(scene.camera(n)?.clone()),
        None => scene.cameras.first().cloned().with_context(|| {
            format!(
                "{} names no camera to start at: pass --camera or --path",
                scene.source.display()
            )
        }),
    }
}

/// A quarter of the view space's longest side per second, so crossing it
/// takes a few seconds; without a view space, a tenth of the scene's.
fn default_speed(scene: &Scene) -> f32 {
    let extent = scene.view_space.map_or(0.0, |s| s.extent());
    if extent > 0.0 {
        extent / 4.0
    } else {
        let (lo, hi) = scene.bounds(scene.animation.start);
        ((hi - lo).length() / 10.0).max(f32::MIN_POSITIVE)
    }
}

/// What `--record` writes into its folder: the frames shown.
const RECORDING: Contents = Contents {
    what: "a recording",
    owns: |name, is_dir| !is_dir && numbered(name, "frame-", &["png"]),
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::TimeInterp;

    /// A draft keeps its cost bounded whatever was asked: re-shading a
    /// moved shadow with 64 samples a pixel cost more than the rest of a
    /// draft; the still frame is made as asked.
    #[test]
    fn a_draft_bounds_its_rays_and_a_still_frame_takes_the_options_given() {
        let given = Options {
            time_interp: TimeInterp::Reshade,
            reshade_samples: 64,
            light_rays: 8,
            ..Options::default()
        };
        let draft = Moving::Draft.options(given, true);
        assert_eq!((draft.reshade_samples, draft.light_rays), (4, 4));
        assert_eq!(
            (draft.supersample, draft.time_interp),
            (1, TimeInterp::Reshade)
        );
        assert_eq!(Moving::Draft.options(given, false), given);
        assert_eq!(Moving::Full.options(given, true), given);
    }
}

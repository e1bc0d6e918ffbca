//! What a frame is asked to be made with, the limits those values keep
//! to, and how a frame's time is brought from its bases' times (decided
//! once per frame, [`TimePlan`]).

use anyhow::{ensure, Result};

use crate::alloc;

#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    serde::Serialize,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum Fill {
    /// A base pixel lands on at most one frame pixel; holes stay empty.
    None,
    /// Each base pixel covers the parallelogram to its right and lower
    /// neighbours' projections, where their depths agree.
    Foreground,
    /// Holes take the farther of their nearest filled neighbours.
    Background,
    /// Foreground, then background.
    Both,
}

#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    serde::Serialize,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum TimeInterp {
    /// Each time's frame projected alone, blended per pixel (the paper's).
    Linear,
    /// Samples moved by their object's motion to the frame's time and
    /// projected together.
    Motion,
    /// Motion-compensated, with the diffuse direct light evaluated again at
    /// the frame's time and mirrors traced again.
    Reshade,
}

#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    serde::Serialize,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum Blend {
    /// The first base (nearest the frame's camera) wins among samples
    /// within the tolerance (pinterp `-q`).
    Nearest,
    /// Samples within the tolerance are averaged, weighted by 1/sin of the
    /// angle between the base's ray and the frame's (pinterp `-a`).
    Average,
}

#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    serde::Serialize,
    strum::Display,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[serde(rename_all = "lowercase")]
#[strum(serialize_all = "lowercase")]
pub enum Filter {
    /// A splat joins every pixel it overlaps, weighed by the overlap, and
    /// decides those whose centres it covers: a box filter of the base's
    /// pixels.
    Box,
    /// A splat reaches only the pixels whose centres it covers: a quarter
    /// to a third less time a frame, for an LRMS up to a tenth higher from
    /// bases as fine as the frame (less of their noise averaged away) and
    /// up to a third from coarser ones, at the same FLIP.
    Cover,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    pub fill: Fill,
    pub time_interp: TimeInterp,
    /// How many base views, nearest first.
    pub bases: usize,
    pub blend: Blend,
    /// Relative depth tolerance (pinterp's `-t`, default 0.02).
    pub tolerance: f32,
    /// Farthest a background fill carries a value, in pixels.
    pub fill_reach: u16,
    /// Light samples per pixel when re-shading, where the light changed
    /// since the base times (elsewhere [`reshade::FIND_SAMPLES`] find that
    /// it did not).
    pub reshade_samples: u32,
    /// Rays per side of a pixel at or beside a light or a silhouette
    /// against the sky ([`lights`]); 0: none.
    pub light_rays: u32,
    pub seed: u64,
    /// Side of the grid of subpixels each frame pixel is synthesized as
    /// and then averaged from (1: none). A z-buffer gives each of its
    /// pixels one surface, so a pixel a silhouette crosses shows the
    /// nearer surface whole where the reference shows both by the share
    /// each covers: thin objects thicken and close the gaps between them.
    /// Subpixels resolve that share. Only splatting fills (`foreground`,
    /// `both`) use them.
    pub supersample: u32,
    /// Which pixels a splat reaches (see [`Filter`]).
    pub filter: Filter,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            fill: Fill::Both,
            time_interp: TimeInterp::Reshade,
            bases: 4,
            blend: Blend::Average,
            tolerance: 0.02,
            fill_reach: 32,
            reshade_samples: 64,
            light_rays: 8,
            seed: 1,
            supersample: 2,
            filter: Filter::Box,
        }
    }
}

/// The most rays per side of a pixel at a light's rim ([`lights`]): 32²
/// rays resolve the share of a pixel a light covers to a thousandth, finer
/// than any preview or error measure shows, at about a thousand rays for
/// each rim pixel; 100,000 asked for 10¹⁰ rays a pixel and never finished.
pub const MAX_LIGHT_RAYS: u32 = 32;

/// The most light samples a pixel takes when re-shading: three sets of
/// shadow rays a pixel (one for the frame's time and one for each base
/// time), so 256 traces some 200 million rays for a 512² frame, more than
/// path tracing it at a few samples a pixel: beyond that re-shading is no
/// longer what synthesis is for.
pub const MAX_RESHADE_SAMPLES: u32 = 256;

/// The most base views a frame projects: each gives a pass per base time
/// it takes (two at most), and a z-buffer entry names its pass in 12 bits
/// (the projection checks that they hold twice this many).
pub const MAX_BASES: usize = 2048;

/// Bytes of a subpixel's z-buffer entry (the projection checks it), for
/// saying how much memory a frame asks for.
pub const SUBPIXEL_BYTES: u64 = 48;

/// The most subpixels a frame is synthesized at: the pixels a range image
/// may hold ([`crate::image::MAX_PIXELS`], 8192²). A subpixel's z-buffer
/// entry alone takes 48 bytes, so this is about 3.2 GB before the frame.
pub const MAX_SUBPIXELS: u64 = crate::image::MAX_PIXELS;

impl Options {
    /// Refuses values that make no frame or unbounded work, for frames of
    /// `width` × `height`: the frame size alone does not say how much a
    /// frame holds, its supersampling squares it. The one check the
    /// command line, the C API and [`super::Synthesizer::frame`] (so the
    /// viewer and the walk) make. `name` turns a field's name
    /// (`light_rays`) into what the caller calls it (the flag
    /// `--light-rays`, the C field `options->light_rays`), so that each
    /// front end reports its own names from one set of limits.
    pub fn validate(
        &self,
        (width, height): (u32, u32),
        name: &dyn Fn(&str) -> String,
    ) -> Result<()> {
        ensure!(
            self.bases > 0,
            "{} 0: synthesis needs at least 1 base view",
            name("bases")
        );
        ensure!(
            self.bases <= MAX_BASES,
            "{} {} must lie in 1..={MAX_BASES}",
            name("bases"),
            self.bases
        );
        ensure!(
            self.tolerance > 0.0 && self.tolerance < 1.0,
            "{} {} must lie in (0, 1): it is the relative depth difference within which samples join",
            name("tolerance"),
            self.tolerance
        );
        ensure!(
            (1..=MAX_RESHADE_SAMPLES).contains(&self.reshade_samples),
            "{} {} must lie in 1..={MAX_RESHADE_SAMPLES}: each sample is three shadow rays a pixel, \
             and more than {MAX_RESHADE_SAMPLES} costs more than path tracing the frame",
            name("reshade_samples"),
            self.reshade_samples
        );
        ensure!(
            self.light_rays <= MAX_LIGHT_RAYS,
            "{} {} must lie in 0..={MAX_LIGHT_RAYS}: it is rays per side of each pixel at a light's rim \
             ({}² of them), and {MAX_LIGHT_RAYS}² already resolve a pixel's share of the light to a thousandth",
            name("light_rays"),
            self.light_rays,
            self.light_rays
        );
        ensure!(
            (1..=MAX_SUPERSAMPLE).contains(&self.supersample),
            "{} {} must lie in 1..={MAX_SUPERSAMPLE}",
            name("supersample"),
            self.supersample
        );
        let k = u64::from(self.subpixels_per_side());
        let n = u64::from(width) * k * u64::from(height) * k;
        ensure!(
            n <= MAX_SUBPIXELS,
            "a {width}x{height} frame at {k}x{k} supersampling ({} {k}) is {n} subpixels, more than the \
             {MAX_SUBPIXELS} (8192x8192) a frame may be synthesized at (about {} of z-buffer); \
             make the frame or {} smaller",
            name("supersample"),
            alloc::bytes(n.saturating_mul(SUBPIXEL_BYTES)),
            name("supersample")
        );
        Ok(())
    }

    /// The subpixels per side a frame is synthesized at: only splatting
    /// fills use them (see [`Options::supersample`]).
    pub fn subpixels_per_side(&self) -> u32 {
        if matches!(self.fill, Fill::Foreground | Fill::Both) {
            self.supersample
        } else {
            1
        }
    }
}

/// The most subpixels per side a frame pixel may be synthesized from.
pub const MAX_SUPERSAMPLE: u32 = 4;

/// How one frame brings its bases' light to its own time: the time
/// interpolation asked for, cut down to what this frame's bases and scene
/// need. Decided once a frame; projection and re-shading follow it rather
/// than each asking the options again.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TimePlan {
    /// Each base time projected into a z-buffer of its own and the two
    /// blended per pixel (`linear`, the paper's `pcomb`).
    pub apart: bool,
    /// Samples moved by their objects' motion to the frame's time.
    pub moved: bool,
    /// Z-buffer entries keep their base time's share of each pixel, which
    /// the per-pixel blend and re-shading weigh the base times by.
    pub alpha: bool,
    /// Mirrors traced again from the frame's rays, and the bases' diffuse
    /// light corrected at the frame's time (re-shading).
    pub reshade: bool,
    /// The diffuse direct light drawn again at the frame's time and every
    /// base time to find where it changed: left out where these are all
    /// one time or nothing in the scene moves, for then every change it
    /// could find is nought.
    pub direct: bool,
}

impl TimePlan {
    /// The plan for a frame at `t` asked for with `interp` from bases at
    /// `times`, in a scene that moves or not.
    pub fn new(interp: TimeInterp, t: f32, times: &[f32], scene_moves: bool) -> Self {
        let reshade = interp == TimeInterp::Reshade;
        Self {
            apart: interp == TimeInterp::Linear,
            moved: interp != TimeInterp::Linear && scene_moves,
            alpha: matches!(interp, TimeInterp::Linear | TimeInterp::Reshade),
            reshade,
            direct: reshade && scene_moves && times.iter().any(|&b| b != t),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_at_its_bases_time_or_in_a_still_scene_draws_no_light_again() {
        let reshade = TimeInterp::Reshade;
        assert!(TimePlan::new(reshade, 0.5, &[0.0, 1.0], true).direct);
        assert!(!TimePlan::new(reshade, 0.5, &[0.5], true).direct);
        assert!(!TimePlan::new(reshade, 0.5, &[0.0, 1.0], false).direct);
        // Mirrors are traced again wherever the frame's camera is.
        assert!(TimePlan::new(reshade, 0.5, &[0.5], false).reshade);
        assert!(!TimePlan::new(TimeInterp::Motion, 0.5, &[0.0, 1.0], true).direct);
    }

    #[test]
    fn one_validate_names_each_front_end_its_own_field() {
        let flag = |f: &str| format!("--{}", f.replace('_', "-"));
        let options = Options {
            supersample: 4,
            ..Options::default()
        };
        options.validate((512, 512), &flag).unwrap();
        let e = options.validate((4096, 4096), &flag).unwrap_err();
        assert!(e.to_string().contains("--supersample 4"), "{e}");
        let none = Options {
            bases: 0,
            ..Options::default()
        };
        let field = |f: &str| format!("options.{f}");
        let e = none.validate((64, 64), &field).unwrap_err();
        assert!(e.to_string().starts_with("options.bases 0"), "{e}");
    }
}

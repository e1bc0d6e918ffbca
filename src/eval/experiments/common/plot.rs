//! PNG line plots of experiment results (plotters, bitmap backend).
//!
//! Text is drawn with DejaVu Sans read from the system (Debian's
//! `fonts-dejavu-core`, installed by `make deps`), so plots look the same on
//! every machine and need no font configuration.

use std::ops::Range;
use std::path::Path;
use std::sync::OnceLock;

use anyhow::{anyhow, Context, Result};
use plotters::coord::ranged1d::{Ranged, ValueFormatter};
use plotters::prelude::*;

/// Where the plots' font is read from.
pub const FONT: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// One labelled set of points, drawn as markers joined by a line.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scale {
    Linear,
    /// Both axes logarithmic (points with a non-positive coordinate are left
    /// out: they have no place on such axes).
    LogLog,
}

#[derive(Clone, Debug)]
pub struct Plot<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub scale: Scale,
    pub series: &'a [Series],
}

const SIZE: (u32, u32) = (900, 600);

/// Tableau 10: distinguishable on white, and for most colour-blind readers.
const COLORS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// `error_per_frame.png` in `dir`: LRMS against scene time, one line per
/// series.
pub fn error_per_frame(dir: &Path, series: &[Series]) -> Result<()> {
    write_png(
        dir.join("error_per_frame.png"),
        &Plot {
            title: "Error per frame",
            x_label: "scene time (s)",
            y_label: "LRMS",
            scale: Scale::Linear,
            series,
        },
    )
}

/// Draws `plot` and writes it to `path` as an RGB PNG.
pub fn write_png(path: impl AsRef<Path>, plot: &Plot) -> Result<()> {
    let path = path.as_ref();
    register_font()?;
    let (w, h) = SIZE;
    let mut rgb = vec![0u8; w as usize * h as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
        let series: Vec<Series> = plot
            .series
            .iter()
            .map(|s| Series {
                label: s.label.clone(),
                points: s
                    .points
                    .iter()
                    .copied()
                    .filter(|&(x, y)| {
                        x.is_finite()
                            && y.is_finite()
                            && (plot.scale == Scale::Linear || (x > 0.0 && y > 0.0))
                    })
                    .collect(),
            })
            .collect();
        let (xr, yr) = bounds(&series, plot.scale);
        let mut builder = ChartBuilder::on(&root);
        builder
            .caption(plot.title, ("sans-serif", 22))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(72);
        match plot.scale {
            Scale::Linear => {
                let chart = builder.build_cartesian_2d(xr, yr);
                draw(chart.map_err(|e| anyhow!("{e}"))?, plot, &series)?;
            }
            Scale::LogLog => {
                let chart = builder.build_cartesian_2d(xr.log_scale(), yr.log_scale());
                draw(chart.map_err(|e| anyhow!("{e}"))?, plot, &series)?;
            }
        }
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    crate::image::png_io::write(path, w, h, &rgb)
        .with_context(|| format!("writing the plot `{}`", plot.title))
}

fn draw<'a, 'b: 'a, X, Y>(
    mut chart: ChartContext<'a, BitMapBackend<'b>, Cartesian2d<X, Y>>,
    plot: &Plot,
    series: &[Series],
) -> Result<()>
where
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(plot.x_label)
        .y_desc(plot.y_label)
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 16));
    if plot.scale == Scale::LogLog {
        mesh.x_label_formatter(&log_label)
            .y_label_formatter(&log_label);
    }
    mesh.draw().map_err(|e| anyhow!("{e}"))?;
    for (i, s) in series.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        chart
            .draw_series(LineSeries::new(
                s.points.iter().copied(),
                color.stroke_width(2),
            ))
            .map_err(|e| anyhow!("{e}"))?
            .label(s.label.as_str())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color.stroke_width(2)));
        chart
            .draw_series(s.points.iter().map(|&p| Circle::new(p, 4, color.filled())))
            .map_err(|e| anyhow!("{e}"))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    Ok(())
}

/// Labels of a logarithmic axis at 1, 2 and 5 times powers of ten only:
/// plotters marks every integer multiple, whose labels run into each other.
fn log_label(v: &f64) -> String {
    let mantissa = v / 10f64.powf(v.log10().floor());
    if [1.0, 2.0, 5.0, 10.0]
        .iter()
        .any(|m| (mantissa - m).abs() < 1e-6)
    {
        super::table::sig(*v, 1)
    } else {
        String::new()
    }
}

/// Axis ranges that hold every point with a margin; a sensible default
/// when there is nothing to show.
fn bounds(series: &[Series], scale: Scale) -> (Range<f64>, Range<f64>) {
    let pts = series.iter().flat_map(|s| s.points.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in pts {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    let pad = |lo: f64, hi: f64| -> Range<f64> {
        match scale {
            _ if lo > hi => match scale {
                Scale::Linear => 0.0..1.0,
                Scale::LogLog => 1e-3..1.0,
            },
            Scale::Linear => {
                let m = if hi > lo {
                    0.05 * (hi - lo)
                } else {
                    0.5 * lo.abs().max(1.0)
                };
                lo - m..hi + m
            }
            Scale::LogLog => lo / 1.5..hi * 1.5,
        }
    };
    // A linear error axis starts at zero: errors are compared to none.
    // The top quarter is left to the legend.
    let mut y = pad(y0, y1);
    match scale {
        Scale::Linear => {
            if y0 >= 0.0 {
                y.start = 0.0;
            }
            y.end += 0.35 * (y.end - y.start);
        }
        Scale::LogLog => y.end *= (y.end / y.start).powf(0.35),
    }
    (pad(x0, x1), y)
}

fn register_font() -> Result<()> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        let bytes = std::fs::read(FONT).map_err(|e| {
            format!(
                "cannot read the plot font {FONT} ({e}): install Debian's fonts-dejavu-core (`make deps`)"
            )
        })?;
        // The font registry keeps `&'static` bytes; this runs once per
        // process, so the one leaked copy is the registry's own.
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
            .map_err(|_| format!("{FONT} is not a font plotters can read"))
    })
    .clone()
    .map_err(|e| anyhow!(e))
}

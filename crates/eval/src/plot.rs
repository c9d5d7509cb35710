//! Plots as PNG and SVG (plotters): the accuracy box plots (one panel per
//! axis, one box per slide position, whiskers at 1.5 IQR) and a residual
//! scatter per calibration method.
//!
//! Text uses DejaVu Sans compiled into the binary (`assets/`, Bitstream Vera
//! licence) through plotters' pure-Rust `ab_glyph` feature: no system font
//! library is needed.

use std::error::Error as StdError;
use std::path::PathBuf;
use std::sync::OnceLock;

use alacs_model::io::OutputDir;
use image::ImageEncoder as _;
use image::codecs::png::PngEncoder;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use crate::accuracy::AccuracyEvaluation;
use crate::calibration::MethodEvaluation;
use crate::{Error, Result};

/// The font every plot's text is set in.
static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// The family name plots ask for.
const FAMILY: &str = "sans-serif";

/// Size of a box-plot figure (three panels side by side), px.
const BOXPLOT_SIZE: (u32, u32) = (1500, 900);

/// Size of a residual figure, px.
const RESIDUAL_SIZE: (u32, u32) = (900, 560);

/// Most points a residual plot draws (half for the inliers, half for the
/// outliers). Past it each series is decimated deterministically
/// ([`decimate`]): per depth column its lowest and highest residual (the
/// envelope, so that every outlier band still shows) and an even stride of
/// the rest. An SVG point takes about 80-180 bytes, so that a plot stays
/// near 3 MB (under 10 MB) whatever the number of samples; the legend
/// still counts every sample.
pub const MAX_PLOT_POINTS: usize = 20_000;

/// A normal distribution's quartiles lie 0.6745 standard deviations from its median.
const QUARTILE_IN_SIGMAS: f64 = 0.6745;

/// Box fill and outline.
const BOX_FILL: RGBColor = RGBColor(166, 206, 227);
const BOX_LINE: RGBColor = RGBColor(31, 120, 180);
/// The predicted-noise marks.
const PREDICTED: RGBColor = RGBColor(51, 160, 44);

type Drawn = std::result::Result<(), Box<dyn StdError>>;

/// Registers the built-in font once.
fn ensure_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err(Error::Plot { path: PathBuf::from("DejaVuSans.ttf"), message: "invalid font".into() })
    }
}

/// Something drawn on any plotters backend.
trait Figure {
    /// Draws the figure on `root`.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Drawn
    where
        DB::ErrorType: 'static;
}

/// Draws the legend of `chart`'s series at `position`, in a translucent
/// white box, its labels `font_size` px.
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
    font_size: u32,
) -> Drawn
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK.mix(0.4))
        .label_font((FAMILY, font_size))
        .draw()?;
    Ok(())
}

/// Draws `figure` into `stem`.png and `stem`.svg in `out` (each encoded in
/// memory, then written atomically); returns both paths.
fn write_png_and_svg(
    out: &mut OutputDir,
    stem: &str,
    size: (u32, u32),
    figure: &impl Figure,
) -> Result<Vec<PathBuf>> {
    ensure_font()?;
    let (png, svg) = (format!("{stem}.png"), format!("{stem}.svg"));
    let plot_error =
        |name: &str, message: String| Error::Plot { path: out.path().join(name), message };

    let mut pixels = vec![0u8; size.0 as usize * size.1 as usize * 3];
    {
        let root = BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area();
        figure.draw(&root).map_err(|e| plot_error(&png, e.to_string()))?;
        root.present().map_err(|e| plot_error(&png, e.to_string()))?;
    }
    let mut encoded = Vec::new();
    PngEncoder::new(&mut encoded)
        .write_image(&pixels, size.0, size.1, image::ExtendedColorType::Rgb8)
        .map_err(|e| plot_error(&png, e.to_string()))?;
    drop(pixels);

    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        figure.draw(&root).map_err(|e| plot_error(&svg, e.to_string()))?;
        root.present().map_err(|e| plot_error(&svg, e.to_string()))?;
    }
    Ok(vec![out.write(&png, encoded)?, out.write(&svg, text)?])
}

/// A tick label: at most three decimals, trailing zeros dropped, no "-0".
fn tick_label(value: &f64) -> String {
    let text = format!("{value:.3}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" { "0".to_string() } else { text.to_string() }
}

/// A range [lo, hi] padded by 6 % (or by `min_pad` when it is empty).
fn padded(lo: f64, hi: f64, min_pad: f64) -> (f64, f64) {
    let pad = ((hi - lo) * 0.06).max(min_pad);
    (lo - pad, hi + pad)
}

/// The accuracy figure: per axis a panel, per slide position a box with
/// whiskers at 1.5 IQR and the points beyond them; the top row to the
/// extremes of the points a fit keeps, the bottom row zoomed to the boxes
/// (points beyond its edge left out, whiskers cut there). Points beyond the
/// fit's threshold ([`crate::AccuracyOptions::rejected_beyond_mm`]) are red
/// crosses beside the boxes (which still count them), at the top row's edge
/// where they lie beyond it.
struct BoxPlots<'a> {
    eval: &'a AccuracyEvaluation,
}

/// How far beyond the quartiles the zoomed row reaches, in IQRs.
const ZOOM_IQRS: f64 = 2.0;

impl BoxPlots<'_> {
    /// The predicted quartiles median +- 0.6745 sigma_z of a slide position's z errors.
    fn predicted(s: &crate::SlideAccuracy) -> (f64, f64) {
        let offset = QUARTILE_IN_SIGMAS * s.predicted_sigma_z_mm;
        (s.error_mm[2].median - offset, s.error_mm[2].median + offset)
    }

    /// One panel: the errors along `axis`, zoomed to the boxes or not.
    fn panel<DB: DrawingBackend>(
        &self,
        panel: &DrawingArea<DB, Shift>,
        axis: usize,
        zoom: bool,
    ) -> Drawn
    where
        DB::ErrorType: 'static,
    {
        let name = ["x", "y", "z"][axis];
        let slides: Vec<f64> = self.eval.slides.iter().map(|s| s.slide_mm).collect();
        let spacing = if slides.len() > 1 {
            slides.windows(2).map(|w| w[1] - w[0]).fold(f64::INFINITY, f64::min)
        } else {
            50.0
        };
        let half_width = 0.25 * spacing;
        let first = slides.first().copied().unwrap_or(0.0);
        let last = slides.last().copied().unwrap_or(0.0);
        let x_range = (first - 0.7 * spacing)..(last + 0.7 * spacing);
        let (mut lo, mut hi) = if zoom {
            self.eval.slides.iter().fold((0.0f64, 0.0f64), |(lo, hi), s| {
                let b = &s.error_mm[axis];
                (lo.min(b.q1 - ZOOM_IQRS * b.iqr()), hi.max(b.q3 + ZOOM_IQRS * b.iqr()))
            })
        } else {
            // The extremes of the points a fit keeps: one stray point does
            // not stretch the panel.
            self.eval
                .points
                .iter()
                .filter(|p| !p.rejected)
                .map(|p| p.error_mm()[axis])
                .fold((0.0f64, 0.0f64), |(lo, hi), e| (lo.min(e), hi.max(e)))
        };
        if axis == 2 {
            for s in &self.eval.slides {
                let (a, b) = Self::predicted(s);
                lo = lo.min(a);
                hi = hi.max(b);
            }
        }
        let (lo, hi) = padded(lo, hi, 0.01);
        let clamp = |v: f64| v.clamp(lo, hi);
        let caption = if zoom {
            format!("{name} error, zoomed to the boxes")
        } else {
            format!("{name}: triangulated - on the board plane")
        };
        let mut chart = ChartBuilder::on(panel)
            .margin(10)
            .caption(caption, (FAMILY, 19))
            .x_label_area_size(42)
            .y_label_area_size(64)
            .build_cartesian_2d(x_range.clone(), lo..hi)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .light_line_style(WHITE)
            .x_labels(slides.len().max(2))
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&tick_label)
            .x_desc("slide position d (mm)")
            .y_desc(format!("{name} error (mm)"))
            .label_style((FAMILY, 15))
            .axis_desc_style((FAMILY, 16))
            .draw()?;
        chart.draw_series(std::iter::once(PathElement::new(
            vec![(x_range.start, 0.0), (x_range.end, 0.0)],
            BLACK.mix(0.3),
        )))?;
        let line = BOX_LINE.stroke_width(2);
        for s in &self.eval.slides {
            let b = &s.error_mm[axis];
            let x = s.slide_mm;
            let cap = 0.5 * half_width;
            let (bottom, top) = (clamp(b.whisker_low), clamp(b.whisker_high));
            chart.draw_series([
                PathElement::new(vec![(x, bottom), (x, clamp(b.q1))], line),
                PathElement::new(vec![(x, clamp(b.q3)), (x, top)], line),
            ])?;
            // The values beyond the whiskers, as points (those inside the panel).
            let outliers = self
                .eval
                .points
                .iter()
                .filter(|p| p.slide_mm == s.slide_mm && !p.rejected)
                .map(|p| p.error_mm()[axis])
                .filter(|&e| b.is_outlier(e) && (lo..=hi).contains(&e))
                .take(MAX_PLOT_POINTS);
            chart
                .draw_series(outliers.map(|e| Circle::new((x, e), 3, BOX_LINE.stroke_width(1))))?;
            // The points the fit rejected, beside the box; beyond the full
            // row's range at its edge, beyond the zoomed row's left out.
            let rejected = self
                .eval
                .points
                .iter()
                .filter(|p| p.slide_mm == s.slide_mm && p.rejected)
                .map(|p| p.error_mm()[axis])
                .filter(|&e| !zoom || (lo..=hi).contains(&e))
                .take(MAX_PLOT_POINTS);
            chart
                .draw_series(rejected.map(|e| {
                    Cross::new((x + 1.4 * half_width, clamp(e)), 4, RED.stroke_width(2))
                }))?;
            // Caps only where the whisker really ends inside the panel.
            for (end, value) in [(bottom, b.whisker_low), (top, b.whisker_high)] {
                if end == value {
                    chart.draw_series(std::iter::once(PathElement::new(
                        vec![(x - cap, end), (x + cap, end)],
                        line,
                    )))?;
                }
            }
            let corners = [(x - half_width, clamp(b.q1)), (x + half_width, clamp(b.q3))];
            chart.draw_series([
                Rectangle::new(corners, BOX_FILL.filled()),
                Rectangle::new(corners, line),
            ])?;
            chart.draw_series(std::iter::once(PathElement::new(
                vec![(x - half_width, clamp(b.median)), (x + half_width, clamp(b.median))],
                BLACK.stroke_width(3),
            )))?;
        }
        if axis == 2 {
            let marks: Vec<PathElement<(f64, f64)>> = self
                .eval
                .slides
                .iter()
                .flat_map(|s| {
                    let (a, b) = Self::predicted(s);
                    let x = s.slide_mm;
                    let w = 1.3 * half_width;
                    [
                        PathElement::new(vec![(x - w, a), (x + w, a)], PREDICTED.stroke_width(2)),
                        PathElement::new(vec![(x - w, b), (x + w, b)], PREDICTED.stroke_width(2)),
                    ]
                })
                .collect();
            chart
                .draw_series(marks)?
                .label(format!(
                    "noise floor: median +- 0.674 sigma_z ({:.3} px)",
                    self.eval.sigma_px
                ))
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], PREDICTED.stroke_width(2))
                });
            if !zoom {
                return Ok(());
            }
            draw_legend(&mut chart, SeriesLabelPosition::LowerRight, 13)?;
        }
        Ok(())
    }
}

impl Figure for BoxPlots<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Drawn
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let (title, body) = root.split_vertically(56);
        let n_rejected = self.eval.n_rejected();
        title.draw(&Text::new(
            format!(
                "Triangulated point minus its board plane, per slide position: {} points ({} per view); boxes: quartiles and median, whiskers: 1.5 IQR, circles: beyond",
                self.eval.points.len(),
                self.eval.points_per_view.as_str()
            ),
            (16, 8),
            (FAMILY, 19).into_font(),
        ))?;
        if let Some(threshold) = self.eval.rejected_beyond_mm {
            title.draw(&Text::new(
                format!(
                    "red crosses beside the boxes: {n_rejected} point(s) beyond the fit's inlier threshold (|z error| > {threshold} mm), at the panel's edge where beyond its range"
                ),
                (16, 32),
                (FAMILY, 16).into_font(),
            ))?;
        }
        for (k, panel) in body.split_evenly((2, 3)).iter().enumerate() {
            self.panel(panel, k % 3, k >= 3)?;
        }
        Ok(())
    }
}

/// One method's residuals against depth, inliers and outliers marked.
struct Residuals<'a> {
    eval: &'a MethodEvaluation,
    depths_mm: &'a [f64],
    /// Each sample's slide position, mm (the colours).
    slides_mm: &'a [f64],
    /// At most this many points drawn ([`MAX_PLOT_POINTS`]).
    max_points: usize,
}

/// The points of a series of `n` (`series` yields them, again on each
/// call) to draw, at most `max`: all of them when they are few; else, with
/// x in `x_range` cut into `max / 4` columns, each column's lowest and
/// highest y (the envelope and its outliers) and every k-th point with
/// k = ceil(2 n / max). Deterministic: the same points give the same plot.
fn decimate<I: Iterator<Item = (f64, f64)>>(
    series: impl Fn() -> I,
    n: usize,
    x_range: (f64, f64),
    max: usize,
) -> Vec<(f64, f64)> {
    if n <= max {
        return series().collect();
    }
    let columns = (max / 4).max(1);
    let width = (x_range.1 - x_range.0).max(f64::MIN_POSITIVE);
    let mut low: Vec<Option<(f64, f64)>> = vec![None; columns];
    let mut high: Vec<Option<(f64, f64)>> = vec![None; columns];
    let step = (2 * n).div_ceil(max.max(1)).max(1);
    let mut kept = Vec::with_capacity(max);
    for (i, (x, y)) in series().enumerate() {
        let column = (((x - x_range.0) / width * columns as f64) as usize).min(columns - 1);
        if low[column].is_none_or(|(_, lo)| y < lo) {
            low[column] = Some((x, y));
        }
        if high[column].is_none_or(|(_, hi)| y > hi) {
            high[column] = Some((x, y));
        }
        if i % step == 0 {
            kept.push((x, y));
        }
    }
    kept.extend(low.into_iter().chain(high).flatten());
    kept
}

/// A slide position to 0.1 mm: the key the plots colour by.
fn slide_key(slide_mm: f64) -> f64 {
    (slide_mm * 10.0).round() / 10.0
}

/// Distinct slide positions of `slides_mm` ([`slide_key`]), ascending.
fn distinct_slides(slides_mm: &[f64]) -> Vec<f64> {
    let mut distinct: Vec<f64> = slides_mm.iter().map(|&d| slide_key(d)).collect();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    distinct
}

/// The colour of slide position `index`.
fn slide_colour(index: usize) -> RGBColor {
    let c = Palette99::pick(index).to_rgba();
    RGBColor(c.0, c.1, c.2)
}

/// The residual axis of a plot zoomed to `shown` (the inliers) and the
/// threshold band +-`threshold_mm` where there is one, padded.
fn zoomed_range(shown: impl Iterator<Item = f64>, threshold_mm: Option<f64>) -> (f64, f64) {
    let band = threshold_mm.unwrap_or(0.0);
    let (lo, hi) = shown.fold((-band, band), |(lo, hi), r| (lo.min(r), hi.max(r)));
    padded(lo, hi, 0.01)
}

/// Draws the threshold band +-`threshold_mm` across `x_range`.
fn draw_band<DB: DrawingBackend, CT: CoordTranslate<From = (f64, f64)>>(
    chart: &mut ChartContext<'_, DB, CT>,
    x_range: (f64, f64),
    threshold_mm: f64,
) -> Drawn
where
    DB::ErrorType: 'static,
{
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(x_range.0, -threshold_mm), (x_range.1, threshold_mm)],
            PREDICTED.mix(0.12).filled(),
        )))?
        .label(format!("inlier threshold +-{threshold_mm:.2} mm"))
        .legend(|(x, y)| {
            Rectangle::new([(x, y - 5), (x + 20, y + 5)], PREDICTED.mix(0.3).filled())
        });
    Ok(())
}

impl Figure for Residuals<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Drawn
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let c = &self.eval.calibration;
        let (z_lo, z_hi) = self
            .depths_mm
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &z| (lo.min(z), hi.max(z)));
        // Zoomed to the fitted samples (and the threshold band of a robust
        // fit): the inliers' structure shows; outliers beyond are drawn at
        // the edge.
        let band = c.ransac_iterations.is_some().then_some(c.threshold_mm);
        let inlier_residuals = self
            .eval
            .residuals_mm
            .iter()
            .zip(&self.eval.is_inlier)
            .filter(|(_, inlier)| **inlier)
            .map(|(r, _)| *r);
        let (z_lo, z_hi) = padded(z_lo, z_hi, 1.0);
        let (r_lo, r_hi) = zoomed_range(inlier_residuals, band);
        let mut chart = ChartBuilder::on(root)
            .margin(14)
            .caption(
                format!(
                    "Method {} ({}): mean |z - z_hat| {:.3} mm, {} of {} samples fitted",
                    c.method.number(),
                    c.method.name(),
                    c.mean_abs_error_mm,
                    c.inliers.len(),
                    c.n_samples
                ),
                (FAMILY, 19),
            )
            .x_label_area_size(46)
            .y_label_area_size(70)
            .build_cartesian_2d(z_lo..z_hi, r_lo..r_hi)?;
        chart
            .configure_mesh()
            .light_line_style(WHITE)
            .x_label_formatter(&tick_label)
            .y_label_formatter(&tick_label)
            .x_desc("depth z from the board pose (mm)")
            .y_desc("z - z_hat (mm)")
            .label_style((FAMILY, 15))
            .axis_desc_style((FAMILY, 16))
            .draw()?;
        if let Some(threshold_mm) = band {
            draw_band(&mut chart, (z_lo, z_hi), threshold_mm)?;
        }
        chart.draw_series(std::iter::once(PathElement::new(
            vec![(z_lo, 0.0), (z_hi, 0.0)],
            BLACK.mix(0.4),
        )))?;
        let slides = distinct_slides(self.slides_mm);
        let slide_of = |i: usize| {
            let d = slide_key(self.slides_mm.get(i).copied().unwrap_or(0.0));
            slides.iter().position(|&s| s == d).unwrap_or(0)
        };
        let points = |inlier: bool, slide: Option<usize>| {
            self.depths_mm
                .iter()
                .zip(&self.eval.residuals_mm)
                .zip(&self.eval.is_inlier)
                .enumerate()
                .filter(move |(i, (_, flag))| {
                    **flag == inlier && slide.is_none_or(|k| slide_of(*i) == k)
                })
                .map(|(_, ((&z, &r), _))| (z, r.clamp(r_lo, r_hi)))
        };
        let drawn = |n: usize, shown: usize| {
            if shown < n { format!("{n} ({shown} drawn)") } else { n.to_string() }
        };
        // The inliers coloured by slide position, the cap shared among them.
        let per_slide = self.max_points / 2 / slides.len().max(1);
        for (k, &slide_mm) in slides.iter().enumerate() {
            let n = points(true, Some(k)).count();
            if n == 0 {
                continue;
            }
            let shown = decimate(|| points(true, Some(k)), n, (z_lo, z_hi), per_slide);
            let colour = slide_colour(k);
            chart
                .draw_series(shown.iter().map(|&p| Circle::new(p, 2, colour.filled())))?
                .label(format!("fitted, slide {slide_mm} mm: {}", drawn(n, shown.len())))
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, colour.filled()));
        }
        let n_out = points(false, None).count();
        if n_out > 0 {
            let beyond = self
                .eval
                .residuals_mm
                .iter()
                .zip(&self.eval.is_inlier)
                .filter(|(r, inlier)| !**inlier && !(r_lo..=r_hi).contains(*r))
                .count();
            let outliers =
                decimate(|| points(false, None), n_out, (z_lo, z_hi), self.max_points / 2);
            chart
                .draw_series(outliers.iter().map(|&p| Cross::new(p, 4, RED.stroke_width(2))))?
                .label(format!(
                    "rejected (outlier), {}; {beyond} beyond the range, at its edge",
                    drawn(n_out, outliers.len())
                ))
                .legend(|(x, y)| Cross::new((x + 10, y), 4, RED.stroke_width(2)));
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 14)?;
        Ok(())
    }
}

/// One view in [`write_view_plots`]: its board pose's reprojection RMS,
/// its slide position, its samples' residuals under the reported laser and
/// whether it is flagged.
#[derive(Debug, Clone)]
pub struct ViewDiagnostics {
    /// The board pose's RMS reprojection error, px (`None`: no pose).
    pub pose_rms_px: Option<f64>,
    /// Slide travel d of the view, mm.
    pub slide_mm: f64,
    /// z - z_hat of each sample, mm.
    pub residuals_mm: Vec<f64>,
    /// Whether the report flags the view's board pose (its RMS): its bar
    /// is drawn red. Views flagged for other reasons keep a plain bar.
    pub pose_flagged: bool,
}

/// Size of the per-view figure, px.
const VIEWS_SIZE: (u32, u32) = (1100, 820);

/// Most residuals drawn per view (an even stride beyond).
const MAX_POINTS_PER_VIEW: usize = 400;

/// The per-view figure: the board poses' RMS as bars (red where the RMS is flagged),
/// and under them each view's residuals as a strip coloured by slide
/// position, zoomed to the threshold band.
struct Views<'a> {
    views: &'a [ViewDiagnostics],
    threshold_mm: f64,
}

impl Figure for Views<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Drawn
    where
        DB::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let (top, bottom) = root.split_vertically(VIEWS_SIZE.1 * 2 / 5);
        let n = self.views.len().max(1) as f64;
        let x_range = 0.5..n + 0.5;
        let rms_max = self.views.iter().filter_map(|v| v.pose_rms_px).fold(0.0_f64, f64::max);
        let mut bars = ChartBuilder::on(&top)
            .margin(12)
            .caption("Board pose reprojection RMS per view", (FAMILY, 18))
            .x_label_area_size(30)
            .y_label_area_size(70)
            .build_cartesian_2d(x_range.clone(), 0.0..(rms_max * 1.15).max(0.01))?;
        bars.configure_mesh()
            .light_line_style(WHITE)
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&tick_label)
            .y_desc("RMS (px)")
            .label_style((FAMILY, 14))
            .axis_desc_style((FAMILY, 15))
            .draw()?;
        bars.draw_series(self.views.iter().enumerate().filter_map(|(i, v)| {
            let x = i as f64 + 1.0;
            let colour = if v.pose_flagged { RED } else { BOX_LINE };
            v.pose_rms_px
                .map(|rms| Rectangle::new([(x - 0.35, 0.0), (x + 0.35, rms)], colour.filled()))
        }))?;

        let slides_of_views: Vec<f64> = self.views.iter().map(|v| v.slide_mm).collect();
        let slides = distinct_slides(&slides_of_views);
        let (r_lo, r_hi) = zoomed_range(
            self.views
                .iter()
                .flat_map(|v| &v.residuals_mm)
                .copied()
                .filter(|r| r.abs() <= self.threshold_mm),
            Some(self.threshold_mm),
        );
        let mut strips = ChartBuilder::on(&bottom)
            .margin(12)
            .caption(
                "Residuals z - z_hat of the reported laser per view (beyond the band: at its edge)",
                (FAMILY, 18),
            )
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(x_range, r_lo..r_hi)?;
        strips
            .configure_mesh()
            .light_line_style(WHITE)
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&tick_label)
            .x_desc("view")
            .y_desc("z - z_hat (mm)")
            .label_style((FAMILY, 14))
            .axis_desc_style((FAMILY, 15))
            .draw()?;
        draw_band(&mut strips, (0.5, n + 0.5), self.threshold_mm)?;
        for (k, &slide_mm) in slides.iter().enumerate() {
            let colour = slide_colour(k);
            let points: Vec<(f64, f64)> = self
                .views
                .iter()
                .enumerate()
                .filter(|(_, v)| slide_key(v.slide_mm) == slide_mm)
                .flat_map(|(i, v)| {
                    let step = v.residuals_mm.len().div_ceil(MAX_POINTS_PER_VIEW).max(1);
                    let count = v.residuals_mm.len().max(1) as f64;
                    v.residuals_mm.iter().enumerate().step_by(step).map(move |(j, r)| {
                        // Spread across the view's column so the strip shows density.
                        let x = i as f64 + 1.0 + 0.6 * (j as f64 / count - 0.5);
                        (x, r.clamp(r_lo, r_hi))
                    })
                })
                .collect();
            if points.is_empty() {
                continue;
            }
            strips
                .draw_series(points.into_iter().map(|p| Circle::new(p, 1, colour.filled())))?
                .label(format!("slide {slide_mm} mm"))
                .legend(move |(x, y)| Circle::new((x + 10, y), 3, colour.filled()));
        }
        draw_legend(&mut strips, SeriesLabelPosition::UpperRight, 13)?;
        Ok(())
    }
}

/// Writes the per-view figure (board pose RMS bars, residual strips
/// coloured by slide, the threshold band) to `stem`.png and `stem`.svg.
pub fn write_view_plots(
    out: &mut OutputDir,
    stem: &str,
    views: &[ViewDiagnostics],
    threshold_mm: f64,
) -> Result<Vec<PathBuf>> {
    write_png_and_svg(out, stem, VIEWS_SIZE, &Views { views, threshold_mm })
}

/// Writes the accuracy box plots to `stem`.png and `stem`.svg in `out`.
pub fn write_accuracy_boxplots(
    out: &mut OutputDir,
    stem: &str,
    eval: &AccuracyEvaluation,
) -> Result<Vec<PathBuf>> {
    write_png_and_svg(out, stem, BOXPLOT_SIZE, &BoxPlots { eval })
}

/// Writes one method's residual scatter (z - z_hat against z; the inliers
/// coloured by slide position, the outliers marked; zoomed to the inliers
/// with a robust fit's threshold band) to `stem`.png and `stem`.svg in `out`.
pub fn write_residual_plot(
    out: &mut OutputDir,
    stem: &str,
    method: &MethodEvaluation,
    depths_mm: &[f64],
    slides_mm: &[f64],
) -> Result<Vec<PathBuf>> {
    write_png_and_svg(
        out,
        stem,
        RESIDUAL_SIZE,
        &Residuals { eval: method, depths_mm, slides_mm, max_points: MAX_PLOT_POINTS },
    )
}

#[cfg(test)]
mod tests {
    use super::{decimate, tick_label};

    #[test]
    fn decimation_keeps_the_extremes_and_the_cap() {
        let n = 100_000;
        let y = |i: usize| if i == 77_777 { 500.0 } else { ((i * 7919) % 1000) as f64 / 1000.0 };
        let series = || (0..n).map(|i| (i as f64 / n as f64, y(i)));
        let kept = decimate(series, n, (0.0, 1.0), 1000);
        assert!(kept.len() <= 1000, "{}", kept.len());
        assert!(kept.contains(&(0.77777, 500.0)), "the outlier shows");
        assert_eq!(kept, decimate(series, n, (0.0, 1.0), 1000), "deterministic");
        assert_eq!(decimate(series, n, (0.0, 1.0), n).len(), n, "few points: all");
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick_label(&-0.0000001), "0");
        assert_eq!(tick_label(&0.05), "0.05");
        assert_eq!(tick_label(&2.0), "2");
        assert_eq!(tick_label(&-1.5), "-1.5");
        assert_eq!(tick_label(&600.0), "600");
    }
}

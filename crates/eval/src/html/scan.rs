//! The scan report: a localization with its frames, per frame the search
//! region, the stripe, the fruit points, the candidate and the fitted
//! sphere's silhouette drawn over a crop around the fruit.

use std::path::PathBuf;

use alacs_locate::fit::Sphere;
use alacs_locate::{Localization, Prior};
use alacs_model::io::OutputDir;
use alacs_model::{Camera, LaserModel};
use image::RgbImage;
use nalgebra::{Point2, Point3, Vector3};
use rayon::prelude::*;

use super::draw::{BLUE, CYAN, Canvas, LIME, MAGENTA, ORANGE, WHITE, YELLOW};
use super::page::{Page, fixed, num, txt};
use crate::Result;

/// Widest overview image on the page (px).
const MAX_OVERVIEW_WIDTH_PX: u32 = 1224;
/// Widest frame crop on the page (px).
const MAX_CROP_WIDTH_PX: u32 = 900;
/// Narrower crops (a far fruit, a low-resolution camera) are enlarged by a
/// whole factor to at least this width (px).
const MIN_CROP_WIDTH_PX: u32 = 320;
/// Margin around the search region in a crop, as a fraction of its size.
const CROP_MARGIN: f64 = 0.15;
/// Points on a projected sphere silhouette.
const SILHOUETTE_POINTS: usize = 90;

/// One frame of a scan, as the report draws it.
#[derive(Debug, Clone, Copy)]
pub struct ScanReportFrame<'a> {
    /// The frame's name (its file), shown on the page.
    pub name: &'a str,
    /// The frame with the laser on.
    pub image: &'a RgbImage,
}

/// What a scan report shows.
#[derive(Debug, Clone, Copy)]
pub struct ScanReport<'a> {
    /// Where the scan came from (its folder), shown on the page.
    pub source: &'a str,
    /// The camera the scan was located with.
    pub camera: &'a Camera,
    /// The laser it was located with.
    pub laser: &'a LaserModel,
    /// The prior (rough position, radius).
    pub prior: &'a Prior,
    /// The frames, in the localization's order.
    pub frames: &'a [ScanReportFrame<'a>],
    /// The localization of these frames.
    pub localization: &'a Localization,
}

/// The image points of the silhouette of `sphere` (the circle where the
/// camera's rays touch it), through the camera's distortion; empty when the
/// camera is inside the sphere.
pub fn sphere_silhouette_px(camera: &Camera, sphere: &Sphere) -> Vec<Point2<f64>> {
    let centre = sphere.centre.coords;
    let distance_mm = centre.norm();
    // Also the NaN of a degenerate sphere.
    if distance_mm.partial_cmp(&sphere.radius_mm) != Some(std::cmp::Ordering::Greater) {
        return Vec::new();
    }
    let axis = centre / distance_mm;
    let helper = if axis.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let u = axis.cross(&helper).normalize();
    let v = axis.cross(&u);
    let sin = sphere.radius_mm / distance_mm;
    let cos = (1.0 - sin * sin).sqrt();
    (0..SILHOUETTE_POINTS)
        .filter_map(|k| {
            let phi = std::f64::consts::TAU * k as f64 / SILHOUETTE_POINTS as f64;
            let ray = axis * cos + (u * phi.cos() + v * phi.sin()) * sin;
            camera.project(&Point3::from(ray * (distance_mm * cos))).ok()
        })
        .collect()
}

/// The rectangle [u0, v0, width, height] around `points` with a margin, or
/// around `fallback` with `half_px` either side.
fn crop_rect(points: &[Point2<f64>], fallback: Option<Point2<f64>>, half_px: f64) -> [u32; 4] {
    let (mut lo, mut hi) = (
        Point2::new(f64::INFINITY, f64::INFINITY),
        Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for p in points.iter().filter(|p| p.x.is_finite() && p.y.is_finite()) {
        lo = Point2::new(lo.x.min(p.x), lo.y.min(p.y));
        hi = Point2::new(hi.x.max(p.x), hi.y.max(p.y));
    }
    // No finite point: a box around the fallback.
    if lo.x > hi.x {
        let centre = fallback.unwrap_or(Point2::new(half_px, half_px));
        lo = centre - nalgebra::Vector2::repeat(half_px);
        hi = centre + nalgebra::Vector2::repeat(half_px);
    }
    let margin = CROP_MARGIN * (hi.x - lo.x).max(hi.y - lo.y) + 4.0;
    let u0 = (lo.x - margin).max(0.0);
    let v0 = (lo.y - margin).max(0.0);
    [
        u0 as u32,
        v0 as u32,
        (hi.x + margin - u0).max(1.0) as u32,
        (hi.y + margin - v0).max(1.0) as u32,
    ]
}

/// Draws one frame's overlays on `canvas`.
fn draw_frame(canvas: &mut Canvas, report: &ScanReport, index: usize, silhouette: &[Point2<f64>]) {
    let answer = report.localization;
    let Some(frame) = answer.frames.get(index) else {
        return;
    };
    let (mark, dot) = (canvas.mark_px(), canvas.dot_px());
    canvas.polyline(&frame.region_outline_px, true, YELLOW);
    canvas.polyline(silhouette, true, MAGENTA);
    if let Some(outline) = answer.fused.as_ref().and_then(|f| f.outline.as_ref()) {
        canvas.circle(&outline.centre_px, outline.radius_px, ORANGE);
        for p in &outline.edges_px {
            canvas.dot(p, dot, ORANGE);
        }
    }
    let mut on_fruit = vec![false; frame.stripe.len()];
    for &i in &frame.fruit {
        if let Some(flag) = on_fruit.get_mut(i) {
            *flag = true;
        }
    }
    for (point, fruit) in frame.stripe.iter().zip(&on_fruit) {
        let p = Point2::new(point.u_px, point.v_px);
        canvas.dot(&p, dot, if *fruit { LIME } else { BLUE });
    }
    let project = |p: &Point3<f64>| report.camera.project(p).ok();
    if let Some(candidate) = &frame.candidate
        && let Some(p) = project(&candidate.position_mm)
    {
        let chosen = answer.holistic.and_then(|h| answer.candidates.get(h)) == Some(candidate);
        canvas.cross(&p, if chosen { 1.5 * mark } else { mark }, CYAN);
        if chosen {
            canvas.circle(&p, 2.0 * mark / canvas.scale(), CYAN);
        }
    }
    if let Some(p) = answer.position_mm.as_ref().and_then(project) {
        canvas.x_mark(&p, 1.3 * mark, WHITE);
    }
}

/// Writes the report as `dir`/index.html with its images (`images/`)
/// beside it. Returns every file written, the page first.
pub fn write_scan_html(out: &mut OutputDir, report: &ScanReport) -> Result<Vec<PathBuf>> {
    let answer = report.localization;
    let silhouette = answer
        .fused
        .as_ref()
        .map(|f| sphere_silhouette_px(report.camera, &f.sphere))
        .unwrap_or_default();
    let rough_px = report.camera.project(&report.prior.rough_position_mm).ok();
    let search_half_px =
        report.camera.fx_px * answer.search_radius_mm / report.prior.rough_position_mm.z.max(1.0);
    let n = report.frames.len().min(answer.frames.len());
    let dir = out.path().to_path_buf();
    // The overview (the middle frame whole, every frame's region on it),
    // then a crop per frame; all encoded before any is written, so that one
    // that fails leaves the folder as it was.
    let names: Vec<String> = (n > 0)
        .then(|| "images/overview.jpg".to_string())
        .into_iter()
        .chain((0..n).map(|i| format!("images/frame{i:02}.jpg")))
        .collect();
    let images: Vec<Vec<u8>> = names
        .par_iter()
        .enumerate()
        .map(|(k, name)| {
            let path = dir.join(name);
            if k == 0 {
                let middle = n / 2;
                let mut canvas = Canvas::whole(report.frames[middle].image, MAX_OVERVIEW_WIDTH_PX);
                for frame in &answer.frames {
                    canvas.polyline(&frame.region_outline_px, true, YELLOW);
                }
                draw_frame(&mut canvas, report, middle, &silhouette);
                if let Some(p) = &rough_px {
                    canvas.cross(p, 2.0 * canvas.mark_px(), ORANGE);
                }
                return canvas.jpeg(&path);
            }
            let i = k - 1;
            let mut outline = answer.frames[i].region_outline_px.clone();
            outline.extend_from_slice(&silhouette);
            let rect = crop_rect(&outline, rough_px, search_half_px);
            let mut canvas =
                Canvas::crop(report.frames[i].image, rect, MIN_CROP_WIDTH_PX, MAX_CROP_WIDTH_PX);
            draw_frame(&mut canvas, report, i, &silhouette);
            canvas.jpeg(&path)
        })
        .collect::<Result<_>>()?;
    let mut files = Vec::new();
    for (name, bytes) in names.iter().zip(images) {
        files.push(out.write(name, bytes)?);
    }

    let title = "alacs scan report";
    let mut page = Page::new(title);
    page.paragraph(
        &format!("Scan {}: {} frames, located with the camera \"{}\" and a {} laser (alpha {:.3} deg, beta {:.3} deg, L0 {:.2} mm, slide scale {:.5}).",
            report.source, report.frames.len(), report.camera.name, report.laser.fidelity.as_str(),
            report.laser.alpha_deg(), report.laser.beta_deg(), report.laser.l0_mm, report.laser.slide_scale),
        None,
    );
    summary(&mut page, report);
    candidates(&mut page, answer);
    page.heading("Frames");
    page.raw(
        "<p class=\"legend\"><span style=\"color:#c90\">&#9645; search region</span><span style=\"color:#28f\">&bull; stripe</span><span style=\"color:#3c3\">&bull; fruit points</span><span style=\"color:#0bb\">+ candidate (circled: the holistic choice)</span><span style=\"color:#c0c\">&#9675; fitted sphere's silhouette</span><span style=\"color:#e80\">&#9675; outline in the image, + rough position</span><span>&times; the answer (white)</span></p>",
    );
    if n > 0 {
        page.figure(
            &["images/overview.jpg"],
            &format!("Overview: frame {} with every frame's search region", n / 2),
            None,
        );
    }
    page.grid_start();
    for (i, frame) in answer.frames.iter().enumerate().take(n) {
        let name = format!("images/frame{i:02}.jpg");
        let caption = format!(
            "Frame {i} ({}, slide {:.1} mm): {} stripe points, {} triangulated, {} on the fruit{}",
            report.frames[i].name,
            frame.slide_mm,
            frame.stripe.len(),
            frame.points_in_camera.len(),
            frame.fruit.len(),
            if frame.candidate.is_some() { ", a candidate" } else { "" }
        );
        page.figure(&[&name], &caption, frame.rejected.as_deref());
    }
    page.grid_end();
    files.insert(0, page.write(out, title)?);
    Ok(files)
}

/// "x, y, z" of a point, mm.
fn xyz(p: &Point3<f64>) -> String {
    format!("{:.2}, {:.2}, {:.2}", p.x, p.y, p.z)
}

/// The localization's summary.
fn summary(page: &mut Page, report: &ScanReport) {
    let answer = report.localization;
    page.heading("Localization");
    let mut rows = vec![
        (vec![txt("status"), txt(answer.status.as_str())], answer.position_mm.is_none()),
        (
            vec![
                txt("position (mm, camera frame)"),
                txt(answer.position_mm.as_ref().map(xyz).unwrap_or_else(|| "-".into())),
            ],
            false,
        ),
        (vec![txt("radius (mm)"), txt(fixed(answer.radius_mm, 2))], false),
        (vec![txt("method"), txt(answer.method.as_str())], false),
        (vec![txt("reason"), txt(answer.reason.clone())], false),
        (vec![txt("rough position (mm)"), txt(xyz(&report.prior.rough_position_mm))], false),
        (
            vec![txt("radius prior (mm)"), txt(format!("{:.1}", report.prior.fruit_radius_mm))],
            false,
        ),
        (
            vec![txt("search ball radius (mm)"), txt(format!("{:.1}", answer.search_radius_mm))],
            false,
        ),
    ];
    if let Some(fused) = &answer.fused {
        rows.push((vec![txt("fused sphere centre (mm)"), txt(xyz(&fused.sphere.centre))], false));
        rows.push((
            vec![
                txt("fused sphere radius (mm)"),
                txt(format!(
                    "{:.2}{}",
                    fused.sphere.radius_mm,
                    if fused.radius_from_prior { " (the prior)" } else { "" }
                )),
            ],
            false,
        ));
        if let Some(e) = &fused.ellipsoid {
            let axes = e.semi_axes_mm();
            rows.push((vec![txt("ellipsoid centre (mm)"), txt(xyz(&e.centre))], false));
            rows.push((
                vec![
                    txt("ellipsoid semi-axes (mm)"),
                    txt(format!("{:.2}, {:.2}, {:.2}", axes.x, axes.y, axes.z)),
                ],
                false,
            ));
        }
        rows.push((
            vec![
                txt("fused points / frames"),
                txt(format!("{} / {}", fused.n_points, fused.n_frames)),
            ],
            false,
        ));
        rows.push((vec![txt("fused RMS (mm)"), txt(format!("{:.3}", fused.rms_mm))], false));
        if let Some(o) = &fused.outline {
            rows.push((
                vec![
                    txt("outline in the image (px)"),
                    txt(format!(
                        "centre {:.1}, {:.1}, radius {:.1}, support {:.2}, fill {:.2}",
                        o.centre_px.x, o.centre_px.y, o.radius_px, o.support, o.fill
                    )),
                ],
                false,
            ));
        }
    }
    if let Some(reason) = &answer.fused_rejected {
        rows.push((vec![txt("free fused fit rejected"), txt(reason.clone())], false));
    }
    page.table(&[txt(""), txt("value")], &rows);
}

/// The candidates table.
fn candidates(page: &mut Page, answer: &Localization) {
    page.heading("Candidates (one per frame)");
    if answer.candidates.is_empty() {
        page.paragraph("No frame gave a candidate.", Some("flag"));
        return;
    }
    let rows = answer
        .candidates
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let chosen = if answer.selected == Some(i) {
                "selected"
            } else if answer.holistic == Some(i) {
                "holistic choice"
            } else {
                ""
            };
            (
                vec![
                    num(c.frame.to_string()),
                    num(format!("{:.1}", c.slide_mm)),
                    num(xyz(&c.position_mm)),
                    num(format!("{:.2}", c.circle_radius_mm)),
                    num(c.n_points.to_string()),
                    num(format!("{:.2}", c.continuity)),
                    num(format!("{:.3}", c.fit_rms_mm)),
                    num(format!("{:.3}", c.score)),
                    txt(chosen),
                ],
                false,
            )
        })
        .collect::<Vec<_>>();
    page.table(
        &[
            num("frame"),
            num("slide (mm)"),
            num("position (mm)"),
            num("circle radius (mm)"),
            num("points"),
            num("continuity"),
            num("fit RMS (mm)"),
            num("score"),
            txt(""),
        ],
        &rows,
    );
}

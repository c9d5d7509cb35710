//! The HTML reports are self-contained: every image and plot the page
//! references is beside it and non-empty, and nothing points off the
//! machine. Quarter-scale renders (612 x 512 px) of a small session and a
//! small scan keep it to a few seconds.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::path::{Path, PathBuf};

use alacs_eval::{
    OutputKind, ScanReport, ScanReportFrame, calibration_report, open_output,
    write_calibration_html, write_scan_html,
};
use alacs_locate::{FrameImages, LocateOptions, Prior, locate};
use alacs_model::{Camera, Fidelity, LaserModel, Session};
use alacs_sim::{
    RenderedScan, ScanOptions, SessionOptions, simulate_rendered_scan, simulate_session,
};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("alacs-html-{name}-{}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    dir
}

fn laser() -> LaserModel {
    LaserModel::from_degrees(Fidelity::High, 19.07, 0.69, 381.98)
}

/// Every `src="..."` and `href="..."` of `html`.
fn references(html: &str) -> Vec<String> {
    let mut found = Vec::new();
    for key in ["src=\"", "href=\""] {
        let mut rest = html;
        while let Some(start) = rest.find(key) {
            rest = &rest[start + key.len()..];
            let end = rest.find('"').unwrap();
            found.push(rest[..end].to_string());
            rest = &rest[end..];
        }
    }
    found
}

/// Checks the page at `dir`/index.html; returns its text and references.
fn check_self_contained(dir: &Path) -> (String, Vec<String>) {
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    let refs = references(&html);
    assert!(!refs.is_empty());
    for r in &refs {
        assert!(
            !r.starts_with("http:") && !r.starts_with("https:") && !r.starts_with("//"),
            "an external link: {r}"
        );
        assert!(!r.starts_with('/') && !r.contains(".."), "not beside the page: {r}");
        let len = std::fs::metadata(dir.join(r)).map(|m| m.len()).unwrap_or(0);
        assert!(len > 0, "{r} is missing or empty");
    }
    assert!(!html.contains("<script"), "no scripts");
    (html, refs)
}

#[test]
fn calibration_report_is_self_contained_and_flags_a_bad_view() {
    let options = SessionOptions {
        n_views: 4,
        slides_mm: vec![0.0, 200.0],
        scale: 0.25,
        seed: 5,
        ..SessionOptions::default()
    };
    let simulated = simulate_session(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap();
    let dir = temp_dir("calibration");
    simulated.write(&dir).unwrap();
    // One view without a board: a grey image, to be flagged with its reason.
    let session = Session::read(&dir).unwrap();
    let blank = image::RgbImage::from_pixel(
        simulated.camera.width_px,
        simulated.camera.height_px,
        image::Rgb([128, 128, 128]),
    );
    blank.save(session.path_of(&session.views[1].image)).unwrap();

    let report = calibration_report(&session, &simulated.camera, &laser(), None, &|| {}).unwrap();
    assert_eq!(report.views.len(), 8);
    assert!(report.views[1].flag.as_deref().unwrap().contains("not used"));
    let good = &report.views[0];
    assert!(good.flag.is_none(), "{:?}", good.flag);
    assert_eq!(good.corners_px.len(), session.board.cols * session.board.rows);
    // With the true laser the residuals are the stripe's and the board pose's
    // noise: well within the inlier threshold even at quarter scale (f = 580 px).
    // At quarter scale a square is about 12 px wide, so most stripe points
    // have a square's edge within 1.5 stripe widths and are no samples.
    assert!(!good.stripe_px.is_empty(), "{:?}", good.flag);
    assert!(good.mean_abs_residual_mm().unwrap() < report.threshold_mm);
    assert!(report.table_1.is_ok() && report.accuracy.is_ok());

    let out = dir.join("report <&>");
    let mut output = open_output(&out, OutputKind::ReportCalibration, false).unwrap();
    let files = write_calibration_html(&mut output, &session, &report, "session <&>").unwrap();
    output.finish().unwrap();
    assert_eq!(files[0], out.join("index.html"));
    let (html, refs) = check_self_contained(&out);
    for i in 1..=8 {
        assert!(refs.contains(&format!("images/view{i:02}.jpg")), "view {i}");
    }
    for plot in [
        "calibration_residuals_method4.png",
        "accuracy_boxplots.png",
        "calibration_views.png",
        "images/corner_coverage.jpg",
    ] {
        assert!(refs.iter().any(|r| r == plot), "{plot}");
    }
    // Issue 17's diagnostics: the coverage counted, the distortion
    // coefficients named, standard deviations beside the camera's values
    // (4 board poses: too few for the laser's bootstrap, and the page says so).
    assert!(html.contains("corner coverage (8 x 6 cells)"), "coverage");
    assert!(html.contains("k1 ") && html.contains("p2 "), "coefficient names");
    assert!(report.camera_std.is_some() && html.contains(" +- "), "standard deviations");
    assert!(report.laser_std.is_none() && html.contains("fewer than 5 board poses"));
    // Two slide positions fit k: no warning that it was held.
    assert!(!html.contains("held at 1"), "a k-held warning on a two-slide session");
    // The quarter-scale images are narrower than the page's: no full-size copies.
    assert!(!refs.iter().any(|r| r.ends_with("_full.jpg")));
    assert!(html.contains("session &lt;&amp;&gt;") && !html.contains("session <&>"));
    assert!(html.contains("Method 4") && html.contains("class=\"bad\""));
    std::fs::remove_dir_all(&dir).ok();
}

/// A simulated quarter-scale scan, its frames and its localization.
struct ScanFixture {
    scan: alacs_sim::SimulatedScan,
    images: Vec<image::RgbImage>,
    prior: Prior,
    answer: alacs_locate::Localization,
}

fn scan_fixture() -> ScanFixture {
    let options = ScanOptions { scale: 0.25, seed: 3, ..ScanOptions::default() };
    let sim = simulate_rendered_scan(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap();
    let frames: Vec<_> = sim.frames().map(FrameImages::from).collect();
    let prior = Prior { rough_position_mm: sim.scan.rough_position_mm, fruit_radius_mm: 40.0 };
    let (camera, laser) = (&sim.scan.camera, &sim.scan.laser);
    let answer = locate(camera, laser, &prior, &frames, &LocateOptions::default()).unwrap();
    let RenderedScan { scan, images } = sim;
    ScanFixture { scan, images, prior, answer }
}

impl ScanFixture {
    /// Writes the report of the first `n` frames (`images` in place of the
    /// fixture's) into `dir`.
    fn write(&self, dir: &Path, images: &[image::RgbImage], force: bool) -> alacs_eval::Result<()> {
        let frames: Vec<_> = images
            .iter()
            .zip(&self.scan.frames)
            .map(|(image, f)| ScanReportFrame { name: &f.image, image })
            .collect();
        let mut out = open_output(dir, OutputKind::ReportScan, force)?;
        write_scan_html(
            &mut out,
            &ScanReport {
                source: "simulated",
                camera: &self.scan.camera,
                laser: &self.scan.laser,
                prior: &self.prior,
                frames: &frames,
                localization: &self.answer,
            },
        )?;
        out.finish()?;
        Ok(())
    }
}

/// The files below `dir`, relative, sorted.
fn files_below(dir: &Path) -> Vec<String> {
    let mut found = Vec::new();
    for sub in ["", "images"] {
        for entry in std::fs::read_dir(dir.join(sub)).unwrap() {
            let path = entry.unwrap().path();
            if path.is_file() {
                found.push(path.strip_prefix(dir).unwrap().display().to_string());
            }
        }
    }
    found.sort();
    found
}

#[test]
fn a_scan_report_refuses_a_calibration_reports_folder() {
    let fixture = scan_fixture();
    let dir = temp_dir("refuses");
    let mut out = open_output(&dir, OutputKind::ReportCalibration, false).unwrap();
    out.write("index.html", "the calibration report").unwrap();
    out.finish().unwrap();
    let refused = fixture.write(&dir, &fixture.images, false).unwrap_err();
    assert!(refused.is_bad_input(), "{refused}");
    assert!(refused.to_string().contains("--force"), "{refused}");
    let page = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert_eq!(page, "the calibration report", "the calibration report's page is kept");
    // A folder with a file of no alacs command is refused too.
    let other = temp_dir("refuses-notes");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("notes.txt"), "mine").unwrap();
    assert!(fixture.write(&other, &fixture.images, false).unwrap_err().is_bad_input());
    // --force writes over both.
    fixture.write(&dir, &fixture.images, true).unwrap();
    fixture.write(&other, &fixture.images, true).unwrap();
    assert_eq!(std::fs::read_to_string(other.join("notes.txt")).unwrap(), "mine");
    check_self_contained(&dir);
    std::fs::remove_dir_all(&dir).ok();
    std::fs::remove_dir_all(&other).ok();
}

#[test]
fn a_rerun_report_removes_its_stale_frames() {
    let fixture = scan_fixture();
    let n = fixture.scan.frames.len();
    assert!(n >= 3);
    let dir = temp_dir("rerun");
    fixture.write(&dir, &fixture.images, false).unwrap();
    assert!(dir.join(format!("images/frame{:02}.jpg", n - 1)).exists());
    // The same command again, with two frames: the other frames' images go.
    fixture.write(&dir, &fixture.images[..2], false).unwrap();
    let files = files_below(&dir);
    assert_eq!(
        files,
        [
            ".alacs-output",
            "images/frame00.jpg",
            "images/frame01.jpg",
            "images/overview.jpg",
            "index.html"
        ]
    );
    check_self_contained(&dir);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_failed_report_leaves_no_empty_images() {
    let fixture = scan_fixture();
    let dir = temp_dir("failed");
    fixture.write(&dir, &fixture.images, false).unwrap();
    let before: Vec<(String, Vec<u8>)> = files_below(&dir)
        .into_iter()
        .map(|f| (f.clone(), std::fs::read(dir.join(&f)).unwrap()))
        .collect();
    // The middle frame (the overview's) too tall for a JPEG (65535 rows at most).
    let mut images = fixture.images.clone();
    let middle = images.len() / 2;
    images[middle] = image::RgbImage::new(1, 66_000);
    let failed = fixture.write(&dir, &images, false).unwrap_err();
    assert!(failed.is_bad_input(), "{failed}");
    assert!(failed.to_string().contains("overview.jpg"), "{failed}");
    // The earlier report is whole: no file emptied, none half-written, no temporary file.
    let after: Vec<(String, Vec<u8>)> = files_below(&dir)
        .into_iter()
        .map(|f| (f.clone(), std::fs::read(dir.join(&f)).unwrap()))
        .collect();
    assert_eq!(after.len(), before.len());
    for ((name, old), (name_after, new)) in before.iter().zip(&after) {
        assert_eq!(name, name_after);
        assert!(!new.is_empty(), "{name} is empty");
        assert_eq!(old, new, "{name} changed");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn scan_report_is_self_contained() {
    let fixture = scan_fixture();
    let (scan, answer) = (&fixture.scan, &fixture.answer);
    let dir = temp_dir("scan");
    fixture.write(&dir, &fixture.images, false).unwrap();
    assert_eq!(files_below(&dir).len(), 3 + scan.frames.len(), "page, overview, frames, manifest");
    let (html, refs) = check_self_contained(&dir);
    assert!(refs.iter().any(|r| r == "images/overview.jpg"));
    for i in 0..scan.frames.len() {
        assert!(refs.contains(&format!("images/frame{i:02}.jpg")), "frame {i}");
    }
    assert!(html.contains(answer.status.as_str()));
    std::fs::remove_dir_all(&dir).ok();
}

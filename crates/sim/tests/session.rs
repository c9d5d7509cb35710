//! Rendered calibration sessions against the model that made them: the laser
//! stripe lies on the laser plane, the corners lie where the pose projects
//! them, renders are deterministic, the files follow FORMATS.md.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;

use alacs_model::{Camera, LaserModel, Ray};
use alacs_sim::{
    BoardScene, Checkerboard, Error, LaserStripe, RayMap, RenderOptions, Scene, Sensor,
    SessionOptions, SimulatedSession, SubpixelPattern, simulate_session,
};
use image::RgbImage;
use nalgebra::{Isometry3, Matrix2, Matrix3, Point2, Point3, Vector2, Vector3};

fn laser() -> LaserModel {
    LaserModel::seed_paper()
}

/// A half-size (1224 x 1024 px) session without sensor noise: only the
/// 8-bit quantization remains, so what the tests measure is the geometry.
fn noiseless_options(n_views: usize, slides_mm: Vec<f64>, seed: u64) -> SessionOptions {
    SessionOptions {
        n_views,
        slides_mm,
        scale: 0.5,
        render: RenderOptions { sensor: Sensor::noiseless(), ..RenderOptions::default() },
        seed,
        ..SessionOptions::default()
    }
}

fn channel(image: &RgbImage, u: u32, v: u32, c: usize) -> f64 {
    f64::from(image.get_pixel(u, v).0[c])
}

/// The analytic laser line on the board at a view: a point and a direction
/// of the intersection of the board plane and the laser plane.
fn laser_line_on_board(
    laser: &LaserModel,
    slide_mm: f64,
    camera_from_board: &Isometry3<f64>,
) -> (Point3<f64>, Vector3<f64>) {
    let plane = laser.plane_in_camera(slide_mm);
    let board_normal = camera_from_board.rotation * Vector3::z();
    let board_offset = board_normal.dot(&camera_from_board.translation.vector);
    let direction = board_normal.cross(&plane.normal).normalize();
    // The point of the line closest to the origin: on both planes, orthogonal to the line.
    let system = Matrix3::from_rows(&[
        board_normal.transpose(),
        plane.normal.transpose(),
        direction.transpose(),
    ]);
    let point = system.try_inverse().unwrap() * Vector3::new(board_offset, plane.offset_mm, 0.0);
    (Point3::from(point), direction)
}

/// The point of the line whose projection lies on image row `v_px`
/// (secant iteration on the projected row), and its projection.
fn line_point_on_row(
    camera: &Camera,
    line: &(Point3<f64>, Vector3<f64>),
    v_px: f64,
) -> Option<(Point3<f64>, Point2<f64>)> {
    let (p0, d) = line;
    let row_at = |t: f64| camera.project(&(p0 + d * t)).map(|px| px.y - v_px);
    let (mut t0, mut t1) = (0.0, 10.0);
    let (mut f0, mut f1) = (row_at(t0).ok()?, row_at(t1).ok()?);
    for _ in 0..50 {
        if (f1 - f0).abs() < 1e-15 {
            break;
        }
        let t2 = t1 - f1 * (t1 - t0) / (f1 - f0);
        (t0, f0) = (t1, f1);
        t1 = t2;
        f1 = row_at(t1).ok()?;
        if f1.abs() < 1e-10 {
            break;
        }
    }
    let point = p0 + d * t1;
    Some((point, camera.project(&point).ok()?))
}

/// Stripe-centre errors (px) of one view, split by the square colour under
/// the stripe: rows where the laser-off image is uniform over the centroid
/// window (so no square edge or board edge falls inside it).
struct StripeErrors {
    white: Vec<f64>,
    black: Vec<f64>,
}

/// Half-width of the centroid window, px: 4 sigma of the 1.5 px stripe,
/// where the Gaussian has fallen to 3e-4 of its peak (0.03 DN of a 100 DN stripe).
const CENTROID_HALF_WIDTH_PX: i64 = 6;

fn stripe_errors(session: &SimulatedSession, index: usize) -> StripeErrors {
    let camera = &session.camera;
    let view = &session.views[index];
    let on = session.render_view(index).unwrap();
    let off = session.render_laser_off(index).unwrap();
    let line = laser_line_on_board(&session.laser, view.slide_mm, &view.camera_from_board);
    let board_from_camera = view.camera_from_board.inverse();
    let mut errors = StripeErrors { white: Vec::new(), black: Vec::new() };
    for v in 0..camera.height_px {
        let Some((point, pixel)) = line_point_on_row(camera, &line, f64::from(v)) else {
            continue;
        };
        let on_board = board_from_camera * point;
        let Some(reflectance) = session.board.reflectance_at(on_board.x, on_board.y) else {
            continue;
        };
        let centre = pixel.x.round() as i64;
        let (lo, hi) = (centre - CENTROID_HALF_WIDTH_PX, centre + CENTROID_HALF_WIDTH_PX);
        if lo < 0 || hi >= i64::from(camera.width_px) {
            continue;
        }
        let columns = (lo..=hi).map(|u| u as u32);
        // A uniform laser-off window: no edge of a square (or of the board) inside it.
        let off_red: Vec<f64> = columns.clone().map(|u| channel(&off, u, v, 0)).collect();
        let spread = off_red.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - off_red.iter().cloned().fold(f64::INFINITY, f64::min);
        if spread > 1.0 {
            continue;
        }
        // Red minus laser-off: the checker pattern cancels, the stripe remains.
        let (mut sum, mut weighted) = (0.0, 0.0);
        for (u, off_value) in columns.zip(&off_red) {
            let signal = channel(&on, u, v, 0) - off_value;
            sum += signal;
            weighted += signal * f64::from(u);
        }
        if sum <= 0.0 {
            continue;
        }
        let error = weighted / sum - pixel.x;
        if reflectance > 0.5 {
            errors.white.push(error);
        } else {
            errors.black.push(error);
        }
    }
    errors
}

fn max_abs(values: &[f64]) -> f64 {
    values.iter().fold(0.0, |m, e| m.max(e.abs()))
}

fn median_abs(values: &[f64]) -> f64 {
    let mut sorted: Vec<f64> = values.iter().map(|e| e.abs()).collect();
    sorted.sort_by(f64::total_cmp);
    sorted[sorted.len() / 2]
}

#[test]
fn stripe_centre_lies_on_the_laser_plane() {
    // Two slide positions, so the line crosses each board at two places.
    let session = simulate_session(
        &Camera::blackfly_s_5mp(),
        &laser(),
        &noiseless_options(3, vec![0.0, 150.0], 11),
    )
    .unwrap();
    let (mut white, mut black) = (Vec::new(), Vec::new());
    for index in 0..session.views.len() {
        let errors = stripe_errors(&session, index);
        assert!(errors.white.len() > 50, "view {index}: {} white rows", errors.white.len());
        white.extend(errors.white);
        black.extend(errors.black);
    }
    println!(
        "stripe centre error over {} rows on white squares: max {:.4} px, median {:.4} px; \
         over {} rows on black squares: max {:.4} px, median {:.4} px",
        white.len(),
        max_abs(&white),
        median_abs(&white),
        black.len(),
        max_abs(&black),
        median_abs(&black),
    );
    // Every row on white: the stripe peaks near 80 DN there, so rounding each
    // pixel to whole DN moves the centroid by at most a few hundredths of a
    // pixel; the geometry itself (box-filtered Gaussian sampled 3 x 3 per
    // pixel, sigma 1.5 px) is exact to far below that.
    assert!(max_abs(&white) < 0.1, "white max {}", max_abs(&white));
    // On black squares (albedo 0.05) the stripe peaks at only ~5 DN over
    // some 6 pixels (~18 DN in all); rounding each to whole DN (sd 0.29 DN)
    // moves the centroid by sqrt(28 * 0.083) / 18 = 0.08 px (sd), so there
    // the quantization, not the geometry, sets the error: the median row is
    // held to 0.15 px.
    assert!(median_abs(&black) < 0.15, "black median {}", median_abs(&black));
}

/// Sub-pixel position of the edge that crosses image column `u` (if
/// `along_column`; else row `u`) near `near` (the other coordinate), from
/// the area the bright side covers: a pixel's value is its bright fraction
/// (box filter), so over the 7 pixels around the edge the normalized values
/// sum to the length of the bright part of the strip, and for a straight
/// edge the strip's mean edge position is the edge at the strip's centre.
/// Exact up to the supersampling's quantization and 8-bit rounding. None
/// when the ends of the cut are not at the two levels (another edge in it).
fn edge_crossing(
    grey: &dyn Fn(i64, i64) -> f64,
    u: i64,
    near: f64,
    along_column: bool,
    (dark, bright): (f64, f64),
) -> Option<f64> {
    let value = |w: i64| if along_column { grey(u, w) } else { grey(w, u) };
    let centre = near.round() as i64;
    let (lo, hi) = (centre - 3, centre + 3);
    let bright_after = value(hi) > value(lo);
    let (first, last) = if bright_after { (dark, bright) } else { (bright, dark) };
    if (value(lo) - first).abs() > 2.0 || (value(hi) - last).abs() > 2.0 {
        return None;
    }
    let covered: f64 = (lo..=hi).map(|w| (value(w) - dark) / (bright - dark)).sum();
    Some(if bright_after { hi as f64 + 0.5 - covered } else { lo as f64 - 0.5 + covered })
}

/// Total-least-squares line through points: (centroid, unit direction).
fn fit_line(points: &[Point2<f64>]) -> (Point2<f64>, Vector2<f64>) {
    let n = points.len() as f64;
    let centroid = points.iter().fold(Vector2::zeros(), |s, p| s + p.coords) / n;
    let mut scatter = Matrix2::zeros();
    for p in points {
        let d = p.coords - centroid;
        scatter += d * d.transpose();
    }
    let eigen = scatter.symmetric_eigen();
    let k = if eigen.eigenvalues[0] > eigen.eigenvalues[1] { 0 } else { 1 };
    (Point2::from(centroid), eigen.eigenvectors.column(k).into_owned())
}

/// The corner as the intersection of its two edges: each edge's crossings
/// measured 4-9 px from the corner on both sides (where a 7-pixel cut meets
/// no other edge), cutting across the edge
/// along whole image rows or columns (no interpolation of the image), and a
/// line fitted through them. Straight board edges stay straight under
/// perspective; the lens bends them by far less than 0.01 px over 8 px.
fn corner_from_edges(
    grey: &dyn Fn(i64, i64) -> f64,
    corner: Point2<f64>,
    axes: [Vector2<f64>; 2],
    levels: (f64, f64),
) -> Option<Point2<f64>> {
    let mut lines = Vec::new();
    for axis in axes {
        // Cut across the edge along columns if the edge runs more horizontally.
        let along_column = axis.x.abs() > axis.y.abs();
        let mut points = Vec::new();
        for t in [-9.0, -8.0, -7.0, -6.0, -5.0, -4.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0] {
            let q = corner + axis * t;
            if along_column {
                let u = q.x.round();
                let v_line = corner.y + (u - corner.x) * axis.y / axis.x;
                if let Some(v) = edge_crossing(grey, u as i64, v_line, true, levels) {
                    points.push(Point2::new(u, v));
                }
            } else {
                let v = q.y.round();
                let u_line = corner.x + (v - corner.y) * axis.x / axis.y;
                if let Some(u) = edge_crossing(grey, v as i64, u_line, false, levels) {
                    points.push(Point2::new(u, v));
                }
            }
        }
        if points.len() < 8 {
            return None;
        }
        lines.push(fit_line(&points));
    }
    let ((p, d), (q, e)) = (lines[0], lines[1]);
    // p + s d = q + t e
    let system = Matrix2::new(d.x, -e.x, d.y, -e.y);
    let st = system.try_inverse()? * (q - p);
    Some(p + d * st.x)
}

#[test]
fn corners_are_saddles_where_the_pose_projects_them() {
    let options = noiseless_options(4, vec![0.0], 5);
    let session = simulate_session(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap();
    let camera = &session.camera;
    let (width, height) = (camera.width_px as usize, camera.height_px as usize);
    let board = session.board;
    let (cols, _) = board.inner_corners;
    let mut errors = Vec::new();
    for index in 0..session.views.len() {
        let pose = session.views[index].camera_from_board;
        let off = session.render_laser_off(index).unwrap();
        let grey: Vec<f64> =
            off.pixels().map(|p| p.0.iter().map(|&c| f64::from(c)).sum::<f64>() / 3.0).collect();
        let at = |p: Point2<f64>| grey[p.y.round() as usize * width + p.x.round() as usize];
        for (k, object) in board.object_points().iter().enumerate() {
            let (col, row) = (k % cols, k / cols);
            let corner = camera.project(&(pose * object)).unwrap();
            // The board's axes in the image at this corner, one pixel long.
            let axis = |delta: Vector3<f64>| {
                (camera.project(&(pose * (object + delta))).unwrap() - corner).normalize()
            };
            let (ex, ey) = (axis(Vector3::x()), axis(Vector3::y()));
            // Samples 2.5 px along each diagonal into the four squares.
            let quadrant = |sx: f64, sy: f64| at(corner + (ex * sx + ey * sy) * 2.5);
            let (pp, mm, pm, mp) = (
                quadrant(1.0, 1.0),
                quadrant(-1.0, -1.0),
                quadrant(1.0, -1.0),
                quadrant(-1.0, 1.0),
            );
            // The square at (+x, +y) of inner corner (col, row) is square
            // (col + 1, row + 1), black when col + row is even (the top-left
            // square (0, 0) is black).
            let (dark, bright) =
                if (col + row) % 2 == 0 { ((pp, mm), (pm, mp)) } else { ((pm, mp), (pp, mm)) };
            // Black squares render near 8 DN, white ones near 130 DN.
            assert!(
                dark.0.max(dark.1) + 40.0 < bright.0.min(bright.1),
                "view {index} corner {k} ({col}, {row}) at {corner}: not a saddle: \
                 dark {dark:?} bright {bright:?}"
            );
            let grey_at = |u: i64, v: i64| {
                let (u, v) = (u.clamp(0, width as i64 - 1), v.clamp(0, height as i64 - 1));
                grey[v as usize * width + u as usize]
            };
            let levels = ((dark.0 + dark.1) / 2.0, (bright.0 + bright.1) / 2.0);
            let refined = corner_from_edges(&grey_at, corner, [ex, ey], levels)
                .unwrap_or_else(|| panic!("view {index} corner {k}: edges not found"));
            errors.push((refined - corner).norm());
        }
    }
    let max = errors.iter().cloned().fold(0.0, f64::max);
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    println!("corner error over {} corners: max {max:.4} px, mean {mean:.4} px", errors.len());
    // Every corner within 0.1 px. With 3 x 3 n-rooks samples an edge along a
    // pixel axis moves in steps of 1/9 px, so its rendered position is off by
    // at most 1/18 = 0.056 px; a corner, two such edges, by at most 0.08 px;
    // 8-bit rounding adds about 0.01 px. (With 12 x 12 samples the same check
    // gives 0.005 px: the geometry itself is exact.)
    assert!(max < 0.1, "max corner error {max} px");
}

#[test]
fn ray_map_agrees_with_the_camera_model() {
    let camera = Camera::blackfly_s_5mp().scaled(0.25);
    for pattern in [SubpixelPattern::Grid, SubpixelPattern::NRooks] {
        let map = RayMap::with_pattern(&camera, 3, pattern).unwrap();
        assert_eq!(map.failed(), 0);
        let offsets = map.offsets_px().to_vec();
        assert_eq!(offsets.len(), 9);
        // Stratified: one sample in each third x third of the pixel, and symmetric about the centre.
        for (k, (du, dv)) in offsets.iter().enumerate() {
            let cell = (((du + 0.5) * 3.0).floor() as usize, ((dv + 0.5) * 3.0).floor() as usize);
            assert_eq!(cell, (k % 3, k / 3), "{pattern:?} sample {k}");
        }
        let mean = offsets.iter().fold((0.0, 0.0), |s, o| (s.0 + o.0, s.1 + o.1));
        assert!(mean.0.abs() < 1e-12 && mean.1.abs() < 1e-12);
        let mut worst: f64 = 0.0;
        for v in (0..camera.height_px).step_by(7) {
            for u in (0..camera.width_px).step_by(5) {
                for (k, (du, dv)) in offsets.iter().enumerate() {
                    let sub = Point2::new(f64::from(u) + du, f64::from(v) + dv);
                    let exact = camera.undistort_pixel(&sub).unwrap();
                    let stored = map.normalized(u, v, k).unwrap();
                    worst = worst.max((stored - exact).norm());
                }
            }
        }
        // f32 storage: a relative rounding of 2^-24 (6e-8) on |p_bar| < 0.6.
        assert!(worst < 1e-7, "ray map differs from undistort_pixel by {worst}");
        assert!(map.normalized(camera.width_px, 0, 0).is_none());
        assert!(map.normalized(0, 0, 9).is_none());
    }
}

#[test]
fn same_seed_same_bytes_different_seed_different_noise() {
    let options = SessionOptions {
        n_views: 2,
        scale: 0.25,
        laser_off: true,
        seed: 42,
        ..SessionOptions::default()
    };
    let camera = Camera::blackfly_s_5mp();
    let a = simulate_session(&camera, &laser(), &options).unwrap();
    let b = simulate_session(&camera, &laser(), &options).unwrap();
    assert_eq!(a.views, b.views);
    for index in 0..a.views.len() {
        assert_eq!(a.render_view(index).unwrap().as_raw(), b.render_view(index).unwrap().as_raw());
        assert_eq!(
            a.render_laser_off(index).unwrap().as_raw(),
            b.render_laser_off(index).unwrap().as_raw()
        );
    }
    // The thread count does not change the bytes (noise is drawn per row).
    let single = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let one_thread = single.install(|| a.render_view(1).unwrap());
    assert_eq!(one_thread.as_raw(), a.render_view(1).unwrap().as_raw());

    // Another noise seed for the same scene: different bytes, and the
    // difference is the sensor noise: two independent draws of about 2 DN
    // (shot) and 0.5 DN (read) each, so a mean |difference| of about 1-3 DN.
    let scene = a.scene(0).unwrap();
    let stripe = a.laser_stripe(0).unwrap();
    let render = |seed| {
        a.ray_map().render(&scene, &a.render.lighting, Some(&stripe), &a.render.sensor, seed)
    };
    let (x, y) = (render(1), render(2));
    assert_ne!(x.as_raw(), y.as_raw());
    let mean_diff = x
        .as_raw()
        .iter()
        .zip(y.as_raw())
        .map(|(&p, &q)| (f64::from(p) - f64::from(q)).abs())
        .sum::<f64>()
        / x.as_raw().len() as f64;
    assert!((0.3..4.0).contains(&mean_diff), "mean |difference| {mean_diff} DN");

    // A different session seed gives different poses.
    let c = simulate_session(&camera, &laser(), &SessionOptions { seed: 43, ..options }).unwrap();
    assert_ne!(a.views[0].camera_from_board, c.views[0].camera_from_board);
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("alacs-sim-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn written_session_follows_formats() {
    let options = SessionOptions {
        n_views: 2,
        slides_mm: vec![0.0, 100.0],
        scale: 0.25,
        laser_off: true,
        seed: 3,
        ..SessionOptions::default()
    };
    let session = simulate_session(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap();
    assert_eq!(session.views.len(), 4);
    assert_eq!(session.image_count(), 6);
    let dir = temp_dir("write");
    let mut calls = Vec::new();
    session.write_with_progress(&dir, |done, total| calls.push((done, total))).unwrap();
    assert_eq!(calls.last(), Some(&(6, 6)));

    // session.yaml
    let text = std::fs::read_to_string(dir.join("session.yaml")).unwrap();
    let yaml: serde_json::Value = serde_saphyr::from_str(&text).unwrap();
    assert_eq!(yaml["board"]["inner_corners"], serde_json::json!([11, 8]));
    assert_eq!(yaml["board"]["square_mm"].as_f64(), Some(30.0));
    let views = yaml["views"].as_array().unwrap();
    assert_eq!(views.len(), 4);
    assert_eq!(views[1]["slide_mm"].as_f64(), Some(100.0));
    for view in views {
        for key in ["image", "image_laser_off"] {
            let name = view[key].as_str().unwrap();
            let image = image::open(dir.join(name)).unwrap();
            assert_eq!((image.width(), image.height()), (612, 512), "{name}");
            assert_eq!(image.color(), image::ColorType::Rgb8);
        }
    }

    // camera.yaml: the camera rendered (scaled).
    let camera = Camera::from_yaml_file(&dir.join("camera.yaml")).unwrap();
    assert_eq!(camera, session.camera);
    assert_eq!((camera.width_px, camera.height_px), (612, 512));

    // truth.json
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth["camera"]["image_width"], 612);
    assert!(truth["camera"]["camera_matrix"]["data"].is_array());
    assert_eq!(truth["laser"]["model"], "high-fidelity");
    assert!((truth["laser"]["l0_mm"].as_f64().unwrap() - 381.98).abs() < 1e-12);
    let views = truth["views"].as_array().unwrap();
    assert_eq!(views.len(), 4);
    for (view, expected) in views.iter().zip(&session.views) {
        assert_eq!(view["image"], expected.image.as_str());
        assert_eq!(view["slide_mm"].as_f64(), Some(expected.slide_mm));
        let matrix = view["camera_from_board"].as_array().unwrap();
        assert_eq!(matrix.len(), 4);
        let homogeneous = expected.camera_from_board.to_homogeneous();
        for (r, row) in matrix.iter().enumerate() {
            let row = row.as_array().unwrap();
            assert_eq!(row.len(), 4);
            for (c, value) in row.iter().enumerate() {
                // serde_json parses floats to within an ulp or two.
                assert!((value.as_f64().unwrap() - homogeneous[(r, c)]).abs() < 1e-9);
            }
        }
        // Translation in mm: the board is 0.6-1.2 m away.
        let z = matrix[2].as_array().unwrap()[3].as_f64().unwrap();
        assert!((300.0..1500.0).contains(&z), "{z}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn invalid_options_are_reported() {
    let camera = Camera::blackfly_s_5mp();
    let check =
        |options: SessionOptions, needle: &str| match simulate_session(&camera, &laser(), &options)
        {
            Err(Error::InvalidOptions(message)) => {
                assert!(message.contains(needle), "{message:?} lacks {needle:?}")
            }
            other => panic!("expected InvalidOptions for {needle}, got {other:?}"),
        };
    check(SessionOptions { depth_mm: (900.0, 600.0), ..SessionOptions::default() }, "depth range");
    check(SessionOptions { depth_mm: (0.0, 600.0), ..SessionOptions::default() }, "depth range");
    check(SessionOptions { n_views: 0, ..SessionOptions::default() }, "a session needs 1 to");
    check(SessionOptions { n_views: 100_000_000, ..SessionOptions::default() }, "1 to 1000");
    check(SessionOptions { scale: 1000.0, ..SessionOptions::default() }, "scale");
    check(SessionOptions { scale: 0.0, ..SessionOptions::default() }, "scale");
    check(SessionOptions { scale: -1.0, ..SessionOptions::default() }, "scale");
    check(SessionOptions { scale: f64::NAN, ..SessionOptions::default() }, "scale");
    check(SessionOptions { slides_mm: vec![], ..SessionOptions::default() }, "slide");
    check(
        SessionOptions {
            board: Checkerboard { inner_corners: (1, 5), ..Checkerboard::default() },
            ..SessionOptions::default()
        },
        "inner corners",
    );
    let render = RenderOptions { supersampling: 0, ..RenderOptions::default() };
    check(SessionOptions { render, ..SessionOptions::default() }, "supersampling");
    // A board that cannot fit the image at these depths is infeasible, not invalid.
    let huge = SessionOptions {
        depth_mm: (300.0, 310.0),
        n_views: 1,
        scale: 0.1,
        ..SessionOptions::default()
    };
    assert!(matches!(simulate_session(&camera, &laser(), &huge), Err(Error::Infeasible(_))));
}

#[test]
fn laser_is_shadowed_by_the_board_and_lights_only_the_side_facing_it() {
    let laser = laser();
    let stripe = LaserStripe::new(&laser, 0.0, &Default::default(), 2320.0);
    let board = Checkerboard::default();
    // A board facing the camera 900 mm away, centred where the laser crosses the middle row.
    let centre = laser.triangulate(&Point2::new(-0.1, 0.0), 0.0).unwrap();
    let pose = Isometry3::translation(centre.x, centre.y, centre.z)
        * Isometry3::translation(-board.centre_in_board().x, -board.centre_in_board().y, 0.0);
    let scene = BoardScene::new(board, pose);
    let hit = scene.intersect(&Ray::through_normalized(-0.1, 0.0)).unwrap();
    assert!((hit.point - centre).norm() < 1e-9);
    // The hit's normal faces the camera; the laser origin is on the camera's side: lit.
    assert!(stripe.irradiance(&scene, &hit) > 0.9 * stripe.power);
    // The segment from the laser origin to the hit does not cross the board elsewhere...
    assert!(!scene.blocked(&stripe.origin, &hit.point));
    // ...but a point behind the board is shadowed by it.
    let behind = centre + Vector3::new(0.0, 0.0, 100.0);
    assert!(scene.blocked(&stripe.origin, &behind));
    // The back of the board (seen from behind) is not lit by a laser in front of it.
    let back = alacs_sim::SurfaceHit { normal: -hit.normal, ..hit };
    assert_eq!(stripe.irradiance(&scene, &back), 0.0);
}

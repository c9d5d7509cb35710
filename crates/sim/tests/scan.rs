//! Orchard scans: the files of FORMATS.md, the seed's scan strategy, the
//! rough position's error, and a laser line that lands on the fruit where
//! the model puts it.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use alacs_model::{Camera, LaserModel};
use alacs_sim::{OrchardOptions, ScanOptions, simulate_scan};
use nalgebra::{Point2, Vector3};

fn laser() -> LaserModel {
    LaserModel::seed_paper()
}

/// A fifth of the 5 MP camera keeps the tests fast; the geometry is the same.
fn small(seed: u64, occlusion: f64, sun: bool) -> ScanOptions {
    let orchard = OrchardOptions { occlusion, ..OrchardOptions::default() };
    ScanOptions { orchard, sun, scale: 0.2, seed, ..ScanOptions::default() }
}

/// By default every fruit lies where the seed's plan reaches it unshifted;
/// `within_reach: false` also places fruit at the edge of the slide's reach.
#[test]
fn fruit_is_placed_within_the_slides_reach_unless_asked() {
    let mut shifted_anywhere = 0;
    for seed in 0..16 {
        let scan =
            simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &small(seed, 0.0, false)).unwrap();
        assert!(!scan.plan.shifted, "seed {seed}: {:?}", scan.plan);
        let anywhere = ScanOptions { within_reach: false, ..small(seed, 0.0, false) };
        let scan = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &anywhere).unwrap();
        shifted_anywhere += usize::from(scan.plan.shifted);
    }
    // About a quarter of the field of view at 0.6-1.2 m is out of reach.
    assert!(shifted_anywhere >= 1, "no fruit out of reach in 16 scenes");
}

#[test]
fn scans_follow_the_seed_strategy_from_a_rough_position() {
    for seed in 0..5 {
        let scan =
            simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &small(seed, 0.0, false)).unwrap();
        let truth = scan.scene.fruit_centre;
        // RGB-D-like error: at most 2 % of the depth along the line of sight,
        // plus a few mm across (2 mm sigma; 5 sigma bound).
        let error = scan.rough_position_mm - truth;
        let along = error.dot(&truth.coords.normalize());
        assert!(along.abs() <= 0.02 * truth.z + 1e-9, "seed {seed}: {along}");
        // 2 mm sigma per axis across: 15 mm is far beyond 5 sigma of the 2-D norm.
        assert!((error - truth.coords.normalize() * along).norm() < 15.0);
        // Five frames 10 mm apart within the stroke, the first on the left
        // half of the fruit as the rough position puts it.
        let slides = &scan.plan.slides_mm;
        assert_eq!(slides.len(), 5);
        assert!(slides.windows(2).all(|w| (w[1] - w[0] - 10.0).abs() < 1e-9));
        assert!(slides.iter().all(|d| (0.0..=200.0).contains(d)));
        if !scan.plan.shifted {
            let start = scan.rough_position_mm - Vector3::x() * 20.0;
            assert!(laser().signed_distance_mm(&start, slides[0]).abs() < 1e-9);
        }
    }
}

#[test]
fn the_laser_lights_the_fruit_where_the_model_puts_it() {
    let scan = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &small(3, 0.0, false)).unwrap();
    let camera = &scan.camera;
    let sigma_px = scan.render_options().laser.stripe_sigma_px;
    let mut on_fruit = 0;
    for (k, frame) in scan.frames.iter().enumerate() {
        let on = scan.render_frame(k, true).unwrap();
        let off = scan.render_frame(k, false).unwrap();
        let plane = laser().plane_in_camera(frame.slide_mm);
        for (u, v, pixel) in on.enumerate_pixels() {
            let lit = i32::from(pixel[0]) - i32::from(off.get_pixel(u, v)[0]);
            if lit < 40 {
                continue;
            }
            // What the pixel's centre ray sees lies in the laser sheet: within
            // 3 stripe sigmas of the plane plus the pixel's own footprint
            // (its 2 x 2 sub-rays spread over one pixel), both in mm at that depth.
            let normalized =
                camera.undistort_pixel(&Point2::new(f64::from(u), f64::from(v))).unwrap();
            let ray = alacs_model::Ray::through_normalized(normalized.x, normalized.y);
            let hit = scan.scene.first_hit(&ray, 0.0).unwrap();
            let mm_per_px = hit.point.z / camera.fx_px;
            let off_plane = plane.signed_distance_mm(&hit.point).abs();
            // A pixel's footprint on a surface seen obliquely is longer: the
            // cosine between the ray and the normal stretches it.
            let cosine = hit.normal.dot(&ray.direction.normalize()).abs().max(0.2);
            assert!(
                off_plane < 3.0 * sigma_px * mm_per_px + mm_per_px / cosine,
                "lit pixel ({u}, {v}) sees a point {off_plane:.2} mm off the laser plane"
            );
            on_fruit += usize::from(hit.object == 0);
        }
    }
    assert!(on_fruit > 20, "only {on_fruit} lit pixels on the fruit");
}

#[test]
fn written_scans_follow_formats_md() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("scan_formats");
    let _ = std::fs::remove_dir_all(&dir);
    let options = ScanOptions { laser_off: true, jpeg_quality: Some(90), ..small(8, 0.3, true) };
    let scan = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap();
    scan.write(&dir, |_, _| {}).unwrap();
    #[derive(serde::Deserialize)]
    struct Frame {
        image: String,
        slide_mm: f64,
        image_laser_off: Option<String>,
    }
    #[derive(serde::Deserialize)]
    struct ScanYaml {
        rough_position_mm: [f64; 3],
        fruit_radius_mm: f64,
        frames: Vec<Frame>,
    }
    let yaml: ScanYaml =
        serde_saphyr::from_str(&std::fs::read_to_string(dir.join("scan.yaml")).unwrap()).unwrap();
    assert_eq!(yaml.frames.len(), 5);
    assert_eq!(yaml.fruit_radius_mm, 40.0);
    assert_eq!(yaml.rough_position_mm[2], scan.rough_position_mm.z);
    for frame in &yaml.frames {
        for name in [Some(&frame.image), frame.image_laser_off.as_ref()].into_iter().flatten() {
            let image = image::open(dir.join(name)).unwrap();
            assert_eq!(
                (image.width(), image.height()),
                (scan.camera.width_px, scan.camera.height_px)
            );
        }
        assert!(frame.image.ends_with(".jpg"));
        assert!((0.0..=200.0).contains(&frame.slide_mm));
    }
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    assert_eq!(truth["fruit"]["radius_mm"], scan.scene.fruit_radius_mm);
    assert_eq!(truth["fruit"]["position_mm"][2], scan.scene.fruit_centre.z);
    assert!(truth["camera"]["camera_matrix"].is_object() && truth["laser"]["l0_mm"].is_number());
    assert_eq!(Camera::from_yaml_file(&dir.join("camera.yaml")).unwrap(), scan.camera);
    assert_eq!(LaserModel::from_yaml_file(&dir.join("laser.yaml")).unwrap().l0_mm, 381.98);
}

#[test]
fn same_seed_same_bytes() {
    let a = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &small(5, 0.2, true)).unwrap();
    let b = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &small(5, 0.2, true)).unwrap();
    let frame = a.render_frame(1, true).unwrap();
    assert_eq!(frame, b.render_frame(1, true).unwrap());
    // The thread count does not change the bytes (blur and noise work per row).
    for threads in [1, 3] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        assert_eq!(pool.install(|| a.render_frame(1, true).unwrap()), frame, "{threads} threads");
    }
    let c = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &small(6, 0.2, true)).unwrap();
    assert_ne!(a.scene.fruit_centre, c.scene.fruit_centre);
}

#[test]
fn sun_brightens_the_scene() {
    let mean = |sun: bool| {
        let scan = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &small(9, 0.0, sun)).unwrap();
        let image = scan.render_frame(0, false).unwrap();
        image.pixels().map(|p| f64::from(p[1])).sum::<f64>()
            / f64::from(image.width() * image.height())
    };
    assert!(mean(true) > 1.3 * mean(false));
}

#[test]
fn invalid_scan_options_are_errors() {
    for options in [
        ScanOptions { scale: 0.0, ..ScanOptions::default() },
        ScanOptions { rough_depth_error: -0.1, ..ScanOptions::default() },
        ScanOptions { jpeg_quality: Some(0), ..ScanOptions::default() },
        ScanOptions {
            orchard: OrchardOptions { occlusion: 1.5, ..OrchardOptions::default() },
            ..ScanOptions::default()
        },
    ] {
        assert!(simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options).is_err());
    }
}

#[test]
fn blur_spreads_edges_and_keeps_the_light() {
    use alacs_sim::{RenderOptions, Sensor, SessionOptions, simulate_session};
    let render = |blur_sigma_px: f64| {
        let sensor = Sensor { blur_sigma_px, ..Sensor::noiseless() };
        let options = SessionOptions {
            n_views: 1,
            scale: 0.2,
            seed: 4,
            render: RenderOptions { sensor, ..RenderOptions::default() },
            ..SessionOptions::default()
        };
        simulate_session(&Camera::blackfly_s_5mp(), &laser(), &options)
            .unwrap()
            .render_view(0)
            .unwrap()
    };
    let (sharp, blurred) = (render(0.0), render(1.0));
    let total = |image: &image::RgbImage| image.pixels().map(|p| f64::from(p[1])).sum::<f64>();
    let n = f64::from(sharp.width() * sharp.height());
    // The blur moves light, it does not make or lose it: the means agree to
    // 8-bit rounding (the uniform background sits at exactly 25.5 DN, which
    // the blurred path's f32 light buffer may round up where the sharp path
    // rounds down).
    let (mean_sharp, mean_blurred) = (total(&sharp) / n, total(&blurred) / n);
    assert!((mean_sharp - mean_blurred).abs() < 1.0, "{mean_sharp} vs {mean_blurred}");
    // The checkerboard's steepest step between neighbours shrinks.
    let steepest = |image: &image::RgbImage| {
        (1..image.width())
            .flat_map(|u| (0..image.height()).map(move |v| (u, v)))
            .map(|(u, v)| {
                (i32::from(image.get_pixel(u, v)[1]) - i32::from(image.get_pixel(u - 1, v)[1]))
                    .abs()
            })
            .max()
            .unwrap()
    };
    assert!(f64::from(steepest(&blurred)) < 0.7 * f64::from(steepest(&sharp)));
}

#[test]
fn speckle_makes_the_stripe_grainy() {
    // On a white board, the lit pixels' laser light varies with speckle on.
    use alacs_sim::{LaserLight, RenderOptions, Sensor, SessionOptions, simulate_session};
    let lit = |speckle_contrast: f64| {
        let options = SessionOptions {
            n_views: 1,
            scale: 0.3,
            seed: 5,
            laser_off: true,
            render: RenderOptions {
                laser: LaserLight { speckle_contrast, ..LaserLight::default() },
                sensor: Sensor::noiseless(),
                ..RenderOptions::default()
            },
            ..SessionOptions::default()
        };
        let session = simulate_session(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap();
        let (on, off) = (session.render_view(0).unwrap(), session.render_laser_off(0).unwrap());
        on.pixels()
            .zip(off.pixels())
            .map(|(a, b)| f64::from(a[0]) - f64::from(b[0]))
            .filter(|d| *d > 0.0)
            .collect::<Vec<f64>>()
    };
    let (plain, grainy) = (lit(0.0), lit(0.5));
    let total = |v: &[f64]| v.iter().sum::<f64>();
    assert_ne!(plain, grainy);
    // Speckle redistributes the light: the total changes by far less than its amplitude.
    assert!((total(&grainy) / total(&plain) - 1.0).abs() < 0.2);
}

/// The sensor is linear in exposure time and gain and clips at its full
/// well: half the exposure halves every unclipped pixel, +6.02 dB of gain
/// doubles it back, and twice the exposure clips what was past half scale.
#[test]
fn the_sensor_scales_with_exposure_and_gain_and_clips_at_its_full_well() {
    use alacs_sim::{Exposure, RenderOptions, Sensor};
    let defaults = small(4, 0.0, true);
    let sensor = Sensor { gain_dn_per_electron: 0.0, read_noise_dn: 0.0, ..defaults.render.sensor };
    let options = ScanOptions { render: RenderOptions { sensor, ..defaults.render }, ..defaults };
    let scan = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap();
    let slide = scan.plan.slides_mm[2];
    let at = |exposure_us: f64, gain_db: f64| {
        scan.render_exposed(slide, true, 2, Exposure { exposure_us, gain_db }).unwrap()
    };
    let reference = at(1000.0, 0.0);
    assert_eq!(reference, scan.render_frame(2, true).unwrap());
    let half = at(500.0, 0.0);
    let half_gained = at(500.0, 20.0 * 2f64.log10());
    let double = at(2000.0, 0.0);
    let (mut compared, mut clipped) = (0, 0);
    for (k, &value) in reference.as_raw().iter().enumerate() {
        let value = f64::from(value);
        if (20.0..250.0).contains(&value) {
            compared += 1;
            assert!((f64::from(half.as_raw()[k]) - value / 2.0).abs() <= 1.0, "byte {k}");
            assert!((f64::from(half_gained.as_raw()[k]) - value).abs() <= 2.0, "byte {k}");
        }
        if value >= 130.0 {
            clipped += 1;
            assert_eq!(double.as_raw()[k], 255, "byte {k}");
        }
        if value >= 255.0 {
            assert!(half.as_raw()[k] >= 127, "byte {k}");
        }
    }
    assert!(compared > 1000 && clipped > 100, "{compared} compared, {clipped} clipped");
    // Invalid settings are refused, not rendered.
    assert!(
        scan.render_exposed(slide, true, 2, Exposure { exposure_us: -1.0, gain_db: 0.0 }).is_err()
    );
    assert!(
        scan.render_exposed(slide, true, 2, Exposure { exposure_us: 1.0, gain_db: 99.0 }).is_err()
    );
}

//! Per-scan randomization (`ScanOptions::randomize`, `RigVariation`): the
//! same bytes for the same seed, the scene unchanged, the calibration files
//! nominal while the images show the drawn errors, every draw within its
//! stated range, and the fruit's subsurface glow widening its stripe.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use alacs_model::{Camera, LaserModel, Ray};
use alacs_sim::{
    DrawRange, FruitColour, LaserLight, OrchardOptions, RenderOptions, RigVariation, ScanOptions,
    Sensor, Shape, simulate_scan,
};
use nalgebra::Point2;

fn laser() -> LaserModel {
    LaserModel::seed_paper()
}

fn options(seed: u64, randomize: bool) -> ScanOptions {
    let orchard = OrchardOptions { occlusion: 0.2, cluster: 1, ..OrchardOptions::default() };
    ScanOptions {
        orchard,
        sun: seed % 2 == 1,
        scale: 0.25,
        seed,
        randomize,
        ..ScanOptions::default()
    }
}

#[test]
fn the_same_seed_randomized_gives_the_same_bytes() {
    let scan = || simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options(7, true)).unwrap();
    let (a, b) = (scan(), scan());
    assert_eq!(a.variation, b.variation);
    assert_eq!(a.truth_json(), b.truth_json());
    for k in [0, 2] {
        assert!(a.render_frame(k, true).unwrap() == b.render_frame(k, true).unwrap(), "frame {k}");
    }
    assert!(a.render_frame(1, false).unwrap() == b.render_frame(1, false).unwrap());
}

/// Off is the option left out: no variation, the calibration rendered, the
/// same bytes and truth (byte-identical to the renderer before the option,
/// checked when it was added).
#[test]
fn randomization_off_is_the_scan_without_the_option() {
    let explicit = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options(4, false)).unwrap();
    let orchard = OrchardOptions { occlusion: 0.2, cluster: 1, ..OrchardOptions::default() };
    let absent = ScanOptions { orchard, scale: 0.25, seed: 4, ..ScanOptions::default() };
    let absent = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &absent).unwrap();
    assert!(explicit.variation.is_none());
    assert_eq!(explicit.rendered_camera, explicit.camera);
    assert_eq!(explicit.rendered_laser, explicit.laser);
    assert_eq!(explicit.scene.appearance, alacs_sim::Appearance::default());
    assert_eq!(explicit.truth_json(), absent.truth_json());
    assert!(explicit.truth_json().get("variation").is_none());
    for k in 0..explicit.frames.len() {
        assert!(explicit.render_frame(k, true).unwrap() == absent.render_frame(k, true).unwrap());
    }
}

/// The scene, the fruit's truth, the plan's calibration and the lighting's
/// direction are the seed's whether randomization is on or off; the images
/// are not.
#[test]
fn randomization_keeps_the_scene_and_the_calibration() {
    for seed in 0..6 {
        let off =
            simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options(seed, false)).unwrap();
        let on = simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options(seed, true)).unwrap();
        assert_eq!(on.scene.fruit_centre, off.scene.fruit_centre, "seed {seed}");
        assert_eq!(on.scene.fruit_radius_mm, off.scene.fruit_radius_mm);
        // The same objects in the same places; the target is given the
        // drawn apple's form.
        assert_eq!(on.scene.objects[1..], off.scene.objects[1..]);
        match (&on.scene.objects[0].shape, &off.scene.objects[0].shape) {
            (
                Shape::Apple { centre, rotation, semi_axes_mm, form },
                Shape::Ellipsoid { centre: c, rotation: r, semi_axes_mm: s },
            ) => {
                assert_eq!((rotation, semi_axes_mm), (r, s));
                // Its volume centroid is the fruit's centre.
                let centroid = centre + rotation * semi_axes_mm.component_mul(&form.centroid());
                assert!((centroid - c).norm() < 1e-9, "seed {seed}");
            }
            other => panic!("seed {seed}: {other:?}"),
        }
        assert_eq!(on.scene.occlusion, off.scene.occlusion);
        assert_eq!(on.lighting.to_light_in_camera, off.lighting.to_light_in_camera);
        // The calibration a localizer is given stays the nominal one.
        assert_eq!(on.camera, off.camera);
        assert_eq!(on.laser, off.laser);
        assert_ne!(on.rendered_camera, on.camera);
        assert_ne!(on.rendered_laser, on.laser);
        let truth = on.truth_json();
        assert_eq!(truth["fruit"], off.truth_json()["fruit"]);
        assert!(on.render_frame(2, true).unwrap() != off.render_frame(2, true).unwrap());
        // The rough position's error stays within the drawn bound.
        let v = on.variation.unwrap();
        let centre = on.scene.fruit_centre;
        let along = (on.rough_position_mm - centre).dot(&centre.coords.normalize());
        assert!(along.abs() <= v.rough_depth_error * centre.z + 1e-9, "seed {seed}");
    }
}

/// camera.yaml and laser.yaml hold the calibration; truth.json the camera
/// and laser the images show, and every drawn value.
#[test]
fn written_randomized_scans_keep_the_calibration_and_record_the_draw() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("scan_randomized");
    let _ = std::fs::remove_dir_all(&dir);
    let camera = Camera::blackfly_s_5mp();
    let scan = simulate_scan(&camera, &laser(), &options(3, true)).unwrap();
    scan.write(&dir, |_, _| {}).unwrap();
    assert_eq!(Camera::from_yaml_file(&dir.join("camera.yaml")).unwrap(), camera.scaled(0.25));
    let written = LaserModel::from_yaml_file(&dir.join("laser.yaml")).unwrap();
    assert!((written.l0_mm - laser().l0_mm).abs() < 1e-9);
    assert!((written.alpha_rad - laser().alpha_rad).abs() < 1e-12);
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap()).unwrap();
    let v = scan.variation.unwrap();
    let variation = &truth["variation"];
    assert_eq!(variation, &v.to_json());
    for key in [
        "stripe_sigma_px",
        "laser_power",
        "profile_flatness",
        "speckle_contrast",
        "subsurface_sigma_mm",
        "subsurface_shift",
        "background_light_factor",
        "blur_sigma_px",
        "exposure_factor",
        "alpha_error_deg",
        "l0_error_mm",
        "beta_error_deg",
        "slide_scale_error",
        "fx_error",
        "cy_error_px",
        "rough_depth_error",
        "rough_lateral_sigma_mm",
    ] {
        assert!(variation[key].is_number(), "{key}");
    }
    assert!(variation["fruit_colour"].is_string());
    assert!(variation["appearance"]["fruit_blush_rgb"].is_array());
    let fx = truth["camera"]["camera_matrix"]["data"][0].as_f64().unwrap();
    assert!((fx - scan.rendered_camera.fx_px).abs() < 1e-9);
    let l0 = truth["laser"]["l0_mm"].as_f64().unwrap();
    assert!((l0 - laser().l0_mm - v.l0_error_mm).abs() < 1e-9);
}

#[test]
fn drawn_values_lie_within_their_ranges_and_vary() {
    let draws: Vec<RigVariation> = (0..200).map(RigVariation::for_seed).collect();
    let check = |name: &str, (low, high): DrawRange, value: fn(&RigVariation) -> f64| {
        let values: Vec<f64> = draws.iter().map(value).collect();
        for v in &values {
            assert!((low..=high).contains(v), "{name}: {v} outside {low}..{high}");
        }
        let min = values.iter().copied().fold(f64::INFINITY, f64::min);
        let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        // 200 uniform draws span nearly all of the range.
        assert!(max - min > 0.9 * (high - low), "{name}: {min}..{max} of {low}..{high}");
    };
    type V = RigVariation;
    check("stripe sigma", V::STRIPE_SIGMA_PX, |v| v.stripe_sigma_px);
    check("laser power", V::LASER_POWER, |v| v.laser_power);
    check("profile flatness", V::PROFILE_FLATNESS, |v| v.profile_flatness);
    check("speckle", V::SPECKLE_CONTRAST, |v| v.speckle_contrast);
    check("subsurface sigma", V::SUBSURFACE_SIGMA_MM, |v| v.subsurface_sigma_mm);
    check("subsurface shift", V::SUBSURFACE_SHIFT, |v| v.subsurface_shift);
    check("fruit specular", V::FRUIT_SPECULAR, |v| v.appearance.fruit_specular);
    check("fruit shininess", V::FRUIT_SHININESS, |v| v.appearance.fruit_shininess);
    check("leaf red", V::LEAF_RGB[0], |v| v.appearance.leaf_rgb[0]);
    check("leaf green", V::LEAF_RGB[1], |v| v.appearance.leaf_rgb[1]);
    check("leaf blue", V::LEAF_RGB[2], |v| v.appearance.leaf_rgb[2]);
    check("leaf specular", V::LEAF_SPECULAR, |v| v.appearance.leaf_specular);
    check("leaf shininess", V::LEAF_SHININESS, |v| v.appearance.leaf_shininess);
    check("background albedo", V::BACKGROUND_ALBEDO_FACTOR, |v| v.background_albedo_factor);
    check("sky", V::BACKGROUND_LIGHT_FACTOR, |v| v.background_light_factor);
    check("blur", V::BLUR_SIGMA_PX, |v| v.blur_sigma_px);
    check("read noise", V::READ_NOISE_DN, |v| v.read_noise_dn);
    check("shot gain", V::GAIN_DN_PER_ELECTRON, |v| v.gain_dn_per_electron);
    check("exposure", V::EXPOSURE_FACTOR, |v| v.exposure_factor);
    // alpha, L0 and beta: a calibration's errors, drawn by calibrating
    // (variation.rs's own test checks their spread and correlation).
    check("slide scale", V::SLIDE_SCALE_ERROR, |v| v.slide_scale_error);
    check("fx", V::FOCAL_ERROR, |v| v.fx_error);
    check("fy", V::FOCAL_ERROR, |v| v.fy_error);
    check("cx", V::PRINCIPAL_POINT_ERROR_PX, |v| v.cx_error_px);
    check("cy", V::PRINCIPAL_POINT_ERROR_PX, |v| v.cy_error_px);
    check("rough depth", V::ROUGH_DEPTH_ERROR, |v| v.rough_depth_error);
    check("rough lateral", V::ROUGH_LATERAL_SIGMA_MM, |v| v.rough_lateral_sigma_mm);
    check("taper", V::TAPER, |v| v.apple_form.taper);
    check("lopsided", V::LOPSIDED, |v| v.apple_form.lopsided);
    check("stem cavity", V::STEM_CAVITY_DEPTH, |v| v.apple_form.stem_cavity_depth);
    check("stem width", V::STEM_CAVITY_WIDTH_RAD, |v| v.apple_form.stem_cavity_width_rad);
    check("calyx cavity", V::CALYX_CAVITY_DEPTH, |v| v.apple_form.calyx_cavity_depth);
    check("calyx width", V::CALYX_CAVITY_WIDTH_RAD, |v| v.apple_form.calyx_cavity_width_rad);
    // Every colour family is drawn, each within its albedo ranges; the
    // laser's reflectance follows the red albedo (leaves 4/3 of it).
    for family in FruitColour::ALL {
        let of_family: Vec<&RigVariation> =
            draws.iter().filter(|v| v.fruit_colour == family).collect();
        assert!(of_family.len() >= 25, "{family:?}: {} of 200", of_family.len());
        let ranges = family.ranges();
        for v in of_family {
            let a = &v.appearance;
            for c in 0..3 {
                let within = |(low, high): DrawRange, x: f64| (low..=high).contains(&x);
                assert!(within(ranges.blush_rgb[c], a.fruit_blush_rgb[c]), "{family:?} {a:?}");
                assert!(within(ranges.ground_rgb[c], a.fruit_ground_rgb[c]), "{family:?} {a:?}");
            }
            assert!(
                (ranges.blush_offset.0..=ranges.blush_offset.1).contains(&a.fruit_blush_offset)
            );
            assert!((a.leaf_laser_reflectance - a.leaf_rgb[0] * 4.0 / 3.0).abs() < 1e-12);
        }
    }
}

/// The width (standard deviation, px) and centroid of the laser's light
/// on row `v` around column `peak`: the laser-on frame minus the laser-off
/// frame in red, within +-`half` px.
fn row_profile(
    on: &image::RgbImage,
    off: &image::RgbImage,
    v: u32,
    peak: u32,
    half: u32,
) -> (f64, f64) {
    let (mut sum, mut first, mut second) = (0.0, 0.0, 0.0);
    for u in peak.saturating_sub(half)..(peak + half + 1).min(on.width()) {
        let lit = (f64::from(on.get_pixel(u, v)[0]) - f64::from(off.get_pixel(u, v)[0])).max(0.0);
        sum += lit;
        first += lit * f64::from(u);
        second += lit * f64::from(u) * f64::from(u);
    }
    let mean = first / sum;
    ((second / sum - mean * mean).max(0.0).sqrt(), mean)
}

/// Light entering the fruit glows around the line: with a subsurface
/// sigma of 2 mm the stripe's row profile on the fruit widens, and the
/// light elsewhere is untouched.
#[test]
fn subsurface_scattering_widens_the_stripe_on_fruit_only() {
    let scan = |subsurface_sigma_mm: f64| {
        let defaults = ScanOptions::default();
        let render = RenderOptions {
            laser: LaserLight {
                subsurface_sigma_mm,
                subsurface_shift: 0.3,
                speckle_contrast: 0.0,
                ..defaults.render.laser
            },
            sensor: Sensor { blur_sigma_px: 0.0, ..Sensor::noiseless() },
            ..defaults.render
        };
        let options = ScanOptions { scale: 0.5, seed: 2, render, ..defaults };
        simulate_scan(&Camera::blackfly_s_5mp(), &laser(), &options).unwrap()
    };
    let (plain, glowing) = (scan(0.0), scan(2.0));
    assert_eq!(plain.scene, glowing.scene);
    let frame = 2;
    let off = plain.render_frame(frame, false).unwrap();
    assert!(off == glowing.render_frame(frame, false).unwrap());
    let (on_plain, on_glowing) =
        (plain.render_frame(frame, true).unwrap(), glowing.render_frame(frame, true).unwrap());
    let camera = &plain.camera;
    let (mut widths_plain, mut widths_glowing, mut unchanged) = (Vec::new(), Vec::new(), 0);
    for v in 0..on_plain.height() {
        // The row's brightest laser pixel in the plain frame.
        let Some((peak, lit)) = (0..on_plain.width())
            .map(|u| {
                (u, i32::from(on_plain.get_pixel(u, v)[0]) - i32::from(off.get_pixel(u, v)[0]))
            })
            .max_by_key(|&(_, lit)| lit)
        else {
            continue;
        };
        if lit < 30 {
            continue;
        }
        // What the peak pixel and its neighbours see: only rows where all of
        // them see the fruit, or none of them.
        let objects: Vec<Option<usize>> = (peak.saturating_sub(8)..=peak + 8)
            .map(|u| {
                let normalized =
                    camera.undistort_pixel(&Point2::new(f64::from(u), f64::from(v))).ok()?;
                let ray = Ray::through_normalized(normalized.x, normalized.y);
                plain.scene.first_hit(&ray, 0.0).map(|hit| hit.object)
            })
            .collect();
        let on_fruit = |o: &Option<usize>| {
            o.is_some_and(|i| plain.scene.objects[i].kind == alacs_sim::Kind::Fruit)
        };
        if objects.iter().all(on_fruit) {
            widths_plain.push(row_profile(&on_plain, &off, v, peak, 8).0);
            widths_glowing.push(row_profile(&on_glowing, &off, v, peak, 8).0);
        } else if !objects.iter().any(on_fruit) {
            let row = |image: &image::RgbImage| {
                (peak.saturating_sub(8)..=peak + 8)
                    .map(|u| *image.get_pixel(u, v))
                    .collect::<Vec<_>>()
            };
            assert_eq!(row(&on_plain), row(&on_glowing), "row {v} off the fruit");
            unchanged += 1;
        }
    }
    assert!(widths_plain.len() >= 20, "{} rows on the fruit", widths_plain.len());
    assert!(unchanged >= 20, "{unchanged} rows off the fruit");
    let mean = |w: &[f64]| w.iter().sum::<f64>() / w.len() as f64;
    let (plain_px, glowing_px) = (mean(&widths_plain), mean(&widths_glowing));
    // 2 mm at about 0.9 m is 2.6 px of the half-scale camera, in quadrature
    // with the line's 1.5 px (plus the pixel's own box).
    assert!(glowing_px > 1.5 * plain_px, "{plain_px:.2} px -> {glowing_px:.2} px");
}

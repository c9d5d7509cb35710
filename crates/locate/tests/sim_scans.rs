//! Localization against the simulator's ground truth: statistical gates
//! over families of scans (N scans: at least k found, none wrong, median
//! and worst bounds), and mechanisms on rendered and synthetic data. The
//! seeds are the tuning range of `examples/families.rs`' families (their
//! reporting range is for docs/ACCURACY.md's table only). A gate changes
//! only with the whole table measured again.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use alacs_locate::{Error, FrameImages, Localization, LocateOptions, Prior, Status, locate};
use alacs_model::Camera;
use alacs_sim::{OrchardOptions, RenderedScan, ScanOptions, SimulatedScan, simulate_rendered_scan};
use common::{laser, locate_in_black_frames};
use nalgebra::Point3;

mod common;

/// Simulates and renders the scan.
fn scan(options: ScanOptions) -> RenderedScan {
    scan_with_laser(&laser(), options)
}

/// Simulates and renders the scan with `laser` (another mount's).
fn scan_with_laser(laser: &alacs_model::LaserModel, options: ScanOptions) -> RenderedScan {
    simulate_rendered_scan(&Camera::blackfly_s_5mp(), laser, &options).unwrap()
}

/// Locates the scan's fruit with its calibration and a radius prior of 40 mm.
fn run(sim: &RenderedScan) -> Localization {
    run_with_prior(sim, 40.0)
}

/// Locates the scan's fruit with its calibration and a radius prior of
/// `fruit_radius_mm`.
fn run_with_prior(sim: &RenderedScan, fruit_radius_mm: f64) -> Localization {
    let frames: Vec<_> = sim.frames().map(FrameImages::from).collect();
    let scan = &sim.scan;
    let prior = Prior { rough_position_mm: scan.rough_position_mm, fruit_radius_mm };
    locate(&scan.camera, &scan.laser, &prior, &frames, &LocateOptions::default()).unwrap()
}

fn error_mm(scan: &SimulatedScan, answer: &Localization) -> Option<f64> {
    answer.position_mm.map(|p| (p - scan.scene.fruit_centre).norm())
}

/// An `ok` answer farther than this from the truth is wrong (issue 40's bar).
const WRONG_MM: f64 = 15.0;

/// What a family of scans gave.
struct Family {
    found: usize,
    wrong: Vec<String>,
    errors_mm: Vec<f64>,
    not_found: Vec<String>,
}

/// Locates `n` half-scale scans of the family `orchard(i)` (sun on odd
/// `i`), seeds from `first`, with a radius prior 13 % below to 15 % above
/// the truth (a detector's circle at 0.6-1.6 m).
fn family(first: u64, n: u64, randomize: bool, orchard: impl Fn(u64) -> OrchardOptions) -> Family {
    let mut family =
        Family { found: 0, wrong: Vec::new(), errors_mm: Vec::new(), not_found: Vec::new() };
    for i in 0..n {
        let seed = first + i;
        let sim = scan(ScanOptions {
            orchard: orchard(i),
            sun: i % 2 == 1,
            scale: 0.5,
            seed,
            randomize,
            ..ScanOptions::default()
        });
        let truth_radius = sim.scan.scene.fruit_radius_mm;
        let factor = 0.87
            + 0.28
                * ((seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 11) as f64 / (1u64 << 53) as f64);
        let answer = run_with_prior(&sim, truth_radius * factor);
        match error_mm(&sim.scan, &answer) {
            Some(e) if e > WRONG_MM => {
                family.wrong.push(format!("seed {seed}: {e:.1} mm: {}", answer.reason))
            }
            Some(e) => {
                family.found += 1;
                family.errors_mm.push(e);
            }
            None => family.not_found.push(format!("seed {seed}: {}", answer.reason)),
        }
    }
    family.errors_mm.sort_by(f64::total_cmp);
    family
}

impl Family {
    fn median_mm(&self) -> f64 {
        self.errors_mm.get(self.errors_mm.len() / 2).copied().unwrap_or(f64::NAN)
    }

    fn worst_mm(&self) -> f64 {
        self.errors_mm.last().copied().unwrap_or(f64::NAN)
    }

    /// Asserts at least `found` found, none wrong, and the median and worst
    /// errors of those found within their bounds.
    fn assert_gate(&self, name: &str, found: usize, median_mm: f64, worst_mm: f64) {
        let context = format!(
            "{name}: {} found, median {:.2} mm, worst {:.2} mm; wrong: {:?}; not found: {:?}",
            self.found,
            self.median_mm(),
            self.worst_mm(),
            self.wrong,
            self.not_found
        );
        eprintln!("{context}");
        assert!(self.wrong.is_empty(), "{context}");
        assert!(self.found >= found, "{context}");
        assert!(self.median_mm() <= median_mm, "{context}");
        assert!(self.worst_mm() <= worst_mm, "{context}");
    }
}

fn hidden(occlusion: f64) -> OrchardOptions {
    OrchardOptions { occlusion, ..OrchardOptions::default() }
}

/// At most 40 % hidden, sun and shade: 12 scans, at least 11 found, none
/// wrong, median within issue 40's 1.5 mm and every answer within 3 mm.
#[test]
fn family_up_to_two_fifths_hidden() {
    let f = family(110_000, 12, false, |i| hidden(0.4 * i as f64 / 11.0));
    f.assert_gate("0-40 % hidden", 11, 1.5, 3.0);
}

/// 60 % hidden: at least six of eight found (issue 40's bar: 70 %), none
/// wrong, median within 2.5 mm.
#[test]
fn family_three_fifths_hidden() {
    let f = family(120_000, 8, false, |_| hidden(0.6));
    f.assert_gate("60 % hidden", 6, 2.5, WRONG_MM);
}

/// Clusters of 2-4 apples, 30 % hidden, a branch in front of some: at
/// least seven of eight found, none wrong (never a neighbour), median
/// within 4 mm (a neighbour touching the target lends the sphere its
/// points: 3-5 mm on half of these eight, docs/ACCURACY.md).
#[test]
fn family_clusters_never_a_neighbour() {
    let f = family(130_000, 8, false, |i| OrchardOptions {
        cluster: 1 + (i % 3) as usize,
        front_branches: ((i / 3) % 2) as usize,
        ..hidden(0.3)
    });
    f.assert_gate("clusters", 7, 4.0, WRONG_MM);
}

/// With the renderer randomized (laser, light in the flesh, colours, the
/// apple's form, lens, Bayer sensor, calibration error; crates/sim's
/// `RigVariation`): at least three
/// quarters found, none wrong, median within 3 mm (the calibration error
/// alone adds half a millimetre to a millimetre, docs/ACCURACY.md).
#[test]
fn family_randomized_rigs_are_never_answered_wrong() {
    let f = family(140_000, 12, true, |i| hidden(0.4 * i as f64 / 11.0));
    f.assert_gate("randomized, 0-40 % hidden", 9, 3.0, WRONG_MM);
}

/// Issue 40's bar: an unoccluded fruit at 0.6-1.2 m within 3 mm in 3-D,
/// spherical or slightly ellipsoidal. Scans whose plan had to be shifted
/// into the slide's stroke (the fruit at the edge of the scanner's reach,
/// so the laser never crosses its left half) are not part of the claim.
#[test]
fn unoccluded_fruit_within_3_mm() {
    let mut checked = 0;
    for (seed, ellipticity) in [(0, 0.0), (1, 0.0), (2, 0.08), (3, 0.08), (4, 0.08), (5, 0.08)] {
        let sim = scan(ScanOptions {
            orchard: OrchardOptions { max_ellipticity: ellipticity, ..OrchardOptions::default() },
            seed,
            ..ScanOptions::default()
        });
        let scan = &sim.scan;
        if scan.plan.shifted {
            continue;
        }
        let answer = run(&sim);
        assert_eq!(answer.status, Status::Ok, "seed {seed}: {}", answer.reason);
        let error = error_mm(scan, &answer).unwrap();
        eprintln!("seed {seed} ellipticity {ellipticity}: {error:.2} mm");
        assert!(error < 3.0, "seed {seed}: {error:.2} mm");
        let radius = answer.radius_mm.unwrap();
        assert!((radius - scan.scene.fruit_radius_mm).abs() < 3.0, "seed {seed}: radius {radius}");
        checked += 1;
    }
    assert!(checked >= 4, "only {checked} scans reached the fruit");
}

/// Issue 17: a slide that moves the laser 0.99 mm per commanded mm. With
/// the slide scale k in the laser model (as `calibrate laser` fits it),
/// localization keeps the unoccluded bar of 4 mm (0.5-0.8 mm on seeds
/// 0-2); the seed's model (k held at 1) was 4.5-4.6 mm off on the scans at
/// 125-171 mm of travel (0.85 mm at 40-80 mm).
#[test]
fn a_slide_with_a_scale_error_is_located_with_its_k() {
    let true_laser = laser().with_slide_scale(0.99);
    let mut checked = 0;
    for seed in [0, 1, 2] {
        let options = ScanOptions { seed, ..ScanOptions::default() };
        let sim = scan_with_laser(&true_laser, options);
        if sim.scan.plan.shifted {
            continue;
        }
        let answer = run(&sim);
        assert_eq!(answer.status, Status::Ok, "seed {seed}: {}", answer.reason);
        let error = error_mm(&sim.scan, &answer).unwrap();
        let frames: Vec<_> = sim.frames().map(FrameImages::from).collect();
        let prior = Prior { rough_position_mm: sim.scan.rough_position_mm, fruit_radius_mm: 40.0 };
        let seed_model = sim.scan.laser.with_slide_scale(1.0);
        let held =
            locate(&sim.scan.camera, &seed_model, &prior, &frames, &LocateOptions::default())
                .unwrap();
        let slides = &sim.scan.plan.slides_mm;
        eprintln!(
            "seed {seed}: slides {:.0}-{:.0} mm, {error:.2} mm with k = 0.99, {:?} mm with k held at 1",
            slides[0],
            slides[slides.len() - 1],
            error_mm(&sim.scan, &held)
        );
        assert!(error < 3.0, "seed {seed}: {error:.2} mm");
        checked += 1;
    }
    assert!(checked >= 2, "only {checked} scans reached the fruit");
}

/// The frames' per-pixel minimum is the scene without the laser only where
/// their slides lie apart: copies of one frame at one slide position light
/// the same pixels, and keep every stripe point the frame alone keeps.
#[test]
fn frames_at_one_slide_keep_their_stripe() {
    let sim = scan(ScanOptions { scale: 0.5, seed: 0, ..ScanOptions::default() });
    let (image, slide_mm) = sim.frames().nth(2).unwrap();
    let prior = Prior { rough_position_mm: sim.scan.rough_position_mm, fruit_radius_mm: 40.0 };
    let at = |n: usize| {
        let frames: Vec<FrameImages> =
            (0..n).map(|_| FrameImages::from((image, slide_mm))).collect();
        let (camera, laser) = (&sim.scan.camera, &sim.scan.laser);
        locate(camera, laser, &prior, &frames, &LocateOptions::default()).unwrap()
    };
    let alone = at(1).frames[0].points_in_camera.len();
    assert!(alone > 50, "{alone} points");
    for frame in at(3).frames {
        assert_eq!(frame.points_in_camera.len(), alone);
    }
}

#[test]
fn frames_that_do_not_fit_the_camera_are_refused() {
    let camera = Camera::blackfly_s_5mp().scaled(0.1);
    let image = image::RgbImage::new(10, 10);
    let frames = [FrameImages { image: &image, image_laser_off: None, slide_mm: 0.0 }];
    let prior = Prior { rough_position_mm: Point3::new(0.0, 0.0, 800.0), fruit_radius_mm: 40.0 };
    let error = locate(&camera, &laser(), &prior, &frames, &LocateOptions::default()).unwrap_err();
    assert!(matches!(error, Error::InvalidInput(ref m) if m.contains("frame 0")), "{error}");
    let error = locate(&camera, &laser(), &prior, &[], &LocateOptions::default()).unwrap_err();
    assert!(error.to_string().contains("no frames"), "{error}");
    let fits = image::RgbImage::new(camera.width_px, camera.height_px);
    let frames = [FrameImages { image: &fits, image_laser_off: Some(&image), slide_mm: 0.0 }];
    let error = locate(&camera, &laser(), &prior, &frames, &LocateOptions::default()).unwrap_err();
    assert!(error.to_string().contains("laser-off image"), "{error}");
    let behind = Prior { rough_position_mm: Point3::new(0.0, 0.0, -5.0), ..prior };
    let frames = [];
    assert!(locate(&camera, &laser(), &behind, &frames, &LocateOptions::default()).is_err());
}

/// A frame where the laser hits nothing near the fruit (a black image)
/// gives `not_found` with a reason naming the frames, not an error.
#[test]
fn an_empty_scan_is_not_found_with_a_reason() {
    let answer = locate_in_black_frames(5, 60.0);
    assert_eq!(answer.status, Status::NotFound);
    assert!(answer.position_mm.is_none());
    assert!(answer.reason.contains("frame 0"), "{}", answer.reason);
}

/// Scans located with inputs that contradict their images (issue 43): the
/// tuning seeds of `examples/contradictions.rs`, 0-40 % hidden, shade and
/// sun, half scale. Frames that all claim one slide position although the
/// stripe moved are never answered, whatever the method; a calibration
/// that puts the fruit beyond the RGB-D camera's stated error (slides all
/// 30 mm off, 7-9 % of the depth) is never answered `ok` beyond 15 mm.
#[test]
fn contradicting_slides_are_never_answered_confidently() {
    use alacs_locate::Method;
    let mut judged = 0;
    for i in 0..6_u64 {
        let orchard =
            OrchardOptions { occlusion: 0.4 * (i as f64 + 0.5) / 6.0, ..Default::default() };
        let options = ScanOptions {
            orchard,
            sun: i % 2 == 1,
            scale: 0.5,
            seed: 500_000 + i,
            ..ScanOptions::default()
        };
        let Ok(sim) = simulate_rendered_scan(&Camera::blackfly_s_5mp(), &laser(), &options) else {
            continue;
        };
        let scan = &sim.scan;
        let prior = Prior { rough_position_mm: scan.rough_position_mm, fruit_radius_mm: 40.0 };
        let first = sim.frames().next().unwrap().1;
        for (claimed, method) in [
            (Box::new(move |_: f64| first) as Box<dyn Fn(f64) -> f64>, Method::Fused),
            (Box::new(move |_: f64| first), Method::Holistic),
            (Box::new(|s: f64| s + 30.0), Method::Fused),
        ] {
            let frames: Vec<FrameImages> =
                sim.frames().map(|(image, s)| FrameImages::from((image, claimed(s)))).collect();
            let options = LocateOptions { method, ..LocateOptions::default() };
            let answer = locate(&scan.camera, &scan.laser, &prior, &frames, &options).unwrap();
            let error = error_mm(scan, &answer);
            assert!(
                answer.status != Status::Ok || error.is_some_and(|e| e <= WRONG_MM),
                "seed {}: ok {error:?} mm off: {}",
                options.seed,
                answer.reason
            );
        }
        // One slide for all: named as the contradiction it is.
        let frames: Vec<FrameImages> =
            sim.frames().map(|(image, _)| FrameImages::from((image, first))).collect();
        let answer =
            locate(&scan.camera, &scan.laser, &prior, &frames, &LocateOptions::default()).unwrap();
        assert!(answer.reason.contains("claim one slide position"), "{}", answer.reason);
        // A contradiction, not a want of evidence: the scan controller
        // takes no more frames for it.
        assert!(answer.contradicted);
        judged += 1;
    }
    assert!(judged >= 5, "only {judged} scans built");
}

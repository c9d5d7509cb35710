//! The localizer judged per family of simulated scans: found rate, wrong
//! rate and error percentiles, as docs/ACCURACY.md's table.
//!
//! `cargo run --release -p alacs-locate --example families -- [--seeds tune|report] [--n N] [--scale S] [--randomize on|off|both] [--family NAME] [--scans] [--round] [--no-form] [--no-glow] [--no-outline] [--true-calibration] [--true-calibration-of camera,laser,slide] [--no-extension] [--anatomy]`
//!
//! Randomized scans draw, per scan, what real rigs vary in (alacs-sim's
//! `RigVariation`: laser, light in the flesh, fruit and leaf colours, lens,
//! sensor, exposure, calibration error, the rough position's error); the
//! table then also breaks them down by the fruit's colour. The last column
//! counts the `ok` answers whose position covariance's 99 % ellipsoid
//! holds the truth: whether the stated uncertainty can be trusted.
//!
//! A scan whose fruit is not found in the seed's five frames is extended
//! as the scan controller extends it (`ScanStrategy::extension`: frames
//! beyond both ends of the sweep, rendered where the slide would stand)
//! and located again; the table's "extended" column counts those scans.
//! `--no-extension` locates the five frames only.
//!
//! Seeds come from two ranges that never meet: `tune` (the default) for
//! development, `report` for the table. `--scans` prints every scan's line
//! and is refused for the reporting range: its single scans are not looked
//! at while developing; each line splits the error along the line of sight
//! and across it, with the answer's radius and the outline's image radius
//! against the truth's, how far the answer's laser points lie behind
//! the true surface along their camera rays (median: the stripe's own
//! error, apart from the fit's), and along the line of sight how far the
//! answer's front lies behind the fruit's and its centre behind its front
//! (against the truth's centre behind the fruit's front). Five switches take a cause out to measure it:
//! `--round` makes every fruit's ellipsoid a sphere (a randomized apple
//! keeps its form, its cavities and taper, within it), `--no-outline`
//! locates without the fruit's outline, `--true-calibration` locates a randomized scan
//! with the calibration its images were rendered with (no calibration
//! error; `--true-calibration-of` a comma list of `camera` (focal length
//! and principal point), `laser` (alpha, L0, beta) and `slide` (its
//! scale k) takes out those parts only), and on randomized rigs `--no-form` renders the apple's plain
//! ellipsoid (no taper, flat cheek or cavities) and `--no-glow` no light in
//! its flesh. `--anatomy` measures the randomized families once per row of
//! docs/ACCURACY.md's table of what the randomized error is made of (each
//! row a set of these switches) and prints that table. Progress goes to
//! standard error, the table (markdown) to standard output.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use alacs_locate::{FrameImages, LocateOptions, Prior, Status, locate};
use alacs_model::{Camera, LaserModel, Ray, ScanStrategy};
use alacs_sim::{OrchardOptions, OrchardScene, ScanOptions, TakeOut, simulate_rendered_scan};

/// First seed of the tuning range.
const TUNE_SEEDS: u64 = 10_000;
/// First seed of the reporting range.
const REPORT_SEEDS: u64 = 1_000_000;
/// Seeds between two families' first seeds, so no two families share a scene.
const FAMILY_STRIDE: u64 = 10_000;
/// An `ok` answer farther than this from the truth is wrong (the bar).
const WRONG_MM: f64 = 15.0;

/// One family: its name and how a scan of it is set up from its index.
struct Family {
    name: &'static str,
    options: fn(u64) -> (OrchardOptions, bool),
}

/// A uniform draw in `lo..hi` from the scan's index (a fixed hash, so a
/// family's scans spread evenly over the range).
fn spread(i: u64, salt: u64, lo: f64, hi: f64) -> f64 {
    let hash = (i ^ salt).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 11;
    lo + (hi - lo) * (hash as f64 / (1u64 << 53) as f64)
}

fn orchard(occlusion: f64) -> OrchardOptions {
    OrchardOptions { occlusion, ..OrchardOptions::default() }
}

const FAMILIES: &[Family] = &[
    Family { name: "shade, 0-40 % hidden", options: |i| (orchard(spread(i, 1, 0.0, 0.4)), false) },
    Family { name: "sun, 0-40 % hidden", options: |i| (orchard(spread(i, 1, 0.0, 0.4)), true) },
    Family { name: "unoccluded, sun or shade", options: |i| (orchard(0.0), i % 2 == 1) },
    Family { name: "60 % hidden, sun or shade", options: |i| (orchard(0.6), i % 2 == 1) },
    Family {
        name: "1.0-1.6 m, 0-20 % hidden",
        options: |i| {
            let o =
                OrchardOptions { depth_mm: (1000.0, 1600.0), ..orchard(spread(i, 2, 0.0, 0.2)) };
            (o, i % 2 == 1)
        },
    },
    Family {
        name: "clusters of 2-4, 0-1 branch in front, 20-40 % hidden",
        options: |i| {
            let o = OrchardOptions {
                cluster: 1 + (i % 3) as usize,
                front_branches: ((i / 3) % 2) as usize,
                ..orchard(spread(i, 3, 0.2, 0.4))
            };
            (o, i % 2 == 1)
        },
    },
];

#[derive(Default, Clone)]
struct Tally {
    scans: usize,
    found: usize,
    wrong: usize,
    /// Errors of the `ok` answers within [`WRONG_MM`].
    errors_mm: Vec<f64>,
    /// Scans that took the extension's frames.
    extended: usize,
    /// `ok` answers with a covariance, and those whose 99 % ellipsoid
    /// holds the truth.
    with_covariance: usize,
    covered: usize,
}

/// Squared Mahalanobis distance within which 99 % of a 3-D Gaussian lies
/// (chi-square, 3 degrees of freedom).
const CHI2_3_99: f64 = 11.345;

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let k = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[k]
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    const USAGE: &str = "families [--seeds tune|report] [--n N] [--scale S] [--randomize on|off|both] [--family NAME] [--scans] [--round] [--no-form] [--no-glow] [--no-outline] [--true-calibration] [--true-calibration-of camera,laser,slide] [--no-extension] [--anatomy]";
    const VALUED: [&str; 6] =
        ["--seeds", "--n", "--scale", "--randomize", "--family", "--true-calibration-of"];
    const SWITCHES: [&str; 8] = [
        "--anatomy",
        "--scans",
        "--round",
        "--no-form",
        "--no-glow",
        "--no-outline",
        "--true-calibration",
        "--no-extension",
    ];
    if args.iter().any(|a| a == "--help" || a == "-h") {
        println!("usage: {USAGE}");
        return;
    }
    let mut k = 0;
    while k < args.len() {
        let arg = args[k].as_str();
        if VALUED.contains(&arg) {
            assert!(k + 1 < args.len(), "{arg} needs a value; usage: {USAGE}");
            k += 2;
        } else {
            assert!(SWITCHES.contains(&arg), "unknown argument {arg}; usage: {USAGE}");
            k += 1;
        }
    }
    let value = |flag: &str| args.iter().position(|a| a == flag).map(|k| args[k + 1].clone());
    let report = match value("--seeds").as_deref() {
        None | Some("tune") => false,
        Some("report") => true,
        Some(other) => panic!("--seeds tune|report, not {other}"),
    };
    let n: u64 = value("--n").map_or(12, |v| v.parse().unwrap());
    let scale: f64 = value("--scale").map_or(0.5, |v| v.parse().unwrap());
    let per_scan = args.iter().any(|a| a == "--scans");
    assert!(
        !(per_scan && report),
        "--scans is for the tuning range: the reporting range's single scans are not looked at"
    );
    // Randomization off, on, or both (the table's two halves).
    let modes: Vec<bool> = match value("--randomize").as_deref() {
        Some("on") => vec![true],
        Some("off") => vec![false],
        None | Some("both") => vec![false, true],
        Some(other) => panic!("--randomize on|off|both, not {other}"),
    };
    println!(
        "{} seeds, {n} scans a family, camera scale {scale}; found: `ok` within {WRONG_MM} mm of the truth; wrong: `ok` beyond it; errors of the found.\n",
        if report { "Reporting" } else { "Tuning" },
    );
    let settings = Settings {
        only: value("--family"),
        n,
        base: if report { REPORT_SEEDS } else { TUNE_SEEDS },
        scale,
        per_scan,
        switches: Switches::from_args(&args),
    };
    if args.iter().any(|a| a == "--anatomy") {
        anatomy(&settings);
        return;
    }
    println!(
        "| family | randomized | found | not found | wrong | median | 90th pct | worst | extended | truth in its 99 % ellipsoid |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut colours: Vec<(String, Tally)> = Vec::new();
    let mut unbuilt = 0;
    for &randomize in &modes {
        let measured = measure(&settings, randomize);
        for (name, tally) in &measured.families {
            print_row(name, randomize, tally);
        }
        print_row("all families", randomize, &measured.total);
        colours.extend(measured.colours);
        unbuilt += measured.unbuilt;
    }
    colours.sort_by(|a, b| a.0.cmp(&b.0));
    for (colour, tally) in &colours {
        print_row(&format!("all families, {colour} fruit"), true, tally);
    }
    if unbuilt > 0 {
        println!("\n{unbuilt} scene(s) the simulator could not build were left out.");
    }
}

/// The switches that take a cause out (module docs).
#[derive(Clone, Copy, Default)]
struct Switches {
    round: bool,
    no_form: bool,
    no_glow: bool,
    no_outline: bool,
    true_calibration: bool,
    /// The parts of the calibration `--true-calibration-of` takes out:
    /// camera, laser, slide.
    true_parts: [bool; 3],
    no_extension: bool,
}

impl Switches {
    fn from_args(args: &[String]) -> Switches {
        let on = |flag: &str| args.iter().any(|a| a == flag);
        Switches {
            round: on("--round"),
            no_form: on("--no-form"),
            no_glow: on("--no-glow"),
            no_outline: on("--no-outline"),
            true_calibration: on("--true-calibration"),
            true_parts: {
                let value = args
                    .iter()
                    .position(|a| a == "--true-calibration-of")
                    .map_or(String::new(), |k| args[k + 1].clone());
                let parts: Vec<&str> = value.split(',').filter(|p| !p.is_empty()).collect();
                for part in &parts {
                    assert!(
                        ["camera", "laser", "slide"].contains(part),
                        "--true-calibration-of takes camera, laser and slide, not {part}"
                    );
                }
                ["camera", "laser", "slide"].map(|name| parts.contains(&name))
            },
            no_extension: on("--no-extension"),
        }
    }
}

/// What a run measures: which families, how many scans from which seed,
/// at which scale, with which causes taken out.
struct Settings {
    only: Option<String>,
    n: u64,
    base: u64,
    scale: f64,
    per_scan: bool,
    switches: Switches,
}

/// One run's tallies: each family's, all of them, and by fruit colour.
struct Measured {
    families: Vec<(&'static str, Tally)>,
    total: Tally,
    colours: Vec<(String, Tally)>,
    unbuilt: usize,
}

/// Every family's scans, rendered with randomization on or off, located
/// and tallied.
fn measure(settings: &Settings, randomize: bool) -> Measured {
    let (n, scale) = (settings.n, settings.scale);
    let nominal = LaserModel::seed_paper();
    let mut measured =
        Measured { families: Vec::new(), total: Tally::default(), colours: Vec::new(), unbuilt: 0 };
    let (colours, unbuilt) = (&mut measured.colours, &mut measured.unbuilt);
    for (f, family) in FAMILIES.iter().enumerate() {
        if settings.only.as_deref().is_some_and(|o| !family.name.contains(o)) {
            continue;
        }
        let mut tally = Tally::default();
        for i in 0..settings.n {
            let seed = settings.base + f as u64 * FAMILY_STRIDE + i;
            let (mut orchard, sun) = (family.options)(i);
            if settings.switches.round {
                orchard.max_ellipticity = 0.0;
            }
            let take_out =
                TakeOut { glow: settings.switches.no_glow, form: settings.switches.no_form };
            let options = ScanOptions {
                orchard,
                sun,
                scale,
                seed,
                randomize,
                take_out,
                ..ScanOptions::default()
            };
            // A scene the simulator cannot build (a sliver of occlusion
            // no leaf can make) is left out and counted.
            let Ok(sim) = simulate_rendered_scan(&Camera::blackfly_s_5mp(), &nominal, &options)
            else {
                *unbuilt += 1;
                continue;
            };
            let scan = &sim.scan;
            let frames: Vec<FrameImages> = sim.frames().map(FrameImages::from).collect();
            // The RGB-D camera's radius: 13 % below to 15 % above the
            // truth, as a detector's circle at 0.6-1.6 m gives it.
            let truth_radius = scan.scene.fruit_radius_mm;
            let prior = Prior {
                rough_position_mm: scan.rough_position_mm,
                fruit_radius_mm: truth_radius * spread(seed, 7, 0.87, 1.15),
            };
            let locate_options = LocateOptions {
                use_outline: !settings.switches.no_outline,
                ..LocateOptions::default()
            };
            // The calibration the localizer is given, or (to measure what
            // the randomized calibration error costs) the one the images
            // were rendered with.
            let switches = &settings.switches;
            let [true_camera, true_laser, true_slide] =
                switches.true_parts.map(|part| part || switches.true_calibration);
            let camera = if true_camera { &scan.rendered_camera } else { &scan.camera };
            let rendered = &scan.rendered_laser;
            let mut laser = scan.laser;
            if true_laser {
                (laser.alpha_rad, laser.l0_mm, laser.beta_rad) =
                    (rendered.alpha_rad, rendered.l0_mm, rendered.beta_rad);
            }
            if true_slide {
                laser.slide_scale = rendered.slide_scale;
            }
            let mut answer = locate(camera, &laser, &prior, &frames, &locate_options)
                .expect("a simulated scan is valid input");
            // Not found in the sweep for want of evidence: the strategy's
            // extension frames (beyond both ends of it), as the scan
            // controller takes them (nearest first does not matter here).
            let mut extended = 0;
            if answer.status != Status::Ok
                && !answer.contradicted
                && !settings.switches.no_extension
            {
                let slides = ScanStrategy::default().extension(&scan.plan);
                let images: Vec<_> = slides
                    .iter()
                    .enumerate()
                    .map(|(k, &d)| {
                        let index = (scan.frames.len() + k) as u64;
                        (scan.render_at(d, true, index).expect("renders"), d)
                    })
                    .collect();
                if !images.is_empty() {
                    extended = images.len();
                    let mut all = frames.clone();
                    all.extend(images.iter().map(|(image, d)| FrameImages::from((image, *d))));
                    answer = locate(camera, &laser, &prior, &all, &locate_options)
                        .expect("a simulated scan is valid input");
                }
            }
            let truth = scan.scene.fruit_centre;
            let error = match (answer.status, answer.position_mm) {
                (Status::Ok, Some(p)) => Some((p - truth).norm()),
                _ => None,
            };
            // Whether the answer's 99 % ellipsoid holds the truth.
            let covered = match (answer.status, answer.position_mm, answer.position_cov_mm2) {
                (Status::Ok, Some(p), Some(cov)) => cov
                    .try_inverse()
                    .map(|inverse| (p - truth).dot(&(inverse * (p - truth))) <= CHI2_3_99),
                _ => None,
            };
            tally.add(error, extended > 0, covered);
            if let Some(v) = &scan.variation {
                let name = format!("{:?}", v.fruit_colour).to_lowercase();
                match colours.iter_mut().find(|(c, _)| *c == name) {
                    Some((_, t)) => t.add(error, extended > 0, covered),
                    None => {
                        let mut t = Tally::default();
                        t.add(error, extended > 0, covered);
                        colours.push((name, t));
                    }
                }
            }
            if settings.per_scan {
                let line = match error {
                    Some(e) => {
                        // The answer's worst standard deviation, to set against its error.
                        let sigma = answer
                            .position_cov_mm2
                            .map_or(f64::NAN, |c| c.symmetric_eigenvalues().max().max(0.0).sqrt());
                        // Of the answer's points (within 2.5 mm of its sphere), those
                        // on the true fruit ([`on_true_fruit`]).
                        let on_truth = answer.fused.as_ref().map_or((0, 0), |f| {
                            let points = answer.frames.iter().flat_map(|r| &r.points_in_camera);
                            points.fold((0, 0), |(t, n), (_, p)| {
                                if f.sphere.distance_mm(p) < 2.5 {
                                    (t + usize::from(on_true_fruit(&scan.scene, p)), n + 1)
                                } else {
                                    (t, n)
                                }
                            })
                        });
                        // How far the answer's points lie behind the true surface
                        // along their camera rays (median, mm): the stripe's own bias
                        // (a wide or glowing stripe, the calibration), apart from the fit.
                        let behind = answer.fused.as_ref().map_or(f64::NAN, |f| {
                            let mut offsets: Vec<f64> = answer
                                .frames
                                .iter()
                                .flat_map(|r| &r.points_in_camera)
                                .filter(|(_, p)| f.sphere.distance_mm(p) < 2.5)
                                .filter_map(|(_, p)| behind_true_fruit_mm(&scan.scene, p))
                                .collect();
                            offsets.sort_by(f64::total_cmp);
                            offsets.get(offsets.len() / 2).copied().unwrap_or(f64::NAN)
                        });
                        // Where the answer's front lies against the fruit's, along
                        // the line of sight through the truth, and how far its centre
                        // lies behind that front against the truth's (mm).
                        let (front, depth, true_depth) =
                            answer.fused.as_ref().map_or((f64::NAN, f64::NAN, f64::NAN), |f| {
                                let sight = truth.coords.normalize();
                                let ray =
                                    Ray { origin: nalgebra::Point3::origin(), direction: sight };
                                let true_front = scan
                                    .scene
                                    .first_hit_among(&ray, 1.0, std::iter::once(0))
                                    .map_or(f64::NAN, |h| h.t);
                                // An ellipsoid's half extent along a unit direction s is
                                // sqrt(s' A^-1 s).
                                let (centre, depth) = match &f.ellipsoid {
                                    Some(e) => (
                                        e.centre,
                                        e.shape.try_inverse().map_or(f64::NAN, |inverse| {
                                            sight.dot(&(inverse * sight)).sqrt()
                                        }),
                                    ),
                                    None => (f.sphere.centre, f.sphere.radius_mm),
                                };
                                (
                                    centre.coords.dot(&sight) - depth - true_front,
                                    depth,
                                    truth.coords.norm() - true_front,
                                )
                            });
                        // The error along the line of sight and across it, and the
                        // answer's radius against the truth's.
                        let p = answer.position_mm.unwrap_or(truth);
                        let sight = truth.coords.normalize();
                        let along = (p - truth).dot(&sight);
                        let across = ((p - truth) - sight * along).norm();
                        let radius = answer.radius_mm.unwrap_or(f64::NAN);
                        // The outline's radius against the true silhouette's, px.
                        let outline_px = answer
                            .fused
                            .as_ref()
                            .and_then(|f| f.outline.as_ref())
                            .map_or(f64::NAN, |o| {
                                let theta = (truth_radius / truth.coords.norm()).asin();
                                o.radius_px - scan.camera.fx_px * theta.tan()
                            });
                        format!(
                            "ok {e:6.2} mm (outline {outline_px:+.2} px, along {along:+.2}, across {across:.2}, radius {:+.1} mm, points {behind:+.2} mm behind, front {front:+.2}, centre {depth:.1} behind it for {true_depth:.1}; sigma {sigma:.1} mm, {} of its {} points on the fruit): {}",
                            radius - truth_radius,
                            on_truth.0,
                            on_truth.1,
                            answer.reason
                        )
                    }
                    None => format!("NOT FOUND: {}", answer.reason),
                };
                if let Some(v) = &scan.variation {
                    println!(
                        "  variation: {:?} sigma {:.2} px flatness {:.2} power {:.2} exposure {:.2} subsurface {:.1} mm blur {:.2} px",
                        v.fruit_colour,
                        v.stripe_sigma_px,
                        v.profile_flatness,
                        v.laser_power,
                        v.exposure_factor,
                        v.subsurface_sigma_mm,
                        v.blur_sigma_px
                    );
                }
                let extension = if extended > 0 {
                    format!(" (after {extended} extension frames)")
                } else {
                    String::new()
                };
                println!(
                    "  seed {seed} z {:.0} r {:.1} hidden {:.0} %{extension}: {line}",
                    truth.z,
                    truth_radius,
                    100.0 * scan.scene.occlusion
                );
                // Each frame's stripe points, those on the fruit's colour, and
                // those on the true fruit ([`on_true_fruit`]).
                let frames: Vec<String> = answer
                    .frames
                    .iter()
                    .map(|r| {
                        let on = r
                            .points_in_camera
                            .iter()
                            .filter(|(_, p)| on_true_fruit(&scan.scene, p))
                            .count();
                        format!("{}/{}/{on}", r.stripe.len(), r.fruit.len())
                    })
                    .collect();
                println!("    frames (stripe/fruit/on the true fruit): {}", frames.join(" "));
            }
            eprint!(
                "\r{} ({}): {}/{n}   ",
                family.name,
                if randomize { "randomized" } else { "fixed" },
                i + 1
            );
        }
        eprintln!();
        measured.total.merge(tally.clone());
        measured.families.push((family.name, tally));
    }
    measured
}

/// The rows of the table of what the randomized error is made of
/// (docs/ACCURACY.md): the causes each row takes out.
const ANATOMY: [(&str, Switches); 7] = {
    const NONE: Switches = Switches {
        round: false,
        no_form: false,
        no_glow: false,
        no_outline: false,
        true_calibration: false,
        true_parts: [false; 3],
        no_extension: false,
    };
    [
        ("nothing", NONE),
        ("`--no-glow --no-form`", Switches { no_glow: true, no_form: true, ..NONE }),
        ("`--true-calibration`", Switches { true_calibration: true, ..NONE }),
        (
            "`--true-calibration --no-glow`",
            Switches { true_calibration: true, no_glow: true, ..NONE },
        ),
        (
            "`--true-calibration --no-form`",
            Switches { true_calibration: true, no_form: true, ..NONE },
        ),
        (
            "`--true-calibration --no-glow --no-form`",
            Switches { true_calibration: true, no_glow: true, no_form: true, ..NONE },
        ),
        (
            "`--true-calibration --no-glow --no-form --round`",
            Switches { true_calibration: true, no_glow: true, no_form: true, round: true, ..NONE },
        ),
    ]
};

/// How far a laser point (camera frame, mm) lies behind the scene's fruit
/// along its camera ray, where that ray meets the fruit first; `None`
/// where it meets something else or nothing.
fn behind_true_fruit_mm(scene: &OrchardScene, p: &nalgebra::Point3<f64>) -> Option<f64> {
    let ray = Ray { origin: nalgebra::Point3::origin(), direction: p.coords.normalize() };
    let hit = scene.first_hit(&ray, 1.0)?;
    (hit.object == 0).then(|| p.coords.norm() - hit.t)
}

/// Whether a laser point (camera frame, mm) lies on the scene's fruit: its
/// camera ray meets the fruit first, within 2.5 mm of the point. The
/// rendered surface, so the apple's form and elongation count as fruit
/// where a sphere of the true radius would not.
fn on_true_fruit(scene: &OrchardScene, p: &nalgebra::Point3<f64>) -> bool {
    behind_true_fruit_mm(scene, p).is_some_and(|behind| behind.abs() < 2.5)
}

/// `--anatomy`: the randomized families once per row of [`ANATOMY`], one
/// line each.
fn anatomy(settings: &Settings) {
    println!(
        "| taken out | found | wrong | median shade / sun | unoccluded median / worst | all families median / 90th pct |"
    );
    println!("|---|---|---|---|---|---|");
    for (name, switches) in ANATOMY {
        let measured = measure(&Settings { switches, only: None, ..*settings }, true);
        let family = |prefix: &str| {
            measured
                .families
                .iter()
                .find(|(n, _)| n.starts_with(prefix))
                .map(|(_, t)| t.sorted_errors_mm())
                .unwrap_or_default()
        };
        let (shade, sun, unoccluded) = (family("shade"), family("sun"), family("unoccluded"));
        let all = measured.total.sorted_errors_mm();
        let mm = |v: f64| format!("{v:.2}");
        println!(
            "| {name} | {} of {} | {} | {} / {} mm | {} / {} mm | {} / {} mm |",
            measured.total.found,
            measured.total.scans,
            measured.total.wrong,
            mm(percentile(&shade, 0.5)),
            mm(percentile(&sun, 0.5)),
            mm(percentile(&unoccluded, 0.5)),
            mm(unoccluded.last().copied().unwrap_or(f64::NAN)),
            mm(percentile(&all, 0.5)),
            mm(percentile(&all, 0.9)),
        );
    }
}

impl Tally {
    fn add(&mut self, error_mm: Option<f64>, extended: bool, covered: Option<bool>) {
        self.scans += 1;
        self.extended += usize::from(extended);
        if let Some(covered) = covered {
            self.with_covariance += 1;
            self.covered += usize::from(covered);
        }
        match error_mm {
            Some(e) if e > WRONG_MM => self.wrong += 1,
            Some(e) => {
                self.found += 1;
                self.errors_mm.push(e);
            }
            None => {}
        }
    }

    /// The errors of the found, smallest first.
    fn sorted_errors_mm(&self) -> Vec<f64> {
        let mut errors = self.errors_mm.clone();
        errors.sort_by(f64::total_cmp);
        errors
    }

    fn merge(&mut self, other: Tally) {
        self.scans += other.scans;
        self.found += other.found;
        self.wrong += other.wrong;
        self.errors_mm.extend(other.errors_mm);
        self.extended += other.extended;
        self.with_covariance += other.with_covariance;
        self.covered += other.covered;
    }
}

fn print_row(name: &str, randomized: bool, tally: &Tally) {
    let errors = tally.sorted_errors_mm();
    let pct = 100.0 * tally.found as f64 / tally.scans.max(1) as f64;
    let mm = |v: f64| if v.is_nan() { "-".to_string() } else { format!("{v:.2} mm") };
    println!(
        "| {name} | {} | {} of {} ({pct:.0} %) | {} | {} | {} | {} | {} | {} | {} of {} |",
        if randomized { "yes" } else { "no" },
        tally.found,
        tally.scans,
        tally.scans - tally.found - tally.wrong,
        tally.wrong,
        mm(percentile(&errors, 0.5)),
        mm(percentile(&errors, 0.9)),
        mm(errors.last().copied().unwrap_or(f64::NAN)),
        tally.extended,
        tally.covered,
        tally.with_covariance,
    );
}

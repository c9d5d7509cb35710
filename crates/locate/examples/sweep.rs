//! Localization errors on a batch of simulated scans, both methods:
//! `cargo run --release -p alacs-locate --example sweep -- [N] [occlusion] [sun] [scale] [first_seed] [ellipticity]`;
//! `CLUSTER=N` (0-3 neighbours) and `BRANCHES=N` (0-4 across the front) add clutter;
//! `PRIOR_MM=35` sets the radius prior (default 40; `random`: 35-45 mm by seed), `COVERAGE=0.1` overrides `LocateOptions::min_coverage`, `OFF=1` renders laser-off images too, `FRAMES=1` prints each frame's candidate or rejection, `DEBUG=1` ellipsoid details,
//! `LASER=alpha_deg,beta_deg,l0_mm` renders with another laser, `LOCATE_LASER=...` locates with another calibration.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use alacs_locate::{FrameImages, LocateOptions, Method, Prior, Status, locate};
use alacs_model::{Camera, Fidelity, LaserModel};
use alacs_sim::{OrchardOptions, ScanOptions, simulate_rendered_scan};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: u64 = args.get(1).map_or(8, |a| a.parse().unwrap());
    let occlusion: f64 = args.get(2).map_or(0.0, |a| a.parse().unwrap());
    let sun = args.get(3).is_some_and(|a| a == "sun");
    let scale: f64 = args.get(4).map_or(1.0, |a| a.parse().unwrap());
    let first: u64 = args.get(5).map_or(0, |a| a.parse().unwrap());
    let ellipticity: f64 = args.get(6).map_or(0.08, |a| a.parse().unwrap());
    // `LASER=alpha_deg,beta_deg,l0_mm`: the laser the scans are rendered
    // with (default the seed's); `LOCATE_LASER=...` the calibration they
    // are located with (default the same: a calibration error if not).
    let laser_from = |name: &str, default: [f64; 3]| {
        let v: Vec<f64> = std::env::var(name)
            .map_or(default.to_vec(), |s| s.split(',').map(|x| x.parse().unwrap()).collect());
        LaserModel::from_degrees(Fidelity::High, v[0], v[1], v[2])
    };
    let true_laser = laser_from("LASER", [19.07, 0.69, 381.98]);
    let laser = laser_from(
        "LOCATE_LASER",
        [true_laser.alpha_rad.to_degrees(), true_laser.beta_rad.to_degrees(), true_laser.l0_mm],
    );
    for seed in first..first + n {
        let options = ScanOptions {
            orchard: OrchardOptions {
                occlusion,
                max_ellipticity: ellipticity,
                cluster: std::env::var("CLUSTER").map_or(0, |c| c.parse().unwrap()),
                front_branches: std::env::var("BRANCHES").map_or(0, |c| c.parse().unwrap()),
                ..OrchardOptions::default()
            },
            sun,
            scale,
            seed,
            ..ScanOptions::default()
        };
        let sim = simulate_rendered_scan(&Camera::blackfly_s_5mp(), &true_laser, &options).unwrap();
        let scan = &sim.scan;
        // `OFF=1`: each frame with its laser-off image.
        let offs: Vec<_> = if std::env::var("OFF").is_ok() {
            (0..scan.frames.len()).map(|i| scan.render_frame(i, false).unwrap()).collect()
        } else {
            Vec::new()
        };
        let frames: Vec<_> = sim
            .frames()
            .enumerate()
            .map(|(i, f)| FrameImages { image_laser_off: offs.get(i), ..FrameImages::from(f) })
            .collect();
        let prior = Prior {
            rough_position_mm: scan.rough_position_mm,
            fruit_radius_mm: std::env::var("PRIOR_MM").map_or(40.0, |r| {
                // `PRIOR_MM=random`: a prior drawn per seed over the
                // simulator's fruit radii, 35-45 mm.
                if r == "random" {
                    let hash = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 11;
                    35.0 + 10.0 * (hash as f64 / (1u64 << 53) as f64)
                } else {
                    r.parse().unwrap()
                }
            }),
        };
        let truth = scan.scene.fruit_centre;
        let start = std::time::Instant::now();
        let mut line = format!(
            "seed {seed:3} z {:6.1} r {:4.1} occ {:3.0}%{} |",
            truth.z,
            scan.scene.fruit_radius_mm,
            100.0 * scan.scene.occlusion,
            if scan.plan.shifted { " shifted" } else { "" }
        );
        for method in [Method::Fused, Method::Holistic] {
            let answer = locate(
                &scan.camera,
                &laser,
                &prior,
                &frames,
                &LocateOptions {
                    method,
                    min_coverage: std::env::var("COVERAGE")
                        .ok()
                        .map_or(0.2, |c| c.parse().unwrap()),
                    ..LocateOptions::default()
                },
            )
            .unwrap();
            match (answer.status, answer.position_mm) {
                (Status::Ok, Some(p)) => {
                    let e = p - truth;
                    line += &format!(
                        " {:8} err ({:6.2} {:6.2} {:6.2}) 3d {:6.2} |",
                        method.as_str(),
                        e.x,
                        e.y,
                        e.z,
                        e.norm()
                    );
                }
                _ => line += &format!(" {:8} NOT FOUND: {} |", method.as_str(), answer.reason),
            }
            if let Some(fit) = &answer.fused {
                line += &format!(
                    " sphere 3d {:6.2} r {:4.1}{} |",
                    (fit.sphere.centre - truth).norm(),
                    fit.sphere.radius_mm,
                    match (&fit.outline, fit.outline_refined, fit.radius_from_prior) {
                        (Some(_), true, _) => " (outline refined)".to_string(),
                        (Some(_), false, _) => format!(" (outline, {} frames)", fit.n_frames),
                        (None, _, true) => " (prior radius)".to_string(),
                        _ => String::new(),
                    }
                );
            }
            if method == Method::Fused {
                let per: Vec<String> = answer
                    .frames
                    .iter()
                    .map(|f| format!("{}/{}", f.fruit.len(), f.stripe.len()))
                    .collect();
                line += &format!(" pts {} |", per.join(" "));
                if let Some(fit) = &answer.fused {
                    // How much of each frame's arc the fit holds, and the
                    // share of the rows its cut spans that they cover.
                    let s = &fit.sphere;
                    let (mut shares, mut cover) = (String::new(), String::new());
                    for f in &answer.frames {
                        let arc: Vec<_> = f
                            .points_in_camera
                            .iter()
                            .filter(|(i, _)| f.fruit.contains(i))
                            .map(|(_, p)| *p)
                            .collect();
                        let held: Vec<f64> = arc
                            .iter()
                            .map(|p| s.distance_mm(p))
                            .filter(|d| d.abs() <= 2.0)
                            .collect();
                        let on = held.len();
                        if on > 0 {
                            let rms = (held.iter().map(|d| d * d).sum::<f64>() / on as f64).sqrt();
                            shares += &format!(" {on}/{}@{rms:.2}", arc.len());
                        }
                        let plane = laser.plane_in_camera(f.slide_mm);
                        let d = (plane.normal.dot(&s.centre.coords) - plane.offset_mm)
                            / plane.normal.norm();
                        let rho = (s.radius_mm.powi(2) - d * d).max(0.0).sqrt();
                        let rows = 2.0 * rho * scan.camera.fy_px / s.centre.z;
                        cover += &format!(" {:.2}", on as f64 / rows.max(1.0));
                    }
                    line += &format!(" arcs on{shares} | framecov{cover} |");
                }
                if let Some(e) = answer.fused.as_ref().and_then(|f| f.ellipsoid) {
                    let a = e.semi_axes_mm();
                    line += &format!(
                        " ell {:.1}/{:.1}/{:.1} ratio {:.3} |",
                        a.x,
                        a.y,
                        a.z,
                        a.max() / a.min()
                    );
                }
            }
        }
        line += &format!(" {:.0} ms", start.elapsed().as_secs_f64() * 1000.0 / 2.0);
        println!("{line}");
        if let Ok(dir) = std::env::var("SAVE") {
            // Each laser-on frame as PNG, with the truth's image (green) and
            // the fused outline (blue) marked, for a look by eye.
            let answer =
                locate(&scan.camera, &laser, &prior, &frames, &LocateOptions::default()).unwrap();
            for (k, f) in frames.iter().enumerate() {
                let mut img = f.image.clone();
                let mut mark = |u: f64, v: f64, c: [u8; 3]| {
                    if u >= 0.0 && v >= 0.0 && (u as u32) < img.width() && (v as u32) < img.height()
                    {
                        img.put_pixel(u as u32, v as u32, image::Rgb(c));
                    }
                };
                if let Ok(px) = scan.camera.project(&truth) {
                    for t in -6..=6 {
                        mark(px.x + f64::from(t), px.y, [0, 255, 0]);
                        mark(px.x, px.y + f64::from(t), [0, 255, 0]);
                    }
                }
                if let Some(o) = answer.fused.as_ref().and_then(|f| f.outline.as_ref()) {
                    for e in &o.edges_px {
                        mark(e.x, e.y, [0, 128, 255]);
                    }
                }
                img.save(format!("{dir}/seed{seed}_frame{k}.png")).unwrap();
            }
        }
        if std::env::var("FRAMES").is_ok() {
            let answer =
                locate(&scan.camera, &laser, &prior, &frames, &LocateOptions::default()).unwrap();
            for (k, f) in answer.frames.iter().enumerate() {
                match &f.candidate {
                    Some(c) => println!(
                        "  frame {k}: candidate err {:6.2} circle r {:5.1} n {} rms {:.2}",
                        (c.position_mm - truth).norm(),
                        c.circle_radius_mm,
                        c.n_points,
                        c.fit_rms_mm
                    ),
                    None => println!("  frame {k}: {}", f.rejected.as_deref().unwrap_or("-")),
                }
            }
            if let Some(why) = &answer.fused_rejected {
                println!("  fused rejected: {why}");
            }
            if let Some(fit) = &answer.fused {
                println!(
                    "  fused: centre err {:.2} r {:.1} n {} frames {} rms {:.2}",
                    (fit.sphere.centre - truth).norm(),
                    fit.sphere.radius_mm,
                    fit.n_points,
                    fit.n_frames,
                    fit.rms_mm
                );
            }
        }
        if std::env::var("DEBUG").is_ok() {
            let answer =
                locate(&scan.camera, &laser, &prior, &frames, &LocateOptions::default()).unwrap();
            println!("reason: {}", answer.reason);
            println!("truth shape {:?}", scan.scene.objects[0].shape);
            for (c, r) in scan.scene.neighbours() {
                println!(
                    "neighbour at {:.1?} r {r:.1}, {:.1} mm from the target",
                    c,
                    (c - truth).norm()
                );
            }
            // The target's ellipsoid (a randomized apple's, whose form departs from it).
            if let alacs_sim::Shape::Ellipsoid { centre, rotation, semi_axes_mm }
            | alacs_sim::Shape::Apple { centre, rotation, semi_axes_mm, .. } =
                &scan.scene.objects[0].shape
            {
                let inverse_squares =
                    nalgebra::Matrix3::from_diagonal(&semi_axes_mm.map(|a| 1.0 / (a * a)));
                let true_fit = alacs_locate::fit::Ellipsoid {
                    centre: *centre,
                    shape: rotation.matrix() * inverse_squares * rotation.matrix().transpose(),
                };
                let points: Vec<_> = answer
                    .frames
                    .iter()
                    .flat_map(|f| {
                        f.points_in_camera
                            .iter()
                            .filter(|(i, _)| f.fruit.contains(i))
                            .map(|(_, p)| *p)
                    })
                    .collect();
                let fitted_for_set = answer.fused.as_ref().and_then(|f| f.ellipsoid);
                let points: Vec<_> = points
                    .iter()
                    .copied()
                    .filter(|p| fitted_for_set.is_none_or(|e| e.distance_mm(p) < 2.0))
                    .collect();
                let rms = |e: &alacs_locate::fit::Ellipsoid| {
                    (points.iter().map(|p| e.distance_mm(p).powi(2)).sum::<f64>()
                        / points.len() as f64)
                        .sqrt()
                };
                let fitted = answer.fused.as_ref().and_then(|f| f.ellipsoid);
                // Too few points (a mostly hidden fruit) fit no ellipsoid.
                match alacs_locate::fit::fit_ellipsoid_from(&points, &true_fit, 0.2, 20.0) {
                    Some(from_truth) => println!(
                        "from truth: centre error {:.2} mm rms {:.3}",
                        (from_truth.centre - true_fit.centre).norm(),
                        rms(&from_truth)
                    ),
                    None => println!("from truth: no ellipsoid fits the {} points", points.len()),
                }
                let signed: Vec<f64> = points
                    .iter()
                    .map(|p| {
                        let d = p - true_fit.centre;
                        ((d.dot(&(true_fit.shape * d))).sqrt() - 1.0) * scan.scene.fruit_radius_mm
                    })
                    .filter(|r| r.abs() < 2.0)
                    .collect();
                let mean = signed.iter().sum::<f64>() / signed.len() as f64;
                let sd = (signed.iter().map(|r| (r - mean).powi(2)).sum::<f64>()
                    / signed.len() as f64)
                    .sqrt();
                println!(
                    "near-truth points {} of {}: signed residual mean {mean:.3} sd {sd:.3}",
                    signed.len(),
                    points.len()
                );
                println!(
                    "points {} rms vs truth {:.3} vs fit {:?}; fitted axes {:?} true {:?}",
                    points.len(),
                    rms(&true_fit),
                    fitted.as_ref().map(rms),
                    fitted.map(|e| e.semi_axes_mm()),
                    semi_axes_mm
                );
            }
            println!("fused {:?}", answer.fused);
            for (k, f) in answer.frames.iter().enumerate() {
                println!(
                    "frame {k}: slide {} stripe {} pts {} fruit {} cand {:?} rej {:?}",
                    f.slide_mm,
                    f.stripe.len(),
                    f.points_in_camera.len(),
                    f.fruit.len(),
                    f.candidate.as_ref().map(|c| (c.circle_radius_mm, c.fit_rms_mm, c.n_points)),
                    f.rejected
                );
            }
        }
    }
}

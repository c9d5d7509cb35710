//! Orchard scene geometry: intersections land on the surfaces, leaves hide
//! what was asked, same seed same scene.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use alacs_model::Ray;
use alacs_sim::{AppleForm, Kind, OrchardOptions, Shape, orchard_scene};
use nalgebra::{Point3, Rotation3, Unit, Vector3};

fn rays() -> impl Iterator<Item = Ray> {
    (0..21).flat_map(|i| {
        (0..21).map(move |j| {
            Ray::through_normalized(-0.1 + 0.01 * f64::from(i), -0.1 + 0.01 * f64::from(j))
        })
    })
}

#[test]
fn ellipsoid_hits_lie_on_the_surface_with_gradient_normals() {
    let rotation = Rotation3::from_euler_angles(0.3, -0.2, 0.9);
    let centre = Point3::new(20.0, -15.0, 800.0);
    let semi_axes = Vector3::new(42.0, 38.0, 40.0);
    let shape = Shape::Ellipsoid { centre, rotation, semi_axes_mm: semi_axes };
    let mut hits = 0;
    for ray in rays() {
        if let Some((t, normal)) = shape.intersect(&ray, 0.0) {
            hits += 1;
            let local = rotation.inverse() * (ray.at(t) - centre);
            let level = local.component_div(&semi_axes).norm_squared();
            assert!((level - 1.0).abs() < 1e-9, "off the surface: {level}");
            let gradient = rotation * local.component_div(&semi_axes.component_mul(&semi_axes));
            assert!((normal - gradient.normalize()).norm() < 1e-9);
            // The first hit faces the camera.
            assert!(normal.dot(&ray.direction) < 0.0);
        }
    }
    assert!(hits > 20, "{hits}");
}

fn round_form() -> AppleForm {
    AppleForm {
        taper: 0.0,
        lopsided: 0.0,
        lopsided_axis: [1.0, 0.0, 0.0],
        stem_cavity_depth: 0.0,
        stem_cavity_width_rad: 0.2,
        calyx_cavity_depth: 0.0,
        calyx_cavity_width_rad: 0.2,
    }
}

#[test]
fn an_apple_without_form_is_its_ellipsoid() {
    let rotation = Rotation3::from_euler_angles(0.3, -0.2, 0.9);
    let centre = Point3::new(20.0, -15.0, 800.0);
    let semi_axes_mm = Vector3::new(42.0, 38.0, 40.0);
    let ellipsoid = Shape::Ellipsoid { centre, rotation, semi_axes_mm };
    let apple = Shape::Apple { centre, rotation, semi_axes_mm, form: round_form() };
    let mut hits = 0;
    for ray in rays() {
        let (a, b) = (ellipsoid.intersect(&ray, 0.0), apple.intersect(&ray, 0.0));
        assert_eq!(a.is_some(), b.is_some(), "{ray:?}");
        if let (Some((ta, na)), Some((tb, nb))) = (a, b) {
            hits += 1;
            // Within a micrometre and a microradian.
            assert!((ray.at(ta) - ray.at(tb)).norm() < 1e-3, "{ta} {tb}");
            assert!((na - nb).norm() < 1e-5, "{na} {nb}");
        }
    }
    assert!(hits > 20, "{hits}");
}

#[test]
fn an_apples_stem_cavity_is_a_dimple_and_its_surface_casts_no_shadow_on_itself() {
    // Stem towards the camera (body +z along camera -z).
    let rotation = Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let centre = Point3::new(0.0, 0.0, 800.0);
    let semi_axes_mm = Vector3::repeat(40.0);
    let form = AppleForm { stem_cavity_depth: 0.2, ..round_form() };
    let apple = Shape::Apple { centre, rotation, semi_axes_mm, form };
    let axis = Ray::through_normalized(0.0, 0.0);
    let (t, normal) = apple.intersect(&axis, 0.0).unwrap();
    // 8 mm deep at the pole, the normal facing the camera.
    assert!((axis.at(t).z - (760.0 + 8.0)).abs() < 1e-6, "{}", axis.at(t).z);
    assert!(normal.dot(&Vector3::z()) < -0.999);
    // A ray leaving the surface outward meets nothing; one going in meets
    // the far side.
    let off_axis = Ray::through_normalized(0.02, 0.01);
    let (t, normal) = apple.intersect(&off_axis, 0.0).unwrap();
    let point = off_axis.at(t);
    let out = Ray { origin: point, direction: normal };
    assert!(apple.intersect(&out, 1e-6).is_none());
    let inward = Ray { origin: point, direction: -normal };
    let (t_far, _) = apple.intersect(&inward, 1e-6).unwrap();
    assert!(t_far > 60.0, "{t_far}");
    // The cavity moves the volume centroid away from the stem: by about the
    // dimple's volume (0.2 x 2 pi 0.2^2 of the unit sphere's 4/3 pi) times
    // its distance from the centre, 0.01 of the radius.
    let centroid = form.centroid();
    assert!(centroid.x.abs() < 1e-9 && centroid.y.abs() < 1e-9, "{centroid}");
    assert!((-0.015..-0.007).contains(&centroid.z), "{centroid}");
    assert!(round_form().centroid().norm() < 1e-9);
}

#[test]
fn leaf_and_branch_hits_are_on_their_surfaces() {
    let normal = Unit::new_normalize(Vector3::new(0.1, 0.2, -1.0));
    let along = Unit::new_normalize(normal.cross(&Vector3::x()));
    let leaf = Shape::Leaf {
        centre: Point3::new(0.0, 0.0, 700.0),
        normal,
        along,
        half_length_mm: 40.0,
        half_width_mm: 18.0,
    };
    let branch = Shape::Branch {
        start: Point3::new(-200.0, 30.0, 750.0),
        end: Point3::new(200.0, -20.0, 760.0),
        radius_mm: 10.0,
    };
    let (mut leaf_hits, mut branch_hits) = (0, 0);
    for ray in rays() {
        if let Some((t, _)) = leaf.intersect(&ray, 0.0) {
            leaf_hits += 1;
            let offset = ray.at(t) - Point3::new(0.0, 0.0, 700.0);
            assert!(offset.dot(&normal).abs() < 1e-9);
        }
        if let Some((t, n)) = branch.intersect(&ray, 0.0) {
            branch_hits += 1;
            let (a, b) = (Point3::new(-200.0, 30.0, 750.0), Point3::new(200.0, -20.0, 760.0));
            let axis = (b - a).normalize();
            let p = ray.at(t);
            let radial = (p - a) - axis * (p - a).dot(&axis);
            assert!((radial.norm() - 10.0).abs() < 1e-9);
            assert!((n - radial.normalize()).norm() < 1e-9);
        }
    }
    assert!(leaf_hits > 0 && branch_hits > 0);
}

#[test]
fn scenes_hide_the_requested_fraction_of_the_fruit() {
    for (occlusion, seed) in [(0.0, 1), (0.2, 2), (0.4, 3), (0.4, 4)] {
        let options = OrchardOptions { occlusion, seed, ..OrchardOptions::default() };
        let scene = orchard_scene(&options).unwrap();
        assert_eq!(scene.objects[0].kind, Kind::Fruit);
        // Leaves are added one at a time until the target is reached, overshooting by at most 0.1.
        assert!(
            scene.occlusion >= occlusion && scene.occlusion <= occlusion + 0.1,
            "asked {occlusion}, built {}",
            scene.occlusion
        );
        assert!((35.0..=45.0).contains(&scene.fruit_radius_mm));
        assert!((600.0..=1200.0).contains(&scene.fruit_centre.z));
    }
}

#[test]
fn a_fully_hidden_fruit_is_fully_hidden() {
    let scene =
        orchard_scene(&OrchardOptions { occlusion: 1.0, seed: 5, ..OrchardOptions::default() })
            .unwrap();
    assert_eq!(scene.occlusion, 1.0);
}

#[test]
fn same_seed_same_scene() {
    let options = OrchardOptions { occlusion: 0.3, seed: 9, ..OrchardOptions::default() };
    assert_eq!(orchard_scene(&options).unwrap(), orchard_scene(&options).unwrap());
    let other = OrchardOptions { seed: 10, ..options.clone() };
    assert_ne!(orchard_scene(&options).unwrap(), orchard_scene(&other).unwrap());
}

#[test]
fn shadow_segments_are_blocked_by_objects_between_their_ends() {
    let scene = orchard_scene(&OrchardOptions { seed: 6, ..OrchardOptions::default() }).unwrap();
    let line_of_sight = scene.fruit_centre.coords.normalize();
    let behind = scene.fruit_centre + line_of_sight * scene.fruit_radius_mm * 3.0;
    let in_front = scene.fruit_centre - line_of_sight * scene.fruit_radius_mm * 1.5;
    // The fruit lies between a point behind it and the camera ...
    assert!(scene.segment_blocked(&behind, &Point3::origin()));
    // ... but not between a point in front of it and the camera (nothing hides it).
    assert!(!scene.segment_blocked(&in_front, &Point3::origin()));
}

#[test]
fn invalid_options_are_errors() {
    for options in [
        OrchardOptions { depth_mm: (900.0, 600.0), ..OrchardOptions::default() },
        OrchardOptions { radius_mm: (0.0, 40.0), ..OrchardOptions::default() },
        OrchardOptions { occlusion: 1.5, ..OrchardOptions::default() },
    ] {
        assert!(orchard_scene(&options).is_err());
    }
}

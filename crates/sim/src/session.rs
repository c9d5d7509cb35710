//! Calibration sessions (FORMATS.md): a checkerboard at random poses, each
//! rendered with the laser line at one or more slide positions (and
//! optionally with the laser off), with session.yaml, camera.yaml and the
//! ground truth in truth.json.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use alacs_model::io::OutputDir;
use alacs_model::{Camera, LaserModel, SESSION_FILE, Session};
use image::RgbImage;
use nalgebra::{Isometry3, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{Value, json};

use crate::board::{BoardScene, BoardsScene, Checkerboard};
use crate::error::{MAX_SESSION_VIEWS, check_positive_range, check_scale, check_slides, save_json};
use crate::progress::ImageWriter;
use crate::render::{LaserStripe, RayMap, RenderOptions, Scene, mix_seed};
use crate::samples::random_tilt;
use crate::truth::{checkerboard_to_json, matrix_rows};
use crate::{Error, Result, SlideError, camera_to_json, laser_to_json};

/// How to generate a calibration session. `Default`: 10 poses at 0.6-1.2 m,
/// tilted up to 40 deg, the laser at d = 0, the default board, lights and
/// sensor, full resolution.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionOptions {
    /// Board poses.
    pub n_views: usize,
    /// Slide positions d, mm: each pose is rendered at each of them (the seed
    /// paper's accuracy experiment uses 0, 50, 100, 150, 200).
    pub slides_mm: Vec<f64>,
    /// Range of the board centre's depth, mm.
    pub depth_mm: (f64, f64),
    /// Largest board tilt away from facing the camera, degrees.
    pub max_tilt_deg: f64,
    /// Largest rotation of the board about its own normal, degrees.
    pub max_roll_deg: f64,
    /// Also render each pose with the laser off (`viewNN_off.png`).
    pub laser_off: bool,
    /// Render the camera resized by this factor ([`Camera::scaled`]); camera.yaml
    /// and truth.json hold the camera actually rendered.
    pub scale: f64,
    /// The target.
    pub board: Checkerboard,
    /// Lights, laser look, supersampling and sensor.
    pub render: RenderOptions,
    /// Seed: same seed, same poses and same image bytes.
    pub seed: u64,
    /// Also render every pose from an RGB-D camera's colour camera
    /// (`viewNN_rgbd.png`, session.yaml's `image_rgbd`): what
    /// `alacs calibrate rgbd` takes.
    pub rgbd: Option<RgbdOptions>,
    /// The slide's own error (scale and axis angle); the default is the
    /// seed's perfect slide.
    pub slide: SlideError,
    /// Let the board reach past the image's border, poses anywhere in the
    /// image: a ChArUco board with at least [`MIN_VISIBLE_CORNER_FRACTION`]
    /// of its inner corners inside it, so that the corners cover the image's
    /// edges and corners; a checkerboard with every inner corner at least
    /// [`MIN_CORNER_BORDER_PX`] inside (its white border and outer squares
    /// may be cut, as in photographs taken near the image's edge).
    pub cut_by_border: bool,
    /// A second board in every view, beside the target and nearer the
    /// camera, leaning back 50-70 deg (as a board lying on a table in front
    /// of the target in photographs of real rigs): a distractor for the
    /// board detector that never hides the target's squares around its
    /// inner corners; the laser may cross it and it may shade the target.
    pub second_board: Option<Checkerboard>,
}

/// A second camera beside the ALACS camera: an RGB-D camera's colour camera.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdOptions {
    /// Its camera (rendered as it is, not scaled).
    pub camera: Camera,
    /// Its pose in the ALACS camera frame: `point_in_alacs = alacs_from_rgbd * point_in_rgbd`.
    pub alacs_from_rgbd: Isometry3<f64>,
}

impl RgbdOptions {
    /// A 1280 x 720 colour camera with a 70 deg horizontal field of view
    /// (a RealSense D435's, roughly), no distortion.
    pub fn colour_camera_720p() -> Camera {
        Camera {
            name: "rgbd_colour_720p".into(),
            width_px: 1280,
            height_px: 720,
            fx_px: 910.0,
            fy_px: 910.0,
            cx_px: 639.5,
            cy_px: 359.5,
            skew_px: 0.0,
            distortion: alacs_model::Distortion::PlumbBob([0.0; 5]),
        }
    }
}

impl Default for SessionOptions {
    fn default() -> Self {
        Self {
            n_views: 10,
            slides_mm: vec![0.0],
            depth_mm: (600.0, 1200.0),
            max_tilt_deg: 40.0,
            max_roll_deg: 10.0,
            laser_off: false,
            scale: 1.0,
            board: Checkerboard::default(),
            render: RenderOptions::default(),
            seed: 0,
            rgbd: None,
            slide: SlideError::default(),
            cut_by_border: false,
            second_board: None,
        }
    }
}

impl SessionOptions {
    /// Checks that the options describe a session.
    pub fn validate(&self) -> Result<()> {
        let invalid = |m: String| Err(Error::InvalidOptions(m));
        if self.n_views == 0 || self.n_views > MAX_SESSION_VIEWS {
            return invalid(format!(
                "{} views: a session needs 1 to {MAX_SESSION_VIEWS}",
                self.n_views
            ));
        }
        check_positive_range("depth range", self.depth_mm)?;
        check_slides(&self.slides_mm)?;
        if !(0.0..90.0).contains(&self.max_tilt_deg) {
            return invalid(format!("tilt {} deg must lie in 0..90", self.max_tilt_deg));
        }
        if !(0.0..=180.0).contains(&self.max_roll_deg) {
            return invalid(format!("roll {} deg must lie in 0..180", self.max_roll_deg));
        }
        check_scale(self.scale)?;
        self.slide.validate()?;
        self.board.validate()?;
        if let Some(second) = &self.second_board {
            second.validate()?;
        }
        self.render.validate()
    }
}

/// One image of a session: a board pose seen with the laser at one slide position.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionView {
    /// File name of the image (laser on).
    pub image: String,
    /// File name of the same pose with the laser off, if rendered (shared by
    /// the views of one pose).
    pub image_laser_off: Option<String>,
    /// Slide travel d, mm.
    pub slide_mm: f64,
    /// Index of the board pose (views at several slides share a pose).
    pub pose: usize,
    /// File name of the pose as the RGB-D camera saw it, if rendered
    /// (shared by the views of one pose).
    pub image_rgbd: Option<String>,
    /// The board's true pose.
    pub camera_from_board: Isometry3<f64>,
    /// The second board's true pose ([`SessionOptions::second_board`]).
    pub camera_from_second_board: Option<Isometry3<f64>>,
}

/// A simulated session: the poses and how to render them. Images are
/// rendered on demand ([`SimulatedSession::render_view`]) or while writing
/// ([`SimulatedSession::write`]), never all held in memory.
#[derive(Debug, Clone)]
pub struct SimulatedSession {
    /// The camera rendered (already scaled).
    pub camera: Camera,
    /// The true laser: the laser given, with the slide's k (see [`SlideError`]).
    pub laser: LaserModel,
    /// The slide's own error.
    pub slide: SlideError,
    /// The target.
    pub board: Checkerboard,
    /// The second board in every view, if any.
    pub second_board: Option<Checkerboard>,
    /// How views are rendered.
    pub render: RenderOptions,
    /// The images, pose by pose, each pose at every slide position.
    pub views: Vec<SessionView>,
    /// The seed the session was generated with.
    pub seed: u64,
    /// The RGB-D camera that also saw every pose, if any.
    pub rgbd: Option<RgbdOptions>,
    ray_map: Arc<RayMap>,
    rgbd_ray_map: Option<Arc<RayMap>>,
}

/// Board poses drawn before a view is declared infeasible.
const MAX_POSE_TRIES: usize = 20_000;

/// Points checked along each side of the board's outline: with lens
/// distortion a straight edge between two corners in the image can bow out
/// of it.
const OUTLINE_POINTS_PER_SIDE: usize = 16;

/// Margin the board's outline keeps from the image border, px.
const IMAGE_MARGIN_PX: f64 = 2.0;

/// With [`SessionOptions::cut_by_border`], the fewest of a ChArUco board's
/// inner corners that must lie in the image.
pub const MIN_VISIBLE_CORNER_FRACTION: f64 = 0.4;

/// With [`SessionOptions::cut_by_border`], how far inside the image every
/// inner corner of a checkerboard lies, px (a corner detector needs a few
/// pixels around a corner).
pub const MIN_CORNER_BORDER_PX: f64 = 8.0;

/// The laser line must cross the inner-corner rectangle over at least this
/// fraction of its shorter side, so every view has laser pixels on the squares.
const MIN_LASER_CHORD_FRACTION: f64 = 0.5;

/// Generates a session per `options`: random board poses, each fully in the
/// image (outline inside it, in front of the camera), facing the camera
/// and the laser, with the laser line crossing the board at every slide
/// position. Builds the camera's ray map (the expensive part: about 45 M
/// undistortions for a 5 MP camera at s = 3); rendering happens later.
pub fn simulate_session(
    camera: &Camera,
    laser: &LaserModel,
    options: &SessionOptions,
) -> Result<SimulatedSession> {
    options.validate()?;
    camera.validate()?;
    laser.validate()?;
    let laser = &options.slide.apply(laser);
    laser.validate()?;
    let camera = camera.scaled(options.scale);
    camera.validate().map_err(|e| {
        Error::InvalidOptions(format!("scale {} gives no usable camera: {e}", options.scale))
    })?;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let multi_slide = options.slides_mm.len() > 1;
    let mut views = Vec::new();
    for pose in 0..options.n_views {
        let poses = sample_poses(&camera, laser, options, &mut rng);
        let (camera_from_board, camera_from_second_board) = poses.ok_or_else(|| {
            Error::Infeasible(format!(
                "view {}: no board pose in {MAX_POSE_TRIES} tries puts the {:.0} x {:.0} mm board \
                 fully in the image at {:.0}-{:.0} mm with the laser line across it at slides {:?} mm{}",
                pose + 1,
                options.board.extent_mm().1 - options.board.extent_mm().0,
                options.board.extent_mm().3 - options.board.extent_mm().2,
                options.depth_mm.0,
                options.depth_mm.1,
                options.slides_mm,
                if options.second_board.is_some() {
                    " and room for the second board in front of it, under it, hiding none of its corners"
                } else {
                    ""
                },
            ))
        })?;
        let image_laser_off = options.laser_off.then(|| format!("view{:02}_off.png", pose + 1));
        let image_rgbd = options.rgbd.as_ref().map(|_| format!("view{:02}_rgbd.png", pose + 1));
        for (k, &slide_mm) in options.slides_mm.iter().enumerate() {
            let image = if multi_slide {
                format!("view{:02}_slide{}.png", pose + 1, k + 1)
            } else {
                format!("view{:02}.png", pose + 1)
            };
            views.push(SessionView {
                image,
                image_laser_off: image_laser_off.clone(),
                slide_mm,
                pose,
                image_rgbd: image_rgbd.clone(),
                camera_from_board,
                camera_from_second_board,
            });
        }
    }
    let ray_map = Arc::new(RayMap::with_pattern(
        &camera,
        options.render.supersampling,
        options.render.pattern,
    )?);
    let rgbd_ray_map = match &options.rgbd {
        Some(rgbd) => {
            rgbd.camera.validate()?;
            Some(Arc::new(RayMap::with_pattern(
                &rgbd.camera,
                options.render.supersampling,
                options.render.pattern,
            )?))
        }
        None => None,
    };
    Ok(SimulatedSession {
        camera,
        laser: *laser,
        slide: options.slide,
        board: options.board,
        second_board: options.second_board,
        render: options.render,
        views,
        seed: options.seed,
        rgbd: options.rgbd.clone(),
        ray_map,
        rgbd_ray_map,
    })
}

/// Target poses drawn before a view with a second board is declared
/// infeasible (each gets [`SECOND_BOARD_TRIES`] tries to place the second board).
const SECOND_BOARD_TARGET_TRIES: usize = 50;

/// Second-board poses tried beside one target pose.
const SECOND_BOARD_TRIES: usize = 200;

/// The second board's lean away from facing the camera, degrees: a board
/// lying on a table seen from a camera above and in front of it.
const SECOND_BOARD_LEAN_DEG: (f64, f64) = (50.0, 70.0);

/// The second board's centre depth as a fraction of the target's: nearer
/// the camera, so that it may hide the target's border and outer squares.
const SECOND_BOARD_DEPTH_FRACTION: (f64, f64) = (0.75, 0.95);

/// Draws the target's pose ([`sample_pose`]) and, with
/// [`SessionOptions::second_board`], the second board's beside it; a target
/// pose that leaves the second board no place is drawn again.
fn sample_poses(
    camera: &Camera,
    laser: &LaserModel,
    options: &SessionOptions,
    rng: &mut ChaCha8Rng,
) -> Option<(Isometry3<f64>, Option<Isometry3<f64>>)> {
    let Some(second) = &options.second_board else {
        return sample_pose(camera, laser, options, rng).map(|pose| (pose, None));
    };
    for _ in 0..SECOND_BOARD_TARGET_TRIES {
        let target = sample_pose(camera, laser, options, rng)?;
        if let Some(beside) = sample_second_pose(camera, &options.board, &target, second, rng) {
            return Some((target, Some(beside)));
        }
    }
    None
}

/// A pose of `second` beside the target at `camera_from_board`: its centre
/// in the image under the target and nearer the camera, leaning back, its
/// printed side to the camera, not behind the target, and hiding none of
/// the target's inner corners nor the centres of the four squares around
/// each (what a corner detector needs to see).
fn sample_second_pose(
    camera: &Camera,
    board: &Checkerboard,
    camera_from_board: &Isometry3<f64>,
    second: &Checkerboard,
    rng: &mut ChaCha8Rng,
) -> Option<Isometry3<f64>> {
    let target = BoardScene::new(*board, *camera_from_board);
    let (x0, x1, _, y1) = board.extent_mm();
    let (_, _, second_y0, second_y1) = second.extent_mm();
    let (sx, sy) = board.square_mm;
    let guarded: Vec<Point3<f64>> = board
        .object_points()
        .iter()
        .flat_map(|c| {
            [(0.0, 0.0), (1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)].map(|(a, b)| {
                camera_from_board * Point3::new(c.x + 0.5 * a * sx, c.y + 0.5 * b * sy, 0.0)
            })
        })
        .collect();
    let origin = Point3::origin();
    let (width, height) = (f64::from(camera.width_px), f64::from(camera.height_px));
    for _ in 0..SECOND_BOARD_TRIES {
        // Below the target in its own plane (up to half the second board's
        // height below its lower edge), then towards the camera along that
        // point's ray: in front of the target, under it in the image.
        let below = Point3::new(
            rng.random_range(x0..=x1),
            y1 + rng.random_range(0.0..=0.5) * (second_y1 - second_y0),
            0.0,
        );
        let depth_fraction =
            rng.random_range(SECOND_BOARD_DEPTH_FRACTION.0..=SECOND_BOARD_DEPTH_FRACTION.1);
        let lean = rng.random_range(SECOND_BOARD_LEAN_DEG.0..=SECOND_BOARD_LEAN_DEG.1).to_radians();
        let (heading, roll) = (rng.random_range(-0.35..=0.35), rng.random_range(-0.2..=0.2));
        let centre = Point3::from((camera_from_board * below).coords * depth_fraction);
        let in_image = camera
            .project(&centre)
            .is_ok_and(|p| (0.0..width).contains(&p.x) && (0.0..height).contains(&p.y));
        if !in_image {
            continue;
        }
        // Leaning back: the board's z axis (into it) turns from the optical
        // axis towards +y (down), its near edge at the bottom of the image.
        let rotation = Rotation3::from_axis_angle(&Vector3::y_axis(), heading)
            * Rotation3::from_axis_angle(&Vector3::x_axis(), -lean)
            * Rotation3::from_axis_angle(&Vector3::z_axis(), roll);
        let pose = Isometry3::from_parts(
            Translation3::from(centre - rotation * second.centre_in_board()),
            UnitQuaternion::from_rotation_matrix(&rotation),
        );
        let scene = BoardScene::new(*second, pose);
        let faces_camera = (rotation * Vector3::z()).dot(&centre.coords) > 0.0;
        if faces_camera
            && !target.blocked(&origin, &centre)
            && !guarded.iter().any(|p| scene.blocked(&origin, p))
        {
            return Some(pose);
        }
    }
    None
}

/// Draws board poses until one passes every check of [`simulate_session`].
fn sample_pose(
    camera: &Camera,
    laser: &LaserModel,
    options: &SessionOptions,
    rng: &mut ChaCha8Rng,
) -> Option<Isometry3<f64>> {
    let board = &options.board;
    let (_, _, y0, y1) = board.extent_mm();
    let inner_width_mm = (board.inner_corners.0 as f64 - 1.0) * board.square_mm.0;
    let (slide_min, slide_max) = options
        .slides_mm
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &d| (lo.min(d), hi.max(d)));
    let middle_plane = laser.plane_in_camera((slide_min + slide_max) / 2.0);
    let half_image_height_n = f64::from(camera.height_px) / 2.0 / camera.fy_px;
    for _ in 0..MAX_POSE_TRIES {
        // The board centre: at a random depth, near where the laser plane (at
        // the middle slide) crosses the camera's middle row, shifted sideways
        // by up to 45 % of the inner corners' width so that the boards cover
        // more of the image (the chord check below keeps the line on the squares).
        let z = rng.random_range(options.depth_mm.0..=options.depth_mm.1);
        let normal = &middle_plane.normal;
        let x_laser = (middle_plane.offset_mm - normal.z * z) / normal.x;
        // A board cut by the border may sit anywhere: its centre up to the
        // image's edge.
        let (reach, y_room) = if options.cut_by_border {
            (0.9, z * half_image_height_n)
        } else {
            (0.45, (z * half_image_height_n - (y1 - y0) / 2.0).max(0.0))
        };
        let x = x_laser + rng.random_range(-reach..=reach) * inner_width_mm;
        let y = rng.random_range(-1.0..=1.0) * y_room;
        let rotation = random_tilt(rng, options.max_tilt_deg)
            * Rotation3::from_axis_angle(
                &Vector3::z_axis(),
                rng.random_range(-1.0..=1.0) * options.max_roll_deg.to_radians(),
            );
        let centre_in_camera = Point3::new(x, y, z);
        let translation = centre_in_camera - rotation * board.centre_in_board();
        let camera_from_board = Isometry3::from_parts(
            Translation3::from(translation),
            UnitQuaternion::from_rotation_matrix(&rotation),
        );
        if pose_is_usable(camera, laser, options, &camera_from_board) {
            return Some(camera_from_board);
        }
    }
    None
}

/// Whether a pose shows the whole board, front side, with the laser line
/// across the squares at every slide position.
fn pose_is_usable(
    camera: &Camera,
    laser: &LaserModel,
    options: &SessionOptions,
    camera_from_board: &Isometry3<f64>,
) -> bool {
    let board = &options.board;
    let normal = camera_from_board.rotation * Vector3::z();
    let centre = camera_from_board * board.centre_in_board();
    // The printed side faces the camera: the board's z axis points away from it.
    if normal.dot(&centre.coords) <= 0.0 {
        return false;
    }
    let (width, height) = (f64::from(camera.width_px), f64::from(camera.height_px));
    // Whether a board point is in front of the camera (first) and in the
    // image, `margin` px inside its border (second).
    let in_image = |point_in_board: Point3<f64>, margin: f64| {
        let point = camera_from_board * point_in_board;
        if point.z <= 0.0 {
            return (false, false);
        }
        let normalized = Point2::new(point.x / point.z, point.y / point.z);
        if !camera.is_distortion_invertible_at(&normalized) {
            return (true, false);
        }
        let pixel = camera.normalized_to_pixel(&normalized);
        let inside = pixel.x >= margin - 0.5
            && pixel.x <= width - 0.5 - margin
            && pixel.y >= margin - 0.5
            && pixel.y <= height - 0.5 - margin;
        (true, inside)
    };
    let outline = board.outline_in_board();
    for (k, corner) in outline.iter().enumerate() {
        let next = outline[(k + 1) % 4];
        for i in 0..OUTLINE_POINTS_PER_SIDE {
            let t = i as f64 / OUTLINE_POINTS_PER_SIDE as f64;
            let (in_front, inside) = in_image(corner + (next - corner) * t, IMAGE_MARGIN_PX);
            if !in_front || (!inside && !options.cut_by_border) {
                return false;
            }
        }
    }
    if options.cut_by_border {
        let corners = board.object_points();
        if board.markers.is_some() {
            let visible = corners.iter().filter(|p| in_image(**p, IMAGE_MARGIN_PX).1).count();
            if (visible as f64) < MIN_VISIBLE_CORNER_FRACTION * corners.len() as f64 {
                return false;
            }
        } else if !corners.iter().all(|p| in_image(*p, MIN_CORNER_BORDER_PX).1) {
            return false;
        }
    }
    options
        .slides_mm
        .iter()
        .all(|&slide_mm| laser_crosses_board(laser, slide_mm, board, camera_from_board))
}

/// Whether the laser at `slide_mm` lights the board's front side along a
/// chord of the inner-corner rectangle at least [`MIN_LASER_CHORD_FRACTION`]
/// of its shorter side long.
fn laser_crosses_board(
    laser: &LaserModel,
    slide_mm: f64,
    board: &Checkerboard,
    camera_from_board: &Isometry3<f64>,
) -> bool {
    let normal = camera_from_board.rotation * Vector3::z();
    let origin = laser.origin_in_camera(slide_mm);
    let on_board = camera_from_board.translation.vector;
    // The laser origin must be on the camera's side of the board (the printed side).
    if normal.dot(&(origin.coords - on_board)) >= 0.0 {
        return false;
    }
    // The laser plane in board coordinates (z = 0): a x + b y = e.
    let plane = laser.plane_in_camera(slide_mm);
    let in_board = camera_from_board.rotation.inverse() * plane.normal;
    let (a, b) = (in_board.x, in_board.y);
    let e = plane.offset_mm - plane.normal.dot(&on_board);
    let norm = a.hypot(b);
    if norm < 1e-12 {
        return false;
    }
    let (cols, rows) = board.inner_corners;
    let (sx, sy) = board.square_mm;
    let (w, h) = ((cols as f64 - 1.0) * sx, (rows as f64 - 1.0) * sy);
    let chord = clip_line_to_rectangle(a / norm, b / norm, e / norm, w, h);
    chord >= MIN_LASER_CHORD_FRACTION * w.min(h)
}

/// Length of the line `a x + b y = e` (a, b a unit normal) inside the
/// rectangle [0, w] x [0, h] (Liang-Barsky clipping).
fn clip_line_to_rectangle(a: f64, b: f64, e: f64, w: f64, h: f64) -> f64 {
    let (px, py) = (a * e, b * e);
    let (dx, dy) = (-b, a);
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for (p, d, lo, hi) in [(px, dx, 0.0, w), (py, dy, 0.0, h)] {
        if d.abs() < 1e-15 {
            if p < lo || p > hi {
                return 0.0;
            }
            continue;
        }
        let (ta, tb) = ((lo - p) / d, (hi - p) / d);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    (t1 - t0).max(0.0)
}

/// Noise stream of the laser-off image of a pose (laser-on images use their view index).
const LASER_OFF_STREAM: u64 = 1 << 32;

/// Seed stream of the RGB-D camera's images (one per pose).
const RGBD_STREAM: u64 = 1 << 33;

impl SimulatedSession {
    /// The camera's ray map (computed once, shared by every view).
    pub fn ray_map(&self) -> &RayMap {
        &self.ray_map
    }

    /// The target board's scene of view `index`'s pose (without the second board).
    pub fn scene(&self, index: usize) -> Result<BoardScene> {
        let view = self.view(index)?;
        Ok(BoardScene::new(self.board, view.camera_from_board))
    }

    /// Everything view `index` shows, as seen from a camera at
    /// `camera_from_alacs` (the identity for the ALACS camera): the target
    /// and the second board, if the session has one.
    fn view_scene(&self, index: usize, camera_from_alacs: &Isometry3<f64>) -> Result<BoardsScene> {
        let view = self.view(index)?;
        let mut boards =
            vec![BoardScene::new(self.board, camera_from_alacs * view.camera_from_board)];
        if let (Some(second), Some(pose)) = (self.second_board, view.camera_from_second_board) {
            boards.push(BoardScene::new(second, camera_from_alacs * pose));
        }
        Ok(BoardsScene::new(boards))
    }

    /// The laser stripe of view `index`.
    pub fn laser_stripe(&self, index: usize) -> Result<LaserStripe> {
        let view = self.view(index)?;
        let mut stripe =
            LaserStripe::new(&self.laser, view.slide_mm, &self.render.laser, self.camera.fx_px);
        stripe.origin = self.slide.origin_in_camera(&self.laser, view.slide_mm);
        Ok(stripe)
    }

    fn view(&self, index: usize) -> Result<&SessionView> {
        self.views.get(index).ok_or_else(|| {
            Error::InvalidOptions(format!(
                "view {index} does not exist (the session has {})",
                self.views.len()
            ))
        })
    }

    /// Renders view `index` with the laser on.
    pub fn render_view(&self, index: usize) -> Result<RgbImage> {
        let scene = self.view_scene(index, &Isometry3::identity())?;
        let stripe = self.laser_stripe(index)?;
        let seed = mix_seed(self.seed, index as u64);
        Ok(self.ray_map.render(
            &scene,
            &self.render.lighting,
            Some(&stripe),
            &self.render.sensor,
            seed,
        ))
    }

    /// Renders view `index`'s pose with the laser off (its own sensor noise).
    pub fn render_laser_off(&self, index: usize) -> Result<RgbImage> {
        let scene = self.view_scene(index, &Isometry3::identity())?;
        let pose = self.view(index)?.pose as u64;
        let seed = mix_seed(self.seed, LASER_OFF_STREAM + pose);
        Ok(self.ray_map.render(&scene, &self.render.lighting, None, &self.render.sensor, seed))
    }

    /// Renders view `index`'s pose as the RGB-D camera sees it (laser off:
    /// its own sensor noise), if the session has one.
    pub fn render_rgbd(&self, index: usize) -> Result<Option<RgbImage>> {
        let (Some(rgbd), Some(ray_map)) = (&self.rgbd, &self.rgbd_ray_map) else {
            return Ok(None);
        };
        let view = self.view(index)?;
        let scene = self.view_scene(index, &rgbd.alacs_from_rgbd.inverse())?;
        let seed = mix_seed(self.seed, RGBD_STREAM + view.pose as u64);
        Ok(Some(ray_map.render(&scene, &self.render.lighting, None, &self.render.sensor, seed)))
    }

    /// session.yaml (FORMATS.md).
    pub fn session_yaml(&self) -> String {
        let session = Session {
            dir: PathBuf::new(),
            board: self.board.spec(),
            views: self
                .views
                .iter()
                .map(|v| alacs_model::SessionView {
                    image: PathBuf::from(&v.image),
                    slide_mm: v.slide_mm,
                    image_laser_off: v.image_laser_off.as_ref().map(PathBuf::from),
                    image_rgbd: v.image_rgbd.as_ref().map(PathBuf::from),
                })
                .collect(),
        };
        session.to_yaml_string(&format!(
            "Simulated by alacs-sim (seed {}); ground truth in truth.json.",
            self.seed
        ))
    }

    /// truth.json (FORMATS.md): the camera rendered, the laser, the board and
    /// each view's `camera_from_board` (4 x 4, row-major, translation in mm).
    pub fn truth_json(&self) -> Value {
        let views: Vec<Value> = self
            .views
            .iter()
            .map(|view| {
                let mut entry = json!({
                    "image": view.image,
                    "slide_mm": view.slide_mm,
                    "pose": view.pose,
                    "camera_from_board": matrix_rows(&view.camera_from_board),
                });
                if let (Some(off), Some(map)) = (&view.image_laser_off, entry.as_object_mut()) {
                    map.insert("image_laser_off".into(), json!(off));
                }
                if let (Some(pose), Some(map)) =
                    (view.camera_from_second_board, entry.as_object_mut())
                {
                    map.insert("camera_from_second_board".into(), json!(matrix_rows(&pose)));
                }
                entry
            })
            .collect();
        let rgbd = self.rgbd.as_ref().map(|rgbd| {
            json!({"camera": camera_to_json(&rgbd.camera), "alacs_from_rgbd": matrix_rows(&rgbd.alacs_from_rgbd)})
        });
        json!({
            "rgbd": rgbd,
            "camera": camera_to_json(&self.camera),
            "laser": laser_to_json(&self.laser),
            "slide": self.slide.to_json(),
            "board": checkerboard_to_json(&self.board),
            "second_board": self.second_board.as_ref().map(checkerboard_to_json),
            "seed": self.seed,
            "supersampling": self.render.supersampling,
            "stripe_sigma_px": self.render.laser.stripe_sigma_px,
            "views": views,
        })
    }

    /// How many images [`SimulatedSession::write`] renders and writes: each
    /// view, plus one laser-off image per pose that has one.
    pub fn image_count(&self) -> usize {
        let mut poses_off: Vec<usize> =
            self.views.iter().filter(|v| v.image_laser_off.is_some()).map(|v| v.pose).collect();
        poses_off.dedup();
        let mut poses_rgbd: Vec<usize> =
            self.views.iter().filter(|v| v.image_rgbd.is_some()).map(|v| v.pose).collect();
        poses_rgbd.dedup();
        self.views.len() + poses_off.len() + poses_rgbd.len()
    }

    /// Writes session.yaml, camera.yaml, truth.json and every image (PNG,
    /// RGB8) into `dir`, creating it ([`OutputDir`]: a folder holding files
    /// this did not write is refused).
    pub fn write(&self, dir: &Path) -> Result<()> {
        self.write_with_progress(dir, |_, _| {})
    }

    /// [`SimulatedSession::write`], calling `progress(done, total)` after
    /// each image.
    pub fn write_with_progress(
        &self,
        dir: &Path,
        progress: impl FnMut(usize, usize),
    ) -> Result<()> {
        OutputDir::fill(dir, "simulate session", false, |out| self.write_into(out, progress))
            .map(drop)
    }

    /// [`SimulatedSession::write_with_progress`] into an open output folder
    /// (the caller may add files and then finishes it).
    pub fn write_into(
        &self,
        out: &mut OutputDir,
        progress: impl FnMut(usize, usize),
    ) -> Result<()> {
        let mut images = ImageWriter::new(out, self.image_count(), None, progress);
        let mut last_off_pose = None;
        let mut last_rgbd_pose = None;
        for (index, view) in self.views.iter().enumerate() {
            images.save(&view.image, &self.render_view(index)?)?;
            if let Some(off) = &view.image_laser_off
                && last_off_pose != Some(view.pose)
            {
                images.save(off, &self.render_laser_off(index)?)?;
                last_off_pose = Some(view.pose);
            }
            if let Some(name) = &view.image_rgbd
                && last_rgbd_pose != Some(view.pose)
                && let Some(image) = self.render_rgbd(index)?
            {
                images.save(name, &image)?;
                last_rgbd_pose = Some(view.pose);
            }
        }
        out.write(SESSION_FILE, self.session_yaml())?;
        out.write("camera.yaml", self.camera.to_yaml_string())?;
        if let Some(rgbd) = &self.rgbd {
            out.write("rgbd_camera.yaml", rgbd.camera.to_yaml_string())?;
        }
        save_json(out, "truth.json", &self.truth_json())
    }
}

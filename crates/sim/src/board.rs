//! The checkerboard calibration target and a scene of one board at a pose.
//!
//! The board frame is OpenCV's (FORMATS.md): origin at the first inner
//! corner, x along a row, y down the columns, z into the board; the inner
//! corners are at (col * square_x, row * square_y, 0). As in OpenCV's
//! pattern, the square at the top-left of the board (up and left of the
//! origin) is black, and a white border surrounds the squares.
//!
//! A ChArUco board ([`Checkerboard::markers`]) carries an ArUco marker in
//! every white square, laid out and numbered as OpenCV lays them out
//! ([`BoardSpec::marker_cell_at`], the model's one copy of that layout), its
//! bits from calib-targets' copy of OpenCV's dictionaries (a bit of 1 is
//! black), with a black border ring of one cell.

use std::sync::OnceLock;

use alacs_model::{ArucoDictionary, BoardSpec, CharucoMarkers, Ray};
use nalgebra::{Isometry3, Point3, Vector3};

use crate::render::{Scene, SurfaceHit};
use crate::{Error, Result};

/// A printed checkerboard: `(cols + 1) x (rows + 1)` squares around
/// `cols x rows` inner corners, in a white border.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Checkerboard {
    /// Inner corners `(cols, rows)`: along x (a row) and along y (a column).
    pub inner_corners: (usize, usize),
    /// Square size along x and along y, mm.
    pub square_mm: (f64, f64),
    /// Width of the white border around the squares, mm.
    pub border_mm: f64,
    /// Albedo of the black squares (all channels and the laser's red).
    pub black_reflectance: f64,
    /// Albedo of the white squares and the border (all channels and the laser's red).
    pub white_reflectance: f64,
    /// The markers of a ChArUco board; `None` for a plain checkerboard.
    pub markers: Option<CharucoMarkers>,
}

impl Default for Checkerboard {
    /// 11 x 8 inner corners of 30 mm squares with a 30 mm border: a
    /// 420 x 330 mm board, which fills a good part of the 5 MP camera's view
    /// at 0.6-1.2 m (the image is 630 x 530 mm at 0.6 m).
    fn default() -> Self {
        Self {
            inner_corners: (11, 8),
            square_mm: (30.0, 30.0),
            border_mm: 30.0,
            black_reflectance: 0.05,
            white_reflectance: 0.85,
            markers: None,
        }
    }
}

/// The marker codes of a dictionary (one `u64` a marker, bits row-major,
/// 1 black), looked up once per dictionary: the renderer asks for every
/// sub-pixel ray.
fn marker_codes(dictionary: ArucoDictionary) -> &'static [u64] {
    static TABLE: OnceLock<Vec<&'static [u64]>> = OnceLock::new();
    let table = TABLE.get_or_init(|| {
        ArucoDictionary::ALL
            .iter()
            .map(|d| {
                calib_targets_aruco::builtins::builtin_dictionary(d.as_str())
                    .filter(|found| found.marker_size() == d.marker_bits())
                    .map_or(&[][..], |found| found.codes())
            })
            .collect()
    });
    let index = ArucoDictionary::ALL.iter().position(|d| *d == dictionary).unwrap_or(usize::MAX);
    table.get(index).copied().unwrap_or(&[])
}

/// A ChArUco marker's side per square side in [`Checkerboard::charuco`]
/// (OpenCV's examples use 0.5-0.8).
pub const CHARUCO_MARKER_PER_SQUARE: f64 = 0.75;

impl Checkerboard {
    /// The default board as a ChArUco board: markers of `dictionary`, each
    /// [`CHARUCO_MARKER_PER_SQUARE`] of a square.
    pub fn charuco(dictionary: ArucoDictionary) -> Checkerboard {
        let board = Checkerboard::default();
        let marker_mm = CHARUCO_MARKER_PER_SQUARE * board.square_mm.0.min(board.square_mm.1);
        Checkerboard { markers: Some(CharucoMarkers { marker_mm, dictionary }), ..board }
    }

    /// A second board for [`crate::SessionOptions::second_board`] beside
    /// `target`: 6 x 4 inner corners of 30 mm squares, another size than the
    /// default target so that only one of them is the board asked for (as
    /// the ChArUco board lying in front of the target in the real
    /// photographs of issue 42). Its markers are DICT_5X5_100, or
    /// DICT_4X4_50 where the target's markers are 5 x 5 bits (OpenCV's
    /// 5 x 5 dictionaries share their first codes), so that no marker is on
    /// both boards.
    pub fn second_charuco(target: &Checkerboard) -> Checkerboard {
        let dictionary = match target.markers {
            Some(m) if m.dictionary.marker_bits() == 5 => ArucoDictionary::Dict4x4_50,
            _ => ArucoDictionary::Dict5x5_100,
        };
        Checkerboard { inner_corners: (6, 4), ..Checkerboard::charuco(dictionary) }
    }

    /// Checks that the board is printable: at least 2 x 2 inner corners,
    /// positive squares, a non-negative border, reflectances in 0..1.
    pub fn validate(&self) -> Result<()> {
        let invalid = |m: String| Err(Error::InvalidOptions(m));
        let (cols, rows) = self.inner_corners;
        if cols < 2 || rows < 2 {
            return invalid(format!(
                "board needs at least 2 x 2 inner corners, got {cols} x {rows}"
            ));
        }
        let (sx, sy) = self.square_mm;
        if !(sx > 0.0 && sy > 0.0 && sx.is_finite() && sy.is_finite()) {
            return invalid(format!("square size {sx} x {sy} mm must be positive"));
        }
        if !(self.border_mm >= 0.0 && self.border_mm.is_finite()) {
            return invalid(format!("board border {} mm must be non-negative", self.border_mm));
        }
        for (name, value) in [("black", self.black_reflectance), ("white", self.white_reflectance)]
        {
            if !(0.0..=1.0).contains(&value) {
                return invalid(format!("{name} reflectance {value} must lie in 0..1"));
            }
        }
        self.spec().check_markers().or_else(|m| invalid(format!("ChArUco board: {m}")))
    }

    /// The board as session.yaml describes it.
    pub fn spec(&self) -> BoardSpec {
        let (cols, rows) = self.inner_corners;
        let (sx, sy) = self.square_mm;
        BoardSpec { markers: self.markers, ..BoardSpec::checkerboard(cols, rows, sx, sy) }
    }

    /// The inner corners in OpenCV's order (row-major from the top-left), in
    /// the board frame: `(col * square_x, row * square_y, 0)`, mm.
    pub fn object_points(&self) -> Vec<Point3<f64>> {
        let (cols, rows) = self.inner_corners;
        let (sx, sy) = self.square_mm;
        (0..rows)
            .flat_map(|row| {
                (0..cols).map(move |col| Point3::new(col as f64 * sx, row as f64 * sy, 0.0))
            })
            .collect()
    }

    /// The board's centre (the middle of the inner corners), board frame, mm.
    pub fn centre_in_board(&self) -> Point3<f64> {
        let (cols, rows) = self.inner_corners;
        let (sx, sy) = self.square_mm;
        Point3::new((cols as f64 - 1.0) * sx / 2.0, (rows as f64 - 1.0) * sy / 2.0, 0.0)
    }

    /// The squares' extent `(x_min, x_max, y_min, y_max)` in the board frame, mm.
    pub fn squares_extent_mm(&self) -> (f64, f64, f64, f64) {
        let (cols, rows) = self.inner_corners;
        let (sx, sy) = self.square_mm;
        (-sx, cols as f64 * sx, -sy, rows as f64 * sy)
    }

    /// The whole board's extent, border included, `(x_min, x_max, y_min, y_max)`, mm.
    pub fn extent_mm(&self) -> (f64, f64, f64, f64) {
        let (x0, x1, y0, y1) = self.squares_extent_mm();
        let b = self.border_mm;
        (x0 - b, x1 + b, y0 - b, y1 + b)
    }

    /// The four outer corners of the board (border included), board frame,
    /// clockwise from the top-left as seen from the front.
    pub fn outline_in_board(&self) -> [Point3<f64>; 4] {
        let (x0, x1, y0, y1) = self.extent_mm();
        [
            Point3::new(x0, y0, 0.0),
            Point3::new(x1, y0, 0.0),
            Point3::new(x1, y1, 0.0),
            Point3::new(x0, y1, 0.0),
        ]
    }

    /// The reflectance of the printed side at board coordinates (x, y), mm;
    /// None off the board.
    #[inline]
    pub fn reflectance_at(&self, x_mm: f64, y_mm: f64) -> Option<f64> {
        let (x0, x1, y0, y1) = self.extent_mm();
        if !(x0..=x1).contains(&x_mm) || !(y0..=y1).contains(&y_mm) {
            return None;
        }
        let (cols, rows) = self.inner_corners;
        let (sx, sy) = self.square_mm;
        // Square (i, j), 0-based from the top-left square (i = 0 is x in [-sx, 0)).
        // x and y are bounded by the board's extent here, so the casts are exact.
        let i = floor_to_i64(x_mm / sx) + 1;
        let j = floor_to_i64(y_mm / sy) + 1;
        let on_squares = (0..=cols as i64).contains(&i) && (0..=rows as i64).contains(&j);
        // The top-left square (0, 0) is black, as in OpenCV's pattern.
        let black = on_squares && ((i + j) % 2 == 0 || self.marker_is_black_at(x_mm, y_mm));
        Some(if black { self.black_reflectance } else { self.white_reflectance })
    }
}

impl Checkerboard {
    /// Whether a ChArUco marker is black at board point (x, y), mm: its
    /// border ring, or a bit of 1.
    fn marker_is_black_at(&self, x_mm: f64, y_mm: f64) -> bool {
        let Some(markers) = self.markers else { return false };
        let Some((id, cell_x, cell_y)) = self.spec().marker_cell_at(x_mm, y_mm) else {
            return false;
        };
        let bits = markers.dictionary.marker_bits();
        let (cx, cy) = (cell_x.floor() as usize, cell_y.floor() as usize);
        if cx == 0 || cy == 0 || cx > bits || cy > bits {
            return true;
        }
        let code = marker_codes(markers.dictionary).get(id).copied().unwrap_or(0);
        (code >> ((cy - 1) * bits + (cx - 1))) & 1 == 1
    }
}

/// floor(x) as an integer for |x| well inside i64's range, without a libm
/// call (the renderer calls this for every sub-pixel ray).
fn floor_to_i64(x: f64) -> i64 {
    // `as` truncates towards zero (and saturates); step down for negatives.
    let truncated = x as i64;
    if (truncated as f64) > x { truncated - 1 } else { truncated }
}

/// A scene of one checkerboard at `camera_from_board`: the printed side
/// faces the camera when the board's z axis points away from it. The back
/// of the board is unprinted (white).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardScene {
    board: Checkerboard,
    camera_from_board: Isometry3<f64>,
    /// Board z axis in the camera frame (the plane's normal).
    normal_in_camera: Vector3<f64>,
    /// normal · p for points p on the board, mm.
    offset_mm: f64,
    /// The board's x and y axes in the camera frame (rows of board_from_camera's rotation).
    x_axis_in_camera: Vector3<f64>,
    y_axis_in_camera: Vector3<f64>,
    /// Board coordinates of the camera centre projected on the axes: x_axis · T, y_axis · T.
    x_of_translation: f64,
    y_of_translation: f64,
}

/// Segment parameters within this of an end (relative) do not block: the
/// shaded point itself lies on the board.
const SEGMENT_END_TOLERANCE: f64 = 1e-9;

impl BoardScene {
    /// The board at a pose (`point_in_camera = camera_from_board * point_in_board`).
    pub fn new(board: Checkerboard, camera_from_board: Isometry3<f64>) -> BoardScene {
        let rotation = camera_from_board.rotation.to_rotation_matrix();
        let normal_in_camera = rotation * Vector3::z();
        let x_axis_in_camera = rotation * Vector3::x();
        let y_axis_in_camera = rotation * Vector3::y();
        let translation = camera_from_board.translation.vector;
        BoardScene {
            board,
            camera_from_board,
            normal_in_camera,
            offset_mm: normal_in_camera.dot(&translation),
            x_axis_in_camera,
            y_axis_in_camera,
            x_of_translation: x_axis_in_camera.dot(&translation),
            y_of_translation: y_axis_in_camera.dot(&translation),
        }
    }

    /// The board.
    pub fn board(&self) -> &Checkerboard {
        &self.board
    }

    /// The board's pose.
    pub fn camera_from_board(&self) -> &Isometry3<f64> {
        &self.camera_from_board
    }

    /// Board coordinates (x, y) of a camera-frame point on the board plane.
    #[inline]
    fn board_xy(&self, point_in_camera: &Point3<f64>) -> (f64, f64) {
        (
            self.x_axis_in_camera.dot(&point_in_camera.coords) - self.x_of_translation,
            self.y_axis_in_camera.dot(&point_in_camera.coords) - self.y_of_translation,
        )
    }

    /// Where the line `origin + t direction` crosses the board plane, if it does.
    #[inline]
    fn plane_parameter(&self, origin: &Point3<f64>, direction: &Vector3<f64>) -> Option<f64> {
        let along = self.normal_in_camera.dot(direction);
        let t = (self.offset_mm - self.normal_in_camera.dot(&origin.coords)) / along;
        t.is_finite().then_some(t)
    }

    /// The hit at `point` (on the plane), seen along `direction`.
    #[inline]
    fn hit(&self, point: Point3<f64>, direction: &Vector3<f64>) -> Option<SurfaceHit> {
        let (x, y) = self.board_xy(&point);
        let printed = self.board.reflectance_at(x, y)?;
        let front = self.normal_in_camera.dot(direction) > 0.0;
        let (reflectance, normal) = if front {
            (printed, -self.normal_in_camera)
        } else {
            (self.board.white_reflectance, self.normal_in_camera)
        };
        Some(SurfaceHit {
            point,
            normal,
            albedo_rgb: [reflectance; 3],
            laser_reflectance: reflectance,
            // A printed board is matte.
            specular: 0.0,
            shininess: 1.0,
            translucent: false,
        })
    }
}

impl Scene for BoardScene {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<SurfaceHit> {
        let t = self.plane_parameter(&ray.origin, &ray.direction)?;
        if t <= 0.0 {
            return None;
        }
        self.hit(ray.origin + ray.direction * t, &ray.direction)
    }

    #[inline]
    fn intersect_camera_ray(&self, x_n: f64, y_n: f64) -> Option<SurfaceHit> {
        // The same as intersect() for a ray from the origin, without the
        // generic origin terms.
        let direction = Vector3::new(x_n, y_n, 1.0);
        let t = self.offset_mm / self.normal_in_camera.dot(&direction);
        if !(t > 0.0 && t.is_finite()) {
            return None;
        }
        self.hit(Point3::from(direction * t), &direction)
    }

    fn blocked(&self, from: &Point3<f64>, to: &Point3<f64>) -> bool {
        let Some(s) = self.plane_parameter(from, &(to - from)) else { return false };
        if !(SEGMENT_END_TOLERANCE..1.0 - SEGMENT_END_TOLERANCE).contains(&s) {
            return false;
        }
        let crossing = from + (to - from) * s;
        let (x, y) = self.board_xy(&crossing);
        self.board.reflectance_at(x, y).is_some()
    }
}

/// Boards in one view: the calibration target and, where a session has one,
/// a second board beside it (a distractor for the board detector, as a
/// ChArUco board lying in front of a checkerboard in photographs of real
/// rigs). Each ray meets the nearest board; every board casts shadows.
#[derive(Debug, Clone, PartialEq)]
pub struct BoardsScene {
    boards: Vec<BoardScene>,
}

impl BoardsScene {
    /// The boards of one view (the nearest hit wins where they overlap).
    pub fn new(boards: Vec<BoardScene>) -> BoardsScene {
        BoardsScene { boards }
    }
}

impl Scene for BoardsScene {
    fn intersect(&self, ray: &Ray) -> Option<SurfaceHit> {
        let along = |hit: &SurfaceHit| (hit.point - ray.origin).dot(&ray.direction);
        self.boards
            .iter()
            .filter_map(|b| b.intersect(ray))
            .min_by(|a, b| along(a).total_cmp(&along(b)))
    }

    #[inline]
    fn intersect_camera_ray(&self, x_n: f64, y_n: f64) -> Option<SurfaceHit> {
        // Camera rays run along +z from the origin: the nearest hit has the least z.
        let mut nearest: Option<SurfaceHit> = None;
        for board in &self.boards {
            if let Some(hit) = board.intersect_camera_ray(x_n, y_n)
                && nearest.as_ref().is_none_or(|n| hit.point.z < n.point.z)
            {
                nearest = Some(hit);
            }
        }
        nearest
    }

    fn blocked(&self, from: &Point3<f64>, to: &Point3<f64>) -> bool {
        self.boards.iter().any(|b| b.blocked(from, to))
    }
}

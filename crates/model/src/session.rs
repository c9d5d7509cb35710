//! session.yaml (FORMATS.md): a calibration session, a checkerboard and the
//! views taken of it, each with the slide position of its laser line.
//!
//! ```yaml
//! board: {inner_corners: [9, 6], square_mm: 25.0}   # columns, rows
//! views:
//!   - image: view01.png
//!     slide_mm: 0.0
//!     image_laser_off: view01_off.png   # optional
//! ```
//!
//! `square_mm` may be one number or `[along_x, along_y]`; `slide_mm` may be
//! left out (0). A ChArUco board adds its markers' side and dictionary:
//! `board: {squares: [10, 7], square_mm: 25.0, marker_mm: 18.75, dictionary:
//! DICT_5X5_100}` (`squares` across and down, as OpenCV counts them, or
//! `inner_corners`). Image paths are relative to the folder that holds
//! session.yaml. Unknown keys are ignored.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// The largest board square accepted, mm: a 1 m square is beyond any
/// calibration board a camera at 0.5-2 m sees whole.
pub const MAX_SQUARE_MM: f64 = 1000.0;

/// The fewest and most inner corners a board has along either side: two
/// make the smallest grid with a square between corners; a thousand is far
/// beyond any printed board (a bound, so a typing error is caught).
pub const INNER_CORNERS_RANGE: std::ops::RangeInclusive<usize> = 2..=1000;

/// The session file's name inside a session folder.
pub const SESSION_FILE: &str = "session.yaml";

/// A calibration board: a checkerboard, or a ChArUco board (a checkerboard
/// with an ArUco marker in each white square, so that a view showing only
/// part of it still labels its corners).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardSpec {
    /// Inner corners per row (columns), as passed to OpenCV; a ChArUco
    /// board's squares across are `cols + 1`.
    pub cols: usize,
    /// Inner corners per column (rows).
    pub rows: usize,
    /// Square size along the board's x axis (along a row).
    pub square_x_mm: f64,
    /// Square size along the board's y axis (down a column).
    pub square_y_mm: f64,
    /// The markers of a ChArUco board; `None` for a plain checkerboard.
    pub markers: Option<CharucoMarkers>,
}

/// The ArUco markers of a ChArUco board, laid out as OpenCV (4.6 and later)
/// does: the top-left square is black, a marker sits in the middle of each
/// white square, numbered 0, 1, ... row by row from the top-left.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CharucoMarkers {
    /// A marker's side, mm (OpenCV's `markerLength`), black border included.
    pub marker_mm: f64,
    /// The dictionary the markers come from.
    pub dictionary: ArucoDictionary,
}

macro_rules! aruco_dictionaries {
    ($($variant:ident = $name:literal, $bits:literal, $size:literal;)*) => {
        /// OpenCV's predefined ArUco and AprilTag dictionaries, by OpenCV's
        /// names (`cv::aruco::PredefinedDictionaryType`).
        #[derive(Debug, Clone, Copy, PartialEq, Eq)]
        #[allow(non_camel_case_types, missing_docs)]
        pub enum ArucoDictionary { $($variant),* }

        impl ArucoDictionary {
            /// Every dictionary, in OpenCV's order.
            pub const ALL: &'static [ArucoDictionary] = &[$(ArucoDictionary::$variant),*];

            /// OpenCV's name, e.g. `DICT_5X5_100`.
            pub fn as_str(self) -> &'static str {
                match self { $(ArucoDictionary::$variant => $name),* }
            }

            /// Bits along a marker's side, border excluded.
            pub fn marker_bits(self) -> usize {
                match self { $(ArucoDictionary::$variant => $bits),* }
            }

            /// Number of markers in the dictionary.
            pub fn size(self) -> usize {
                match self { $(ArucoDictionary::$variant => $size),* }
            }
        }
    };
}

aruco_dictionaries! {
    Dict4x4_50 = "DICT_4X4_50", 4, 50;
    Dict4x4_100 = "DICT_4X4_100", 4, 100;
    Dict4x4_250 = "DICT_4X4_250", 4, 250;
    Dict4x4_1000 = "DICT_4X4_1000", 4, 1000;
    Dict5x5_50 = "DICT_5X5_50", 5, 50;
    Dict5x5_100 = "DICT_5X5_100", 5, 100;
    Dict5x5_250 = "DICT_5X5_250", 5, 250;
    Dict5x5_1000 = "DICT_5X5_1000", 5, 1000;
    Dict6x6_50 = "DICT_6X6_50", 6, 50;
    Dict6x6_100 = "DICT_6X6_100", 6, 100;
    Dict6x6_250 = "DICT_6X6_250", 6, 250;
    Dict6x6_1000 = "DICT_6X6_1000", 6, 1000;
    Dict7x7_50 = "DICT_7X7_50", 7, 50;
    Dict7x7_100 = "DICT_7X7_100", 7, 100;
    Dict7x7_250 = "DICT_7X7_250", 7, 250;
    Dict7x7_1000 = "DICT_7X7_1000", 7, 1000;
    ArucoOriginal = "DICT_ARUCO_ORIGINAL", 5, 1024;
    AprilTag16h5 = "DICT_APRILTAG_16h5", 4, 30;
    AprilTag25h9 = "DICT_APRILTAG_25h9", 5, 35;
    AprilTag36h10 = "DICT_APRILTAG_36h10", 6, 2320;
    AprilTag36h11 = "DICT_APRILTAG_36h11", 6, 587;
    ArucoMip36h12 = "DICT_ARUCO_MIP_36h12", 6, 250;
}

impl ArucoDictionary {
    /// The dictionary of an OpenCV name (`DICT_5X5_100`; the `DICT_` prefix
    /// may be left out, letters in any case).
    pub fn from_name(name: &str) -> Option<ArucoDictionary> {
        let upper = name.trim().to_ascii_uppercase();
        let prefixed = if upper.starts_with("DICT_") { upper } else { format!("DICT_{upper}") };
        Self::ALL.iter().copied().find(|d| d.as_str().to_ascii_uppercase() == prefixed)
    }
}

impl ArucoDictionary {
    /// [`ArucoDictionary::from_name`], or an error that names `name` and
    /// lists the dictionaries.
    pub fn parse(name: &str) -> std::result::Result<ArucoDictionary, String> {
        Self::from_name(name).ok_or_else(|| {
            format!(
                "{name:?} is not one of OpenCV's dictionaries ({})",
                Self::ALL.iter().map(|d| d.as_str()).collect::<Vec<_>>().join(", ")
            )
        })
    }
}

impl std::fmt::Display for ArucoDictionary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl BoardSpec {
    /// A plain checkerboard.
    pub fn checkerboard(cols: usize, rows: usize, square_x_mm: f64, square_y_mm: f64) -> Self {
        BoardSpec { cols, rows, square_x_mm, square_y_mm, markers: None }
    }

    /// Number of inner corners.
    pub fn corner_count(&self) -> usize {
        self.cols * self.rows
    }

    /// Inner corner `index` (OpenCV's row-major order) in the board frame:
    /// `(col * square_x, row * square_y, 0)`. (OpenCV's ChArUco object
    /// points are the same corners one square further right and down: its
    /// origin is the board's outer corner.)
    pub fn corner_in_board(&self, index: usize) -> nalgebra::Point3<f64> {
        let (col, row) = (index % self.cols, index / self.cols);
        nalgebra::Point3::new(col as f64 * self.square_x_mm, row as f64 * self.square_y_mm, 0.0)
    }

    /// Checks a ChArUco board's markers (a checkerboard passes): each
    /// smaller than a square, and a dictionary with a marker for every
    /// white square. The error names the key (`marker_mm`, `dictionary`).
    pub fn check_markers(&self) -> std::result::Result<(), String> {
        let Some(CharucoMarkers { marker_mm, dictionary }) = self.markers else {
            return Ok(());
        };
        let square_mm = self.square_x_mm.min(self.square_y_mm);
        if !(marker_mm.is_finite() && marker_mm > 0.0 && marker_mm < square_mm) {
            return Err(format!(
                "`marker_mm` must be positive and smaller than a square ({} mm), got {}",
                crate::Num(square_mm),
                crate::Num(marker_mm)
            ));
        }
        let (needed, (across, down)) = (self.marker_count(), self.squares());
        if needed > dictionary.size() {
            return Err(format!(
                "`dictionary` {dictionary} has {} markers; a {across} x {down}-square board needs {needed}",
                dictionary.size()
            ));
        }
        Ok(())
    }

    /// Squares across and down: `(cols + 1, rows + 1)`.
    pub fn squares(&self) -> (usize, usize) {
        (self.cols + 1, self.rows + 1)
    }

    /// Number of markers a ChArUco board of this size carries: one per
    /// white square.
    pub fn marker_count(&self) -> usize {
        let (across, down) = self.squares();
        across * down / 2
    }

    /// The square `(i, j)` (0-based from the top-left square, `i` across)
    /// that holds the point `(x_mm, y_mm)` of the board frame, if any.
    pub fn square_at(&self, x_mm: f64, y_mm: f64) -> Option<(usize, usize)> {
        let i = (x_mm / self.square_x_mm).floor() + 1.0;
        let j = (y_mm / self.square_y_mm).floor() + 1.0;
        let (across, down) = self.squares();
        ((0.0..across as f64).contains(&i) && (0.0..down as f64).contains(&j))
            .then_some((i as usize, j as usize))
    }

    /// The id of the marker in square `(i, j)`, OpenCV's layout (see
    /// [`CharucoMarkers`]): `None` for a black square, a square off the
    /// board, or a plain checkerboard.
    pub fn marker_id_at_square(&self, i: usize, j: usize) -> Option<usize> {
        let (across, down) = self.squares();
        let white = (i + j) % 2 == 1;
        if self.markers.is_none() || !white || i >= across || j >= down {
            return None;
        }
        // White squares before row j, then before column i in row j.
        Some((j / 2) * across + (j % 2) * (across / 2) + (i + j % 2) / 2)
    }

    /// The marker under a point of the board frame: its id and the point in
    /// marker cells `(column, row)` from the marker's top-left corner
    /// (0 ..= bits + 2, the black border ring included). `None` off the markers.
    pub fn marker_cell_at(&self, x_mm: f64, y_mm: f64) -> Option<(usize, f64, f64)> {
        let markers = self.markers?;
        let (i, j) = self.square_at(x_mm, y_mm)?;
        let id = self.marker_id_at_square(i, j)?;
        let centre_x = (i as f64 - 0.5) * self.square_x_mm;
        let centre_y = (j as f64 - 0.5) * self.square_y_mm;
        let half = markers.marker_mm / 2.0;
        let (dx, dy) = (x_mm - centre_x + half, y_mm - centre_y + half);
        let inside =
            (0.0..markers.marker_mm).contains(&dx) && (0.0..markers.marker_mm).contains(&dy);
        let cells = (markers.dictionary.marker_bits() + 2) as f64;
        inside.then(|| (id, dx / markers.marker_mm * cells, dy / markers.marker_mm * cells))
    }
}

/// One view of a session.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionView {
    /// The image, relative to the session folder as written in the file.
    pub image: PathBuf,
    /// Slide travel d of the laser when the image was taken.
    pub slide_mm: f64,
    /// The same pose with the laser off, where the session has one.
    pub image_laser_off: Option<PathBuf>,
    /// The same pose as the RGB-D camera's colour image saw it, where the
    /// session has one (`alacs calibrate rgbd`).
    pub image_rgbd: Option<PathBuf>,
}

/// A calibration session as read from session.yaml.
#[derive(Debug, Clone, PartialEq)]
pub struct Session {
    /// The folder holding session.yaml; image paths are relative to it.
    pub dir: PathBuf,
    /// The checkerboard.
    pub board: BoardSpec,
    /// The views, in file order.
    pub views: Vec<SessionView>,
}

#[derive(Deserialize, Serialize)]
struct SessionFile {
    board: BoardFile,
    views: Vec<ViewFile>,
}

#[derive(Deserialize, Serialize)]
struct BoardFile {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    inner_corners: Option<Vec<i64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    squares: Option<Vec<i64>>,
    square_mm: SquareFile,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    marker_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    dictionary: Option<String>,
}

#[derive(Deserialize, Serialize)]
#[serde(untagged)]
enum SquareFile {
    Same(f64),
    PerAxis(Vec<f64>),
}

#[derive(Deserialize, Serialize)]
struct ViewFile {
    image: String,
    #[serde(default)]
    slide_mm: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    image_laser_off: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    image_rgbd: Option<String>,
}

/// The board of session.yaml, checked (errors name the key).
fn parse_board(file: BoardFile) -> std::result::Result<BoardSpec, String> {
    let (cols, rows) = match (file.inner_corners.as_deref(), file.squares.as_deref()) {
        (Some(&[cols, rows]), None)
            if INNER_CORNERS_RANGE.contains(&(cols as usize))
                && INNER_CORNERS_RANGE.contains(&(rows as usize)) =>
        {
            (cols as usize, rows as usize)
        }
        (None, Some(&[across, down]))
            if (3..=1001).contains(&across) && (3..=1001).contains(&down) =>
        {
            (across as usize - 1, down as usize - 1)
        }
        (Some(_), Some(_)) => {
            return Err("`board` gives both `inner_corners` and `squares`; give one".into());
        }
        (None, None) => {
            return Err(
                "`board` needs `inner_corners` [columns, rows] (or `squares` [across, down])"
                    .into(),
            );
        }
        (Some(other), None) => {
            return Err(format!(
                "`board.inner_corners` must be [columns, rows], each 2..1000, got {other:?}"
            ));
        }
        (None, Some(other)) => {
            return Err(format!(
                "`board.squares` must be [across, down], each 3..1001, got {other:?}"
            ));
        }
    };
    let (square_x_mm, square_y_mm) = match file.square_mm {
        SquareFile::Same(s) => (s, s),
        SquareFile::PerAxis(v) if v.len() == 2 => (v[0], v[1]),
        SquareFile::PerAxis(v) => {
            return Err(format!(
                "`board.square_mm` must be one number or [along_x, along_y], got {} values",
                v.len()
            ));
        }
    };
    for s in [square_x_mm, square_y_mm] {
        if !(s.is_finite() && s > 0.0 && s <= MAX_SQUARE_MM) {
            return Err(format!(
                "`board.square_mm` must lie in (0, {MAX_SQUARE_MM}] mm, got {}",
                crate::Num(s)
            ));
        }
    }
    let mut board = BoardSpec::checkerboard(cols, rows, square_x_mm, square_y_mm);
    board.markers = match (file.marker_mm, file.dictionary) {
        (None, None) => None,
        (Some(marker_mm), Some(name)) => {
            let dictionary =
                ArucoDictionary::parse(&name).map_err(|e| format!("`board.dictionary` {e}"))?;
            Some(CharucoMarkers { marker_mm, dictionary })
        }
        (Some(_), None) => return Err("`board.marker_mm` needs `board.dictionary`".into()),
        (None, Some(_)) => return Err("`board.dictionary` needs `board.marker_mm`".into()),
    };
    board.check_markers().map_err(|e| format!("`board`: {e}"))?;
    Ok(board)
}

impl Session {
    /// Reads `dir/session.yaml`. Checks the board and every view's values;
    /// does not open the images.
    pub fn read(dir: &Path) -> Result<Session> {
        let path = dir.join(SESSION_FILE);
        let text = crate::io::read_text(&path)?;
        Self::parse(&text, dir, &path)
    }

    /// session.yaml's text for this session, after `header` (comment lines
    /// without the `#`, may be empty). The one writer of session.yaml.
    pub fn to_yaml_string(&self, header: &str) -> String {
        let b = &self.board;
        let file = SessionFile {
            board: BoardFile {
                inner_corners: Some(vec![b.cols as i64, b.rows as i64]),
                squares: None,
                square_mm: if b.square_x_mm == b.square_y_mm {
                    SquareFile::Same(b.square_x_mm)
                } else {
                    SquareFile::PerAxis(vec![b.square_x_mm, b.square_y_mm])
                },
                marker_mm: b.markers.map(|m| m.marker_mm),
                dictionary: b.markers.map(|m| m.dictionary.as_str().to_string()),
            },
            views: self
                .views
                .iter()
                .map(|v| ViewFile {
                    image: v.image.to_string_lossy().into_owned(),
                    slide_mm: v.slide_mm,
                    image_laser_off: v
                        .image_laser_off
                        .as_ref()
                        .map(|p| p.to_string_lossy().into_owned()),
                    image_rgbd: v.image_rgbd.as_ref().map(|p| p.to_string_lossy().into_owned()),
                })
                .collect(),
        };
        let mut text: String = header.lines().map(|l| format!("# {l}\n")).collect();
        // Serializing plain strings, numbers and lists cannot fail.
        text.push_str(&serde_saphyr::to_string(&file).unwrap_or_default());
        text
    }

    /// Parses session.yaml text; `dir` is the folder the image paths are
    /// relative to, `path` names the file in errors.
    pub fn parse(text: &str, dir: &Path, path: &Path) -> Result<Session> {
        let parse_error = |message: String| Error::Parse { path: path.to_path_buf(), message };
        let file: SessionFile = serde_saphyr::from_str(text)
            .map_err(|e| parse_error(crate::error::yaml_message(&e)))?;
        let board = parse_board(file.board).map_err(parse_error)?;
        if file.views.is_empty() {
            return Err(parse_error("`views` is empty".into()));
        }
        let mut views = Vec::with_capacity(file.views.len());
        for (i, view) in file.views.into_iter().enumerate() {
            if view.image.trim().is_empty() {
                return Err(parse_error(format!("views[{i}]: `image` is empty")));
            }
            if !(view.slide_mm.is_finite() && view.slide_mm.abs() <= crate::MAX_ABS_SLIDE_MM) {
                return Err(parse_error(format!(
                    "views[{i}] ({}): `slide_mm` is {:e}; it must be finite and within +-{} mm",
                    view.image,
                    view.slide_mm,
                    crate::MAX_ABS_SLIDE_MM
                )));
            }
            views.push(SessionView {
                image: PathBuf::from(view.image),
                slide_mm: view.slide_mm,
                image_laser_off: view.image_laser_off.map(PathBuf::from),
                image_rgbd: view.image_rgbd.map(PathBuf::from),
            });
        }
        Ok(Session { dir: dir.to_path_buf(), board, views })
    }

    /// A session of every PNG and JPEG image in `dir` (in name order), all
    /// taken at `slide_mm`, for `board`: what `alacs session init` writes
    /// as a start. An image `X_off.EXT` beside `X.EXT` (any extension)
    /// becomes X's `image_laser_off`; hidden files are skipped. A folder
    /// without images is refused naming it.
    pub fn from_image_folder(dir: &Path, board: BoardSpec, slide_mm: f64) -> Result<Session> {
        let io_error = |error| Error::Io { path: dir.to_path_buf(), error };
        let mut names = Vec::new();
        for entry in std::fs::read_dir(dir).map_err(io_error)? {
            let entry = entry.map_err(io_error)?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let ext = Path::new(&name).extension().map(|e| e.to_string_lossy().to_lowercase());
            let is_image = matches!(ext.as_deref(), Some("png" | "jpg" | "jpeg"));
            if is_image && !name.starts_with('.') && entry.path().is_file() {
                names.push(name);
            }
        }
        names.sort();
        let stem = |name: &str| {
            Path::new(name)
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        };
        let off_of = |name: &str| {
            let on = format!("{}_off", stem(name));
            names.iter().find(|n| stem(n) == on).cloned()
        };
        let is_off = |name: &str| {
            stem(name).strip_suffix("_off").is_some_and(|on| names.iter().any(|n| stem(n) == on))
        };
        let views: Vec<SessionView> = names
            .iter()
            .filter(|n| !is_off(n))
            .map(|n| SessionView {
                image: PathBuf::from(n),
                slide_mm,
                image_laser_off: off_of(n).map(PathBuf::from),
                image_rgbd: None,
            })
            .collect();
        if views.is_empty() {
            return Err(Error::Io {
                path: dir.to_path_buf(),
                error: std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "no PNG or JPEG images in the folder",
                ),
            });
        }
        Ok(Session { dir: dir.to_path_buf(), board, views })
    }

    /// The full path of an image named in the session.
    pub fn path_of(&self, image: &Path) -> PathBuf {
        self.dir.join(image)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn parse(text: &str) -> Result<Session> {
        Session::parse(text, Path::new("/data/s"), Path::new("/data/s/session.yaml"))
    }

    #[test]
    fn written_entries_read_back_whatever_the_file_names() {
        let names = ["view01.png", "a: b #c.png", "say \"hi\"\\x.png", "tab\there.png", "- 01.png"];
        let session = Session {
            dir: PathBuf::from("/data/s"),
            board: BoardSpec::checkerboard(9, 6, 21.167, 21.125),
            views: names
                .iter()
                .enumerate()
                .map(|(k, name)| SessionView {
                    image: PathBuf::from(name),
                    slide_mm: k as f64 * 10.5,
                    image_laser_off: Some(PathBuf::from(name)),
                    image_rgbd: (k % 2 == 0).then(|| PathBuf::from(name)),
                })
                .collect(),
        };
        let text = session.to_yaml_string("simulated\nby a test");
        assert!(text.starts_with("# simulated\n# by a test\n"), "{text}");
        assert_eq!(parse(&text).unwrap(), session);
    }

    #[test]
    fn a_folder_of_images_becomes_a_session_with_laser_off_pairs() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["b.png", "a.jpg", "a_off.jpg", "notes.txt", ".hidden.png", "c_off.png"] {
            std::fs::write(dir.path().join(name), "x").unwrap();
        }
        let board = BoardSpec::checkerboard(9, 6, 25.0, 25.0);
        let session = Session::from_image_folder(dir.path(), board, 50.0).unwrap();
        let images: Vec<_> = session.views.iter().map(|v| v.image.to_string_lossy()).collect();
        // c_off.png has no c.png: it is a view of its own.
        assert_eq!(images, ["a.jpg", "b.png", "c_off.png"]);
        assert_eq!(session.views[0].image_laser_off, Some(PathBuf::from("a_off.jpg")));
        assert!(session.views.iter().all(|v| v.slide_mm == 50.0));
        let text = session.to_yaml_string("");
        let read = Session::parse(&text, dir.path(), Path::new("session.yaml")).unwrap();
        assert_eq!(read, session);
        let empty = tempfile::tempdir().unwrap();
        let error = Session::from_image_folder(empty.path(), board, 0.0).unwrap_err();
        assert!(error.to_string().contains("no PNG or JPEG"), "{error}");
    }

    #[test]
    fn reads_the_formats_example() {
        let session = parse(
            "board: {inner_corners: [9, 6], square_mm: 25.0}\nviews:\n  - image: view01.png\n    slide_mm: 50.0\n    image_laser_off: view01_off.png\n  - image: view02.png\n",
        )
        .unwrap();
        assert_eq!(session.board, BoardSpec::checkerboard(9, 6, 25.0, 25.0));
        assert_eq!(session.views.len(), 2);
        assert_eq!(session.views[0].slide_mm, 50.0);
        assert_eq!(session.views[0].image_laser_off, Some(PathBuf::from("view01_off.png")));
        assert_eq!(session.views[1].slide_mm, 0.0);
        assert_eq!(session.path_of(&session.views[1].image), PathBuf::from("/data/s/view02.png"));
        assert_eq!(session.board.corner_in_board(10), nalgebra::Point3::new(25.0, 25.0, 0.0));
    }

    #[test]
    fn per_axis_squares() {
        let session = parse(
            "board: {inner_corners: [9, 6], square_mm: [21.167, 21.125]}\nviews: [{image: a.png}]\n",
        )
        .unwrap();
        assert_eq!((session.board.square_x_mm, session.board.square_y_mm), (21.167, 21.125));
    }

    #[test]
    fn a_charuco_board_reads_by_squares_and_writes_back() {
        let session = parse(
            "board: {squares: [10, 7], square_mm: 25, marker_mm: 18.75, dictionary: 5x5_100}\nviews: [{image: a.png}]\n",
        )
        .unwrap();
        let markers = CharucoMarkers { marker_mm: 18.75, dictionary: ArucoDictionary::Dict5x5_100 };
        assert_eq!(
            session.board,
            BoardSpec { markers: Some(markers), ..BoardSpec::checkerboard(9, 6, 25.0, 25.0) }
        );
        assert_eq!(session.board.marker_count(), 35);
        let text = session.to_yaml_string("");
        assert!(text.contains("DICT_5X5_100"), "{text}");
        assert_eq!(parse(&text).unwrap(), session);
    }

    #[test]
    fn markers_are_numbered_as_opencv_lays_them_out() {
        // 5 x 4 squares: white squares are those with (i + j) odd.
        let mut board = BoardSpec::checkerboard(4, 3, 10.0, 10.0);
        assert_eq!(board.marker_id_at_square(1, 0), None, "a checkerboard has no markers");
        board.markers =
            Some(CharucoMarkers { marker_mm: 6.0, dictionary: ArucoDictionary::Dict4x4_50 });
        let mut expected = 0;
        for j in 0..4 {
            for i in 0..5 {
                if (i + j) % 2 == 1 {
                    assert_eq!(board.marker_id_at_square(i, j), Some(expected), "({i}, {j})");
                    expected += 1;
                } else {
                    assert_eq!(board.marker_id_at_square(i, j), None, "({i}, {j})");
                }
            }
        }
        assert_eq!(expected, board.marker_count());
        // Square (1, 0) spans x in [0, 10), y in [-10, 0); its 6 mm marker [2, 8) x [-8, -2).
        assert_eq!(board.marker_cell_at(5.0, -5.0), Some((0, 3.0, 3.0)));
        assert_eq!(board.marker_cell_at(1.0, -5.0), None);
        assert_eq!(board.marker_cell_at(-5.0, -5.0), None, "black square");
    }

    #[test]
    fn bad_files_name_the_key() {
        for (text, key) in [
            (
                "board: {inner_corners: [9], square_mm: 25}\nviews: [{image: a.png}]",
                "inner_corners",
            ),
            ("board: {inner_corners: [9, 6], square_mm: -1}\nviews: [{image: a.png}]", "square_mm"),
            (
                "board: {inner_corners: [9, 6], square_mm: [1, 2, 3]}\nviews: [{image: a}]",
                "square_mm",
            ),
            ("board: {inner_corners: [9, 6], square_mm: 25}\nviews: []", "views"),
            (
                "board: {inner_corners: [9, 6], square_mm: 25}\nviews: [{image: a, slide_mm: .nan}]",
                "slide_mm",
            ),
            ("board: {inner_corners: [9, 6]}\nviews: [{image: a}]", "square_mm"),
            ("board: {square_mm: 25}\nviews: [{image: a}]", "inner_corners"),
            (
                "board: {inner_corners: [9, 6], squares: [10, 7], square_mm: 25}\nviews: [{image: a}]",
                "squares",
            ),
            (
                "board: {squares: [10, 7], square_mm: 25, marker_mm: 18}\nviews: [{image: a}]",
                "dictionary",
            ),
            (
                "board: {squares: [10, 7], square_mm: 25, marker_mm: 18, dictionary: DICT_9X9}\nviews: [{image: a}]",
                "DICT_9X9",
            ),
            (
                "board: {squares: [10, 7], square_mm: 25, marker_mm: 30, dictionary: DICT_4X4_50}\nviews: [{image: a}]",
                "marker_mm",
            ),
            (
                "board: {squares: [12, 9], square_mm: 25, marker_mm: 18, dictionary: DICT_4X4_50}\nviews: [{image: a}]",
                "needs 54",
            ),
        ] {
            let message = parse(text).unwrap_err().to_string();
            assert!(message.contains(key), "{message} should name {key}");
            assert!(message.contains("session.yaml"), "{message}");
        }
    }
}

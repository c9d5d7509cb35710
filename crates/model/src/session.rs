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
//! left out (0). Image paths are relative to the folder that holds
//! session.yaml. Unknown keys are ignored.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::{Error, Result};

/// The session file's name inside a session folder.
pub const SESSION_FILE: &str = "session.yaml";

/// A checkerboard: its inner-corner grid and square size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoardSpec {
    /// Inner corners per row (columns), as passed to OpenCV.
    pub cols: usize,
    /// Inner corners per column (rows).
    pub rows: usize,
    /// Square size along the board's x axis (along a row).
    pub square_x_mm: f64,
    /// Square size along the board's y axis (down a column).
    pub square_y_mm: f64,
}

impl BoardSpec {
    /// Number of inner corners.
    pub fn corner_count(&self) -> usize {
        self.cols * self.rows
    }

    /// Inner corner `index` (OpenCV's row-major order) in the board frame:
    /// `(col * square_x, row * square_y, 0)`.
    pub fn corner_in_board(&self, index: usize) -> nalgebra::Point3<f64> {
        let (col, row) = (index % self.cols, index / self.cols);
        nalgebra::Point3::new(col as f64 * self.square_x_mm, row as f64 * self.square_y_mm, 0.0)
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
}

/// One entry of session.yaml's `views` or scan.yaml's `frames` (FORMATS.md),
/// for the programs that write them; the names are quoted, so any file name
/// reads back as written. A writer may append keys of its own to the entry,
/// indented by four spaces.
pub fn image_entry_yaml(image: &str, slide_mm: f64, image_laser_off: Option<&str>) -> String {
    let mut text = format!("  - image: {}\n    slide_mm: {slide_mm:?}\n", yaml_quoted(image));
    if let Some(off) = image_laser_off {
        text.push_str(&format!("    image_laser_off: {}\n", yaml_quoted(off)));
    }
    text
}

/// `text` as a YAML double-quoted scalar.
fn yaml_quoted(text: &str) -> String {
    let mut quoted = String::with_capacity(text.len() + 2);
    quoted.push('"');
    for c in text.chars() {
        match c {
            '"' => quoted.push_str("\\\""),
            '\\' => quoted.push_str("\\\\"),
            c if c.is_control() => quoted.push_str(&format!("\\u{:04x}", u32::from(c))),
            c => quoted.push(c),
        }
    }
    quoted.push('"');
    quoted
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

#[derive(Deserialize)]
struct SessionFile {
    board: BoardFile,
    views: Vec<ViewFile>,
}

#[derive(Deserialize)]
struct BoardFile {
    inner_corners: Vec<i64>,
    square_mm: SquareFile,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum SquareFile {
    Same(f64),
    PerAxis(Vec<f64>),
}

#[derive(Deserialize)]
struct ViewFile {
    image: String,
    #[serde(default)]
    slide_mm: f64,
    #[serde(default)]
    image_laser_off: Option<String>,
}

impl Session {
    /// Reads `dir/session.yaml`. Checks the board and every view's values;
    /// does not open the images.
    pub fn read(dir: &Path) -> Result<Session> {
        let path = dir.join(SESSION_FILE);
        let text = std::fs::read_to_string(&path)
            .map_err(|error| Error::Io { path: path.clone(), error })?;
        Self::parse(&text, dir, &path)
    }

    /// Parses session.yaml text; `dir` is the folder the image paths are
    /// relative to, `path` names the file in errors.
    pub fn parse(text: &str, dir: &Path, path: &Path) -> Result<Session> {
        let parse_error = |message: String| Error::Parse { path: path.to_path_buf(), message };
        let file: SessionFile = serde_saphyr::from_str(text)
            .map_err(|e| parse_error(e.without_snippet().to_string()))?;
        let board = match file.board.inner_corners.as_slice() {
            &[cols, rows] if cols >= 2 && rows >= 2 && cols <= 1000 && rows <= 1000 => {
                let (square_x_mm, square_y_mm) = match file.board.square_mm {
                    SquareFile::Same(s) => (s, s),
                    SquareFile::PerAxis(v) if v.len() == 2 => (v[0], v[1]),
                    SquareFile::PerAxis(v) => {
                        return Err(parse_error(format!(
                            "`board.square_mm` must be one number or [along_x, along_y], got {} values",
                            v.len()
                        )));
                    }
                };
                for s in [square_x_mm, square_y_mm] {
                    if !(s.is_finite() && s > 0.0) {
                        return Err(parse_error(format!(
                            "`board.square_mm` must be positive and finite, got {s}"
                        )));
                    }
                }
                BoardSpec { cols: cols as usize, rows: rows as usize, square_x_mm, square_y_mm }
            }
            other => {
                return Err(parse_error(format!(
                    "`board.inner_corners` must be [columns, rows], each 2..1000, got {other:?}"
                )));
            }
        };
        if file.views.is_empty() {
            return Err(parse_error("`views` is empty".into()));
        }
        let mut views = Vec::with_capacity(file.views.len());
        for (i, view) in file.views.into_iter().enumerate() {
            if view.image.trim().is_empty() {
                return Err(parse_error(format!("views[{i}]: `image` is empty")));
            }
            if !view.slide_mm.is_finite() {
                return Err(parse_error(format!(
                    "views[{i}] ({}): `slide_mm` is {}; it must be finite",
                    view.image, view.slide_mm
                )));
            }
            views.push(SessionView {
                image: PathBuf::from(view.image),
                slide_mm: view.slide_mm,
                image_laser_off: view.image_laser_off.map(PathBuf::from),
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
        let mut text = String::from("board: {inner_corners: [9, 6], square_mm: 25.0}\nviews:\n");
        for (k, name) in names.iter().enumerate() {
            text.push_str(&image_entry_yaml(name, k as f64 * 10.5, Some(name)));
        }
        let session = parse(&text).unwrap();
        for (k, (view, name)) in session.views.iter().zip(names).enumerate() {
            assert_eq!(view.image, Path::new(name));
            assert_eq!(view.image_laser_off.as_deref(), Some(Path::new(name)));
            assert_eq!(view.slide_mm, k as f64 * 10.5);
        }
    }

    #[test]
    fn reads_the_formats_example() {
        let session = parse(
            "board: {inner_corners: [9, 6], square_mm: 25.0}\nviews:\n  - image: view01.png\n    slide_mm: 50.0\n    image_laser_off: view01_off.png\n  - image: view02.png\n",
        )
        .unwrap();
        assert_eq!(
            session.board,
            BoardSpec { cols: 9, rows: 6, square_x_mm: 25.0, square_y_mm: 25.0 }
        );
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
        ] {
            let message = parse(text).unwrap_err().to_string();
            assert!(message.contains(key), "{message} should name {key}");
            assert!(message.contains("session.yaml"), "{message}");
        }
    }
}

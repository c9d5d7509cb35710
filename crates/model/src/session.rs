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

use serde::{Deserialize, Serialize};

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
    inner_corners: Vec<i64>,
    square_mm: SquareFile,
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
                inner_corners: vec![b.cols as i64, b.rows as i64],
                square_mm: if b.square_x_mm == b.square_y_mm {
                    SquareFile::Same(b.square_x_mm)
                } else {
                    SquareFile::PerAxis(vec![b.square_x_mm, b.square_y_mm])
                },
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
            board: BoardSpec { cols: 9, rows: 6, square_x_mm: 21.167, square_y_mm: 21.125 },
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
        let board = BoardSpec { cols: 9, rows: 6, square_x_mm: 25.0, square_y_mm: 25.0 };
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

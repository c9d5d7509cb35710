//! camera.yaml (FORMATS.md): the ROS `camera_calibration_parsers` format,
//! plus the OpenCV `FileStorage` YAML that OpenCV's calibration samples write.
//!
//! Reading is lenient where the meaning is unambiguous: `camera_name`
//! defaults to `camera`; `rectification_matrix` and `projection_matrix` may
//! be missing (intrinsics always come from `camera_matrix`); a missing
//! `distortion_model` is inferred from the number of coefficients (4 or 5:
//! `plumb_bob`, 8: `rational_polynomial`); `plumb_bob` accepts 4 coefficients
//! (k3 = 0); `rows`/`cols` may be omitted, and the coefficients may have
//! any shape that holds their number (ROS writes 1 x n, OpenCV n x 1).
//! Coefficients that are all zero (or none: `data: []`) read as
//! [`Distortion::None`]. Unknown keys are ignored.

use std::borrow::Cow;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{Camera, Distortion};
use crate::{Error, Result};

/// `camera_name` when the file has none.
const DEFAULT_CAMERA_NAME: &str = "camera";

/// Tolerance for the fixed entries of `camera_matrix` (0 below the diagonal,
/// 1 in the corner): tools write them exactly, this only forgives a printed
/// rounding.
const FIXED_ENTRY_TOLERANCE: f64 = 1e-9;

/// A matrix as ROS (`{rows, cols, data}`) and OpenCV (`!!opencv-matrix` with
/// `dt: d`, ignored like every unknown key) write it, or a bare list of its
/// values (a ROS `CameraInfo` message's `k` and `d` as `ros2 topic echo`
/// prints them).
#[derive(Debug, Clone, Serialize)]
struct MatrixFile {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rows: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    cols: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    data: Option<Vec<f64>>,
}

/// `{rows, cols, data}`, the mapping form of [`MatrixFile`].
#[derive(Deserialize)]
struct MatrixMapping {
    #[serde(default)]
    rows: Option<usize>,
    #[serde(default)]
    cols: Option<usize>,
    #[serde(default)]
    data: Option<Vec<f64>>,
}

/// A mapping, or a bare list of the values. Written out (not `untagged`) so
/// that the numbers are read as numbers in place, and a bad value is
/// reported under its key by the checks of [`MatrixFile::values`].
impl<'de> Deserialize<'de> for MatrixFile {
    fn deserialize<D: serde::Deserializer<'de>>(
        deserializer: D,
    ) -> std::result::Result<Self, D::Error> {
        struct MatrixVisitor;
        impl<'de> serde::de::Visitor<'de> for MatrixVisitor {
            type Value = MatrixFile;

            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a matrix: {rows, cols, data} or a list of its values")
            }

            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> std::result::Result<MatrixFile, A::Error> {
                let mut data = Vec::new();
                while let Some(value) = seq.next_element::<f64>()? {
                    data.push(value);
                }
                Ok(MatrixFile { rows: None, cols: None, data: Some(data) })
            }

            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> std::result::Result<MatrixFile, A::Error> {
                let MatrixMapping { rows, cols, data } =
                    MatrixMapping::deserialize(serde::de::value::MapAccessDeserializer::new(map))?;
                Ok(MatrixFile { rows, cols, data })
            }
        }
        deserializer.deserialize_any(MatrixVisitor)
    }
}

impl MatrixFile {
    fn new(rows: usize, cols: usize, data: Vec<f64>) -> Self {
        Self { rows: Some(rows), cols: Some(cols), data: Some(data) }
    }

    /// The data, checked against `rows` x `cols` where the file gives them.
    fn values(&self, key: &str) -> std::result::Result<&[f64], String> {
        let data = self.data.as_deref().ok_or_else(|| format!("`{key}`: missing key `data`"))?;
        match (self.rows, self.cols) {
            (Some(rows), Some(cols)) if rows.checked_mul(cols) != Some(data.len()) => Err(format!(
                "`{key}`: rows {rows} x cols {cols} does not match the {} values of `data`",
                data.len()
            )),
            _ => Ok(data),
        }
    }

    /// The data of a matrix that must have `rows` x `cols` values.
    fn values_of_shape(
        &self,
        key: &str,
        rows: usize,
        cols: usize,
    ) -> std::result::Result<&[f64], String> {
        let data = self.values(key)?;
        let shape_matches =
            self.rows.is_none_or(|r| r == rows) && self.cols.is_none_or(|c| c == cols);
        if data.len() != rows * cols || !shape_matches {
            return Err(format!(
                "`{key}` must be {rows} x {cols} ({} values), got {} x {} ({} values)",
                rows * cols,
                self.rows.map_or("?".to_string(), |r| r.to_string()),
                self.cols.map_or("?".to_string(), |c| c.to_string()),
                data.len()
            ));
        }
        if let Some((i, value)) = data.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(format!(
                "`{key}`: data[{i}] is {}; values must be finite",
                crate::Num(*value)
            ));
        }
        Ok(data)
    }
}

/// camera.yaml as written on disk. Every key is optional here so that a
/// missing one is reported by name; unknown keys (OpenCV's
/// `calibration_time`, `avg_reprojection_error`, ...) are ignored.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct CameraFile {
    #[serde(default, skip_serializing_if = "Option::is_none", alias = "width")]
    image_width: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none", alias = "height")]
    image_height: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    camera_name: Option<String>,
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        alias = "cameraMatrix",
        alias = "K",
        alias = "k"
    )]
    camera_matrix: Option<MatrixFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    distortion_model: Option<String>,
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        alias = "distCoeffs",
        alias = "D",
        alias = "d"
    )]
    distortion_coefficients: Option<MatrixFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rectification_matrix: Option<MatrixFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    projection_matrix: Option<MatrixFile>,
}

impl From<&Camera> for CameraFile {
    fn from(camera: &Camera) -> Self {
        let (fx, fy, cx, cy, s) =
            (camera.fx_px, camera.fy_px, camera.cx_px, camera.cy_px, camera.skew_px);
        let (model, coefficients) = camera.distortion.ros_model();
        CameraFile {
            image_width: Some(camera.width_px),
            image_height: Some(camera.height_px),
            camera_name: Some(camera.name.clone()),
            camera_matrix: Some(MatrixFile::new(3, 3, vec![fx, s, cx, 0.0, fy, cy, 0.0, 0.0, 1.0])),
            distortion_model: Some(model.to_string()),
            distortion_coefficients: Some(MatrixFile::new(1, coefficients.len(), coefficients)),
            rectification_matrix: Some(MatrixFile::new(
                3,
                3,
                vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            )),
            projection_matrix: Some(MatrixFile::new(
                3,
                4,
                vec![fx, s, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            )),
        }
    }
}

impl CameraFile {
    /// The camera this file describes, or a message naming the offending key.
    fn into_camera(self) -> std::result::Result<Camera, String> {
        let size = |key: &str, value: Option<u32>| match value {
            None => Err(format!("missing key `{key}`")),
            Some(0) => Err(format!("`{key}` must be positive, got 0")),
            Some(size) => Ok(size),
        };
        let width_px = size("image_width", self.image_width)?;
        let height_px = size("image_height", self.image_height)?;

        let matrix = self.camera_matrix.as_ref().ok_or("missing key `camera_matrix`")?;
        let k = matrix.values_of_shape("camera_matrix", 3, 3)?;
        let fixed = [(3, 0.0), (6, 0.0), (7, 0.0), (8, 1.0)];
        if fixed.iter().any(|&(i, expected)| (k[i] - expected).abs() > FIXED_ENTRY_TOLERANCE) {
            return Err(format!(
                "`camera_matrix` must be [fx, skew, cx, 0, fy, cy, 0, 0, 1], got {k:?}"
            ));
        }
        let (fx_px, skew_px, cx_px, fy_px, cy_px) = (k[0], k[1], k[2], k[4], k[5]);
        if !(fx_px > 0.0 && fy_px > 0.0) {
            return Err(format!(
                "`camera_matrix`: focal lengths must be positive, got fx {fx_px}, fy {fy_px}"
            ));
        }

        // Checked for shape only: the intrinsics come from camera_matrix. A
        // matrix without `rows` and `cols` (a bare list) must hold the
        // values of its shape.
        let check_shape = |matrix: &Option<MatrixFile>, key: &str, count: usize| {
            let Some(matrix) = matrix else { return Ok(()) };
            let data = matrix.values(key)?;
            if matrix.rows.is_none() && matrix.cols.is_none() && data.len() != count {
                return Err(format!("`{key}` must hold {count} values, got {}", data.len()));
            }
            Ok(())
        };
        check_shape(&self.rectification_matrix, "rectification_matrix", 9)?;
        check_shape(&self.projection_matrix, "projection_matrix", 12)?;

        let distortion = self.distortion()?;
        let camera = Camera {
            name: self.camera_name.unwrap_or_else(|| DEFAULT_CAMERA_NAME.to_string()),
            width_px,
            height_px,
            fx_px,
            fy_px,
            cx_px,
            cy_px,
            skew_px,
            distortion,
        };
        // What the keys' own checks above leave (an absurd image size, a
        // non-finite intrinsic) is refused by the one camera check.
        camera.validate().map_err(|e| e.to_string())?;
        Ok(camera)
    }

    fn distortion(&self) -> std::result::Result<Distortion, String> {
        const KEY: &str = "distortion_coefficients";
        let matrix =
            self.distortion_coefficients.as_ref().ok_or("missing key `distortion_coefficients`")?;
        let data = matrix.values(KEY)?;
        if let Some((i, value)) = data.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(format!(
                "`{KEY}`: data[{i}] is {}; coefficients must be finite",
                crate::Num(*value)
            ));
        }
        if let Some((i, value)) =
            data.iter().enumerate().find(|(_, v)| v.abs() > super::MAX_ABS_DISTORTION)
        {
            return Err(format!(
                "`{KEY}`: data[{i}] is {value:e}, beyond +-{:e}: no lens has it (a unit or typing error)",
                super::MAX_ABS_DISTORTION
            ));
        }
        let model = match self.distortion_model.as_deref().map(str::trim) {
            Some(name) => name.to_ascii_lowercase(),
            None => match data.len() {
                0 | 4 | 5 => "plumb_bob".to_string(),
                8 => "rational_polynomial".to_string(),
                n => {
                    return Err(format!(
                        "missing key `distortion_model`, and {n} values of `{KEY}` match no \
                         supported model (4 or 5: plumb_bob, 8: rational_polynomial)"
                    ));
                }
            },
        };
        let distortion = match (model.as_str(), data) {
            (_, []) => Distortion::None,
            ("plumb_bob", &[k1, k2, p1, p2]) => Distortion::PlumbBob([k1, k2, p1, p2, 0.0]),
            ("plumb_bob", &[k1, k2, p1, p2, k3]) => Distortion::PlumbBob([k1, k2, p1, p2, k3]),
            ("rational_polynomial", &[k1, k2, p1, p2, k3, k4, k5, k6]) => {
                Distortion::RationalPolynomial([k1, k2, p1, p2, k3, k4, k5, k6])
            }
            ("plumb_bob", _) => {
                return Err(format!(
                    "`{KEY}`: plumb_bob takes 4 or 5 coefficients, got {}",
                    data.len()
                ));
            }
            ("rational_polynomial", _) => {
                return Err(format!(
                    "`{KEY}`: rational_polynomial takes 8 coefficients, got {}",
                    data.len()
                ));
            }
            (other, _) => {
                return Err(format!(
                    "`distortion_model`: `{other}` is not supported \
                     (supported: plumb_bob, rational_polynomial)"
                ));
            }
        };
        Ok(if distortion.is_identity() { Distortion::None } else { distortion })
    }
}

/// OpenCV `FileStorage` YAML -> plain YAML: drops the `%YAML:1.0` directive
/// line (not valid YAML 1.2 syntax) and the `!!opencv-matrix` (and
/// `!!opencv-nd-matrix`) tags, whose mappings (`rows`, `cols`, `dt`, `data`)
/// then read like ROS matrices.
fn strip_opencv_syntax(text: &str) -> Cow<'_, str> {
    const TAG: &str = "!!opencv-";
    let has_directive = text.trim_start().starts_with("%YAML:");
    if !has_directive && !text.contains(TAG) {
        return Cow::Borrowed(text);
    }
    let mut plain = String::with_capacity(text.len());
    let mut lines = text.lines().peekable();
    if has_directive {
        // Blank lines and the directive itself.
        while lines.next_if(|line| !line.trim_start().starts_with("%YAML:")).is_some() {}
        lines.next();
    }
    for line in lines {
        let mut rest = line;
        while let Some(start) = rest.find(TAG) {
            plain.push_str(&rest[..start]);
            let tag_len = rest[start..].find(char::is_whitespace).unwrap_or(rest.len() - start);
            rest = &rest[start + tag_len..];
        }
        plain.push_str(rest);
        plain.push('\n');
    }
    Cow::Owned(plain)
}

/// An f64 as a YAML float that YAML 1.1 readers (PyYAML, so ROS Python
/// tools) also read as a float: shortest round-trip digits, always a `.` in
/// the mantissa and a sign on the exponent (`1.0e-5`, not `1e-5`).
fn yaml_float(value: f64) -> String {
    if value.is_nan() {
        return ".nan".to_string();
    }
    if value.is_infinite() {
        return if value > 0.0 { ".inf".to_string() } else { "-.inf".to_string() };
    }
    let text = format!("{value:?}");
    match text.split_once('e') {
        None => text,
        Some((mantissa, exponent)) => {
            let mantissa =
                if mantissa.contains('.') { mantissa.to_string() } else { format!("{mantissa}.0") };
            let exponent = if exponent.starts_with('-') {
                exponent.to_string()
            } else {
                format!("+{exponent}")
            };
            format!("{mantissa}e{exponent}")
        }
    }
}

/// A YAML scalar for a string: plain where that cannot be read as anything
/// but this string, double-quoted (JSON escapes, valid YAML) otherwise.
fn yaml_string(text: &str) -> String {
    let plain_safe = text.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && text.chars().all(|c| c.is_ascii_alphanumeric() || "_-./".contains(c))
        && !matches!(
            text.to_ascii_lowercase().as_str(),
            "true" | "false" | "null" | "yes" | "no" | "on" | "off" | "y" | "n" | "nan" | "inf"
        );
    if plain_safe {
        return text.to_string();
    }
    let mut quoted = String::from("\"");
    for c in text.chars() {
        match c {
            '"' => quoted.push_str("\\\""),
            '\\' => quoted.push_str("\\\\"),
            '\n' => quoted.push_str("\\n"),
            '\t' => quoted.push_str("\\t"),
            c if c.is_control() => quoted.push_str(&format!("\\u{:04x}", u32::from(c))),
            c => quoted.push(c),
        }
    }
    quoted.push('"');
    quoted
}

/// One `key: {rows, cols, data: [..]}` block in the ROS layout, or the
/// same as an `!!opencv-matrix` (`dt: d`) in OpenCV's.
fn write_matrix(
    out: &mut String,
    key: &str,
    matrix: Option<&MatrixFile>,
    format: CameraFileFormat,
) {
    let Some(matrix) = matrix else { return };
    let data = matrix.data.as_deref().unwrap_or_default();
    let values: Vec<String> = data.iter().map(|&v| yaml_float(v)).collect();
    let (rows, cols) = (matrix.rows.unwrap_or(1), matrix.cols.unwrap_or(data.len()));
    let values = values.join(", ");
    out.push_str(&match format {
        CameraFileFormat::Ros => {
            format!("{key}:\n  rows: {rows}\n  cols: {cols}\n  data: [{values}]\n")
        }
        CameraFileFormat::OpenCv => format!(
            "{key}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {values} ]\n"
        ),
    });
}

impl Camera {
    /// Parses camera.yaml text: the ROS `camera_calibration_parsers` format
    /// or OpenCV `FileStorage` YAML (FORMATS.md; the leniencies are in this
    /// module's docs). Errors name the key and what is wrong with it.
    pub fn from_yaml_str(text: &str) -> Result<Camera> {
        Self::parse_yaml(text, Path::new("<string>"))
    }

    /// Reads camera.yaml; errors name the file.
    pub fn from_yaml_file(path: &Path) -> Result<Camera> {
        let text = crate::io::read_text(path)?;
        Self::parse_yaml(&text, path)
    }

    fn parse_yaml(text: &str, path: &Path) -> Result<Camera> {
        let parse_error = |message: String| Error::Parse { path: path.to_path_buf(), message };
        let file: CameraFile = serde_saphyr::from_str(&strip_opencv_syntax(text))
            // One line ("line L column C: ..."), without the source snippet.
            .map_err(|e| parse_error(crate::error::yaml_message(&e)))?;
        file.into_camera().map_err(parse_error)
    }

    /// camera.yaml text in the ROS format with every key: `camera_matrix`
    /// K, `rectification_matrix` the identity, `projection_matrix` [K | 0].
    /// Floats are written with shortest round-trip digits, so reading the
    /// text back gives this camera exactly (a distortion whose coefficients
    /// are all zero reads back as [`Distortion::None`]).
    pub fn to_yaml_string(&self) -> String {
        self.to_yaml_string_as(CameraFileFormat::Ros)
    }

    /// camera.yaml text in OpenCV's `FileStorage` YAML, which
    /// `cv2.FileStorage` reads: the `%YAML:1.0` header, `image_width`,
    /// `image_height`, `camera_matrix` and `distortion_coefficients` as
    /// `!!opencv-matrix` (`dt: d`; the coefficients 1 x n, OpenCV's order),
    /// and `camera_name` and `distortion_model` as strings (which OpenCV
    /// ignores and alacs reads back). Shortest round-trip digits, so alacs
    /// reads the text back as this camera exactly.
    pub fn to_opencv_yaml_string(&self) -> String {
        self.to_yaml_string_as(CameraFileFormat::OpenCv)
    }

    /// camera.yaml text in `format` (see [`Camera::to_yaml_string`] and
    /// [`Camera::to_opencv_yaml_string`]).
    pub fn to_yaml_string_as(&self, format: CameraFileFormat) -> String {
        let file = CameraFile::from(self);
        let (model, _) = self.distortion.ros_model();
        let (header, name, model) = match format {
            CameraFileFormat::Ros => ("", yaml_string(&self.name), model.to_string()),
            CameraFileFormat::OpenCv => {
                ("%YAML:1.0\n---\n", yaml_string_quoted(&self.name), format!("\"{model}\""))
            }
        };
        let mut out = format!(
            "{header}image_width: {}\nimage_height: {}\ncamera_name: {name}\n",
            self.width_px, self.height_px
        );
        write_matrix(&mut out, "camera_matrix", file.camera_matrix.as_ref(), format);
        out.push_str(&format!("distortion_model: {model}\n"));
        write_matrix(
            &mut out,
            "distortion_coefficients",
            file.distortion_coefficients.as_ref(),
            format,
        );
        if format == CameraFileFormat::Ros {
            write_matrix(
                &mut out,
                "rectification_matrix",
                file.rectification_matrix.as_ref(),
                format,
            );
            write_matrix(&mut out, "projection_matrix", file.projection_matrix.as_ref(), format);
        }
        out
    }

    /// Writes camera.yaml ([`Camera::to_yaml_string`]) atomically.
    pub fn to_yaml_file(&self, path: &Path) -> Result<()> {
        self.to_yaml_file_as(path, CameraFileFormat::Ros)
    }

    /// Writes camera.yaml in `format` atomically.
    pub fn to_yaml_file_as(&self, path: &Path, format: CameraFileFormat) -> Result<()> {
        crate::io::write_file(path, self.to_yaml_string_as(format))
    }
}

/// The layouts alacs writes camera.yaml in; it reads both (and OpenCV's and
/// ROS's usual key names) without being told.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CameraFileFormat {
    /// ROS `camera_calibration_parsers` YAML ([`Camera::to_yaml_string`]).
    #[default]
    Ros,
    /// OpenCV `FileStorage` YAML ([`Camera::to_opencv_yaml_string`]).
    OpenCv,
}

/// A string as OpenCV's `FileStorage` writes one: always double-quoted
/// (JSON escapes), so its YAML parser never takes it for a number.
fn yaml_string_quoted(text: &str) -> String {
    let plain = yaml_string(text);
    if plain.starts_with('"') { plain } else { format!("\"{plain}\"") }
}

/// Serializes as camera.yaml's keys (so `serde_json::to_value(&camera)` is
/// camera.yaml in JSON, as truth.json holds it).
impl Serialize for Camera {
    fn serialize<S: serde::Serializer>(
        &self,
        serializer: S,
    ) -> std::result::Result<S::Ok, S::Error> {
        CameraFile::from(self).serialize(serializer)
    }
}

/// Deserializes camera.yaml's keys, with the same checks and leniencies as
/// [`Camera::from_yaml_str`].
impl<'de> Deserialize<'de> for Camera {
    fn deserialize<D: serde::Deserializer<'de>>(
        deserializer: D,
    ) -> std::result::Result<Self, D::Error> {
        CameraFile::deserialize(deserializer)?.into_camera().map_err(serde::de::Error::custom)
    }
}

//! A learned detector (cargo feature `onnx`): a YOLO-style ONNX model run
//! on the CPU by tract, in pure Rust (no runtime is downloaded at build).
//!
//! The user brings the model and its class names. The image is letterboxed
//! into the model's input (scaled to fit, centred, padded grey 114 as the
//! YOLO exporters train), fed as RGB in 0-1, NCHW. Two output layouts are
//! read, told apart by their shape and the number of classes C:
//! YOLOv8 and later `[1, 4 + C, N]` (centre x, centre y, width, height,
//! then a score per class) and YOLOv5 `[1, N, 5 + C]` (the same four, an
//! objectness, then class probabilities; score = objectness x class).
//! Boxes of the fruit classes above the score threshold survive greedy
//! non-maximum suppression and become circles of their longer side (a
//! fruit cut by a leaf keeps its diameter in the other), in image pixels.

use std::path::Path;

use image::RgbImage;
use nalgebra::Point2;
use tract_onnx::prelude::*;
use tract_onnx::tract_hir::infer::Factoid as _;
use tract_onnx::tract_hir::internal::DimLike as _;

use crate::{Detection, Error, Result};

/// The grey YOLO exporters pad letterboxed images with, 0-255.
const LETTERBOX_GREY: u8 = 114;

/// Settings of [`OnnxDetector`].
#[derive(Debug, Clone, PartialEq)]
pub struct OnnxOptions {
    /// The model's class names, in its output order.
    pub class_names: Vec<String>,
    /// The classes that are fruit (any case), e.g. `apple`.
    pub fruit_classes: Vec<String>,
    /// Boxes scoring below this are dropped (0-1; Ultralytics' default 0.25).
    pub score_threshold: f64,
    /// A box overlapping a better one of its class by more than this
    /// intersection over union is the same fruit (Ultralytics' 0.45).
    pub iou_threshold: f64,
}

impl OnnxOptions {
    /// `class_names` with `apple` as the fruit and Ultralytics' thresholds.
    pub fn new(class_names: Vec<String>) -> Self {
        Self {
            class_names,
            fruit_classes: vec!["apple".into()],
            score_threshold: 0.25,
            iou_threshold: 0.45,
        }
    }
}

/// A loaded model, ready to run on images of any size.
pub struct OnnxDetector {
    plan: std::sync::Arc<TypedSimplePlan>,
    /// The model file, for messages.
    path: std::path::PathBuf,
    /// The model's input, px.
    input_width: u32,
    input_height: u32,
    /// Indices of the fruit classes among `options.class_names`.
    fruit: Vec<usize>,
    options: OnnxOptions,
}

impl std::fmt::Debug for OnnxDetector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnnxDetector")
            .field("input", &(self.input_width, self.input_height))
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

/// Largest model file read, bytes: the largest YOLOv8 export (x, 640 px)
/// is about 260 MB; a file several times that is not a detector's model.
pub const MAX_MODEL_BYTES: u64 = 1 << 30;

/// A model's error as bad input naming the file.
fn bad_model(path: &Path, what: impl std::fmt::Display) -> Error {
    Error::InvalidInput(format!("{}: {what}", path.display()))
}

impl OnnxDetector {
    /// Loads the ONNX model at `path`: one image input `[1, 3, H, W]` (a
    /// dynamic size is fixed at 640 x 640), one output of a layout the
    /// module docs name.
    pub fn load(path: &Path, options: OnnxOptions) -> Result<Self> {
        if options.class_names.is_empty() {
            return Err(bad_model(path, "the model's class names are needed (none given)"));
        }
        let fruit: Vec<usize> = options
            .class_names
            .iter()
            .enumerate()
            .filter(|(_, n)| options.fruit_classes.iter().any(|f| f.eq_ignore_ascii_case(n.trim())))
            .map(|(i, _)| i)
            .collect();
        if fruit.is_empty() {
            return Err(bad_model(
                path,
                format!(
                    "none of the classes {:?} is a fruit class {:?}",
                    options.class_names, options.fruit_classes
                ),
            ));
        }
        if !((0.0..=1.0).contains(&options.score_threshold)
            && (0.0..=1.0).contains(&options.iou_threshold))
        {
            return Err(bad_model(path, "the score and IoU thresholds lie within 0-1"));
        }
        // A regular file within the limit: tract reads the path itself (an
        // ONNX file may keep its weights beside it), and a FIFO would block.
        drop(alacs_model::io::open_bounded(path, MAX_MODEL_BYTES)?);
        let model = tract_onnx::onnx()
            .model_for_path(path)
            .map_err(|e| bad_model(path, format!("not an ONNX model tract can read: {e}")))?;
        let fact = model.input_fact(0).map_err(|e| bad_model(path, e))?.clone();
        let mut dims: Vec<Option<usize>> =
            fact.shape.dims().map(|d| d.concretize().and_then(|d| d.to_usize().ok())).collect();
        if dims.is_empty() {
            dims = vec![None; 4]; // an input of unknown rank
        }
        let (height, width) = match dims.as_slice() {
            [_, Some(3) | None, h, w] => (h.unwrap_or(640), w.unwrap_or(640)),
            _ => return Err(bad_model(path, format!("the input is {dims:?}, not [1, 3, H, W]"))),
        };
        let plan = model
            .with_input_fact(0, f32::fact([1, 3, height, width]).into())
            .and_then(|m| m.into_optimized())
            .and_then(|m| m.into_runnable())
            .map_err(|e| bad_model(path, format!("tract cannot run it: {e}")))?;
        let to_u32 = |v: usize| u32::try_from(v).map_err(|_| bad_model(path, "input too large"));
        Ok(Self {
            plan,
            path: path.to_owned(),
            input_width: to_u32(width)?,
            input_height: to_u32(height)?,
            fruit,
            options,
        })
    }

    /// The fruit in `image`, strongest first.
    pub fn detect(&self, image: &RgbImage) -> Result<Vec<Detection>> {
        let (w, h) = image.dimensions();
        if w == 0 || h == 0 {
            return Err(Error::InvalidInput("the image is empty".into()));
        }
        // Letterbox: scaled to fit, centred, padded grey.
        let scale = f64::min(
            f64::from(self.input_width) / f64::from(w),
            f64::from(self.input_height) / f64::from(h),
        );
        let (sw, sh) = (
            ((f64::from(w) * scale).round() as u32).clamp(1, self.input_width),
            ((f64::from(h) * scale).round() as u32).clamp(1, self.input_height),
        );
        let resized = image::imageops::resize(image, sw, sh, image::imageops::FilterType::Triangle);
        let (pad_x, pad_y) = ((self.input_width - sw) / 2, (self.input_height - sh) / 2);
        let (iw, ih) = (self.input_width as usize, self.input_height as usize);
        let input: Tensor = tract_ndarray::Array4::from_shape_fn((1, 3, ih, iw), |(_, c, y, x)| {
            let (x, y) = (x as u32, y as u32);
            let inside = x >= pad_x && y >= pad_y && x < pad_x + sw && y < pad_y + sh;
            let v =
                if inside { resized.get_pixel(x - pad_x, y - pad_y).0[c] } else { LETTERBOX_GREY };
            f32::from(v) / 255.0
        })
        .into();
        let outputs = self
            .plan
            .run(tvec!(input.into()))
            .map_err(|e| Error::Failed(format!("the model failed to run: {e}")))?;
        let output = outputs[0]
            .to_plain_array_view::<f32>()
            .map_err(|e| Error::Failed(format!("the model's output is not float32: {e}")))?;
        let shape = output.shape().to_vec();
        let c = self.options.class_names.len();
        let boxes = match shape.as_slice() {
            [1, rows, n] if *rows == 4 + c => (0..*n)
                .map(|i| {
                    let at = |r: usize| f64::from(output[[0, r, i]]);
                    let scores: Vec<f64> = (0..c).map(|k| at(4 + k)).collect();
                    ([at(0), at(1), at(2), at(3)], scores)
                })
                .collect::<Vec<_>>(),
            [1, n, cols] if *cols == 5 + c => (0..*n)
                .map(|i| {
                    let at = |k: usize| f64::from(output[[0, i, k]]);
                    let scores: Vec<f64> = (0..c).map(|k| at(4) * at(5 + k)).collect();
                    ([at(0), at(1), at(2), at(3)], scores)
                })
                .collect(),
            _ => {
                return Err(Error::InvalidInput(format!(
                    "{}: the output is {shape:?}; for {c} class names [1, {}, N] (YOLOv8) or [1, N, {}] (YOLOv5) is read",
                    self.path.display(),
                    4 + c,
                    5 + c
                )));
            }
        };
        // The best class of each box; fruit above the threshold.
        let mut candidates: Vec<([f64; 4], usize, f64)> = boxes
            .into_iter()
            .filter_map(|(b, scores)| {
                let (class, &score) =
                    scores.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
                let finite = b.iter().all(|v| v.is_finite()) && score.is_finite();
                (finite
                    && self.fruit.contains(&class)
                    && score >= self.options.score_threshold
                    && b[2] > 0.0
                    && b[3] > 0.0)
                    .then_some((b, class, score))
            })
            .collect();
        candidates.sort_by(|a, b| b.2.total_cmp(&a.2));
        let mut kept: Vec<([f64; 4], usize, f64)> = Vec::new();
        for candidate in candidates {
            let same = kept.iter().any(|k| {
                k.1 == candidate.1 && iou(&k.0, &candidate.0) > self.options.iou_threshold
            });
            if !same {
                kept.push(candidate);
            }
        }
        Ok(kept
            .into_iter()
            .map(|([cx, cy, bw, bh], _, score)| Detection {
                centre_px: Point2::new(
                    (cx - f64::from(pad_x)) / scale,
                    (cy - f64::from(pad_y)) / scale,
                ),
                radius_px: 0.5 * bw.max(bh) / scale,
                score,
                rough: None,
            })
            .collect())
    }
}

/// Intersection over union of two centre-size boxes.
fn iou(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let overlap = |ca: f64, sa: f64, cb: f64, sb: f64| {
        ((ca + sa / 2.0).min(cb + sb / 2.0) - (ca - sa / 2.0).max(cb - sb / 2.0)).max(0.0)
    };
    let inter = overlap(a[0], a[2], b[0], b[2]) * overlap(a[1], a[3], b[1], b[3]);
    let union = a[2] * a[3] + b[2] * b[3] - inter;
    if union > 0.0 { inter / union } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iou_of_boxes() {
        assert!((iou(&[0.0, 0.0, 2.0, 2.0], &[0.0, 0.0, 2.0, 2.0]) - 1.0).abs() < 1e-12);
        assert!((iou(&[0.0, 0.0, 2.0, 2.0], &[1.0, 0.0, 2.0, 2.0]) - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(iou(&[0.0, 0.0, 1.0, 1.0], &[5.0, 5.0, 1.0, 1.0]), 0.0);
    }
}

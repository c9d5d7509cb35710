//! Fruit in an RGB-D camera's images: the first step of the seed's
//! perception module (a detector in the colour image, the rough 3-D
//! position from the aligned depth), which the ALACS scan then refines.
//!
//! **Detect** ([`detect`]): a classical detector that needs no model file.
//! 1. Every pixel is classed fruit-coloured or not ([`colour`]): red,
//!    bicolour and yellow apple skin, not leaves, sky, bark, grey posts or
//!    white labels.
//! 2. The fruit-coloured pixels' Euclidean distance to the nearest other
//!    pixel: a round fruit's largest inscribed circle is its distance
//!    map's peak, and touching fruit keep a peak each ([`circles`]).
//! 3. Peaks become circles, strongest first; a peak inside a circle
//!    already taken is the same fruit. A circle is kept when it is round
//!    (the ring just outside it is mostly not fruit-coloured: a branch or a
//!    trunk continues through its ring, a fruit does not) and of a size a
//!    fruit can have.
//!
//! What it cannot do: green apples among green leaves (their colours
//! overlap), fruit smaller than [`DetectOptions::min_radius_px`], and a
//! fruit cut in two by a branch shows as two circles.
//!
//! **A learned detector** (cargo feature `onnx`: `OnnxDetector`): a
//! YOLO-style ONNX model the user brings, with its class names, run on the
//! CPU by tract (pure Rust); its boxes become the same [`Detection`]s.
//!
//! **Locate** ([`locate_detections`]): with a depth image aligned to the
//! colour image (uint16 millimetres, 0 no data; or float32 metres, NaN no
//! data: REP 118) and the colour camera, each fruit's centre: the depths
//! of its own fruit-coloured pixels (not the box, whose corners hold
//! leaves and background) near its middle, each moved back to the centre
//! by the sphere's depth there, their median (holes and flying pixels at
//! edges drop out); the radius from the circle at that depth; and the
//! covariance of the RGB-D camera's own error ([`depth`]).

mod circles;
pub mod colour;
pub mod depth;
mod error;
#[cfg(feature = "onnx")]
mod onnx;
mod output;

pub use circles::{DetectOptions, Detection, detect};
pub use depth::{DepthImage, DepthModel, RoughPosition, locate_detections};
pub use error::{Error, Result};
#[cfg(feature = "onnx")]
pub use onnx::{OnnxDetector, OnnxOptions};
pub use output::detections_json;

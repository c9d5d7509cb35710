//! The ALACS simulator: seeded scenes with ground truth, the test oracle of
//! every accuracy claim in alacs.
//!
//! So far it generates calibration samples like the seed paper's (Section
//! 4.1): a checkerboard at several poses 0.6-1.2 m from the camera, a few
//! laser points per view, depth noise and gross outliers, with the truth
//! (camera, laser, which rows are outliers) beside them.
//!
//! It also renders calibration sessions (FORMATS.md): a checkerboard at
//! random poses with the laser line across it at one or more slide
//! positions, through the real camera model (one ray per sub-pixel from
//! [`RayMap`], eq. (3)), Lambertian shading, the laser plane of eqs.
//! (7)-(8) with a Gaussian cross-section and shadows, and a noisy 8-bit
//! sensor, with session.yaml, camera.yaml and truth.json.
//!
//! # Examples
//! ```
//! use alacs_sim::{SampleOptions, simulate_samples};
//! use alacs_model::{Camera, Fidelity, LaserModel};
//!
//! let laser = LaserModel::seed_paper();
//! let options = SampleOptions { outlier_fraction: 0.2, ..SampleOptions::default() };
//! let sim = simulate_samples(&Camera::blackfly_s_5mp(), &laser, &options).unwrap();
//! assert_eq!(sim.samples.len(), 30);
//! assert_eq!(sim.outliers.len(), 6);
//! ```
//!
//! A small calibration session (a tenth of the 5 MP camera's resolution):
//! ```
//! use alacs_sim::{SessionOptions, simulate_session};
//! use alacs_model::{Camera, Fidelity, LaserModel};
//!
//! let laser = LaserModel::seed_paper();
//! let options = SessionOptions { n_views: 2, scale: 0.1, seed: 7, ..SessionOptions::default() };
//! let session = simulate_session(&Camera::blackfly_s_5mp(), &laser, &options)?;
//! let image = session.render_view(0)?; // the board with the laser line, RGB8
//! assert_eq!(image.dimensions(), (245, 205));
//! // session.write(dir) writes session.yaml, camera.yaml, truth.json and the PNGs.
//! # Ok::<(), alacs_sim::Error>(())
//! ```

mod bayer;
mod board;
mod error;
mod orchard;
mod progress;
mod render;
mod rgbd;
mod samples;
mod scan;
mod session;
mod slide;
mod truth;
mod variation;

pub use board::{BoardScene, BoardsScene, CHARUCO_MARKER_PER_SQUARE, Checkerboard};
pub use error::{
    Error, MAX_SAMPLE_ROW_BYTES, MAX_SAMPLES, MAX_SCALE, MAX_SESSION_VIEWS, MAX_SLIDE_POSITIONS,
    Result,
};
pub use orchard::{
    Appearance, AppleForm, CameraRayGrid, Hit, Kind, MAX_CLUSTER, Material, Object, OrchardOptions,
    OrchardScene, Shape, orchard_scene, value_noise,
};
pub use render::{
    AmbientCache, Exposure, IRRADIANCE_UNIT_W_PER_M2, LaserLight, LaserStripe, Lighting,
    MAX_GAIN_DB, MAX_SUPERSAMPLING, REFERENCE_EXPOSURE_US, RayMap, RenderOptions, Scene, Sensor,
    SubpixelPattern, SurfaceHit, mix_seed,
};
pub use rgbd::{DepthMillimetres, RgbdApple, RgbdErrors, RgbdView};
pub use samples::{SampleOptions, SimulatedSamples, simulate_samples};
pub use scan::{
    RenderedScan, ScanFrame, ScanOptions, SimulatedScan, simulate_rendered_scan, simulate_scan,
};
pub use session::{
    MIN_CORNER_BORDER_PX, MIN_VISIBLE_CORNER_FRACTION, RgbdOptions, SessionOptions, SessionView,
    SimulatedSession, simulate_session,
};
pub use slide::{MAX_SLIDE_ANGLE_DEG, SlideError};
pub use truth::{camera_to_json, laser_to_json};
pub use variation::{DrawRange, FruitColour, FruitColourRanges, RigVariation, TakeOut};

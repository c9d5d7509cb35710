//! The command line, as close to what the user typed as possible; each
//! command turns these into validated library options.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};

/// alacs: the Active LAser-Camera Scanner. Millimetre fruit positions from a
/// line laser on a slide and a camera.
#[derive(Debug, Parser)]
#[command(name = "alacs", version, about, long_about = None)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Calibrate the camera (intrinsics), the laser (the laser-camera
    /// extrinsics and slide scale) or the RGB-D camera's pose.
    #[command(subcommand)]
    Calibrate(CalibrateCommand),
    /// Map laser pixels to 3-D points in the camera frame (eqs. (3), (7), (8)).
    Triangulate(TriangulateArgs),
    /// Extract the laser stripe of one frame (u_px,v_px,strength), to check exposure.
    Stripe(StripeArgs),
    /// Locate the target fruit from a scan folder (scan.yaml and its frames).
    Localize(LocalizeArgs),
    /// Find fruit in an RGB-D camera's colour image, and with its aligned
    /// depth and camera their rough 3-D positions.
    Detect(DetectArgs),
    /// Reproduce the seed paper's experiments as reports: Table 1 with
    /// residual plots, the accuracy box plots per slide position.
    #[command(subcommand)]
    Evaluate(EvaluateCommand),
    /// Write a self-contained HTML report (a page with its images beside it):
    /// a calibration against its session, or a scan's localization.
    #[command(subcommand)]
    Report(ReportCommand),
    /// Generate simulated data with ground truth.
    #[command(subcommand)]
    Simulate(SimulateCommand),
    /// Run the main job on the built-in simulator and print the results.
    Demo(DemoArgs),
    /// Start a calibration session from a folder of images.
    #[command(subcommand)]
    Session(SessionCommand),
    /// Scan a fruit with the rig and locate it: the seed's 5-frame active scan
    /// from the RGB-D camera's rough position, on the simulated rig (--sim) or
    /// a rig.toml (--rig).
    Scan(ScanArgs),
    /// The rig of a rig.toml: check its devices.
    #[command(subcommand)]
    Rig(RigCommand),
    /// Recorded scans (ROS 2 bags, MCAP): to and from scan folders.
    #[command(subcommand)]
    Bag(BagCommand),
    /// Run the ROS 2 node: the action <ns>/localize_fruit (alacs_msgs/action/LocalizeFruit),
    /// the RGB-D front end and <ns>/scan_detected, its topics and parameters, until SIGINT
    /// or SIGTERM (`alacs formats`).
    Ros(Box<RosArgs>),
    /// Rewrite a file in another tool's layout.
    #[command(subcommand)]
    Convert(ConvertCommand),
    /// Print the contract: every file this binary reads and writes, every
    /// `--json` object and the exit codes (docs/FORMATS.md, built in).
    Formats,
}

/// `alacs convert`
#[derive(Debug, Subcommand)]
pub enum ConvertCommand {
    /// A camera.yaml (ROS, OpenCV FileStorage, or their usual key names:
    /// cameraMatrix/distCoeffs, K/D) to the ROS or the OpenCV layout.
    Camera(ConvertCameraArgs),
}

/// `alacs convert camera`
#[derive(Debug, Args)]
pub struct ConvertCameraArgs {
    /// The camera file to read.
    #[arg(long, value_name = "FILE")]
    pub input: PathBuf,
    /// Where to write it (may be the input).
    #[arg(short, long, value_name = "FILE")]
    pub output: PathBuf,
    /// The layout to write.
    #[arg(long, value_enum, default_value_t = CameraFormatArg::Opencv)]
    pub format: CameraFormatArg,
    /// Print one JSON object (`alacs formats`) on standard output instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The layout of a written camera.yaml.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum CameraFormatArg {
    /// ROS camera_calibration_parsers YAML (camera_matrix, distortion_model, ...).
    Ros,
    /// OpenCV FileStorage YAML (%YAML:1.0, !!opencv-matrix), as cv2.FileStorage reads it.
    Opencv,
}

impl From<CameraFormatArg> for alacs::model::CameraFileFormat {
    fn from(format: CameraFormatArg) -> Self {
        match format {
            CameraFormatArg::Ros => alacs::model::CameraFileFormat::Ros,
            CameraFormatArg::Opencv => alacs::model::CameraFileFormat::OpenCv,
        }
    }
}

impl Command {
    /// Whether `--json` was given: standard output then carries one JSON
    /// object, also when the command fails (`alacs formats`).
    pub fn json(&self) -> bool {
        match self {
            Command::Calibrate(CalibrateCommand::Laser(a)) => a.json,
            Command::Calibrate(CalibrateCommand::Camera(a)) => a.json,
            Command::Calibrate(CalibrateCommand::Rgbd(a)) => a.json,
            Command::Triangulate(a) => a.json,
            Command::Stripe(a) => a.json,
            Command::Localize(a) => a.json,
            Command::Detect(a) => a.json,
            Command::Evaluate(EvaluateCommand::Calibration(a)) => a.json,
            Command::Evaluate(EvaluateCommand::Accuracy(a)) => a.json,
            Command::Report(ReportCommand::Calibration(a)) => a.json,
            Command::Report(ReportCommand::Scan(a)) => a.json,
            Command::Simulate(SimulateCommand::Samples(a)) => a.json,
            Command::Simulate(SimulateCommand::Session(a)) => a.json,
            Command::Simulate(SimulateCommand::Scan(a)) => a.json,
            Command::Simulate(SimulateCommand::Rgbd(a)) => a.json,
            Command::Demo(a) => a.json,
            Command::Scan(a) => a.json,
            Command::Rig(RigCommand::Check(a)) => a.json,
            Command::Bag(BagCommand::Export(a)) => a.json,
            Command::Bag(BagCommand::Import(a)) => a.json,
            Command::Session(SessionCommand::Init(a)) => a.json,
            Command::Ros(a) => a.json,
            Command::Convert(ConvertCommand::Camera(a)) => a.json,
            Command::Formats => false,
        }
    }
}

/// `alacs session ...`
#[derive(Debug, Subcommand)]
pub enum SessionCommand {
    /// Write DIR/session.yaml (`alacs formats`) listing the folder's PNG and
    /// JPEG images in name order; `X_off.png` beside `X.png` becomes X's
    /// laser-off image.
    Init(SessionInitArgs),
}

/// `alacs session init`
#[derive(Debug, Args)]
pub struct SessionInitArgs {
    /// The folder of board images; session.yaml is written into it.
    pub dir: PathBuf,
    /// Inner corners of the checkerboard, COLSxROWS (as OpenCV counts them, e.g. 9x6).
    #[arg(long, value_name = "COLSxROWS", value_parser = crate::values::board_corners)]
    pub board: (usize, usize),
    /// Square size in mm, or X,Y for squares that are not exactly square.
    #[arg(long, value_name = "S", allow_hyphen_values = true, value_parser = crate::values::square_mm)]
    pub square_mm: (f64, f64),
    /// Slide travel d of every view, mm (edit session.yaml for views taken
    /// at different slide positions).
    #[arg(long, value_name = "D", default_value_t = 0.0, value_parser = slide_mm)]
    pub slide_mm: f64,
    /// A ChArUco board: its markers' OpenCV dictionary (e.g. DICT_5X5_100);
    /// --board still counts inner corners (squares - 1 each way).
    #[arg(long, value_name = "DICTIONARY", requires = "marker_mm", value_parser = crate::values::dictionary)]
    pub charuco: Option<alacs::model::ArucoDictionary>,
    /// A ChArUco marker's side in mm (OpenCV's markerLength).
    #[arg(long, value_name = "M", requires = "charuco")]
    pub marker_mm: Option<f64>,
    /// Replace an existing session.yaml.
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object on standard output: {"session", "n_views", "images"}.
    #[arg(long)]
    pub json: bool,
}

/// `alacs calibrate ...`
#[derive(Debug, Subcommand)]
pub enum CalibrateCommand {
    /// Fit (alpha, L0, beta) (the seed paper's eq. (9)) to samples u_n,v_n,z_mm[,slide_mm],
    /// or to dense samples from a session's images with a calibrated camera.
    Laser(CalibrateLaserArgs),
    /// Calibrate the camera (intrinsics, plumb_bob distortion) from a session's board views.
    Camera(CalibrateCameraArgs),
    /// Calibrate the RGB-D camera's pose in the ALACS camera frame
    /// (alacs_from_rgbd) from board views both cameras saw (session.yaml's
    /// image_rgbd).
    Rgbd(CalibrateRgbdArgs),
}

/// `alacs calibrate rgbd`
#[derive(Debug, Args)]
pub struct CalibrateRgbdArgs {
    /// The session folder (views with `image_rgbd`).
    #[arg(long, value_name = "DIR")]
    pub session: PathBuf,
    /// The ALACS camera's calibration.
    #[arg(long, value_name = "FILE")]
    pub camera: PathBuf,
    /// The RGB-D camera's colour camera calibration.
    #[arg(long, value_name = "FILE")]
    pub rgbd_camera: PathBuf,
    /// Print one JSON object: {"alacs_from_rgbd": {"xyz_mm", "rpy_deg",
    /// "matrix"}, "poses", "rejected", "rotation_rms_deg", "translation_rms_mm"}.
    #[arg(long)]
    pub json: bool,
}

/// `alacs evaluate ...`
#[derive(Debug, Subcommand)]
pub enum EvaluateCommand {
    /// The seed paper's Table 1: all four calibration methods on samples (or on
    /// a session's dense samples), as text, JSON and a residual plot per method.
    Calibration(EvaluateCalibrationArgs),
    /// The seed paper's accuracy experiment: a session's board views at several
    /// slide positions, each laser point triangulated with the laser model and
    /// compared with its ray on the board plane; box plots per slide position.
    Accuracy(EvaluateAccuracyArgs),
}

/// `alacs evaluate calibration`
#[derive(Debug, Args)]
pub struct EvaluateCalibrationArgs {
    /// Samples CSV: header u_n,v_n,z_mm and optionally slide_mm and pose.
    #[arg(
        long,
        value_name = "FILE",
        required_unless_present = "session",
        conflicts_with = "session"
    )]
    pub samples: Option<PathBuf>,
    /// Session folder: dense laser samples from its images (as `calibrate laser --session`).
    #[arg(long, value_name = "DIR")]
    pub session: Option<PathBuf>,
    /// The calibrated camera.yaml of the session (default: calibrate the camera
    /// from the session's board views first).
    #[arg(long, value_name = "FILE", requires = "session")]
    pub camera: Option<PathBuf>,
    /// The controls of that camera calibration (without --camera).
    #[command(flatten)]
    pub controls: CameraControlArgs,
    /// Folder for the artefacts (created): calibration_table1.txt,
    /// calibration.json, calibration_residuals_method{1..4}.png and .svg.
    #[arg(long, value_name = "DIR", default_value = "evaluation")]
    pub out: PathBuf,
    #[command(flatten)]
    pub folder: ForceArg,
    /// RANSAC inlier threshold epsilon on |z - z_hat|, in mm.
    #[arg(
        long,
        value_name = "E",
        default_value_t = alacs::calib::DEFAULT_THRESHOLD_MM,
        value_parser = positive_up_to(MAX_THRESHOLD_MM)
    )]
    pub threshold_mm: f64,
    /// RANSAC seed (same seed, same result).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Print one JSON object on standard output instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Which laser points of a view `evaluate accuracy` uses.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum PointsArg {
    /// Every stripe pixel on the board (one per image row).
    All,
    /// Three per view, evenly spaced along the stripe, as the seed paper.
    #[value(name = "3")]
    Three,
}

/// `alacs report ...`
#[derive(Debug, Subcommand)]
pub enum ReportCommand {
    /// A camera and a laser against a calibration session: intrinsics, the
    /// laser and Table 1 on the session's samples, per view the corners, the
    /// board pose's RMS and the residuals, residual and accuracy plots, and
    /// every view's image with the corners and the stripe drawn over it.
    Calibration(ReportCalibrationArgs),
    /// A scan's localization: the result, the candidates, and every frame
    /// with its search region, stripe, fruit points, candidate and the
    /// fitted sphere drawn over it.
    Scan(ReportScanArgs),
}

/// `alacs report calibration`
#[derive(Debug, Args)]
pub struct ReportCalibrationArgs {
    /// Session folder (session.yaml beside the images).
    #[arg(long, value_name = "DIR")]
    pub session: PathBuf,
    /// The calibrated camera (camera.yaml).
    #[arg(long, value_name = "FILE")]
    pub camera: PathBuf,
    /// The calibrated laser (laser.yaml).
    #[arg(long, value_name = "FILE")]
    pub laser: PathBuf,
    /// Folder for the report (created): index.html, images/, plots.
    #[arg(long, value_name = "DIR", default_value = "report")]
    pub out: PathBuf,
    #[command(flatten)]
    pub folder: ForceArg,
    /// Print one JSON object on standard output: {"html": .., "files": [..], ..}.
    #[arg(long)]
    pub json: bool,
}

/// `alacs report scan`
#[derive(Debug, Args)]
pub struct ReportScanArgs {
    /// Scan folder (scan.yaml beside the frames).
    #[arg(long, value_name = "DIR")]
    pub scan: PathBuf,
    /// The calibrated camera (camera.yaml).
    #[arg(long, value_name = "FILE")]
    pub camera: PathBuf,
    /// The calibrated laser (laser.yaml).
    #[arg(long, value_name = "FILE")]
    pub laser: PathBuf,
    /// How the final position is chosen.
    #[arg(long, value_enum, default_value_t = LocalizeMethodArg::Fused)]
    pub method: LocalizeMethodArg,
    #[command(flatten)]
    pub rough_error: RoughErrorArgs,
    /// Which fruit of a scan naming several (scan.yaml's `targets`, from 0)
    /// the report is about.
    #[arg(long, value_name = "K", default_value_t = 0)]
    pub target: usize,
    /// Folder for the report (created): index.html and images/.
    #[arg(long, value_name = "DIR", default_value = "report")]
    pub out: PathBuf,
    #[command(flatten)]
    pub folder: ForceArg,
    /// Print one JSON object on standard output: {"html": .., "files": [..],
    /// "localization": {...as localize --json}}.
    #[arg(long)]
    pub json: bool,
}

/// `alacs evaluate accuracy`
#[derive(Debug, Args)]
pub struct EvaluateAccuracyArgs {
    /// Session folder (session.yaml beside the images) with views at several slide positions.
    #[arg(long, value_name = "DIR")]
    pub session: PathBuf,
    /// The calibrated camera (camera.yaml).
    #[arg(long, value_name = "FILE")]
    pub camera: PathBuf,
    /// The calibrated laser to evaluate (laser.yaml).
    #[arg(long, value_name = "FILE")]
    pub laser: PathBuf,
    /// Folder for the artefacts (created): accuracy.json, accuracy_points.csv,
    /// accuracy_boxplots.png and .svg.
    #[arg(long, value_name = "DIR", default_value = "evaluation")]
    pub out: PathBuf,
    #[command(flatten)]
    pub folder: ForceArg,
    /// Points per view: all, or 3 as the seed paper.
    #[arg(long, value_enum, default_value = "all")]
    pub points: PointsArg,
    /// Stripe-centre noise (px) for the predicted noise floor
    /// sigma_z = z^2 cos(alpha) sigma_px / (f L); default: measured from the session.
    #[arg(long, value_name = "PX")]
    pub sigma_px: Option<f64>,
    /// Print one JSON object on standard output instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `alacs calibrate camera`
#[derive(Debug, Args)]
pub struct CalibrateCameraArgs {
    /// Session folder (session.yaml beside the images).
    #[arg(long, value_name = "DIR")]
    pub session: PathBuf,
    /// Write the calibrated camera.yaml here.
    #[arg(short, long, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// The layout of --output: ROS camera_calibration_parsers YAML, or
    /// OpenCV FileStorage YAML (cv2.FileStorage reads it; alacs reads both).
    #[arg(long, value_enum, default_value_t = CameraFormatArg::Ros, requires = "output")]
    pub format: CameraFormatArg,
    /// OpenCV's camera calibration controls.
    #[command(flatten)]
    pub controls: CameraControlArgs,
    /// Print one JSON object (`alacs formats`) on standard output instead of text.
    #[arg(long)]
    pub json: bool,
}

/// OpenCV's camera calibration controls (`calibrate camera`, and
/// `evaluate calibration --session` when it calibrates the camera).
#[derive(Debug, Args)]
pub struct CameraControlArgs {
    /// The distortion model fitted (default: the --initial camera's, else
    /// plumb_bob).
    #[arg(long, value_enum)]
    pub distortion: Option<DistortionArg>,
    /// Intrinsics held instead of fitted, as OpenCV's flags (comma-separated
    /// or repeated): k3 (CALIB_FIX_K3), tangential (CALIB_ZERO_TANGENT_DIST),
    /// aspect (CALIB_FIX_ASPECT_RATIO), principal-point
    /// (CALIB_FIX_PRINCIPAL_POINT); held values come from --initial, else
    /// 0, 0, fx/fy = 1 and the image centre.
    #[arg(long, value_enum, value_delimiter = ',', value_name = "WHAT")]
    pub fix: Vec<FixArg>,
    /// A starting camera.yaml (OpenCV's CALIB_USE_INTRINSIC_GUESS): its
    /// intrinsics and distortion start the fit and give the held values.
    #[arg(long, value_name = "FILE")]
    pub initial: Option<PathBuf>,
}

impl CameraControlArgs {
    /// Whether any control was given.
    pub fn any(&self) -> bool {
        self.distortion.is_some() || !self.fix.is_empty() || self.initial.is_some()
    }
}

/// What finds the fruit in the RGB-D camera's images (`alacs ros`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum RgbdDetectorArg {
    /// alacs-detect's classical detector (red, bicolour and yellow apples).
    Builtin,
    /// Another detector's vision_msgs/Detection2DArray on <ns>/detections_2d.
    Topic,
    /// None: no RGB-D subscriptions.
    None,
}

/// A distortion model `calibrate camera` fits.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum DistortionArg {
    /// k1, k2, p1, p2, k3 (OpenCV's default).
    #[value(name = "plumb_bob")]
    PlumbBob,
    /// k1, k2, p1, p2, k3, k4, k5, k6 (OpenCV's CALIB_RATIONAL_MODEL).
    #[value(name = "rational_polynomial")]
    RationalPolynomial,
}

/// An intrinsic `calibrate camera` can hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FixArg {
    /// k3 (CALIB_FIX_K3).
    K3,
    /// p1 = p2 = 0 (CALIB_ZERO_TANGENT_DIST).
    Tangential,
    /// fx / fy (CALIB_FIX_ASPECT_RATIO).
    Aspect,
    /// cx, cy (CALIB_FIX_PRINCIPAL_POINT).
    PrincipalPoint,
}

/// The residual minimized by the least-squares step.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ResidualArg {
    /// z - z_hat, the seed paper's eq. (9) (default).
    Depth,
    /// Distance of the measured point from the laser plane.
    Plane,
}

/// `alacs calibrate laser`
#[derive(Debug, Args)]
pub struct CalibrateLaserArgs {
    /// Samples CSV: header u_n,v_n,z_mm and optionally slide_mm and pose.
    #[arg(
        long,
        value_name = "FILE",
        required_unless_present = "session",
        conflicts_with = "session"
    )]
    pub samples: Option<PathBuf>,
    /// Session folder: laser samples from its images (board pose per view,
    /// every stripe pixel on the board); needs --camera.
    #[arg(long, value_name = "DIR", requires = "camera")]
    pub session: Option<PathBuf>,
    /// The calibrated camera.yaml of the session's camera.
    #[arg(long, value_name = "FILE", requires = "session")]
    pub camera: Option<PathBuf>,
    /// Take the camera as exact in the standard deviations (it was calibrated
    /// from far more views than the session holds); by default each bootstrap
    /// replicate re-calibrates it from the session's board poses.
    #[arg(long, requires = "session")]
    pub camera_exact: bool,
    /// Write the session's laser samples to this CSV (u_n,v_n,z_mm,slide_mm,pose).
    #[arg(long, value_name = "FILE", requires = "session")]
    pub export_samples: Option<PathBuf>,
    /// The seed paper's method: 1 low fidelity, 2 low fidelity + RANSAC,
    /// 3 high fidelity, 4 high fidelity + RANSAC.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(1..=4))]
    pub method: u8,
    /// Run all four methods and print the paper's Table 1.
    #[arg(long)]
    pub compare: bool,
    /// RANSAC inlier threshold epsilon on |z - z_hat|, in mm.
    #[arg(
        long,
        value_name = "E",
        default_value_t = alacs::calib::DEFAULT_THRESHOLD_MM,
        value_parser = positive_up_to(MAX_THRESHOLD_MM)
    )]
    pub threshold_mm: f64,
    /// RANSAC seed (same seed, same result).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// RANSAC cap on hypotheses (k_max).
    #[arg(long, value_name = "K", default_value_t = 2000)]
    pub max_iterations: usize,
    /// Residual the least-squares fit minimizes.
    #[arg(long, value_enum, default_value = "depth")]
    pub residual: ResidualArg,
    /// Hold the slide scale k at 1 (the seed paper's L = L0 - d) instead of
    /// fitting L = L0 - k d where the samples span two or more slide positions.
    #[arg(long)]
    pub hold_slide_scale: bool,
    /// Print one JSON object (`alacs formats`) on standard output instead of text.
    #[arg(long)]
    pub json: bool,
    /// Write the fitted laser.yaml here (the --method result; with --compare, Method 4 unless --method says otherwise).
    #[arg(short, long, value_name = "FILE")]
    pub output: Option<PathBuf>,
}

/// `alacs stripe`
#[derive(Debug, Args)]
pub struct StripeArgs {
    /// The frame (PNG or JPEG, colour).
    #[arg(long, value_name = "FILE")]
    pub image: PathBuf,
    /// The same view with the laser off: the score becomes red(on) - red(off).
    #[arg(long, value_name = "FILE")]
    pub laser_off: Option<PathBuf>,
    /// Search only this rectangle: u0,v0,u1,v1 (pixels, inclusive).
    #[arg(long, value_name = "U0,V0,U1,V1", allow_hyphen_values = true, value_parser = crate::values::roi)]
    pub roi: Option<[u32; 4]>,
    /// Smallest peak score counted as laser (DN); default 12, or 10 with --orchard.
    #[arg(long, value_name = "DN")]
    pub min_strength: Option<f32>,
    /// An orchard frame: the settings `alacs localize` uses (a line detector
    /// against the fruit's own colour, up to 3 peaks per row, clipped-line and
    /// colour checks) instead of those for a calibration board.
    #[arg(long)]
    pub orchard: bool,
    /// Print one JSON object on standard output instead of CSV.
    #[arg(long)]
    pub json: bool,
}

/// `alacs triangulate`
#[derive(Debug, Args)]
pub struct TriangulateArgs {
    /// camera.yaml (ROS camera_calibration_parsers format).
    #[arg(long, value_name = "FILE")]
    pub camera: PathBuf,
    /// laser.yaml.
    #[arg(long, value_name = "FILE")]
    pub laser: PathBuf,
    /// Slide travel d in mm (L = L0 - k d).
    #[arg(long, value_name = "D", value_parser = slide_mm)]
    pub slide_mm: f64,
    /// Pixels CSV with header u_px,v_px.
    #[arg(long, value_name = "FILE")]
    pub pixels: PathBuf,
    /// Print {"points_mm": [[x, y, z], ...]} instead of CSV.
    #[arg(long)]
    pub json: bool,
}

/// `alacs simulate ...`
#[derive(Debug, Subcommand)]
pub enum SimulateCommand {
    /// Calibration samples like the seed paper's (samples.csv + truth.json).
    Samples(SimulateSamplesArgs),
    /// A rendered calibration session: checkerboard views with the laser
    /// line (session.yaml, camera.yaml, PNGs, truth.json).
    Session(SimulateSessionArgs),
    /// An orchard scan: five frames of an apple with the laser stepping across it
    /// (scan.yaml, camera.yaml, laser.yaml, frames, truth.json).
    Scan(SimulateScanArgs),
    /// What the RGB-D camera sees of the scene `scan --sim --seed N` scans:
    /// color.png, depth.png (16-bit mm, aligned), camera.yaml, truth.json.
    Rgbd(SimulateRgbdArgs),
}

/// `alacs simulate samples`
#[derive(Debug, Args)]
pub struct SimulateSamplesArgs {
    /// Output folder (created).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    #[command(flatten)]
    pub folder: ForceArg,
    /// Seed: same seed, same bytes.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Board poses.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=alacs::sim::MAX_SAMPLES as i64))]
    pub views: u32,
    /// Laser points per view (views x points at most 10,000,000).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=alacs::sim::MAX_SAMPLES as i64))]
    pub points_per_view: u32,
    /// Board distance range MIN,MAX in mm.
    #[arg(long, value_name = "MIN,MAX", default_value = "600,1200", value_parser = crate::values::distance_range_mm)]
    pub depth_mm: (f64, f64),
    /// Standard deviation of the depth noise, mm.
    #[arg(long, default_value_t = 0.5, value_parser = number_in(0.0, 1000.0))]
    pub noise_mm: f64,
    /// Fraction of samples made outliers (0 to 1).
    #[arg(long, default_value_t = 0.0, value_parser = number_in(0.0, 1.0))]
    pub outliers: f64,
    /// Slide positions in mm, cycled over the views, e.g. 0,50,100.
    #[arg(long, value_name = "D,D,...", default_value = "0", value_delimiter = ',', allow_hyphen_values = true, value_parser = slide_mm)]
    pub slides: Vec<f64>,
    /// The true camera and laser.
    #[command(flatten)]
    pub truth: TruthArgs,
    /// Print a JSON summary on standard output.
    #[arg(long)]
    pub json: bool,
}

/// `alacs simulate session`
#[derive(Debug, Args)]
pub struct SimulateSessionArgs {
    /// Output folder (created).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    #[command(flatten)]
    pub folder: ForceArg,
    /// Seed: same seed, same bytes.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Board poses.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=alacs::sim::MAX_SESSION_VIEWS as i64))]
    pub views: u32,
    /// Slide positions in mm; every pose is rendered at each, e.g. 0,50,100,150,200.
    #[arg(long, value_name = "D,D,...", default_value = "0", value_delimiter = ',', allow_hyphen_values = true, value_parser = slide_mm)]
    pub slides: Vec<f64>,
    /// Also render every pose with the laser off (viewNN_off.png).
    #[arg(long)]
    pub laser_off: bool,
    /// Render the camera resized by this factor (camera.yaml holds the resized camera).
    #[arg(long, value_name = "F", default_value_t = 1.0, value_parser = positive_up_to(alacs::sim::MAX_SCALE))]
    pub scale: f64,
    /// Also render every pose from an RGB-D camera's colour camera (1280 x
    /// 720, 70 deg) at this pose in the ALACS camera frame: x,y,z mm, roll,
    /// pitch, yaw deg (as --alacs-from-rgbd); writes viewNN_rgbd.png,
    /// rgbd_camera.yaml and the truth (`alacs calibrate rgbd`).
    #[arg(long, value_name = "X,Y,Z,ROLL,PITCH,YAW", allow_hyphen_values = true, value_parser = crate::values::pose)]
    pub rgbd_pose: Option<nalgebra::Isometry3<f64>>,
    /// Board centre distance range MIN,MAX in mm.
    #[arg(long, value_name = "MIN,MAX", default_value = "600,1200", value_parser = crate::values::distance_range_mm)]
    pub depth_mm: (f64, f64),
    /// Largest board tilt away from facing the camera, degrees.
    #[arg(long, default_value_t = 40.0, value_parser = number_in(0.0, 89.0))]
    pub max_tilt_deg: f64,
    /// Render a ChArUco board: an ArUco marker of this OpenCV dictionary
    /// (e.g. DICT_5X5_100) in every white square, its side 0.75 of a square.
    #[arg(long, value_name = "DICTIONARY", value_parser = crate::values::dictionary)]
    pub charuco: Option<alacs::model::ArucoDictionary>,
    /// Let the board reach past the image's border, poses anywhere in the
    /// image: a ChArUco board with at least 40 % of its inner corners in it,
    /// a checkerboard with every inner corner 8 px inside (its outer squares
    /// may be cut).
    #[arg(long)]
    pub cut_by_border: bool,
    /// Put a second board in every view, as in photographs of real rigs: a
    /// 6 x 4 ChArUco board (30 mm squares, DICT_5X5_100 or, where the
    /// target's markers are 5 x 5, DICT_4X4_50) leaning back 50-70
    /// deg in front of and under the target, hiding none of its corners
    /// (truth.json: second_board, camera_from_second_board).
    #[arg(long)]
    pub second_board: bool,
    /// The simulated slide.
    #[command(flatten)]
    pub slide: SlideArgs,
    /// How images are rendered.
    #[command(flatten)]
    pub render: RenderArgs,
    /// The true camera and laser.
    #[command(flatten)]
    pub truth: TruthArgs,
    /// Print a JSON summary on standard output.
    #[arg(long)]
    pub json: bool,
}

/// `--force` of every command that writes an output folder.
#[derive(Debug, Args)]
pub struct ForceArg {
    /// Write into the output folder even if it holds files this command did
    /// not write (they stay, unless an earlier run of it wrote them).
    #[arg(long)]
    pub force: bool,
}

/// The simulated slide's own error.
#[derive(Debug, Args)]
pub struct SlideArgs {
    /// The slide's scale error: the laser's travel per commanded mm along
    /// the slide's axis (1: the seed paper's perfect slide).
    #[arg(long, value_name = "S", default_value_t = 1.0, value_parser = number_in(0.8, 1.25))]
    pub slide_scale: f64,
    /// The angle of the slide's axis to the laser's baseline, degrees (in
    /// the plane of the baseline and the optical axis): the stripe shows
    /// L = L0 - k d with k = scale cos(angle); truth.json's laser holds k.
    #[arg(long, value_name = "DEG", default_value_t = 0.0, allow_hyphen_values = true,
          value_parser = number_in(-alacs::sim::MAX_SLIDE_ANGLE_DEG, alacs::sim::MAX_SLIDE_ANGLE_DEG))]
    pub slide_angle_deg: f64,
}

impl From<&SlideArgs> for alacs::sim::SlideError {
    fn from(args: &SlideArgs) -> Self {
        alacs::sim::SlideError { scale: args.slide_scale, angle_deg: args.slide_angle_deg }
    }
}

/// A simulated orchard scene: an apple behind leaves, in shade or sun.
#[derive(Debug, Args)]
#[command(next_help_heading = "Simulated scene (--sim, and a rig.toml's \"sim\" devices)")]
pub struct SceneArgs {
    /// Seed: same seed, same scene and bytes.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Fraction of the fruit hidden behind leaves (0 to 1).
    #[arg(long, value_name = "F", default_value_t = 0.0, value_parser = number_in(0.0, 1.0))]
    pub occlusion: f64,
    /// Direct sunlight instead of shade.
    #[arg(long)]
    pub sun: bool,
    /// Other apples touching the target, beside or behind it (a cluster of
    /// 1 + N apples), 0-3.
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=3))]
    pub cluster: u8,
    /// Branches crossing in front of the fruit, 0-4.
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=4))]
    pub front_branches: u8,
    /// Every apple of the cluster (`--cluster N`) is a target, each with a
    /// rough position of the simulated RGB-D camera, all in one sweep
    /// (scan.yaml's `targets`).
    #[arg(long)]
    pub all_targets: bool,
    /// Fruit distance range MIN,MAX in mm.
    #[arg(long, value_name = "MIN,MAX", default_value = "600,1200", value_parser = crate::values::distance_range_mm)]
    pub depth_mm: (f64, f64),
    /// Render the camera resized by this factor (camera.yaml holds the resized camera).
    #[arg(long, value_name = "F", default_value_t = 1.0, value_parser = positive_up_to(alacs::sim::MAX_SCALE))]
    pub scale: f64,
    /// Draw from the seed what real rigs and fruit vary in: the laser's
    /// width and power, light in the flesh, fruit and leaf colours, lens
    /// blur, sensor noise, exposure, the calibration's error and the rough
    /// position's (docs/ACCURACY.md lists the ranges). The images show the
    /// drawn rig; camera.yaml and laser.yaml hold the calibration the
    /// localizer is given, truth.json what was drawn.
    #[arg(long)]
    pub randomize: bool,
}

/// The truth a simulator renders with.
#[derive(Debug, Args)]
pub struct TruthArgs {
    /// Camera to render with (default: a FLIR Blackfly S 5 MP-like camera).
    #[arg(long, value_name = "FILE")]
    pub camera: Option<PathBuf>,
    /// Laser to render with (overrides --alpha-deg, --beta-deg, --l0-mm).
    #[arg(long, value_name = "FILE")]
    pub laser: Option<PathBuf>,
    /// True alpha, degrees.
    #[arg(long, default_value_t = 19.07, value_parser = number_in(-89.0, 89.0))]
    pub alpha_deg: f64,
    /// True beta, degrees.
    #[arg(long, default_value_t = 0.69, value_parser = number_in(-45.0, 45.0))]
    pub beta_deg: f64,
    /// True L0, mm.
    #[arg(long, default_value_t = 381.98, value_parser = positive_up_to(alacs::model::MAX_ABS_SLIDE_MM))]
    pub l0_mm: f64,
}

/// How the simulator renders images.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Width (sigma) of the laser stripe's Gaussian cross-section, pixels.
    #[arg(long, default_value_t = 1.5, value_parser = positive_up_to(100.0))]
    pub stripe_sigma_px: f64,
    /// Rays per pixel along each axis (s x s per pixel).
    #[arg(long, value_name = "S", default_value_t = 3)]
    pub supersampling: usize,
    /// Turn the sensor's shot and read noise off (8-bit rounding remains).
    #[arg(long)]
    pub no_noise: bool,
}

/// `alacs simulate scan`
#[derive(Debug, Args)]
pub struct SimulateScanArgs {
    /// Output folder (created).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    #[command(flatten)]
    pub folder: ForceArg,
    /// The orchard scene.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Also render every frame with the laser off (frameN_off.png).
    #[arg(long)]
    pub laser_off: bool,
    /// Also place fruit the slide cannot sweep as planned (by default the
    /// scene is redrawn until the seed's plan fits the stroke unshifted).
    #[arg(long)]
    pub anywhere: bool,
    /// Write JPEG frames of this quality (1-100) instead of PNG.
    #[arg(long, value_name = "Q", value_parser = clap::value_parser!(u8).range(1..=100))]
    pub jpeg: Option<u8>,
    /// The frames' fixed exposure time, microseconds, as a camera without
    /// metering takes them (1000 us: at 0 dB a white surface under 100 W/m^2
    /// in the red band fills the pixel; a sunlit red apple clips with the laser on it).
    #[arg(long, value_name = "US", default_value_t = alacs::sim::REFERENCE_EXPOSURE_US, value_parser = positive_up_to(10.0e6))]
    pub exposure_us: f64,
    /// The frames' analogue gain, dB.
    #[arg(long, value_name = "DB", default_value_t = 0.0, value_parser = number_in(0.0, alacs::sim::MAX_GAIN_DB))]
    pub gain_db: f64,
    /// The simulated slide.
    #[command(flatten)]
    pub slide: SlideArgs,
    /// How images are rendered.
    #[command(flatten)]
    pub render: RenderArgs,
    /// The true camera and laser.
    #[command(flatten)]
    pub truth: TruthArgs,
    /// Print a JSON summary on standard output.
    #[arg(long)]
    pub json: bool,
}

/// `alacs simulate rgbd`
#[derive(Debug, Args)]
pub struct SimulateRgbdArgs {
    /// Output folder (created).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    #[command(flatten)]
    pub folder: ForceArg,
    /// The orchard scene (the same seed and options as `scan --sim` give the same scene).
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Pose of the RGB-D camera in the ALACS camera frame, as `scan
    /// --alacs-from-rgbd`: X,Y,Z mm, then roll, pitch, yaw deg.
    #[arg(
        long,
        value_name = "X,Y,Z,ROLL,PITCH,YAW",
        default_value = "0,0,0,0,0,0",
        allow_hyphen_values = true,
        value_parser = crate::values::pose
    )]
    pub alacs_from_rgbd: nalgebra::Isometry3<f64>,
    /// Print a JSON summary on standard output.
    #[arg(long)]
    pub json: bool,
}

/// `alacs detect`
#[derive(Debug, Args)]
pub struct DetectArgs {
    /// The colour image (PNG or JPEG).
    #[arg(long, value_name = "FILE")]
    pub image: PathBuf,
    /// The depth image aligned to it: a 16-bit greyscale PNG of millimetres, 0 no data.
    #[arg(long, value_name = "FILE", requires = "camera")]
    pub depth: Option<PathBuf>,
    /// The colour camera (camera.yaml or an OpenCV/ROS camera file alacs reads).
    #[arg(long, value_name = "FILE", requires = "depth")]
    pub camera: Option<PathBuf>,
    /// Smallest fruit radius in the image, px (the built-in detector).
    #[arg(long, value_name = "PX", default_value_t = 6.0, value_parser = positive_up_to(10_000.0))]
    pub min_radius_px: f64,
    /// A YOLO-style ONNX model instead of the built-in detector (YOLOv8
    /// [1, 4+C, N] or YOLOv5 [1, N, 5+C] output; needs a build with
    /// `--features onnx`).
    #[arg(long, value_name = "FILE.onnx", requires = "classes")]
    pub model: Option<PathBuf>,
    /// The model's class names in its output order, comma separated.
    #[arg(long, value_name = "NAMES", value_delimiter = ',', requires = "model")]
    pub classes: Vec<String>,
    /// With --model: the classes that are fruit, comma separated (any case).
    #[arg(long, value_name = "NAMES", value_delimiter = ',', default_value = "apple")]
    pub fruit_classes: Vec<String>,
    /// With --model: boxes scoring below this are dropped.
    #[arg(long, value_name = "0-1", default_value_t = 0.25, value_parser = number_in(0.0, 1.0))]
    pub min_score: f64,
    /// Print one JSON object (docs/FORMATS.md, "alacs detect") instead of text.
    #[arg(long)]
    pub json: bool,
}

/// How `localize` chooses the final position.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum LocalizeMethodArg {
    /// One estimator over every frame's laser points: hypotheses scored by one
    /// objective, the best accepted where it beats every other explanation.
    Fused,
    /// The best single-frame candidate (the seed paper's holistic evaluation),
    /// answered only where the frames together confirm it.
    Holistic,
}

impl LocalizeMethodArg {
    /// The library's method.
    pub fn method(self) -> alacs::locate::Method {
        match self {
            LocalizeMethodArg::Fused => alacs::locate::Method::Fused,
            LocalizeMethodArg::Holistic => alacs::locate::Method::Holistic,
        }
    }
}

/// How far the RGB-D camera's rough position may be off: the fruit is
/// searched within it, and an answer beyond it (with its own uncertainty)
/// is `not_found` as contradicting the RGB-D camera.
#[derive(Debug, Args, Clone, Copy)]
pub struct RoughErrorArgs {
    /// The rough position's largest depth error, as a fraction of the
    /// distance (0.03: 3 %; a detector on a RealSense-class camera at
    /// 0.5-1.5 m gives 1-3 %).
    #[arg(long, value_name = "F", default_value_t = 0.03, value_parser = number_in(0.001, 0.5))]
    pub rough_depth_error: f64,
    /// The rough position's largest error across the line of sight, mm.
    #[arg(long, value_name = "MM", default_value_t = 10.0, value_parser = number_in(0.1, 1000.0))]
    pub rough_lateral_error_mm: f64,
}

impl RoughErrorArgs {
    /// The localizer's options with these errors and `method`.
    pub fn locate_options(&self, method: alacs::locate::Method) -> alacs::locate::LocateOptions {
        alacs::locate::LocateOptions {
            method,
            rough_depth_error: self.rough_depth_error,
            rough_lateral_error_mm: self.rough_lateral_error_mm,
            ..alacs::locate::LocateOptions::default()
        }
    }
}

/// `alacs localize`
#[derive(Debug, Args)]
pub struct LocalizeArgs {
    /// Scan folder (scan.yaml beside the frames).
    #[arg(long, value_name = "DIR", required_unless_present = "bag", conflicts_with = "bag")]
    pub scan: Option<PathBuf>,
    /// A recorded scan (MCAP, from `scan --record` or `alacs ros --record`).
    #[arg(long, value_name = "FILE.mcap")]
    pub bag: Option<PathBuf>,
    /// Which scan of the bag, from 0.
    #[arg(long, value_name = "N", default_value_t = 0, requires = "bag")]
    pub bag_scan: usize,
    /// The calibrated camera (camera.yaml).
    #[arg(long, value_name = "FILE")]
    pub camera: PathBuf,
    /// The calibrated laser (laser.yaml).
    #[arg(long, value_name = "FILE")]
    pub laser: PathBuf,
    /// How the final position is chosen.
    #[arg(long, value_enum, default_value_t = LocalizeMethodArg::Fused)]
    pub method: LocalizeMethodArg,
    #[command(flatten)]
    pub rough_error: RoughErrorArgs,
    /// Also write every triangulated laser point (frame, on the fruit or
    /// not) and the fitted centre as a point cloud: .ply (binary PLY) or
    /// .pcd (binary PCD), millimetres, ALACS camera frame.
    #[arg(long, value_name = "FILE")]
    pub points: Option<PathBuf>,
    /// Print one JSON object (`alacs formats`) on standard output instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `alacs demo`
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Seed of the simulated data.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Folder for the evaluation artefacts (created): Table 1 with residual
    /// plots, the accuracy box plots and their JSON, and two HTML reports
    /// (report_calibration/index.html, report_scan/index.html).
    #[arg(long, value_name = "DIR", default_value = "alacs-demo")]
    pub out: PathBuf,
    #[command(flatten)]
    pub folder: ForceArg,
    /// Print one JSON object on standard output instead of text.
    #[arg(long)]
    pub json: bool,
}

/// The rig a scan runs on, the RGB-D camera's pose and the calibration
/// the frames are localized with (`alacs scan`, `alacs ros`).
#[derive(Debug, Args)]
pub struct RigArgs {
    /// Use the built-in simulated rig (an orchard scene rendered by the
    /// simulator).
    #[arg(long, conflicts_with = "rig_file")]
    pub sim: bool,
    /// Use the rig of this rig.toml (`alacs formats`): a GRBL slide and
    /// laser, and "sim" devices for what the rig lacks (they show the
    /// simulated scene below).
    #[arg(long = "rig", value_name = "FILE")]
    pub rig_file: Option<PathBuf>,
    /// The simulated orchard scene.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Also capture every frame with the laser off (for differencing).
    /// Without it a metered scan takes laser-off frames when the scene is bright.
    #[arg(long)]
    pub laser_off: bool,
    /// Do not meter: keep the camera's exposure and gain (rig.toml's, or the
    /// simulated camera's 1000 us at 0 dB). By default the target is metered
    /// with the laser off before each scan and the exposure set so that the
    /// fruit does not clip.
    #[arg(long)]
    pub fixed_exposure: bool,
    /// How the slide takes the frames: stop_and_go (the seed's: move,
    /// settle, capture, per frame) or continuous (one run through the
    /// positions, frames captured on the way, each at the slide's position
    /// at mid-exposure). Default: rig.toml's [scan] mode, else stop_and_go.
    #[arg(long, value_name = "MODE", value_parser = crate::values::scan_mode)]
    pub scan_mode: Option<alacs::rig::ScanModeName>,
    /// Pose of the RGB-D camera in the ALACS camera frame: translation in mm,
    /// then roll, pitch, yaw in degrees (R = Rz(yaw) Ry(pitch) Rx(roll));
    /// point_in_alacs = R point_in_rgbd + (x, y, z). The simulated RGB-D camera
    /// is mounted there and reports the rough position in its own frame.
    /// Default: rig.toml's [rgbd] alacs_from_rgbd with --rig, else 0,0,0,0,0,0.
    #[arg(
        long,
        alias = "rgbd-to-alacs",
        value_name = "X,Y,Z,ROLL,PITCH,YAW",
        allow_hyphen_values = true,
        value_parser = crate::values::pose
    )]
    pub alacs_from_rgbd: Option<nalgebra::Isometry3<f64>>,
    #[command(flatten)]
    pub rough_error: RoughErrorArgs,
    /// Localize with this calibrated camera.yaml instead of the simulation's true camera.
    #[arg(long, value_name = "FILE")]
    pub camera: Option<PathBuf>,
    /// Plan and localize with this calibrated laser.yaml instead of the simulation's true laser.
    #[arg(long, value_name = "FILE")]
    pub laser: Option<PathBuf>,
}

/// `alacs scan`
#[derive(Debug, Args)]
pub struct ScanArgs {
    /// The rig and the calibration.
    #[command(flatten)]
    pub rig: RigArgs,
    /// The rough position in the RGB-D camera's frame, mm (what its
    /// detector gave). Default with a simulated camera: the simulated
    /// RGB-D camera's; required otherwise.
    /// Repeat it for several fruit: one sweep covers them all.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, value_parser = crate::values::point_mm)]
    pub rough_mm: Vec<nalgebra::Point3<f64>>,
    /// Write the scan folder (scan.yaml, frames, camera.yaml, laser.yaml)
    /// here, and truth.json when the camera is simulated.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Record the scan as a ROS 2 bag (MCAP): every image with the slide
    /// and laser, the camera, the goal and the result.
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Write into --out even if it holds files this command did not write,
    /// and replace an existing --record file.
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object on standard output: docs/FORMATS.md's localize object
    /// plus "truth", "error_mm" and "error_3d_mm" (for several fruit, each
    /// of "targets").
    #[arg(long)]
    pub json: bool,
}

/// A value parser for a finite number in `[low, high]`: clap's error then
/// names the option and the value (`invalid value '1e308' for '--noise-mm
/// <NOISE_MM>': ...`), exit 2. Ranges are sanity bounds that refuse unit or
/// typing errors, not tuning limits.
fn number_in(low: f64, high: f64) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
    move |text: &str| {
        let value: f64 = text.trim().parse().map_err(|_| format!("`{text}` is not a number"))?;
        if value.is_finite() && (low..=high).contains(&value) {
            Ok(value)
        } else {
            Err(format!("must be a finite number from {low} to {high}"))
        }
    }
}

/// [`number_in`] for a positive number up to `high` (0 excluded).
fn positive_up_to(high: f64) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
    move |text: &str| {
        let value = number_in(0.0, high)(text)?;
        if value > 0.0 { Ok(value) } else { Err(format!("must be positive, at most {high}")) }
    }
}

/// A slide travel in mm: finite and within +-[`alacs::model::MAX_ABS_SLIDE_MM`].
fn slide_mm(text: &str) -> Result<f64, String> {
    number_in(-alacs::model::MAX_ABS_SLIDE_MM, alacs::model::MAX_ABS_SLIDE_MM)(text)
}

/// The largest RANSAC threshold accepted, mm: a metre is no inlier band.
pub const MAX_THRESHOLD_MM: f64 = 1000.0;

/// `alacs bag ...`
#[derive(Debug, Subcommand)]
pub enum BagCommand {
    /// Write a recorded scan as a scan folder (scan.yaml and PNG frames).
    Export(BagExportArgs),
    /// Record a scan folder as a ROS 2 bag (MCAP).
    Import(BagImportArgs),
}

/// `alacs bag export`
#[derive(Debug, Args)]
pub struct BagExportArgs {
    /// The recording.
    #[arg(value_name = "FILE.mcap")]
    pub bag: PathBuf,
    /// The scan folder to write.
    #[arg(value_name = "DIR")]
    pub out: PathBuf,
    /// Which scan of the bag, from 0.
    #[arg(long = "scan", value_name = "N", default_value_t = 0)]
    pub scan_index: usize,
    #[command(flatten)]
    pub folder: ForceArg,
    /// Print one JSON object: {"bag", "scan", "scans", "frames", "out", "messages"}.
    #[arg(long)]
    pub json: bool,
}

/// `alacs bag import`
#[derive(Debug, Args)]
pub struct BagImportArgs {
    /// The scan folder.
    #[arg(value_name = "DIR")]
    pub scan: PathBuf,
    /// The recording to write.
    #[arg(value_name = "FILE.mcap")]
    pub bag: PathBuf,
    /// The camera, recorded as CameraInfo with every image (default: the
    /// folder's camera.yaml when there is one).
    #[arg(long, value_name = "FILE")]
    pub camera: Option<PathBuf>,
    /// The topics' namespace.
    #[arg(long, value_name = "NS", default_value = "/alacs")]
    pub namespace: String,
    /// Replace FILE.mcap if it exists.
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object: {"bag", "frames", "images"}.
    #[arg(long)]
    pub json: bool,
}

/// `alacs rig ...`
#[derive(Debug, Subcommand)]
pub enum RigCommand {
    /// Connect the rig's devices, home the slide, move it to 0, half the
    /// stroke and the stroke, switch the laser on and off and capture a
    /// frame, printing each step with its time and result. Exit 1 naming
    /// the device and the step that failed (the laser then switched off).
    Check(RigCheckArgs),
}

/// `alacs rig check`
#[derive(Debug, Args)]
pub struct RigCheckArgs {
    /// The rig's description.
    #[arg(long = "rig", value_name = "FILE")]
    pub rig_file: PathBuf,
    /// The scene that "sim" devices show.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Print one JSON object: {"rig", "passed", "steps": [{"device", "step",
    /// "seconds", "ok", "detail" | "error"}]}.
    #[arg(long)]
    pub json: bool,
}

/// `alacs ros`
#[derive(Debug, Args)]
pub struct RosArgs {
    /// The rig and the calibration (--sim: the simulated rig, localized
    /// with the simulation's true camera and laser unless --camera / --laser).
    #[command(flatten)]
    pub rig: RigArgs,
    /// Every option as a ROS 2 parameter (filled from the parsed command
    /// line: [`crate::ros_args::parameters`]).
    #[arg(skip)]
    pub parameters: Vec<alacs::ros::NodeParameter>,
    /// Namespace of the node, its action and topics (two units on one robot:
    /// /alacs_left and /alacs_right).
    #[arg(long, value_name = "NS", default_value = "/alacs")]
    pub namespace: String,
    /// The node's name.
    #[arg(long, value_name = "NAME", default_value = "alacs")]
    pub node_name: String,
    /// The ALACS camera's optical frame (results, clouds, images).
    #[arg(long, value_name = "FRAME", default_value = "alacs_camera_optical_frame")]
    pub camera_frame: String,
    /// The RGB-D camera's optical frame (rough positions may come in it).
    #[arg(long, value_name = "FRAME", default_value = "rgbd_camera_optical_frame")]
    pub rgbd_frame: String,
    /// The frame the ALACS camera is mounted on: /tf_static carries
    /// MOUNT -> the camera's optical frame at --mount-from-camera. (The
    /// RGB-D camera's frame is its driver's, never given a parent here.)
    #[arg(long, value_name = "FRAME", default_value = "alacs_link")]
    pub mount_frame: String,
    /// Pose of the ALACS camera's optical frame in the mount frame: X,Y,Z
    /// mm, then roll, pitch, yaw deg (as --alacs-from-rgbd). Default: the
    /// optical rotation of a camera's body frame (REP 103), no offset.
    #[arg(
        long,
        value_name = "X,Y,Z,ROLL,PITCH,YAW",
        default_value = "0,0,0,-90,0,-90",
        allow_hyphen_values = true,
        value_parser = crate::values::pose
    )]
    pub mount_from_camera: nalgebra::Isometry3<f64>,
    /// Publish no static transform (the robot's URDF mounts the camera).
    #[arg(long)]
    pub no_static_tf: bool,
    /// The RGB-D camera's namespace: its color/image_raw,
    /// aligned_depth_to_color/image_raw and color/camera_info (realsense-ros'
    /// names) are searched for fruit, published on <ns>/fruit_rough
    /// (vision_msgs/Detection3DArray) for <ns>/scan_detected.
    #[arg(long, value_name = "NS", default_value = "/camera/camera")]
    pub rgbd_ns: String,
    /// What finds the fruit in the RGB-D camera's colour images: the
    /// built-in detector, another detector's boxes on <ns>/detections_2d
    /// (vision_msgs/Detection2DArray, stamped as the image), or nothing
    /// (no RGB-D subscriptions: goals bring the rough position).
    #[arg(long, value_enum, default_value = "builtin")]
    pub rgbd_detector: RgbdDetectorArg,
    /// With --rgbd-detector topic: the class ids that are fruit, comma
    /// separated (any case; boxes without hypotheses are kept).
    #[arg(long, value_name = "CLASSES", value_delimiter = ',', default_value = "apple")]
    pub detection_classes: Vec<String>,
    /// A topic or the action under another name, FROM:=TO (as `--ros-args
    /// -r FROM:=TO`); repeatable.
    #[arg(long, value_name = "FROM:=TO")]
    pub remap: Vec<String>,
    /// Do not publish the captured frames on <ns>/image.
    #[arg(long)]
    pub no_images: bool,
    /// Stop after this many goals (tests, soaks).
    #[arg(long, value_name = "N")]
    pub max_goals: Option<u64>,
    /// Record every goal's scan as a ROS 2 bag (MCAP), written when the node stops.
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Print one JSON object on standard output when the node stops:
    /// {"goals", "found", "rejected", "errors", "cancelled"}.
    #[arg(long)]
    pub json: bool,
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::panic)]
    use clap::Parser as _;

    use super::Cli;

    /// Every option parsed into its type is read back as that type (clap
    /// checks the field's type only when the option is given).
    #[test]
    fn every_typed_option_parses_into_its_field() {
        <Cli as clap::CommandFactory>::command().debug_assert();
        for line in [
            "alacs stripe --image f.png --roi 0,0,9,9",
            "alacs simulate samples --out d --slides 0,100 --depth-mm 600,900",
            "alacs simulate session --out d --rgbd-pose 0,0,0,0,0,90 --charuco DICT_5X5_100 --slides 0,100 --depth-mm 600,900",
            "alacs simulate scan --out d --depth-mm 600,900",
            "alacs simulate rgbd --out d --alacs-from-rgbd 1,2,3,0,0,0",
            "alacs session init d --board 9x6 --square-mm 25,24 --charuco DICT_5X5_100 --marker-mm 18",
            "alacs scan --sim --rough-mm 0,0,800 --rough-mm 50,0,800 --alacs-from-rgbd 0,0,0,0,0,0 --scan-mode continuous",
            "alacs ros --sim --mount-from-camera 0,0,0,0,0,0",
        ] {
            let cli = Cli::try_parse_from(line.split_whitespace())
                .unwrap_or_else(|e| panic!("{line}: {e}"));
            // Reading every field: a type mismatch would have panicked above.
            let _ = format!("{cli:?}");
        }
    }
}

//! rig.toml: the rig's description (docs/FORMATS.md, "rig.toml"), read in
//! this one place with errors that name the file, the section and the key.

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Deserialize;

use crate::{Error, Result};

/// A rig: its slide, laser, camera and the RGB-D camera's pose.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigConfig {
    /// The slide carrying the laser.
    pub slide: SlideConfig,
    /// The laser's switch.
    #[serde(default)]
    pub laser: LaserConfig,
    /// The ALACS camera.
    #[serde(default)]
    pub camera: CameraConfig,
    /// The RGB-D camera that gives the rough position.
    #[serde(default)]
    pub rgbd: RgbdConfig,
    /// How the slide takes the frames.
    #[serde(default)]
    pub scan: ScanConfig,
}

/// `mode` of `[scan]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum ScanModeName {
    /// The seed's: per frame, move, settle, capture.
    #[default]
    StopAndGo,
    /// One run of the slide through the frames' positions, the camera
    /// capturing on the way (the slide and camera must time-stamp: GRBL
    /// and GenICam drivers do).
    Continuous,
}

impl ScanModeName {
    /// Parses one of [`ScanMode::NAMES`](alacs_scanner::ScanMode::NAMES)
    /// (`--scan-mode`; rig.toml's `mode` reads through serde, the same names).
    pub fn parse(name: &str) -> std::result::Result<Self, String> {
        match alacs_scanner::ScanMode::NAMES.iter().position(|n| *n == name) {
            Some(0) => Ok(ScanModeName::StopAndGo),
            Some(_) => Ok(ScanModeName::Continuous),
            None => Err(format!(
                "scan mode `{name}`: use {}",
                alacs_scanner::ScanMode::NAMES.join(" or ")
            )),
        }
    }
}

/// `[scan]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScanConfig {
    /// `mode`: "stop_and_go" (the default) or "continuous".
    #[serde(default)]
    pub mode: ScanModeName,
    /// `sweep_speed_mm_per_s`: the fastest continuous sweep (the slide's
    /// own limit and the smear limit may make it slower).
    #[serde(default = "default_sweep_speed")]
    pub sweep_speed_mm_per_s: f64,
    /// `max_smear_px`: how far the stripe may move during one exposure of a
    /// continuous sweep, pixels.
    #[serde(default = "default_max_smear_px")]
    pub max_smear_px: f64,
}

impl Default for ScanConfig {
    fn default() -> Self {
        Self {
            mode: ScanModeName::default(),
            sweep_speed_mm_per_s: default_sweep_speed(),
            max_smear_px: default_max_smear_px(),
        }
    }
}

/// Which slide driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SlideDriver {
    /// A GRBL 1.1 controller on a serial port.
    Grbl,
    /// The simulated slide.
    Sim,
}

/// `[slide]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SlideConfig {
    /// `driver`: "grbl" or "sim".
    pub driver: SlideDriver,
    /// `port`: the controller's serial port (grbl), e.g. /dev/ttyUSB0.
    #[serde(default)]
    pub port: String,
    /// `baud`: 115200 for GRBL 1.1.
    #[serde(default = "default_baud")]
    pub baud: u32,
    /// `axis`: the controller's axis that carries the laser, X, Y or Z.
    #[serde(default = "default_axis")]
    pub axis: String,
    /// `stroke_mm`: travel d from 0 to this is reachable.
    #[serde(default = "default_stroke_mm")]
    pub stroke_mm: f64,
    /// `feed_mm_per_min`: the feed rate of the moves (G1 F).
    #[serde(default = "default_feed")]
    pub feed_mm_per_min: f64,
    /// `home`: home the axis (`$H`) when the rig connects.
    #[serde(default = "default_true")]
    pub home: bool,
    /// `axis_mm_at_zero`: the controller's coordinate (work coordinates,
    /// mm) where the slide travel d is 0.
    #[serde(default)]
    pub axis_mm_at_zero: f64,
    /// `direction`: +1 when the controller's coordinate grows with d, -1
    /// when it shrinks.
    #[serde(default = "default_direction")]
    pub direction: i8,
    /// `tolerance_mm`: the largest difference between target and reported
    /// position when the slide stands.
    #[serde(default = "default_tolerance_mm")]
    pub tolerance_mm: f64,
    /// `command_timeout_s`: the longest wait for a command's answer.
    #[serde(default = "default_command_timeout_s")]
    pub command_timeout_s: f64,
    /// `homing_timeout_s`: the longest wait for homing.
    #[serde(default = "default_homing_timeout_s")]
    pub homing_timeout_s: f64,
    /// `move_timeout_s`: the longest wait for a move of the scan to end
    /// with the slide standing at its target.
    #[serde(default = "default_move_timeout_s")]
    pub move_timeout_s: f64,
}

/// Which laser driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LaserDriver {
    /// The spindle output of the slide's GRBL controller (M3 S<power> / M5,
    /// spindle mode: `$32=0`).
    GrblSpindle,
    /// A relay on a serial port of its own (USB relay modules): fixed bytes
    /// switch it on and off.
    SerialRelay,
    /// The simulated laser.
    Sim,
}

/// `[laser]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaserConfig {
    /// `driver`: "grbl-spindle" or "sim".
    pub driver: LaserDriver,
    /// `power`: the spindle value S of the on command (0-100000).
    #[serde(default = "default_power")]
    pub power: u32,
    /// `on_command`: the G-code that switches the laser on; `{power}` is
    /// replaced by `power`.
    #[serde(default = "default_on_command")]
    pub on_command: String,
    /// `off_command`: the G-code that switches it off.
    #[serde(default = "default_off_command")]
    pub off_command: String,
    /// `settle_ms`: time the laser needs after switching before it is
    /// steady (or dark).
    #[serde(default)]
    pub settle_ms: f64,
    /// `port`: the relay's serial port (serial-relay).
    #[serde(default)]
    pub port: String,
    /// `baud`: the relay's baud rate (serial-relay).
    #[serde(default = "default_relay_baud")]
    pub baud: u32,
    /// `on_bytes`: what switches the relay on, hexadecimal ("A0 01 01 A2").
    #[serde(default)]
    pub on_bytes: String,
    /// `off_bytes`: what switches it off, hexadecimal.
    #[serde(default)]
    pub off_bytes: String,
}

impl Default for LaserConfig {
    fn default() -> Self {
        Self {
            driver: LaserDriver::Sim,
            power: default_power(),
            on_command: default_on_command(),
            off_command: default_off_command(),
            settle_ms: 0.0,
            port: String::new(),
            baud: default_relay_baud(),
            on_bytes: String::new(),
            off_bytes: String::new(),
        }
    }
}

/// Which camera driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CameraDriver {
    /// A GenICam camera through aravis (cargo feature `genicam`).
    Genicam,
    /// The simulator's camera, rendering the scene at the slide's position.
    Sim,
}

/// `[camera]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraConfig {
    /// `driver`: "genicam" or "sim".
    pub driver: CameraDriver,
    /// `device`: the GenICam device id; the first camera found when empty.
    #[serde(default)]
    pub device: String,
    /// `exposure_us`: the exposure time, microseconds.
    #[serde(default = "default_exposure_us")]
    pub exposure_us: f64,
    /// `gain_db`: the analogue gain, dB.
    #[serde(default)]
    pub gain_db: f64,
    /// `metering`: before each scan the controller meters the target with
    /// the laser off and sets the exposure (from `exposure_us`) so the
    /// fruit does not clip; false keeps `exposure_us` and `gain_db` fixed.
    #[serde(default = "default_true")]
    pub metering: bool,
    /// `bright_below_us`: a metered exposure shorter than this is a bright
    /// scene, scanned with laser-off frames for differencing.
    #[serde(default = "default_bright_below_us")]
    pub bright_below_us: f64,
}

impl Default for CameraConfig {
    fn default() -> Self {
        Self {
            driver: CameraDriver::Sim,
            device: String::new(),
            exposure_us: default_exposure_us(),
            gain_db: 0.0,
            metering: true,
            bright_below_us: default_bright_below_us(),
        }
    }
}

/// `[rgbd]`.
#[derive(Debug, Clone, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RgbdConfig {
    /// `alacs_from_rgbd`: the RGB-D camera's pose in the ALACS camera frame,
    /// x y z in mm, roll pitch yaw in degrees.
    #[serde(default)]
    pub alacs_from_rgbd: [f64; 6],
}

fn default_baud() -> u32 {
    115_200
}
fn default_axis() -> String {
    "X".into()
}
fn default_stroke_mm() -> f64 {
    alacs_model::SLIDE_STROKE_MM
}
fn default_feed() -> f64 {
    3000.0
}
fn default_true() -> bool {
    true
}
fn default_direction() -> i8 {
    1
}
fn default_tolerance_mm() -> f64 {
    0.05
}
fn default_command_timeout_s() -> f64 {
    2.0
}
fn default_homing_timeout_s() -> f64 {
    60.0
}
fn default_move_timeout_s() -> f64 {
    10.0
}
fn default_relay_baud() -> u32 {
    9600
}
fn default_power() -> u32 {
    1000
}
fn default_on_command() -> String {
    "M3 S{power}".into()
}
fn default_off_command() -> String {
    "M5".into()
}
fn default_exposure_us() -> f64 {
    1000.0
}
fn default_bright_below_us() -> f64 {
    600.0
}
fn default_sweep_speed() -> f64 {
    alacs_scanner::sweep::DEFAULT_MAX_SWEEP_SPEED_MM_PER_S
}
fn default_max_smear_px() -> f64 {
    alacs_scanner::sweep::DEFAULT_MAX_SMEAR_PX
}

impl RigConfig {
    /// Reads and checks rig.toml.
    pub fn from_file(path: &Path) -> Result<Self> {
        let text = alacs_model::io::read_text(path)?;
        Self::from_toml(&text, path)
    }

    /// Parses and checks rig.toml's text; `path` names it in errors.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self> {
        // One line: where, then what (the parser's own text quotes the line
        // over several).
        let config: RigConfig = toml::from_str(text).map_err(|e| {
            let at = e.span().map(|span| {
                let before = text.get(..span.start).unwrap_or(text);
                let line = before.matches('\n').count() + 1;
                let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
                format!("line {line}, column {column}: ")
            });
            Error::Config {
                path: path.to_path_buf(),
                message: format!(
                    "{}{}",
                    at.unwrap_or_default(),
                    e.message().trim().replace('\n', " ")
                ),
            }
        })?;
        config.validate(path)?;
        Ok(config)
    }

    /// Checks every value against its range and the drivers against each other.
    pub fn validate(&self, path: &Path) -> Result<()> {
        let bad = |key: &str, message: String| Error::Config {
            path: PathBuf::from(path),
            message: format!("{key}: {message}"),
        };
        let s = &self.slide;
        let positive = |key: &str, value: f64, max: f64| {
            if value.is_finite() && value > 0.0 && value <= max {
                Ok(())
            } else {
                Err(bad(key, format!("{value} must be positive and at most {max}")))
            }
        };
        positive("[slide] stroke_mm", s.stroke_mm, 10_000.0)?;
        positive("[slide] feed_mm_per_min", s.feed_mm_per_min, 1.0e6)?;
        positive("[slide] tolerance_mm", s.tolerance_mm, 10.0)?;
        positive("[slide] command_timeout_s", s.command_timeout_s, 3600.0)?;
        positive("[slide] homing_timeout_s", s.homing_timeout_s, 3600.0)?;
        positive("[slide] move_timeout_s", s.move_timeout_s, 3600.0)?;
        positive("[scan] sweep_speed_mm_per_s", self.scan.sweep_speed_mm_per_s, 10_000.0)?;
        positive("[scan] max_smear_px", self.scan.max_smear_px, 100.0)?;
        if !(s.axis_mm_at_zero.is_finite() && s.axis_mm_at_zero.abs() <= 100_000.0) {
            return Err(bad(
                "[slide] axis_mm_at_zero",
                format!("{} must be finite, within +-100000 mm", s.axis_mm_at_zero),
            ));
        }
        if s.direction != 1 && s.direction != -1 {
            return Err(bad("[slide] direction", format!("{} must be 1 or -1", s.direction)));
        }
        if !matches!(s.axis.as_str(), "X" | "Y" | "Z") {
            return Err(bad("[slide] axis", format!("`{}` must be X, Y or Z", s.axis)));
        }
        if s.driver == SlideDriver::Grbl {
            if s.port.trim().is_empty() {
                return Err(bad(
                    "[slide] port",
                    "the grbl driver needs the controller's serial port, e.g. \
                     port = \"/dev/ttyUSB0\""
                        .into(),
                ));
            }
            if !(300..=4_000_000).contains(&s.baud) {
                return Err(bad("[slide] baud", format!("{} must lie within 300-4000000", s.baud)));
            }
        }
        let l = &self.laser;
        if l.driver == LaserDriver::GrblSpindle && s.driver != SlideDriver::Grbl {
            return Err(bad(
                "[laser] driver",
                "\"grbl-spindle\" switches the laser on the slide's GRBL controller, but \
                 [slide] driver is not \"grbl\""
                    .into(),
            ));
        }
        if l.power > 100_000 {
            return Err(bad("[laser] power", format!("{} must lie within 0-100000", l.power)));
        }
        for (key, command) in
            [("[laser] on_command", &l.on_command), ("[laser] off_command", &l.off_command)]
        {
            if command.trim().is_empty() || command.len() > 70 || !command.is_ascii() {
                return Err(bad(
                    key,
                    format!("`{command}` must be one ASCII G-code line of at most 70 characters"),
                ));
            }
            if command.contains(['\n', '\r', '?', '!', '~']) {
                return Err(bad(
                    key,
                    format!(
                        "`{command}` must not hold a line break or a real-time command (? ! ~)"
                    ),
                ));
            }
        }
        if l.driver == LaserDriver::SerialRelay {
            if l.port.trim().is_empty() {
                return Err(bad(
                    "[laser] port",
                    "the serial-relay driver needs the relay's serial port".into(),
                ));
            }
            if !(300..=4_000_000).contains(&l.baud) {
                return Err(bad("[laser] baud", format!("{} must lie within 300-4000000", l.baud)));
            }
            let on = parse_hex(&l.on_bytes).map_err(|m| bad("[laser] on_bytes", m))?;
            let off = parse_hex(&l.off_bytes).map_err(|m| bad("[laser] off_bytes", m))?;
            if on == off {
                return Err(bad("[laser] off_bytes", "must differ from on_bytes".into()));
            }
        }
        if !(l.settle_ms.is_finite() && (0.0..=10_000.0).contains(&l.settle_ms)) {
            return Err(bad(
                "[laser] settle_ms",
                format!("{} must lie within 0-10000", l.settle_ms),
            ));
        }
        let c = &self.camera;
        positive("[camera] exposure_us", c.exposure_us, 10.0e6)?;
        positive("[camera] bright_below_us", c.bright_below_us, 10.0e6)?;
        if !(c.gain_db.is_finite() && (0.0..=48.0).contains(&c.gain_db)) {
            return Err(bad("[camera] gain_db", format!("{} must lie within 0-48 dB", c.gain_db)));
        }
        let pose = &self.rgbd.alacs_from_rgbd;
        if pose[..3]
            .iter()
            .any(|t| !(t.is_finite() && t.abs() <= alacs_model::MAX_ROUGH_DISTANCE_MM))
        {
            return Err(bad(
                "[rgbd] alacs_from_rgbd",
                format!(
                    "the translation {:?} mm must lie within +-{} mm",
                    &pose[..3],
                    alacs_model::MAX_ROUGH_DISTANCE_MM
                ),
            ));
        }
        if pose[3..].iter().any(|a| !(a.is_finite() && a.abs() <= 360.0)) {
            return Err(bad(
                "[rgbd] alacs_from_rgbd",
                format!("roll, pitch and yaw {:?} must lie within +-360 deg", &pose[3..]),
            ));
        }
        Ok(())
    }

    /// Whether any device is simulated (the rig then needs a scene).
    pub fn has_simulated_devices(&self) -> bool {
        self.slide.driver == SlideDriver::Sim
            || self.laser.driver == LaserDriver::Sim
            || self.camera.driver == CameraDriver::Sim
    }
}

impl SlideConfig {
    /// The controller's coordinate of slide travel `d_mm`.
    pub fn axis_mm(&self, d_mm: f64) -> f64 {
        self.axis_mm_at_zero + f64::from(self.direction) * d_mm
    }

    /// The slide travel d of the controller's coordinate `axis_mm`.
    pub fn travel_mm(&self, axis_mm: f64) -> f64 {
        (axis_mm - self.axis_mm_at_zero) * f64::from(self.direction)
    }

    /// `command_timeout_s` as a duration.
    pub fn command_timeout(&self) -> Duration {
        Duration::from_secs_f64(self.command_timeout_s)
    }

    /// `move_timeout_s` as a duration.
    pub fn move_timeout(&self) -> Duration {
        Duration::from_secs_f64(self.move_timeout_s)
    }

    /// `homing_timeout_s` as a duration.
    pub fn homing_timeout(&self) -> Duration {
        Duration::from_secs_f64(self.homing_timeout_s)
    }
}

/// Bytes written in hexadecimal, pairs of digits with optional spaces
/// ("A0 01 01 A2"), 1 to 64 bytes.
pub fn parse_hex(text: &str) -> std::result::Result<Vec<u8>, String> {
    let digits: String = text.chars().filter(|c| !c.is_whitespace()).collect();
    if digits.is_empty() || !digits.len().is_multiple_of(2) || digits.len() > 128 {
        return Err(format!("`{text}` must be 1 to 64 bytes in hexadecimal, e.g. \"A0 01 01 A2\""));
    }
    (0..digits.len())
        .step_by(2)
        .map(|i| {
            digits
                .get(i..i + 2)
                .and_then(|pair| u8::from_str_radix(pair, 16).ok())
                .ok_or_else(|| format!("`{text}` is not hexadecimal bytes"))
        })
        .collect()
}

impl LaserConfig {
    /// The on command with its power.
    pub fn on_line(&self) -> String {
        self.on_command.replace("{power}", &self.power.to_string())
    }
}

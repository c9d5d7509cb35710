//! A GRBL 1.1 controller on a serial port: the slide on one of its axes and
//! the laser on its spindle output (M3 S / M5).
//!
//! GRBL's streaming protocol, as its documentation gives it: every line
//! sent gets one `ok` or `error:N`; `ALARM:N` reports a fault (the machine
//! is then locked until `$H` or `$X`); the real-time bytes `?` (status
//! report `<Idle|MPos:x,y,z|...>`), `!` (feed hold) and 0x18 (soft reset)
//! act at once. A motion's `ok` comes when it is queued, not when it ends,
//! so a move is done when the status report says `Idle` at the target.
//!
//! What this driver does:
//! - connecting: a soft reset and GRBL's banner (`Grbl 1.1h ['$' for
//!   help]`), then homing (`$H`) when rig.toml asks for it;
//! - a move: the target checked against the stroke before anything is
//!   sent, `G90 G1 <axis>.. F..`, then `?` every 20 ms until the slide
//!   stands at the target (a lost `ok` does not stop it: the status report
//!   is the truth); on timeout a feed hold and a soft reset stop the slide;
//! - the laser: the on and off commands of rig.toml, each waiting for its
//!   `ok` (GRBL runs M3 and M5 after the queued motion);
//! - every failure names the port, the command and GRBL's own words for
//!   the error or alarm code; lines that are not GRBL's are skipped.

use std::collections::BTreeMap;
use std::io::{Read as _, Write as _};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use alacs_scanner::hardware::{check_sweep_speed, check_target};
use alacs_scanner::{Device, Error as DeviceError, LaserSwitch, Slide, SlideReport};

use crate::config::{LaserConfig, SlideConfig};

/// How often the status is polled while the slide moves.
const STATUS_PERIOD: Duration = Duration::from_millis(20);

/// How long a read waits at most before looking at the clock again.
const READ_SLICE: Duration = Duration::from_millis(10);

/// The longest line GRBL sends; a longer one is garbage and dropped.
const MAX_LINE: usize = 256;

/// How long the driver waits for the banner after a soft reset: an Arduino
/// that resets when the port opens takes about 2 s to boot.
const BANNER_WAIT: Duration = Duration::from_millis(2500);

/// How long a slide standing at its target waits for its move's `ok`
/// before taking it as lost.
const LOST_OK_WAIT: Duration = Duration::from_millis(100);

/// How long a feed hold may take to bring the slide to rest before the
/// soft reset.
const HOLD_WAIT: Duration = Duration::from_secs(2);

/// A GRBL controller's answer to a line, or a line it sent by itself.
#[derive(Debug, Clone, PartialEq)]
enum Reply {
    Ok,
    Error(u32),
    Alarm(u32),
    Status(Status),
    Banner(String),
    /// `[MSG:..]`, `[GC:..]`, `$N=V` and other lines of GRBL's.
    Message(String),
}

/// A status report as GRBL sends it.
#[derive(Debug, Clone, PartialEq)]
struct Status {
    /// `Idle`, `Run`, `Hold:0`, `Home`, `Alarm`, ...
    state: String,
    /// The position, machine or work coordinates as `$10` asks.
    position: Position,
    /// The work coordinate offset, in the reports that carry it.
    work_offset: Option<[f64; 3]>,
}

/// A reported position, X Y Z in mm.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Position {
    Machine([f64; 3]),
    Work([f64; 3]),
}

/// The state and the work position (what G90 moves address) of a report.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisStatus {
    /// `Idle`, `Run`, `Hold:0`, `Home`, `Alarm`, ...
    pub state: String,
    /// Work position X, Y, Z, mm.
    pub work_mm: [f64; 3],
}

/// Why a controller operation failed (the device is added by its user).
#[derive(Debug, Clone, PartialEq)]
enum Fault {
    Timeout { timeout: Duration, detail: String },
    Failed(String),
}

impl Fault {
    fn on(self, device: Device) -> DeviceError {
        match self {
            Fault::Timeout { timeout, detail } => {
                DeviceError::Timeout { device, step: None, timeout, detail }
            }
            Fault::Failed(message) => DeviceError::Device { device, step: None, message },
        }
    }
}

/// GRBL 1.1's words for its error codes.
fn error_meaning(code: u32) -> &'static str {
    match code {
        1 => "a G-code word has no letter",
        2 => "a number is missing or malformed",
        3 => "unknown '$' command",
        4 => "negative value for a positive setting",
        5 => "homing is not enabled in the settings ($22)",
        8 => "'$' command only when idle",
        9 => "G-code locked out during alarm or jog",
        10 => "soft limits need homing enabled",
        11 => "line too long",
        15 => "jog target exceeds machine travel",
        17 => "laser mode needs PWM output",
        20 => "unsupported or invalid G-code command",
        21 => "two G-code commands of one modal group",
        22 => "feed rate not set",
        23 => "a G-code command needs an integer value",
        24 => "two G-code commands that both use axis words",
        25 => "a G-code word repeated in the block",
        26 => "no axis words where the command needs them",
        33 => "invalid motion target",
        _ => "see GRBL 1.1's error codes",
    }
}

/// GRBL 1.1's words for its alarm codes.
fn alarm_meaning(code: u32) -> &'static str {
    match code {
        1 => "hard limit triggered; position lost, home again",
        2 => "soft limit: the motion target exceeds the machine travel; position kept",
        3 => "reset while in motion; position lost, home again",
        4 | 5 => "probe fail",
        6 => "homing fail: reset during homing",
        7 => "homing fail: safety door opened during homing",
        8 => "homing fail: the limit switch did not clear when pulling off",
        9 => "homing fail: no limit switch within the search distance",
        10 => "homing fail: second dual-axis switch not found",
        _ => "see GRBL 1.1's alarm codes",
    }
}

/// Parses one line from the controller; `None` for garbage.
fn parse_reply(line: &str) -> Option<Reply> {
    let line = line.trim();
    if line == "ok" {
        return Some(Reply::Ok);
    }
    if let Some(code) = line.strip_prefix("error:") {
        return code.trim().parse().ok().map(Reply::Error);
    }
    if let Some(code) = line.strip_prefix("ALARM:") {
        return code.trim().parse().ok().map(Reply::Alarm);
    }
    if line.starts_with("Grbl ") {
        return Some(Reply::Banner(line.to_string()));
    }
    if let Some(report) = line.strip_prefix('<').and_then(|l| l.strip_suffix('>')) {
        return parse_status(report).map(Reply::Status);
    }
    if line.starts_with('[') && line.ends_with(']') || line.starts_with('$') {
        return Some(Reply::Message(line.to_string()));
    }
    None
}

/// Reads a status report's fields (without `<` `>`): the state and `MPos`
/// or `WPos`, and `WCO` when the report carries it.
fn parse_status(report: &str) -> Option<Status> {
    let mut fields = report.split('|');
    let state = fields.next()?.to_string();
    if state.is_empty() {
        return None;
    }
    let triple = |values: &str| -> Option<[f64; 3]> {
        let v: Vec<f64> =
            values.split(',').map(|v| v.trim().parse().ok()).collect::<Option<_>>()?;
        (v.len() >= 3 && v.iter().all(|x| x.is_finite())).then(|| [v[0], v[1], v[2]])
    };
    let mut position = None;
    let mut work_offset = None;
    for field in fields {
        if let Some(values) = field.strip_prefix("MPos:") {
            position = Some(Position::Machine(triple(values)?));
        } else if let Some(values) = field.strip_prefix("WPos:") {
            position = Some(Position::Work(triple(values)?));
        } else if let Some(values) = field.strip_prefix("WCO:") {
            work_offset = Some(triple(values)?);
        }
    }
    Some(Status { state, position: position?, work_offset })
}

/// A GRBL 1.1 controller on a serial port.
pub struct GrblController {
    port: Box<dyn serialport::SerialPort>,
    /// The port's name, for messages.
    name: String,
    /// Bytes read but not yet a whole line.
    pending: Vec<u8>,
    /// The work coordinate offset of the last report that carried one.
    work_offset: [f64; 3],
    /// The controller's settings (`$$`), read once by the first device
    /// that checks them.
    settings: Option<BTreeMap<u32, String>>,
}

impl std::fmt::Debug for GrblController {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GrblController").field("port", &self.name).finish_non_exhaustive()
    }
}

impl GrblController {
    /// Opens the controller on `config.port` and resets it: GRBL's banner
    /// must come within 2.5 s. Does not home.
    fn open(config: &SlideConfig) -> Result<Self, Fault> {
        let port =
            serialport::new(&config.port, config.baud).timeout(READ_SLICE).open().map_err(|e| {
                Fault::Failed(format!("cannot open the serial port {}: {e}", config.port))
            })?;
        let mut controller = Self {
            port,
            name: config.port.clone(),
            pending: Vec::new(),
            work_offset: [0.0; 3],
            settings: None,
        };
        controller.reset(BANNER_WAIT.max(config.command_timeout()))?;
        Ok(controller)
    }

    fn failed(&self, message: impl std::fmt::Display) -> Fault {
        Fault::Failed(format!("GRBL on {}: {message}", self.name))
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), Fault> {
        self.port
            .write_all(bytes)
            .and_then(|()| self.port.flush())
            .map_err(|e| self.failed(format!("the serial port failed (unplugged?): {e}")))
    }

    /// Sends one line (a newline is added).
    fn send_line(&mut self, line: &str) -> Result<(), Fault> {
        self.write(format!("{line}\n").as_bytes())
    }

    /// The next reply before `deadline`, or `None` when it passes. Garbage
    /// lines are skipped.
    fn next_reply(&mut self, deadline: Instant) -> Result<Option<Reply>, Fault> {
        loop {
            while let Some(end) = self.pending.iter().position(|&b| b == b'\n') {
                let line: Vec<u8> = self.pending.drain(..=end).collect();
                if let Some(reply) = parse_reply(&String::from_utf8_lossy(&line)) {
                    return Ok(Some(reply));
                }
            }
            if self.pending.len() > MAX_LINE {
                self.pending.clear();
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            let mut buffer = [0u8; 256];
            match self.port.read(&mut buffer) {
                Ok(0) => {
                    return Err(self.failed("the serial port closed (the device vanished?)"));
                }
                Ok(n) => self.pending.extend_from_slice(&buffer[..n]),
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut
                            | std::io::ErrorKind::WouldBlock
                            | std::io::ErrorKind::Interrupted
                    ) => {}
                Err(e) => {
                    return Err(self.failed(format!("the serial port failed (unplugged?): {e}")));
                }
            }
        }
    }

    /// The state and work position of a report: GRBL sends the work
    /// offset only now and then, so the last one is kept.
    fn axis_status(&mut self, status: Status) -> AxisStatus {
        if let Some(offset) = status.work_offset {
            self.work_offset = offset;
        }
        let work_mm = match status.position {
            Position::Work(work) => work,
            Position::Machine(m) => {
                let o = self.work_offset;
                [m[0] - o[0], m[1] - o[1], m[2] - o[2]]
            }
        };
        AxisStatus { state: status.state, work_mm }
    }

    /// Soft reset (0x18) and GRBL's banner within `wait`.
    fn reset(&mut self, wait: Duration) -> Result<(), Fault> {
        // Whatever the controller said before (an old banner) is stale.
        self.pending.clear();
        let _ = self.port.clear(serialport::ClearBuffer::Input);
        self.write(&[0x18])?;
        let deadline = Instant::now() + wait;
        loop {
            match self.next_reply(deadline)? {
                Some(Reply::Banner(banner)) => {
                    if !banner.starts_with("Grbl 1.") {
                        return Err(self.failed(format!(
                            "`{banner}` is not GRBL 1.1, the protocol this driver speaks"
                        )));
                    }
                    break;
                }
                Some(_) => {}
                None => {
                    return Err(Fault::Timeout {
                        timeout: wait,
                        detail: format!(
                            "no GRBL banner on {} after a soft reset: is a GRBL 1.1 controller \
                             there, at this baud rate?",
                            self.name
                        ),
                    });
                }
            }
        }
        // The messages that follow the banner (the homing lock).
        let settle = Instant::now() + Duration::from_millis(50);
        while self.next_reply(settle)?.is_some() {}
        Ok(())
    }

    /// The fault of `ALARM:code` after `line`. GRBL then runs nothing until
    /// a soft reset, which this sends: the controller stays locked in
    /// alarm (G-code refused with error:9 until homed or unlocked), with
    /// the spindle, and so a laser on it, off.
    fn alarm(&mut self, code: u32, line: &str) -> Fault {
        let fault = self.failed(format!("ALARM:{code} ({}) after `{line}`", alarm_meaning(code)));
        let _ = self.reset(BANNER_WAIT);
        fault
    }

    /// The fault of a banner that came unasked: the controller reset itself
    /// (power, a DTR reset) and lost its position.
    fn reset_itself(&self, banner: &str, line: &str) -> Fault {
        self.failed(format!(
            "the controller reset itself (`{banner}`) during `{line}`; its position is lost: \
             home it again"
        ))
    }

    /// Sends `line` and waits for its `ok` at most `timeout`.
    fn command(&mut self, line: &str, timeout: Duration) -> Result<(), Fault> {
        self.command_with(line, timeout, |_| {})
    }

    /// [`GrblController::command`], handing each message line before the
    /// `ok` (`$$`'s settings, `[...]` feedback) to `on_message`.
    fn command_with(
        &mut self,
        line: &str,
        timeout: Duration,
        mut on_message: impl FnMut(&str),
    ) -> Result<(), Fault> {
        self.send_line(line)?;
        let deadline = Instant::now() + timeout;
        loop {
            match self.next_reply(deadline)? {
                Some(Reply::Ok) => return Ok(()),
                Some(Reply::Message(message)) => on_message(&message),
                Some(Reply::Error(code)) => {
                    return Err(self.failed(format!(
                        "`{line}` refused: error:{code} ({})",
                        error_meaning(code)
                    )));
                }
                Some(Reply::Alarm(code)) => {
                    return Err(self
                        .failed(format!("ALARM:{code} ({}) after `{line}`", alarm_meaning(code))));
                }
                Some(_) => {}
                None => {
                    return Err(Fault::Timeout {
                        timeout,
                        detail: format!("no `ok` from GRBL on {} for `{line}`", self.name),
                    });
                }
            }
        }
    }

    /// The controller's settings (`$$`): number and value, as GRBL prints
    /// them (`$32=0`), within `timeout`.
    fn settings(&mut self, timeout: Duration) -> Result<BTreeMap<u32, String>, Fault> {
        let mut settings = BTreeMap::new();
        self.command_with("$$", timeout, |line| {
            if let Some((number, value)) =
                line.strip_prefix('$').and_then(|rest| rest.split_once('='))
                && let Ok(number) = number.trim().parse()
            {
                // A comment may follow the value: `$32=0 (laser mode)`.
                let value = value.split_whitespace().next().unwrap_or_default();
                settings.insert(number, value.to_string());
            }
        })?;
        Ok(settings)
    }

    /// The value of setting `number` (`None` where the controller has no
    /// such setting), reading `$$` the first time.
    fn setting(&mut self, number: u32, timeout: Duration) -> Result<Option<String>, Fault> {
        if self.settings.is_none() {
            self.settings = Some(self.settings(timeout)?);
        }
        Ok(self.settings.as_ref().and_then(|s| s.get(&number).cloned()))
    }

    /// Refuses settings that break the slide's positions: report inches
    /// (`$13=1`) would read every position 25.4 times too small.
    fn check_slide_settings(&mut self, timeout: Duration) -> Result<(), Fault> {
        match self.setting(REPORT_INCHES_SETTING, timeout)?.as_deref() {
            Some("0") | None => Ok(()),
            Some(value) => Err(self.failed(format!(
                "${REPORT_INCHES_SETTING}={value} (report inches) gives the slide's positions in inches, read as mm; set ${REPORT_INCHES_SETTING}=0"
            ))),
        }
    }

    /// Refuses settings that break a scan with the laser on the spindle
    /// output: laser mode (`$32=1`) powers the output only while the axes
    /// move, so the laser would be dark in every frame taken at a standing
    /// slide.
    fn check_spindle_laser_settings(&mut self, timeout: Duration) -> Result<(), Fault> {
        match self.setting(LASER_MODE_SETTING, timeout)?.as_deref() {
            Some("0") | None => Ok(()),
            Some(value) => Err(self.failed(format!(
                "${LASER_MODE_SETTING}={value} (laser mode) powers the spindle output only while the slide moves, so the laser would be dark in every frame; set ${LASER_MODE_SETTING}=0"
            ))),
        }
    }

    /// One status report, within `timeout`.
    pub fn status(&mut self, timeout: Duration) -> Result<AxisStatus, DeviceError> {
        self.query_status(timeout).map_err(|f| f.on(Device::Slide))
    }

    fn query_status(&mut self, timeout: Duration) -> Result<AxisStatus, Fault> {
        self.write(b"?")?;
        let deadline = Instant::now() + timeout;
        loop {
            match self.next_reply(deadline)? {
                Some(Reply::Status(status)) => return Ok(self.axis_status(status)),
                Some(Reply::Alarm(code)) => {
                    return Err(self.failed(format!("ALARM:{code} ({})", alarm_meaning(code))));
                }
                Some(_) => {}
                None => {
                    return Err(Fault::Timeout {
                        timeout,
                        detail: format!("no status report from GRBL on {}", self.name),
                    });
                }
            }
        }
    }

    /// Homes (`$H`), waiting at most `timeout`; the machine must be idle after.
    fn home(&mut self, timeout: Duration, status_timeout: Duration) -> Result<(), Fault> {
        if let Err(fault) = self.command("$H", timeout) {
            // A homing cycle still running is stopped.
            if matches!(fault, Fault::Timeout { .. }) {
                let _ = self.reset(BANNER_WAIT);
            }
            return Err(fault);
        }
        let status = self.query_status(status_timeout)?;
        if status.state != "Idle" {
            return Err(self.failed(format!("not idle after homing: {}", status.state)));
        }
        Ok(())
    }

    /// Stops a motion: feed hold, then (once the slide stands, or after
    /// 2 s) a soft reset that empties GRBL's queue.
    fn stop(&mut self) {
        if self.write(b"!").is_err() {
            return;
        }
        let deadline = Instant::now() + HOLD_WAIT;
        while Instant::now() < deadline {
            match self.query_status(STATUS_PERIOD * 5) {
                Ok(status) if status.state == "Hold:0" || status.state == "Idle" => break,
                Ok(_) => std::thread::sleep(STATUS_PERIOD),
                Err(_) => break,
            }
        }
        let _ = self.reset(BANNER_WAIT);
    }

    /// Moves `axis` (0, 1, 2: X, Y, Z) to `target_mm` (work coordinates) at
    /// `feed` and waits until it stands there within `tolerance_mm`, at
    /// most `timeout`. Returns the reported position.
    fn move_axis(
        &mut self,
        axis: usize,
        target_mm: f64,
        feed_mm_per_min: f64,
        tolerance_mm: f64,
        timeout: Duration,
    ) -> Result<f64, Fault> {
        let letter = ["X", "Y", "Z"].get(axis).copied().unwrap_or("X");
        let line = format!("G90 G1 {letter}{target_mm:.3} F{feed_mm_per_min:.0}");
        self.send_line(&line)?;
        let start = Instant::now();
        let deadline = start + timeout;
        let mut last: Option<AxisStatus> = None;
        // The line's `ok` (GRBL sends it when the move is queued); a status
        // report can come before it, and an `ok` left unread would be taken
        // for the next command's.
        let mut queued = false;
        // Since when the slide has stood at the target without that `ok`.
        let mut standing_since: Option<Instant> = None;
        loop {
            if Instant::now() >= deadline {
                self.stop();
                let where_ = last
                    .map(|s| format!("; last report {} at {:.3} mm", s.state, s.work_mm[axis]))
                    .unwrap_or_else(|| "; no status report came".into());
                return Err(Fault::Timeout {
                    timeout,
                    detail: format!(
                        "GRBL on {} did not stand at {target_mm:.3} mm after `{line}`{where_}; \
                         feed hold and soft reset sent",
                        self.name
                    ),
                });
            }
            self.write(b"?")?;
            let poll = (Instant::now() + STATUS_PERIOD).min(deadline);
            while let Some(reply) = self.next_reply(poll)? {
                match reply {
                    Reply::Error(code) => {
                        return Err(self.failed(format!(
                            "`{line}` refused: error:{code} ({})",
                            error_meaning(code)
                        )));
                    }
                    Reply::Alarm(code) => return Err(self.alarm(code, &line)),
                    Reply::Banner(banner) => return Err(self.reset_itself(&banner, &line)),
                    Reply::Ok => queued = true,
                    Reply::Status(status) => {
                        let status = self.axis_status(status);
                        if status.state.starts_with("Alarm") {
                            return Err(
                                self.failed(format!("the controller is in alarm during `{line}`"))
                            );
                        }
                        let at = status.work_mm[axis];
                        if status.state == "Idle" && (at - target_mm).abs() <= tolerance_mm {
                            // Standing there, with the `ok` read, or long
                            // after it should have come (it was lost).
                            let since = *standing_since.get_or_insert_with(Instant::now);
                            if queued || since.elapsed() >= LOST_OK_WAIT {
                                return Ok(at);
                            }
                        } else {
                            standing_since = None;
                        }
                        last = Some(status);
                    }
                    Reply::Message(_) => {}
                }
            }
        }
    }
}

/// Locks the shared controller; a poisoned lock only means another device
/// panicked while holding it, and the port itself is still usable.
fn lock(controller: &Mutex<GrblController>) -> MutexGuard<'_, GrblController> {
    controller.lock().unwrap_or_else(PoisonError::into_inner)
}

/// GRBL 1.1's laser-mode setting (`$32`; 1: the spindle output is powered
/// only while the axes move, for laser cutters).
const LASER_MODE_SETTING: u32 = 32;

/// GRBL 1.1's report-inches setting (`$13`; 1: status reports in inches).
const REPORT_INCHES_SETTING: u32 = 13;

/// Opens the GRBL controller of `config` (a soft reset and its banner);
/// the slide and the laser on it share it.
pub fn connect(config: &SlideConfig) -> Result<Arc<Mutex<GrblController>>, DeviceError> {
    GrblController::open(config).map(|c| Arc::new(Mutex::new(c))).map_err(|f| f.on(Device::Slide))
}

/// The slide on a GRBL controller's axis.
#[derive(Debug)]
pub struct GrblSlide {
    controller: Arc<Mutex<GrblController>>,
    config: SlideConfig,
    axis: usize,
}

impl GrblSlide {
    /// The slide of `config` on `controller`.
    pub fn new(controller: Arc<Mutex<GrblController>>, config: SlideConfig) -> Self {
        let axis = match config.axis.as_str() {
            "Y" => 1,
            "Z" => 2,
            _ => 0,
        };
        Self { controller, config, axis }
    }

    /// Homes the slide (`$H`).
    pub fn home(&mut self) -> Result<(), DeviceError> {
        let timeout = self.config.command_timeout();
        lock(&self.controller)
            .home(self.config.homing_timeout(), timeout)
            .map_err(|f| f.on(Device::Slide))
    }

    /// Reads the controller's settings (`$$`) and refuses those that break
    /// the slide's positions (`$13=1`, inches), naming the setting.
    pub fn check_settings(&mut self) -> Result<(), DeviceError> {
        let timeout = self.config.command_timeout();
        lock(&self.controller).check_slide_settings(timeout).map_err(|f| f.on(Device::Slide))
    }

    /// Whether the controller reports an alarm (it needs homing or `$X`).
    pub fn state(&mut self) -> Result<String, DeviceError> {
        let timeout = self.config.command_timeout();
        lock(&self.controller).status(timeout).map(|s| s.state)
    }
}

impl Slide for GrblSlide {
    fn stroke_mm(&self) -> f64 {
        self.config.stroke_mm
    }

    fn move_to(&mut self, target_mm: f64, timeout: Duration) -> alacs_scanner::Result<f64> {
        check_target(target_mm, self.config.stroke_mm)?;
        let axis_mm = self.config.axis_mm(target_mm);
        let reached = lock(&self.controller)
            .move_axis(
                self.axis,
                axis_mm,
                self.config.feed_mm_per_min,
                self.config.tolerance_mm,
                timeout,
            )
            .map_err(|f| f.on(Device::Slide))?;
        Ok(self.config.travel_mm(reached))
    }

    fn position_mm(&mut self) -> alacs_scanner::Result<f64> {
        let timeout = self.config.command_timeout();
        let status = lock(&self.controller).status(timeout)?;
        Ok(self.config.travel_mm(status.work_mm[self.axis]))
    }

    /// Sends `G90 G1` to the target at the speed (GRBL caps it at the
    /// axis's `$110`-`$112` maximum rate) and returns once GRBL has queued
    /// it (its `ok`): the move has begun.
    fn start_move(&mut self, target_mm: f64, speed_mm_per_s: f64) -> alacs_scanner::Result<()> {
        check_target(target_mm, self.config.stroke_mm)?;
        check_sweep_speed(speed_mm_per_s)?;
        let letter = ["X", "Y", "Z"].get(self.axis).copied().unwrap_or("X");
        let axis_mm = self.config.axis_mm(target_mm);
        let feed_mm_per_min = speed_mm_per_s * 60.0;
        let line = format!("G90 G1 {letter}{axis_mm:.3} F{feed_mm_per_min:.1}");
        let timeout = self.config.command_timeout();
        lock(&self.controller).command(&line, timeout).map_err(|f| f.on(Device::Slide))
    }

    /// A status report (`?`). GRBL computes the position when it reads the
    /// `?` and then sends the report, so the report's moment is taken as
    /// its arrival less the report's transmission at the port's baud rate
    /// (about 4 ms at 115200; a USB serial adapter's own latency, up to a
    /// few ms, is not known and not removed).
    fn report(&mut self) -> alacs_scanner::Result<SlideReport> {
        let timeout = self.config.command_timeout();
        let sent = Instant::now();
        let status = lock(&self.controller).status(timeout)?;
        let arrived = Instant::now();
        let transmission = Duration::from_secs_f64(
            REPORT_BYTES * BITS_PER_BYTE / f64::from(self.config.baud.max(1)),
        );
        let at = arrived.checked_sub(transmission).map_or(sent, |at| at.max(sent));
        if status.state.starts_with("Alarm") {
            return Err(DeviceError::Device {
                device: Device::Slide,
                step: None,
                message: format!("GRBL reports {} during a sweep", status.state),
            });
        }
        Ok(SlideReport {
            position_mm: self.config.travel_mm(status.work_mm[self.axis]),
            at,
            moving: status.state != "Idle",
        })
    }
}

/// A status report's length, bytes: `<Run|MPos:100.000,0.000,0.000|FS:3000,0>` and CR LF.
const REPORT_BYTES: f64 = 44.0;

/// A serial byte with its start and stop bits.
const BITS_PER_BYTE: f64 = 10.0;

/// The laser on a GRBL controller's spindle output. Dropping it switches
/// the laser off (best effort).
#[derive(Debug)]
pub struct GrblLaser {
    controller: Arc<Mutex<GrblController>>,
    config: LaserConfig,
    timeout: Duration,
}

impl GrblLaser {
    /// The laser of `config` on `controller`; `timeout` for each command.
    /// The controller's settings (`$$`, read once per controller) are
    /// checked first: laser mode (`$32=1`) is refused, naming the setting.
    pub fn new(
        controller: Arc<Mutex<GrblController>>,
        config: LaserConfig,
        timeout: Duration,
    ) -> Result<Self, DeviceError> {
        lock(&controller).check_spindle_laser_settings(timeout).map_err(|f| f.on(Device::Laser))?;
        Ok(Self { controller, config, timeout })
    }
}

impl LaserSwitch for GrblLaser {
    fn set(&mut self, on: bool) -> alacs_scanner::Result<()> {
        let line = if on { self.config.on_line() } else { self.config.off_command.clone() };
        let result = lock(&self.controller).command(&line, self.timeout);
        match result {
            Ok(()) => {}
            // GRBL stops the spindle on every reset and alarm, and then
            // locks G-code out (error:9): the laser is off.
            Err(Fault::Failed(message)) if !on && message.contains("error:9 ") => {}
            Err(fault) => return Err(fault.on(Device::Laser)),
        }
        if self.config.settle_ms > 0.0 {
            std::thread::sleep(Duration::from_secs_f64(self.config.settle_ms / 1000.0));
        }
        Ok(())
    }
}

impl Drop for GrblLaser {
    fn drop(&mut self) {
        let line = self.config.off_command.clone();
        let _ = lock(&self.controller).command(&line, self.timeout);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_reports_parse_with_machine_or_work_positions() {
        let status = parse_status("Idle|MPos:10.000,0.000,0.000|FS:0,0").unwrap();
        assert_eq!(status.state, "Idle");
        assert_eq!(status.position, Position::Machine([10.0, 0.0, 0.0]));
        assert_eq!(status.work_offset, None);
        let status =
            parse_status("Run|MPos:10.000,2.000,0.000|FS:500,0|WCO:5.000,0.000,0.000").unwrap();
        assert_eq!(status.work_offset, Some([5.0, 0.0, 0.0]));
        let status = parse_status("Hold:0|WPos:-1.500,0.000,0.000|Bf:15,128").unwrap();
        assert_eq!(status.state, "Hold:0");
        assert_eq!(status.position, Position::Work([-1.5, 0.0, 0.0]));
    }

    #[test]
    fn garbage_lines_are_not_replies() {
        for line in ["", "\u{fffd}@@garbage@@", "<>", "<Idle|MPos:a,b,c>", "error:x", "okay"] {
            assert_eq!(parse_reply(line), None, "{line:?}");
        }
        assert_eq!(parse_reply("ok\r"), Some(Reply::Ok));
        assert_eq!(parse_reply("error:9"), Some(Reply::Error(9)));
        assert_eq!(parse_reply("ALARM:2"), Some(Reply::Alarm(2)));
        assert!(matches!(parse_reply("Grbl 1.1h ['$' for help]"), Some(Reply::Banner(_))));
        assert!(matches!(parse_reply("[MSG:'$H'|'$X' to unlock]"), Some(Reply::Message(_))));
    }
}

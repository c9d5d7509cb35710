//! The scan controller: from the RGB-D camera's rough fruit position to the
//! frames of an active scan, then to the fruit's centre.
//!
//! 1. The rough position is carried from the RGB-D camera's frame into the
//!    ALACS camera's ([`ControllerConfig::alacs_from_rgbd`]).
//! 2. The seed's strategy plans the slide positions from it
//!    ([`ScanStrategy::plan`]: the laser on the left half of the fruit,
//!    then steps to the right, shifted into the stroke). Several fruit
//!    ([`ScanController::run_targets_with_progress`]) are covered in one
//!    sweep ([`ScanStrategy::plan_sweep`]), each with its own five frames.
//! 3. With [`ControllerConfig::metering`], once the slide stands at the
//!    first frame's position, the target is metered with the laser off and
//!    the camera's exposure set so that the fruit (the brightest of several)
//!    does not clip
//!    ([`crate::metering`]); a bright scene also gets laser-off frames.
//! 4. Per frame: move the slide and wait until it settles, switch the laser
//!    on, capture; with [`ControllerConfig::capture_laser_off`] (or a bright
//!    scene), switch it off and capture again at the same position.
//!    Or, with [`ScanMode::Continuous`], one run of the slide through
//!    the positions, frames captured on the way ([`crate::sweep`]).
//! 5. The laser is switched off at the end, and whenever a step fails.
//! 6. Where localization did not find a fruit in those frames for want of
//!    evidence, a few more beyond both ends of its sweep, stop-and-go
//!    ([`ScanController::localize_extending`], [`ScanStrategy::extension`]),
//!    and localization of it again with all of them.
//!
//! The frames keep the positions the slide reported, not the plan's:
//! localization triangulates with where the laser was.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};

use alacs_locate::{FrameImages, Localization, LocateOptions, Prior, Status, locate};
use alacs_model::io::OutputDir;
use alacs_model::{
    Camera, DEFAULT_FRUIT_RADIUS_MM, FrameExposure, LaserModel, MAX_SCAN_TARGETS, SCAN_FILE,
    SHARED_FRAME_MM, Scan, ScanFrameSpec, ScanPlan, ScanStrategy, ScanTarget,
};
use image::RgbImage;
use nalgebra::{Isometry3, Point3};

use crate::hardware::Rig;
use crate::metering::{MeteredExposure, Metering, meter};
use crate::sweep::{Sweep, run_sweep};
use crate::{Error, Result, Step};

/// Settings of [`ScanController`]. `Default`: the seed's strategy, the
/// RGB-D and ALACS frames the same, no laser-off frames, a 40 mm radius
/// prior, no metering (the camera's exposure as it is).
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerConfig {
    /// Frames, step and stroke of the scan (the seed paper's by default).
    pub strategy: ScanStrategy,
    /// The pose of the RGB-D camera in the ALACS camera frame:
    /// `point_in_alacs = alacs_from_rgbd * point_in_rgbd` (mm). Identity by
    /// default (a rough position already in the ALACS frame).
    pub alacs_from_rgbd: Isometry3<f64>,
    /// Also capture every frame with the laser off (for differencing).
    pub capture_laser_off: bool,
    /// Longest wait for the slide to reach and settle at a position.
    pub move_timeout: Duration,
    /// Longest wait for one frame.
    pub capture_timeout: Duration,
    /// The fruit radius prior, mm (plans the start and seeds localization).
    pub fruit_radius_mm: f64,
    /// Largest difference between a commanded and a reported slide
    /// position, mm, before the scan stops.
    pub position_tolerance_mm: f64,
    /// Meter the target and set the camera's exposure before the frames
    /// (`None`: leave the camera's exposure and gain as they are).
    pub metering: Option<Metering>,
    /// Stop-and-go (the seed's) or a continuous sweep.
    pub mode: ScanMode,
}

/// How the slide takes the frames.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum ScanMode {
    /// The seed's: per frame, move, settle, capture.
    #[default]
    StopAndGo,
    /// One run of the slide through the frames' positions, the camera
    /// capturing on the way ([`crate::sweep`]); the slide and camera must
    /// report positions and exposure times ([`crate::Slide::report`],
    /// [`crate::FrameCamera::capture_timed`]).
    Continuous(Sweep),
}

impl ScanMode {
    /// The modes' names in rig.toml, the CLI, scan --json and the ROS
    /// node: stop-and-go's, then the continuous sweep's.
    pub const NAMES: [&'static str; 2] = ["stop_and_go", "continuous"];

    /// The mode's name (one of [`ScanMode::NAMES`]).
    pub fn name(&self) -> &'static str {
        Self::name_of(matches!(self, ScanMode::Continuous(_)))
    }

    /// The name of the continuous sweep (`true`) or of stop-and-go.
    pub fn name_of(continuous: bool) -> &'static str {
        Self::NAMES[usize::from(continuous)]
    }
}

impl Default for ControllerConfig {
    fn default() -> Self {
        Self {
            strategy: ScanStrategy::default(),
            alacs_from_rgbd: Isometry3::identity(),
            capture_laser_off: false,
            move_timeout: Duration::from_secs(10),
            capture_timeout: Duration::from_secs(2),
            fruit_radius_mm: DEFAULT_FRUIT_RADIUS_MM,
            position_tolerance_mm: DEFAULT_POSITION_TOLERANCE_MM,
            metering: None,
            mode: ScanMode::StopAndGo,
        }
    }
}

/// A slide that settles 0.5 mm from its target moves the laser plane about
/// 0.5 mm at the fruit; the frames keep the reported position, so this only
/// catches a slide that did not go where it was sent.
const DEFAULT_POSITION_TOLERANCE_MM: f64 = 0.5;

/// Runs active scans with a laser model (the calibrated laser.yaml) and
/// [`ControllerConfig`].
#[derive(Debug, Clone)]
pub struct ScanController {
    laser: LaserModel,
    config: ControllerConfig,
}

/// One captured frame.
#[derive(Debug, Clone)]
pub struct CapturedFrame {
    /// Where the plan put the slide, mm.
    pub planned_slide_mm: f64,
    /// Where the slide reported it settled, mm: the frame's slide travel d.
    pub slide_mm: f64,
    /// The frame with the laser on.
    pub image: RgbImage,
    /// The same view with the laser off, if captured: shared by every
    /// frame of a continuous sweep (one reference frame), written once.
    pub image_laser_off: Option<Arc<RgbImage>>,
    /// When the laser-on image and the laser-off image (if any) arrived
    /// (the host's clock).
    pub captured_at: [Option<SystemTime>; 2],
}

/// What a scan captured.
#[derive(Debug, Clone)]
pub struct CapturedScan {
    /// The rough fruit centre as the RGB-D camera gave it, its frame, mm.
    pub rough_position_in_rgbd_mm: Point3<f64>,
    /// The rough fruit centre in the ALACS camera frame, mm.
    pub rough_position_mm: Point3<f64>,
    /// The fruit radius prior, mm.
    pub fruit_radius_mm: f64,
    /// The fruit after the first of a scan of several
    /// ([`ScanController::run_targets_with_progress`]), in their order;
    /// empty for one fruit.
    pub more_targets: Vec<ScanTarget>,
    /// The plan the scan followed.
    pub plan: ScanPlan,
    /// The frames, in plan order, then any extension frames
    /// ([`ScanController::localize_extending`]) in the order taken.
    pub frames: Vec<CapturedFrame>,
    /// The camera's exposure over the frames, if known (the controller
    /// knows it when it metered).
    pub exposure: Option<FrameExposure>,
    /// A continuous sweep's speed, mm/s: the fastest the slide went over a
    /// frame, from its reports (`None`: stop-and-go).
    pub sweep_speed_mm_per_s: Option<f64>,
}

impl CapturedScan {
    /// The name of the mode the frames were taken in ([`ScanMode::NAMES`]):
    /// a sweep speed says continuous.
    pub fn mode_name(&self) -> &'static str {
        ScanMode::name_of(self.sweep_speed_mm_per_s.is_some())
    }
}

/// A fruit to scan: its rough centre in the ALACS camera's frame and the
/// radius prior, mm.
pub type FruitToScan = (Point3<f64>, f64);

impl ScanController {
    /// A controller planning with `laser`; checks the configuration.
    pub fn new(laser: LaserModel, config: ControllerConfig) -> Result<Self> {
        laser.validate().map_err(|e| Error::InvalidInput(format!("laser: {e}")))?;
        let invalid = |m: String| Err(Error::InvalidInput(m));
        let s = &config.strategy;
        if s.frames == 0 {
            return invalid("the strategy has no frames".into());
        }
        if !(s.step_mm.is_finite() && s.stroke_mm.is_finite() && s.stroke_mm > 0.0) {
            return invalid(format!(
                "the strategy's step {} mm and stroke {} mm must be finite, the stroke positive",
                s.step_mm, s.stroke_mm
            ));
        }
        if !s.start_left_of_centre.is_finite() {
            return invalid("the strategy's start must be finite".into());
        }
        if !(config.fruit_radius_mm.is_finite() && config.fruit_radius_mm > 0.0) {
            return invalid(format!(
                "the fruit radius prior {} mm must be positive",
                config.fruit_radius_mm
            ));
        }
        if !(config.position_tolerance_mm.is_finite() && config.position_tolerance_mm >= 0.0) {
            return invalid(format!(
                "the position tolerance {} mm must be non-negative",
                config.position_tolerance_mm
            ));
        }
        if config.move_timeout.is_zero() || config.capture_timeout.is_zero() {
            return invalid("timeouts must be longer than zero".into());
        }
        if let Some(metering) = &config.metering {
            metering.validate()?;
        }
        if let ScanMode::Continuous(sweep) = &config.mode {
            sweep.validate()?;
        }
        let transform = config.alacs_from_rgbd.to_homogeneous();
        if !transform.iter().all(|v| v.is_finite()) {
            return invalid("the RGB-D to ALACS transform must be finite".into());
        }
        Ok(Self { laser, config })
    }

    /// The configuration.
    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }

    /// The laser model the controller plans with.
    pub fn laser(&self) -> &LaserModel {
        &self.laser
    }

    /// The rough position in the ALACS camera frame, checked to lie in
    /// front of the camera.
    pub fn rough_in_alacs(&self, rough_position_in_rgbd_mm: &Point3<f64>) -> Result<Point3<f64>> {
        let rough = self.config.alacs_from_rgbd * rough_position_in_rgbd_mm;
        if !(rough.coords.iter().all(|c| c.is_finite()) && rough.z > 0.0) {
            let r = rough_position_in_rgbd_mm;
            return Err(Error::InvalidInput(format!(
                "the rough position ({:.1}, {:.1}, {:.1}) mm of the RGB-D camera is at ({:.1}, {:.1}, {:.1}) mm in the ALACS camera frame, not in front of the camera; check alacs_from_rgbd",
                r.x, r.y, r.z, rough.x, rough.y, rough.z
            )));
        }
        Ok(rough)
    }

    /// The plan for a rough position in the RGB-D frame.
    pub fn plan(&self, rough_position_in_rgbd_mm: &Point3<f64>) -> Result<ScanPlan> {
        let rough = self.rough_in_alacs(rough_position_in_rgbd_mm)?;
        Ok(self.config.strategy.plan(&self.laser, &rough, self.config.fruit_radius_mm))
    }

    /// The sweep's plan for several fruit (rough positions in the RGB-D
    /// camera's frame, 1 to [`MAX_SCAN_TARGETS`],
    /// [`ScanStrategy::plan_sweep`]), and each fruit in the ALACS camera's
    /// frame with the configured radius.
    pub fn plan_targets(
        &self,
        rough_positions_in_rgbd_mm: &[Point3<f64>],
    ) -> Result<(ScanPlan, Vec<FruitToScan>)> {
        let n = rough_positions_in_rgbd_mm.len();
        if !(1..=MAX_SCAN_TARGETS).contains(&n) {
            return Err(Error::InvalidInput(format!(
                "{n} rough positions: a scan covers 1-{MAX_SCAN_TARGETS} fruit"
            )));
        }
        let radius_mm = self.config.fruit_radius_mm;
        let fruit = rough_positions_in_rgbd_mm
            .iter()
            .map(|r| self.rough_in_alacs(r).map(|r| (r, radius_mm)))
            .collect::<Result<Vec<_>>>()?;
        Ok((self.config.strategy.plan_sweep(&self.laser, &fruit), fruit))
    }

    /// How many images the sweep of one fruit captures at most: laser-on
    /// and laser-off frames (a sweep's one laser-off reference frame), and
    /// the metering frames; an extension
    /// ([`ScanController::localize_extending`]) takes more. A metered scene that is not bright takes no
    /// laser-off frames; the progress callback of
    /// [`ScanController::run_with_progress`] has the count of each scan.
    pub fn image_count(&self) -> usize {
        let frames = self.config.strategy.frames;
        let laser_off = self.config.capture_laser_off || self.config.metering.is_some();
        let images = match self.config.mode {
            ScanMode::StopAndGo => frames * (1 + usize::from(laser_off)),
            ScanMode::Continuous(_) => frames + 1,
        };
        images + self.config.metering.as_ref().map_or(0, |m| m.max_frames)
    }

    /// Scans the fruit roughly at `rough_position_in_rgbd_mm` (the RGB-D
    /// camera's frame) with `rig`.
    pub fn run(
        &self,
        rig: &mut Rig<'_>,
        rough_position_in_rgbd_mm: &Point3<f64>,
    ) -> Result<CapturedScan> {
        self.run_with_progress(rig, rough_position_in_rgbd_mm, |_, _| {})
    }

    /// [`ScanController::run`], calling `progress(done, total)` after each
    /// image (metering frames first; `total` is known once metering is done
    /// and counts them).
    pub fn run_with_progress(
        &self,
        rig: &mut Rig<'_>,
        rough_position_in_rgbd_mm: &Point3<f64>,
        progress: impl FnMut(usize, usize),
    ) -> Result<CapturedScan> {
        self.run_targets_with_progress(
            rig,
            std::slice::from_ref(rough_position_in_rgbd_mm),
            progress,
        )
    }

    /// Scans several fruit (rough positions in the RGB-D camera's frame,
    /// 1 to [`MAX_SCAN_TARGETS`]) in one sweep ([`ScanStrategy::plan_sweep`]):
    /// each fruit gets its own five frames, frames that fall together are
    /// taken once, and metering keeps the brightest fruit below clipping.
    /// One fruit is [`ScanController::run_with_progress`].
    pub fn run_targets_with_progress(
        &self,
        rig: &mut Rig<'_>,
        rough_positions_in_rgbd_mm: &[Point3<f64>],
        mut progress: impl FnMut(usize, usize),
    ) -> Result<CapturedScan> {
        let (plan, fruit) = self.plan_targets(rough_positions_in_rgbd_mm)?;
        // The plan fits the strategy's stroke; the slide's may be shorter.
        let stroke_mm = rig.slide.stroke_mm();
        if let Some(target_mm) = plan.first_beyond_stroke(stroke_mm) {
            return Err(Error::OutOfStroke { step: Some(Step::Planning), target_mm, stroke_mm });
        }
        let captured = match &self.config.mode {
            ScanMode::StopAndGo => self.capture_frames(rig, &plan, &fruit, &mut progress),
            ScanMode::Continuous(sweep) => {
                self.capture_sweep(sweep, rig, &plan, &fruit, &mut progress)
            }
        };
        let (frames, exposure, sweep_speed_mm_per_s) = match captured {
            Ok(captured) => captured,
            Err(error) => {
                // Whatever failed, the laser goes off; the first error is the one reported.
                let _ = rig.laser.set(false);
                return Err(error);
            }
        };
        rig.laser.set(false).map_err(|e| e.at(Step::Finish))?;
        let more_targets = fruit
            .iter()
            .zip(rough_positions_in_rgbd_mm)
            .skip(1)
            .map(|(&(rough_position_mm, fruit_radius_mm), &in_rgbd)| ScanTarget {
                rough_position_mm,
                fruit_radius_mm,
                rough_position_in_rgbd_mm: Some(in_rgbd),
            })
            .collect();
        Ok(CapturedScan {
            rough_position_in_rgbd_mm: rough_positions_in_rgbd_mm[0],
            rough_position_mm: fruit[0].0,
            fruit_radius_mm: fruit[0].1,
            more_targets,
            plan,
            frames,
            exposure: exposure
                .map(|e| FrameExposure { exposure_us: e.exposure_us, gain_db: e.gain_db }),
            sweep_speed_mm_per_s,
        })
    }

    /// Meters the targets, if configured.
    fn meter(
        &self,
        rig: &mut Rig<'_>,
        fruit: &[(Point3<f64>, f64)],
    ) -> Result<Option<MeteredExposure>> {
        let Some(metering) = &self.config.metering else { return Ok(None) };
        meter(metering, rig, fruit, self.config.capture_timeout).map(Some)
    }

    /// Moves, meters (at the first frame's position, once the slide is
    /// there), and captures every frame.
    fn capture_frames(
        &self,
        rig: &mut Rig<'_>,
        plan: &ScanPlan,
        fruit: &[(Point3<f64>, f64)],
        progress: &mut impl FnMut(usize, usize),
    ) -> Result<Captured> {
        let mut exposure = None;
        let mut laser_off = self.config.capture_laser_off;
        let images = |laser_off: bool| plan.slides_mm.len() * (1 + usize::from(laser_off));
        let mut total = images(laser_off);
        let mut done = 0;
        let mut frames = Vec::with_capacity(plan.slides_mm.len());
        for (frame, &target_mm) in plan.slides_mm.iter().enumerate() {
            let slide_mm = self.move_slide(rig, frame, target_mm)?;
            if frame == 0 {
                exposure = self.meter(rig, fruit)?;
                if let Some(metered) = exposure {
                    laser_off |= metered.bright;
                    total = metered.frames + images(laser_off);
                    done = metered.frames;
                    progress(done, total);
                }
            }
            let mut tick = || {
                done += 1;
                progress(done, total);
            };
            frames.push(self.capture_frame(rig, frame, target_mm, slide_mm, laser_off, &mut tick)?);
        }
        Ok((frames, exposure, None))
    }

    /// Moves the slide for frame `frame` and checks where it settled.
    fn move_slide(&self, rig: &mut Rig<'_>, frame: usize, target_mm: f64) -> Result<f64> {
        let step = Step::Move { frame, target_mm };
        let slide_mm =
            rig.slide.move_to(target_mm, self.config.move_timeout).map_err(|e| e.at(step))?;
        let tolerance_mm = self.config.position_tolerance_mm;
        if !(slide_mm.is_finite() && (slide_mm - target_mm).abs() <= tolerance_mm) {
            return Err(Error::PositionMismatch {
                step: Some(step),
                target_mm,
                reached_mm: slide_mm,
                tolerance_mm,
            });
        }
        Ok(slide_mm)
    }

    /// Captures frame `frame` where the slide stands: laser on, then with
    /// `laser_off` off as well, calling `tick` after each image.
    fn capture_frame(
        &self,
        rig: &mut Rig<'_>,
        frame: usize,
        planned_slide_mm: f64,
        slide_mm: f64,
        laser_off: bool,
        tick: &mut impl FnMut(),
    ) -> Result<CapturedFrame> {
        let image = self.capture(rig, frame, true)?;
        let on_at = SystemTime::now();
        tick();
        let (image_laser_off, off_at) = if laser_off {
            let off = self.capture(rig, frame, false)?;
            tick();
            (Some(Arc::new(off)), Some(SystemTime::now()))
        } else {
            (None, None)
        };
        Ok(CapturedFrame {
            planned_slide_mm,
            slide_mm,
            image,
            image_laser_off,
            captured_at: [Some(on_at), off_at],
        })
    }

    /// The slide positions that extend `scan` for its fruit `missed`
    /// (indices into [`CapturedScan::priors`]): each missed fruit's
    /// [`ScanStrategy::extension`] of its own plan, within `stroke_mm`,
    /// none within [`SHARED_FRAME_MM`] of a frame taken or of another;
    /// nearest the slide's last position first on its side, then the other
    /// side, so the slide crosses the sweep once.
    pub fn extension_slides(
        &self,
        scan: &CapturedScan,
        missed: &[usize],
        stroke_mm: f64,
    ) -> Vec<f64> {
        let strategy = &self.config.strategy;
        let priors = scan.priors();
        let mut taken = scan.slides_mm();
        let mut slides: Vec<f64> = Vec::new();
        for prior in missed.iter().filter_map(|&k| priors.get(k)) {
            let plan = strategy.plan(&self.laser, &prior.rough_position_mm, prior.fruit_radius_mm);
            for d in strategy.extension(&plan) {
                if d <= stroke_mm && taken.iter().all(|t| (d - t).abs() >= SHARED_FRAME_MM) {
                    taken.push(d);
                    slides.push(d);
                }
            }
        }
        let here = scan.frames.last().map_or(0.0, |f| f.slide_mm);
        let (mut ahead, mut behind): (Vec<f64>, Vec<f64>) =
            slides.into_iter().partition(|d| *d >= here);
        ahead.sort_by(f64::total_cmp);
        behind.sort_by(|a, b| b.total_cmp(a));
        ahead.extend(behind);
        ahead
    }

    /// Captures frames at `slides_mm` stop-and-go, at the exposure the
    /// camera was left at by the scan, and appends them to `scan`.
    /// Laser-off frames are taken where the scan took them per frame; a
    /// continuous sweep's one laser-off reference serves the new frames too
    /// (the scene stands still). Calls `progress(done, total)` after each
    /// image. The laser is off at the end and whenever a step fails; a
    /// failure adds no frame.
    pub fn capture_more(
        &self,
        rig: &mut Rig<'_>,
        scan: &mut CapturedScan,
        slides_mm: &[f64],
        mut progress: impl FnMut(usize, usize),
    ) -> Result<()> {
        let reference_off = scan
            .sweep_speed_mm_per_s
            .and_then(|_| scan.frames.first().and_then(|f| f.image_laser_off.clone()));
        let laser_off =
            reference_off.is_none() && scan.frames.iter().any(|f| f.image_laser_off.is_some());
        let total = slides_mm.len() * (1 + usize::from(laser_off));
        let mut done = 0;
        let first = scan.frames.len();
        let mut added = Vec::with_capacity(slides_mm.len());
        let mut capture = || -> Result<()> {
            for (k, &target_mm) in slides_mm.iter().enumerate() {
                let frame = first + k;
                let slide_mm = self.move_slide(rig, frame, target_mm)?;
                let mut tick = || {
                    done += 1;
                    progress(done, total);
                };
                let mut captured =
                    self.capture_frame(rig, frame, target_mm, slide_mm, laser_off, &mut tick)?;
                if let Some(off) = &reference_off {
                    captured.image_laser_off = Some(Arc::clone(off));
                    captured.captured_at[1] = scan.frames[0].captured_at[1];
                }
                added.push(captured);
            }
            Ok(())
        };
        let captured = capture();
        // Whatever happened, the laser goes off; the first error is the one reported.
        let off = rig.laser.set(false).map_err(|e| e.at(Step::Finish));
        captured?;
        off?;
        scan.frames.extend(added);
        Ok(())
    }

    /// Localizes every fruit of `scan`; where one is not found for want of
    /// evidence (not where its inputs contradict each other), extends the
    /// sweep for it ([`ScanController::extension_slides`],
    /// [`ScanController::capture_more`]) and localizes it again with all
    /// frames. The answers found in the sweep stay. `on_extension` hears
    /// the positions before the slide moves, `progress` the extension's
    /// images. Localization's errors (bad input) are the error; a device
    /// failure during the extension leaves the scan and the sweep's answers
    /// as they were and is [`Localized::extension_error`].
    #[allow(clippy::too_many_arguments)]
    pub fn localize_extending(
        &self,
        rig: &mut Rig<'_>,
        scan: &mut CapturedScan,
        camera: &Camera,
        laser: &LaserModel,
        options: &LocateOptions,
        on_extension: impl FnOnce(&[f64]),
        progress: impl FnMut(usize, usize),
    ) -> Result<Localized> {
        let started = Instant::now();
        let mut answers = scan.localize_targets(camera, laser, options)?;
        let mut localizing = started.elapsed();
        let missed: Vec<usize> = answers
            .iter()
            .enumerate()
            .filter(|(_, a)| a.status != Status::Ok && !a.contradicted)
            .map(|(k, _)| k)
            .collect();
        let slides = self.extension_slides(scan, &missed, rig.slide.stroke_mm());
        if slides.is_empty() {
            return Ok(Localized { answers, added: 0, extension_error: None, localizing });
        }
        on_extension(&slides);
        if let Err(error) = self.capture_more(rig, scan, &slides, progress) {
            return Ok(Localized { answers, added: 0, extension_error: Some(error), localizing });
        }
        let started = Instant::now();
        let frames = scan.frame_images();
        let priors = scan.priors();
        for k in missed {
            if let (Some(answer), Some(prior)) = (answers.get_mut(k), priors.get(k)) {
                *answer = locate(camera, laser, prior, &frames, options)?;
            }
        }
        localizing += started.elapsed();
        Ok(Localized { answers, added: slides.len(), extension_error: None, localizing })
    }

    /// Meters (where the slide stands: the laser is off, so its position
    /// does not matter), then sweeps ([`run_sweep`]).
    fn capture_sweep(
        &self,
        sweep: &Sweep,
        rig: &mut Rig<'_>,
        plan: &ScanPlan,
        fruit: &[(Point3<f64>, f64)],
        progress: &mut impl FnMut(usize, usize),
    ) -> Result<Captured> {
        let exposure = self.meter(rig, fruit)?;
        let laser_off =
            self.config.capture_laser_off || exposure.as_ref().is_some_and(|m| m.bright);
        let metered = exposure.as_ref().map_or(0, |m| m.frames);
        // The reference frame and one frame per position.
        let total = metered + 1 + plan.slides_mm.len();
        let mut done = metered;
        progress(done, total);
        let mut tick = || {
            done += 1;
            progress(done, total);
        };
        let captured = run_sweep(
            sweep,
            &self.laser,
            rig,
            plan,
            fruit,
            self.config.move_timeout,
            self.config.capture_timeout,
            &mut tick,
        )?;
        let reference_off = laser_off.then(|| Arc::new(captured.reference_off));
        let off_at = laser_off.then_some(captured.reference_at);
        let frames = captured
            .frames
            .into_iter()
            .map(|f| CapturedFrame {
                planned_slide_mm: f.planned_slide_mm,
                slide_mm: f.slide_mm,
                image: f.image,
                image_laser_off: reference_off.clone(),
                captured_at: [Some(f.captured_at), off_at],
            })
            .collect();
        Ok((frames, exposure, Some(captured.speed_mm_per_s)))
    }

    /// Switches the laser on (`laser_on`) or off and captures frame `frame`.
    fn capture(&self, rig: &mut Rig<'_>, frame: usize, laser_on: bool) -> Result<RgbImage> {
        rig.laser.set(laser_on).map_err(|e| e.at(Step::Laser { frame, on: laser_on }))?;
        rig.camera
            .capture(self.config.capture_timeout)
            .map_err(|e| e.at(Step::Capture { frame, laser_on }))
    }
}

/// What [`ScanController::localize_extending`] gives.
#[derive(Debug)]
pub struct Localized {
    /// One answer per fruit, in [`CapturedScan::priors`]' order.
    pub answers: Vec<Localization>,
    /// Frames the extension added to the scan.
    pub added: usize,
    /// Why the extension's frames were not taken, if a device failed: the
    /// answers are then the sweep's.
    pub extension_error: Option<Error>,
    /// Time spent localizing (not the rig's).
    pub localizing: Duration,
}

/// What a capture returns: the frames, the metered exposure, a sweep's speed.
type Captured = (Vec<CapturedFrame>, Option<MeteredExposure>, Option<f64>);

/// File name of frame `index`'s laser-on or laser-off PNG.
fn frame_file(index: usize, laser_on: bool) -> String {
    if laser_on { format!("frame{index}.png") } else { format!("frame{index}_off.png") }
}

impl CapturedScan {
    /// The first frame sharing frame `index`'s laser-off image (a sweep's
    /// one reference frame is written once, under that frame's name).
    fn laser_off_owner(&self, index: usize) -> Option<usize> {
        let off = self.frames.get(index)?.image_laser_off.as_ref()?;
        self.frames
            .iter()
            .position(|f| f.image_laser_off.as_ref().is_some_and(|o| Arc::ptr_eq(o, off)))
    }

    /// The file of frame `index`'s laser-off image.
    fn laser_off_file(&self, index: usize) -> Option<String> {
        self.laser_off_owner(index).map(|owner| frame_file(owner, false))
    }

    /// Frame `index`'s laser-off image if it is the first frame that has it:
    /// the one to write.
    fn own_laser_off(&self, index: usize) -> Option<&RgbImage> {
        if self.laser_off_owner(index)? != index {
            return None;
        }
        self.frames.get(index)?.image_laser_off.as_deref()
    }

    /// The frames as [`alacs_locate::locate`] takes them.
    pub fn frame_images(&self) -> Vec<FrameImages<'_>> {
        self.frames
            .iter()
            .map(|f| FrameImages {
                image: &f.image,
                image_laser_off: f.image_laser_off.as_deref(),
                slide_mm: f.slide_mm,
            })
            .collect()
    }

    /// What localization knows before it looks: the rough position (ALACS
    /// frame) and the radius prior (of the first fruit of several).
    pub fn prior(&self) -> Prior {
        Prior { rough_position_mm: self.rough_position_mm, fruit_radius_mm: self.fruit_radius_mm }
    }

    /// The prior of every fruit scanned, in order.
    pub fn priors(&self) -> Vec<Prior> {
        std::iter::once(self.prior()).chain(self.more_targets.iter().map(Prior::from)).collect()
    }

    /// Locates every fruit scanned ([`CapturedScan::priors`]), each as a
    /// scan of it alone would.
    pub fn localize_targets(
        &self,
        camera: &Camera,
        laser: &LaserModel,
        options: &LocateOptions,
    ) -> Result<Vec<Localization>> {
        let frames = self.frame_images();
        self.priors()
            .iter()
            .map(|prior| Ok(locate(camera, laser, prior, &frames, options)?))
            .collect()
    }

    /// Locates the fruit in the frames with the calibrated `camera` and `laser`.
    pub fn localize(
        &self,
        camera: &Camera,
        laser: &LaserModel,
        options: &LocateOptions,
    ) -> Result<Localization> {
        Ok(locate(camera, laser, &self.prior(), &self.frame_images(), options)?)
    }

    /// The slide positions the frames were taken at, mm.
    pub fn slides_mm(&self) -> Vec<f64> {
        self.frames.iter().map(|f| f.slide_mm).collect()
    }

    /// How many images [`CapturedScan::write`] writes (a laser-off image
    /// that frames share, once).
    pub fn image_count(&self) -> usize {
        (0..self.frames.len())
            .map(|index| 1 + usize::from(self.own_laser_off(index).is_some()))
            .sum()
    }

    /// This scan as scan.yaml describes it (docs/FORMATS.md), with the frame
    /// files [`CapturedScan::write`] names (`frame0.png`, `frame0_off.png`,
    /// ...) and the extra keys of the scan controller.
    pub fn to_scan(&self, dir: &Path) -> Scan {
        Scan {
            dir: dir.to_path_buf(),
            rough_position_mm: self.rough_position_mm,
            fruit_radius_mm: self.fruit_radius_mm,
            frames: self
                .frames
                .iter()
                .enumerate()
                .map(|(index, frame)| ScanFrameSpec {
                    image: frame_file(index, true).into(),
                    slide_mm: frame.slide_mm,
                    image_laser_off: self.laser_off_file(index).map(Into::into),
                    planned_slide_mm: Some(frame.planned_slide_mm),
                })
                .collect(),
            rough_position_in_rgbd_mm: Some(self.rough_position_in_rgbd_mm),
            more_targets: self.more_targets.clone(),
            plan_shifted_into_stroke: Some(self.plan.shifted),
            sweep_speed_mm_per_s: self.sweep_speed_mm_per_s,
            exposure: self.exposure,
        }
    }

    /// scan.yaml's text for this scan.
    pub fn scan_yaml(&self) -> String {
        self.to_scan(Path::new("")).to_yaml_string(if self.sweep_speed_mm_per_s.is_some() {
            "Captured by alacs-scanner in a continuous sweep. rough_position_mm is the RGB-D\n\
                 camera's rough position carried into the ALACS camera frame; slide_mm where the\n\
                 slide was at each frame's mid-exposure (an extension's frames, after the\n\
                 sweep's, where it settled)."
        } else {
            "Captured by alacs-scanner. rough_position_mm is the RGB-D camera's rough\n\
                 position carried into the ALACS camera frame; slide_mm where the slide settled."
        })
    }

    /// Writes the scan folder (FORMATS.md): scan.yaml and the PNG frames,
    /// creating `dir` ([`OutputDir`]: a folder holding files this did not
    /// write is refused). Localize it with the rig's calibrated camera.yaml
    /// and laser.yaml.
    pub fn write(&self, dir: &Path) -> Result<()> {
        OutputDir::fill(dir, "scan", false, |out| self.write_into(out)).map(drop)
    }

    /// [`CapturedScan::write`] into an open output folder (the caller may
    /// add files, e.g. camera.yaml, and then finishes it).
    pub fn write_into(&self, out: &mut OutputDir) -> Result<()> {
        use image::ImageEncoder as _;
        let mut save = |image: &RgbImage, name: String| {
            out.write_with(&name, |w| {
                image::codecs::png::PngEncoder::new(w)
                    .write_image(
                        image.as_raw(),
                        image.width(),
                        image.height(),
                        image::ExtendedColorType::Rgb8,
                    )
                    .map_err(std::io::Error::other)
            })
        };
        for (index, frame) in self.frames.iter().enumerate() {
            save(&frame.image, frame_file(index, true))?;
            if let Some(off) = self.own_laser_off(index) {
                save(off, frame_file(index, false))?;
            }
        }
        out.write(SCAN_FILE, self.scan_yaml())?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

    use std::cell::RefCell;
    use std::rc::Rc;

    use alacs_model::SLIDE_STROKE_MM;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    use super::*;
    use crate::hardware::{FrameCamera, LaserSwitch, Slide};
    use crate::{Device, Step};

    /// What the fake devices were told, in order.
    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Call {
        Move(f64),
        Laser(bool),
        Capture { laser_on: bool, slide_mm: f64 },
    }

    #[derive(Default)]
    struct State {
        calls: Vec<Call>,
        laser_on: bool,
        slide_mm: f64,
    }

    type Shared = Rc<RefCell<State>>;

    struct FakeSlide {
        state: Shared,
        stroke_mm: f64,
        /// The n-th move (from 0) times out.
        timeout_at: Option<usize>,
        /// The slide settles this far from the target.
        settle_error_mm: f64,
        moves: usize,
    }

    struct FakeCamera {
        state: Shared,
        timeout_at: Option<usize>,
        captures: usize,
    }

    struct FakeLaser {
        state: Shared,
    }

    impl Slide for FakeSlide {
        fn stroke_mm(&self) -> f64 {
            self.stroke_mm
        }
        fn move_to(&mut self, target_mm: f64, timeout: Duration) -> Result<f64> {
            if !(0.0..=self.stroke_mm).contains(&target_mm) {
                return Err(Error::OutOfStroke {
                    step: None,
                    target_mm,
                    stroke_mm: self.stroke_mm,
                });
            }
            let mut state = self.state.borrow_mut();
            state.calls.push(Call::Move(target_mm));
            self.moves += 1;
            timeout_at(self.timeout_at, self.moves, Device::Slide, timeout, "stalled")?;
            state.slide_mm = target_mm + self.settle_error_mm;
            Ok(state.slide_mm)
        }
        fn position_mm(&mut self) -> Result<f64> {
            Ok(self.state.borrow().slide_mm)
        }
    }

    /// A fake device's timeout on its `count`-th call when `at` is that
    /// call's index.
    fn timeout_at(
        at: Option<usize>,
        count: usize,
        device: Device,
        timeout: Duration,
        detail: &str,
    ) -> Result<()> {
        if at == Some(count - 1) {
            return Err(Error::Timeout { device, step: None, timeout, detail: detail.into() });
        }
        Ok(())
    }

    impl FrameCamera for FakeCamera {
        fn capture(&mut self, timeout: Duration) -> Result<RgbImage> {
            let mut state = self.state.borrow_mut();
            let call = Call::Capture { laser_on: state.laser_on, slide_mm: state.slide_mm };
            state.calls.push(call);
            self.captures += 1;
            timeout_at(self.timeout_at, self.captures, Device::Camera, timeout, "")?;
            // The laser state in the red channel, to check the pairing of images.
            Ok(RgbImage::from_pixel(4, 3, image::Rgb([u8::from(state.laser_on) * 200, 0, 0])))
        }

        fn set_exposure_us(&mut self, exposure_us: f64) -> Result<f64> {
            Ok(exposure_us)
        }

        fn set_gain_db(&mut self, gain_db: f64) -> Result<f64> {
            Ok(gain_db)
        }
    }

    impl LaserSwitch for FakeLaser {
        fn set(&mut self, on: bool) -> Result<()> {
            let mut state = self.state.borrow_mut();
            state.calls.push(Call::Laser(on));
            state.laser_on = on;
            Ok(())
        }
    }

    struct FakeRig {
        state: Shared,
        slide: FakeSlide,
        camera: FakeCamera,
        laser: FakeLaser,
    }

    impl FakeRig {
        fn new() -> Self {
            let state: Shared = Rc::default();
            Self {
                slide: FakeSlide {
                    state: state.clone(),
                    stroke_mm: SLIDE_STROKE_MM,
                    timeout_at: None,
                    settle_error_mm: 0.0,
                    moves: 0,
                },
                camera: FakeCamera { state: state.clone(), timeout_at: None, captures: 0 },
                laser: FakeLaser { state: state.clone() },
                state,
            }
        }

        fn run(&mut self, controller: &ScanController, rough: Point3<f64>) -> Result<CapturedScan> {
            let mut rig =
                Rig { slide: &mut self.slide, camera: &mut self.camera, laser: &mut self.laser };
            controller.run(&mut rig, &rough)
        }

        fn calls(&self) -> Vec<Call> {
            self.state.borrow().calls.clone()
        }

        fn moves(&self) -> Vec<f64> {
            self.calls()
                .iter()
                .filter_map(|c| match c {
                    Call::Move(d) => Some(*d),
                    _ => None,
                })
                .collect()
        }
    }

    fn laser() -> LaserModel {
        LaserModel::seed_paper()
    }

    fn controller(config: ControllerConfig) -> ScanController {
        ScanController::new(laser(), config).unwrap()
    }

    #[test]
    fn image_count_of_a_sweep_counts_its_reference_frame_not_a_laser_off_frame_per_frame() {
        let sweep = ScanMode::Continuous(Sweep::new(Camera::blackfly_s_5mp()));
        let config = ControllerConfig { mode: sweep.clone(), ..ControllerConfig::default() };
        assert_eq!(controller(config).image_count(), 6);
        let config = ControllerConfig {
            mode: sweep,
            capture_laser_off: true,
            ..ControllerConfig::default()
        };
        assert_eq!(controller(config).image_count(), 6);
        assert_eq!(controller(ControllerConfig::default()).image_count(), 5);
    }

    #[test]
    fn a_continuous_sweep_on_a_slide_that_cannot_report_is_refused_before_anything_moves() {
        let rough = Point3::new(20.0, -10.0, 800.0);
        let config = ControllerConfig {
            mode: ScanMode::Continuous(Sweep::new(Camera::blackfly_s_5mp())),
            ..ControllerConfig::default()
        };
        let mut rig = FakeRig::new();
        let error = rig.run(&controller(config), rough).unwrap_err();
        assert_eq!(error.device(), Some(Device::Slide));
        let message = error.to_string();
        assert!(message.contains("does not report its position while moving"), "{message}");
        assert!(message.contains("stop-and-go"), "{message}");
        assert!(rig.moves().is_empty());
        assert!(!rig.state.borrow().laser_on);
    }

    #[test]
    fn the_slide_follows_the_plan_with_the_laser_on_for_every_capture() {
        let rough = Point3::new(20.0, -10.0, 800.0);
        let plan = ScanStrategy::default().plan(&laser(), &rough, 40.0);
        assert!(!plan.shifted);
        let mut rig = FakeRig::new();
        let scan = rig.run(&controller(ControllerConfig::default()), rough).unwrap();
        assert_eq!(rig.moves(), plan.slides_mm);
        assert_eq!(scan.plan, plan);
        assert_eq!(scan.slides_mm(), plan.slides_mm);
        assert_eq!(scan.rough_position_mm, rough);
        let mut expected = Vec::new();
        for &d in &plan.slides_mm {
            expected.extend([
                Call::Move(d),
                Call::Laser(true),
                Call::Capture { laser_on: true, slide_mm: d },
            ]);
        }
        expected.push(Call::Laser(false));
        assert_eq!(rig.calls(), expected);
        assert!(
            scan.frames.iter().all(|f| f.image_laser_off.is_none() && f.image[(0, 0)][0] == 200)
        );
    }

    #[test]
    fn laser_off_frames_follow_each_laser_on_frame_at_the_same_position() {
        let rough = Point3::new(0.0, 0.0, 700.0);
        let config = ControllerConfig { capture_laser_off: true, ..ControllerConfig::default() };
        let mut rig = FakeRig::new();
        let scan = rig.run(&controller(config), rough).unwrap();
        let calls = rig.calls();
        assert_eq!(calls.len(), 5 * 5 + 1);
        for (k, chunk) in calls.chunks(5).take(5).enumerate() {
            let d = scan.plan.slides_mm[k];
            assert_eq!(
                chunk,
                [
                    Call::Move(d),
                    Call::Laser(true),
                    Call::Capture { laser_on: true, slide_mm: d },
                    Call::Laser(false),
                    Call::Capture { laser_on: false, slide_mm: d },
                ]
            );
        }
        assert_eq!(calls.last(), Some(&Call::Laser(false)));
        for frame in &scan.frames {
            assert_eq!(frame.image[(0, 0)][0], 200);
            assert_eq!(frame.image_laser_off.as_ref().unwrap()[(0, 0)][0], 0);
        }
        assert_eq!(scan.image_count(), 10);
    }

    #[test]
    fn the_rough_position_is_carried_into_the_alacs_frame() {
        // The RGB-D camera 60 mm above and 40 mm left of the ALACS camera,
        // turned 5 degrees about y (mm, radians).
        let alacs_from_rgbd = Isometry3::from_parts(
            Translation3::new(-40.0, -60.0, 10.0),
            UnitQuaternion::from_euler_angles(0.0, 5f64.to_radians(), 0.0),
        );
        let rough_in_rgbd = Point3::new(30.0, 50.0, 750.0);
        let rough_in_alacs = alacs_from_rgbd * rough_in_rgbd;
        let config = ControllerConfig { alacs_from_rgbd, ..ControllerConfig::default() };
        let mut rig = FakeRig::new();
        let scan = rig.run(&controller(config), rough_in_rgbd).unwrap();
        assert!((scan.rough_position_mm - rough_in_alacs).norm() < 1e-9);
        assert_eq!(scan.rough_position_in_rgbd_mm, rough_in_rgbd);
        let plan = ScanStrategy::default().plan(&laser(), &rough_in_alacs, 40.0);
        assert_eq!(rig.moves(), plan.slides_mm);
        // Untransformed, the plan would differ.
        let naive = ScanStrategy::default().plan(&laser(), &rough_in_rgbd, 40.0);
        assert!((naive.slides_mm[0] - plan.slides_mm[0]).abs() > 1.0);
    }

    #[test]
    fn a_plan_beyond_the_stroke_is_shifted_into_it_not_cut() {
        // Far right: the start lies beyond the stroke's last 40 mm; far
        // left: before 0.
        for (x, first) in [(350.0, SLIDE_STROKE_MM - 40.0), (-300.0, 0.0)] {
            let rough = Point3::new(x, 0.0, 800.0);
            let mut rig = FakeRig::new();
            let scan = rig.run(&controller(ControllerConfig::default()), rough).unwrap();
            assert!(scan.plan.shifted, "x {x}: {:?}", scan.plan);
            let moves = rig.moves();
            assert_eq!(moves.len(), 5);
            assert_eq!(moves[0], first);
            assert!(moves.windows(2).all(|w| (w[1] - w[0] - 10.0).abs() < 1e-9));
            assert!(moves.iter().all(|d| (0.0..=SLIDE_STROKE_MM).contains(d)));
        }
    }

    #[test]
    fn a_slide_shorter_than_the_plan_is_refused_before_anything_moves() {
        let mut rig = FakeRig::new();
        rig.slide.stroke_mm = 100.0;
        let rough = Point3::new(150.0, 0.0, 800.0);
        let error = rig.run(&controller(ControllerConfig::default()), rough).unwrap_err();
        assert!(matches!(error, Error::OutOfStroke { step: Some(Step::Planning), .. }), "{error}");
        assert_eq!(error.device(), Some(Device::Slide));
        assert!(rig.calls().is_empty());
        assert!(error.to_string().contains("outside the stroke 0..100"), "{error}");
    }

    #[test]
    fn a_slide_timeout_names_the_slide_and_the_frame_and_turns_the_laser_off() {
        let mut rig = FakeRig::new();
        rig.slide.timeout_at = Some(2);
        let config =
            ControllerConfig { move_timeout: Duration::from_secs(3), ..Default::default() };
        let error = rig.run(&controller(config), Point3::new(0.0, 0.0, 800.0)).unwrap_err();
        assert_eq!(error.device(), Some(Device::Slide));
        assert!(matches!(error.step(), Some(Step::Move { frame: 2, .. })), "{error:?}");
        let message = error.to_string();
        assert!(
            message.starts_with("slide error at frame 2, moving the slide to")
                && message.contains("timed out after 3.000 s (stalled)"),
            "{message}"
        );
        assert_eq!(rig.calls().last(), Some(&Call::Laser(false)));
        assert_eq!(rig.moves().len(), 3);
    }

    #[test]
    fn a_camera_timeout_names_the_camera_and_the_capture() {
        let mut rig = FakeRig::new();
        rig.camera.timeout_at = Some(3);
        let config = ControllerConfig { capture_laser_off: true, ..Default::default() };
        let error = rig.run(&controller(config), Point3::new(0.0, 0.0, 800.0)).unwrap_err();
        assert_eq!(error.device(), Some(Device::Camera));
        assert_eq!(error.step(), Some(Step::Capture { frame: 1, laser_on: false }));
        assert!(
            error.to_string().starts_with(
                "camera error at frame 1, capturing with the laser off: timed out after 2.000 s"
            ),
            "{error}"
        );
        assert_eq!(rig.calls().last(), Some(&Call::Laser(false)));
    }

    #[test]
    fn frames_keep_the_reported_position_and_a_slide_off_target_stops_the_scan() {
        let rough = Point3::new(0.0, 0.0, 800.0);
        let mut rig = FakeRig::new();
        rig.slide.settle_error_mm = 0.2;
        let scan = rig.run(&controller(ControllerConfig::default()), rough).unwrap();
        for frame in &scan.frames {
            assert!((frame.slide_mm - frame.planned_slide_mm - 0.2).abs() < 1e-12);
        }
        assert!(scan.scan_yaml().contains("planned_slide_mm"));

        let mut rig = FakeRig::new();
        rig.slide.settle_error_mm = 1.0;
        let error = rig.run(&controller(ControllerConfig::default()), rough).unwrap_err();
        assert!(matches!(
            error,
            Error::PositionMismatch { step: Some(Step::Move { frame: 0, .. }), .. }
        ));
        assert!(error.to_string().contains("1.000 mm from the target"), "{error}");
        assert_eq!(rig.calls().last(), Some(&Call::Laser(false)));
    }

    #[test]
    fn bad_configurations_and_rough_positions_are_refused() {
        for config in [
            ControllerConfig { fruit_radius_mm: 0.0, ..Default::default() },
            ControllerConfig { move_timeout: Duration::ZERO, ..Default::default() },
            ControllerConfig {
                strategy: ScanStrategy { frames: 0, ..ScanStrategy::default() },
                ..Default::default()
            },
        ] {
            assert!(matches!(ScanController::new(laser(), config), Err(Error::InvalidInput(_))));
        }
        // 1 m behind the ALACS camera once turned half a turn about y.
        let alacs_from_rgbd = Isometry3::rotation(Vector3::y() * std::f64::consts::PI);
        let config = ControllerConfig { alacs_from_rgbd, ..Default::default() };
        let mut rig = FakeRig::new();
        let error = rig.run(&controller(config), Point3::new(0.0, 0.0, 1000.0)).unwrap_err();
        assert!(error.to_string().contains("not in front of the camera"), "{error}");
        assert!(rig.calls().is_empty());
    }

    #[test]
    fn scan_yaml_reads_back_as_a_formats_md_scan() {
        let mut rig = FakeRig::new();
        let config = ControllerConfig { capture_laser_off: true, ..Default::default() };
        let scan = rig.run(&controller(config), Point3::new(5.0, 1.0, 900.0)).unwrap();
        let dir = std::env::temp_dir().join(format!("alacs-scanner-yaml-{}", std::process::id()));
        scan.write(&dir).unwrap();
        let read = alacs_model::Scan::read(&dir).unwrap();
        assert_eq!(read.rough_position_mm, scan.rough_position_mm);
        assert_eq!(read.fruit_radius_mm, 40.0);
        assert_eq!(read.frames.len(), 5);
        for (k, (spec, frame)) in read.frames.iter().zip(&scan.frames).enumerate() {
            assert_eq!(spec.slide_mm, frame.slide_mm);
            assert_eq!(spec.image, Path::new(&format!("frame{k}.png")));
            let off = read.path_of(spec.image_laser_off.as_ref().unwrap());
            assert_eq!(
                image::open(off).unwrap().to_rgb8(),
                **frame.image_laser_off.as_ref().unwrap()
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

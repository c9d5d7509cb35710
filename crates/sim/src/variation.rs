//! Per-scan randomization ([`ScanOptions::randomize`](crate::ScanOptions::randomize)):
//! what real rigs and fruit vary in, drawn per scan so that a localizer
//! tuned on the simulator cannot learn one renderer (issue 40, item 2).
//!
//! [`RigVariation::for_seed`] draws every value from its own generator
//! (the scan's seed with a fixed salt), so the scene, its lighting and the
//! fruit are the same with randomization on or off. Every draw is uniform
//! over the range of the constant named beside its field; sources are
//! pointers of `../shared/REFERENCES.md` or the renderer's own units
//! (`crate::render`'s module documentation).

use alacs_model::{Camera, LaserModel};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use serde_json::Value;

use crate::orchard::{Appearance, AppleForm, Shape};
use crate::render::{Lighting, RenderOptions};

/// The error of a paper-like laser calibration (the true laser minus the
/// fitted one: alpha in degrees, L0 in mm, beta in degrees), made by
/// calibrating: samples of the seed paper's laser seen by the 5 MP camera
/// ([`crate::simulate_samples`]'s paper-like defaults, depth noise
/// [`RigVariation::CALIBRATION_DEPTH_NOISE_MM`], no outliers: RANSAC has
/// removed them), then eq. (9)'s least squares by Gauss-Newton from the
/// truth (the problem is nearly linear there).
fn laser_calibration_error(seed: u64) -> [f64; 3] {
    let truth = LaserModel::seed_paper();
    let options = crate::SampleOptions {
        depth_noise_mm: RigVariation::CALIBRATION_DEPTH_NOISE_MM,
        seed,
        ..crate::SampleOptions::default()
    };
    // The paper-like layout always has samples (its defaults are valid);
    // should it not, the calibration is exact.
    let Ok(sim) = crate::simulate_samples(&Camera::blackfly_s_5mp(), &truth, &options) else {
        return [0.0; 3];
    };
    let mut fitted = truth;
    for _ in 0..5 {
        let mut h = nalgebra::Matrix3::<f64>::zeros();
        let mut g = nalgebra::Vector3::<f64>::zeros();
        for sample in &sim.samples {
            let n = nalgebra::Point2::new(sample.u_n, sample.v_n);
            let (Ok(z), Ok(grad)) = (
                fitted.depth_mm(&n, sample.slide_mm),
                fitted.depth_gradient_params(&n, sample.slide_mm),
            ) else {
                continue;
            };
            let j = nalgebra::Vector3::new(grad[0], grad[1], grad[2]);
            h += j * j.transpose();
            g += j * (sample.z_mm - z);
        }
        let Some(step) = h.cholesky().map(|c| c.solve(&g)) else { break };
        fitted.alpha_rad += step[0];
        fitted.l0_mm += step[1];
        fitted.beta_rad += step[2];
    }
    [
        (truth.alpha_rad - fitted.alpha_rad).to_degrees(),
        truth.l0_mm - fitted.l0_mm,
        (truth.beta_rad - fitted.beta_rad).to_degrees(),
    ]
}

/// Causes of error a randomized scan can be rendered without
/// ([`ScanOptions::take_out`](crate::ScanOptions::take_out)): to measure
/// what each costs the localizer, not a rig or a fruit anyone has. Nothing
/// is taken out by default.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TakeOut {
    /// No light in the fruit's flesh: the stripe on the fruit as on a
    /// leaf ([`RigVariation::subsurface_sigma_mm`] 0).
    pub glow: bool,
    /// The target apple's plain ellipsoid: no taper, flat cheek or
    /// cavities ([`RigVariation::apple_form`] none).
    pub form: bool,
}

/// A range of a uniform draw, (low, high), both included.
pub type DrawRange = (f64, f64);

/// Salt of the variation's generator (with the scan's seed).
const VARIATION_SEED: u64 = 0x7661_7269_6174_696f;

/// A fruit's colour family: the cultivar of a scan's apples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum FruitColour {
    /// A full red blush (e.g. 'Red Delicious').
    Red,
    /// Red blush in patches over a green-yellow ground (e.g. 'Gala').
    Bicolour,
    /// Yellow, a faint orange blush at most (e.g. 'Golden Delicious').
    Yellow,
    /// Green, no blush (e.g. 'Granny Smith').
    Green,
}

/// The albedo ranges of one [`FruitColour`] (linear RGB, per channel).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FruitColourRanges {
    /// The blush's albedo.
    pub blush_rgb: [DrawRange; 3],
    /// The ground colour's albedo.
    pub ground_rgb: [DrawRange; 3],
    /// [`Appearance::fruit_blush_offset`]: how much of the fruit is blushed.
    pub blush_offset: DrawRange,
}

impl FruitColour {
    /// Every family, drawn with equal odds.
    pub const ALL: [FruitColour; 4] =
        [FruitColour::Red, FruitColour::Bicolour, FruitColour::Yellow, FruitColour::Green];

    /// The family's albedo ranges. Linear RGB from apple skin spectra: an
    /// anthocyanin blush reflects little below 600 nm and 35-65 % in the red;
    /// chlorophyll's ground colour peaks near 550 nm and absorbs at 670-680
    /// nm (REFERENCES.md, Saeys et al. 2008), so a green apple's red albedo,
    /// and with it its reflectance at the laser's 650 nm, is the lowest,
    /// 0.2-0.32 (still 3 times a leaf's).
    pub fn ranges(self) -> FruitColourRanges {
        const RED_BLUSH: [DrawRange; 3] = [(0.35, 0.6), (0.03, 0.08), (0.03, 0.07)];
        const GREEN_YELLOW: [DrawRange; 3] = [(0.38, 0.5), (0.45, 0.6), (0.08, 0.16)];
        match self {
            FruitColour::Red => FruitColourRanges {
                blush_rgb: RED_BLUSH,
                ground_rgb: GREEN_YELLOW,
                blush_offset: (0.2, 0.8),
            },
            FruitColour::Bicolour => FruitColourRanges {
                blush_rgb: RED_BLUSH,
                ground_rgb: GREEN_YELLOW,
                blush_offset: (-0.6, 0.0),
            },
            FruitColour::Yellow => FruitColourRanges {
                blush_rgb: [(0.5, 0.65), (0.2, 0.3), (0.05, 0.1)],
                ground_rgb: [(0.55, 0.72), (0.5, 0.65), (0.1, 0.2)],
                blush_offset: (-1.6, -1.0),
            },
            FruitColour::Green => FruitColourRanges {
                blush_rgb: RED_BLUSH,
                ground_rgb: [(0.2, 0.32), (0.42, 0.58), (0.08, 0.15)],
                // 1.6 n - 1.6 <= 0 for noise n in 0..1: no blush.
                blush_offset: (-2.0, -1.6),
            },
        }
    }
}

/// One scan's drawn rig, fruit and camera: every value
/// [`ScanOptions::randomize`](crate::ScanOptions::randomize) changes, as
/// truth.json's `variation` records it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RigVariation {
    /// The laser line's sigma, px of the rendered image ([`Self::STRIPE_SIGMA_PX`]).
    pub stripe_sigma_px: f64,
    /// The laser's peak irradiance, [`crate::LaserLight::power`] ([`Self::LASER_POWER`]).
    pub laser_power: f64,
    /// The line's cross-section, Gaussian to flat-topped,
    /// [`crate::LaserLight::profile_flatness`] ([`Self::PROFILE_FLATNESS`]).
    pub profile_flatness: f64,
    /// Laser speckle's amplitude ([`Self::SPECKLE_CONTRAST`]).
    pub speckle_contrast: f64,
    /// The fruit's subsurface glow, sigma in mm ([`Self::SUBSURFACE_SIGMA_MM`]).
    pub subsurface_sigma_mm: f64,
    /// The glow's shift per mm of its sigma and per sine of incidence ([`Self::SUBSURFACE_SHIFT`]).
    pub subsurface_shift: f64,
    /// The fruit's colour family ([`FruitColour::ranges`]).
    pub fruit_colour: FruitColour,
    /// The materials' colours and gloss: fruit ([`FruitColour::ranges`],
    /// [`Self::FRUIT_SPECULAR`], [`Self::FRUIT_SHININESS`]), leaves
    /// ([`Self::LEAF_RGB`], [`Self::LEAF_SPECULAR`], [`Self::LEAF_SHININESS`])
    /// and background foliage ([`Self::BACKGROUND_ALBEDO_FACTOR`]).
    pub appearance: Appearance,
    /// Factor on the background foliage's albedo ([`Self::BACKGROUND_ALBEDO_FACTOR`]).
    pub background_albedo_factor: f64,
    /// Factor on the radiance of rays that hit nothing, the sky through the
    /// canopy ([`Self::BACKGROUND_LIGHT_FACTOR`]).
    pub background_light_factor: f64,
    /// The lens's blur, px ([`Self::BLUR_SIGMA_PX`]).
    pub blur_sigma_px: f64,
    /// Read noise, DN ([`Self::READ_NOISE_DN`]).
    pub read_noise_dn: f64,
    /// Shot noise's DN per electron ([`Self::GAIN_DN_PER_ELECTRON`]).
    pub gain_dn_per_electron: f64,
    /// Factor on the sensor's [`crate::Sensor::exposure_dn`] ([`Self::EXPOSURE_FACTOR`]).
    pub exposure_factor: f64,
    /// The rendered laser's alpha minus the calibration's, degrees
    /// ([`Self::CALIBRATION_DEPTH_NOISE_MM`]).
    pub alpha_error_deg: f64,
    /// The rendered laser's L0 minus the calibration's, mm (as alpha's).
    pub l0_error_mm: f64,
    /// The rendered laser's beta minus the calibration's, degrees (as alpha's).
    pub beta_error_deg: f64,
    /// The rendered slide scale k over the calibration's, minus 1 ([`Self::SLIDE_SCALE_ERROR`]).
    pub slide_scale_error: f64,
    /// The rendered camera's fx over the calibration's, minus 1 ([`Self::FOCAL_ERROR`]).
    pub fx_error: f64,
    /// The rendered camera's fy over the calibration's, minus 1 ([`Self::FOCAL_ERROR`]).
    pub fy_error: f64,
    /// The rendered camera's cx minus the calibration's, px at full scale
    /// ([`Self::PRINCIPAL_POINT_ERROR_PX`]).
    pub cx_error_px: f64,
    /// The rendered camera's cy minus the calibration's, px at full scale
    /// ([`Self::PRINCIPAL_POINT_ERROR_PX`]).
    pub cy_error_px: f64,
    /// The rough position's largest error along the line of sight, a
    /// fraction of the depth ([`Self::ROUGH_DEPTH_ERROR`]).
    pub rough_depth_error: f64,
    /// The rough position's error across the line of sight, sigma in mm
    /// ([`Self::ROUGH_LATERAL_SIGMA_MM`]).
    pub rough_lateral_sigma_mm: f64,
    /// The target apple's form ([`Self::TAPER`], [`Self::LOPSIDED`],
    /// [`Self::STEM_CAVITY_DEPTH`] and the others of [`AppleForm`]).
    pub apple_form: AppleForm,
}

impl RigVariation {
    /// Laser line sigma, px: 1.5 px is 0.6 mm at 0.9 m on the 5 MP camera
    /// (`crate::render`'s units); a line laser's focus setting and depth of
    /// field make it 0.4-1 mm, a 1/e^2 width of 1.6-4 mm.
    pub const STRIPE_SIGMA_PX: DrawRange = (1.0, 2.5);
    /// Laser peak irradiance (1.0: a 100 mW line, 100 W/m^2 at its centre at
    /// 0.9 m): a line's peak falls as 1 / range, +-33 % over 0.6-1.2 m, which
    /// the renderer holds constant, and modules differ in power.
    pub const LASER_POWER: DrawRange = (0.6, 1.5);
    /// The line's cross-section ([`crate::LaserLight::profile_flatness`]):
    /// a single-mode diode's line is Gaussian across (0); a multimode
    /// diode's, the usual one at 100 mW and more, carries several
    /// transverse modes and is flatter-topped, nearer a super-Gaussian
    /// (RP Photonics' encyclopedia, "flat-top beams"; laser-line makers'
    /// notes on intensity distribution), up to the flattest of the model
    /// (1/sqrt 2). Symmetric: an asymmetric line's offset is taken up by
    /// the calibration, which sees the same line.
    pub const PROFILE_FLATNESS: DrawRange = (0.0, 0.7);
    /// Speckle amplitude: fully developed speckle (contrast 1) averaged
    /// over a pixel's aperture and the fruit's volume scattering.
    pub const SPECKLE_CONTRAST: DrawRange = (0.1, 0.5);
    /// The fruit's subsurface glow, sigma along the surface, mm. REFERENCES.md
    /// (Saeys et al. 2008, Lu et al. 2020): flesh mu_s' ~ 1/mm, mu_a a few
    /// 0.01/mm in the red, so light diffuses 1/mu_eff = 1/sqrt(3 mu_a
    /// (mu_a + mu_s')) ~ 2-4 mm; the skin's 3x scattering keeps it shallower.
    pub const SUBSURFACE_SIGMA_MM: DrawRange = (0.5, 3.0);
    /// The glow's forward shift per mm of sigma and per sine of incidence
    /// across the line: oblique-incidence diffusion moves the diffuse
    /// centroid by 3 D sin(theta_t) ~ sin(theta_i) / (1.35 mu_s'), under
    /// 0.75 mm at mu_s' ~ 1/mm (Wang and Jacques, Applied Optics 1995).
    pub const SUBSURFACE_SHIFT: DrawRange = (0.1, 0.5);
    /// Fruit highlight strength: a dusty bloom to a polished, waxy
    /// cuticle (0.25 without randomization; Blinn-Phong, not a measured BRDF).
    pub const FRUIT_SPECULAR: DrawRange = (0.05, 0.6);
    /// Fruit highlight exponent (40 without randomization).
    pub const FRUIT_SHININESS: DrawRange = (15.0, 80.0);
    /// Leaf albedo, linear RGB: green leaves reflect 10-20 % near 550 nm
    /// and a few % in the red, where chlorophyll absorbs (REFERENCES.md);
    /// young, old, sunlit and shaded leaves. The laser's 650 nm reflectance
    /// is 4/3 the red albedo, as without randomization (0.08 for 0.06).
    pub const LEAF_RGB: [DrawRange; 3] = [(0.04, 0.09), (0.14, 0.30), (0.03, 0.08)];
    /// Leaf highlight strength: matte to the waxy upper side of a leaf.
    pub const LEAF_SPECULAR: DrawRange = (0.02, 0.3);
    /// Leaf highlight exponent.
    pub const LEAF_SHININESS: DrawRange = (8.0, 40.0);
    /// Factor on the background foliage's albedo: denser or sparser,
    /// darker or lighter canopy behind the fruit.
    pub const BACKGROUND_ALBEDO_FACTOR: DrawRange = (0.6, 1.6);
    /// Factor on the sky's radiance through the canopy (0.3 in shade, 0.9
    /// in sun without randomization): from a closed canopy to open sky,
    /// which clips at the longest exposures.
    pub const BACKGROUND_LIGHT_FACTOR: DrawRange = (0.5, 2.0);
    /// Lens blur, px: a lens focused on the fruit, with its depth of field
    /// and aberrations (0.5 px without randomization).
    pub const BLUR_SIGMA_PX: DrawRange = (0.3, 1.0);
    /// Read noise, DN (0.5 DN, 20 e-, without randomization): 8-bit
    /// machine-vision output, quantization and fixed-pattern noise included.
    pub const READ_NOISE_DN: DrawRange = (0.25, 1.5);
    /// DN per electron: full wells of 5,100-20,400 e- over 255 DN (10,200
    /// e-, the IMX264-like pixel of `crate::render`'s units, without
    /// randomization).
    pub const GAIN_DN_PER_ELECTRON: DrawRange = (0.0125, 0.05);
    /// Factor on the sensor's DN per unit radiance: the lens's f-number
    /// (half a stop either way), its transmission and the quantum
    /// efficiency, known to tens of percent (`crate::render`'s units); at
    /// the high end a sunlit red apple clips at the reference exposure.
    pub const EXPOSURE_FACTOR: DrawRange = (0.6, 1.6);
    /// The laser calibration the scan is located with: a paper-like one
    /// (the seed paper's Table 1), 30 samples on 10 board poses at
    /// 0.6-1.2 m with this much depth noise, mm, fitted by least squares.
    /// Its errors of alpha, L0 and beta are drawn by making that
    /// calibration, not independently: they come correlated as a fit makes
    /// them, with the spread docs/calibration.md measures (RMS alpha 0.016
    /// deg, L0 0.24 mm, beta 0.031 deg); drawn independently, the same
    /// spreads would tilt the plane by millimetres inside the volume the
    /// samples pin down. A session calibration (dense samples at three
    /// slide positions) is about ten times tighter.
    pub const CALIBRATION_DEPTH_NOISE_MM: f64 = 0.5;
    /// The slide's scale k as rendered over as calibrated, minus 1: a lead
    /// screw's pitch error or a belt's stretch (tenths of a percent).
    pub const SLIDE_SCALE_ERROR: DrawRange = (-0.003, 0.003);
    /// fx and fy as rendered over as calibrated, minus 1: a lens warmed
    /// since its calibration (whose bootstrap sigma is 0.005 %, docs/calibration.md: fx
    /// +-0.11 px; a refocused lens needs a new calibration).
    pub const FOCAL_ERROR: DrawRange = (-0.001, 0.001);
    /// cx and cy as rendered minus as calibrated, px at full scale (scaled
    /// with the image): a lens bumped or refocused since its calibration.
    pub const PRINCIPAL_POINT_ERROR_PX: DrawRange = (-1.5, 1.5);
    /// The rough position's largest depth error, a fraction of the depth:
    /// RealSense D435 RMS under 2 % at 2 m growing with z^2 (0.6-1.6 % at
    /// 0.6-1.6 m), up to the seed paper's 2 % and a bit past it for a
    /// fruit's centre taken from its surface (REFERENCES.md).
    pub const ROUGH_DEPTH_ERROR: DrawRange = (0.005, 0.025);
    /// How much narrower the apple's calyx end is ([`AppleForm::taper`]):
    /// from a globose fruit to a conic one 12 % narrower at the calyx pole
    /// (UPOV's apple guidelines, TG/14, grade the shape from globose to
    /// conical; the range is our reading, not measured).
    pub const TAPER: DrawRange = (0.0, 0.12);
    /// One cheek flatter than the other ([`AppleForm::lopsided`]): up to 6 %
    /// of the radius there.
    pub const LOPSIDED: DrawRange = (0.0, 0.06);
    /// Stem cavity depth, a fraction of the radius: 4-10 mm on a 40 mm
    /// apple (TG/14 grades the stalk cavity from shallow to deep).
    pub const STEM_CAVITY_DEPTH: DrawRange = (0.10, 0.25);
    /// Stem cavity's angular sigma, radians: a dimple 15-30 mm across on a
    /// 40 mm apple.
    pub const STEM_CAVITY_WIDTH_RAD: DrawRange = (0.15, 0.30);
    /// Calyx basin depth, a fraction of the radius: 2-6 mm (TG/14's eye basin).
    pub const CALYX_CAVITY_DEPTH: DrawRange = (0.05, 0.15);
    /// Calyx basin's angular sigma, radians.
    pub const CALYX_CAVITY_WIDTH_RAD: DrawRange = (0.12, 0.25);
    /// The rough position's error across the line of sight, sigma in mm: a
    /// detector's box centre a pixel or two off on a D435 depth image
    /// (about 1.5 mm per pixel at 1 m, 848 x 480 over 87 deg).
    pub const ROUGH_LATERAL_SIGMA_MM: DrawRange = (1.0, 4.0);

    /// The variation of the scan with `seed`, from a generator of its own
    /// (the seed with a fixed salt): the scene of the seed does not change.
    pub fn for_seed(seed: u64) -> RigVariation {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ VARIATION_SEED);
        let mut draw = |(low, high): DrawRange| rng.random_range(low..=high);
        let stripe_sigma_px = draw(Self::STRIPE_SIGMA_PX);
        let laser_power = draw(Self::LASER_POWER);
        let speckle_contrast = draw(Self::SPECKLE_CONTRAST);
        let subsurface_sigma_mm = draw(Self::SUBSURFACE_SIGMA_MM);
        let subsurface_shift = draw(Self::SUBSURFACE_SHIFT);
        let family = draw((0.0, 4.0)).floor().clamp(0.0, 3.0) as usize;
        let fruit_colour = FruitColour::ALL[family];
        let ranges = fruit_colour.ranges();
        let fruit_blush_rgb = ranges.blush_rgb.map(&mut draw);
        let fruit_ground_rgb = ranges.ground_rgb.map(&mut draw);
        let fruit_blush_offset = draw(ranges.blush_offset);
        let fruit_specular = draw(Self::FRUIT_SPECULAR);
        let fruit_shininess = draw(Self::FRUIT_SHININESS);
        let leaf_rgb = Self::LEAF_RGB.map(&mut draw);
        let leaf_specular = draw(Self::LEAF_SPECULAR);
        let leaf_shininess = draw(Self::LEAF_SHININESS);
        let background_albedo_factor = draw(Self::BACKGROUND_ALBEDO_FACTOR);
        let background_light_factor = draw(Self::BACKGROUND_LIGHT_FACTOR);
        let nominal = Appearance::default();
        let appearance = Appearance {
            fruit_blush_rgb,
            fruit_ground_rgb,
            fruit_blush_offset,
            fruit_specular,
            fruit_shininess,
            leaf_rgb,
            leaf_laser_reflectance: leaf_rgb[0] * nominal.leaf_laser_reflectance
                / nominal.leaf_rgb[0],
            leaf_specular,
            leaf_shininess,
            background_rgb: nominal.background_rgb.map(|c| c * background_albedo_factor),
            background_laser_reflectance: nominal.background_laser_reflectance
                * background_albedo_factor,
        };
        let mut variation = RigVariation {
            stripe_sigma_px,
            laser_power,
            // Drawn last, below: a later addition, so that the draws made
            // before it stay what they were.
            profile_flatness: 0.0,
            speckle_contrast,
            subsurface_sigma_mm,
            subsurface_shift,
            fruit_colour,
            appearance,
            background_albedo_factor,
            background_light_factor,
            blur_sigma_px: draw(Self::BLUR_SIGMA_PX),
            read_noise_dn: draw(Self::READ_NOISE_DN),
            gain_dn_per_electron: draw(Self::GAIN_DN_PER_ELECTRON),
            exposure_factor: draw(Self::EXPOSURE_FACTOR),
            // Made last, below, from the generator's next value.
            alpha_error_deg: 0.0,
            l0_error_mm: 0.0,
            beta_error_deg: 0.0,
            slide_scale_error: draw(Self::SLIDE_SCALE_ERROR),
            fx_error: draw(Self::FOCAL_ERROR),
            fy_error: draw(Self::FOCAL_ERROR),
            cx_error_px: draw(Self::PRINCIPAL_POINT_ERROR_PX),
            cy_error_px: draw(Self::PRINCIPAL_POINT_ERROR_PX),
            rough_depth_error: draw(Self::ROUGH_DEPTH_ERROR),
            rough_lateral_sigma_mm: draw(Self::ROUGH_LATERAL_SIGMA_MM),
            // Drawn last, below, after the calibration's value.
            apple_form: AppleForm::NONE,
        };
        [variation.alpha_error_deg, variation.l0_error_mm, variation.beta_error_deg] =
            laser_calibration_error(rng.random());
        let mut draw = |(low, high): DrawRange| rng.random_range(low..=high);
        let lopsided_angle = draw((0.0, std::f64::consts::TAU));
        variation.apple_form = AppleForm {
            taper: draw(Self::TAPER),
            lopsided: draw(Self::LOPSIDED),
            lopsided_axis: [lopsided_angle.cos(), lopsided_angle.sin(), 0.0],
            stem_cavity_depth: draw(Self::STEM_CAVITY_DEPTH),
            stem_cavity_width_rad: draw(Self::STEM_CAVITY_WIDTH_RAD),
            calyx_cavity_depth: draw(Self::CALYX_CAVITY_DEPTH),
            calyx_cavity_width_rad: draw(Self::CALYX_CAVITY_WIDTH_RAD),
        };
        variation.profile_flatness = draw(Self::PROFILE_FLATNESS);
        variation
    }

    /// The variation with the causes `take_out` names left out; the other
    /// draws stay as they are.
    pub fn without(mut self, take_out: TakeOut) -> RigVariation {
        if take_out.glow {
            self.subsurface_sigma_mm = 0.0;
            self.subsurface_shift = 0.0;
        }
        if take_out.form {
            self.apple_form = AppleForm::NONE;
        }
        self
    }

    /// `shape` given the drawn apple's form, where it is an ellipsoid (the
    /// target fruit), placed so that the apple's volume centroid lies at the
    /// ellipsoid's centre (the truth stays the fruit's centre); any other
    /// shape as it is. The form lies within its ellipsoid, which that moves
    /// by up to 2.5 % of the radius (a deep stem cavity): a neighbour placed
    /// touching the scene's ellipsoid may overlap the apple by up to about
    /// half a millimetre.
    pub fn apple_shape(&self, shape: &Shape) -> Shape {
        match shape {
            Shape::Ellipsoid { .. } if self.apple_form == AppleForm::NONE => shape.clone(),
            Shape::Ellipsoid { centre, rotation, semi_axes_mm } => Shape::Apple {
                centre: centre - rotation * semi_axes_mm.component_mul(&self.apple_form.centroid()),
                rotation: *rotation,
                semi_axes_mm: *semi_axes_mm,
                form: self.apple_form,
            },
            other => other.clone(),
        }
    }

    /// `render` with the drawn laser look and sensor (the exposure time and
    /// gain kept, [`crate::Sensor::exposure_dn`] times the drawn factor),
    /// through a Bayer filter ([`crate::Sensor::bayer`]): colour
    /// machine-vision cameras (the Blackfly S colour models among them)
    /// record one colour per pixel through an RGGB mosaic, and bilinear
    /// demosaicing is the simplest of the interpolations their SDKs offer,
    /// the one that spreads a thin red line the most.
    pub fn render_options(&self, render: &RenderOptions) -> RenderOptions {
        let mut out = *render;
        out.laser.stripe_sigma_px = self.stripe_sigma_px;
        out.laser.power = self.laser_power;
        out.laser.profile_flatness = self.profile_flatness;
        out.laser.speckle_contrast = self.speckle_contrast;
        out.laser.subsurface_sigma_mm = self.subsurface_sigma_mm;
        out.laser.subsurface_shift = self.subsurface_shift;
        out.sensor.blur_sigma_px = self.blur_sigma_px;
        out.sensor.read_noise_dn = self.read_noise_dn;
        out.sensor.gain_dn_per_electron = self.gain_dn_per_electron;
        out.sensor.exposure_dn = render.sensor.exposure_dn * self.exposure_factor;
        out.sensor.bayer = true;
        out
    }

    /// `lighting` with the drawn sky behind the canopy.
    pub fn lighting(&self, lighting: &Lighting) -> Lighting {
        Lighting { background: lighting.background * self.background_light_factor, ..*lighting }
    }

    /// The camera the images are taken with: `calibrated` (already scaled
    /// by `scale`) with the drawn focal and principal-point errors, the
    /// latter given at full scale.
    pub fn rendered_camera(&self, calibrated: &Camera, scale: f64) -> Camera {
        Camera {
            fx_px: calibrated.fx_px * (1.0 + self.fx_error),
            fy_px: calibrated.fy_px * (1.0 + self.fy_error),
            cx_px: calibrated.cx_px + self.cx_error_px * scale,
            cy_px: calibrated.cy_px + self.cy_error_px * scale,
            ..calibrated.clone()
        }
    }

    /// The laser the images show: `calibrated` with the drawn errors of
    /// alpha, L0, beta and the slide's scale.
    pub fn rendered_laser(&self, calibrated: &LaserModel) -> LaserModel {
        LaserModel {
            alpha_rad: calibrated.alpha_rad + self.alpha_error_deg.to_radians(),
            beta_rad: calibrated.beta_rad + self.beta_error_deg.to_radians(),
            l0_mm: calibrated.l0_mm + self.l0_error_mm,
            slide_scale: calibrated.slide_scale * (1.0 + self.slide_scale_error),
            ..*calibrated
        }
    }

    /// truth.json's `variation` object: every drawn value by its field's name.
    pub fn to_json(&self) -> Value {
        // Plain numbers, strings and arrays: serializing cannot fail.
        serde_json::to_value(self).unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The drawn laser calibration errors have the spread of the paper-like
    /// calibration docs/calibration.md measures over 500 sets (RMS alpha
    /// 0.016 deg, L0 0.24 mm, beta 0.031 deg, with 20 % outliers removed by
    /// RANSAC), and move a point inside the calibrated volume by much less
    /// than the same spreads drawn independently would.
    #[test]
    fn the_calibration_error_has_a_calibrations_spread_and_correlation() {
        let errors: Vec<[f64; 3]> = (0..300).map(laser_calibration_error).collect();
        let rms = |k: usize| {
            (errors.iter().map(|e| e[k] * e[k]).sum::<f64>() / errors.len() as f64).sqrt()
        };
        let (alpha, l0, beta) = (rms(0), rms(1), rms(2));
        assert!((0.008..0.03).contains(&alpha), "alpha RMS {alpha} deg");
        assert!((0.12..0.45).contains(&l0), "L0 RMS {l0} mm");
        assert!((0.015..0.06).contains(&beta), "beta RMS {beta} deg");
        // A fruit at 0.8 m on the optical axis, slide at 150 mm.
        let truth = LaserModel::seed_paper();
        let n = nalgebra::Point2::new(0.0, 0.0);
        let depth_error = |e: &[f64; 3]| {
            let fitted = LaserModel {
                alpha_rad: truth.alpha_rad - e[0].to_radians(),
                l0_mm: truth.l0_mm - e[1],
                beta_rad: truth.beta_rad - e[2].to_radians(),
                ..truth
            };
            let slide = (truth.l0_mm - 0.8e3 * truth.alpha_rad.sin()) / truth.slide_scale;
            (fitted.depth_mm(&n, slide).unwrap() - truth.depth_mm(&n, slide).unwrap()).abs()
        };
        let correlated: f64 = errors.iter().map(depth_error).sum::<f64>() / errors.len() as f64;
        // The same marginals, each error's sign drawn anew.
        let independent: f64 = errors
            .iter()
            .enumerate()
            .map(|(i, e)| {
                let flip = |k: usize| if (i >> k) & 1 == 1 { -1.0 } else { 1.0 };
                depth_error(&[e[0] * flip(0), e[1] * flip(1), e[2] * flip(2)])
            })
            .sum::<f64>()
            / errors.len() as f64;
        eprintln!(
            "RMS alpha {alpha:.4} deg, L0 {l0:.3} mm, beta {beta:.4} deg; mean depth error at 0.8 m: {correlated:.3} mm as fitted, {independent:.3} mm independent"
        );
        assert!(correlated < 0.5 * independent, "{correlated} vs {independent}");
    }

    /// Taking a cause out leaves every other draw as it was: no glow leaves
    /// the apple's form, no form renders the scene's own ellipsoid (its
    /// centre the truth), and nothing taken out is the seed's variation.
    #[test]
    fn taking_a_cause_out_changes_that_cause_only() {
        let drawn = RigVariation::for_seed(7);
        assert!(drawn.subsurface_sigma_mm > 0.0 && drawn.apple_form != AppleForm::NONE);
        assert_eq!(drawn.without(TakeOut::default()), drawn);
        let no_glow = drawn.without(TakeOut { glow: true, form: false });
        assert_eq!((no_glow.subsurface_sigma_mm, no_glow.subsurface_shift), (0.0, 0.0));
        assert_eq!(
            RigVariation { subsurface_sigma_mm: 0.3, subsurface_shift: 0.2, ..no_glow },
            RigVariation { subsurface_sigma_mm: 0.3, subsurface_shift: 0.2, ..drawn }
        );
        let no_form = drawn.without(TakeOut { glow: false, form: true });
        assert_eq!(RigVariation { apple_form: drawn.apple_form, ..no_form }, drawn);
        let ellipsoid = Shape::Ellipsoid {
            centre: nalgebra::Point3::new(10.0, -5.0, 900.0),
            rotation: nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 1.1),
            semi_axes_mm: nalgebra::Vector3::new(38.0, 40.0, 41.0),
        };
        assert_eq!(no_form.apple_shape(&ellipsoid), ellipsoid);
        assert!(matches!(drawn.apple_shape(&ellipsoid), Shape::Apple { .. }));
    }
}

//! GenICam cameras (USB3 Vision, GigE Vision: the seed's FLIR Blackfly S)
//! through aravis, behind the cargo feature `genicam` (Debian:
//! libaravis-dev, libusb-1.0-0-dev).
//!
//! The camera runs in software-trigger mode: a capture empties the stream
//! of frames taken before it, triggers, and keeps only a frame whose host
//! arrival time is after the trigger, so the frame was exposed after the
//! call began (the scanner's contract). Mono8, RGB8 and the four 8-bit
//! Bayer layouts come out as RGB8 at full resolution (bilinear demosaic).

use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use alacs_scanner::{Device, Error as DeviceError, FrameCamera, TimedFrame};
use aravis::glib;
use aravis::prelude::*;
use aravis::{AcquisitionMode, Auto, Buffer, BufferStatus, Camera, PixelFormat};
use image::RgbImage;

/// Buffers queued on the stream.
const BUFFERS: usize = 4;

fn camera_error(message: impl std::fmt::Display) -> DeviceError {
    DeviceError::Device { device: Device::Camera, step: None, message: message.to_string() }
}

/// A GenICam camera in software-trigger mode.
pub struct GenicamCamera {
    camera: Camera,
    stream: aravis::Stream,
    /// The device as rig.toml names it ("" for the first found), for messages.
    device: String,
}

impl std::fmt::Debug for GenicamCamera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GenicamCamera").field("device", &self.device).finish_non_exhaustive()
    }
}

impl GenicamCamera {
    /// Opens `device` (an id, serial name or address; the first camera found
    /// when empty), sets software trigger and continuous acquisition, and
    /// starts streaming.
    pub fn open(device: &str) -> Result<Self, DeviceError> {
        let name = if device.is_empty() { "the first GenICam camera" } else { device };
        let fail = |what: &str, e: glib::Error| camera_error(format!("{name}: {what}: {e}"));
        let camera = Camera::new((!device.is_empty()).then_some(device))
            .map_err(|e| fail("cannot be opened", e))?;
        if camera.is_exposure_auto_available().unwrap_or(false) {
            camera.set_exposure_time_auto(Auto::Off).map_err(|e| fail("auto exposure", e))?;
        }
        if camera.is_gain_auto_available().unwrap_or(false) {
            camera.set_gain_auto(Auto::Off).map_err(|e| fail("auto gain", e))?;
        }
        if !camera.is_feature_available("TriggerSoftware").unwrap_or(false) {
            return Err(camera_error(format!(
                "{name}: has no software trigger (TriggerSoftware), which the scanner needs to \
                 know a frame was exposed after the slide stopped"
            )));
        }
        camera.set_trigger("Software").map_err(|e| fail("software trigger", e))?;
        camera
            .set_acquisition_mode(AcquisitionMode::Continuous)
            .map_err(|e| fail("acquisition mode", e))?;
        if camera.is_gv_device() {
            let _ = camera.gv_auto_packet_size();
        }
        let stream = camera.create_stream().map_err(|e| fail("no stream", e))?;
        let payload = camera.payload().map_err(|e| fail("payload size", e))? as usize;
        for _ in 0..BUFFERS {
            stream.push_buffer(Buffer::new_allocate(payload));
        }
        camera.start_acquisition().map_err(|e| fail("acquisition does not start", e))?;
        Ok(Self { camera, stream, device: name.to_string() })
    }

    /// The camera's vendor, model and id, for the rig's description.
    pub fn describe(&self) -> String {
        format!(
            "{} {} ({})",
            self.camera.vendor_name().map(|s| s.to_string()).unwrap_or_default(),
            self.camera.model_name().map(|s| s.to_string()).unwrap_or_default(),
            self.camera.device_id().map(|s| s.to_string()).unwrap_or_default()
        )
    }

    fn fail(&self, what: impl std::fmt::Display) -> DeviceError {
        camera_error(format!("{}: {what}", self.device))
    }
}

impl Drop for GenicamCamera {
    fn drop(&mut self) {
        let _ = self.camera.stop_acquisition();
    }
}

fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .ok()
        .and_then(|d| u64::try_from(d.as_nanos()).ok())
        .unwrap_or(0)
}

impl GenicamCamera {
    /// A frame triggered in software after this call began, and when the
    /// trigger that gave it was sent (the host's clock).
    fn grab(&mut self, timeout: Duration) -> alacs_scanner::Result<(RgbImage, Instant)> {
        // Frames taken before this call are stale: back to the queue.
        while let Some(buffer) = self.stream.try_pop_buffer() {
            self.stream.push_buffer(buffer);
        }
        let deadline = Instant::now() + timeout;
        let mut triggered_ns = now_ns();
        let mut triggered_at = Instant::now();
        self.camera.software_trigger().map_err(|e| self.fail(format!("trigger: {e}")))?;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(DeviceError::Timeout {
                    device: Device::Camera,
                    step: None,
                    timeout,
                    detail: format!("no frame from {} after a software trigger", self.device),
                });
            }
            let micros = u64::try_from(left.as_micros()).unwrap_or(u64::MAX);
            let Some(buffer) = self.stream.timeout_pop_buffer(micros) else { continue };
            let status = buffer.status();
            let arrived_ns = buffer.system_timestamp();
            if status != BufferStatus::Success {
                // A lost frame (GigE without resends): trigger again.
                self.stream.push_buffer(buffer);
                triggered_ns = now_ns();
                triggered_at = Instant::now();
                self.camera.software_trigger().map_err(|e| self.fail(format!("trigger: {e}")))?;
                continue;
            }
            if arrived_ns < triggered_ns {
                self.stream.push_buffer(buffer);
                continue;
            }
            let (width, height) = (buffer.image_width(), buffer.image_height());
            let format = buffer.image_pixel_format();
            let data = buffer.image_data();
            self.stream.push_buffer(buffer);
            let (Ok(width), Ok(height)) = (u32::try_from(width), u32::try_from(height)) else {
                return Err(self.fail(format!("a frame of {width} x {height} px")));
            };
            let image = to_rgb(format, width, height, &data).map_err(|e| self.fail(e))?;
            return Ok((image, triggered_at));
        }
    }
}

impl FrameCamera for GenicamCamera {
    fn capture(&mut self, timeout: Duration) -> alacs_scanner::Result<RgbImage> {
        Ok(self.grab(timeout)?.0)
    }

    /// The exposure starts at the software trigger: its moment on the host
    /// is taken just before the trigger command is sent, so the stamp is
    /// early by the command's round trip and the camera's trigger latency
    /// (for GigE Vision typically well under 1 ms; a sweep at 50 mm/s
    /// moves the slide 0.05 mm in 1 ms).
    fn capture_timed(&mut self, timeout: Duration) -> alacs_scanner::Result<TimedFrame> {
        let exposure_us =
            self.camera.exposure_time().map_err(|e| self.fail(format!("exposure: {e}")))?;
        let (image, exposure_start) = self.grab(timeout)?;
        let exposure = Duration::try_from_secs_f64(exposure_us * 1e-6)
            .map_err(|_| self.fail(format!("exposure time {exposure_us} us")))?;
        Ok(TimedFrame { image, exposure_start, exposure })
    }

    fn set_exposure_us(&mut self, exposure_us: f64) -> alacs_scanner::Result<f64> {
        let (low, high) =
            self.camera.exposure_time_bounds().map_err(|e| self.fail(format!("exposure: {e}")))?;
        if !(exposure_us.is_finite() && (low..=high).contains(&exposure_us)) {
            return Err(self.fail(format!("exposure {exposure_us} us is outside {low}-{high} us")));
        }
        self.camera
            .set_exposure_time(exposure_us)
            .map_err(|e| self.fail(format!("exposure: {e}")))?;
        self.camera.exposure_time().map_err(|e| self.fail(format!("exposure: {e}")))
    }

    fn set_gain_db(&mut self, gain_db: f64) -> alacs_scanner::Result<f64> {
        let (low, high) = self.camera.gain_bounds().map_err(|e| self.fail(format!("gain: {e}")))?;
        if !(gain_db.is_finite() && (low..=high).contains(&gain_db)) {
            return Err(self.fail(format!("gain {gain_db} is outside {low}-{high}")));
        }
        self.camera.set_gain(gain_db).map_err(|e| self.fail(format!("gain: {e}")))?;
        self.camera.gain().map_err(|e| self.fail(format!("gain: {e}")))
    }
}

/// Converts a frame of `format` to RGB8 at full resolution.
pub fn to_rgb(
    format: PixelFormat,
    width: u32,
    height: u32,
    data: &[u8],
) -> Result<RgbImage, String> {
    let pixels = width as usize * height as usize;
    let short = |needed: usize| {
        format!("a {width} x {height} px frame holds {} bytes, {needed} needed", data.len())
    };
    // Colour (0 R, 1 G, 2 B) of the 2 x 2 cell's (0,0), (1,0), (0,1), (1,1).
    let cfa = match format {
        PixelFormat::RGB_8_PACKED => {
            let bytes = data.get(..pixels * 3).ok_or_else(|| short(pixels * 3))?;
            return RgbImage::from_raw(width, height, bytes.to_vec())
                .ok_or_else(|| short(pixels * 3));
        }
        PixelFormat::MONO_8 => {
            let bytes = data.get(..pixels).ok_or_else(|| short(pixels))?;
            let rgb = bytes.iter().flat_map(|&v| [v, v, v]).collect();
            return RgbImage::from_raw(width, height, rgb).ok_or_else(|| short(pixels));
        }
        PixelFormat::BAYER_RG_8 => [0, 1, 1, 2],
        PixelFormat::BAYER_BG_8 => [2, 1, 1, 0],
        PixelFormat::BAYER_GR_8 => [1, 0, 2, 1],
        PixelFormat::BAYER_GB_8 => [1, 2, 0, 1],
        other => {
            return Err(format!(
                "pixel format 0x{:08x}: Mono8, RGB8 or an 8-bit Bayer format are read",
                other.raw()
            ));
        }
    };
    let raw = data.get(..pixels).ok_or_else(|| short(pixels))?;
    Ok(demosaic(width, height, raw, cfa))
}

/// Bilinear demosaic: each colour of a pixel is the mean of that colour's
/// sites in its 3 x 3 neighbourhood (the pixel itself where it has it).
fn demosaic(width: u32, height: u32, raw: &[u8], cfa: [usize; 4]) -> RgbImage {
    let (w, h) = (width as i64, height as i64);
    let colour = |x: i64, y: i64| cfa[((y & 1) * 2 + (x & 1)) as usize];
    RgbImage::from_fn(width, height, |x, y| {
        let (x, y) = (i64::from(x), i64::from(y));
        let own = colour(x, y);
        let mut sum = [0u32; 3];
        let mut count = [0u32; 3];
        for dy in -1..=1 {
            for dx in -1..=1 {
                let (nx, ny) = (x + dx, y + dy);
                if nx < 0 || ny < 0 || nx >= w || ny >= h {
                    continue;
                }
                let c = colour(nx, ny);
                if c == own && (dx, dy) != (0, 0) {
                    continue;
                }
                sum[c] += u32::from(raw[(ny * w + nx) as usize]);
                count[c] += 1;
            }
        }
        let value = |c: usize| sum[c].checked_div(count[c]).unwrap_or(0) as u8;
        image::Rgb([value(0), value(1), value(2)])
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flat_colour_survives_every_bayer_layout() {
        // A flat (R, G, B) field mosaicked in each layout demosaics to itself.
        let (w, h) = (6u32, 4u32);
        let rgb = [200u8, 100, 50];
        for (format, cfa) in [
            (PixelFormat::BAYER_RG_8, [0, 1, 1, 2]),
            (PixelFormat::BAYER_BG_8, [2, 1, 1, 0]),
            (PixelFormat::BAYER_GR_8, [1, 0, 2, 1]),
            (PixelFormat::BAYER_GB_8, [1, 2, 0, 1]),
        ] {
            let raw: Vec<u8> = (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .map(|(x, y)| rgb[cfa[((y & 1) * 2 + (x & 1)) as usize]])
                .collect();
            let image = to_rgb(format, w, h, &raw).unwrap_or_default();
            assert!(image.pixels().all(|p| p.0 == rgb), "{format:?}");
        }
    }

    #[test]
    fn a_short_frame_is_an_error_not_a_panic() {
        assert!(to_rgb(PixelFormat::MONO_8, 10, 10, &[0; 99]).is_err());
        assert!(to_rgb(PixelFormat::BAYER_RG_8, 10, 10, &[0; 5]).is_err());
        assert!(to_rgb(PixelFormat::RGB_8_PACKED, 2, 2, &[0; 11]).is_err());
    }
}

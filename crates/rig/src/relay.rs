//! A laser switched by a relay on a serial port of its own (the common USB
//! relay modules): rig.toml's `on_bytes` and `off_bytes` are written as
//! they are. Such relays do not answer, so a write that fails (the port
//! unplugged) is the only fault they can show. Dropping the switch writes
//! the off bytes (best effort).

use std::io::Write as _;
use std::time::Duration;

use alacs_scanner::{Device, Error as DeviceError, LaserSwitch};

use crate::config::{LaserConfig, parse_hex};

/// The laser on a serial relay.
pub struct SerialRelayLaser {
    port: Box<dyn serialport::SerialPort>,
    name: String,
    on: Vec<u8>,
    off: Vec<u8>,
    settle: Duration,
}

impl std::fmt::Debug for SerialRelayLaser {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialRelayLaser").field("port", &self.name).finish_non_exhaustive()
    }
}

fn laser_error(message: String) -> DeviceError {
    DeviceError::Device { device: Device::Laser, step: None, message }
}

impl SerialRelayLaser {
    /// Opens the relay of `config` (a checked rig.toml `[laser]`).
    pub fn open(config: &LaserConfig) -> Result<Self, DeviceError> {
        let on = parse_hex(&config.on_bytes).map_err(laser_error)?;
        let off = parse_hex(&config.off_bytes).map_err(laser_error)?;
        let port = serialport::new(&config.port, config.baud)
            .timeout(Duration::from_millis(100))
            .open()
            .map_err(|e| {
                laser_error(format!("cannot open the relay's serial port {}: {e}", config.port))
            })?;
        Ok(Self {
            port,
            name: config.port.clone(),
            on,
            off,
            settle: Duration::from_secs_f64(config.settle_ms / 1000.0),
        })
    }
}

impl LaserSwitch for SerialRelayLaser {
    fn set(&mut self, on: bool) -> alacs_scanner::Result<()> {
        let bytes = if on { &self.on } else { &self.off };
        self.port.write_all(bytes).and_then(|()| self.port.flush()).map_err(|e| {
            laser_error(format!("the relay on {} failed (unplugged?): {e}", self.name))
        })?;
        std::thread::sleep(self.settle);
        Ok(())
    }
}

impl Drop for SerialRelayLaser {
    fn drop(&mut self) {
        let _ = self.port.write_all(&self.off).and_then(|()| self.port.flush());
    }
}

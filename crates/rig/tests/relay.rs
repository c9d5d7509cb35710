//! The serial-relay laser on a pseudo-terminal: the bytes rig.toml gives
//! go out as they are, off when the rig connects, on and off as asked, off
//! when the rig closes; a relay whose port is gone is an error naming the
//! laser and the port.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, ChildStdout, Command, Stdio};
use std::sync::Arc;

use alacs_model::{Camera, LaserModel};
use alacs_rig::{RealRig, RigConfig};
use alacs_scanner::Device;
use alacs_sim::{ScanOptions, simulate_scan};

const ON: [u8; 4] = [0xA0, 0x01, 0x01, 0xA2];
const OFF: [u8; 4] = [0xA0, 0x01, 0x00, 0xA1];

/// A pseudo-terminal whose master side Python holds: it prints the slave's
/// path, then every byte written to the slave, in hexadecimal, a read a line.
const RELAY: &str = r#"
import os, select, sys, time, tty
master, slave = os.openpty()
tty.setraw(master)
print(os.ttyname(slave), flush=True)
os.close(slave)
end = time.monotonic() + 30
while time.monotonic() < end:
    ready, _, _ = select.select([master], [], [], 0.05)
    try:
        data = os.read(master, 64) if ready else b""
    except OSError:  # no slave open yet
        time.sleep(0.01)
        continue
    if data:
        print(data.hex(), flush=True)
"#;

struct Relay {
    child: Child,
    lines: BufReader<ChildStdout>,
    port: String,
    received: Vec<u8>,
}

impl Drop for Relay {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Relay {
    fn start() -> Self {
        let python = std::env::var("ALACS_PYTHON").unwrap_or_else(|_| "python3".into());
        let mut child = Command::new(python)
            .args(["-c", RELAY])
            .stdout(Stdio::piped())
            .spawn()
            .expect("python3 runs");
        let mut lines = BufReader::new(child.stdout.take().unwrap());
        let mut port = String::new();
        lines.read_line(&mut port).unwrap();
        Self { child, lines, port: port.trim().to_string(), received: Vec::new() }
    }

    /// The next `n` bytes the relay received.
    fn next(&mut self, n: usize) -> Vec<u8> {
        while self.received.len() < n {
            let mut line = String::new();
            assert!(self.lines.read_line(&mut line).unwrap() > 0, "the relay ended");
            let hex = line.trim();
            self.received.extend(
                (0..hex.len()).step_by(2).map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap()),
            );
        }
        self.received.drain(..n).collect()
    }
}

/// A small simulated scene for the simulated slide and camera.
fn scene() -> Arc<alacs_sim::SimulatedScan> {
    let options = ScanOptions { scale: 0.1, ..ScanOptions::default() };
    Arc::new(simulate_scan(&Camera::blackfly_s_5mp(), &LaserModel::seed_paper(), &options).unwrap())
}

#[test]
fn a_serial_relay_switches_the_laser_with_its_bytes_and_ends_off() {
    let mut relay = Relay::start();
    let config = RigConfig::from_toml(
        &format!(
            "[slide]\ndriver = \"sim\"\n[camera]\ndriver = \"sim\"\n\
             [laser]\ndriver = \"serial-relay\"\nport = \"{}\"\n\
             on_bytes = \"A0 01 01 A2\"\noff_bytes = \"a00100a1\"\n",
            relay.port
        ),
        Path::new("rig.toml"),
    )
    .unwrap();
    let mut rig = RealRig::open(&config, Some(scene())).unwrap();
    assert_eq!(relay.next(4), OFF, "off when the rig connects");
    rig.rig().laser.set(true).unwrap();
    assert_eq!(relay.next(4), ON);
    rig.rig().laser.set(false).unwrap();
    assert_eq!(relay.next(4), OFF);
    rig.rig().laser.set(true).unwrap();
    assert_eq!(relay.next(4), ON);
    drop(rig);
    assert_eq!(relay.next(4), OFF, "off when the rig closes");
}

#[test]
fn a_relay_whose_port_is_gone_is_an_error_naming_the_laser_and_the_port() {
    let config = RigConfig::from_toml(
        "[slide]\ndriver = \"sim\"\n[laser]\ndriver = \"serial-relay\"\n\
         port = \"/dev/alacs-no-relay\"\non_bytes = \"01\"\noff_bytes = \"00\"\n",
        Path::new("rig.toml"),
    )
    .unwrap();
    let error = RealRig::open(&config, Some(scene())).unwrap_err();
    let alacs_rig::Error::Device(device_error) = &error else { panic!("{error}") };
    assert_eq!(device_error.device(), Some(Device::Laser), "{error}");
    assert!(error.to_string().contains("/dev/alacs-no-relay"), "{error}");
    for (text, key) in [
        ("on_bytes = \"A0 1\"\noff_bytes = \"00\"", "[laser] on_bytes"),
        ("on_bytes = \"zz\"\noff_bytes = \"00\"", "[laser] on_bytes"),
        ("on_bytes = \"01\"\noff_bytes = \"01\"", "[laser] off_bytes"),
        ("on_bytes = \"01\"\noff_bytes = \"\"", "[laser] off_bytes"),
    ] {
        let toml = format!(
            "[slide]\ndriver = \"sim\"\n[laser]\ndriver = \"serial-relay\"\nport = \"/dev/x\"\n{text}\n"
        );
        let error = RigConfig::from_toml(&toml, Path::new("rig.toml")).unwrap_err().to_string();
        assert!(error.contains(key), "{text}: {error}");
    }
}

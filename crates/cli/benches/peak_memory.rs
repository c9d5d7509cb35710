//! Peak memory of the `alacs` program on the worst inputs the contract
//! allows (docs/FORMATS.md, "Limits"): each case runs the real binary and
//! reads the child's peak resident set size from the kernel (VmHWM in
//! /proc), so the number is the whole process's, allocator included.
//!
//!     cargo bench -p alacs-cli --bench peak_memory
//!
//! The inputs are made with `alacs simulate` into a temporary folder first
//! (a few minutes on 2 cores: one full-resolution scan, 2 million samples).
//! The numbers go into docs/SPEED.md's "Memory" table.

// A benchmark program: failing loudly is its error handling.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use alacs::Scan;

const ALACS: &str = env!("CARGO_BIN_EXE_alacs");

/// The peak resident set size of process `pid` so far (VmHWM), MiB.
fn peak_rss_mib(pid: u32) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// Runs `alacs args...` to its end; returns its exit code, wall time (s)
/// and peak RSS (MiB): the kernel's high-water mark (VmHWM), read every
/// 2 ms until the process exits (it only grows, so the last reading is
/// the peak but for the last 2 ms of the run).
fn measure(args: &[&str]) -> (i32, f64, f64) {
    let start = Instant::now();
    let mut child = Command::new(ALACS)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn alacs");
    let mut peak = 0.0_f64;
    let status = loop {
        if let Some(mib) = peak_rss_mib(child.id()) {
            peak = peak.max(mib);
        }
        if let Some(status) = child.try_wait().expect("wait") {
            break status;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    };
    (status.code().unwrap_or(-1), start.elapsed().as_secs_f64(), peak)
}

/// Runs a setup command, which must succeed.
fn setup(args: &[&str]) {
    let (code, seconds, _) = measure(args);
    assert_eq!(code, 0, "setup `alacs {}` failed", args.join(" "));
    eprintln!("  setup ({seconds:.1} s): alacs {}", args.join(" "));
}

fn arg(path: &Path) -> String {
    path.display().to_string()
}

/// A scan folder of `n` frames at full resolution: the 5 frames of `scan`
/// repeated (the memory of a scan does not depend on what its frames show).
fn long_scan(scan: &Path, n: usize, out: &Path) -> PathBuf {
    let mut long = Scan::read(scan).unwrap();
    let frames = long.frames.clone();
    long.frames = (0..n).map(|i| frames[i % frames.len()].clone()).collect();
    for frame in &mut long.frames {
        frame.image = scan.join(&frame.image);
        frame.image_laser_off = frame.image_laser_off.as_ref().map(|off| scan.join(off));
    }
    std::fs::create_dir_all(out).unwrap();
    long.dir = out.to_path_buf();
    long.write_yaml("# peak_memory bench: frames repeated").unwrap();
    out.to_path_buf()
}

fn main() {
    // `cargo bench` passes `--bench`; nothing to filter here.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scan = d.join("scan");
    let samples = d.join("samples");
    eprintln!("making the inputs in {}", d.display());
    setup(&["simulate", "scan", "--out", &arg(&scan), "--laser-off", "--seed", "1"]);
    setup(&[
        "simulate",
        "samples",
        "--out",
        &arg(&samples),
        "--views",
        "200000",
        "--points-per-view",
        "10",
        "--outliers",
        "0.3",
    ]);
    let scan64 = long_scan(&scan, alacs::locate::MAX_SCAN_FRAMES, &d.join("scan64"));
    // The same 64 frames as a recording (`localize --bag` reads it as it goes).
    let bag64 = d.join("scan64.mcap");
    setup(&["bag", "import", &arg(&scan64), &arg(&bag64)]);
    let bag64 = arg(&bag64);
    let scan5 = arg(&scan);
    let scan64 = arg(&scan64);
    let camera = arg(&scan.join("camera.yaml"));
    let laser = arg(&scan.join("laser.yaml"));
    let csv = arg(&samples.join("samples.csv"));
    let zero = "/dev/zero".to_string();
    let big = d.join("big.yaml");
    // A 300 MB scan.yaml: refused by size before it is parsed.
    std::fs::write(&big, vec![b'#'; 300 << 20]).unwrap();
    let big_scan = d.join("big_scan");
    std::fs::create_dir_all(&big_scan).unwrap();
    std::fs::rename(&big, big_scan.join("scan.yaml")).unwrap();
    let big_scan = arg(&big_scan);
    let out = |name: &str| arg(&d.join(name));
    // A 240 MB pixels.csv (12 million pixels over the 5 MP image).
    let pixels = d.join("pixels.csv");
    {
        use std::io::Write as _;
        let mut w = std::io::BufWriter::new(std::fs::File::create(&pixels).unwrap());
        writeln!(w, "u_px,v_px").unwrap();
        for i in 0..12_000_000_u64 {
            let (u, v) = ((i * 7919) % 2448, (i * 104_729) % 2048);
            writeln!(w, "{u}.{:03},{v}.{:03}", i % 1000, (i / 7) % 1000).unwrap();
        }
    }
    let pixels = arg(&pixels);

    let (report64, eval2m, session_x2) = (out("report64"), out("eval2m"), out("session_x2"));
    let scan_x2 = out("scan_x2");
    fn localize_args<'a>(scan: &'a str, camera: &'a str, laser: &'a str) -> Vec<&'a str> {
        vec!["localize", "--scan", scan, "--camera", camera, "--laser", laser]
    }
    let cases: Vec<(&str, Vec<&str>)> = vec![
        (
            "localize, 5 frames at 5 MP with laser-off images",
            localize_args(&scan5, &camera, &laser),
        ),
        (
            "localize, 64 frames at 5 MP with laser-off images (MAX_SCAN_FRAMES)",
            localize_args(&scan64, &camera, &laser),
        ),
        ("localize --bag, the same 64 frames recorded in MCAP", {
            let mut a = vec!["localize", "--bag", &bag64];
            a.extend_from_slice(&localize_args(&scan64, &camera, &laser)[3..]);
            a
        }),
        ("report scan, 64 frames at 5 MP (holds every frame)", {
            let mut a = vec!["report", "scan"];
            a.extend_from_slice(&localize_args(&scan64, &camera, &laser)[1..]);
            a.extend_from_slice(&["--out", &report64]);
            a
        }),
        (
            "calibrate laser, 2,000,000 samples (30 % outliers), Method 4",
            vec!["calibrate", "laser", "--samples", &csv],
        ),
        (
            "evaluate calibration, 2,000,000 samples (plots decimated)",
            vec!["evaluate", "calibration", "--samples", &csv, "--out", &eval2m],
        ),
        (
            "triangulate --json, 12,000,000 pixels (a 240 MB pixels.csv)",
            vec![
                "triangulate",
                "--camera",
                &camera,
                "--laser",
                &laser,
                "--slide-mm",
                "100",
                "--pixels",
                &pixels,
                "--json",
            ],
        ),
        (
            "calibrate laser --samples /dev/zero (refused: not a regular file)",
            vec!["calibrate", "laser", "--samples", &zero],
        ),
        (
            "localize, a 300 MB scan.yaml (refused at the size limit)",
            localize_args(&big_scan, &camera, &laser),
        ),
        (
            "simulate session --scale 2 (MAX_SCALE: 20 MP), 1 view",
            vec!["simulate", "session", "--scale", "2", "--views", "1", "--out", &session_x2],
        ),
        (
            "simulate scan --scale 2 (MAX_SCALE: 20 MP), 5 frames",
            vec!["simulate", "scan", "--scale", "2", "--out", &scan_x2],
        ),
    ];
    println!("| case | exit | time (s) | peak RSS (MiB) |");
    println!("|---|---|---|---|");
    for (name, args) in &cases {
        let (code, seconds, mib) = measure(args);
        println!("| {name} | {code} | {seconds:.1} | {mib:.0} |");
    }
}

//! Files checked like a vehicle's software must be: MCAP checksums, things
//! that are not regular files, bounded reads, and physically impossible
//! values (`drive_io::plausibility`).

// Helpers outside #[test] functions unwrap too: a failure is a test failure.
#![allow(clippy::unwrap_used)]

use drive_io::plausibility::{self, Finding, Severity};
use drive_io::{
    read_drive, read_drive_with, read_estimate, read_vehicle, write_drive, DriveError, ReadOptions,
    MAX_CSV_LINE_BYTES, MAX_TEXT_FILE_BYTES,
};
use interfaces::drive::{
    Drive, GnssAntenna, GnssSample, ImuSample, VehicleParams, Wheel, WheelSample, WheelSeries,
    WheelUnit, WheelUnits,
};
use std::path::{Path, PathBuf};

const TPR: f64 = 48.0;
const C: f64 = 2.0;
const TRACK: f64 = 1.5;

/// A car at 10 m/s weaving left and right (yaw rate 0.4 sin(2 pi t / 30)
/// rad/s) for `secs` seconds: wheels at 100 Hz in `unit` (cumulative ticks
/// never wrap here), GNSS at 10 Hz, IMU at 100 Hz with a little noise.
fn weaving(unit: WheelUnit, secs: f64) -> Drive {
    let dt = 0.01;
    let n = (secs / dt) as usize;
    let (mut x, mut y, mut yaw) = (0.0f64, 0.0f64, 0.0f64);
    let (mut nl, mut nr) = (0.0f64, 0.0f64);
    let mut wheels = Vec::with_capacity(n);
    let mut gnss = Vec::new();
    let mut imu = Vec::with_capacity(n);
    for i in 0..n {
        let t = i as f64 * dt;
        let v = 10.0;
        let w = 0.4 * (std::f64::consts::TAU * t / 30.0).sin();
        let (vl, vr) = (v - 0.5 * w * TRACK, v + 0.5 * w * TRACK);
        let value = |n: f64, vw: f64| match unit {
            WheelUnit::Ticks => (n * TPR).floor(),
            WheelUnit::Rev => n,
            WheelUnit::RadS => vw / C * std::f64::consts::TAU,
            WheelUnit::MS => vw,
        };
        wheels.push(WheelSample {
            t_s: t,
            rl: value(nl, vl),
            rr: value(nr, vr),
            fl: None,
            fr: None,
        });
        if i % 10 == 0 {
            gnss.push(GnssSample {
                t_s: t,
                x_m: x,
                y_m: y,
                sigma_m: None,
            });
        }
        imu.push(ImuSample {
            t_s: t,
            gz_rad_s: w + 1e-3 * (37.0 * t).sin(),
            ax_m_s2: Some(0.01 * (3.0 * t).sin()),
            ay_m_s2: Some(v * w),
            az_m_s2: None,
            gx_rad_s: None,
            gy_rad_s: None,
        });
        x += v * yaw.cos() * dt;
        y += v * yaw.sin() * dt;
        yaw += w * dt;
        nl += vl / C * dt;
        nr += vr / C * dt;
    }
    Drive {
        vehicle: VehicleParams {
            name: None,
            track_width_m: TRACK,
            nominal_circumference_m: C,
            wheelbase_m: None,
            ticks_per_rev: Some(TPR),
            gnss: GnssAntenna::default(),
        },
        wheels: WheelSeries {
            units: WheelUnits::rear(unit),
            samples: wheels,
        },
        gnss: Some(gnss),
        imu: Some(imu),
        heading: None,
        truth: None,
        truth_params: None,
    }
}

// ------------------------------------------------------------ MCAP CRCs

/// (opcode, record offset, body range) of the top-level records.
fn records(bytes: &[u8]) -> Vec<(u8, usize, std::ops::Range<usize>)> {
    let mut out = Vec::new();
    let mut pos = 8;
    while pos + 9 <= bytes.len() {
        let op = bytes[pos];
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        out.push((op, pos, pos + 9..pos + 9 + len));
        if op == 0x02 {
            break; // footer
        }
        pos += 9 + len;
    }
    out
}

fn written_mcap(dir: &Path) -> (PathBuf, Vec<u8>, Drive) {
    let d = weaving(WheelUnit::Ticks, 20.0);
    let path = dir.join("drive.mcap");
    write_drive(&d, &path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    (path, bytes, d)
}

#[test]
fn an_intact_recording_passes_its_crcs() {
    let dir = tempfile::tempdir().unwrap();
    let (path, bytes, d) = written_mcap(dir.path());
    // The writer does give CRCs (else this test would prove nothing).
    let chunk = records(&bytes).into_iter().find(|r| r.0 == 0x06).unwrap();
    let crc = u32::from_le_bytes(
        bytes[chunk.2.start + 24..chunk.2.start + 28]
            .try_into()
            .unwrap(),
    );
    assert_ne!(crc, 0);
    let loaded = read_drive(&path).unwrap();
    assert_eq!(loaded.drive, d);
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
}

#[test]
fn a_changed_byte_in_a_chunk_is_an_error_naming_the_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut bytes, d) = written_mcap(dir.path());
    let (_, offset, body) = records(&bytes).into_iter().find(|r| r.0 == 0x06).unwrap();
    // A byte in the middle of the chunk's records (a digit of some value).
    let k = (body.start + body.end) / 2;
    bytes[k] ^= 0x01;
    std::fs::write(&path, &bytes).unwrap();
    let e = read_drive(&path).unwrap_err();
    let msg = e.to_string();
    match e {
        DriveError::ChunkCrc {
            chunk_index,
            offset: at,
            expected,
            actual,
            ..
        } => {
            assert_eq!(chunk_index, 0);
            assert_eq!(at, offset as u64);
            assert_ne!(expected, actual);
        }
        other => panic!("not a ChunkCrc: {other}"),
    }
    assert!(
        msg.contains("drive.mcap")
            && msg.contains("chunk 0")
            && msg.contains(&format!("byte {offset}")),
        "{msg}"
    );
    // Recovery only when asked: the chunk is left out with a warning naming it.
    let rec = read_drive_with(
        &path,
        ReadOptions {
            skip_corrupt_chunks: true,
            ..ReadOptions::default()
        },
    )
    .unwrap_or_else(|e| match e {
        DriveError::TruncatedMcap {
            partial: Some(p), ..
        } => *p,
        e => panic!("{e}"),
    });
    assert!(
        rec.warnings.iter().any(|w| w.contains("chunk 0")
            && w.contains(&format!("byte {offset}"))
            && w.contains("skipped")),
        "{:?}",
        rec.warnings
    );
    assert!(rec.drive.wheels.samples.len() < d.wheels.samples.len());
}

#[test]
fn a_changed_byte_outside_the_chunks_fails_the_data_section_crc() {
    let dir = tempfile::tempdir().unwrap();
    let (path, mut bytes, _) = written_mcap(dir.path());
    // The last byte of the first Metadata record (inside a value string).
    let (_, _, body) = records(&bytes).into_iter().find(|r| r.0 == 0x0C).unwrap();
    bytes[body.end - 1] ^= 0x01;
    std::fs::write(&path, &bytes).unwrap();
    let e = read_drive(&path).unwrap_err();
    assert!(matches!(e, DriveError::DataSectionCrc { .. }), "{e}");
    assert!(e.to_string().contains("data section is corrupt"), "{e}");
    let rec = read_drive_with(
        &path,
        ReadOptions {
            skip_corrupt_chunks: true,
            ..ReadOptions::default()
        },
    );
    // With recovery the mismatch is a warning (the changed text itself may
    // still be refused by the TOML parser, naming the metadata record).
    if let Ok(rec) = rec {
        assert!(
            rec.warnings
                .iter()
                .any(|w| w.contains("data section fails its CRC")),
            "{:?}",
            rec.warnings
        );
    }
}

// ------------------------------------------------------------ not regular files

fn minimal_folder() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("vehicle.toml"),
        "track_width_m = 1.5\nnominal_circumference_m = 2.0\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("wheels.csv"),
        "t_s,rl_rev,rr_rev\n0,0,0\n0.1,1,1\n",
    )
    .unwrap();
    dir
}

#[test]
fn a_directory_in_place_of_a_stream_file_is_named() {
    let dir = minimal_folder();
    std::fs::create_dir(dir.path().join("imu.csv")).unwrap();
    let e = read_drive(dir.path()).unwrap_err();
    assert!(matches!(e, DriveError::NotAFile { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("imu.csv") && msg.contains("a directory"),
        "{msg}"
    );
}

fn mkfifo(path: &Path) -> bool {
    match std::process::Command::new("mkfifo").arg(path).status() {
        Ok(s) if s.success() => true,
        other => {
            eprintln!("skipped: mkfifo is not available ({other:?})");
            false
        }
    }
}

#[test]
fn a_fifo_is_refused_without_opening_it() {
    let dir = minimal_folder();
    let fifo = dir.path().join("gnss.csv");
    if !mkfifo(&fifo) {
        return;
    }
    // Opening a FIFO would block this test forever.
    let e = read_drive(dir.path()).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("gnss.csv") && msg.contains("FIFO"), "{msg}");
    // As the drive itself, as vehicle.toml, as an estimate file.
    let e = read_drive(&fifo).unwrap_err();
    assert!(e.to_string().contains("FIFO"), "{e}");
    let toml = dir.path().join("v.toml");
    assert!(mkfifo(&toml));
    let e = read_vehicle(&toml).unwrap_err();
    assert!(
        e.to_string().contains("v.toml") && e.to_string().contains("FIFO"),
        "{e}"
    );
    let json = dir.path().join("est.json");
    assert!(mkfifo(&json));
    let e = read_estimate(&json).unwrap_err().to_string();
    assert!(e.contains("est.json") && e.contains("FIFO"), "{e}");
    // vehicle.toml itself a FIFO: not "missing".
    let v = dir.path().join("vehicle.toml");
    std::fs::remove_file(&v).unwrap();
    assert!(mkfifo(&v));
    let e = read_drive(dir.path()).unwrap_err();
    assert!(matches!(e, DriveError::NotAFile { .. }), "{e}");
}

#[cfg(unix)]
#[test]
fn a_link_to_a_device_is_refused() {
    use std::os::unix::fs::symlink;
    let dir = minimal_folder();
    symlink("/dev/zero", dir.path().join("heading.csv")).unwrap();
    let e = read_drive(dir.path()).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("heading.csv")
            && msg.contains("/dev/zero")
            && msg.contains("character device"),
        "{msg}"
    );
    let drive = dir.path().join("zero.mcap");
    symlink("/dev/urandom", &drive).unwrap();
    let e = read_drive(&drive).unwrap_err();
    assert!(e.to_string().contains("/dev/urandom"), "{e}");
    let toml = dir.path().join("zero.toml");
    symlink("/dev/zero", &toml).unwrap();
    let e = read_vehicle(&toml).unwrap_err();
    assert!(e.to_string().contains("character device"), "{e}");
    let json = dir.path().join("zero.json");
    symlink("/dev/zero", &json).unwrap();
    let e = read_estimate(&json).unwrap_err().to_string();
    assert!(
        e.contains("zero.json") && e.contains("character device"),
        "{e}"
    );
    // A broken link is named as such, not taken as "no such stream".
    let dir = minimal_folder();
    symlink(dir.path().join("nowhere.csv"), dir.path().join("imu.csv")).unwrap();
    let e = read_drive(dir.path()).unwrap_err();
    assert!(e.to_string().contains("symbolic link"), "{e}");
}

// ------------------------------------------------------------ bounded reads

#[test]
fn an_overlong_csv_line_is_an_error_naming_file_and_line() {
    let dir = minimal_folder();
    let wheels = dir.path().join("wheels.csv");
    // A header line of 1 MiB without a newline.
    std::fs::write(&wheels, "t".repeat(1 << 20)).unwrap();
    let e = read_drive(dir.path()).unwrap_err();
    assert!(
        matches!(e, DriveError::LineTooLong { line: 1, limit, .. } if limit == MAX_CSV_LINE_BYTES),
        "{e}"
    );
    assert!(e.to_string().contains("wheels.csv:1"), "{e}");
    // A row line.
    let long = format!("t_s,rl_rev,rr_rev\n0,0,0\n0.1,1,{}\n", "9".repeat(100_000));
    std::fs::write(&wheels, long).unwrap();
    let e = read_drive(dir.path()).unwrap_err();
    assert!(matches!(e, DriveError::LineTooLong { line: 3, .. }), "{e}");
    // A line of exactly the limit is read (a comment here).
    let at = format!("t_s,rl_rev,rr_rev\n{}\n", "#".repeat(MAX_CSV_LINE_BYTES));
    std::fs::write(&wheels, at).unwrap();
    read_drive(dir.path()).unwrap();
}

#[test]
fn echoed_cells_are_cut_to_forty_characters() {
    let dir = minimal_folder();
    let cell = "x".repeat(5000);
    std::fs::write(
        dir.path().join("wheels.csv"),
        format!("t_s,rl_rev,rr_rev\n0,0,{cell}\n"),
    )
    .unwrap();
    let e = read_drive(dir.path()).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains(&format!("{}…", "x".repeat(40))), "{msg}");
    assert!(!msg.contains(&"x".repeat(41)), "{msg}");
    assert!(msg.len() < 300, "{}", msg.len());
}

#[test]
fn oversized_toml_and_json_are_refused_naming_the_limit() {
    let dir = minimal_folder();
    let big = |p: &Path| {
        let f = std::fs::File::create(p).unwrap();
        f.set_len(MAX_TEXT_FILE_BYTES + 1).unwrap(); // sparse: no disk used
    };
    big(&dir.path().join("vehicle.toml"));
    let e = read_drive(dir.path()).unwrap_err();
    assert!(matches!(e, DriveError::FileTooLarge { .. }), "{e}");
    assert!(
        e.to_string().contains("vehicle.toml")
            && e.to_string().contains(&MAX_TEXT_FILE_BYTES.to_string()),
        "{e}"
    );
    let toml = dir.path().join("big.toml");
    big(&toml);
    assert!(matches!(
        read_vehicle(&toml),
        Err(DriveError::FileTooLarge { .. })
    ));
    let json = dir.path().join("big.json");
    big(&json);
    let e = read_estimate(&json).unwrap_err().to_string();
    assert!(
        e.contains("big.json") && e.contains(&MAX_TEXT_FILE_BYTES.to_string()),
        "{e}"
    );
}

#[test]
fn non_finite_and_overflowing_cells_are_refused_on_reading() {
    let dir = minimal_folder();
    for cell in ["1e309", "inf", "NaN", "-1e400"] {
        std::fs::write(
            dir.path().join("wheels.csv"),
            format!("t_s,rl_rev,rr_rev\n0,0,0\n0.1,{cell},1\n"),
        )
        .unwrap();
        let e = read_drive(dir.path()).unwrap_err();
        assert!(
            e.to_string()
                .contains("NaN or infinite values are not allowed"),
            "{cell}: {e}"
        );
    }
}

// ------------------------------------------------------------ plausibility

#[test]
fn a_clean_drive_has_no_findings() {
    for unit in WheelUnit::ALL {
        let d = weaving(unit, 120.0);
        assert!(
            plausibility::unwrap_wheel_counters(&d).is_none(),
            "{unit:?}"
        );
        let f = plausibility::check(&d);
        assert!(f.is_empty(), "{unit:?}: {f:?}");
    }
}

#[test]
fn an_impossible_wheel_rate_names_stream_time_and_value() {
    let mut d = weaving(WheelUnit::RadS, 30.0);
    d.wheels.samples[500].rl = 1e308;
    let f = plausibility::check(&d);
    let e = f.iter().find(|f| f.is_error()).expect("an error");
    assert!(
        matches!(e, Finding::ImpossibleWheelRate { wheel: Wheel::Rl, value, samples: 1, .. } if *value == 1e308),
        "{e}"
    );
    let msg = e.to_string();
    assert!(
        msg.contains("wheels.rl") && msg.contains("t = 5 s") && msg.contains("1e308"),
        "{msg}"
    );
    // A count that jumps (one changed digit) is as impossible.
    let mut d = weaving(WheelUnit::Ticks, 30.0);
    d.wheels.samples[1000].rr += 90_000.0;
    let f = plausibility::check(&d);
    assert!(
        f.iter().any(|f| matches!(
            f,
            Finding::ImpossibleWheelRate {
                wheel: Wheel::Rr,
                ..
            }
        )),
        "{f:?}"
    );
}

#[test]
fn a_wrapping_tick_counter_is_unwrapped_and_reported() {
    let clean = weaving(WheelUnit::Ticks, 120.0);
    for bits in [16u32, 8] {
        let m = 2f64.powi(bits as i32);
        let mut d = clean.clone();
        for s in &mut d.wheels.samples {
            // Start near the top so that even a 16-bit counter wraps.
            s.rl = (s.rl + 60_000.0).rem_euclid(m);
            s.rr = (s.rr + 60_000.0).rem_euclid(m);
        }
        // Wrapped, the counter looks like an impossible jump.
        assert!(plausibility::check(&d).iter().any(Finding::is_error));
        let (fixed, findings) = plausibility::unwrap_wheel_counters(&d).expect("wraps found");
        assert_eq!(findings.len(), 2, "{findings:?}");
        assert!(
            findings.iter().all(
                |f| matches!(f, Finding::CounterWrapped { bits: b, .. } if *b == bits)
                    && f.severity() == Severity::Warning
            ),
            "{findings:?}"
        );
        assert!(findings[0].to_string().contains("unwrapped"));
        // Unwrapped = the original up to a constant per wheel.
        let (a, b) = (&fixed.wheels.samples, &clean.wheels.samples);
        let off = b[0].rl - a[0].rl;
        assert!(a
            .iter()
            .zip(b)
            .all(|(x, y)| (y.rl - x.rl - off).abs() < 1e-6));
        assert!(plausibility::check(&fixed).is_empty());
    }
}

#[test]
fn reversed_wheel_signs_are_reported() {
    let clean = weaving(WheelUnit::Ticks, 120.0);
    // Both count down while the car drives forward.
    let mut d = clean.clone();
    for s in &mut d.wheels.samples {
        (s.rl, s.rr) = (-s.rl, -s.rr);
    }
    let f = plausibility::check(&d);
    assert!(
        f.iter().any(
            |f| matches!(f, Finding::WheelsReversed { ratio, .. } if *ratio < -0.8) && f.is_error()
        ),
        "{f:?}"
    );
    // One counts down, the other up.
    let mut d = clean.clone();
    for s in &mut d.wheels.samples {
        s.rr = -s.rr;
    }
    let f = plausibility::check(&d);
    assert!(
        f.iter().any(|f| matches!(f, Finding::WheelsOpposed { .. })),
        "{f:?}"
    );
    assert!(f[0].to_string().contains("opposite directions"), "{f:?}");
    // Left and right exchanged.
    let mut d = clean;
    for s in &mut d.wheels.samples {
        (s.rl, s.rr) = (s.rr, s.rl);
    }
    let f = plausibility::check(&d);
    assert!(
        f.iter().any(|f| matches!(f, Finding::WheelsSwapped { .. })),
        "{f:?}"
    );
}

#[test]
fn a_dead_imu_is_reported_while_the_wheels_turn() {
    let mut d = weaving(WheelUnit::RadS, 120.0);
    for s in d.imu.as_mut().unwrap() {
        s.gz_rad_s = 0.0;
        s.ax_m_s2 = Some(0.0);
        s.ay_m_s2 = Some(0.0);
    }
    let f = plausibility::check(&d);
    let gz = f
        .iter()
        .find(|f| {
            matches!(
                f,
                Finding::ImuStuck {
                    field: "gz_rad_s",
                    whole_drive: true,
                    ..
                }
            )
        })
        .unwrap_or_else(|| panic!("{f:?}"));
    assert!(gz.to_string().contains("dead or stuck"), "{gz}");
    assert!(
        f.iter().any(|f| matches!(
            f,
            Finding::ImuStuck {
                field: "ay_m_s2",
                ..
            }
        )),
        "{f:?}"
    );
    // A constant gyro on a straight drive is no evidence of anything.
    let mut d = weaving(WheelUnit::RadS, 120.0);
    for s in &mut d.wheels.samples {
        s.rr = s.rl;
    }
    for s in d.imu.as_mut().unwrap() {
        s.gz_rad_s = 0.0;
    }
    let f = plausibility::check(&d);
    assert!(
        !f.iter().any(|f| matches!(
            f,
            Finding::ImuStuck {
                field: "gz_rad_s",
                ..
            }
        )),
        "{f:?}"
    );
}

#[test]
fn a_stuck_wheel_is_reported() {
    // rl stays at one count for 10 s (100 m) of a 120 s drive: a warning.
    let mut d = weaving(WheelUnit::Ticks, 120.0);
    let held = d.wheels.samples[3000].rl;
    for s in &mut d.wheels.samples[3000..4000] {
        s.rl = held;
    }
    // (unstick the rest so the counter does not jump back)
    let jump = d.wheels.samples[4000].rl - held;
    for s in &mut d.wheels.samples[4000..] {
        s.rl -= jump;
    }
    let f = plausibility::check(&d);
    let stuck = f
        .iter()
        .find(|f| {
            matches!(
                f,
                Finding::WheelStuck {
                    wheel: Wheel::Rl,
                    ..
                }
            )
        })
        .unwrap_or_else(|| panic!("{f:?}"));
    assert_eq!(stuck.severity(), Severity::Warning, "{stuck}");
    assert!(
        stuck.to_string().contains("wheels.rl") && stuck.to_string().contains("stuck"),
        "{stuck}"
    );
    // A rate wheel frozen at 30 rad/s for 60 s while the car speeds up: an error.
    let mut d = weaving(WheelUnit::RadS, 120.0);
    for (i, s) in d
        .wheels
        .samples
        .iter_mut()
        .enumerate()
        .skip(3000)
        .take(6000)
    {
        s.rl = 30.0;
        s.rr += 0.001 * (i - 3000) as f64;
    }
    let f = plausibility::check(&d);
    let stuck = f
        .iter()
        .find(|f| {
            matches!(
                f,
                Finding::WheelStuck {
                    wheel: Wheel::Rl,
                    changing_speed: true,
                    ..
                }
            )
        })
        .unwrap_or_else(|| panic!("{f:?}"));
    assert!(stuck.is_error(), "{stuck}");
}

/// Gaussian noise from a fixed seed (no rand dependency here).
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn gauss(&mut self, sigma: f64) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        sigma * (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

/// `weaving` with a 10 s standstill first and a real gyro: bias 0.005 rad/s
/// and white noise of 0.003 rad/s per sample; wheel rates with noise too.
fn stop_then_weave(secs: f64) -> Drive {
    let mut d = weaving(WheelUnit::RadS, secs);
    let mut noise = Noise(7);
    let stop = 1000;
    let n = d.wheels.samples.len();
    // Shift the motion 10 s later; the car stands before it.
    let shift = |t: f64| t + 10.0;
    for s in &mut d.wheels.samples {
        s.t_s = shift(s.t_s);
    }
    for g in d.gnss.as_mut().unwrap() {
        g.t_s = shift(g.t_s);
    }
    for s in d.imu.as_mut().unwrap() {
        s.t_s = shift(s.t_s);
    }
    let mut wheels: Vec<WheelSample> = (0..stop)
        .map(|i| WheelSample {
            t_s: i as f64 * 0.01,
            rl: 0.0,
            rr: 0.0,
            fl: None,
            fr: None,
        })
        .collect();
    wheels.append(&mut d.wheels.samples);
    for s in &mut wheels {
        s.rl += noise.gauss(0.05);
        s.rr += noise.gauss(0.05);
    }
    d.wheels.samples = wheels;
    let mut imu: Vec<ImuSample> = (0..stop)
        .map(|i| ImuSample {
            t_s: i as f64 * 0.01,
            gz_rad_s: 0.0,
            ax_m_s2: Some(0.0),
            ay_m_s2: Some(0.0),
            az_m_s2: None,
            gx_rad_s: None,
            gy_rad_s: None,
        })
        .collect();
    imu.extend(d.imu.take().unwrap());
    for s in &mut imu {
        s.gz_rad_s += 0.005 + noise.gauss(0.003);
    }
    d.imu = Some(imu);
    assert_eq!(d.wheels.samples.len(), n + stop);
    d
}

#[test]
fn a_track_width_that_contradicts_the_drive_is_reported() {
    // The car's track is TRACK; vehicle.toml says 30 % more or less.
    for (unit, base) in [
        (WheelUnit::Ticks, weaving(WheelUnit::Ticks, 120.0)),
        (WheelUnit::RadS, stop_then_weave(120.0)),
    ] {
        for factor in [1.3, 0.7] {
            let mut d = base.clone();
            d.vehicle.track_width_m = TRACK * factor;
            let f = plausibility::check(&d);
            let Some(found) = f
                .iter()
                .find(|f| matches!(f, Finding::TrackWidthContradicted { .. }))
            else {
                panic!("{unit:?} x{factor}: {f:?}")
            };
            let Finding::TrackWidthContradicted {
                nominal_m,
                effective_m,
                sigma_m,
                ..
            } = found
            else {
                unreachable!()
            };
            assert_eq!(*nominal_m, TRACK * factor);
            assert!(
                (effective_m / TRACK - 1.0).abs() < 0.03 && *sigma_m < 0.05,
                "{unit:?} x{factor}: {found}"
            );
            assert_eq!(found.severity(), Severity::Warning);
            let msg = found.to_string();
            assert!(
                msg.contains(&format!(
                    "vehicle.toml's track_width_m = {} m contradicts the drive: the wheels and the gyro agree on 1.",
                    TRACK * factor
                )) && msg.contains(" ± "),
                "{msg}"
            );
            // Nothing else is wrong with the drive.
            assert_eq!(f.len(), 1, "{f:?}");
        }
        // The right track: no finding; 5 % off (tyre scrub): none either.
        for factor in [1.0, 1.05, 0.95] {
            let mut d = base.clone();
            d.vehicle.track_width_m = TRACK * factor;
            let f = plausibility::check(&d);
            assert!(f.is_empty(), "{unit:?} x{factor}: {f:?}");
        }
    }
}

#[test]
fn a_straight_drive_or_no_gyro_says_nothing_about_the_track() {
    let mut d = weaving(WheelUnit::RadS, 120.0);
    d.vehicle.track_width_m = TRACK * 1.3;
    d.imu = None;
    assert!(plausibility::check(&d).is_empty());
    // Straight: the gyro shows no turn above its noise.
    let mut d = weaving(WheelUnit::RadS, 120.0);
    d.vehicle.track_width_m = TRACK * 1.3;
    for s in &mut d.wheels.samples {
        s.rr = s.rl;
    }
    for s in d.imu.as_mut().unwrap() {
        s.gz_rad_s = 1e-3 * (37.0 * s.t_s).sin();
    }
    let f = plausibility::check(&d);
    assert!(f.is_empty(), "{f:?}");
}

#[test]
fn a_ten_minute_pause_is_reported_with_time_and_length() {
    let mut d = weaving(WheelUnit::Ticks, 120.0);
    let later = |t: &mut f64| {
        if *t >= 60.0 {
            *t += 600.0;
        }
    };
    d.wheels.samples.iter_mut().for_each(|s| later(&mut s.t_s));
    d.gnss
        .as_mut()
        .unwrap()
        .iter_mut()
        .for_each(|s| later(&mut s.t_s));
    d.imu
        .as_mut()
        .unwrap()
        .iter_mut()
        .for_each(|s| later(&mut s.t_s));
    let f = plausibility::check(&d);
    assert_eq!(f.len(), 1, "{f:?}");
    let Finding::WheelPause {
        t_s,
        duration_s,
        median_interval_s,
    } = f[0]
    else {
        panic!("{f:?}")
    };
    assert!((t_s - 59.99).abs() < 1e-6 && (duration_s - 600.01).abs() < 1e-6);
    assert!((median_interval_s - 0.01).abs() < 1e-9);
    assert_eq!(f[0].severity(), Severity::Warning);
    let msg = f[0].to_string();
    assert!(
        msg.contains("pauses for 600.0 s at t = 59.99") && msg.contains("1.000e-2 s"),
        "{msg}"
    );
    // A 2 s hole (200 intervals, but shorter than 5 s) is no pause.
    let mut d = weaving(WheelUnit::Ticks, 120.0);
    d.wheels.samples.retain(|s| !(50.0..52.0).contains(&s.t_s));
    assert!(plausibility::check(&d).is_empty());
}

/// The 21-byte recording the fuzzer found: a header whose profile string
/// declares 4 GiB. It is refused naming the field, without asking for the
/// memory (the `mcap` crate reserves a declared length before reading it).
#[test]
fn a_length_prefix_beyond_its_record_is_refused_without_allocating_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("tiny.mcap");
    let mut bytes = b"\x89MCAP0\r\n".to_vec();
    bytes.push(0x01);
    bytes.extend_from_slice(&4u64.to_le_bytes());
    bytes.extend_from_slice(&[0xFF; 4]);
    assert_eq!(bytes.len(), 21);
    std::fs::write(&path, &bytes).expect("write");
    let e = drive_io::read_drive(&path)
        .expect_err("refused")
        .to_string();
    assert!(e.contains("header profile"), "{e}");
}

/// The revolutions the drive's rear-left wheel covers (cumulative counts in
/// revolutions from the first to the last sample).
fn rl_revolutions(d: &Drive) -> f64 {
    let revs = d.wheel_revolutions().unwrap();
    revs.last().unwrap().rl - revs.first().unwrap().rl
}

#[test]
fn a_counter_spike_is_set_aside_and_a_counter_jump_re_referenced() {
    let clean = weaving(WheelUnit::Ticks, 60.0);
    let total = rl_revolutions(&clean);
    // A spike: two samples far off, then the counter is back.
    let mut spiked = clean.clone();
    spiked.wheels.samples[1000].rl = -7.6e16;
    spiked.wheels.samples[1001].rl = 4e9;
    let (fixed, f) = plausibility::set_aside_impossible(&spiked).expect("found");
    assert_eq!(fixed.wheels.samples.len(), clean.wheels.samples.len() - 2);
    assert!(
        matches!(
            f.as_slice(),
            [Finding::WheelSamplesSetAside {
                wheel: Wheel::Rl,
                set_aside: 2,
                jumps: 0,
                ..
            }]
        ),
        "{f:?}"
    );
    assert_eq!(f[0].severity(), Severity::Warning);
    assert!((rl_revolutions(&fixed) - total).abs() < 1e-9);
    assert!(
        plausibility::check(&fixed).is_empty(),
        "{:?}",
        plausibility::check(&fixed)
    );
    // A jump that stays: the counter continues from its last good value;
    // one sample interval's distance is estimated (within a count).
    let mut jumped = clean.clone();
    for s in &mut jumped.wheels.samples[3000..] {
        s.rl += 1e7;
    }
    let (fixed, f) = plausibility::set_aside_impossible(&jumped).expect("found");
    assert!(
        matches!(
            f.as_slice(),
            [Finding::WheelSamplesSetAside {
                set_aside: 0,
                jumps: 1,
                ..
            }]
        ),
        "{f:?}"
    );
    assert!(
        (rl_revolutions(&fixed) - total).abs() <= 1.5 / TPR,
        "{} against {total}",
        rl_revolutions(&fixed)
    );
    assert!(plausibility::check(&fixed).is_empty());
}

#[test]
fn a_front_glitch_empties_its_cells_and_a_1e308_jump_leaves_a_stuck_wheel() {
    let mut d = weaving(WheelUnit::RadS, 60.0);
    d.wheels.units.fl = Some(WheelUnit::RadS);
    for s in &mut d.wheels.samples {
        s.fl = Some(s.rl);
    }
    d.wheels.samples[2000].fl = Some(-7.6e16);
    let (fixed, f) = plausibility::set_aside_impossible(&d).expect("found");
    assert_eq!(
        fixed.wheels.samples.len(),
        d.wheels.samples.len(),
        "rear rows kept"
    );
    assert_eq!(fixed.wheels.samples[2000].fl, None);
    assert!(
        f[0].to_string().contains("does not read this channel"),
        "{}",
        f[0]
    );
    // A counter that jumps to 1e308 and stays loses its later increments in
    // floating point: what is left shows the wheel standing still.
    let mut d = weaving(WheelUnit::Ticks, 60.0);
    for s in &mut d.wheels.samples[3000..] {
        s.rl += 1e308;
    }
    let all = plausibility::findings(&d);
    assert!(
        all.iter().any(|f| matches!(
            f,
            Finding::WheelStuck {
                wheel: Wheel::Rl,
                major: true,
                ..
            }
        ) && f.is_error()),
        "{all:?}"
    );
}

#[test]
fn the_gyro_tells_mirrored_wheels_from_a_mirrored_gnss_track() {
    let clean = weaving(WheelUnit::RadS, 120.0);
    assert!(plausibility::check(&clean).is_empty());
    // The GNSS track mirrored (north negated, as exchanged lat/lon do up to
    // a rotation): the gyro and the wheels agree, the course does not.
    let mut mirrored = clean.clone();
    for f in mirrored.gnss.as_mut().unwrap() {
        f.y_m = -f.y_m;
    }
    let f = plausibility::check(&mirrored);
    assert!(
        matches!(f.as_slice(), [Finding::GnssMirrored { ratio, .. }] if *ratio < -0.8),
        "{f:?}"
    );
    assert!(
        f[0].is_error() && f[0].to_string().contains("x_m and y_m"),
        "{}",
        f[0]
    );
    // Without a gyro the drive cannot tell the two apart, and says so.
    mirrored.imu = None;
    let f = plausibility::check(&mirrored);
    assert!(
        matches!(
            f.as_slice(),
            [Finding::WheelsSwapped {
                against: "the GNSS course",
                ..
            }]
        ),
        "{f:?}"
    );
    assert!(
        f[0].to_string().contains("or the GNSS track is mirrored"),
        "{}",
        f[0]
    );
    // Reversed wheels with a gyro and no GNSS at all: the gyro names them.
    let mut reversed = clean;
    reversed.gnss = None;
    for s in &mut reversed.wheels.samples {
        (s.rl, s.rr) = (-s.rl, -s.rr);
    }
    let f = plausibility::check(&reversed);
    assert!(
        f.iter().any(|f| matches!(
            f,
            Finding::WheelsReversed {
                against: "the gyro",
                ..
            }
        )),
        "{f:?}"
    );
}

#[test]
fn a_utf16_file_and_a_cut_last_line_are_named_as_such() {
    let dir = minimal_folder();
    let wheels = dir.path().join("wheels.csv");
    // UTF-16BE with its byte-order mark: valid UTF-8 bytes, meaningless.
    let text = "t_s,rl_rev,rr_rev\n0,0,0\n0.1,1,1\n";
    let mut bytes = vec![0xfe, 0xff];
    for u in text.encode_utf16() {
        bytes.extend(u.to_be_bytes());
    }
    std::fs::write(&wheels, &bytes).unwrap();
    let e = read_drive(dir.path()).unwrap_err().to_string();
    assert!(e.contains("wheels.csv") && e.contains("UTF-16BE"), "{e}");
    // The same without the mark.
    std::fs::write(&wheels, &bytes[2..]).unwrap();
    let e = read_drive(dir.path()).unwrap_err().to_string();
    assert!(e.contains("UTF-16BE"), "{e}");
    // A last line without its line end (a file cut while written).
    std::fs::write(&wheels, "t_s,rl_rev,rr_rev\n0,0,0\n0.1,1,1\n0.2,2,1").unwrap();
    let loaded = read_drive(dir.path()).unwrap();
    assert!(
        loaded
            .warnings
            .iter()
            .any(|w| w.contains("wheels.csv") && w.contains("line 4") && w.contains("no line end")),
        "{:?}",
        loaded.warnings
    );
}

#[test]
fn info_flags_a_vehicle_no_car_has_and_measures_the_wheels_as_read() {
    let mut d = weaving(WheelUnit::RadS, 60.0);
    d.vehicle.track_width_m = -1.5;
    let summary = drive_io::summarize(&d);
    assert!(
        summary
            .findings
            .iter()
            .any(|f| f.severity == Severity::Error && f.message.contains("track_width_m = -1.5")),
        "{:?}",
        summary.findings
    );
    // A glitch does not become a distance.
    let mut d = weaving(WheelUnit::RadS, 60.0);
    let clean = drive_io::summarize(&d).distance_wheels_m.unwrap();
    d.wheels.samples[3000].rl = -7.6e16;
    let glitched = drive_io::summarize(&d).distance_wheels_m.unwrap();
    assert!(
        (glitched - clean).abs() < 1e-3 * clean,
        "{glitched} against {clean}"
    );
}

//! The main job: the whole process graph on a built-in drive.
//!
//! [`run`] simulates the default drive ([`default_drive`]: the `mixed` loop,
//! wheels miscalibrated like the paper's 2.2 m guess, a long GNSS outage cut
//! into its second half), starts `calibrator serve` and `odometry serve` as
//! child processes (the binaries beside this one), publishes the drive like
//! `sensor-bridge replay` at a multiple of real time, and shows live what
//! happens: the children's logs, the odometry's mode switches and the estimate
//! it uses, and its error against the simulator's truth. At the end it prints
//! the dead-reckoning error at the end of the outage with the nominal and the
//! calibrated circumferences ([`outage_report`], the odometry's own
//! dead-reckoning code) and writes a picture of the tracks ([`tracks_svg`]).
//!
//! Ctrl-C reaches every process of the terminal's process group: each stops
//! cleanly, and the demo waits for its children before it exits.

pub mod report;
pub mod svg;

use anyhow::{bail, Context, Result};
use iceoryx2::prelude::CallbackProgression;
use interfaces::bus::{self, Bus, BusSettings};
use interfaces::drive::Drive;
use interfaces::wire::{CircumferenceEstimate, Pose, PoseMode};
use sensor_bridge::replay::{replay, to_wire, Pacing, ReplayOptions};
use simulator::{simulate, Scenario, SimConfig};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Options of the demo.
#[derive(Debug, Clone, PartialEq)]
pub struct DemoOptions {
    /// Where the drive, the estimate, the result and the picture go.
    pub out_dir: PathBuf,
    /// Replay speed, times real time.
    pub speed: f64,
    /// Simulator seed.
    pub seed: u64,
    /// Length of the GNSS outage cut into the second half, s.
    pub outage_s: f64,
    /// The nominal (miscalibrated) circumference in vehicle.toml, m.
    pub nominal_circumference_m: f64,
    /// Keep the calibrator's state file from an earlier run (default: start fresh).
    pub keep_state: bool,
    /// Directory of the `calibrator` and `odometry` binaries.
    pub bin_dir: PathBuf,
}

/// The default drive and its long GNSS outage `(start, end)`, s.
///
/// The `mixed` loop (city, highway, a short tunnel) of the simulator, with
/// `vehicle.toml` saying `nominal` for every wheel (the true ones are about
/// 2.04 m); every GNSS fix from 60 % of the drive on, for `outage_s`, removed
/// (it ends at least 20 s before the drive does).
pub fn default_drive(seed: u64, nominal: f64, outage_s: f64) -> Result<(Drive, (f64, f64))> {
    let mut config = SimConfig::new(Scenario::Mixed, seed);
    config.nominal_circumference_m = Some(nominal);
    let mut drive = simulate(&config).context("simulating the default drive")?;
    let (t0, t1) = match (drive.wheels.samples.first(), drive.wheels.samples.last()) {
        (Some(a), Some(b)) => (a.t_s, b.t_s),
        _ => bail!("the simulated drive has no wheel samples"),
    };
    let start = t0 + 0.6 * (t1 - t0);
    let end = (start + outage_s).min(t1 - 20.0);
    if end <= start + 5.0 {
        bail!(
            "the drive ({:.0} s) is too short for a {outage_s} s outage",
            t1 - t0
        );
    }
    if let Some(g) = drive.gnss.as_mut() {
        g.retain(|f| f.t_s < start || f.t_s > end);
    }
    Ok((drive, (start, end)))
}

/// A child process whose stderr is shown with a prefix; killed and reaped on drop.
struct ChildProc {
    label: &'static str,
    child: Option<Child>,
}

impl ChildProc {
    fn spawn(
        label: &'static str,
        exe: &Path,
        args: &[String],
        settings: &BusSettings,
    ) -> Result<ChildProc> {
        let mut cmd = Command::new(exe);
        cmd.args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        if std::env::var_os("RUST_LOG").is_none() {
            cmd.env("RUST_LOG", "info");
        }
        for (k, v) in settings.env() {
            cmd.env(k, v);
        }
        let mut child = cmd
            .spawn()
            .with_context(|| format!("starting {}", exe.display()))?;
        for stream in [
            child
                .stdout
                .take()
                .map(|s| Box::new(s) as Box<dyn std::io::Read + Send>),
            child
                .stderr
                .take()
                .map(|s| Box::new(s) as Box<dyn std::io::Read + Send>),
        ]
        .into_iter()
        .flatten()
        {
            std::thread::spawn(move || {
                for line in BufReader::new(stream).lines() {
                    let Ok(line) = line else { break };
                    eprintln!("[{label:<10}] {line}");
                }
            });
        }
        Ok(ChildProc {
            label,
            child: Some(child),
        })
    }

    /// SIGTERM, then wait up to `grace`, then SIGKILL; returns whether it exited cleanly.
    fn stop(&mut self, grace: Duration) -> bool {
        let Some(mut child) = self.child.take() else {
            return true;
        };
        if let Ok(Some(status)) = child.try_wait() {
            return status.success();
        }
        let _ = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status();
        let start = Instant::now();
        while start.elapsed() < grace {
            if let Ok(Some(status)) = child.try_wait() {
                return status.success();
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        eprintln!(
            "[demo      ] {} did not stop within {grace:?}: killing it",
            self.label
        );
        let _ = child.kill();
        let _ = child.wait();
        false
    }
}

impl Drop for ChildProc {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// What the viewer saw.
#[derive(Debug, Default)]
struct Seen {
    poses: Vec<Pose>,
    estimates: Vec<CircumferenceEstimate>,
}

/// Subscribe to poses and estimates and show the changes live until `stop`.
fn viewer(
    settings: BusSettings,
    drive: Arc<Drive>,
    stop: Arc<AtomicBool>,
    last_pose_t: Arc<AtomicI64>,
    ready: std::sync::mpsc::Sender<()>,
) -> Result<Seen> {
    let bus = Bus::open(&settings, "demo-viewer")?;
    let poses = bus.subscriber::<Pose>()?;
    let estimates = bus.subscriber::<CircumferenceEstimate>()?;
    let waitset = bus.waitset()?;
    let _g1 = bus::wake_on(&waitset, "attach poses", poses.listener())?;
    let _g2 = bus::wake_on(&waitset, "attach estimates", estimates.listener())?;
    let _tick = bus::tick_every(&waitset, Duration::from_millis(100))?;
    let _ = ready.send(());
    let truth = drive.truth.clone().unwrap_or_default();
    let mut seen = Seen::default();
    let mut last_mode: Option<u8> = None;
    let mut last_version: Option<u64> = None;
    let mut next_status_s = f64::NEG_INFINITY;
    loop {
        let result = bus::wait_once(&waitset, None, |_| CallbackProgression::Continue)?;
        poses.take_events()?;
        estimates.take_events()?;
        while let Some(e) = estimates.receive()? {
            seen.estimates.push(e);
        }
        while let Some(p) = poses.receive()? {
            let t = p.header.t_s();
            if last_mode != Some(p.mode) {
                let name = |m: Option<u8>| {
                    m.and_then(PoseMode::from_code)
                        .map_or("-".to_string(), |m| format!("{m:?}"))
                };
                eprintln!(
                    "[demo      ] t = {t:7.1} s  odometry mode {} -> {}",
                    name(last_mode),
                    name(Some(p.mode))
                );
                last_mode = Some(p.mode);
            }
            if last_version != Some(p.estimate_version) {
                eprintln!(
                    "[demo      ] t = {t:7.1} s  odometry poses now use estimate v{}",
                    p.estimate_version
                );
                last_version = Some(p.estimate_version);
            }
            if t >= next_status_s {
                next_status_s = t + 30.0;
                let err = report::truth_at(&truth, t)
                    .map(|(x, y)| format!("{:.2} m", (p.x_m - x).hypot(p.y_m - y)))
                    .unwrap_or_else(|| "-".to_string());
                eprintln!(
                    "[demo      ] t = {t:7.1} s  pose x = {:8.1} m, y = {:8.1} m, {:?}, error vs truth {err}",
                    p.x_m,
                    p.y_m,
                    PoseMode::from_code(p.mode).unwrap_or(PoseMode::NoFix)
                );
            }
            last_pose_t.store(p.header.t_ns, Ordering::SeqCst);
            seen.poses.push(p);
        }
        if bus::stop_requested_by(result) || stop.load(Ordering::SeqCst) {
            break;
        }
    }
    Ok(seen)
}

/// Run the demo (see the module doc).
pub fn run(opts: &DemoOptions) -> Result<()> {
    if !(opts.speed.is_finite() && opts.speed > 0.0) {
        bail!("--speed {} is not a positive number", opts.speed);
    }
    let calibrator_exe = opts.bin_dir.join("calibrator");
    let odometry_exe = opts.bin_dir.join("odometry");
    for exe in [&calibrator_exe, &odometry_exe] {
        if !exe.is_file() {
            bail!(
                "{} not found: build the workspace first (cargo build --release --workspace)",
                exe.display()
            );
        }
    }
    std::fs::create_dir_all(&opts.out_dir)
        .with_context(|| format!("creating {}", opts.out_dir.display()))?;
    let drive_dir = opts.out_dir.join("drive");
    let state = opts.out_dir.join("estimate.json");
    if !opts.keep_state {
        let _ = std::fs::remove_file(&state);
    }

    eprintln!(
        "[demo      ] simulating the default drive (mixed loop, seed {}, nominal circumference {} m)",
        opts.seed, opts.nominal_circumference_m
    );
    let (drive, outage) = default_drive(opts.seed, opts.nominal_circumference_m, opts.outage_s)?;
    drive_io::write_drive(&drive, &drive_dir)
        .with_context(|| format!("writing {}", drive_dir.display()))?;
    if let Some(t) = &drive.truth_params {
        eprintln!(
            "[demo      ] true rear circumferences {:.4} / {:.4} m; GNSS outage {:.0}..{:.0} s ({:.0} s); \
             replay at {}x real time ({:.0} s)",
            t.circumference_m.rl,
            t.circumference_m.rr,
            outage.0,
            outage.1,
            outage.1 - outage.0,
            opts.speed,
            drive.wheel_duration_s() / opts.speed
        );
    }
    let wire = to_wire(&drive)?;

    // A graph of our own: it never meets another one on this machine.
    let settings = BusSettings {
        prefix: Some(format!("wcdemo_{}_", std::process::id())),
        root: Some(std::env::temp_dir().join(format!("wheelcal-demo-{}", std::process::id()))),
        stall_timeout: None,
        pose_budget: None,
        live_budget: None,
    };
    let bus = Bus::open(&settings, "demo-bridge")?;
    let drive = Arc::new(drive);
    let stop = Arc::new(AtomicBool::new(false));
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let last_pose_t = Arc::new(AtomicI64::new(i64::MIN));
    let viewer_handle = {
        let (s, d, st, lp) = (
            settings.clone(),
            drive.clone(),
            stop.clone(),
            last_pose_t.clone(),
        );
        std::thread::spawn(move || viewer(s, d, st, lp, ready_tx))
    };
    let _ = ready_rx.recv_timeout(Duration::from_secs(10));

    let vehicle = drive_dir.join("vehicle.toml").display().to_string();
    let mut calibrator = ChildProc::spawn(
        "calibrator",
        &calibrator_exe,
        &[
            "serve".to_string(),
            "--vehicle".to_string(),
            vehicle.clone(),
            "--state".to_string(),
            state.display().to_string(),
        ],
        &settings,
    )?;
    let mut odometry = ChildProc::spawn(
        "odometry",
        &odometry_exe,
        &[
            "serve".to_string(),
            "--vehicle".to_string(),
            vehicle.clone(),
        ],
        &settings,
    )?;

    let replay_opts = ReplayOptions {
        pacing: Pacing::Speed(opts.speed),
        wait_subscribers: 2,
        wait_timeout: Some(Duration::from_secs(30)),
        settle: Duration::from_millis(300),
        linger: Duration::from_millis(500),
        progress_every_s: 60.0,
        ..ReplayOptions::default()
    };
    let stats = replay(&bus, &wire, &replay_opts);
    let interrupted =
        bus::shutdown_requested() || stats.as_ref().map(|s| s.interrupted).unwrap_or(false);

    // Let the odometry publish the pose of the last wheel sample (unless interrupted).
    let last_wheel_t = wire.wheels.last().map_or(0, |w| w.header.t_ns);
    let waited = Instant::now();
    while !interrupted
        && last_pose_t.load(Ordering::SeqCst) < last_wheel_t
        && waited.elapsed() < Duration::from_secs(5)
        && !bus::shutdown_requested()
    {
        std::thread::sleep(Duration::from_millis(20));
    }
    let calibrator_ok = calibrator.stop(Duration::from_secs(10));
    let odometry_ok = odometry.stop(Duration::from_secs(10));
    stop.store(true, Ordering::SeqCst);
    let seen = viewer_handle
        .join()
        .map_err(|_| anyhow::anyhow!("the viewer thread panicked"))??;
    drop(bus);
    settings.remove_leftovers();
    let stats = stats.context("publishing the drive")?;
    if interrupted {
        eprintln!(
            "[demo      ] interrupted after {} samples; every process stopped (calibrator {}, odometry {})",
            stats.total(),
            if calibrator_ok { "cleanly" } else { "killed" },
            if odometry_ok { "cleanly" } else { "killed" }
        );
        return Ok(());
    }
    let result = report::outage_report(&drive, outage, &seen.poses, &seen.estimates)?;
    println!("{}", result.render());
    let json = opts.out_dir.join("demo-result.json");
    std::fs::write(&json, serde_json::to_string_pretty(&result)? + "\n")
        .with_context(|| format!("writing {}", json.display()))?;
    let picture = opts.out_dir.join("tracks.svg");
    let svg = svg::tracks_svg(&drive, outage, &seen.poses, &result)?;
    std::fs::write(&picture, svg).with_context(|| format!("writing {}", picture.display()))?;
    println!("picture of the tracks: {}", picture.display());
    println!("numbers: {}", json.display());
    Ok(())
}

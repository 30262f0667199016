//! A process graph for integration tests: real binaries, started as child
//! processes in their own iceoryx2 prefix and root path.
//!
//! [`Graph`] owns every child; dropping it (also while a failing test
//! unwinds) kills and reaps them all, prints their logs when the test failed,
//! and removes the graph's shared-memory leftovers. Waiting uses generous
//! watchdogs ([`WATCHDOG`]) that turn a hang into a failure; no test asserts a
//! maximum runtime.
//!
//! Binaries are taken from the target directory of the test executable
//! (`target/<profile>/`). `cargo test --workspace` does not build the binaries
//! of packages without integration tests, so [`bin`] runs `cargo build` for
//! them once per test process (a no-op when they are fresh) when the test
//! runs under cargo.

use interfaces::bus::{Bus, BusSettings, Topic, TopicSubscriber};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Longest wait for anything in a graph test; reaching it is a failure.
pub const WATCHDOG: Duration = Duration::from_secs(120);

/// The workspace binaries a graph is made of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bin {
    /// `sensor-bridge`.
    SensorBridge,
    /// `calibrator`.
    Calibrator,
    /// `odometry`.
    Odometry,
    /// `gateway` (Zenoh between hosts).
    Gateway,
}

impl Bin {
    /// Binary (and package) name.
    pub fn name(self) -> &'static str {
        match self {
            Bin::SensorBridge => "sensor-bridge",
            Bin::Calibrator => "calibrator",
            Bin::Odometry => "odometry",
            Bin::Gateway => "gateway",
        }
    }
}

/// `target/<profile>/` of the running test executable.
pub fn target_profile_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("the test executable has a path");
    // target/<profile>/deps/<test>-<hash>
    let deps = exe.parent().expect("deps dir");
    deps.parent().expect("profile dir").to_path_buf()
}

/// The cargo profile the running executable was built with: target/debug
/// holds the dev profile's builds, any other folder is named after its
/// profile (release, or deploy for `cargo bench --profile deploy`).
fn profile_name() -> String {
    match target_profile_dir().file_name().and_then(|n| n.to_str()) {
        Some("debug") | None => "dev".to_string(),
        Some(profile) => profile.to_string(),
    }
}

fn build_all_once() {
    static BUILT: OnceLock<()> = OnceLock::new();
    BUILT.get_or_init(|| {
        let Ok(cargo) = std::env::var("CARGO") else {
            return; // not run by cargo: use what is there
        };
        let profile_dir = target_profile_dir();
        let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("../Cargo.toml");
        let mut cmd = Command::new(cargo);
        cmd.args(["build", "-q", "--manifest-path"]).arg(manifest);
        // The binaries of the same profile as this executable.
        cmd.args(["--profile", &profile_name()]);
        for b in [
            Bin::SensorBridge,
            Bin::Calibrator,
            Bin::Odometry,
            Bin::Gateway,
        ] {
            cmd.args(["--bin", b.name()]);
        }
        // The same target directory as the test executable.
        if let Some(target) = profile_dir.parent() {
            cmd.env("CARGO_TARGET_DIR", target);
        }
        let status = cmd
            .status()
            .expect("run cargo build for the graph binaries");
        assert!(
            status.success(),
            "cargo build of the graph binaries failed: {status}"
        );
    });
}

/// Path of a workspace binary (built first when running under cargo).
pub fn bin(b: Bin) -> PathBuf {
    build_all_once();
    let path = target_profile_dir().join(b.name());
    assert!(
        path.is_file(),
        "{} not found: build the workspace binaries with this executable's profile first \
         (cargo build --workspace --profile {})",
        path.display(),
        profile_name()
    );
    path
}

/// One child process of a graph.
#[derive(Debug)]
struct Proc {
    label: String,
    child: Option<Child>,
    log: PathBuf,
    status: Option<ExitStatus>,
}

/// Handle of a child in a [`Graph`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProcId(usize);

/// A graph of child processes sharing one isolated iceoryx2 prefix and root.
#[derive(Debug)]
pub struct Graph {
    /// The iceoryx2 settings every child gets.
    pub settings: BusSettings,
    /// Scratch directory (logs, state files, drives); removed at the end.
    pub dir: tempfile::TempDir,
    procs: Vec<Proc>,
}

impl Graph {
    /// A new, empty graph; `tag` names it in the prefix.
    pub fn new(tag: &str) -> Graph {
        interfaces::logging::init();
        let dir = tempfile::tempdir().expect("tempdir");
        let settings = BusSettings::isolated(tag, dir.path());
        Graph {
            settings,
            dir,
            procs: Vec::new(),
        }
    }

    /// A path in the scratch directory.
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// A node for the test itself in this graph.
    pub fn bus(&self, name: &str) -> Bus {
        Bus::open(&self.settings, name).expect("test node")
    }

    /// Start `b` with `args`; its stdout and stderr go to a log file.
    pub fn spawn(&mut self, label: &str, b: Bin, args: &[&str]) -> ProcId {
        self.spawn_exe(label, &bin(b), args)
    }

    /// Start any executable in the graph (e.g. a benchmark re-running itself).
    pub fn spawn_exe(&mut self, label: &str, exe: &Path, args: &[&str]) -> ProcId {
        let log = self.path(&format!("{label}-{}.log", self.procs.len()));
        let out = std::fs::File::create(&log).expect("log file");
        let err = out.try_clone().expect("log file");
        let mut cmd = Command::new(exe);
        cmd.args(args)
            .stdin(Stdio::null())
            .stdout(out)
            .stderr(err)
            .current_dir(self.dir.path())
            .env("RUST_LOG", "info")
            .env_remove("WHEELCAL_IOX_PREFIX")
            .env_remove("WHEELCAL_IOX_ROOT");
        for (k, v) in self.settings.env() {
            cmd.env(k, v);
        }
        let child = cmd
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {}: {e}", exe.display()));
        self.procs.push(Proc {
            label: label.to_string(),
            child: Some(child),
            log,
            status: None,
        });
        ProcId(self.procs.len() - 1)
    }

    /// The log of a child so far.
    pub fn log(&self, id: ProcId) -> String {
        std::fs::read_to_string(&self.procs[id.0].log).unwrap_or_default()
    }

    /// Process id of a running child.
    pub fn pid(&self, id: ProcId) -> u32 {
        self.procs[id.0]
            .child
            .as_ref()
            .map(|c| c.id())
            .expect("child running")
    }

    /// True while the child runs.
    pub fn is_running(&mut self, id: ProcId) -> bool {
        let p = &mut self.procs[id.0];
        match p.child.as_mut() {
            None => false,
            Some(c) => match c.try_wait() {
                Ok(Some(status)) => {
                    p.status = Some(status);
                    p.child = None;
                    false
                }
                _ => true,
            },
        }
    }

    /// Send SIGTERM (a clean stop request).
    pub fn terminate(&mut self, id: ProcId) {
        if self.is_running(id) {
            let pid = self.pid(id).to_string();
            let _ = Command::new("kill").args(["-TERM", &pid]).status();
        }
    }

    /// SIGKILL and reap (no cleanup in the child: it leaves its iceoryx2 resources behind).
    pub fn kill(&mut self, id: ProcId) -> Option<ExitStatus> {
        let p = &mut self.procs[id.0];
        if let Some(mut c) = p.child.take() {
            let _ = c.kill();
            p.status = c.wait().ok();
        }
        p.status
    }

    /// Wait (watchdog) for the child to exit; returns its status.
    pub fn wait_exit(&mut self, id: ProcId) -> ExitStatus {
        let start = Instant::now();
        while self.is_running(id) {
            assert!(
                start.elapsed() < WATCHDOG,
                "watchdog: {} did not exit\n{}",
                self.procs[id.0].label,
                self.log(id)
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        self.procs[id.0].status.expect("exit status")
    }

    /// [`Graph::wait_exit`], calling `between` every millisecond meanwhile
    /// (to drain subscribers, so that a lossless publisher never waits on the test).
    pub fn wait_exit_with(&mut self, id: ProcId, mut between: impl FnMut()) -> ExitStatus {
        let start = Instant::now();
        while self.is_running(id) {
            assert!(
                start.elapsed() < WATCHDOG,
                "watchdog: {} did not exit\n{}",
                self.procs[id.0].label,
                self.log(id)
            );
            between();
            std::thread::sleep(Duration::from_millis(1));
        }
        between();
        self.procs[id.0].status.expect("exit status")
    }

    /// Wait (watchdog) until `needle` appears in the child's log; returns the log.
    pub fn wait_log(&mut self, id: ProcId, needle: &str) -> String {
        let start = Instant::now();
        loop {
            let log = self.log(id);
            if log.contains(needle) {
                return log;
            }
            let running = self.is_running(id);
            assert!(
                running || self.log(id).contains(needle),
                "{} exited without logging {needle:?}:\n{log}",
                self.procs[id.0].label
            );
            assert!(
                start.elapsed() < WATCHDOG,
                "watchdog: {} never logged {needle:?}:\n{log}",
                self.procs[id.0].label
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn dump_logs(&self) {
        for (i, p) in self.procs.iter().enumerate() {
            eprintln!("----- {} log -----\n{}", p.label, self.log(ProcId(i)));
        }
    }
}

impl Drop for Graph {
    fn drop(&mut self) {
        for p in &mut self.procs {
            if let Some(mut c) = p.child.take() {
                let _ = c.kill();
                let _ = c.wait();
            }
        }
        if std::thread::panicking() {
            self.dump_logs();
        }
        self.settings.remove_leftovers();
    }
}

/// Wait (watchdog) until `cond` holds, polling every 10 ms; `what` names it in the failure.
pub fn wait_until(what: &str, mut cond: impl FnMut() -> bool) {
    let start = Instant::now();
    while !cond() {
        assert!(
            start.elapsed() < WATCHDOG,
            "watchdog: waited in vain for {what}"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// A Zenoh TCP endpoint on loopback with a port free right now (the OS
/// picks it), for a gateway to listen on.
pub fn free_tcp_endpoint() -> String {
    let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind a loopback port");
    let port = l.local_addr().expect("local address").port();
    format!("tcp/127.0.0.1:{port}")
}

/// Write a `calibrator serve` state file holding estimate `version`, as the
/// service writes it (pretty JSON, the antenna fields left out when absent).
/// The circumferences are those of the simulator's `Paper` car, which the
/// graph tests drive (unworn 2.19 m, rear wear 2.2 / 1.8 mm of radius): the
/// odometry drops an estimate the fixes contradict, as one 7 % off would be.
pub fn seeded_calibrator_state(path: &Path, version: u64) {
    let state = serde_json::json!({
        "version": version,
        "t_s": 100.0,
        "circumference_m": { "rl": 2.1762, "rr": 2.1787 },
        "sigma_m": { "rl": 0.001, "rr": 0.001 },
        "track_width_m": 1.58,
        "gyro_bias_rad_s": 0.0,
        "gyro_scale": 0.0,
        "side_slip_gain_rad_per_m_s2": null,
        "quality_m": 1.0
    });
    let text = serde_json::to_string_pretty(&state).expect("state json");
    std::fs::write(path, text + "\n").expect("state file");
}

/// Receive everything waiting on `sub` into `out`; returns how many.
pub fn drain<T: Topic>(sub: &TopicSubscriber<T>, out: &mut Vec<T>) -> usize {
    let _ = sub.take_events();
    let mut n = 0;
    while let Some(s) = sub.receive().expect("receive") {
        out.push(s);
        n += 1;
    }
    n
}

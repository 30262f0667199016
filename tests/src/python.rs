//! Python for the example subscribers' tests.
//!
//! Python is looked for in `WHEELCAL_PYTHON`, then
//! `target/python-venv/bin/python`, then `python3`. When none of them can
//! import the module but `python3` exists, the venv `target/python-venv` is
//! made and the package installed from PyPI into it (once; set
//! `WHEELCAL_PYTHON_NO_INSTALL=1` to forbid that). The error says why no
//! Python could be had, for the test to print when it skips.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// A Python that can `import module`, installing `pip_spec` (e.g.
/// `iceoryx2==0.10.0`) into `target/python-venv` when needed.
pub fn python_with(module: &str, pip_spec: &str) -> Result<PathBuf, String> {
    let workspace = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut candidates: Vec<PathBuf> = Vec::new();
    if let Ok(p) = std::env::var("WHEELCAL_PYTHON") {
        candidates.push(PathBuf::from(p));
    }
    candidates.push(workspace.join("target/python-venv/bin/python"));
    candidates.push(PathBuf::from("python3"));
    let import = format!("import {module}");
    let mut reasons = Vec::new();
    for c in candidates {
        match Command::new(&c)
            .args(["-c", &import])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
        {
            Ok(s) if s.success() => return Ok(c),
            Ok(_) => reasons.push(format!("{}: cannot import {module}", c.display())),
            Err(e) => reasons.push(format!("{}: {e}", c.display())),
        }
    }
    if std::env::var_os("WHEELCAL_PYTHON_NO_INSTALL").is_some() {
        return Err(reasons.join("; "));
    }
    // Make the venv (if missing) and install the package (PyPI), then try again.
    let venv = workspace.join("target/python-venv");
    let python = venv.join("bin/python");
    if !python.exists() {
        let made = Command::new("python3")
            .args(["-m", "venv"])
            .arg(&venv)
            .status()
            .map_err(|e| format!("{}; python3 -m venv: {e}", reasons.join("; ")))?;
        if !made.success() {
            return Err(format!("{}; python3 -m venv failed", reasons.join("; ")));
        }
    }
    let installed = Command::new(&python)
        .args(["-m", "pip", "install", "-q", pip_spec])
        .status()
        .map_err(|e| format!("pip install {pip_spec}: {e}"))?;
    if !installed.success() {
        return Err(format!("pip install {pip_spec} failed (no network?)"));
    }
    Ok(python)
}

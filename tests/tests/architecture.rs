//! The shape of the house, checked from the sources (no build needed):
//!
//! - no service crate depends on another service crate (normal, dev or
//!   build dependency), and the simulator is only a dev-dependency of the
//!   services, but for the sensor bridge whose `simulate` command is its
//!   front end;
//! - no module import cycle in any crate root (each library and each binary):
//!   the files of a crate, linked by the `crate::` and `super::` paths they
//!   name, form no cycle;
//! - the algorithm libraries are pure: outside their tests they name no file
//!   system, thread, wall clock or command-line parsing;
//! - the pure libraries do not build the process side: `cargo tree` of each
//!   (normal dependencies, default features) holds no iceoryx2, tracing
//!   subscriber, command-line parser or `anyhow` (the bus is behind the
//!   `bus` feature of `interfaces`, the drive reader's options behind the
//!   `cli` feature of `drive-io`, the calibrator's and the odometry's binaries
//!   behind their `cli`).
//!
//! Run alone: `cargo test --release -p integration-tests --test architecture`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

const SERVICES: [&str; 4] = ["sensor-bridge", "calibrator", "odometry", "gateway"];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the tests crate has a parent")
        .to_path_buf()
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The dependency names of each `[*dependencies]` table of a manifest.
fn dependency_tables(manifest: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let text = read(manifest);
    let value: toml::Value = text
        .parse()
        .unwrap_or_else(|e| panic!("{}: {e}", manifest.display()));
    let mut out = BTreeMap::new();
    for table in ["dependencies", "dev-dependencies", "build-dependencies"] {
        let names = value
            .get(table)
            .and_then(|t| t.as_table())
            .map(|t| t.keys().cloned().collect())
            .unwrap_or_default();
        out.insert(table.to_string(), names);
    }
    out
}

#[test]
fn no_service_depends_on_another_and_the_simulator_is_a_dev_dependency() {
    for service in SERVICES {
        let manifest = root().join("services").join(service).join("Cargo.toml");
        let tables = dependency_tables(&manifest);
        for (table, names) in &tables {
            for other in SERVICES {
                assert!(
                    !names.contains(other),
                    "{}: [{table}] names the service `{other}`",
                    manifest.display()
                );
            }
        }
        if service != "sensor-bridge" {
            assert!(
                !tables["dependencies"].contains("simulator"),
                "{}: the simulator is a dev-dependency only",
                manifest.display()
            );
        }
    }
}

/// One file of a crate root: its module path and its text without comments
/// and without its `#[cfg(test)]` tail.
struct ModFile {
    module: Vec<String>,
    path: PathBuf,
    code: String,
}

/// Lines of code, comments removed (line comments only: this code base has
/// no block comments).
fn strip_comments(text: &str) -> String {
    text.lines()
        .map(|l| match l.find("//") {
            Some(i) if !l[..i].contains('"') => &l[..i],
            _ => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The file of child module `name` declared by the file `parent` (module
/// path `parent_mod`).
fn child_file(parent: &Path, is_root: bool, name: &str) -> Option<PathBuf> {
    let stem = parent.file_stem()?.to_str()?;
    let dir = parent.parent()?;
    let base = if is_root || stem == "mod" {
        dir.to_path_buf()
    } else {
        dir.join(stem)
    };
    [
        base.join(format!("{name}.rs")),
        base.join(name).join("mod.rs"),
    ]
    .into_iter()
    .find(|p| p.is_file())
}

/// Every file of the crate rooted at `root_file`, by following `mod x;`
/// declarations (`#[path]` attributes are not used in this code base).
fn crate_files(root_file: &Path) -> Vec<ModFile> {
    let mut out = Vec::new();
    let mut stack = vec![(root_file.to_path_buf(), Vec::<String>::new(), true)];
    while let Some((path, module, is_root)) = stack.pop() {
        let code = strip_comments(&read(&path));
        for line in code.lines() {
            let t = line.trim();
            let t = t.strip_prefix("pub ").unwrap_or(t);
            let t = t.strip_prefix("pub(crate) ").unwrap_or(t);
            if let Some(rest) = t.strip_prefix("mod ") {
                if let Some(name) = rest.strip_suffix(';') {
                    let file = child_file(&path, is_root, name.trim())
                        .unwrap_or_else(|| panic!("{}: mod {name} has no file", path.display()));
                    let mut m = module.clone();
                    m.push(name.trim().to_string());
                    stack.push((file, m, false));
                }
            }
        }
        let code = match code.find("#[cfg(test)]\nmod tests") {
            Some(i) => code[..i].to_string(),
            None => code,
        };
        out.push(ModFile { module, path, code });
    }
    out
}

/// The module paths a file names through `crate::` and `super::`.
fn referenced_modules(file: &ModFile) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let is_dir_module = file
        .path
        .file_name()
        .is_some_and(|n| n == "mod.rs" || n == "lib.rs" || n == "main.rs");
    let bytes = file.code.as_bytes();
    for (anchor, up) in [("crate::", None), ("super::", Some(()))] {
        let mut from = 0;
        while let Some(i) = file.code[from..].find(anchor) {
            let start = from + i;
            from = start + anchor.len();
            if start > 0 && (bytes[start - 1].is_ascii_alphanumeric() || bytes[start - 1] == b'_') {
                continue;
            }
            let mut base = if up.is_some() {
                let mut m = file.module.clone();
                // `super` of a file module is its parent; `super` of a
                // mod.rs is the parent of its folder's module, the same.
                let _ = is_dir_module;
                m.pop();
                m
            } else {
                Vec::new()
            };
            let rest = &file.code[from..];
            let mut path_rest = rest;
            // `super::super::x`
            while let Some(r) = path_rest.strip_prefix("super::") {
                base.pop();
                path_rest = r;
            }
            // Brace groups (`crate::{a, b::C}`) name each of their modules.
            if let Some(group) = path_rest.strip_prefix('{') {
                let end = group.find('}').unwrap_or(group.len());
                for part in group[..end].split(',') {
                    let mut m = base.clone();
                    m.extend(
                        part.trim()
                            .split("::")
                            .map(|s| s.trim().to_string())
                            .filter(|s| !s.is_empty()),
                    );
                    out.push(m);
                }
                continue;
            }
            let ident: String = path_rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_' || *c == ':')
                .collect();
            let mut m = base;
            m.extend(
                ident
                    .split("::")
                    .filter(|s| !s.is_empty())
                    .map(str::to_string),
            );
            out.push(m);
        }
    }
    out
}

/// A cycle among the files of one crate root, if there is one.
fn find_cycle(files: &[ModFile]) -> Option<Vec<String>> {
    let index: BTreeMap<Vec<String>, usize> = files
        .iter()
        .enumerate()
        .map(|(i, f)| (f.module.clone(), i))
        .collect();
    let mut edges: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); files.len()];
    for (i, f) in files.iter().enumerate() {
        for mut m in referenced_modules(f) {
            // The longest prefix that is a module file is the file it names.
            while !m.is_empty() && !index.contains_key(&m) {
                m.pop();
            }
            if let Some(&j) = index.get(&m) {
                // A file naming its own module or an ancestor through which
                // the path passes only (the crate root) is not an arrow.
                if j != i && !m.is_empty() {
                    edges[i].insert(j);
                }
            }
        }
    }
    // Depth-first search with colours.
    fn visit(
        n: usize,
        edges: &[BTreeSet<usize>],
        colour: &mut [u8],
        stack: &mut Vec<usize>,
    ) -> Option<Vec<usize>> {
        colour[n] = 1;
        stack.push(n);
        for &m in &edges[n] {
            if colour[m] == 1 {
                let at = stack.iter().position(|&s| s == m).unwrap_or(0);
                let mut cycle = stack[at..].to_vec();
                cycle.push(m);
                return Some(cycle);
            }
            if colour[m] == 0 {
                if let Some(c) = visit(m, edges, colour, stack) {
                    return Some(c);
                }
            }
        }
        stack.pop();
        colour[n] = 2;
        None
    }
    let mut colour = vec![0u8; files.len()];
    for n in 0..files.len() {
        if colour[n] == 0 {
            let mut stack = Vec::new();
            if let Some(c) = visit(n, &edges, &mut colour, &mut stack) {
                return Some(
                    c.into_iter()
                        .map(|i| files[i].path.display().to_string())
                        .collect(),
                );
            }
        }
    }
    None
}

/// Every crate root of the workspace's libraries and binaries.
fn crate_roots() -> Vec<PathBuf> {
    let mut roots = Vec::new();
    for group in ["interfaces", "libraries", "services", "examples", "tests"] {
        let dir = root().join(group);
        let mut crates = vec![dir.clone()];
        if let Ok(entries) = std::fs::read_dir(&dir) {
            for e in entries.flatten() {
                crates.push(e.path());
            }
        }
        for c in crates {
            for f in ["src/lib.rs", "src/main.rs"] {
                let p = c.join(f);
                if p.is_file() {
                    roots.push(p);
                }
            }
        }
    }
    roots
}

#[test]
fn no_crate_has_a_module_import_cycle() {
    let roots = crate_roots();
    assert!(roots.len() >= 10, "found only {roots:?}");
    let mut cycles = Vec::new();
    for r in &roots {
        let files = crate_files(r);
        if let Some(c) = find_cycle(&files) {
            cycles.push(c.join(" -> "));
        }
    }
    assert!(
        cycles.is_empty(),
        "module import cycles:\n{}",
        cycles.join("\n")
    );
}

#[test]
fn the_cycle_finder_finds_a_cycle() {
    let file = |module: &[&str], code: &str| ModFile {
        module: module.iter().map(|s| s.to_string()).collect(),
        path: PathBuf::from(module.join("/")),
        code: code.to_string(),
    };
    let files = vec![
        file(&[], "mod a; mod b; mod c;"),
        file(&["a"], "use crate::b::X;"),
        file(&["b"], "use super::c::{Y, Z};"),
        file(&["c"], "fn f() { crate::a::g() }"),
    ];
    assert!(find_cycle(&files).is_some());
    let acyclic = vec![
        file(&[], "mod a; mod b; mod c;"),
        file(&["a"], "use crate::b::X;"),
        file(&["b"], "use super::c::{Y, Z};"),
        file(&["c"], "fn f() {}"),
    ];
    assert!(find_cycle(&acyclic).is_none());
}

/// The pure algorithm libraries: data in, results out.
#[test]
fn the_algorithm_libraries_touch_no_files_threads_clock_or_cli() {
    let libs = [
        "libraries/vehicle-model/src/lib.rs",
        "libraries/simulator/src/lib.rs",
        "libraries/report/src/lib.rs",
        "libraries/stats/src/lib.rs",
        "services/calibrator/src/lib.rs",
        "services/odometry/src/lib.rs",
    ];
    let banned = [
        "std::fs",
        "std::thread",
        "File::",
        "clap",
        "SystemTime",
        "Instant::now",
        "iceoryx2",
        "interfaces::bus",
    ];
    let mut found = Vec::new();
    for lib in libs {
        for f in crate_files(&root().join(lib)) {
            for b in banned {
                // A whole name: `EstimateFile::` is not `File::`.
                let whole = f.code.match_indices(b).any(|(i, _)| {
                    !f.code[..i]
                        .chars()
                        .next_back()
                        .is_some_and(|c| c.is_alphanumeric() || c == '_')
                });
                if whole {
                    found.push(format!("{}: {b}", f.path.display()));
                }
            }
        }
    }
    assert!(
        found.is_empty(),
        "impure library code:\n{}",
        found.join("\n")
    );
}

/// The packages `package` builds with its default features, its normal
/// dependencies only (no dev or build dependencies), as `cargo tree` resolves
/// them for that package alone (a workspace build unifies features across
/// members; this is what the package builds by itself). `extra` are further
/// `cargo tree` arguments (`--no-default-features`).
fn normal_dependencies(package: &str, extra: &[&str]) -> BTreeSet<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_string());
    let out = Command::new(cargo)
        .current_dir(root())
        .args([
            "tree",
            "--offline",
            "-p",
            package,
            "-e",
            "normal",
            "--prefix",
            "none",
        ])
        .args(["--format", "{p}"])
        .args(extra)
        .output()
        .unwrap_or_else(|e| panic!("cargo tree -p {package}: {e}"));
    assert!(
        out.status.success(),
        "cargo tree -p {package} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let names: BTreeSet<String> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .map(str::to_string)
        .collect();
    assert!(
        names.contains(package),
        "cargo tree -p {package} did not list the package itself: {names:?}"
    );
    names
}

/// What a pure library must not build: the bus, the process's log
/// subscriber, the command line and the binaries' error type.
fn process_side(names: &BTreeSet<String>) -> Vec<String> {
    names
        .iter()
        .filter(|n| {
            n.starts_with("iceoryx2")
                || ["tracing-subscriber", "clap", "anyhow", "zenoh"].contains(&n.as_str())
        })
        .cloned()
        .collect()
}

#[test]
fn the_pure_libraries_do_not_build_the_bus_or_the_command_line() {
    let mut found = Vec::new();
    for (package, extra) in [
        ("vehicle-model", &[][..]),
        ("simulator", &[]),
        ("drive-io", &[]),
        ("report", &[]),
        ("stats", &[]),
        ("interfaces", &["--no-default-features"]),
        ("odometry", &["--no-default-features"]),
        ("calibrator", &["--no-default-features"]),
    ] {
        let side = process_side(&normal_dependencies(package, extra));
        if !side.is_empty() {
            found.push(format!(
                "{package} {}: {}",
                extra.join(" "),
                side.join(", ")
            ));
        }
    }
    assert!(
        found.is_empty(),
        "pure libraries that build the process side:\n{}",
        found.join("\n")
    );
}

/// The check above sees the process side where it is: `interfaces` with
/// its default `bus` feature and `drive-io` with `cli`.
#[test]
fn the_process_side_is_seen_where_it_is() {
    let bus = process_side(&normal_dependencies("interfaces", &[]));
    assert!(
        bus.iter().any(|n| n == "iceoryx2") && bus.iter().any(|n| n == "tracing-subscriber"),
        "interfaces with `bus`: {bus:?}"
    );
    let cli = process_side(&normal_dependencies("drive-io", &["--features", "cli"]));
    assert!(
        cli.iter().any(|n| n == "clap"),
        "drive-io with `cli`: {cli:?}"
    );
}

/// The calibration's stages in the order they run
/// (`docs/design/calibration-stages.md`): each a folder of
/// `services/calibrator/src` with one entry point taking the product of
/// the stage before.
const STAGES: [&str; 6] = ["check", "clocks", "reference", "fit", "sigmas", "result"];
/// The modules beside the stages, which any stage may use and which use
/// no stage.
const SHARED: [&str; 9] = [
    "config",
    "error",
    "error_model",
    "method",
    "products",
    "series",
    "smoother",
    "streams",
    "warnings",
];
/// Arrows from a stage to a later one that the code still has (file,
/// module named). None is left; the list may only shrink.
const KNOWN_BACKWARDS: [(&str, &str); 0] = [];

/// Every (file relative to `src`, module it names) of the calibrator's
/// library whose first path segment is a stage or a shared module.
fn calibrator_arrows() -> Vec<(String, String, String)> {
    let src = root().join("services/calibrator/src");
    let mut out = Vec::new();
    for f in crate_files(&src.join("lib.rs")) {
        let Some(from) = f.module.first().cloned() else {
            continue;
        };
        let rel = f
            .path
            .strip_prefix(&src)
            .expect("a file of the crate")
            .display()
            .to_string();
        for m in referenced_modules(&f) {
            if let Some(to) = m.first() {
                out.push((rel.clone(), from.clone(), to.clone()));
            }
        }
    }
    out
}

#[test]
fn each_calibration_stage_uses_only_the_stages_above_it() {
    let rank = |m: &str| STAGES.iter().position(|s| *s == m);
    let arrows = calibrator_arrows();
    for stage in STAGES {
        assert!(
            arrows.iter().any(|(_, from, _)| from == stage),
            "the stage `{stage}` has no file (or names no module)"
        );
    }
    let mut wrong = BTreeSet::new();
    let mut known_seen = BTreeSet::new();
    for (file, from, to) in &arrows {
        let shared_from = SHARED.contains(&from.as_str());
        let bad = match (rank(from), rank(to)) {
            // A stage naming a later stage.
            (Some(a), Some(b)) => b > a,
            // A shared module naming a stage.
            (None, Some(_)) => shared_from,
            _ => false,
        };
        if !bad {
            continue;
        }
        if KNOWN_BACKWARDS.contains(&(file.as_str(), to.as_str())) {
            known_seen.insert((file.clone(), to.clone()));
        } else {
            wrong.insert(format!("{file} names `{to}`"));
        }
    }
    assert!(
        wrong.is_empty(),
        "a stage names a later stage, or a shared module a stage:\n{}",
        wrong.into_iter().collect::<Vec<_>>().join("\n")
    );
    for (file, to) in KNOWN_BACKWARDS {
        assert!(
            known_seen.contains(&(file.to_string(), to.to_string())),
            "{file} no longer names `{to}`: take it off KNOWN_BACKWARDS"
        );
    }
}

#[test]
fn the_calibration_driver_runs_the_stages_top_to_bottom() {
    let text = strip_comments(&read(&root().join("services/calibrator/src/pipeline.rs")));
    let at = |call: &str| {
        text.find(call)
            .unwrap_or_else(|| panic!("pipeline.rs does not call `{call}`"))
    };
    let order = [
        at("check::drive("),
        at("clocks::align("),
        at("reference::build("),
        at("fit::run("),
        at("sigmas::of("),
        at("result::assemble("),
    ];
    assert!(
        order.windows(2).all(|w| w[0] < w[1]),
        "pipeline.rs calls the stages out of order: {order:?}"
    );
}

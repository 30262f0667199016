//! Where the development data lives: the real drives in `shared/data/real`
//! beside the repository (never copied into it). For tests and benchmarks,
//! which skip with a printed reason when the folder is absent.

use std::path::PathBuf;

/// The real-drive folder beside the repository, whether or not it exists.
pub fn real_data_dir() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/real"
    ))
}

/// The folder of the real drive `name`, or `None` with the reason printed
/// when it is absent (the caller skips).
pub fn real_drive(name: &str) -> Option<PathBuf> {
    let path = real_data_dir().join(name);
    if path.is_dir() {
        Some(path)
    } else {
        eprintln!("skipped: the real drive {} is absent", path.display());
        None
    }
}

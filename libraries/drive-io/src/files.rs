//! Opening the files of a drive with care: only regular files are opened
//! (a FIFO would block the open, a device such as `/dev/zero` never ends),
//! and small text files (TOML, JSON) are read only up to a size limit.
//! The services' state files are read the same way ([`read_state_text`])
//! and written so that neither a power loss nor another local user can
//! corrupt or redirect them ([`write_durably`]).

use super::DriveError;
use std::fs::{File, FileType};
use std::io::Read;
use std::path::Path;

/// Largest `vehicle.toml` / `truth.toml` / estimate JSON read, bytes
/// (16 MiB; real ones are a few hundred bytes).
pub const MAX_TEXT_FILE_BYTES: u64 = 16 << 20;

/// What a file type is, in words ("a directory", "a FIFO (named pipe)", ...).
fn kind_of(ft: &FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if ft.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if ft.is_char_device() {
            return "a character device";
        }
        if ft.is_block_device() {
            return "a block device";
        }
        if ft.is_socket() {
            return "a socket";
        }
    }
    if ft.is_dir() {
        "a directory"
    } else if ft.is_file() {
        "a regular file"
    } else if ft.is_symlink() {
        "a symbolic link"
    } else {
        "not a regular file"
    }
}

/// What is at `path`, for an error message; symbolic links are described
/// with their target.
pub(crate) fn describe(path: &Path) -> String {
    match std::fs::symlink_metadata(path) {
        Err(e) => format!("nothing readable ({e})"),
        Ok(m) if m.file_type().is_symlink() => {
            let target = std::fs::read_link(path)
                .map(|t| t.display().to_string())
                .unwrap_or_else(|_| "?".to_string());
            match std::fs::metadata(path) {
                Ok(t) => format!("a symbolic link to {target} ({})", kind_of(&t.file_type())),
                Err(e) => format!("a symbolic link to {target}, which cannot be followed ({e})"),
            }
        }
        Ok(m) => kind_of(&m.file_type()).to_string(),
    }
}

/// `Ok(false)` when nothing is at `path` (not even a broken link),
/// `Ok(true)` when it is a regular file (links followed), otherwise
/// [`DriveError::NotAFile`] naming what it is. Nothing is opened.
pub(crate) fn regular_file_present(path: &Path) -> Result<bool, DriveError> {
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
        Err(e) => return Err(DriveError::io(path, e)),
        Ok(_) => {}
    }
    match std::fs::metadata(path) {
        Ok(m) if m.is_file() => Ok(true),
        Ok(_) => Err(not_a_file(path)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(not_a_file(path)),
        Err(e) => Err(DriveError::io(path, e)),
    }
}

fn not_a_file(path: &Path) -> DriveError {
    DriveError::NotAFile {
        path: path.to_path_buf(),
        what: describe(path),
    }
}

/// Open `path` for reading when it is a regular file (checked before
/// opening, and again on the open file); also gives its length.
pub(crate) fn open_regular(path: &Path) -> Result<(File, u64), DriveError> {
    if !regular_file_present(path)? {
        return Err(DriveError::io(
            path,
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        ));
    }
    let file = File::open(path).map_err(|e| DriveError::io(path, e))?;
    let meta = file.metadata().map_err(|e| DriveError::io(path, e))?;
    if !meta.is_file() {
        return Err(not_a_file(path));
    }
    Ok((file, meta.len()))
}

/// The bytes of a regular file, however long.
pub(crate) fn read_regular(path: &Path) -> Result<Vec<u8>, DriveError> {
    let (mut file, len) = open_regular(path)?;
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    file.read_to_end(&mut bytes)
        .map_err(|e| DriveError::io(path, e))?;
    Ok(bytes)
}

/// The text of a regular file of at most `limit` bytes; a larger one is
/// [`DriveError::FileTooLarge`] (and is not read beyond the limit).
pub(crate) fn read_text_limited(path: &Path, limit: u64) -> Result<String, DriveError> {
    let (file, len) = open_regular(path)?;
    let too_large = |size: u64| DriveError::FileTooLarge {
        path: path.to_path_buf(),
        size,
        limit,
    };
    if len > limit {
        return Err(too_large(len));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| DriveError::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64));
    }
    String::from_utf8(bytes).map_err(|e| {
        DriveError::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!(
                    "not valid UTF-8 text (at byte {})",
                    e.utf8_error().valid_up_to()
                ),
            ),
        )
    })
}

/// The text of a small state file, `Ok(None)` when nothing is at `path`;
/// anything but a regular file, or one larger than `limit` bytes, is an
/// error naming it (a FIFO is never opened).
pub fn read_state_text(path: &Path, limit: u64) -> Result<Option<String>, DriveError> {
    if !regular_file_present(path)? {
        return Ok(None);
    }
    read_text_limited(path, limit).map(Some)
}

/// Replace `path` with `bytes` durably: a fresh temporary file beside it,
/// created exclusively (`O_CREAT | O_EXCL`: an existing file or a planted
/// symbolic link of that name is never followed or overwritten) and
/// readable by the owner only, fsynced, renamed over `path` (a link at
/// `path` is replaced, not followed), and the directory fsynced. A crash or
/// power loss at any point leaves the old file or the new one, whole. The
/// temporary file is removed when a step fails.
pub fn write_durably(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    use std::os::unix::fs::OpenOptionsExt;
    use std::sync::atomic::{AtomicU64, Ordering};
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "state".into());
    // A name no other writer uses: the process, a per-process count and
    // the clock's nanoseconds.
    static COUNT: AtomicU64 = AtomicU64::new(0);
    let count = COUNT.fetch_add(1, Ordering::Relaxed);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    let tmp = dir.join(format!(
        ".{name}.{}.{count}.{nanos:09}.tmp",
        std::process::id()
    ));
    let written = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(&tmp)
        .and_then(|mut f| {
            f.write_all(bytes)?;
            f.sync_all()
        })
        .and_then(|()| std::fs::rename(&tmp, path));
    if let Err(e) = written {
        // Best effort: the temporary file may not even exist.
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
    }
    File::open(&dir).and_then(|d| d.sync_all())
}

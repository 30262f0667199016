//! The one error type of drive input and output.

use super::LoadedDrive;
use std::path::PathBuf;

/// Why a drive could not be read or written.
///
/// Every variant names the file, and the line/column or the MCAP channel,
/// so that a user can find the fault without a debugger.
#[derive(Debug, thiserror::Error)]
pub enum DriveError {
    /// A file or folder could not be read, written or created.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A required file of the drive folder is absent.
    #[error("{}: required file is missing", path.display())]
    MissingFile {
        /// The file that should exist.
        path: PathBuf,
    },
    /// The path is neither a drive folder nor an MCAP recording.
    #[error("{}: not a drive folder or an MCAP file ({reason})", path.display())]
    UnknownFormat {
        /// The path given.
        path: PathBuf,
        /// What was found instead.
        reason: String,
    },
    /// A TOML file (`vehicle.toml`, `truth.toml`) is malformed or lacks a key.
    #[error("{}: {message}", path.display())]
    Toml {
        /// The TOML file (or the MCAP metadata record holding it).
        path: PathBuf,
        /// The parser's message (it names the key, line and column).
        message: String,
    },
    /// A CSV header lacks a required column.
    #[error("{}:{line}: missing required column `{column}`", path.display())]
    MissingColumn {
        /// The CSV file.
        path: PathBuf,
        /// Line of the header (1-based).
        line: usize,
        /// The column that is required (or the alternatives, for wheels).
        column: String,
    },
    /// `wheels.csv` has a column that looks like a wheel column but is not one
    /// of `rl|rr|fl|fr` + `_rev|_ticks|_rad_s|_m_s`.
    #[error(
        "{}:{line}: unknown wheel column `{column}` (wheel columns are rl|rr|fl|fr followed by _rev, _ticks, _rad_s or _m_s)",
        path.display()
    )]
    UnknownWheelColumn {
        /// The CSV file.
        path: PathBuf,
        /// Line of the header (1-based).
        line: usize,
        /// The offending column name.
        column: String,
    },
    /// A CSV header is malformed (duplicate column, two units for one wheel,
    /// both x/y and lat/lon, ...).
    #[error("{}:{line}: {message}", path.display())]
    BadHeader {
        /// The CSV file.
        path: PathBuf,
        /// Line of the header (1-based).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A CSV cell is not a finite number.
    #[error("{}:{line}: column `{column}`: {reason}: `{cell}`", path.display())]
    BadCell {
        /// The CSV file.
        path: PathBuf,
        /// Line of the row (1-based).
        line: usize,
        /// The column name.
        column: String,
        /// The cell's text.
        cell: Box<str>,
        /// Why it was refused ("not a number", "NaN or infinite values are not allowed").
        reason: &'static str,
    },
    /// A required cell is empty.
    #[error("{}:{line}: column `{column}`: required value is empty", path.display())]
    MissingValue {
        /// The CSV file.
        path: PathBuf,
        /// Line of the row (1-based).
        line: usize,
        /// The column name.
        column: String,
    },
    /// A row has a different number of cells than the header.
    #[error("{}:{line}: {found} cells, but the header has {expected} columns", path.display())]
    CellCount {
        /// The CSV file.
        path: PathBuf,
        /// Line of the row (1-based).
        line: usize,
        /// Cells in the header.
        expected: usize,
        /// Cells in the row.
        found: usize,
    },
    /// `t_s` does not strictly increase.
    #[error(
        "{}:{line}: t_s = {t_s} does not increase (previous row has t_s = {previous_t_s}); times must strictly increase",
        path.display()
    )]
    TimeNotIncreasing {
        /// The CSV file.
        path: PathBuf,
        /// Line of the offending row (1-based).
        line: usize,
        /// Its time.
        t_s: f64,
        /// The time of the row before it.
        previous_t_s: f64,
    },
    /// The MCAP file is malformed (not truncated: wrong magic, bad record,
    /// missing drive metadata, bad message on a channel).
    #[error("{}: {location}: {message}", path.display())]
    Mcap {
        /// The MCAP file.
        path: PathBuf,
        /// Where: a byte offset, a channel and message number, or a metadata record.
        location: String,
        /// What is wrong.
        message: String,
    },
    /// The MCAP file ends in the middle of its data. `partial` holds
    /// everything read before the damage.
    #[error(
        "{}: truncated ({file_len} bytes): {record}; read {messages_read} messages before the damage at byte {offset}",
        path.display()
    )]
    TruncatedMcap {
        /// The MCAP file.
        path: PathBuf,
        /// Byte offset where the damaged (incomplete) record starts, or the
        /// file length when the file ends between records without a footer.
        offset: u64,
        /// Length of the file in bytes.
        file_len: u64,
        /// Which record is damaged and how.
        record: String,
        /// Messages recovered.
        messages_read: usize,
        /// The drive as far as it could be read (its warnings name the
        /// damage); `None` when even the drive metadata was lost.
        partial: Option<Box<LoadedDrive>>,
    },
    /// A chunk's records do not give the CRC its header states: the file
    /// was changed after it was written. Reading with
    /// [`crate::ReadOptions::skip_corrupt_chunks`] leaves the chunk out
    /// (with a warning naming it) instead.
    #[error(
        "{}: chunk {chunk_index} (Chunk record at byte {offset}) is corrupt: its records have CRC {actual:#010x}, the chunk says {expected:#010x}",
        path.display()
    )]
    ChunkCrc {
        /// The MCAP file.
        path: PathBuf,
        /// Index of the chunk in the file, 0 first.
        chunk_index: usize,
        /// Byte offset of the Chunk record.
        offset: u64,
        /// The CRC the chunk header states.
        expected: u32,
        /// The CRC of its records as they are.
        actual: u32,
    },
    /// The bytes before the DataEnd record do not give the data section CRC
    /// it states (a record outside the chunks, or a chunk header, changed).
    #[error(
        "{}: the data section is corrupt: its CRC is {actual:#010x}, the DataEnd record at byte {data_end_offset} says {expected:#010x}",
        path.display()
    )]
    DataSectionCrc {
        /// The MCAP file.
        path: PathBuf,
        /// Byte offset of the DataEnd record.
        data_end_offset: u64,
        /// The CRC the DataEnd record states.
        expected: u32,
        /// The CRC of the data section as it is.
        actual: u32,
    },
    /// Something other than a regular file (a directory, a FIFO, a device,
    /// a socket, a broken link) where a file is expected. Nothing was opened.
    #[error("{}: expected a regular file, found {what}", path.display())]
    NotAFile {
        /// The path given.
        path: PathBuf,
        /// What it is ("a FIFO (named pipe)", "a symbolic link to /dev/zero (a character device)", ...).
        what: String,
    },
    /// A file is larger than the limit for its kind (TOML files).
    #[error("{}: {size} bytes, more than the {limit} bytes allowed for this file", path.display())]
    FileTooLarge {
        /// The file.
        path: PathBuf,
        /// Its size (at least), bytes.
        size: u64,
        /// The limit, bytes.
        limit: u64,
    },
    /// A CSV line is longer than the limit (it was not read whole).
    #[error("{}:{line}: line longer than {limit} bytes", path.display())]
    LineTooLong {
        /// The CSV file.
        path: PathBuf,
        /// Line number (1-based).
        line: usize,
        /// The limit, bytes.
        limit: usize,
    },
    /// A CSV line is not valid UTF-8.
    #[error("{}:{line}: not valid UTF-8 text", path.display())]
    NotUtf8 {
        /// The CSV file.
        path: PathBuf,
        /// Line number (1-based).
        line: usize,
    },
    /// A recording carries no vehicle parameters (a ROS 2 bag) and none
    /// were given ([`crate::ReadOptions::vehicle`]).
    #[error(
        "{}: a ROS 2 bag carries no vehicle parameters; give a vehicle.toml (the tools' --vehicle)",
        path.display()
    )]
    NoVehicle {
        /// The recording.
        path: PathBuf,
    },
    /// A topic-to-role assignment does not parse.
    #[error("{origin}: {message}")]
    TopicMap {
        /// Where the assignment came from (e.g. `--topic`).
        origin: String,
        /// What is wrong.
        message: String,
    },
    /// A topic of a ROS 2 bag does not fit the role it is read as: absent,
    /// of another message type or encoding, or lacking the named joints.
    #[error("{}: topic {topic} ({}): {message}", path.display(), role.name())]
    Topic {
        /// The bag.
        path: PathBuf,
        /// The topic.
        topic: String,
        /// The role it was to fill.
        role: crate::Role,
        /// What was expected and what was found.
        message: String,
    },
    /// More than one topic of a ROS 2 bag could fill a role and none was
    /// named.
    #[error(
        "{}: {} topics could be the {} stream: {}; name one (e.g. --topic {}={})",
        path.display(),
        candidates.len(),
        role.name(),
        candidates.join(", "),
        role.name(),
        candidates.first().and_then(|c| c.split(' ').next()).unwrap_or("TOPIC")
    )]
    AmbiguousTopic {
        /// The bag.
        path: PathBuf,
        /// The role.
        role: crate::Role,
        /// The candidates, each as `topic (type)`.
        candidates: Vec<String>,
    },
    /// A line of an NMEA 0183 log is not a valid sentence (bad checksum,
    /// garbage, a field out of range).
    #[error("{}:{line}: {message}", path.display())]
    Nmea {
        /// The log.
        path: PathBuf,
        /// Line number (1-based).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// An in-memory drive cannot be written because it breaks the format's
    /// rules (a non-finite value, times not increasing, ticks without
    /// `ticks_per_rev`).
    #[error("cannot write drive: {stream}[{index}]: {message}")]
    InvalidDrive {
        /// The stream (`wheels`, `gnss`, ... or `vehicle`).
        stream: String,
        /// Sample index within the stream.
        index: usize,
        /// What is wrong.
        message: String,
    },
}

impl DriveError {
    /// An [`DriveError::Io`] for `path`.
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> DriveError {
        DriveError::Io {
            path: path.into(),
            source,
        }
    }
}

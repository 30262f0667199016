//! The record walk of an MCAP file: every whole record up to the first
//! damage, chunk contents included, so that a truncated recording can be
//! read up to where it is cut (the records of a cut uncompressed chunk
//! included; a cut compressed chunk is lost whole).
//!
//! Compressed chunks (`zstd`, `lz4`) are decompressed into a buffer that
//! grows with what the codec actually produces, never beyond the size the
//! chunk header declares nor [`MAX_CHUNK_RECORDS_BYTES`]; the records must
//! come out exactly that long and match the chunk's CRC.

use super::crc::crc32;
use super::layout;
use crate::DriveError;
use mcap::records::{op, Record};
use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;

/// The most bytes a compressed chunk may decompress to (whatever its header
/// declares): 512 MiB, far above any writer's chunk size (rosbag2 and the
/// `mcap` crate write chunks of about 1 MiB), far below what would exhaust
/// memory.
pub const MAX_CHUNK_RECORDS_BYTES: u64 = 512 << 20;

/// A message as found in the file.
pub(super) struct RawMessage<'a> {
    /// The channel it was written on.
    pub channel_id: u16,
    /// Byte offset of its record in the file or, inside a compressed chunk,
    /// in the chunk's decompressed records.
    pub offset: u64,
    /// Byte offset of the compressed chunk holding it, if any.
    pub compressed_chunk: Option<u64>,
    /// Its log time, ns.
    pub log_time: u64,
    /// The message (JSON, or CDR in a ROS 2 bag): borrowed from the file,
    /// owned when it was decompressed.
    pub data: Cow<'a, [u8]>,
}

impl RawMessage<'_> {
    /// Where the message's record is, for errors: "record at byte N" or
    /// "record at byte N of the zstd/lz4 chunk at byte M".
    pub fn location(&self) -> String {
        match self.compressed_chunk {
            None => format!("record at byte {}", self.offset),
            Some(chunk) => format!(
                "record at byte {} of the decompressed chunk at byte {chunk}",
                self.offset
            ),
        }
    }
}

/// A channel record.
pub(super) struct ChannelInfo {
    /// Its topic.
    pub topic: String,
    /// Its schema id (0: none).
    pub schema_id: u16,
    /// Its message encoding.
    pub encoding: String,
    /// Its metadata.
    pub metadata: BTreeMap<String, String>,
}

/// A schema record (its data is not kept).
pub(super) struct SchemaInfo {
    /// Its name (a ROS 2 bag's is the message type, e.g. `sensor_msgs/msg/Imu`).
    pub name: String,
    /// Its encoding (`jsonschema`, `ros2msg`, ...).
    pub encoding: String,
}

/// Where a file stops making sense.
pub(super) struct Damage {
    /// Byte offset of the damaged record.
    pub offset: u64,
    /// What is wrong with it.
    pub record: String,
}

/// Everything a walk over the records found.
#[derive(Default)]
pub(super) struct Scan<'a> {
    /// Channels by id.
    pub channels: BTreeMap<u16, ChannelInfo>,
    /// Schemas by id.
    pub schemas: BTreeMap<u16, SchemaInfo>,
    /// Metadata records by name.
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Messages in file order.
    pub messages: Vec<RawMessage<'a>>,
    /// The first damage found, if any.
    pub damage: Option<Damage>,
    /// A DataEnd record was read.
    pub data_end_seen: bool,
    /// Recovery: skip a chunk whose records fail their CRC (listed in
    /// `corrupt_chunks`) and accept a data section CRC mismatch (kept in
    /// `data_crc_mismatch`) instead of failing.
    pub skip_corrupt_chunks: bool,
    /// Chunks skipped for a CRC mismatch (recovery only).
    pub corrupt_chunks: Vec<CorruptChunk>,
    /// The data section CRC mismatch accepted under recovery.
    pub data_crc_mismatch: Option<CorruptChunk>,
    /// Chunks met so far (the next chunk's index).
    chunk_count: usize,
    footer_seen: bool,
}

/// A checksum that does not match: which chunk (or the data section) and
/// the two values.
pub(super) struct CorruptChunk {
    /// Index of the chunk in the file (0 first); unused for the data section.
    pub index: usize,
    /// Byte offset of the Chunk (or DataEnd) record.
    pub offset: u64,
    /// The CRC the file gives.
    pub expected: u32,
    /// The CRC of the bytes as they are.
    pub actual: u32,
}

fn op_name(op: u8) -> String {
    match op {
        op::HEADER => "Header".into(),
        op::FOOTER => "Footer".into(),
        op::SCHEMA => "Schema".into(),
        op::CHANNEL => "Channel".into(),
        op::MESSAGE => "Message".into(),
        op::CHUNK => "Chunk".into(),
        op::MESSAGE_INDEX => "MessageIndex".into(),
        op::CHUNK_INDEX => "ChunkIndex".into(),
        op::ATTACHMENT => "Attachment".into(),
        op::ATTACHMENT_INDEX => "AttachmentIndex".into(),
        op::STATISTICS => "Statistics".into(),
        op::METADATA => "Metadata".into(),
        op::METADATA_INDEX => "MetadataIndex".into(),
        op::SUMMARY_OFFSET => "SummaryOffset".into(),
        op::DATA_END => "DataEnd".into(),
        other => format!("opcode 0x{other:02x}"),
    }
}

fn le_u64(b: &[u8]) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[..8]);
    u64::from_le_bytes(a)
}

fn le_u32(b: &[u8]) -> u32 {
    let mut a = [0u8; 4];
    a.copy_from_slice(&b[..4]);
    u32::from_le_bytes(a)
}

/// One framed record: (opcode, body start, declared body length).
enum Frame {
    Complete {
        op: u8,
        body: std::ops::Range<usize>,
    },
    /// The record runs past the end of the buffer.
    Cut {
        op: Option<u8>,
        declared: u64,
        present: usize,
    },
}

fn frame(buf: &[u8], pos: usize) -> Frame {
    let rest = buf.len() - pos;
    if rest < 9 {
        return Frame::Cut {
            op: buf.get(pos).copied(),
            declared: 0,
            present: rest,
        };
    }
    let op = buf[pos];
    let len = le_u64(&buf[pos + 1..]);
    let start = pos + 9;
    match usize::try_from(len).ok().and_then(|l| start.checked_add(l)) {
        Some(end) if end <= buf.len() => Frame::Complete {
            op,
            body: start..end,
        },
        _ => Frame::Cut {
            op: Some(op),
            declared: len,
            present: rest - 9,
        },
    }
}

/// Decompress a chunk's `records` (`zstd` or `lz4`), which must give
/// exactly `declared` bytes (the chunk's uncompressed size), at most
/// [`MAX_CHUNK_RECORDS_BYTES`]. The output grows with what the codec
/// produces: a small chunk declaring a huge size allocates nothing large.
pub(super) fn decompress(
    compression: &str,
    records: &[u8],
    declared: u64,
) -> Result<Vec<u8>, String> {
    if declared > MAX_CHUNK_RECORDS_BYTES {
        return Err(format!(
            "the chunk declares {declared} uncompressed bytes, more than the {MAX_CHUNK_RECORDS_BYTES} this reader accepts"
        ));
    }
    let mut out = Vec::new();
    // One byte beyond the declared size tells "too long" from "exact".
    let limit = declared + 1;
    let read = match compression {
        "zstd" => zstd::stream::read::Decoder::with_buffer(records)
            .and_then(|d| d.take(limit).read_to_end(&mut out)),
        "lz4" => lz4::Decoder::new(records).and_then(|d| d.take(limit).read_to_end(&mut out)),
        other => {
            return Err(format!(
                "chunk compressed with `{other}`; this build reads uncompressed, `zstd` and `lz4` chunks"
            ))
        }
    };
    read.map_err(|e| format!("cannot decompress its `{compression}` records: {e}"))?;
    let got = out.len() as u64;
    if got > declared {
        return Err(format!(
            "its `{compression}` records decompress to more than the {declared} bytes the chunk declares"
        ));
    }
    if got < declared {
        return Err(format!(
            "its `{compression}` records decompress to {got} bytes, the chunk declares {declared}"
        ));
    }
    Ok(out)
}

/// Byte offset of the records inside a chunk body, and the compression.
fn chunk_records_start(body: &[u8]) -> Option<(usize, String)> {
    // message_start_time u64, message_end_time u64, uncompressed_size u64,
    // uncompressed_crc u32, compression string (u32 length + bytes),
    // records length u64, records.
    let str_len = le_u32(body.get(28..32)?) as usize;
    let compression = body.get(32..32 + str_len)?;
    let start = 32 + str_len + 8;
    if body.len() < start {
        return None;
    }
    Some((start, String::from_utf8_lossy(compression).into_owned()))
}

/// How a walk keeps message data: borrowed from the file, or copied out of
/// a decompressed chunk's buffer.
type Keep<'k, 'b, 'a> = &'k dyn Fn(&'b [u8]) -> Cow<'a, [u8]>;

/// Where a walk is: the file itself, or the records of a chunk.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Within {
    /// The file's records.
    File,
    /// An uncompressed chunk's records (offsets are file offsets).
    Chunk,
    /// A compressed chunk's decompressed records, the chunk record being at
    /// this file offset (offsets are within the records).
    CompressedChunk(u64),
}

impl<'a> Scan<'a> {
    fn handle<'b>(
        &mut self,
        path: &Path,
        op: u8,
        body: &'b [u8],
        offset: u64,
        within: Within,
        keep: Keep<'_, 'b, 'a>,
    ) -> Result<(), DriveError> {
        let location = || match within {
            Within::CompressedChunk(chunk) => format!(
                "{} record at byte {offset} of the decompressed chunk at byte {chunk}",
                op_name(op)
            ),
            _ => format!("{} record at byte {offset}", op_name(op)),
        };
        layout::check(op, body).map_err(|message| DriveError::Mcap {
            path: path.to_path_buf(),
            location: location(),
            message,
        })?;
        let record = mcap::parse_record(op, body).map_err(|e| DriveError::Mcap {
            path: path.to_path_buf(),
            location: location(),
            message: e.to_string(),
        })?;
        match record {
            Record::Channel(c) => {
                self.channels.insert(
                    c.id,
                    ChannelInfo {
                        topic: c.topic,
                        schema_id: c.schema_id,
                        encoding: c.message_encoding,
                        metadata: c.metadata,
                    },
                );
            }
            Record::Schema { header, .. } => {
                self.schemas.insert(
                    header.id,
                    SchemaInfo {
                        name: header.name,
                        encoding: header.encoding,
                    },
                );
            }
            Record::Message { header, data } => {
                let data = match data {
                    Cow::Borrowed(d) => keep(d),
                    Cow::Owned(d) => Cow::Owned(d),
                };
                self.messages.push(RawMessage {
                    channel_id: header.channel_id,
                    offset,
                    compressed_chunk: match within {
                        Within::CompressedChunk(chunk) => Some(chunk),
                        _ => None,
                    },
                    log_time: header.log_time,
                    data,
                });
            }
            Record::Metadata(m) => {
                self.metadata.insert(m.name, m.metadata);
            }
            Record::DataEnd(_) => self.data_end_seen = true,
            Record::Footer(_) => self.footer_seen = true,
            _ => {}
        }
        Ok(())
    }

    /// Walk the records of the whole file `buf` from `start` (after the magic).
    /// Stops at the first damaged record (recorded in `self.damage`) or the
    /// footer.
    pub fn walk_file(
        &mut self,
        path: &Path,
        buf: &'a [u8],
        start: usize,
    ) -> Result<(), DriveError> {
        self.walk(path, buf, start, 0, Within::File, &|d| Cow::Borrowed(d))
    }

    /// Walk the records of `buf[start..]` (the whole file, or a chunk's
    /// records); `base` is the offset of `buf[0]` (in the file, or in the
    /// decompressed records). Stops at the first damaged record (recorded
    /// in `self.damage`) or the footer.
    fn walk<'b>(
        &mut self,
        path: &Path,
        buf: &'b [u8],
        start: usize,
        base: u64,
        within: Within,
        keep: Keep<'_, 'b, 'a>,
    ) -> Result<(), DriveError> {
        let in_chunk = within != Within::File;
        let mut pos = start;
        while pos < buf.len() {
            let offset = base + pos as u64;
            match frame(buf, pos) {
                Frame::Complete { op, body } => {
                    let end = body.end;
                    let body = &buf[body];
                    if op == op::DATA_END && !in_chunk {
                        self.check_data_crc(path, buf, body, offset)?;
                    }
                    if op == op::CHUNK && !in_chunk {
                        self.chunk(path, body, offset + 9, keep)?;
                        if self.damage.is_some() {
                            return Ok(());
                        }
                    } else {
                        self.handle(path, op, body, offset, within, keep)?;
                    }
                    pos = end;
                    if self.footer_seen {
                        return Ok(());
                    }
                }
                Frame::Cut {
                    op,
                    declared,
                    present,
                } => {
                    let rest = buf.len() - pos;
                    let mut record = match op {
                        Some(op) if rest >= 9 => format!(
                            "the {} record at byte {offset} declares {declared} bytes but only {present} follow",
                            op_name(op)
                        ),
                        _ => format!("the record header at byte {offset} is cut after {rest} of 9 bytes"),
                    };
                    // A cut chunk: when its records are uncompressed, read
                    // those that are whole; compressed ones are lost.
                    if op == Some(op::CHUNK) && !in_chunk {
                        self.chunk_count += 1;
                    }
                    if op == Some(op::CHUNK) && !in_chunk && rest > 9 {
                        let body = &buf[pos + 9..];
                        if let Some((records_start, compression)) = chunk_records_start(body) {
                            if compression.is_empty() {
                                self.walk(
                                    path,
                                    body,
                                    records_start,
                                    offset + 9,
                                    Within::Chunk,
                                    keep,
                                )?;
                            } else {
                                record.push_str(&format!(
                                    " (its `{compression}`-compressed messages are lost)"
                                ));
                            }
                        }
                    }
                    self.damage = Some(Damage { offset, record });
                    return Ok(());
                }
            }
        }
        if !in_chunk && !self.footer_seen {
            self.damage = Some(Damage {
                offset: buf.len() as u64,
                record: format!(
                    "the file ends at byte {} without a Footer record",
                    buf.len()
                ),
            });
        }
        Ok(())
    }

    /// Check the DataEnd record's data section CRC (when nonzero) against
    /// the bytes before the record (`buf` is the whole file).
    fn check_data_crc(
        &mut self,
        path: &Path,
        buf: &[u8],
        body: &[u8],
        offset: u64,
    ) -> Result<(), DriveError> {
        let Some(expected) = body.get(..4).map(le_u32) else {
            return Ok(());
        };
        let Some(data) = usize::try_from(offset).ok().and_then(|o| buf.get(..o)) else {
            return Ok(());
        };
        if expected == 0 {
            return Ok(());
        }
        let actual = crc32(data);
        if actual == expected {
            return Ok(());
        }
        if self.skip_corrupt_chunks {
            self.data_crc_mismatch = Some(CorruptChunk {
                index: 0,
                offset,
                expected,
                actual,
            });
            return Ok(());
        }
        Err(DriveError::DataSectionCrc {
            path: path.to_path_buf(),
            data_end_offset: offset,
            expected,
            actual,
        })
    }

    /// A complete chunk record (body at file offset `base`).
    fn chunk<'b>(
        &mut self,
        path: &Path,
        body: &'b [u8],
        base: u64,
        keep: Keep<'_, 'b, 'a>,
    ) -> Result<(), DriveError> {
        let index = self.chunk_count;
        self.chunk_count += 1;
        let Some((start, compression)) = chunk_records_start(body) else {
            return Err(DriveError::Mcap {
                path: path.to_path_buf(),
                location: format!("Chunk record at byte {}", base - 9),
                message: "malformed chunk header".to_string(),
            });
        };
        let records_len = le_u64(&body[start - 8..]);
        let end = usize::try_from(records_len)
            .ok()
            .and_then(|l| start.checked_add(l))
            .filter(|e| *e <= body.len())
            .ok_or_else(|| DriveError::Mcap {
                path: path.to_path_buf(),
                location: format!("Chunk record at byte {}", base - 9),
                message: format!("records length {records_len} exceeds the chunk"),
            })?;
        let decompressed = if compression.is_empty() {
            None
        } else {
            let declared = le_u64(&body[16..24]);
            let records =
                decompress(&compression, &body[start..end], declared).map_err(|message| {
                    DriveError::Mcap {
                        path: path.to_path_buf(),
                        location: format!("Chunk record at byte {} (chunk {index})", base - 9),
                        message,
                    }
                })?;
            Some(records)
        };
        let records: &[u8] = decompressed.as_deref().unwrap_or(&body[start..end]);
        // uncompressed_crc: 0 means "not computed".
        let expected = le_u32(&body[24..28]);
        if expected != 0 {
            let actual = crc32(records);
            if actual != expected {
                let corrupt = CorruptChunk {
                    index,
                    offset: base - 9,
                    expected,
                    actual,
                };
                if self.skip_corrupt_chunks {
                    self.corrupt_chunks.push(corrupt);
                    return Ok(());
                }
                return Err(DriveError::ChunkCrc {
                    path: path.to_path_buf(),
                    chunk_index: corrupt.index,
                    offset: corrupt.offset,
                    expected,
                    actual,
                });
            }
        }
        let mut inner_damage = None;
        std::mem::swap(&mut inner_damage, &mut self.damage);
        match &decompressed {
            None => self.walk(path, &body[..end], start, base, Within::Chunk, keep)?,
            Some(records) => self.walk(
                path,
                records,
                0,
                0,
                Within::CompressedChunk(base - 9),
                &|d| Cow::Owned(d.to_vec()),
            )?,
        }
        if let Some(d) = self.damage.take() {
            // A complete chunk whose records do not frame: corrupt, not truncated.
            return Err(DriveError::Mcap {
                path: path.to_path_buf(),
                location: format!(
                    "Chunk record at byte {}, inner record at byte {}{}",
                    base - 9,
                    d.offset,
                    if decompressed.is_some() {
                        " of its decompressed records"
                    } else {
                        ""
                    }
                ),
                message: d.record,
            });
        }
        self.damage = inner_damage;
        Ok(())
    }
}

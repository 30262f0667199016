//! The frame every gateway message travels in: a fixed 80-byte header, then
//! the sample's bytes exactly as they lie in shared memory.
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `WCGW` |
//! | 4 | 1 | header version, [`HEADER_VERSION`] |
//! | 5 | 1 | byte order of the payload: 1 little-endian, 2 big-endian |
//! | 6 | 1 | kind: 0 a sample, 1 the end of the stream (no payload) |
//! | 7 | 1 | reserved, 0 |
//! | 8 | 4 | payload size, bytes (u32 little-endian) |
//! | 12 | 4 | reserved, 0 |
//! | 16 | 8 | id of the gateway that sent it (u64 little-endian) |
//! | 24 | 8 | id of the publisher in the sending graph (u64 little-endian; 0 for an end of stream) |
//! | 32 | 48 | type name, UTF-8, zero-padded: the versioned `#[type_name]` (`wheelcal/Pose/v1`; the `/vN` is the layout version) |
//! | 80 | size | the payload |
//!
//! The header's own fields are little-endian whatever the host; the byte
//! order field says how the payload's numbers are laid out. A receiver takes
//! a frame only when type name, size and byte order are its own
//! ([`Frame::check`]); anything else is a [`FrameError`] that names the topic.

/// First four bytes of every frame.
pub const MAGIC: [u8; 4] = *b"WCGW";
/// The version of this header layout.
pub const HEADER_VERSION: u8 = 1;
/// Bytes before the payload.
pub const HEADER_LEN: usize = 80;
/// Longest type name the header holds, bytes.
pub const TYPE_NAME_MAX: usize = 48;

/// Byte order code of a little-endian payload.
pub const LITTLE_ENDIAN: u8 = 1;
/// Byte order code of a big-endian payload.
pub const BIG_ENDIAN: u8 = 2;

/// The byte order code of this host.
pub const fn native_byte_order() -> u8 {
    if cfg!(target_endian = "little") {
        LITTLE_ENDIAN
    } else {
        BIG_ENDIAN
    }
}

/// What a frame carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// One sample.
    Sample,
    /// The publisher on the sending side announced the end of its stream.
    EndOfStream,
}

impl Kind {
    fn code(self) -> u8 {
        match self {
            Kind::Sample => 0,
            Kind::EndOfStream => 1,
        }
    }
}

/// A decoded frame, borrowing its payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Sample or end of stream.
    pub kind: Kind,
    /// Byte order code of the payload ([`LITTLE_ENDIAN`], [`BIG_ENDIAN`]).
    pub byte_order: u8,
    /// The sending gateway.
    pub gateway: u64,
    /// The publisher of the sample in the sending graph (its sequence
    /// numbers are in the samples' headers).
    pub origin: u64,
    /// The type name as sent.
    pub type_name: &'a str,
    /// The payload (empty for [`Kind::EndOfStream`]).
    pub payload: &'a [u8],
}

/// A frame that cannot be taken; every variant names the topic.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// Shorter than the header or than the size it states.
    #[error("{topic}: frame of {len} bytes is truncated (header {HEADER_LEN} + payload {payload} bytes)")]
    Truncated {
        /// The topic (key expression) it came on.
        topic: String,
        /// Bytes received.
        len: usize,
        /// Payload size the header states (0 when the header itself is short).
        payload: usize,
    },
    /// Not a gateway frame at all.
    #[error("{topic}: not a wheelcal gateway frame (magic {found:02x?}, expected \"WCGW\")")]
    Magic {
        /// The topic.
        topic: String,
        /// The first four bytes.
        found: [u8; 4],
    },
    /// A header version this gateway does not know.
    #[error(
        "{topic}: gateway header version {found}, this gateway reads version {HEADER_VERSION}"
    )]
    Version {
        /// The topic.
        topic: String,
        /// The version found.
        found: u8,
    },
    /// Unknown kind or byte-order code, or a malformed type name.
    #[error("{topic}: malformed gateway header: {detail}")]
    Malformed {
        /// The topic.
        topic: String,
        /// What is wrong.
        detail: String,
    },
    /// The sender's type is not this side's type of the topic.
    #[error(
        "{topic}: type mismatch: the sender publishes {found:?} ({found_size} bytes), this side \
         expects {expected:?} ({expected_size} bytes); the two hosts run incompatible wheelcal \
         versions, the sample is dropped"
    )]
    TypeMismatch {
        /// The topic.
        topic: String,
        /// This side's type name.
        expected: String,
        /// This side's size.
        expected_size: usize,
        /// The sender's type name.
        found: String,
        /// The sender's payload size.
        found_size: usize,
    },
    /// The payload's byte order is not this host's.
    #[error(
        "{topic}: the sender's payload is {found}, this host is {expected}: the gateway carries \
         samples as they lie in memory and does not swap bytes; the sample is dropped"
    )]
    ByteOrder {
        /// The topic.
        topic: String,
        /// The sender's order.
        found: &'static str,
        /// This host's order.
        expected: &'static str,
    },
}

fn order_name(code: u8) -> &'static str {
    match code {
        LITTLE_ENDIAN => "little-endian",
        BIG_ENDIAN => "big-endian",
        _ => "of unknown byte order",
    }
}

/// Append a frame to `out` (cleared first): the header, then `payload`.
///
/// Fails only for a type name longer than [`TYPE_NAME_MAX`] bytes or a
/// payload above 4 GiB, which no wire type has.
pub fn encode(
    out: &mut Vec<u8>,
    kind: Kind,
    (gateway, origin): (u64, u64),
    type_name: &str,
    payload: &[u8],
) -> Result<(), String> {
    let name = type_name.as_bytes();
    if name.len() > TYPE_NAME_MAX {
        return Err(format!(
            "type name {type_name:?} is longer than {TYPE_NAME_MAX} bytes"
        ));
    }
    let size = u32::try_from(payload.len()).map_err(|_| "payload above 4 GiB".to_string())?;
    out.clear();
    out.reserve(HEADER_LEN + payload.len());
    out.extend_from_slice(&MAGIC);
    out.push(HEADER_VERSION);
    out.push(native_byte_order());
    out.push(kind.code());
    out.push(0);
    out.extend_from_slice(&size.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&gateway.to_le_bytes());
    out.extend_from_slice(&origin.to_le_bytes());
    out.extend_from_slice(name);
    out.resize(HEADER_LEN, 0);
    out.extend_from_slice(payload);
    Ok(())
}

/// Split a received frame into header fields and payload; `topic` names the
/// key expression in errors. Checks the frame's own form only; whether the
/// type is the expected one is [`Frame::check`].
pub fn decode<'a>(topic: &str, bytes: &'a [u8]) -> Result<Frame<'a>, FrameError> {
    let topic_s = || topic.to_string();
    if bytes.len() < HEADER_LEN {
        return Err(FrameError::Truncated {
            topic: topic_s(),
            len: bytes.len(),
            payload: 0,
        });
    }
    let mut magic = [0u8; 4];
    magic.copy_from_slice(&bytes[0..4]);
    if magic != MAGIC {
        return Err(FrameError::Magic {
            topic: topic_s(),
            found: magic,
        });
    }
    if bytes[4] != HEADER_VERSION {
        return Err(FrameError::Version {
            topic: topic_s(),
            found: bytes[4],
        });
    }
    let byte_order = bytes[5];
    if byte_order != LITTLE_ENDIAN && byte_order != BIG_ENDIAN {
        return Err(FrameError::Malformed {
            topic: topic_s(),
            detail: format!("byte order code {byte_order}"),
        });
    }
    let kind = match bytes[6] {
        0 => Kind::Sample,
        1 => Kind::EndOfStream,
        k => {
            return Err(FrameError::Malformed {
                topic: topic_s(),
                detail: format!("kind {k}"),
            })
        }
    };
    let u32_at =
        |at: usize| u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    let size = u32_at(8) as usize;
    let u64_at = |at: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&bytes[at..at + 8]);
        u64::from_le_bytes(b)
    };
    let gateway = u64_at(16);
    let origin = u64_at(24);
    let name_field = &bytes[32..32 + TYPE_NAME_MAX];
    let name_len = name_field
        .iter()
        .position(|&b| b == 0)
        .unwrap_or(TYPE_NAME_MAX);
    let type_name =
        std::str::from_utf8(&name_field[..name_len]).map_err(|e| FrameError::Malformed {
            topic: topic_s(),
            detail: format!("type name is not UTF-8: {e}"),
        })?;
    if bytes.len() != HEADER_LEN + size {
        return Err(FrameError::Truncated {
            topic: topic_s(),
            len: bytes.len(),
            payload: size,
        });
    }
    Ok(Frame {
        kind,
        byte_order,
        gateway,
        origin,
        type_name,
        payload: &bytes[HEADER_LEN..],
    })
}

impl Frame<'_> {
    /// Whether this frame carries `type_name` of `size` bytes in this host's
    /// byte order (an end-of-stream frame: the type name alone); `topic`
    /// names the key expression in the error.
    pub fn check(&self, topic: &str, type_name: &str, size: usize) -> Result<(), FrameError> {
        let found_size = self.payload.len();
        let size_ok = self.kind == Kind::EndOfStream || found_size == size;
        if self.type_name != type_name || !size_ok {
            return Err(FrameError::TypeMismatch {
                topic: topic.to_string(),
                expected: type_name.to_string(),
                expected_size: size,
                found: self.type_name.to_string(),
                found_size,
            });
        }
        if self.byte_order != native_byte_order() {
            return Err(FrameError::ByteOrder {
                topic: topic.to_string(),
                found: order_name(self.byte_order),
                expected: order_name(native_byte_order()),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_round_trips() {
        let mut buf = Vec::new();
        encode(
            &mut buf,
            Kind::Sample,
            (0x0102_0304_0506_0708, 5),
            "wheelcal/Imu/v1",
            &[9; 72],
        )
        .expect("encode");
        assert_eq!(buf.len(), HEADER_LEN + 72);
        assert_eq!(&buf[..4], b"WCGW");
        let f = decode("k", &buf).expect("decode");
        assert_eq!(f.kind, Kind::Sample);
        assert_eq!((f.gateway, f.origin), (0x0102_0304_0506_0708, 5));
        assert_eq!(f.type_name, "wheelcal/Imu/v1");
        assert_eq!(f.payload, &[9; 72][..]);
        f.check("k", "wheelcal/Imu/v1", 72).expect("matches");
        encode(&mut buf, Kind::EndOfStream, (7, 0), "wheelcal/Imu/v1", &[]).expect("encode");
        let f = decode("k", &buf).expect("decode");
        assert_eq!((f.kind, f.payload.len()), (Kind::EndOfStream, 0));
        f.check("k", "wheelcal/Imu/v1", 72)
            .expect("an end of stream has no payload");
    }

    #[test]
    fn a_mismatch_is_an_error_naming_the_topic() {
        let mut buf = Vec::new();
        encode(&mut buf, Kind::Sample, (1, 2), "wheelcal/Imu/v2", &[0; 80]).expect("encode");
        let f = decode("wheelcal/sensors/imu", &buf).expect("decode");
        let e = f
            .check("wheelcal/sensors/imu", "wheelcal/Imu/v1", 72)
            .expect_err("mismatch")
            .to_string();
        assert!(e.starts_with("wheelcal/sensors/imu: type mismatch"), "{e}");
        assert!(e.contains("\"wheelcal/Imu/v2\" (80 bytes)"), "{e}");
        assert!(e.contains("\"wheelcal/Imu/v1\" (72 bytes)"), "{e}");
        // Same name, other size: also a mismatch.
        encode(&mut buf, Kind::Sample, (1, 2), "wheelcal/Imu/v1", &[0; 64]).expect("encode");
        let f = decode("t", &buf).expect("decode");
        assert!(matches!(
            f.check("t", "wheelcal/Imu/v1", 72),
            Err(FrameError::TypeMismatch { found_size: 64, .. })
        ));
        // The other byte order.
        encode(&mut buf, Kind::Sample, (1, 2), "wheelcal/Imu/v1", &[0; 72]).expect("encode");
        buf[5] = if native_byte_order() == LITTLE_ENDIAN {
            BIG_ENDIAN
        } else {
            LITTLE_ENDIAN
        };
        let e = decode("t", &buf)
            .expect("decode")
            .check("t", "wheelcal/Imu/v1", 72)
            .expect_err("byte order");
        assert!(matches!(e, FrameError::ByteOrder { .. }), "{e}");
    }

    #[test]
    fn broken_frames_are_refused() {
        let mut buf = Vec::new();
        encode(&mut buf, Kind::Sample, (1, 2), "wheelcal/Imu/v1", &[0; 72]).expect("encode");
        assert!(matches!(
            decode("t", &buf[..40]),
            Err(FrameError::Truncated { len: 40, .. })
        ));
        assert!(matches!(
            decode("t", &buf[..HEADER_LEN + 10]),
            Err(FrameError::Truncated { payload: 72, .. })
        ));
        let mut bad = buf.clone();
        bad[0] = b'X';
        assert!(matches!(decode("t", &bad), Err(FrameError::Magic { .. })));
        let mut bad = buf.clone();
        bad[4] = 9;
        assert!(matches!(
            decode("t", &bad),
            Err(FrameError::Version { found: 9, .. })
        ));
        let mut bad = buf.clone();
        bad[6] = 5;
        assert!(matches!(
            decode("t", &bad),
            Err(FrameError::Malformed { .. })
        ));
        assert!(encode(&mut buf, Kind::Sample, (1, 2), &"x".repeat(49), &[]).is_err());
    }
}

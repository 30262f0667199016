//! Every length prefix of a record checked against the record's body before
//! the `mcap` crate parses it: the crate reserves a string's or a byte
//! array's declared length before it reads it, so a 21-byte file declaring a
//! 4 GiB header string asked for 4 GiB (found by `fuzz/`). The layouts are
//! the MCAP specification's, per opcode; a record whose prefixes do not fit
//! is an error naming the field.

/// Reads a record body field by field, checking each declared length.
struct Fields<'a> {
    body: &'a [u8],
    pos: usize,
}

impl<'a> Fields<'a> {
    fn skip(&mut self, n: usize, field: &'static str) -> Result<(), String> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.body.len());
        match end {
            Some(e) => {
                self.pos = e;
                Ok(())
            }
            None => Err(format!(
                "{field} needs {n} bytes at byte {} of a {}-byte record",
                self.pos,
                self.body.len()
            )),
        }
    }

    fn len_prefix(&mut self, width: usize, field: &'static str) -> Result<usize, String> {
        let bytes = self
            .body
            .get(self.pos..self.pos + width)
            .ok_or_else(|| format!("{field}: its length is cut off"))?;
        let mut le = [0u8; 8];
        le[..width].copy_from_slice(bytes);
        self.pos += width;
        usize::try_from(u64::from_le_bytes(le)).map_err(|_| format!("{field}: length too large"))
    }

    /// A u32-length-prefixed string or byte array.
    fn prefixed32(&mut self, field: &'static str) -> Result<(), String> {
        let n = self.len_prefix(4, field)?;
        self.skip(n, field)
    }

    /// A u64-length-prefixed byte array.
    fn prefixed64(&mut self, field: &'static str) -> Result<(), String> {
        let n = self.len_prefix(8, field)?;
        self.skip(n, field)
    }

    /// A map of strings to strings: a u32 byte length, then entries.
    fn string_map(&mut self, field: &'static str) -> Result<(), String> {
        let n = self.len_prefix(4, field)?;
        let end = self.pos;
        self.skip(n, field)?;
        let mut inner = Fields {
            body: &self.body[end..end + n],
            pos: 0,
        };
        while inner.pos < inner.body.len() {
            inner.prefixed32(field)?;
            inner.prefixed32(field)?;
        }
        Ok(())
    }
}

/// Check the length prefixes of a record with opcode `op`.
pub(super) fn check(op: u8, body: &[u8]) -> Result<(), String> {
    let mut f = Fields { body, pos: 0 };
    match op {
        // Header: profile, library.
        0x01 => {
            f.prefixed32("header profile")?;
            f.prefixed32("header library")
        }
        // Schema: id, name, encoding, data.
        0x03 => {
            f.skip(2, "schema id")?;
            f.prefixed32("schema name")?;
            f.prefixed32("schema encoding")?;
            f.prefixed32("schema data")
        }
        // Channel: id, schema id, topic, encoding, metadata.
        0x04 => {
            f.skip(4, "channel ids")?;
            f.prefixed32("channel topic")?;
            f.prefixed32("channel message encoding")?;
            f.string_map("channel metadata")
        }
        // Chunk: times, sizes, crc, compression, records.
        0x06 => {
            f.skip(28, "chunk header")?;
            f.prefixed32("chunk compression")?;
            f.prefixed64("chunk records")
        }
        // Message index: channel id, (time, offset) array.
        0x07 => {
            f.skip(2, "message index channel")?;
            f.prefixed32("message index records")
        }
        // Chunk index: offsets and lengths, message index offsets, compression, sizes.
        0x08 => {
            f.skip(32, "chunk index header")?;
            f.prefixed32("chunk index message index offsets")?;
            f.skip(8, "chunk index message index length")?;
            f.prefixed32("chunk index compression")?;
            f.skip(16, "chunk index sizes")
        }
        // Attachment: times, name, media type, data, crc.
        0x09 => {
            f.skip(16, "attachment times")?;
            f.prefixed32("attachment name")?;
            f.prefixed32("attachment media type")?;
            f.prefixed64("attachment data")?;
            f.skip(4, "attachment crc")
        }
        // Attachment index: offsets, times, size, name, media type.
        0x0A => {
            f.skip(40, "attachment index header")?;
            f.prefixed32("attachment index name")?;
            f.prefixed32("attachment index media type")
        }
        // Statistics: counts, times, channel message counts.
        0x0B => {
            f.skip(42, "statistics counts")?;
            f.prefixed32("statistics channel message counts")
        }
        // Metadata: name, map.
        0x0C => {
            f.prefixed32("metadata name")?;
            f.string_map("metadata")
        }
        // Metadata index: offset, length, name.
        0x0D => {
            f.skip(16, "metadata index header")?;
            f.prefixed32("metadata index name")
        }
        // Footer, message, summary offset, data end: fixed fields only.
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_declared_length_beyond_the_record_is_refused_before_parsing() {
        // The 21-byte file the fuzzer found: a header whose profile string
        // declares 4 GiB.
        let header = [0x00, 0x00, 0x00, 0x00];
        assert!(check(0x01, &header[..0]).is_err());
        let profile_huge = [0xFF, 0xFF, 0xFF, 0xFF];
        let e = check(0x01, &profile_huge).unwrap_err();
        assert!(e.contains("header profile"), "{e}");
        // A good header: "ros1" and "x".
        let mut good = vec![4, 0, 0, 0];
        good.extend_from_slice(b"ros1");
        good.extend_from_slice(&[1, 0, 0, 0, b'x']);
        assert_eq!(check(0x01, &good), Ok(()));
        // A metadata map whose inner value declares more than the map holds.
        let mut meta = vec![1, 0, 0, 0, b'm'];
        let mut map = vec![1, 0, 0, 0, b'k'];
        map.extend_from_slice(&[0xF0, 0xFF, 0xFF, 0x7F]);
        meta.extend_from_slice(&(map.len() as u32).to_le_bytes());
        meta.extend_from_slice(&map);
        let e = check(0x0C, &meta).unwrap_err();
        assert!(e.contains("metadata"), "{e}");
    }
}

//! A reader of CDR (OMG XCDR version 1, the encoding rosbag2 stores):
//! a 4-byte encapsulation header (`00 00` big endian, `00 01` little
//! endian, then two option bytes), then the fields in order, each primitive
//! aligned to its own size counted from the end of the header. Strings are
//! a `u32` length (with the terminating NUL) and the bytes; sequences a
//! `u32` count and the elements; fixed arrays the elements alone.
//!
//! Every read checks the bounds; a declared length beyond the message is
//! an error, never an allocation.

/// Reads one CDR message.
pub(crate) struct Cdr<'a> {
    /// The message after the encapsulation header.
    data: &'a [u8],
    pos: usize,
    little: bool,
}

/// Why a message does not decode.
pub(crate) type CdrResult<T> = Result<T, String>;

impl<'a> Cdr<'a> {
    /// A reader of `message`, header included.
    pub fn new(message: &'a [u8]) -> CdrResult<Cdr<'a>> {
        let (header, data) = message.split_at_checked(4).ok_or_else(|| {
            format!(
                "{} bytes, too short for the 4-byte CDR encapsulation header",
                message.len()
            )
        })?;
        let little = match (header[0], header[1]) {
            (0, 0) => false,
            (0, 1) => true,
            (a, b) => {
                return Err(format!(
                    "encapsulation {a:02x} {b:02x} is not plain CDR (00 00 big endian or 00 01 little endian)"
                ))
            }
        };
        Ok(Cdr {
            data,
            pos: 0,
            little,
        })
    }

    fn align(&mut self, n: usize) -> CdrResult<()> {
        let pad = (n - self.pos % n) % n;
        self.take(pad, "padding").map(|_| ())
    }

    fn take(&mut self, n: usize, what: &str) -> CdrResult<&'a [u8]> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.data.len())
            .ok_or_else(|| {
                format!(
                    "the message ends at byte {} of its data, inside {what} (needs {n} bytes from byte {})",
                    self.data.len(),
                    self.pos
                )
            })?;
        let bytes = &self.data[self.pos..end];
        self.pos = end;
        Ok(bytes)
    }

    fn fixed<const N: usize>(&mut self, what: &str) -> CdrResult<[u8; N]> {
        self.align(N)?;
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N, what)?);
        if self.little == cfg!(target_endian = "big") {
            a.reverse();
        }
        Ok(a)
    }

    /// An `int8`/`uint8`.
    pub fn u8(&mut self, what: &str) -> CdrResult<u8> {
        Ok(self.take(1, what)?[0])
    }

    /// A `uint16`.
    pub fn u16(&mut self, what: &str) -> CdrResult<u16> {
        self.fixed::<2>(what).map(u16::from_ne_bytes)
    }

    /// A `uint32`.
    pub fn u32(&mut self, what: &str) -> CdrResult<u32> {
        self.fixed::<4>(what).map(u32::from_ne_bytes)
    }

    /// An `int32`.
    pub fn i32(&mut self, what: &str) -> CdrResult<i32> {
        self.fixed::<4>(what).map(i32::from_ne_bytes)
    }

    /// A `float64`.
    pub fn f64(&mut self, what: &str) -> CdrResult<f64> {
        self.fixed::<8>(what).map(f64::from_ne_bytes)
    }

    /// `N` `float64`s (a fixed array, or consecutive fields).
    pub fn f64s<const N: usize>(&mut self, what: &str) -> CdrResult<[f64; N]> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64(what)?;
        }
        Ok(out)
    }

    /// A sequence's element count, checked against the bytes left (each
    /// element takes at least `min_element_bytes`).
    fn count(&mut self, min_element_bytes: usize, what: &str) -> CdrResult<usize> {
        let n = self.u32(what)? as usize;
        let left = self.data.len() - self.pos;
        if n.saturating_mul(min_element_bytes) > left {
            return Err(format!(
                "{what} declares {n} elements but only {left} bytes follow"
            ));
        }
        Ok(n)
    }

    /// A `string` (UTF-8, its terminating NUL dropped).
    pub fn string(&mut self, what: &str) -> CdrResult<String> {
        let n = self.count(1, what)?;
        let bytes = self.take(n, what)?;
        let bytes = bytes.strip_suffix(&[0]).unwrap_or(bytes);
        String::from_utf8(bytes.to_vec()).map_err(|_| format!("{what} is not UTF-8"))
    }

    /// A `string[]`.
    pub fn strings(&mut self, what: &str) -> CdrResult<Vec<String>> {
        let n = self.count(4, what)?;
        (0..n).map(|_| self.string(what)).collect()
    }

    /// A `float64[]`.
    pub fn f64_seq(&mut self, what: &str) -> CdrResult<Vec<f64>> {
        let n = self.count(8, what)?;
        (0..n).map(|_| self.f64(what)).collect()
    }

    /// Skip `n` `float64`s.
    pub fn skip_f64s(&mut self, n: usize, what: &str) -> CdrResult<()> {
        for _ in 0..n {
            self.f64(what)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_counts_from_after_the_header_in_both_byte_orders() {
        // u8 1, then f64 2.5 aligned to 8, then string "ab".
        for little in [true, false] {
            let mut m = vec![0, u8::from(little), 0, 0, 1];
            m.extend_from_slice(&[0; 7]);
            let f = 2.5f64;
            m.extend_from_slice(&if little {
                f.to_le_bytes()
            } else {
                f.to_be_bytes()
            });
            let n = 3u32;
            m.extend_from_slice(&if little {
                n.to_le_bytes()
            } else {
                n.to_be_bytes()
            });
            m.extend_from_slice(b"ab\0");
            let mut c = Cdr::new(&m).expect("header");
            assert_eq!(c.u8("a"), Ok(1));
            assert_eq!(c.f64("b"), Ok(2.5));
            assert_eq!(c.string("c").as_deref(), Ok("ab"));
        }
    }

    #[test]
    fn a_huge_declared_length_is_an_error_not_an_allocation() {
        let m = [0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff];
        let mut c = Cdr::new(&m).expect("header");
        let e = c.f64_seq("velocity").expect_err("too long");
        assert!(e.contains("velocity"), "{e}");
        assert!(Cdr::new(&[0, 1]).is_err());
        assert!(Cdr::new(&[0, 2, 0, 0]).is_err());
    }
}

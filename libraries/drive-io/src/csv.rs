//! The small CSV dialect of drive folders: first non-comment line is the
//! header, comma separated, `#` starts a comment line, an empty cell is a
//! missing value, blank lines are skipped. Cells are trimmed. What
//! spreadsheets add is taken too: a UTF-8 byte-order mark before the header,
//! and header names or cells in double quotes (`"t_s"`; no comma inside).

use super::files::open_regular;
use super::DriveError;
use std::fmt::Write as _;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

/// Longest line of a drive CSV file, bytes (64 KiB: a row of the widest
/// stream is under 200 bytes). A longer line is
/// [`DriveError::LineTooLong`], found without reading the line whole.
pub const MAX_CSV_LINE_BYTES: usize = 64 << 10;

/// Most characters of a file's text (a cell, a column name, a key) quoted
/// in an error or warning; longer text is cut with an ellipsis.
const MAX_ECHO_CHARS: usize = 40;

/// `text` cut to [`MAX_ECHO_CHARS`] characters, with `…` when cut.
pub(super) fn clip(text: &str) -> String {
    match text.char_indices().nth(MAX_ECHO_CHARS) {
        Some((i, _)) => format!("{}…", &text[..i]),
        None => text.to_string(),
    }
}

/// Each line of a parser's message cut to a few times [`MAX_ECHO_CHARS`]
/// (a TOML error quotes the offending line, which may be huge).
pub(super) fn clip_lines(text: &str) -> String {
    const MAX: usize = 3 * MAX_ECHO_CHARS;
    text.lines()
        .map(|l| match l.char_indices().nth(MAX) {
            Some((i, _)) => format!("{}…", &l[..i]),
            None => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// A CSV file with its header parsed, read line by line.
pub(super) struct CsvFile {
    path: PathBuf,
    reader: Box<dyn BufRead>,
    /// Column names of the header.
    pub columns: Vec<String>,
    /// 1-based line of the header.
    pub header_line: usize,
    /// Which columns some caller asked for.
    claimed: Vec<bool>,
    /// The last data line, when it has no line end.
    unterminated_line: Option<usize>,
}

/// `s` without the double quotes around it, if it has them.
fn unquote(s: &str) -> &str {
    s.strip_prefix('"')
        .and_then(|t| t.strip_suffix('"'))
        .map_or(s, str::trim)
}

fn is_skipped(line: &str) -> bool {
    let t = line.trim();
    t.is_empty() || t.starts_with('#')
}

/// Read the next line (without its `\n`) into `buf`; `Ok(false)` at the end
/// of the file. `line` is the 1-based number of the line read, for errors.
fn next_line(
    reader: &mut dyn BufRead,
    buf: &mut Vec<u8>,
    path: &Path,
    line: usize,
) -> Result<bool, DriveError> {
    next_line_ended(reader, buf, path, line).map(|l| l.is_some())
}

/// [`next_line`], also saying whether the line had its line end: `Some(true)`
/// for a line ending in `\n`, `Some(false)` for a last line without one.
fn next_line_ended(
    reader: &mut dyn BufRead,
    buf: &mut Vec<u8>,
    path: &Path,
    line: usize,
) -> Result<Option<bool>, DriveError> {
    buf.clear();
    let limit = MAX_CSV_LINE_BYTES as u64 + 1;
    let n = reader
        .take(limit)
        .read_until(b'\n', buf)
        .map_err(|e| DriveError::io(path, e))?;
    if n == 0 {
        return Ok(None);
    }
    if buf.last() == Some(&b'\n') {
        buf.pop();
        return Ok(Some(true));
    }
    if buf.len() > MAX_CSV_LINE_BYTES {
        return Err(DriveError::LineTooLong {
            path: path.to_path_buf(),
            line,
            limit: MAX_CSV_LINE_BYTES,
        });
    }
    Ok(Some(false))
}

/// `Some("UTF-16BE")` or `Some("UTF-16LE")` when the first line is UTF-16
/// text (its byte-order mark, or ASCII with a NUL byte beside every
/// character), which reads as valid but meaningless UTF-8.
fn utf16(first_line: &[u8]) -> Option<&'static str> {
    match first_line {
        [0xfe, 0xff, ..] => return Some("UTF-16BE"),
        [0xff, 0xfe, ..] => return Some("UTF-16LE"),
        _ => {}
    }
    let pairs = first_line.len() / 2;
    if pairs < 2 {
        return None;
    }
    let nul_at = |k: usize| {
        first_line
            .chunks(2)
            .filter(|c| c.len() == 2 && c[k] == 0)
            .count()
    };
    if nul_at(0) == pairs {
        Some("UTF-16BE")
    } else if nul_at(1) == pairs {
        Some("UTF-16LE")
    } else {
        None
    }
}

fn as_text<'b>(buf: &'b [u8], path: &Path, line: usize) -> Result<&'b str, DriveError> {
    std::str::from_utf8(buf).map_err(|_| DriveError::NotUtf8 {
        path: path.to_path_buf(),
        line,
    })
}

impl CsvFile {
    /// Open `path` (a regular file only) and parse its header.
    pub fn open(path: &Path) -> Result<CsvFile, DriveError> {
        let (file, _) = open_regular(path)?;
        CsvFile::from_reader(path, Box::new(BufReader::with_capacity(1 << 16, file)))
    }

    /// Parse the header of the text `reader` gives (read from `path`).
    pub fn from_reader(path: &Path, mut reader: Box<dyn BufRead>) -> Result<CsvFile, DriveError> {
        let mut line_no = 0;
        let mut buf = Vec::new();
        let mut header = None;
        while next_line(reader.as_mut(), &mut buf, path, line_no + 1)? {
            line_no += 1;
            if line_no == 1 {
                if let Some(encoding) = utf16(&buf) {
                    return Err(DriveError::BadHeader {
                        path: path.to_path_buf(),
                        line: 1,
                        message: format!(
                            "the file is {encoding} encoded, not UTF-8: save it as UTF-8 (plain text)"
                        ),
                    });
                }
            }
            let mut line = as_text(&buf, path, line_no)?;
            if line_no == 1 {
                // A spreadsheet's UTF-8 byte-order mark.
                line = line.strip_prefix('\u{feff}').unwrap_or(line);
            }
            if !is_skipped(line) {
                header = Some(line.to_string());
                break;
            }
        }
        let Some(header) = header else {
            return Err(DriveError::BadHeader {
                path: path.to_path_buf(),
                line: line_no.max(1),
                message: "no header line (the file is empty)".to_string(),
            });
        };
        let columns: Vec<String> = header
            .split(',')
            .map(|c| unquote(c.trim()).to_string())
            .collect();
        for (i, c) in columns.iter().enumerate() {
            if c.is_empty() {
                return Err(DriveError::BadHeader {
                    path: path.to_path_buf(),
                    line: line_no,
                    message: format!("column {} of the header has no name", i + 1),
                });
            }
            if columns[..i].contains(c) {
                return Err(DriveError::BadHeader {
                    path: path.to_path_buf(),
                    line: line_no,
                    message: format!("column `{}` appears twice", clip(c)),
                });
            }
        }
        let claimed = vec![false; columns.len()];
        Ok(CsvFile {
            path: path.to_path_buf(),
            reader,
            columns,
            header_line: line_no,
            claimed,
            unterminated_line: None,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Index of column `name`, if present (and mark it as used).
    pub fn optional(&mut self, name: &str) -> Option<usize> {
        let i = self.columns.iter().position(|c| c == name)?;
        self.claimed[i] = true;
        Some(i)
    }

    /// Index of column `name`, or an error naming it.
    pub fn required(&mut self, name: &str) -> Result<usize, DriveError> {
        self.optional(name)
            .ok_or_else(|| DriveError::MissingColumn {
                path: self.path.clone(),
                line: self.header_line,
                column: name.to_string(),
            })
    }

    /// Mark column `i` as used.
    pub fn claim(&mut self, i: usize) {
        self.claimed[i] = true;
    }

    /// A warning when the last line has no line end (the file may have been
    /// cut while it was written), after [`CsvFile::for_each_row`].
    pub fn cut_warning(&self) -> Option<String> {
        self.unterminated_line.map(|line| {
            format!(
                "{}: line {line}, the last, has no line end: the file may have been cut while it was written \
                 (the line is read as it is; check its values)",
                self.path.display()
            )
        })
    }

    /// A warning listing the columns nobody asked for, if any.
    pub fn unknown_columns_warning(&self) -> Option<String> {
        let unknown: Vec<String> = self
            .columns
            .iter()
            .zip(&self.claimed)
            .filter(|(_, used)| !**used)
            .map(|(c, _)| clip(c))
            .collect();
        if unknown.is_empty() {
            None
        } else {
            Some(format!(
                "{}: ignored unknown column(s): {}",
                self.path.display(),
                unknown.join(", ")
            ))
        }
    }

    /// Call `f(row)` for every data row, in order (the file is read as it
    /// goes, one line at a time).
    pub fn for_each_row(
        &mut self,
        mut f: impl FnMut(&Row<'_>) -> Result<(), DriveError>,
    ) -> Result<(), DriveError> {
        let mut buf = Vec::with_capacity(256);
        let mut line_no = self.header_line;
        while let Some(ended) =
            next_line_ended(self.reader.as_mut(), &mut buf, &self.path, line_no + 1)?
        {
            line_no += 1;
            if !ended {
                self.unterminated_line = Some(line_no);
            }
            let line = as_text(&buf, &self.path, line_no)?;
            if is_skipped(line) {
                continue;
            }
            let mut cells: Vec<&str> = Vec::with_capacity(self.columns.len());
            cells.extend(line.split(',').map(|c| unquote(c.trim())));
            if cells.len() != self.columns.len() {
                return Err(DriveError::CellCount {
                    path: self.path.clone(),
                    line: line_no,
                    expected: self.columns.len(),
                    found: cells.len(),
                });
            }
            f(&Row {
                path: &self.path,
                columns: &self.columns,
                line: line_no,
                cells: &cells,
            })?;
        }
        Ok(())
    }
}

/// One data row.
pub(super) struct Row<'a> {
    path: &'a Path,
    columns: &'a [String],
    /// 1-based line number.
    pub line: usize,
    cells: &'a [&'a str],
}

impl Row<'_> {
    /// The value of column `i`: `None` when the cell is empty, an error when
    /// it is not a finite number.
    pub fn get(&self, i: usize) -> Result<Option<f64>, DriveError> {
        let cell = self.cells[i];
        if cell.is_empty() {
            return Ok(None);
        }
        match cell.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Some(v)),
            Ok(_) => Err(self.bad_cell(i, "NaN or infinite values are not allowed")),
            Err(_) => Err(self.bad_cell(i, "not a number")),
        }
    }

    /// The value of column `i`, which must not be empty.
    pub fn need(&self, i: usize) -> Result<f64, DriveError> {
        self.get(i)?.ok_or_else(|| DriveError::MissingValue {
            path: self.path.to_path_buf(),
            line: self.line,
            column: clip(&self.columns[i]),
        })
    }

    /// The value of an optional column.
    pub fn opt(&self, i: Option<usize>) -> Result<Option<f64>, DriveError> {
        match i {
            Some(i) => self.get(i),
            None => Ok(None),
        }
    }

    /// A [`DriveError::BadCell`] for column `i` of this row (the cell's
    /// text cut to 40 characters).
    pub fn bad_cell(&self, i: usize, reason: &'static str) -> DriveError {
        DriveError::BadCell {
            path: self.path.to_path_buf(),
            line: self.line,
            column: clip(&self.columns[i]),
            cell: clip(self.cells[i]).into(),
            reason,
        }
    }

    /// Error unless `t` is greater than `previous`; then remember `t`.
    pub fn check_time(&self, t: f64, previous: &mut Option<f64>) -> Result<(), DriveError> {
        if let Some(p) = *previous {
            if t <= p {
                return Err(DriveError::TimeNotIncreasing {
                    path: self.path.to_path_buf(),
                    line: self.line,
                    t_s: t,
                    previous_t_s: p,
                });
            }
        }
        *previous = Some(t);
        Ok(())
    }
}

/// Builds CSV text; floats use Rust's shortest round-trip formatting so that
/// reading back gives the same bits.
pub(super) struct CsvWriter {
    out: String,
}

impl CsvWriter {
    /// Start with a header.
    pub fn new(columns: &[&str], rows: usize) -> CsvWriter {
        let mut out = String::with_capacity(16 * columns.len() * (rows + 1));
        out.push_str(&columns.join(","));
        out.push('\n');
        CsvWriter { out }
    }

    /// Append one row; `None` is an empty cell.
    pub fn row(&mut self, cells: &[Option<f64>]) {
        for (i, c) in cells.iter().enumerate() {
            if i > 0 {
                self.out.push(',');
            }
            if let Some(v) = c {
                // Writing to a String cannot fail.
                let _ = write!(self.out, "{v}");
            }
        }
        self.out.push('\n');
    }

    /// The text.
    pub fn finish(self) -> String {
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> (Vec<String>, Vec<Vec<Option<f64>>>) {
        let reader = Box::new(std::io::Cursor::new(text.as_bytes().to_vec()));
        let mut f = CsvFile::from_reader(Path::new("wheels.csv"), reader).expect("header");
        let n = f.columns.len();
        let mut rows = Vec::new();
        f.for_each_row(|r| {
            rows.push((0..n).map(|i| r.get(i)).collect::<Result<Vec<_>, _>>()?);
            Ok(())
        })
        .expect("rows");
        (f.columns.clone(), rows)
    }

    #[test]
    fn a_byte_order_mark_and_quoted_names_read_like_the_plain_file() {
        let plain = read("t_s,rl_rev\n0.0,1.5\n0.1,1.6\n");
        let spreadsheet = read("\u{feff}\"t_s\",\"rl_rev\"\r\n\"0.0\",1.5\r\n0.1,\"1.6\"\r\n");
        assert_eq!(plain.0, vec!["t_s", "rl_rev"]);
        assert_eq!(spreadsheet, plain);
    }

    #[test]
    fn a_byte_order_mark_later_in_the_file_is_not_taken_away() {
        let reader = Box::new(std::io::Cursor::new(
            "t_s,rl_rev\n\u{feff}0.0,1.5\n".as_bytes().to_vec(),
        ));
        let mut f = CsvFile::from_reader(Path::new("wheels.csv"), reader).expect("header");
        let err = f.for_each_row(|r| r.get(0).map(|_| ())).unwrap_err();
        assert!(err.to_string().contains("wheels.csv"), "{err}");
    }
}

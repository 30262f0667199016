//! The small CSV dialect of drive folders: first non-comment line is the
//! header, comma separated, `#` starts a comment line, an empty cell is a
//! missing value, blank lines are skipped. Cells are trimmed.

use super::DriveError;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A CSV file's text with its header parsed.
pub(super) struct CsvFile {
    path: PathBuf,
    text: String,
    /// Column names of the header.
    pub columns: Vec<String>,
    /// 1-based line of the header.
    pub header_line: usize,
    /// Byte offset of the first line after the header.
    body_start: usize,
    /// Which columns some caller asked for.
    claimed: Vec<bool>,
}

fn is_skipped(line: &str) -> bool {
    let t = line.trim();
    t.is_empty() || t.starts_with('#')
}

impl CsvFile {
    /// Read and parse the header of `path`.
    pub fn open(path: &Path) -> Result<CsvFile, DriveError> {
        let text = std::fs::read_to_string(path).map_err(|e| DriveError::io(path, e))?;
        CsvFile::from_text(path, text)
    }

    /// Parse the header of `text` (read from `path`).
    pub fn from_text(path: &Path, text: String) -> Result<CsvFile, DriveError> {
        let mut offset = 0;
        let mut line_no = 0;
        let mut header = None;
        for line in text.split_inclusive('\n') {
            line_no += 1;
            offset += line.len();
            if !is_skipped(line) {
                header = Some(line);
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
        let columns: Vec<String> = header.split(',').map(|c| c.trim().to_string()).collect();
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
                    message: format!("column `{c}` appears twice"),
                });
            }
        }
        let claimed = vec![false; columns.len()];
        Ok(CsvFile {
            path: path.to_path_buf(),
            text,
            columns,
            header_line: line_no,
            body_start: offset,
            claimed,
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

    /// A warning listing the columns nobody asked for, if any.
    pub fn unknown_columns_warning(&self) -> Option<String> {
        let unknown: Vec<&str> = self
            .columns
            .iter()
            .zip(&self.claimed)
            .filter(|(_, used)| !**used)
            .map(|(c, _)| c.as_str())
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

    /// Call `f(row)` for every data row, in order.
    pub fn for_each_row(
        &self,
        mut f: impl FnMut(&Row<'_>) -> Result<(), DriveError>,
    ) -> Result<(), DriveError> {
        let mut cells: Vec<&str> = Vec::with_capacity(self.columns.len());
        let lines = self.text[self.body_start..].split('\n');
        for (line_no, line) in (self.header_line + 1..).zip(lines) {
            if is_skipped(line) {
                continue;
            }
            cells.clear();
            cells.extend(line.split(',').map(str::trim));
            if cells.len() != self.columns.len() {
                return Err(DriveError::CellCount {
                    path: self.path.clone(),
                    line: line_no,
                    expected: self.columns.len(),
                    found: cells.len(),
                });
            }
            f(&Row {
                file: self,
                line: line_no,
                cells: &cells,
            })?;
        }
        Ok(())
    }
}

/// One data row.
pub(super) struct Row<'a> {
    file: &'a CsvFile,
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
            path: self.file.path.clone(),
            line: self.line,
            column: self.file.columns[i].clone(),
        })
    }

    /// The value of an optional column.
    pub fn opt(&self, i: Option<usize>) -> Result<Option<f64>, DriveError> {
        match i {
            Some(i) => self.get(i),
            None => Ok(None),
        }
    }

    /// A [`DriveError::BadCell`] for column `i` of this row.
    pub fn bad_cell(&self, i: usize, reason: &'static str) -> DriveError {
        DriveError::BadCell {
            path: self.file.path.clone(),
            line: self.line,
            column: self.file.columns[i].clone(),
            cell: self.cells[i].into(),
            reason,
        }
    }

    /// Error unless `t` is greater than `previous`; then remember `t`.
    pub fn check_time(&self, t: f64, previous: &mut Option<f64>) -> Result<(), DriveError> {
        if let Some(p) = *previous {
            if t <= p {
                return Err(DriveError::TimeNotIncreasing {
                    path: self.file.path.clone(),
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

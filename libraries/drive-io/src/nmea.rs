//! NMEA 0183 GNSS logs: the GNSS stream of a drive folder may be a
//! `gnss.nmea` file (the receiver's log as it is) in place of `gnss.csv`.
//!
//! - Sentences: `GGA` (time of day, position, fix quality) and `RMC` (time
//!   of day, date, position, status), any talker (`GP`, `GN`, `GL`, ...).
//!   Every other sentence is counted in a warning and ignored.
//! - Every line must be a sentence `$...*hh` whose checksum (the XOR of
//!   the bytes between `$` and `*`) matches; an empty line is skipped; any
//!   other line is an error naming its number ([`DriveError::Nmea`]).
//! - One fix per time of day: a GGA and an RMC of the same second are one
//!   fix (the GGA's position). A GGA with quality 0 and an RMC with status
//!   `V` (no fix) give no fix; each such sentence is counted in a warning.
//! - Times: `t_s` is seconds since the UNIX epoch (UTC, leap seconds not
//!   counted, as UNIX time does): the date from the RMC sentences, the
//!   time of day from each sentence, a day added when the time of day goes
//!   back by more than 12 h (midnight). A log without RMC has no date:
//!   `t_s` is then seconds since 00:00 UTC of its first day (a warning
//!   says so). The other files of the drive folder must use the same clock.
//! - No `sigma_m`: neither sentence gives a position's standard deviation
//!   (HDOP is not one).

use crate::csv::clip;
use crate::files::read_regular;
use crate::DriveError;
use std::path::Path;

/// The file name of an NMEA log in a drive folder.
pub const NMEA_FILE: &str = "gnss.nmea";

/// A fix of an NMEA log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NmeaFix {
    /// Time, s (see the module documentation for the clock).
    pub t_s: f64,
    /// Latitude, degrees (WGS84), north positive.
    pub lat_deg: f64,
    /// Longitude, degrees, east positive.
    pub lon_deg: f64,
}

/// An NMEA log read: its fixes in time order and the warnings.
#[derive(Debug, Clone, PartialEq)]
pub struct NmeaLog {
    /// The fixes, times strictly increasing.
    pub fixes: Vec<NmeaFix>,
    /// True when an RMC sentence gave the date (times are UNIX time).
    pub dated: bool,
    /// Human-readable warnings, each naming the file.
    pub warnings: Vec<String>,
}

/// Read an NMEA 0183 log file (see the module documentation).
pub fn read_nmea(path: &Path) -> Result<NmeaLog, DriveError> {
    let bytes = read_regular(path)?;
    parse_nmea(path, &bytes)
}

/// One sentence's contribution.
struct Sentence {
    line: usize,
    /// Time of day, s.
    tod: f64,
    /// Days since the UNIX epoch (RMC only).
    date: Option<i64>,
    /// Position, when the sentence says there is a fix.
    position: Option<(f64, f64)>,
    /// A GGA (its position is preferred).
    gga: bool,
}

/// Parse an NMEA 0183 log's bytes (`path` names it in errors).
pub fn parse_nmea(path: &Path, bytes: &[u8]) -> Result<NmeaLog, DriveError> {
    let read = read_sentences(path, bytes)?;
    let mut warnings = read.warnings(path);
    let (epochs, date0) = epochs(path, read.sentences)?;
    if date0.is_none() && !epochs.is_empty() {
        warnings.push(format!(
            "{}: no RMC sentence gives the date: t_s is seconds since 00:00 UTC of the log's first day",
            path.display()
        ));
    }
    let base = date0.map_or(0, |(d, _)| d);
    let fixes = epochs
        .into_iter()
        .filter_map(|e| {
            let (lat_deg, lon_deg) = e.position?;
            Some(NmeaFix {
                t_s: ((base + e.day) * 86_400) as f64 + e.tod,
                lat_deg,
                lon_deg,
            })
        })
        .collect();
    Ok(NmeaLog {
        fixes,
        dated: date0.is_some(),
        warnings,
    })
}

/// An NMEA error at `line` of `path`.
fn nmea_error(path: &Path, line: usize, message: String) -> DriveError {
    DriveError::Nmea {
        path: path.to_path_buf(),
        line,
        message,
    }
}

/// The GGA and RMC sentences of a log, and what was left out.
struct ReadSentences {
    sentences: Vec<Sentence>,
    /// Sentences other than GGA and RMC.
    other: usize,
    /// Sentences that say there is no fix.
    no_fix: usize,
}

impl ReadSentences {
    /// What the reading says about the sentences left out.
    fn warnings(&self, path: &Path) -> Vec<String> {
        let mut warnings = Vec::new();
        let p = path.display();
        let (other, no_fix) = (self.other, self.no_fix);
        if other > 0 {
            warnings.push(format!(
                "{p}: ignored {other} sentence(s) other than GGA and RMC"
            ));
        }
        if no_fix > 0 {
            warnings.push(format!(
                "{p}: {no_fix} sentence(s) say there is no fix (GGA quality 0, RMC status V): no fix taken from them"
            ));
        }
        warnings
    }
}

/// Every line of the log checked and its GGA and RMC sentences parsed.
fn read_sentences(path: &Path, bytes: &[u8]) -> Result<ReadSentences, DriveError> {
    let err = |line: usize, message: String| nmea_error(path, line, message);
    let mut read = ReadSentences {
        sentences: Vec::new(),
        other: 0,
        no_fix: 0,
    };
    for (k, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = k + 1;
        let text = std::str::from_utf8(raw)
            .map_err(|_| err(line, "not valid UTF-8 text".to_string()))?
            .trim();
        if text.is_empty() {
            continue;
        }
        let fields = checked_fields(text).map_err(|m| err(line, m))?;
        let kind = fields[0];
        if kind.starts_with('P') || kind.len() != 5 {
            read.other += 1;
            continue;
        }
        let s = match &kind[2..] {
            "GGA" => gga(&fields),
            "RMC" => rmc(&fields),
            _ => {
                read.other += 1;
                continue;
            }
        }
        .map_err(|m| err(line, format!("{kind}: {m}")))?;
        let Some(mut s) = s else {
            continue;
        };
        s.line = line;
        if s.position.is_none() {
            read.no_fix += 1;
        }
        read.sentences.push(s);
    }
    Ok(read)
}

/// The sentences of one time of day.
struct Epoch {
    line: usize,
    day: i64,
    tod: f64,
    position: Option<(f64, f64)>,
    from_gga: bool,
}

/// The log's first day (days since the UNIX epoch) and the line of the
/// RMC that gave it, when one does.
type FirstDay = Option<(i64, usize)>;

/// The sentences grouped by time of day, with the days counted across
/// midnight (a GGA's position preferred), and the log's first day (days
/// since the UNIX epoch) with the line that gave it, when an RMC dates it.
/// An error when the time of day goes back, or the dates disagree.
fn epochs(path: &Path, sentences: Vec<Sentence>) -> Result<(Vec<Epoch>, FirstDay), DriveError> {
    let err = |line: usize, message: String| nmea_error(path, line, message);
    let mut epochs: Vec<Epoch> = Vec::new();
    let mut date0: FirstDay = None;
    for s in sentences {
        let day = match epochs.last_mut() {
            Some(e) if e.tod == s.tod => {
                if s.position.is_some() && (e.position.is_none() || (s.gga && !e.from_gga)) {
                    e.position = s.position;
                    e.from_gga = s.gga;
                }
                e.day
            }
            last => {
                let day = match last {
                    None => 0,
                    Some(e) if s.tod < e.tod - 43_200.0 => e.day + 1,
                    Some(e) if s.tod < e.tod => {
                        return Err(err(
                            s.line,
                            format!(
                                "time of day {} s is before the previous sentence's {} s (line {}); times must increase",
                                s.tod, e.tod, e.line
                            ),
                        ))
                    }
                    Some(e) => e.day,
                };
                epochs.push(Epoch {
                    line: s.line,
                    day,
                    tod: s.tod,
                    position: s.position,
                    from_gga: s.gga,
                });
                day
            }
        };
        if let Some(date) = s.date {
            let first_day = date - day;
            match date0 {
                None => date0 = Some((first_day, s.line)),
                Some((d, l)) if d != first_day => {
                    return Err(err(
                        s.line,
                        format!(
                            "the date is {}, but the sentences since line {l} put it at {}",
                            civil(date),
                            civil(d + day)
                        ),
                    ))
                }
                Some(_) => {}
            }
        }
    }
    Ok((epochs, date0))
}

/// The fields of a `$...*hh` sentence whose checksum matches (the first
/// is the talker and type, e.g. `GPGGA`).
fn checked_fields(text: &str) -> Result<Vec<&str>, String> {
    let Some(body) = text.strip_prefix('$') else {
        return Err(format!(
            "not an NMEA sentence (it must start with `$`): `{}`",
            clip(text)
        ));
    };
    let Some((data, sum)) = body.rsplit_once('*') else {
        return Err(format!("no checksum (`*hh` at the end): `{}`", clip(text)));
    };
    let stated = u8::from_str_radix(sum, 16)
        .ok()
        .filter(|_| sum.len() == 2)
        .ok_or_else(|| format!("checksum `{}` is not two hex digits", clip(sum)))?;
    let actual = data.bytes().fold(0u8, |a, b| a ^ b);
    if actual != stated {
        return Err(format!(
            "checksum mismatch: the sentence says {stated:02X}, its bytes give {actual:02X}"
        ));
    }
    let fields: Vec<&str> = data.split(',').collect();
    if fields[0].is_empty() || !fields[0].bytes().all(|b| b.is_ascii_alphanumeric()) {
        return Err(format!("`{}` is not a sentence type", clip(fields[0])));
    }
    Ok(fields)
}

fn field<'a>(fields: &[&'a str], i: usize, name: &str) -> Result<&'a str, String> {
    fields
        .get(i)
        .copied()
        .ok_or_else(|| format!("too few fields (no {name})"))
}

/// `hhmmss.ss` → seconds of the day.
fn time_of_day(text: &str) -> Result<f64, String> {
    let bad = || format!("time `{}` is not hhmmss[.ss]", clip(text));
    if text.len() < 6 || !text.is_char_boundary(6) {
        return Err(bad());
    }
    let (hms, frac) = text.split_at(6);
    if !hms.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    let num = |r: std::ops::Range<usize>| hms[r].parse::<u32>().map_err(|_| bad());
    let (h, m, s) = (num(0..2)?, num(2..4)?, num(4..6)?);
    let frac = if frac.is_empty() {
        0.0
    } else {
        let digits = frac.strip_prefix('.').ok_or_else(bad)?;
        if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad());
        }
        format!("0.{digits}").parse::<f64>().map_err(|_| bad())?
    };
    // 60 seconds: a leap second.
    if h > 23 || m > 59 || s > 60 {
        return Err(bad());
    }
    Ok(f64::from(h * 3600 + m * 60 + s) + frac)
}

/// `ddmm.mmmm`/`dddmm.mmmm` and a hemisphere → signed degrees.
fn angle(text: &str, hemi: &str, lat: bool) -> Result<f64, String> {
    let what = if lat { "latitude" } else { "longitude" };
    let bad = || format!("{what} `{}` `{}` is not a position", clip(text), clip(hemi));
    let deg_digits = if lat { 2 } else { 3 };
    let dot = text.find('.').unwrap_or(text.len());
    if dot != deg_digits + 2 || !text.is_char_boundary(deg_digits) {
        return Err(bad());
    }
    let (d, m) = text.split_at(deg_digits);
    if !d.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    let deg: f64 = d.parse().map_err(|_| bad())?;
    let min: f64 = m.parse().map_err(|_| bad())?;
    if !(0.0..60.0).contains(&min) || !min.is_finite() {
        return Err(bad());
    }
    let v = deg + min / 60.0;
    let sign = match (hemi, lat) {
        ("N", true) | ("E", false) => 1.0,
        ("S", true) | ("W", false) => -1.0,
        _ => return Err(bad()),
    };
    if v > if lat { 90.0 } else { 180.0 } {
        return Err(bad());
    }
    Ok(sign * v)
}

/// A GGA: `None` when its time is empty (a receiver without time yet).
fn gga(f: &[&str]) -> Result<Option<Sentence>, String> {
    let time = field(f, 1, "time")?;
    if time.is_empty() {
        return Ok(None);
    }
    let tod = time_of_day(time)?;
    let quality = field(f, 6, "fix quality")?;
    let quality: u8 = quality
        .parse()
        .map_err(|_| format!("fix quality `{}` is not a number", clip(quality)))?;
    let position = if quality == 0 {
        None
    } else {
        Some((
            angle(field(f, 2, "latitude")?, field(f, 3, "N/S")?, true)?,
            angle(field(f, 4, "longitude")?, field(f, 5, "E/W")?, false)?,
        ))
    };
    Ok(Some(Sentence {
        line: 0,
        tod,
        date: None,
        position,
        gga: true,
    }))
}

/// An RMC: `None` when its time is empty.
fn rmc(f: &[&str]) -> Result<Option<Sentence>, String> {
    let time = field(f, 1, "time")?;
    if time.is_empty() {
        return Ok(None);
    }
    let tod = time_of_day(time)?;
    let status = field(f, 2, "status")?;
    let position = match status {
        "A" => Some((
            angle(field(f, 3, "latitude")?, field(f, 4, "N/S")?, true)?,
            angle(field(f, 5, "longitude")?, field(f, 6, "E/W")?, false)?,
        )),
        "V" => None,
        other => return Err(format!("status `{}` is neither A nor V", clip(other))),
    };
    let date = field(f, 9, "date")?;
    let date = if date.is_empty() {
        None
    } else {
        Some(days_of_ddmmyy(date)?)
    };
    Ok(Some(Sentence {
        line: 0,
        tod,
        date,
        position,
        gga: false,
    }))
}

/// `ddmmyy` → days since 1970-01-01 (years 80-99 are 19xx, else 20xx).
fn days_of_ddmmyy(text: &str) -> Result<i64, String> {
    let bad = || format!("date `{}` is not ddmmyy", clip(text));
    if text.len() != 6 || !text.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    let num = |r: std::ops::Range<usize>| text[r].parse::<i64>().map_err(|_| bad());
    let (d, m, y) = (num(0..2)?, num(2..4)?, num(4..6)?);
    let year = if y >= 80 { 1900 + y } else { 2000 + y };
    let leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
    let days_in_month = [
        31,
        if leap { 29 } else { 28 },
        31,
        30,
        31,
        30,
        31,
        31,
        30,
        31,
        30,
        31,
    ];
    if !(1..=12).contains(&m) || d < 1 || d > days_in_month[(m - 1) as usize] {
        return Err(bad());
    }
    Ok(days_from_civil(year, m, d))
}

/// Days since 1970-01-01 of a proleptic Gregorian date.
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// `YYYY-MM-DD` of days since 1970-01-01.
fn civil(days: i64) -> String {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!("{y:04}-{m:02}-{d:02}")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sentence(body: &str) -> String {
        let sum = body.bytes().fold(0u8, |a, b| a ^ b);
        format!("${body}*{sum:02X}")
    }

    #[test]
    fn gga_and_rmc_give_unix_time_and_degrees() {
        let log = [
            sentence("GPRMC,235959.50,A,4807.0380,N,01131.0000,E,022.4,084.4,311299,003.1,W"),
            sentence("GPGGA,235959.50,4807.0390,N,01131.0000,E,1,08,0.9,545.4,M,46.9,M,,"),
            sentence("GPGSV,3,1,11,03,03,111,00"),
            sentence("GPGGA,000000.50,4807.0400,S,01131.0000,W,1,08,0.9,545.4,M,46.9,M,,"),
            String::new(),
        ]
        .join("\r\n");
        let r = parse_nmea(Path::new("g.nmea"), log.as_bytes()).expect("parse");
        assert!(r.dated);
        assert_eq!(r.fixes.len(), 2);
        // 1999-12-31 23:59:59.5 UTC.
        assert_eq!(r.fixes[0].t_s, 946_684_799.5);
        assert_eq!(r.fixes[1].t_s, 946_684_800.5);
        // The GGA's position, not the RMC's.
        assert!((r.fixes[0].lat_deg - (48.0 + 7.039 / 60.0)).abs() < 1e-12);
        assert!(r.fixes[1].lat_deg < 0.0 && r.fixes[1].lon_deg < 0.0);
        assert_eq!(civil(days_from_civil(2024, 2, 29)), "2024-02-29");
    }

    #[test]
    fn bad_lines_are_errors_naming_the_line() {
        let good = sentence("GPGGA,120000,4807.0390,N,01131.0000,E,1,08,0.9,545.4,M,46.9,M,,");
        let bad_sum = format!("{}0", &good[..good.len() - 1]);
        for (text, needle) in [
            (format!("{good}\n{bad_sum}\n"), "checksum mismatch"),
            (format!("{good}\nhello\n"), "not an NMEA sentence"),
            (format!("{good}\n$GPGGA,1\n"), "no checksum"),
        ] {
            match parse_nmea(Path::new("g.nmea"), text.as_bytes()) {
                Err(DriveError::Nmea { line, message, .. }) => {
                    assert_eq!(line, 2, "{message}");
                    assert!(message.contains(needle), "{message}");
                }
                other => panic!("{other:?}"),
            }
        }
    }
}

//! The drive folder (`shared/design/drive-format.md`), read and written.

use super::csv::{clip, clip_lines, CsvFile, CsvWriter, Row};
use super::files::{read_text_limited, regular_file_present, MAX_TEXT_FILE_BYTES};
use super::geodesy::LocalFrame;
use super::streams::{wheel_column_names, wheel_value, Stream, MAX_FIELDS, WHEELS_CSV};
use super::{DriveError, LoadedDrive};
use interfaces::drive::{
    Drive, GnssSample, HeadingSample, ImuSample, TruthParams, TruthSample, VehicleParams, Wheel,
    WheelSample, WheelSeries, WheelUnit, WheelUnits,
};
use std::path::{Path, PathBuf};

/// File names of the format (the stream files' names are in `streams`).
const VEHICLE_TOML: &str = "vehicle.toml";
const TRUTH_TOML: &str = "truth.toml";
const ALL_FILES: [&str; 7] = [
    VEHICLE_TOML,
    WHEELS_CSV,
    GnssSample::CSV_FILE,
    ImuSample::CSV_FILE,
    HeadingSample::CSV_FILE,
    TruthSample::CSV_FILE,
    TRUTH_TOML,
];

/// Keys `vehicle.toml` knows; others are ignored with a warning.
const VEHICLE_KEYS: [&str; 6] = [
    "name",
    "track_width_m",
    "nominal_circumference_m",
    "wheelbase_m",
    "ticks_per_rev",
    "gnss",
];
const GNSS_KEYS: [&str; 4] = [
    "antenna_x_m",
    "antenna_y_m",
    "origin_lat_deg",
    "origin_lon_deg",
];

// ---------------------------------------------------------------- reading

/// Read a drive folder; `given` vehicle parameters stand in for its
/// `vehicle.toml`.
pub(super) fn read_folder(
    dir: &Path,
    given: Option<&VehicleParams>,
) -> Result<LoadedDrive, DriveError> {
    let mut warnings = Vec::new();
    let vehicle_path = dir.join(VEHICLE_TOML);
    let present = regular_file_present(&vehicle_path)?;
    let mut vehicle = match given {
        Some(v) => {
            if present {
                warnings.push(format!(
                    "{}: not read: the vehicle parameters given stand in for it",
                    vehicle_path.display()
                ));
            }
            v.clone()
        }
        None if !present => return Err(DriveError::MissingFile { path: vehicle_path }),
        None => {
            let text = read_text_limited(&vehicle_path, MAX_TEXT_FILE_BYTES)?;
            parse_vehicle_toml(&vehicle_path, &text, &mut warnings)?
        }
    };

    let wheels_path = dir.join(WHEELS_CSV);
    if !regular_file_present(&wheels_path)? {
        return Err(DriveError::MissingFile { path: wheels_path });
    }
    let wheels = read_wheels(&wheels_path, &vehicle, &mut warnings)?;

    let gnss = match (
        optional_stream::<GnssSample>(dir, &mut warnings)?,
        optional_file(dir, crate::nmea::NMEA_FILE)?,
    ) {
        (Some(_), Some(nmea)) => {
            return Err(DriveError::Nmea {
                path: nmea,
                line: 1,
                message: format!(
                    "the folder also has {}: give the GNSS fixes in one of them",
                    GnssSample::CSV_FILE
                ),
            })
        }
        (None, Some(nmea)) => {
            // Latitude and longitude in x_m, y_m until `into_enu`, as for
            // a lat/lon gnss.csv.
            let log = crate::nmea::read_nmea(&nmea)?;
            warnings.extend(log.warnings);
            let samples = log
                .fixes
                .iter()
                .map(|f| GnssSample {
                    t_s: f.t_s,
                    x_m: f.lat_deg,
                    y_m: f.lon_deg,
                    sigma_m: None,
                })
                .collect();
            Some(RawStream {
                position: PositionKind::LatLon,
                samples,
            })
        }
        (gnss, None) => gnss,
    };
    let imu = optional_stream::<ImuSample>(dir, &mut warnings)?;
    let heading = optional_stream::<HeadingSample>(dir, &mut warnings)?;
    let truth = optional_stream::<TruthSample>(dir, &mut warnings)?;
    let truth_params = match optional_file(dir, TRUTH_TOML)? {
        Some(p) => {
            let text = read_text_limited(&p, MAX_TEXT_FILE_BYTES)?;
            Some(parse_truth_toml(&p, &text)?)
        }
        None => None,
    };

    // One ENU origin for every lat/lon file: vehicle.toml's, else the first
    // GNSS fix, else the first truth position.
    let frame = local_frame(
        &vehicle_path,
        &mut vehicle,
        [
            gnss.as_ref().and_then(RawStream::lat_lon_start),
            truth.as_ref().and_then(RawStream::lat_lon_start),
        ],
    )?;
    let gnss = gnss.map(|raw| raw.into_enu(frame.as_ref()));
    let imu = imu.map(|raw| raw.samples);
    let heading = heading.map(|raw| raw.samples);
    let truth = truth.map(|raw| raw.into_enu(frame.as_ref()));

    warn_about_other_files(dir, &mut warnings);
    Ok(LoadedDrive {
        drive: Drive {
            vehicle,
            wheels,
            gnss,
            imu,
            heading,
            truth,
            truth_params,
        },
        warnings,
    })
}

/// `dir/name` when it is there: `None` when nothing is at that path, an
/// error when something other than a regular file is (a directory, a FIFO,
/// a link to a device is not "no such stream").
fn optional_file(dir: &Path, name: &str) -> Result<Option<PathBuf>, DriveError> {
    let p = dir.join(name);
    Ok(regular_file_present(&p)?.then_some(p))
}

/// Read stream `S`'s file when the folder has it.
fn optional_stream<S: Stream>(
    dir: &Path,
    warnings: &mut Vec<String>,
) -> Result<Option<RawStream<S>>, DriveError> {
    optional_file(dir, S::CSV_FILE)?
        .map(|p| read_stream(&p, warnings))
        .transpose()
}

/// CSV and TOML files in the folder that the format does not know.
fn warn_about_other_files(dir: &Path, warnings: &mut Vec<String>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let mut others: Vec<String> = entries
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| {
            (n.ends_with(".csv") || n.ends_with(".toml")) && !ALL_FILES.contains(&n.as_str())
        })
        .collect();
    if !others.is_empty() {
        others.sort();
        warnings.push(format!(
            "{}: ignored file(s) that are not part of the drive-folder format: {}",
            dir.display(),
            others.join(", ")
        ));
    }
}

/// The numeric values of `vehicle.toml` by key (`gnss.` keys in the
/// `[gnss]` table); each must be finite.
pub(super) fn vehicle_values(v: &VehicleParams) -> [(&'static str, Option<f64>); 8] {
    [
        ("track_width_m", Some(v.track_width_m)),
        ("nominal_circumference_m", Some(v.nominal_circumference_m)),
        ("wheelbase_m", v.wheelbase_m),
        ("ticks_per_rev", v.ticks_per_rev),
        ("gnss.antenna_x_m", v.gnss.antenna_x_m),
        ("gnss.antenna_y_m", v.gnss.antenna_y_m),
        ("gnss.origin_lat_deg", v.gnss.origin_lat_deg),
        ("gnss.origin_lon_deg", v.gnss.origin_lon_deg),
    ]
}

/// Parse `vehicle.toml` text; unknown keys become a warning.
pub(super) fn parse_vehicle_toml(
    path: &Path,
    text: &str,
    warnings: &mut Vec<String>,
) -> Result<VehicleParams, DriveError> {
    let toml_error = |e: toml::de::Error| DriveError::Toml {
        path: path.to_path_buf(),
        message: clip_lines(e.to_string().trim_end()),
    };
    let table: toml::Table = toml::from_str(text).map_err(toml_error)?;
    let mut unknown: Vec<String> = table
        .keys()
        .filter(|k| !VEHICLE_KEYS.contains(&k.as_str()))
        .cloned()
        .collect();
    if let Some(toml::Value::Table(g)) = table.get("gnss") {
        unknown.extend(
            g.keys()
                .filter(|k| !GNSS_KEYS.contains(&k.as_str()))
                .map(|k| format!("gnss.{k}")),
        );
    }
    if !unknown.is_empty() {
        let listed: Vec<String> = unknown.iter().map(|k| clip(k)).collect();
        warnings.push(format!(
            "{}: ignored unknown key(s): {}",
            path.display(),
            listed.join(", ")
        ));
    }
    let vehicle: VehicleParams = toml::from_str(text).map_err(toml_error)?;
    for (key, value) in vehicle_values(&vehicle) {
        if let Some(v) = value {
            if !v.is_finite() {
                return Err(DriveError::Toml {
                    path: path.to_path_buf(),
                    message: format!("`{key}` = {v} is not a finite number"),
                });
            }
        }
    }
    if vehicle.gnss.origin_lat_deg.is_some() != vehicle.gnss.origin_lon_deg.is_some() {
        return Err(DriveError::Toml {
            path: path.to_path_buf(),
            message: "[gnss] needs both origin_lat_deg and origin_lon_deg, or neither".to_string(),
        });
    }
    Ok(vehicle)
}

/// Parse `truth.toml` text.
pub(super) fn parse_truth_toml(path: &Path, text: &str) -> Result<TruthParams, DriveError> {
    toml::from_str(text).map_err(|e| DriveError::Toml {
        path: path.to_path_buf(),
        message: clip_lines(e.to_string().trim_end()),
    })
}

/// What a wheel column name means.
enum WheelColumn {
    /// A valid `W_unit` column.
    Wheel(Wheel, WheelUnit),
    /// Looks like a wheel column but is not one.
    Unknown,
    /// Not a wheel column at all.
    Other,
}

fn classify_wheel_column(name: &str) -> WheelColumn {
    for wheel in Wheel::ALL {
        for unit in WheelUnit::ALL {
            let prefix = wheel.prefix();
            if name.len() == prefix.len() + 1 + unit.suffix().len()
                && name.starts_with(prefix)
                && name[prefix.len()..].starts_with('_')
                && name.ends_with(unit.suffix())
            {
                return WheelColumn::Wheel(wheel, unit);
            }
        }
    }
    let wheel_prefix = Wheel::ALL.iter().any(|w| {
        name.strip_prefix(w.prefix())
            .is_some_and(|r| r.starts_with('_'))
    });
    let unit_suffix = WheelUnit::ALL.iter().any(|u| {
        name.strip_suffix(u.suffix())
            .is_some_and(|r| r.ends_with('_'))
    });
    if wheel_prefix || unit_suffix {
        WheelColumn::Unknown
    } else {
        WheelColumn::Other
    }
}

fn read_wheels(
    path: &Path,
    vehicle: &VehicleParams,
    warnings: &mut Vec<String>,
) -> Result<WheelSeries, DriveError> {
    let mut csv = CsvFile::open(path)?;
    let t_col = csv.required("t_s")?;
    // (column index, unit) per wheel, in Wheel::ALL order.
    let mut found: [Option<(usize, WheelUnit)>; 4] = [None; 4];
    let columns = csv.columns.clone();
    for (i, name) in columns.iter().enumerate() {
        if i == t_col {
            continue;
        }
        match classify_wheel_column(name) {
            WheelColumn::Wheel(wheel, unit) => {
                let slot = &mut found[wheel as usize];
                if let Some((other, _)) = slot {
                    return Err(DriveError::BadHeader {
                        path: path.to_path_buf(),
                        line: csv.header_line,
                        message: format!(
                            "wheel {} has two columns, `{}` and `{}`; give exactly one",
                            wheel.prefix(),
                            columns[*other],
                            clip(name)
                        ),
                    });
                }
                *slot = Some((i, unit));
                csv.claim(i);
            }
            WheelColumn::Unknown => {
                return Err(DriveError::UnknownWheelColumn {
                    path: path.to_path_buf(),
                    line: csv.header_line,
                    column: clip(name),
                })
            }
            WheelColumn::Other => {}
        }
    }
    for wheel in [Wheel::Rl, Wheel::Rr] {
        if found[wheel as usize].is_none() {
            let p = wheel.prefix();
            return Err(DriveError::MissingColumn {
                path: path.to_path_buf(),
                line: csv.header_line,
                column: format!("{p}_rev, {p}_ticks, {p}_rad_s or {p}_m_s"),
            });
        }
    }
    for (i, unit) in found.iter().flatten() {
        if *unit == WheelUnit::Ticks && vehicle.ticks_per_rev.is_none() {
            return Err(DriveError::BadHeader {
                path: path.to_path_buf(),
                line: csv.header_line,
                message: format!(
                    "column `{}` needs `ticks_per_rev` in vehicle.toml",
                    columns[*i]
                ),
            });
        }
    }
    let unit_of = |w: Wheel| found[w as usize].map(|(_, u)| u);
    let col_of = |w: Wheel| found[w as usize].map(|(i, _)| i);
    let (rl_col, rr_col) = match (col_of(Wheel::Rl), col_of(Wheel::Rr)) {
        (Some(a), Some(b)) => (a, b),
        _ => unreachable_missing(path)?,
    };
    let units = WheelUnits {
        rl: unit_of(Wheel::Rl).unwrap_or(WheelUnit::Rev),
        rr: unit_of(Wheel::Rr).unwrap_or(WheelUnit::Rev),
        fl: unit_of(Wheel::Fl),
        fr: unit_of(Wheel::Fr),
    };
    let (fl_col, fr_col) = (col_of(Wheel::Fl), col_of(Wheel::Fr));
    let mut samples = Vec::new();
    let mut previous = None;
    csv.for_each_row(|row| {
        let t_s = row.need(t_col)?;
        row.check_time(t_s, &mut previous)?;
        samples.push(WheelSample {
            t_s,
            rl: row.need(rl_col)?,
            rr: row.need(rr_col)?,
            fl: row.opt(fl_col)?,
            fr: row.opt(fr_col)?,
        });
        Ok(())
    })?;
    warnings.extend(csv.unknown_columns_warning());
    warnings.extend(csv.cut_warning());
    Ok(WheelSeries { units, samples })
}

/// Never reached (rl and rr were checked); keeps library code free of unwrap.
fn unreachable_missing(path: &Path) -> Result<(usize, usize), DriveError> {
    Err(DriveError::MissingColumn {
        path: path.to_path_buf(),
        line: 1,
        column: "rl/rr".to_string(),
    })
}

/// How a position file gives its positions.
#[derive(Clone, Copy, PartialEq)]
enum PositionKind {
    /// `x_m,y_m` (and every stream without positions).
    Enu,
    /// `lat_deg,lon_deg`.
    LatLon,
}

/// A stream as its file gives it: for `lat_deg,lon_deg` files, the samples'
/// `x_m,y_m` hold latitude and longitude until [`RawStream::into_enu`].
struct RawStream<S> {
    position: PositionKind,
    samples: Vec<S>,
}

impl<S: Stream> RawStream<S> {
    /// `Some(first position)` for a lat/lon file (`Some(None)` when it has no
    /// row), `None` for an ENU one.
    fn lat_lon_start(&self) -> Option<Option<(f64, f64)>> {
        (self.position == PositionKind::LatLon).then(|| {
            self.samples
                .first()
                .and_then(|s| Some((s.value(1)?, s.value(2)?)))
        })
    }

    /// The samples in ENU.
    fn into_enu(self, frame: Option<&LocalFrame>) -> Vec<S> {
        // ENU files, and lat/lon files without a frame (impossible: a frame
        // is made whenever a lat/lon file has a row), are as read.
        let (PositionKind::LatLon, Some(frame)) = (self.position, frame) else {
            return self.samples;
        };
        let mut values = [None; MAX_FIELDS];
        let n = S::FIELDS.len();
        self.samples
            .into_iter()
            .filter_map(|s| {
                for (k, v) in values[..n].iter_mut().enumerate() {
                    *v = s.value(k);
                }
                let (x, y) = frame.to_en(values[1]?, values[2]?);
                (values[1], values[2]) = (Some(x), Some(y));
                S::from_values(&values[..n])
            })
            .collect()
    }
}

/// Latitude within ±90°, longitude within ±360°.
fn check_lat_lon(
    row: &Row<'_>,
    lat_col: usize,
    lon_col: usize,
    lat: f64,
    lon: f64,
) -> Result<(), DriveError> {
    if lat.abs() > 90.0 {
        return Err(row.bad_cell(lat_col, "latitude outside ±90°"));
    }
    if lon.abs() > 360.0 {
        return Err(row.bad_cell(lon_col, "longitude outside ±360°"));
    }
    Ok(())
}

/// Find `x_m,y_m` or `lat_deg,lon_deg`.
fn position_columns(csv: &mut CsvFile) -> Result<(PositionKind, usize, usize), DriveError> {
    let has = |c: &CsvFile, n: &str| c.columns.iter().any(|x| x == n);
    let enu = has(csv, "x_m") || has(csv, "y_m");
    let geo = has(csv, "lat_deg") || has(csv, "lon_deg");
    if enu && geo {
        return Err(DriveError::BadHeader {
            path: csv.path().to_path_buf(),
            line: csv.header_line,
            message: "both x_m/y_m and lat_deg/lon_deg columns; give one pair".to_string(),
        });
    }
    if geo {
        Ok((
            PositionKind::LatLon,
            csv.required("lat_deg")?,
            csv.required("lon_deg")?,
        ))
    } else if enu {
        Ok((
            PositionKind::Enu,
            csv.required("x_m")?,
            csv.required("y_m")?,
        ))
    } else {
        Err(DriveError::MissingColumn {
            path: csv.path().to_path_buf(),
            line: csv.header_line,
            column: "x_m,y_m or lat_deg,lon_deg".to_string(),
        })
    }
}

/// Read the CSV file of stream `S`: `t_s` strictly increasing, the required
/// columns present and filled, lat/lon in range.
fn read_stream<S: Stream>(
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<RawStream<S>, DriveError> {
    let mut csv = CsvFile::open(path)?;
    let n = S::FIELDS.len();
    // Column of each field, in S::FIELDS order (`t_s` first).
    let mut cols: [Option<usize>; MAX_FIELDS] = [None; MAX_FIELDS];
    let t_col = csv.required(S::FIELDS[0].name)?;
    cols[0] = Some(t_col);
    let mut position = PositionKind::Enu;
    // The lat/lon columns, in a lat/lon file.
    let mut lat_lon = None;
    let mut next = 1;
    if S::LAT_LON {
        let (kind, a, b) = position_columns(&mut csv)?;
        (position, cols[1], cols[2], next) = (kind, Some(a), Some(b), 3);
        if kind == PositionKind::LatLon {
            lat_lon = Some((a, b));
        }
    }
    for (col, field) in cols[next..n].iter_mut().zip(&S::FIELDS[next..]) {
        *col = if field.required {
            Some(csv.required(field.name)?)
        } else {
            csv.optional(field.name)
        };
    }
    let fix_col = if S::FIX_COLUMN {
        csv.optional("fix")
    } else {
        None
    };
    let mut samples = Vec::new();
    let mut values = [None; MAX_FIELDS];
    let mut previous = None;
    let mut no_fix = 0usize;
    let mut first_no_fix_line = 0usize;
    csv.for_each_row(|row| {
        let t_s = row.need(t_col)?;
        row.check_time(t_s, &mut previous)?;
        if row.opt(fix_col)? == Some(0.0) {
            if no_fix == 0 {
                first_no_fix_line = row.line;
            }
            no_fix += 1;
            return Ok(());
        }
        values[0] = Some(t_s);
        for k in 1..n {
            values[k] = match (S::FIELDS[k].required, cols[k]) {
                (true, Some(i)) => Some(row.need(i)?),
                (_, col) => row.opt(col)?,
            };
            if let (2, Some((a, b)), Some(lat), Some(lon)) = (k, lat_lon, values[1], values[2]) {
                check_lat_lon(row, a, b, lat, lon)?;
            }
        }
        samples.extend(S::from_values(&values[..n]));
        Ok(())
    })?;
    if no_fix > 0 {
        warnings.push(format!(
            "{}: ignored {no_fix} row(s) with fix = 0 (no fix), the first at line {first_no_fix_line}",
            path.display()
        ));
    }
    warnings.extend(csv.unknown_columns_warning());
    warnings.extend(csv.cut_warning());
    Ok(RawStream { position, samples })
}

/// The ENU frame for lat/lon files, recording its origin in the vehicle
/// parameters so that a writer (which writes x_m,y_m) loses nothing.
/// `starts` holds, per position stream, what [`RawStream::lat_lon_start`] gives.
fn local_frame(
    vehicle_path: &Path,
    vehicle: &mut VehicleParams,
    starts: [Option<Option<(f64, f64)>>; 2],
) -> Result<Option<LocalFrame>, DriveError> {
    if starts.iter().all(Option::is_none) {
        return Ok(None);
    }
    let origin = match (vehicle.gnss.origin_lat_deg, vehicle.gnss.origin_lon_deg) {
        (Some(lat), Some(lon)) => Some((lat, lon)),
        _ => starts.into_iter().flatten().flatten().next(),
    };
    let Some((lat, lon)) = origin else {
        // Lat/lon files without a single row: nothing to convert.
        return Ok(None);
    };
    if lat.abs() > 90.0 {
        return Err(DriveError::Toml {
            path: vehicle_path.to_path_buf(),
            message: format!("[gnss] origin_lat_deg = {lat} is outside ±90°"),
        });
    }
    vehicle.gnss.origin_lat_deg = Some(lat);
    vehicle.gnss.origin_lon_deg = Some(lon);
    Ok(Some(LocalFrame::new(lat, lon, 0.0)))
}

// ---------------------------------------------------------------- writing

/// `vehicle.toml` text of a drive.
pub(super) fn vehicle_toml(vehicle: &VehicleParams) -> Result<String, DriveError> {
    toml::to_string(vehicle).map_err(|e| DriveError::InvalidDrive {
        stream: "vehicle".to_string(),
        index: 0,
        message: format!("cannot serialise as TOML: {e}"),
    })
}

/// `truth.toml` text of a drive.
pub(super) fn truth_toml(truth: &TruthParams) -> Result<String, DriveError> {
    toml::to_string(truth).map_err(|e| DriveError::InvalidDrive {
        stream: "truth_params".to_string(),
        index: 0,
        message: format!("cannot serialise as TOML: {e}"),
    })
}

/// Write a drive folder (the drive has been validated).
pub(super) fn write_folder(drive: &Drive, dir: &Path) -> Result<(), DriveError> {
    std::fs::create_dir_all(dir).map_err(|e| DriveError::io(dir, e))?;
    let mut files: Vec<(&str, String)> = vec![
        (VEHICLE_TOML, vehicle_toml(&drive.vehicle)?),
        (WHEELS_CSV, wheels_csv(drive)),
    ];
    files.extend(stream_csv::<GnssSample>(drive));
    files.extend(stream_csv::<ImuSample>(drive));
    files.extend(stream_csv::<HeadingSample>(drive));
    files.extend(stream_csv::<TruthSample>(drive));
    if let Some(p) = &drive.truth_params {
        files.push((TRUTH_TOML, truth_toml(p)?));
    }
    for name in ALL_FILES {
        let path = dir.join(name);
        // Never open a FIFO or a device in place of a drive file (the open
        // would block, or write into the device).
        let present = regular_file_present(&path)?;
        match files.iter().find(|(n, _)| *n == name) {
            Some((_, text)) => std::fs::write(&path, text).map_err(|e| DriveError::io(&path, e))?,
            None if present => std::fs::remove_file(&path).map_err(|e| DriveError::io(&path, e))?,
            None => {}
        }
    }
    Ok(())
}

fn wheels_csv(drive: &Drive) -> String {
    let columns = wheel_column_names(&drive.wheels.units);
    let mut names = vec!["t_s"];
    names.extend(columns.iter().map(|(_, n)| n.as_str()));
    let samples = &drive.wheels.samples;
    let mut w = CsvWriter::new(&names, samples.len());
    let mut row = Vec::with_capacity(names.len());
    for s in samples {
        row.clear();
        row.push(Some(s.t_s));
        for (wheel, _) in &columns {
            row.push(wheel_value(s, *wheel));
        }
        w.row(&row);
    }
    w.finish()
}

/// The CSV file of stream `S` when the drive has it: `t_s` and the required
/// columns, then each optional column that some row has a value in.
fn stream_csv<S: Stream>(drive: &Drive) -> Option<(&'static str, String)> {
    let samples = S::of(drive)?;
    let present: Vec<bool> = (0..S::FIELDS.len())
        .map(|k| S::FIELDS[k].required || samples.iter().any(|s| s.value(k).is_some()))
        .collect();
    let cols: Vec<&str> = S::FIELDS
        .iter()
        .zip(&present)
        .filter(|(_, p)| **p)
        .map(|(f, _)| f.name)
        .collect();
    let mut w = CsvWriter::new(&cols, samples.len());
    let mut row = Vec::with_capacity(cols.len());
    for s in samples {
        row.clear();
        row.extend(
            (0..S::FIELDS.len())
                .filter(|k| present[*k])
                .map(|k| s.value(k)),
        );
        w.row(&row);
    }
    Some((S::CSV_FILE, w.finish()))
}

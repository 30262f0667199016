//! The drive folder (`shared/design/drive-format.md`), read and written.

use super::csv::{CsvFile, CsvWriter, Row};
use super::geodesy::LocalFrame;
use super::{DriveError, LoadedDrive};
use interfaces::drive::{
    Drive, GnssSample, HeadingSample, ImuSample, TruthParams, TruthSample, VehicleParams, Wheel,
    WheelSample, WheelSeries, WheelUnit, WheelUnits,
};
use std::path::{Path, PathBuf};

/// File names of the format.
pub(super) const VEHICLE_TOML: &str = "vehicle.toml";
pub(super) const WHEELS_CSV: &str = "wheels.csv";
pub(super) const GNSS_CSV: &str = "gnss.csv";
pub(super) const IMU_CSV: &str = "imu.csv";
pub(super) const HEADING_CSV: &str = "heading.csv";
pub(super) const TRUTH_CSV: &str = "truth.csv";
pub(super) const TRUTH_TOML: &str = "truth.toml";
const ALL_FILES: [&str; 7] = [
    VEHICLE_TOML,
    WHEELS_CSV,
    GNSS_CSV,
    IMU_CSV,
    HEADING_CSV,
    TRUTH_CSV,
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

/// Read a drive folder.
pub(super) fn read_folder(dir: &Path) -> Result<LoadedDrive, DriveError> {
    let mut warnings = Vec::new();
    let vehicle_path = dir.join(VEHICLE_TOML);
    if !vehicle_path.is_file() {
        return Err(DriveError::MissingFile { path: vehicle_path });
    }
    let text =
        std::fs::read_to_string(&vehicle_path).map_err(|e| DriveError::io(&vehicle_path, e))?;
    let mut vehicle = parse_vehicle_toml(&vehicle_path, &text, &mut warnings)?;

    let wheels_path = dir.join(WHEELS_CSV);
    if !wheels_path.is_file() {
        return Err(DriveError::MissingFile { path: wheels_path });
    }
    let wheels = read_wheels(&wheels_path, &vehicle, &mut warnings)?;

    let gnss_raw = optional_file(dir, GNSS_CSV)
        .map(|p| read_gnss(&p, &mut warnings))
        .transpose()?;
    let imu = optional_file(dir, IMU_CSV)
        .map(|p| read_imu(&p, &mut warnings))
        .transpose()?;
    let heading = optional_file(dir, HEADING_CSV)
        .map(|p| read_heading(&p, &mut warnings))
        .transpose()?;
    let truth_raw = optional_file(dir, TRUTH_CSV)
        .map(|p| read_truth(&p, &mut warnings))
        .transpose()?;
    let truth_params = match optional_file(dir, TRUTH_TOML) {
        Some(p) => {
            let text = std::fs::read_to_string(&p).map_err(|e| DriveError::io(&p, e))?;
            Some(parse_truth_toml(&p, &text)?)
        }
        None => None,
    };

    // One ENU origin for every lat/lon file: vehicle.toml's, else the first
    // GNSS fix, else the first truth position.
    let frame = local_frame(
        &vehicle_path,
        &mut vehicle,
        gnss_raw.as_ref(),
        truth_raw.as_ref(),
    )?;
    let gnss = gnss_raw.map(|raw| {
        raw.rows
            .iter()
            .map(|r| {
                let (x_m, y_m) = raw.position.to_enu(frame.as_ref(), r.a, r.b);
                GnssSample {
                    t_s: r.t_s,
                    x_m,
                    y_m,
                    sigma_m: r.extra,
                }
            })
            .collect()
    });
    let truth = truth_raw.map(|raw| {
        raw.rows
            .iter()
            .map(|r| {
                let (x_m, y_m) = raw.position.to_enu(frame.as_ref(), r.a, r.b);
                TruthSample {
                    t_s: r.t_s,
                    x_m,
                    y_m,
                    yaw_rad: r.extra,
                }
            })
            .collect()
    });

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

fn optional_file(dir: &Path, name: &str) -> Option<PathBuf> {
    let p = dir.join(name);
    p.is_file().then_some(p)
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

/// Parse `vehicle.toml` text; unknown keys become a warning.
pub(super) fn parse_vehicle_toml(
    path: &Path,
    text: &str,
    warnings: &mut Vec<String>,
) -> Result<VehicleParams, DriveError> {
    let toml_error = |e: toml::de::Error| DriveError::Toml {
        path: path.to_path_buf(),
        message: e.to_string().trim_end().to_string(),
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
        warnings.push(format!(
            "{}: ignored unknown key(s): {}",
            path.display(),
            unknown.join(", ")
        ));
    }
    let vehicle: VehicleParams = toml::from_str(text).map_err(toml_error)?;
    let values = [
        ("track_width_m", Some(vehicle.track_width_m)),
        (
            "nominal_circumference_m",
            Some(vehicle.nominal_circumference_m),
        ),
        ("wheelbase_m", vehicle.wheelbase_m),
        ("ticks_per_rev", vehicle.ticks_per_rev),
        ("gnss.antenna_x_m", vehicle.gnss.antenna_x_m),
        ("gnss.antenna_y_m", vehicle.gnss.antenna_y_m),
        ("gnss.origin_lat_deg", vehicle.gnss.origin_lat_deg),
        ("gnss.origin_lon_deg", vehicle.gnss.origin_lon_deg),
    ];
    for (key, value) in values {
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
        message: e.to_string().trim_end().to_string(),
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
                            "wheel {} has two columns, `{}` and `{name}`; give exactly one",
                            wheel.prefix(),
                            columns[*other]
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
                    column: name.clone(),
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
    /// `x_m,y_m`.
    Enu,
    /// `lat_deg,lon_deg`.
    LatLon,
}

impl PositionKind {
    fn to_enu(self, frame: Option<&LocalFrame>, a: f64, b: f64) -> (f64, f64) {
        match (self, frame) {
            (PositionKind::LatLon, Some(f)) => f.to_en(a, b),
            // Enu, or LatLon without a frame (impossible: a frame is made
            // whenever a lat/lon file has a row).
            _ => (a, b),
        }
    }
}

/// A position row before lat/lon conversion: `a,b` are x,y or lat,lon;
/// `extra` is sigma_m (gnss) or yaw_rad (truth).
struct RawPositionRow {
    t_s: f64,
    a: f64,
    b: f64,
    extra: Option<f64>,
}

struct RawPositions {
    position: PositionKind,
    rows: Vec<RawPositionRow>,
}

/// Latitude within ±90°, longitude within ±360°.
fn check_lat_lon(
    row: &Row<'_>,
    position: PositionKind,
    lat_col: usize,
    lon_col: usize,
    lat: f64,
    lon: f64,
) -> Result<(), DriveError> {
    if position == PositionKind::LatLon {
        if lat.abs() > 90.0 {
            return Err(row.bad_cell(lat_col, "latitude outside ±90°"));
        }
        if lon.abs() > 360.0 {
            return Err(row.bad_cell(lon_col, "longitude outside ±360°"));
        }
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

fn read_gnss(path: &Path, warnings: &mut Vec<String>) -> Result<RawPositions, DriveError> {
    let mut csv = CsvFile::open(path)?;
    let t_col = csv.required("t_s")?;
    let (position, a_col, b_col) = position_columns(&mut csv)?;
    let sigma_col = csv.optional("sigma_m");
    let fix_col = csv.optional("fix");
    let mut rows = Vec::new();
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
        let (a, b) = (row.need(a_col)?, row.need(b_col)?);
        check_lat_lon(row, position, a_col, b_col, a, b)?;
        rows.push(RawPositionRow {
            t_s,
            a,
            b,
            extra: row.opt(sigma_col)?,
        });
        Ok(())
    })?;
    if no_fix > 0 {
        warnings.push(format!(
            "{}: ignored {no_fix} row(s) with fix = 0 (no fix), the first at line {first_no_fix_line}",
            path.display()
        ));
    }
    warnings.extend(csv.unknown_columns_warning());
    Ok(RawPositions { position, rows })
}

fn read_truth(path: &Path, warnings: &mut Vec<String>) -> Result<RawPositions, DriveError> {
    let mut csv = CsvFile::open(path)?;
    let t_col = csv.required("t_s")?;
    let (position, a_col, b_col) = position_columns(&mut csv)?;
    let yaw_col = csv.optional("yaw_rad");
    let mut rows = Vec::new();
    let mut previous = None;
    csv.for_each_row(|row| {
        let t_s = row.need(t_col)?;
        row.check_time(t_s, &mut previous)?;
        let (a, b) = (row.need(a_col)?, row.need(b_col)?);
        check_lat_lon(row, position, a_col, b_col, a, b)?;
        rows.push(RawPositionRow {
            t_s,
            a,
            b,
            extra: row.opt(yaw_col)?,
        });
        Ok(())
    })?;
    warnings.extend(csv.unknown_columns_warning());
    Ok(RawPositions { position, rows })
}

/// The ENU frame for lat/lon files, recording its origin in the vehicle
/// parameters so that a writer (which writes x_m,y_m) loses nothing.
fn local_frame(
    vehicle_path: &Path,
    vehicle: &mut VehicleParams,
    gnss: Option<&RawPositions>,
    truth: Option<&RawPositions>,
) -> Result<Option<LocalFrame>, DriveError> {
    let geo: Vec<&RawPositions> = [gnss, truth]
        .into_iter()
        .flatten()
        .filter(|r| r.position == PositionKind::LatLon)
        .collect();
    if geo.is_empty() {
        return Ok(None);
    }
    let origin = match (vehicle.gnss.origin_lat_deg, vehicle.gnss.origin_lon_deg) {
        (Some(lat), Some(lon)) => Some((lat, lon)),
        _ => geo.iter().find_map(|r| r.rows.first()).map(|r| (r.a, r.b)),
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

fn read_imu(path: &Path, warnings: &mut Vec<String>) -> Result<Vec<ImuSample>, DriveError> {
    let mut csv = CsvFile::open(path)?;
    let t_col = csv.required("t_s")?;
    let gz = csv.required("gz_rad_s")?;
    let ax = csv.optional("ax_m_s2");
    let ay = csv.optional("ay_m_s2");
    let az = csv.optional("az_m_s2");
    let gx = csv.optional("gx_rad_s");
    let gy = csv.optional("gy_rad_s");
    let mut out = Vec::new();
    let mut previous = None;
    csv.for_each_row(|row| {
        let t_s = row.need(t_col)?;
        row.check_time(t_s, &mut previous)?;
        out.push(ImuSample {
            t_s,
            gz_rad_s: row.need(gz)?,
            ax_m_s2: row.opt(ax)?,
            ay_m_s2: row.opt(ay)?,
            az_m_s2: row.opt(az)?,
            gx_rad_s: row.opt(gx)?,
            gy_rad_s: row.opt(gy)?,
        });
        Ok(())
    })?;
    warnings.extend(csv.unknown_columns_warning());
    Ok(out)
}

fn read_heading(path: &Path, warnings: &mut Vec<String>) -> Result<Vec<HeadingSample>, DriveError> {
    let mut csv = CsvFile::open(path)?;
    let t_col = csv.required("t_s")?;
    let yaw = csv.required("yaw_rad")?;
    let sigma = csv.optional("sigma_rad");
    let mut out = Vec::new();
    let mut previous = None;
    csv.for_each_row(|row| {
        let t_s = row.need(t_col)?;
        row.check_time(t_s, &mut previous)?;
        out.push(HeadingSample {
            t_s,
            yaw_rad: row.need(yaw)?,
            sigma_rad: row.opt(sigma)?,
        });
        Ok(())
    })?;
    warnings.extend(csv.unknown_columns_warning());
    Ok(out)
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

/// The `wheels.csv` column names for `units`, in Wheel::ALL order.
pub(super) fn wheel_column_names(units: &WheelUnits) -> Vec<(Wheel, String)> {
    Wheel::ALL
        .iter()
        .filter_map(|&w| {
            units
                .of(w)
                .map(|u| (w, format!("{}_{}", w.prefix(), u.suffix())))
        })
        .collect()
}

/// Write a drive folder (the drive has been validated).
pub(super) fn write_folder(drive: &Drive, dir: &Path) -> Result<(), DriveError> {
    std::fs::create_dir_all(dir).map_err(|e| DriveError::io(dir, e))?;
    let mut files: Vec<(&str, String)> = vec![
        (VEHICLE_TOML, vehicle_toml(&drive.vehicle)?),
        (WHEELS_CSV, wheels_csv(drive)),
    ];
    if let Some(g) = &drive.gnss {
        let sigma = g.iter().any(|s| s.sigma_m.is_some());
        let mut cols = vec!["t_s", "x_m", "y_m"];
        if sigma {
            cols.push("sigma_m");
        }
        let mut w = CsvWriter::new(&cols, g.len());
        for s in g {
            let row = [Some(s.t_s), Some(s.x_m), Some(s.y_m), s.sigma_m];
            w.row(&row[..cols.len()]);
        }
        files.push((GNSS_CSV, w.finish()));
    }
    if let Some(imu) = &drive.imu {
        let names = ["ax_m_s2", "ay_m_s2", "az_m_s2", "gx_rad_s", "gy_rad_s"];
        let get = |s: &ImuSample| [s.ax_m_s2, s.ay_m_s2, s.az_m_s2, s.gx_rad_s, s.gy_rad_s];
        // An optional column is written when any row has a value in it.
        let present: Vec<bool> = (0..names.len())
            .map(|k| imu.iter().any(|s| get(s)[k].is_some()))
            .collect();
        let mut cols = vec!["t_s", "gz_rad_s"];
        cols.extend(
            names
                .iter()
                .zip(&present)
                .filter(|(_, p)| **p)
                .map(|(n, _)| *n),
        );
        let mut w = CsvWriter::new(&cols, imu.len());
        let mut row = Vec::with_capacity(cols.len());
        for s in imu {
            row.clear();
            row.push(Some(s.t_s));
            row.push(Some(s.gz_rad_s));
            row.extend(
                get(s)
                    .iter()
                    .zip(&present)
                    .filter(|(_, p)| **p)
                    .map(|(v, _)| *v),
            );
            w.row(&row);
        }
        files.push((IMU_CSV, w.finish()));
    }
    if let Some(h) = &drive.heading {
        let sigma = h.iter().any(|s| s.sigma_rad.is_some());
        let cols: &[&str] = if sigma {
            &["t_s", "yaw_rad", "sigma_rad"]
        } else {
            &["t_s", "yaw_rad"]
        };
        let mut w = CsvWriter::new(cols, h.len());
        for s in h {
            let row = [Some(s.t_s), Some(s.yaw_rad), s.sigma_rad];
            w.row(&row[..cols.len()]);
        }
        files.push((HEADING_CSV, w.finish()));
    }
    if let Some(t) = &drive.truth {
        let yaw = t.iter().any(|s| s.yaw_rad.is_some());
        let cols: &[&str] = if yaw {
            &["t_s", "x_m", "y_m", "yaw_rad"]
        } else {
            &["t_s", "x_m", "y_m"]
        };
        let mut w = CsvWriter::new(cols, t.len());
        for s in t {
            let row = [Some(s.t_s), Some(s.x_m), Some(s.y_m), s.yaw_rad];
            w.row(&row[..cols.len()]);
        }
        files.push((TRUTH_CSV, w.finish()));
    }
    if let Some(p) = &drive.truth_params {
        files.push((TRUTH_TOML, truth_toml(p)?));
    }
    for name in ALL_FILES {
        let path = dir.join(name);
        match files.iter().find(|(n, _)| *n == name) {
            Some((_, text)) => std::fs::write(&path, text).map_err(|e| DriveError::io(&path, e))?,
            None if path.is_file() => {
                std::fs::remove_file(&path).map_err(|e| DriveError::io(&path, e))?
            }
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
            row.push(match wheel {
                Wheel::Rl => Some(s.rl),
                Wheel::Rr => Some(s.rr),
                Wheel::Fl => s.fl,
                Wheel::Fr => s.fr,
            });
        }
        w.row(&row);
    }
    w.finish()
}

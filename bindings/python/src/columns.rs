//! A drive built from in-memory columns (a numpy array or a pandas column
//! per field, handed over as little-endian float64 bytes): the drive
//! format's stream and column names, the vehicle from `vehicle.toml`
//! text, positions in `x_m`/`y_m` or `lat_deg`/`lon_deg`, checked by
//! `drive_io::validate` as a written drive is. A missing, unknown or
//! misshapen column is an error naming the stream and the column.

use anyhow::{anyhow, bail, Context, Result};
use drive_io::geodesy::LocalFrame;
use drive_io::LoadedDrive;
use interfaces::drive::{
    Drive, GnssSample, HeadingSample, ImuSample, TruthSample, WheelSample, WheelSeries, WheelUnit,
    WheelUnits,
};
use std::collections::BTreeMap;
use std::path::Path;

/// One stream's columns by name, as bytes.
type RawColumns = BTreeMap<String, Vec<u8>>;

/// The columns of one stream, decoded, all of one length.
struct Columns<'a> {
    stream: &'a str,
    values: BTreeMap<&'a str, Vec<f64>>,
    rows: usize,
}

impl<'a> Columns<'a> {
    fn new(stream: &'a str, raw: &'a RawColumns, known: &[&str]) -> Result<Columns<'a>> {
        let mut values = BTreeMap::new();
        let mut rows = None;
        for (name, bytes) in raw {
            if !known.contains(&name.as_str()) {
                bail!(
                    "stream `{stream}`: unknown column `{name}` (known: {})",
                    known.join(", ")
                );
            }
            if bytes.len() % 8 != 0 {
                bail!("stream `{stream}`, column `{name}`: not a float64 array");
            }
            let v: Vec<f64> = bytes
                .chunks_exact(8)
                .map(|c| {
                    let mut b = [0u8; 8];
                    b.copy_from_slice(c);
                    f64::from_le_bytes(b)
                })
                .collect();
            match rows {
                None => rows = Some(v.len()),
                Some(n) if n != v.len() => bail!(
                    "stream `{stream}`, column `{name}`: {} rows, the other columns {n}",
                    v.len()
                ),
                Some(_) => {}
            }
            values.insert(name.as_str(), v);
        }
        Ok(Columns {
            stream,
            values,
            rows: rows.unwrap_or(0),
        })
    }

    /// Keep the rows `keep` says, in every column.
    fn keep_rows(&mut self, keep: impl Fn(&Columns<'a>, usize) -> bool) {
        let kept: Vec<usize> = (0..self.rows).filter(|&i| keep(self, i)).collect();
        for v in self.values.values_mut() {
            *v = kept.iter().map(|&i| v[i]).collect();
        }
        self.rows = kept.len();
    }

    fn required(&self, name: &str) -> Result<&[f64]> {
        self.values
            .get(name)
            .map(Vec::as_slice)
            .ok_or_else(|| anyhow!("stream `{}`: the column `{name}` is missing", self.stream))
    }

    /// An optional column's value at row `i` (`None` when the column is
    /// absent or the value is NaN, as an empty CSV cell reads).
    fn optional(&self, name: &str, i: usize) -> Option<f64> {
        self.values
            .get(name)
            .and_then(|v| v.get(i).copied())
            .filter(|x| !x.is_nan())
    }
}

/// The drive `streams` and `vehicle_toml` describe; `name` names it in errors.
pub(crate) fn drive(
    name: &str,
    vehicle_toml: &str,
    streams: &BTreeMap<String, RawColumns>,
) -> Result<LoadedDrive> {
    let vehicle_path = Path::new(name).join("vehicle.toml");
    let loaded = drive_io::vehicle_from_toml_str(&vehicle_path, vehicle_toml)
        .with_context(|| format!("cannot read drive {name}"))?;
    let mut vehicle = loaded.vehicle;
    let warnings = loaded.warnings;
    for s in streams.keys() {
        if !["wheels", "gnss", "imu", "heading", "truth"].contains(&s.as_str()) {
            bail!("drive {name}: unknown stream `{s}` (known: wheels, gnss, imu, heading, truth)");
        }
    }
    let raw_wheels = streams
        .get("wheels")
        .ok_or_else(|| anyhow!("drive {name}: the stream `wheels` is missing"))?;
    let wheels = wheel_series(raw_wheels).with_context(|| format!("drive {name}"))?;
    // One local frame for every lat/lon stream: vehicle.toml's origin, else
    // the first fix of the GNSS (or truth) stream.
    let mut frame = match (vehicle.gnss.origin_lat_deg, vehicle.gnss.origin_lon_deg) {
        (Some(lat), Some(lon)) => Some(LocalFrame::new(lat, lon, 0.0)),
        _ => None,
    };
    let gnss = match streams.get("gnss") {
        Some(raw) => {
            let names = ["t_s", "x_m", "y_m", "lat_deg", "lon_deg", "sigma_m", "fix"];
            let mut c = Columns::new("gnss", raw, &names)?;
            // `fix` = 0: no fix, the row is ignored (as in gnss.csv).
            c.keep_rows(|c, i| c.optional("fix", i) != Some(0.0));
            let (x, y) = positions(&c, &mut frame)?;
            let t = c.required("t_s")?;
            Some(
                (0..c.rows)
                    .map(|i| GnssSample {
                        t_s: t[i],
                        x_m: x[i],
                        y_m: y[i],
                        sigma_m: c.optional("sigma_m", i),
                    })
                    .collect(),
            )
        }
        None => None,
    };
    let truth = match streams.get("truth") {
        Some(raw) => {
            let c = Columns::new(
                "truth",
                raw,
                &["t_s", "x_m", "y_m", "lat_deg", "lon_deg", "yaw_rad"],
            )?;
            let (x, y) = positions(&c, &mut frame)?;
            let t = c.required("t_s")?;
            Some(
                (0..c.rows)
                    .map(|i| TruthSample {
                        t_s: t[i],
                        x_m: x[i],
                        y_m: y[i],
                        yaw_rad: c.optional("yaw_rad", i),
                    })
                    .collect(),
            )
        }
        None => None,
    };
    if let Some(f) = &frame {
        vehicle.gnss.origin_lat_deg = Some(f.origin_lat_deg());
        vehicle.gnss.origin_lon_deg = Some(f.origin_lon_deg());
    }
    let imu = match streams.get("imu") {
        Some(raw) => {
            let names = [
                "t_s", "gz_rad_s", "ax_m_s2", "ay_m_s2", "az_m_s2", "gx_rad_s", "gy_rad_s",
            ];
            let c = Columns::new("imu", raw, &names)?;
            let (t, gz) = (c.required("t_s")?, c.required("gz_rad_s")?);
            Some(
                (0..c.rows)
                    .map(|i| ImuSample {
                        t_s: t[i],
                        gz_rad_s: gz[i],
                        ax_m_s2: c.optional("ax_m_s2", i),
                        ay_m_s2: c.optional("ay_m_s2", i),
                        az_m_s2: c.optional("az_m_s2", i),
                        gx_rad_s: c.optional("gx_rad_s", i),
                        gy_rad_s: c.optional("gy_rad_s", i),
                    })
                    .collect(),
            )
        }
        None => None,
    };
    let heading = match streams.get("heading") {
        Some(raw) => {
            let c = Columns::new("heading", raw, &["t_s", "yaw_rad", "sigma_rad"])?;
            let (t, yaw) = (c.required("t_s")?, c.required("yaw_rad")?);
            Some(
                (0..c.rows)
                    .map(|i| HeadingSample {
                        t_s: t[i],
                        yaw_rad: yaw[i],
                        sigma_rad: c.optional("sigma_rad", i),
                    })
                    .collect(),
            )
        }
        None => None,
    };
    let drive = Drive {
        vehicle,
        wheels,
        gnss,
        imu,
        heading,
        truth,
        truth_params: None,
    };
    drive_io::validate(&drive).with_context(|| format!("cannot read drive {name}"))?;
    Ok(LoadedDrive { drive, warnings })
}

/// The wheels: `t_s` and the rear columns in one unit (`rl_rad_s`,
/// `rr_rad_s`, or `_rev`, `_ticks`, `_m_s`), the front ones optional.
fn wheel_series(raw: &RawColumns) -> Result<WheelSeries> {
    let mut known = vec!["t_s".to_string()];
    for w in ["rl", "rr", "fl", "fr"] {
        for u in WheelUnit::ALL {
            known.push(format!("{w}_{}", u.suffix()));
        }
    }
    let known_ref: Vec<&str> = known.iter().map(String::as_str).collect();
    let c = Columns::new("wheels", raw, &known_ref)?;
    let unit_of = |wheel: &str| -> Result<Option<(WheelUnit, String)>> {
        let found: Vec<(WheelUnit, String)> = WheelUnit::ALL
            .into_iter()
            .map(|u| (u, format!("{wheel}_{}", u.suffix())))
            .filter(|(_, n)| c.values.contains_key(n.as_str()))
            .collect();
        match found.len() {
            0 => Ok(None),
            1 => Ok(found.into_iter().next()),
            _ => bail!("stream `wheels`: more than one column for the wheel `{wheel}`"),
        }
    };
    let missing =
        |w: &str| anyhow!("stream `wheels`: no column for the wheel `{w}` (e.g. `{w}_rad_s`)");
    let (rl_unit, rl_name) = unit_of("rl")?.ok_or_else(|| missing("rl"))?;
    let (rr_unit, rr_name) = unit_of("rr")?.ok_or_else(|| missing("rr"))?;
    let fl = unit_of("fl")?;
    let fr = unit_of("fr")?;
    let t = c.required("t_s")?;
    let (rl, rr) = (c.required(&rl_name)?, c.required(&rr_name)?);
    let samples = (0..c.rows)
        .map(|i| WheelSample {
            t_s: t[i],
            rl: rl[i],
            rr: rr[i],
            fl: fl.as_ref().and_then(|(_, n)| c.optional(n, i)),
            fr: fr.as_ref().and_then(|(_, n)| c.optional(n, i)),
        })
        .collect();
    Ok(WheelSeries {
        units: WheelUnits {
            rl: rl_unit,
            rr: rr_unit,
            fl: fl.map(|(u, _)| u),
            fr: fr.map(|(u, _)| u),
        },
        samples,
    })
}

/// The east and north columns of a position stream: `x_m`/`y_m` as they
/// are, or `lat_deg`/`lon_deg` in `frame` (set from the first row when
/// there is none yet).
fn positions(c: &Columns<'_>, frame: &mut Option<LocalFrame>) -> Result<(Vec<f64>, Vec<f64>)> {
    let has = |n: &str| c.values.contains_key(n);
    match (has("x_m") || has("y_m"), has("lat_deg") || has("lon_deg")) {
        (true, true) => bail!(
            "stream `{}`: both x_m/y_m and lat_deg/lon_deg columns: give one pair",
            c.stream
        ),
        (true, false) => Ok((c.required("x_m")?.to_vec(), c.required("y_m")?.to_vec())),
        (false, true) => {
            let (lat, lon) = (c.required("lat_deg")?, c.required("lon_deg")?);
            if frame.is_none() {
                if let (Some(&la), Some(&lo)) = (lat.first(), lon.first()) {
                    if la.abs() > 90.0 || !la.is_finite() || !lo.is_finite() {
                        bail!(
                            "stream `{}`: row 0: lat_deg = {la}, lon_deg = {lo} is not a position",
                            c.stream
                        );
                    }
                    *frame = Some(LocalFrame::new(la, lo, 0.0));
                }
            }
            let Some(f) = frame.as_ref() else {
                return Ok((Vec::new(), Vec::new()));
            };
            Ok(lat
                .iter()
                .zip(lon)
                .map(|(&la, &lo)| f.to_en(la, lo))
                .unzip())
        }
        (false, false) => bail!(
            "stream `{}`: no position columns (x_m, y_m or lat_deg, lon_deg)",
            c.stream
        ),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn bytes(v: &[f64]) -> Vec<u8> {
        v.iter().flat_map(|x| x.to_le_bytes()).collect()
    }

    fn wheels(n: usize) -> RawColumns {
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
        let w = vec![10.0; n];
        [("t_s", t), ("rl_rad_s", w.clone()), ("rr_rad_s", w)]
            .into_iter()
            .map(|(k, v)| (k.to_string(), bytes(&v)))
            .collect()
    }

    const VEHICLE: &str = "track_width_m = 1.5\nnominal_circumference_m = 1.9\n";

    #[test]
    fn columns_give_the_drive_a_written_folder_reads_back_as() {
        let mut streams = BTreeMap::new();
        streams.insert("wheels".to_string(), wheels(50));
        let gnss: RawColumns = [
            ("t_s", vec![0.0, 0.1, 0.2]),
            ("lat_deg", vec![47.0, 47.00001, 47.00002]),
            ("lon_deg", vec![19.0, 19.0, 19.0]),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), bytes(&v)))
        .collect();
        streams.insert("gnss".to_string(), gnss);
        let loaded = drive("mem", VEHICLE, &streams).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d");
        drive_io::write_drive(&loaded.drive, &path).unwrap();
        let back = drive_io::read_drive(&path).unwrap();
        assert_eq!(back.drive, loaded.drive);
        let g = loaded.drive.gnss.unwrap();
        assert_eq!((g[0].x_m, g[0].y_m), (0.0, 0.0));
        assert!((g[2].y_m - 2.22).abs() < 0.01, "{}", g[2].y_m);
    }

    #[test]
    fn gnss_rows_without_a_fix_are_left_out() {
        let mut streams = BTreeMap::new();
        streams.insert("wheels".to_string(), wheels(50));
        let gnss: RawColumns = [
            ("t_s", vec![0.0, 0.1, 0.2]),
            ("x_m", vec![1.0, 2.0, 3.0]),
            ("y_m", vec![0.0, 0.0, 0.0]),
            ("fix", vec![1.0, 0.0, 1.0]),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), bytes(&v)))
        .collect();
        streams.insert("gnss".to_string(), gnss);
        let g = drive("mem", VEHICLE, &streams).unwrap().drive.gnss.unwrap();
        assert_eq!(g.iter().map(|s| s.x_m).collect::<Vec<_>>(), vec![1.0, 3.0]);
    }

    #[test]
    fn a_bad_column_is_named() {
        let mut streams = BTreeMap::new();
        let mut w = wheels(5);
        w.insert("rl_speed".to_string(), bytes(&[0.0; 5]));
        streams.insert("wheels".to_string(), w);
        let e = format!("{:#}", drive("mem", VEHICLE, &streams).err().unwrap());
        assert!(e.contains("rl_speed") && e.contains("wheels"), "{e}");
        let mut w = wheels(5);
        w.insert("t_s".to_string(), bytes(&[0.0, 0.1, 0.1, 0.2, 0.3]));
        streams.insert("wheels".to_string(), w);
        let e = format!("{:#}", drive("mem", VEHICLE, &streams).err().unwrap());
        assert!(e.contains("wheels"), "{e}");
        streams.insert("wheels".to_string(), wheels(5));
        streams.insert("gnss".to_string(), wheels(4));
        let e = format!("{:#}", drive("mem", VEHICLE, &streams).err().unwrap());
        assert!(e.contains("gnss") && e.contains("rl_rad_s"), "{e}");
    }
}

//! Writes the seed corpus of the fuzz targets, `fuzz/corpus/<target>/`,
//! from a small synthetic drive (made here, written with drive-io's own
//! writers) and a few hand-written inputs. No third-party data.
//!
//! `cargo run --release --example make_corpus` (from `fuzz/`); it replaces
//! the files it writes (named `seed-*`) and leaves other files alone.

use interfaces::drive::{
    Drive, GnssAntenna, GnssSample, HeadingSample, ImuSample, TruthParams, TruthSample,
    VehicleParams, WheelCircumferences, WheelSample, WheelSeries, WheelUnit, WheelUnits,
};
use interfaces::wire::{CircumferenceEstimate, Header};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use vehicle_model::estimate::Estimate;

/// Stream files, in the order of the `csv_stream` target's selector byte.
const CSV_FILES: [&str; 5] = ["wheels.csv", "gnss.csv", "imu.csv", "heading.csv", "truth.csv"];

fn drive(samples: usize, units: WheelUnits, with_optional: bool) -> Drive {
    let t = |i: usize| i as f64 * 0.1;
    let wheel = |i: usize, scale: f64| i as f64 * 0.05 * scale;
    let mut effects = BTreeMap::new();
    effects.insert(
        "side_slip".to_string(),
        BTreeMap::from([("k_beta".to_string(), 0.002)]),
    );
    Drive {
        vehicle: VehicleParams {
            name: Some("fuzz seed".to_string()),
            track_width_m: 1.6,
            nominal_circumference_m: 2.0,
            wheelbase_m: with_optional.then_some(2.7),
            ticks_per_rev: Some(96.0),
            gnss: GnssAntenna {
                antenna_x_m: with_optional.then_some(1.2),
                antenna_y_m: with_optional.then_some(0.0),
                origin_lat_deg: with_optional.then_some(48.1),
                origin_lon_deg: with_optional.then_some(11.5),
            },
        },
        wheels: WheelSeries {
            units,
            samples: (0..samples)
                .map(|i| WheelSample {
                    t_s: t(i),
                    rl: wheel(i, 1.0),
                    rr: wheel(i, 1.01),
                    fl: units.fl.map(|_| wheel(i, 0.99)),
                    fr: units.fr.map(|_| wheel(i, 1.02)),
                })
                .collect(),
        },
        gnss: Some(
            (0..samples / 2)
                .map(|i| GnssSample {
                    t_s: t(2 * i) + 0.01,
                    x_m: i as f64 * 0.2,
                    y_m: i as f64 * 0.01,
                    sigma_m: (with_optional && i % 3 != 0).then_some(0.02),
                })
                .collect(),
        ),
        imu: Some(
            (0..samples)
                .map(|i| ImuSample {
                    t_s: t(i) + 0.005,
                    gz_rad_s: 0.01 * (i as f64).sin(),
                    ax_m_s2: with_optional.then_some(0.1),
                    ay_m_s2: with_optional.then_some(-0.05),
                    az_m_s2: None,
                    gx_rad_s: None,
                    gy_rad_s: None,
                })
                .collect(),
        ),
        heading: with_optional.then(|| {
            (0..samples / 4)
                .map(|i| HeadingSample {
                    t_s: t(4 * i) + 0.02,
                    yaw_rad: 0.05 * i as f64,
                    sigma_rad: Some(0.01),
                })
                .collect()
        }),
        truth: with_optional.then(|| {
            (0..samples)
                .map(|i| TruthSample {
                    t_s: t(i),
                    x_m: i as f64 * 0.1,
                    y_m: 0.0,
                    yaw_rad: Some(0.0),
                })
                .collect()
        }),
        truth_params: with_optional.then(|| TruthParams {
            track_width_m: 1.61,
            circumference_m: WheelCircumferences {
                rl: 2.01,
                rr: 2.02,
                fl: 2.0,
                fr: 2.0,
            },
            effects,
            extra: BTreeMap::new(),
        }),
    }
}

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    std::fs::create_dir_all(dir).expect("create the corpus folder");
    std::fs::write(dir.join(name), bytes).expect("write a seed");
}

/// The `csv_stream` input for `file` with `content`.
fn csv_seed(file: &str, content: &[u8]) -> Vec<u8> {
    let pick = CSV_FILES.iter().position(|f| *f == file).expect("a stream file") as u8;
    let mut out = vec![pick];
    out.extend_from_slice(content);
    out
}

/// The `wire_estimate` input: the fields in the target's order, little-endian.
fn wire_bytes(w: &CircumferenceEstimate) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend(w.header.t_ns.to_le_bytes());
    out.extend(w.header.seq.to_le_bytes());
    out.extend(w.version.to_le_bytes());
    for v in [
        w.c_rl_m,
        w.c_rr_m,
        w.sigma_rl_m,
        w.sigma_rr_m,
        w.track_width_m,
        w.gyro_bias_rad_s,
        w.gyro_scale,
        w.quality_m,
    ] {
        out.extend(v.to_le_bytes());
    }
    out.extend(w.extension_count.to_le_bytes());
    out.extend(w._pad.to_le_bytes());
    for x in &w.extensions {
        out.extend(x.effect_code.to_le_bytes());
        out.extend(x.param_count.to_le_bytes());
        for p in x.params {
            out.extend(p.to_le_bytes());
        }
    }
    out
}

const ESTIMATES: [&str; 4] = [
    r#"{"circumference_m": {"rl": 2.01, "rr": 2.02}, "track_width_m": 1.6}"#,
    r#"{"circumference_m": {"rl": 2.01, "rr": 2.02}, "track_width_m": 1.6,
 "gyro_bias_rad_s": 0.001, "gyro_scale": -0.002, "sigma_m": {"rl": 0.001, "rr": 0.0012},
 "gnss_antenna_m": [1.2, 0.1], "sigma_gnss_antenna_m": [0.05, 0.04]}"#,
    r#"{"circumference_m": {"rl": 2.01, "rr": 2.02}, "track_width_m": 1.6, "gyro_bias_rad_s": null,
 "gyro": {"antenna_m": [1.1, -0.1], "sigma_antenna_m": [0.02, 0.03]},
 "effects": {"k_beta": 0.002, "k_z": 0.0001, "k_v": 1e-5, "k_s": 0.01, "track_rel": 0.01,
  "drift_d": 0.003, "drift_time_constant_s": 600.0}}"#,
    r#"{"circumference_m": {"rl": -1, "rr": 1e400}, "track_width_m": 0}"#,
];

const VEHICLE_TOMLS: [&str; 3] = [
    "track_width_m = 1.6\nnominal_circumference_m = 2.0\n",
    "name = \"x\"\ntrack_width_m = 1.6\nnominal_circumference_m = 2.0\nwheelbase_m = 2.7\n\
     ticks_per_rev = 96\nunknown = 1\n[gnss]\nantenna_x_m = 1.2\nantenna_y_m = 0.0\n\
     origin_lat_deg = 48.1\norigin_lon_deg = 11.5\nextra = true\n",
    "track_width_m = nan\nnominal_circumference_m = inf\n[gnss]\norigin_lat_deg = 91.0\n",
];

const TRUTH_TOML: &str = "track_width_m = 1.61\nscenario = \"city\"\nseed = 7\n\
    [circumference_m]\nrl = 2.01\nrr = 2.02\nfl = 2.0\nfr = 2.0\n\
    [effects.side_slip]\nk_beta = 0.002\n[sensors]\nrate_hz = [100, 10]\nt = 1979-05-27T07:32:00Z\n";

/// Hand-written CSV inputs for the dialect's corners.
const CSV_EXTRA: [(&str, &str); 6] = [
    (
        "wheels.csv",
        "# comment\n\nt_s, rl_ticks ,rr_ticks,fl_m_s,fr_m_s,other\n0,0,0,1.0,1.0,x\n0.1,10,11,,1.1,y\r\n",
    ),
    (
        "gnss.csv",
        "t_s,lat_deg,lon_deg,sigma_m,fix\n0,48.1,11.5,0.02,1\n0.5,48.1001,11.5001,,0\n1,48.1002,11.5002,0.03,4\n",
    ),
    ("imu.csv", "t_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2,gx_rad_s,gy_rad_s\n0,0.1,0,0,9.81,0,0\n0.01,0.1,,,,,\n"),
    ("heading.csv", "t_s,yaw_rad\n0,0\n0,1\n"),
    ("truth.csv", "t_s,lat_deg,lon_deg,yaw_rad\n0,95,11.5,0\n"),
    ("wheels.csv", "t_s,rl_rev,rr_rev\n0,NaN,inf\n0.1,1e308,-0\n"),
];

fn main() {
    let root = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "corpus".to_string()));
    let scratch = std::env::temp_dir().join(format!("wheelcal-make-corpus-{}", std::process::id()));
    let drives = [
        ("rear-rev", drive(4, WheelUnits::rear(WheelUnit::Rev), false)),
        ("all-full", drive(8, WheelUnits::all(WheelUnit::Ticks), true)),
        ("mixed", {
            let mut units = WheelUnits::rear(WheelUnit::MS);
            units.fl = Some(WheelUnit::RadS);
            drive(4, units, true)
        }),
    ];
    for (name, d) in &drives {
        // The drive folder: every stream file becomes a csv_stream seed.
        let folder = scratch.join(name);
        drive_io::write_drive(d, &folder).expect("write the folder");
        for file in CSV_FILES {
            if let Ok(content) = std::fs::read(folder.join(file)) {
                let stem = file.trim_end_matches(".csv");
                write(
                    &root.join("csv_stream"),
                    &format!("seed-{name}-{stem}"),
                    &csv_seed(file, &content),
                );
            }
        }
        for file in ["vehicle.toml", "truth.toml"] {
            if let Ok(content) = std::fs::read(folder.join(file)) {
                let stem = file.trim_end_matches(".toml");
                write(&root.join("vehicle_toml"), &format!("seed-{name}-{stem}"), &content);
            }
        }
        // The MCAP recording, whole, cut short, and with a changed byte.
        let mcap = scratch.join(format!("{name}.mcap"));
        drive_io::write_drive(d, &mcap).expect("write the recording");
        let bytes = std::fs::read(&mcap).expect("read the recording back");
        let out = root.join("mcap_recording");
        write(&out, &format!("seed-{name}"), &bytes);
        write(&out, &format!("seed-{name}-truncated"), &bytes[..bytes.len() * 2 / 3]);
        let mut flipped = bytes.clone();
        let i = bytes.len() / 2;
        flipped[i] ^= 0x55;
        write(&out, &format!("seed-{name}-flipped"), &flipped);
    }
    for (i, (file, content)) in CSV_EXTRA.iter().enumerate() {
        write(
            &root.join("csv_stream"),
            &format!("seed-hand-{i}"),
            &csv_seed(file, content.as_bytes()),
        );
    }
    for (i, text) in VEHICLE_TOMLS.iter().enumerate() {
        write(&root.join("vehicle_toml"), &format!("seed-hand-vehicle-{i}"), text.as_bytes());
    }
    write(&root.join("vehicle_toml"), "seed-hand-truth", TRUTH_TOML.as_bytes());
    for (i, text) in ESTIMATES.iter().enumerate() {
        write(&root.join("estimate_json"), &format!("seed-hand-{i}"), text.as_bytes());
        if let Ok(e) = Estimate::from_json_str(text, "seed") {
            let wire = e.to_wire(Header { t_ns: 1_000_000_000, seq: 3 }, i as u64 + 1);
            write(&root.join("wire_estimate"), &format!("seed-{i}"), &wire_bytes(&wire));
        }
    }
    write(
        &root.join("wire_estimate"),
        "seed-default",
        &wire_bytes(&CircumferenceEstimate::default()),
    );
    std::fs::remove_dir_all(&scratch).expect("remove the scratch folder");
    println!("seed corpus written to {}", root.display());
}

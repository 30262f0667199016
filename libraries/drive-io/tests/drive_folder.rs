//! Drive-folder reading: every bad-input case names file, line and column;
//! skipped rows and ignored columns produce warnings.

// Helpers outside #[test] functions unwrap too: a failure is a test failure.
#![allow(clippy::unwrap_used)]

use drive_io::{read_drive, write_drive, DriveError, LoadedDrive};
use std::path::Path;

const VEHICLE: &str = "track_width_m = 1.5\nnominal_circumference_m = 2.0\n";
const WHEELS: &str = "t_s,rl_rev,rr_rev\n0.0,0,0\n0.1,0.1,0.1\n0.2,0.2,0.2\n";

/// A drive folder with `vehicle.toml` and `wheels.csv` defaults, overridden or
/// extended by `files`.
fn folder(files: &[(&str, &str)]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("vehicle.toml"), VEHICLE).unwrap();
    std::fs::write(dir.path().join("wheels.csv"), WHEELS).unwrap();
    for (name, text) in files {
        std::fs::write(dir.path().join(name), text).unwrap();
    }
    dir
}

fn read(files: &[(&str, &str)]) -> Result<LoadedDrive, DriveError> {
    let dir = folder(files);
    read_drive(dir.path())
}

fn error(files: &[(&str, &str)]) -> String {
    match read(files) {
        Ok(_) => panic!("expected an error for {files:?}"),
        Err(e) => e.to_string(),
    }
}

fn assert_contains(message: &str, parts: &[&str]) {
    for p in parts {
        assert!(message.contains(p), "`{p}` not in message: {message}");
    }
}

#[test]
fn a_minimal_folder_reads() {
    let loaded = read(&[]).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let d = loaded.drive;
    assert_eq!(d.wheels.samples.len(), 3);
    assert_eq!(d.wheels.samples[2].rl, 0.2);
    assert!(d.gnss.is_none() && d.imu.is_none() && d.heading.is_none() && d.truth.is_none());
    assert_eq!(d.vehicle.track_width_m, 1.5);
}

#[test]
fn missing_required_column_is_named() {
    let msg = error(&[("wheels.csv", "t_s,rl_rev\n0,0\n")]);
    assert_contains(
        &msg,
        &[
            "wheels.csv:1",
            "missing required column",
            "rr_rev",
            "rr_rad_s",
        ],
    );
    let msg = error(&[("wheels.csv", "rl_rev,rr_rev\n0,0\n")]);
    assert_contains(&msg, &["wheels.csv:1", "missing required column `t_s`"]);
    let msg = error(&[("imu.csv", "t_s,ax_m_s2\n0,1\n")]);
    assert_contains(&msg, &["imu.csv:1", "missing required column `gz_rad_s`"]);
    let msg = error(&[("gnss.csv", "t_s,x_m\n0,1\n")]);
    assert_contains(&msg, &["gnss.csv:1", "missing required column `y_m`"]);
    let msg = error(&[("gnss.csv", "t_s,sigma_m\n0,1\n")]);
    assert_contains(&msg, &["gnss.csv:1", "x_m,y_m or lat_deg,lon_deg"]);
    let msg = error(&[("heading.csv", "t_s,sigma_rad\n0,1\n")]);
    assert_contains(
        &msg,
        &["heading.csv:1", "missing required column `yaw_rad`"],
    );
    // The header line is counted after comments.
    let msg = error(&[("truth.csv", "# a comment\n\nt_s,x_m\n0,1\n")]);
    assert_contains(&msg, &["truth.csv:3", "missing required column `y_m`"]);
}

#[test]
fn missing_required_file_or_key_is_named() {
    let dir = folder(&[]);
    std::fs::remove_file(dir.path().join("wheels.csv")).unwrap();
    let msg = read_drive(dir.path()).unwrap_err().to_string();
    assert_contains(&msg, &["wheels.csv", "required file is missing"]);
    let msg = error(&[("vehicle.toml", "track_width_m = 1.5\n")]);
    assert_contains(&msg, &["vehicle.toml", "nominal_circumference_m"]);
}

#[test]
fn non_numeric_cell_names_file_line_and_column() {
    let msg = error(&[("gnss.csv", "t_s,x_m,y_m\n0,1,2\n1,abc,2\n")]);
    assert_contains(
        &msg,
        &["gnss.csv:3", "column `x_m`", "not a number", "`abc`"],
    );
    let msg = error(&[(
        "wheels.csv",
        "t_s,rl_rev,rr_rev\n0,0,0\n# comment\n0.1,0.1,1,5\n",
    )]);
    assert_contains(
        &msg,
        &["wheels.csv:4", "4 cells, but the header has 3 columns"],
    );
}

#[test]
fn empty_required_cell_is_an_error() {
    let msg = error(&[("wheels.csv", "t_s,rl_rev,rr_rev\n0,0,0\n0.1,,0.1\n")]);
    assert_contains(
        &msg,
        &["wheels.csv:3", "column `rl_rev`", "required value is empty"],
    );
}

#[test]
fn time_going_backwards_names_file_and_line() {
    let msg = error(&[(
        "wheels.csv",
        "t_s,rl_rev,rr_rev\n0.1,0,0\n0.2,0,0\n0.15,0,0\n",
    )]);
    assert_contains(
        &msg,
        &[
            "wheels.csv:4",
            "t_s = 0.15 does not increase",
            "previous row has t_s = 0.2",
        ],
    );
    // Equal times are not increasing either.
    let msg = error(&[("imu.csv", "t_s,gz_rad_s\n# c\n1,0\n1,0\n")]);
    assert_contains(&msg, &["imu.csv:4", "t_s = 1 does not increase"]);
}

#[test]
fn nan_and_infinite_cells_are_refused() {
    let msg = error(&[("imu.csv", "t_s,gz_rad_s\n0,0.1\n0.01,NaN\n")]);
    assert_contains(
        &msg,
        &["imu.csv:3", "column `gz_rad_s`", "NaN or infinite", "`NaN`"],
    );
    let msg = error(&[("heading.csv", "t_s,yaw_rad,sigma_rad\n0,0.1,-inf\n")]);
    assert_contains(
        &msg,
        &[
            "heading.csv:2",
            "column `sigma_rad`",
            "NaN or infinite",
            "`-inf`",
        ],
    );
    let msg = error(&[("wheels.csv", "t_s,rl_rev,rr_rev\nnan,0,0\n")]);
    assert_contains(&msg, &["wheels.csv:2", "column `t_s`", "NaN or infinite"]);
    let msg = error(&[(
        "vehicle.toml",
        "track_width_m = nan\nnominal_circumference_m = 2.0\n",
    )]);
    assert_contains(
        &msg,
        &["vehicle.toml", "track_width_m", "not a finite number"],
    );
}

#[test]
fn unknown_wheel_column_is_an_error() {
    let msg = error(&[("wheels.csv", "t_s,rl_furlongs,rr_rev\n0,0,0\n")]);
    assert_contains(
        &msg,
        &["wheels.csv:1", "unknown wheel column `rl_furlongs`"],
    );
    let msg = error(&[("wheels.csv", "t_s,rl_rev,rr_rev,xx_rev\n0,0,0,0\n")]);
    assert_contains(&msg, &["wheels.csv:1", "unknown wheel column `xx_rev`"]);
    let msg = error(&[("wheels.csv", "t_s,rl_rev,rr_rev,rl_rad_s\n0,0,0,0\n")]);
    assert_contains(
        &msg,
        &[
            "wheels.csv:1",
            "wheel rl has two columns",
            "rl_rev",
            "rl_rad_s",
        ],
    );
    let msg = error(&[("wheels.csv", "t_s,rl_ticks,rr_ticks\n0,0,0\n")]);
    assert_contains(&msg, &["wheels.csv:1", "rl_ticks", "ticks_per_rev"]);
}

#[test]
fn fix_zero_rows_are_skipped_with_a_warning() {
    let gnss =
        "t_s,x_m,y_m,sigma_m,fix\n0,1,2,0.5,1\n0.1,,,,0\n0.2,3,4,,1\n0.3,9,9,1,0\n0.4,5,6,,\n";
    let loaded = read(&[("gnss.csv", gnss)]).unwrap();
    let g = loaded.drive.gnss.unwrap();
    assert_eq!(
        g.iter().map(|s| s.t_s).collect::<Vec<_>>(),
        vec![0.0, 0.2, 0.4]
    );
    assert_eq!(g[0].sigma_m, Some(0.5));
    assert_eq!(g[1].sigma_m, None);
    assert_eq!(loaded.warnings.len(), 1, "{:?}", loaded.warnings);
    assert_contains(
        &loaded.warnings[0],
        &[
            "gnss.csv",
            "ignored 2 row(s) with fix = 0",
            "first at line 3",
        ],
    );
}

#[test]
fn unknown_columns_are_ignored_with_a_warning() {
    let loaded = read(&[
        ("wheels.csv", "t_s,rl_rev,speed,rr_rev\n0,0,9,0\n0.1,1,9,1\n"),
        ("imu.csv", "t_s,gz_rad_s,temp_c,mag_x\n0,0.1,20,3\n"),
        ("notes.csv", "whatever\n"),
        ("vehicle.toml", "track_width_m = 1.5\nnominal_circumference_m = 2.0\ncolour = \"red\"\n[gnss]\nheight_m = 1.0\n"),
    ])
    .unwrap();
    let w = loaded.warnings.join("\n");
    assert_contains(&w, &["wheels.csv: ignored unknown column(s): speed"]);
    assert_contains(&w, &["imu.csv: ignored unknown column(s): temp_c, mag_x"]);
    assert_contains(
        &w,
        &["vehicle.toml: ignored unknown key(s): colour, gnss.height_m"],
    );
    assert_contains(&w, &["not part of the drive-folder format: notes.csv"]);
    assert_eq!(loaded.drive.wheels.samples[1].rr, 1.0);
    assert_eq!(loaded.drive.imu.unwrap()[0].gz_rad_s, 0.1);
}

#[test]
fn comments_blank_lines_empty_cells_and_crlf() {
    let wheels = "# recorded by hand\r\nt_s, rl_rad_s ,rr_rad_s,fl_rad_s\r\n0,1,2,\r\n\r\n# pause\r\n0.5,1,2,3\r\n";
    let d = read(&[("wheels.csv", wheels)]).unwrap().drive;
    assert_eq!(d.wheels.samples.len(), 2);
    assert_eq!(d.wheels.samples[0].fl, None);
    assert_eq!(d.wheels.samples[1].fl, Some(3.0));
    assert_eq!(d.wheels.samples[1].fr, None);
    assert!(d.wheels.units.fr.is_none());
}

#[test]
fn lat_lon_is_converted_with_one_origin_recorded_in_the_vehicle() {
    let gnss = "t_s,lat_deg,lon_deg\n0,32.0,35.0\n1,32.001,35.0\n2,32.001,35.001\n";
    let truth = "t_s,lat_deg,lon_deg,yaw_rad\n-1,32.0,35.0,0.5\n0.5,32.0,35.001,\n";
    let d = read(&[("gnss.csv", gnss), ("truth.csv", truth)])
        .unwrap()
        .drive;
    assert_eq!(d.vehicle.gnss.origin_lat_deg, Some(32.0));
    assert_eq!(d.vehicle.gnss.origin_lon_deg, Some(35.0));
    let g = d.gnss.unwrap();
    assert_eq!((g[0].x_m, g[0].y_m), (0.0, 0.0));
    // 0.001 deg of latitude at 32 deg is about 110.85 m; of longitude about 94.5 m.
    assert!(
        g[1].x_m.abs() < 1e-6 && (g[1].y_m - 110.85).abs() < 0.05,
        "{:?}",
        g[1]
    );
    assert!((g[2].x_m - 94.48).abs() < 0.05, "{:?}", g[2]);
    let t = d.truth.unwrap();
    assert_eq!((t[0].x_m, t[0].y_m, t[0].yaw_rad), (0.0, 0.0, Some(0.5)));
    let frame = drive_io::geodesy::LocalFrame::new(32.0, 35.0, 0.0);
    assert_eq!(
        (t[1].x_m, t[1].y_m),
        frame.to_en(32.0, 35.001),
        "truth uses the GNSS origin"
    );

    // An origin given in vehicle.toml wins over the first fix.
    let vehicle = "track_width_m = 1.5\nnominal_circumference_m = 2.0\n[gnss]\norigin_lat_deg = 32.001\norigin_lon_deg = 35.0\nantenna_x_m = 1.2\n";
    let d = read(&[("gnss.csv", gnss), ("vehicle.toml", vehicle)])
        .unwrap()
        .drive;
    let g = d.gnss.unwrap();
    assert!(
        (g[0].y_m + 110.85).abs() < 0.05 && g[1].y_m.abs() < 1e-6,
        "{g:?}"
    );
    assert_eq!(d.vehicle.gnss.antenna_x_m, Some(1.2));

    let msg = error(&[("gnss.csv", "t_s,lat_deg,lon_deg\n0,95,35\n")]);
    assert_contains(
        &msg,
        &["gnss.csv:2", "column `lat_deg`", "latitude outside"],
    );
    let msg = error(&[("gnss.csv", "t_s,lat_deg,lon_deg,x_m,y_m\n0,32,35,0,0\n")]);
    assert_contains(&msg, &["gnss.csv:1", "both x_m/y_m and lat_deg/lon_deg"]);
}

#[test]
fn ticks_use_ticks_per_rev_and_write_back() {
    let vehicle = "name = \"cart\"\ntrack_width_m = 1.5\nnominal_circumference_m = 2.0\nticks_per_rev = 96\nwheelbase_m = 2.7\n";
    let wheels = "t_s,rl_ticks,rr_ticks,fl_m_s,fr_rev\n0,0,0,1.5,10\n0.1,96,48,1.5,10.5\n";
    let loaded = read(&[("vehicle.toml", vehicle), ("wheels.csv", wheels)]).unwrap();
    let revs = loaded.drive.wheel_revolutions().unwrap();
    assert_eq!(revs[1].rl, 1.0);
    assert_eq!(revs[1].rr, 0.5);
    let out = tempfile::tempdir().unwrap();
    write_drive(&loaded.drive, out.path()).unwrap();
    let text = std::fs::read_to_string(out.path().join("wheels.csv")).unwrap();
    assert!(
        text.starts_with("t_s,rl_ticks,rr_ticks,fl_m_s,fr_rev\n"),
        "{text}"
    );
    assert_eq!(read_drive(out.path()).unwrap().drive, loaded.drive);
}

#[test]
fn writing_refuses_a_drive_that_would_not_read_back() {
    let mut d = read(&[]).unwrap().drive;
    d.wheels.samples[1].rr = f64::NAN;
    let out = tempfile::tempdir().unwrap();
    let msg = write_drive(&d, &out.path().join("x"))
        .unwrap_err()
        .to_string();
    assert_contains(&msg, &["wheels[1]", "rr = NaN is not finite"]);
    d.wheels.samples[1].rr = 0.0;
    d.wheels.samples[2].t_s = 0.05;
    let msg = write_drive(&d, &out.path().join("x.mcap"))
        .unwrap_err()
        .to_string();
    assert_contains(&msg, &["wheels[2]", "does not increase"]);
    assert!(!Path::new(&out.path().join("x.mcap")).exists());
}

#[test]
fn writing_a_folder_removes_stale_drive_files_only() {
    let dir = folder(&[
        ("heading.csv", "t_s,yaw_rad\n0,1\n"),
        ("notes.txt", "keep me"),
    ]);
    let d = read_drive(dir.path()).unwrap().drive;
    let mut without_heading = d.clone();
    without_heading.heading = None;
    write_drive(&without_heading, dir.path()).unwrap();
    assert!(!dir.path().join("heading.csv").exists());
    assert!(dir.path().join("notes.txt").exists());
    assert_eq!(read_drive(dir.path()).unwrap().drive, without_heading);
}

#[test]
fn the_error_type_stays_small() {
    // Callers wrap DriveError in their own errors; clippy's result_large_err
    // fires at 128 bytes.
    assert!(
        std::mem::size_of::<DriveError>() <= 88,
        "{}",
        std::mem::size_of::<DriveError>()
    );
}

/// A service's `--vehicle` file is checked as a drive's `vehicle.toml` is,
/// and a drive folder gives the vehicle `read_drive` gives.
#[test]
fn a_vehicle_file_for_a_service_is_checked_like_a_drives() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("car.toml");
    std::fs::write(&path, format!("{VEHICLE}wheel_base_m = 2.6\n")).unwrap();
    let loaded = drive_io::read_vehicle(&path).unwrap();
    assert_eq!(loaded.vehicle.track_width_m, 1.5);
    assert_eq!(loaded.vehicle.nominal_circumference_m, 2.0);
    assert_eq!(loaded.warnings.len(), 1, "{:?}", loaded.warnings);
    assert_contains(&loaded.warnings[0], &["car.toml", "wheel_base_m"]);

    std::fs::write(
        &path,
        "track_width_m = nan\nnominal_circumference_m = 2.0\n",
    )
    .unwrap();
    let msg = drive_io::read_vehicle(&path).unwrap_err().to_string();
    assert_contains(&msg, &["car.toml", "track_width_m", "not a finite number"]);

    let msg = drive_io::read_vehicle(&dir.path().join("absent.toml"))
        .unwrap_err()
        .to_string();
    assert_contains(&msg, &["absent.toml"]);

    // A folder with lat/lon fixes and no origin: the origin is the first fix.
    let drive = folder(&[(
        "gnss.csv",
        "t_s,lat_deg,lon_deg\n0.0,47.5,19.0\n0.1,47.5,19.0\n",
    )]);
    let from_folder = drive_io::read_vehicle(drive.path()).unwrap().vehicle;
    assert_eq!(from_folder, read_drive(drive.path()).unwrap().drive.vehicle);
    assert_eq!(from_folder.gnss.origin_lat_deg, Some(47.5));
}

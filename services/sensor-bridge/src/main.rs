//! `sensor-bridge` command-line entry point.
//!
//! Each subcommand is one variant of [`Command`] dispatching to one function.

mod drive_input;
mod graph_cmds;
mod simulate_cmd;
mod twin_cmd;

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use drive_input::DriveInput;
use drive_io::plausibility::{self, Severity};
use drive_io::{write_drive_with, DriveError, DriveSummary, LoadedDrive, WriteOptions};
use std::path::{Path, PathBuf};

/// Drives in and out, the simulator, and the iceoryx2 bridge.
#[derive(Parser)]
#[command(name = "sensor-bridge", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Convert a drive between a drive folder and an MCAP recording (either
    /// direction; OUT ending in .mcap is written as MCAP, anything else as a folder).
    Convert(ConvertArgs),
    /// Summarise a drive: duration, distance, rate and gaps of every stream,
    /// GNSS outages, physically impossible values (plausibility), loading warnings.
    Info(InfoArgs),
    /// Publish a drive over iceoryx2 with its recorded timestamps, paced at
    /// --speed FACTOR times real time or as fast as subscribers take it (--max).
    Replay(graph_cmds::ReplayArgs),
    /// Subscribe to every sensor topic and write a recording (until Ctrl-C,
    /// or the end of the stream with --until-end).
    Record(graph_cmds::RecordArgs),
    /// Simulate a drive with its own truth (truth.csv, truth.toml): scenario
    /// paper, garage, mixed or long; every physics-catalogue effect is a knob.
    /// With --publish [--speed F | --max] it is also published live, as by `replay`.
    /// With --like DRIVE [--effects-from DIAGNOSIS.json]: the twin of a recorded drive.
    Simulate(simulate_cmd::SimulateArgs),
}

#[derive(Args)]
struct ConvertArgs {
    /// Input drive: a drive folder or an .mcap file (ours, compressed or
    /// not, or a ROS 2 bag with --vehicle).
    input: PathBuf,
    /// Output: an .mcap file or a folder.
    output: PathBuf,
    /// Convert what can be read from a truncated MCAP instead of failing.
    #[arg(long)]
    allow_truncated: bool,
    /// Leave out each MCAP chunk whose records fail their CRC (a warning
    /// names each one) instead of refusing the recording.
    #[arg(long)]
    skip_corrupt_chunks: bool,
    #[command(flatten)]
    input_options: DriveInput,
    #[command(flatten)]
    foxglove: FoxgloveArgs,
}

/// Whether an MCAP output also carries Foxglove's well-known schemas.
#[derive(Args, Debug)]
pub(crate) struct FoxgloveArgs {
    /// Leave out the channels in Foxglove's well-known schemas (GNSS in
    /// lat/lon for the Map panel, true poses and transforms for the 3D
    /// panel, warnings for the Log panel). They are written by default:
    /// they are derived from the drive's own channels, which readers use,
    /// and make the file 10-40 % larger (the real drives: wid-trial02
    /// 4.46 -> 4.94 MB, comma2k19-seg40 2.07 -> 2.87 MB).
    #[arg(long)]
    pub no_foxglove: bool,
}

impl FoxgloveArgs {
    /// The write options for an output with these `warnings` (logged in
    /// the recording); says when the GNSS has no geodetic origin.
    pub fn write_options(
        &self,
        drive: &interfaces::drive::Drive,
        out: &Path,
        warnings: Vec<String>,
    ) -> WriteOptions {
        let foxglove = !self.no_foxglove && drive_io::is_mcap_path(out);
        let origin = drive.vehicle.gnss.origin_lat_deg.is_some();
        if foxglove && drive.gnss.is_some() && !origin {
            tracing::info!(
                "the GNSS fixes have no geodetic origin (vehicle.toml [gnss] origin_lat_deg, origin_lon_deg): \
                 {} gets no foxglove.LocationFix channel (Foxglove's Map panel stays empty)",
                out.display()
            );
        }
        WriteOptions {
            foxglove,
            warnings,
            ..WriteOptions::default()
        }
    }
}

#[derive(Args)]
struct InfoArgs {
    /// A drive folder or an .mcap file (ours, compressed or not, or a ROS 2
    /// bag with --vehicle).
    drive: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
    /// Leave out each MCAP chunk whose records fail their CRC (a warning
    /// names each one) instead of refusing the recording.
    #[arg(long)]
    skip_corrupt_chunks: bool,
    #[command(flatten)]
    input: DriveInput,
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    interfaces::logging::init();
    match cli.command {
        Command::Convert(args) => convert(&args),
        Command::Info(args) => info(&args),
        Command::Replay(args) => graph_cmds::run_replay(&args),
        Command::Record(args) => graph_cmds::run_record(&args),
        Command::Simulate(args) => match &args.like {
            Some(like) => twin_cmd::run(&args, like)
                .map(|_| ())
                .context("simulate --like"),
            None => simulate_cmd::run(&args).map(|_| ()).context("simulate"),
        },
    }
}

fn print_warnings(loaded: &LoadedDrive) {
    for w in &loaded.warnings {
        tracing::warn!("{w}");
    }
}

fn convert(args: &ConvertArgs) -> Result<()> {
    if args.input == args.output {
        bail!(
            "input and output are the same path: {}",
            args.input.display()
        );
    }
    let read = args
        .input_options
        .read(&args.input, args.skip_corrupt_chunks)?;
    // A truncated recording: what was read before the damage, with a
    // warning naming the damage (kept in the converted recording's log),
    // only with --allow-truncated.
    let loaded = drive_io::cli::accept_truncated(read, args.allow_truncated)
        .with_context(|| format!("reading {}", args.input.display()))?;
    print_warnings(&loaded);
    // What is said here is also logged in the recording (foxglove.Log).
    let mut warnings = loaded.warnings.clone();
    // The conversion keeps every value as it is; what is physically
    // impossible is said here, before anyone calibrates on it.
    for f in plausibility::findings(&loaded.drive) {
        let text = match f.severity() {
            Severity::Error => {
                format!("plausibility error (the calibrator refuses this drive): {f}")
            }
            Severity::Warning => format!("plausibility warning: {f}"),
        };
        tracing::warn!("{text}");
        warnings.push(text);
    }
    let options = args
        .foxglove
        .write_options(&loaded.drive, &args.output, warnings);
    write_drive_with(&loaded.drive, &args.output, &options)
        .with_context(|| format!("writing {}", args.output.display()))?;
    tracing::info!(
        "wrote {} ({} wheel samples)",
        args.output.display(),
        loaded.drive.wheels.samples.len()
    );
    Ok(())
}

fn print_summary(loaded: &LoadedDrive, path: &Path, json: bool) -> Result<()> {
    let summary = DriveSummary::of_loaded(loaded);
    if json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!("drive:     {}", path.display());
        print!("{summary}");
    }
    Ok(())
}

fn info(args: &InfoArgs) -> Result<()> {
    match args.input.read(&args.drive, args.skip_corrupt_chunks)? {
        Ok(loaded) => print_summary(&loaded, &args.drive, args.json),
        Err(DriveError::TruncatedMcap {
            partial: Some(partial),
            path,
            offset,
            file_len,
            record,
            messages_read,
        }) => {
            // Show what could be read, then fail with the damage.
            print_summary(&partial, &args.drive, args.json)?;
            Err(DriveError::TruncatedMcap {
                path,
                offset,
                file_len,
                record,
                messages_read,
                partial: None,
            })
            .context("the recording is damaged; the summary above covers what was read")
        }
        Err(e) => Err(e).with_context(|| format!("reading {}", args.drive.display())),
    }
}

//! `sensor-bridge` command-line entry point.

fn main() {}

//! `calibrator` command-line entry point.

fn main() {}

//! `odometry` command-line entry point.

fn main() {}

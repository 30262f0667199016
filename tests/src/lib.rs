//! Integration tests of the workspace: [`graph`] starts the real binaries as a
//! process graph over iceoryx2 for the `graph_*` tests, and [`demo`] is the
//! main job (`wheelcal-demo`) that runs the whole graph on a built-in drive;
//! [`latency`] has what the latency benchmarks share.

pub mod demo;
pub mod graph;
pub mod latency;

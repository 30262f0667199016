//! Integration tests of the workspace: [`graph`] starts the real binaries as a
//! process graph over iceoryx2 for the `graph_*` tests; [`latency`] has what
//! the latency benchmarks share; [`faults`] is the fault suite (services
//! killed at random moments); [`python`] finds a Python for the example
//! subscribers' tests; [`campaign`] judges the bad-input campaign bench's
//! outcomes; [`outages`] what the clock-fault bench and tests score. The main job (`wheelcal-demo`) lives in
//! `examples/demo`.

pub mod campaign;
pub mod faults;
pub mod graph;
pub mod latency;
pub mod outages;
pub mod python;

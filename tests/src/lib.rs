//! Integration tests of the workspace; [`graph`] starts the real binaries
//! as a process graph over iceoryx2 for the `graph_*` tests.

pub mod graph;

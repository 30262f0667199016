//! The wheelcal gateway: carries chosen topics of the local iceoryx2 graph
//! to other hosts over Zenoh, and topics of other hosts into the local graph.
//!
//! Why a crate of its own: Zenoh (and the async runtime under it) is a large
//! dependency that only a multi-host set-up needs. Living in this crate
//! alone, it is built only with it (`cargo build --release -p gateway`); the
//! services, which hold no Zenoh code, stay as lean as before, and no service
//! crate depends on another (the gateway depends on `interfaces` only).
//!
//! The library holds what is decided without a network or a bus: the frame
//! format ([`header`]) and which topics go which way ([`routes`]). The
//! process (the `gateway` binary) holds the Zenoh session and the iceoryx2
//! ports. Design: `docs/design/gateway.md`.

pub mod header;
pub mod routes;

//! The Zenoh session: peer mode, the given endpoints, scouting off unless
//! asked, and the liveliness token that tells peers this gateway is up.

use crate::GatewaySettings;
use anyhow::{anyhow, Result};
use gateway::routes::Routes;
use zenoh::liveliness::LivelinessToken;
use zenoh::{Session, Wait};

/// A JSON5 list of strings.
fn json_list(items: &[String]) -> String {
    let quoted: Vec<String> = items.iter().map(|s| format!("{s:?}")).collect();
    format!("[{}]", quoted.join(","))
}

/// Open the Zenoh session of `settings`.
pub fn open(settings: &GatewaySettings) -> Result<Session> {
    let mut config = zenoh::Config::default();
    let set = |config: &mut zenoh::Config, key: &str, value: &str| {
        config
            .insert_json5(key, value)
            .map_err(|e| anyhow!("zenoh setting {key} = {value}: {e}"))
    };
    set(&mut config, "mode", "\"peer\"")?;
    if !settings.listen.is_empty() {
        set(
            &mut config,
            "listen/endpoints",
            &json_list(&settings.listen),
        )?;
    }
    if !settings.connect.is_empty() {
        set(
            &mut config,
            "connect/endpoints",
            &json_list(&settings.connect),
        )?;
        // A peer that went away is looked for again every 0.2 s at first,
        // then every second (Zenoh's defaults: 1 s, then 4 s).
        set(
            &mut config,
            "connect/retry",
            "{ period_init_ms: 200, period_max_ms: 1000, period_increase_factor: 2 }",
        )?;
    }
    let scouting = if settings.scouting { "true" } else { "false" };
    set(&mut config, "scouting/multicast/enabled", scouting)?;
    zenoh::open(config)
        .wait()
        .map_err(|e| anyhow!("cannot open the Zenoh session: {e}"))
}

/// Declare this gateway's liveliness token (after its subscribers).
pub fn declare_token(session: &Session, routes: &Routes, id: u64) -> Result<LivelinessToken> {
    let key = routes.gateway_token(id);
    session
        .liveliness()
        .declare_token(&key)
        .wait()
        .map_err(|e| anyhow!("cannot declare the liveliness token {key}: {e}"))
}

/// Close the session (a failure only logged: the process ends anyway).
pub fn close(session: Session) {
    if let Err(e) = session.close().wait() {
        tracing::warn!("gateway: closing the Zenoh session: {e}");
    }
}

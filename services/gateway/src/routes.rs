//! Which topics a gateway carries which way, from the command line or a
//! TOML file, checked so that no topic can come back to where it came from.
//!
//! A topic is either sent (`out`: local graph -> Zenoh) or received (`in`:
//! Zenoh -> local graph) by a gateway, never both, and a graph has at most
//! one gateway (the gateway refuses to start beside another). So a sample
//! enters Zenoh only from the graph whose gateway sends its topic, and is
//! published only into graphs whose gateways receive it, which never send it
//! on: no sample crosses Zenoh twice, whatever the hosts' configurations.

use interfaces::bus::{Delivery, Topic};
use interfaces::wire::{CircumferenceEstimate, GnssFix, Heading, Imu, Pose, WheelRotations};
use serde::Deserialize;

/// A topic of the graph the gateway can carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum TopicId {
    /// `wheelcal/sensors/wheels`.
    Wheels,
    /// `wheelcal/sensors/gnss`.
    Gnss,
    /// `wheelcal/sensors/imu`.
    Imu,
    /// `wheelcal/sensors/heading`.
    Heading,
    /// `wheelcal/calibration/estimate`.
    Estimate,
    /// `wheelcal/odometry/pose`.
    Pose,
}

/// Every topic, in the order the short names are listed in help texts.
pub const ALL_TOPICS: [TopicId; 6] = [
    TopicId::Wheels,
    TopicId::Gnss,
    TopicId::Imu,
    TopicId::Heading,
    TopicId::Estimate,
    TopicId::Pose,
];

impl TopicId {
    /// The short name used on the command line and in the TOML file.
    pub fn short(self) -> &'static str {
        match self {
            TopicId::Wheels => "wheels",
            TopicId::Gnss => "gnss",
            TopicId::Imu => "imu",
            TopicId::Heading => "heading",
            TopicId::Estimate => "estimate",
            TopicId::Pose => "pose",
        }
    }

    /// The iceoryx2 service name.
    pub fn service(self) -> &'static str {
        self.info().0
    }

    /// The versioned type name.
    pub fn type_name(self) -> &'static str {
        self.info().1
    }

    /// The sample size, bytes.
    pub fn size(self) -> usize {
        self.info().2
    }

    /// True for a "latest value" topic (history 1: the estimate): a late
    /// subscriber on another host gets the latest sample too.
    pub fn is_latest(self) -> bool {
        matches!(self.info().3, Delivery::Latest { .. })
    }

    fn info(self) -> (&'static str, &'static str, usize, Delivery) {
        fn of<T: Topic>() -> (&'static str, &'static str, usize, Delivery) {
            (T::SERVICE, T::TYPE_NAME, size_of::<T>(), T::DELIVERY)
        }
        match self {
            TopicId::Wheels => of::<WheelRotations>(),
            TopicId::Gnss => of::<GnssFix>(),
            TopicId::Imu => of::<Imu>(),
            TopicId::Heading => of::<Heading>(),
            TopicId::Estimate => of::<CircumferenceEstimate>(),
            TopicId::Pose => of::<Pose>(),
        }
    }

    /// The Zenoh key expression of the topic under `namespace` (empty: the
    /// service name itself, e.g. `wheelcal/odometry/pose`).
    pub fn key(self, namespace: &str) -> String {
        if namespace.is_empty() {
            self.service().to_string()
        } else {
            format!("{}/{}", namespace.trim_end_matches('/'), self.service())
        }
    }

    /// The topic with this short name.
    pub fn parse(name: &str) -> Result<TopicId, RouteError> {
        ALL_TOPICS
            .into_iter()
            .find(|t| t.short() == name.trim())
            .ok_or_else(|| RouteError::UnknownTopic(name.trim().to_string()))
    }
}

/// A list of short topic names, comma-separated (`wheels,gnss,imu`).
pub fn parse_list(list: &str) -> Result<Vec<TopicId>, RouteError> {
    list.split(',')
        .filter(|s| !s.trim().is_empty())
        .map(TopicId::parse)
        .collect()
}

/// Bad routing settings.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RouteError {
    /// A name that is no topic.
    #[error("unknown topic {0:?} (topics: wheels, gnss, imu, heading, estimate, pose)")]
    UnknownTopic(String),
    /// A topic listed both ways.
    #[error(
        "topic {0:?} is both sent (out) and received (in): a gateway carries a topic one way \
         only, so that nothing it receives can go back"
    )]
    BothWays(&'static str),
    /// Nothing to carry.
    #[error("no topic to carry: give --out and/or --in (or `out`/`in` in the config file)")]
    Nothing,
    /// The namespace is not a usable key expression prefix.
    #[error("namespace {0:?}: use letters, digits, '-', '_' and '/' only (no wildcards)")]
    Namespace(String),
    /// The TOML file could not be read.
    #[error("{file}: {detail}")]
    File {
        /// The file.
        file: String,
        /// What is wrong (line and column for a syntax error).
        detail: String,
    },
}

/// The topics a gateway sends and receives, checked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Routes {
    /// Local graph -> Zenoh.
    pub out: Vec<TopicId>,
    /// Zenoh -> local graph.
    pub inbound: Vec<TopicId>,
    /// Key expression prefix of every topic (empty: none).
    pub namespace: String,
}

impl Routes {
    /// Check and build: duplicates are merged, a topic may not go both ways,
    /// and at least one topic must go somewhere.
    pub fn new(
        out: &[TopicId],
        inbound: &[TopicId],
        namespace: &str,
    ) -> Result<Routes, RouteError> {
        let mut out = out.to_vec();
        let mut inbound = inbound.to_vec();
        out.sort();
        out.dedup();
        inbound.sort();
        inbound.dedup();
        if let Some(t) = out.iter().find(|t| inbound.contains(t)) {
            return Err(RouteError::BothWays(t.short()));
        }
        if out.is_empty() && inbound.is_empty() {
            return Err(RouteError::Nothing);
        }
        let ns = namespace.trim_matches('/');
        if !ns
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '/'))
            || ns.contains("//")
        {
            return Err(RouteError::Namespace(namespace.to_string()));
        }
        Ok(Routes {
            out,
            inbound,
            namespace: ns.to_string(),
        })
    }

    /// Key expression of the liveliness token of gateway `id`.
    pub fn gateway_token(&self, id: u64) -> String {
        format!("{}/{id:016x}", self.gateway_tokens())
    }

    /// Key expression matching every gateway's liveliness token.
    pub fn gateway_tokens(&self) -> String {
        if self.namespace.is_empty() {
            "wheelcal/_gateways".to_string()
        } else {
            format!("{}/wheelcal/_gateways", self.namespace)
        }
    }
}

/// The gateway's TOML file: every field optional, the command line's
/// settings of the same name take precedence.
///
/// ```toml
/// out = ["wheels", "gnss", "imu", "heading", "estimate"]
/// in = ["pose"]
/// namespace = "car7"
/// listen = ["tcp/0.0.0.0:7447"]
/// connect = ["tcp/192.168.1.20:7447"]
/// ```
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileSettings {
    /// Topics sent (short names).
    #[serde(default)]
    pub out: Vec<String>,
    /// Topics received (short names).
    #[serde(default, rename = "in")]
    pub inbound: Vec<String>,
    /// Key expression prefix.
    pub namespace: Option<String>,
    /// Zenoh endpoints to listen on.
    #[serde(default)]
    pub listen: Vec<String>,
    /// Zenoh endpoints to connect to.
    #[serde(default)]
    pub connect: Vec<String>,
    /// Zenoh multicast scouting (off unless set true).
    pub scouting: Option<bool>,
}

impl FileSettings {
    /// Parse the TOML text of `file` (named in errors).
    pub fn parse(file: &str, text: &str) -> Result<FileSettings, RouteError> {
        toml::from_str(text).map_err(|e| RouteError::File {
            file: file.to_string(),
            detail: e.to_string(),
        })
    }

    /// The `out` topics.
    pub fn out_topics(&self) -> Result<Vec<TopicId>, RouteError> {
        self.out.iter().map(|s| TopicId::parse(s)).collect()
    }

    /// The `in` topics.
    pub fn in_topics(&self) -> Result<Vec<TopicId>, RouteError> {
        self.inbound.iter().map(|s| TopicId::parse(s)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lists_parse_and_topics_know_their_types() {
        let l = parse_list("wheels, gnss,imu,heading,estimate").expect("list");
        assert_eq!(l.len(), 5);
        assert_eq!(TopicId::Pose.type_name(), "wheelcal/Pose/v1");
        assert_eq!(TopicId::Pose.size(), 128);
        assert_eq!(TopicId::Estimate.size(), 416);
        assert!(TopicId::Estimate.is_latest());
        assert!(!TopicId::Wheels.is_latest());
        assert_eq!(TopicId::Pose.key(""), "wheelcal/odometry/pose");
        assert_eq!(TopicId::Pose.key("car7/"), "car7/wheelcal/odometry/pose");
        let e = parse_list("wheels,odo").expect_err("unknown").to_string();
        assert!(e.contains("\"odo\""), "{e}");
    }

    #[test]
    fn a_topic_cannot_go_both_ways() {
        let e = Routes::new(&[TopicId::Pose, TopicId::Wheels], &[TopicId::Pose], "")
            .expect_err("both ways");
        assert_eq!(e, RouteError::BothWays("pose"));
        assert_eq!(Routes::new(&[], &[], ""), Err(RouteError::Nothing));
        let r =
            Routes::new(&[TopicId::Imu, TopicId::Imu], &[TopicId::Pose], "car7").expect("routes");
        assert_eq!(r.out, vec![TopicId::Imu]);
        assert_eq!(
            r.gateway_token(255),
            "car7/wheelcal/_gateways/00000000000000ff"
        );
        assert!(Routes::new(&[TopicId::Imu], &[], "car/*").is_err());
    }

    #[test]
    fn the_toml_file_names_its_errors() {
        let f = FileSettings::parse(
            "gw.toml",
            "out = [\"wheels\"]\nin = [\"pose\"]\nconnect = [\"tcp/10.0.0.2:7447\"]\n",
        )
        .expect("parse");
        assert_eq!(f.out_topics().expect("out"), vec![TopicId::Wheels]);
        assert_eq!(f.in_topics().expect("in"), vec![TopicId::Pose]);
        let e = FileSettings::parse("gw.toml", "outt = []\n")
            .expect_err("unknown field")
            .to_string();
        assert!(e.starts_with("gw.toml: "), "{e}");
        assert!(e.contains("outt"), "{e}");
    }
}

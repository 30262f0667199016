//! Which topic of a ROS 2 bag gives which stream of the drive.
//!
//! Written as `role=topic` assignments (`gnss=/fix`, `imu=/imu/data`,
//! `wheels=/joint_states`) and, for a `sensor_msgs/msg/JointState` wheels
//! topic, `joints.W=NAME` (W one of `rl rr fl fr`), or as a TOML file:
//!
//! ```toml
//! gnss = "/fix"
//! imu = "/imu/data"
//! wheels = "/joint_states"
//! [joints]
//! rl = "rear_left_wheel_joint"
//! rr = "rear_right_wheel_joint"
//! ```
//!
//! A role left out is chosen by message type (see docs/drive-format.md, "Recordings from other tools").

use crate::csv::clip;
use crate::files::{read_text_limited, MAX_TEXT_FILE_BYTES};
use crate::DriveError;
use interfaces::drive::Wheel;
use std::collections::BTreeMap;
use std::path::Path;

/// What a topic is read as.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Role {
    /// GNSS fixes (`sensor_msgs/msg/NavSatFix`).
    Gnss,
    /// IMU samples (`sensor_msgs/msg/Imu`).
    Imu,
    /// Wheel speeds (`sensor_msgs/msg/JointState`,
    /// `geometry_msgs/msg/TwistStamped` or `nav_msgs/msg/Odometry`).
    Wheels,
}

impl Role {
    /// Every role.
    pub const ALL: [Role; 3] = [Role::Gnss, Role::Imu, Role::Wheels];

    /// Its name in assignments and TOML keys.
    pub fn name(self) -> &'static str {
        match self {
            Role::Gnss => "gnss",
            Role::Imu => "imu",
            Role::Wheels => "wheels",
        }
    }

    /// The message types a topic of this role may have.
    pub fn types(self) -> &'static [&'static str] {
        match self {
            Role::Gnss => &["sensor_msgs/msg/NavSatFix"],
            Role::Imu => &["sensor_msgs/msg/Imu"],
            Role::Wheels => &[
                "sensor_msgs/msg/JointState",
                "geometry_msgs/msg/TwistStamped",
                "nav_msgs/msg/Odometry",
            ],
        }
    }
}

/// Topic per role, and the wheel joints of a `JointState` topic; what is
/// left out is chosen from the bag (see docs/drive-format.md, "Recordings from other tools").
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TopicMap {
    /// Topic per role.
    pub topics: BTreeMap<Role, String>,
    /// Joint name per wheel, for a `sensor_msgs/msg/JointState` wheels topic.
    pub joints: BTreeMap<Wheel, String>,
}

impl TopicMap {
    /// True when nothing is given.
    pub fn is_empty(&self) -> bool {
        self.topics.is_empty() && self.joints.is_empty()
    }

    /// Apply one `role=topic` or `joints.W=NAME` assignment (a later one
    /// for the same role or wheel replaces an earlier one).
    pub fn assign(&mut self, assignment: &str) -> Result<(), String> {
        let Some((key, value)) = assignment.split_once('=') else {
            return Err(format!(
                "`{}` is not KEY=VALUE (e.g. gnss=/fix, joints.rl=rear_left_wheel_joint)",
                clip(assignment)
            ));
        };
        self.set(key.trim(), value.trim())
    }

    fn set(&mut self, key: &str, value: &str) -> Result<(), String> {
        if value.is_empty() {
            return Err(format!("`{}` has an empty value", clip(key)));
        }
        if let Some(role) = Role::ALL.into_iter().find(|r| r.name() == key) {
            self.topics.insert(role, value.to_string());
            return Ok(());
        }
        if let Some(w) = key.strip_prefix("joints.") {
            let Some(wheel) = Wheel::ALL.into_iter().find(|x| x.prefix() == w) else {
                return Err(format!("`{}`: the wheels are rl, rr, fl, fr", clip(key)));
            };
            self.joints.insert(wheel, value.to_string());
            return Ok(());
        }
        Err(format!(
            "unknown key `{}` (the keys are gnss, imu, wheels and joints.rl|rr|fl|fr)",
            clip(key)
        ))
    }

    /// Parse a topic-map TOML file's text (`path` names it in errors).
    pub fn from_toml_str(path: &Path, text: &str) -> Result<TopicMap, DriveError> {
        let err = |message: String| DriveError::Toml {
            path: path.to_path_buf(),
            message,
        };
        let table: toml::Table = toml::from_str(text).map_err(|e| err(e.to_string()))?;
        let mut map = TopicMap::default();
        for (key, value) in &table {
            match (key.as_str(), value) {
                ("joints", toml::Value::Table(joints)) => {
                    for (wheel, name) in joints {
                        let toml::Value::String(name) = name else {
                            return Err(err(format!("`joints.{}` must be a string", clip(wheel))));
                        };
                        map.set(&format!("joints.{wheel}"), name).map_err(err)?;
                    }
                }
                (key, toml::Value::String(topic)) => map.set(key, topic).map_err(err)?,
                (key, _) => {
                    return Err(err(format!(
                        "`{}` must be a string (or, for `joints`, a table)",
                        clip(key)
                    )))
                }
            }
        }
        Ok(map)
    }

    /// A topic-map TOML file, then `assignments` over it (the command line
    /// refines the file). `origin` names the assignments in errors (e.g.
    /// `--topic`).
    pub fn from_sources(
        file: Option<&Path>,
        assignments: &[String],
        origin: &str,
    ) -> Result<TopicMap, DriveError> {
        let mut map = match file {
            Some(path) => {
                let text = read_text_limited(path, MAX_TEXT_FILE_BYTES)?;
                TopicMap::from_toml_str(path, &text)?
            }
            None => TopicMap::default(),
        };
        for a in assignments {
            map.assign(a).map_err(|message| DriveError::TopicMap {
                origin: origin.to_string(),
                message,
            })?;
        }
        Ok(map)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn assignments_and_toml_give_the_same_map() {
        let mut a = TopicMap::default();
        for s in [
            "gnss=/fix",
            "imu = /imu/data",
            "wheels=/joint_states",
            "joints.rl=l",
        ] {
            a.assign(s).expect("assignment");
        }
        let text = "gnss = \"/fix\"\nimu = \"/imu/data\"\nwheels = \"/joint_states\"\n[joints]\nrl = \"l\"\n";
        let b = TopicMap::from_toml_str(Path::new("map.toml"), text).expect("toml");
        assert_eq!(a, b);
        assert!(a.assign("speed=/x").is_err());
        assert!(a.assign("gnss").is_err());
        assert!(a.assign("joints.xx=a").is_err());
        assert!(TopicMap::from_toml_str(Path::new("m.toml"), "gnss = 3").is_err());
    }
}

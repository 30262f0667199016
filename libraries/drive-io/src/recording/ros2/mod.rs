//! A ROS 2 bag (rosbag2's MCAP storage: `ros2msg` schemas, `cdr`
//! messages) read as a drive.
//!
//! - Streams: `gnss` from a `sensor_msgs/msg/NavSatFix` topic, `imu` from a
//!   `sensor_msgs/msg/Imu` topic, `wheels` from a `sensor_msgs/msg/JointState`
//!   topic (two or four named wheel joints, velocities in rad/s) or from a
//!   body twist (`geometry_msgs/msg/TwistStamped`, `nav_msgs/msg/Odometry`),
//!   turned into rear wheel speeds with the vehicle's track width. Which
//!   topic fills which role: [`crate::TopicMap`], else by message type.
//! - Times: the header stamps, as seconds since the UNIX epoch (the drive's
//!   one clock, as absolute as the bag gives it); a zero stamp falls back to
//!   the message's log time. Within a stream the samples are sorted by
//!   stamp and a repeated stamp is dropped, each with a warning.
//! - The vehicle parameters come from [`crate::ReadOptions::vehicle`]: a bag
//!   has none.

mod cdr;
mod msgs;

use super::scan::{RawMessage, Scan};
use crate::geodesy::LocalFrame;
use crate::topic_map::Role;
use crate::{DriveError, LoadedDrive, ReadOptions};
use interfaces::drive::{
    Drive, GnssSample, ImuSample, VehicleParams, Wheel, WheelSample, WheelSeries, WheelUnit,
    WheelUnits,
};
use std::collections::BTreeMap;
use std::path::Path;

const JOINT_STATE: &str = "sensor_msgs/msg/JointState";
const ODOMETRY: &str = "nav_msgs/msg/Odometry";

/// True when the scanned MCAP looks like a ROS 2 bag: some channel carries
/// CDR messages, or some schema is a ROS 2 message definition.
pub(super) fn is_ros2(scan: &Scan<'_>) -> bool {
    scan.channels.values().any(|c| c.encoding == "cdr")
        || scan
            .schemas
            .values()
            .any(|s| s.encoding == "ros2msg" || s.encoding == "ros2idl")
}

/// A topic of the bag: its channels (usually one), type and encoding.
struct TopicInfo<'s> {
    topic: &'s str,
    type_name: &'s str,
    encoding: &'s str,
    channels: Vec<u16>,
}

impl TopicInfo<'_> {
    fn describe(&self) -> String {
        format!(
            "{} ({})",
            self.topic,
            if self.type_name.is_empty() {
                "no schema"
            } else {
                self.type_name
            }
        )
    }
}

/// The bag's topics, in name order.
fn topics<'s>(scan: &'s Scan<'_>) -> Vec<TopicInfo<'s>> {
    let mut by_topic: BTreeMap<&str, TopicInfo<'s>> = BTreeMap::new();
    for (id, c) in &scan.channels {
        let type_name = scan
            .schemas
            .get(&c.schema_id)
            .map_or("", |s| s.name.as_str());
        by_topic
            .entry(c.topic.as_str())
            .or_insert_with(|| TopicInfo {
                topic: c.topic.as_str(),
                type_name,
                encoding: c.encoding.as_str(),
                channels: Vec::new(),
            })
            .channels
            .push(*id);
    }
    by_topic.into_values().collect()
}

/// The topic that fills `role`: the one named, else the one of a fitting
/// type (for wheels a `JointState` one first, then a twist), `None` when
/// the bag has none.
fn pick<'t, 's>(
    path: &Path,
    all: &'t [TopicInfo<'s>],
    role: Role,
    named: Option<&String>,
) -> Result<Option<&'t TopicInfo<'s>>, DriveError> {
    let topic_err = |topic: &str, message: String| DriveError::Topic {
        path: path.to_path_buf(),
        topic: topic.to_string(),
        role,
        message,
    };
    if let Some(name) = named {
        let Some(t) = all.iter().find(|t| t.topic == name.as_str()) else {
            let listed: Vec<String> = all.iter().map(TopicInfo::describe).collect();
            return Err(topic_err(
                name,
                format!("not in the bag; its topics are: {}", listed.join(", ")),
            ));
        };
        if !role.types().contains(&t.type_name) {
            return Err(topic_err(
                name,
                format!(
                    "its messages are `{}`, expected {}",
                    t.type_name,
                    role.types().join(" or ")
                ),
            ));
        }
        if t.encoding != "cdr" {
            return Err(topic_err(
                name,
                format!("message encoding `{}`, expected `cdr`", t.encoding),
            ));
        }
        return Ok(Some(t));
    }
    let of_types = |types: &[&str]| -> Vec<&'t TopicInfo<'s>> {
        all.iter()
            .filter(|t| types.contains(&t.type_name) && t.encoding == "cdr")
            .collect()
    };
    let mut candidates = of_types(role.types());
    if role == Role::Wheels {
        let joints = of_types(&[JOINT_STATE]);
        if !joints.is_empty() {
            candidates = joints;
        }
    }
    match candidates.as_slice() {
        [] => Ok(None),
        [one] => Ok(Some(*one)),
        many => Err(DriveError::AmbiguousTopic {
            path: path.to_path_buf(),
            role,
            candidates: many.iter().map(|t| t.describe()).collect(),
        }),
    }
}

/// Seconds since the UNIX epoch of a stamp in nanoseconds (one rounding).
fn seconds(ns: i64) -> f64 {
    ns.div_euclid(1_000_000_000) as f64 + ns.rem_euclid(1_000_000_000) as f64 * 1e-9
}

/// What one topic's decoding produced, before the time order is enforced.
struct Decoded<T> {
    /// (stamp ns, sample) in file order.
    items: Vec<(i64, T)>,
    /// Messages left out, by reason (reason → (count, first message index)).
    skipped: BTreeMap<String, (usize, usize)>,
    zero_stamps: usize,
}

impl<T> Decoded<T> {
    fn new() -> Self {
        Decoded {
            items: Vec::new(),
            skipped: BTreeMap::new(),
            zero_stamps: 0,
        }
    }

    fn skip(&mut self, index: usize, reason: &str) {
        self.skipped
            .entry(reason.to_string())
            .or_insert((0, index))
            .0 += 1;
    }

    /// Push a sample, its stamp replaced by the log time when zero.
    fn push(&mut self, stamp_ns: i64, m: &RawMessage<'_>, sample: T) {
        let stamp = if stamp_ns == 0 {
            self.zero_stamps += 1;
            i64::try_from(m.log_time).unwrap_or(i64::MAX)
        } else {
            stamp_ns
        };
        self.items.push((stamp, sample));
    }

    /// Sorted by stamp, repeated stamps dropped; every change a warning.
    fn into_timeline(
        mut self,
        path: &Path,
        topic: &str,
        warnings: &mut Vec<String>,
    ) -> Vec<(f64, T)> {
        let p = path.display();
        for (reason, (n, first)) in &self.skipped {
            warnings.push(format!(
                "{p}: topic {topic}: left out {n} message(s) {reason} (the first is message {first})"
            ));
        }
        if self.zero_stamps > 0 {
            warnings.push(format!(
                "{p}: topic {topic}: {} message(s) have a zero header stamp; their log time is used",
                self.zero_stamps
            ));
        }
        let out_of_order = self.items.windows(2).filter(|w| w[1].0 < w[0].0).count();
        if out_of_order > 0 {
            warnings.push(format!(
                "{p}: topic {topic}: {out_of_order} message(s) stamped earlier than the one before; sorted by stamp"
            ));
            self.items.sort_by_key(|(t, _)| *t);
        }
        let before = self.items.len();
        self.items.dedup_by_key(|(t, _)| *t);
        let repeated = before - self.items.len();
        if repeated > 0 {
            warnings.push(format!(
                "{p}: topic {topic}: dropped {repeated} message(s) whose stamp repeats the one before (the first kept)"
            ));
        }
        self.items
            .into_iter()
            .map(|(ns, s)| (seconds(ns), s))
            .collect()
    }
}

/// The messages of a topic, in file order.
fn messages_of<'m, 'a>(scan: &'m Scan<'a>, topic: &TopicInfo<'_>) -> Vec<&'m RawMessage<'a>> {
    scan.messages
        .iter()
        .filter(|m| topic.channels.contains(&m.channel_id))
        .collect()
}

/// Decode every message of `topic` with `decode`, which gives `Ok(None)` for
/// a message to leave out (having called `skip`).
fn decode_topic<T, M>(
    path: &Path,
    scan: &Scan<'_>,
    topic: &TopicInfo<'_>,
    parse: impl Fn(&[u8]) -> Result<M, String>,
    mut convert: impl FnMut(usize, M, &mut Decoded<T>) -> Option<(i64, T)>,
) -> Result<Decoded<T>, DriveError> {
    let mut out = Decoded::new();
    for (i, m) in messages_of(scan, topic).into_iter().enumerate() {
        let msg = parse(&m.data).map_err(|e| DriveError::Mcap {
            path: path.to_path_buf(),
            location: format!("channel {}, message {i} ({})", topic.topic, m.location()),
            message: format!("bad `{}` message: {e}", topic.type_name),
        })?;
        if let Some((stamp, sample)) = convert(i, msg, &mut out) {
            out.push(stamp, m, sample);
        }
    }
    Ok(out)
}

/// Read a scanned ROS 2 bag as a drive.
pub(super) fn assemble(
    path: &Path,
    scan: &Scan<'_>,
    options: &ReadOptions,
    mut warnings: Vec<String>,
) -> Result<LoadedDrive, DriveError> {
    let Some(vehicle) = options.vehicle.clone() else {
        return Err(DriveError::NoVehicle {
            path: path.to_path_buf(),
        });
    };
    let all = topics(scan);
    let named = |role: Role| options.topics.topics.get(&role);
    let gnss_topic = pick(path, &all, Role::Gnss, named(Role::Gnss))?;
    let imu_topic = pick(path, &all, Role::Imu, named(Role::Imu))?;
    let Some(wheels_topic) = pick(path, &all, Role::Wheels, named(Role::Wheels))? else {
        let listed: Vec<String> = all.iter().map(TopicInfo::describe).collect();
        return Err(DriveError::Mcap {
            path: path.to_path_buf(),
            location: "topics".to_string(),
            message: format!(
                "no wheels topic (a {}); the bag's topics are: {}",
                Role::Wheels.types().join(", "),
                listed.join(", ")
            ),
        });
    };
    let used: Vec<&str> = [gnss_topic, imu_topic, Some(wheels_topic)]
        .into_iter()
        .flatten()
        .map(|t| t.topic)
        .collect();
    let ignored: Vec<String> = all
        .iter()
        .filter(|t| !used.contains(&t.topic))
        .map(TopicInfo::describe)
        .collect();
    if !ignored.is_empty() {
        warnings.push(format!(
            "{}: ignored topic(s) that are not drive streams: {}",
            path.display(),
            ignored.join(", ")
        ));
    }
    let mut vehicle = vehicle;
    let wheels = read_wheels(path, scan, wheels_topic, options, &vehicle, &mut warnings)?;
    let gnss = gnss_topic
        .map(|t| read_gnss(path, scan, t, &mut vehicle, &mut warnings))
        .transpose()?;
    let imu = imu_topic
        .map(|t| read_imu(path, scan, t, &mut warnings))
        .transpose()?;
    Ok(LoadedDrive {
        drive: Drive {
            vehicle,
            wheels,
            gnss,
            imu,
            heading: None,
            truth: None,
            truth_params: None,
        },
        warnings,
    })
}

fn read_gnss(
    path: &Path,
    scan: &Scan<'_>,
    topic: &TopicInfo<'_>,
    vehicle: &mut VehicleParams,
    warnings: &mut Vec<String>,
) -> Result<Vec<GnssSample>, DriveError> {
    let decoded = decode_topic(path, scan, topic, msgs::nav_sat_fix, |i, m, d| {
        if m.status < 0 {
            d.skip(i, "with status NO_FIX");
            return None;
        }
        if !(m.latitude.is_finite()
            && m.longitude.is_finite()
            && m.latitude.abs() <= 90.0
            && m.longitude.abs() <= 360.0)
        {
            d.skip(i, "with a latitude or longitude that is not a position");
            return None;
        }
        // Horizontal 1-sigma: the RMS of the east and north sigmas.
        let (ve, vn) = (m.covariance[0], m.covariance[4]);
        let sigma =
            (m.covariance_type > 0 && ve.is_finite() && vn.is_finite() && ve > 0.0 && vn > 0.0)
                .then(|| (0.5 * (ve + vn)).sqrt());
        Some((m.stamp_ns, (m.latitude, m.longitude, sigma)))
    })?;
    let fixes = decoded.into_timeline(path, topic.topic, warnings);
    let origin = match (vehicle.gnss.origin_lat_deg, vehicle.gnss.origin_lon_deg) {
        (Some(lat), Some(lon)) => Some((lat, lon)),
        _ => fixes.first().map(|(_, (lat, lon, _))| (*lat, *lon)),
    };
    let Some((lat0, lon0)) = origin else {
        return Ok(Vec::new());
    };
    vehicle.gnss.origin_lat_deg = Some(lat0);
    vehicle.gnss.origin_lon_deg = Some(lon0);
    let frame = LocalFrame::new(lat0, lon0, 0.0);
    Ok(fixes
        .into_iter()
        .map(|(t_s, (lat, lon, sigma_m))| {
            let (x_m, y_m) = frame.to_en(lat, lon);
            GnssSample {
                t_s,
                x_m,
                y_m,
                sigma_m,
            }
        })
        .collect())
}

fn read_imu(
    path: &Path,
    scan: &Scan<'_>,
    topic: &TopicInfo<'_>,
    warnings: &mut Vec<String>,
) -> Result<Vec<ImuSample>, DriveError> {
    let decoded = decode_topic(path, scan, topic, msgs::imu, |i, m, d| {
        if m.angular_velocity_cov0 == -1.0 {
            d.skip(i, "without an angular velocity (covariance[0] = -1)");
            return None;
        }
        let accel = (m.linear_acceleration_cov0 != -1.0).then_some(m.linear_acceleration);
        let values = m.angular_velocity.iter().chain(accel.iter().flatten());
        if !values.clone().all(|v| v.is_finite()) {
            d.skip(i, "with a value that is not finite");
            return None;
        }
        let [gx, gy, gz] = m.angular_velocity;
        Some((
            m.stamp_ns,
            ImuSample {
                t_s: 0.0,
                gz_rad_s: gz,
                ax_m_s2: accel.map(|a| a[0]),
                ay_m_s2: accel.map(|a| a[1]),
                az_m_s2: accel.map(|a| a[2]),
                gx_rad_s: Some(gx),
                gy_rad_s: Some(gy),
            },
        ))
    })?;
    Ok(decoded
        .into_timeline(path, topic.topic, warnings)
        .into_iter()
        .map(|(t_s, s)| ImuSample { t_s, ..s })
        .collect())
}

fn read_wheels(
    path: &Path,
    scan: &Scan<'_>,
    topic: &TopicInfo<'_>,
    options: &ReadOptions,
    vehicle: &VehicleParams,
    warnings: &mut Vec<String>,
) -> Result<WheelSeries, DriveError> {
    let (units, decoded) = match topic.type_name {
        JOINT_STATE => joint_wheels(path, scan, topic, options, warnings)?,
        _ => twist_wheels(path, scan, topic, vehicle, warnings)?,
    };
    let samples: Vec<WheelSample> = decoded
        .into_timeline(path, topic.topic, warnings)
        .into_iter()
        .map(|(t_s, s)| WheelSample { t_s, ..s })
        .collect();
    if samples.is_empty() {
        return Err(DriveError::Topic {
            path: path.to_path_buf(),
            topic: topic.topic.to_string(),
            role: Role::Wheels,
            message: "no usable wheel message".to_string(),
        });
    }
    Ok(WheelSeries { units, samples })
}

/// Body twist → rear wheel speeds: `v ∓ ω·t/2` (left −, right +) with the
/// vehicle's rear track `t`, in m/s (the `_m_s` unit, relative to the
/// nominal circumference).
fn twist_wheels(
    path: &Path,
    scan: &Scan<'_>,
    topic: &TopicInfo<'_>,
    vehicle: &VehicleParams,
    warnings: &mut Vec<String>,
) -> Result<(WheelUnits, Decoded<WheelSample>), DriveError> {
    let parse = if topic.type_name == ODOMETRY {
        msgs::odometry
    } else {
        msgs::twist_stamped
    };
    let half_track = 0.5 * vehicle.track_width_m;
    let decoded = decode_topic(path, scan, topic, parse, |i, m, d| {
        if !(m.speed.is_finite() && m.yaw_rate.is_finite()) {
            d.skip(i, "with a speed or yaw rate that is not finite");
            return None;
        }
        Some((
            m.stamp_ns,
            WheelSample {
                t_s: 0.0,
                rl: m.speed - m.yaw_rate * half_track,
                rr: m.speed + m.yaw_rate * half_track,
                fl: None,
                fr: None,
            },
        ))
    })?;
    warnings.push(format!(
        "{}: topic {} ({}) gives a body speed and yaw rate, not wheel speeds: the rear wheel speeds \
         are speed ∓ yaw rate × track_width_m/2 (track {} m) in m/s against nominal_circumference_m; \
         the calibrated left/right difference holds only if that yaw rate came from the wheels",
        path.display(),
        topic.topic,
        topic.type_name,
        vehicle.track_width_m
    ));
    Ok((WheelUnits::rear(WheelUnit::MS), decoded))
}

/// The wheel joints: those named, the others found by name (`left`/`right`
/// with `rear`/`back` or `front`, or just `left`/`right` when there are
/// only two such joints).
fn wheel_joints(
    path: &Path,
    topic: &TopicInfo<'_>,
    names: &[String],
    options: &ReadOptions,
) -> Result<BTreeMap<Wheel, usize>, DriveError> {
    let err = |message: String| DriveError::Topic {
        path: path.to_path_buf(),
        topic: topic.topic.to_string(),
        role: Role::Wheels,
        message,
    };
    let lower: Vec<String> = names.iter().map(|n| n.to_lowercase()).collect();
    let has = |i: usize, words: &[&str]| words.iter().any(|w| lower[i].contains(w));
    let mut found = BTreeMap::new();
    for wheel in Wheel::ALL {
        if let Some(name) = options.topics.joints.get(&wheel) {
            let Some(i) = names.iter().position(|n| n == name) else {
                return Err(err(format!(
                    "no joint `{name}` (joints.{}); the joints are: {}",
                    wheel.prefix(),
                    names.join(", ")
                )));
            };
            found.insert(wheel, i);
            continue;
        }
        let side: &[&str] = match wheel {
            Wheel::Rl | Wheel::Fl => &["left"],
            Wheel::Rr | Wheel::Fr => &["right"],
        };
        let on_side: Vec<usize> = (0..names.len()).filter(|&i| has(i, side)).collect();
        let matching: Vec<usize> = match wheel {
            Wheel::Rl | Wheel::Rr => {
                let rear: Vec<usize> = on_side
                    .iter()
                    .copied()
                    .filter(|&i| has(i, &["rear", "back"]))
                    .collect();
                if rear.is_empty() {
                    on_side
                        .iter()
                        .copied()
                        .filter(|&i| !has(i, &["front"]))
                        .collect()
                } else {
                    rear
                }
            }
            Wheel::Fl | Wheel::Fr => on_side
                .iter()
                .copied()
                .filter(|&i| has(i, &["front"]))
                .collect(),
        };
        match matching.as_slice() {
            [one] => {
                found.insert(wheel, *one);
            }
            [] if matches!(wheel, Wheel::Fl | Wheel::Fr) => {}
            _ => {
                return Err(err(format!(
                    "cannot tell which joint is the {} wheel among: {}; name it (joints.{}=NAME)",
                    wheel.prefix(),
                    names.join(", "),
                    wheel.prefix()
                )))
            }
        }
    }
    // A front pair only when both are there.
    if found.contains_key(&Wheel::Fl) != found.contains_key(&Wheel::Fr) {
        found.remove(&Wheel::Fl);
        found.remove(&Wheel::Fr);
    }
    Ok(found)
}

/// `JointState` velocities (rad/s) of the wheel joints; when the topic
/// gives no velocities, its positions as cumulative revolutions.
fn joint_wheels(
    path: &Path,
    scan: &Scan<'_>,
    topic: &TopicInfo<'_>,
    options: &ReadOptions,
    warnings: &mut Vec<String>,
) -> Result<(WheelUnits, Decoded<WheelSample>), DriveError> {
    let err = |message: String| DriveError::Topic {
        path: path.to_path_buf(),
        topic: topic.topic.to_string(),
        role: Role::Wheels,
        message,
    };
    // The joints and the unit, from the first message that names joints.
    let mut first = None;
    for (i, m) in messages_of(scan, topic).into_iter().enumerate() {
        let js = msgs::joint_state(&m.data).map_err(|e| DriveError::Mcap {
            path: path.to_path_buf(),
            location: format!("channel {}, message {i} ({})", topic.topic, m.location()),
            message: format!("bad `{JOINT_STATE}` message: {e}"),
        })?;
        if !js.names.is_empty() {
            first = Some(js);
            break;
        }
    }
    let Some(first) = first else {
        return Err(err("no message names any joint".to_string()));
    };
    let joints = wheel_joints(path, topic, &first.names, options)?;
    let names: BTreeMap<Wheel, String> = joints
        .iter()
        .map(|(w, &i)| (*w, first.names[i].clone()))
        .collect();
    let unit = if first.velocity.len() == first.names.len() {
        WheelUnit::RadS
    } else if first.position.len() == first.names.len() {
        WheelUnit::Rev
    } else {
        return Err(err(format!(
            "the joint states give neither a velocity nor a position per joint ({} names, {} velocities, {} positions)",
            first.names.len(),
            first.velocity.len(),
            first.position.len()
        )));
    };
    let listed: Vec<String> = names
        .iter()
        .map(|(w, n)| format!("{}={n}", w.prefix()))
        .collect();
    warnings.push(format!(
        "{}: topic {}: wheel joints {}, {}",
        path.display(),
        topic.topic,
        listed.join(", "),
        if unit == WheelUnit::RadS {
            "velocities in rad/s"
        } else {
            "no velocities: positions read as cumulative wheel angles (rad, never wrapped)"
        }
    ));
    let front = names.contains_key(&Wheel::Fl);
    let units = WheelUnits {
        rl: unit,
        rr: unit,
        fl: front.then_some(unit),
        fr: front.then_some(unit),
    };
    let decoded = decode_topic(path, scan, topic, msgs::joint_state, |i, m, d| {
        let values = if unit == WheelUnit::RadS {
            &m.velocity
        } else {
            &m.position
        };
        let mut v = [None; 4];
        for (wheel, name) in &names {
            let Some(k) = m.names.iter().position(|n| n == name) else {
                d.skip(i, "without every wheel joint");
                return None;
            };
            let Some(&x) = values.get(k) else {
                d.skip(i, "without a value for every named joint");
                return None;
            };
            v[*wheel as usize] = Some(if unit == WheelUnit::Rev {
                x / std::f64::consts::TAU
            } else {
                x
            });
        }
        if !v.iter().flatten().all(|x| x.is_finite()) {
            d.skip(i, "with a wheel value that is not finite");
            return None;
        }
        let (Some(rl), Some(rr)) = (v[0], v[1]) else {
            return None; // never: rl and rr are always among the joints
        };
        Some((
            m.stamp_ns,
            WheelSample {
                t_s: 0.0,
                rl,
                rr,
                fl: v[2],
                fr: v[3],
            },
        ))
    })?;
    Ok((units, decoded))
}

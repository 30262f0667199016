//! The recording's JSON messages and their JSON schemas, from the stream
//! descriptions of [`crate::streams`]: one object per sample holding `t_s`
//! and the values under their drive-folder column names; a missing optional
//! value is an absent key.

use crate::streams::{
    wheel_unit_description, wheel_value, Field, Stream, MAX_FIELDS, T_S, WHEELS_SCHEMA_DESCRIPTION,
    WHEELS_SCHEMA_TITLE,
};
use interfaces::drive::{Wheel, WheelSample, WheelUnit, WheelUnits};
use serde::de::{DeserializeSeed, Error as _, MapAccess, SeqAccess, Visitor};
use serde::ser::SerializeStruct;
use serde::{Deserializer, Serialize, Serializer};
use std::marker::PhantomData;

// ------------------------------------------------------------- streams

/// A sample of stream `S` serialised as its message
/// (`{"t_s":..,"x_m":..,...}`, absent optional values left out).
pub(super) struct MsgOut<'a, S>(pub &'a S);

impl<S: Stream> Serialize for MsgOut<'_, S> {
    fn serialize<Ser: Serializer>(&self, ser: Ser) -> Result<Ser::Ok, Ser::Error> {
        let present = (0..S::FIELDS.len())
            .filter(|&k| self.0.value(k).is_some())
            .count();
        let mut m = ser.serialize_struct(S::MESSAGE, present)?;
        for (k, field) in S::FIELDS.iter().enumerate() {
            if let Some(v) = self.0.value(k) {
                m.serialize_field(field.name, &v)?;
            }
        }
        m.end()
    }
}

/// Reads a message of stream `S`: an object whose keys are the stream's
/// fields, each at most once, the required ones present (or an array of the
/// values in field order). Its errors read as serde's derived ones for a
/// struct named [`Stream::MESSAGE`].
pub(super) struct MsgIn<S>(PhantomData<fn() -> S>);

impl<S> MsgIn<S> {
    /// The reader.
    pub fn new() -> MsgIn<S> {
        MsgIn(PhantomData)
    }
}

impl<'de, S: Stream> DeserializeSeed<'de> for MsgIn<S> {
    type Value = S;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<S, D::Error> {
        d.deserialize_struct(S::MESSAGE, S::KEYS, self)
    }
}

/// A sample from its values, once every required one is known to be there.
fn sample<S: Stream, E: serde::de::Error>(values: &[Option<f64>]) -> Result<S, E> {
    S::from_values(&values[..S::FIELDS.len()])
        .ok_or_else(|| E::custom(format!("a required value of {} is missing", S::MESSAGE)))
}

impl<'de, S: Stream> Visitor<'de> for MsgIn<S> {
    type Value = S;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "struct {}", S::MESSAGE)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<S, A::Error> {
        let mut values = [None; MAX_FIELDS];
        for (k, field) in S::FIELDS.iter().enumerate() {
            values[k] = if field.required {
                let Some(v) = seq.next_element::<f64>()? else {
                    let expected =
                        format!("struct {} with {} elements", S::MESSAGE, S::FIELDS.len());
                    return Err(A::Error::invalid_length(k, &expected.as_str()));
                };
                Some(v)
            } else {
                seq.next_element::<Option<f64>>()?.flatten()
            };
        }
        sample(&values)
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<S, A::Error> {
        let mut values = [None; MAX_FIELDS];
        let mut seen = [false; MAX_FIELDS];
        while let Some(k) = map.next_key_seed(KeyIn::<S>(PhantomData))? {
            if seen[k] {
                return Err(A::Error::duplicate_field(S::KEYS[k]));
            }
            seen[k] = true;
            values[k] = if S::FIELDS[k].required {
                Some(map.next_value::<f64>()?)
            } else {
                map.next_value::<Option<f64>>()?
            };
        }
        if let Some(field) = S::FIELDS
            .iter()
            .zip(seen)
            .find_map(|(f, seen)| (f.required && !seen).then_some(f))
        {
            return Err(A::Error::missing_field(field.name));
        }
        sample(&values)
    }
}

/// Reads a key of a stream-`S` message as the index of its field.
struct KeyIn<S>(PhantomData<fn() -> S>);

impl<'de, S: Stream> DeserializeSeed<'de> for KeyIn<S> {
    type Value = usize;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<usize, D::Error> {
        d.deserialize_identifier(self)
    }
}

impl<S: Stream> Visitor<'_> for KeyIn<S> {
    type Value = usize;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("field identifier")
    }

    fn visit_str<E: serde::de::Error>(self, key: &str) -> Result<usize, E> {
        S::KEYS
            .iter()
            .position(|k| *k == key)
            .ok_or_else(|| E::unknown_field(key, S::KEYS))
    }
}

// ------------------------------------------------------------- wheels

/// A wheel sample serialised with its unit-bearing column names
/// (`{"t_s":..,"rl_rad_s":..,...}`).
pub(super) struct WheelMsgOut<'a> {
    /// The channel's wheel columns.
    pub columns: &'a [(Wheel, String)],
    /// The sample.
    pub sample: &'a WheelSample,
}

impl Serialize for WheelMsgOut<'_> {
    fn serialize<S: Serializer>(&self, ser: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut m = ser.serialize_map(None)?;
        m.serialize_entry("t_s", &self.sample.t_s)?;
        for (wheel, name) in self.columns {
            if let Some(v) = wheel_value(self.sample, *wheel) {
                m.serialize_entry(name, &v)?;
            }
        }
        m.end()
    }
}

/// Reads a wheel message whose keys must be `t_s` and the channel's wheel columns.
pub(super) struct WheelMsgIn<'a> {
    /// The channel's wheel columns.
    pub columns: &'a [(Wheel, String)],
}

impl<'de> DeserializeSeed<'de> for WheelMsgIn<'_> {
    type Value = WheelSample;
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<WheelSample, D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for WheelMsgIn<'_> {
    type Value = WheelSample;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a wheel sample object")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<WheelSample, A::Error> {
        let mut t_s = None;
        let mut values: [Option<f64>; 4] = [None; 4];
        while let Some(key) = map.next_key::<String>()? {
            if key == "t_s" {
                t_s = Some(map.next_value::<f64>()?);
            } else if let Some((wheel, _)) = self.columns.iter().find(|(_, n)| *n == key) {
                values[*wheel as usize] = Some(map.next_value::<f64>()?);
            } else {
                let expected: Vec<&str> = self.columns.iter().map(|(_, n)| n.as_str()).collect();
                return Err(A::Error::custom(format!(
                    "unexpected key `{key}` (this channel's keys are t_s, {})",
                    expected.join(", ")
                )));
            }
        }
        let need = |v: Option<f64>, name: &str| {
            v.ok_or_else(|| A::Error::custom(format!("missing `{name}`")))
        };
        let rear = |w: Wheel| {
            let name = self
                .columns
                .iter()
                .find(|(x, _)| *x == w)
                .map_or(w.prefix(), |(_, n)| n.as_str());
            need(values[w as usize], name)
        };
        Ok(WheelSample {
            t_s: need(t_s, "t_s")?,
            rl: rear(Wheel::Rl)?,
            rr: rear(Wheel::Rr)?,
            fl: values[Wheel::Fl as usize],
            fr: values[Wheel::Fr as usize],
        })
    }
}

// ------------------------------------------------------------- schemas

fn number(description: &str) -> serde_json::Value {
    serde_json::json!({ "type": "number", "description": description })
}

/// A JSON schema of an object of numbers; `fields` are (name, description,
/// required).
fn schema(title: &str, description: &str, fields: &[(&str, &str, bool)]) -> Vec<u8> {
    let mut properties = serde_json::Map::new();
    let mut required = Vec::new();
    for (name, desc, req) in fields {
        properties.insert((*name).to_string(), number(desc));
        if *req {
            required.push(serde_json::Value::String((*name).to_string()));
        }
    }
    let value = serde_json::json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "description": description,
        "type": "object",
        "properties": properties,
        "required": required,
        "additionalProperties": false,
    });
    value.to_string().into_bytes()
}

fn as_tuple(f: &Field) -> (&str, &str, bool) {
    (f.name, f.description, f.required)
}

/// The JSON schema of stream `S`'s messages.
pub(super) fn stream_schema<S: Stream>() -> Vec<u8> {
    let fields: Vec<(&str, &str, bool)> = S::FIELDS.iter().map(as_tuple).collect();
    schema(S::SCHEMA_TITLE, S::SCHEMA_DESCRIPTION, &fields)
}

/// The JSON schema of the wheel messages with these columns and units.
pub(super) fn wheels_schema(columns: &[(Wheel, String)], units: &WheelUnits) -> Vec<u8> {
    let descriptions: Vec<(String, String, bool)> = columns
        .iter()
        .map(|(w, n)| {
            let unit = units.of(*w).unwrap_or(WheelUnit::Rev);
            (
                n.clone(),
                format!("{}: {}", w.prefix(), wheel_unit_description(unit)),
                matches!(w, Wheel::Rl | Wheel::Rr),
            )
        })
        .collect();
    let mut fields = vec![as_tuple(&T_S)];
    fields.extend(
        descriptions
            .iter()
            .map(|(n, d, r)| (n.as_str(), d.as_str(), *r)),
    );
    schema(WHEELS_SCHEMA_TITLE, WHEELS_SCHEMA_DESCRIPTION, &fields)
}

//! A trial's 1 kHz trace as an MCAP file, the log format of ROS 2 tools (Foxglove, PlotJuggler,
//! `ros2 bag`): the same samples as the CSV trace ([`super::session::trace_csv`]), as JSON
//! messages with a JSON Schema per topic, each stamped with the trial's time since its start
//! (log and publish time, ns). Topics, all in the robot's `base` frame (m, rad, N, N m):
//!
//! - `/tcp/pose` (`foxglove.PoseInFrame`): the measured TCP pose, position and quaternion, which
//!   Foxglove's 3-D panel draws;
//! - `/tcp/pose_rpy` (`pegtwin.PoseRpy`): the same pose as x, y, z, roll, pitch, yaw
//!   (R = Rz(yaw) Ry(pitch) Rx(roll)), for plots;
//! - `/wrench/estimated` and `/wrench/true` (`pegtwin.Wrench`, as `geometry_msgs/Wrench`): the
//!   external wrench the controller estimates, and the one the contacts apply;
//! - `/phase` (`pegtwin.Phase`): the trial's phase and whether the estimate says contact.

use super::session::TraceRow;
use crate::error::{Error, Result};
use nalgebra::UnitQuaternion;
use serde_json::json;
use std::collections::BTreeMap;
use std::io::Cursor;

/// A JSON Schema's `{sec, nsec}` time stamp (foxglove's `time`).
const TIME: &str =
    r#"{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}}"#;

/// One topic: its name, its schema's name and the JSON Schema of its messages.
struct Topic {
    name: &'static str,
    schema: &'static str,
    properties: String,
}

/// The topics of a trace, in the order [`messages`] gives their messages.
fn topics() -> [Topic; 5] {
    let xyz = |names: [&str; 3]| {
        let fields: Vec<String> = (names.iter())
            .map(|n| format!(r#""{n}":{{"type":"number"}}"#))
            .collect();
        format!(
            r#"{{"type":"object","properties":{{{}}}}}"#,
            fields.join(",")
        )
    };
    let stamped =
        |rest: String| format!(r#""timestamp":{TIME},"frame_id":{{"type":"string"}},{rest}"#);
    let numbers = |names: &[&str]| {
        (names.iter())
            .map(|n| format!(r#""{n}":{{"type":"number"}}"#))
            .collect::<Vec<_>>()
            .join(",")
    };
    let pose = format!(
        r#""pose":{{"type":"object","properties":{{"position":{},"orientation":{}}}}}"#,
        xyz(["x", "y", "z"]),
        r#"{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}"#
    );
    let wrench = format!(
        r#""force":{},"torque":{}"#,
        xyz(["x", "y", "z"]),
        xyz(["x", "y", "z"])
    );
    [
        Topic {
            name: "/tcp/pose",
            schema: "foxglove.PoseInFrame",
            properties: stamped(pose),
        },
        Topic {
            name: "/tcp/pose_rpy",
            schema: "pegtwin.PoseRpy",
            properties: stamped(numbers(&["x", "y", "z", "roll", "pitch", "yaw"])),
        },
        Topic {
            name: "/wrench/estimated",
            schema: "pegtwin.Wrench",
            properties: stamped(wrench.clone()),
        },
        Topic {
            name: "/wrench/true",
            schema: "pegtwin.Wrench",
            properties: stamped(wrench),
        },
        Topic {
            name: "/phase",
            schema: "pegtwin.Phase",
            properties: format!(
                r#""timestamp":{TIME},"phase":{{"type":"string"}},"contact":{{"type":"boolean"}}"#
            ),
        },
    ]
}

/// The messages of one trace sample, one per topic in [`topics`]' order.
fn messages(r: &TraceRow) -> [serde_json::Value; 5] {
    let ns = time_ns(r.time_s);
    let stamp = json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000});
    let [x, y, z, roll, pitch, yaw] = r.tcp;
    let q = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
    let wrench = |w: &[f64; 6]| {
        json!({"timestamp": stamp, "frame_id": "base",
               "force": {"x": w[0], "y": w[1], "z": w[2]},
               "torque": {"x": w[3], "y": w[4], "z": w[5]}})
    };
    [
        json!({"timestamp": stamp, "frame_id": "base", "pose": {
            "position": {"x": x, "y": y, "z": z},
            "orientation": {"x": q.i, "y": q.j, "z": q.k, "w": q.w}}}),
        json!({"timestamp": stamp, "frame_id": "base",
               "x": x, "y": y, "z": z, "roll": roll, "pitch": pitch, "yaw": yaw}),
        wrench(&r.est_wrench),
        wrench(&r.true_wrench),
        json!({"timestamp": stamp, "phase": r.phase, "contact": r.contact}),
    ]
}

/// A trace time, s, as whole nanoseconds since the trial's start.
fn time_ns(time_s: f64) -> u64 {
    (time_s.max(0.0) * 1e9).round() as u64
}

/// The trace `rows` as the bytes of an MCAP file (module docs).
pub fn trace_mcap(rows: &[TraceRow]) -> Result<Vec<u8>> {
    let io = |e: mcap::McapError| Error::Input(format!("cannot write the MCAP trace: {e}"));
    let mut writer = mcap::WriteOptions::new()
        .profile("")
        .library(format!("pegtwin {}", env!("CARGO_PKG_VERSION")))
        .create(Cursor::new(Vec::new()))
        .map_err(io)?;
    let mut channels = Vec::new();
    for topic in topics() {
        let schema = format!(
            r#"{{"title":"{}","type":"object","properties":{{{}}}}}"#,
            topic.schema, topic.properties
        );
        let id = (writer.add_schema(topic.schema, "jsonschema", schema.as_bytes())).map_err(io)?;
        channels.push(
            writer
                .add_channel(id, topic.name, "json", &BTreeMap::new())
                .map_err(io)?,
        );
    }
    for (sequence, r) in rows.iter().enumerate() {
        let time = time_ns(r.time_s);
        for (channel_id, message) in channels.iter().zip(messages(r)) {
            let header = mcap::records::MessageHeader {
                channel_id: *channel_id,
                sequence: sequence as u32,
                log_time: time,
                publish_time: time,
            };
            let data = serde_json::to_vec(&message).expect("a message serialises");
            writer.write_to_known_channel(&header, &data).map_err(io)?;
        }
    }
    writer.finish().map_err(io)?;
    Ok(writer.into_inner().into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_schema_is_json_and_a_sample_gives_a_message_per_topic() {
        for topic in topics() {
            let schema = format!(
                r#"{{"type":"object","properties":{{{}}}}}"#,
                topic.properties
            );
            serde_json::from_str::<serde_json::Value>(&schema).unwrap();
        }
        let row = TraceRow {
            time_s: 1.25,
            phase: "observe",
            tcp: [0.5, 0.0, 0.2, std::f64::consts::PI, 0.0, 0.3],
            est_wrench: [0.0, 0.0, -5.0, 0.0, 0.0, 0.0],
            true_wrench: [0.0; 6],
            contact: true,
        };
        let m = messages(&row);
        assert_eq!(m[0]["timestamp"], json!({"sec": 1, "nsec": 250_000_000}));
        assert_eq!(m[2]["force"]["z"], json!(-5.0));
        let bytes = trace_mcap(&[row]).unwrap();
        assert!(bytes.starts_with(b"\x89MCAP0\r\n"));
    }
}

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use mcap::Compression;
use mcap::records::MessageHeader;
use proptest::prelude::*;

use super::cdr::{JointStateMsg, decode_joint_state};
use super::*;

/// sensor_msgs/msg/JointState as rosbag2 stores it: the .msg text (comments
/// trimmed) followed by its dependencies.
const MSG_DEF: &str = "\
# This is a message that holds data to describe the state of a set of torque controlled joints.
std_msgs/Header header

string[] name
float64[] position
float64[] velocity
float64[] effort

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
";

/// Test-only CDR encoder, written independently of the decoder.
struct Enc {
    out: Vec<u8>,
    le: bool,
}

impl Enc {
    fn pad(&mut self, size: usize) {
        while !(self.out.len() - 4).is_multiple_of(size) {
            self.out.push(0);
        }
    }
    fn u32(&mut self, v: u32) {
        self.pad(4);
        let b = if self.le {
            v.to_le_bytes()
        } else {
            v.to_be_bytes()
        };
        self.out.extend_from_slice(&b);
    }
    fn f64(&mut self, v: f64) {
        self.pad(8);
        let b = if self.le {
            v.to_le_bytes()
        } else {
            v.to_be_bytes()
        };
        self.out.extend_from_slice(&b);
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.out.extend_from_slice(s.as_bytes());
        self.out.push(0);
    }
}

fn encode(m: &JointStateMsg, le: bool) -> Vec<u8> {
    let mut e = Enc {
        out: vec![0, u8::from(le), 0, 0],
        le,
    };
    e.u32(m.sec as u32);
    e.u32(m.nanosec);
    e.string(&m.frame_id);
    e.u32(m.name.len() as u32);
    m.name.iter().for_each(|n| e.string(n));
    for values in [&m.position, &m.velocity, &m.effort] {
        e.u32(values.len() as u32);
        values.iter().for_each(|&v| e.f64(v));
    }
    e.out
}

fn names(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

/// Message `i` with values that identify sample, joint and field.
fn sample(i: usize, joints: &[&str]) -> JointStateMsg {
    let v = |field: f64| {
        (0..joints.len())
            .map(|j| field + i as f64 * 0.001 + j as f64 * 10.0)
            .collect()
    };
    JointStateMsg {
        sec: 1_700_000_000 + (i / 100) as i32,
        nanosec: (i % 100) as u32 * 10_000_000,
        frame_id: String::new(),
        name: names(joints),
        position: v(0.5),
        velocity: v(-1.25),
        effort: v(3.0),
    }
}

struct Topic<'a> {
    name: &'a str,
    schema: &'a str,
    messages: Vec<Vec<u8>>,
}

fn js_topic(name: &str, messages: Vec<Vec<u8>>) -> Topic<'_> {
    Topic {
        name,
        schema: JOINT_STATE_SCHEMA,
        messages,
    }
}

fn write_bag(dir: &Path, compression: Option<Compression>, topics: &[Topic]) -> PathBuf {
    let path = dir.join("bag_0.mcap");
    let file = BufWriter::new(File::create(&path).unwrap());
    let mut w = mcap::WriteOptions::new()
        .compression(compression)
        .profile("ros2")
        .create(file)
        .unwrap();
    for topic in topics {
        let schema = w
            .add_schema(topic.schema, "ros2msg", MSG_DEF.as_bytes())
            .unwrap();
        let channel = w
            .add_channel(schema, topic.name, CDR_ENCODING, &BTreeMap::new())
            .unwrap();
        for (i, data) in topic.messages.iter().enumerate() {
            let log_time = 1_000_000_000 + i as u64 * 10_000_000;
            let header = MessageHeader {
                channel_id: channel,
                sequence: i as u32,
                log_time,
                publish_time: log_time,
            };
            w.write_to_known_channel(&header, data).unwrap();
        }
    }
    w.finish().unwrap();
    path
}

fn bag_of(dir: &Path, msgs: &[JointStateMsg]) -> PathBuf {
    let data = msgs.iter().map(|m| encode(m, true)).collect();
    write_bag(dir, None, &[js_topic("/joint_states", data)])
}

fn read(
    path: &Path,
    topic: Option<&str>,
    joints: Option<&[&str]>,
) -> Result<JointStates, BagError> {
    let options = BagOptions {
        topic: topic.map(str::to_string),
        joints: joints.map(names),
        model: None,
    };
    read_joint_states(path, &options)
}

/// The error and its sources, as the command line prints them.
fn err_text(path: &Path, result: Result<JointStates, BagError>) -> String {
    let error = result.expect_err("expected an error");
    let mut text = error.to_string();
    let mut source = std::error::Error::source(&error);
    while let Some(inner) = source {
        text.push_str(&format!(": {inner}"));
        source = inner.source();
    }
    assert!(
        text.contains(&path.display().to_string()),
        "no path in: {text}"
    );
    text
}

const J3: [&str; 3] = ["shoulder", "elbow", "wrist"];

/// A corrupt byte anywhere in a compressed bag is an error or a valid
/// read, never an allocation of a corrupt length (which aborted the
/// process before records and chunks were bounded).
#[test]
fn corrupt_compressed_chunks_are_errors() {
    let msgs: Vec<_> = (0..200).map(|i| sample(i, &J3)).collect();
    let data: Vec<_> = msgs.iter().map(|m| encode(m, true)).collect();
    for compression in [Compression::Zstd, Compression::Lz4] {
        let dir = tempfile::tempdir().unwrap();
        let path = write_bag(
            dir.path(),
            Some(compression),
            &[js_topic("/joint_states", data.clone())],
        );
        let good = std::fs::read(&path).unwrap();
        for at in (8..good.len() - 8).step_by(5) {
            for value in [0xD9, good[at] ^ 0xFF] {
                let mut bad = good.clone();
                bad[at] = value;
                std::fs::write(&path, &bad).unwrap();
                // Either outcome is fine; reaching the next line is the test.
                let _ = read(&path, None, None);
            }
        }
    }
}

#[test]
fn round_trip_all_compressions() {
    let msgs: Vec<_> = (0..200).map(|i| sample(i, &J3)).collect();
    let data: Vec<_> = msgs.iter().map(|m| encode(m, true)).collect();
    for (compression, label) in [
        (Some(Compression::Zstd), "zstd"),
        (Some(Compression::Lz4), "lz4"),
        (None, ""),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let path = write_bag(
            dir.path(),
            compression,
            &[js_topic("/joint_states", data.clone())],
        );
        // The chunks really are compressed as asked.
        let summary = mcap::Summary::read(&std::fs::read(&path).unwrap())
            .unwrap()
            .unwrap();
        assert!(!summary.chunk_indexes.is_empty());
        assert!(summary.chunk_indexes.iter().all(|c| c.compression == label));
        let js = read(&path, None, None).unwrap();
        assert_eq!(js.joints, names(&J3));
        assert_eq!(js.t.len(), 200);
        for (i, m) in msgs.iter().enumerate() {
            assert_eq!(
                (js.position[i].clone(), js.velocity[i].clone()),
                (m.position.clone(), m.velocity.clone())
            );
            assert_eq!(js.effort[i], m.effort);
            assert!(
                (js.t[i] - i as f64 * 0.01).abs() < 1e-9,
                "t[{i}] = {}",
                js.t[i]
            );
        }
    }
}

#[test]
fn big_endian_messages() {
    let msgs: Vec<_> = (0..5).map(|i| sample(i, &J3)).collect();
    let dir = tempfile::tempdir().unwrap();
    let path = write_bag(
        dir.path(),
        None,
        &[js_topic(
            "/js",
            msgs.iter().map(|m| encode(m, false)).collect(),
        )],
    );
    let js = read(&path, None, None).unwrap();
    assert_eq!(js.position[4], msgs[4].position);
    assert_eq!(js.effort[2], msgs[2].effort);
}

#[test]
fn selection_reorders_and_matches_other_publishers_by_name() {
    let mut msgs: Vec<_> = (0..4).map(|i| sample(i, &J3)).collect();
    // A different driver publishes a reordered subset with its own values.
    msgs[2] = sample(2, &["wrist", "shoulder"]);
    let dir = tempfile::tempdir().unwrap();
    let path = bag_of(dir.path(), &msgs);
    let js = read(&path, None, Some(&["wrist", "shoulder"])).unwrap();
    assert_eq!(js.joints, names(&["wrist", "shoulder"]));
    assert_eq!(
        js.position[0],
        vec![msgs[0].position[2], msgs[0].position[0]]
    );
    assert_eq!(js.velocity[2], msgs[2].velocity);
    // The subset lacks elbow: error naming message and joint.
    let text = err_text(&path, read(&path, None, None));
    assert!(
        text.contains("message 2") && text.contains("'elbow' is missing"),
        "{text}"
    );
}

#[test]
fn unknown_or_repeated_joint_requests() {
    let dir = tempfile::tempdir().unwrap();
    let path = bag_of(dir.path(), &[sample(0, &J3), sample(1, &J3)]);
    let text = err_text(&path, read(&path, None, Some(&["elbow", "knee"])));
    assert!(
        text.contains("'knee'") && text.contains("'shoulder', 'elbow', 'wrist'"),
        "{text}"
    );
    let text = err_text(&path, read(&path, None, Some(&["elbow", "elbow"])));
    assert!(text.contains("requested twice"), "{text}");
}

#[test]
fn topic_choice() {
    let data = |n| (0..n).map(|i| encode(&sample(i, &J3), true)).collect();
    let other = Topic {
        name: "/tf",
        schema: "tf2_msgs/msg/TFMessage",
        messages: vec![vec![0, 1, 0, 0]],
    };
    let dir = tempfile::tempdir().unwrap();
    let path = write_bag(
        dir.path(),
        Some(Compression::Zstd),
        &[
            js_topic("/a/joint_states", data(3)),
            js_topic("/b/joint_states", data(4)),
            other,
        ],
    );
    let text = err_text(&path, read(&path, None, None));
    assert!(
        text.contains("'/a/joint_states', '/b/joint_states'") && text.contains("pass --topic"),
        "{text}"
    );
    assert_eq!(
        read(&path, Some("/b/joint_states"), None).unwrap().t.len(),
        4
    );
    let text = err_text(&path, read(&path, Some("/tf"), None));
    assert!(text.contains("tf2_msgs/msg/TFMessage"), "{text}");
    let text = err_text(&path, read(&path, Some("/nope"), None));
    assert!(
        text.contains("'/nope'") && text.contains("'/tf' (tf2_msgs/msg/TFMessage, cdr)"),
        "{text}"
    );

    let only_tf = Topic {
        name: "/tf",
        schema: "tf2_msgs/msg/TFMessage",
        messages: vec![vec![0, 1, 0, 0]],
    };
    let dir = tempfile::tempdir().unwrap();
    let path = write_bag(dir.path(), None, &[only_tf]);
    let text = err_text(&path, read(&path, None, None));
    assert!(
        text.contains("no topic carries") && text.contains("'/tf' (tf2_msgs/msg/TFMessage, cdr)"),
        "{text}"
    );
}

#[test]
fn empty_effort_is_rejected() {
    let mut msgs = vec![sample(0, &J3), sample(1, &J3)];
    msgs[1].effort.clear();
    let dir = tempfile::tempdir().unwrap();
    let path = bag_of(dir.path(), &msgs);
    let text = err_text(&path, read(&path, None, None));
    assert!(
        text.contains("message 1")
            && text.contains("'effort' is empty")
            && text.contains("position, velocity and effort"),
        "{text}"
    );
    // Empty velocity: effort after it is read best-effort, velocity is named.
    msgs[1] = sample(1, &J3);
    msgs[1].velocity.clear();
    let path = bag_of(dir.path(), &msgs);
    let text = err_text(&path, read(&path, None, None));
    assert!(text.contains("'velocity' is empty"), "{text}");
}

#[test]
fn truncated_messages_are_errors() {
    let full = encode(&sample(7, &J3), true);
    for len in 0..full.len() {
        assert!(
            decode_joint_state(&full[..len]).is_err(),
            "cut at {len} decoded"
        );
    }
    assert!(decode_joint_state(&full).is_ok());
    let good = encode(&sample(0, &J3), true);
    let dir = tempfile::tempdir().unwrap();
    let path = write_bag(
        dir.path(),
        None,
        &[js_topic("/js", vec![good, full[..full.len() - 3].to_vec()])],
    );
    let text = err_text(&path, read(&path, None, None));
    assert!(
        text.contains("message 1 (log time 1010000000 ns)") && text.contains("'effort'"),
        "{text}"
    );
}

#[test]
fn hostile_sequence_lengths_fail_before_allocating() {
    let mut m = sample(0, &J3);
    m.name.clear();
    let data = encode(&m, true);
    // Header is 4 + 8 (stamp) + 4 + 1 (empty frame_id) padded to 20: name count follows.
    let at = 20;
    assert_eq!(data[at..at + 4], [0; 4]);
    let mut hostile = data.clone();
    hostile[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let err = decode_joint_state(&hostile).unwrap_err();
    assert!(
        matches!(err, CdrError::Truncated { what: "name", need, .. } if need == u64::from(u32::MAX) * 4),
        "{err}"
    );
    // The position count follows the (now empty) names.
    hostile = data;
    hostile[at + 4..at + 8].copy_from_slice(&u32::MAX.to_le_bytes());
    let err = decode_joint_state(&hostile).unwrap_err();
    assert!(
        matches!(
            err,
            CdrError::Truncated {
                what: "position",
                ..
            }
        ),
        "{err}"
    );
}

#[test]
fn stamps_must_increase() {
    let mut msgs: Vec<_> = (0..4).map(|i| sample(i, &J3)).collect();
    msgs[2].nanosec = msgs[1].nanosec;
    let dir = tempfile::tempdir().unwrap();
    let path = bag_of(dir.path(), &msgs);
    let text = err_text(&path, read(&path, None, None));
    assert!(
        text.contains("message 2")
            && text.contains("not increasing")
            && text.contains("header stamps"),
        "{text}"
    );
    msgs[2].nanosec = 0;
    let path = bag_of(dir.path(), &msgs);
    assert!(err_text(&path, read(&path, None, None)).contains("message 2"));
}

#[test]
fn zero_stamps_fall_back_to_log_time() {
    let mut msgs: Vec<_> = (0..3).map(|i| sample(i, &J3)).collect();
    for m in &mut msgs {
        (m.sec, m.nanosec) = (0, 0);
    }
    let dir = tempfile::tempdir().unwrap();
    let js = read(&bag_of(dir.path(), &msgs), None, None).unwrap();
    assert_eq!(js.t, vec![0.0, 0.01, 0.02]);
}

#[test]
fn a_simulation_clock_starting_at_zero_is_one_clock() {
    // Header stamps 0, 0.01, 0.02 s; log times of the wall clock.
    let mut msgs: Vec<_> = (0..3).map(|i| sample(i, &J3)).collect();
    for (i, m) in msgs.iter_mut().enumerate() {
        (m.sec, m.nanosec) = (0, i as u32 * 10_000_000);
    }
    let dir = tempfile::tempdir().unwrap();
    let js = read(&bag_of(dir.path(), &msgs), None, None).unwrap();
    assert_eq!(js.t, vec![0.0, 0.01, 0.02]);
}

#[test]
fn non_finite_values_and_short_bags() {
    let mut msgs = vec![sample(0, &J3), sample(1, &J3)];
    msgs[1].velocity[1] = f64::NAN;
    let dir = tempfile::tempdir().unwrap();
    let path = bag_of(dir.path(), &msgs);
    let text = err_text(&path, read(&path, None, None));
    assert!(
        text.contains("message 1") && text.contains("velocity of joint 'elbow' is NaN"),
        "{text}"
    );
    let path = bag_of(dir.path(), &msgs[..1]);
    assert!(err_text(&path, read(&path, None, None)).contains("1 message(s)"));
    let missing = dir.path().join("absent.mcap");
    assert!(err_text(&missing, read(&missing, None, None)).contains("cannot read"));
    std::fs::write(&missing, b"not an mcap").unwrap();
    assert!(err_text(&missing, read(&missing, None, None)).contains("not a readable MCAP"));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, failure_persistence: None, ..ProptestConfig::default() })]
    /// Whole bags with random bytes replaced or the file cut: an error that
    /// names the file, or joint states, never a panic.
    #[test]
    fn mutated_bags_never_panic(
        edits in proptest::collection::vec((any::<usize>(), any::<u8>(), any::<bool>()), 1..8),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let msgs: Vec<JointStateMsg> = (0..6).map(|i| sample(i, &["a", "b"])).collect();
        let path = bag_of(dir.path(), &msgs);
        let mut bytes = std::fs::read(&path).unwrap();
        for (at, byte, cut) in edits {
            let at = at % bytes.len().max(1);
            if cut {
                bytes.truncate(at.max(1));
            } else if at < bytes.len() {
                bytes[at] = byte;
            }
        }
        std::fs::write(&path, &bytes).unwrap();
        if let Err(e) = read(&path, None, None) {
            let text = e.to_string();
            prop_assert!(text.contains("bag") || text.contains(".mcap"), "{}", text);
        }
    }

    #[test]
    fn decoder_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..256), le in any::<bool>()) {
        // Also with a valid header, so the body parsing is exercised.
        let mut framed = vec![0, u8::from(le), 0, 0];
        framed.extend_from_slice(&bytes);
        let _ = decode_joint_state(&bytes);
        let _ = decode_joint_state(&framed);
    }

    #[test]
    fn decoder_round_trips(
        sec in any::<i32>(),
        nanosec in any::<u32>(),
        frame_id in "[a-z_/]{0,12}",
        joints in proptest::collection::vec(("[a-zA-Z0-9_]{0,10}", -1e300..1e300f64, -1e300..1e300f64, -1e300..1e300f64), 0..8),
        le in any::<bool>(),
    ) {
        let msg = JointStateMsg {
            sec,
            nanosec,
            frame_id,
            name: joints.iter().map(|j| j.0.clone()).collect(),
            position: joints.iter().map(|j| j.1).collect(),
            velocity: joints.iter().map(|j| j.2).collect(),
            effort: joints.iter().map(|j| j.3).collect(),
        };
        prop_assert_eq!(decode_joint_state(&encode(&msg, le)).unwrap(), msg);
    }
}

mod names;

//! Joint-state series from ROS 2 bags stored as MCAP (rosbag2's `mcap`
//! storage plugin), decoded from `sensor_msgs/msg/JointState` in CDR.
//!
//! Message indices in errors count the messages on the selected topic from 0,
//! in file order; log times are the bag's nanoseconds.

mod cdr;
#[cfg(test)]
mod tests;

use std::collections::BTreeMap;
use std::fmt;
use std::io;
use std::path::{Path, PathBuf};

use thiserror::Error;

pub use cdr::CdrError;
use cdr::JointStateMsg;

/// Schema name rosbag2 records for joint states.
pub const JOINT_STATE_SCHEMA: &str = "sensor_msgs/msg/JointState";
/// Channel message encoding rosbag2 records for ROS 2 messages.
pub const CDR_ENCODING: &str = "cdr";

/// One joint-state series from a bag, joints in the order asked for.
#[derive(Debug, Clone, PartialEq)]
pub struct JointStates {
    /// Names, in the selected order.
    pub joints: Vec<String>,
    /// Seconds from the first kept message (header stamps; the log times
    /// when no message of the bag has a stamp set).
    pub t: Vec<f64>,
    /// `[sample][joint]`.
    pub position: Vec<Vec<f64>>,
    pub velocity: Vec<Vec<f64>>,
    pub effort: Vec<Vec<f64>>,
    /// How the joints were chosen.
    pub order: JointOrder,
    /// Messages skipped because they name none of the chosen joints
    /// (another publisher's on the same topic, a gripper's).
    pub ignored_messages: usize,
}

/// How the joints of a [`JointStates`] were chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointOrder {
    /// By `--joints`, in its order.
    Requested,
    /// By the model's joint names, in the model's order.
    ModelNames,
    /// The first message's joints in its order (no names to match).
    FirstMessage,
}

/// Which topic and joints to read; `None` picks automatically.
#[derive(Debug, Clone, Default)]
pub struct BagOptions {
    /// Needed only when the bag has several `JointState` topics.
    pub topic: Option<String>,
    /// Selection and order by name (`--joints`); wins over `model`.
    pub joints: Option<Vec<String>>,
    /// The model's joint names, base first: the bag is read by these names
    /// when it carries them all; without either list, the first message's
    /// joints are read in its order.
    pub model: Option<Vec<String>>,
}

/// Where in a bag a message-level problem is.
#[derive(Debug, Clone)]
pub struct MessageAt {
    pub path: PathBuf,
    pub topic: String,
    pub index: usize,
    pub log_time: u64,
}

impl fmt::Display for MessageAt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: topic '{}', message {} (log time {} ns)",
            self.path.display(),
            self.topic,
            self.index,
            self.log_time
        )
    }
}

/// Errors from reading joint states out of a bag.
#[derive(Debug, Error)]
pub enum BagError {
    // The source's text is printed by the caller's error chain, not here.
    #[error("{}: cannot read the bag", .path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("{}: not a readable MCAP file", .path.display())]
    Mcap {
        path: PathBuf,
        #[source]
        source: mcap::McapError,
    },
    #[error("{}: no topic carries {JOINT_STATE_SCHEMA} in {CDR_ENCODING} encoding; the bag has {found}", .path.display())]
    NoJointStateTopic { path: PathBuf, found: String },
    #[error("{}: several {JOINT_STATE_SCHEMA} topics ({topics}); pass --topic to choose one", .path.display())]
    SeveralTopics { path: PathBuf, topics: String },
    #[error("{}: no messages on topic '{topic}'; the bag has {found}", .path.display())]
    TopicNotFound {
        path: PathBuf,
        topic: String,
        found: String,
    },
    #[error(
        "{}: topic '{topic}' has schema '{schema}' in '{encoding}' encoding, expected {JOINT_STATE_SCHEMA} in {CDR_ENCODING}",
        .path.display()
    )]
    WrongTopicType {
        path: PathBuf,
        topic: String,
        schema: String,
        encoding: String,
    },
    #[error("{}: topic '{topic}' has {count} message(s), at least 2 are needed", .path.display())]
    TooFewMessages {
        path: PathBuf,
        topic: String,
        count: usize,
    },
    #[error("{}: joint '{joint}' is requested twice", .path.display())]
    RequestedTwice { path: PathBuf, joint: String },
    #[error("{}: joint '{joint}' is not in the bag; the messages on '{topic}' name {present}", .path.display())]
    UnknownJoint {
        path: PathBuf,
        topic: String,
        joint: String,
        present: String,
    },
    #[error(
        "{}: the model's joint '{joint}' is not on topic '{topic}', which names {present}; pass --joints \
         with the bag's names in the model's order",
        .path.display()
    )]
    ModelJointMissing {
        path: PathBuf,
        topic: String,
        joint: String,
        present: String,
    },
    #[error(
        "{at}: names {present}, none of the first message's joints ({first}): the topic carries \
         several publishers' joints; pass --joints with the arm's joints in the model's order"
    )]
    SeveralJointSets {
        at: MessageAt,
        first: String,
        present: String,
    },
    #[error("{at}: malformed JointState")]
    Decode {
        at: MessageAt,
        #[source]
        source: CdrError,
    },
    #[error("{at}: names no joints")]
    NoJoints { at: MessageAt },
    #[error("{at}: joint name '{joint}' appears more than once")]
    DuplicateJoint { at: MessageAt, joint: String },
    #[error(
        "{at}: '{field}' is empty; this tool needs position, velocity and effort for every joint"
    )]
    EmptyField { at: MessageAt, field: &'static str },
    #[error("{at}: '{field}' has {found} values for {names} joint names")]
    LengthMismatch {
        at: MessageAt,
        field: &'static str,
        found: usize,
        names: usize,
    },
    #[error("{at}: joint '{joint}' is missing; this message names {present}")]
    MissingJoint {
        at: MessageAt,
        joint: String,
        present: String,
    },
    #[error("{at}: {field} of joint '{joint}' is {value}, expected a finite number")]
    NonFinite {
        at: MessageAt,
        field: &'static str,
        joint: String,
        value: f64,
    },
    #[error(
        "{at}: time stamps are not increasing ({current:.9} s after {previous:.9} s, from the first message); record with header stamps set per sample by the driver"
    )]
    NotIncreasing {
        at: MessageAt,
        previous: f64,
        current: f64,
    },
}

type Raw = Vec<(u64, Vec<u8>)>;

/// Reads the joint states of one topic; see the module docs for the error conventions.
pub fn read_joint_states(path: &Path, options: &BagOptions) -> Result<JointStates, BagError> {
    crate::output::note_input(path);
    let bytes = crate::bounded::read(path).map_err(|source| BagError::Io {
        path: path.into(),
        source,
    })?;
    let (topic, raw) = collect_topic(path, &bytes, options.topic.as_deref())?;
    drop(bytes);
    let at = |index: usize, log_time: u64| MessageAt {
        path: path.into(),
        topic: topic.clone(),
        index,
        log_time,
    };
    let messages = decode_all(raw, &at)?;
    if messages.len() < 2 {
        return Err(BagError::TooFewMessages {
            path: path.into(),
            topic,
            count: messages.len(),
        });
    }
    let (joints, order) = select(path, &topic, &messages, options)?;
    let kept = keep(&messages, &joints, order, &at)?;
    if kept.len() < 2 {
        return Err(BagError::TooFewMessages {
            path: path.into(),
            topic,
            count: kept.len(),
        });
    }
    let mut out = JointStates {
        t: Vec::with_capacity(kept.len()),
        position: Vec::with_capacity(kept.len()),
        velocity: Vec::with_capacity(kept.len()),
        effort: Vec::with_capacity(kept.len()),
        ignored_messages: messages.len() - kept.len(),
        order,
        joints,
    };
    fill_values(&mut out, &messages, &kept, &at)?;
    fill_times(&mut out, &messages, &kept, &at)?;
    Ok(out)
}

/// Every message decoded, with its log time, its names checked (the
/// values are checked where they are read: another publisher's messages
/// may lack effort).
fn decode_all(
    raw: Raw,
    at: &impl Fn(usize, u64) -> MessageAt,
) -> Result<Vec<(u64, JointStateMsg)>, BagError> {
    let mut messages = Vec::with_capacity(raw.len());
    for (index, (log_time, data)) in raw.into_iter().enumerate() {
        let at = || at(index, log_time);
        let msg = cdr::decode_joint_state(&data)
            .map_err(|source| BagError::Decode { at: at(), source })?;
        if msg.name.is_empty() {
            return Err(BagError::NoJoints { at: at() });
        }
        if let Some(joint) = first_duplicate(&msg.name) {
            return Err(BagError::DuplicateJoint { at: at(), joint });
        }
        messages.push((log_time, msg));
    }
    Ok(messages)
}

fn fields(msg: &JointStateMsg) -> [(&'static str, &Vec<f64>); 3] {
    [
        ("position", &msg.position),
        ("velocity", &msg.velocity),
        ("effort", &msg.effort),
    ]
}

/// The joints to read and why: `--joints` as given; else the model's
/// joints when the topic names them all (in any order, among others);
/// else the first message's joints in its order.
fn select(
    path: &Path,
    topic: &str,
    messages: &[(u64, JointStateMsg)],
    options: &BagOptions,
) -> Result<(Vec<String>, JointOrder), BagError> {
    let present = names_on_topic(messages);
    let absent = |list: &[String]| list.iter().find(|j| !present.contains(j)).cloned();
    if let Some(list) = &options.joints {
        if let Some(joint) = first_duplicate(list) {
            return Err(BagError::RequestedTwice {
                path: path.into(),
                joint,
            });
        }
        if let Some(joint) = absent(list) {
            return Err(BagError::UnknownJoint {
                path: path.into(),
                topic: topic.into(),
                joint,
                present: quoted(&present),
            });
        }
        return Ok((list.clone(), JointOrder::Requested));
    }
    if let Some(model) = &options.model {
        match absent(model) {
            None => return Ok((model.clone(), JointOrder::ModelNames)),
            // Some of the model's names but not all: reading in message
            // order would pair joints by position with names that disagree.
            Some(joint) if model.iter().any(|j| present.contains(j)) => {
                return Err(BagError::ModelJointMissing {
                    path: path.into(),
                    topic: topic.into(),
                    joint,
                    present: quoted(&present),
                });
            }
            Some(_) => {}
        }
    }
    Ok((messages[0].1.name.clone(), JointOrder::FirstMessage))
}

/// Every joint name on the topic, in order of first appearance.
fn names_on_topic(messages: &[(u64, JointStateMsg)]) -> Vec<String> {
    let mut seen = std::collections::HashSet::new();
    let mut present = Vec::new();
    let mut last: Option<&Vec<String>> = None;
    for (_, msg) in messages {
        // Publishers repeat one name list: skip the set work when it does.
        if last == Some(&msg.name) {
            continue;
        }
        last = Some(&msg.name);
        for name in &msg.name {
            if seen.insert(name.as_str()) {
                present.push(name.clone());
            }
        }
    }
    present
}

/// The messages to read, each with the column of every selected joint.
/// A message naming none of the selected joints is another publisher's (a
/// gripper's) and is skipped when the selection was explicit; one naming
/// some but not all is an error.
fn keep(
    messages: &[(u64, JointStateMsg)],
    joints: &[String],
    order: JointOrder,
    at: &impl Fn(usize, u64) -> MessageAt,
) -> Result<Vec<(usize, Vec<usize>)>, BagError> {
    let mut kept = Vec::with_capacity(messages.len());
    let mut last: Option<(&Vec<String>, Option<Vec<usize>>)> = None;
    for (index, (log_time, msg)) in messages.iter().enumerate() {
        let columns = match &last {
            Some((names, columns)) if *names == &msg.name => columns.clone(),
            _ => {
                let found: Vec<Option<usize>> = joints
                    .iter()
                    .map(|j| msg.name.iter().position(|n| n == j))
                    .collect();
                let columns = if found.iter().all(Option::is_none) {
                    if order == JointOrder::FirstMessage {
                        return Err(BagError::SeveralJointSets {
                            at: at(index, *log_time),
                            first: quoted(joints),
                            present: quoted(&msg.name),
                        });
                    }
                    None
                } else if let Some(missing) = found.iter().position(Option::is_none) {
                    return Err(BagError::MissingJoint {
                        at: at(index, *log_time),
                        joint: joints[missing].clone(),
                        present: quoted(&msg.name),
                    });
                } else {
                    Some(found.into_iter().flatten().collect())
                };
                last = Some((&msg.name, columns.clone()));
                columns
            }
        };
        if let Some(columns) = columns {
            kept.push((index, columns));
        }
    }
    Ok(kept)
}

/// Positions, velocities and efforts of the kept messages, checked finite.
fn fill_values(
    out: &mut JointStates,
    messages: &[(u64, JointStateMsg)],
    kept: &[(usize, Vec<usize>)],
    at: &impl Fn(usize, u64) -> MessageAt,
) -> Result<(), BagError> {
    for (index, columns) in kept {
        let (log_time, msg) = &messages[*index];
        let at = || at(*index, *log_time);
        let sinks = [&mut out.position, &mut out.velocity, &mut out.effort];
        for ((field, values), sink) in fields(msg).into_iter().zip(sinks) {
            if values.is_empty() {
                return Err(BagError::EmptyField { at: at(), field });
            }
            if values.len() != msg.name.len() {
                return Err(BagError::LengthMismatch {
                    at: at(),
                    field,
                    found: values.len(),
                    names: msg.name.len(),
                });
            }
            let mut row = Vec::with_capacity(columns.len());
            for (&c, joint) in columns.iter().zip(&out.joints) {
                let value = values[c];
                if !value.is_finite() {
                    return Err(BagError::NonFinite {
                        at: at(),
                        field,
                        joint: joint.clone(),
                        value,
                    });
                }
                row.push(value);
            }
            sink.push(row);
        }
    }
    Ok(())
}

/// Seconds from the first kept message, on one clock for the whole
/// series: the header stamps when any kept message has one set (a
/// simulation clock may start at exactly zero), else the log times.
fn fill_times(
    out: &mut JointStates,
    messages: &[(u64, JointStateMsg)],
    kept: &[(usize, Vec<usize>)],
    at: &impl Fn(usize, u64) -> MessageAt,
) -> Result<(), BagError> {
    let stamped = kept.iter().any(|(index, _)| {
        let msg = &messages[*index].1;
        msg.sec != 0 || msg.nanosec != 0
    });
    let mut t0 = None;
    let mut previous: Option<i128> = None;
    for (index, _) in kept {
        let (log_time, msg) = &messages[*index];
        // Integer nanoseconds so that the ordering check is exact.
        let ns = if stamped {
            i128::from(msg.sec) * 1_000_000_000 + i128::from(msg.nanosec)
        } else {
            i128::from(*log_time)
        };
        let t0 = *t0.get_or_insert(ns);
        let seconds = |ns: i128| (ns - t0) as f64 / 1e9;
        if let Some(prev) = previous
            && ns <= prev
        {
            return Err(BagError::NotIncreasing {
                at: at(*index, *log_time),
                previous: seconds(prev),
                current: seconds(ns),
            });
        }
        previous = Some(ns);
        out.t.push(seconds(ns));
    }
    Ok(())
}

/// Largest record or chunk (compressed or decompressed) of a bag, bytes.
const MAX_RECORD_BYTES: usize = 256 << 20;

/// Streams the whole bag once, keeping the raw messages of the JointState
/// topics that may be selected, then picks the topic.
fn collect_topic(
    path: &Path,
    bytes: &[u8],
    wanted: Option<&str>,
) -> Result<(String, Raw), BagError> {
    let mcap_error = |source| BagError::Mcap {
        path: path.into(),
        source,
    };
    // topic -> (schema, encoding), for error messages.
    let mut seen: BTreeMap<String, (String, String)> = BTreeMap::new();
    let mut candidates: BTreeMap<String, Raw> = BTreeMap::new();
    // Every record and chunk, compressed or not, is bounded before it is
    // buffered or decompressed: a corrupt length or compressed stream is an
    // error, not an allocation of its claimed size.
    let options = mcap::sans_io::LinearReaderOptions::default()
        .with_record_length_limit(MAX_RECORD_BYTES)
        .with_prevalidate_chunk_crcs(true);
    for message in mcap::io::MessageReader::new_with_options(bytes, options) {
        let message = message.map_err(mcap_error)?;
        let channel = &message.channel;
        let schema = channel
            .schema
            .as_ref()
            .map_or("(no schema)", |s| s.name.as_str());
        if !seen.contains_key(&channel.topic) {
            let kind = (schema.to_string(), channel.message_encoding.clone());
            seen.insert(channel.topic.clone(), kind);
        }
        let keep = schema == JOINT_STATE_SCHEMA
            && channel.message_encoding == CDR_ENCODING
            && wanted.is_none_or(|w| w == channel.topic);
        if keep {
            let topic = channel.topic.clone();
            let entry = (message.log_time, message.data.into_owned());
            candidates.entry(topic).or_default().push(entry);
        }
    }
    let found = || {
        if seen.is_empty() {
            return "no messages".to_string();
        }
        let topics: Vec<String> = seen
            .iter()
            .map(|(topic, (schema, encoding))| format!("'{topic}' ({schema}, {encoding})"))
            .collect();
        format!("topics {}", topics.join(", "))
    };
    if let Some(topic) = wanted {
        if let Some(raw) = candidates.remove(topic) {
            return Ok((topic.to_string(), raw));
        }
        return Err(match seen.get(topic) {
            Some((schema, encoding)) => BagError::WrongTopicType {
                path: path.into(),
                topic: topic.to_string(),
                schema: schema.clone(),
                encoding: encoding.clone(),
            },
            None => BagError::TopicNotFound {
                path: path.into(),
                topic: topic.to_string(),
                found: found(),
            },
        });
    }
    if candidates.len() > 1 {
        let topics: Vec<String> = candidates.keys().cloned().collect();
        return Err(BagError::SeveralTopics {
            path: path.into(),
            topics: quoted(&topics),
        });
    }
    candidates
        .pop_first()
        .ok_or_else(|| BagError::NoJointStateTopic {
            path: path.into(),
            found: found(),
        })
}

fn first_duplicate(names: &[String]) -> Option<String> {
    let mut sorted: Vec<&String> = names.iter().collect();
    sorted.sort_unstable();
    sorted
        .windows(2)
        .find(|w| w[0] == w[1])
        .map(|w| w[0].clone())
}

fn quoted(names: &[String]) -> String {
    let quoted: Vec<String> = names.iter().map(|n| format!("'{n}'")).collect();
    quoted.join(", ")
}

//! Hand-written decoder for `sensor_msgs/msg/JointState` in plain CDR (XCDR1),
//! the encoding rosbag2 stores. Every read is bounds-checked, and sequence
//! lengths are checked against the bytes left before anything is allocated.

use thiserror::Error;

/// A decoded `sensor_msgs/msg/JointState`.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct JointStateMsg {
    pub sec: i32,
    pub nanosec: u32,
    pub frame_id: String,
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
}

/// Why a message's bytes are not a valid CDR `JointState`.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum CdrError {
    #[error("only {len} bytes, too short for the 4-byte CDR encapsulation header")]
    NoHeader { len: usize },
    #[error(
        "unsupported CDR encapsulation {0:#04x} {1:#04x}; expected plain CDR (0x00 0x00 big endian or 0x00 0x01 little endian)"
    )]
    Encapsulation(u8, u8),
    #[error(
        "'{what}' needs {need} bytes at byte {offset}, but only {left} remain (truncated or malformed message)"
    )]
    Truncated {
        what: &'static str,
        offset: usize,
        need: u64,
        left: usize,
    },
    #[error("'{what}' is not valid UTF-8")]
    Utf8 { what: &'static str },
}

/// Decodes one message, encapsulation header included.
pub(crate) fn decode_joint_state(data: &[u8]) -> Result<JointStateMsg, CdrError> {
    let (head, body) = data
        .split_first_chunk::<4>()
        .ok_or(CdrError::NoHeader { len: data.len() })?;
    let le = match (head[0], head[1]) {
        (0, 0) => false,
        (0, 1) => true,
        (a, b) => return Err(CdrError::Encapsulation(a, b)),
    };
    let mut r = Reader {
        buf: body,
        pos: 0,
        le,
    };
    let sec = r.u32("header.stamp.sec")? as i32;
    let nanosec = r.u32("header.stamp.nanosec")?;
    let frame_id = r.string("header.frame_id")?;
    let name = r.strings("name")?;
    // Writers disagree on whether an empty float64[] is followed by padding to
    // 8, so after an empty array the later ones are best-effort. The caller
    // rejects the empty array first, so a misread never reaches the output.
    let mut lenient = false;
    let position = r.f64s_after_empty("position", &mut lenient)?;
    let velocity = r.f64s_after_empty("velocity", &mut lenient)?;
    let effort = r.f64s_after_empty("effort", &mut lenient)?;
    Ok(JointStateMsg {
        sec,
        nanosec,
        frame_id,
        name,
        position,
        velocity,
        effort,
    })
}

struct Reader<'a> {
    buf: &'a [u8],
    /// Offset in `buf`, which starts after the encapsulation header: CDR
    /// alignment is relative to there.
    pos: usize,
    le: bool,
}

impl<'a> Reader<'a> {
    fn take(&mut self, need: u64, what: &'static str) -> Result<&'a [u8], CdrError> {
        let left = self.buf.len().saturating_sub(self.pos);
        match usize::try_from(need) {
            Ok(n) if n <= left => {
                let bytes = &self.buf[self.pos..self.pos + n];
                self.pos += n;
                Ok(bytes)
            }
            _ => Err(CdrError::Truncated {
                what,
                offset: self.pos + 4,
                need,
                left,
            }),
        }
    }

    fn u32(&mut self, what: &'static str) -> Result<u32, CdrError> {
        // May step past the end; `take` then reports it.
        self.pos = self.pos.next_multiple_of(4);
        let mut b = [0; 4];
        b.copy_from_slice(self.take(4, what)?);
        Ok(if self.le {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    }

    fn string(&mut self, what: &'static str) -> Result<String, CdrError> {
        let len = self.u32(what)?;
        let bytes = self.take(len.into(), what)?;
        // The length counts the trailing NUL; tolerate writers that omit it.
        let bytes = bytes.strip_suffix(&[0]).unwrap_or(bytes);
        String::from_utf8(bytes.to_vec()).map_err(|_| CdrError::Utf8 { what })
    }

    fn strings(&mut self, what: &'static str) -> Result<Vec<String>, CdrError> {
        let count = self.u32(what)?;
        // Each element needs at least its 4-byte length: check before allocating.
        self.check_room(u64::from(count) * 4, what)?;
        (0..count).map(|_| self.string(what)).collect()
    }

    fn f64s(&mut self, what: &'static str) -> Result<Vec<f64>, CdrError> {
        let count = self.u32(what)?;
        if count == 0 {
            return Ok(Vec::new());
        }
        self.pos = self.pos.next_multiple_of(8);
        let bytes = self.take(u64::from(count) * 8, what)?;
        let le = self.le;
        Ok(bytes
            .chunks_exact(8)
            .map(|c| {
                let mut b = [0; 8];
                b.copy_from_slice(c);
                if le {
                    f64::from_le_bytes(b)
                } else {
                    f64::from_be_bytes(b)
                }
            })
            .collect())
    }

    fn f64s_after_empty(
        &mut self,
        what: &'static str,
        lenient: &mut bool,
    ) -> Result<Vec<f64>, CdrError> {
        match self.f64s(what) {
            Ok(v) => {
                *lenient |= v.is_empty();
                Ok(v)
            }
            Err(_) if *lenient => Ok(Vec::new()),
            Err(e) => Err(e),
        }
    }

    fn check_room(&self, need: u64, what: &'static str) -> Result<(), CdrError> {
        let left = self.buf.len().saturating_sub(self.pos);
        if need > left as u64 {
            return Err(CdrError::Truncated {
                what,
                offset: self.pos + 4,
                need,
                left,
            });
        }
        Ok(())
    }
}

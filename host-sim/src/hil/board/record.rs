//! The board's own record (`record S`, `dump`) read from the console and
//! written as a 1 ms run log.
//!
//! The dump is checked whole ([`BoardRecord::from_reply`]): the announced
//! frame count, every frame's COBS, CRC and payload, the chunks' sequence
//! numbers, and the row count of the head. Any failure is an error naming
//! the frame; a dump is never read as a shorter log.

use std::io::Write as _;
use std::path::Path;

use dca_app::frame::{self, FrameError};
use dca_app::record::{RecordChunk, RecordHead, RecordedRow, CHUNK_ROWS, RECORD_DT_S};
use dca_core::controller::ControllerKind;

use super::console::{frames_announced, Reply};
use crate::io::files::{self, PathError};

/// Why a dump could not be read.
#[derive(Debug, thiserror::Error)]
pub enum DumpError {
    /// The board answered with an error.
    #[error("the board refused `dump`: {0}")]
    Refused(String),
    /// The reply did not announce frames.
    #[error("the reply to `dump` did not announce its frames (`dump rows=N frames=F`)")]
    NoAnnouncement,
    /// Fewer or more frames came than announced.
    #[error("the dump announced {announced} frames and {got} arrived: frames were lost")]
    Count {
        /// Announced.
        announced: usize,
        /// Received.
        got: usize,
    },
    /// A frame did not decode.
    #[error("dump frame {index} is damaged ({}): the dump is incomplete", .error.as_str())]
    Frame {
        /// Its place in the dump, 0 for the head.
        index: usize,
        /// Why.
        error: FrameError,
    },
    /// A chunk out of sequence.
    #[error("dump frame {index} carries sequence number {seq}: frames were lost")]
    Sequence {
        /// Its place in the dump.
        index: usize,
        /// Its sequence number.
        seq: u32,
    },
    /// The head's row count does not match the frames.
    #[error("the dump's head says {rows} rows, which {frames} frames cannot hold")]
    Rows {
        /// Rows in the head.
        rows: u32,
        /// Frames received.
        frames: usize,
    },
    /// The record has fewer than two rows (not a run log).
    #[error("the record has {0} row(s); a run log needs at least 2")]
    TooShort(u32),
    /// The file.
    #[error(transparent)]
    File(#[from] PathError),
}

/// A record read from a dump.
#[derive(Clone, Debug, PartialEq)]
pub struct BoardRecord {
    /// The dump's head (row count, controller, calibration).
    pub head: RecordHead,
    /// The rows, 1 ms apart, the first at t = 0.
    pub rows: Vec<RecordedRow>,
}

impl BoardRecord {
    /// Read the reply to `dump`, checking every frame.
    pub fn from_reply(reply: &Reply) -> Result<Self, DumpError> {
        if !reply.is_ok() {
            return Err(DumpError::Refused(reply.last.clone()));
        }
        let announced = reply
            .lines
            .iter()
            .find_map(|l| frames_announced(l))
            .ok_or(DumpError::NoAnnouncement)?;
        if reply.frames.len() != announced || announced == 0 {
            return Err(DumpError::Count {
                announced,
                got: reply.frames.len(),
            });
        }
        let mut bodies = reply.frames.clone();
        let head: RecordHead =
            frame::decode(&mut bodies[0]).map_err(|error| DumpError::Frame { index: 0, error })?;
        if head.frames() as usize != announced {
            return Err(DumpError::Rows {
                rows: head.rows,
                frames: announced,
            });
        }
        let mut rows = Vec::with_capacity(head.rows as usize);
        for (index, body) in bodies.iter_mut().enumerate().skip(1) {
            let chunk: RecordChunk =
                frame::decode(body).map_err(|error| DumpError::Frame { index, error })?;
            if chunk.seq as usize != index {
                return Err(DumpError::Sequence {
                    index,
                    seq: chunk.seq,
                });
            }
            let first = (index - 1) * CHUNK_ROWS;
            let n = (head.rows as usize - first).min(CHUNK_ROWS);
            rows.extend(chunk.rows[..n].iter().map(|r| head.row(r)));
        }
        Ok(Self { head, rows })
    }

    /// The controller the record was made with.
    pub fn controller(&self) -> Option<ControllerKind> {
        ControllerKind::ALL
            .get(usize::from(self.head.controller))
            .copied()
    }

    /// The record as a run log (docs/interfaces.md section 1): the
    /// metadata `controller`, `source=dca-firmware record`, `step_s=0.001`
    /// and `extra`, then one row per tick.
    pub fn to_log_text(&self, extra: &[(&str, String)]) -> String {
        let mut out = String::from("# dca-log v1\n");
        if let Some(k) = self.controller() {
            out.push_str(&format!("# controller={}\n", k.name()));
        }
        out.push_str("# source=dca-firmware record\n");
        for (k, v) in extra {
            out.push_str(&format!("# {k}={v}\n"));
        }
        out.push_str(&format!("# step_s={RECORD_DT_S}\n"));
        out.push_str("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n,faults\n");
        for (i, r) in self.rows.iter().enumerate() {
            let s = &r.sample;
            out.push_str(&format!(
                "{}.{:03},{:.9},{:.9},{:.9},{:.9},{:.1},{:.1},{:.3},{}\n",
                i / 1000,
                i % 1000,
                r.ref_m,
                r.v_cmd_mps,
                s.xi_m,
                s.xo_m,
                s.p1_pa,
                s.p2_pa,
                s.ft_n,
                r.faults
            ));
        }
        out
    }

    /// Write the record as a run log to `path`.
    pub fn write(&self, path: &Path, extra: &[(&str, String)]) -> Result<(), DumpError> {
        if self.rows.len() < 2 {
            return Err(DumpError::TooShort(self.rows.len() as u32));
        }
        let mut f = files::create(path)?;
        f.write_all(self.to_log_text(extra).as_bytes())
            .map_err(|e| PathError::new(path, e))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dca_app::frame::MAX_FRAME_LEN;
    use dca_app::record::{PackedRow, Packer};
    use dca_app::settings::Calibration;
    use dca_core::controller::Sample;

    /// The reply the firmware sends for `rows` rows (without the delimiters).
    fn reply(n: u32) -> Reply {
        let cal = Calibration::nominal();
        let p = Packer::new(&cal);
        let rows: Vec<PackedRow> = (0..n)
            .map(|k| {
                let s = Sample {
                    xo_m: 1e-3 * k as f32,
                    ..Sample::default()
                };
                p.pack(1e-4 * k as f32, 0.01, &s, 0)
            })
            .collect();
        let head = RecordHead::new(n, 4, &cal);
        let mut frames = Vec::new();
        let mut buf = [0u8; MAX_FRAME_LEN];
        let k = frame::encode(&head, &mut buf).unwrap();
        frames.push(buf[..k - 1].to_vec());
        for (i, c) in rows.chunks(CHUNK_ROWS).enumerate() {
            let mut chunk = RecordChunk {
                seq: i as u32 + 1,
                ..RecordChunk::default()
            };
            chunk.rows[..c.len()].copy_from_slice(c);
            let k = frame::encode(&chunk, &mut buf).unwrap();
            frames.push(buf[..k - 1].to_vec());
        }
        Reply {
            lines: vec![format!("dump rows={n} frames={}", frames.len())],
            last: "ok".into(),
            frames,
        }
    }

    #[test]
    fn a_whole_dump_reads_back_as_a_1_ms_run_log() {
        let r = BoardRecord::from_reply(&reply(8)).unwrap();
        assert_eq!(r.rows.len(), 8);
        assert_eq!(r.controller(), Some(ControllerKind::CmpcEso));
        let text = r.to_log_text(&[]);
        let log = crate::io::runlog::RunLog::parse(&text, "record").unwrap();
        assert_eq!(log.len(), 8);
        assert!((log.t_s[7] - 0.007).abs() < 1e-12);
        assert!((log.dt_s() - 0.001).abs() < 1e-12);
        // The reference column within half its resolution.
        assert!((log.ref_m[5] - 5e-4).abs() <= dca_app::record::REF_LSB_M / 2.0 + 1e-9);
    }

    #[test]
    fn a_lost_or_damaged_frame_is_an_error() {
        let whole = reply(10);
        let mut lost = whole.clone();
        lost.frames.remove(2);
        let e = BoardRecord::from_reply(&lost).unwrap_err();
        assert!(matches!(e, DumpError::Count { .. }), "{e}");
        // A lost frame with a matching count (a delimiter merged two).
        let mut merged = whole.clone();
        let second = merged.frames.remove(3);
        merged.frames[2].extend(second);
        merged.lines = vec![format!("dump rows=10 frames={}", merged.frames.len())];
        assert!(BoardRecord::from_reply(&merged).is_err());
        let mut bad = whole.clone();
        bad.frames[1][5] ^= 0x10;
        let e = BoardRecord::from_reply(&bad).unwrap_err();
        assert!(matches!(e, DumpError::Frame { index: 1, .. }), "{e}");
        let mut swapped = whole.clone();
        swapped.frames.swap(1, 2);
        let e = BoardRecord::from_reply(&swapped).unwrap_err();
        assert!(matches!(e, DumpError::Sequence { index: 1, seq: 2 }), "{e}");
        let refused = Reply {
            last: "error: nothing recorded".into(),
            ..Reply::default()
        };
        assert!(matches!(
            BoardRecord::from_reply(&refused),
            Err(DumpError::Refused(_))
        ));
    }
}

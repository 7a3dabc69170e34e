//! The smoother's temporary files (`docs/derivations/rts_smoother.md`, section 3): the
//! forward nodes as the run records them, read back in reverse in blocks by the backward
//! pass, and the smoothed node data, written in blocks by the backward pass and read forward
//! in blocks by the correction of the records. Both are unnamed temporary files of the system
//! temporary directory (`tempfile::tempfile`: removed when closed, also after an error or a
//! crash); everything is little-endian, f64 as recorded.
//!
//! A node record: a flag word (u64: bit 0 posterior, bit 1 correction, bit 2 transition),
//! the time, the packed prior, the packed posterior, the correction and the transition when
//! flagged (f64 each), then the record's length in bytes (u64) so that the file can be read
//! from its end. A smoothed record: time, linked (1 or 0), `dx_post` (n), `dx_prior` (n), the
//! 9 x 9 core covariance (81), the variances (n), f64 each: `3 n + 83` values.

use super::{Node, SmoothError};
use nav_core::model::CORE_DIM;
use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::sync::Arc;

const F_POST: u64 = 1;
const F_CORR: u64 = 2;
const F_PHI: u64 = 4;

/// Bytes read from a node file at a time (at least one record).
pub(crate) const NODE_BLOCK_BYTES: usize = 1 << 20;
/// Smoothed records per block (written by the backward pass, read by the cursors).
pub(crate) const SMOOTHED_BLOCK: usize = 256;
/// Buffer of the node file's writer, bytes.
pub(crate) const NODE_WRITE_BUF: usize = 256 << 10;

/// Values of a packed covariance of dimension n.
pub(crate) fn packed_len(n: usize) -> usize {
    n * (n + 1) / 2
}

/// Values of a stored transition of dimension n (9 core rows, then the diagonal below).
pub(crate) fn phi_len(n: usize) -> usize {
    CORE_DIM * n + n.saturating_sub(CORE_DIM)
}

/// Values of a smoothed record of dimension n.
pub(crate) fn smoothed_len(n: usize) -> usize {
    3 * n + 83
}

fn io(e: std::io::Error) -> SmoothError {
    SmoothError::Io(e.to_string())
}

/// Writes node records to a temporary file.
#[derive(Debug)]
pub(crate) struct NodeWriter {
    w: BufWriter<File>,
    bytes: u64,
    buf: Vec<u8>,
}

impl NodeWriter {
    /// A new temporary file.
    pub(crate) fn new() -> std::io::Result<Self> {
        Ok(Self {
            w: BufWriter::with_capacity(NODE_WRITE_BUF, tempfile::tempfile()?),
            bytes: 0,
            buf: Vec::new(),
        })
    }

    /// Appends one node.
    pub(crate) fn write(&mut self, node: &Node) -> std::io::Result<()> {
        let b = &mut self.buf;
        b.clear();
        let flags = u64::from(node.p_post.is_some()) * F_POST
            + u64::from(node.correction.is_some()) * F_CORR
            + u64::from(node.phi.is_some()) * F_PHI;
        b.extend_from_slice(&flags.to_le_bytes());
        b.extend_from_slice(&node.t_s.to_le_bytes());
        let parts = [
            Some(&node.p_prior),
            node.p_post.as_ref(),
            node.correction.as_ref(),
            node.phi.as_ref(),
        ];
        for v in parts.into_iter().flatten().flatten() {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let len = b.len() as u64 + 8;
        b.extend_from_slice(&len.to_le_bytes());
        self.w.write_all(b)?;
        self.bytes += len;
        Ok(())
    }

    /// Flushes the file: it and its length, bytes.
    pub(crate) fn finish(self) -> std::io::Result<(File, u64)> {
        let bytes = self.bytes;
        let f = self.w.into_inner().map_err(|e| e.into_error())?;
        Ok((f, bytes))
    }
}

/// Reads `len` bytes at `at` of a shared file.
fn read_at(f: &File, at: u64, buf: &mut Vec<u8>, len: usize) -> std::io::Result<()> {
    buf.resize(len, 0);
    let mut r = f;
    r.seek(SeekFrom::Start(at))?;
    r.read_exact(buf)
}

fn u64_at(b: &[u8], i: usize) -> Option<u64> {
    let s = b.get(i..i + 8)?;
    let mut a = [0u8; 8];
    a.copy_from_slice(s);
    Some(u64::from_le_bytes(a))
}

/// The nodes of a node file from the last to the first, read in blocks of
/// [`NODE_BLOCK_BYTES`]; yields `(index, node)`.
pub(crate) struct RevNodes<'a> {
    file: &'a File,
    n: usize,
    /// Bytes of the file not yet returned (records before `pos`).
    pos: u64,
    /// Index of the next node returned.
    next: usize,
    buf: Vec<u8>,
    /// File offset of `buf[0]`.
    buf_at: u64,
}

impl<'a> RevNodes<'a> {
    /// Over `file` of `bytes` bytes holding `count` nodes of dimension `n`.
    pub(crate) fn new(file: &'a File, n: usize, bytes: u64, count: usize) -> Self {
        Self {
            file,
            n,
            pos: bytes,
            next: count,
            buf: Vec::new(),
            buf_at: bytes,
        }
    }

    /// Bytes `[a, b)` of the file, from the block in memory or a new block ending at `b`.
    fn range(&mut self, a: u64, b: u64) -> Result<&[u8], SmoothError> {
        let end = self.buf_at + self.buf.len() as u64;
        if a < self.buf_at || b > end {
            let start = b.saturating_sub(NODE_BLOCK_BYTES as u64).min(a);
            read_at(self.file, start, &mut self.buf, (b - start) as usize).map_err(io)?;
            self.buf_at = start;
        }
        let i = (a - self.buf_at) as usize;
        let j = (b - self.buf_at) as usize;
        self.buf.get(i..j).ok_or(SmoothError::Size(self.next))
    }

    fn read_one(&mut self) -> Result<Node, SmoothError> {
        let k = self.next;
        let bad = SmoothError::Size(k);
        if self.pos < 8 {
            return Err(bad);
        }
        let len = u64_at(self.range(self.pos - 8, self.pos)?, 0).ok_or(bad.clone())?;
        if len < 24 || len > self.pos {
            return Err(bad);
        }
        let n = self.n;
        let at = self.pos - len;
        let rec = self.range(at, self.pos - 8)?;
        let flags = u64_at(rec, 0).ok_or(bad.clone())?;
        let mut vals = rec
            .get(8..)
            .unwrap_or(&[])
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]));
        let t_s = vals.next().ok_or(bad.clone())?;
        let mut take = |len: usize| -> Option<Vec<f64>> {
            let v: Vec<f64> = vals.by_ref().take(len).collect();
            (v.len() == len).then_some(v)
        };
        let p_prior = take(packed_len(n)).ok_or(bad.clone())?;
        let mut opt = |flag: u64, len: usize| -> Result<Option<Vec<f64>>, SmoothError> {
            if flags & flag == 0 {
                return Ok(None);
            }
            take(len).map(Some).ok_or(SmoothError::Size(k))
        };
        let p_post = opt(F_POST, packed_len(n))?;
        let correction = opt(F_CORR, n)?;
        let phi = opt(F_PHI, phi_len(n))?;
        if vals.next().is_some() {
            return Err(bad);
        }
        self.pos = at;
        Ok(Node {
            t_s,
            p_prior,
            p_post,
            correction,
            phi,
        })
    }
}

impl Iterator for RevNodes<'_> {
    type Item = Result<(usize, Node), SmoothError>;

    fn next(&mut self) -> Option<Self::Item> {
        let k = self.next.checked_sub(1)?;
        self.next = k;
        match self.read_one() {
            Ok(node) => Some(Ok((k, node))),
            Err(e) => {
                // stop after an error
                self.next = 0;
                Some(Err(e))
            }
        }
    }
}

/// Writes the smoothed records of a backward pass (from the last node to the first) in
/// blocks of [`SMOOTHED_BLOCK`] records at their place in the file.
pub(crate) struct SmoothedWriter {
    file: File,
    rec: usize,
    /// Records of the current block, last node first.
    blk: Vec<f64>,
    /// Index of the last record stored in `blk`.
    lowest: usize,
    bytes: Vec<u8>,
}

impl SmoothedWriter {
    /// A temporary file for records of dimension `n`.
    pub(crate) fn new(n: usize) -> Result<Self, SmoothError> {
        let rec = smoothed_len(n);
        Ok(Self {
            file: tempfile::tempfile().map_err(io)?,
            rec,
            blk: Vec::with_capacity(rec * SMOOTHED_BLOCK),
            lowest: 0,
            bytes: Vec::new(),
        })
    }

    /// Stores the record of node `k` (called for k descending by one); `vals` are its values.
    pub(crate) fn push(
        &mut self,
        k: usize,
        vals: impl Iterator<Item = f64>,
    ) -> Result<(), SmoothError> {
        let start = self.blk.len();
        self.blk.extend(vals);
        if self.blk.len() - start != self.rec {
            return Err(SmoothError::Size(k));
        }
        self.lowest = k;
        if self.blk.len() >= self.rec * SMOOTHED_BLOCK {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<(), SmoothError> {
        if self.blk.is_empty() {
            return Ok(());
        }
        self.bytes.clear();
        for r in self.blk.chunks_exact(self.rec).rev() {
            for v in r {
                self.bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        let at = (self.lowest * self.rec * 8) as u64;
        self.file.seek(SeekFrom::Start(at)).map_err(io)?;
        self.file.write_all(&self.bytes).map_err(io)?;
        self.blk.clear();
        Ok(())
    }

    /// Writes the rest: the file.
    pub(crate) fn finish(mut self) -> Result<Arc<File>, SmoothError> {
        self.flush()?;
        Ok(Arc::new(self.file))
    }
}

/// Blocks of smoothed records read forward ([`SMOOTHED_BLOCK`] records at a time).
#[derive(Debug)]
pub(crate) struct SmoothedBlocks<'a> {
    file: Option<&'a File>,
    rec: usize,
    count: usize,
    /// Index of the first record in `vals`.
    start: usize,
    vals: Vec<f64>,
    bytes: Vec<u8>,
}

impl<'a> SmoothedBlocks<'a> {
    pub(crate) fn new(file: Option<&'a File>, n: usize, count: usize) -> Self {
        Self {
            file,
            rec: smoothed_len(n),
            count,
            start: 0,
            vals: Vec::new(),
            bytes: Vec::new(),
        }
    }

    fn loaded(&self, k: usize) -> bool {
        k >= self.start && (k - self.start + 1) * self.rec <= self.vals.len()
    }

    /// Records `k` and `k + 1` (None past the end), reading a new block when needed.
    pub(crate) fn pair(&mut self, k: usize) -> Result<(&[f64], Option<&[f64]>), SmoothError> {
        let has_next = k + 1 < self.count;
        if !(self.loaded(k) && (!has_next || self.loaded(k + 1))) {
            let file = self.file.ok_or(SmoothError::Empty)?;
            let m = SMOOTHED_BLOCK.min(self.count.saturating_sub(k));
            read_at(
                file,
                (k * self.rec * 8) as u64,
                &mut self.bytes,
                m * self.rec * 8,
            )
            .map_err(io)?;
            self.vals.clear();
            self.vals.extend(
                self.bytes
                    .chunks_exact(8)
                    .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]])),
            );
            self.start = k;
        }
        let r = self.rec;
        let i = (k - self.start) * r;
        let here = self.vals.get(i..i + r).ok_or(SmoothError::Size(k))?;
        let next = if has_next {
            Some(
                self.vals
                    .get(i + r..i + 2 * r)
                    .ok_or(SmoothError::Size(k + 1))?,
            )
        } else {
            None
        };
        Ok((here, next))
    }

    /// Time of record `k`.
    pub(crate) fn time(&mut self, k: usize) -> Result<f64, SmoothError> {
        Ok(self.pair(k)?.0.first().copied().unwrap_or(f64::NAN))
    }
}

//! The GNSS fixes of a run as a stream with a bounded look-ahead ([`FixAhead`]).
//!
//! The engine reads the fixes from an iterator (a file reader, or a list in memory) and keeps
//! only those it may still need: from the first fix not yet given to the navigator, and from
//! the start of the next imposed outage not yet reached (its snapshot takes the fixes it
//! withholds, up to the outage's end). The start-up reads as far ahead as it looks (the static
//! window's fixes, the first fix fast enough for a velocity course, the fixes of the course
//! look-ahead); what it read before the initial epoch is dropped when the run starts.

use super::super::RunError;
use nav_core::types::GnssFix;
use std::cell::RefCell;
use std::collections::VecDeque;

/// A source of GNSS fixes in time order: the engine's input.
pub type FixSource<'a> = Box<dyn Iterator<Item = Result<GnssFix, RunError>> + 'a>;

/// Fixes in time order by index, read on demand (the start-up's view of the fixes:
/// [`super::super::InitData::gnss`]).
pub trait FixLookup {
    /// Fix `index` (0 = the first of the record), or None past the end (or after a read
    /// error, which the owner reports).
    fn fix(&self, index: usize) -> Option<GnssFix>;
}

impl FixLookup for &[GnssFix] {
    fn fix(&self, index: usize) -> Option<GnssFix> {
        self.get(index).copied()
    }
}

impl FixLookup for Vec<GnssFix> {
    fn fix(&self, index: usize) -> Option<GnssFix> {
        self.get(index).copied()
    }
}

impl FixLookup for RefCell<FixAhead<'_>> {
    fn fix(&self, index: usize) -> Option<GnssFix> {
        self.borrow_mut().get(index)
    }
}

/// The fixes from `index` on, in time order.
pub fn fixes_from(src: &dyn FixLookup, index: usize) -> impl Iterator<Item = GnssFix> + '_ {
    (index..).map_while(move |i| src.fix(i))
}

/// A stream of fixes with a look-ahead buffer: fix `i` read when asked for, kept until
/// released ([`FixAhead::release`]).
pub struct FixAhead<'a> {
    src: FixSource<'a>,
    buf: VecDeque<GnssFix>,
    /// Index of `buf[0]` in the stream.
    base: usize,
    /// The source is exhausted (or failed).
    done: bool,
    /// The first read error (the source stops there).
    err: Option<RunError>,
    /// Most fixes held at once.
    peak: usize,
}

impl<'a> FixAhead<'a> {
    /// Reads `src` on demand.
    pub fn new(src: FixSource<'a>) -> Self {
        Self {
            src,
            buf: VecDeque::new(),
            base: 0,
            done: false,
            err: None,
            peak: 0,
        }
    }

    /// Fix `index`, reading ahead to it. None: past the end, after a read error
    /// ([`FixAhead::take_err`]), or already released.
    pub fn get(&mut self, index: usize) -> Option<GnssFix> {
        let k = index.checked_sub(self.base)?;
        while self.buf.len() <= k && !self.done {
            match self.src.next() {
                Some(Ok(f)) => {
                    self.buf.push_back(f);
                    self.peak = self.peak.max(self.buf.len());
                }
                Some(Err(e)) => {
                    self.err.get_or_insert(e);
                    self.done = true;
                }
                None => self.done = true,
            }
        }
        self.buf.get(k).copied()
    }

    /// Drops the fixes before index `before` whose time is before `t_keep_s` (fixes are in
    /// time order: it stops at the first one kept).
    pub fn release(&mut self, before: usize, t_keep_s: f64) {
        while self.base < before {
            match self.buf.front() {
                Some(f) if f.t_s < t_keep_s => {
                    self.buf.pop_front();
                    self.base += 1;
                }
                _ => break,
            }
        }
    }

    /// Index of the first fix at or after `t_s` (reads ahead to it; fixes released before
    /// are counted as earlier).
    pub fn first_at_or_after(&mut self, t_s: f64) -> usize {
        let mut i = self.base;
        while self.get(i).is_some_and(|f| f.t_s < t_s) {
            i += 1;
        }
        i
    }

    /// The number of fixes in the stream: reads the rest without keeping it.
    pub fn count(&mut self) -> usize {
        let mut n = self.base + self.buf.len();
        while !self.done {
            match self.src.next() {
                Some(Ok(_)) => n += 1,
                Some(Err(e)) => {
                    self.err.get_or_insert(e);
                    self.done = true;
                }
                None => self.done = true,
            }
        }
        n
    }

    /// The first read error, if any (taken).
    pub fn take_err(&mut self) -> Option<RunError> {
        self.err.take()
    }

    /// Most fixes held at once so far.
    pub fn peak(&self) -> usize {
        self.peak
    }

    /// Index of the first fix held (those before were released).
    pub fn first_held(&self) -> usize {
        self.base
    }

    /// Fixes held now.
    pub fn held(&self) -> usize {
        self.buf.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix(t_s: f64) -> GnssFix {
        GnssFix {
            t_s,
            ..GnssFix::default()
        }
    }

    #[test]
    fn reads_ahead_releases_and_counts() {
        let v: Vec<GnssFix> = (0..10).map(|k| fix(f64::from(k))).collect();
        let mut a = FixAhead::new(Box::new(v.iter().copied().map(Ok)));
        assert_eq!(a.get(3).map(|f| f.t_s), Some(3.0));
        assert_eq!(a.held(), 4);
        // release before index 3, but keep from t = 1 on
        a.release(3, 1.0);
        assert_eq!(a.held(), 3);
        assert_eq!(a.get(0), None);
        assert_eq!(a.get(1).map(|f| f.t_s), Some(1.0));
        assert_eq!(a.first_held(), 1);
        a.release(3, f64::INFINITY);
        assert_eq!(a.get(1), None);
        assert_eq!(a.first_held(), 3);
        assert_eq!(a.first_at_or_after(5.5), 6);
        assert_eq!(a.get(10), None);
        // fixes 3..=9 held at most: the released ones never came back
        assert_eq!(a.held(), 7);
        assert_eq!(a.peak(), 7);
        assert_eq!(a.count(), 10);
        assert!(a.take_err().is_none());
    }

    #[test]
    fn a_list_in_memory_is_looked_up_like_the_stream() {
        let v: Vec<GnssFix> = (0..3).map(|k| fix(f64::from(k))).collect();
        let slice = v.as_slice();
        for src in [&v as &dyn FixLookup, &slice] {
            let t: Vec<f64> = fixes_from(src, 1).map(|f| f.t_s).collect();
            assert_eq!(t, [1.0, 2.0]);
        }
    }

    #[test]
    fn keeps_the_first_error() {
        let src = vec![Ok(fix(0.0)), Err(RunError::NoImu), Ok(fix(2.0))];
        let mut a = FixAhead::new(Box::new(src.into_iter()));
        assert!(a.get(0).is_some());
        assert!(a.get(1).is_none());
        assert!(a.get(2).is_none());
        assert_eq!(a.count(), 1);
        assert!(matches!(a.take_err(), Some(RunError::NoImu)));
    }
}

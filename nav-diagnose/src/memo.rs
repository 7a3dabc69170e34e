//! The diagnosis's runs remembered by what determines them ([`RunMemo`]): a diagnosis asks
//! for the same model on the same data more than once (a refined GNSS noise factor that lands
//! on a trial already run, a clock drift in a time offset's place equal to the drift beside
//! the configuration in the round before, the re-tuning's start equal to the search's current
//! model), and a run's records depend only on the IMU data as the model sees it (the record
//! through its [`Adjust`](crate::imu_cache::Adjust)ment; the fixes and the truth are the
//! diagnosis's) and on the run's options. The navigation recording rate changes which
//! navigation records a run writes, not the filter: a request for the innovations is answered
//! by any kept run of the same key, a request for a scored search run ([`Eval`]) only by a
//! scored run at the same rate (a run kept for its innovations has no navigation to score).
//!
//! A remembered run is answered in place of a new one: the same records, bit for bit. The
//! memo keeps the last [`MEMO_RUNS`] runs and at most [`MEMO_INNOVATIONS`] innovation records
//! in all (memory bounded, still proportional to the fixes); a run asked for again after it
//! was dropped is run again.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use nav_engine::run::{RunOptions, RunOutput};

use crate::imu_cache::Case;
use crate::Eval;

/// Runs the memo keeps (the oldest dropped first): on the real drive (default command) every
/// repeated request came within 26 runs of its first.
pub(crate) const MEMO_RUNS: usize = 32;

/// Innovation records the memo keeps in all (about 160 bytes each, a scored run's counted
/// twice for its navigation records nearest the fixes: at most about 20 MiB), the oldest runs
/// dropped first beyond it.
pub(crate) const MEMO_INNOVATIONS: usize = 1 << 17;

/// What a remembered run answers.
#[derive(Clone)]
enum Kept {
    /// A run kept for its innovations ([`crate::spill::run_innovations`]'s output).
    Innovations(Arc<RunOutput>),
    /// A scored search run with its navigation recording rate, Hz (None: every epoch).
    Eval(Box<Eval>, Option<f64>),
}

impl Kept {
    fn innovation_count(&self) -> usize {
        match self {
            Kept::Innovations(r) => r.innovations.len(),
            Kept::Eval(e, _) => e.run.innovations.len() + e.run.nav.len(),
        }
    }
}

/// The runs of one diagnosis remembered by their key ([`RunMemo::key`]); shared by the views
/// of its data ([`Case`]).
#[derive(Default)]
pub(crate) struct RunMemo {
    kept: Mutex<VecDeque<(String, Kept)>>,
}

impl std::fmt::Debug for RunMemo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let n = self.kept.lock().map_or(0, |k| k.len());
        write!(f, "RunMemo({n} runs)")
    }
}

impl RunMemo {
    /// What determines a run of `opts` on `case` besides the data every run of the diagnosis
    /// shares: the IMU adjustment and every option but the navigation recording rate.
    pub(crate) fn key(case: &Case, opts: &RunOptions) -> String {
        let mut o = opts.clone();
        o.record.nav_rate_hz = None;
        format!("{:?}|{o:?}", case.imu.adjust())
    }

    /// The latest kept run of `key` that `pick` takes.
    fn find(&self, key: &str, pick: impl Fn(&Kept) -> Option<Kept>) -> Option<Kept> {
        let kept = self.kept.lock().ok()?;
        kept.iter()
            .rev()
            .filter(|(k, _)| k == key)
            .find_map(|(_, v)| pick(v))
    }

    fn keep(&self, key: String, v: Kept) {
        let Ok(mut kept) = self.kept.lock() else {
            return;
        };
        kept.push_back((key, v));
        let mut total: usize = kept.iter().map(|(_, v)| v.innovation_count()).sum();
        while kept.len() > MEMO_RUNS || (total > MEMO_INNOVATIONS && kept.len() > 1) {
            if let Some((_, v)) = kept.pop_front() {
                total -= v.innovation_count();
            }
        }
    }

    /// The innovations-only output of the run of `key` ([`crate::spill::run_innovations`]):
    /// a run kept for them, or a scored search run's without its navigation, snapshots and
    /// epochs (the fields that run leaves empty).
    pub(crate) fn innovations(&self, key: &str) -> Option<RunOutput> {
        let kept = self.find(key, |v| Some(v.clone()))?;
        Some(match kept {
            Kept::Innovations(r) => (*r).clone(),
            Kept::Eval(e, _) => {
                let mut r = (*e.run).clone();
                r.nav = Vec::new();
                r.epochs = Vec::new();
                r.snapshots = Vec::new();
                r.history = None;
                r
            }
        })
    }

    /// Keeps the innovations-only output `out` of the run of `key`.
    pub(crate) fn keep_innovations(&self, key: String, out: &RunOutput) {
        self.keep(key, Kept::Innovations(Arc::new(out.clone())));
    }

    /// The scored search run of `key` recorded at `nav_rate_hz`, when kept.
    pub(crate) fn eval(&self, key: &str, nav_rate_hz: Option<f64>) -> Option<Eval> {
        match self.find(key, |v| match v {
            Kept::Eval(_, r) if *r == nav_rate_hz => Some(v.clone()),
            _ => None,
        })? {
            Kept::Eval(e, _) => Some(*e),
            Kept::Innovations(_) => None,
        }
    }

    /// Keeps the scored search run `ev` of `key` recorded at `nav_rate_hz`.
    pub(crate) fn keep_eval(&self, key: String, nav_rate_hz: Option<f64>, ev: &Eval) {
        self.keep(key, Kept::Eval(Box::new(ev.clone()), nav_rate_hz));
    }
}

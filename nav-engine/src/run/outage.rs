//! GNSS outages imposed on a run: a fix whose time tag lies in `[start, start + duration)` is
//! withheld from the filter (but still compared with the solution: on real data the withheld
//! fixes are the reference).

use serde::{Deserialize, Serialize};

/// One outage, absolute time (GPS seconds of week).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Outage {
    /// Start, GPS seconds of week.
    pub start_s: f64,
    /// Duration, s. Fixes with tag in `[start_s, start_s + duration_s)` are withheld.
    pub duration_s: f64,
}

impl Outage {
    /// End (exclusive), GPS seconds of week.
    pub fn end_s(&self) -> f64 {
        self.start_s + self.duration_s
    }

    /// Whether a fix tagged `t_s` falls inside the outage.
    pub fn contains(&self, t_s: f64) -> bool {
        t_s >= self.start_s && t_s < self.end_s()
    }

    /// Shifted by `t0_s` (for outages given relative to the first IMU epoch).
    pub fn shifted(&self, t0_s: f64) -> Self {
        Self {
            start_s: self.start_s + t0_s,
            duration_s: self.duration_s,
        }
    }
}

/// Repeating outages: `duration_s` every `period_s`, the first starting `first_start_s` after
/// the reference time (the first IMU epoch), as long as an outage ends before the data end.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PeriodicOutages {
    /// Start of the first outage, s after the reference time.
    pub first_start_s: f64,
    /// Duration of each outage, s.
    pub duration_s: f64,
    /// Period, s.
    pub period_s: f64,
}

impl PeriodicOutages {
    /// KF-GINS paper's protocol: 60 s outages every 180 s. The first one starts 180 s after the
    /// start of the data (the filter has converged by then).
    pub const KF_GINS: Self = Self {
        first_start_s: 180.0,
        duration_s: 60.0,
        period_s: 180.0,
    };

    /// The outages in absolute time for data starting at `t0_s` and ending at `t_end_s`: every
    /// outage that ends at or before `t_end_s`.
    pub fn expand(&self, t0_s: f64, t_end_s: f64) -> Vec<Outage> {
        let mut out = Vec::new();
        if !(self.period_s > 0.0 && self.duration_s > 0.0) {
            return out;
        }
        let mut s = t0_s + self.first_start_s;
        while s + self.duration_s <= t_end_s + 1e-9 {
            out.push(Outage {
                start_s: s,
                duration_s: self.duration_s,
            });
            s += self.period_s;
        }
        out
    }
}

/// Parses `START:DURATION` (seconds; START relative to whatever the caller says).
pub fn parse_outage(s: &str) -> Result<Outage, String> {
    let (a, b) = s
        .split_once(':')
        .ok_or_else(|| format!("outage `{s}`: expected START:DURATION in seconds"))?;
    let start_s: f64 = a
        .trim()
        .parse()
        .map_err(|e| format!("outage `{s}`: start: {e}"))?;
    let duration_s: f64 = b
        .trim()
        .parse()
        .map_err(|e| format!("outage `{s}`: duration: {e}"))?;
    if !(start_s.is_finite() && start_s >= 0.0 && duration_s.is_finite() && duration_s > 0.0) {
        return Err(format!("outage `{s}`: start must be >= 0 and duration > 0"));
    }
    Ok(Outage {
        start_s,
        duration_s,
    })
}

/// Parses `FIRST:DURATION:PERIOD` (seconds) for [`PeriodicOutages`].
pub fn parse_periodic(s: &str) -> Result<PeriodicOutages, String> {
    let parts: Vec<&str> = s.split(':').collect();
    let [a, b, c] = parts.as_slice() else {
        return Err(format!(
            "periodic outage `{s}`: expected FIRST:DURATION:PERIOD in seconds"
        ));
    };
    let num = |x: &str, what: &str| -> Result<f64, String> {
        x.trim()
            .parse::<f64>()
            .map_err(|e| format!("periodic outage `{s}`: {what}: {e}"))
    };
    let p = PeriodicOutages {
        first_start_s: num(a, "first start")?,
        duration_s: num(b, "duration")?,
        period_s: num(c, "period")?,
    };
    if !(p.first_start_s.is_finite()
        && p.first_start_s >= 0.0
        && p.duration_s.is_finite()
        && p.duration_s > 0.0
        && p.period_s.is_finite()
        && p.period_s >= p.duration_s)
    {
        return Err(format!(
            "periodic outage `{s}`: need FIRST >= 0, DURATION > 0 and PERIOD >= DURATION"
        ));
    }
    Ok(p)
}

/// Sorts outages by start and checks them (finite, positive duration).
pub fn normalise(outages: &mut [Outage]) -> Result<(), String> {
    for o in outages.iter() {
        if !(o.start_s.is_finite() && o.duration_s.is_finite() && o.duration_s > 0.0) {
            return Err(format!(
                "outage start {} s, duration {} s: must be finite with a positive duration",
                o.start_s, o.duration_s
            ));
        }
    }
    outages.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
    Ok(())
}

/// Index of the outage containing `t_s`, if any (outages sorted by start).
pub fn find(outages: &[Outage], t_s: f64) -> Option<usize> {
    outages.iter().position(|o| o.contains(t_s))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_rejects() {
        let o = parse_outage("120:10").unwrap();
        assert_eq!((o.start_s, o.duration_s), (120.0, 10.0));
        assert!(parse_outage("120").is_err());
        assert!(parse_outage("x:1").is_err());
        assert!(parse_outage("1:0").is_err());
        let p = parse_periodic("120:30:60").unwrap();
        assert_eq!(p.period_s, 60.0);
        assert!(parse_periodic("120:30").is_err());
        assert!(parse_periodic("120:60:30").is_err());
    }

    #[test]
    fn periodic_expansion_keeps_outages_inside_the_data() {
        let p = PeriodicOutages {
            first_start_s: 120.0,
            duration_s: 30.0,
            period_s: 60.0,
        };
        let v = p.expand(1000.0, 1000.0 + 548.0);
        let starts: Vec<f64> = v.iter().map(|o| o.start_s - 1000.0).collect();
        assert_eq!(
            starts,
            vec![120.0, 180.0, 240.0, 300.0, 360.0, 420.0, 480.0]
        );
        let k = PeriodicOutages::KF_GINS.expand(0.0, 548.0);
        assert_eq!(k.len(), 2);
        assert_eq!(k[1].start_s, 360.0);
        assert!(v[0].contains(1120.0) && !v[0].contains(1150.0));
    }
}

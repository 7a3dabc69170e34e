//! The diagnosis's IMU record file (`nav_diagnose::imu_cache`): samples and their file
//! lines read back bit for bit from any index, messages naming the file and line, a bias
//! step and a time shift applied as the samples are read, the samples kept near the fixes
//! holding the nearest sample of the whole record and its predecessor, the coasting on the
//! streamed samples the same as on the samples in memory, and the file removed with its
//! folder.

use std::sync::Arc;

use nav_core::types::ImuSample;
use nav_diagnose::changepoint::BiasStepSensor;
use nav_diagnose::imu_cache::{Adjust, Case, ImuCache};
use nav_diagnose::spill::temp_folder;
use nav_engine::run::{CaseData, ImuSourceInfo};

fn bits(s: &ImuSample) -> [u64; 8] {
    s.to_values().map(f64::to_bits)
}

/// `n` samples at irregular times (steps of 5 ms with a jitter, a 0.3 s gap), values that do
/// not round-trip through text, a temperature from sample `temp_from` on.
fn samples(n: usize, temp_from: usize) -> Vec<ImuSample> {
    let mut t = 1000.0;
    (0..n)
        .map(|k| {
            let x = k as f64;
            t += 0.005 + 1e-4 * (x * 0.7).sin() + if k == n / 2 { 0.3 } else { 0.0 };
            ImuSample {
                t_s: t,
                dtheta_rad: [1e-5 * x.sin(), -1e-300, std::f64::consts::PI / (x + 1.0)],
                dv_mps: [0.1 / 3.0, -0.049 * x.cos(), -0.098 + 1e-17 * x],
                temperature_c: if k >= temp_from {
                    20.0 + 0.01 * x
                } else {
                    f64::NAN
                },
            }
        })
        .collect()
}

fn cache_of(imu: &[ImuSample], path: Option<&str>) -> ImuCache {
    let folder = temp_folder().unwrap();
    let info = ImuSourceInfo {
        path: path.map(Into::into),
        increments_span_gaps: false,
    };
    let it = imu.iter().enumerate().map(|(k, s)| Ok((*s, 3 * k + 2)));
    ImuCache::write(&folder, it, info).unwrap()
}

#[test]
fn samples_and_lines_read_back_bit_for_bit_from_any_index_and_the_file_goes_with_its_folder() {
    let imu = samples(3000, 100);
    let c = cache_of(&imu, Some("imu.txt"));
    assert_eq!(c.len(), imu.len());
    assert_eq!(c.first_t_s(), Some(imu[0].t_s));
    assert_eq!(c.first_temperature_c(), Some(imu[100].temperature_c));
    for from in [0, 1, 1499, 2999, 3000, 5000] {
        let back: Vec<(ImuSample, usize)> =
            c.read_from(from).unwrap().map(Result::unwrap).collect();
        assert_eq!(back.len(), imu.len().saturating_sub(from), "from {from}");
        for (k, (s, line)) in back.iter().enumerate() {
            assert_eq!(bits(s), bits(&imu[from + k]));
            assert_eq!(*line, 3 * (from + k) + 2);
        }
    }
    assert_eq!(c.locate(10), "imu.txt line 32");
    let no_file = cache_of(&imu[..5], None);
    assert_eq!(no_file.locate(3), "IMU sample 3");
    let path = c.path().to_path_buf();
    let folder = c.folder().path().to_path_buf();
    assert!(path.exists());
    drop(c);
    assert!(!path.exists() && !folder.exists());
}

/// A record file cut short (half a record after sample 1500, the reads in blocks of
/// 1024): every whole sample before the cut is returned, then an error naming the file, the
/// sample and its byte offset; nothing after it.
#[test]
fn a_record_file_cut_short_returns_its_whole_samples_then_an_error_naming_the_sample() {
    use nav_diagnose::imu_cache::IMU_RECORD_BYTES;
    let imu = samples(3000, 0);
    let c = cache_of(&imu, Some("imu.txt"));
    let f = std::fs::OpenOptions::new()
        .write(true)
        .open(c.path())
        .unwrap();
    f.set_len((1500 * IMU_RECORD_BYTES + IMU_RECORD_BYTES / 2) as u64)
        .unwrap();
    for from in [0, 1024, 1499, 1500, 2000] {
        let mut ok = 0;
        let mut errs = Vec::new();
        for r in c.read_from(from).unwrap() {
            match r {
                Ok((s, _)) => {
                    assert!(errs.is_empty(), "a sample after the error");
                    assert_eq!(bits(&s), bits(&imu[from + ok]));
                    ok += 1;
                }
                Err(e) => errs.push(e.to_string()),
            }
        }
        assert_eq!(ok, 1500usize.saturating_sub(from), "from {from}");
        let [e] = errs.as_slice() else {
            panic!("from {from}: {errs:?}")
        };
        let k = from.max(1500);
        assert!(
            e.contains(&c.path().display().to_string())
                && e.contains(&format!("before sample {k} (byte offset {})", k * 72))
                && e.contains(&format!("{} sample(s) missing", 3000 - k)),
            "{e}"
        );
    }
}

#[test]
fn a_bias_step_and_a_time_shift_are_applied_as_the_samples_are_read_from_any_index() {
    let imu = samples(400, 0);
    let data = CaseData {
        imu: imu.clone(),
        ..CaseData::default()
    };
    let folder = temp_folder().unwrap();
    let cache = ImuCache::from_case(&folder, &data).unwrap();
    let case = Case::new(data, Arc::new(cache));
    let t_step = imu[150].t_s + 1e-4;
    let step = [1e-3, -2e-3, 0.5];
    let moved = case.adjusted(Adjust {
        bias_step: Some((BiasStepSensor::Gyro, t_step, step)),
        time_shift_s: 0.125,
    });
    // what a corrected copy of the record holds: the step times each interval starting at or
    // after the step time, then the times moved
    let expected: Vec<ImuSample> = imu
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let mut s = *s;
            if k > 0 && imu[k - 1].t_s >= t_step {
                let dt = s.t_s - imu[k - 1].t_s;
                for (x, b) in s.dtheta_rad.iter_mut().zip(step) {
                    *x -= b * dt;
                }
            }
            s.t_s -= 0.125;
            s
        })
        .collect();
    for from in [0, 1, 150, 151, 152, 399] {
        let got: Vec<ImuSample> = moved.imu.samples_from(from).collect();
        assert_eq!(got.len(), imu.len() - from);
        for (k, s) in got.iter().enumerate() {
            assert_eq!(
                bits(s),
                bits(&expected[from + k]),
                "from {from}, sample {k}"
            );
        }
    }
    assert_eq!(moved.imu.first_t_s(), Some(imu[0].t_s - 0.125));
    // the recorded data unchanged beside it
    let rec: Vec<ImuSample> = case.imu.samples_from(0).collect();
    assert!(rec.iter().zip(&imu).all(|(a, b)| bits(a) == bits(b)));
}

/// Index of the sample nearest `t` (the later one on a tie), as the diagnosis's statistics
/// pick it in a sorted list.
fn nearest(v: &[ImuSample], t: f64) -> usize {
    let i = v.partition_point(|s| s.t_s < t).min(v.len() - 1);
    if i > 0 && (t - v[i - 1].t_s).abs() < (v[i].t_s - t).abs() {
        i - 1
    } else {
        i
    }
}

#[test]
fn the_samples_kept_near_the_fixes_hold_the_nearest_sample_and_its_predecessor() {
    let imu = samples(5000, 2345);
    let c = Case::new(
        CaseData::default(),
        Arc::new(cache_of(&imu, Some("imu.txt"))),
    );
    // before the record, on samples, on midpoints (ties), in the gap, after the record
    let mut times = vec![imu[0].t_s - 1.0, imu[0].t_s];
    for k in (7..5000).step_by(211) {
        times.push(imu[k].t_s);
        times.push(0.5 * (imu[k].t_s + imu[k - 1].t_s));
        times.push(imu[k].t_s + 0.0026);
    }
    times.push(imu[2500].t_s - 0.2);
    times.push(imu[4999].t_s + 3.0);
    times.sort_by(f64::total_cmp);
    let near = c.imu.near(&times).unwrap();
    assert!(near.len() <= 2 * times.len() + 4, "{} kept", near.len());
    assert!(near.windows(2).all(|w| w[0].t_s < w[1].t_s));
    for &t in &times {
        let (i, j) = (nearest(&imu, t), nearest(&near, t));
        assert_eq!(bits(&near[j]), bits(&imu[i]), "t {t}");
        if i > 0 {
            assert_eq!(bits(&near[j - 1]), bits(&imu[i - 1]), "t {t}");
        } else {
            assert_eq!(bits(&near[1]), bits(&imu[1]));
        }
    }
    // the first sample with a temperature is kept (the regressors' reference)
    let first_temp = near.iter().find(|s| s.temperature_c.is_finite()).unwrap();
    assert_eq!(bits(first_temp), bits(&imu[2345]));
}

#[test]
fn an_imu_sample_out_of_order_is_named_by_its_file_and_line_through_the_record_file() {
    use nav_core::earth::Llh;
    use nav_engine::run::RunOptions;
    let pos = Llh::from_deg(30.5, 114.3, 20.0);
    let t0 = 100_000.0;
    let mut imu: Vec<ImuSample> = test_support::standing::imu(pos, t0, 200.0, 2000).collect();
    imu[700].t_s = imu[698].t_s;
    let lines: Vec<usize> = (0..imu.len()).map(|k| 2 * k + 5).collect();
    let p = nav_engine::Prepared {
        case: CaseData {
            imu,
            gnss: test_support::standing::fixes(pos, t0, 1.0, 9).collect(),
            truth: None,
            imu_origin: Some(nav_io::ImuOrigin {
                path: "logs/imu.txt".into(),
                lines,
                increments_span_gaps: false,
            }),
        },
        opts: RunOptions::standing_start(t0, pos),
        week: 2227,
        description: "standing vehicle".into(),
    };
    let opts = nav_diagnose::DiagnoseOptions::default();
    let Err(e) = nav_diagnose::diagnose(&p, &opts) else {
        panic!("a sample out of order must end the diagnosis with an error");
    };
    let msg = format!("{e:#}");
    assert!(msg.contains("logs/imu.txt line 1405"), "{msg}");
}

//! Streaming Allan variance against a direct block-mean computation, and its state size.
use nav_core::allan::StreamingAllan;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Direct non-overlapping AVAR from the block means (an independent, obvious implementation).
fn direct_avar(y: &[f64], m: usize) -> Option<(f64, usize)> {
    let means: Vec<f64> = y
        .chunks_exact(m)
        .map(|c| c.iter().sum::<f64>() / m as f64)
        .collect();
    if means.len() < 2 {
        return None;
    }
    let s: f64 = means.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum();
    Some((s / (2.0 * (means.len() - 1) as f64), means.len() - 1))
}

#[test]
fn streaming_avar_equals_direct_block_means_at_every_octave() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    // White + random walk + a 9.81 offset, an odd length so partial blocks exist.
    let n = 100_003;
    let mut rw = 0.0;
    let y: Vec<f64> = (0..n)
        .map(|_| {
            rw += 1e-3 * rng.sample::<f64, _>(StandardNormal);
            9.81 + 0.02 * rng.sample::<f64, _>(StandardNormal) + rw
        })
        .collect();
    let mut s = StreamingAllan::<18>::new();
    for &v in &y {
        assert!(s.push(v));
    }
    assert_eq!(s.n_samples(), n as u64);
    for level in 0..18 {
        let m = 1usize << level;
        match direct_avar(&y, m) {
            Some((want, terms)) => {
                let got = s.avar(level).expect("streaming value");
                assert_eq!(s.n_terms(level), terms as u64, "level {level}");
                let rel = (got - want).abs() / want;
                assert!(rel < 1e-9, "level {level}: {got} vs {want} ({rel:e})");
            }
            None => assert!(s.avar(level).is_none(), "level {level}"),
        }
    }
}

#[test]
fn streaming_state_is_small_and_fixed() {
    // 24 bytes per level + offset + count.
    assert_eq!(core::mem::size_of::<StreamingAllan<16>>(), 24 * 16 + 16);
    assert_eq!(core::mem::size_of::<StreamingAllan<24>>(), 24 * 24 + 16);
}

#[test]
fn streaming_ignores_non_finite_samples() {
    let mut s = StreamingAllan::<4>::new();
    assert!(!s.push(f64::NAN));
    assert!(!s.push(f64::INFINITY));
    assert_eq!(s.n_samples(), 0);
    s.push(1.0);
    s.push(3.0);
    assert_eq!(s.avar(0), Some(2.0));
    s.reset();
    assert_eq!(s.n_samples(), 0);
    assert_eq!(s.avar(0), None);
}

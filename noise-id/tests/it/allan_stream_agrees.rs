//! nav-core's streaming (octave-pyramid, non-overlapping) Allan variance agrees with the host's
//! non-overlapping ADEV on the same data.
use nav_core::allan::StreamingAllan;
use nav_sim::noise::{GaussMarkov, RandomWalk, White};
use noise_id::{Deviation, Phase};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

#[test]
fn streaming_allan_equals_host_non_overlapping_adev_to_1e9() {
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let dt = 0.01;
    let mut w = White::from_psd(6.2865e-9, dt);
    let mut g = GaussMarkov::new(2.4360e-11, 45.0, dt);
    let mut k = RandomWalk::new(2.6731e-12, dt);
    let n = 1_000_003;
    let y: Vec<f64> = (0..n)
        .map(|_| 9.81 + w.next(&mut rng) + g.next(&mut rng) + k.next(&mut rng))
        .collect();
    let mut s = StreamingAllan::<20>::new();
    for &v in &y {
        s.push(v);
    }
    let phase = Phase::from_rate(&y);
    let mut compared = 0;
    for level in 0..20 {
        let m = 1usize << level;
        let host = phase.variance(Deviation::Adev, m);
        match (host, s.avar(level)) {
            (Some((h, nt)), Some(st)) => {
                assert_eq!(nt as u64, s.n_terms(level), "level {level}");
                let rel = (st - h).abs() / h;
                assert!(
                    rel < 1e-9,
                    "level {level}: streaming {st} host {h} rel {rel:e}"
                );
                compared += 1;
            }
            (None, None) => {}
            (a, b) => panic!("level {level}: host {a:?} streaming {b:?}"),
        }
    }
    assert!(compared >= 18, "{compared}");
}

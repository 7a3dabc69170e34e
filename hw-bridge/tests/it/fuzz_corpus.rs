//! The fuzz corpus and every saved crasher as regression tests, plus a bounded random-input
//! run of each fuzz property on stable Rust (the libFuzzer targets in `fuzz/` need
//! `RUSTC_BOOTSTRAP=1 cargo fuzz run <target>`).

use hw_bridge::fuzz_checks;
use rand::{Rng, SeedableRng};
use std::path::Path;

type Check = fn(&[u8]);

const TARGETS: [(&str, Check); 4] = [
    ("wire_decoder", fuzz_checks::wire_decoder),
    ("nmea", fuzz_checks::nmea),
    ("gnss_stream", fuzz_checks::gnss_stream),
    ("capture", fuzz_checks::capture),
];

fn files_in(dir: &Path) -> Vec<std::path::PathBuf> {
    match std::fs::read_dir(dir) {
        Ok(rd) => rd.filter_map(|e| e.ok().map(|e| e.path())).collect(),
        Err(_) => Vec::new(),
    }
}

#[test]
fn fuzz_corpus_and_regressions_pass_every_property() {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../fuzz"));
    let mut n = 0;
    for (name, check) in TARGETS {
        for sub in ["corpus", "regressions"] {
            for f in files_in(&root.join(sub).join(name)) {
                let data = std::fs::read(&f).unwrap();
                check(&data);
                n += 1;
            }
        }
    }
    println!("{n} corpus/regression inputs checked");
    assert!(n >= 4, "the seed corpus is missing ({n} inputs)");
}

/// Valid frames, NMEA sentences and UBX packets with random damage: the stable-Rust stand-in
/// for a bounded fuzz run (fixed seed, a few seconds).
#[test]
fn bounded_random_inputs_pass_every_property() {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../fuzz/corpus"));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2024);
    for (name, check) in TARGETS {
        let seeds: Vec<Vec<u8>> = files_in(&root.join(name))
            .into_iter()
            .map(|f| std::fs::read(f).unwrap())
            .collect();
        for _ in 0..3000 {
            let mut data = if seeds.is_empty() || rng.random_bool(0.2) {
                (0..rng.random_range(0..600))
                    .map(|_| rng.random())
                    .collect()
            } else {
                seeds[rng.random_range(0..seeds.len())].clone()
            };
            for _ in 0..rng.random_range(0..6) {
                if data.is_empty() {
                    break;
                }
                let i = rng.random_range(0..data.len());
                match rng.random_range(0..3) {
                    0 => data[i] ^= 1 << rng.random_range(0..8),
                    1 => {
                        data.remove(i);
                    }
                    _ => data.insert(i, rng.random()),
                }
            }
            check(&data);
        }
    }
}

//! Writes a drive of `nav_sim::undeclared` with its GNSS gaps in the file only (no
//! imposed outages: `case.toml` lists none, so `host-sim diagnose --config DIR/kf-gins.yaml`
//! sees the recording as a user's, with its truth for the metrics).
//!
//! `cargo run --release -p host-sim --example undeclared_drive -- DIR EFFECT MINUTES SEED GAPS`
//! with EFFECT a block name of [`Effect`] (`accel_scale_factor`, ...) or `none`.
use nav_sim::undeclared::{generate, DriveSpec, Effect};

fn main() -> anyhow::Result<()> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let [dir, effect, minutes, seed, gaps] = a.as_slice() else {
        anyhow::bail!("usage: undeclared_drive DIR EFFECT|none MINUTES SEED GAPS");
    };
    let effect = match effect.as_str() {
        "none" => None,
        e => Some(
            Effect::ALL
                .into_iter()
                .find(|x| x.block_name() == e)
                .ok_or_else(|| anyhow::anyhow!("unknown effect {e}"))?,
        ),
    };
    let spec = DriveSpec {
        minutes: minutes.parse()?,
        seed: seed.parse()?,
        file_gaps: Some(gaps.parse()?),
        ..DriveSpec::new(effect)
    };
    let t = std::time::Instant::now();
    let mut drive = generate(&spec)?;
    // the gaps are in the GNSS file; the case file imposes no outage on the run
    drive.case.errors.gnss.outages.clear();
    drive.write(std::path::Path::new(dir))?;
    println!(
        "{} in {:.1} s -> {dir}",
        drive.describe(),
        t.elapsed().as_secs_f64()
    );
    Ok(())
}

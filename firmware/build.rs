//! Puts the selected board's memory layout on the linker path and adds the link scripts for
//! the firmware binaries only (host crates are untouched).
//!
//! The default board (emulated MPS2-AN386) uses the workspace's top-level `memory.x`; a real
//! board uses `firmware/boards/<board>/memory.x`, chosen by its `board-<board>` feature.
use std::{env, fs, path::PathBuf};

/// Real boards with their own layout: (cargo feature env name, folder under boards/).
const BOARDS: &[(&str, &str)] = &[("CARGO_FEATURE_BOARD_STM32F407", "stm32f407")];

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR set by cargo"));
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let mut memory_x = manifest.join("..").join("memory.x");
    for (feature, dir) in BOARDS {
        if env::var_os(feature).is_some() {
            memory_x = manifest.join("boards").join(dir).join("memory.x");
        }
    }
    fs::copy(&memory_x, out.join("memory.x"))
        .unwrap_or_else(|e| panic!("copy {}: {e}", memory_x.display()));
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory_x.display());
    for (_, dir) in BOARDS {
        println!(
            "cargo:rerun-if-changed={}",
            manifest.join("boards").join(dir).join("memory.x").display()
        );
    }
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    if env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}

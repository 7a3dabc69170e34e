//! The integration tests of `nav-io` in one test binary: one build and one link instead of one
//! per file. Tests with a counting global allocator (memory bounds) stay separate binaries
//! in `tests/`.

mod gnss_input;
mod io_csv;
mod io_fuzz;
mod io_gnss_encode;
mod io_gnss_leap;
mod io_gnss_logs;
mod io_gnsscsv;
mod io_imu_fast;
mod io_kfgins;
mod io_pos;
mod io_real_data;
mod io_runcfg;
mod io_runcfg_validation;
mod io_small_damage;
mod io_tag_clock;
mod io_text;
mod numfmt;

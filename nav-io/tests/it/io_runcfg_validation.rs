//! Run-configuration validation: negative or zero noise densities, unknown effect
//! names and unknown keys are errors naming the file and the line.

use nav_io::runcfg::key_line;
use nav_io::{read_run_config, IoError};

const BASE: &str = r#"name = "v"
effects = ["lever_arm", "time_offset"]

[imu]
path = "imu.txt"
format = "text"

[gnss]
path = "gnss.txt"
format = "text"

[init]
pos_std_m = [1.0, 1.0, 2.0]
vel_std_mps = [0.1, 0.1, 0.1]
att_std_deg = [1.0, 1.0, 5.0]

[init.align]
static_s = 10.0

[noise.accel]
vrw_mps_per_sqrt_h = 0.03
gm_sigma_ug = 50.0
t_b_s = 300.0

[noise.gyro]
arw_deg_per_sqrt_h = 0.2
k_deg_per_h_per_sqrt_h = 1.0
"#;

fn err_of(text: &str) -> IoError {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("mine.toml");
    std::fs::write(&p, text).unwrap();
    let e = read_run_config(&p).unwrap_err();
    assert!(matches!(e, IoError::Config { .. }), "{e:?}");
    assert!(e.to_string().contains("mine.toml"), "{e}");
    e
}

#[test]
fn the_base_configuration_is_valid() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ok.toml");
    std::fs::write(&p, BASE).unwrap();
    let c = read_run_config(&p).unwrap();
    assert_eq!(c.effects.len(), 2);
}

/// A configuration without a required table is refused naming the table and the file, not
/// with the position the TOML parser gives it (the start of the file).
#[test]
fn a_missing_table_is_named_without_a_position() {
    let start = BASE.find("[noise.accel]").unwrap();
    let e = err_of(&BASE[..start]);
    // the whole chain, as the command lines print it
    let mut m = e.to_string();
    let mut src = std::error::Error::source(&e);
    while let Some(s) = src {
        m.push_str(&format!(": {s}"));
        src = s.source();
    }
    assert!(
        m.contains("missing table [noise] (the IMU noise model)"),
        "{m}"
    );
    assert!(!m.contains("line 1") && !m.contains("column"), "{m}");
    // two missing: both named
    let no_gnss = BASE.replace("[gnss]\npath = \"gnss.txt\"\nformat = \"text\"\n", "");
    let m = err_of(&no_gnss[..no_gnss.find("[noise.accel]").unwrap()]).to_string();
    assert!(
        m.contains("missing tables [gnss] (the GNSS input), [noise] (the IMU noise model)"),
        "{m}"
    );
    // a required key inside a table keeps the parser's position (its table's)
    let m = err_of(&BASE.replace("path = \"imu.txt\"\n", "")).to_string();
    assert!(m.contains("missing field `path`"), "{m}");
}

#[test]
fn negative_density_is_an_error_with_its_line() {
    // the TOML reader squared -0.2 deg/sqrt(h) into a valid PSD before
    let e = err_of(&BASE.replace("arw_deg_per_sqrt_h = 0.2", "arw_deg_per_sqrt_h = -0.2"));
    let m = e.to_string();
    assert!(
        m.contains("line 26: noise.gyro.arw_deg_per_sqrt_h: -0.2 is not allowed"),
        "{m}"
    );
    let e = err_of(&BASE.replace("gm_sigma_ug = 50.0", "gm_sigma_ug = -50.0"));
    assert!(
        e.to_string().contains("line 22: noise.accel.gm_sigma_ug"),
        "{e}"
    );
}

#[test]
fn zero_white_noise_and_zero_correlation_time_are_errors_with_their_lines() {
    let e = err_of(&BASE.replace("vrw_mps_per_sqrt_h = 0.03", "vrw_mps_per_sqrt_h = 0.0"));
    let m = e.to_string();
    assert!(m.contains("line 21: noise.accel.vrw_mps_per_sqrt_h"), "{m}");
    assert!(m.contains("trust the sensor absolutely"), "{m}");
    let e = err_of(&BASE.replace("t_b_s = 300.0", "t_b_s = 0.0"));
    assert!(e.to_string().contains("line 23: noise.accel.t_b_s"), "{e}");
    // a zero random walk is just "no random walk": accepted
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ok.toml");
    std::fs::write(
        &p,
        BASE.replace(
            "k_deg_per_h_per_sqrt_h = 1.0",
            "k_deg_per_h_per_sqrt_h = 0.0",
        ),
    )
    .unwrap();
    read_run_config(&p).unwrap();
}

#[test]
fn unknown_effect_name_is_an_error_with_its_line_and_the_known_names() {
    let e = err_of(&BASE.replace("\"time_offset\"", "\"time_ofset\""));
    let m = e.to_string();
    assert!(
        m.contains("line 2: effects: \"time_ofset\" is not an effect name"),
        "{m}"
    );
    assert!(m.contains("gyro_g_sensitivity"), "{m}");
}

#[test]
fn unknown_key_is_an_error_with_its_line() {
    let e = err_of(&BASE.replace("static_s = 10.0", "static_s = 10.0\nstatic_seconds = 5.0"));
    let m = e.to_string();
    assert!(m.contains("static_seconds") && m.contains("line 19"), "{m}");
}

#[test]
fn key_line_follows_tables() {
    assert_eq!(key_line(BASE, "", "effects"), Some(2));
    assert_eq!(key_line(BASE, "noise.gyro", "arw_deg_per_sqrt_h"), Some(26));
    assert_eq!(key_line(BASE, "noise.accel", "arw_deg_per_sqrt_h"), None);
    assert_eq!(key_line(BASE, "init.align", "static_s"), Some(18));
}

/// Noise values may be given per axis `[x, y, z]` (as `host-sim allan` writes them); a wrong
/// length or a negative element is an error naming the line.
#[test]
fn per_axis_noise_values_are_read_and_checked() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("axes.toml");
    let text = BASE
        .replace(
            "vrw_mps_per_sqrt_h = 0.03",
            "s_n = [1.0e-6, 2.0e-6, 3.0e-6]",
        )
        .replace(
            "gm_sigma_ug = 50.0",
            "s_b = [1.0e-10, 0.0, 4.0e-10]\nbias_init_ug = 2000",
        );
    std::fs::write(&p, &text).unwrap();
    let c = read_run_config(&p).unwrap();
    let a = c.noise.accel.to_sensor_noise().unwrap();
    assert_eq!(a.s_n, [1.0e-6, 2.0e-6, 3.0e-6]);
    assert_eq!(a.s_b, [1.0e-10, 0.0, 4.0e-10]);
    assert_eq!(a.t_b_s, 300.0);
    let b0 = 2000.0 * nav_core::config::units::UG_MPS2;
    assert!(
        a.bias_init_sigma.iter().all(|v| (v - b0).abs() < 1e-15),
        "{a:?}"
    );
    // the gyro's single number still means all three axes
    let g = c.noise.gyro.to_sensor_noise().unwrap();
    assert!(g.s_n[0] > 0.0 && g.s_n[0] == g.s_n[1] && g.s_n[1] == g.s_n[2]);

    let e = err_of(&text.replace("[1.0e-6, 2.0e-6, 3.0e-6]", "[1.0e-6, 2.0e-6]"));
    assert!(e.to_string().contains("array of three numbers"), "{e}");
    assert!(e.to_string().contains("line 21"), "{e}");
    let e = err_of(&text.replace("[1.0e-6, 2.0e-6, 3.0e-6]", "[1.0e-6, -2.0e-6, 3.0e-6]"));
    assert!(
        e.to_string()
            .contains("line 21: noise.accel.s_n: -0.000002 is not allowed"),
        "{e}"
    );
    let e = err_of(&text.replace("[1.0e-6, 2.0e-6, 3.0e-6]", "[1.0e-6, 0.0, 3.0e-6]"));
    assert!(e.to_string().contains("trust the sensor absolutely"), "{e}");
}

#[test]
fn unknown_key_suggests_the_nearest_valid_one_with_its_line() {
    let e = err_of(&BASE.replace("static_s = 10.0", "statc_s = 10.0"));
    let m = e.to_string();
    assert!(
        m.contains("statc_s") && m.contains("line 18") && m.contains("did you mean `static_s`?"),
        "{m}"
    );
    let e = err_of(&BASE.replace("format = \"text\"\n\n[gnss]", "fromat = \"text\"\n\n[gnss]"));
    let m = e.to_string();
    assert!(m.contains("did you mean `format`?"), "{m}");
    let e = err_of(&BASE.replace("arw_deg_per_sqrt_h", "arw_deg_per_sqr_h"));
    let m = e.to_string();
    assert!(m.contains("did you mean `arw_deg_per_sqrt_h`?"), "{m}");
    // a misspelt value of a closed list: the nearest value
    let e = err_of(&BASE.replace("format = \"text\"\n\n[gnss]", "format = \"txt\"\n\n[gnss]"));
    assert!(e.to_string().contains("did you mean `text`?"), "{e}");
    // nothing near: no guess
    let e = err_of(&BASE.replace("static_s = 10.0", "colour = 3"));
    assert!(!e.to_string().contains("did you mean"), "{e}");
}

/// A key written in the wrong table is named with the table where it belongs (found from the
/// configuration's own types), with its line; a key of several tables lists them all; a
/// table's own near misspelling still gets "did you mean".
#[test]
fn a_key_in_the_wrong_table_names_the_table_where_it_belongs() {
    let e = err_of(&BASE.replace(
        "format = \"text\"\n\n[gnss]",
        "format = \"text\"\nsigma_scale = 10.0\n\n[gnss]",
    ));
    let m = e.to_string();
    assert!(
        m.contains("line 7")
            && m.trim_end()
                .ends_with("; `sigma_scale` is a key of [gnss], not [imu]"),
        "{m}"
    );
    // a key of the top level written under a table, and one of a nested table
    let e = err_of(&BASE.replace("static_s = 10.0", "static_s = 10.0\nstart_s = 5.0"));
    let m = e.to_string();
    assert!(
        m.contains("`start_s` is a key of the top level (before any [table]), not [init.align]"),
        "{m}"
    );
    let e = err_of(&BASE.replace(
        "pos_std_m = [1.0, 1.0, 2.0]",
        "pos_std_m = [1.0, 1.0, 2.0]\nstatic_s = 3.0",
    ));
    let m = e.to_string();
    assert!(
        m.contains("`static_s` is a key of [init.align], not [init]"),
        "{m}"
    );
    let e = err_of(&BASE.replace(
        "format = \"text\"\n\n[gnss]",
        "format = \"text\"\nlever_arm_m = [0.0, 0.0, 1.0]\n\n[gnss]",
    ));
    let m = e.to_string();
    assert!(
        m.contains(
            "`lever_arm_m` is a key of [aiding.nhc], [aiding.odometer] and [gnss], not [imu]"
        ),
        "{m}"
    );
    // a key of no table: no such hint
    let e = err_of(&BASE.replace("static_s = 10.0", "colour = 3"));
    assert!(!e.to_string().contains("is a key of"), "{e}");
}

#[test]
fn init_is_optional_and_defaults_to_an_alignment_from_the_data() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("no_init.toml");
    let start = BASE.find("[init]").unwrap();
    let end = BASE.find("[noise.accel]").unwrap();
    let text = format!("{}{}", &BASE[..start], &BASE[end..]);
    std::fs::write(&p, &text).unwrap();
    let c = read_run_config(&p).unwrap();
    assert_eq!(c.init, nav_io::runcfg::InitConfig::default());
    let nav_io::InitMode::Align(a) = c.init.mode().unwrap() else {
        panic!("default init is an alignment")
    };
    assert_eq!(*a, nav_io::runcfg::DEFAULT_ALIGN);
    assert_eq!(a.static_s, nav_io::runcfg::DEFAULT_STATIC_S);
    // [init.align] with its window only; the sigmas default
    let text = BASE
        .replace("pos_std_m = [1.0, 1.0, 2.0]\n", "")
        .replace("vel_std_mps = [0.1, 0.1, 0.1]\n", "")
        .replace("att_std_deg = [1.0, 1.0, 5.0]\n", "");
    std::fs::write(&p, &text).unwrap();
    let c = read_run_config(&p).unwrap();
    assert_eq!(c.init.pos_std_m, [1.0, 1.0, 2.0]);
    assert_eq!(c.init.att_std_deg, [2.0, 2.0, 10.0]);
    assert_eq!(c.init.align.as_ref().unwrap().static_s, 10.0);
}

//! `write_f64` (ryu digits laid out as `Display`) writes exactly what `format!("{}")` writes,
//! so `nav.txt` stays byte-identical to the files written before: every kind of f64 (random
//! bit patterns: subnormals, huge, tiny, integers, negative zero, NaN, infinities) and the
//! values a navigation file holds.
use nav_core::types::NavSolution;
use nav_io::{write_f64, write_nav_line};
use proptest::prelude::*;

fn ours(x: f64) -> String {
    let mut v = Vec::new();
    write_f64(&mut v, &mut ryu::Buffer::new(), x).unwrap();
    String::from_utf8(v).unwrap()
}

#[test]
fn special_values_match_display() {
    let xs = [
        0.0,
        -0.0,
        1.0,
        -1.0,
        0.1,
        0.5,
        1e-7,
        1.5e-7,
        -2.5e-5,
        1e15,
        1e16,
        1.2345e17,
        1e21,
        1e22,
        123456789012345680.0,
        f64::MAX,
        f64::MIN_POSITIVE,
        5e-324,
        -5e-324,
        f64::EPSILON,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        200000.005,
        30.527_624_193_1,
        114.356_789_012_345,
        2227.0,
        std::f64::consts::PI,
    ];
    for x in xs {
        assert_eq!(ours(x), format!("{x}"), "{x:e}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(20_000))]
    #[test]
    fn any_bits_match_display(bits in any::<u64>()) {
        let x = f64::from_bits(bits);
        prop_assert_eq!(ours(x), format!("{x}"));
    }

    #[test]
    fn nav_values_match_display(t in 0.0f64..604_800.0, lat in -90.0f64..90.0, v in -1e-3f64..1e-3) {
        for x in [t, lat, v, v * 1e-6, lat.to_radians().to_degrees()] {
            prop_assert_eq!(ours(x), format!("{x}"));
        }
    }
}

#[test]
fn nav_line_is_the_display_line() {
    let n = NavSolution {
        week: 2227,
        t_s: 200_000.005,
        lat_rad: 0.5328,
        lon_rad: 1.9959,
        h_m: -0.0,
        vel_ned_mps: [1e-9, -12.5, 0.0],
        rpy_rad: [1e-7, -3.0, 2.5],
        ..NavSolution::default()
    };
    let mut v = Vec::new();
    write_nav_line(&mut v, &n).unwrap();
    let want = format!(
        "{} {} {} {} {} {} {} {} {} {} {}\n",
        n.week,
        n.t_s,
        n.lat_rad.to_degrees(),
        n.lon_rad.to_degrees(),
        n.h_m,
        n.vel_ned_mps[0],
        n.vel_ned_mps[1],
        n.vel_ned_mps[2],
        n.rpy_rad[0].to_degrees(),
        n.rpy_rad[1].to_degrees(),
        n.rpy_rad[2].to_degrees()
    );
    assert_eq!(String::from_utf8(v).unwrap(), want);
}

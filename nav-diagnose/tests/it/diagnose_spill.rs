//! The diagnosis's file of navigation records (`nav_diagnose::spill::NavFile`): read
//! back bit for bit, a file cut short reported with its name, the temporary folder removed
//! with its last holder.

use nav_core::types::NavSolution;
use nav_diagnose::spill::{temp_folder, NavFile};

fn bits(s: &NavSolution) -> Vec<u64> {
    let mut v = vec![u64::from(s.week), u64::from(s.status)];
    v.extend(
        [s.t_s, s.lat_rad, s.lon_rad, s.h_m]
            .iter()
            .chain(&s.vel_ned_mps)
            .chain(&s.rpy_rad)
            .chain(&s.pos_std_ned_m)
            .chain(&s.vel_std_ned_mps)
            .chain(&s.att_std_rad)
            .map(|x| x.to_bits()),
    );
    v
}

#[test]
fn nav_records_read_back_bit_for_bit_and_the_folder_goes_with_the_last_holder() {
    let folder = temp_folder().unwrap();
    let nav: Vec<NavSolution> = (0..1000u32)
        .map(|i| {
            let x = f64::from(i);
            NavSolution {
                week: 2227,
                t_s: 1000.0 + x * 0.005,
                lat_rad: 0.5 + x * 1e-9,
                lon_rad: -1.2 - x * 1e-9,
                h_m: 100.0 + x / 7.0,
                vel_ned_mps: [x / 3.0, -x, f64::NAN],
                rpy_rad: [0.1, -0.2, x.sin()],
                pos_std_ned_m: [1.0 / (x + 1.0); 3],
                vel_std_ned_mps: [f64::INFINITY, 0.0, -0.0],
                att_std_rad: [1e-300, 1e300, 3.0],
                status: i,
            }
        })
        .collect();
    let f = NavFile::from_slice(&folder, "t", &nav).unwrap();
    assert_eq!(f.len(), nav.len());
    assert_eq!(f.first_t_s(), Some(1000.0));
    assert_eq!(f.last_t_s(), Some(nav[999].t_s));
    let back = f.load().unwrap();
    assert_eq!(back.len(), nav.len());
    assert!(nav.iter().zip(&back).all(|(a, b)| bits(a) == bits(b)));
    // a file cut short: the records before the cut, then an error naming the file
    let p = f.path().to_path_buf();
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() - 10]).unwrap();
    let r: Vec<_> = f.records().unwrap().collect();
    assert_eq!(r.len(), nav.len());
    assert!(r[..nav.len() - 1].iter().all(Result::is_ok));
    let e = r[nav.len() - 1].as_ref().unwrap_err().to_string();
    assert!(e.contains("t.nav.bin"), "{e}");
    // the folder goes with the last holder
    let dir = folder.path().to_path_buf();
    drop(folder);
    assert!(dir.exists());
    drop(f);
    assert!(!dir.exists());
}

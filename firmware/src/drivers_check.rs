//! On-target checks of the firmware's drivers against simulated hardware: the ICM-42688-P
//! driver talks to a register-file model of the chip (auto-incrementing burst reads, bit 7 =
//! read) through the `embedded_hal::spi::SpiDevice` trait, exactly as to the real chip.

use core::convert::Infallible;
use embedded_hal::spi::{ErrorType, Operation, SpiDevice};
use firmware::icm42688::{self, Icm42688};
use firmware::{error, info};

/// Register file of a simulated ICM-42688-P.
struct FakeIcm {
    regs: [u8; 128],
    writes: u32,
}

impl ErrorType for FakeIcm {
    type Error = Infallible;
}

impl FakeIcm {
    fn exchange(&mut self, buf: &mut [u8]) {
        let Some((&mut first, rest)) = buf.split_first_mut() else {
            return;
        };
        let reg = usize::from(first & 0x7F);
        if first & 0x80 != 0 {
            for (i, b) in rest.iter_mut().enumerate() {
                *b = self.regs.get(reg + i).copied().unwrap_or(0);
            }
        } else if let Some(&v) = rest.first() {
            if let Some(r) = self.regs.get_mut(reg) {
                *r = v;
            }
            self.writes += 1;
        }
    }
}

impl SpiDevice for FakeIcm {
    fn transaction(&mut self, ops: &mut [Operation<'_, u8>]) -> Result<(), Infallible> {
        for op in ops {
            match op {
                Operation::TransferInPlace(buf) => self.exchange(buf),
                Operation::Write(data) => {
                    let mut tmp = [0u8; 16];
                    let n = data.len().min(tmp.len());
                    tmp[..n].copy_from_slice(&data[..n]);
                    self.exchange(&mut tmp[..n]);
                }
                _ => {}
            }
        }
        Ok(())
    }
}

fn close(a: f64, b: f64) -> bool {
    let d = if a > b { a - b } else { b - a };
    let m = if b < 0.0 { -b } else { b };
    d <= 1e-12 * m.max(1e-300)
}

/// Runs the checks; logs each and returns whether all passed.
pub fn run() -> bool {
    let mut ok = true;
    let mut check = |name: &str, pass: bool| {
        info!(
            "selftest: driver check {}: {}",
            name,
            if pass { "ok" } else { "FAILED" }
        );
        ok &= pass;
    };

    // wrong chip: typed error, no configuration written
    let mut fake = FakeIcm {
        regs: [0; 128],
        writes: 0,
    };
    fake.regs[usize::from(icm42688::REG_WHO_AM_I)] = 0x12;
    let r = Icm42688::new(fake, icm42688::Config::default());
    check(
        "icm42688 rejects WHO_AM_I 0x12",
        matches!(r, Err(icm42688::Error::WrongId(0x12))),
    );

    // right chip: configuration registers as the datasheet wants them
    let mut fake = FakeIcm {
        regs: [0; 128],
        writes: 0,
    };
    fake.regs[usize::from(icm42688::REG_WHO_AM_I)] = icm42688::WHO_AM_I_VALUE;
    let Ok(mut imu) = Icm42688::new(fake, icm42688::Config::default()) else {
        error!("selftest: icm42688 init failed on a correct WHO_AM_I");
        return false;
    };
    let mut regs = [0u8; 4];
    for (r, a) in regs.iter_mut().zip([
        icm42688::REG_GYRO_CONFIG0,
        icm42688::REG_ACCEL_CONFIG0,
        icm42688::REG_PWR_MGMT0,
        icm42688::REG_DEVICE_CONFIG,
    ]) {
        *r = imu.read(a).unwrap_or(0xFF);
    }
    // +-2000 dps / +-16 g (FS_SEL 0), 200 Hz (ODR 7), low-noise mode, soft reset issued
    check(
        "icm42688 configuration registers",
        regs == [0x07, 0x07, 0x0F, 0x01],
    );

    // burst decoding: known raw words -> SI increments in FRD
    let mut fake = imu.release();
    let words: [i16; 7] = [1325, 2048, -1024, -2048, 164, -328, 82];
    for (i, w) in words.iter().enumerate() {
        let [hi, lo] = w.to_be_bytes();
        fake.regs[usize::from(icm42688::REG_TEMP_DATA1) + 2 * i] = hi;
        fake.regs[usize::from(icm42688::REG_TEMP_DATA1) + 2 * i + 1] = lo;
    }
    let Ok(mut imu) = Icm42688::new(fake, icm42688::Config::default()) else {
        return false;
    };
    let dt = 0.005;
    let Ok(s) = imu.read_sample(100.0, dt) else {
        return false;
    };
    let g = 9.806_65;
    let d2r = core::f64::consts::PI / 180.0;
    // chip (x, y, z) -> FRD (x, -y, -z); 2048 LSB/g, 16.4 LSB/(deg/s), T = raw/132.48 + 25
    let want_dv = [g * dt, 0.5 * g * dt, g * dt];
    let want_dth = [10.0 * d2r * dt, 20.0 * d2r * dt, -5.0 * d2r * dt];
    let pass = s.t_s == 100.0
        && s.dv_mps.iter().zip(want_dv).all(|(a, b)| close(*a, b))
        && s.dtheta_rad.iter().zip(want_dth).all(|(a, b)| close(*a, b))
        && close(s.temperature_c, 1325.0 / 132.48 + 25.0);
    check("icm42688 burst read -> FRD increments", pass);
    ok
}

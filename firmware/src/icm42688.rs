//! Register-level driver of the TDK InvenSense ICM-42688-P 6-axis MEMS IMU over an
//! `embedded_hal::spi::SpiDevice` (SPI mode 0 or 3, up to 24 MHz; chip select handled by the
//! `SpiDevice`). It configures low-noise mode, full scale and output data rate, and reads the
//! temperature, accelerometer and gyro registers (0x1D..=0x2A, 14 bytes, big-endian) in one
//! burst into an [`ImuSample`] of increments over the sample interval.
//!
//! Register map (datasheet DS-000347, user bank 0): DEVICE_CONFIG 0x11 (bit 0 soft reset),
//! TEMP_DATA1 0x1D, INT_STATUS 0x2D (bit 3 data ready), PWR_MGMT0 0x4E, GYRO_CONFIG0 0x4F
//! (FS_SEL bits 7:5, ODR bits 3:0), ACCEL_CONFIG0 0x50, WHO_AM_I 0x75 (reads 0x47),
//! REG_BANK_SEL 0x76. A read sets bit 7 of the address.

use embedded_hal::spi::SpiDevice;
use nav_core::types::ImuSample;

/// DEVICE_CONFIG register.
pub const REG_DEVICE_CONFIG: u8 = 0x11;
/// First data register (TEMP_DATA1); the burst runs to GYRO_DATA_Z0 (0x2A).
pub const REG_TEMP_DATA1: u8 = 0x1D;
/// INT_STATUS register.
pub const REG_INT_STATUS: u8 = 0x2D;
/// PWR_MGMT0 register.
pub const REG_PWR_MGMT0: u8 = 0x4E;
/// GYRO_CONFIG0 register.
pub const REG_GYRO_CONFIG0: u8 = 0x4F;
/// ACCEL_CONFIG0 register.
pub const REG_ACCEL_CONFIG0: u8 = 0x50;
/// WHO_AM_I register.
pub const REG_WHO_AM_I: u8 = 0x75;
/// REG_BANK_SEL register.
pub const REG_BANK_SEL: u8 = 0x76;
/// WHO_AM_I value of the ICM-42688-P.
pub const WHO_AM_I_VALUE: u8 = 0x47;
/// INT_STATUS data-ready bit.
pub const INT_STATUS_DATA_RDY: u8 = 1 << 3;
/// Bytes of the data burst (temperature, 3 accelerometer, 3 gyro axes; 2 bytes each).
pub const BURST_LEN: usize = 14;
const READ: u8 = 0x80;

/// Output data rate (register code).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Odr {
    /// 1 kHz.
    Hz1000 = 0x06,
    /// 200 Hz.
    Hz200 = 0x07,
    /// 100 Hz.
    Hz100 = 0x08,
}

impl Odr {
    /// The rate, Hz.
    pub fn hz(self) -> f64 {
        match self {
            Self::Hz1000 => 1000.0,
            Self::Hz200 => 200.0,
            Self::Hz100 => 100.0,
        }
    }
}

/// Gyro full scale (register code) with its sensitivity.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GyroRange {
    /// +-2000 deg/s, 16.4 LSB/(deg/s).
    Dps2000 = 0,
    /// +-1000 deg/s, 32.8 LSB/(deg/s).
    Dps1000 = 1,
    /// +-500 deg/s, 65.5 LSB/(deg/s).
    Dps500 = 2,
    /// +-250 deg/s, 131 LSB/(deg/s).
    Dps250 = 3,
}

impl GyroRange {
    /// Sensitivity, LSB per deg/s.
    pub fn lsb_per_dps(self) -> f64 {
        match self {
            Self::Dps2000 => 16.4,
            Self::Dps1000 => 32.8,
            Self::Dps500 => 65.5,
            Self::Dps250 => 131.0,
        }
    }
}

/// Accelerometer full scale (register code) with its sensitivity.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AccelRange {
    /// +-16 g, 2048 LSB/g.
    G16 = 0,
    /// +-8 g, 4096 LSB/g.
    G8 = 1,
    /// +-4 g, 8192 LSB/g.
    G4 = 2,
    /// +-2 g, 16384 LSB/g.
    G2 = 3,
}

impl AccelRange {
    /// Sensitivity, LSB per g.
    pub fn lsb_per_g(self) -> f64 {
        match self {
            Self::G16 => 2048.0,
            Self::G8 => 4096.0,
            Self::G4 => 8192.0,
            Self::G2 => 16384.0,
        }
    }
}

/// Mounting of the chip: body FRD axis i is `sign[i]` times chip axis `axis[i]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AxisMap {
    /// Chip axis (0 x, 1 y, 2 z) for body forward, right, down.
    pub axis: [u8; 3],
    /// Sign (+1 or -1) per body axis.
    pub sign: [i8; 3],
}

impl AxisMap {
    /// Chip x forward, y left, z up (component side up, x to the front): FRD = (x, -y, -z).
    pub const X_FORWARD_Z_UP: Self = Self {
        axis: [0, 1, 2],
        sign: [1, -1, -1],
    };

    fn apply(&self, v: [f64; 3]) -> [f64; 3] {
        let mut out = [0.0; 3];
        for ((o, &a), &s) in out.iter_mut().zip(&self.axis).zip(&self.sign) {
            *o = f64::from(s) * v.get(usize::from(a)).copied().unwrap_or(0.0);
        }
        out
    }
}

/// Driver settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Config {
    /// Output data rate of both sensors.
    pub odr: Odr,
    /// Gyro full scale.
    pub gyro_range: GyroRange,
    /// Accelerometer full scale.
    pub accel_range: AccelRange,
    /// Mounting.
    pub axes: AxisMap,
}

impl Default for Config {
    /// 200 Hz, +-2000 deg/s, +-16 g, chip x forward and z up.
    fn default() -> Self {
        Self {
            odr: Odr::Hz200,
            gyro_range: GyroRange::Dps2000,
            accel_range: AccelRange::G16,
            axes: AxisMap::X_FORWARD_Z_UP,
        }
    }
}

/// Errors of the driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error<E> {
    /// The SPI bus failed.
    Spi(E),
    /// WHO_AM_I did not read 0x47: no ICM-42688-P on this chip select.
    WrongId(u8),
}

impl<E: core::fmt::Debug> core::fmt::Display for Error<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Spi(e) => write!(f, "icm42688: SPI error {e:?}"),
            Self::WrongId(id) => write!(
                f,
                "icm42688: WHO_AM_I reads {id:#04x}, expected {WHO_AM_I_VALUE:#04x}"
            ),
        }
    }
}

impl<E: core::fmt::Debug> core::error::Error for Error<E> {}

/// One burst in physical units, chip axes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Raw {
    /// Specific force, m/s^2 (chip axes).
    pub accel_mps2: [f64; 3],
    /// Angular rate, rad/s (chip axes).
    pub gyro_radps: [f64; 3],
    /// Die temperature, degrees Celsius.
    pub temperature_c: f64,
}

/// The ICM-42688-P on an SPI device.
pub struct Icm42688<S> {
    spi: S,
    cfg: Config,
}

/// Standard gravity used by the datasheet's g unit, m/s^2.
const G_MPS2: f64 = 9.806_65;

impl<S: SpiDevice> Icm42688<S> {
    /// Checks WHO_AM_I, soft-resets, and configures both sensors in low-noise mode at the
    /// given rate and ranges. The caller waits >= 1 ms after power-up before calling and
    /// >= 45 ms after it before the first read (gyro start-up).
    pub fn new(spi: S, cfg: Config) -> Result<Self, Error<S::Error>> {
        let mut d = Self { spi, cfg };
        d.write(REG_BANK_SEL, 0)?;
        let id = d.read(REG_WHO_AM_I)?;
        if id != WHO_AM_I_VALUE {
            return Err(Error::WrongId(id));
        }
        d.write(REG_DEVICE_CONFIG, 0x01)?;
        d.write(REG_BANK_SEL, 0)?;
        d.write(
            REG_GYRO_CONFIG0,
            ((cfg.gyro_range as u8) << 5) | cfg.odr as u8,
        )?;
        d.write(
            REG_ACCEL_CONFIG0,
            ((cfg.accel_range as u8) << 5) | cfg.odr as u8,
        )?;
        // gyro and accelerometer in low-noise mode
        d.write(REG_PWR_MGMT0, 0x0F)?;
        Ok(d)
    }

    /// The settings.
    pub fn config(&self) -> &Config {
        &self.cfg
    }

    /// Gives the SPI device back.
    pub fn release(self) -> S {
        self.spi
    }

    /// Reads one register.
    pub fn read(&mut self, reg: u8) -> Result<u8, Error<S::Error>> {
        let mut buf = [reg | READ, 0];
        self.spi.transfer_in_place(&mut buf).map_err(Error::Spi)?;
        Ok(buf[1])
    }

    /// Writes one register.
    pub fn write(&mut self, reg: u8, value: u8) -> Result<(), Error<S::Error>> {
        self.spi.write(&[reg & !READ, value]).map_err(Error::Spi)
    }

    /// Whether a new sample is ready (INT_STATUS data-ready bit; reading clears it).
    pub fn data_ready(&mut self) -> Result<bool, Error<S::Error>> {
        Ok(self.read(REG_INT_STATUS)? & INT_STATUS_DATA_RDY != 0)
    }

    /// Reads the data registers in one burst and converts them to physical units.
    pub fn read_raw(&mut self) -> Result<Raw, Error<S::Error>> {
        let mut buf = [0u8; 1 + BURST_LEN];
        buf[0] = REG_TEMP_DATA1 | READ;
        self.spi.transfer_in_place(&mut buf).map_err(Error::Spi)?;
        let w = |i: usize| -> f64 {
            let hi = buf.get(1 + 2 * i).copied().unwrap_or(0);
            let lo = buf.get(2 + 2 * i).copied().unwrap_or(0);
            f64::from(i16::from_be_bytes([hi, lo]))
        };
        let a = G_MPS2 / self.cfg.accel_range.lsb_per_g();
        let g = core::f64::consts::PI / 180.0 / self.cfg.gyro_range.lsb_per_dps();
        Ok(Raw {
            temperature_c: w(0) / 132.48 + 25.0,
            accel_mps2: [w(1) * a, w(2) * a, w(3) * a],
            gyro_radps: [w(4) * g, w(5) * g, w(6) * g],
        })
    }

    /// Reads one sample as increments over the interval (t_s - dt_s, t_s] in body FRD axes
    /// (rectangle rule: the chip outputs filtered rates, not increments).
    pub fn read_sample(&mut self, t_s: f64, dt_s: f64) -> Result<ImuSample, Error<S::Error>> {
        let r = self.read_raw()?;
        let gyro = self.cfg.axes.apply(r.gyro_radps);
        let accel = self.cfg.axes.apply(r.accel_mps2);
        Ok(ImuSample {
            t_s,
            dtheta_rad: gyro.map(|v| v * dt_s),
            dv_mps: accel.map(|v| v * dt_s),
            temperature_c: r.temperature_c,
        })
    }
}

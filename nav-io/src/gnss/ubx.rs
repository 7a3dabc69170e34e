//! u-blox UBX NAV-PVT (class 0x01, id 0x07, 92 bytes) to [`GnssFix`], using the `ublox` crate.
//!
//! Mapping: `t_s = iTOW / 1000` (GPS time of week of the navigation epoch, s); latitude and
//! longitude from 1e-7 deg; height above the ellipsoid from mm; NED velocity from mm/s.
//! Standard deviations: `hAcc` for north and east and `vAcc` for down (u-blox's accuracy
//! estimates; `hAcc` is a horizontal radius, so using it per axis is conservative by up to
//! sqrt(2)); `sAcc` for each velocity axis. Quality: no `gnssFixOK` flag, or a fix type other
//! than 3-D / GNSS+DR, gives `NoFix` (a 2-D fix has an assumed height); otherwise carrier
//! fixed -> `RtkFixed`, carrier float -> `RtkFloat`, differential -> `Dgnss`, else `Single`.

use nav_core::types::{FixQuality, GnssFix};
use ublox::nav_pvt::common::{NavPvtFlags, NavPvtValidFlags};
use ublox::nav_pvt::proto23::NavPvtRef;
use ublox::proto23::PacketRef;
use ublox::{GnssFixType, UbxPacket};

/// The fix in a UBX packet, `None` when the packet is not NAV-PVT.
pub fn fix_from_packet(p: &UbxPacket<'_>) -> Option<GnssFix> {
    match p {
        UbxPacket::Proto23(PacketRef::NavPvt(pvt)) => Some(fix_from_nav_pvt(pvt)),
        _ => None,
    }
}

/// A UTC calendar time: (year, month, day, hour, minute, second with the fraction).
pub type UtcTime = (i32, u32, u32, u32, u32, f64);

/// The UTC date and time of a NAV-PVT packet, (year, month, day, hour, minute, second with
/// the fraction), when the receiver flags both the date and the time valid.
pub fn utc_of_nav_pvt(p: &NavPvtRef<'_>) -> Option<UtcTime> {
    let v = p.valid();
    if !(v.contains(NavPvtValidFlags::VALID_DATE) && v.contains(NavPvtValidFlags::VALID_TIME)) {
        return None;
    }
    Some((
        i32::from(p.year()),
        u32::from(p.month()),
        u32::from(p.day()),
        u32::from(p.hour()),
        u32::from(p.min()),
        f64::from(p.sec()) + f64::from(p.nanosec()) * 1e-9,
    ))
}

/// Maps a NAV-PVT packet (see the module doc).
pub fn fix_from_nav_pvt(p: &NavPvtRef<'_>) -> GnssFix {
    let flags = p.flags();
    let fix_type = p.fix_type();
    let usable = flags.contains(NavPvtFlags::GPS_FIX_OK)
        && matches!(
            fix_type,
            GnssFixType::Fix3D | GnssFixType::GPSPlusDeadReckoning
        );
    let quality = if !usable {
        FixQuality::NoFix
    } else if flags.contains(NavPvtFlags::CARR_SOLN_FIXED) {
        FixQuality::RtkFixed
    } else if flags.contains(NavPvtFlags::CARR_SOLN_FLOAT) {
        FixQuality::RtkFloat
    } else if flags.contains(NavPvtFlags::DIFF_SOLN) {
        FixQuality::Dgnss
    } else {
        FixQuality::Single
    };
    let h_acc = p.horizontal_accuracy();
    let v_acc = p.vertical_accuracy();
    let s_acc = p.speed_accuracy();
    GnssFix {
        t_s: f64::from(p.itow()) / 1000.0,
        lat_rad: p.latitude().to_radians(),
        lon_rad: p.longitude().to_radians(),
        h_m: p.height_above_ellipsoid(),
        pos_std_ned_m: [h_acc, h_acc, v_acc],
        vel_ned_mps: [p.vel_north(), p.vel_east(), p.vel_down()],
        vel_std_ned_mps: [s_acc, s_acc, s_acc],
        has_velocity: usable,
        quality,
        num_sats: p.num_satellites(),
    }
}

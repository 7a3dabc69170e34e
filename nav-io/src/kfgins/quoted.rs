//! Numbers of a KF-GINS YAML written as numbers or as quoted strings: KF-GINS reads its
//! configuration with yaml-cpp, whose `as<double>()` / `as<int>()` convert a scalar's text
//! whether it was quoted or not (`imudatarate: "200"`, `initpos: ["30.1", ...]`). A string
//! that is not a number is refused, and the YAML parser names its key, line and column.

use serde::de::{Deserializer, Error, Unexpected, Visitor};
use std::fmt;

/// A number given plain or quoted.
struct Num(f64);

struct NumVisitor;

impl Visitor<'_> for NumVisitor {
    type Value = Num;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a number (plain or quoted)")
    }

    fn visit_f64<E: Error>(self, v: f64) -> Result<Num, E> {
        Ok(Num(v))
    }

    fn visit_i64<E: Error>(self, v: i64) -> Result<Num, E> {
        Ok(Num(v as f64))
    }

    fn visit_u64<E: Error>(self, v: u64) -> Result<Num, E> {
        Ok(Num(v as f64))
    }

    fn visit_str<E: Error>(self, v: &str) -> Result<Num, E> {
        let t = v.trim();
        // YAML's own spellings of the special values, as a plain scalar would read
        let special = match t {
            ".nan" | ".NaN" | ".NAN" => Some(f64::NAN),
            ".inf" | ".Inf" | ".INF" | "+.inf" | "+.Inf" | "+.INF" => Some(f64::INFINITY),
            "-.inf" | "-.Inf" | "-.INF" => Some(f64::NEG_INFINITY),
            _ => None,
        };
        special
            .or_else(|| crate::parse_f64(t))
            .map(Num)
            .ok_or_else(|| E::invalid_value(Unexpected::Str(v), &self))
    }
}

impl<'de> serde::Deserialize<'de> for Num {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(NumVisitor)
    }
}

/// A number, plain or quoted.
pub(super) fn f64<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    <Num as serde::Deserialize>::deserialize(d).map(|n| n.0)
}

/// Three numbers, each plain or quoted.
pub(super) fn f64x3<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
    <[Num; 3] as serde::Deserialize>::deserialize(d).map(|v| v.map(|n| n.0))
}

/// Three numbers, each plain or quoted, when the key is given.
pub(super) fn opt_f64x3<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[f64; 3]>, D::Error> {
    <Option<[Num; 3]> as serde::Deserialize>::deserialize(d).map(|o| o.map(|v| v.map(|n| n.0)))
}

/// A non-negative integer, plain or quoted (a quoted one written as an integer).
pub(super) fn u32<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
    struct U32Visitor;
    impl Visitor<'_> for U32Visitor {
        type Value = u32;

        fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
            f.write_str("a non-negative integer (plain or quoted)")
        }

        fn visit_u64<E: Error>(self, v: u64) -> Result<u32, E> {
            u32::try_from(v).map_err(|_| E::invalid_value(Unexpected::Unsigned(v), &self))
        }

        fn visit_i64<E: Error>(self, v: i64) -> Result<u32, E> {
            u32::try_from(v).map_err(|_| E::invalid_value(Unexpected::Signed(v), &self))
        }

        fn visit_f64<E: Error>(self, v: f64) -> Result<u32, E> {
            Err(E::invalid_type(Unexpected::Float(v), &self))
        }

        fn visit_str<E: Error>(self, v: &str) -> Result<u32, E> {
            v.trim()
                .parse()
                .map_err(|_| E::invalid_value(Unexpected::Str(v), &self))
        }
    }
    d.deserialize_any(U32Visitor)
}

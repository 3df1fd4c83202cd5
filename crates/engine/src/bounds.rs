//! The named bounds every number from outside (plans, station configs) is
//! checked against before anything is allocated or moved in proportion to
//! it: finite, of the right sign, and within a bound whose name the error
//! gives, so the user can see which limit was hit.

use std::ops::RangeInclusive;

/// Highest range or level of a plan [g] (well above any centrifuge test of
/// a VBA; the station's rate limit and fixtures' rating are checked after).
pub const MAX_LEVEL_G: f64 = 1_000.0;
/// Most levels in a plan.
pub const MAX_LEVELS: usize = 500;
/// Most levels a plan's `[sequential]` adds per mounting.
pub const MAX_SEQUENTIAL_LEVELS: u32 = 50;
/// Longest warm-up [s] (one day).
pub const MAX_WARMUP_S: f64 = 86_400.0;
/// Longest dwell at one level, and the longest adaptive dwell [s] (one hour).
pub const MAX_DWELL_S: u32 = 3_600;
/// Longest hold and the longest wait for stability at a level [s] (one day).
pub const MAX_SETTLE_S: u32 = 86_400;
/// Most restarts of a point after rate excursions.
pub const MAX_RESTARTS: u32 = 1_000;
/// Widest rate tolerance [ppm] (1 %).
pub const MAX_RATE_TOLERANCE_PPM: f64 = 10_000.0;
/// Largest drift, noise and standard-error thresholds [µg] or [µg/s] (1 g).
pub const MAX_UG: f64 = 1e6;
/// Most chamber temperatures in one plan.
pub const MAX_TEMPERATURES: usize = 20;
/// Largest temperature change accepted as a limit [°C].
pub const MAX_TEMPERATURE_CHANGE_C: f64 = 100.0;
/// The instrument temperatures a limit may name [°C] (a VBA's whole range and then some).
pub const INSTRUMENT_TEMPERATURE_RANGE_C: (f64, f64) = (-100.0, 200.0);
/// Largest k2 limit [µg/g²] and other figure limits [ppm, µg].
pub const MAX_FIGURE_LIMIT: f64 = 1e6;
/// Longest serial number, plan name or operator name [characters].
pub const MAX_NAME_CHARS: usize = 200;
/// Highest instrument rail voltage [V].
pub const MAX_RAIL_V: f64 = 60.0;
/// Highest rail current limit [A].
pub const MAX_RAIL_A: f64 = 20.0;
/// Highest current one instrument may draw [A].
pub const MAX_INSTRUMENT_A: f64 = 1.0;
/// Longest arm radius [m].
pub const MAX_ARM_RADIUS_M: f64 = 10.0;
/// Highest fixture rating [g].
pub const MAX_ARM_G: f64 = 10_000.0;
/// Most counter modules on one station.
pub const MAX_MODULES: usize = 64;

/// Why a number from outside was refused: what was given and what is
/// allowed, naming the bound.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BoundError {
    /// Not a finite number (NaN or infinite).
    #[error("{value} is not a number; give a finite value from {min} to {max} {unit}")]
    NotFinite {
        /// The value given.
        value: f64,
        /// The lowest allowed.
        min: f64,
        /// The highest allowed.
        max: f64,
        /// Its unit.
        unit: String,
    },
    /// Outside the named bound.
    #[error("{value} {unit} is outside {min} to {max} {unit} ({bound})")]
    Outside {
        /// The value given.
        value: f64,
        /// The lowest allowed.
        min: f64,
        /// The highest allowed.
        max: f64,
        /// Its unit.
        unit: String,
        /// The bound's name (`MAX_LEVEL_G`).
        bound: String,
    },
    /// Zero or below where only a value above zero will do.
    #[error("{value} {unit}: must be above 0")]
    NotPositive {
        /// The value given.
        value: f64,
        /// Its unit.
        unit: String,
    },
}

/// Why a text typed by a person was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TextError {
    /// A name holds a control or format character.
    #[error("'{shown}' holds an invisible character U+{code:04X}; type it again without it")]
    InvisibleInName {
        /// The name as shown ([`shown`]).
        shown: String,
        /// The character's code point.
        code: u32,
    },
    /// A reason is empty or too long.
    #[error("say why in 1 to {max_chars} characters")]
    ReasonLength {
        /// The most characters allowed.
        max_chars: usize,
    },
    /// A reason holds a control or format character.
    #[error(
        "'{shown}' holds a control or invisible character U+{code:04X}; type it again without it"
    )]
    InvisibleInReason {
        /// The reason as shown ([`shown`]).
        shown: String,
        /// The character's code point.
        code: u32,
    },
}

/// Check that `value` is finite and inside `range` (bounds named `bound`),
/// in `unit`; the error says what was given and what is allowed.
pub fn check(
    value: f64,
    range: RangeInclusive<f64>,
    unit: &str,
    bound: &str,
) -> Result<(), BoundError> {
    if !value.is_finite() {
        return Err(BoundError::NotFinite {
            value,
            min: *range.start(),
            max: *range.end(),
            unit: unit.to_string(),
        });
    }
    if !range.contains(&value) {
        return Err(BoundError::Outside {
            value,
            min: *range.start(),
            max: *range.end(),
            unit: unit.to_string(),
            bound: bound.to_string(),
        });
    }
    Ok(())
}

/// As [`check`], for a value that must be above zero (zero excluded).
pub fn check_positive(value: f64, max: f64, unit: &str, bound: &str) -> Result<(), BoundError> {
    check(value, 0.0..=max, unit, bound)?;
    if value <= 0.0 {
        return Err(BoundError::NotPositive {
            value,
            unit: unit.to_string(),
        });
    }
    Ok(())
}

/// Whether `c` is a control or format character (a line break, a NUL, a
/// zero-width space, a right-to-left override): never shown or kept as is.
pub fn is_invisible(c: char) -> bool {
    use unicode_general_category::{GeneralCategory, get_general_category};
    c.is_control() || get_general_category(c) == GeneralCategory::Format
}

/// A name from outside shortened for an error message or the audit log
/// (at most 60 characters), its control and format characters written as
/// escapes (`adm\u{a}FORGED`), so it cannot forge a line or reorder text.
pub fn shown(name: &str) -> String {
    const SHOWN: usize = 60;
    let mut chars = name.chars();
    let head: String = chars
        .by_ref()
        .take(SHOWN)
        .map(|c| {
            if is_invisible(c) {
                c.escape_unicode().to_string()
            } else {
                c.to_string()
            }
        })
        .collect();
    if chars.next().is_some() {
        format!("{head}… ({} characters)", name.chars().count())
    } else {
        head
    }
}

/// The longest device identity kept of a device's reply [characters].
pub const MAX_DEVICE_IDENTITY_CHARS: usize = 200;

/// What a device answered of itself (`*IDN?`, a firmware id), as it is
/// stored and shown: NFKC-normalised and trimmed, every control or format
/// character written as an escape (an escape sequence, a NUL, a
/// right-to-left override cannot reach a terminal, a report or the
/// register's comparison as such), at most [`MAX_DEVICE_IDENTITY_CHARS`].
/// A device's reply is never refused: it is what the device said.
pub fn device_reply(text: &str) -> String {
    use unicode_normalization::UnicodeNormalization;
    let normal: String = text.nfkc().collect();
    let escaped: String = normal
        .trim()
        .chars()
        .map(|c| {
            if is_invisible(c) {
                c.escape_unicode().to_string()
            } else {
                c.to_string()
            }
        })
        .collect();
    let count = escaped.chars().count();
    if count > MAX_DEVICE_IDENTITY_CHARS {
        let head: String = escaped.chars().take(MAX_DEVICE_IDENTITY_CHARS).collect();
        format!("{head}… ({count} characters)")
    } else {
        escaped
    }
}

/// A name typed by a person (a serial number, a device's identity) as it is
/// compared and kept: NFKC-normalised (a fullwidth `Ａ` is `A`) and
/// trimmed; refused, naming the character, when it holds a format
/// character (a zero-width space, a right-to-left override) or a control
/// character, which would let two look-alike names sit side by side.
pub fn person_text(text: &str) -> Result<String, TextError> {
    use unicode_normalization::UnicodeNormalization;
    if let Some(c) = text.chars().find(|&c| is_invisible(c)) {
        return Err(TextError::InvisibleInName {
            shown: shown(text),
            code: u32::from(c),
        });
    }
    Ok(text.nfkc().collect::<String>().trim().to_string())
}

/// A reason typed by a person (an exclusion, an override) as kept: 1 to
/// `max_chars` characters once trimmed, no control or format character.
pub fn reason_text(text: &str, max_chars: usize) -> Result<String, TextError> {
    let trimmed = text.trim();
    if trimmed.is_empty() || trimmed.chars().count() > max_chars {
        return Err(TextError::ReasonLength { max_chars });
    }
    if let Some(c) = trimmed.chars().find(|&c| is_invisible(c)) {
        return Err(TextError::InvisibleInReason {
            shown: shown(trimmed),
            code: u32::from(c),
        });
    }
    Ok(trimmed.to_string())
}

/// Why a serial is refused for mixing scripts (Latin with Cyrillic or
/// Greek letters, as `SN-А1` with a Cyrillic А), if it does (UTS #39's
/// single-script rule, by the `unicode-security` crate).
pub fn mixed_script(serial: &str) -> Option<String> {
    use unicode_security::MixedScript;
    (!serial.is_single_script()).then(|| {
        format!(
            "'{serial}' mixes letters of several scripts ({}); type it again from its label",
            non_ascii(serial)
        )
    })
}

/// Whether two different texts look alike (the same UTS #39 skeleton, as
/// `SN-A1` and `SN-А1`).
pub fn look_alike(a: &str, b: &str) -> bool {
    a != b && unicode_security::skeleton(a).eq(unicode_security::skeleton(b))
}

/// The characters of `text` beyond ASCII, named by code point (`А U+0410`).
pub fn non_ascii(text: &str) -> String {
    let named: Vec<String> = text
        .chars()
        .filter(|c| !c.is_ascii())
        .map(|c| format!("{c} U+{:04X}", u32::from(c)))
        .collect();
    if named.is_empty() {
        "ASCII only".into()
    } else {
        named.join(", ")
    }
}

/// True for a run identifier as runs are named: 1 to 64 ASCII letters,
/// digits, `-` or `_` (nothing a path or a query could be made of).
pub fn is_run_id(id: &str) -> bool {
    (1..=64).contains(&id.len())
        && id
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_negative_and_huge_values_are_refused_with_the_bound() {
        assert!(matches!(
            check(f64::NAN, 0.0..=1.0, "s", "B"),
            Err(BoundError::NotFinite { .. })
        ));
        assert!(check(f64::INFINITY, 0.0..=1.0, "s", "B").is_err());
        let e = check(2.0, 0.0..=1.0, "s", "MAX_B").expect_err("above");
        assert!(matches!(&e, BoundError::Outside { bound, .. } if bound == "MAX_B"));
        // The words a user reads are the ones before the type.
        assert_eq!(e.to_string(), "2 s is outside 0 to 1 s (MAX_B)");
        assert_eq!(
            check_positive(0.0, 1.0, "A", "B"),
            Err(BoundError::NotPositive {
                value: 0.0,
                unit: "A".into()
            })
        );
        assert!(check_positive(0.5, 1.0, "A", "B").is_ok());
        assert_eq!(shown("abc"), "abc");
        assert_eq!(shown("adm\nFORGED"), "adm\\u{a}FORGED");
        assert!(shown("station\u{202E}A").contains("\\u{202e}"));
        assert!(reason_text("ok\u{200B}", 10).is_err());
        assert_eq!(
            device_reply(" FMU\u{1b}[2J-8\u{202e}\u{0} "),
            "FMU\\u{1b}[2J-8\\u{202e}\\u{0}"
        );
        assert_eq!(device_reply("ＡＣＵＴＲＯＬ,3000"), "ACUTROL,3000");
        assert!(device_reply(&"x".repeat(500)).ends_with("(500 characters)"));
        assert_eq!(
            reason_text("  ", 10),
            Err(TextError::ReasonLength { max_chars: 10 })
        );
        assert_eq!(reason_text(" ok ", 10).as_deref(), Ok("ok"));
        assert!(mixed_script("SN-\u{0410}1").is_some());
        assert!(mixed_script("SN-A1").is_none());
        assert!(mixed_script("批次-7").is_none());
        assert!(look_alike("SN-A1", "SN-\u{0410}1"));
        assert!(!look_alike("SN-A1", "SN-A2"));
        assert!(shown(&"x".repeat(1000)).ends_with("(1000 characters)"));
    }
}

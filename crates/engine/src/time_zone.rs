//! The station's time zone: a fixed offset from UTC (`time_zone =
//! "UTC+08:00"` in station.toml), in which its pages and reports show
//! times, the zone said beside them. A fixed offset, not
//! a zone database name: the stations this serves keep one offset all year
//! (China has no daylight saving), and a database would have to be kept up
//! to date on every station PC.

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// The widest offsets in use on Earth [min]: UTC−12:00 to UTC+14:00.
const LOWEST_MIN: i32 = -12 * 60;
const HIGHEST_MIN: i32 = 14 * 60;

/// A fixed offset from UTC, whole quarter hours.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct UtcOffset {
    minutes: i32,
}

/// A time zone that is not an offset from UTC this station takes.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "time_zone = '{0}': write an offset from UTC as UTC+HH:MM (UTC+08:00 for China), from UTC-12:00 to UTC+14:00 in quarter hours, or UTC"
)]
pub struct NotAnOffset(pub String);

impl UtcOffset {
    /// UTC itself.
    pub const UTC: UtcOffset = UtcOffset { minutes: 0 };

    /// Minutes east of UTC.
    pub fn minutes(self) -> i32 {
        self.minutes
    }

    /// Seconds east of UTC.
    pub fn seconds(self) -> i64 {
        i64::from(self.minutes) * 60
    }

    /// Read `UTC`, `UTC+08:00`, `+08:00`, `UTC-05:30` or `UTC+8`; the
    /// error says what is accepted.
    pub fn parse(text: &str) -> Result<UtcOffset, NotAnOffset> {
        let bad = || NotAnOffset(text.to_string());
        let t = text.trim();
        let rest = t.strip_prefix("UTC").unwrap_or(t);
        if rest.is_empty() {
            return Ok(UtcOffset::UTC);
        }
        let (sign, digits) = match rest.as_bytes().first() {
            Some(b'+') => (1, &rest[1..]),
            Some(b'-') => (-1, &rest[1..]),
            _ => return Err(bad()),
        };
        let (hours, minutes) = match digits.split_once(':') {
            Some((h, m)) => (h, m),
            None => (digits, "0"),
        };
        let number = |s: &str| {
            (!s.is_empty() && s.len() <= 2 && s.bytes().all(|b| b.is_ascii_digit()))
                .then(|| s.parse::<i32>().ok())
                .flatten()
        };
        let (Some(h), Some(m)) = (number(hours), number(minutes)) else {
            return Err(bad());
        };
        let total = sign * (h * 60 + m);
        if m >= 60 || m % 15 != 0 || !(LOWEST_MIN..=HIGHEST_MIN).contains(&total) {
            return Err(bad());
        }
        Ok(UtcOffset { minutes: total })
    }
}

impl std::fmt::Display for UtcOffset {
    /// `UTC` or `UTC+08:00`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.minutes == 0 {
            return f.write_str("UTC");
        }
        let sign = if self.minutes < 0 { '-' } else { '+' };
        let m = self.minutes.abs();
        write!(f, "UTC{sign}{:02}:{:02}", m / 60, m % 60)
    }
}

impl Serialize for UtcOffset {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.to_string())
    }
}

impl<'de> Deserialize<'de> for UtcOffset {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        UtcOffset::parse(&text).map_err(serde::de::Error::custom)
    }
}

/// The `time_zone` of a station config's text, read alone (a config
/// another release wrote, with keys this one does not know, still says its
/// zone); UTC when the text names none. The error when it names one this
/// release cannot read.
pub fn of_station_config(text: &str) -> Result<UtcOffset, NotAnOffset> {
    let table: toml::Table = match toml::from_str(text) {
        Ok(t) => t,
        Err(_) => return Err(NotAnOffset("(the station config is not TOML)".into())),
    };
    match table.get("time_zone") {
        None => Ok(UtcOffset::UTC),
        Some(toml::Value::String(zone)) => UtcOffset::parse(zone),
        Some(other) => Err(NotAnOffset(other.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_read_and_are_said_the_same_way() {
        for (text, minutes, said) in [
            ("UTC", 0, "UTC"),
            ("UTC+08:00", 480, "UTC+08:00"),
            ("+8", 480, "UTC+08:00"),
            ("UTC-05:30", -330, "UTC-05:30"),
            ("UTC+14:00", 840, "UTC+14:00"),
            ("UTC-12:00", -720, "UTC-12:00"),
        ] {
            let z = UtcOffset::parse(text).expect(text);
            assert_eq!(
                (z.minutes(), z.to_string().as_str()),
                (minutes, said),
                "{text}"
            );
        }
        for bad in [
            "UTC+15:00",
            "UTC-12:15",
            "UTC+08:07",
            "Asia/Shanghai",
            "UTC+8:60",
            "UTC+",
            "UTC+123",
            "",
        ] {
            if bad.is_empty() {
                continue;
            }
            let e = UtcOffset::parse(bad).expect_err(bad);
            assert_eq!(e, NotAnOffset(bad.to_string()));
            assert!(e.to_string().contains("UTC+08:00 for China"), "{e}");
        }
    }
}

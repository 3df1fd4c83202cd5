//! Small text helpers every report shares: HTML escaping, CSV fields,
//! numbers to a fixed number of decimals, civil dates.

/// Escape text for HTML. Five replacements: no crate needed for this.
pub(crate) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&#39;")
}

pub(crate) fn csv_field(s: &str) -> String {
    spinbench_store::csv_text_field(s)
}

pub(crate) fn fmt(v: Option<f64>, decimals: usize) -> String {
    v.map_or("—".into(), |v| format!("{v:.decimals$}"))
}

pub(crate) fn unix_date(t: i64) -> String {
    let secs = t.rem_euclid(86_400);
    format!(
        "{} {:02}:{:02} UTC",
        spinbench_store::equipment::civil_date(t),
        secs / 3600,
        secs % 3600 / 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn html_text_is_escaped_and_dates_are_civil() {
        assert_eq!(esc("<a&'\">"), "&lt;a&amp;&#39;&quot;&gt;");
        assert_eq!(unix_date(0), "1970-01-01 00:00 UTC");
        assert_eq!(unix_date(1_795_277_084), "2026-11-21 16:04 UTC");
        assert_eq!(unix_date(951_782_400), "2000-02-29 00:00 UTC");
    }
}

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

/// The CSS family name of the embedded CJK font, listed in every HTML
/// report's `font-family` after the system fonts.
pub(crate) const CJK_FAMILY: &str = "spinbench CJK";

/// Put the embedded font, cut down to the Chinese, Japanese and full-width
/// characters of `html`, into its style (at the `/*CJK*/` mark) as a data
/// URL: the self-contained report shows Chinese on a machine with no CJK
/// font. A report without such characters carries none.
pub(crate) fn with_cjk_font(html: String) -> String {
    use base64::Engine;
    let cjk = |c: &char| matches!(*c as u32, 0x2E80..=0x9FFF | 0xFF00..=0xFFEF);
    let chars: String = html
        .chars()
        .filter(cjk)
        .collect::<std::collections::BTreeSet<char>>()
        .into_iter()
        .collect();
    let face = if chars.is_empty() {
        String::new()
    } else {
        crate::web_font(&chars).map_or_else(
            |_| String::new(),
            |font| {
                format!(
                    "@font-face{{font-family:'{CJK_FAMILY}';src:url(data:font/ttf;base64,{}) format('truetype');unicode-range:U+2E80-9FFF,U+FF00-FFEF}}",
                    base64::engine::general_purpose::STANDARD.encode(font)
                )
            },
        )
    };
    html.replacen("/*CJK*/", &face, 1)
}

/// An HTML table with `id`: its headers, then its rows, every cell escaped
/// (the batch report's and its control charts' tables).
pub(crate) fn html_table<S: AsRef<str>>(
    h: &mut String,
    id: &str,
    headers: &[S],
    rows: &[Vec<String>],
) {
    h.push_str(&format!("<table id=\"{id}\"><tr>"));
    for head in headers {
        h.push_str(&format!("<th>{}</th>", esc(head.as_ref())));
    }
    h.push_str("</tr>\n");
    for row in rows {
        h.push_str("<tr>");
        for cell in row {
            h.push_str(&format!("<td>{}</td>", esc(cell)));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
}

pub(crate) fn csv_field(s: &str) -> String {
    spinbench_store::csv_text_field(s)
}

pub(crate) fn fmt(v: Option<f64>, decimals: usize) -> String {
    v.map_or("—".into(), |v| format!("{v:.decimals$}"))
}

pub(crate) fn unix_date(t: i64) -> String {
    unix_date_in(t, spinbench_engine::time_zone::UtcOffset::UTC)
}

/// `t` [Unix s] as "YYYY-MM-DD HH:MM" in `zone`, the zone said after it.
pub(crate) fn unix_date_in(t: i64, zone: spinbench_engine::time_zone::UtcOffset) -> String {
    let local = t + zone.seconds();
    let secs = local.rem_euclid(86_400);
    format!(
        "{} {:02}:{:02} {zone}",
        spinbench_store::equipment::civil_date(local),
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
        let china = spinbench_engine::time_zone::UtcOffset::parse("UTC+08:00").expect("zone");
        // 16:04 UTC is past midnight in China: the next day.
        assert_eq!(
            unix_date_in(1_795_277_084 + 4 * 3600, china),
            "2026-11-22 04:04 UTC+08:00"
        );
    }
}

//! The language of a report or a page (issue 16, part 5): English or
//! Simplified Chinese, every word from the one catalogue
//! (`locales/spinbench.yml`, read at compile time by rust-i18n).

/// A language the station speaks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub enum Lang {
    /// English (the default).
    #[default]
    En,
    /// Simplified Chinese (zh-CN).
    ZhCn,
}

impl Lang {
    /// Every language, default first.
    pub const ALL: [Lang; 2] = [Lang::En, Lang::ZhCn];

    /// Its BCP 47 tag, as the catalogue names it.
    pub fn code(self) -> &'static str {
        match self {
            Lang::En => "en",
            Lang::ZhCn => "zh-CN",
        }
    }

    /// A tag as a browser or a user gives it: `en`, `en-GB`, `zh`,
    /// `zh-CN`, `zh-Hans`, `zh-Hans-CN` (case-insensitive); `None` for
    /// another language.
    pub fn parse(tag: &str) -> Option<Lang> {
        let tag = tag.trim().to_ascii_lowercase();
        let primary = tag.split(['-', '_']).next().unwrap_or("");
        match primary {
            "en" => Some(Lang::En),
            // Traditional Chinese is not in the catalogue: not offered as zh-CN.
            "zh" if !(tag.contains("hant") || tag.contains("-tw") || tag.contains("-hk")) => {
                Some(Lang::ZhCn)
            }
            _ => None,
        }
    }

    /// The first language of an HTTP `Accept-Language` header the station
    /// speaks, by the header's q values (English when none is).
    pub fn from_accept_language(header: &str) -> Lang {
        let mut offered: Vec<(f64, usize, Lang)> = header
            .split(',')
            .take(32)
            .enumerate()
            .filter_map(|(i, part)| {
                let mut pieces = part.split(';');
                let lang = Lang::parse(pieces.next()?)?;
                let q = pieces
                    .find_map(|p| p.trim().strip_prefix("q="))
                    .and_then(|q| q.trim().parse::<f64>().ok())
                    .filter(|q| q.is_finite() && (0.0..=1.0).contains(q))
                    .unwrap_or(1.0);
                (q > 0.0).then_some((q, i, lang))
            })
            .collect();
        offered.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        offered.first().map_or(Lang::En, |o| o.2)
    }
}

/// The catalogue's text of `key` in `lang` (the key itself when missing,
/// so a gap shows rather than hides).
pub fn tr(lang: Lang, key: &str) -> String {
    rust_i18n::t!(key, locale = lang.code()).into_owned()
}

/// Every entry of the catalogue whose key starts with `prefix`, in `lang`
/// (the web UI's part: `web.`), as key → text.
pub fn catalogue(lang: Lang, prefix: &str) -> std::collections::BTreeMap<String, String> {
    crate::_rust_i18n_backend()
        .messages_for_locale(lang.code())
        .unwrap_or_default()
        .into_iter()
        .filter(|(k, _)| k.starts_with(prefix))
        .map(|(k, text)| (k.into_owned(), text.into_owned()))
        .collect()
}

/// A table header in `lang` ("radius [m]" → "半径 [m]").
pub fn header(lang: Lang, english: &str) -> String {
    let key = format!("head.{english}");
    let text = tr(lang, &key);
    if text == key {
        english.to_string()
    } else {
        text
    }
}

/// An outcome's word in `lang` (its class in the markup stays the English name).
pub fn outcome(lang: Lang, name: &str) -> String {
    let key = format!("outcome.{name}");
    let text = tr(lang, &key);
    if text == key { name.to_string() } else { text }
}

/// A date and time as `lang` writes it: "2026-11-23 15:11 UTC" or
/// "2026年11月23日 15:11 UTC".
pub fn date_time(lang: Lang, unix_s: i64) -> String {
    match lang {
        Lang::En => crate::unix_date(unix_s),
        Lang::ZhCn => {
            let (y, m, d) = spinbench_store::equipment::civil_from_days(unix_s.div_euclid(86_400));
            let secs = unix_s.rem_euclid(86_400);
            format!(
                "{y}年{m}月{d}日 {:02}:{:02} UTC",
                secs / 3600,
                secs % 3600 / 60
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tags_and_accept_language() {
        assert_eq!(Lang::parse("zh-Hans-CN"), Some(Lang::ZhCn));
        assert_eq!(Lang::parse("ZH_cn"), Some(Lang::ZhCn));
        assert_eq!(Lang::parse("zh-TW"), None);
        assert_eq!(Lang::parse("de"), None);
        assert_eq!(
            Lang::from_accept_language("zh-CN,zh;q=0.9,en;q=0.8"),
            Lang::ZhCn
        );
        assert_eq!(
            Lang::from_accept_language("de-DE, en;q=0.5, zh;q=0.7"),
            Lang::ZhCn
        );
        assert_eq!(Lang::from_accept_language("fr"), Lang::En);
        assert_eq!(Lang::from_accept_language("zh;q=0, en"), Lang::En);
    }

    #[test]
    fn the_catalogue_has_both_languages() {
        assert_eq!(tr(Lang::ZhCn, "report.summary"), "汇总");
        // The web UI's part, complete in both languages.
        let (en, zh) = (catalogue(Lang::En, "web."), catalogue(Lang::ZhCn, "web."));
        assert!(en.len() > 40, "{}", en.len());
        assert_eq!(en.keys().collect::<Vec<_>>(), zh.keys().collect::<Vec<_>>());
        assert_eq!(zh["web.nav.history"], "历史");
        assert_eq!(tr(Lang::En, "report.summary"), "Summary");
        assert_eq!(header(Lang::ZhCn, "radius [m]"), "半径 [m]");
        assert_eq!(header(Lang::ZhCn, "no such header"), "no such header");
        assert_eq!(outcome(Lang::ZhCn, "fail"), "不合格");
        assert_eq!(
            date_time(Lang::ZhCn, 1_795_446_697),
            "2026年11月23日 15:11 UTC"
        );
        assert_eq!(date_time(Lang::En, 1_795_446_697), "2026-11-23 15:11 UTC");
    }
}

//! The language of a report or a page: English or
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

/// The catalogue's `key` in `lang`, or `fallback` when the catalogue has none.
pub fn tr_or(lang: Lang, key: &str, fallback: &str) -> String {
    let text = tr(lang, key);
    if text == key {
        fallback.to_string()
    } else {
        text
    }
}

/// An enum's serde name (`Beyond3Sigma` → `beyond3_sigma`), as the
/// catalogue's keys and the API name it; empty for a value that is not a
/// plain name.
pub fn serde_name(value: impl serde::Serialize) -> String {
    serde_json::to_value(value)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_default()
}

/// A table header in `lang` ("radius [m]" → "半径 [m]").
pub fn header(lang: Lang, english: &str) -> String {
    tr_or(lang, &format!("head.{english}"), english)
}

/// An outcome's word in `lang` (its class in the markup stays the English name).
pub fn outcome(lang: Lang, name: &str) -> String {
    tr_or(lang, &format!("outcome.{name}"), name)
}

/// A date and time as `lang` writes it, in UTC: "2026-11-23 15:11 UTC" or
/// "2026年11月23日 15:11 UTC".
pub fn date_time(lang: Lang, unix_s: i64) -> String {
    date_time_in(lang, unix_s, spinbench_engine::time_zone::UtcOffset::UTC)
}

/// A date and time as `lang` writes it in the station's `zone`, the zone
/// said ("2026年11月23日 23:11 UTC+08:00").
pub fn date_time_in(
    lang: Lang,
    unix_s: i64,
    zone: spinbench_engine::time_zone::UtcOffset,
) -> String {
    match lang {
        Lang::En => crate::unix_date_in(unix_s, zone),
        Lang::ZhCn => {
            let local = unix_s + zone.seconds();
            let (y, m, d) = spinbench_store::equipment::civil_from_days(local.div_euclid(86_400));
            let secs = local.rem_euclid(86_400);
            format!(
                "{y}年{m}月{d}日 {:02}:{:02} {zone}",
                secs / 3600,
                secs % 3600 / 60
            )
        }
    }
}

/// The catalogue's `key` in `lang` filled with `args` (`%{name}` each; a
/// word-valued argument through `arg.<name>.<value>` when the catalogue has
/// it, so `rule = guarded` reads "（保护带判定规则）"); `None` when the
/// catalogue has no such key or a placeholder has no value.
pub fn fill(
    lang: Lang,
    key: &str,
    args: &std::collections::BTreeMap<String, String>,
) -> Option<String> {
    let template = tr(lang, key);
    if template == key {
        return None;
    }
    let mut out = String::with_capacity(template.len() + 32);
    let mut rest = template.as_str();
    while let Some(start) = rest.find("%{") {
        out.push_str(&rest[..start]);
        let after = &rest[start + 2..];
        let end = after.find('}')?;
        let name = &after[..end];
        let value = args.get(name)?;
        let word_key = format!("arg.{name}.{value}");
        let word = tr(lang, &word_key);
        out.push_str(if word == word_key { value } else { &word });
        rest = &after[end + 1..];
    }
    out.push_str(rest);
    Some(out)
}

/// A text of the engine's, given as its wording, in `lang` (the catalogue's
/// `say.<key>`); `None` when the catalogue cannot word it.
pub fn say(lang: Lang, wording: &spinbench_engine::event::Wording) -> Option<String> {
    fill(lang, &format!("say.{}", wording.key), &wording.args)
}

/// A decision rule's description (English: the engine's own).
pub fn decision_rule(lang: Lang, rule: spinbench_engine::plan::DecisionRule) -> String {
    match lang {
        Lang::En => rule.describe().to_string(),
        _ => tr_or(lang, &format!("rule.{}", rule.name()), rule.describe()),
    }
}

/// A decision rule's short name in `lang` (`guarded` → 保护带判定).
pub fn decision_rule_name(lang: Lang, rule: spinbench_engine::plan::DecisionRule) -> String {
    tr_or(lang, &format!("rule_name.{}", rule.name()), rule.name())
}

/// A device's role as `lang` names it (`instrument supply` → 仪表电源,
/// `fmu 2` → 计数模块 2); the role itself when the catalogue has no word.
pub fn device_role(lang: Lang, role: spinbench_engine::DeviceRole) -> String {
    let key = format!("device.{}", role.kind());
    let word = tr(lang, &key);
    if word == key {
        return role.name();
    }
    match role {
        spinbench_engine::DeviceRole::Fmu(n) => format!("{word} {n}"),
        _ => word,
    }
}

/// A run state's word (`completed` → "已完成").
pub fn state(lang: Lang, state: spinbench_store::StoredState) -> String {
    tr_or(lang, &format!("state.{state}"), state.as_str())
}

/// A reason of an outcome in `lang`. English: its text, as the engine wrote
/// it. Another language: the catalogue's `reason.<code>` (with a `variant`
/// value, `reason.<code>.<variant>`) filled with its values; a reason the
/// catalogue cannot word (a record written before reasons kept their values,
/// or a note of the reduction's own) its code's title, then the English text.
pub fn reason(lang: Lang, r: &spinbench_engine::Reason) -> String {
    if lang == Lang::En {
        return r.text.clone();
    }
    let code = r.code_name();
    let key = match r.args.get("variant") {
        Some(variant) => format!("reason.{code}.{variant}"),
        None => format!("reason.{code}"),
    };
    fill(lang, &key, &r.args).unwrap_or_else(|| {
        let title = tr(lang, &format!("reason_title.{code}"));
        format!("{title}：{}", r.text)
    })
}

/// A level left out of an instrument's reduction, in `lang` (who, which
/// level, how many readings, and the reason as its author wrote it).
pub fn exclusion(lang: Lang, e: &spinbench_analysis::exclusion::LevelExclusion) -> String {
    if lang == Lang::En {
        return e.to_string();
    }
    let (by, reason) = match anomaly_rule_exclusion(lang, e) {
        Some(worded) => worded,
        None => (e.by.clone(), e.reason.clone()),
    };
    let args = [
        ("by", by),
        ("mount", e.mount.to_string()),
        ("g", e.g.to_string()),
        ("unit", e.unit.clone().unwrap_or_default()),
        ("readings", e.points_removed.to_string()),
        ("reason", reason),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    let key = if e.unit.is_some() {
        "reason.excluded_of_unit"
    } else {
        "reason.excluded"
    };
    fill(lang, key, &args).unwrap_or_else(|| e.to_string())
}

/// Who and why of a level the anomaly rule left out, in `lang`. An
/// engineer's exclusion is shown in the words its author wrote; the rule's
/// are the station's own words, so they are worded in every language. The
/// record keeps the rule's English text only, so its numbers (the residual,
/// t and p) are read back from it; a text of another form is shown as it is.
fn anomaly_rule_exclusion(
    lang: Lang,
    e: &spinbench_analysis::exclusion::LevelExclusion,
) -> Option<(String, String)> {
    let rule = ["own", "exclude"].into_iter().find(|r| {
        e.by.starts_with(&format!("the anomaly rule (anomalies = \"{r}\""))
    })?;
    let rest = e
        .reason
        .strip_prefix("off the curve through the other levels by ")?;
    let (residual, rest) = rest.split_once(" µg (t = ")?;
    let (t, rest) = rest.split_once(", p = ")?;
    let (p, _) = rest.split_once(", ")?;
    let args = [("residual", residual), ("t", t), ("p", p)]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    let by = tr(lang, &format!("exclusion.by_anomaly_rule.{rule}"));
    Some((by, fill(lang, "exclusion.anomaly_rule_reason", &args)?))
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
        // The engine's texts the page words, and the run states: both languages.
        for prefix in ["say.", "state."] {
            let (en, zh) = (catalogue(Lang::En, prefix), catalogue(Lang::ZhCn, prefix));
            assert!(en.len() > 5, "{prefix}");
            assert_eq!(en.keys().collect::<Vec<_>>(), zh.keys().collect::<Vec<_>>());
        }
        assert_eq!(zh["web.nav.history"], "历史");
        assert_eq!(tr(Lang::En, "report.summary"), "Summary");
        assert_eq!(header(Lang::ZhCn, "radius [m]"), "半径 [m]");
        assert_eq!(header(Lang::ZhCn, "no such header"), "no such header");
        assert_eq!(outcome(Lang::ZhCn, "fail"), "不合格");
        use spinbench_engine::DeviceRole;
        assert_eq!(device_role(Lang::ZhCn, DeviceRole::Fmu(2)), "计数模块 2");
        assert_eq!(
            device_role(Lang::ZhCn, DeviceRole::InstrumentSupply),
            "仪表电源"
        );
        assert_eq!(device_role(Lang::En, DeviceRole::Fmu(2)), "fmu 2");
        assert_eq!(device_role(Lang::En, DeviceRole::Centrifuge), "centrifuge");
        assert_eq!(
            date_time(Lang::ZhCn, 1_795_446_697),
            "2026年11月23日 15:11 UTC"
        );
        assert_eq!(date_time(Lang::En, 1_795_446_697), "2026-11-23 15:11 UTC");
    }

    #[test]
    fn every_fault_and_step_the_engine_words_is_in_the_catalogue() {
        use spinbench_engine::EngineError;
        use spinbench_engine::executor::wording;
        use spinbench_engine::plan::{Fixture, Step};
        let faults = [
            EngineError::ModuleSilent {
                module: 2,
                seconds: 3.0,
            },
            EngineError::InterlockOpen,
            EngineError::SupplyTripped { volts: 1.0 },
            EngineError::NoChamber,
            EngineError::ChamberAlarm {
                word: 4,
                air_c: 30.0,
                setpoint_c: 25.0,
            },
            EngineError::OverTemperature {
                slot: 3,
                celsius: 90.0,
                limit_c: 85.0,
            },
            EngineError::NotStable("x".into()),
            EngineError::Aborted("operator".into()),
            EngineError::Power("x".into()),
            EngineError::Sink("x".into()),
            EngineError::NoUnits,
            EngineError::Rate("x".into()),
        ];
        for e in &faults {
            let w = e.wording();
            for lang in Lang::ALL {
                assert!(say(lang, &w).is_some(), "{lang:?} {w:?}");
            }
        }
        assert_eq!(
            say(Lang::ZhCn, &EngineError::InterlockOpen.wording()).as_deref(),
            Some("离心机联锁已断开；转台已停止（请关好舱门并复位联锁）")
        );
        // English from the catalogue reads as the engine's own text, word for word.
        for e in &faults {
            assert_eq!(say(Lang::En, &e.wording()), Some(e.to_string()), "{e:?}");
        }
        let steps = [
            Step::PowerOn,
            Step::CheckAlive,
            Step::WarmUp { seconds: 60.0 },
            Step::Mount {
                fixtures: vec![Some(Fixture::Up)],
            },
            Step::Tumble { up: false },
            Step::Soak { setpoint_c: -20.0 },
            Step::CrossTumble { as_on_arm: true },
            Step::Radius { pass: 0 },
            Step::Level {
                pass: 1,
                g_nominal: 5.0,
                direction: spinbench_analysis::Direction::Down,
            },
            Step::Decide { pass: 1, round: 0 },
            Step::Stop,
        ];
        for step in &steps {
            for lang in Lang::ALL {
                assert!(say(lang, &wording(step)).is_some(), "{lang:?} {step:?}");
            }
        }
        assert_eq!(
            say(Lang::ZhCn, &wording(&steps[8])).as_deref(),
            Some("5 g 向下（第 2 遍）")
        );
        use spinbench_analysis::control::WesternElectric as We;
        for rule in [
            We::Beyond3Sigma,
            We::TwoOfThreeBeyond2Sigma,
            We::FourOfFiveBeyond1Sigma,
            We::EightOnOneSide,
        ] {
            assert!(crate::control::rule_text(Lang::ZhCn, rule).starts_with("规则"));
            assert_eq!(crate::control::rule_text(Lang::En, rule), rule.describe());
        }
    }

    #[test]
    fn reasons_are_worded_from_the_catalogue_with_their_values() {
        use spinbench_engine::{Reason, ReasonCode};
        let over = Reason::new(
            ReasonCode::K2OverLimit,
            "|k2| 31.200 ± 2.000 µg/g² above the limit 25 µg/g² (guarded rule)",
        )
        .with("value", "31.200 ± 2.000")
        .with("unit", "µg/g²")
        .with("limit", 25)
        .with("rule", "guarded");
        assert_eq!(reason(Lang::En, &over), over.text);
        assert_eq!(
            reason(Lang::ZhCn, &over),
            "|k2| 31.200 ± 2.000 µg/g² 超过限值 25 µg/g²（保护带判定规则）"
        );
        // A word-valued argument whose word is empty in the catalogue.
        let simple = over.clone().with("rule", "simple");
        assert_eq!(
            reason(Lang::ZhCn, &simple),
            "|k2| 31.200 ± 2.000 µg/g² 超过限值 25 µg/g²"
        );
        let level = Reason::new(ReasonCode::NoOutput, "no output at 30 g")
            .with("variant", "level")
            .with("g", 30);
        assert_eq!(reason(Lang::ZhCn, &level), "在 30 g 时无输出");
        // A record written before reasons kept their values: the code's
        // title, then the text as written.
        let old = Reason::new(ReasonCode::Noisy, "noisy: 900 µg");
        assert_eq!(reason(Lang::ZhCn, &old), "噪声过大：noisy: 900 µg");
        // Every code has its title.
        for code in [
            "dead",
            "no_output",
            "noisy",
            "drifting",
            "tumble_failed",
            "radius_failed",
            "no_points",
            "cannot_reduce",
            "k2_over_limit",
            "k2_near_limit",
            "k2_inconclusive",
            "nonlinearity_over_limit",
            "nonlinearity_near_limit",
            "asymmetry_over_limit",
            "asymmetry_near_limit",
            "hysteresis_over_limit",
            "hysteresis_near_limit",
            "no_k2",
            "analysis_note",
            "incomplete",
            "temperature_unsettled",
            "over_temperature",
            "other",
        ] {
            let key = format!("reason_title.{code}");
            assert_ne!(tr(Lang::ZhCn, &key), key);
            let r = Reason {
                code: serde_json::from_value(serde_json::json!(code)).expect("a reason code"),
                text: String::new(),
                args: Default::default(),
            };
            assert_eq!(r.code_name(), code);
        }
    }
}

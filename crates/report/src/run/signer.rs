//! What a signer reads on a run report's first page,
//! the same in the PDF and the HTML: the run's identity, the decision
//! (which quantity was judged, against what limit, by which rule), one row
//! per instrument with K2 ± U95 and each mounting's k2 ± U95, its verdict
//! and one reason, the operator's actions and the station's notices. Every
//! "±" is the budget's U95, the value the verdict used.

use crate::lang::{self, Lang, tr};
use crate::run::RunReport;
use spinbench_engine::Outcome;
use spinbench_store::{NoticeKind, OperatorAction, ResultFigures, RunNotice};

/// One instrument's line of the signer's table.
#[derive(Debug, Clone, PartialEq)]
pub struct VerdictRow {
    /// Serial number.
    pub serial: String,
    /// Slot (from 1).
    pub slot: i64,
    /// The instrument's K2 ± U95 [µg/g²] ("—" when not measured).
    pub k2: String,
    /// Mounting P's k2 ± U95 [µg/g²].
    pub k2_p: String,
    /// Mounting N's k2 ± U95 [µg/g²].
    pub k2_n: String,
    /// The outcome.
    pub outcome: Outcome,
    /// The outcome in the report's language.
    pub verdict: String,
    /// The first reason, in the report's language ("—" for a plain pass).
    pub reason: String,
}

/// "value ± U95" to three decimals, "value" without its U95, "—" without a value.
pub(crate) fn plus_minus(value: Option<f64>, u95: Option<f64>) -> String {
    match (value, u95) {
        (Some(v), Some(u)) => format!("{v:.3} ± {u:.3}"),
        (Some(v), None) => format!("{v:.3}"),
        _ => "—".into(),
    }
}

/// One row per instrument, in slot order.
pub fn verdict_rows(report: &RunReport, lang: Lang) -> Vec<VerdictRow> {
    report
        .units
        .iter()
        .map(|u| {
            let record = u.record();
            let f = ResultFigures::of(record);
            VerdictRow {
                serial: u.result.serial.clone(),
                slot: u.result.slot + 1,
                k2: plus_minus(f.instrument_k2, f.instrument_k2_u95),
                k2_p: plus_minus(f.k2_p, f.k2_p_u95),
                k2_n: plus_minus(f.k2_n, f.k2_n_u95),
                outcome: u.result.outcome,
                verdict: lang::outcome(lang, u.result.outcome.as_str()),
                reason: record
                    .reasons
                    .first()
                    .map(|r| lang::reason(lang, r))
                    .or_else(|| record.exclusions.first().map(|e| lang::exclusion(lang, e)))
                    .unwrap_or_else(|| "—".into()),
            }
        })
        .collect()
}

/// The signer's table's headers, in `lang`.
pub fn verdict_headers(lang: Lang) -> [String; 7] {
    [
        "serial",
        "slot",
        "K2 ± U95 [µg/g²]",
        "k2 P ± U95 [µg/g²]",
        "k2 N ± U95 [µg/g²]",
        "outcome",
        "reason",
    ]
    .map(|h| lang::header(lang, h))
}

/// What was judged, in one sentence: the quantity, its limit and the rule
/// (`None` for a run whose records do not say: made before the decision
/// was recorded).
pub fn decision_text(report: &RunReport, lang: Lang) -> Option<String> {
    let decision = report.units.iter().find_map(|u| u.record().decision)?;
    let args = [
        (
            "measurand",
            tr(lang, &format!("measurand.{}", decision.measurand.name())),
        ),
        ("limit", format!("{}", decision.limit_ug_per_g2)),
        ("rule", lang::decision_rule(lang, decision.rule)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    lang::fill(lang, "report.decision", &args)
}

/// How many instruments had each outcome, worst first ("2 fail, 1
/// inconclusive, 8 pass"), in `lang`.
pub fn tally_text(report: &RunReport, lang: Lang) -> String {
    let worst_first = [
        Outcome::Fail,
        Outcome::Incomplete,
        Outcome::Inconclusive,
        Outcome::Marginal,
        Outcome::Pass,
    ];
    let parts: Vec<String> = worst_first
        .iter()
        .filter_map(|o| {
            let n = report
                .units
                .iter()
                .filter(|u| u.result.outcome == *o)
                .count();
            (n > 0).then(|| format!("{n} {}", lang::outcome(lang, o.as_str())))
        })
        .collect();
    rust_i18n::t!(
        "report.tally",
        n = report.units.len(),
        outcomes = parts.join(&tr(lang, "report.list_separator")),
        locale = lang.code()
    )
    .into_owned()
}

/// Every operator action of the run, as [`action_line`] words each.
pub fn action_lines(report: &RunReport, lang: Lang) -> Vec<(String, String, String)> {
    report
        .record
        .operator_actions
        .iter()
        .map(|a| action_line(report, lang, a))
        .collect()
}

/// Every notice and fault of the run, as [`notice_line`] words each.
pub fn notice_lines(report: &RunReport, lang: Lang) -> Vec<(String, String, String)> {
    report
        .record
        .notices
        .iter()
        .map(|n| notice_line(report, lang, n))
        .collect()
}

/// An operator's action in `lang`: (time in the station's zone, who, what).
pub fn action_line(report: &RunReport, lang: Lang, a: &OperatorAction) -> (String, String, String) {
    (report.time(lang, a.at), a.who.clone(), action_text(lang, a))
}

/// What an operator did, in `lang`: worded from its stored wording (the
/// prompt's fixtures), so nothing English is re-read; an action recorded
/// before wordings were kept shows its stored text.
pub fn action_text(lang: Lang, a: &OperatorAction) -> String {
    a.wording
        .as_ref()
        .filter(|w| w.key == "action.prompt")
        .and_then(|w| {
            let fixtures = w.args.get("fixtures")?;
            let prompt = prompt_text(lang, fixtures)?;
            let args = [
                ("answer".to_string(), w.args.get("answer")?.clone()),
                ("prompt".to_string(), prompt),
            ]
            .into_iter()
            .collect();
            lang::fill(lang, "report.action_prompt", &args)
        })
        .unwrap_or_else(|| a.action.clone())
}

/// The operator's prompt from its fixture codes per slot (comma-separated,
/// empty for a slot left alone), as the Run page words it.
fn prompt_text(lang: Lang, fixtures: &str) -> Option<String> {
    let held: Vec<(usize, &str)> = fixtures
        .split(',')
        .enumerate()
        .filter(|(_, code)| !code.is_empty())
        .collect();
    let first = held.first()?.1;
    let arg = |pairs: &[(&str, String)]| {
        pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.clone()))
            .collect()
    };
    if held.iter().all(|(_, code)| *code == first) {
        return lang::fill(
            lang,
            "say.prompt.mount_all",
            &arg(&[("fixture", first.to_string())]),
        );
    }
    let list = held
        .iter()
        .map(|(slot, code)| {
            lang::fill(
                lang,
                "say.prompt.mount_slot",
                &arg(&[
                    ("slot", (slot + 1).to_string()),
                    ("fixture", code.to_string()),
                ]),
            )
        })
        .collect::<Option<Vec<String>>>()?
        .join(&tr(lang, "report.list_separator"));
    lang::fill(lang, "say.prompt.mount_list", &arg(&[("list", list)]))
}

/// A notice or fault of the station in `lang`: (time, kind, what), from its
/// wording when the catalogue can word it, else its stored text.
pub fn notice_line(report: &RunReport, lang: Lang, n: &RunNotice) -> (String, String, String) {
    let kind = match n.kind {
        NoticeKind::Notice => tr(lang, "report.notice"),
        NoticeKind::Fault => tr(lang, "report.fault"),
    };
    let what = match lang {
        Lang::En => n.message.clone(),
        _ => n
            .wording
            .as_ref()
            .and_then(|w| lang::say(lang, w))
            .unwrap_or_else(|| n.message.clone()),
    };
    (report.time(lang, n.at), kind, what)
}

/// The sign-off block's three labels: tested by, reviewed by, date.
pub fn sign_off_labels(lang: Lang) -> [String; 3] {
    [
        tr(lang, "report.tested_by"),
        tr(lang, "report.reviewed_by"),
        tr(lang, "report.sign_date"),
    ]
}

/// The run's identity rows for the first page: (label, value), fewer than
/// the full header (the rule is in the decision, the prediction in the
/// detail).
pub fn identity_rows(report: &RunReport, lang: Lang) -> Vec<(String, String)> {
    crate::meta_rows_in(report, lang)
        .into_iter()
        .filter(|(label, _)| {
            !matches!(
                *label,
                "decision rule" | "prediction" | "instrument temperature"
            )
        })
        .map(|(label, value)| (tr(lang, &format!("meta.{label}")), value))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use spinbench_engine::event::Wording;

    fn action(fixtures: &str, answer: &str) -> OperatorAction {
        OperatorAction {
            at: 1_795_277_084,
            who: "op".into(),
            action: "went on at the prompt: (English as stored)".into(),
            wording: Some(
                Wording::new("action.prompt")
                    .with("answer", answer)
                    .with("fixtures", fixtures),
            ),
        }
    }

    #[test]
    fn an_operator_action_is_worded_from_its_fixtures_in_each_language() {
        let en = action_text(Lang::En, &action("arm_p,arm_p", "went_on"));
        assert!(
            en.contains("Mount every instrument on the arm in mounting P"),
            "{en}"
        );
        assert!(en.starts_with("went on"), "{en}");
        let zh = action_text(Lang::ZhCn, &action("arm_p,,arm_n", "aborted"));
        assert!(zh.contains("工位 1") && zh.contains("工位 3"), "{zh}");
        assert!(zh.contains("中止"), "{zh}");
        assert!(!zh.chars().any(|c| c.is_ascii_lowercase()), "{zh}");
        // An action of an older release keeps its stored text.
        let mut old = action("arm_p", "went_on");
        old.wording = None;
        assert_eq!(action_text(Lang::ZhCn, &old), old.action);
    }

    #[test]
    fn plus_minus_shows_what_is_known() {
        assert_eq!(plus_minus(Some(-17.7421), Some(11.58)), "-17.742 ± 11.580");
        assert_eq!(plus_minus(Some(3.0), None), "3.000");
        assert_eq!(plus_minus(None, Some(1.0)), "—");
    }
}

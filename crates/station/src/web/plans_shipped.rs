//! The plans a new station starts with (a function check, the shipped
//! check, the full test, the temperature test), put into its plans
//! directory once.

use anyhow::{Context, Result};

/// The plan a fresh data directory starts with, so a new station has one to run.
const EXAMPLE_PLAN: &str = r#"# A function check: ±10 g in both mountings, a few minutes; too short to
# decide K2 against a 20 µg/g² limit (the New-run form says so). Edit or add
# plans as an engineer.
name = "short ±10 g"
range_g = 10
levels = [0, 1, 2, 4, 6, 8, 10]
passes = ["P", "N"]
warmup_s = 0
dwell = { seconds = 3 }
stability = { hold_s = 3 }
[serials]
1 = "SN-001"
"#;

/// The plans a new station's plans directory starts with: (file name, text).
pub(crate) const SHIPPED_PLANS: [(&str, &str); 4] = [
    ("short", EXAMPLE_PLAN),
    (
        "check-70g",
        include_str!("../../../../packaging/plans/check-70g.toml"),
    ),
    (
        "full-70g",
        include_str!("../../../../packaging/plans/full-70g.toml"),
    ),
    (
        "temperature",
        include_str!("../../../../packaging/plans/temperature.toml"),
    ),
];

/// Put the shipped plans a station starts from into `plans_dir`, once (a
/// `.shipped` mark remembers it): a plan of that name already there is
/// kept, and a shipped plan an engineer deleted afterwards stays deleted.
pub(super) fn offer_shipped_plans(plans_dir: &std::path::Path) -> Result<()> {
    let mark = plans_dir.join(".shipped");
    if mark.exists() {
        return Ok(());
    }
    for (name, text) in SHIPPED_PLANS {
        let path = plans_dir.join(format!("{name}.toml"));
        if !path.exists() {
            std::fs::write(&path, text)
                .with_context(|| format!("{}: cannot write a shipped plan", path.display()))?;
        }
    }
    std::fs::write(
        &mark,
        "the shipped plans were put here once; delete this file to have the missing ones again\n",
    )
    .with_context(|| format!("{}: cannot write", mark.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn every_shipped_plan_reads_and_is_designed_on_the_defaults() {
        for (name, text) in super::SHIPPED_PLANS {
            let plan = spinbench_engine::TestPlan::from_toml(text)
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            // The check is measured until the verdict is certain; the full
            // test stays the published plan as it was.
            assert_eq!(plan.sequential.is_some(), name == "check-70g", "{name}");
            let designed = plan
                .designed(&spinbench_analysis::design::StationModel::default())
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(designed.range_g >= 10.0, "{name}");
            // The levels chosen by the data are in the prediction's time.
            let extra = designed
                .prediction
                .as_ref()
                .and_then(|p| p.sequential_centrifuge_time_max_s);
            assert_eq!(extra.is_some(), name == "check-70g", "{name}");
            assert!(extra.is_none_or(|t| t > 0.0), "{name}: {extra:?}");
            // The ±10 g function check cannot decide K2 (and says so on
            // the form); every other shipped plan can.
            assert_eq!(
                designed.decision_warning().is_none(),
                name != "short",
                "{name}: {:?}",
                designed.decision_warning()
            );
        }
    }

    #[test]
    fn every_decision_warning_is_worded_the_same_in_english_and_in_chinese() {
        use spinbench_report::lang::{Lang, say};
        let model = spinbench_analysis::design::StationModel::default();
        let (_, short) = super::SHIPPED_PLANS[0];
        // A limit 1.5 times the short plan's predicted U95: over half of it.
        let u95 = spinbench_engine::TestPlan::from_toml(short)
            .and_then(|p| p.designed(&model))
            .ok()
            .and_then(|p| p.prediction)
            .map(|p| p.k2_u95_ug_per_g2)
            .expect("the short plan's prediction");
        let variants = [
            (
                "too_wide",
                format!("{short}\n[limits]\nk2_max_ug_per_g2 = 0.001\n"),
            ),
            (
                "over_half",
                format!(
                    "{short}\n[limits]\nk2_max_ug_per_g2 = {}\n",
                    (1.5 * u95).round()
                ),
            ),
            (
                "judges_k2_max",
                format!("{short}\n[limits]\nk2_max_ug_per_g2 = 20\ndecide_on = \"k2_max\"\n"),
            ),
            (
                "one_mounting",
                format!(
                    "passes = [\"P\"]\n{}",
                    short.replace("passes =", "# passes =")
                ),
            ),
        ];
        for (case, text) in variants {
            let plan = spinbench_engine::TestPlan::from_toml(&text)
                .unwrap_or_else(|e| panic!("{case}: {e}\n{text}"))
                .designed(&model)
                .unwrap_or_else(|e| panic!("{case}: {e}"));
            let english = plan
                .decision_warning()
                .unwrap_or_else(|| panic!("{case}: no warning"));
            let wording = plan
                .decision_wording()
                .expect("a wording beside the warning");
            assert_eq!(wording.key, format!("plan.decision.{case}"));
            // The catalogue's English is the engine's text, word for word;
            // the Chinese is a text of its own with the same numbers.
            assert_eq!(
                say(Lang::En, &wording).as_deref(),
                Some(english.as_str()),
                "{case}"
            );
            let chinese = say(Lang::ZhCn, &wording).unwrap_or_else(|| panic!("{case}: no zh"));
            assert_ne!(chinese, english, "{case}");
            for value in wording.args.values() {
                assert!(
                    chinese.contains(value.as_str()),
                    "{case}: {value} in {chinese}"
                );
            }
        }
    }
}

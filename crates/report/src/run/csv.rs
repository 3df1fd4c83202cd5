//! A run's summary as CSV.

use crate::{DECISION_HEADERS, RunReport, SUMMARY_HEADERS, csv_field, numbers, summary};

/// The summary table as CSV (full precision: `{:?}` reads back to the same number).
pub fn summary_csv(report: &RunReport) -> String {
    let mut out = SUMMARY_HEADERS
        .iter()
        .chain(&DECISION_HEADERS)
        .copied()
        .collect::<Vec<_>>()
        .join(",");
    out.push('\n');
    for row in summary(report) {
        let mut cells = vec![
            csv_field(&row.serial),
            row.slot.to_string(),
            row.mount.clone(),
        ];
        cells.extend(
            numbers(&row)
                .iter()
                .map(|v| v.map_or(String::new(), |v| format!("{v:?}"))),
        );
        cells.push(row.outcome.clone());
        cells.push(csv_field(&row.reasons));
        let number = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:?}"));
        cells.push(number(row.instrument_k2_ug_per_g2));
        cells.push(number(row.instrument_k2_u95_ug_per_g2));
        cells.push(row.judged.clone());
        cells.push(number(row.limit_ug_per_g2));
        cells.push(row.rule.clone());
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    out
}

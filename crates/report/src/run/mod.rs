//! One run's report: its records gathered from the store (here), the
//! summary rows and point cells every format shares (`summary`), and each
//! format (`csv`, `html`, `xlsx`; the PDF is `crate::pdf`).

mod csv;
mod html;
pub mod signer;
mod summary;
mod xlsx;

pub use csv::summary_csv;
pub use html::{html, html_in};
pub use summary::{DECISION_HEADERS, SUMMARY_HEADERS, SummaryRow, summary, summary_in};
pub(crate) use summary::{POINT_HEADERS, SUMMARY_DECIMALS, meta_rows_in, numbers, point_cells};
pub(crate) use xlsx::xlsx_in;

use crate::{Lang, ReportError, lang};
use spinbench_store::{PointRow, ResultRow, RunRecord, RunRow, Store};

/// One instrument of a run.
#[derive(Debug, Clone)]
pub struct UnitReport {
    /// The stored result row, with the whole record as the engine wrote it.
    pub result: ResultRow,
    /// The instrument's points, in the order taken.
    pub points: Vec<PointRow>,
}

impl UnitReport {
    /// The instrument's record.
    pub fn record(&self) -> &spinbench_engine::UnitRecord {
        &self.result.record
    }

    /// Its reasons in one line, then any level left out (who, why), so a
    /// result that was reduced without some readings says so wherever it is shown.
    pub fn reasons_text(&self) -> String {
        self.reasons_text_in(Lang::En)
    }

    /// [`UnitReport::reasons_text`] in `lang` (`lang::reason`, `lang::exclusion`).
    pub fn reasons_text_in(&self, lang: Lang) -> String {
        let r = &self.result.record;
        let separator = if lang == Lang::En { "; " } else { "；" };
        r.reasons
            .iter()
            .map(|reason| lang::reason(lang, reason))
            .chain(r.exclusions.iter().map(|e| lang::exclusion(lang, e)))
            .collect::<Vec<_>>()
            .join(separator)
    }
}

/// Everything a run's report shows.
#[derive(Debug, Clone)]
pub struct RunReport {
    /// The run, as a listing shows it.
    pub run: RunRow,
    /// The whole record (plan, devices, operator actions, the end).
    pub record: RunRecord,
    /// Every instrument, in slot order.
    pub units: Vec<UnitReport>,
    /// The runs that retest this one (`spinbench retest`), oldest first.
    pub retested_by: Vec<String>,
    /// The station's time zone when it ran (read once from its config as
    /// the run recorded it; UTC when it said none or cannot be read).
    pub zone: spinbench_engine::time_zone::UtcOffset,
}

impl RunReport {
    /// A time of the run [Unix s] as `lang` writes it, in the station's zone.
    pub fn time(&self, lang: Lang, unix_s: i64) -> String {
        lang::date_time_in(lang, unix_s, self.zone)
    }
}

/// Read a run's report data from the store.
pub fn gather(store: &Store, run_id: &str) -> Result<RunReport, ReportError> {
    let record = store
        .run_record(run_id)?
        .ok_or_else(|| ReportError::NoRun(run_id.to_string()))?;
    let units = record
        .results
        .iter()
        .map(|result| UnitReport {
            result: result.clone(),
            points: record
                .points
                .iter()
                .filter(|p| p.slot == result.slot)
                .cloned()
                .collect(),
        })
        .collect();
    let retested_by = store.retests_of(run_id)?;
    Ok(RunReport {
        run: record.row(),
        zone: recorded_zone(&record),
        record,
        units,
        retested_by,
    })
}

/// The station's time zone in a run's recorded config, its `time_zone`
/// read alone (a config another release wrote, with keys this one does not
/// know, still says its zone); UTC when absent or unreadable.
fn recorded_zone(record: &RunRecord) -> spinbench_engine::time_zone::UtcOffset {
    record
        .start
        .station_config
        .as_deref()
        .and_then(|text| spinbench_engine::time_zone::of_station_config(text).ok())
        .unwrap_or(spinbench_engine::time_zone::UtcOffset::UTC)
}

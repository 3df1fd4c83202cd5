//! Readable run labels: `2026-11-24 · station 1 · #7`,
//! the day the run started by the station's clock (its `time_zone` then,
//! kept with the run as `runs.utc_offset_s`), the
//! station's name and the run's sequence number among that station's runs
//! of that day. The sequence is given when the run is first stored and
//! kept in `runs.seq`; the id stays the run's key, the label is how people
//! name it, and either is accepted where a run is typed
//! ([`Store::resolve_run`]).

use super::{RunRow, Store, StoreError};

/// The separator between a label's parts.
pub const LABEL_SEPARATOR: &str = " · ";

/// A run's label from its start time on the station's clock [Unix s plus
/// the station's offset from UTC], station and sequence number.
pub fn run_label(started_at_s: i64, station: &str, seq: i64) -> String {
    format!(
        "{}{LABEL_SEPARATOR}{station}{LABEL_SEPARATOR}#{seq}",
        crate::equipment::civil_date(started_at_s)
    )
}

/// The label as a file-name part: `2026-11-24_station-1_7` (only ASCII
/// letters, digits, `-` and `_`; anything else in the station's name
/// becomes `-`).
pub fn label_file_part(started_at_s: i64, station: &str, seq: i64) -> String {
    let station: String = station
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '-'
            }
        })
        .collect();
    format!(
        "{}_{}_{seq}",
        crate::equipment::civil_date(started_at_s),
        station.trim_matches('-')
    )
}

/// The UTC times [Unix s] within which every station's day `day` (days
/// since 1970-01-01 on its own clock) lies, whatever its zone (UTC−12:00
/// to UTC+14:00): a query's window, whose rows are then kept by their own
/// day ([`run_day`]). (The column is a timestamp on PostgreSQL, so the
/// day cannot be computed in SQL both back ends share.)
pub fn day_window(day: i64) -> (i64, i64) {
    (day * 86_400 - 14 * 3_600, (day + 1) * 86_400 + 12 * 3_600)
}

/// A run's day on its station's clock (days since 1970-01-01).
pub fn run_day(started_at_s: i64, utc_offset_s: i64) -> i64 {
    (started_at_s + utc_offset_s).div_euclid(86_400)
}

/// A typed label taken apart: the day (days since 1970-01-01), the station
/// if given, and the sequence number.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TypedLabel {
    /// The day the run started.
    pub day: i64,
    /// The station's name, when the label gave one.
    pub station: Option<String>,
    /// The run's number on that station that day.
    pub seq: i64,
}

/// At most this many runs a station can start in a day (a typed sequence
/// number above it is not a label).
pub const MAX_RUNS_PER_DAY: i64 = 100_000;

/// Parse a typed label: `2026-11-24 · station 1 · #7` as printed, or typed
/// with `/` between the parts (`2026-11-24/station 1/#7`), or without the
/// station (`2026-11-24 #7`, when one station ran a #7 that day). `None`
/// when `text` is not a label.
pub fn parse_label(text: &str) -> Option<TypedLabel> {
    let text = text.trim();
    let (head, seq) = text.rsplit_once('#')?;
    let seq: i64 = seq.trim().parse().ok()?;
    if !(1..=MAX_RUNS_PER_DAY).contains(&seq) {
        return None;
    }
    let head = head.trim().trim_end_matches(['·', '/']).trim();
    let (date, station) = match head.find(['·', '/']) {
        Some(at) => {
            let sep_len = head[at..].chars().next().map_or(1, char::len_utf8);
            (head[..at].trim(), Some(head[at + sep_len..].trim()))
        }
        None => (head, None),
    };
    let day = crate::equipment::parse_date(date)?;
    let station = station.filter(|s| !s.is_empty()).map(str::to_string);
    Some(TypedLabel { day, station, seq })
}

impl RunRow {
    /// The run's readable label (`2026-11-24 · station 1 · #7`); the id for
    /// a run stored before labels were given.
    pub fn label(&self) -> String {
        match self.seq {
            Some(seq) => run_label(self.started_at + self.utc_offset_s, &self.station, seq),
            None => self.id.clone(),
        }
    }

    /// The label as a file-name part ([`label_file_part`]); `None` for a
    /// run without a label.
    pub fn label_file_part(&self) -> Option<String> {
        self.seq
            .map(|seq| label_file_part(self.started_at + self.utc_offset_s, &self.station, seq))
    }
}

impl Store {
    /// `text` as a run id: the id of the run a label names ([`resolve_run`]),
    /// and any other text unchanged (for a caller that judges ids itself).
    ///
    /// [`resolve_run`]: Store::resolve_run
    pub fn id_of_label(&self, text: &str) -> Result<String, StoreError> {
        if parse_label(text).is_some() && self.run(text)?.is_none() {
            self.resolve_run(text)
        } else {
            Ok(text.to_string())
        }
    }

    /// The id of the run `text` names: a run id, or a label ([`parse_label`]).
    /// An error that says what to type when it names none, or several.
    pub fn resolve_run(&self, text: &str) -> Result<String, StoreError> {
        let what = "find the run";
        if self.run(text)?.is_some() {
            return Ok(text.to_string());
        }
        let Some(label) = parse_label(text) else {
            return Err(StoreError::message(
                &self.target,
                what,
                format!(
                    "no run '{text}': give a run id or a label such as \
                     '2026-11-24 · station 1 · #7' (see `spinbench runs list`)"
                ),
            ));
        };
        // The day is each run's station's.
        let (from, to) = day_window(label.day);
        let mut rows = self.runs_where(
            "r.seq = $1 AND r.started_at >= $2 AND r.started_at < $3",
            &[label.seq.into(), from.into(), to.into()],
        )?;
        rows.retain(|r| run_day(r.started_at, r.utc_offset_s) == label.day);
        if let Some(station) = &label.station {
            rows.retain(|r| r.station.trim() == station.as_str());
        }
        match rows.as_slice() {
            [one] => Ok(one.id.clone()),
            [] => Err(StoreError::message(
                &self.target,
                what,
                format!("no run is labelled '{text}' (see `spinbench runs list`)"),
            )),
            many => Err(StoreError::message(
                &self.target,
                what,
                format!(
                    "'{text}' names {} runs, one on each of the stations {}: add the station \
                     ('{}')",
                    many.len(),
                    many.iter()
                        .map(|r| format!("'{}'", r.station))
                        .collect::<Vec<_>>()
                        .join(", "),
                    many[0].label()
                ),
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_label_is_printed_and_read_back_in_every_typed_form() {
        // 2026-11-24 12:00 UTC.
        let t = 1_795_478_400 + 43_200;
        let label = run_label(t, "station 1", 7);
        assert_eq!(label, "2026-11-24 · station 1 · #7");
        let want = TypedLabel {
            day: t / 86_400,
            station: Some("station 1".into()),
            seq: 7,
        };
        for typed in [
            label.as_str(),
            "2026-11-24/station 1/#7",
            " 2026-11-24 / station 1 / # 7 ",
        ] {
            assert_eq!(parse_label(typed).as_ref(), Some(&want), "{typed}");
        }
        let bare = parse_label("2026-11-24 #7").expect("a label without the station");
        assert_eq!((bare.day, bare.station, bare.seq), (want.day, None, 7));
        for not_a_label in [
            "run-1795561294-193cfe02a89e",
            "2026-11-24",
            "2026-13-24 #7",
            "2026-11-24 #0",
            "2026-11-24 #-3",
            "2026-11-24 #999999999999",
            "#7",
            "",
        ] {
            assert_eq!(parse_label(not_a_label), None, "{not_a_label}");
        }
        assert_eq!(
            label_file_part(t, "station 1 / bay: A", 7),
            "2026-11-24_station-1---bay--A_7"
        );
    }
}

//! CSV as people and spreadsheets read it: a run's points in the input
//! format of `spinbench analyze`, and text cells guarded against formula
//! injection.

use super::{Store, StoreError};

/// The characters that make a spreadsheet program read a cell as a formula.
pub const FORMULA_STARTS: [char; 6] = ['=', '+', '-', '@', '\t', '\r'];

/// A text field of a CSV file written for people and spreadsheets: a text
/// that starts like a formula (`=HYPERLINK(…)`, `+cmd|…`, `@SUM…`) gets a
/// leading `'` so spreadsheet programs show it as text (OWASP's advice for
/// CSV injection); then it is quoted where CSV needs it. Only for text
/// (serials, names, reasons), never for numbers, whose `-` is a sign.
/// `spinbench analyze` takes the `'` off again when it reads the file.
pub fn csv_text_field(s: &str) -> String {
    let s = if s.starts_with(FORMULA_STARTS) {
        format!("'{s}")
    } else {
        s.to_string()
    };
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s
    }
}

/// Undo [`csv_text_field`]'s guard: `'=X` read back is `=X`.
pub fn csv_text_unguarded(s: &str) -> &str {
    match s.strip_prefix('\'') {
        Some(rest) if rest.starts_with(FORMULA_STARTS) => rest,
        _ => s,
    }
}

fn csv_field(s: &str) -> String {
    csv_text_field(s)
}

impl Store {
    /// The points of a run as CSV in the `spinbench analyze` format
    /// (`unit,mount,g_nominal,g_applied,output,direction,run`), in the order taken.
    pub fn points_csv(&self, run_id: &str) -> Result<String, StoreError> {
        let mut out = String::from("unit,mount,g_nominal,g_applied,output,direction,run\n");
        for p in self.points(run_id)? {
            // `{:?}` on f64 prints the shortest text that reads back to the same number.
            out.push_str(&format!(
                "{},{},{:?},{:?},{:?},{},{run_id}\n",
                csv_field(&p.serial),
                p.mount,
                p.g_nominal,
                p.g_applied,
                p.output_hz,
                p.direction.as_str()
            ));
        }
        Ok(out)
    }
}

//! Reading averaged points from a file: CSV, or a spreadsheet (XLSX, XLS,
//! ODS) read with calamine.
//!
//! The format is a header row and one row per averaged point with the
//! columns `unit,mount,g_nominal,g_applied,output` (any order, any case;
//! other columns are ignored). `g_applied` may be left empty and then equals
//! `g_nominal`. Two optional columns: `direction` (`up`/`down`, otherwise
//! inferred from the row order) and `run` (a label; several runs of one
//! serial number give its repeatability). Rows keep their file order within
//! a unit, so ascending and descending passes are told apart.
//!
//! Every error names the file, the line (or sheet and cell), the column and
//! what was expected; nothing here panics on any input.

mod formats;
mod rows;
#[cfg(test)]
mod tests;

pub use formats::parse_csv;
use formats::{column_letters, read_parquet, read_spreadsheet};
use rows::parse_rows;

use spinbench_analysis::{Direction, Mount, Point, UnitPoints};
use std::fmt;
use std::path::{Path, PathBuf};

/// The columns a points file must have.
pub const REQUIRED_COLUMNS: [&str; 5] = ["unit", "mount", "g_nominal", "g_applied", "output"];
/// Optional columns that the reader understands.
pub const OPTIONAL_COLUMNS: [&str; 2] = ["direction", "run"];

/// Where in a file something is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Location {
    /// A CSV line (1-based), and a column if one is meant.
    Line {
        /// Line number, 1-based.
        line: u64,
        /// Column position (1-based) and header name (empty when not yet known).
        column: Option<(usize, String)>,
    },
    /// A spreadsheet cell.
    Cell {
        /// Sheet name.
        sheet: String,
        /// Row number as the spreadsheet shows it (1-based).
        row: u64,
        /// Column as the spreadsheet shows it (A, B, …), with the header name.
        column: Option<(String, String)>,
    },
}

/// A points file could not be read; says where and what was expected.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PointsFileError {
    /// The file.
    pub path: PathBuf,
    /// Where in it, when a place is known (boxed to keep `Result`s small).
    pub location: Option<Box<Location>>,
    /// What is wrong and what was expected.
    pub message: String,
}

impl fmt::Display for PointsFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        match self.location.as_deref() {
            Some(Location::Line { line, column }) => {
                write!(f, ":{line}")?;
                match column {
                    Some((pos, name)) if name.is_empty() => write!(f, ": column {pos}")?,
                    Some((pos, name)) => write!(f, ": column {pos} ({name})")?,
                    None => {}
                }
            }
            Some(Location::Cell { sheet, row, column }) => {
                write!(f, ": sheet '{sheet}'")?;
                match column {
                    Some((letter, name)) => write!(f, ", cell {letter}{row} ({name})")?,
                    None => write!(f, ", row {row}")?,
                }
            }
            None => {}
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for PointsFileError {}

/// One cell as read from the file.
#[derive(Debug, Clone, PartialEq)]
enum Cell {
    Empty,
    Text(String),
    Number(f64),
    /// A spreadsheet error value such as `#DIV/0!`.
    Error(String),
}

/// One row as read, with where it came from.
struct RawRow {
    /// Line (CSV) or spreadsheet row number, 1-based.
    number: u64,
    cells: Vec<Cell>,
}

/// The kind of file, from its name or its first bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Csv,
    Spreadsheet,
    Parquet,
}

/// All the points of a file, grouped by unit (and run) in order of first appearance.
#[derive(Debug, Clone, PartialEq)]
pub struct PointsFile {
    /// The units found.
    pub units: Vec<UnitPoints>,
    /// Number of data rows read.
    pub rows: usize,
    /// Rows that repeat an earlier row exactly, one at a time (two readings
    /// that agree to the printed digits): kept, and said so; rows that
    /// repeat the row just before them (a row written twice): dropped, and
    /// said so.
    pub warnings: Vec<String>,
    /// Units with a row whose values cannot be read (not a number, not
    /// finite, no mounting): not reduced, each with its bad rows named; the
    /// file's other units are.
    pub rejected: Vec<RejectedUnit>,
}

/// A unit of a points file that cannot be reduced because of bad rows.
#[derive(Debug, Clone, PartialEq)]
pub struct RejectedUnit {
    /// Serial number.
    pub unit: String,
    /// Run label, when the file has one.
    pub run: Option<String>,
    /// What is wrong, row by row.
    pub errors: Vec<String>,
}

/// Consecutive rows repeating earlier rows exactly that make a repeated
/// block (a file appended twice): refused.
const REPEATED_BLOCK_ROWS: usize = 3;

/// Read a points file; `sheet` picks a spreadsheet sheet (default: the first).
pub fn read_points_file(path: &Path, sheet: Option<&str>) -> Result<PointsFile, PointsFileError> {
    let err = |message: String| PointsFileError {
        path: path.to_path_buf(),
        location: None,
        message,
    };
    let bytes = std::fs::read(path).map_err(|e| err(format!("cannot read the file: {e}")))?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let kind = match ext.as_deref() {
        Some("xlsx" | "xlsm" | "xls" | "xlsb" | "ods") => Kind::Spreadsheet,
        Some("csv" | "txt") => Kind::Csv,
        Some("parquet") => Kind::Parquet,
        _ if bytes.starts_with(b"PAR1") => Kind::Parquet,
        // A zip (XLSX/ODS) or OLE (XLS) signature means a spreadsheet.
        _ if bytes.starts_with(b"PK\x03\x04") || bytes.starts_with(&[0xD0, 0xCF, 0x11, 0xE0]) => {
            Kind::Spreadsheet
        }
        _ => Kind::Csv,
    };
    match kind {
        Kind::Csv => parse_csv(path, &bytes),
        Kind::Spreadsheet => read_spreadsheet(path, sheet),
        Kind::Parquet => read_parquet(path),
    }
}

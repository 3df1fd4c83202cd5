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

/// A Parquet file (as `spinbench export --format parquet` writes): its
/// column names are the header row; row n of the data is line n + 1.
fn read_parquet(path: &Path) -> Result<PointsFile, PointsFileError> {
    use parquet::file::reader::{FileReader, SerializedFileReader};
    use parquet::record::Field;
    let err = |message: String| PointsFileError {
        path: path.to_path_buf(),
        location: None,
        message,
    };
    let file = std::fs::File::open(path).map_err(|e| err(format!("cannot read the file: {e}")))?;
    let reader = SerializedFileReader::new(file)
        .map_err(|e| err(format!("not a readable Parquet file: {e}")))?;
    let header: Vec<Cell> = reader
        .metadata()
        .file_metadata()
        .schema_descr()
        .columns()
        .iter()
        .map(|c| Cell::Text(c.name().to_string()))
        .collect();
    let mut rows = vec![RawRow {
        number: 1,
        cells: header,
    }];
    let iter = reader
        .get_row_iter(None)
        .map_err(|e| err(format!("cannot read the rows: {e}")))?;
    for (i, row) in iter.enumerate() {
        let row = row.map_err(|e| err(format!("row {}: {e}", i + 1)))?;
        let cells = row
            .get_column_iter()
            .map(|(_, field)| match field {
                Field::Null => Cell::Empty,
                Field::Str(s) if s.trim().is_empty() => Cell::Empty,
                Field::Str(s) => Cell::Text(s.trim().to_string()),
                Field::Double(v) => Cell::Number(*v),
                Field::Float(v) => Cell::Number(f64::from(*v)),
                Field::Long(v) => Cell::Number(*v as f64),
                Field::Int(v) => Cell::Number(f64::from(*v)),
                other => Cell::Text(other.to_string()),
            })
            .collect();
        rows.push(RawRow {
            number: i as u64 + 2,
            cells,
        });
    }
    parse_rows(path, None, rows)
}

/// Parse CSV bytes (from `path`, which is only used in messages).
pub fn parse_csv(path: &Path, bytes: &[u8]) -> Result<PointsFile, PointsFileError> {
    // Excel writes a UTF-8 byte-order mark; it is not part of the first header name.
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_reader(bytes);
    let mut rows = Vec::new();
    for record in reader.byte_records() {
        let record = record.map_err(|e| {
            let line = e.position().map(|p| p.line());
            PointsFileError {
                path: path.to_path_buf(),
                location: line.map(|line| Box::new(Location::Line { line, column: None })),
                message: format!("not valid CSV: {e}"),
            }
        })?;
        let number = record.position().map_or(0, |p| p.line());
        let mut cells = Vec::with_capacity(record.len());
        for (i, field) in record.iter().enumerate() {
            let text = std::str::from_utf8(field).map_err(|_| PointsFileError {
                path: path.to_path_buf(),
                location: Some(Box::new(Location::Line {
                    line: number,
                    column: Some((i + 1, String::new())),
                })),
                message: "the field is not valid UTF-8 text; save the file as UTF-8 CSV".into(),
            })?;
            cells.push(if text.is_empty() {
                Cell::Empty
            } else {
                Cell::Text(text.to_string())
            });
        }
        rows.push(RawRow { number, cells });
    }
    parse_rows(path, None, rows)
}

fn read_spreadsheet(path: &Path, sheet: Option<&str>) -> Result<PointsFile, PointsFileError> {
    use calamine::{Data, Reader, open_workbook_auto};
    let err = |message: String| PointsFileError {
        path: path.to_path_buf(),
        location: None,
        message,
    };
    let mut workbook =
        open_workbook_auto(path).map_err(|e| err(format!("cannot open the spreadsheet: {e}")))?;
    let names = workbook.sheet_names();
    let name = match sheet {
        Some(s) => names
            .iter()
            .find(|n| n.as_str() == s)
            .cloned()
            .ok_or_else(|| {
                err(format!(
                    "no sheet named '{s}'; the sheets are: {}",
                    names.join(", ")
                ))
            })?,
        None => names
            .first()
            .cloned()
            .ok_or_else(|| err("the workbook has no sheets".into()))?,
    };
    // XLSX is read cell by cell, by the cells that exist: a sheet's declared
    // size (one cell at XFD1048576 makes it 17 billion cells) is never allocated.
    if let calamine::Sheets::Xlsx(xlsx) = &mut workbook {
        return read_xlsx_cells(path, xlsx, &name);
    }
    let range = workbook
        .worksheet_range(&name)
        .map_err(|e| err(format!("cannot read sheet '{name}': {e}")))?;
    let (row0, col0) = range.start().unwrap_or((0, 0));
    // Cells before the used range's first column are empty; keep positions absolute.
    let lead = col0 as usize;
    let rows = range
        .rows()
        .enumerate()
        .map(|(i, row)| RawRow {
            number: u64::from(row0) + i as u64 + 1,
            cells: std::iter::repeat_n(Cell::Empty, lead)
                .chain(row.iter().map(|d| match d {
                    Data::Empty => Cell::Empty,
                    Data::Int(v) => Cell::Number(*v as f64),
                    Data::Float(v) => Cell::Number(*v),
                    Data::String(s) | Data::DateTimeIso(s) | Data::DurationIso(s) => text_cell(s),
                    Data::Bool(b) => Cell::Text(b.to_string()),
                    Data::DateTime(dt) => Cell::Text(dt.to_string()),
                    Data::Error(e) => Cell::Error(e.to_string()),
                }))
                .collect(),
        })
        .collect();
    parse_rows(path, Some(&name), rows)
}

/// A text cell, trimmed; blank text is an empty cell.
fn text_cell(s: &str) -> Cell {
    match s.trim() {
        "" => Cell::Empty,
        t => Cell::Text(t.to_string()),
    }
}

/// Most cells read from one sheet (far above any points file).
const MAX_SHEET_CELLS: usize = 10_000_000;

/// The rows of an XLSX sheet from the cells that exist, in the order stored.
fn read_xlsx_cells<RS: std::io::Read + std::io::Seek>(
    path: &Path,
    xlsx: &mut calamine::Xlsx<RS>,
    name: &str,
) -> Result<PointsFile, PointsFileError> {
    use calamine::DataRef;
    let err = |message: String| PointsFileError {
        path: path.to_path_buf(),
        location: None,
        message,
    };
    let mut reader = xlsx
        .worksheet_cells_reader(name)
        .map_err(|e| err(format!("cannot read sheet '{name}': {e}")))?;
    let mut rows: std::collections::BTreeMap<u32, Vec<(u32, Cell)>> = Default::default();
    let mut count = 0usize;
    while let Some(cell) = reader
        .next_cell()
        .map_err(|e| err(format!("cannot read sheet '{name}': {e}")))?
    {
        let (row, column) = cell.get_position();
        let value = match cell.get_value() {
            DataRef::Empty => continue,
            DataRef::Int(v) => Cell::Number(*v as f64),
            DataRef::Float(v) => Cell::Number(*v),
            DataRef::String(s) | DataRef::DateTimeIso(s) | DataRef::DurationIso(s) => text_cell(s),
            DataRef::SharedString(s) => text_cell(s),
            DataRef::Bool(b) => Cell::Text(b.to_string()),
            DataRef::DateTime(dt) => Cell::Text(dt.to_string()),
            DataRef::Error(e) => Cell::Error(e.to_string()),
        };
        if value == Cell::Empty {
            continue;
        }
        count += 1;
        if count > MAX_SHEET_CELLS {
            return Err(err(format!(
                "sheet '{name}' has more than {MAX_SHEET_CELLS} cells; a points file has one row per point"
            )));
        }
        rows.entry(row).or_default().push((column, value));
    }
    let rows = rows
        .into_iter()
        .map(|(row, cells)| {
            let width = cells
                .iter()
                .map(|(c, _)| *c as usize + 1)
                .max()
                .unwrap_or(0);
            let mut line = vec![Cell::Empty; width];
            for (c, value) in cells {
                line[c as usize] = value;
            }
            RawRow {
                number: u64::from(row) + 1,
                cells: line,
            }
        })
        .collect();
    parse_rows(path, Some(name), rows)
}

/// Spreadsheet column letters for a 0-based index (0 → A, 26 → AA).
fn column_letters(mut index: usize) -> String {
    let mut letters = Vec::new();
    loop {
        letters.push(b'A' + (index % 26) as u8);
        if index < 26 {
            break;
        }
        index = index / 26 - 1;
    }
    letters.reverse();
    String::from_utf8_lossy(&letters).into_owned()
}

/// Longest serial number read from a points file [characters].
const MAX_UNIT_CHARS: usize = 200;

/// Column indices of the known columns.
struct Columns {
    unit: usize,
    mount: usize,
    g_nominal: usize,
    g_applied: usize,
    output: usize,
    direction: Option<usize>,
    run: Option<usize>,
}

fn parse_rows(
    path: &Path,
    sheet: Option<&str>,
    rows: Vec<RawRow>,
) -> Result<PointsFile, PointsFileError> {
    let at = |number: u64, column: Option<(usize, &str)>| match sheet {
        Some(sheet) => Location::Cell {
            sheet: sheet.to_string(),
            row: number,
            column: column.map(|(i, n)| (column_letters(i), n.to_string())),
        },
        None => Location::Line {
            line: number,
            column: column.map(|(i, n)| (i + 1, n.to_string())),
        },
    };
    let fail = |location: Option<Location>, message: String| PointsFileError {
        path: path.to_path_buf(),
        location: location.map(Box::new),
        message,
    };
    let expected_header = REQUIRED_COLUMNS.join(",");

    let mut rows = rows
        .into_iter()
        .filter(|r| r.cells.iter().any(|c| *c != Cell::Empty));
    let Some(header) = rows.next() else {
        return Err(fail(
            None,
            format!(
                "the file has no rows; expected a header row with the columns {expected_header}"
            ),
        ));
    };

    // Header: names are trimmed and compared without case.
    let mut names: Vec<Option<String>> = Vec::with_capacity(header.cells.len());
    // First column of each name: duplicates found in one pass, not by a
    // search per column (a header of many columns must not be quadratic).
    let mut first_of: std::collections::HashMap<String, usize> = Default::default();
    for (i, cell) in header.cells.iter().enumerate() {
        let name = match cell {
            Cell::Text(t) => Some(t.trim().to_ascii_lowercase()),
            Cell::Number(v) => Some(v.to_string()),
            Cell::Empty | Cell::Error(_) => None,
        };
        if let Some(n) = &name
            && let Some(&first) = first_of.get(n.as_str())
        {
            return Err(fail(
                Some(at(header.number, Some((i, n)))),
                format!(
                    "duplicate header '{n}' (it is also column {}); each column name may appear once",
                    match sheet {
                        Some(_) => column_letters(first),
                        None => (first + 1).to_string(),
                    }
                ),
            ));
        }
        if let Some(n) = &name {
            first_of.insert(n.clone(), i);
        }
        names.push(name);
    }
    let find = |name: &str| first_of.get(name).copied();
    let missing: Vec<&str> = REQUIRED_COLUMNS
        .iter()
        .copied()
        .filter(|c| find(c).is_none())
        .collect();
    if missing.len() == REQUIRED_COLUMNS.len() {
        let found: Vec<String> = header
            .cells
            .iter()
            .map(|c| match c {
                Cell::Text(t) => t.clone(),
                Cell::Number(v) => v.to_string(),
                _ => String::new(),
            })
            .collect();
        return Err(fail(
            Some(at(header.number, None)),
            format!(
                "expected a header row naming the columns {expected_header}; found '{}'",
                found.join(",")
            ),
        ));
    }
    if !missing.is_empty() {
        let hint = if missing == ["g_applied"] {
            " (an empty g_applied column means the applied level equals g_nominal)"
        } else {
            ""
        };
        return Err(fail(
            Some(at(header.number, None)),
            format!(
                "missing column(s) {} in the header; the columns are {expected_header}{hint}",
                missing.join(", ")
            ),
        ));
    }
    let required = |name: &str| find(name).unwrap_or(usize::MAX);
    let columns = Columns {
        unit: required("unit"),
        mount: required("mount"),
        g_nominal: required("g_nominal"),
        g_applied: required("g_applied"),
        output: required("output"),
        direction: find("direction"),
        run: find("run"),
    };

    let mut units: Vec<UnitPoints> = Vec::new();
    let mut count = 0usize;
    // Every row's content (unit, run, mount, levels, output, direction, bit
    // for bit) and where it was first seen. A block of rows repeated exactly
    // is a file appended twice, not new points, and is refused by name; a
    // single repeated row (two readings equal to the printed digits) is kept
    // with a warning.
    let mut seen: std::collections::HashMap<String, u64> = Default::default();
    let mut warnings = Vec::new();
    let mut repeated_run: Vec<(u64, u64)> = Vec::new();
    let mut rejected: Vec<RejectedUnit> = Vec::new();
    let mut previous_key: Option<(String, u64)> = None;
    for row in rows {
        let cell = |i: usize| row.cells.get(i).unwrap_or(&Cell::Empty);
        let loc = |i: usize, name: &str| Some(at(row.number, Some((i, name))));
        let text = |i: usize, name: &str| -> Result<Option<String>, PointsFileError> {
            match cell(i) {
                Cell::Empty => Ok(None),
                Cell::Text(t) => Ok(Some(t.clone())),
                // A serial number typed as a number: 2601.0 reads as "2601".
                Cell::Number(v) => Ok(Some(v.to_string())),
                Cell::Error(e) => Err(fail(loc(i, name), format!("the cell holds the error {e}"))),
            }
        };
        let number = |i: usize, name: &str| -> Result<Option<f64>, PointsFileError> {
            let value = match cell(i) {
                Cell::Empty => return Ok(None),
                Cell::Number(v) => *v,
                Cell::Text(t) => t.trim().parse::<f64>().map_err(|_| {
                    fail(
                        loc(i, name),
                        format!("expected a number, found '{}'", t.trim()),
                    )
                })?,
                Cell::Error(e) => {
                    return Err(fail(
                        loc(i, name),
                        format!("expected a number, the cell holds the error {e}"),
                    ));
                }
            };
            if !value.is_finite() {
                return Err(fail(
                    loc(i, name),
                    format!("expected a finite number, found {value}"),
                ));
            }
            Ok(Some(value))
        };

        let unit = text(columns.unit, "unit")?.ok_or_else(|| {
            fail(
                loc(columns.unit, "unit"),
                "expected a unit serial number, the cell is empty".into(),
            )
        })?;
        // A serial written by `export` as '=… (a guard against CSV formula
        // injection) reads back as itself.
        let unit = spinbench_store::csv_text_unguarded(&unit).to_string();
        if unit.chars().count() > MAX_UNIT_CHARS {
            return Err(fail(
                loc(columns.unit, "unit"),
                format!(
                    "a serial number of {} characters ('{}'); at most {MAX_UNIT_CHARS}",
                    unit.chars().count(),
                    unit.chars().take(40).collect::<String>()
                ),
            ));
        }
        let run = match columns.run {
            Some(i) => text(i, "run")?,
            None => None,
        };

        let parsed = (|| -> Result<(Mount, f64, f64, f64, Option<Direction>), PointsFileError> {
            let mount_text = text(columns.mount, "mount")?.unwrap_or_default();
            let mount = Mount::parse(&mount_text).ok_or_else(|| {
                fail(
                    loc(columns.mount, "mount"),
                    format!(
                        "expected P (input axis toward the spin axis) or N (away), found '{mount_text}'"
                    ),
                )
            })?;
            let g_nominal = number(columns.g_nominal, "g_nominal")?.ok_or_else(|| {
                fail(
                    loc(columns.g_nominal, "g_nominal"),
                    "expected the nominal level in g, the cell is empty".into(),
                )
            })?;
            let g_applied = number(columns.g_applied, "g_applied")?.unwrap_or(g_nominal);
            let output = number(columns.output, "output")?.ok_or_else(|| {
                fail(
                    loc(columns.output, "output"),
                    "expected the averaged instrument output, the cell is empty".into(),
                )
            })?;
            let direction = match columns.direction {
                Some(i) => match text(i, "direction")? {
                    None => None,
                    Some(t) => Some(Direction::parse(&t).ok_or_else(|| {
                        fail(
                            loc(i, "direction"),
                            format!("expected up or down, found '{t}'"),
                        )
                    })?),
                },
                None => None,
            };
            Ok((mount, g_nominal, g_applied, output, direction))
        })();
        let (mount, g_nominal, g_applied, output, direction) = match parsed {
            Ok(values) => values,
            Err(e) => {
                let message = e.to_string();
                match rejected
                    .iter_mut()
                    .find(|r: &&mut RejectedUnit| r.unit == unit && r.run == run)
                {
                    Some(r) => r.errors.push(message),
                    None => rejected.push(RejectedUnit {
                        unit,
                        run,
                        errors: vec![message],
                    }),
                }
                continue;
            }
        };
        let key = format!(
            "{unit}\u{1f}{run:?}\u{1f}{mount}\u{1f}{:x}\u{1f}{:x}\u{1f}{:x}\u{1f}{direction:?}",
            g_nominal.to_bits(),
            g_applied.to_bits(),
            output.to_bits()
        );
        let place = |n: u64| match sheet {
            Some(_) => format!("row {n}"),
            None => format!("line {n}"),
        };
        // A row that repeats the row just before it is the same row written
        // twice (a station never takes two readings of one level bit for bit
        // alike back to back): dropped, said so.
        if let Some((previous, previous_line)) = &previous_key
            && *previous == key
        {
            warnings.push(format!(
                "{}: {} repeats {} just before it exactly (unit {unit}, mounting {mount}, {g_nominal} g, output {output}): a row written twice; dropped",
                path.display(),
                place(row.number),
                place(*previous_line)
            ));
            continue;
        }
        previous_key = Some((key.clone(), row.number));
        match seen.get(&key) {
            Some(&first) => {
                repeated_run.push((row.number, first));
                if repeated_run.len() >= REPEATED_BLOCK_ROWS {
                    let (start, original) = repeated_run[0];
                    return Err(fail(
                        Some(at(start, None)),
                        format!(
                            "{} and the rows after it repeat {} onwards exactly ({} rows in a row): \
                             a file appended twice? Each averaged point may appear once; remove the repeated rows",
                            place(start),
                            place(original),
                            repeated_run.len()
                        ),
                    ));
                }
                warnings.push(format!(
                    "{}: {} repeats {} exactly (unit {unit}, mounting {mount}, {g_nominal} g, output {output}); kept as a second reading",
                    path.display(),
                    place(row.number),
                    place(first)
                ));
            }
            None => {
                repeated_run.clear();
                seen.insert(key, row.number);
            }
        }
        let point = Point {
            mount,
            g_nominal,
            g_applied,
            output,
            direction,
        };
        match units.iter_mut().find(|u| u.unit == unit && u.run == run) {
            Some(u) => u.points.push(point),
            None => units.push(UnitPoints {
                unit,
                run,
                points: vec![point],
            }),
        }
        count += 1;
    }
    // A unit with a bad row is not reduced at all (a fit without the row
    // would pass as a reduction of every point).
    units.retain(|u| !rejected.iter().any(|r| r.unit == u.unit && r.run == u.run));
    if units.is_empty() {
        if let Some(r) = rejected.first()
            && let Some(first) = r.errors.first()
        {
            return Err(fail(None, format!("no unit can be reduced: {first}")));
        }
        return Err(fail(
            Some(at(header.number, None)),
            "the header is followed by no data rows; expected one row per averaged point".into(),
        ));
    }
    Ok(PointsFile {
        units,
        rows: count,
        warnings,
        rejected,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<PointsFile, PointsFileError> {
        parse_csv(Path::new("t.csv"), text.as_bytes())
    }

    #[test]
    fn column_letters_match_spreadsheets() {
        assert_eq!(column_letters(0), "A");
        assert_eq!(column_letters(25), "Z");
        assert_eq!(column_letters(26), "AA");
        assert_eq!(column_letters(701), "ZZ");
        assert_eq!(column_letters(702), "AAA");
    }

    #[test]
    fn reads_columns_in_any_order_with_bom_and_comments() {
        let f = parse(
            "\u{feff}Output, MOUNT,unit,g_applied,g_nominal,notes\n# a comment\n35.5,P,SN1,,0,x\n135.6,p,SN1,1.0004,1,\n",
        )
        .expect("parse");
        assert_eq!(f.rows, 2);
        let u = &f.units[0];
        assert_eq!(u.unit, "SN1");
        assert_eq!(u.points[0].g_applied, 0.0);
        assert_eq!(u.points[1].g_applied, 1.0004);
        assert_eq!(u.points[1].output, 135.6);
    }

    #[test]
    fn groups_by_unit_and_run_in_first_appearance_order() {
        let f = parse(
            "unit,mount,g_nominal,g_applied,output,run\nB,P,0,,1,r1\nA,P,0,,1,r1\nB,P,1,,2,r1\nB,P,0,,1,r2\n",
        )
        .expect("parse");
        let keys: Vec<(String, Option<String>, usize)> = f
            .units
            .iter()
            .map(|u| (u.unit.clone(), u.run.clone(), u.points.len()))
            .collect();
        assert_eq!(
            keys,
            vec![
                ("B".into(), Some("r1".into()), 2),
                ("A".into(), Some("r1".into()), 1),
                ("B".into(), Some("r2".into()), 1)
            ]
        );
    }

    #[test]
    fn a_repeated_block_is_refused_and_a_single_repeated_row_is_said() {
        let head = "unit,mount,g_nominal,g_applied,output\n";
        let block = "A,P,0,0,1\nA,P,5,5,501\nA,P,10,10,1001\n";
        let e = parse(&format!("{head}{block}{block}")).expect_err("appended twice");
        let message = e.to_string();
        assert!(
            message.contains(":5") && message.contains("line 2"),
            "{message}"
        );
        assert!(message.contains("appended twice"), "{message}");
        let one = parse(&format!("{head}{block}A,P,5,5,501\n")).expect("a coincident reading");
        assert_eq!(one.rows, 4);
        assert_eq!(one.warnings.len(), 1);
        assert!(
            one.warnings[0].contains("line 5 repeats line 3"),
            "{:?}",
            one.warnings
        );
        // A level visited again with another reading is a new point.
        let ok = parse("unit,mount,g_nominal,g_applied,output\nA,P,0,0,1\nA,P,0,0,1.0001\n")
            .expect("a repeated visit");
        assert_eq!(ok.rows, 2);
    }

    #[test]
    fn errors_name_line_and_column() {
        let head = "unit,mount,g_nominal,g_applied,output\n";
        let cases = [
            ("", "no rows"),
            ("SN1,P,0,,1\n", "expected a header row"),
            (
                "unit,mount,g_nominal,output\nA,P,0,1\n",
                "missing column(s) g_applied",
            ),
            (
                "unit,mount,unit,g_nominal,g_applied,output\n",
                "t.csv:1: column 3 (unit): duplicate header",
            ),
            (
                &format!("{head}A,X,0,,1\n"),
                "t.csv:2: column 2 (mount): expected P",
            ),
            (
                &format!("{head}A,P,zero,,1\n"),
                "t.csv:2: column 3 (g_nominal): expected a number, found 'zero'",
            ),
            (
                &format!("{head}A,P,0,,NaN\n"),
                "t.csv:2: column 5 (output): expected a finite number",
            ),
            (
                &format!("{head}A,P,0,,inf\n"),
                "column 5 (output): expected a finite number",
            ),
            (
                &format!("{head}A,P,0,,\n"),
                "column 5 (output): expected the averaged",
            ),
            (
                &format!("{head},P,0,,1\n"),
                "column 1 (unit): expected a unit serial",
            ),
            (head, "no data rows"),
        ];
        for (text, want) in cases {
            let err = parse(text).expect_err(text).to_string();
            assert!(
                err.contains(want),
                "input {text:?}\n  got: {err}\n want: {want}"
            );
        }
    }

    #[test]
    fn invalid_utf8_is_an_error_not_a_panic() {
        let err = parse_csv(
            Path::new("b.csv"),
            b"unit,mount,g_nominal,g_applied,output\nA\xff,P,0,,1\n",
        )
        .expect_err("bad utf8");
        assert!(err.to_string().contains("b.csv:2: column 1"), "{err}");
    }
}

//! Each file format's cells: CSV, XLSX/ODS (through calamine, and the
//! XLSX sheet's own cells when a sheet declares a huge range) and Parquet.

use super::{Cell, Location, Path, PointsFile, PointsFileError, RawRow, parse_rows};

/// A Parquet file (as `spinbench export --format parquet` writes): its
/// column names are the header row; row n of the data is line n + 1.
pub(super) fn read_parquet(path: &Path) -> Result<PointsFile, PointsFileError> {
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

pub(super) fn read_spreadsheet(
    path: &Path,
    sheet: Option<&str>,
) -> Result<PointsFile, PointsFileError> {
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
pub(super) fn text_cell(s: &str) -> Cell {
    match s.trim() {
        "" => Cell::Empty,
        t => Cell::Text(t.to_string()),
    }
}

/// Most cells read from one sheet (far above any points file).
pub(super) const MAX_SHEET_CELLS: usize = 10_000_000;

/// The rows of an XLSX sheet from the cells that exist, in the order stored.
pub(super) fn read_xlsx_cells<RS: std::io::Read + std::io::Seek>(
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
pub(super) fn column_letters(mut index: usize) -> String {
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

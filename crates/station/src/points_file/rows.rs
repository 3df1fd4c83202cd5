//! The rows of any format into units' points: the header's columns, every
//! cell checked (a bad number rejects its unit only, naming the row),
//! repeated rows and blocks.

use super::{
    Cell, Direction, Location, Mount, Path, Point, PointsFile, PointsFileError,
    REPEATED_BLOCK_ROWS, REQUIRED_COLUMNS, RawRow, RejectedUnit, UnitPoints, column_letters,
};

/// Longest serial number read from a points file [characters].
pub(super) const MAX_UNIT_CHARS: usize = 200;

/// Column indices of the known columns.
pub(super) struct Columns {
    unit: usize,
    mount: usize,
    g_nominal: usize,
    g_applied: usize,
    output: usize,
    direction: Option<usize>,
    run: Option<usize>,
}

pub(super) fn parse_rows(
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

//! `spinbench export RUN --format csv|xlsx|parquet`: a run's points (in the
//! input format of `spinbench analyze`, so re-analysis round-trips) and its
//! per-instrument results. CSV holds the points; XLSX a `points` sheet
//! (first, so `analyze` reads it) and a `results` sheet; Parquet the points
//! (Snappy-compressed), readable by `analyze` and by any data tool.

use anyhow::{Context, Result, bail};
use spinbench_store::{PointRow, ResultRow, Store, StoreTarget};
use std::path::Path;
use std::sync::Arc;

/// Export formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExportFormat {
    /// Comma-separated points.
    Csv,
    /// A workbook: points and results.
    Xlsx,
    /// Apache Parquet points.
    Parquet,
}

impl ExportFormat {
    /// Parse `csv`, `xlsx` or `parquet`.
    pub fn parse(text: &str) -> Result<ExportFormat> {
        match text.to_ascii_lowercase().as_str() {
            "csv" => Ok(ExportFormat::Csv),
            "xlsx" => Ok(ExportFormat::Xlsx),
            "parquet" => Ok(ExportFormat::Parquet),
            other => bail!("--format {other}: use csv, xlsx or parquet"),
        }
    }
}

/// The columns of a point export, first the seven `analyze` reads.
const POINT_COLUMNS: [&str; 12] = [
    "unit",
    "mount",
    "g_nominal",
    "g_applied",
    "output",
    "direction",
    "run",
    "step",
    "slot",
    "rate_deg_s",
    "std_hz",
    "n",
];

/// Write the run's export to `out` (a file) in `format`.
pub fn export_run(store: &Store, run_id: &str, format: ExportFormat, out: &Path) -> Result<()> {
    match format {
        ExportFormat::Csv => std::fs::write(out, store.points_csv(run_id)?)
            .with_context(|| format!("{}: cannot write", out.display())),
        ExportFormat::Xlsx => {
            write_xlsx(&store.points(run_id)?, &store.results(run_id)?, run_id, out)
        }
        ExportFormat::Parquet => write_parquet(&store.points(run_id)?, run_id, out),
    }
}

fn write_xlsx(points: &[PointRow], results: &[ResultRow], run_id: &str, out: &Path) -> Result<()> {
    use rust_xlsxwriter::{Format, Workbook};
    let mut book = Workbook::new();
    let bold = Format::new().set_bold();
    let sheet = book.add_worksheet().set_name("points")?;
    for (c, h) in POINT_COLUMNS.iter().enumerate() {
        sheet.write_string_with_format(0, c as u16, *h, &bold)?;
    }
    for (i, p) in points.iter().enumerate() {
        let r = (i + 1) as u32;
        sheet.write_string(r, 0, &p.serial)?;
        sheet.write_string(r, 1, p.mount.to_string())?;
        sheet.write_number(r, 2, p.g_nominal)?;
        sheet.write_number(r, 3, p.g_applied)?;
        sheet.write_number(r, 4, p.output_hz)?;
        sheet.write_string(r, 5, p.direction.as_str())?;
        sheet.write_string(r, 6, run_id)?;
        sheet.write_number(r, 7, p.step as f64)?;
        sheet.write_number(r, 8, (p.slot + 1) as f64)?;
        sheet.write_number(r, 9, p.rate_deg_s)?;
        sheet.write_number(r, 10, p.std_hz)?;
        sheet.write_number(r, 11, p.n as f64)?;
    }
    let sheet = book.add_worksheet().set_name("results")?;
    let headers = [
        "serial",
        "slot",
        "mount",
        "outcome",
        "k2_max [µg/g²]",
        "k0 [g]",
        "k1 [Hz/g]",
        "k2 [µg/g²]",
        "k2 ci95 low [µg/g²]",
        "k2 ci95 high [µg/g²]",
        "k3 [µg/g³]",
        "residual rms [µg]",
        "reasons",
    ];
    for (c, h) in headers.iter().enumerate() {
        sheet.write_string_with_format(0, c as u16, *h, &bold)?;
    }
    let mut r = 1u32;
    for result in results {
        let record = &result.record;
        let reasons = record.reasons.join("; ");
        let fits: Vec<(String, Option<&spinbench_analysis::Ieee1293Fit>)> =
            match record.analysis.as_ref().map(|a| &a.fits) {
                Some(fits) if !fits.is_empty() => fits
                    .iter()
                    .map(|(m, f)| (m.to_string(), Some(&f.fit)))
                    .collect(),
                _ => vec![(String::new(), None)],
            };
        for (mount, fit) in fits {
            sheet.write_string(r, 0, &result.serial)?;
            sheet.write_number(r, 1, (result.slot + 1) as f64)?;
            sheet.write_string(r, 2, &mount)?;
            sheet.write_string(r, 3, result.outcome.as_str())?;
            if let Some(k) = result.k2_max_ug_per_g2 {
                sheet.write_number(r, 4, k)?;
            }
            if let Some(f) = fit {
                let ci = f.ci95.k2_ug_per_g2;
                let numbers = [
                    Some(f.k0_g),
                    Some(f.k1),
                    f.k2_ug_per_g2,
                    ci.map(|c| c[0]),
                    ci.map(|c| c[1]),
                    f.k3_ug_per_g3,
                    Some(f.residual_rms_ug),
                ];
                for (k, v) in numbers.iter().enumerate() {
                    if let Some(v) = v {
                        sheet.write_number(r, 5 + k as u16, *v)?;
                    }
                }
            }
            sheet.write_string(r, 12, &reasons)?;
            r += 1;
        }
    }
    book.save(out)
        .with_context(|| format!("{}: cannot write the workbook", out.display()))?;
    Ok(())
}

fn write_parquet(points: &[PointRow], run_id: &str, out: &Path) -> Result<()> {
    use parquet::basic::Compression;
    use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int64Type};
    use parquet::file::properties::WriterProperties;
    use parquet::file::writer::SerializedFileWriter;
    use parquet::schema::parser::parse_message_type;
    let schema = Arc::new(parse_message_type(
        "message points {
            REQUIRED BYTE_ARRAY unit (UTF8);
            REQUIRED BYTE_ARRAY mount (UTF8);
            REQUIRED DOUBLE g_nominal;
            REQUIRED DOUBLE g_applied;
            REQUIRED DOUBLE output;
            REQUIRED BYTE_ARRAY direction (UTF8);
            REQUIRED BYTE_ARRAY run (UTF8);
            REQUIRED INT64 step;
            REQUIRED INT64 slot;
            REQUIRED DOUBLE rate_deg_s;
            REQUIRED DOUBLE std_hz;
            REQUIRED INT64 n;
        }",
    )?);
    let props = Arc::new(
        WriterProperties::builder()
            .set_compression(Compression::SNAPPY)
            .build(),
    );
    let file =
        std::fs::File::create(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let mut writer = SerializedFileWriter::new(file, schema, props)?;
    let mut group = writer.next_row_group()?;
    let text = |f: &dyn Fn(&PointRow) -> String| -> Vec<ByteArray> {
        points
            .iter()
            .map(|p| ByteArray::from(f(p).as_str()))
            .collect()
    };
    let mut column = 0;
    while let Some(mut writer) = group.next_column()? {
        let name = POINT_COLUMNS[column];
        match name {
            "unit" | "mount" | "direction" | "run" => {
                let values = text(&|p: &PointRow| match name {
                    "unit" => p.serial.clone(),
                    "mount" => p.mount.to_string(),
                    "direction" => p.direction.as_str().to_string(),
                    _ => run_id.to_string(),
                });
                writer
                    .typed::<ByteArrayType>()
                    .write_batch(&values, None, None)?;
            }
            "step" | "slot" | "n" => {
                let values: Vec<i64> = points
                    .iter()
                    .map(|p| match name {
                        "step" => p.step,
                        "slot" => p.slot + 1,
                        _ => p.n,
                    })
                    .collect();
                writer
                    .typed::<Int64Type>()
                    .write_batch(&values, None, None)?;
            }
            _ => {
                let values: Vec<f64> = points
                    .iter()
                    .map(|p| match name {
                        "g_nominal" => p.g_nominal,
                        "g_applied" => p.g_applied,
                        "output" => p.output_hz,
                        "rate_deg_s" => p.rate_deg_s,
                        _ => p.std_hz,
                    })
                    .collect();
                writer
                    .typed::<DoubleType>()
                    .write_batch(&values, None, None)?;
            }
        }
        writer.close()?;
        column += 1;
    }
    group.close()?;
    writer.close()?;
    Ok(())
}

/// Refuse an `export --out` path that would destroy something: an existing
/// file (unless `force`), and never, even with `force`, the store itself
/// (or its WAL and shared-memory files), another SQLite database, or a file
/// inside a run directory (its journal, capture, plan or reports).
pub fn check_out_path(out: &Path, db: &StoreTarget, force: bool) -> Result<()> {
    let shown = out.display();
    if out.is_dir() {
        bail!("--out {shown}: is a directory; give a file name");
    }
    // Compare real paths: `d/./spinbench.db` and a symbolic link are the store too.
    let real = |p: &Path| -> Option<std::path::PathBuf> {
        match std::fs::canonicalize(p) {
            Ok(r) => Some(r),
            Err(_) => {
                let parent = p.parent().filter(|d| !d.as_os_str().is_empty())?;
                Some(std::fs::canonicalize(parent).ok()?.join(p.file_name()?))
            }
        }
    };
    let target = real(out);
    if let (StoreTarget::File(store), Some(target)) = (db, &target) {
        for suffix in ["", "-wal", "-shm", "-journal"] {
            let mut name = store.as_os_str().to_owned();
            name.push(suffix);
            if real(Path::new(&name)).as_ref() == Some(target) {
                bail!("--out {shown}: that is the store{suffix} itself; export to another file");
            }
        }
    }
    if let Some(target) = &target
        && target
            .ancestors()
            .skip(1)
            .any(|dir| dir.join(spinbench_engine::journal::JOURNAL_FILE).is_file())
    {
        bail!(
            "--out {shown}: inside a run directory (its records are never overwritten); export elsewhere"
        );
    }
    if out.exists() {
        let mut head = [0u8; 16];
        let is_database = std::fs::File::open(out)
            .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
            .is_ok()
            && head.starts_with(b"SQLite format 3\0");
        if is_database {
            bail!("--out {shown}: is an SQLite database; export to another file");
        }
        if !force {
            bail!("--out {shown}: exists; give --force to replace it, or another file name");
        }
    }
    Ok(())
}

//! The commands that write reports from the store (`report`,
//! `batch-report`) and `replay` (a run's raw bytes checked against it).

use super::{ReportOutput, open_store};
use anyhow::{Context, Result};
use spinbench_store::StoreTarget;
use std::io::Write;
use std::path::{Path, PathBuf};

/// `spinbench report RUN`.
pub(super) fn report(run: &str, o: &ReportOutput, out: &mut dyn Write) -> Result<()> {
    let store = open_store(&o.db)?;
    let run = &store.resolve_run(run)?;
    let files = spinbench_report::write_reports_in(
        &store,
        run,
        &report_formats(&o.format)?,
        &o.out,
        o.lang,
    )
    .with_context(|| format!("{}: report of run '{run}'", o.db))?;
    print_paths(out, &files)?;
    Ok(())
}

/// `spinbench batch-report [RUN…]`.
pub(super) fn batch_report(
    runs: &[String],
    baseline_runs: usize,
    o: &ReportOutput,
    out: &mut dyn Write,
) -> Result<()> {
    let store = open_store(&o.db)?;
    let runs = runs
        .iter()
        .map(|r| store.resolve_run(r))
        .collect::<Result<Vec<_>, _>>()?;
    let files = spinbench_report::write_batch_reports(
        &store,
        &runs,
        baseline_runs,
        &report_formats(&o.format)?,
        &o.out,
        o.lang,
    )
    .with_context(|| format!("{}: batch report", o.db))?;
    print_paths(out, &files)?;
    Ok(())
}

/// `spinbench replay RUN`.
pub(super) fn replay(
    run: &str,
    data: &Path,
    db: Option<StoreTarget>,
    out: &mut dyn Write,
) -> Result<()> {
    let given = Path::new(run);
    let dir = if given.join(crate::paths::STATION_FILE).exists() {
        given.to_path_buf()
    } else {
        data.join(crate::paths::RUNS_DIR).join(run)
    };
    if !dir.is_dir() {
        anyhow::bail!(
            "{}: no such run directory (give a run id under --data, or the run's directory)",
            dir.display()
        );
    }
    let db = db.unwrap_or_else(|| {
        StoreTarget::File(
            dir.parent()
                .and_then(Path::parent)
                .unwrap_or(data)
                .join(crate::paths::DB_FILE),
        )
    });
    let store = open_store(&db)?;
    let report = crate::replay::replay(&dir, &store)?;
    for m in &report.modules {
        writeln!(
            out,
            "module {}: {} bytes, {} frames ({} bad), {} whole one-second windows{}",
            m.module,
            m.bytes,
            m.frames,
            m.bad_frames,
            m.windows,
            if m.cut_short {
                " (capture cut short: read up to its last flush)"
            } else {
                ""
            }
        )?;
    }
    writeln!(
        out,
        "one-second values: {} of {} stored found bit-exact in the replay",
        report.values_matched, report.values_stored
    )?;
    writeln!(
        out,
        "points: {} of {} stored re-derived from the replayed values (largest difference {:.3e} Hz)",
        report.points_matched, report.points_stored, report.max_point_diff_hz
    )?;
    if !report.all_match() {
        anyhow::bail!("the replay does not reproduce everything the store holds");
    }
    writeln!(out, "the raw bytes reproduce the stored run")?;
    Ok(())
}

/// The report formats of `--format` (all four when none is given).
fn report_formats(given: &[String]) -> Result<Vec<spinbench_report::ReportFormat>> {
    use spinbench_report::ReportFormat;
    if given.is_empty() {
        return Ok(ReportFormat::ALL.to_vec());
    }
    given
        .iter()
        .map(|f| {
            ReportFormat::parse(f)
                .with_context(|| format!("--format {f}: use pdf, html, xlsx or csv"))
        })
        .collect()
}

/// One path per line.
fn print_paths(out: &mut dyn Write, paths: &[PathBuf]) -> Result<()> {
    for path in paths {
        writeln!(out, "{}", path.display())?;
    }
    Ok(())
}

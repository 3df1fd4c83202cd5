//! The commands that read runs back: `runs list`, `runs show`, `unit`
//! (every run of one serial, with its repeatability) and `export`.

use super::open_store;
use anyhow::Result;
use spinbench_store::StoreTarget;
use std::io::Write;
use std::path::PathBuf;

/// `spinbench runs list`.
pub(super) fn runs_list(db: &StoreTarget, out: &mut dyn Write) -> Result<()> {
    let store = open_store(db)?;
    let runs = store.runs()?;
    // The label column as wide as its longest (a station's name sets it).
    let width = runs
        .iter()
        .map(|r| r.label().chars().count())
        .max()
        .unwrap_or(0)
        .max("label".len());
    writeln!(
        out,
        "{:<width$}  {:<28} {:<10} {:>6} {:>7}",
        "label", "run", "state", "units", "points"
    )?;
    for r in runs {
        let label = r.label();
        let pad = width.saturating_sub(label.chars().count());
        writeln!(
            out,
            "{label}{:pad$}  {:<28} {:<10} {:>6} {:>7}",
            "", r.id, r.state, r.units, r.points
        )?;
    }
    Ok(())
}

/// `spinbench runs show RUN`.
pub(super) fn runs_show(run: &str, db: &StoreTarget, out: &mut dyn Write) -> Result<()> {
    let store = open_store(db)?;
    let run = &store.resolve_run(run)?;
    let Some(r) = store.run(run)? else {
        anyhow::bail!("{db}: no run '{run}' (see `spinbench runs list`)");
    };
    writeln!(
        out,
        "run {} ({}) — {} — {}{}",
        r.label(),
        r.id,
        r.station,
        r.state,
        r.reason.map(|x| format!(": {x}")).unwrap_or_default()
    )?;
    for u in store.results(run)? {
        let judged = match &u.unreadable {
            Some(why) => format!("its stored record cannot be read ({why})"),
            None => u.record.judged_text(),
        };
        writeln!(
            out,
            "  slot {:>2} {:<12} {:<12} {judged}",
            u.slot + 1,
            u.serial,
            u.outcome,
        )?;
    }
    Ok(())
}

/// `spinbench unit SERIAL`.
pub(super) fn unit(serial: &str, db: &StoreTarget, out: &mut dyn Write) -> Result<()> {
    let store = open_store(db)?;
    let history = store.unit_history(serial)?;
    if history.is_empty() {
        anyhow::bail!("{db}: no results for serial '{serial}'");
    }
    for h in &history {
        let p_k1 = h
            .record
            .analysis
            .as_ref()
            .and_then(|a| a.fits.get(&spinbench_analysis::Mount::P))
            .map(|f| f.fit.k1);
        writeln!(
            out,
            "{:<28} slot {:>2} {:<12} k1(P) {:>12}  {}",
            h.run_id,
            h.slot + 1,
            h.outcome,
            p_k1.map_or("—".into(), |v| format!("{v:.6}")),
            h.record.judged_text()
        )?;
    }
    // The one definition of repeatability (as `analyze` and the batch
    // report give it), over the tests measured whole.
    let measured: Vec<&spinbench_analysis::UnitAnalysis> = history
        .iter()
        .filter(|h| h.outcome != spinbench_engine::Outcome::Incomplete)
        .filter_map(|h| h.record.analysis.as_ref())
        .collect();
    match spinbench_analysis::unit::repeatability_of(&measured) {
        Some(r) => writeln!(
            out,
            "scale-factor repeatability over {} runs: {:.3} ppm (bias {:.1} µg)",
            r.runs, r.scale_factor_ppm, r.bias_ug
        )?,
        None => writeln!(out, "scale-factor repeatability: needs at least two runs")?,
    }
    Ok(())
}

/// `spinbench export RUN`.
pub(super) fn export(
    run: &str,
    format: &str,
    file: Option<PathBuf>,
    force: bool,
    db: &StoreTarget,
    out: &mut dyn Write,
) -> Result<()> {
    let format = crate::export::ExportFormat::parse(format)?;
    if let Some(f) = &file {
        crate::export::check_out_path(f, db, force)?;
    }
    let store = open_store(db)?;
    let run = &store.resolve_run(run)?;
    match (file, format) {
        (Some(f), _) => crate::export::export_run(&store, run, format, &f)?,
        (None, crate::export::ExportFormat::Csv) => write!(out, "{}", store.points_csv(run)?)?,
        (None, _) => {
            anyhow::bail!("--out FILE is needed for xlsx and parquet (binary formats)")
        }
    }
    Ok(())
}

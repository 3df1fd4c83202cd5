//! The `spinbench` command line: the arguments (parsed in one place,
//! `args`) and the dispatch (here) to one module per command.
//!
//! | module | commands |
//! |---|---|
//! | this | `analyze`, `demo`, `serve` (their work lives in [`crate::points_file`], [`crate::demo`], [`crate::web`]) |
//! | `run` | `run` |
//! | `plan_design` | `plan design` |
//! | `records` | `runs list`, `runs show`, `unit`, `export` |
//! | `reports` | `report`, `batch-report`, `replay` |
//! | `sim` | `sim` |
//! | `user` | `user add`, `user list` |

mod args;

pub use args::{
    Cli, Command, EquipmentAction, PlanAction, ReportOutput, RunsAction, TokenAction, UserAction,
};

use crate::paths::parse_store;
use crate::points_file::read_points_file;
use crate::render::render_dataset;
use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use spinbench_analysis::exclusion::LevelExclusion;
use spinbench_analysis::uncertainty::TypeBInputs;
use spinbench_analysis::{AnalysisOptions, DatasetAnalysis, ModelOrder, analyze_dataset};
use spinbench_store::StoreTarget;
use std::io::Write;
use std::path::{Path, PathBuf};

mod backup;
mod equipment;
mod plan_design;
mod records;
mod reports;
mod run;
#[cfg(feature = "sim")]
mod sim;
mod user;

/// Open an existing store to read it (a missing file is an error, not a
/// new empty store; a read-only file or disk can be read).
fn open_store(db: &StoreTarget) -> Result<spinbench_store::Store> {
    if let StoreTarget::File(path) = db
        && !path.exists()
    {
        anyhow::bail!(
            "{}: no store here; runs are stored under --data (default spinbench-data), or give --db",
            path.display()
        );
    }
    Ok(spinbench_store::Store::open_read_only(db)?)
}

/// Read and reduce a points file.
pub fn analyze_file(file: &Path, order: u8, sheet: Option<&str>) -> Result<DatasetAnalysis> {
    analyze_file_excluding(file, order, sheet, Vec::new(), AnalysisOptions::default())
}

/// Read and check a Type B inputs file (`analyze --type-b`).
pub fn read_type_b(file: &Path) -> Result<TypeBInputs> {
    let text = std::fs::read_to_string(file)
        .with_context(|| format!("cannot read the Type B inputs {}", file.display()))?;
    anyhow::ensure!(
        text.len() <= 64 * 1024,
        "{}: a Type B inputs file is a few lines; this one is {} bytes",
        file.display(),
        text.len()
    );
    let inputs: TypeBInputs =
        toml::from_str(&text).with_context(|| format!("{}: not Type B inputs", file.display()))?;
    inputs
        .validate()
        .map_err(|e| anyhow::anyhow!("{}: {e}", file.display()))?;
    Ok(inputs)
}

/// Read a points file, leave out the excluded levels, reduce it; the
/// exclusions (with how many readings each removed) are in the result.
pub fn analyze_file_excluding(
    file: &Path,
    order: u8,
    sheet: Option<&str>,
    mut exclusions: Vec<LevelExclusion>,
    options: AnalysisOptions,
) -> Result<DatasetAnalysis> {
    let order = ModelOrder::from_degree(order)
        .with_context(|| format!("model order {order} is not 1, 2 or 3"))?;
    let mut points = read_points_file(file, sheet)?;
    for w in &points.warnings {
        eprintln!("warning: {w}");
    }
    spinbench_analysis::exclusion::apply_all(&mut points.units, &mut exclusions)
        .with_context(|| file.display().to_string())?;
    let mut analysis = analyze_dataset(&points.units, AnalysisOptions { order, ..options });
    analysis.exclusions = exclusions;
    for r in points.rejected {
        analysis.failed.push(spinbench_analysis::unit::UnitFailure {
            unit: r.unit,
            run: r.run,
            error: format!(
                "bad row(s), the unit is not reduced: {}",
                r.errors.join("; ")
            ),
        });
    }
    Ok(analysis)
}

/// Run a parsed command line, writing its output to `out`.
pub fn run(cli: Cli, out: &mut dyn Write) -> Result<()> {
    match cli.command {
        Command::Analyze {
            file,
            json,
            order,
            sheet,
            exclude_level,
            reason,
            type_b,
            anomalies,
            by,
        } => {
            let type_b = type_b
                .as_deref()
                .map(read_type_b)
                .transpose()?
                .unwrap_or_default();
            let by = match by {
                Some(name) if !name.trim().is_empty() => name.trim().to_string(),
                Some(_) => bail!("--by: give the name of who makes the exclusion"),
                None => crate::users::os_user(),
            };
            let exclusions = exclude_level
                .iter()
                .map(|e| LevelExclusion::parse(e, reason.as_deref().unwrap_or(""), &by))
                .collect::<Result<Vec<_>, _>>()?;
            let analysis = analyze_file_excluding(
                &file,
                order,
                sheet.as_deref(),
                exclusions,
                AnalysisOptions {
                    type_b,
                    anomalies,
                    ..AnalysisOptions::default()
                },
            )?;
            if json {
                serde_json::to_writer_pretty(&mut *out, &analysis)?;
                writeln!(out)?;
            } else {
                write!(
                    out,
                    "{}",
                    render_dataset(&file.display().to_string(), &analysis)
                )?;
            }
            // Every unit that could be reduced is printed; the exit status
            // says whether some could not (each named above, and here).
            if !analysis.failed.is_empty() {
                out.flush()?;
                let names: Vec<String> = analysis
                    .failed
                    .iter()
                    .map(|f| format!("{}: {}", f.unit, f.error))
                    .collect();
                anyhow::bail!(
                    "{}: {} of {} unit(s) could not be reduced (the others are above):\n  {}",
                    file.display(),
                    analysis.failed.len(),
                    analysis.failed.len() + analysis.units.len(),
                    names.join("\n  ")
                );
            }
            Ok(())
        }
        #[cfg(feature = "sim")]
        Command::Demo {
            bench,
            tumble_positions,
            temperatures,
            levels,
            target_k2_u95,
            anomalies,
            decide_on,
            sequential,
            published,
            json,
            data,
            db,
        } => crate::demo::demo(
            &bench,
            crate::demo::DemoPlanChoice {
                tumble_positions,
                temperatures_c: temperatures,
                levels_g: (!levels.is_empty()).then_some(levels),
                target_k2_u95,
                anomalies,
                decide_on,
                sequential_levels_per_pass: sequential,
                published,
            },
            json,
            &data,
            db.as_ref(),
            out,
        ),
        Command::Run {
            plan,
            station,
            simulate,
            bench,
            resume,
            override_overdue,
            data,
            quiet,
            db,
        } => run::run_plan(
            run::Source::file(&plan, "plan")?,
            station
                .as_deref()
                .map(|p| run::Source::file(p, "station config"))
                .transpose()?,
            simulate_with(simulate, &bench)?,
            &bench,
            resume.as_deref(),
            &data,
            db,
            quiet,
            override_overdue.as_deref(),
            out,
        ),
        Command::Retest {
            run,
            include_fails,
            station,
            simulate,
            bench,
            data,
            quiet,
            db,
        } => run::retest(
            &run,
            spinbench_engine::retest::RetestChoice { include_fails },
            station.as_deref(),
            simulate_with(simulate, &bench)?,
            &bench,
            &data,
            db,
            quiet,
            out,
        ),
        Command::Runs {
            action: RunsAction::List { db },
        } => records::runs_list(&db, out),
        Command::Runs {
            action: RunsAction::Show { run, db },
        } => records::runs_show(&run, &db, out),
        Command::Unit { serial, db } => records::unit(&serial, &db, out),
        Command::Export {
            run,
            format,
            out: file,
            force,
            db,
        } => records::export(&run, &format, file, force, &db, out),
        Command::Report { run, output } => reports::report(&run, &output, out),
        Command::BatchReport {
            runs,
            baseline_runs,
            output,
        } => reports::batch_report(&runs, baseline_runs as usize, &output, out),
        Command::Replay { run, data, db } => reports::replay(&run, &data, db, out),
        Command::Serve { args } => crate::web::serve(args, out),
        Command::Backup { dir, db, data } => backup::backup(&dir, &db, data.as_deref(), out),
        Command::Doctor {
            station,
            simulate,
            bench,
            data,
            db,
        } => {
            let db = db.unwrap_or_else(|| StoreTarget::File(data.join(crate::run_setup::DB_FILE)));
            let simulated = simulate_with(simulate, &bench)?.then_some(&bench);
            crate::doctor::run(station.as_deref(), simulated, &db, &data, out)
        }
        Command::Restore { backup, db } => backup::restore(&backup, &db, out),
        Command::Migrate {
            db,
            history,
            grant,
            grant_analyst,
        } => backup::migrate(&db, history, (&grant, &grant_analyst), out),
        Command::Prune {
            older_than,
            archive,
            dry_run,
            db,
        } => crate::prune::prune(&db, older_than, &archive, dry_run, out).map(|_| ()),
        Command::Equipment { action } => match action {
            EquipmentAction::List { station, db } => equipment::list(station.as_deref(), &db, out),
            EquipmentAction::Set {
                role,
                identity,
                certificate,
                calibrated,
                due,
                station,
                db,
            } => equipment::set(
                &equipment::Entry {
                    role: &role,
                    identity: &identity,
                    certificate: &certificate,
                    calibrated: &calibrated,
                    due: &due,
                    station: station.as_deref(),
                },
                &db,
                out,
            ),
        },
        Command::User { action } => match action {
            UserAction::Add { name, role, db } => user::add(&name, &role, &db, out),
            UserAction::List { db } => user::list(&db, out),
            UserAction::Role { name, role, db } => {
                user::change(&name, Some(&role), false, &db, out)
            }
            UserAction::Passwd { name, db } => user::change(&name, None, true, &db, out),
            UserAction::Remove { name, db } => user::remove(&name, &db, out),
        },
        Command::Token { action } => match action {
            TokenAction::Add { name, role, db } => user::add_token(&name, &role, &db, out),
            TokenAction::List { db } => user::list_tokens(&db, out),
            TokenAction::Revoke { name, db } => user::revoke_token(&name, &db, out),
        },
        Command::Plan { action } => match action {
            PlanAction::Design {
                target_k2_u95,
                plan,
                station,
                runs,
                data,
                db,
                json,
            } => {
                let db =
                    db.unwrap_or_else(|| StoreTarget::File(data.join(crate::run_setup::DB_FILE)));
                plan_design::design(
                    plan_design::DesignArgs {
                        target_k2_u95,
                        plan: plan.as_deref(),
                        station: station.as_deref(),
                        runs: runs as usize,
                        db: &db,
                        json,
                    },
                    out,
                )
            }
        },
        #[cfg(feature = "sim")]
        Command::Sim {
            bench,
            speed,
            tcp,
            truth,
            run_for,
        } => sim::run_sim(&bench, speed, tcp, truth, run_for, out),
    }
}

/// `--simulate`, checked with the bench's arguments: a bench config file
/// is for the virtual bench only.
fn simulate_with(simulate: bool, bench: &crate::virtual_bench::BenchArgs) -> Result<bool> {
    if bench.names_a_file() && !simulate {
        anyhow::bail!(
            "--bench names a virtual bench's config: add --simulate to run on the virtual bench"
        );
    }
    Ok(simulate)
}

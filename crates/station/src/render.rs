//! Human-readable output of `spinbench analyze`: one table per unit.

use spinbench_analysis::model::Interval;
use spinbench_analysis::uncertainty::Uncertainty;
use spinbench_analysis::unit::UnitAnalysis;
use spinbench_analysis::{DatasetAnalysis, Mount, MountingFit};
use std::fmt::Write;

/// `value ± half-width` of a 95 % interval, or the bare value.
fn with_ci(value: f64, ci: Option<Interval>, decimals: usize) -> String {
    match ci {
        Some([lo, hi]) => format!("{value:+.decimals$} ± {:.decimals$}", (hi - lo) / 2.0),
        None => format!("{value:+.decimals$}"),
    }
}

fn opt(value: Option<f64>, decimals: usize, unit: &str) -> String {
    value.map_or_else(|| "—".to_string(), |v| format!("{v:.decimals$}{unit}"))
}

/// `value ± U95` of the GUM budget, or the bare value: the one interval a
/// coefficient is printed with (the regression interval, which ignores the
/// budget's other sources, is in the JSON as `ci95`).
fn with_u95(value: f64, u: Option<&Uncertainty>, decimals: usize) -> String {
    match u {
        Some(u) => format!("{value:+.decimals$} ± {:.decimals$}", u.u95),
        None => format!("{value:+.decimals$}"),
    }
}

/// The table rows of one mounting's fit: (label, text), each coefficient
/// with its budget's U95 (the regression interval when no budget could be made).
fn fit_rows(mounting: &MountingFit) -> Vec<(&'static str, String)> {
    let fit = &mounting.fit;
    let ci = &fit.ci95;
    let interval = |value: f64,
                    u: Option<&Option<Uncertainty>>,
                    ci: Option<Interval>,
                    decimals: usize| match mounting.uncertainty {
        Some(_) => with_u95(value, u.and_then(Option::as_ref), decimals),
        None => with_ci(value, ci, decimals),
    };
    let u = mounting.uncertainty.as_ref();
    vec![
        (
            "points / levels",
            format!("{} / {}", fit.points, fit.levels),
        ),
        ("k0 [g]", interval(fit.k0_g, u.map(|u| &u.k0_g), ci.k0_g, 7)),
        (
            "k1 [output/g]",
            interval(fit.k1, u.map(|u| &u.k1), ci.k1, 6),
        ),
        (
            "k2 [µg/g²]",
            fit.k2_ug_per_g2.map_or_else(
                || "—".into(),
                |v| interval(v, u.map(|u| &u.k2_ug_per_g2), ci.k2_ug_per_g2, 3),
            ),
        ),
        (
            "k3 [µg/g³]",
            fit.k3_ug_per_g3.map_or_else(
                || "—".into(),
                |v| interval(v, u.map(|u| &u.k3_ug_per_g3), ci.k3_ug_per_g3, 4),
            ),
        ),
        ("residual RMS [µg]", format!("{:.3}", fit.residual_rms_ug)),
        ("R²", opt(fit.r_squared, 12, "")),
        ("AIC / BIC", format!("{:.2} / {:.2}", fit.aic, fit.bic)),
    ]
}

/// Render a whole dataset analysis for a terminal.
pub fn render_dataset(source: &str, analysis: &DatasetAnalysis) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "spinbench analyze {source}: {} unit(s), order-{} model k1·(k0 + a + k2·a² + k3·a³), method.md (2)",
        analysis.units.len(),
        analysis.order.degree()
    );
    let _ = writeln!(
        out,
        "± is the expanded uncertainty U95 of each coefficient's GUM budget (repeatability, model inadequacy when the model does not fit, and the Type B inputs given); the full-range fits are secondary figures, printed without an interval (their regression intervals are in the JSON)"
    );
    for e in &analysis.exclusions {
        let _ = writeln!(out, "{e}");
    }
    for t in &analysis.table_signatures {
        let run = t
            .run
            .as_deref()
            .map(|r| format!(" (run {r})"))
            .unwrap_or_default();
        let _ = writeln!(
            out,
            "{}{run}; each point's applied acceleration corrected by it, its uncertainty in the budget (table signature)",
            t.signature.describe()
        );
    }
    for e in analysis.units.iter().flat_map(|u| &u.rule_exclusions) {
        let _ = writeln!(out, "{e}");
    }
    for unit in &analysis.units {
        out.push('\n');
        render_unit(&mut out, unit);
    }
    for f in &analysis.failed {
        let run = f
            .run
            .as_deref()
            .map(|r| format!(" run {r}"))
            .unwrap_or_default();
        let _ = writeln!(out, "\n== {}{run} — NOT REDUCED ==\n  {}", f.unit, f.error);
    }
    out
}

fn render_unit(out: &mut String, unit: &UnitAnalysis) {
    let mounts: Vec<String> = unit.fits.keys().map(Mount::to_string).collect();
    let run = unit
        .run
        .as_deref()
        .map(|r| format!(" run {r}"))
        .unwrap_or_default();
    let _ = writeln!(
        out,
        "== {}{run} — mounting {} ==",
        unit.unit,
        mounts.join(" and ")
    );

    // The per-mounting fits side by side (method.md §3.4).
    const LABEL: usize = 22;
    const COLUMN: usize = 30;
    let _ = write!(out, "  {:LABEL$}", "per mounting, vs |a|");
    for fit in unit.fits.values() {
        let head = match fit.mount {
            Mount::P => "P (IA toward axis)",
            Mount::N => "N (IA away from axis)",
        };
        let _ = write!(out, "{head:COLUMN$}");
    }
    out.truncate(out.trim_end().len());
    out.push('\n');
    let columns: Vec<Vec<(&str, String)>> = unit.fits.values().map(fit_rows).collect();
    if let Some(first) = columns.first() {
        for (row, (label, _)) in first.iter().enumerate() {
            let _ = write!(out, "  {label:LABEL$}");
            for col in &columns {
                let _ = write!(out, "{:COLUMN$}", col[row].1);
            }
            out.truncate(out.trim_end().len());
            out.push('\n');
        }
    }
    if let (Some(k2), Some(m)) = (unit.k2_max_ug_per_g2, unit.k2_max_mount) {
        let _ = writeln!(out, "  k2_max = {k2:.3} µg/g² (mounting {m})");
    }
    if let Some(j) = &unit.joint {
        let _ = writeln!(out, "  {j}");
    }

    if let Some(full) = &unit.full_range {
        let f = &full.fit;
        let mounts: Vec<String> = full.mounts.iter().map(Mount::to_string).collect();
        let _ = writeln!(
            out,
            "  full range, signed input ({}): K0 = {:+.7} g, K1 = {:+.6}, K2 = {} µg/g², K3 = {} µg/g³, residual RMS {:.3} µg",
            mounts.join("+"),
            f.k0_g,
            f.k1,
            opt(f.k2_ug_per_g2, 4, ""),
            opt(f.k3_ug_per_g3, 5, ""),
            f.residual_rms_ug,
        );
    }
    if let Some(k) = unit.full_range.as_ref().and_then(|f| f.with_koq.as_ref()) {
        let _ = writeln!(
            out,
            "  full range with Koq·a·|a| (method.md (12)): K2 = {:.3} µg/g², Koq (+ arm stretch) = {:.3} µg/g², residual RMS {:.3} µg",
            k.k2_ug_per_g2, k.koq_ug_per_g2, k.residual_rms_ug
        );
    }
    if let Some(sf) = &unit.scale_factor {
        let _ = writeln!(
            out,
            "  scale factor (10)-(11) K1(a) = KA + KB·a + KC·a²: KA = {:.6}, KB/KA = {:.3} µg/g², KC/KA = {:.4} µg/g³; residual max {:.3} ppm, RMS {:.3} ppm",
            sf.ka,
            sf.kb_over_ka_ug_per_g2,
            sf.kc_over_ka_ug_per_g3,
            sf.residual_max_ppm,
            sf.residual_rms_ppm
        );
    }
    let fig = &unit.figures;
    let nonlinearity = fig.nonlinearity.map_or_else(
        || "—".into(),
        |n| {
            format!(
                "{:.3} ppm FS (at {:+.1} g, FS {:.1} g)",
                n.ppm_fs, n.at_g, n.full_scale_g
            )
        },
    );
    let hysteresis = fig.hysteresis.map_or_else(
        || "—".into(),
        |h| format!("{:+.3} µg ({} at {} g)", h.ug, h.mount, h.g_nominal),
    );
    let repeatability = fig.repeatability.as_ref().map_or_else(
        || "—".into(),
        |r| {
            format!(
                "{:.3} ppm over {} runs (bias {:.3} µg)",
                r.scale_factor_ppm, r.runs, r.bias_ug
            )
        },
    );
    let _ = writeln!(
        out,
        "  figures: asymmetry {}; nonlinearity {nonlinearity}; hysteresis {hysteresis}; repeatability {repeatability}",
        opt(fig.asymmetry_ppm, 3, " ppm"),
    );
    for fit in unit.fits.values() {
        if let Some(d) = &fit.diagnostics {
            let _ = writeln!(out, "  diagnostics {}: {d}", fit.mount);
        }
        if let Some(u) = fit
            .uncertainty
            .as_ref()
            .and_then(|u| u.k2_ug_per_g2.as_ref())
        {
            let _ = writeln!(out, "  k2 {} budget (GUM, µg/g²): {u}", fit.mount);
        }
    }
    if let Some(u) = unit.joint.as_ref().and_then(|j| j.uncertainty.as_ref()) {
        let _ = writeln!(out, "  K2 budget (GUM, µg/g²): {}", u.k2_even_ug_per_g2);
    }
    for (mount, cmp) in &unit.model_comparison {
        let ranked: Vec<String> = cmp
            .candidates
            .iter()
            .map(|c| {
                format!(
                    "{} Δ{:.1} w{:.2} ({:.3} µg)",
                    c.model, c.delta, c.weight, c.residual_rms_ug
                )
            })
            .collect();
        let _ = writeln!(
            out,
            "  models {mount}, by {}: {}",
            cmp.criterion.to_uppercase(),
            ranked.join(", ")
        );
    }
    for note in &unit.notes {
        let _ = writeln!(out, "  note: {note}");
    }
}

//! Human-readable output of `spinbench analyze`: one table per unit.

use spinbench_analysis::model::Interval;
use spinbench_analysis::unit::UnitAnalysis;
use spinbench_analysis::{DatasetAnalysis, Ieee1293Fit, Mount};
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

/// The table rows of one fit: (label, text).
fn fit_rows(fit: &Ieee1293Fit) -> Vec<(&'static str, String)> {
    let ci = &fit.ci95;
    vec![
        (
            "points / levels",
            format!("{} / {}", fit.points, fit.levels),
        ),
        ("k0 [g]", with_ci(fit.k0_g, ci.k0_g, 7)),
        ("k1 [output/g]", with_ci(fit.k1, ci.k1, 6)),
        (
            "k2 [µg/g²]",
            fit.k2_ug_per_g2
                .map_or_else(|| "—".into(), |v| with_ci(v, ci.k2_ug_per_g2, 3)),
        ),
        (
            "k3 [µg/g³]",
            fit.k3_ug_per_g3
                .map_or_else(|| "—".into(), |v| with_ci(v, ci.k3_ug_per_g3, 4)),
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
    let _ = writeln!(out, "uncertainties are 95 % intervals (Student t)");
    for e in &analysis.exclusions {
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
    let columns: Vec<Vec<(&str, String)>> = unit.fits.values().map(|f| fit_rows(&f.fit)).collect();
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
            "  full range, signed input ({}): K0 = {} g, K1 = {}, K2 = {} µg/g², K3 = {} µg/g³, residual RMS {:.3} µg",
            mounts.join("+"),
            with_ci(f.k0_g, f.ci95.k0_g, 7),
            with_ci(f.k1, f.ci95.k1, 6),
            f.k2_ug_per_g2
                .map_or_else(|| "—".into(), |v| with_ci(v, f.ci95.k2_ug_per_g2, 4)),
            f.k3_ug_per_g3
                .map_or_else(|| "—".into(), |v| with_ci(v, f.ci95.k3_ug_per_g3, 5)),
            f.residual_rms_ug,
        );
    }
    if let Some(k) = unit.full_range.as_ref().and_then(|f| f.with_koq.as_ref()) {
        let ci = |c: Option<[f64; 2]>| {
            c.map_or_else(
                || "—".into(),
                |[lo, hi]| format!("± {:.3}", 0.5 * (hi - lo)),
            )
        };
        let _ = writeln!(
            out,
            "  full range with Koq·a·|a| (method.md (12)): K2 = {:.3} {} µg/g², Koq (+ arm stretch) = {:.3} {} µg/g², residual RMS {:.3} µg",
            k.k2_ug_per_g2,
            ci(k.k2_ci95),
            k.koq_ug_per_g2,
            ci(k.koq_ci95),
            k.residual_rms_ug
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

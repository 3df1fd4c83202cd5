//! The lines under an instrument's figures in a report: levels left out, its
//! temperatures, its temperature coefficients, how its radius was read, the
//! reduction's verdict on its model per mounting, the uncertainty budgets and
//! the two mountings reduced together (method.md (15)). Every line is worded
//! from the catalogue (`diag.*` in `locales/spinbench.yml`) in the report's
//! language; the numbers are formatted here, once, for both.

use crate::UnitReport;
use crate::lang::{self, Lang};
use spinbench_analysis::diagnostics::Diagnostics;
use spinbench_analysis::joint::JointK2;
use spinbench_analysis::uncertainty::{Uncertainty, sig};
use std::collections::BTreeMap;

/// The catalogue's `key` in `lang` filled with `args` (the key itself when
/// the catalogue cannot word it, so a gap shows rather than hides).
fn line(lang: Lang, key: &str, args: &[(&str, String)]) -> String {
    let args: BTreeMap<String, String> = args
        .iter()
        .map(|(k, v)| (k.to_string(), v.clone()))
        .collect();
    lang::fill(lang, key, &args).unwrap_or_else(|| key.to_string())
}

/// The reduction's own verdict on its model, a line per mounting, and the
/// two mountings reduced together (method.md (15)), in English.
pub fn diagnostic_lines(u: &UnitReport) -> Vec<String> {
    diagnostic_lines_in(u, Lang::En)
}

/// [`diagnostic_lines`] in `lang`.
pub fn diagnostic_lines_in(u: &UnitReport, lang: Lang) -> Vec<String> {
    let r = u.record();
    let mut lines: Vec<String> = r
        .exclusions
        .iter()
        .chain(r.analysis.iter().flat_map(|a| &a.rule_exclusions))
        .map(|e| lang::exclusion(lang, e))
        .collect();
    if let Some(text) = temperature_line_in(&r.points, lang) {
        lines.push(text);
    }
    if let Some(c) = &r.temperature_coefficients {
        let k2 = match (c.k2_ug_per_g2_per_c, c.k2_ug_per_g2_per_c_u95) {
            (Some(v), Some(u)) => line(
                lang,
                "diag.tempco_k2",
                &[("value", format!("{v:+.4}")), ("u95", format!("{u:.4}"))],
            ),
            _ => String::new(),
        };
        lines.push(line(
            lang,
            "diag.tempco",
            &[
                ("temperatures", c.temperatures.to_string()),
                ("k0", format!("{:+.2}", c.k0_ug_per_c)),
                ("k0_u95", format!("{:.2}", c.k0_ug_per_c_u95)),
                ("k1", format!("{:+.2}", c.k1_ppm_per_c)),
                ("k1_u95", format!("{:.2}", c.k1_ppm_per_c_u95)),
                ("k2", k2),
            ],
        ));
    }
    if !r.radius_reading_u_ppm.is_empty() || r.cross_axis_ug_per_g.is_some() {
        let radius: Vec<String> = r
            .radius_reading_u_ppm
            .iter()
            .map(|(m, u)| {
                let name = match m {
                    spinbench_analysis::Mount::P => "R+",
                    spinbench_analysis::Mount::N => "R−",
                };
                format!("{name} ±{u:.1} ppm")
            })
            .collect();
        let radius = radius.join(", ");
        lines.push(match r.cross_axis_ug_per_g {
            Some(c) => line(
                lang,
                "diag.radius_cross_axis",
                &[("radius", radius), ("cross_axis", format!("{c:+.1}"))],
            ),
            None => line(lang, "diag.radius_no_cross_axis", &[("radius", radius)]),
        });
    }
    let Some(a) = r.analysis.as_ref() else {
        return lines;
    };
    for (mount, fit) in &a.fits {
        if let Some(d) = &fit.diagnostics {
            lines.push(line(
                lang,
                "diag.mounting",
                &[
                    ("mount", mount.to_string()),
                    ("verdict", model_verdict(lang, d)),
                ],
            ));
        }
        if let Some(k2) = fit
            .uncertainty
            .as_ref()
            .and_then(|u| u.k2_ug_per_g2.as_ref())
        {
            lines.push(line(
                lang,
                "diag.mounting_uncertainty",
                &[("mount", mount.to_string()), ("budget", budget(lang, k2))],
            ));
        }
    }
    if let Some(j) = &a.joint {
        lines.push(joint(lang, j));
        if let Some(u) = &j.uncertainty {
            lines.push(line(
                lang,
                "diag.joint_uncertainty",
                &[("budget", budget(lang, &u.k2_even_ug_per_g2))],
            ));
        }
    }
    lines
}

/// One mounting's lack of fit, pure error, outlier levels and the range of
/// k2 with one level left out (as `Diagnostics`' Display words it in English).
fn model_verdict(lang: Lang, d: &Diagnostics) -> String {
    let mut text = match &d.lack_of_fit {
        Some(l) => line(
            lang,
            "diag.lack_of_fit",
            &[
                ("f", format!("{:.2}", l.f)),
                ("dof1", l.dof[0].to_string()),
                ("dof2", l.dof[1].to_string()),
                ("p", format!("{:.2e}", l.p_value)),
                (
                    "misfit",
                    if l.p_value < 0.001 {
                        line(lang, "diag.model_does_not_fit", &[])
                    } else {
                        String::new()
                    },
                ),
            ],
        ),
        None => line(lang, "diag.no_lack_of_fit", &[]),
    };
    if let Some(pe) = d.pure_error_rms_ug {
        text.push_str(&line(
            lang,
            "diag.pure_error",
            &[("rms", format!("{pe:.1}"))],
        ));
    }
    if let Some(tau) = d.between_level_ug.filter(|t| *t >= 0.5) {
        text.push_str(&line(
            lang,
            "diag.between_levels",
            &[("tau", format!("{tau:.0}"))],
        ));
    }
    if d.outlier_levels.is_empty() {
        text.push_str(&line(lang, "diag.no_outlier", &[]));
    } else {
        let levels: Vec<String> = d
            .outlier_levels
            .iter()
            .map(|o| {
                line(
                    lang,
                    "diag.outlier",
                    &[
                        ("g", o.g.to_string()),
                        ("residual", format!("{:+.0}", o.residual_ug)),
                        ("t", format!("{:.1}", o.t)),
                        ("p", format!("{:.1e}", o.p)),
                    ],
                )
            })
            .collect();
        text.push_str(&line(
            lang,
            "diag.outliers",
            &[("levels", levels.join(", "))],
        ));
    }
    let by_k2 = |a: &&spinbench_analysis::diagnostics::Influence,
                 b: &&spinbench_analysis::diagnostics::Influence| {
        a.k2_without_ug_per_g2.total_cmp(&b.k2_without_ug_per_g2)
    };
    if let (Some(lo), Some(hi)) = (
        d.influence.iter().min_by(by_k2),
        d.influence.iter().max_by(by_k2),
    ) {
        text.push_str(&line(
            lang,
            "diag.influence",
            &[
                ("low", format!("{:.3}", lo.k2_without_ug_per_g2)),
                ("low_g", lo.g.to_string()),
                ("high", format!("{:.3}", hi.k2_without_ug_per_g2)),
                ("high_g", hi.g.to_string()),
            ],
        ));
    }
    text
}

/// A budget's contribution as a reader takes it in: three significant
/// figures, "< 0.0001" below that (a timebase's 10⁻¹³ µg/g² is nothing,
/// and twelve zeros said so badly).
fn contribution(v: f64) -> String {
    if v.is_finite() && v.abs() < 1e-4 {
        "< 0.0001".to_string()
    } else {
        sig(v)
    }
}

/// Effective degrees of freedom as shown: one decimal, "> 1000" beyond
/// (the interval's factor is then 1.96 to three figures), "∞" without.
fn degrees(dof: Option<f64>) -> String {
    match dof {
        None => "∞".to_string(),
        Some(d) if d > 1000.0 => "> 1000".to_string(),
        Some(d) => format!("{d:.1}"),
    }
}

/// An uncertainty with its budget: "U95 2.10 (u 1.02, ν 14.2: repeatability (A) 0.98, …)".
fn budget(lang: Lang, u: &Uncertainty) -> String {
    let dof = degrees(u.dof_eff);
    let parts: Vec<String> = u
        .budget
        .iter()
        .map(|c| {
            let key = format!("source.{}", lang::serde_name(c.source));
            let word = lang::tr_or(lang, &key, &c.source.to_string());
            format!("{word} {}", contribution(c.u))
        })
        .collect();
    line(
        lang,
        "diag.budget",
        &[
            ("u95", sig(u.u95)),
            ("u", sig(u.u)),
            ("dof", dof),
            ("sources", parts.join(", ")),
        ],
    )
}

/// The two mountings reduced together (method.md (15)).
fn joint(lang: Lang, j: &JointK2) -> String {
    let u = |v: Option<f64>| v.map_or_else(|| "—".into(), |u| format!("{u:.3}"));
    line(
        lang,
        "diag.joint",
        &[
            ("k2", format!("{:.3}", j.k2_even_ug_per_g2)),
            ("k2_u95", u(j.k2_even_u95)),
            ("odd", format!("{:.3}", j.k2_odd_ug_per_g2)),
            ("odd_u95", u(j.k2_odd_u95)),
        ],
    )
}

/// The instrument's temperatures over its points, when its module reported
/// them: the range of the points' means, the largest change within one
/// point, how far f1 + f2 (the thermal proxy) moved, and the points taken
/// while the temperature moved more than the plan allowed.
pub fn temperature_line(points: &[spinbench_engine::PointRecord]) -> Option<String> {
    temperature_line_in(points, Lang::En)
}

/// [`temperature_line`] in `lang`.
pub fn temperature_line_in(points: &[spinbench_engine::PointRecord], lang: Lang) -> Option<String> {
    let means: Vec<f64> = points.iter().filter_map(|p| p.temperature_c).collect();
    if means.is_empty() {
        return None;
    }
    let (lo, hi) = means
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| {
            (lo.min(t), hi.max(t))
        });
    let within = points
        .iter()
        .filter_map(|p| p.temperature_change_c)
        .fold(0.0, f64::max);
    let sums: Vec<f64> = points.iter().filter_map(|p| p.resonator_sum_hz).collect();
    let proxy = match (
        sums.iter().copied().reduce(f64::min),
        sums.iter().copied().reduce(f64::max),
    ) {
        (Some(a), Some(b)) if a > 0.0 => line(
            lang,
            "diag.temperature_proxy",
            &[("ppm", format!("{:.1}", (b - a) / a * 1e6))],
        ),
        _ => String::new(),
    };
    let unsettled = points.iter().filter(|p| p.temperature_unsettled).count();
    let flagged = if unsettled > 0 {
        line(
            lang,
            "diag.temperature_flagged",
            &[("count", unsettled.to_string())],
        )
    } else {
        String::new()
    };
    Some(line(
        lang,
        "diag.temperature",
        &[
            ("low", format!("{lo:.2}")),
            ("high", format!("{hi:.2}")),
            ("within", format!("{within:.3}")),
            ("proxy", proxy),
            ("flagged", flagged),
        ],
    ))
}

#[cfg(test)]
mod budget_tests {
    use super::*;

    #[test]
    fn budgets_say_nothing_and_many_degrees_plainly() {
        assert_eq!(contribution(3.2e-13), "< 0.0001");
        assert_eq!(contribution(5.17), "5.17");
        assert_eq!(degrees(Some(396_808_424.0)), "> 1000");
        assert_eq!(degrees(Some(17.64)), "17.6");
        assert_eq!(degrees(None), "∞");
    }
}

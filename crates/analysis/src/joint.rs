//! The two mountings reduced together (IEEE Std 836; method.md (15)): the
//! instrument's own second-order term K2 changes sign with the mounting,
//! while arm stretch and the odd-quadratic term Koq enter both alike. In
//! the per-mounting convention k2_P = K2 + c' and k2_N = c' − K2, so
//!
//! ```text
//! K2 = (k2_P − k2_N)/2   (even, the instrument's)
//! c' = (k2_P + k2_N)/2   (odd: Koq plus arm stretch)
//! ```
//!
//! With both mountings' GUM budgets ([`crate::uncertainty`]) a source both
//! share (the rate read-back, g_local, the timebase, the arm stretch) adds
//! with its sign and each mounting's own sources in quadrature; without
//! them the two fits' standard errors combine as u² = (u_P² + u_N²)/4. The
//! effective degrees of freedom are by Welch–Satterthwaite and U = t₀.₉₇₅(ν)·u.
//! The published per-mounting k2 and k2_max stay as the method defines them.

use crate::model::MountingFit;
use crate::statistics::student_t_975;
use crate::uncertainty::{
    MountingBudget, PairedInadequacy, Uncertainty, coverage_factor_95, joint_uncertainty,
};
use serde::{Deserialize, Serialize};

/// K2 and the odd part, each with its uncertainty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointK2 {
    /// K2 = (k2_P − k2_N)/2, the instrument's even second-order term [µg/g²].
    pub k2_even_ug_per_g2: f64,
    /// Its expanded uncertainty at 95 % [µg/g²].
    #[serde(rename = "k2_even_U95")]
    pub k2_even_u95: Option<f64>,
    /// (k2_P + k2_N)/2: the odd-quadratic term plus arm stretch [µg/g²].
    pub k2_odd_ug_per_g2: f64,
    /// Its expanded uncertainty at 95 % [µg/g²].
    #[serde(rename = "k2_odd_U95")]
    pub k2_odd_u95: Option<f64>,
    /// K2's standard uncertainty [µg/g²] (the odd part's is in `uncertainty`).
    pub u_ug_per_g2: Option<f64>,
    /// Effective degrees of freedom (Welch–Satterthwaite).
    pub dof_eff: Option<f64>,
    /// The GUM budgets of K2 and of the odd part, when both mountings have one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<JointUncertainty>,
}

/// The GUM uncertainty of K2 and of the odd part.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointUncertainty {
    /// Of K2 (even) [µg/g²].
    pub k2_even_ug_per_g2: Uncertainty,
    /// Of the odd part [µg/g²].
    pub k2_odd_ug_per_g2: Uncertainty,
}

impl std::fmt::Display for JointK2 {
    /// One line for `analyze` and the reports.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let u = |v: Option<f64>| v.map_or_else(|| "—".into(), |u| format!("{u:.3}"));
        write!(
            f,
            "both mountings (method.md (15)): K2 (even, the instrument's) = {:.3} ± {} µg/g²; odd part (Koq + arm stretch) = {:.3} ± {} µg/g² (U95)",
            self.k2_even_ug_per_g2,
            u(self.k2_even_u95),
            self.k2_odd_ug_per_g2,
            u(self.k2_odd_u95)
        )
    }
}

/// Combine the two mountings' fits (and their GUM budgets, when given);
/// `None` unless both have k2.
pub fn joint_k2(
    p: &MountingFit,
    n: &MountingFit,
    budgets: Option<(&MountingBudget, &MountingBudget)>,
    paired: Option<PairedInadequacy>,
) -> Option<JointK2> {
    let (kp, kn) = (p.fit.k2_ug_per_g2?, n.fit.k2_ug_per_g2?);
    if let Some((even, odd)) = budgets.and_then(|(bp, bn)| joint_uncertainty(bp, bn, paired)) {
        return Some(JointK2 {
            k2_even_ug_per_g2: 0.5 * (kp - kn),
            k2_even_u95: Some(even.u95),
            k2_odd_ug_per_g2: 0.5 * (kp + kn),
            k2_odd_u95: Some(odd.u95),
            u_ug_per_g2: Some(even.u),
            dof_eff: even.dof_eff,
            uncertainty: Some(JointUncertainty {
                k2_even_ug_per_g2: even,
                k2_odd_ug_per_g2: odd,
            }),
        });
    }
    let sp = p.fit.std_error.k2_ug_per_g2;
    let sn = n.fit.std_error.k2_ug_per_g2;
    let (u, dof) = match (sp, sn) {
        (Some(sp), Some(sn)) => {
            let u = 0.5 * (sp * sp + sn * sn).sqrt();
            // ν_eff = u⁴ / Σ (cᵢ·uᵢ)⁴/νᵢ with cᵢ = ½.
            let term = |s: f64, dof: usize| (0.5 * s).powi(4) / dof.max(1) as f64;
            let dof = u.powi(4) / (term(sp, p.fit.dof) + term(sn, n.fit.dof));
            (Some(u), dof.is_finite().then_some(dof))
        }
        _ => (None, None),
    };
    // Student t at the effective dof, rounded down (conservative).
    let expanded = match (u, dof) {
        (Some(u), Some(dof)) => Some(coverage_factor_95(Some(dof)) * u),
        _ => None,
    };
    Some(JointK2 {
        k2_even_ug_per_g2: 0.5 * (kp - kn),
        k2_even_u95: expanded,
        k2_odd_ug_per_g2: 0.5 * (kp + kn),
        k2_odd_u95: expanded,
        u_ug_per_g2: u,
        dof_eff: dof,
        uncertainty: None,
    })
}

/// The full-range fit over signed input with the odd-quadratic term of
/// method.md (12): output = c0 + c1·a + c2·a² + c3·a³ + c_oq·a·|a| + c_e·|a|³.
/// Across
/// both mountings a² (even) and a·|a| (odd) part, so K2 and Koq (plus arm
/// stretch, which enters as c·a·|a| on the signed input) come out together.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FullRangeKoq {
    /// K2, the even second-order term [µg/g²].
    pub k2_ug_per_g2: f64,
    /// Its 95 % interval.
    pub k2_ci95: Option<[f64; 2]>,
    /// Koq (plus arm stretch), the odd-quadratic term [µg/g²].
    pub koq_ug_per_g2: f64,
    /// Its 95 % interval.
    pub koq_ci95: Option<[f64; 2]>,
    /// RMS of the residuals as acceleration [µg].
    pub residual_rms_ug: f64,
}

/// Fit the full range with Koq; `None` unless both signs of input and at
/// least seven levels are present.
pub fn full_range_koq(points: &[crate::Point], what: &str) -> Option<FullRangeKoq> {
    use crate::lsq;
    let x: Vec<f64> = points.iter().map(crate::Point::g_signed).collect();
    let y: Vec<f64> = points.iter().map(|p| p.output).collect();
    let both_signs = x.iter().any(|&a| a > 0.0) && x.iter().any(|&a| a < 0.0);
    let mut levels: Vec<f64> = points
        .iter()
        .map(|p| p.mount.input_sign() * p.g_nominal.abs())
        .collect();
    levels.sort_by(f64::total_cmp);
    levels.dedup();
    if !both_signs || levels.len() < 7 {
        return None;
    }
    // The even cubic |a|³ too: K2 times the stretch (2·K2·c·|a|³) is even in
    // signed input, and left out it would bias K2.
    let design = nalgebra::DMatrix::from_fn(x.len(), 6, |i, j| {
        let a = x[i];
        match j {
            4 => a * a.abs(),
            5 => a.abs().powi(3),
            _ => a.powi(j as i32),
        }
    });
    let fit = lsq::solve(&design, &y, what).ok()?;
    let c = &fit.coefficients;
    let c1 = c[1];
    if c1 == 0.0 || !c1.is_finite() {
        return None;
    }
    let t = student_t_975(fit.stats.dof);
    // k = c/c1: the interval from c's standard error over |c1| (c1's own
    // relative uncertainty is parts per million against this).
    let interval = |j: usize| -> Option<[f64; 2]> {
        let se = fit.covariance.as_ref()?[(j, j)].max(0.0).sqrt() / c1.abs() * crate::UG_PER_G;
        let v = c[j] / c1 * crate::UG_PER_G;
        let t = t?;
        Some([v - t * se, v + t * se])
    };
    Some(FullRangeKoq {
        k2_ug_per_g2: c[2] / c1 * crate::UG_PER_G,
        k2_ci95: interval(2),
        koq_ug_per_g2: c[4] / c1 * crate::UG_PER_G,
        koq_ci95: interval(4),
        residual_rms_ug: fit.stats.residual_rms / c1.abs() * crate::UG_PER_G,
    })
}

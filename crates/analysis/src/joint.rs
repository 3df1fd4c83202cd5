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
//! The two passes are independent fits: u² = (u_P² + u_N²)/4, with the
//! effective degrees of freedom by Welch–Satterthwaite and U = t₀.₉₇₅(ν)·u.
//! The published per-mounting k2 and k2_max stay as the method defines them.

use crate::model::{MountingFit, student_t_975};
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
    /// Their (common) standard uncertainty [µg/g²].
    pub u_ug_per_g2: Option<f64>,
    /// Effective degrees of freedom (Welch–Satterthwaite).
    pub dof_eff: Option<f64>,
}

/// Combine the two mountings' fits; `None` unless both have k2.
pub fn joint_k2(p: &MountingFit, n: &MountingFit) -> Option<JointK2> {
    let (kp, kn) = (p.fit.k2_ug_per_g2?, n.fit.k2_ug_per_g2?);
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
    // Student t at the (fractional) effective dof, rounded down (conservative).
    let expanded = match (u, dof) {
        (Some(u), Some(dof)) => student_t_975(dof.floor().max(1.0) as usize).map(|t| t * u),
        _ => None,
    };
    Some(JointK2 {
        k2_even_ug_per_g2: 0.5 * (kp - kn),
        k2_even_u95: expanded,
        k2_odd_ug_per_g2: 0.5 * (kp + kn),
        k2_odd_u95: expanded,
        u_ug_per_g2: u,
        dof_eff: dof,
    })
}

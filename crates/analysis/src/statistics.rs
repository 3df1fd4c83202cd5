//! Distribution quantiles the reduction's intervals use (Student's t, from
//! statrs), apart from the model and the budgets that both use them, so
//! neither reaches into the other for them.

use statrs::distribution::{ContinuousCDF, StudentsT};

/// The two-sided 95 % Student-t quantile t(0.975, dof); `None` for dof = 0.
pub fn student_t_975(dof: usize) -> Option<f64> {
    student_t_quantile(0.975, dof)
}

/// The Student-t quantile t(p, dof); `None` for dof = 0 or p outside (0, 1).
pub fn student_t_quantile(p: f64, dof: usize) -> Option<f64> {
    if dof == 0 || !(p > 0.0 && p < 1.0) {
        return None;
    }
    let dist = StudentsT::new(0.0, 1.0, dof as f64).ok()?;
    Some(dist.inverse_cdf(p))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn student_t_matches_tables() {
        assert!((student_t_975(1).expect("t") - 12.706).abs() < 1e-3);
        assert!((student_t_975(10).expect("t") - 2.228).abs() < 1e-3);
        assert!(student_t_975(0).is_none());
        assert!(student_t_quantile(1.0, 5).is_none());
    }
}

//! The stability statistics, as pure functions over plain numbers: the
//! rate on speed, the drift slope test (through `analysis::lsq`, like every
//! other fit), an instrument's own scatter and the standard error of a mean.

use spinbench_analysis::UG_PER_G;
use spinbench_analysis::lsq::{polynomial_design, solve};

/// A table counts as at rest below this rate [deg/s].
pub const AT_REST_DEG_S: f64 = 0.05;

/// The rate is on speed: within `tolerance_ppm` of the demand (and within
/// [`AT_REST_DEG_S`] at rest).
pub fn on_speed(rate_deg_s: f64, demand_deg_s: f64, tolerance_ppm: f64) -> bool {
    let tol = (demand_deg_s.abs() * tolerance_ppm * 1e-6).max(AT_REST_DEG_S);
    (rate_deg_s - demand_deg_s).abs() <= tol
}

/// The slope test over one-second outputs `y` [Hz]: the least-squares slope
/// (one value per second), as acceleration through the scale factor
/// `k1_hz_per_g`, above `limit_ug_per_s` and significant at `t_crit`
/// (|slope| > t·SE). Fewer than three values never drift.
pub fn drifting(y: &[f64], k1_hz_per_g: f64, limit_ug_per_s: f64, t_crit: f64) -> bool {
    if y.len() < 3 {
        return false;
    }
    let t: Vec<f64> = (0..y.len()).map(|i| i as f64).collect();
    let Ok(fit) = solve(&polynomial_design(&t, 1), y, "drift slope") else {
        return false;
    };
    let slope = fit.coefficients[1];
    let se = fit
        .covariance
        .as_ref()
        .map_or(0.0, |c| c[(1, 1)].max(0.0).sqrt());
    let slope_ug = slope.abs() / k1_hz_per_g * UG_PER_G;
    slope_ug > limit_ug_per_s && slope.abs() > t_crit * se
}

/// Each series' own one-second scatter [µg], from series in g of the
/// instruments of one counter module over the same windows: the common mode
/// (the median deviation per window, when there are at least three series)
/// is removed, then σ = std(Δ)/√2 of the successive differences, which
/// ignores slow trends.
pub fn own_scatter_ug(series: &[Vec<f64>]) -> Vec<f64> {
    let windows = series.iter().map(Vec::len).min().unwrap_or(0);
    let means: Vec<f64> = series.iter().map(|y| mean_std(y).0).collect();
    let common: Vec<f64> = (0..windows)
        .map(|t| {
            if series.len() < 3 {
                return 0.0;
            }
            let mut dev: Vec<f64> = series.iter().zip(&means).map(|(y, m)| y[t] - m).collect();
            dev.sort_by(f64::total_cmp);
            dev[dev.len() / 2]
        })
        .collect();
    series
        .iter()
        .map(|y| {
            let own: Vec<f64> = y.iter().zip(&common).map(|(v, c)| v - c).collect();
            let diffs: Vec<f64> = own.windows(2).map(|d| d[1] - d[0]).collect();
            mean_std(&diffs).1 / std::f64::consts::SQRT_2 * UG_PER_G
        })
        .collect()
}

/// The standard error of the mean of one-second outputs `y` [Hz] as
/// acceleration [µg]; `None` below two values.
pub fn sem_ug(y: &[f64], k1_hz_per_g: f64) -> Option<f64> {
    if y.len() < 2 {
        return None;
    }
    let (_, std) = mean_std(y);
    Some(std / (y.len() as f64).sqrt() / k1_hz_per_g * UG_PER_G)
}

/// The mean of `y` and its spread (highest minus lowest); `None` for no values.
pub fn mean_spread(y: &[f64]) -> Option<(f64, f64)> {
    if y.is_empty() {
        return None;
    }
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let (lo, hi) = y
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    Some((mean, hi - lo))
}

/// Mean and sample standard deviation (0 for one value).
pub fn mean_std(y: &[f64]) -> (f64, f64) {
    let n = y.len() as f64;
    let mean = y.iter().sum::<f64>() / n;
    let var = if y.len() > 1 {
        y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    (mean, var.sqrt())
}

#[cfg(test)]
mod tests {
    use super::{drifting, on_speed, own_scatter_ug, sem_ug};

    #[test]
    fn a_slope_is_drift_only_when_large_and_significant() {
        let k1 = 100.0;
        // 10 µg/s of drift: 1e-3 Hz/s at 100 Hz/g, no noise.
        let ramp: Vec<f64> = (0..5).map(|i| 30.0 + 1e-3 * i as f64).collect();
        assert!(drifting(&ramp, k1, 3.0, 3.0));
        assert!(!drifting(&ramp, k1, 30.0, 3.0), "below the limit");
        // The same slope buried in noise is not significant.
        let noisy: Vec<f64> = [0.0, 0.05, -0.04, 0.06, -0.03]
            .iter()
            .enumerate()
            .map(|(i, n)| 30.0 + 1e-3 * i as f64 + n)
            .collect();
        assert!(!drifting(&noisy, k1, 3.0, 3.0));
        assert!(
            !drifting(&ramp[..2], k1, 3.0, 3.0),
            "two values never drift"
        );
    }

    #[test]
    fn the_common_mode_is_not_an_instruments_own_noise() {
        // Three instruments that move together, one with its own jitter.
        let common = [0.0, 1e-4, -1e-4, 2e-4, 0.0, -2e-4];
        let jitter = [0.0, 5e-5, -5e-5, 5e-5, -5e-5, 0.0];
        let series: Vec<Vec<f64>> = (0..3)
            .map(|k| {
                common
                    .iter()
                    .zip(&jitter)
                    .map(|(c, j)| 1.0 + c + if k == 2 { *j } else { 0.0 })
                    .collect()
            })
            .collect();
        let scatter = own_scatter_ug(&series);
        assert!(scatter[0] < 1.0 && scatter[1] < 1.0, "{scatter:?}");
        assert!(scatter[2] > 10.0, "{scatter:?}");
        assert!(on_speed(1000.01, 1000.0, 20.0));
        assert!(!on_speed(1000.1, 1000.0, 20.0));
        assert_eq!(sem_ug(&[1.0], 100.0), None);
    }
}

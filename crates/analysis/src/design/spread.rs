//! What a run's median K2 U95 may come out at: the instruments differ in
//! their between-level scatter τ (one has an activity dip at a level that
//! weighs on K2, the next has none), so the median over a run's few
//! instruments scatters from run to run far more than the noise makes it.
//! The planner's point prediction is the median instrument's U95; this is
//! the range that a run of `n` instruments lands in with probability
//! [`RUN_RANGE_PROBABILITY`], from the τ distribution the station learned.
//!
//! The median of `n` draws is the k-th order statistic (k = ⌈n/2⌉, or the
//! two middle ones for an even n), whose distribution function is
//! `P(X₍ₖ₎ ≤ x) = P(Bin(n, F(x)) ≥ k)`; U95 grows with τ, so the range's
//! ends are the U95 of the order statistic's 10 % and 90 % points. F is
//! the learned deciles, linear between them. Written here because it is a
//! dozen lines of arithmetic over a binomial tail no crate in the tree has.

use super::{Candidate, K2Terms, StationModel};
use crate::AnalysisError;

/// Fewest instrument-runs whose τ make a distribution (below: no range).
pub const MIN_SPREAD_INSTRUMENTS: usize = 10;
/// The probability that a run's median K2 U95 falls in the predicted range.
pub const RUN_RANGE_PROBABILITY: f64 = 0.8;
/// Most instruments a range is computed for (a station's slots).
const MAX_INSTRUMENTS: usize = 1_000;

/// τ at 0, 10, … 100 % of `taus` [µg] (linear between order statistics);
/// `None` below [`MIN_SPREAD_INSTRUMENTS`] finite values.
pub(super) fn deciles(taus: &[f64]) -> Option<[f64; 11]> {
    let mut v: Vec<f64> = taus.iter().copied().filter(|t| t.is_finite()).collect();
    if v.len() < MIN_SPREAD_INSTRUMENTS {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let mut out = [0.0; 11];
    for (i, d) in out.iter_mut().enumerate() {
        let at = i as f64 / 10.0 * (v.len() - 1) as f64;
        let lo = at.floor() as usize;
        let hi = (lo + 1).min(v.len() - 1);
        *d = v[lo] + (at - lo as f64) * (v[hi] - v[lo]);
    }
    Some(out)
}

/// The range [µg/g²] a run of `instruments` instruments' median K2 U95
/// falls in with probability [`RUN_RANGE_PROBABILITY`] on `plan` (module
/// docs); `None` when the model has no learned τ distribution.
pub fn run_median_range(
    model: &StationModel,
    plan: &Candidate,
    instruments: usize,
) -> Result<Option<[f64; 2]>, AnalysisError> {
    if !(1..=MAX_INSTRUMENTS).contains(&instruments) {
        return Err(AnalysisError::InvalidInput(format!(
            "a run of {instruments} instruments: 1 to {MAX_INSTRUMENTS}"
        )));
    }
    let Some(deciles) = model.between_level_deciles_ug else {
        return Ok(None);
    };
    let terms = K2Terms::of(model, plan)?;
    let tail = (1.0 - RUN_RANGE_PROBABILITY) / 2.0;
    let (k_low, k_high) = (instruments.div_ceil(2), instruments / 2 + 1);
    let low = tau_at(&deciles, order_statistic_point(instruments, k_low, tail));
    let high = tau_at(
        &deciles,
        order_statistic_point(instruments, k_high, 1.0 - tail),
    );
    Ok(Some([terms.u95(low), terms.u95(high)]))
}

/// The probability p at which `P(Bin(n, p) ≥ k) = q` (bisection: the tail
/// grows with p).
fn order_statistic_point(n: usize, k: usize, q: f64) -> f64 {
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if binomial_upper_tail(n, k, mid) < q {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// `P(Bin(n, p) ≥ k)`.
fn binomial_upper_tail(n: usize, k: usize, p: f64) -> f64 {
    if k == 0 {
        return 1.0;
    }
    if k > n || p <= 0.0 {
        return 0.0;
    }
    if p >= 1.0 {
        return 1.0;
    }
    // The pmf from j = 0 upward, in logs (n up to MAX_INSTRUMENTS).
    let (lp, lq) = (p.ln(), (1.0 - p).ln());
    let mut log_choose = 0.0_f64;
    let mut sum = 0.0;
    for j in 0..=n {
        if j > 0 {
            log_choose += ((n - j + 1) as f64).ln() - (j as f64).ln();
        }
        if j >= k {
            let term = log_choose + j as f64 * lp + (n - j) as f64 * lq;
            sum += term.exp();
        }
    }
    sum.clamp(0.0, 1.0)
}

/// The learned τ at probability `p` (linear between the deciles).
fn tau_at(deciles: &[f64; 11], p: f64) -> f64 {
    let at = (p.clamp(0.0, 1.0) * 10.0).min(10.0);
    let i = (at.floor() as usize).min(9);
    deciles[i] + (at - i as f64) * (deciles[i + 1] - deciles[i])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_binomial_tail_and_its_inverse_agree() {
        // P(Bin(3, ½) ≥ 2) = ½ exactly; the median of 3 has it at p = ½.
        assert!((binomial_upper_tail(3, 2, 0.5) - 0.5).abs() < 1e-12);
        assert!((order_statistic_point(3, 2, 0.5) - 0.5).abs() < 1e-9);
        assert_eq!(binomial_upper_tail(5, 0, 0.3), 1.0);
        assert_eq!(binomial_upper_tail(5, 6, 0.3), 0.0);
        // p = 0 and 1 hold their ends (logs of 0 give no NaN).
        assert_eq!(binomial_upper_tail(4, 2, 0.0), 0.0);
        assert!((binomial_upper_tail(4, 2, 1.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_run_median_range_brackets_the_median_instrument_and_narrows_with_more_instruments() {
        let taus: Vec<f64> = (0..40).map(|i| 50.0 * i as f64).collect();
        let d = deciles(&taus).expect("40 instruments");
        assert_eq!((d[0], d[10]), (0.0, 1950.0));
        assert!((d[5] - 975.0).abs() < 1e-9);
        let model = StationModel {
            between_level_deciles_ug: Some(d),
            between_level_ug: d[5],
            ..StationModel::default()
        };
        let plan = Candidate::published(&[0.0, 1.0, 5.0, 10.0, 20.0, 30.0, 40.0, 50.0], 2);
        let point = super::super::predict(&model, &plan)
            .expect("predict")
            .k2_u95_ug_per_g2;
        let [lo12, hi12] = run_median_range(&model, &plan, 12)
            .expect("range")
            .expect("some");
        let [lo48, hi48] = run_median_range(&model, &plan, 48)
            .expect("range")
            .expect("some");
        assert!(lo12 < point && point < hi12, "{lo12} {point} {hi12}");
        assert!(
            lo12 < lo48 && hi48 < hi12,
            "12: {lo12}–{hi12}, 48: {lo48}–{hi48}"
        );
        // A model with no learned distribution gives no range; 0 instruments is refused.
        assert_eq!(
            run_median_range(&StationModel::default(), &plan, 12).expect("ok"),
            None
        );
        assert!(run_median_range(&model, &plan, 0).is_err());
        assert_eq!(deciles(&taus[..9]), None);
    }
}

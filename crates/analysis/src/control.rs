//! Control charts across runs: an individuals chart's
//! limits from a baseline period and the Western Electric rules.
//!
//! ```text
//! centre  x̄ = mean of the baseline values
//! σ̂      = mean moving range of the baseline / d₂,  d₂ = 1.128 (n = 2)
//! zones   A: beyond 2σ̂, B: beyond 1σ̂, C: within 1σ̂, each side of x̄
//! ```
//!
//! The moving range gives the short-term σ a drift does not inflate (the
//! standard individuals chart, ISO 7870-2). The four Western Electric rules
//! (Western Electric, *Statistical Quality Control Handbook*, 1956):
//! 1. one point beyond 3σ̂;
//! 2. two of three successive points beyond 2σ̂ on the same side;
//! 3. four of five successive points beyond 1σ̂ on the same side;
//! 4. eight successive points on the same side of the centre.
//!
//! Written here because no maintained Rust crate implements them; they are
//! a few lines each.

use serde::{Deserialize, Serialize};

/// d₂ for moving ranges of two successive points.
pub const D2_N2: f64 = 1.128;

/// The fewest baseline values that give limits.
pub const MIN_BASELINE: usize = 5;

/// An individuals chart's centre and σ̂.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ControlLimits {
    /// Centre line x̄.
    pub centre: f64,
    /// σ̂ from the mean moving range.
    pub sigma: f64,
}

impl ControlLimits {
    /// Limits from baseline values; `None` with fewer than [`MIN_BASELINE`]
    /// finite values or no spread at all.
    pub fn from_baseline(values: &[f64]) -> Option<ControlLimits> {
        let v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        if v.len() < MIN_BASELINE {
            return None;
        }
        let centre = v.iter().sum::<f64>() / v.len() as f64;
        let mr = v.windows(2).map(|w| (w[1] - w[0]).abs()).sum::<f64>() / (v.len() - 1) as f64;
        let sigma = mr / D2_N2;
        (sigma > 0.0 && sigma.is_finite()).then_some(ControlLimits { centre, sigma })
    }

    /// The lower and upper control limits, x̄ ∓ 3σ̂.
    pub fn limits(&self) -> (f64, f64) {
        (
            self.centre - 3.0 * self.sigma,
            self.centre + 3.0 * self.sigma,
        )
    }

    fn z(&self, x: f64) -> f64 {
        (x - self.centre) / self.sigma
    }
}

/// A Western Electric rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WesternElectric {
    /// One point beyond 3σ̂.
    Beyond3Sigma,
    /// Two of three successive points beyond 2σ̂ on one side.
    TwoOfThreeBeyond2Sigma,
    /// Four of five successive points beyond 1σ̂ on one side.
    FourOfFiveBeyond1Sigma,
    /// Eight successive points on one side of the centre.
    EightOnOneSide,
}

impl WesternElectric {
    /// The rule's number (1–4) and what it says.
    pub fn describe(self) -> &'static str {
        match self {
            WesternElectric::Beyond3Sigma => "rule 1: a point beyond 3σ",
            WesternElectric::TwoOfThreeBeyond2Sigma => {
                "rule 2: two of three successive points beyond 2σ on one side"
            }
            WesternElectric::FourOfFiveBeyond1Sigma => {
                "rule 3: four of five successive points beyond 1σ on one side"
            }
            WesternElectric::EightOnOneSide => {
                "rule 4: eight successive points on one side of the centre"
            }
        }
    }
}

/// A rule broken: at which point (the last of the run of points that
/// breaks it) and which rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Violation {
    /// Index of the point in the series.
    pub index: usize,
    /// The rule.
    pub rule: WesternElectric,
}

/// Every point at which a rule is broken (a point may break several).
/// Non-finite values are skipped (they neither break nor count).
pub fn western_electric(values: &[f64], limits: &ControlLimits) -> Vec<Violation> {
    let points: Vec<(usize, f64)> = values
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .map(|(i, &v)| (i, limits.z(v)))
        .collect();
    let mut out = Vec::new();
    // `k` of the last `n` points beyond `beyond` σ on one side.
    let k_of_n = |end: usize, k: usize, n: usize, beyond: f64| -> bool {
        if end + 1 < n {
            return false;
        }
        let window = &points[end + 1 - n..=end];
        let last = window[n - 1].1;
        let same_side = |z: f64| z * last.signum() > beyond;
        same_side(last) && window.iter().filter(|(_, z)| same_side(*z)).count() >= k
    };
    for (end, &(index, z)) in points.iter().enumerate() {
        let mut broke = |rule| out.push(Violation { index, rule });
        if z.abs() > 3.0 {
            broke(WesternElectric::Beyond3Sigma);
        }
        if k_of_n(end, 2, 3, 2.0) {
            broke(WesternElectric::TwoOfThreeBeyond2Sigma);
        }
        if k_of_n(end, 4, 5, 1.0) {
            broke(WesternElectric::FourOfFiveBeyond1Sigma);
        }
        if k_of_n(end, 8, 8, 0.0) {
            broke(WesternElectric::EightOnOneSide);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    const LIMITS: ControlLimits = ControlLimits {
        centre: 0.0,
        sigma: 1.0,
    };

    fn rules(values: &[f64]) -> Vec<(usize, WesternElectric)> {
        western_electric(values, &LIMITS)
            .into_iter()
            .map(|v| (v.index, v.rule))
            .collect()
    }

    #[test]
    fn each_rule_at_its_boundary() {
        use WesternElectric::*;
        // Rule 1: 3.01 breaks it, 2.99 does not.
        assert_eq!(rules(&[0.5, 3.01, -0.5]), [(1, Beyond3Sigma)]);
        assert!(rules(&[0.5, 2.99, -0.5]).is_empty());
        // Rule 2: two of three beyond 2σ on one side; not on opposite sides.
        assert_eq!(rules(&[2.1, 0.0, 2.1]), [(2, TwoOfThreeBeyond2Sigma)]);
        assert!(rules(&[2.1, 0.0, -2.1]).is_empty());
        // Rule 3: four of five beyond 1σ on one side.
        assert_eq!(
            rules(&[1.1, 1.1, -0.5, 1.1, 1.1]),
            [(4, FourOfFiveBeyond1Sigma)]
        );
        assert!(rules(&[1.1, 1.1, -0.5, 0.9, 1.1]).is_empty());
        // Rule 4: eight on one side; seven are not.
        assert_eq!(rules(&[0.1; 8]), [(7, EightOnOneSide)]);
        assert!(rules(&[0.1; 7]).is_empty());
        // Non-finite values neither break nor count.
        let gap = [0.1, 0.1, 0.1, f64::NAN, 0.1, 0.1, 0.1, 0.1];
        assert!(rules(&gap).is_empty(), "seven values");
        assert_eq!(rules(&[&gap[..], &[0.1]].concat()), [(8, EightOnOneSide)]);
    }

    #[test]
    fn limits_come_from_the_moving_range_and_need_a_baseline() {
        let l = ControlLimits::from_baseline(&[1.0, 2.0, 1.0, 2.0, 1.0]).expect("limits");
        assert!((l.centre - 1.4).abs() < 1e-12);
        assert!((l.sigma - 1.0 / D2_N2).abs() < 1e-12);
        assert!(ControlLimits::from_baseline(&[1.0, 2.0, 1.0, 2.0]).is_none());
        assert!(
            ControlLimits::from_baseline(&[3.0; 8]).is_none(),
            "no spread"
        );
    }

    #[test]
    fn a_stable_process_rarely_alarms_and_a_drift_soon_does() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(16);
        let noise = Normal::new(0.0, 1.0).expect("normal");
        let mut false_alarm_runs = 0;
        let mut detected_by = Vec::new();
        for _ in 0..500 {
            let baseline: Vec<f64> = (0..20).map(|_| noise.sample(&mut rng)).collect();
            let limits = ControlLimits::from_baseline(&baseline).expect("limits");
            // 20 more stable points.
            let stable: Vec<f64> = (0..20).map(|_| noise.sample(&mut rng)).collect();
            if !western_electric(&stable, &limits).is_empty() {
                false_alarm_runs += 1;
            }
            // A drift of 0.25σ per point.
            let drift: Vec<f64> = (0..20)
                .map(|i| noise.sample(&mut rng) + 0.25 * i as f64)
                .collect();
            if let Some(v) = western_electric(&drift, &limits).first() {
                detected_by.push(v.index);
            }
        }
        // Four rules over 20 points: ≈ 10–30 % of stable series alarm somewhere.
        assert!(false_alarm_runs < 200, "{false_alarm_runs} of 500");
        assert!(detected_by.len() > 490, "{}", detected_by.len());
        detected_by.sort_unstable();
        assert!(detected_by[detected_by.len() / 2] <= 10, "{detected_by:?}");
    }
}

//! The batch's statistics: medians, and each figure's distribution with its
//! robust outliers.

use super::{BatchTest, Distribution, Outlier};

pub(crate) fn median(sorted: &[f64]) -> f64 {
    let n = sorted.len();
    if n % 2 == 1 {
        sorted[n / 2]
    } else {
        0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
    }
}

/// Statistics, histogram (Sturges' number of bins) and robust outliers of one figure.
pub(crate) fn distribution(
    name: &'static str,
    unit: &'static str,
    tests: &[BatchTest],
    value: fn(&BatchTest) -> Option<f64>,
) -> Option<Distribution> {
    let with: Vec<(&BatchTest, f64)> = tests
        .iter()
        .filter_map(|t| value(t).filter(|v| v.is_finite()).map(|v| (t, v)))
        .collect();
    if with.is_empty() {
        return None;
    }
    let values: Vec<f64> = with.iter().map(|(_, v)| *v).collect();
    let n = values.len();
    let mean = values.iter().sum::<f64>() / n as f64;
    let std = if n > 1 {
        (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
    } else {
        0.0
    };
    let mut sorted = values.clone();
    sorted.sort_by(f64::total_cmp);
    let (min, max) = (sorted[0], sorted[n - 1]);
    let med = median(&sorted);
    let mut deviations: Vec<f64> = sorted.iter().map(|v| (v - med).abs()).collect();
    deviations.sort_by(f64::total_cmp);
    let mad = median(&deviations);
    let outliers = if mad > 0.0 {
        with.iter()
            .map(|(t, v)| (t, *v, 0.6745 * (v - med) / mad))
            .filter(|(_, _, z)| z.abs() > 3.5)
            .map(|(t, v, z)| Outlier {
                serial: t.serial.clone(),
                run_id: t.run_id.clone(),
                value: v,
                robust_z: z,
            })
            .collect()
    } else {
        Vec::new()
    };
    let count = ((n as f64).log2().ceil() as usize + 1).clamp(1, 30);
    let width = if max > min {
        (max - min) / count as f64
    } else {
        1.0
    };
    let mut bins: Vec<(f64, f64, usize)> = (0..count)
        .map(|i| (min + i as f64 * width, min + (i + 1) as f64 * width, 0))
        .collect();
    for v in &values {
        let i = (((v - min) / width) as usize).min(count - 1);
        bins[i].2 += 1;
    }
    Some(Distribution {
        name,
        unit,
        n,
        mean,
        std,
        min,
        median: med,
        max,
        bins,
        outliers,
        values,
    })
}

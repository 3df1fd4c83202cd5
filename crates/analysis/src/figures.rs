//! Scale-factor figures of merit (method.md §3.4): asymmetry, nonlinearity,
//! hysteresis and repeatability.

use crate::lsq;
use crate::points::{Mount, Point, levels_of};
use crate::{AnalysisError, PPM, UG_PER_G};
use serde::{Deserialize, Serialize};

/// Scale-factor asymmetry: (|K+| − |K−|) / mean(|K+|, |K−|) [ppm], from the
/// scale factors of the P (+a) and N (−a) mountings.
pub fn asymmetry_ppm(k1_positive: f64, k1_negative: f64) -> Option<f64> {
    let (p, n) = (k1_positive.abs(), k1_negative.abs());
    let mean = (p + n) / 2.0;
    (mean > 0.0).then(|| (p - n) / mean * PPM)
}

/// Nonlinearity against the best straight line over full scale.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Nonlinearity {
    /// Largest deviation from the least-squares straight line, as acceleration [µg].
    pub max_deviation_ug: f64,
    /// Full scale: the largest |input| among the points [g].
    pub full_scale_g: f64,
    /// max deviation / full scale [ppm FS].
    pub ppm_fs: f64,
    /// Signed input at which the largest deviation occurs [g].
    pub at_g: f64,
}

/// The largest deviation of the points from their best straight line
/// (least squares of output on signed input), over full scale (method.md §3.4).
pub fn nonlinearity(points: &[Point], what: &str) -> Result<Nonlinearity, AnalysisError> {
    let x: Vec<f64> = points.iter().map(Point::g_signed).collect();
    let y: Vec<f64> = points.iter().map(|p| p.output).collect();
    let fit = lsq::solve(
        &lsq::polynomial_design(&x, 1),
        &y,
        &format!("{what} straight line"),
    )?;
    let slope = fit.coefficients[1].abs();
    if slope == 0.0 {
        return Err(AnalysisError::ZeroScaleFactor {
            what: what.to_string(),
        });
    }
    let (worst, residual) =
        fit.residuals
            .iter()
            .enumerate()
            .fold((0, 0.0_f64), |(wi, wr), (i, r)| {
                if r.abs() > wr.abs() {
                    (i, *r)
                } else {
                    (wi, wr)
                }
            });
    let full_scale_g = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let dev_g = residual.abs() / slope;
    Ok(Nonlinearity {
        max_deviation_ug: dev_g * UG_PER_G,
        full_scale_g,
        ppm_fs: if full_scale_g > 0.0 {
            dev_g / full_scale_g * PPM
        } else {
            0.0
        },
        at_g: x[worst],
    })
}

/// Hysteresis: the largest ascending − descending difference at one level.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Hysteresis {
    /// The difference with the largest magnitude, ascending minus descending,
    /// as acceleration (output difference / |k1|) [µg].
    pub ug: f64,
    /// Mounting where it occurs.
    pub mount: Mount,
    /// Nominal level where it occurs [g].
    pub g_nominal: f64,
}

/// Hysteresis over every level that was visited both ascending and
/// descending, at the same applied acceleration: the part of the up − down
/// output difference that the two passes' applied accelerations explain is
/// removed with the fit's local slope there, dF/da = k1·(1 + 2·k2·a +
/// 3·k3·a²) (method.md (2)), so a table whose rate differs by a few ppm
/// between the passes does not show as instrument hysteresis (with k1 alone,
/// a 10 ppm faster descent read as −114 µg on perfect data). `slope(mount,
/// a)` gives the mounting's output per g of applied magnitude at |a| = a.
/// `None` when no level has both directions.
pub fn hysteresis(
    points: &[Point],
    slope: impl Fn(Mount, f64) -> Option<f64>,
) -> Option<Hysteresis> {
    let mut worst: Option<Hysteresis> = None;
    for mount in [Mount::P, Mount::N] {
        for level in levels_of(points.iter().filter(|p| p.mount == mount)) {
            if let (Some(up), Some(down), Some(g_up), Some(g_down)) =
                (level.output_up, level.output_down, level.g_up, level.g_down)
            {
                let Some(k) = slope(mount, 0.5 * (g_up + g_down).abs()).filter(|k| *k != 0.0)
                else {
                    continue;
                };
                // Express as acceleration in this mounting's input direction.
                let ug = ((up - down) - k * (g_up - g_down)) / k.abs() * UG_PER_G;
                if worst.is_none_or(|w| ug.abs() > w.ug.abs()) {
                    worst = Some(Hysteresis {
                        ug,
                        mount,
                        g_nominal: level.g_nominal,
                    });
                }
            }
        }
    }
    worst
}

/// Repeatability across repeated tests of one unit under the same conditions:
/// (largest − smallest) / mean of the values [ppm] (method.md §3.4).
/// Needs at least two values.
pub fn repeatability_ppm(values: &[f64]) -> Option<f64> {
    if values.len() < 2 {
        return None;
    }
    let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = values.iter().copied().fold(f64::INFINITY, f64::min);
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    (mean != 0.0).then(|| (max - min) / mean.abs() * PPM)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::points::{Direction, infer_directions};

    #[test]
    fn asymmetry_of_equal_scale_factors_is_zero() {
        assert_eq!(asymmetry_ppm(100.0, -100.0), Some(0.0));
        let a = asymmetry_ppm(100.01, -99.99).expect("asym");
        assert!((a - 200.0).abs() < 1e-6, "{a}");
    }

    #[test]
    fn repeatability_is_spread_over_mean() {
        let r = repeatability_ppm(&[100.0, 100.001, 99.999]).expect("rep");
        assert!((r - 20.0).abs() < 1e-6, "{r}");
        assert_eq!(repeatability_ppm(&[1.0]), None);
    }

    #[test]
    fn nonlinearity_of_a_quadratic_is_its_largest_bow() {
        // y = 100·(a + 1e-5·a²) over 0..10 g: best line residual max is known.
        let pts: Vec<Point> = (0..=10)
            .map(|i| {
                let a = f64::from(i);
                Point {
                    mount: Mount::P,
                    g_nominal: a,
                    g_applied: a,
                    output: 100.0 * (a + 1e-5 * a * a),
                    direction: None,
                }
            })
            .collect();
        let nl = nonlinearity(&pts, "q").expect("nl");
        assert_eq!(nl.full_scale_g, 10.0);
        // The LS line through a parabola on 0..10 deviates most at the ends:
        // residual at a=0 is −(c·(mean(a²) − slope·mean(a)))… check against a direct computation.
        let xs: Vec<f64> = (0..=10).map(f64::from).collect();
        let xbar = 5.0;
        let ys: Vec<f64> = xs.iter().map(|a| a * a * 1e-5).collect();
        let ybar = ys.iter().sum::<f64>() / 11.0;
        let sxx: f64 = xs.iter().map(|a| (a - xbar) * (a - xbar)).sum();
        let sxy: f64 = xs
            .iter()
            .zip(&ys)
            .map(|(a, y)| (a - xbar) * (y - ybar))
            .sum();
        let b = sxy / sxx;
        let c0 = ybar - b * xbar;
        let max_dev = xs
            .iter()
            .zip(&ys)
            .map(|(a, y)| (y - c0 - b * a).abs())
            .fold(0.0, f64::max);
        let slope_g = 1.0 + b; // per-g slope of the line (output/100)
        assert!((nl.max_deviation_ug - max_dev / slope_g * 1e6).abs() < 1e-6);
    }

    #[test]
    fn hysteresis_picks_the_largest_level_difference() {
        let mut pts: Vec<Point> = [0.0, 5.0, 10.0, 5.0, 0.0]
            .into_iter()
            .map(|g| Point {
                mount: Mount::P,
                g_nominal: g,
                g_applied: g,
                output: 100.0 * g,
                direction: None,
            })
            .collect();
        pts[3].output += 0.002; // descending 5 g reads 20 µg high
        infer_directions(&mut pts);
        assert_eq!(pts[3].direction, Some(Direction::Down));
        let h = hysteresis(&pts, |_, _| Some(100.0)).expect("h");
        assert!((h.ug + 20.0).abs() < 1e-6, "{h:?}");
        assert_eq!(h.g_nominal, 5.0);
    }

    #[test]
    fn a_table_running_faster_on_the_way_down_is_not_hysteresis() {
        // Mounting N (k1 < 0 against |a|): the descending 40 g pass ran at
        // 3 ppm more rate (6 ppm more g); the instrument has no hysteresis.
        let k1 = -100.0;
        let mut pts: Vec<Point> = [(20.0, 1.0), (40.0, 1.0), (60.0, 1.0), (40.0, 1.000_006)]
            .into_iter()
            .map(|(g, scale)| Point {
                mount: Mount::N,
                g_nominal: g,
                g_applied: -g * scale,
                output: k1 * g * scale,
                direction: None,
            })
            .collect();
        infer_directions(&mut pts);
        let h = hysteresis(&pts, |_, _| Some(k1)).expect("h");
        assert!(h.ug.abs() < 1e-6, "{h:?}");
        // A real 15 µg offset of the descending pass still shows (up − down).
        pts[3].output += 0.0015;
        let h = hysteresis(&pts, |_, _| Some(k1)).expect("h");
        assert!((h.ug + 15.0).abs() < 1e-6, "{h:?}");
    }
}

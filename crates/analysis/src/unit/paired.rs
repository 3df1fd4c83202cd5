//! K2's model inadequacy with the two mountings' levels paired (each
//! shared level, or block of adjacent ones, left out of both together).

use crate::model::{ModelOrder, MountingFit};
use crate::points::{Mount, Point};
use std::collections::BTreeMap;

/// The model inadequacy of K2 and the odd part with the two mountings'
/// levels paired ([`crate::uncertainty::PairedInadequacy`]): when the
/// half-difference (half-sum) shows a significant lack of fit
/// ([`crate::inadequacy::paired_lack_of_fit`]), the jackknife of K2 (the
/// odd part) with each shared level left out of both mountings, beyond its
/// repeatability. `None` when the mountings cannot be paired (each
/// mounting's own is used instead).
pub(super) fn paired_inadequacy(
    by_mount: &BTreeMap<Mount, Vec<Point>>,
    fits: &BTreeMap<Mount, MountingFit>,
    budgets: &BTreeMap<Mount, crate::uncertainty::MountingBudget>,
    order: ModelOrder,
    label: &str,
) -> Option<crate::uncertainty::PairedInadequacy> {
    use crate::uncertainty::Source;
    // Each mounting's residuals from its fit: the one pure error of the
    // reduction (crate::inadequacy::pure_error), as the per-mounting budget's.
    let residuals = |m: Mount| -> Option<Vec<f64>> {
        let fit = fits.get(&m)?;
        (fit.fit.residuals.len() == by_mount.get(&m)?.len())
            .then(|| fit.fit.residuals.iter().map(|r| r.residual).collect())
    };
    let (rp, rn) = (residuals(Mount::P)?, residuals(Mount::N)?);
    fn series<'a>(
        points: &'a [Point],
        residuals: &'a [f64],
        fit: &MountingFit,
    ) -> Option<crate::inadequacy::MountingSeries<'a>> {
        let levels = crate::inadequacy::levels(points);
        let (ss, dof_pe) = crate::inadequacy::pure_error(&levels, residuals);
        (dof_pe > 0).then(|| crate::inadequacy::MountingSeries {
            points,
            residuals,
            k1: fit.fit.k1,
            sigma2: ss / dof_pe as f64,
            dof_pe,
        })
    }
    let (p, n) = (
        series(by_mount.get(&Mount::P)?, &rp, fits.get(&Mount::P)?)?,
        series(by_mount.get(&Mount::N)?, &rn, fits.get(&Mount::N)?)?,
    );
    let degree = usize::from(order.degree());
    let what = format!("{label} both mountings");
    let shared: Vec<f64> = crate::inadequacy::levels(p.points)
        .iter()
        .map(|l| l.g)
        .filter(|g| n.points.iter().any(|q| q.g_nominal.abs() == *g))
        .collect();
    if shared.len() < degree + 2 || degree < 2 {
        return None;
    }
    // k2 of both mountings with level g left out of both.
    let k2_without_all = |points: &[Point], gs: &[f64]| {
        let kept: Vec<Point> = points
            .iter()
            .filter(|q| !gs.contains(&q.g_nominal.abs()))
            .copied()
            .collect();
        crate::model::fit_ieee1293(&kept, order, crate::model::Convention::PerMounting, &what)
            .ok()
            .and_then(|f| f.k2_ug_per_g2)
    };
    let k2_without = |points: &[Point], g: f64| k2_without_all(points, &[g]);
    let mut without: Vec<[f64; 2]> = Vec::new();
    for &g in &shared {
        let (kp, kn) = (k2_without(p.points, g)?, k2_without(n.points, g)?);
        without.push([0.5 * (kp - kn), 0.5 * (kp + kn)]);
    }
    // Each shared level's leverage: the mean of its leverage in the two fits.
    let leverage_of = |points: &[Point]| {
        let levels = crate::inadequacy::levels(points);
        let x: Vec<f64> = points.iter().map(Point::g_magnitude).collect();
        let h = crate::inadequacy::level_leverage(
            &levels,
            &crate::lsq::polynomial_design(&x, degree),
            &what,
        )
        .ok()?;
        Some(
            shared
                .iter()
                .map(|g| levels.iter().position(|l| l.g == *g).map_or(0.0, |i| h[i]))
                .collect::<Vec<f64>>(),
        )
    };
    let (hp, hn) = (leverage_of(p.points)?, leverage_of(n.points)?);
    let leverage: Vec<f64> = hp.iter().zip(&hn).map(|(a, b)| 0.5 * (a + b)).collect();
    let (kp, kn) = (
        fits.get(&Mount::P)?.fit.k2_ug_per_g2?,
        fits.get(&Mount::N)?.fit.k2_ug_per_g2?,
    );
    let full = [0.5 * (kp - kn), 0.5 * (kp + kn)];
    let mut jk = crate::inadequacy::jackknife_variance(full, &without, &leverage);
    // A misfit of one mounting spread over neighbouring levels (a
    // resonance's wings): blocks of adjacent shared levels too, when the
    // half-difference's level residuals are serially correlated.
    let misfit_at = |series: &crate::inadequacy::MountingSeries, g: f64| {
        let members: Vec<f64> = series
            .points
            .iter()
            .zip(series.residuals)
            .filter(|(q, _)| q.g_nominal.abs() == g)
            .map(|(_, r)| *r / series.k1)
            .collect();
        members.iter().sum::<f64>() / members.len().max(1) as f64
    };
    let half_difference: Vec<f64> = shared
        .iter()
        .map(|&g| 0.5 * (misfit_at(&p, g) - misfit_at(&n, g)))
        .collect();
    if crate::inadequacy::neighbours_correlated(&half_difference) {
        let b = crate::inadequacy::NEIGHBOUR_BLOCK;
        let mut blocks: Vec<[f64; 2]> = Vec::new();
        for w in shared.windows(b) {
            let (bp, bn) = (k2_without_all(p.points, w)?, k2_without_all(n.points, w)?);
            blocks.push([0.5 * (bp - bn), 0.5 * (bp + bn)]);
        }
        let jb = crate::inadequacy::block_jackknife(full, &blocks, &leverage, b);
        jk = [jk[0].max(jb[0]), jk[1].max(jb[1])];
    }
    // A smooth misfit of one mounting (a broad bump, a step): the part the
    // cubic absorbs, read through the shape that best explains the
    // half-difference (crate::inadequacy::smooth). Each of P's points at
    // its level's half-difference, so that a level weighs by its readings.
    let x: Vec<f64> = p.points.iter().map(Point::g_magnitude).collect();
    let at: Vec<f64> = p
        .points
        .iter()
        .map(|q| {
            shared
                .iter()
                .position(|s| *s == q.g_nominal.abs())
                .map_or(0.0, |i| half_difference[i])
        })
        .collect();
    // The levels flagged off the curve in either mounting: the jackknife's.
    let flagged: Vec<f64> = [Mount::P, Mount::N]
        .iter()
        .filter_map(|m| fits.get(m)?.diagnostics.as_ref())
        .flat_map(|d| d.outlier_levels.iter().map(|o| o.g))
        .collect();
    let set_aside: Vec<bool> = p
        .points
        .iter()
        .map(|q| flagged.contains(&q.g_nominal.abs()))
        .collect();
    let levels_read = shared.iter().filter(|g| !flagged.contains(g)).count();
    // One reading's pure error in the half-difference [g²].
    let sigma2_half = 0.25 * (p.sigma2 / (p.k1 * p.k1) + n.sigma2 / (n.k1 * n.k1));
    let read = |misfit: &[f64], read_degree: usize| {
        let readings = crate::inadequacy::Readings {
            x: &x,
            misfit,
            set_aside: &set_aside,
            read_degree,
        };
        crate::inadequacy::smooth_misfit(&readings, sigma2_half, levels_read, degree, 2, &what)
            .filter(|s| {
                s.effect.is_finite()
                    && s.significant(
                        sigma2_half,
                        p.dof_pe + n.dof_pe,
                        levels_read.saturating_sub(read_degree + 1),
                    )
            })
    };
    // The two mountings share the instrument's cubic coefficient (K3 reads
    // as +K3 in both per-mounting fits against |a|, and a table error
    // shifts both alike), so a half-difference of the cubics is part of a
    // misfit that one mounting's cubic absorbed (a ramp, a broad step):
    // it is also read with that part put back, through a quadratic, the
    // effect on K2 staying the cubic fits'; the larger effect counts.
    // With a quadratic model there is no shared coefficient to read against.
    let shared_cubic = match (
        degree,
        fits.get(&Mount::P)?.fit.k3_ug_per_g3,
        fits.get(&Mount::N)?.fit.k3_ug_per_g3,
    ) {
        (3, Some(k3p), Some(k3n)) => {
            let half = 0.5 * (k3p - k3n) / crate::UG_PER_G;
            let with_cubic: Vec<f64> = at
                .iter()
                .zip(&x)
                .map(|(m, g)| m + half * g.powi(3))
                .collect();
            read(&with_cubic, 2)
        }
        _ => None,
    };
    let smooth = [read(&at, degree), shared_cubic]
        .into_iter()
        .flatten()
        .max_by(|a, b| a.effect.abs().total_cmp(&b.effect.abs()));
    if let Some(s) = smooth {
        let effect = s.effect * crate::UG_PER_G;
        jk[0] = jk[0].max(effect * effect);
    }
    let repeat = |m: Mount| {
        budgets
            .get(&m)
            .and_then(|b| b.effects.iter().find(|e| e.source == Source::Repeatability))
            .map_or(0.0, |e| e.delta[2])
    };
    let repeatability = 0.5 * repeat(Mount::P).hypot(repeat(Mount::N));
    let dof = (shared.len() - (degree + 1)) as f64;
    let part = |even: bool, index: usize| {
        let significant = crate::inadequacy::paired_lack_of_fit(&p, &n, degree, even, &what)
            .ok()
            .flatten()
            .is_some_and(|(_, pv)| pv < crate::uncertainty::LACK_OF_FIT_ALPHA);
        let significant = significant || (even && smooth.is_some());
        let u = crate::inadequacy::inadequacy_beyond(jk[index], repeatability);
        (significant && u > 0.0).then_some((u, dof))
    };
    Some(crate::uncertainty::PairedInadequacy {
        even: part(true, 0),
        odd: part(false, 1),
    })
}

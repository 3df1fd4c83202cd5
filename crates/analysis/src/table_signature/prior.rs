//! What past runs on the same centrifuge measured of its signature,
//! pooled with a new run's (docs/method.md §6).

use super::{SE_FLOOR_UG, TableSignature, disagreement};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What past runs on the same centrifuge measured of its signature: per
/// level the inverse-variance mean of their own signatures and its
/// standard error, pooled with a new run's before its correction is made.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Prior {
    /// (level [g], signature [µg], standard error [µg]).
    pub levels: Vec<(f64, f64, f64)>,
    /// The runs it rests on.
    pub runs: usize,
    /// The instruments it rests on.
    pub instruments: usize,
    /// The older runs left out because their signature disagrees with the
    /// newer ones' (the table changed since).
    #[serde(default)]
    pub set_aside_runs: usize,
}

impl Prior {
    /// Pool the runs' own signatures (each run's `levels`, its measurement
    /// alone), `past` newest first: the newest run and each older one while
    /// it agrees with those newer than it and none of those found the table
    /// changed ([`disagreement`]); `None` without any.
    pub fn of(past: &[TableSignature]) -> Option<Prior> {
        let mut agreeing: Vec<&TableSignature> = Vec::new();
        for sig in past {
            if let Some(newer) = Prior::pooled(&agreeing)
                && (agreeing.iter().any(|s| s.change.is_some())
                    || !disagreement(&newer.levels, &sig.levels).is_empty())
            {
                break;
            }
            agreeing.push(sig);
        }
        let mut prior = Prior::pooled(&agreeing)?;
        prior.set_aside_runs = past.len() - agreeing.len();
        Some(prior)
    }

    /// The inverse-variance pool of `past`, every one of them.
    fn pooled(past: &[&TableSignature]) -> Option<Prior> {
        if past.is_empty() {
            return None;
        }
        let mut sums: BTreeMap<u64, (f64, f64)> = BTreeMap::new();
        for sig in past {
            for l in &sig.levels {
                let w = 1.0 / l.se_ug.max(SE_FLOOR_UG).powi(2);
                let e = sums.entry(l.g.to_bits()).or_default();
                e.0 += w * l.residual_ug;
                e.1 += w;
            }
        }
        let mut levels: Vec<(f64, f64, f64)> = sums
            .into_iter()
            .filter(|(_, (_, w))| *w > 0.0)
            .map(|(g, (ws, w))| (f64::from_bits(g), ws / w, w.sqrt().recip()))
            .collect();
        levels.sort_by(|a, b| a.0.total_cmp(&b.0));
        Some(Prior {
            levels,
            runs: past.len(),
            instruments: past.iter().map(|s| s.instruments).sum(),
            set_aside_runs: 0,
        })
    }

    /// `s` (standard errors `se`) at `levels` pooled with this prior by
    /// inverse variance, level by level (a level it lacks is left as is).
    pub(super) fn pool(&self, levels: &[f64], s: &[f64], se: &[f64]) -> (Vec<f64>, Vec<f64>) {
        levels
            .iter()
            .enumerate()
            .map(|(i, g)| match self.levels.iter().find(|(l, _, _)| l == g) {
                Some(&(_, ps, pse)) => {
                    let (w, wp) = (se[i].powi(-2), pse.max(SE_FLOOR_UG).powi(-2));
                    ((w * s[i] + wp * ps) / (w + wp), (w + wp).sqrt().recip())
                }
                None => (s[i], se[i]),
            })
            .unzip()
    }
}

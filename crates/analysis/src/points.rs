//! Averaged points: the input of every reduction (method.md §3.3).

use serde::{Deserialize, Serialize};
use std::fmt;

/// How an instrument is mounted on the centrifuge arm (method.md §3.3).
///
/// The declaration order (P before N) is the order used in every map and report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum Mount {
    /// Input axis pointing at the spin axis: the instrument sees +a.
    P,
    /// Input axis pointing away from the spin axis: the instrument sees −a.
    N,
}

impl Mount {
    /// The sign of the input acceleration in this mounting: +1 for P, −1 for N.
    pub fn input_sign(self) -> f64 {
        match self {
            Mount::P => 1.0,
            Mount::N => -1.0,
        }
    }

    /// Parse the `mount` field of a points file: `P` or `N`, any case.
    pub fn parse(text: &str) -> Option<Mount> {
        match text.trim() {
            "P" | "p" => Some(Mount::P),
            "N" | "n" => Some(Mount::N),
            _ => None,
        }
    }
}

impl fmt::Display for Mount {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Mount::P => "P",
            Mount::N => "N",
        })
    }
}

/// Whether a point was taken while the acceleration was rising or falling.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Direction {
    /// Ascending pass.
    Up,
    /// Descending pass.
    Down,
}

impl Direction {
    /// Parse `up`/`down` (also `u`/`d`, `asc`/`desc`, `ascending`/`descending`), any case.
    pub fn parse(text: &str) -> Option<Direction> {
        match text.trim().to_ascii_lowercase().as_str() {
            "up" | "u" | "asc" | "ascending" => Some(Direction::Up),
            "down" | "d" | "desc" | "descending" => Some(Direction::Down),
            _ => None,
        }
    }

    /// Its serde name: `up` or `down`.
    pub fn as_str(self) -> &'static str {
        match self {
            Direction::Up => "up",
            Direction::Down => "down",
        }
    }
}

/// One averaged point: n one-second outputs at one stable level.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// Mounting of the instrument during this point.
    pub mount: Mount,
    /// The level's nominal acceleration [g]; identifies the level.
    pub g_nominal: f64,
    /// The acceleration actually applied at this instrument's radius [g],
    /// method.md (9). Magnitude; the sign comes from `mount`.
    pub g_applied: f64,
    /// Mean instrument output at this point [output units, Hz for a VBA].
    pub output: f64,
    /// Ascending or descending pass; `None` lets [`infer_directions`] decide.
    pub direction: Option<Direction>,
}

impl Point {
    /// The magnitude of the applied acceleration [g] (method.md §3.4).
    pub fn g_magnitude(&self) -> f64 {
        self.g_applied.abs()
    }

    /// The signed input acceleration [g]: +|a| in mounting P, −|a| in N.
    pub fn g_signed(&self) -> f64 {
        self.mount.input_sign() * self.g_applied.abs()
    }
}

/// Fill in missing directions of one mounting's points, in the order they
/// were taken: every point up to and including the first visit of the highest
/// level is ascending, every later point descending (the published up-then-
/// down sequence, method.md §3.3). Points that already carry a direction keep it.
pub fn infer_directions(points: &mut [Point]) {
    let Some(top) = points
        .iter()
        .map(|p| p.g_nominal.abs())
        .fold(None, |m: Option<f64>, g| Some(m.map_or(g, |m| m.max(g))))
    else {
        return;
    };
    let mut passed_top = false;
    for p in points.iter_mut() {
        let dir = if passed_top {
            Direction::Down
        } else {
            Direction::Up
        };
        if p.g_nominal.abs() == top {
            passed_top = true;
        }
        p.direction.get_or_insert(dir);
    }
}

/// The published level table (method.md §3.3): 0, 1, 5, then every 5 g up to
/// `max_g` (and `max_g` itself if it is not a multiple of 5).
pub fn published_levels(max_g: f64) -> Vec<f64> {
    let mut levels = vec![0.0];
    if max_g >= 1.0 {
        levels.push(1.0);
    }
    let mut g = 5.0;
    while g <= max_g {
        levels.push(g);
        g += 5.0;
    }
    if levels.last().is_some_and(|&last| last < max_g) {
        levels.push(max_g);
    }
    levels
}

/// The sequence of an up-then-down pass over `levels` (ascending), visiting
/// the top level once: 0, 1, …, m, …, 1, 0.
pub fn up_down(levels: &[f64]) -> Vec<f64> {
    levels
        .iter()
        .chain(levels.iter().rev().skip(1))
        .copied()
        .collect()
}

/// Number of distinct nominal levels among `points`.
pub fn distinct_levels<'a>(points: impl IntoIterator<Item = &'a Point>) -> usize {
    let mut levels: Vec<f64> = points.into_iter().map(|p| p.g_nominal.abs()).collect();
    levels.sort_by(f64::total_cmp);
    levels.dedup();
    levels.len()
}

/// Points grouped by nominal level, sorted by level, for one mounting.
#[derive(Debug, Clone, PartialEq)]
pub struct Level {
    /// Nominal level [g] (magnitude).
    pub g_nominal: f64,
    /// Mean applied acceleration magnitude over the level's points [g].
    pub g_applied: f64,
    /// Mean output over the level's points.
    pub output: f64,
    /// Mean output of ascending points, if any.
    pub output_up: Option<f64>,
    /// Mean output of descending points, if any.
    pub output_down: Option<f64>,
    /// Mean applied acceleration magnitude of ascending points, if any [g].
    pub g_up: Option<f64>,
    /// Mean applied acceleration magnitude of descending points, if any [g].
    pub g_down: Option<f64>,
    /// Number of points at this level.
    pub count: usize,
}

/// Group one mounting's points by nominal level (ascending and descending
/// visits of the same level are averaged; each direction is also kept).
pub fn levels_of<'a>(points: impl IntoIterator<Item = &'a Point>) -> Vec<Level> {
    let mut sorted: Vec<&Point> = points.into_iter().collect();
    sorted.sort_by(|a, b| a.g_nominal.abs().total_cmp(&b.g_nominal.abs()));
    let mean = |xs: &[f64]| (!xs.is_empty()).then(|| xs.iter().sum::<f64>() / xs.len() as f64);
    sorted
        .chunk_by(|a, b| a.g_nominal.abs() == b.g_nominal.abs())
        .map(|group| {
            let pick = |d: Direction, value: fn(&Point) -> f64| -> Vec<f64> {
                group
                    .iter()
                    .filter(|p| p.direction == Some(d))
                    .map(|p| value(p))
                    .collect()
            };
            let output = |p: &Point| p.output;
            let outputs: Vec<f64> = group.iter().map(|p| p.output).collect();
            let applied: Vec<f64> = group.iter().map(|p| p.g_magnitude()).collect();
            Level {
                g_nominal: group[0].g_nominal.abs(),
                g_applied: mean(&applied).unwrap_or(0.0),
                output: mean(&outputs).unwrap_or(0.0),
                output_up: mean(&pick(Direction::Up, output)),
                output_down: mean(&pick(Direction::Down, output)),
                g_up: mean(&pick(Direction::Up, Point::g_magnitude)),
                g_down: mean(&pick(Direction::Down, Point::g_magnitude)),
                count: group.len(),
            }
        })
        .collect()
}

/// The points of one unit (serial number) from one run, in the order taken.
#[derive(Debug, Clone, PartialEq)]
pub struct UnitPoints {
    /// Serial number.
    pub unit: String,
    /// Label of the run (test) these points come from, when there are several.
    pub run: Option<String>,
    /// The averaged points, in the order they were taken.
    pub points: Vec<Point>,
}

impl UnitPoints {
    /// "unit 'SN12'" or "unit 'SN12' run '3'", for messages.
    pub fn label(&self) -> String {
        match &self.run {
            Some(run) => format!("unit '{}' run '{run}'", self.unit),
            None => format!("unit '{}'", self.unit),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(g: f64) -> Point {
        Point {
            mount: Mount::P,
            g_nominal: g,
            g_applied: g,
            output: g,
            direction: None,
        }
    }

    #[test]
    fn directions_follow_up_then_down() {
        let mut pts: Vec<Point> = [0.0, 1.0, 5.0, 10.0, 10.0, 5.0, 1.0, 0.0]
            .into_iter()
            .map(pt)
            .collect();
        infer_directions(&mut pts);
        let dirs: Vec<Direction> = pts.iter().filter_map(|p| p.direction).collect();
        use Direction::*;
        assert_eq!(dirs, vec![Up, Up, Up, Up, Down, Down, Down, Down]);
    }

    #[test]
    fn levels_average_repeats_and_keep_directions() {
        let mut pts: Vec<Point> = [0.0, 5.0, 10.0, 5.0, 0.0].into_iter().map(pt).collect();
        pts[3].output = 7.0;
        infer_directions(&mut pts);
        let levels = levels_of(&pts);
        assert_eq!(levels.len(), 3);
        assert_eq!(levels[1].count, 2);
        assert_eq!(levels[1].output, 6.0);
        assert_eq!(levels[1].output_up, Some(5.0));
        assert_eq!(levels[1].output_down, Some(7.0));
        assert_eq!(levels[2].output_down, None);
    }

    #[test]
    fn published_table_steps_by_five() {
        assert_eq!(
            published_levels(20.0),
            vec![0.0, 1.0, 5.0, 10.0, 15.0, 20.0]
        );
        assert_eq!(published_levels(72.0).last(), Some(&72.0));
        assert_eq!(published_levels(70.0).len(), 16);
        assert_eq!(up_down(&[0.0, 1.0, 5.0]), vec![0.0, 1.0, 5.0, 1.0, 0.0]);
    }

    #[test]
    fn mount_and_direction_parse() {
        assert_eq!(Mount::parse(" n "), Some(Mount::N));
        assert_eq!(Mount::parse("X"), None);
        assert_eq!(Direction::parse("Desc"), Some(Direction::Down));
        assert_eq!(Direction::parse("sideways"), None);
    }
}

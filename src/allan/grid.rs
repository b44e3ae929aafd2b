//! τ grids: which averaging factors to evaluate.
//!
//! A grid is a set of unique whole averaging factors m ≥ 1, ascending. Log spacing keeps the cost
//! per row at K ≈ 10 per decade instead of one per sample, which is what makes the streaming engine
//! O(K) per sample.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// How averaging factors are chosen (**contract** names for `--taus`: `all`, `octave`, `decade`, N).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum TauGrid {
    /// Every m from 1 to the maximum.
    All,
    /// Powers of two: 1, 2, 4, 8, …
    Octave,
    /// 1, 2, 4 times powers of ten (Stable32's "decade": 1, 2, 4, 10, 20, 40, 100, …).
    Decade,
    /// N log-spaced factors per decade, rounded to unique integers.
    PerDecade(u32),
}

impl Default for TauGrid {
    /// Ten per decade (docs/design.md §2).
    fn default() -> Self {
        TauGrid::PerDecade(10)
    }
}

/// A `--taus` value that is none of `all`, `octave`, `decade` or a positive whole number.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("invalid tau grid '{0}': expected all, octave, decade, or a number of points per decade (1..=1000)")]
pub struct TauGridError(pub String);

impl FromStr for TauGrid {
    type Err = TauGridError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "all" => Ok(TauGrid::All),
            "octave" => Ok(TauGrid::Octave),
            "decade" => Ok(TauGrid::Decade),
            n => match n.parse::<u32>() {
                Ok(k) if (1..=1000).contains(&k) => Ok(TauGrid::PerDecade(k)),
                _ => Err(TauGridError(s.to_string())),
            },
        }
    }
}

impl fmt::Display for TauGrid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TauGrid::All => f.write_str("all"),
            TauGrid::Octave => f.write_str("octave"),
            TauGrid::Decade => f.write_str("decade"),
            TauGrid::PerDecade(n) => write!(f, "{n}"),
        }
    }
}

impl TauGrid {
    /// The averaging factors 1 ≤ m ≤ `max_m`, unique and ascending.
    ///
    /// ```
    /// use fdavar::allan::TauGrid;
    /// assert_eq!(TauGrid::Decade.factors(250), vec![1, 2, 4, 10, 20, 40, 100, 200]);
    /// assert_eq!(TauGrid::Octave.factors(9), vec![1, 2, 4, 8]);
    /// assert_eq!(TauGrid::PerDecade(3).factors(10), vec![1, 2, 5, 10]);
    /// ```
    pub fn factors(&self, max_m: usize) -> Vec<usize> {
        if max_m == 0 {
            return Vec::new();
        }
        let mut out: Vec<usize> = match *self {
            TauGrid::All => (1..=max_m).collect(),
            TauGrid::Octave => std::iter::successors(Some(1usize), |m| m.checked_mul(2))
                .take_while(|&m| m <= max_m)
                .collect(),
            TauGrid::Decade => std::iter::successors(Some(1usize), |d| d.checked_mul(10))
                .take_while(|&d| d <= max_m)
                .flat_map(|d| [d, 2 * d, 4 * d])
                .filter(|&m| m <= max_m)
                .collect(),
            TauGrid::PerDecade(n) => {
                let n = f64::from(n.max(1));
                let decades = (max_m as f64).log10();
                let steps = (decades * n).floor() as usize;
                (0..=steps)
                    .map(|k| 10f64.powf(k as f64 / n).round() as usize)
                    .filter(|&m| (1..=max_m).contains(&m))
                    .collect()
            }
        };
        out.dedup();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grids_parse_and_print() {
        for s in ["all", "octave", "decade", "10"] {
            assert_eq!(s.parse::<TauGrid>().unwrap().to_string(), s);
        }
        assert!("0".parse::<TauGrid>().is_err());
        assert!("many".parse::<TauGrid>().is_err());
    }

    #[test]
    fn per_decade_is_unique_ascending_and_bounded() {
        let f = TauGrid::PerDecade(10).factors(100_000);
        assert!(f.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(f.first(), Some(&1));
        assert_eq!(f.last(), Some(&100_000));
        assert!(TauGrid::All.factors(0).is_empty());
    }
}

//! Adaptive windows driven by the F value: the seed's Eq. 3 (`sign`) and a bounded proportional step.
//!
//! Both shrink the window when the window's variance ratio F exceeds its steady target F̃ (a change
//! is inside the window: a short window tracks it) and grow it otherwise (steady: a long window gives
//! a confident estimate). When F or F̃ is unknown (no valid samples yet, F̃ still being learned) the
//! window holds: no evidence, no move.
//!
//! Rejected alternative: treating an unknown F as "steady" and growing; after a long gap that would
//! make the first rows of new data use the longest window exactly where a change is most likely.

use super::{WindowBounds, WindowPolicy};

/// Eq. 3 of the seed, exactly: the window moves by ±ΔW by the sign of F − F̃, then is clamped.
///
/// # Formula
/// ```text
/// W(t+1) = clamp(W(t) − sign(F(t) − F̃)·ΔW, λ1, λ2)
/// ```
/// where W is the window length in samples, F(t) the variance ratio of the window at t (Eq. 2),
/// F̃ its steady target, ΔW the step and [λ1, λ2] the bounds. sign(0) = 0.
///
/// # References
/// Yang H. et al., Electronics Optics & Control 23(10), 2016, Eq. 3.
///
/// ```
/// use fdavar::davar::{SignPolicy, WindowPolicy};
/// let mut p = SignPolicy::new(171, 501, 4);
/// assert_eq!(p.next(501, Some(5.0), Some(3.3)), 497);
/// assert_eq!(p.next(501, Some(1.0), Some(3.3)), 501);
/// assert_eq!(p.next(173, Some(50.0), Some(3.3)), 171);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SignPolicy {
    bounds: WindowBounds,
    step: usize,
}

impl SignPolicy {
    /// λ1 = `min`, λ2 = `max`, ΔW = `step` samples (validated by [`crate::params`]).
    pub fn new(min: usize, max: usize, step: usize) -> Self {
        SignPolicy {
            bounds: WindowBounds { min, max },
            step,
        }
    }
}

impl WindowPolicy for SignPolicy {
    fn name(&self) -> &'static str {
        "sign"
    }

    fn bounds(&self) -> WindowBounds {
        self.bounds
    }

    fn initial(&self) -> usize {
        self.bounds.max
    }

    fn next(&mut self, w: usize, f: Option<f64>, f_target: Option<f64>) -> usize {
        match (f, f_target) {
            (Some(f), Some(target)) => {
                let step = self.step as i64;
                let delta = match f.partial_cmp(&target) {
                    Some(std::cmp::Ordering::Greater) => -step,
                    Some(std::cmp::Ordering::Less) => step,
                    _ => 0,
                };
                self.bounds.clamp(w as i64 + delta)
            }
            _ => self.bounds.clamp(w as i64),
        }
    }
}

/// A step that grows with how far F is from F̃ on a log scale, bounded.
///
/// The seed's text says "the larger F, the more the window shrinks", which Eq. 3 does not do. This
/// policy does: ΔW per doubling (or halving) of F relative to F̃, rounded up to an even number of
/// samples (so an odd window stays odd and centred), at most `max_step`.
///
/// # Formula
/// ```text
/// s = min(max_step, 2·⌈ΔW·|log₂(F/F̃)| / 2⌉)
/// W(t+1) = clamp(W(t) − sign(F − F̃)·s, λ1, λ2)
/// ```
/// where ΔW is the step per factor 2 of F/F̃ and max_step the largest move per row.
///
/// ```
/// use fdavar::davar::{ProportionalPolicy, WindowPolicy};
/// let mut p = ProportionalPolicy::new(171, 501, 4, 32);
/// assert_eq!(p.next(401, Some(6.6), Some(3.3)), 397);   // F = 2F̃: one ΔW
/// assert_eq!(p.next(401, Some(26.4), Some(3.3)), 389);  // F = 8F̃: three ΔW
/// assert_eq!(p.next(401, Some(3.3e6), Some(3.3)), 369); // bounded by max_step
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProportionalPolicy {
    bounds: WindowBounds,
    step: usize,
    max_step: usize,
}

impl ProportionalPolicy {
    /// λ1 = `min`, λ2 = `max`, ΔW = `step` per doubling of F/F̃, at most `max_step` per row.
    pub fn new(min: usize, max: usize, step: usize, max_step: usize) -> Self {
        ProportionalPolicy {
            bounds: WindowBounds { min, max },
            step,
            max_step,
        }
    }
}

impl WindowPolicy for ProportionalPolicy {
    fn name(&self) -> &'static str {
        "proportional"
    }

    fn bounds(&self) -> WindowBounds {
        self.bounds
    }

    fn initial(&self) -> usize {
        self.bounds.max
    }

    fn next(&mut self, w: usize, f: Option<f64>, f_target: Option<f64>) -> usize {
        let (Some(f), Some(target)) = (f, f_target) else {
            return self.bounds.clamp(w as i64);
        };
        if !(f > 0.0 && target > 0.0) {
            return self.bounds.clamp(w as i64);
        }
        let log_ratio = (f / target).log2();
        let half_steps = (self.step as f64 * log_ratio.abs() / 2.0).ceil();
        let size = ((2.0 * half_steps) as usize).min(self.max_step) as i64;
        let delta = if log_ratio > 0.0 { -size } else { size };
        self.bounds.clamp(w as i64 + delta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sign_walks_both_ways_and_respects_bounds() {
        let mut p = SignPolicy::new(171, 501, 4);
        assert_eq!(p.initial(), 501);
        assert_eq!(p.next(501, Some(0.1), Some(1.0)), 501);
        assert_eq!(p.next(301, Some(0.1), Some(1.0)), 305);
        assert_eq!(p.next(301, Some(1.0), Some(1.0)), 301);
        assert_eq!(p.next(301, None, Some(1.0)), 301);
        assert_eq!(p.next(301, Some(9.0), None), 301);
        assert_eq!(p.next(171, Some(9.0), Some(1.0)), 171);
    }

    #[test]
    fn proportional_grows_with_distance_and_is_symmetric_in_log() {
        let mut p = ProportionalPolicy::new(171, 501, 4, 64);
        let up = 401 - p.next(401, Some(4.0), Some(1.0)) as i64;
        let down = p.next(401, Some(0.25), Some(1.0)) as i64 - 401;
        assert_eq!(up, 8);
        assert_eq!(down, 8);
        let near = 401 - p.next(401, Some(1.01), Some(1.0)) as i64;
        assert_eq!(near, 2, "the smallest move keeps parity");
        assert_eq!(p.next(401, Some(1.0), Some(1.0)), 401);
        assert_eq!(p.next(401, Some(f64::NAN), Some(1.0)), 401);
    }
}

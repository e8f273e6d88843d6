//! Newton's stopping test by its rate: the corrections still to come, estimated from the
//! last full steps, instead of one more iteration to measure the next.
//!
//! The tolerance bounds the velocity change further iterations would make. Measuring it
//! takes an iteration whose own step is below the tolerance (an assembly, a factorization
//! and a line search spent to confirm what the last two steps already showed). After two
//! full steps (no line-search cut, no second-order correction) of residuals r₋₁ and r₀ with
//! ratio q = r₀/r₋₁ < ½, the corrections still to come sum to at most r₀ q/(1 − q) if the
//! contraction holds, the tail of a geometric series; below the tolerance the loop ends,
//! and those corrections are not made (the measured test makes the one it measures: its
//! runs end closer to a converged one). The contraction holds where
//! convergence is superlinear, so the contact-free loop counts only steps with its first
//! Hessians, unshifted (projected ones converge linearly at a rate that worsens as the fast
//! modes die out), and where sliders have friction, which lags the normal force an
//! iteration behind (a fixed-point iteration of its own), only once the normal forces'
//! changes contract by the same test (`Integrator::friction_budget`). The contact
//! step's model is partly bounded and may converge linearly (`tail.rs`); it counts steps
//! whose ADMM converged, and the bound q < ½ keeps out the slow tails (their ratios are
//! well above it).
//!
//! The examples without contacts then take fewer Newton iterations a step, and their
//! outputs stay well within the tolerance's budget of the same graph run at 1e-7 m/s (the
//! examples' `--stats-json` and outputs measure it; figures in
//! docs/history/issue-71-comments.md; curtain_rail's sliders have friction). Not taken:
//! counting every full step (projected ones too) saves more on hair and sliders but takes
//! projected Newton on buckling cloth centimetres off the converged run, and so does the
//! square of the ratio as the estimate (Newton's quadratic rate taken for granted).

use crate::settings::StepStats;

/// The largest ratio of two full steps for which their contraction is trusted to hold.
const RATE_MAX: f64 = 0.5;

/// The last full step's residual of one Newton loop.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct RateStop {
    last: Option<f64>,
}

impl RateStop {
    /// After an iteration whose step of residual `res` was taken (`full`: whole and as
    /// computed; any other step forgets the last): the corrections still to come, estimated
    /// from the contraction since the last full step, when they are below `tolerance`.
    pub(super) fn done(&mut self, res: f64, full: bool, tolerance: f64) -> Option<f64> {
        if !full || !res.is_finite() {
            self.last = None;
            return None;
        }
        // A zero last residual gives a ratio of ∞ or NaN: no estimate.
        let estimate = self.last.and_then(|prev| {
            let q = res / prev;
            (q < RATE_MAX).then(|| res * q / (1.0 - q))
        });
        self.last = Some(res);
        estimate.filter(|&e| e < tolerance)
    }

    /// [`Self::done`] against `budget`, the tolerance left to this estimate (None: the loop
    /// may not end by its rate now, such as while sliders' lagged friction has not settled),
    /// recorded in `stats` (converged, counted, its estimate kept) when the loop is to end.
    /// The residual is recorded either way.
    pub(super) fn ends_within(
        &mut self,
        budget: Option<f64>,
        stats: &mut StepStats,
        res: f64,
        full: bool,
    ) -> bool {
        let Some(estimate) = self.done(res, full, budget.unwrap_or(f64::NEG_INFINITY)) else {
            return false;
        };
        stats.converged = true;
        stats.rate_stops += 1;
        stats.estimate = Some(estimate);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::super::Integrator;
    use super::super::order::tests::{farthest, shell_sheet};
    use super::*;
    use crate::settings::Settings;

    /// A sheet hanging from two corners falls for 12 steps at a tolerance of 1e-4 m/s and at
    /// 1e-10: some of the first run's steps end by the estimate, and it stays within the
    /// budget the tolerance allows (1e-4 m/s for h a step: 2.5e-5 m over 12 steps of 1/48 s)
    /// of the converged run.
    #[test]
    fn steps_ended_by_their_rate_keep_to_the_tolerance() {
        let h = 1.0 / 48.0;
        let run = |tolerance: f64| {
            let (sys, mut state) = shell_sheet(12, 1e-3);
            let mut it = Integrator::new(&sys).unwrap();
            let settings = Settings {
                tolerance,
                max_iterations: 100,
                ..Settings::default()
            };
            let mut stops = 0;
            for _ in 0..12 {
                stops += it
                    .step(&sys, &mut state, None, h, &settings)
                    .unwrap()
                    .rate_stops;
            }
            (state, stops)
        };
        let (coarse, stops) = run(1e-4);
        let (fine, _) = run(1e-10);
        assert!(stops > 0, "no step ended by its rate");
        let off = farthest(&coarse, &fine);
        assert!(off < 12.0 * h * 1e-4, "{off:e} m from the converged run");
    }

    #[test]
    fn a_fast_contraction_ends_the_loop_a_slow_one_or_a_cut_step_does_not() {
        // 1e-3 then 1e-4: q = 0.1, the tail 1e-4 · 0.1/0.9 = 1.1e-5.
        let mut r = RateStop::default();
        assert!(r.done(1e-3, true, 2e-5).is_none());
        let e = r
            .done(1e-4, true, 2e-5)
            .expect("an estimate below the tolerance");
        assert!((e - 1e-5 / 0.9).abs() < 1e-18, "{e:e}");
        // The same with a tolerance below the tail's sum.
        let mut r = RateStop::default();
        assert!(r.done(1e-3, true, 1e-5).is_none());
        assert!(r.done(1e-4, true, 1e-5).is_none());
        // A slow contraction (q = 0.6) is not trusted however small its tail.
        let mut r = RateStop::default();
        assert!(r.done(1e-3, true, 1.0).is_none());
        assert!(r.done(6e-4, true, 1.0).is_none());
        // A step cut by the line search forgets the last full one.
        let mut r = RateStop::default();
        assert!(r.done(1e-3, true, 1.0).is_none());
        assert!(r.done(1e-4, false, 1.0).is_none());
        assert!(r.done(1e-5, true, 1.0).is_none());
        assert!(r.done(1e-6, true, 1.0).is_some());
        // No estimate from a zero or non-finite residual.
        let mut r = RateStop::default();
        assert!(r.done(0.0, true, 1.0).is_none());
        assert!(r.done(0.0, true, 1.0).is_none());
        assert!(r.done(f64::NAN, true, 1.0).is_none());
        assert!(r.done(1e-9, true, 1.0).is_none());
    }
}

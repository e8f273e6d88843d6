//! Extrapolation of a Newton tail along one direction: a linearly converging one summed
//! (Aitken's Δ²), a growing one taken several steps ahead.
//!
//! The contact step's Newton model is stiffer than the incremental potential where cloth is
//! compressed: its membranes keep at most `CONTACT_CURVATURE` of the inertia as negative
//! curvature, so that ADMM sees a convex model. Along a mode whose true curvature is below
//! the model's, each full step covers the same fraction 1 − r of the distance left, and the
//! steps form a geometric series: traced on cloth_drape's contact steps, tails of tens of
//! iterations whose successive steps are parallel to three digits, at a ratio r below 1
//! that holds from step to step (figures in docs/history/issue-71-comments.md). The
//! distance left after a step d is then
//! d r/(1 − r), so once two successive ratios agree the step is tried at 1/(1 − r) its
//! length (the sum of the series), and the line search judges it like any other: a step
//! that does not decrease the objective enough is halved, down to the plain full step.
//! It cuts cloth_drape's and cloth_pile's Newton iterations a step (the examples'
//! `--stats-json` and `bench/ensemble.py` measure it).
//!
//! Where a fold snaps through, the series grows instead: parallel full steps each longer
//! than the last for several iterations (traced on cloth_pile), the bounded model
//! underrating how far the unstable shape goes. Once two successive ratios are ≥ 1 the step
//! is tried at MAX_STRETCH its length (the ratios speed up, so no sum predicts the end; the
//! line search halves it back where the fold ends sooner). That cuts cloth_drape's and
//! cloth_pile's iterations again, each ending about as near its run at a hundredth of the
//! tolerance as without it; a few steps ahead (1 + r + r² + r³) gains less (figures in
//! docs/history/issue-71-comments.md).
//!
//! The contact step bounds the stretch so no point moves more than half the smallest
//! contact distance beyond the full step (rigid groups' members bounded by their arcs), and
//! runs it only for systems with membranes and without rods (`Integrator::tails`: hair's
//! long tails are crawls, not this series, and stretching them let strands pass through
//! strands).

/// Successive steps this parallel (cosine) count as one mode's series (stricter, at 0.999
/// with ratios agreeing to 0.01 and no halving, the tails are found only at their ends and
/// most of the gain is lost; figures in docs/history/issue-71-comments.md).
const PARALLEL: f64 = 0.99;
/// Two successive ratios agreeing to within this make a geometric series.
const RATIO_AGREES: f64 = 0.05;
/// The longest extrapolation, as a multiple of the step (the sum at r = 0.95; closer to 1
/// the steps crawl rather than converge, and the line search halves it towards 1), and a
/// growing series' (on cloth_pile 20× the step takes fewer Newton iterations than the
/// growing series taken 8 or 16 steps ahead uncapped; figures in
/// docs/history/issue-71-comments.md).
const MAX_STRETCH: f64 = 20.0;

/// The last full steps of a Newton loop, to recognize a geometric tail. Sized once per
/// step (its buffer holds one direction).
#[derive(Default)]
pub(super) struct Tail {
    last: Vec<f64>,
    last_norm: f64,
    /// The ratio of the last full step to the one before it, when they were parallel.
    last_ratio: Option<f64>,
    valid: bool,
}

impl Tail {
    /// Forgets the steps seen (a new time step, a step that was not a plain full one).
    pub(super) fn reset(&mut self, dofs: usize) {
        self.last.clear();
        self.last.resize(dofs, 0.0);
        self.valid = false;
        self.last_ratio = None;
    }

    /// Breaks the series (a step whose contact problem was not solved to the tolerance).
    pub(super) fn forget(&mut self) {
        self.valid = false;
        self.last_ratio = None;
    }

    /// The length to try `dir` at first: `1 / (1 − r)` when `dir` continues a geometric
    /// series of parallel full steps (its ratio r < 1 agreeing with the previous one),
    /// MAX_STRETCH when it continues a growing one (r and the previous ratio ≥ 1), else 1.
    /// Records nothing: [`Self::taken`] does once the line search has decided.
    pub(super) fn stretch(&self, dir: &[f64]) -> (f64, Option<f64>) {
        if !self.valid || self.last_norm == 0.0 {
            return (1.0, None);
        }
        // Sequential sums: the same bits at any thread count.
        let (mut dot, mut nn) = (0.0, 0.0);
        for (d, l) in dir.iter().zip(&self.last) {
            dot += d * l;
            nn += d * d;
        }
        let norm = nn.sqrt();
        if norm == 0.0 || dot < PARALLEL * norm * self.last_norm {
            return (1.0, None);
        }
        let r = norm / self.last_norm;
        let stretch = match self.last_ratio {
            Some(q) if r < 1.0 && (r - q).abs() <= RATIO_AGREES => {
                (1.0 / (1.0 - r)).min(MAX_STRETCH)
            }
            // A growing series (a fold leaving an unstable shape).
            Some(q) if r >= 1.0 && q >= 1.0 => MAX_STRETCH,
            _ => 1.0,
        };
        (stretch, Some(r))
    }

    /// Records the step the line search took: `alpha` times `dir`, `ratio` what
    /// [`Self::stretch`] measured. Only a plain full step (α = 1) starts or continues a series.
    pub(super) fn taken(&mut self, dir: &[f64], alpha: f64, ratio: Option<f64>) {
        if alpha != 1.0 {
            self.forget();
            return;
        }
        self.last_ratio = if self.valid { ratio } else { None };
        self.last.copy_from_slice(dir);
        self.last_norm = dir.iter().map(|d| d * d).sum::<f64>().sqrt();
        self.valid = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A geometric series of parallel steps of ratio 0.9 is summed from its third step:
    /// stretch 1/(1 − 0.9) = 10, exact to rounding.
    #[test]
    fn a_geometric_series_of_parallel_steps_is_summed() {
        let mut t = Tail::default();
        t.reset(3);
        let dir = |k: i32| [0.9f64.powi(k), 2.0 * 0.9f64.powi(k), -0.9f64.powi(k)];
        assert_eq!(t.stretch(&dir(0)).0, 1.0);
        t.taken(&dir(0), 1.0, None);
        let (s, r) = t.stretch(&dir(1));
        assert_eq!(s, 1.0, "one ratio is not yet a series");
        t.taken(&dir(1), 1.0, r);
        let (s, _) = t.stretch(&dir(2));
        assert!((s - 10.0).abs() < 1e-9, "{s}");
    }

    /// Parallel full steps that keep their length or grow (a fold snapping through) are
    /// extrapolated MAX_STRETCH times from the third: the ratios need not agree (they grow
    /// as the fold speeds up), but both must be ≥ 1.
    #[test]
    fn a_growing_series_of_parallel_steps_is_taken_several_steps_ahead() {
        let mut t = Tail::default();
        t.reset(2);
        t.taken(&[1.0, 0.0], 1.0, None);
        let (s, r) = t.stretch(&[1.0, 0.0]);
        assert_eq!(s, 1.0, "one ratio is not yet a series");
        t.taken(&[1.0, 0.0], 1.0, r);
        assert_eq!(t.stretch(&[1.0, 0.0]).0, MAX_STRETCH);
        let (s, r) = t.stretch(&[1.5, 0.0]);
        assert_eq!(s, MAX_STRETCH);
        t.taken(&[1.5, 0.0], 1.0, r);
        // Shrinking after growth: not a converging series yet.
        assert_eq!(t.stretch(&[1.2, 0.0]).0, 1.0);
    }

    /// A turn, a changing ratio or a step the line search shortened breaks the series.
    #[test]
    fn turns_changing_ratios_and_short_steps_break_the_series() {
        let mut t = Tail::default();
        t.reset(2);
        t.taken(&[1.0, 0.0], 1.0, None);
        let (_, r) = t.stretch(&[0.9, 0.0]);
        t.taken(&[0.9, 0.0], 1.0, r);
        assert_eq!(t.stretch(&[0.0, 0.81]).0, 1.0, "a turn");
        assert_eq!(t.stretch(&[0.7, 0.0]).0, 1.0, "ratio 0.78 after 0.9");
        assert!(t.stretch(&[0.81, 0.0]).0 > 1.0);
        t.taken(&[0.81, 0.0], 0.5, None);
        assert_eq!(t.stretch(&[0.73, 0.0]).0, 1.0, "after a halved step");
        assert_eq!(Tail::default().stretch(&[1.0, 0.0]).0, 1.0);
    }
}

//! The Newton direction: H's factorization (with inertia added where the exact Hessian is
//! not positive definite, `shift_ladder`), or conjugate gradients preconditioned by the
//! one-ring's or the single-precision factor, and the solves with the factor kept.

use super::{Hessians, Integrator, Mode, Route, one_ring, shift_ladder};
use crate::settings::{StepError, StepStats};
use crate::system::SolidSystem;
use nalgebra::Vector3;
use std::time::Instant;

impl Integrator {
    /// `dir` ← −H⁻¹ `grad` with the last factor, or by conjugate gradients preconditioned
    /// with the one-ring factor on a preconditioned route: false when they met a direction of
    /// non-positive curvature (H is not positive definite). Should they not converge, the
    /// rest of the step factors H itself, starting with this direction.
    pub(super) fn solve_direction(&mut self, stats: &mut StepStats) -> bool {
        if let Some(pre) = self.dirs.preconditioner() {
            let t = Instant::now();
            let (outcome, its) = pre.solve(
                &self.lin.values,
                &self.lin.col_ptr,
                &self.lin.row_idx,
                &self.work.grad,
                &mut self.work.dir,
            );
            stats.solve_seconds += t.elapsed().as_secs_f64();
            stats.cg_iterations += its;
            match outcome {
                one_ring::Outcome::Converged => return true,
                one_ring::Outcome::Indefinite => return false,
                one_ring::Outcome::Failed => {
                    self.dirs.route = Route::Factor;
                    if !self.try_factor(stats) {
                        return false;
                    }
                }
            }
        }
        for (d, g) in self.work.dir.iter_mut().zip(&self.work.grad) {
            *d = -g;
        }
        let mut dir = std::mem::take(&mut self.work.dir);
        self.solve_in_place(stats, &mut dir);
        self.work.dir = dir;
        true
    }

    /// ‖dir‖∞ · `scale` (the residual the tolerance is compared with).
    pub(super) fn direction_size(&self, scale: f64) -> f64 {
        self.step_size(&self.work.dir) * scale
    }

    /// The largest displacement of a vertex by the step `d` (over the nodes): a group's
    /// rotation node is in radians, so its members' displacements count instead.
    /// NaN when any entry of `d` is not finite: `f64::max` skips a NaN, so without the check a
    /// direction with non-finite entries would pass as a short one (and end a contact step
    /// "converged" with non-finite positions, reported only at the next step).
    pub(super) fn step_size(&self, d: &[f64]) -> f64 {
        if d.iter().any(|v| !v.is_finite()) {
            return f64::NAN;
        }
        if self.groups.is_empty() {
            return d.iter().fold(0.0f64, |m, d| m.max(d.abs()));
        }
        let free = d[..3 * self.groups.first]
            .iter()
            .fold(0.0f64, |m, d| m.max(d.abs()));
        free.max(self.member_step_size(d))
    }

    /// Factorizes `values` + `shift`·I and solves for the direction `dir = −H⁻¹ grad`. If the
    /// factorization meets a non-positive pivot (a singular Hessian: rigid modes of a free
    /// static body, a straight chain's zero transverse stiffness), the diagonal shift grows
    /// ×100 from 1e-10 of the largest diagonal entry until it succeeds (Levenberg–Marquardt).
    pub(super) fn newton_direction(
        &mut self,
        stats: &mut StepStats,
        shift: f64,
    ) -> Result<(), StepError> {
        self.factor(stats, shift)?;
        if !self.solve_direction(stats) {
            // Conjugate gradients met non-positive curvature in a matrix meant to be
            // positive definite (projected): H's own factor decides, its shift grown as needed.
            self.dirs.route = Route::Factor;
            self.factor(stats, 0.0)?;
            self.solve_direction(stats);
        }
        Ok(())
    }

    /// Factorizes `values` + `shift`·I (growing the shift as [`Self::newton_direction`] says).
    pub(super) fn factor(&mut self, stats: &mut StepStats, shift: f64) -> Result<(), StepError> {
        let t = Instant::now();
        let mut applied = shift;
        self.shift_diagonal(shift);
        let mut tries = 0;
        loop {
            stats.factorizations += 1;
            // Projected or regularized Hessians need no proof of definiteness: M₊.
            let outcome = match self.factor_preconditioner(false) {
                Some(true) => Ok(()),
                Some(false) => Err(faer::linalg::solvers::LltError::NonPositivePivot { index: 0 }),
                None => self.factor_once(),
            };
            match outcome {
                Ok(()) => break,
                Err(e) if tries >= 8 => {
                    return Err(StepError::Factorization(format!(
                        "{e:?} even with a diagonal shift of {applied:e}"
                    )));
                }
                // A NaN or infinite entry (a degenerate element, a diverged iterate) fails
                // at every shift: say so, instead of shifting by a scale the NaN hides.
                Err(_) if tries == 0 && self.lin.values.iter().any(|v| !v.is_finite()) => {
                    return Err(StepError::Factorization(
                        "the Newton matrix has non-finite entries (NaN or infinite)".into(),
                    ));
                }
                Err(_) => {
                    let more = if applied == 0.0 {
                        // The matrix is still unshifted here: its largest entry sets the
                        // first shift (taken only on failure: a pass over every value).
                        let scale = self.lin.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                        1e-10 * scale.max(f64::MIN_POSITIVE)
                    } else {
                        99.0 * applied
                    };
                    self.shift_diagonal(more);
                    applied += more;
                    tries += 1;
                }
            }
        }
        stats.factor_seconds += t.elapsed().as_secs_f64();
        Ok(())
    }

    /// One numeric factorization of `values` as they are: whether it succeeded (false: a
    /// non-positive pivot, the matrix is not positive definite).
    pub(super) fn try_factor(&mut self, stats: &mut StepStats) -> bool {
        let t = Instant::now();
        // The exact Hessian's try: M₋'s success proves H positive definite, as H's own
        // factorization would (a CG blind to H's negative curvature could otherwise end at
        // a saddle of the step's objective).
        let ok = match self.factor_preconditioner(true) {
            Some(ok) => ok,
            None => self.factor_once().is_ok(),
        };
        stats.factor_seconds += t.elapsed().as_secs_f64();
        stats.factorizations += 1;
        ok
    }

    /// On a preconditioned route, factors its preconditioner from `values`: whether it
    /// was positive definite, or `None` when H is to be factored instead (no preconditioner,
    /// or it declined: then the rest of the step factors H).
    pub(super) fn factor_preconditioner(&mut self, certify: bool) -> Option<bool> {
        let pre: Option<&mut one_ring::OneRing> = self.dirs.preconditioner();
        match pre?.factor(&self.lin.values, certify) {
            one_ring::Factored::Positive => Some(true),
            one_ring::Factored::NotPositive => Some(false),
            one_ring::Factored::Declined
                if self.dirs.route == Route::OneRing && self.dirs.single.is_some() =>
            {
                self.dirs.route = Route::Single;
                self.factor_preconditioner(certify)
            }
            one_ring::Factored::Declined => {
                self.dirs.route = Route::Factor;
                None
            }
        }
    }

    /// One numeric Cholesky factorization of `values`.
    pub(super) fn factor_once(&mut self) -> Result<(), faer::linalg::solvers::LltError> {
        self.dirs.factor.factor(&self.lin.values)
    }

    /// Factorizes `values` (assembled with [`Hessians::First`]) and solves for the direction,
    /// adding inertia ([`shift_ladder`]'s tries) while it is not positive definite (its
    /// factorization fails, or conjugate gradients meet non-positive curvature).
    /// Returns `Some(shifted)` (whether inertia was added) on success. `last_shift` is the
    /// inertia that succeeded last in this step (0: none yet); a success updates it.
    pub(super) fn factor_first(
        &mut self,
        sys: &SolidSystem,
        h: f64,
        last_shift: &mut f64,
        stats: &mut StepStats,
    ) -> Option<bool> {
        if self.try_factor(stats) && self.solve_direction(stats) {
            return Some(false);
        }
        let mut added = 0.0;
        for kappa in shift_ladder(*last_shift) {
            self.shift_inertia(sys, h, kappa);
            added += kappa;
            stats.shifted += 1;
            if self.try_factor(stats) && self.solve_direction(stats) {
                *last_shift = added;
                return Some(true);
            }
        }
        None
    }

    /// The Newton direction with the exact (where cheap) Hessian: assembles it and factorizes
    /// it; if it is not positive definite, adds inertia (a smaller effective step, still the
    /// exact Hessian's shape) as [`shift_ladder`] says. Returns `Some(shifted)` with the
    /// direction in `dir`, or `None` when every try failed or the gradient is not finite
    /// (then `values` hold no usable matrix: the caller assembles the projected one).
    /// A shifted direction is shorter than Newton's: it must not end the iteration.
    ///
    /// Where membranes carry a stress (`carried`) their Hessians are the mixed form's, with
    /// the geometric term's tension at the carried stress (see `Membrane::eval_carried`);
    /// the inertia tries shift that matrix.
    pub(super) fn first_direction(
        &mut self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
        last_shift: &mut f64,
        stats: &mut StepStats,
    ) -> Option<bool> {
        let t = Instant::now();
        self.assemble_with(sys, x, x0, Mode::Dynamic { h }, Hessians::First);
        stats.assembly_seconds += t.elapsed().as_secs_f64();
        if !self.work.grad.iter().all(|g| g.is_finite()) {
            return None;
        }
        self.factor_first(sys, h, last_shift, stats)
    }

    /// `b` ← A⁻¹ `b` with the factor the last direction was found with: the
    /// preconditioner's while conjugate gradients are on, else H's.
    pub(super) fn solve_with_last(&mut self, b: &mut [f64]) {
        match self.dirs.preconditioner() {
            Some(pre) => pre.apply(b),
            None => self.dirs.factor.solve_in_place(b),
        }
    }

    /// Solves with the last factor in place (`b` ← H⁻¹ b, 3 entries per free vertex).
    pub(super) fn solve_in_place(&mut self, stats: &mut StepStats, b: &mut [f64]) {
        let t = Instant::now();
        self.dirs.factor.solve_in_place(b);
        stats.solve_seconds += t.elapsed().as_secs_f64();
    }
}

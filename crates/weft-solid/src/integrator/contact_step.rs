//! The contact step's Newton loop: implicit Euler whose end-of-step velocities obey
//! Signorini–Coulomb at every contact (Daviet 2020; `contacts.rs` says what a contact is,
//! `admm.rs` holds ADMM on each Newton model).
//!
//! Each Newton iteration: assemble the incremental potential's Hessian at x
//! (`Hessians::Contact`), hand it to [`Admm`] (its split, factorization and rounds), then
//! line-search the last primal step's direction on the primal objective (the potential plus
//! the contacts' augmented and damping terms), with a geometric tail's extrapolation
//! (`tail.rs`), a slider's stick cap and the rods' second-order correction. The loop ends
//! when the Newton step is below the tolerance with ADMM converged, or by the rate of the
//! full steps (`rate.rs`), or gives up where the caller retries smaller
//! ([`ContactSet::give_up`]).

use super::admm::Admm;
use super::contacts::{Contact, ContactSet, ContactStats, DIVERGED, STALLED};
use super::tail::Tail;
use super::{CONTACT_CURVATURE, Hessians, Integrator, Mode, NONE};
use crate::settings::{Method, Settings, StepError, StepStats};
use crate::system::{SolidSystem, State};
use nalgebra::Vector3;

impl Integrator {
    /// [`Integrator::step_contacts`]'s Newton step, on a worker of the thread pool.
    pub(super) fn step_contacts_here(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        pinned_to: Option<&[Vector3<f64>]>,
        h: f64,
        settings: &Settings,
        set: ContactSet<'_>,
    ) -> Result<(StepStats, ContactStats), StepError> {
        let contacts = set.contacts;
        sys.check(state)?;
        if let Some(p) = &self.hooks.progress {
            p.solve(contacts.len());
        }
        // First: a rebuild resets every work buffer (the prediction's among them).
        let rebuilt = self.ensure_extra(sys, self.contact_blocks(contacts))?;
        // No contacts (none detected ahead; the exact check may still add some, and the
        // step is then solved again from this answer): the contact-free Newton, whose exact
        // Hessians (inertia added where indefinite) converge quadratically where ADMM's
        // projected ones converge linearly (hair_on_head's strands take fewer iterations a
        // step before they reach the head; figures in docs/history/issue-71-comments.md).
        if contacts.is_empty()
            && matches!(settings.method, Method::Newton | Method::ProjectedNewton)
        {
            let stats = self.step_from(sys, state, set.guess, pinned_to, h, settings)?;
            let cstats = ContactStats {
                pattern_rebuilt: rebuilt,
                ..Default::default()
            };
            return Ok((stats, cstats));
        }
        self.contact_newton(sys, state, pinned_to, h, settings, set, rebuilt)
    }

    /// The Newton loop of a step with contacts (`rebuilt`: whether its pattern was rebuilt
    /// for their blocks): a Newton model per iteration, ADMM on it, a line search.
    #[allow(clippy::too_many_arguments)]
    fn contact_newton(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        pinned_to: Option<&[Vector3<f64>]>,
        h: f64,
        settings: &Settings,
        set: ContactSet<'_>,
        rebuilt: bool,
    ) -> Result<(StepStats, ContactStats), StepError> {
        self.fill_budget(sys, h, CONTACT_CURVATURE);
        let x0 = state.x.clone();
        let target = |i: usize| pinned_to.map_or(x0[i], |p| p[i]);
        let guess = set.guess.filter(|g| {
            g.len() == state.x.len() && g.iter().all(|p| p.iter().all(|c| c.is_finite()))
        });
        let mut x = state.x.clone();
        self.predict(sys, state, &mut x, &target, guess, h);
        let mut admm = Admm::new(self, sys, &set, h)?;
        let mut stats = StepStats::default();
        let mut cstats = ContactStats {
            pattern_rebuilt: rebuilt,
            ..Default::default()
        };
        let dofs = 3 * self.lin.n_free;
        let mut delta = vec![0.0; dofs];
        let mut stall = Stall::default();
        // The stopping test by the full steps' rate (`rate.rs`).
        let mut rate = super::rate::RateStop::default();
        let mut friction_rate = super::rate::RateStop::default();
        // Whether a step of this loop stopped at a slider's stick point (`stick_cap`).
        let mut stuck = false;
        // The last full steps, to sum a geometric tail (`tail.rs`).
        let mut tail = Tail::default();
        if self.modes.tails {
            tail.reset(dofs);
        }
        for it in 0..settings.max_iterations.max(1) {
            if self.should_stop() {
                return Err(StepError::Interrupted { iteration: it });
            }
            // The first model's membranes read the tension of the stress at x⁰ (the last
            // step's converged one), not the first guess's overshoot (see
            // `Membrane::eval_contact_carried`); later models read the iterate's. Carried
            // through the iterations as in the contact-free loop, the stress makes cloth_pile's
            // contact steps crawl and retry substeps (`bench/ensemble.py` measures it; figures
            // in docs/history/issue-71-comments.md). Set and cleared around the one assembly,
            // so no other solve reads it.
            if it == 0 {
                self.start_carried(sys, &x0, settings.method == Method::Newton);
                self.start_slide_forces(sys, true);
            }
            let t = std::time::Instant::now();
            self.assemble_with(sys, &x, &x0, Mode::Dynamic { h }, Hessians::Contact);
            stats.assembly_seconds += t.elapsed().as_secs_f64();
            self.carried.clear();
            if it == 0 {
                admm.estimate(&self.lin, &x, &x0, h);
            }
            admm.split(self, &mut stats, &x, &x0, h)?;
            let limits = (set.max_admm, settings.tolerance);
            let admm_converged =
                admm.rounds(self, &mut stats, &mut cstats, &mut delta, limits, h, it)?;
            // A direction of the model's converged contact problem that continues a
            // geometric series of full steps is tried at the series' sum first.
            let (stretch, ratio, capped) = self.contact_stretch(
                sys,
                &tail,
                admm_converged,
                (&x, &x0),
                &delta,
                h,
                (set.reach, stuck),
            );
            stuck |= capped;
            let corrections = stats.corrections;
            let (trial, alpha) =
                self.contact_search(sys, &admm, (&x, &x0), &delta, h, stretch, &mut stats);
            let step = alpha * self.step_size(&delta) / h;
            if alpha > 1.0 {
                stats.extrapolations += 1;
            }
            if self.modes.tails {
                if admm_converged {
                    tail.taken(&delta, alpha, ratio);
                } else {
                    tail.forget();
                }
            }
            x = trial;
            if !sys.sliders.is_empty() {
                self.predict_slide_forces(&delta, alpha);
            }
            stats.iterations = it + 1;
            stats.residuals.push(step);
            self.report_newton(it + 1, step);
            if !step.is_finite() {
                return Err(StepError::NonFinite { iteration: it });
            }
            // Against the tolerance too: a first step of zero (the guess already the
            // primal answer) makes no later step a divergence.
            let first = stats.residuals[0].max(settings.tolerance);
            if set.give_up && step > DIVERGED * first {
                return Err(StepError::Diverged {
                    iteration: it,
                    step,
                    first,
                });
            }
            // (Not an iteration that left a slider's friction out, `SlideForces`, nor one cut
            // at a stick point, `stick_cap`.)
            if step < settings.tolerance
                && admm_converged
                && !self.sliders.slide_forces.frictionless
                && !capped
            {
                stats.converged = true;
                break;
            }
            // Or the corrections still to come are estimated below it: the last two steps
            // full (not extrapolated, cut or corrected) with the contact laws met (ADMM
            // converged). This loop's model is partly bounded (membranes) and can converge
            // linearly (`tail.rs`: ratios of 0.81–0.92), which the ratio's bound of ½
            // excludes; the distances the contact tests assert hold.
            let full =
                alpha == 1.0 && admm_converged && stats.corrections == corrections && !capped;
            // Sliders' lagged friction settled too, their tail within the tolerance with
            // the steps' (`friction_budget`).
            let budget = self.friction_budget(sys, &mut friction_rate, full, settings);
            if rate.ends_within(budget, &mut stats, step, full) {
                break;
            }
            if stall.ends(
                step < settings.tolerance && !capped,
                admm.last().0,
                set.give_up,
            ) {
                break;
            }
        }
        if !stats.converged {
            return Err(unconverged(&stats, &admm, settings.tolerance));
        }
        admm.finish(&x, &x0, h, set.contacts.len(), &mut cstats);
        for ((v, xi), x0i) in state.v.iter_mut().zip(&x).zip(&x0) {
            *v = (xi - x0i) / h;
        }
        state.x = x;
        Ok((stats, cstats))
    }

    /// The blocks `contacts` need beyond the elements' (free index pairs, sorted, lower
    /// first): pairs of a contact's moving vertices that share no element.
    fn contact_blocks(&self, contacts: &[Contact]) -> Vec<(u32, u32)> {
        let mut need = Vec::new();
        for c in contacts {
            let free: Vec<u32> = c
                .vertices
                .iter()
                .zip(&c.weights)
                .filter(|&(&v, &w)| w != 0.0 && w.is_finite() && (v as usize) < self.lin.n)
                .map(|(&v, _)| self.lin.free_of[v as usize])
                .filter(|&f| f != NONE)
                .collect();
            for (p, &a) in free.iter().enumerate() {
                for &b in &free[p + 1..] {
                    let key = (a.min(b), a.max(b));
                    let element = self.lin.block_slot(a as usize, b as usize).is_some()
                        && self.lin.extra.binary_search(&key).is_err();
                    if !element && a != b {
                        need.push(key);
                    }
                }
            }
        }
        need.sort_unstable();
        need.dedup();
        need
    }

    /// Where this iteration's line search starts along `delta`: 1, or the sum of a geometric
    /// tail of full steps (`tail.rs`) when ADMM converged, no point moving more than half the
    /// `reach` beyond the full step; then cut at a frictional slider's stick point unless a
    /// step was already (`stuck`). The stretch, the tail's ratio, and whether it was cut.
    #[allow(clippy::too_many_arguments)]
    fn contact_stretch(
        &self,
        sys: &SolidSystem,
        tail: &Tail,
        admm_converged: bool,
        (x, x0): (&[Vector3<f64>], &[Vector3<f64>]),
        delta: &[f64],
        h: f64,
        (reach, stuck): (f64, bool),
    ) -> (f64, Option<f64>, bool) {
        let (mut stretch, ratio) = if admm_converged && self.modes.tails {
            tail.stretch(delta)
        } else {
            (1.0, None)
        };
        if stretch > 1.0 {
            // No point more than half the reach beyond the full step (`largest_move`
            // bounds rigid groups' members too; a slider's projection back onto its rail
            // or surface, after, is not bounded by it).
            let cap = 1.0 + 0.5 * reach / self.largest_move(delta);
            // A NaN cap (a NaN reach, or 0/0) allows no extrapolation.
            stretch = if cap >= 1.0 { stretch.min(cap) } else { 1.0 };
        }
        // Stopped at a frictional slider's stick point (`stick_cap`), once a step, the
        // extrapolation included. Such a step is short by construction: it ends no loop,
        // by its size or by the rate (its halvings may bring α back to 1).
        let capped = !stuck && Self::slide_friction(sys) && {
            let cap = self.stick_cap(sys, x, x0, delta, h, stretch);
            let cut = cap < stretch;
            stretch = cap;
            cut
        };
        (stretch, ratio, capped)
    }

    /// Backtracking (Armijo) on the primal objective ([`Admm::augmented`]) at the last
    /// primal step's targets, along its Newton direction `delta` (it descends: the factored
    /// matrix is SPD), from `stretch` (above 1: an extrapolation, taken only on a measured
    /// decrease) down. The trial positions and the step length α taken.
    #[allow(clippy::too_many_arguments)]
    fn contact_search(
        &mut self,
        sys: &SolidSystem,
        admm: &Admm<'_>,
        (x, x0): (&[Vector3<f64>], &[Vector3<f64>]),
        delta: &[f64],
        h: f64,
        stretch: f64,
        stats: &mut StepStats,
    ) -> (Vec<Vector3<f64>>, f64) {
        let phi = |s: &Self, x: &[Vector3<f64>]| {
            admm.augmented(s.objective(sys, x, x0, Mode::Dynamic { h }), x, x0, h)
        };
        let slope = admm.slope(&self.work.grad, delta, h);
        let e0 = phi(self, x);
        let xmax = x.iter().fold(0.0f64, |m, p| m.max(p.amax()));
        let mut trial = x.to_vec();
        let mut alpha = stretch;
        loop {
            self.place(sys, x, delta, alpha, &mut trial);
            let armijo = phi(self, &trial) <= e0 + 1e-4 * alpha * slope;
            let unresolvable = -slope * alpha <= 64.0 * f64::EPSILON * self.force_scale * xmax;
            // The escapes (a decrease below rounding, a vanishing step) are for steps no
            // longer than the model's own.
            if armijo || (alpha <= 1.0 && (unresolvable || alpha < 1e-10)) {
                break;
            }
            if alpha > 1.0 {
                // The extrapolation did not decrease the objective enough: shorter, down
                // to the full step.
                alpha = (0.5 * alpha).max(1.0);
                stats.extrapolation_halvings += 1;
                continue;
            }
            // As in the contact-free step: a second-order correction of the rods' lengths.
            // It moves contact vertices too (by O(d²/L)): the next iteration's contact solve
            // puts them back where the law wants them, and the step that ends a Newton loop
            // is below the tolerance (or, ended by the rate, a full step with no
            // correction), so its correction is negligible. Holding them left the segments
            // between two contacts uncorrected, and their full steps were halved.
            if alpha == 1.0 && !self.correction.is_empty() {
                stats.correction_sweeps += self.correction.apply(
                    &self.lin.free_of,
                    &sys.mass,
                    x,
                    delta,
                    &trial,
                    &mut self.work.x_soc,
                );
                let mut soc = std::mem::take(&mut self.work.x_soc);
                self.retract(sys, &mut soc);
                self.work.x_soc = soc;
                if phi(self, &self.work.x_soc) <= e0 + 1e-4 * slope {
                    trial.copy_from_slice(&self.work.x_soc);
                    stats.corrections += 1;
                    break;
                }
            }
            alpha *= 0.5;
            stats.halvings += 1;
        }
        (trial, alpha)
    }
}

/// Newton steps below the tolerance in a row while ADMM did not converge, and ADMM's primal
/// residual when they began.
struct Stall {
    count: usize,
    from: f64,
}

impl Default for Stall {
    fn default() -> Self {
        Self {
            count: 0,
            from: f64::NAN,
        }
    }
}

impl Stall {
    /// Counts this iteration (`short`: its step below the tolerance and not cut at a stick
    /// point; `primal`: ADMM's last primal residual) and says whether the loop ends.
    ///
    /// It is given up on where the caller retries smaller (`give_up`) after [`STALLED`]
    /// such steps; at its last try, once ADMM's distance from the contact laws has not
    /// halved over the stall either: Newton has nothing left to move and ADMM makes no
    /// progress, so the iterations left would end the same way, later (a frame whose every
    /// halving failed so spent up to 100 iterations of 200 ADMM rounds each before saying
    /// so). A NaN residual is no progress either.
    fn ends(&mut self, short: bool, primal: f64, give_up: bool) -> bool {
        self.count = if short { self.count + 1 } else { 0 };
        if self.count == 1 {
            self.from = primal;
        }
        let halved = primal <= 0.5 * self.from;
        self.count >= STALLED && (give_up || !halved)
    }
}

/// The error of a contact step whose Newton loop ended unconverged: the contacts' when
/// Newton is done (its last step below the tolerance) and ADMM is not, else Newton's.
fn unconverged(stats: &StepStats, admm: &Admm<'_>, tolerance: f64) -> StepError {
    let step = stats.residuals.last().copied().unwrap_or(f64::NAN);
    if step < tolerance {
        let (primal, dual) = admm.last();
        return StepError::ContactsNotConverged {
            iterations: stats.iterations,
            step,
            primal,
            dual,
            tolerance,
        };
    }
    stats.not_converged(tolerance)
}

#[cfg(test)]
mod tests {
    use super::super::admm::JOINED_MAX;
    use super::*;
    use crate::settings::Method;
    use nalgebra::Matrix3;

    /// A free 1 kg vertex at the origin at rest under gravity −y, Newton to 1e-12 m/s.
    fn one_vertex() -> (SolidSystem, State, Integrator, Settings) {
        let mut sys = SolidSystem::new(vec![1.0]);
        sys.gravity = Vector3::new(0.0, -9.81, 0.0);
        let s = State {
            x: vec![Vector3::zeros()],
            v: vec![Vector3::zeros()],
        };
        let integ = Integrator::new(&sys).unwrap();
        let settings = Settings {
            method: Method::Newton,
            tolerance: 1e-12,
            max_iterations: 20,
        };
        (sys, s, integ, settings)
    }

    /// A contact at every vertex of `x` with the floor whose normal is axis `up` (y or z:
    /// its first tangent x), the gap the vertex's height.
    fn on_floor(x: &[Vector3<f64>], up: usize, friction: f64) -> Vec<Contact> {
        // The frame's rows: the normal e_up, then e_x and the remaining axis.
        assert!(up == 1 || up == 2, "the floor's normal is y or z");
        let mut frame = Matrix3::zeros();
        frame[(0, up)] = 1.0;
        frame[(1, 0)] = 1.0;
        frame[(2, 3 - up)] = 1.0;
        (0..x.len() as u32)
            .map(|i| Contact {
                frame,
                gap: x[i as usize][up],
                friction,
                ..Contact::vertex(i)
            })
            .collect()
    }

    /// A step's contacts with no warm start, no guess and σ from 1.
    fn cold(contacts: &[Contact], max_admm: usize) -> ContactSet<'_> {
        ContactSet::new(contacts, max_admm)
    }

    /// A direction with a NaN entry has a NaN size (not its finite entries' largest), so the
    /// steps that measure it report it instead of taking it.
    #[test]
    fn a_non_finite_direction_is_not_a_short_one() {
        let (_, _, integ, _) = one_vertex();
        assert_eq!(integ.step_size(&[1e-3, 0.0, -2e-3]), 2e-3);
        assert!(integ.step_size(&[1e-3, f64::NAN, 0.0]).is_nan());
        assert!(integ.step_size(&[f64::INFINITY, 0.0, 0.0]).is_nan());
    }

    /// One 1 kg vertex on a plane through the origin tilted θ about z, friction μ, gravity −y,
    /// h = 0.01 s for 1 s: (displacement along the slope, velocity along it, largest speed
    /// off the plane).
    fn incline(theta_deg: f64, mu: f64, with_ghost: bool) -> (f64, f64, f64) {
        let th = theta_deg.to_radians();
        let n = Vector3::new(-th.sin(), th.cos(), 0.0);
        let t1 = Vector3::new(th.cos(), th.sin(), 0.0);
        let t2 = Vector3::z();
        let frame = Matrix3::from_rows(&[n.transpose(), t1.transpose(), t2.transpose()]);
        let (sys, mut s, mut integ, settings) = one_vertex();
        let mut off = 0.0f64;
        for _ in 0..100 {
            let c = Contact {
                frame,
                gap: s.x[0].dot(&n),
                velocity: Vector3::zeros(),
                friction: mu,
                cohesion: 0.0,
                damping: 0.0,
                ..Contact::vertex(0)
            };
            // A second plane, tilted 35° towards the slope's downhill side and 1 mm away: it
            // never touches, and must change nothing.
            let ghost = {
                let r =
                    nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), 35f64.to_radians());
                let (n2, t12) = (r * n, r * t1);
                Contact {
                    frame: Matrix3::from_rows(&[n2.transpose(), t12.transpose(), t2.transpose()]),
                    gap: 1e-3,
                    ..c
                }
            };
            let two = [c, ghost];
            let (_, cs) = integ
                .step_contacts(
                    &sys,
                    &mut s,
                    None,
                    0.01,
                    &settings,
                    ContactSet::new(if with_ghost { &two } else { &two[..1] }, 200),
                )
                .unwrap();
            assert!(cs.max_residual < 1e-9, "{}", cs.max_residual);
            off = off.max(s.v[0].dot(&n).abs());
        }
        (s.x[0].dot(&t1), s.v[0].dot(&t1), off)
    }

    /// VERIFY.md's incline: with tan θ ≤ μ the vertex sticks exactly (below 1e-9 m over 1 s);
    /// above, it slides with a = g(sin θ − μ cos θ): implicit Euler's velocity after n steps
    /// is exactly n h a, so within 1e-6 relative; it never leaves or enters the plane.
    #[test]
    fn a_vertex_on_an_incline_sticks_exactly_or_slides_by_coulomb() {
        let (x, v, off) = incline(20.0, 0.5, false);
        assert!(
            x.abs() < 1e-9 && v.abs() < 1e-9 && off < 1e-9,
            "{x} {v} {off}"
        );
        let (th, mu) = (30f64.to_radians(), 0.3);
        let a = 9.81 * (th.sin() - mu * th.cos());
        let (_, v, off) = incline(30.0, mu, false);
        let (_, vg, _) = incline(30.0, mu, true);
        assert!((vg / v - 1.0).abs() < 1e-9, "{vg} vs {v}");
        assert!(((-v) / a - 1.0).abs() < 1e-6, "{v} vs {a}");
        assert!(off < 1e-9, "{off}");
    }

    /// Contacts that contradict each other (a vertex on a floor, y ≥ 0, that a ceiling also
    /// wants 1 cm below it, y ≤ −0.01): ADMM cannot meet both laws while Newton's steps are
    /// already below the tolerance. A solve that may give up fails after [`STALLED`]
    /// Newton iterations; one that may not fails there too, as ADMM's distance from the
    /// laws stays flat over those iterations (no progress: more would end the same way).
    /// Both report the contacts, not Newton, as what did not converge.
    #[test]
    fn contradicting_contacts_fail_early_when_the_caller_can_retry() {
        // Rows: the normal, then two tangents.
        let floor = Matrix3::new(0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        let ceiling = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        let contact = |frame, gap| Contact {
            frame,
            gap,
            velocity: Vector3::zeros(),
            friction: 0.0,
            cohesion: 0.0,
            damping: 0.0,
            ..Contact::vertex(0)
        };
        let contacts = [contact(floor, 0.0), contact(ceiling, -0.01)];
        let solve = |give_up: bool| {
            let (sys, mut s, mut integ, mut settings) = one_vertex();
            settings.tolerance = 1e-6;
            settings.max_iterations = 60;
            let set = ContactSet {
                give_up,
                ..ContactSet::new(&contacts, 50)
            };
            match integ.step_contacts(&sys, &mut s, None, 0.01, &settings, set) {
                Err(StepError::ContactsNotConverged { iterations, .. }) => iterations,
                other => panic!("{other:?}"),
            }
        };
        for give_up in [true, false] {
            let early = solve(give_up);
            assert!((STALLED..=STALLED + 2).contains(&early), "{early}");
        }
    }

    /// Cohesion: a 1 kg vertex under a ceiling (n = −y) stays when the collider may pull
    /// with more than its weight's impulse m g h a step, and falls when it may pull less: the
    /// threshold within 5 % (VERIFY: 1.05 and 0.95 × m g h).
    #[test]
    fn cohesion_holds_a_vertex_under_a_ceiling_up_to_its_weight() {
        let hang = |factor: f64| {
            let frame = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
            let (sys, mut s, mut integ, settings) = one_vertex();
            let h = 0.01;
            for _ in 0..50 {
                let c = Contact {
                    frame,
                    gap: -s.x[0].y,
                    velocity: Vector3::zeros(),
                    friction: 0.5,
                    cohesion: factor * 9.81 * h,
                    damping: 0.0,
                    ..Contact::vertex(0)
                };
                if c.gap > 1e-3 {
                    // Torn off: out of reach, no contact.
                    integ.step(&sys, &mut s, None, h, &settings).unwrap();
                    continue;
                }
                integ
                    .step_contacts(&sys, &mut s, None, h, &settings, ContactSet::new(&[c], 200))
                    .unwrap();
            }
            s.x[0].y
        };
        assert!(hang(1.05).abs() < 1e-9, "{}", hang(1.05));
        assert!(hang(0.95) < -1e-2, "{}", hang(0.95));
    }

    /// Two 1 kg vertices 0.2 m apart, joined by a stiff stretch (EA = 10⁴ N), at rest on a
    /// knife edge under their middle (a contact at weights (½, ½), n = +y, μ = 1): the edge
    /// carries both weights exactly, as one impulse 2 m g h a step, and nothing moves (below
    /// 1e-9 m over 0.5 s). Off the middle (weights (¾, ¼)) the bar tips: the contact point
    /// stays on the edge (to 1e-9 m) while the far vertex falls. Without the stretch the
    /// vertices share no block, and the step says so instead of solving something else.
    #[test]
    fn a_contact_between_two_vertices_carries_them_by_its_weights() {
        use crate::energy::RodStretch;
        let bar = |stretch: bool| {
            let mut sys = SolidSystem::new(vec![1.0, 1.0]);
            sys.gravity = Vector3::new(0.0, -9.81, 0.0);
            if stretch {
                sys.elements.stretches.push(RodStretch {
                    v: [0, 1],
                    rest_length: 0.2,
                    k: 1e4,
                });
            }
            let s = State {
                x: vec![Vector3::new(-0.1, 0.0, 0.0), Vector3::new(0.1, 0.0, 0.0)],
                v: vec![Vector3::zeros(); 2],
            };
            (sys, s)
        };
        let settings = Settings {
            method: Method::Newton,
            tolerance: 1e-12,
            max_iterations: 50,
        };
        let h = 0.01;
        let frame = Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        let run = |w: f64, steps: usize| {
            let (sys, mut s) = bar(true);
            let mut integ = Integrator::new(&sys).unwrap();
            let mut last = [0.0; 3];
            for _ in 0..steps {
                let c = Contact {
                    frame,
                    gap: (1.0 - w) * s.x[0].y + w * s.x[1].y,
                    friction: 1.0,
                    ..Contact::points(&[(0, 1.0 - w), (1, w)])
                };
                let cs = [c];
                let set = ContactSet::new(&cs, 500);
                let (_, cs) = integ
                    .step_contacts(&sys, &mut s, None, h, &settings, set)
                    .unwrap();
                last = cs.impulses[0];
            }
            (s, last)
        };
        let (s, r) = run(0.5, 50);
        let moved = (s.x[0] - Vector3::new(-0.1, 0.0, 0.0))
            .amax()
            .max((s.x[1] - Vector3::new(0.1, 0.0, 0.0)).amax());
        assert!(moved < 1e-9, "{moved}");
        assert!((r[0] / (2.0 * 9.81 * h) - 1.0).abs() < 1e-9, "{r:?}");
        let (s, _) = run(0.25, 20);
        let point = 0.75 * s.x[0].y + 0.25 * s.x[1].y;
        assert!(point.abs() < 1e-9 && s.x[1].y < -1e-3, "{point} {:?}", s.x);
        // Without the stretch the vertices share no element: the step adds their block to
        // the pattern for it, and the answer is the same.
        let (sys, mut s) = bar(false);
        let mut integ = Integrator::new(&sys).unwrap();
        let c = Contact {
            frame,
            friction: 1.0,
            ..Contact::points(&[(0, 0.5), (1, 0.5)])
        };
        let cs = [c];
        let set = ContactSet::new(&cs, 500);
        let (_, cs) = integ
            .step_contacts(&sys, &mut s, None, h, &settings, set)
            .unwrap();
        assert!(s.x[0].y.abs() < 1e-9 && s.x[1].y.abs() < 1e-9, "{:?}", s.x);
        assert!((cs.impulses[0][0] / (2.0 * 9.81 * h) - 1.0).abs() < 1e-9);
    }

    /// Two solids meeting: free vertices with no element between them (a contact's point is
    /// the difference of a point of each, as issue 14's contacts between deforming solids
    /// are). A 1 kg vertex at 1 m/s hits a vertex of mass m at rest, touching (gap 0), no
    /// gravity: the contact is perfectly inelastic, so both leave at 1/(1 + m) m/s, and
    /// momentum is conserved, to 1e-9. A vertex falling at 2 m/s onto a free triangle of
    /// three 1 kg vertices (barycentric weights (0.2, 0.3, 0.5)) 1 mm below it: the point
    /// stops on the triangle's plane (to 1e-9 m) and momentum is conserved.
    #[test]
    fn contacts_between_separate_solids_conserve_momentum() {
        let settings = Settings {
            method: Method::Newton,
            tolerance: 1e-12,
            max_iterations: 50,
        };
        let h = 0.01;
        for m in [1.0, 3.0] {
            let sys = SolidSystem::new(vec![1.0, m]);
            let mut s = State {
                x: vec![Vector3::zeros(), Vector3::new(0.05, 0.0, 0.0)],
                v: vec![Vector3::new(1.0, 0.0, 0.0), Vector3::zeros()],
            };
            let mut integ = Integrator::new(&sys).unwrap();
            // n = +x: the second vertex's side; the point is x₁ − x₀.
            let frame = Matrix3::identity();
            let c = Contact {
                frame,
                ..Contact::points(&[(1, 1.0), (0, -1.0)])
            };
            let cs = [c];
            let set = ContactSet::new(&cs, 1000);
            integ
                .step_contacts(&sys, &mut s, None, h, &settings, set)
                .unwrap();
            let want = 1.0 / (1.0 + m);
            assert!((s.v[0].x - want).abs() < 1e-9 && (s.v[1].x - want).abs() < 1e-9);
            assert!((s.v[0].x + m * s.v[1].x - 1.0).abs() < 1e-9, "{:?}", s.v);
        }
        let sys = SolidSystem::new(vec![1.0; 4]);
        let tri = [
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(1.0, 0.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
        ];
        let b = [0.2, 0.3, 0.5];
        let above = b[0] * tri[0] + b[1] * tri[1] + b[2] * tri[2] + Vector3::new(0.0, 1e-3, 0.0);
        let mut s = State {
            x: vec![above, tri[0], tri[1], tri[2]],
            v: vec![
                Vector3::new(0.0, -2.0, 0.0),
                Vector3::zeros(),
                Vector3::zeros(),
                Vector3::zeros(),
            ],
        };
        let mut integ = Integrator::new(&sys).unwrap();
        let c = Contact {
            frame: Matrix3::new(0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0),
            gap: 1e-3,
            friction: 0.5,
            ..Contact::points(&[(0, 1.0), (1, -b[0]), (2, -b[1]), (3, -b[2])])
        };
        let cs = [c];
        let set = ContactSet::new(&cs, 2000);
        let (_, cs) = integ
            .step_contacts(&sys, &mut s, None, h, &settings, set)
            .unwrap();
        let q = b[0] * s.x[1] + b[1] * s.x[2] + b[2] * s.x[3];
        assert!((s.x[0].y - q.y).abs() < 1e-9, "{} {}", s.x[0].y, q.y);
        let p: Vector3<f64> = s.v.iter().sum();
        assert!((p - Vector3::new(0.0, -2.0, 0.0)).amax() < 1e-9, "{p}");
        assert!(cs.impulses[0][0] > 0.0);
    }

    /// Nonlinear with contacts: a stiff chain (4 segments of 0.1 m, EA = 10⁴ N, 10 g a
    /// vertex) pinned at (0, 0.3, 0), released horizontal, falls onto a floor y = 0 with
    /// friction 0.3. Every free vertex gets a floor contact each step (its gap the height it
    /// starts the step at). Every step converges, no vertex ever goes below the floor by more
    /// than 1e-9 m, and the chain comes to lie on it (its tip within 1 mm of the floor).
    #[test]
    fn a_stiff_chain_falls_onto_a_floor_without_entering_it() {
        let (s, _, lowest) = chain_on_floor(JOINED_MAX, 200);
        assert!(lowest > -1e-9, "{lowest}");
        assert!(s[4].y < 1e-3, "{:?}", s[4]);
    }

    /// The bound that keeps an extrapolated step within half the contact distance of the
    /// full step holds for rigid groups' members, whose rotation node is in radians: placing
    /// a step (a turn of 0.03 rad of a group 2.2 m in radius) at α = 3 instead of 1 moves no
    /// point more than 2 × `largest_move` (to rounding), and the bound is reached within
    /// 10 % (the translation and the turn push the far member nearly the same way). Reading
    /// the direction's 3-vectors as moves instead (as the stretch's bound first did) misses
    /// the members' arcs: it would allow less than half the move.
    #[test]
    fn a_stretched_step_moves_no_point_farther_than_its_bound() {
        let mut sys = SolidSystem::new(vec![0.01; 5]);
        sys.rigid.push(crate::system::RigidGroup {
            vertices: vec![1, 2, 3],
        });
        let x = vec![
            Vector3::new(-1.0, 0.0, 0.0),
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(3.0, 0.0, 0.0),
            Vector3::new(0.0, 3.0, 0.0),
            Vector3::new(2.0, 0.0, 0.0),
        ];
        let mut integ = Integrator::new(&sys).unwrap();
        integ.groups.centers(&sys, &x);
        // Free vertices 0 and 4 (nodes 0, 1), then the group's translation and turn.
        let mut dir = vec![0.0; 12];
        dir[0] = 0.01;
        dir[4] = -0.02;
        dir[7] = 0.05;
        dir[11] = 0.03;
        let bound = integ.largest_move(&dir);
        let (mut one, mut three) = (x.clone(), x.clone());
        integ.place(&sys, &x, &dir, 1.0, &mut one);
        integ.place(&sys, &x, &dir, 3.0, &mut three);
        let apart = super::super::order::tests::farthest(
            &State { x: one, v: vec![] },
            &State {
                x: three,
                v: vec![],
            },
        );
        assert!(
            apart <= 2.0 * bound * (1.0 + 1e-12),
            "{apart} > 2 × {bound}"
        );
        assert!(apart > 0.9 * 2.0 * bound, "{apart} ≪ 2 × {bound}");
        let chunks = dir
            .chunks_exact(3)
            .map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
            .fold(0.0f64, f64::max);
        assert!(4.0 * chunks < apart, "{chunks}");
    }

    /// A sheet squeezed to 0.8 of its width on a floor, its contact steps solved with and
    /// without summing geometric tails (`tail.rs`): the same answer in fewer iterations.
    /// Reference (an estimate, not a proof): each solve stops at a full step below the
    /// tolerance τ = 1e-7 m/s, and along a tail of ratio r ≤ 0.95 the minimizer is still up
    /// to r/(1 − r) ≤ 19 such steps away, so after k + 1 steps the two runs may differ by
    /// about 20 τ h (k + 1) (measured:
    /// 1.4e-8 m after the first step, 1.8e-9 m after the fourth, against 4.2e-8 … 1.7e-7).
    /// Iterations: measured 95 against 170 over four steps (17 extrapolated); asserted
    /// at most 3/4.
    #[test]
    fn summing_a_geometric_tail_ends_a_contact_step_where_full_steps_end() {
        let (tolerance, h) = (1e-7, 1.0 / 48.0);
        let run = |tails: bool| {
            let (sys, mut s) = super::super::order::tests::shell_sheet(8, 1e-3);
            for p in s.x.iter_mut() {
                p.x *= 0.8;
            }
            let mut integ = Integrator::new(&sys).unwrap();
            integ.modes.tails = tails;
            let settings = Settings {
                method: Method::Newton,
                tolerance,
                max_iterations: 200,
            };
            let (mut iterations, mut extrapolated) = (0, 0);
            let mut after = Vec::new();
            for _ in 0..4 {
                let contacts = on_floor(&s.x, 2, 0.2);
                let (st, _) = integ
                    .step_contacts(&sys, &mut s, None, h, &settings, cold(&contacts, 500))
                    .unwrap();
                iterations += st.iterations;
                extrapolated += st.extrapolations;
                after.push(s.clone());
            }
            (after, iterations, extrapolated)
        };
        let (with, n_with, extrapolated) = run(true);
        let (without, n_without, none) = run(false);
        assert!(extrapolated > 0 && none == 0, "{extrapolated} {none}");
        for (k, (a, b)) in with.iter().zip(&without).enumerate() {
            let apart = super::super::order::tests::farthest(a, b);
            let bound = 20.0 * tolerance * h * (k + 1) as f64;
            assert!(apart < bound, "step {k}: {apart} m apart");
        }
        assert!(4 * n_with <= 3 * n_without, "{n_with} against {n_without}");
    }

    /// A rod compressed to half its rest length (EA = 10⁴ N, 1 g a vertex, h = 0.01 s)
    /// lying on a floor y = 0, both vertices touching it, gravity −y: the exact stretch
    /// Hessian's transverse term k s/l = −10⁵ N/m outweighs the inertia m/h² = 10 N/m, so
    /// the contact point's diagonal block along the normal is negative. Its ρ̂ must still
    /// be positive (the inertia floor): with ρ̂ < 0 the augmented term is concave and the
    /// iterates run away (figures in docs/history/issue-71-comments.md). Each
    /// step converges, the rod opens symmetrically along x (its midpoint held to 1e-12 m)
    /// and stays on the floor (1e-9 m).
    #[test]
    fn a_compressed_rod_on_a_floor_keeps_a_positive_contact_stiffness() {
        use crate::energy::RodStretch;
        let mut sys = SolidSystem::new(vec![1e-3; 2]);
        sys.gravity = Vector3::new(0.0, -9.81, 0.0);
        sys.elements.stretches.push(RodStretch {
            v: [0, 1],
            rest_length: 0.1,
            k: 1e4,
        });
        let mut s = State {
            x: vec![
                Vector3::new(-0.025, 0.0, 0.0),
                Vector3::new(0.025, 0.0, 0.0),
            ],
            v: vec![Vector3::zeros(); 2],
        };
        let mut integ = Integrator::new(&sys).unwrap();
        let settings = Settings {
            method: Method::Newton,
            tolerance: 1e-9,
            max_iterations: 50,
        };
        for _ in 0..5 {
            let contacts = on_floor(&s.x, 1, 0.3);
            integ
                .step_contacts(&sys, &mut s, None, 0.01, &settings, cold(&contacts, 500))
                .unwrap();
            assert!(s.x.iter().all(|p| p.y > -1e-9), "{:?}", s.x);
            assert!((s.x[0].x + s.x[1].x).abs() < 1e-12, "{:?}", s.x);
        }
        assert!(s.x[1].x > 0.025, "{:?}", s.x);
    }

    #[test]
    fn contacts_that_rejoin_by_a_low_rank_correction_give_the_refactorized_answer() {
        // The same 60 steps of the chain landing (its vertices' contacts leave and rejoin the
        // split as they bounce), rejoins by the kept factor and its correction, then by a
        // factorization each: the same linear systems, so the same answer to the solves'
        // rounding and the tolerance (1e-9 m/s over 5 ms steps: 5e-12 m a step).
        let (low_rank, refactorizations_lr, _) = chain_on_floor(JOINED_MAX, 60);
        let (refactored, refactorizations, _) = chain_on_floor(0, 60);
        let far = low_rank
            .iter()
            .zip(&refactored)
            .map(|(a, b)| (a - b).amax())
            .fold(0.0, f64::max);
        assert!(far < 1e-9, "{far}");
        assert!(
            refactorizations_lr < refactorizations,
            "{refactorizations_lr} against {refactorizations}"
        );
    }

    /// A stiff five-vertex chain, held at one end, released level 0.3 m above a floor:
    /// positions after `steps` of 5 ms, the ADMM's refactorizations and the lowest height
    /// any vertex ended a step at, with rejoins added to the kept factor up to `joined_max`
    /// columns.
    fn chain_on_floor(joined_max: usize, steps: usize) -> (Vec<Vector3<f64>>, usize, f64) {
        use crate::energy::RodStretch;
        let n = 5;
        let mut sys = SolidSystem::new(vec![0.01; n]);
        sys.gravity = Vector3::new(0.0, -9.81, 0.0);
        sys.pinned[0] = true;
        for i in 0..n as u32 - 1 {
            sys.elements.stretches.push(RodStretch {
                v: [i, i + 1],
                rest_length: 0.1,
                k: 1e4,
            });
        }
        let mut s = State {
            x: (0..n)
                .map(|i| Vector3::new(0.1 * i as f64, 0.3, 0.0))
                .collect(),
            v: vec![Vector3::zeros(); n],
        };
        let mut integ = Integrator::new(&sys).unwrap();
        integ.modes.joined_max = joined_max;
        let settings = Settings {
            method: Method::Newton,
            tolerance: 1e-9,
            max_iterations: 50,
        };
        let frame = Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        let (mut refactorizations, mut lowest) = (0, f64::INFINITY);
        for _ in 0..steps {
            let contacts: Vec<Contact> = (1..n as u32)
                .map(|i| Contact {
                    frame,
                    gap: s.x[i as usize].y,
                    velocity: Vector3::zeros(),
                    friction: 0.3,
                    cohesion: 0.0,
                    damping: 0.0,
                    ..Contact::vertex(i)
                })
                .collect();
            let (_, cs) = integ
                .step_contacts(&sys, &mut s, None, 0.005, &settings, cold(&contacts, 500))
                .unwrap();
            refactorizations += cs.refactorizations;
            lowest = lowest.min(s.x.iter().map(|p| p.y).fold(f64::INFINITY, f64::min));
        }
        (s.x, refactorizations, lowest)
    }
}

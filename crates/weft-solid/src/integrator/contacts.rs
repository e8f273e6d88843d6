//! Implicit Euler with hard frictional contacts against kinematic colliders, after Daviet 2020
//! (`weft-sim`'s collision detection hands it the contacts; the derivations are in
//! `docs/contacts.md`).
//!
//! ADMM on the split z_c = H_c v, H_c v = R_c(Σⱼ wⱼ vⱼ − v_c) the relative velocity of a
//! contact's point (a vertex, or a point between vertices) in its frame. Newton outside:
//! assemble the incremental potential's Hessian at x (`Element::eval_contact`: rods' exact,
//! membranes' exact with their negative curvature bounded by a share of the inertia so they
//! cannot make the model indefinite, the rest projected to PSD), add ρ_c/h² (w wᵀ ⊗ I) on the contact's
//! vertex blocks (RᵀR = I; blocks between vertices that share no element, as between two
//! solids, are added to the pattern for the step: `Integrator::ensure_extra`) and
//! factor once. ADMM inside on that Newton model: each primal step is one solve with the same
//! factor (only the right-hand side changes), each contact step the closed-form
//! [`solve_local`]. The stationarity of the primal objective E(x) + Σ ρ_c/2 ‖H_c v − z_c −
//! r_c/ρ_c‖² at H_c v = z_c is ∇E = Σ H_cᵀ r_c/h, the momentum balance with the colliders'
//! impulses r_c [N·s], shared by the point's vertices in proportion to their weights.

use super::tail::Tail;
use super::{CONTACT_CURVATURE, Hessians, Integrator, Mode, NONE};
use crate::contact::{residual, solve_local};
use crate::settings::{Method, Settings, StepError, StepStats};
use crate::system::{SolidSystem, State};
use nalgebra::{Matrix3, Vector3};

/// Most vertices a contact's point is made of (a triangle's three and a point: issue 14's
/// point–triangle and edge–edge contacts; a collider contact uses one or two).
pub const CONTACT_VERTICES: usize = 4;

/// A point of a solid touching a kinematic collider. The point is Σ wⱼ xⱼ over the contact's
/// vertices (a vertex: one weight 1; a point on a hair segment: (1 − s, s)); an entry of
/// weight 0 is unused. The vertices may belong to different solids (a point of one less a
/// point of the other, `velocity` zero): the step adds the blocks its matrix lacks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// The vertices the point is made of.
    pub vertices: [u32; CONTACT_VERTICES],
    /// Their weights (unused entries 0).
    pub weights: [f64; CONTACT_VERTICES],
    /// Rows n, t₁, t₂: the contact frame, n out of the collider (orthonormal).
    pub frame: Matrix3<f64>,
    /// Distance to the collider minus the thickness at the start of the step [m] (negative:
    /// penetrating; pass the fraction of it to resolve this step).
    pub gap: f64,
    /// The collider's velocity at the contact point [m/s].
    pub velocity: Vector3<f64>,
    /// Friction coefficient μ ≥ 0.
    pub friction: f64,
    /// The most the collider may pull, as an impulse over the step [N·s] (cohesion).
    pub cohesion: f64,
    /// Damping of the normal relative velocity [1/s]: a force −c m (n·(v − v_c)) n on the
    /// point over the step, m = Σ |wⱼ| mⱼ (implicit: ½ c m h (n·(v − v_c))² in the objective).
    pub damping: f64,
}

impl Contact {
    /// A contact of vertex `v` alone, its other fields zero (set them).
    pub fn vertex(v: u32) -> Self {
        Self::points(&[(v, 1.0)])
    }

    /// A contact at Σ wⱼ x_vⱼ over `points` (at most [`CONTACT_VERTICES`]; the rest are
    /// dropped), its other fields zero.
    pub fn points(points: &[(u32, f64)]) -> Self {
        let mut c = Contact {
            vertices: [0; CONTACT_VERTICES],
            weights: [0.0; CONTACT_VERTICES],
            frame: Matrix3::identity(),
            gap: 0.0,
            velocity: Vector3::zeros(),
            friction: 0.0,
            cohesion: 0.0,
            damping: 0.0,
        };
        for (k, &(v, w)) in points.iter().take(CONTACT_VERTICES).enumerate() {
            c.vertices[k] = v;
            c.weights[k] = w;
        }
        c
    }

    /// The point's velocity over a step from `x0` to `x` of `h`.
    fn point_velocity(&self, x: &[Vector3<f64>], x0: &[Vector3<f64>], h: f64) -> Vector3<f64> {
        let mut v = Vector3::zeros();
        for (&i, &w) in self.vertices.iter().zip(&self.weights) {
            if w != 0.0 {
                v += w * (x[i as usize] - x0[i as usize]);
            }
        }
        v / h
    }

    /// The point's velocity relative to the contact's, in its frame (normal first).
    fn relative_velocity(&self, x: &[Vector3<f64>], x0: &[Vector3<f64>], h: f64) -> Vector3<f64> {
        self.frame * (self.point_velocity(x, x0, h) - self.velocity)
    }
}

/// A contact as the ADMM sees it: its moving vertices and where their blocks are.
struct Active<'a> {
    c: &'a Contact,
    /// (free index, weight) of the vertices that move.
    free: [(usize, f64); CONTACT_VERTICES],
    count: usize,
    /// `base[p][q]`: the slot of block (f_p, f_q) in f_q's column, so entry (a, b) of that
    /// block is entry 3b + a of `block_mut(f_q, base[p][q])`.
    base: [[usize; CONTACT_VERTICES]; CONTACT_VERTICES],
    /// Σ |wⱼ| mⱼ: the point's mass for its damping.
    mass: f64,
    /// Per moving vertex: the least normal stiffness its block counts for in ρ̂ (see
    /// `step_contacts_here`), (1 − CONTACT_CURVATURE) m/h².
    floor: [f64; CONTACT_VERTICES],
}

impl Active<'_> {
    fn free(&self) -> &[(usize, f64)] {
        &self.free[..self.count]
    }
}

/// The contacts of a step and how far their ADMM may go.
#[derive(Clone, Copy, Debug)]
pub struct ContactSet<'a> {
    /// The contacts.
    pub contacts: &'a [Contact],
    /// ADMM iterations allowed per Newton iteration.
    pub max_admm: usize,
    /// Impulses to start from, one per contact [N·s] in its frame (the last step's, matched
    /// by the caller; shorter than `contacts`: the rest start at zero).
    pub warm: &'a [[f64; 3]],
    /// Newton's first iterate (end-of-step positions, e.g. the last coupling iteration's), as
    /// in [`Integrator::step_from`]; `None`: x⁰ + h v⁰. Ignored when of the wrong length or
    /// not finite.
    pub guess: Option<&'a [Vector3<f64>]>,
    /// ADMM's first scale σ of every contact's ρ = σ ρ̂ (the last solve's
    /// [`ContactStats::sigma`] when a step is solved again; 0 or not finite: 1).
    pub sigma: f64,
    /// The caller retries a failed step smaller: a solve whose Newton steps are below the
    /// tolerance while ADMM stays off the contact laws for [`STALLED`] iterations fails
    /// then, not at the iteration limit, and so does one whose step grows past [`DIVERGED`]
    /// times its first. `false`: every iteration allowed is spent, unless such a stall
    /// also leaves ADMM's primal residual above half of what it was when the stall began
    /// (no progress: the solve fails then).
    pub give_up: bool,
    /// The smallest distance [m] the contacts' detection keeps between surfaces. A step
    /// extrapolated along a geometric tail (`tail.rs`) moves no point (rigid groups'
    /// members included; a slider's projection back onto its rail excepted) more than half
    /// of it beyond the full step, which reduces the chance of carrying a point through a
    /// surface the step's contacts do not hold (unbounded, hair_pile's ensemble met 17
    /// pass-throughs where 1 was met without extrapolation; bounded, 5). 0 (or NaN): no
    /// extrapolation; ∞ (no pairs): bounded only by the stretch's cap of 20.
    pub reach: f64,
}

/// Newton iterations in a row with steps below the tolerance and ADMM not converged after
/// which a solve that may give up ([`ContactSet::give_up`]) does. Traced on hair_pile: such
/// a solve's Newton steps stayed below the tolerance from its 23rd iteration to its 100th
/// while ADMM ended 0.21 m/s off the laws each time (contacts that contradict each other);
/// the step was then retried in halves, as it is now 67 iterations sooner.
pub(crate) const STALLED: usize = 10;

/// How many times its first step a contact solve's Newton step may be before a solve that
/// may give up ([`ContactSet::give_up`]) calls it diverged. Measured over hair_pile,
/// hair_on_head, cloth_drape and cloth_pile (thirty-third session): solves that converged
/// took steps up to 8.1e4 times their first (hair_on_head, one step at its third iteration),
/// and those that diverged passed 1e11 times it within a few iterations, then wandered at
/// 1e21–1e24 m/s until the iteration limit (ADMM ending 20–170 m/s off its laws and the line
/// search accepting steps towards its targets), only then retried smaller.
pub(crate) const DIVERGED: f64 = 1e7;

/// What the contact solve did over a step.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ContactStats {
    /// ADMM iterations, summed over Newton iterations.
    pub admm_iterations: usize,
    /// Refactorizations made to rebalance ρ between ADMM's residuals, or for contacts that
    /// rejoined the split once the low-rank correction was full.
    pub refactorizations: usize,
    /// Rounds whose rejoining contacts were added to the kept factor as a low-rank
    /// correction (`Joined`) instead of a refactorization.
    pub low_rank_joins: usize,
    /// Whether the pattern was rebuilt for blocks between vertices that share no element
    /// (contacts between solids) this step.
    pub pattern_rebuilt: bool,
    /// Seconds in the ADMM loops (their solves, contact projections and refactorizations).
    pub admm_seconds: f64,
    /// The largest distance from Coulomb's law at the end (`contact::residual`, as a
    /// velocity: impulse residuals divided by ρ).
    pub max_residual: f64,
    /// Each contact's impulse in its frame [N·s] (normal first), in `contacts`' order (zero
    /// for contacts on held vertices).
    pub impulses: Vec<[f64; 3]>,
    /// ADMM's scale σ of ρ at the end (0 when no ADMM ran).
    pub sigma: f64,
}

impl Integrator {
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

    /// The contacts that move something, with their blocks; `index` maps each back to
    /// `contacts`.
    fn activate<'a>(
        &self,
        sys: &SolidSystem,
        contacts: &'a [Contact],
        h: f64,
    ) -> Result<(Vec<usize>, Vec<Active<'a>>), StepError> {
        let mut index = Vec::new();
        let mut active = Vec::new();
        for (k, c) in contacts.iter().enumerate() {
            let mut a = Active {
                c,
                free: [(0, 0.0); CONTACT_VERTICES],
                count: 0,
                base: [[0; CONTACT_VERTICES]; CONTACT_VERTICES],
                mass: 0.0,
                floor: [0.0; CONTACT_VERTICES],
            };
            let mut valid = true;
            for (&v, &w) in c.vertices.iter().zip(&c.weights) {
                if w == 0.0 {
                    continue;
                }
                let v = v as usize;
                if v >= self.lin.n || !w.is_finite() {
                    valid = false;
                    break;
                }
                a.mass += w.abs() * sys.mass[v];
                if self.lin.free_of[v] != NONE {
                    a.free[a.count] = (self.lin.free_of[v] as usize, w);
                    a.floor[a.count] = (1.0 - CONTACT_CURVATURE) * sys.mass[v] / (h * h);
                    a.count += 1;
                }
            }
            // Contacts on held vertices only have nothing to move.
            if !valid || a.count == 0 {
                continue;
            }
            for p in 0..a.count {
                for q in 0..a.count {
                    a.base[p][q] = self
                        .lin.block_slot(a.free[p].0, a.free[q].0)
                        .ok_or_else(|| {
                            StepError::Factorization(format!(
                                "contact {k}: its vertices {:?} share no element, so the system has no block for them",
                                c.vertices
                            ))
                        })?;
                }
            }
            index.push(k);
            active.push(a);
        }
        Ok((index, active))
    }

    /// Adds `scale` × (w wᵀ ⊗ m) to the contact's blocks: m a 3×3 (by rows, a then b).
    fn add_contact_blocks(&mut self, a: &Active<'_>, scale: f64, m: &Matrix3<f64>) {
        for (p, &(_, wp)) in a.free().iter().enumerate() {
            for (q, &(fq, wq)) in a.free().iter().enumerate() {
                let f = scale * wp * wq;
                for (v, m) in self
                    .lin
                    .block_mut(fq, a.base[p][q])
                    .iter_mut()
                    .zip(m.as_slice())
                {
                    *v += f * m;
                }
            }
        }
    }

    /// Adds the contacts `joining` (indices into `active`, their ρ in `rho`, already added to
    /// the matrix's values for the next factorization) to `joined` as three columns each,
    /// W's new columns solved with the kept factor. False (and `joined` cleared) when S is
    /// not numerically positive definite: the caller factorizes instead.
    fn join_low_rank(
        &mut self,
        joined: &mut Joined,
        active: &[Active<'_>],
        rho: &[f64],
        joining: &[usize],
        h: f64,
        stats: &mut StepStats,
    ) -> bool {
        let dofs = 3 * self.lin.n_free;
        for &k in joining {
            let a = &active[k];
            let scale = rho[k].sqrt() / h;
            for axis in 0..3 {
                let col: Vec<(usize, f64)> = a
                    .free()
                    .iter()
                    .map(|&(f, w)| (3 * f + axis, scale * w))
                    .collect();
                let start = joined.w.len();
                joined.w.resize(start + dofs, 0.0);
                let w = &mut joined.w[start..];
                for &(i, v) in &col {
                    w[i] += v;
                }
                self.solve_in_place(stats, w);
                joined.u.push(col);
            }
        }
        let m = joined.u.len();
        let s = nalgebra::DMatrix::from_fn(m, m, |i, j| {
            let uw: f64 = joined.u[i]
                .iter()
                .map(|&(d, v)| v * joined.w[j * dofs + d])
                .sum();
            uw + if i == j { 1.0 } else { 0.0 }
        });
        // S is SPD (I plus a Gram matrix in A⁻¹'s inner product); symmetrized against rounding.
        joined.s = ((&s + s.transpose()) * 0.5).cholesky();
        joined.t = nalgebra::DVector::zeros(m);
        if joined.s.is_none() {
            joined.clear();
            return false;
        }
        true
    }

    /// [`Integrator::step`] with `set.contacts`: implicit Euler whose end-of-step velocities
    /// obey Signorini–Coulomb at every contact. ADMM stops when the split's primal and dual
    /// residuals are below `settings.tolerance` [m/s], within `set.max_admm` iterations a
    /// Newton iteration; each Newton update is line-searched on the primal objective. With
    /// no contacts, a Newton method's step is [`Integrator::step_from`]'s (from the guess).
    pub fn step_contacts(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        pinned_to: Option<&[Vector3<f64>]>,
        h: f64,
        settings: &Settings,
        set: ContactSet<'_>,
    ) -> Result<(StepStats, ContactStats), StepError> {
        // On a worker of the thread pool, for the assembly's fork–joins (see `in_pool`).
        super::in_pool(self.threaded(), || {
            self.step_contacts_here(sys, state, pinned_to, h, settings, set)
        })
    }

    fn step_contacts_here(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        pinned_to: Option<&[Vector3<f64>]>,
        h: f64,
        settings: &Settings,
        set: ContactSet<'_>,
    ) -> Result<(StepStats, ContactStats), StepError> {
        let (contacts, max_admm) = (set.contacts, set.max_admm);
        sys.check(state)?;
        if let Some(p) = &self.hooks.progress {
            p.solve(contacts.len());
        }
        // First: a rebuild resets every work buffer (the prediction's among them).
        let rebuilt = self.ensure_extra(sys, self.contact_blocks(contacts))?;
        // No contacts (none detected ahead; the exact check may still add some, and the
        // step is then solved again from this answer): the contact-free Newton, whose exact
        // Hessians (inertia added where indefinite) converge quadratically where ADMM's
        // projected ones converge linearly — 4–5 iterations a step on hair_on_head's strands
        // before they reach the head, against 7–8. Measured (24 frames, Newton iterations a
        // step): hair_on_head 13.54 → 12.23, hair_pile 12.68 → 12.18 (and 3 → 0 retried
        // substeps), cloth_pile 12.61 → 12.39, cloth_drape 14.21 → 14.20.
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
        self.fill_budget(sys, h, CONTACT_CURVATURE);
        let x0 = state.x.clone();
        let target = |i: usize| pinned_to.map_or(x0[i], |p| p[i]);
        let guess = set.guess.filter(|g| {
            g.len() == state.x.len() && g.iter().all(|p| p.iter().all(|c| c.is_finite()))
        });
        let mut x = state.x.clone();
        self.predict(sys, state, &mut x, &target, guess, h);
        let (index, active) = self.activate(sys, contacts, h)?;
        // ρ_c = σ ρ̂_c: ρ̂_c the point's effective mass along the normal, h² / Σⱼ wⱼ²/dⱼ with
        // dⱼ = nᵀ(M + h²K)ⱼⱼ n (a diagonal Delassus approximation, Daviet 2020), σ one scale
        // for every contact, balanced between the ADMM residuals (Boyd et al. 2011, §3.4.1)
        // at the cost of a refactorization whenever it changes. Each dⱼ counts for at least
        // (1 − CONTACT_CURVATURE) mⱼ/h², what the budgeted Hessians leave of the inertia:
        // a rod's exact Hessian can take a compressed strand's block below it, to negative,
        // and a negative ρ̂ made the augmented term concave (hair_pile's ensemble at
        // CONTACT_CURVATURE = 0.5: iterates at 1e50 m, a failed run; at 0.9 two of its
        // eight runs meet a negative ρ̂, and the floor moves the ensemble's mean by rounding:
        // 9.60 → 9.59 Newton iterations a step, 25 → 23 retried substeps).
        let mut rho_hat = vec![0.0; active.len()];
        // Starting where the last solve of this step ended (a round solved again), else 1.
        let mut sigma = if set.sigma > 0.0 && set.sigma.is_finite() {
            set.sigma
        } else {
            1.0
        };
        let mut rho = vec![0.0; active.len()];
        // Per contact: left out of this Newton iteration's augmented terms (see below).
        let mut free = vec![false; active.len()];
        // Per contact: how often it had to rejoin in this step (see below).
        let mut rejoins = vec![0u8; active.len()];
        let mut z = vec![Vector3::zeros(); active.len()];
        let mut r: Vec<Vector3<f64>> = index
            .iter()
            .map(|&k| {
                set.warm
                    .get(k)
                    .map_or_else(Vector3::zeros, |w| Vector3::from(*w))
            })
            .collect();
        let mut stats = StepStats::default();
        let mut cstats = ContactStats {
            pattern_rebuilt: rebuilt,
            ..Default::default()
        };
        let dofs = 3 * self.lin.n_free;
        let mut delta = vec![0.0; dofs];
        // The velocity each contact's term pulls its point towards in the last primal step.
        let mut want = vec![Vector3::zeros(); active.len()];
        // Each contact point's velocity at the Newton iterate (fixed during an ADMM loop).
        let mut vel = vec![Vector3::zeros(); active.len()];
        let identity = Matrix3::identity();
        // The value slot of row a, column b of free vertex f's diagonal block.
        let block = |s: &Self, f: usize, a: usize, b: usize| {
            super::block_entry(&s.lin.col_ptr, f, s.lin.diag_slot[f] as usize, a, b)
        };
        // The last ADMM round's (primal, dual) residuals, for the error when it does not end.
        let mut last_admm = (f64::NAN, f64::NAN);
        // Contacts joined since the last factorization (see `Joined`).
        let mut joined_lr = Joined::default();
        // Newton steps below the tolerance in a row while ADMM did not converge, and ADMM's
        // primal residual when they began.
        let mut stalled = 0;
        let mut stalled_from = f64::NAN;
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
            // through the iterations as in the contact-free loop, cloth_pile retried a substep
            // in every run of an ensemble (a contact step's Newton loop crawling past 100
            // iterations). Measured (ensembles by bench/ensemble.py, Newton iterations a
            // step): cloth_drape 9.82 → 9.08, cloth_pile 8.88 → 8.28 (4 runs each), hair_pile
            // 8.11 → 7.91 (8 runs; retried substeps 2.0 → 2.75), BENCHMARKS.md, thirty-third
            // session. Set and cleared around the one assembly, so no other solve reads it.
            if it == 0 {
                self.start_carried(sys, &x0, settings.method == Method::Newton);
                self.start_slide_forces(sys, true);
            }
            let t = std::time::Instant::now();
            self.assemble_with(sys, &x, &x0, Mode::Dynamic { h }, Hessians::Contact);
            stats.assembly_seconds += t.elapsed().as_secs_f64();
            self.carried.clear();
            if it == 0 {
                for (k, a) in active.iter().enumerate() {
                    let n = a.c.frame.row(0).transpose();
                    let mut compliance = 0.0;
                    for (j, &(f, w)) in a.free().iter().enumerate() {
                        let mut d = 0.0;
                        for aa in 0..3 {
                            for bb in 0..3 {
                                d += n[aa] * self.lin.values[block(self, f, aa, bb)] * n[bb];
                            }
                        }
                        compliance += w * w / d.max(a.floor[j]);
                    }
                    rho_hat[k] = h * h / compliance;
                    // z starts at the relative velocity of the prediction, made admissible
                    // (u_N ≥ −gap/h), so the first primal step is not pulled to rest.
                    let mut u = a.c.relative_velocity(&x, &x0, h);
                    u[0] = u[0].max(-a.c.gap / h);
                    z[k] = u;
                }
            }
            // A contact with no impulse whose point separates at the iterate (or keeps its gap)
            // is left out of the augmented terms: its ρ/2‖v − v_want‖² would only pull the
            // point towards its last velocity, a proximal term that makes the whole Newton
            // iteration crawl at the rate ρ/(ρ + λ) of the softest mode it touches
            // (measured on hair_on_head: residuals falling 0.6 % an iteration, steps ending
            // at the iteration limit). It joins back, with a refactorization, the moment a
            // primal step would move it into its collider; after two such returns it stays
            // in until the step ends: freed and rejoined at every other iteration, a contact
            // made Newton cycle (measured: the coupled hair_underwater at frame 96 when the
            // triangular solves' rounding changed, a period of six iterations between 5.7e-4
            // and 6.4e-3 m/s until the iteration limit). With cohesion the take-off impulse
            // is not zero: those contacts always stay in.
            for (k, a) in active.iter().enumerate() {
                let c = a.c;
                let mut u = c.relative_velocity(&x, &x0, h);
                u[0] += c.gap / h;
                free[k] =
                    rejoins[k] < 2 && c.cohesion == 0.0 && r[k] == Vector3::zeros() && u[0] > 0.0;
                rho[k] = if free[k] { 0.0 } else { sigma * rho_hat[k] };
                if free[k] {
                    z[k] = u;
                    z[k][0] -= c.gap / h;
                } else {
                    self.add_contact_blocks(a, rho[k] / (h * h), &identity);
                }
                let dm = a.c.damping * a.mass / h;
                if dm > 0.0 {
                    // d m/h · n nᵀ ⊗ w wᵀ on the point's blocks (their full 3×3 are stored).
                    let n = a.c.frame.row(0).transpose();
                    self.add_contact_blocks(a, dm, &(n * n.transpose()));
                }
            }
            self.factor(&mut stats, 0.0)?;
            joined_lr.clear();
            for (v, a) in vel.iter_mut().zip(&active) {
                *v = a.c.point_velocity(&x, &x0, h);
            }
            let mut admm_converged = false;
            let admm_start = std::time::Instant::now();
            for round in 0..max_admm.max(1) {
                // A long ADMM (contact_iterations is the user's) still answers a stop.
                if round % 16 == 15 && self.should_stop() {
                    return Err(StepError::Interrupted { iteration: it });
                }
                cstats.admm_iterations += 1;
                if let Some(p) = &self.hooks.progress {
                    p.admm();
                }
                for (d, g) in delta.iter_mut().zip(&self.work.grad) {
                    *d = -g;
                }
                for (k, a) in active.iter().enumerate() {
                    let v = vel[k];
                    // A free contact pulls nowhere (its ρ is zero; r/ρ would be 0/0).
                    want[k] = if free[k] {
                        v
                    } else {
                        a.c.velocity + a.c.frame.transpose() * (z[k] + r[k] / rho[k])
                    };
                    let g = rho[k] / h * (v - want[k]) + damping_force(a, v);
                    for &(f, w) in a.free() {
                        for aa in 0..3 {
                            delta[3 * f + aa] -= w * g[aa];
                        }
                    }
                }
                self.solve_in_place(&mut stats, &mut delta);
                joined_lr.correct(&mut delta);
                let (mut primal, mut dual) = (0.0f64, 0.0f64);
                // The contacts that join the split this round.
                let mut joining: Vec<usize> = Vec::new();
                for (k, a) in active.iter().enumerate() {
                    let c = a.c;
                    let mut moved = Vector3::zeros();
                    for &(f, w) in a.free() {
                        moved += w * Vector3::new(delta[3 * f], delta[3 * f + 1], delta[3 * f + 2]);
                    }
                    let hv = c.frame * (vel[k] + moved / h - c.velocity);
                    if free[k] {
                        if hv[0] + c.gap / h >= 0.0 {
                            // Still taking off: u = hv, no impulse, nothing to split.
                            dual = dual.max((hv - z[k]).amax());
                            z[k] = hv;
                            continue;
                        }
                        // The step would enter the collider: the contact joins the split
                        // from here, starting from the admissible part of hv.
                        free[k] = false;
                        rejoins[k] += 1;
                        joining.push(k);
                        rho[k] = sigma * rho_hat[k];
                        self.add_contact_blocks(a, rho[k] / (h * h), &identity);
                        z[k] = hv;
                        z[k][0] = z[k][0].max(-c.gap / h);
                        primal = primal.max((hv - z[k]).amax());
                        continue;
                    }
                    let mut w = hv - r[k] / rho[k];
                    // u_N ≥ −gap/h: the same law for w shifted by the gap.
                    w[0] += c.gap / h;
                    let (u, rn, _) = solve_local(w.into(), c.friction, c.cohesion, rho[k]);
                    let mut zn = Vector3::from(u);
                    zn[0] -= c.gap / h;
                    primal = primal.max((hv - zn).amax());
                    dual = dual.max((zn - z[k]).amax());
                    z[k] = zn;
                    r[k] = Vector3::from(rn);
                }
                last_admm = (primal, dual);
                if !joining.is_empty() {
                    let low_rank = joined_lr.u.len() + 3 * joining.len() <= self.modes.joined_max
                        && self.join_low_rank(
                            &mut joined_lr,
                            &active,
                            &rho,
                            &joining,
                            h,
                            &mut stats,
                        );
                    if low_rank {
                        cstats.low_rank_joins += 1;
                    } else {
                        cstats.refactorizations += 1;
                        self.factor(&mut stats, 0.0)?;
                        joined_lr.clear();
                    }
                    continue;
                }
                if primal < settings.tolerance && dual < settings.tolerance {
                    admm_converged = true;
                    break;
                }
                // Residual balancing every few iterations: a lagging primal residual asks
                // for a larger ρ, a lagging dual one for a smaller.
                if round % 8 == 7 {
                    let factor = if dual > 10.0 * primal {
                        0.25
                    } else if primal > 10.0 * dual {
                        4.0
                    } else {
                        1.0
                    };
                    let next = (sigma * factor).clamp(1e-8, 1e8);
                    if next != sigma {
                        for (k, a) in active.iter().enumerate() {
                            if free[k] {
                                continue;
                            }
                            let change = (next - sigma) * rho_hat[k];
                            self.add_contact_blocks(a, change / (h * h), &identity);
                            rho[k] = next * rho_hat[k];
                        }
                        sigma = next;
                        cstats.refactorizations += 1;
                        self.factor(&mut stats, 0.0)?;
                        joined_lr.clear();
                    }
                }
            }
            cstats.admm_seconds += admm_start.elapsed().as_secs_f64();
            // Backtracking (Armijo) on the primal objective at the last primal step's targets,
            // whose Newton direction delta is: it descends (the factored matrix is SPD).
            let phi = |s: &Self, x: &[Vector3<f64>]| {
                let mut e = s.objective(sys, x, &x0, Mode::Dynamic { h });
                for (k, a) in active.iter().enumerate() {
                    let v = a.c.point_velocity(x, &x0, h);
                    e += 0.5 * rho[k] * (v - want[k]).norm_squared();
                    let un = a.c.frame.row(0).transpose().dot(&(v - a.c.velocity));
                    e += 0.5 * a.c.damping * a.mass * h * un * un;
                }
                e
            };
            let mut slope: f64 = self.work.grad.iter().zip(&delta).map(|(g, d)| g * d).sum();
            for (k, a) in active.iter().enumerate() {
                let v = vel[k];
                let g = rho[k] / h * (v - want[k]) + damping_force(a, v);
                for &(f, w) in a.free() {
                    slope += w * (0..3).map(|aa| g[aa] * delta[3 * f + aa]).sum::<f64>();
                }
            }
            let e0 = phi(self, &x);
            let xmax = x.iter().fold(0.0f64, |m, p| m.max(p.amax()));
            // A direction of the model's converged contact problem that continues a
            // geometric series of full steps is tried at the series' sum first.
            let (mut stretch, ratio) = if admm_converged && self.modes.tails {
                tail.stretch(&delta)
            } else {
                (1.0, None)
            };
            if stretch > 1.0 {
                // No point more than half the reach beyond the full step (`largest_move`
                // bounds rigid groups' members too; a slider's projection back onto its rail
                // or surface, after, is not bounded by it).
                let cap = 1.0 + 0.5 * set.reach / self.largest_move(&delta);
                // A NaN cap (a NaN reach, or 0/0) allows no extrapolation.
                stretch = if cap >= 1.0 { stretch.min(cap) } else { 1.0 };
            }
            // Stopped at a frictional slider's stick point (`stick_cap`), once a step, the
            // extrapolation included. Such a step is short by construction: it ends no loop,
            // by its size or by the rate (its halvings may bring α back to 1).
            let capped = !stuck && Self::slide_friction(sys) && {
                let cap = self.stick_cap(sys, &x, &x0, &delta, h, stretch);
                let cut = cap < stretch;
                stretch = cap;
                cut
            };
            stuck |= capped;
            let mut trial = x.clone();
            let mut alpha = stretch;
            let corrections = stats.corrections;
            loop {
                self.place(sys, &x, &delta, alpha, &mut trial);
                let armijo = phi(self, &trial) <= e0 + 1e-4 * alpha * slope;
                let unresolvable = -slope * alpha <= 64.0 * f64::EPSILON * self.force_scale * xmax;
                // An extrapolation is taken only on a measured decrease: the escapes (a
                // decrease below rounding, a vanishing step) are for steps no longer than the
                // model's own.
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
                // It moves contact vertices too (by O(d²/L)): the next iteration's contact
                // solve puts them back where the law wants them, and the step that ends a
                // Newton loop is below the tolerance (or, ended by the rate, a full step with
                // no correction), so its correction is negligible. Holding them (as before)
                // left the segments between two contacts uncorrected, and their full steps
                // were halved: hair_on_head 13.3 → 7.7 iterations a step in the last
                // exact-check round of each (what the statistics then counted), 11.2 → 5.8 s
                // for the run.
                if alpha == 1.0 && !self.correction.is_empty() {
                    stats.correction_sweeps += self.correction.apply(
                        &self.lin.free_of,
                        &sys.mass,
                        &x,
                        &delta,
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
            // (Not an iteration that left a slider's friction out, `SlideForces`, nor one cut at a
            // stick point, `stick_cap`.)
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
            // excludes; the distances the contact tests assert hold, and cloth_drape ends as
            // near its run at a hundredth of the tolerance as before (3.6e-5 m, BENCHMARKS).
            // Measured (ensembles of 8, Newton iterations a step, with the contact-free
            // loop's rate stop as well): hair_on_head 9.98 → 8.70, hair_pile 9.59 → 7.72,
            // cloth_drape 10.55 → 9.81, cloth_pile 10.28 → 8.88.
            let full =
                alpha == 1.0 && admm_converged && stats.corrections == corrections && !capped;
            // Sliders' lagged friction settled too, their tail within the tolerance with
            // the steps' (`friction_budget`).
            let budget = self.friction_budget(sys, &mut friction_rate, full, settings);
            if rate.ends_within(budget, &mut stats, step, full) {
                break;
            }
            stalled = if step < settings.tolerance && !capped {
                stalled + 1
            } else {
                0
            };
            if stalled == 1 {
                stalled_from = last_admm.0;
            }
            // Given up on where the caller retries smaller; at its last try, once ADMM's
            // distance from the contact laws has not halved over the stall either: Newton
            // has nothing left to move and ADMM makes no progress, so the iterations left
            // would end the same way, later (a frame whose every halving failed so spent
            // up to 100 iterations of 200 ADMM rounds each before saying so).
            // (A NaN residual is no progress either.)
            let halved = last_admm.0 <= 0.5 * stalled_from;
            let flat = !halved;
            if stalled >= STALLED && (set.give_up || flat) {
                break;
            }
        }
        if !stats.converged {
            let step = stats.residuals.last().copied().unwrap_or(f64::NAN);
            if step < settings.tolerance {
                // Newton is done; the contacts are not.
                return Err(StepError::ContactsNotConverged {
                    iterations: stats.iterations,
                    step,
                    primal: last_admm.0,
                    dual: last_admm.1,
                    tolerance: settings.tolerance,
                });
            }
            return Err(stats.not_converged(settings.tolerance));
        }
        cstats.sigma = sigma;
        for (k, a) in active.iter().enumerate() {
            let c = a.c;
            let mut u = c.relative_velocity(&x, &x0, h);
            u[0] += c.gap / h;
            let res = residual(u.into(), r[k].into(), c.friction, c.cohesion);
            // Scaled by the contact's weight (a free contact's ρ is zero this iteration).
            let weight = (sigma * rho_hat[k]).max(f64::MIN_POSITIVE);
            cstats.max_residual = cstats.max_residual.max(res / weight);
        }
        cstats.impulses = vec![[0.0; 3]; contacts.len()];
        for (&k, rk) in index.iter().zip(&r) {
            cstats.impulses[k] = (*rk).into();
        }
        for ((v, xi), x0i) in state.v.iter_mut().zip(&x).zip(&x0) {
            *v = (xi - x0i) / h;
        }
        state.x = x;
        Ok((stats, cstats))
    }
}

/// The gradient of the contact's damping term ½ c m h (n·(v − v_c))² in the point's
/// position: c m (n·(v − v_c)) n.
fn damping_force(a: &Active<'_>, v: Vector3<f64>) -> Vector3<f64> {
    let c = a.c;
    if c.damping == 0.0 {
        return Vector3::zeros();
    }
    let n = c.frame.row(0).transpose();
    c.damping * a.mass * n.dot(&(v - c.velocity)) * n
}

/// Contacts that joined ADMM's augmented terms since the last factorization, as a low-rank
/// correction of that factor (Sherman–Morrison–Woodbury): a joining contact adds
/// ρ/h² (w wᵀ ⊗ I) = Σₐ uₐuₐᵀ to the matrix, uₐ = (√ρ/h) Σⱼ wⱼ e₃ⱼ₊ₐ (three columns), and
/// (A + UUᵀ)⁻¹b = y − W S⁻¹Uᵀy with y = A⁻¹b, W = A⁻¹U and S = I + UᵀW (small, dense). A join
/// then costs three solves a contact instead of a factorization: on the cloth pile 2,474 of
/// 5,881 factorizations were joins.
#[derive(Default)]
struct Joined {
    /// Each column of U: its nonzeros (DOF, value).
    u: Vec<Vec<(usize, f64)>>,
    /// W = A⁻¹U, column after column (`dofs` each).
    w: Vec<f64>,
    /// The Cholesky factor of S = I + UᵀW.
    s: Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
    /// Uᵀy, then S⁻¹Uᵀy: each correction's scratch (sized at each join).
    t: nalgebra::DVector<f64>,
}

/// Most columns [`Joined`] holds before the factor is made again (8 contacts' worth): each
/// column costs a solve when added and an axpy in every later solve.
pub(super) const JOINED_MAX: usize = 24;

impl Joined {
    fn clear(&mut self) {
        self.u.clear();
        self.w.clear();
        self.s = None;
    }

    /// Makes `delta` (A⁻¹b) into (A + UUᵀ)⁻¹b.
    fn correct(&mut self, delta: &mut [f64]) {
        let Some(s) = &self.s else { return };
        let dofs = delta.len();
        for (t, col) in self.t.iter_mut().zip(&self.u) {
            *t = col.iter().map(|&(i, v)| v * delta[i]).sum::<f64>();
        }
        s.solve_mut(&mut self.t);
        for (j, zj) in self.t.iter().enumerate() {
            for (d, w) in delta.iter_mut().zip(&self.w[j * dofs..(j + 1) * dofs]) {
                *d -= zj * w;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::settings::Method;

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
        ContactSet {
            contacts,
            max_admm,
            warm: &[],
            guess: None,
            sigma: 0.0,
            give_up: false,
            reach: f64::INFINITY,
        }
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
                    ContactSet {
                        contacts: if with_ghost { &two } else { &two[..1] },
                        max_admm: 200,
                        warm: &[],
                        guess: None,
                        sigma: 0.0,
                        give_up: false,
                        reach: f64::INFINITY,
                    },
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
                contacts: &contacts,
                max_admm: 50,
                warm: &[],
                guess: None,
                sigma: 0.0,
                give_up,
                reach: f64::INFINITY,
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
                    .step_contacts(
                        &sys,
                        &mut s,
                        None,
                        h,
                        &settings,
                        ContactSet {
                            contacts: &[c],
                            max_admm: 200,
                            warm: &[],
                            guess: None,
                            sigma: 0.0,
                            give_up: false,
                            reach: f64::INFINITY,
                        },
                    )
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
                let set = ContactSet {
                    contacts: &[c],
                    max_admm: 500,
                    warm: &[],
                    guess: None,
                    sigma: 0.0,
                    give_up: false,
                    reach: f64::INFINITY,
                };
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
        let set = ContactSet {
            contacts: &[c],
            max_admm: 500,
            warm: &[],
            guess: None,
            sigma: 0.0,
            give_up: false,
            reach: f64::INFINITY,
        };
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
            let set = ContactSet {
                contacts: &[c],
                max_admm: 1000,
                warm: &[],
                guess: None,
                sigma: 0.0,
                give_up: false,
                reach: f64::INFINITY,
            };
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
        let set = ContactSet {
            contacts: &[c],
            max_admm: 2000,
            warm: &[],
            guess: None,
            sigma: 0.0,
            give_up: false,
            reach: f64::INFINITY,
        };
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
    /// be positive (the inertia floor): with ρ̂ < 0 the augmented term was concave and the
    /// iterates left for 1e50 m (hair_pile at CONTACT_CURVATURE = 0.5, frame 11). Each
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

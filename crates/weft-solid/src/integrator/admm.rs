//! ADMM on one Newton model of a contact step (Daviet 2020; the Newton loop around it is
//! `contact_step.rs`, the derivations `docs/contacts.md`).
//!
//! [`Admm`] owns every contact's state over the step and runs its phases, in this order in
//! each Newton iteration:
//! 1. [`Admm::estimate`] (first iteration only): ρ̂ from a diagonal Delassus estimate, and z
//!    at the prediction's relative velocity;
//! 2. [`Admm::split`]: which contacts the augmented terms hold, their blocks ρ/h² (w wᵀ ⊗ I)
//!    and damping added to the Newton model, one factorization;
//! 3. [`Admm::rounds`]: primal steps (one solve each with that factor), the closed-form local
//!    Signorini–Coulomb solves, contacts rejoining (a low-rank correction, [`Joined`], or a
//!    refactorization) and residual balancing of ρ;
//! 4. the line search reads [`Admm::augmented`] and [`Admm::slope`];
//! 5. [`Admm::finish`]: the residual of Coulomb's law and the impulses.
//!
//! ρ_c = σ ρ̂_c: ρ̂_c the point's effective mass along the normal, h² / Σⱼ wⱼ²/dⱼ with
//! dⱼ = nᵀ(M + h²K)ⱼⱼ n (a diagonal Delassus approximation, Daviet 2020), σ one scale for
//! every contact, balanced between the ADMM residuals (Boyd et al. 2011, §3.4.1) at the cost
//! of a refactorization whenever it changes. Each dⱼ counts for at least
//! (1 − CONTACT_CURVATURE) mⱼ/h², what the budgeted Hessians leave of the inertia: a rod's
//! exact Hessian can take a compressed strand's block below it, to negative, and a negative
//! ρ̂ makes the augmented term concave, so the iterates run away; the floor keeps ρ̂
//! positive (`contact_step.rs`'s compressed rod on a floor tests it).

use super::contacts::{CONTACT_VERTICES, Contact, ContactSet, ContactStats};
use super::linear::LinearSystem;
use super::{CONTACT_CURVATURE, Integrator, NONE};
use crate::contact::{residual, solve_local};
use crate::settings::{StepError, StepStats};
use crate::system::SolidSystem;
use nalgebra::{Matrix3, Vector3};

/// A contact as the ADMM sees it: its moving vertices and where their blocks are.
pub(super) struct Active<'a> {
    pub(super) c: &'a Contact,
    /// (free index, weight) of the vertices that move.
    free: [(usize, f64); CONTACT_VERTICES],
    count: usize,
    /// `base[p][q]`: the slot of block (f_p, f_q) in f_q's column, so entry (a, b) of that
    /// block is entry 3b + a of `block_mut(f_q, base[p][q])`.
    base: [[usize; CONTACT_VERTICES]; CONTACT_VERTICES],
    /// Σ |wⱼ| mⱼ: the point's mass for its damping.
    mass: f64,
    /// Per moving vertex: the least normal stiffness its block counts for in ρ̂ (see the
    /// module's doc), (1 − CONTACT_CURVATURE) m/h².
    floor: [f64; CONTACT_VERTICES],
}

impl Active<'_> {
    pub(super) fn free(&self) -> &[(usize, f64)] {
        &self.free[..self.count]
    }

    /// Adds `scale` × (w wᵀ ⊗ m) to the contact's blocks: m a 3×3 (by rows, a then b).
    fn add_blocks(&self, lin: &mut LinearSystem, scale: f64, m: &Matrix3<f64>) {
        for (p, &(_, wp)) in self.free().iter().enumerate() {
            for (q, &(fq, wq)) in self.free().iter().enumerate() {
                let f = scale * wp * wq;
                for (v, m) in lin
                    .block_mut(fq, self.base[p][q])
                    .iter_mut()
                    .zip(m.as_slice())
                {
                    *v += f * m;
                }
            }
        }
    }

    /// The gradient of the contact's damping term ½ c m h (n·(v − v_c))² in the point's
    /// position: c m (n·(v − v_c)) n.
    fn damping_force(&self, v: Vector3<f64>) -> Vector3<f64> {
        let c = self.c;
        if c.damping == 0.0 {
            return Vector3::zeros();
        }
        let n = c.frame.row(0).transpose();
        c.damping * self.mass * n.dot(&(v - c.velocity)) * n
    }
}

/// Every contact's ADMM state over one contact step, one entry per contact that moves
/// something (`index` maps each back to the caller's list).
pub(super) struct Admm<'a> {
    active: Vec<Active<'a>>,
    index: Vec<usize>,
    /// Each contact's effective mass along its normal (see the module's doc).
    rho_hat: Vec<f64>,
    /// The one scale of every contact's ρ = σ ρ̂.
    sigma: f64,
    rho: Vec<f64>,
    /// Per contact: left out of this Newton iteration's augmented terms ([`Admm::split`]).
    free: Vec<bool>,
    /// Per contact: how often it had to rejoin in this step ([`Admm::split`]).
    rejoins: Vec<u8>,
    /// The split's variable (a relative velocity in the contact's frame) and the impulses.
    z: Vec<Vector3<f64>>,
    r: Vec<Vector3<f64>>,
    /// The velocity each contact's term pulls its point towards in the last primal step.
    want: Vec<Vector3<f64>>,
    /// Each contact point's velocity at the Newton iterate (fixed during the rounds).
    vel: Vec<Vector3<f64>>,
    /// The last round's (primal, dual) residuals, for the error when the step does not end.
    last: (f64, f64),
    /// Contacts joined since the last factorization (see [`Joined`]).
    joined: Joined,
}

impl<'a> Admm<'a> {
    /// The contacts of `set` that move something (contacts on held vertices only have
    /// nothing to move), starting from its warm impulses and its σ (else 1).
    pub(super) fn new(
        integ: &Integrator,
        sys: &SolidSystem,
        set: &ContactSet<'a>,
        h: f64,
    ) -> Result<Self, StepError> {
        let lin = &integ.lin;
        let mut index = Vec::new();
        let mut active = Vec::new();
        for (k, c) in set.contacts.iter().enumerate() {
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
                if v >= lin.n || !w.is_finite() {
                    valid = false;
                    break;
                }
                a.mass += w.abs() * sys.mass[v];
                if lin.free_of[v] != NONE {
                    a.free[a.count] = (lin.free_of[v] as usize, w);
                    a.floor[a.count] = (1.0 - CONTACT_CURVATURE) * sys.mass[v] / (h * h);
                    a.count += 1;
                }
            }
            if !valid || a.count == 0 {
                continue;
            }
            for p in 0..a.count {
                for q in 0..a.count {
                    a.base[p][q] = lin.block_slot(a.free[p].0, a.free[q].0).ok_or_else(|| {
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
        let n = active.len();
        let r = index
            .iter()
            .map(|&k| {
                set.warm
                    .get(k)
                    .map_or_else(Vector3::zeros, |w| Vector3::from(*w))
            })
            .collect();
        // Starting where the last solve of this step ended (a round solved again), else 1.
        let sigma = if set.sigma > 0.0 && set.sigma.is_finite() {
            set.sigma
        } else {
            1.0
        };
        Ok(Self {
            active,
            index,
            rho_hat: vec![0.0; n],
            sigma,
            rho: vec![0.0; n],
            free: vec![false; n],
            rejoins: vec![0; n],
            z: vec![Vector3::zeros(); n],
            r,
            want: vec![Vector3::zeros(); n],
            vel: vec![Vector3::zeros(); n],
            last: (f64::NAN, f64::NAN),
            joined: Joined::default(),
        })
    }

    /// The last round's (primal, dual) residuals (NaN before any).
    pub(super) fn last(&self) -> (f64, f64) {
        self.last
    }

    /// Phase 1, at the first Newton model (assembled in `lin`): each contact's ρ̂, and z at
    /// the relative velocity of the prediction x, made admissible (u_N ≥ −gap/h), so the
    /// first primal step is not pulled to rest.
    pub(super) fn estimate(
        &mut self,
        lin: &LinearSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
    ) {
        for (k, a) in self.active.iter().enumerate() {
            let n = a.c.frame.row(0).transpose();
            let mut compliance = 0.0;
            for (j, &(f, w)) in a.free().iter().enumerate() {
                let mut d = 0.0;
                for aa in 0..3 {
                    for bb in 0..3 {
                        let slot =
                            super::block_entry(&lin.col_ptr, f, lin.diag_slot[f] as usize, aa, bb);
                        d += n[aa] * lin.values[slot] * n[bb];
                    }
                }
                compliance += w * w / d.max(a.floor[j]);
            }
            self.rho_hat[k] = h * h / compliance;
            let mut u = a.c.relative_velocity(x, x0, h);
            u[0] = u[0].max(-a.c.gap / h);
            self.z[k] = u;
        }
    }

    /// Phase 2: the augmented terms of the Newton model assembled at x, and its
    /// factorization.
    ///
    /// A contact with no impulse whose point separates at the iterate (or keeps its gap) is
    /// left out of the augmented terms: its ρ/2‖v − v_want‖² would only pull the point
    /// towards its last velocity, a proximal term that makes the whole Newton iteration
    /// crawl at the rate ρ/(ρ + λ) of the softest mode it touches (on hair_on_head the
    /// residuals barely fall, and steps end at the iteration limit). It joins back the moment
    /// a primal step would move it into its collider ([`Admm::rounds`]); after two such
    /// returns it stays in until the step ends: freed and rejoined at every other iteration,
    /// a contact can make Newton cycle until the iteration limit (as in the coupled
    /// hair_underwater example; figures in docs/history/issue-71-comments.md).
    /// With cohesion the take-off impulse is not zero: those contacts always stay in.
    pub(super) fn split(
        &mut self,
        integ: &mut Integrator,
        stats: &mut StepStats,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
    ) -> Result<(), StepError> {
        let identity = Matrix3::identity();
        for (k, a) in self.active.iter().enumerate() {
            let c = a.c;
            let mut u = c.relative_velocity(x, x0, h);
            u[0] += c.gap / h;
            self.free[k] = self.rejoins[k] < 2
                && c.cohesion == 0.0
                && self.r[k] == Vector3::zeros()
                && u[0] > 0.0;
            self.rho[k] = if self.free[k] {
                0.0
            } else {
                self.sigma * self.rho_hat[k]
            };
            if self.free[k] {
                self.z[k] = u;
                self.z[k][0] -= c.gap / h;
            } else {
                a.add_blocks(&mut integ.lin, self.rho[k] / (h * h), &identity);
            }
            let dm = a.c.damping * a.mass / h;
            if dm > 0.0 {
                // d m/h · n nᵀ ⊗ w wᵀ on the point's blocks (their full 3×3 are stored).
                let n = a.c.frame.row(0).transpose();
                a.add_blocks(&mut integ.lin, dm, &(n * n.transpose()));
            }
        }
        integ.factor(stats, 0.0)?;
        self.joined.clear();
        for (v, a) in self.vel.iter_mut().zip(&self.active) {
            *v = a.c.point_velocity(x, x0, h);
        }
        Ok(())
    }

    /// Phase 3: ADMM's rounds on the factored model, at most `max_admm`, until the split's
    /// primal and dual residuals are below `tolerance` [m/s] (true) or the rounds run out.
    /// `delta` holds the last primal step's Newton direction; `grad` is the model's
    /// gradient; `it` the Newton iteration (for an interruption's error).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn rounds(
        &mut self,
        integ: &mut Integrator,
        stats: &mut StepStats,
        cstats: &mut ContactStats,
        delta: &mut [f64],
        (max_admm, tolerance): (usize, f64),
        h: f64,
        it: usize,
    ) -> Result<bool, StepError> {
        let start = std::time::Instant::now();
        let mut converged = false;
        for round in 0..max_admm.max(1) {
            // A long ADMM (contact_iterations is the user's) still answers a stop.
            if round % 16 == 15 && integ.should_stop() {
                return Err(StepError::Interrupted { iteration: it });
            }
            cstats.admm_iterations += 1;
            if let Some(p) = &integ.hooks.progress {
                p.admm();
            }
            self.primal_rhs(&integ.work.grad, delta, h);
            integ.solve_in_place(stats, delta);
            self.joined.correct(delta);
            let (primal, dual, joining) = self.local_solves(&mut integ.lin, delta, h);
            self.last = (primal, dual);
            if !joining.is_empty() {
                let low_rank = self.joined.u.len() + 3 * joining.len() <= integ.modes.joined_max
                    && self
                        .joined
                        .join(integ, &self.active, &self.rho, &joining, h, stats);
                if low_rank {
                    cstats.low_rank_joins += 1;
                } else {
                    cstats.refactorizations += 1;
                    integ.factor(stats, 0.0)?;
                    self.joined.clear();
                }
                continue;
            }
            if primal < tolerance && dual < tolerance {
                converged = true;
                break;
            }
            if round % 8 == 7 {
                self.balance(integ, stats, cstats, (primal, dual), h)?;
            }
        }
        cstats.admm_seconds += start.elapsed().as_secs_f64();
        Ok(converged)
    }

    /// The primal step's right-hand side: −∇E less each held contact's pull towards its
    /// target velocity (a free contact pulls nowhere: its ρ is zero and r/ρ would be 0/0).
    fn primal_rhs(&mut self, grad: &[f64], delta: &mut [f64], h: f64) {
        for (d, g) in delta.iter_mut().zip(grad) {
            *d = -g;
        }
        for (k, a) in self.active.iter().enumerate() {
            let v = self.vel[k];
            self.want[k] = if self.free[k] {
                v
            } else {
                a.c.velocity + a.c.frame.transpose() * (self.z[k] + self.r[k] / self.rho[k])
            };
            let g = self.rho[k] / h * (v - self.want[k]) + a.damping_force(v);
            for &(f, w) in a.free() {
                for aa in 0..3 {
                    delta[3 * f + aa] -= w * g[aa];
                }
            }
        }
    }

    /// Each contact's local solve at the primal step `delta`: (primal, dual) residuals, and
    /// the free contacts whose step would enter their collider, which join the split here
    /// (their augmented blocks added to `lin`, starting from the admissible part of hv).
    fn local_solves(
        &mut self,
        lin: &mut LinearSystem,
        delta: &[f64],
        h: f64,
    ) -> (f64, f64, Vec<usize>) {
        let identity = Matrix3::identity();
        let (mut primal, mut dual) = (0.0f64, 0.0f64);
        let mut joining: Vec<usize> = Vec::new();
        for (k, a) in self.active.iter().enumerate() {
            let c = a.c;
            let mut moved = Vector3::zeros();
            for &(f, w) in a.free() {
                moved += w * Vector3::new(delta[3 * f], delta[3 * f + 1], delta[3 * f + 2]);
            }
            let hv = c.frame * (self.vel[k] + moved / h - c.velocity);
            if self.free[k] {
                if hv[0] + c.gap / h >= 0.0 {
                    // Still taking off: u = hv, no impulse, nothing to split.
                    dual = dual.max((hv - self.z[k]).amax());
                    self.z[k] = hv;
                    continue;
                }
                self.free[k] = false;
                self.rejoins[k] += 1;
                joining.push(k);
                self.rho[k] = self.sigma * self.rho_hat[k];
                a.add_blocks(lin, self.rho[k] / (h * h), &identity);
                self.z[k] = hv;
                self.z[k][0] = self.z[k][0].max(-c.gap / h);
                primal = primal.max((hv - self.z[k]).amax());
                continue;
            }
            let mut w = hv - self.r[k] / self.rho[k];
            // u_N ≥ −gap/h: the same law for w shifted by the gap.
            w[0] += c.gap / h;
            let (u, rn, _) = solve_local(w.into(), c.friction, c.cohesion, self.rho[k]);
            let mut zn = Vector3::from(u);
            zn[0] -= c.gap / h;
            primal = primal.max((hv - zn).amax());
            dual = dual.max((zn - self.z[k]).amax());
            self.z[k] = zn;
            self.r[k] = Vector3::from(rn);
        }
        (primal, dual, joining)
    }

    /// Residual balancing (every eighth round): a lagging primal residual asks for a larger
    /// ρ, a lagging dual one for a smaller; a change refactors.
    fn balance(
        &mut self,
        integ: &mut Integrator,
        stats: &mut StepStats,
        cstats: &mut ContactStats,
        (primal, dual): (f64, f64),
        h: f64,
    ) -> Result<(), StepError> {
        let factor = if dual > 10.0 * primal {
            0.25
        } else if primal > 10.0 * dual {
            4.0
        } else {
            1.0
        };
        let next = (self.sigma * factor).clamp(1e-8, 1e8);
        if next != self.sigma {
            let identity = Matrix3::identity();
            for (k, a) in self.active.iter().enumerate() {
                if self.free[k] {
                    continue;
                }
                let change = (next - self.sigma) * self.rho_hat[k];
                a.add_blocks(&mut integ.lin, change / (h * h), &identity);
                self.rho[k] = next * self.rho_hat[k];
            }
            self.sigma = next;
            cstats.refactorizations += 1;
            integ.factor(stats, 0.0)?;
            self.joined.clear();
        }
        Ok(())
    }

    /// Phase 4: `e`, the incremental potential at x, plus the contacts' augmented and
    /// damping terms at the last primal step's targets: the line search's objective.
    pub(super) fn augmented(
        &self,
        mut e: f64,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
    ) -> f64 {
        for (k, a) in self.active.iter().enumerate() {
            let v = a.c.point_velocity(x, x0, h);
            e += 0.5 * self.rho[k] * (v - self.want[k]).norm_squared();
            let un = a.c.frame.row(0).transpose().dot(&(v - a.c.velocity));
            e += 0.5 * a.c.damping * a.mass * h * un * un;
        }
        e
    }

    /// The slope of [`Admm::augmented`] along `delta` at the iterate (`grad`: the
    /// potential's gradient there).
    pub(super) fn slope(&self, grad: &[f64], delta: &[f64], h: f64) -> f64 {
        let mut slope: f64 = grad.iter().zip(delta).map(|(g, d)| g * d).sum();
        for (k, a) in self.active.iter().enumerate() {
            let v = self.vel[k];
            let g = self.rho[k] / h * (v - self.want[k]) + a.damping_force(v);
            for &(f, w) in a.free() {
                slope += w * (0..3).map(|aa| g[aa] * delta[3 * f + aa]).sum::<f64>();
            }
        }
        slope
    }

    /// Phase 5, at the converged x: σ, the largest distance from Coulomb's law (impulse
    /// residuals scaled by each contact's weight) and every contact's impulse, in the
    /// caller's order (zero for contacts on held vertices), into `cstats`.
    pub(super) fn finish(
        &self,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
        contacts: usize,
        cstats: &mut ContactStats,
    ) {
        cstats.sigma = self.sigma;
        for (k, a) in self.active.iter().enumerate() {
            let c = a.c;
            let mut u = c.relative_velocity(x, x0, h);
            u[0] += c.gap / h;
            let res = residual(u.into(), self.r[k].into(), c.friction, c.cohesion);
            // Scaled by the contact's weight (a free contact's ρ is zero this iteration).
            let weight = (self.sigma * self.rho_hat[k]).max(f64::MIN_POSITIVE);
            cstats.max_residual = cstats.max_residual.max(res / weight);
        }
        cstats.impulses = vec![[0.0; 3]; contacts];
        for (&k, rk) in self.index.iter().zip(&self.r) {
            cstats.impulses[k] = (*rk).into();
        }
    }
}

/// Contacts that joined ADMM's augmented terms since the last factorization, as a low-rank
/// correction of that factor (Sherman–Morrison–Woodbury): a joining contact adds
/// ρ/h² (w wᵀ ⊗ I) = Σₐ uₐuₐᵀ to the matrix, uₐ = (√ρ/h) Σⱼ wⱼ e₃ⱼ₊ₐ (three columns), and
/// (A + UUᵀ)⁻¹b = y − W S⁻¹Uᵀy with y = A⁻¹b, W = A⁻¹U and S = I + UᵀW (small, dense). A join
/// then costs three solves a contact instead of a factorization, and where contacts leave
/// and rejoin often (cloth_pile) joins replace a large share of the factorizations (the
/// example's `--stats-json` counts them; figures in docs/history/issue-71-comments.md).
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

    /// Adds the contacts `joining` (indices into `active`, their ρ in `rho`, already added
    /// to the matrix's values for the next factorization) as three columns each, W's new
    /// columns solved with the kept factor. False (and cleared) when S is not numerically
    /// positive definite: the caller factorizes instead.
    fn join(
        &mut self,
        integ: &mut Integrator,
        active: &[Active<'_>],
        rho: &[f64],
        joining: &[usize],
        h: f64,
        stats: &mut StepStats,
    ) -> bool {
        let dofs = 3 * integ.lin.n_free;
        for &k in joining {
            let a = &active[k];
            let scale = rho[k].sqrt() / h;
            for axis in 0..3 {
                let col: Vec<(usize, f64)> = a
                    .free()
                    .iter()
                    .map(|&(f, w)| (3 * f + axis, scale * w))
                    .collect();
                let start = self.w.len();
                self.w.resize(start + dofs, 0.0);
                let w = &mut self.w[start..];
                for &(i, v) in &col {
                    w[i] += v;
                }
                integ.solve_in_place(stats, w);
                self.u.push(col);
            }
        }
        let m = self.u.len();
        let s = nalgebra::DMatrix::from_fn(m, m, |i, j| {
            let uw: f64 = self.u[i]
                .iter()
                .map(|&(d, v)| v * self.w[j * dofs + d])
                .sum();
            uw + if i == j { 1.0 } else { 0.0 }
        });
        // S is SPD (I plus a Gram matrix in A⁻¹'s inner product); symmetrized against rounding.
        self.s = ((&s + s.transpose()) * 0.5).cholesky();
        self.t = nalgebra::DVector::zeros(m);
        if self.s.is_none() {
            self.clear();
            return false;
        }
        true
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

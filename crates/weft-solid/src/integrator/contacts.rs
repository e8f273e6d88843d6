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
//! [`solve_local`](crate::contact::solve_local). The stationarity of the primal objective E(x) + Σ ρ_c/2 ‖H_c v − z_c −
//! r_c/ρ_c‖² at H_c v = z_c is ∇E = Σ H_cᵀ r_c/h, the momentum balance with the colliders'
//! impulses r_c [N·s], shared by the point's vertices in proportion to their weights.
//!
//! Where each part lives: this file says what a contact is ([`Contact`]), what a step is
//! given ([`ContactSet`]) and what its solve did ([`ContactStats`]); `contact_step.rs` is the
//! Newton loop and its line search; `admm.rs` is ADMM on each Newton model, in named phases.

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
    pub(super) fn point_velocity(
        &self,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
    ) -> Vector3<f64> {
        let mut v = Vector3::zeros();
        for (&i, &w) in self.vertices.iter().zip(&self.weights) {
            if w != 0.0 {
                v += w * (x[i as usize] - x0[i as usize]);
            }
        }
        v / h
    }

    /// The point's velocity relative to the contact's, in its frame (normal first).
    pub(super) fn relative_velocity(
        &self,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
    ) -> Vector3<f64> {
        self.frame * (self.point_velocity(x, x0, h) - self.velocity)
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
    /// in [`Integrator::step_from`](super::Integrator::step_from); `None`: x⁰ + h v⁰. Ignored when of the wrong length or
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
    /// surface the step's contacts do not hold (unbounded, extrapolation makes such
    /// pass-throughs far more frequent on hair_pile; bounded, only a few more than without
    /// it: `bench/ensemble.py` measures it, figures in docs/history/issue-71-comments.md).
    /// 0 (or NaN): no extrapolation; ∞ (no pairs): bounded only by the stretch's cap of 20.
    pub reach: f64,
}

impl<'a> ContactSet<'a> {
    /// `contacts` solved from a cold start (no warm impulses, no guess, σ = 1), every
    /// iteration allowed spent, no extrapolation bound: the plain problem, which a caller
    /// with history changes field by field.
    pub fn new(contacts: &'a [Contact], max_admm: usize) -> Self {
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
}

/// Newton iterations in a row with steps below the tolerance and ADMM not converged after
/// which a solve that may give up ([`ContactSet::give_up`]) does. Such a solve has nothing
/// left for Newton to move while ADMM stays off the laws each time (contacts that
/// contradict each other, as traced on hair_pile): waiting for the iteration limit only
/// delays the retry in halves it ends in (figures in docs/history/issue-71-comments.md).
pub(crate) const STALLED: usize = 10;

/// How many times its first step a contact solve's Newton step may be before a solve that
/// may give up ([`ContactSet::give_up`]) calls it diverged: far above the growth of the
/// solves that converge, far below what diverging ones reach within a few iterations, after
/// which they wander until the iteration limit (ADMM far off its laws and the line search
/// accepting steps towards its targets), only then retried smaller. `bench/ensemble.py` on
/// hair_pile, hair_on_head, cloth_drape and cloth_pile measures both; figures in
/// docs/history/issue-71-comments.md.
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

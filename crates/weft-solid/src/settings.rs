//! What a step is asked (method, tolerance, iteration limit), what it reports, and why it
//! can fail.

use crate::system::SystemError;

/// How a step is integrated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Symplectic Euler: cheap, conditionally stable (h below ~2/ω_max).
    Explicit,
    /// One projected Newton step from x⁰ + h v⁰ (Baraff–Witkin style linearized implicit Euler).
    Linearized,
    /// Newton iterated to tolerance (implicit Euler solved exactly), each iteration with the
    /// exact Hessian where it is cheap and positive definite (quadratic convergence), else
    /// with more inertia, else projected (see `Element::eval_first`). Steps with contacts
    /// (their ADMM needs an SPD model) use projected Hessians throughout.
    Newton,
    /// Projected Newton iterated to tolerance: every element Hessian projected to PSD at
    /// every iteration (the same answer; kept for comparison, it converges linearly where
    /// cloth buckles).
    ProjectedNewton,
    /// No inertia: each step moves pinned vertices to their targets and finds the static
    /// equilibrium from where the last one was (the tolerance is ‖Δx‖∞ in metres);
    /// velocities are zero. Steps then load a structure gradually (a static solve of a
    /// cantilever, a drape's rest shape), not time.
    Static,
}

/// Step settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Integration method.
    pub method: Method,
    /// Newton stops when ‖Δx‖∞ / h, the largest velocity change a further iteration would make,
    /// is below this [m/s] (for [`Integrator::solve_static`]: ‖Δx‖∞ in metres): measured by
    /// that iteration's step, or estimated from the contraction of the last two full steps
    /// (at a ratio q < ½, the geometric tail r q/(1 − q) of the last step's r; time steps
    /// only: with [`Method::Newton`] its unshifted first Hessians' iterations, and in contact
    /// steps the iterations whose ADMM converged; `integrator/rate.rs`).
    pub tolerance: f64,
    /// Newton iteration limit.
    pub max_iterations: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            method: Method::Newton,
            tolerance: 1e-6,
            max_iterations: 50,
        }
    }
}

/// What one step did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StepStats {
    /// Newton iterations (1 for linearized, 0 for explicit).
    pub iterations: usize,
    /// ‖Δx‖∞ / h per iteration [m/s].
    pub residuals: Vec<f64>,
    /// True when the tolerance was met (always for explicit and linearized).
    pub converged: bool,
    /// Step-length halvings in the line search, summed over iterations.
    pub halvings: usize,
    /// Seconds assembling gradients and Hessians.
    pub assembly_seconds: f64,
    /// Seconds in numeric factorization.
    pub factor_seconds: f64,
    /// Numeric factorizations, the failed ones included (inertia tries, regularization,
    /// a contact step's refactorizations).
    pub factorizations: usize,
    /// Seconds in triangular solves (and the one-ring preconditioner's conjugate gradients).
    pub solve_seconds: f64,
    /// Conjugate-gradient iterations of the one-ring preconditioner, summed over directions.
    pub cg_iterations: usize,
    /// Factorizations retried with added inertia because the exact Hessian was not
    /// positive definite ([`Method::Newton`]).
    pub shifted: usize,
    /// Iterations that used the projected Hessians under [`Method::Newton`] (every retry
    /// with inertia failed).
    pub projected: usize,
    /// Full Newton steps rejected by the line search and accepted after a second-order
    /// correction of the rods' lengths.
    pub corrections: usize,
    /// Iterations those corrections took, accepted or not (tridiagonal projections along
    /// strands, or Gauss–Seidel sweeps where segments are not chains).
    pub correction_sweeps: usize,
    /// Contact-step iterations whose step was taken at the sum of a geometric tail's series
    /// (`integrator/tail.rs`) instead of at full length.
    pub extrapolations: usize,
    /// Halvings of extrapolated trials (each halving of a step longer than the full one,
    /// down to the full step; one try from 20 counts up to 5): what the tail's sums cost
    /// in objective evaluations where they did not pay.
    pub extrapolation_halvings: usize,
    /// Moves along a direction of negative curvature after a shifted Newton step
    /// (`integrator/curvature.rs`).
    pub curvature_moves: usize,
    /// Patches around lagging vertices solved by their own Newton iterations after a
    /// Newton step, and moved (`integrator/elimination.rs`).
    pub eliminations: usize,
    /// Newton loops ended by their rate's estimate of the corrections still to come
    /// (`integrator/rate.rs`), one iteration before a step below the tolerance would have
    /// been measured.
    pub rate_stops: usize,
    /// Where the loop ended by its rate: the estimate of the corrections still to come
    /// [m/s] (below the tolerance; the last residual is the last step's, above it).
    pub estimate: Option<f64>,
}

impl StepStats {
    /// Adds the work of an earlier solve of the same step that was thrown away (a contact
    /// step solved again after its exact check added contacts): its iterations, halvings,
    /// seconds and tries count; its residuals and convergence do not.
    pub fn absorb(&mut self, earlier: &StepStats) {
        self.iterations += earlier.iterations;
        self.halvings += earlier.halvings;
        self.assembly_seconds += earlier.assembly_seconds;
        self.factor_seconds += earlier.factor_seconds;
        self.factorizations += earlier.factorizations;
        self.solve_seconds += earlier.solve_seconds;
        self.cg_iterations += earlier.cg_iterations;
        self.shifted += earlier.shifted;
        self.projected += earlier.projected;
        self.corrections += earlier.corrections;
        self.correction_sweeps += earlier.correction_sweeps;
        self.extrapolations += earlier.extrapolations;
        self.extrapolation_halvings += earlier.extrapolation_halvings;
        self.rate_stops += earlier.rate_stops;
        self.curvature_moves += earlier.curvature_moves;
        self.eliminations += earlier.eliminations;
    }

    /// What the step left to converge [m/s]: the rate's estimate where the loop ended by it,
    /// else the last iteration's residual (NaN with none).
    pub fn final_residual(&self) -> f64 {
        self.estimate
            .unwrap_or_else(|| self.residuals.last().copied().unwrap_or(f64::NAN))
    }

    /// The error of a step that ran out of iterations with these statistics.
    pub(crate) fn not_converged(&self, tolerance: f64) -> StepError {
        StepError::NotConverged {
            iterations: self.iterations,
            residual: self.residuals.last().copied().unwrap_or(f64::NAN),
            tolerance,
        }
    }
}

/// Why a step failed. The state is left as it was before the step.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum StepError {
    /// The system is inconsistent (see [`SystemError`]).
    #[error(transparent)]
    System(#[from] SystemError),
    /// A NaN or infinity appeared.
    ///
    /// Explicit integration of a stiff system with too large a step.
    #[error(
        "non-finite values at iteration {iteration} (the step is unstable or the input is degenerate)"
    )]
    NonFinite {
        /// Newton iteration (0 for explicit).
        iteration: usize,
    },
    /// Newton hit its iteration limit.
    ///
    /// A tolerance of 1e-14 m/s cannot be met in f64.
    #[error(
        "Newton did not converge in {iterations} iterations (residual {residual:e} m/s, tolerance {tolerance:e})"
    )]
    NotConverged {
        /// Iterations done.
        iterations: usize,
        /// Last ‖Δx‖∞/h.
        residual: f64,
        /// The tolerance asked for.
        tolerance: f64,
    },
    /// Newton's steps became small, but the contacts' ADMM did not meet the contact laws to
    /// the tolerance within its iterations (the last Newton iteration's ADMM residuals).
    #[error(
        "the contacts did not converge: after {iterations} Newton iterations the step is {step:e} m/s, but the last ADMM ended {primal:e} m/s from the contact laws and still moving {dual:e} m/s (tolerance {tolerance:e}); {}",
        if dual < tolerance { "it stalled, so the laws cannot be met this step (contacts that contradict each other, or a collider stepping into the solid faster than the step lets it leave)" } else { "more contact_iterations may help" }
    )]
    ContactsNotConverged {
        /// Newton iterations done.
        iterations: usize,
        /// The last Newton step, ‖Δx‖∞/h [m/s].
        step: f64,
        /// The last ADMM's primal residual [m/s].
        primal: f64,
        /// The last ADMM's dual residual [m/s].
        dual: f64,
        /// The tolerance asked for.
        tolerance: f64,
    },
    /// A contact solve that may be retried smaller diverged: a Newton step grown past a large
    /// multiple of its first (or of the tolerance, if larger; the factor is `DIVERGED` in
    /// `integrator/contacts.rs`), after which the iterate is no longer near any answer; the
    /// caller retries the step smaller.
    #[error(
        "the contact solve diverged at Newton iteration {iteration}: a step of {step:e} m/s against {first:e} m/s at the first (or the tolerance)"
    )]
    Diverged {
        /// Newton iteration (0-based).
        iteration: usize,
        /// That iteration's step, ‖Δx‖∞/h [m/s].
        step: f64,
        /// The first iteration's step [m/s].
        first: f64,
    },
    /// The step would end with primitives of the solids passing through each other (found by
    /// continuous detection after the contacts' last re-solve): a smaller step is tried.
    #[error(
        "the step would end with {pairs} pair(s) of primitives passing through each other (continuous detection)"
    )]
    Intersecting {
        /// Pairs whose paths cross.
        pairs: usize,
    },
    /// The sparse Cholesky factorization failed (the matrix was not positive definite).
    #[error("sparse Cholesky failed: {0}")]
    Factorization(String),
    /// The system's matrix or its factor ([`Integrator::new_within`]), or a step's contacts,
    /// would not fit in the memory allowed; nothing large was allocated.
    ///
    /// `the Cholesky factor needs about 3.17 GiB, more than the 2.00 GiB available; use fewer
    /// vertices (a coarser mesh, fewer strands or segments)`
    #[error(
        "{what} needs about {need_gib:.2} GiB, more than the {limit_gib:.2} GiB available; {hint}"
    )]
    TooLarge {
        /// What would not fit.
        what: String,
        /// Estimated need [GiB].
        need_gib: f64,
        /// The limit [GiB].
        limit_gib: f64,
        /// What to change.
        hint: String,
    },
    /// A step's contact detection would hold more contacts, or candidate pairs of
    /// primitives, than the memory allowed lets it (a contact band wide against the scene's
    /// spacing): it stopped before allocating them.
    ///
    /// `the contacts of this step would outgrow the 1.50 GiB allowed for them (more than
    /// 393216 contacts); the widest contact band is 2 m, …`
    #[error(
        "the contacts of this step would outgrow the {limit_gib:.2} GiB allowed for them (more than {count} {what}); {hint}"
    )]
    ContactsTooMany {
        /// What was counted: "contacts" or "pairs of primitives within reach".
        what: &'static str,
        /// The most that fit.
        count: usize,
        /// The memory allowed for them [GiB].
        limit_gib: f64,
        /// What to change.
        hint: String,
    },
    /// The stop check ([`Integrator::set_stop`]) asked the step to end.
    #[error("stopped at Newton iteration {iteration}")]
    Interrupted {
        /// Newton iteration at which the step stopped (0-based).
        iteration: usize,
    },
}

/// What the caller of a failed step does next: the solver's answer (Houdini's solvers answer
/// success, repeat, substep or fail), so a caller acts on it instead of on a list of error
/// variants, and a new variant is classified where it is defined.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Next {
    /// A smaller step may succeed: the caller may retry the step in parts.
    RetrySmaller,
    /// No smaller step would help (the system is inconsistent, its memory would not fit):
    /// report it.
    Fail,
    /// The caller asked the step to stop: stop, keeping what was done.
    Stop,
}

impl StepError {
    /// What the caller does next (see [`Next`]).
    pub fn next(&self) -> Next {
        match self {
            StepError::NonFinite { .. }
            | StepError::NotConverged { .. }
            | StepError::ContactsNotConverged { .. }
            | StepError::Diverged { .. }
            | StepError::Intersecting { .. }
            | StepError::Factorization(_) => Next::RetrySmaller,
            StepError::System(_)
            | StepError::TooLarge { .. }
            | StepError::ContactsTooMany { .. } => Next::Fail,
            StepError::Interrupted { .. } => Next::Stop,
        }
    }

    /// A short name of the failure's kind, for counting retried steps by cause (the message,
    /// [`std::fmt::Display`], has the numbers).
    pub fn kind(&self) -> &'static str {
        match self {
            StepError::System(_) => "inconsistent system",
            StepError::NonFinite { .. } => "non-finite values",
            StepError::NotConverged { .. } => "Newton did not converge",
            StepError::ContactsNotConverged { .. } => "contacts did not converge",
            StepError::Diverged { .. } => "contact solve diverged",
            StepError::Intersecting { .. } => "primitives would pass through each other",
            StepError::Factorization(_) => "factorization failed",
            StepError::TooLarge { .. } => "too large",
            StepError::ContactsTooMany { .. } => "too many contacts",
            StepError::Interrupted { .. } => "stopped",
        }
    }
}

/// [`StepError::TooLarge`]'s advice where the system's vertices are what is large.
pub const FEWER_VERTICES: &str = "use fewer vertices (a coarser mesh, fewer strands or segments)";

/// [`StepError::TooLarge`] for `need` bytes of `what` against `limit` bytes.
pub fn too_large(
    what: impl Into<String>,
    need: u64,
    limit: u64,
    hint: impl Into<String>,
) -> StepError {
    const GIB: f64 = (1u64 << 30) as f64;
    StepError::TooLarge {
        what: what.into(),
        need_gib: need as f64 / GIB,
        limit_gib: limit as f64 / GIB,
        hint: hint.into(),
    }
}

/// Asked once per Newton iteration (and per explicit step): true when the step should end
/// with [`StepError::Interrupted`] (Ctrl-C, a time limit, a host's cancel).
pub type StopCheck = std::sync::Arc<dyn Fn() -> bool + Send + Sync>;

//! Time stepping: implicit Euler by Newton (exact Hessians where positive definite, projected
//! ones otherwise), its one-step linearization, and symplectic Euler for comparison.
//!
//! Implicit Euler is the minimizer of the incremental potential
//! `E(x) = Σᵢ mᵢ/(2h²)‖xᵢ − x̂ᵢ‖² + Σᵢ c mᵢ/(2h)‖xᵢ − x⁰ᵢ‖² + Σₑ Eₑ(x)`,
//! `x̂ = x⁰ + h v⁰ + h² (g + M⁻¹f)` (the damping term gives the force −c m v with v = (x − x⁰)/h),
//! plus, for drag towards a flow u, `Σᵢ (1/2h) rᵢᵀ Dᵢ rᵢ`, `rᵢ = xᵢ − x⁰ᵢ − h uᵢ` (force −D(v − u)).
//! Its Hessian, with element Hessians projected to PSD, is SPD whenever every free vertex has
//! mass, so each Newton direction descends and a backtracking line search on E makes the
//! iteration converge from any start. The exact Hessian converges faster (quadratically
//! where projection drops the negative stiffness of buckling cloth): it is used whenever its
//! Cholesky factorization succeeds, which proves it positive definite, so every direction
//! still descends (with the one-ring preconditioner, `one_ring.rs`, the factorization of a
//! sparser matrix below it gives that proof, and conjugate gradients the direction). The sparsity pattern (3×3 blocks between vertices that
//! share an element) and the symbolic Cholesky analysis are built once per system; each
//! iteration only refills values and refactors numerically, into buffers allocated once.
//!
//! The [`Integrator`] is one type in rooms, each a field with its own type: `lin`
//! (`LinearSystem`, `linear.rs`: pattern, slots, assembled values), `dirs` (the
//! factorization and the preconditioners), `work` (buffers), `sliders`, `hooks` (stop,
//! progress, memory limit) and `modes` (settings fixed at build). Its methods live by phase:
//! `build.rs` (pattern, slots, symbolic analysis), `assemble.rs` (objective, gradient,
//! Hessian), `direction.rs` (factorization, preconditioned CG), `newton.rs` (the steps and
//! the Newton loop), `contact_step.rs` and `admm.rs` (the contact step). A second step method
//! plugs in beside `newton.rs` (ARCHITECTURE.md). Its settings, statistics and errors are in
//! `settings.rs`.

mod admm;
mod analysis;
mod assemble;
mod build;
mod contact_step;
mod contacts;
mod correction;
mod curvature;
mod direction;
mod elimination;
mod factor;
mod linear;
mod newton;
mod one_ring;
mod order;
mod partition;
mod pool;
mod rate;
mod rigid;
mod sliding;
mod solve;
mod split;
mod tail;

use crate::energy::{Local, SharedHinges};
use crate::progress::Progress;
pub use crate::settings::{Method, Settings, StepError, StepStats, StopCheck};
use crate::system::{SolidSystem, State};
pub use contacts::{CONTACT_VERTICES, Contact, ContactSet, ContactStats};
use factor::Factor;
use linear::{LinearSystem, block_entry, value_index};
use nalgebra::{Matrix2, Vector3};
use pool::in_pool;
use std::cell::RefCell;
use std::sync::Arc;

/// The line search's element energies are computed in parallel from this many elements:
/// below it the fork–join costs more than it saves.
const PARALLEL_MIN: usize = 256;

thread_local! {
    /// Each thread's element buffer (73 kB: allocated once per thread, never per element).
    /// Boxed and zeroed on the heap: built by value, its initializer gives every call of
    /// `LOCAL.with` a 73 kB stack frame, probed page by page on every element, a cost that
    /// shows in a small sheet's short steps (`bench/peers`' squares measure it; figures in
    /// docs/history/issue-71-comments.md).
    static LOCAL: RefCell<Box<Local>> = RefCell::new(new_local());
}

/// A zeroed [`Local`] on the heap, never on the stack.
#[cold]
#[inline(never)]
fn new_local() -> Box<Local> {
    // SAFETY: `Local` is plain numbers (usize, f64 and arrays of f64), for which all-zero
    // bits are a valid value (0 and 0.0).
    unsafe { Box::<Local>::new_zeroed().assume_init() }
}

const NONE: u32 = u32::MAX;

/// Which element Hessians assembly uses.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Hessians {
    /// Every one projected to PSD: the sum is SPD whenever every free vertex has mass.
    Projected,
    /// [`crate::energy::Element::eval_first`]: exact where cheap; the sum may be indefinite.
    First,
    /// [`crate::energy::Element::eval_contact`] with each element's `budget` entry
    /// ([`Integrator::fill_budget`]): a contact step's model (exact for rods, membranes'
    /// negative curvature bounded).
    Contact,
}

/// Inertia added, as a fraction of mᵢ/h² per vertex, the first time an exact Hessian is not
/// positive definite; each retry adds 5× the last (in all 0.01, 0.06, 0.31, 1.56),
/// [`SHIFT_TRIES`] tries (one more after a restart, [`shift_ladder`]), before the projected
/// Hessians are used instead. Starting this small keeps the shifted direction near the exact
/// Newton step, so buckling cloth keeps its fast convergence; going straight to the projected
/// Hessians costs iterations, since projected steps stagnate where the cloth buckles (the
/// hanging cloth's Newton counts measure it; figures in docs/history/issue-71-comments.md).
const FIRST_SHIFT: f64 = 0.01;
const SHIFT_TRIES: usize = 4;

/// Later in the same step, the tries start at this fraction of the inertia that last made the
/// Hessian positive definite (never below [`FIRST_SHIFT`]): an iterate near the last needs
/// about as much, so starting near it skips tries that would fail, at about the same Newton
/// iterations. Carried from one step to the next it would cost iterations (the shifted
/// directions are shorter), and a step would depend on the steps before it. A restart that
/// fails climbs back to that last inertia before growing 5× a try ([`shift_ladder`]). The
/// examples' inertia tries and iterations (`--stats-json`) and `bench/peers`' hanging square
/// measure it; figures in docs/history/issue-71-comments.md.
const SHIFT_RESTART: f64 = 0.5;

/// The inertia each try of one iteration adds (fractions of mᵢ/h², summed over the tries),
/// given `last`, the total that last made the exact Hessian positive definite in this step
/// (0: none yet). From nothing: 0.01, then 5× the last increment ([`SHIFT_TRIES`] tries:
/// totals 0.01, 0.06, 0.31, 1.56). From `last` = L above 0.01: its [`SHIFT_RESTART`]
/// fraction first (at least 0.01), then back to L itself, then increments growing 5× from
/// the larger of the first two (one try more: totals ½L, L, 3.5L, 16L, 78.5L for L ≥ 0.02;
/// 0.01, L, L + 0.05, L + 0.30, L + 1.55 below, so the ceiling never falls under the fresh
/// ladder's). Growing 5× straight from ½L (totals ½L, 3L, 15.5L, 78L) would leave a failed
/// restart 3× above the inertia that had just worked: where a sheet buckles the totals then
/// rise and fall from iteration to iteration, each direction too short, and the step can end
/// short of its converged answer. Climbing back to L keeps the shift near what worked, even
/// where that costs a buckling step iterations (`bench/sheet_graph.py`'s sheets and the
/// examples' counts measure it; figures in docs/history/issue-71-comments.md).
fn shift_ladder(last: f64) -> impl Iterator<Item = f64> {
    let start = (SHIFT_RESTART * last).max(FIRST_SHIFT);
    let back = (start < last).then_some(last - start);
    let tries = SHIFT_TRIES + usize::from(back.is_some());
    let mut next = start;
    (0..tries).map(move |k| {
        let inc = next;
        next = match (k, back) {
            (0, Some(b)) => b,
            // After the climb back: 5× the larger step, not 5× a climb of less than 0.01.
            (1, Some(b)) => 5.0 * b.max(start),
            _ => 5.0 * inc,
        };
        inc
    })
}

/// The fraction α of each vertex's inertia mᵢ/h² that a contact step's membranes may spend
/// on their negative curvature ([`Integrator::fill_budget`]; the rest keeps the model
/// positive definite). Keeping most of the exact Hessian's negative curvature brings the
/// contact step's Newton model near the true one where cloth is compressed, so it takes
/// fewer iterations and retries fewer substeps than projected membranes (α = 0), while the
/// inertia left keeps ADMM's model convex. A smaller α gains less; one closer to 1 gains
/// nothing more. `weft bench contact` and `bench/ensemble.py` on the contact examples
/// measure it; figures in docs/history/issue-71-comments.md.
const CONTACT_CURVATURE: f64 = 0.9;

/// What is minimized: the incremental potential of a time step, or the static potential.
#[derive(Clone, Copy)]
enum Mode {
    Dynamic { h: f64 },
    Static,
}

/// Where a step starts: x⁰, each held vertex's target, and the caller's guess of the end
/// positions (checked: right length, finite).
#[derive(Clone, Copy)]
struct Start<'a> {
    x0: &'a [Vector3<f64>],
    target: &'a dyn Fn(usize) -> Vector3<f64>,
    guess: Option<&'a [Vector3<f64>]>,
}

/// The direction solver's room: H's factorization and the preconditioners CG may use in
/// its place, and which one this step and this iteration use.
struct Directions {
    /// The system matrix's factorization.
    factor: Factor,
    /// Where the pattern holds the two-ring of wide elements (shell bending) and a factor of
    /// its one-ring costs much less: that sparser matrix, preconditioning conjugate
    /// gradients on H in the steps' Newton iterations (`one_ring.rs`). Built at the first
    /// step that uses it; a contact step's ADMM never does (it factors H; a contact step
    /// without contacts is a contact-free step, and a rebuild for contacts' blocks starts a
    /// new integrator without it).
    one_ring: Option<one_ring::OneRing>,
    /// Where H's factorization is large (`one_ring::SINGLE_MIN_FLOPS`): H's own pattern
    /// factored in single precision, preconditioning CG as the one-ring's factor does, for
    /// the steps in which that declines (bending that outweighs the inertia) or where there
    /// is none.
    single: Option<one_ring::OneRing>,
    /// Whether `one_ring` and `single` were built (or found not to pay) for this pattern.
    one_ring_tried: bool,
    /// What the current Newton iteration's directions go through: set by `minimize` for a
    /// step, turned to [`Route::Factor`] for the rest of it where a preconditioner fails or
    /// declines, and from the one-ring's to the single-precision one where that declines.
    route: Route,
}

/// The direction solvers that exist: H's own factorization, or conjugate gradients
/// preconditioned by one of the two cheaper factors (`one_ring.rs`).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Route {
    /// H's factorization (`factor.rs`): every contact step, static solve and linearized step.
    Factor,
    /// CG preconditioned by the factor of H's one-ring (`Directions::one_ring`).
    OneRing,
    /// CG preconditioned by H's pattern factored in single precision (`Directions::single`).
    Single,
}

impl Directions {
    /// The preconditioner the Newton directions go through on `route`, if it exists.
    fn preconditioner(&mut self) -> Option<&mut one_ring::OneRing> {
        match self.route {
            Route::Factor => None,
            Route::OneRing => self.one_ring.as_mut(),
            Route::Single => self.single.as_mut(),
        }
    }
}

/// Work buffers of the Newton loop and its searches, sized at build: a step allocates none.
struct Work {
    grad: Vec<f64>,
    dir: Vec<f64>,
    x_hat: Vec<Vector3<f64>>,
    x_trial: Vec<Vector3<f64>>,
    /// The second-order correction's trial positions.
    x_soc: Vec<Vector3<f64>>,
    /// Negative curvature's vector, work vector and inertia diagonal (`curvature.rs`).
    curv_v: Vec<f64>,
    curv_w: Vec<f64>,
    curv_d: Vec<f64>,
    local: Local,
    /// Per element scratch (energies, gradient magnitudes), summed in element order so every
    /// total is bit-identical at any thread count.
    per_element: RefCell<Vec<f64>>,
}

/// Sliders' state at the last assembly (`sliding.rs`).
struct Sliders {
    /// Per free vertex: its slider's index in the system, or NONE (`sliding.rs`).
    slide_of: Vec<u32>,
    /// Per slider: its projector at the last assembly, and its diagonal's mean before it.
    slide_proj: Vec<nalgebra::Matrix3<f64>>,
    slide_scale: Vec<f64>,
    /// Per slider: the normal force its friction reads at the last assembly [N].
    slide_normal: Vec<f64>,
    /// Per slider: the force its target supplies, as the Newton model predicts it
    /// (`sliding.rs`, `SlideForces`).
    slide_forces: sliding::SlideForces,
}

/// What the caller hands in: the stop check, the progress line, the memory limit.
struct Hooks {
    stop: Option<StopCheck>,
    /// Where the steps are, for a progress line (`progress.rs`); written, never read.
    progress: Option<Arc<Progress>>,
    /// The memory limit the pattern was built within (kept for rebuilds).
    max_bytes: Option<u64>,
}

/// Settings fixed at build (tests change them to compare variants).
struct Modes {
    /// Never split (tests).
    whole_only: bool,
    /// Most low-rank columns a contact step adds to a kept factor for contacts that rejoin
    /// its split (`contacts.rs`, `Joined`; 0: refactorize at every rejoin, as tests compare).
    joined_max: usize,
    /// Whether a contact step sums a geometric tail of its full steps (`tail.rs`): systems
    /// with membranes (whose clamped curvature makes the tails) and no rods. Rods' exact
    /// Hessians make none; their tails are crawls (hair sliding over hair, steps falling
    /// slowly an iteration), and summing those lets strands pass through strands more often
    /// and can fail a run (`bench/ensemble.py` on hair_pile measures it; figures in
    /// docs/history/issue-71-comments.md). Tests set it to compare.
    tails: bool,
}

/// A stepper for one system: owns the sparsity pattern, the symbolic factorization and every
/// work buffer, so stepping allocates nothing per iteration.
pub struct Integrator {
    /// The pattern, the slots and the assembled values ([`LinearSystem`]).
    lin: LinearSystem,
    /// The factorization and the preconditioners ([`Directions`]).
    dirs: Directions,
    /// Work buffers ([`Work`]).
    work: Work,
    /// Sliders' state ([`Sliders`]).
    sliders: Sliders,
    /// The caller's stop check, progress line and memory limit ([`Hooks`]).
    hooks: Hooks,
    /// Settings fixed at build ([`Modes`]).
    modes: Modes,
    /// The rods' second-order correction (their segments and its scratch).
    correction: correction::LengthCorrection,
    /// The lagging vertices' local solves (`elimination.rs`): adjacency built on first use.
    elimination: elimination::Elimination,
    /// Per element: the negative curvature its contact-step Hessian may keep
    /// ([`Integrator::fill_budget`]), and the step and fraction it was filled for.
    budget: Vec<f64>,
    budget_for: (f64, f64),
    /// The midedge bending elements' hinges, each computed once an evaluation instead of
    /// once from each side (`SharedHinges`), and those elements' range of element indices.
    hinges: Option<RefCell<SharedHinges>>,
    midedges: std::ops::Range<usize>,
    /// Σ |gradient entries| of every term at the last assembly: with the size of the
    /// positions it bounds the floating-point resolution of the objective.
    force_scale: f64,
    /// Rigid groups: their nodes, members and Jacobians' data (`rigid.rs`).
    groups: rigid::Groups,
    /// Per membrane (the first elements), the stress whose tension its Hessian's geometric
    /// term reads in a contact-free Newton step's first tries: the mixed form's carried
    /// stress (`Membrane::eval_carried`), started at each step from the stress at x⁰ and
    /// moved by each accepted step's linear prediction; in a contact step, the stress at x⁰
    /// for its first model's assembly only (`Membrane::eval_contact_carried`). Empty
    /// otherwise.
    carried: Vec<Matrix2<f64>>,
}

impl Integrator {
    /// Sets (or clears) the check asked once per Newton iteration; when it answers true the
    /// step ends with [`StepError::Interrupted`] and the state is left as it was.
    pub fn set_stop(&mut self, stop: Option<StopCheck>) {
        self.hooks.stop = stop;
    }

    /// Sets (or clears) where the steps store their progress for a progress line.
    pub fn set_progress(&mut self, progress: Option<Arc<Progress>>) {
        self.hooks.progress = progress;
    }

    /// Says how much more the process may allocate now (`available` bytes, as measured by its
    /// caller): the limit the later factors are built within (a rebuild for contacts, the
    /// preconditioners) becomes that plus what this integrator already holds. A limit set
    /// once at the start would not see what the process allocated since (the frames kept,
    /// the files written), so under a tight `ulimit -v` a factor built within it could still
    /// fail to allocate (weft-cli's `tests/memory.rs` runs such ceilings). Without a limit
    /// (`new`), none is set.
    pub fn set_available(&mut self, available: u64) {
        if self.hooks.max_bytes.is_some() {
            self.hooks.max_bytes = Some(available.saturating_add(self.held_bytes()));
        }
    }

    /// Takes `old`'s stop check and progress (an integrator built anew for another structure
    /// answers the same stop and reports to the same line).
    pub fn keep_hooks(&mut self, old: Integrator) {
        self.hooks.stop = old.hooks.stop;
        self.hooks.progress = old.hooks.progress;
    }

    /// Where the steps store their progress, if anywhere.
    pub fn progress(&self) -> Option<&Arc<Progress>> {
        self.hooks.progress.as_ref()
    }

    /// [`Self::step`] with Newton starting from `guess` (end-of-step positions, e.g. the
    /// last coupling iteration's) instead of x⁰ + h v⁰. The answer is the same minimizer to
    /// the tolerance; a good guess needs fewer iterations. Pinned vertices still go to their
    /// targets; a guess of the wrong length, or not finite, is ignored.
    ///
    /// The one place a step chooses its method: each method's step lives in its own file
    /// (`newton.rs`: implicit, static and explicit steps), so another plugs in here.
    pub fn step_from(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        guess: Option<&[Vector3<f64>]>,
        pinned_to: Option<&[Vector3<f64>]>,
        h: f64,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        sys.check(state)?;
        let guess = guess.filter(|g| {
            g.len() == state.x.len() && g.iter().all(|p| p.iter().all(|c| c.is_finite()))
        });
        let x0 = state.x.clone();
        let target = |i: usize| pinned_to.map_or(x0[i], |p| p[i]);
        let start = Start {
            x0: &x0,
            target: &target,
            guess,
        };
        match settings.method {
            Method::Explicit => self.explicit_step(sys, state, start, h),
            Method::Static => self.static_step(sys, state, start, settings),
            Method::Newton | Method::ProjectedNewton | Method::Linearized => {
                self.implicit_step(sys, state, start, h, settings)
            }
        }
    }

    /// [`Integrator::step`] with `set.contacts`: implicit Euler whose end-of-step velocities
    /// obey Signorini–Coulomb at every contact. ADMM stops when the split's primal and dual
    /// residuals are below `settings.tolerance` [m/s], within `set.max_admm` iterations a
    /// Newton iteration; each Newton update is line-searched on the primal objective. With
    /// no contacts, a Newton method's step is [`Integrator::step_from`]'s (from the guess).
    ///
    /// Every method's contact step is Newton's (`contact_step.rs`) today; a method with its
    /// own takes its arm here.
    pub fn step_contacts(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        pinned_to: Option<&[Vector3<f64>]>,
        h: f64,
        settings: &Settings,
        set: ContactSet<'_>,
    ) -> Result<(StepStats, ContactStats), StepError> {
        match settings.method {
            Method::Explicit
            | Method::Linearized
            | Method::Newton
            | Method::ProjectedNewton
            | Method::Static => {
                // On a worker of the thread pool, for the assembly's fork–joins (`in_pool`).
                in_pool(self.threaded(), || {
                    self.step_contacts_here(sys, state, pinned_to, h, settings, set)
                })
            }
        }
    }

    /// Stores Newton iteration `iteration`'s (1-based) step [m/s] for the progress line.
    fn report_newton(&self, iteration: usize, step: f64) {
        if let Some(p) = &self.hooks.progress {
            p.newton(iteration, step);
        }
    }

    fn should_stop(&self) -> bool {
        self.hooks.stop.as_ref().is_some_and(|s| s())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The inertia ladder's totals: 5× steps from nothing; from a last shift L, ½L (at least
    /// the first shift), then L again, then increments 5× the larger of the first two, growing
    /// 5× a try.
    #[test]
    fn the_inertia_ladder_climbs_back_to_the_last_shift_before_growing() {
        let totals = |last: f64| -> Vec<f64> {
            shift_ladder(last)
                .scan(0.0, |t, k| {
                    *t += k;
                    Some(*t)
                })
                .collect()
        };
        let close = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-12 * y)
        };
        let fresh = totals(0.0);
        assert!(close(&fresh, &[0.01, 0.06, 0.31, 1.56]), "{fresh:?}");
        let restart = totals(1.56);
        let want: Vec<f64> = [0.5, 1.0, 3.5, 16.0, 78.5]
            .iter()
            .map(|f| f * 1.56)
            .collect();
        assert!(close(&restart, &want), "{restart:?}");
        // ½L below the first shift: from the first shift, back to L, then 5× the larger
        // of the two steps (the ceiling no lower than the fresh ladder's).
        let low = totals(0.015);
        assert!(close(&low, &[0.01, 0.015, 0.065, 0.315, 1.565]), "{low:?}");
        for l in [0.0101, 0.013125, 0.019, 0.02, 0.5, 3.0] {
            let t = totals(l);
            assert!(t.windows(2).all(|w| w[1] > w[0]), "{l}: {t:?}");
            assert!(*t.last().unwrap() >= 1.56, "{l}: {t:?}");
        }
        // L at the first shift: nothing to climb back to.
        assert!(close(&totals(0.01), &fresh));
    }

    /// One memory limit holds for H's factor and its preconditioners together: with room for
    /// H's factor and half its single-precision twin, the twin (which alone would fit) is
    /// not built and the step factors H instead; unlimited, the twin is built. Both steps
    /// converge.
    #[test]
    fn the_preconditioners_share_the_memory_limit_with_h() {
        // 48² vertices: H's split factorization costs 1.57e8 flops, above the twin's 1e8.
        let (sys, state) = order::tests::shell_sheet(48, 1e-3);
        let settings = Settings::default();
        let h = 1.0 / 24.0;
        let mut free = Integrator::new(&sys).unwrap();
        assert!(
            free.dirs.factor.flops() >= one_ring::SINGLE_MIN_FLOPS,
            "{:e}",
            free.dirs.factor.flops()
        );
        let mut s1 = state.clone();
        free.step(&sys, &mut s1, None, h, &settings).unwrap();
        let twin = free
            .dirs
            .single
            .as_ref()
            .expect("unlimited: the twin is built")
            .bytes();
        let limit = free.dirs.factor.bytes() + twin / 2;
        // Checked each against the whole limit, H's factor and the twin would both fit.
        assert!(twin <= limit);
        // Set after building: the pattern's own check (a bound from the stencils' pairs, 47 MB
        // here) is above this small system's factors (H's 25 MB, the one-ring's 11, the twin's
        // 10), which at 317² dominate instead.
        let mut tight = Integrator::new(&sys).unwrap();
        tight.hooks.max_bytes = Some(limit);
        let mut s2 = state.clone();
        tight.step(&sys, &mut s2, None, h, &settings).unwrap();
        assert!(tight.dirs.single.is_none());
        let used =
            tight.dirs.factor.bytes() + tight.dirs.one_ring.as_ref().map_or(0, |o| o.bytes());
        assert!(used <= limit, "{used} > {limit}");
    }

    /// A matrix with a NaN entry is reported as such, at once, not after eight diagonal
    /// shifts whose scale the NaN hid (the message read "even with a diagonal shift of
    /// 2.2e-304").
    #[test]
    fn a_non_finite_matrix_is_reported_not_shifted() {
        let (sys, state) = order::tests::shell_sheet(4, 1e-3);
        let mut it = Integrator::new(&sys).unwrap();
        let h = 1.0 / 48.0;
        it.work.x_hat = state.x.clone();
        it.assemble_with(
            &sys,
            &state.x,
            &state.x,
            Mode::Dynamic { h },
            Hessians::Projected,
        );
        let mut stats = StepStats::default();
        assert!(it.factor(&mut stats, 0.0).is_ok());
        it.lin.values[0] = f64::NAN;
        let before = stats.factorizations;
        let err = it.factor(&mut stats, 0.0).unwrap_err().to_string();
        assert!(err.contains("non-finite"), "{err}");
        assert_eq!(stats.factorizations - before, 1);
    }

    /// The assembled matrix (elements scattered below the diagonal, mirrored above it) is
    /// exactly symmetric and equals the sum of every element's own Hessian and the inertia,
    /// entry by entry (to rounding: the sums run in another order), on a bent, held sheet
    /// with shell bending, for both kinds of element Hessians.
    #[test]
    fn the_mirrored_matrix_is_the_sum_of_the_element_hessians() {
        let (sys, state) = order::tests::shell_sheet(6, 1e-3);
        // Bent and squeezed, so the exact Hessians differ from the projected ones.
        let x: Vec<Vector3<f64>> = state
            .x
            .iter()
            .map(|p| Vector3::new(0.9 * p.x, p.y, 0.2 * (3.0 * p.x).sin() * p.y))
            .collect();
        let h = 1.0 / 48.0;
        let mut it = Integrator::new(&sys).unwrap();
        let dofs = 3 * it.lin.n_free;
        it.fill_budget(&sys, h, CONTACT_CURVATURE);
        for hessians in [Hessians::Projected, Hessians::First, Hessians::Contact] {
            it.work.x_hat = x.clone();
            it.assemble_with(&sys, &x, &x, Mode::Dynamic { h }, hessians);
            let mut dense = vec![0.0; dofs * dofs];
            for (i, &f) in it.lin.free_of.iter().enumerate() {
                if f != NONE {
                    for c in 0..3 {
                        let d = 3 * f as usize + c;
                        dense[d * dofs + d] += sys.mass[i] / (h * h);
                    }
                }
            }
            let mut local = Local::default();
            let mut ei = 0;
            sys.elements.for_each(|e| {
                match hessians {
                    Hessians::Projected => e.eval(&x, true, &mut local),
                    Hessians::First => e.eval_first(&x, &mut local),
                    Hessians::Contact => e.eval_contact(&x, it.budget[ei], &mut local),
                }
                ei += 1;
                let v = e.vertices();
                for (a, &va) in v.iter().enumerate() {
                    for (b, &vb) in v.iter().enumerate() {
                        let (fa, fb) = (it.lin.free_of[va as usize], it.lin.free_of[vb as usize]);
                        if fa == NONE || fb == NONE {
                            continue;
                        }
                        for rr in 0..3 {
                            for cc in 0..3 {
                                let (r, c) = (3 * fa as usize + rr, 3 * fb as usize + cc);
                                dense[c * dofs + r] += local.hess[3 * b + cc][3 * a + rr];
                            }
                        }
                    }
                }
            });
            let scale = dense.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for c in 0..dofs {
                for p in it.lin.col_ptr[c]..it.lin.col_ptr[c + 1] {
                    let r = it.lin.row_idx[p];
                    let v = it.lin.values[value_index(&it.lin.col_ptr, p, c)];
                    let t = it.lin.values[value_index(
                        &it.lin.col_ptr,
                        it.lin.col_ptr[r]
                            + (it.lin.row_idx[it.lin.col_ptr[r]..it.lin.col_ptr[r + 1]])
                                .binary_search(&c)
                                .unwrap(),
                        r,
                    )];
                    assert_eq!(v.to_bits(), t.to_bits(), "({r}, {c}) not symmetric");
                    assert!(
                        (v - dense[c * dofs + r]).abs() <= 1e-12 * scale,
                        "({r}, {c}): {v} against {}",
                        dense[c * dofs + r]
                    );
                }
            }
        }
    }
}

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
//! Why one file of about 1500 lines: it is one type, the [`Integrator`], whose pattern, slots,
//! assembly tree and factor buffers are built together in `new_within` and used together by
//! assembly and the Newton loop; splitting it would spread those invariants over files. Its
//! settings, statistics and errors are in `settings.rs`.

mod analysis;
mod contacts;
mod correction;
mod curvature;
mod elimination;
mod factor;
mod linear;
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
use crate::system::{SolidSystem, State, SystemError};
pub use contacts::{CONTACT_VERTICES, Contact, ContactSet, ContactStats};
use factor::Factor;
use linear::{LinearSystem, Shared, block_entry, value_index};
use nalgebra::{Matrix2, Matrix3, Vector3};
use pool::in_pool;
use rayon::prelude::*;
use std::cell::RefCell;
use std::sync::Arc;
use std::time::Instant;

/// The line search's element energies are computed in parallel from this many elements:
/// below it the fork–join costs more than it saves.
const PARALLEL_MIN: usize = 256;

thread_local! {
    /// Each thread's element buffer (73 kB: allocated once per thread, never per element).
    /// Boxed and zeroed on the heap: built by value, its initializer gave every call of
    /// `LOCAL.with` a 73 kB stack frame, probed page by page on every element (7 % of a
    /// 25-vertex sheet's step).
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
/// Hessians are used instead. Measured on the hanging cloth (24 frames): from 0.01, 8.8
/// Newton iterations a step (at most 17); going straight to the projected Hessians, 9.4 (at
/// most 49: projected steps stagnate where the cloth buckles).
const FIRST_SHIFT: f64 = 0.01;
const SHIFT_TRIES: usize = 4;

/// Later in the same step, the tries start at this fraction of the inertia that last made the
/// Hessian positive definite (never below [`FIRST_SHIFT`]): an iterate near the last needs
/// about as much. Measured (24 frames; iterations, inertia tries, falls back to projection):
/// cloth_hang 428, 304, 11 → 429, 159, 6 (farm-bench wall A/B 0.93); curtain_rail 319, 358,
/// 17 → 313, 327, 14; cloth_release 259, 141, 14 → 256, 100, 14; the hanging square of
/// `bench/peers` at 16², 874, 677, 146 → 881, 621, 126. Carried from one step to the next
/// it cost the square 23–50 % more iterations at fractions 0.2–0.5 and cloth_hang 77 % at 1
/// (the shifted directions are shorter), and a step would depend on the steps before it.
/// A restart that fails climbs back to that last inertia before growing 5× a try
/// ([`shift_ladder`]).
const SHIFT_RESTART: f64 = 0.5;

/// The inertia each try of one iteration adds (fractions of mᵢ/h², summed over the tries),
/// given `last`, the total that last made the exact Hessian positive definite in this step
/// (0: none yet). From nothing: 0.01, then 5× the last increment ([`SHIFT_TRIES`] tries:
/// totals 0.01, 0.06, 0.31, 1.56). From `last` = L above 0.01: its [`SHIFT_RESTART`]
/// fraction first (at least 0.01), then back to L itself, then increments growing 5× from
/// the larger of the first two (one try more: totals ½L, L, 3.5L, 16L, 78.5L for L ≥ 0.02;
/// 0.01, L, L + 0.05, L + 0.30, L + 1.55 below, so the ceiling never falls under the fresh
/// ladder's). Growing 5× straight from ½L (totals ½L, 3L, 15.5L, 78L) left a failed restart
/// 3× above the inertia that had just worked: where a sheet buckles (the 128² sheet of
/// `bench/sheet_graph.py`, its fourth frame) the totals then rose and fell 4.7, 2.3, 7.0,
/// 3.5, 1.8, 5.3, … m/h² over 18 iterations, each direction too short. Measured (Newton
/// iterations a step, factorizations): that sheet 6.83, 67 → 6.00, 58 over 6 frames;
/// cloth_hang 6.17, 376 → 6.06, 370; cloth_release 3.96, 299 → 3.83, 292; curtain_rail
/// and buttoned_panel unchanged; the 32² sheet 5.33 → 7.00, where the ratchet's large shifts
/// had ended the buckling step 0.79 mm short of its converged answer (now 4.3e-7 m).
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
/// positive definite). Measured (24 frames; Newton iterations a step, retried substeps,
/// wall), projected membranes (α = 0) → α = 0.9: cloth_drape 14.25 → 12.58, 0 → 0,
/// farm-bench wall A/B 0.93; cloth_pile 11.71 → 10.58, 0 → 0, A/B 0.93; hair_pile over 8
/// rounding-level perturbations (`bench/ensemble.py`) 10.36 → 9.60, 34 → 25 retried, mean
/// wall 9.87 → 9.59 s (BENCHMARKS.md, twenty-fourth session).
/// α = 0.5 gained half as much; 0.99 no more than 0.9 (cloth_drape 12.40, cloth_pile 10.88).
const CONTACT_CURVATURE: f64 = 0.9;

/// Where the first `vertices` free nodes sit (`free_of`: each vertex's node), from the
/// system's layout; empty without one. For dissection and the split.
fn free_layout(sys: &SolidSystem, free_of: &[u32], vertices: usize) -> Vec<Vector3<f64>> {
    if sys.layout.len() != free_of.len() {
        return Vec::new();
    }
    let mut at = vec![Vector3::zeros(); vertices];
    for (v, &f) in free_of.iter().enumerate() {
        if let Some(p) = at.get_mut(f as usize) {
            *p = sys.layout[v];
        }
    }
    at
}

/// What is minimized: the incremental potential of a time step, or the static potential.
#[derive(Clone, Copy)]
enum Mode {
    Dynamic { h: f64 },
    Static,
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
    /// Whether this step's preconditioned directions go through `single`, not `one_ring`.
    pcg_single: bool,
    /// Whether the current Newton iteration's directions go through a preconditioner
    /// (`one_ring`, or `single` where `pcg_single` is set).
    pcg: bool,
}

impl Directions {
    /// The preconditioner the Newton directions go through while `pcg` is set: the
    /// one-ring's, or the single-precision one (`pcg_single`).
    fn preconditioner(&mut self) -> Option<&mut one_ring::OneRing> {
        match (self.pcg, self.pcg_single) {
            (false, _) => None,
            (true, false) => self.one_ring.as_mut(),
            (true, true) => self.single.as_mut(),
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
    /// 0.3 % an iteration), and summing those in hair_pile (hair with a cloth) gave 5–17
    /// pass-throughs and one failed run in 8 where the plain steps gave 1 and none.
    /// Tests set it to compare.
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
    /// the files written): measured under a tight `ulimit -v`, the one-ring's split of a 100²
    /// sheet failed to allocate at the first step with the limit of the setup frame. Without
    /// a limit (`new`), none is set.
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

    /// Stores Newton iteration `iteration`'s (1-based) step [m/s] for the progress line.
    fn report_newton(&self, iteration: usize, step: f64) {
        if let Some(p) = &self.hooks.progress {
            p.newton(iteration, step);
        }
    }

    fn should_stop(&self) -> bool {
        self.hooks.stop.as_ref().is_some_and(|s| s())
    }

    /// Builds the pattern and symbolic factorization for `sys`.
    pub fn new(sys: &SolidSystem) -> Result<Self, StepError> {
        Self::new_within(sys, None)
    }

    /// [`Self::new`], refusing (with [`StepError::TooLarge`], before allocating them) a
    /// pattern or a Cholesky factor larger than `max_bytes`: the pattern is bounded by the
    /// sum over elements of (stencil size)², the factor's size is exact once the symbolic
    /// analysis has run.
    pub fn new_within(sys: &SolidSystem, max_bytes: Option<u64>) -> Result<Self, StepError> {
        Self::build(sys, (max_bytes, max_bytes), Vec::new(), false)
    }

    /// [`Self::new`] without the two-halves split: every factorization whole (tests compare
    /// the two).
    #[cfg(test)]
    pub(crate) fn new_whole(sys: &SolidSystem) -> Result<Self, StepError> {
        Self::build(sys, (None, None), Vec::new(), true)
    }

    /// Makes the pattern the elements' plus exactly the blocks of `extra` (pairs of free
    /// vertex indices, sorted, each lower first): contacts between vertices that share no
    /// element need them. Rebuilds the pattern, ordering and symbolic factorization only
    /// when `extra` differs from the current one, so the pattern is a function of the system
    /// and the step's contacts alone, never of the history (a resumed run factors the same
    /// matrices).
    /// Returns whether it rebuilt.
    fn ensure_extra(
        &mut self,
        sys: &SolidSystem,
        extra: Vec<(u32, u32)>,
    ) -> Result<bool, StepError> {
        if extra == self.lin.extra {
            return Ok(false);
        }
        let (stop, progress) = (self.hooks.stop.take(), self.hooks.progress.take());
        let (joined_max, tails) = (self.modes.joined_max, self.modes.tails);
        // The new pattern and factors are built while these are held.
        let room = self
            .hooks
            .max_bytes
            .map(|limit| limit.saturating_sub(self.held_bytes()));
        *self = Self::build(
            sys,
            (self.hooks.max_bytes, room),
            extra,
            self.modes.whole_only,
        )?;
        self.hooks.stop = stop;
        self.hooks.progress = progress;
        self.modes.joined_max = joined_max;
        self.modes.tails = tails;
        Ok(true)
    }

    /// The memory the pattern's buffers and the factors hold, as estimated against the limit
    /// when they were built.
    fn held_bytes(&self) -> u64 {
        let pre = [self.dirs.one_ring.as_ref(), self.dirs.single.as_ref()];
        pre.into_iter()
            .flatten()
            .fold(self.dirs.factor.bytes(), |b, o| b.saturating_add(o.bytes()))
    }

    /// The integrator for `sys` with the pattern's `extra` blocks: `max_bytes` the limit it
    /// keeps for the factors it builds later, `room` what this build may take.
    fn build(
        sys: &SolidSystem,
        (max_bytes, room): (Option<u64>, Option<u64>),
        extra: Vec<(u32, u32)>,
        whole_only: bool,
    ) -> Result<Self, StepError> {
        // What the steps run on, made here (a solver node's setup frame) rather than in the
        // first step: rayon's global pool starts its workers on first use, and this thread's
        // element scratch is zeroed page by page on first touch. Measured on the 4² square of
        // `bench/peers` (linearized, one substep): its first step 280–520 µs → about 145 µs,
        // its later ones about 40 µs.
        let _ = rayon::current_num_threads();
        LOCAL.with(|_| ());
        if let Some(limit) = room {
            // The contacts' blocks between solids, in both triangles.
            let mut pairs = 2 * extra.len() as u64;
            sys.elements.for_each(|e| {
                let k = e.vertices().len() as u64;
                pairs = pairs.saturating_add(k * k);
            });
            // Per stencil pair at most: a neighbour entry and a slot (u32 each), and a 3×3
            // block of row indices and values (8 bytes each); plus per vertex its buffers.
            let need = pairs
                .saturating_mul(8 + 9 * 16)
                .saturating_add((sys.mass.len() as u64).saturating_mul(256));
            if need > limit {
                return Err(crate::settings::too_large(
                    "the system matrix",
                    need,
                    limit,
                    crate::settings::FEWER_VERTICES,
                ));
            }
        }
        let n = sys.mass.len();
        let mut free_of = vec![NONE; n];
        let member = {
            let mut m = vec![false; n];
            for g in &sys.rigid {
                for &v in &g.vertices {
                    if let Some(s) = m.get_mut(v as usize) {
                        *s = true;
                    }
                }
            }
            m
        };
        let mut n_free = 0usize;
        for (i, f) in free_of.iter_mut().enumerate() {
            if !sys.pinned.get(i).copied().unwrap_or(false) && !member[i] {
                *f = n_free as u32;
                n_free += 1;
            }
        }
        let n_vertices = n_free;
        // Rigid groups: two nodes each after the free vertices (`rigid.rs`).
        let mut groups = rigid::Groups::new(sys, &mut free_of, n_free);
        n_free += 2 * sys.rigid.len();
        // The nodes a vertex moves with: its own, its group's two, or none.
        let nodes_of = |v: u32| -> ([u32; 2], usize) {
            let f = free_of.get(v as usize).copied().unwrap_or(NONE);
            if f != NONE {
                return ([f, NONE], 1);
            }
            match groups.of.get(v as usize) {
                Some(&g) if g != NONE => {
                    let t = groups.node[g as usize];
                    ([t, t + 1], 2)
                }
                _ => ([NONE; 2], 0),
            }
        };
        // Block neighbours of each node (itself included), sorted.
        let mut nbrs: Vec<Vec<u32>> = (0..n_free as u32).map(|j| vec![j]).collect();
        for &t in &groups.node {
            nbrs[t as usize].push(t + 1);
            nbrs[t as usize + 1].push(t);
        }
        sys.elements.for_each(|e| {
            for &a in e.vertices() {
                let (na, ka) = nodes_of(a);
                for &b in e.vertices() {
                    let (nb, kb) = nodes_of(b);
                    for &fa in &na[..ka] {
                        for &fb in &nb[..kb] {
                            nbrs[fb as usize].push(fa);
                        }
                    }
                }
            }
        });
        for &(a, b) in &extra {
            if let (Some(la), true) = (nbrs.get_mut(a as usize), (b as usize) < n_free) {
                la.push(b);
                nbrs[b as usize].push(a);
            }
        }
        for l in &mut nbrs {
            l.sort_unstable();
            l.dedup();
        }
        let dofs = 3 * n_free;
        let mut col_ptr = Vec::with_capacity(dofs + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for l in &nbrs {
            for _cc in 0..3 {
                for &i in l {
                    for rr in 0..3 {
                        row_idx.push(3 * i as usize + rr);
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        let mut slots = Vec::new();
        let mut slot_offset = Vec::with_capacity(sys.elements.len());
        let mut ei = 0u32;
        sys.elements.for_each(|e| {
            slot_offset.push(slots.len());
            let v = e.vertices();
            let grouped = v
                .iter()
                .any(|&a| groups.of.get(a as usize).is_some_and(|&g| g != NONE));
            if grouped {
                groups.elements.push(ei);
            }
            ei += 1;
            for &b in v {
                for &a in v {
                    let (fa, fb) = (
                        free_of.get(a as usize).copied().unwrap_or(NONE),
                        free_of.get(b as usize).copied().unwrap_or(NONE),
                    );
                    // Row node fa, column node fb: the lower triangle only.
                    slots.push(if fa != NONE && fb != NONE && fa >= fb && !grouped {
                        nbrs[fb as usize]
                            .binary_search(&fa)
                            .expect("pattern holds every pair") as u32
                    } else {
                        NONE
                    });
                }
            }
        });
        let diag_slot: Vec<u32> = (0..n_free)
            .map(|j| nbrs[j].binary_search(&(j as u32)).expect("diagonal") as u32)
            .collect();
        let upper_start = std::iter::once(0)
            .chain(diag_slot.iter().scan(0, |acc, &d| {
                *acc += d as usize;
                Some(*acc)
            }))
            .take(n_free)
            .collect();
        let upper_src = (0..n_free)
            .flat_map(|j| {
                let nbrs = &nbrs;
                nbrs[j][..diag_slot[j] as usize].iter().map(move |&i| {
                    nbrs[i as usize]
                        .binary_search(&(j as u32))
                        .expect("symmetric pattern") as u32
                })
            })
            .collect();
        let at = free_layout(sys, &free_of, n_vertices);
        // Not split with rigid groups (their nodes couple every member).
        let may_split = sys.rigid.is_empty() && !whole_only;
        // Held beside the factor: the pattern's indices and values (16 bytes an entry),
        // its slots and neighbour lists, and per vertex and per element the work buffers
        // built after it (trial positions, the assembly's partition, the shared hinges,
        // the length correction: 512 bytes each bounds them; measured under a tight
        // `ulimit -v`, the hinges' table was what failed without them).
        let held = (16 * row_idx.len() + 8 * col_ptr.len() + 4 * (slots.len() + dofs)) as u64
            + nbrs.iter().map(|l| 24 + 4 * l.len() as u64).sum::<u64>()
            + 512 * (n + sys.elements.len()) as u64;
        let factor = Factor::new(&nbrs, &col_ptr, &row_idx, &at, may_split, (room, held))?;
        // Which elements may be assembled concurrently (`partition.rs`), by their free
        // vertices only (pinned ones are never written).
        let stencils: partition::Stencils = (0..sys.elements.len())
            .filter(|&ei| groups.elements.binary_search(&(ei as u32)).is_err())
            .map(|ei| {
                let free = sys
                    .elements
                    .get(ei)
                    .vertices()
                    .iter()
                    .copied()
                    .filter(|&v| free_of.get(v as usize).is_some_and(|&f| f != NONE))
                    .collect();
                (ei as u32, free)
            })
            .collect();
        let parts = partition::partition(stencils, n, &sys.layout);
        let values = vec![0.0; row_idx.len()];
        let per_element = RefCell::new(vec![0.0; slot_offset.len()]);
        Ok(Integrator {
            lin: LinearSystem {
                n,
                free_of,
                n_free,
                col_ptr,
                row_idx,
                values,
                slots,
                diag_slot,
                upper_src,
                upper_start,
                slot_offset,
                parts,
                extra,
            },
            dirs: Directions {
                factor,
                one_ring: None,
                single: None,
                one_ring_tried: false,
                pcg_single: false,
                pcg: false,
            },
            work: Work {
                grad: vec![0.0; dofs],
                dir: vec![0.0; dofs],
                x_hat: vec![Vector3::zeros(); n],
                x_trial: vec![Vector3::zeros(); n],
                x_soc: vec![Vector3::zeros(); n],
                curv_v: Vec::new(),
                curv_w: Vec::new(),
                curv_d: Vec::new(),
                local: Local::default(),
                per_element,
            },
            sliders: Sliders {
                slide_of: Vec::new(),
                slide_proj: Vec::new(),
                slide_scale: Vec::new(),
                slide_normal: Vec::new(),
                slide_forces: sliding::SlideForces::default(),
            },
            hooks: Hooks {
                stop: None,
                progress: None,
                max_bytes,
            },
            modes: Modes {
                whole_only,
                joined_max: contacts::JOINED_MAX,
                tails: !sys.elements.membranes.is_empty()
                    && sys.elements.stretches.is_empty()
                    && sys.elements.bends.is_empty()
                    && sys.elements.clamps.is_empty(),
            },
            elimination: elimination::Elimination::default(),
            correction: correction::LengthCorrection::new(
                sys.elements
                    .stretches
                    .iter()
                    .map(|s| (s.v[0], s.v[1]))
                    .collect(),
                n,
            ),
            force_scale: 0.0,
            groups,
            carried: Vec::new(),
            budget: Vec::new(),
            budget_for: (f64::NAN, f64::NAN),
            hinges: (!sys.elements.midedges.is_empty())
                .then(|| RefCell::new(SharedHinges::new(&sys.elements.midedges))),
            midedges: sys.elements.midedge_range(),
        })
    }

    /// Nonzeros stored in the system matrix (both triangles).
    pub fn nonzeros(&self) -> usize {
        self.lin.row_idx.len()
    }

    /// Whether vertex `i` is held (pinned): neither free nor in a rigid group.
    fn held(&self, i: usize) -> bool {
        self.lin.free_of[i] == NONE && self.groups.of.get(i).is_none_or(|&g| g == NONE)
    }

    /// Free (unpinned) vertices.
    pub fn free_vertices(&self) -> usize {
        self.lin.n_free
    }

    fn objective(
        &self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        mode: Mode,
    ) -> f64 {
        let mut e = 0.0;
        for i in 0..self.lin.n {
            if !self.held(i) {
                let m = sys.mass[i];
                e += match mode {
                    Mode::Dynamic { h } => self.vertex_energy(sys, x, x0, h, i),
                    // Static: the potential of gravity and the constant loads.
                    Mode::Static => -(m * sys.gravity + sys.force(i)).dot(&x[i]),
                };
            }
        }
        let mut per = self.work.per_element.borrow_mut();
        let parallel = per.len() >= PARALLEL_MIN && rayon::current_num_threads() > 1;
        if let Some(h) = &self.hinges {
            refresh_hinges(&mut h.borrow_mut(), x, false);
        }
        let hinges = self.hinges.as_ref().map(|h| h.borrow());
        let hinges = hinges.as_deref();
        let midedges = &self.midedges;
        let energy = |i: usize| match hinges.filter(|_| midedges.contains(&i)) {
            Some(h) => {
                let k = i - midedges.start;
                h.energy(k, &sys.elements.midedges[k])
            }
            None => sys.elements.get(i).energy(x),
        };
        if parallel {
            per.par_iter_mut()
                .enumerate()
                .for_each(|(i, pe)| *pe = energy(i));
        } else {
            for (i, pe) in per.iter_mut().enumerate() {
                *pe = energy(i);
            }
        }
        // Summed in element order: the same bits at any thread count.
        let e = per.iter().fold(e, |a, b| a + b);
        match mode {
            Mode::Dynamic { h } if !sys.sliders.is_empty() => {
                e + self.friction_energy(sys, x, x0, h)
            }
            _ => e,
        }
    }

    /// Vertex `i`'s own terms of a dynamic step's objective: inertia, damping and drag.
    fn vertex_energy(
        &self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
        i: usize,
    ) -> f64 {
        let m = sys.mass[i];
        let mut e = m / (2.0 * h * h) * (x[i] - self.work.x_hat[i]).norm_squared()
            + sys.damping(i) * m / (2.0 * h) * (x[i] - x0[i]).norm_squared();
        // Drag: (1/2h) rᵀDr with r = x − x⁰ − h u, whose gradient is D(v − u).
        if let Some(d) = sys.drag(i) {
            let r = x[i] - x0[i] - h * d.flow;
            e += 0.5 / h * r.dot(&(d.matrix * r));
        }
        e
    }

    /// The gradient and Hessian of [`Self::vertex_energy`]: a (x − x̂) + b (x − x⁰) and
    /// (a + b) I, a = m/h², b = c m/h, plus drag's D(v − u) and D/h.
    fn vertex_terms(
        &self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        h: f64,
        i: usize,
    ) -> (Vector3<f64>, Matrix3<f64>) {
        let m = sys.mass[i];
        let (a, b) = (m / (h * h), sys.damping(i) * m / h);
        let mut g = a * (x[i] - self.work.x_hat[i]) + b * (x[i] - x0[i]);
        let mut hess = (a + b) * Matrix3::identity();
        if let Some(d) = sys.drag(i) {
            g += d.matrix * ((x[i] - x0[i]) / h - d.flow);
            hess += d.matrix / h;
        }
        (g, hess)
    }

    /// Fills `grad` and `values` at `x`, with every element Hessian projected to PSD.
    fn assemble(&mut self, sys: &SolidSystem, x: &[Vector3<f64>], x0: &[Vector3<f64>], mode: Mode) {
        self.assemble_with(sys, x, x0, mode, Hessians::Projected);
    }

    /// Fills `grad` and `values` at `x` with the chosen element Hessians.
    fn assemble_with(
        &mut self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        mode: Mode,
        hessians: Hessians,
    ) {
        self.work.grad.iter_mut().for_each(|g| *g = 0.0);
        self.lin.values.iter_mut().for_each(|v| *v = 0.0);
        self.force_scale = 0.0;
        if !self.groups.is_empty() {
            self.assemble_members(sys, x, x0, mode);
        }
        for i in 0..self.lin.n {
            let f = self.lin.free_of[i];
            if f == NONE {
                continue;
            }
            let m = sys.mass[i];
            let (g, diag) = match mode {
                Mode::Dynamic { h } => {
                    let (a, b) = (m / (h * h), sys.damping(i) * m / h);
                    (a * (x[i] - self.work.x_hat[i]) + b * (x[i] - x0[i]), a + b)
                }
                Mode::Static => (-(m * sys.gravity + sys.force(i)), 0.0),
            };
            let f = f as usize;
            let mut g = g;
            if let (Mode::Dynamic { h }, Some(d)) = (mode, sys.drag(i)) {
                // Gradient D(v − u), Hessian D/h: a full 3×3 diagonal block.
                g += d.matrix * ((x[i] - x0[i]) / h - d.flow);
                let block = self.lin.block_mut(f, self.lin.diag_slot[f] as usize);
                for (v, m) in block.iter_mut().zip(d.matrix.as_slice()) {
                    *v += m / h;
                }
            }
            for c in 0..3 {
                self.work.grad[3 * f + c] += g[c];
                let k = self.lin.diagonal_entry(f, c);
                self.lin.values[k] += diag;
            }
            self.force_scale += g.abs().sum();
        }
        let parallel = rayon::current_num_threads() > 1;
        if let Some(h) = self.hinges.as_mut() {
            refresh_hinges(h.get_mut(), x, true);
        }
        let values = Shared(self.lin.values.as_mut_ptr());
        let grad = Shared(self.work.grad.as_mut_ptr());
        let mut per = self.work.per_element.borrow_mut();
        let scale = Shared(per.as_mut_ptr());
        let (free_of, col_ptr, slots, offsets) = (
            &self.lin.free_of,
            &self.lin.col_ptr,
            &self.lin.slots,
            &self.lin.slot_offset,
        );
        let hinges_ref = self.hinges.as_ref().map(|h| h.borrow());
        let hinges = hinges_ref.as_deref();
        let midedges = &self.midedges;
        let budget = &self.budget;
        let carried = &self.carried;
        let work = |&ei: &u32| {
            LOCAL.with(|l| {
                let local = &mut **l.borrow_mut();
                let ei = ei as usize;
                let el = sys.elements.get(ei);
                // Midedge bending's Hessian is its Gauss–Newton term in both modes.
                match (hinges.filter(|_| midedges.contains(&ei)), hessians) {
                    (Some(h), _) => {
                        let k = ei - midedges.start;
                        h.eval(k, &sys.elements.midedges[k], local);
                    }
                    (None, Hessians::Projected) => el.eval(x, true, local),
                    (None, Hessians::First) if ei < carried.len() => {
                        sys.elements.membranes[ei].eval_carried(x, &carried[ei], local)
                    }
                    (None, Hessians::First) => el.eval_first(x, local),
                    (None, Hessians::Contact) if ei < carried.len() => sys.elements.membranes[ei]
                        .eval_contact_carried(x, budget[ei], &carried[ei], local),
                    (None, Hessians::Contact) => el.eval_contact(x, budget[ei], local),
                }
                // SAFETY: see `Shared`: elements run concurrently write disjoint entries, and
                // `per_element[ei]` belongs to this element alone.
                unsafe {
                    scatter(
                        el.vertices(),
                        local,
                        free_of,
                        col_ptr,
                        &slots[offsets[ei]..],
                        values,
                        grad,
                        scale.at(ei),
                    )
                };
            })
        };
        self.lin.parts.run(&work, parallel);
        drop(per);
        drop(hinges_ref);
        self.lin.mirror_upper();
        if !self.groups.is_empty() {
            // Elements with a member: through the groups' Jacobians, in element order.
            // The scratch moves out by its box (a `Local` is 73 kB: moving it by value per
            // element cost more than the element).
            let mut local = self.groups.local.take().unwrap_or_default();
            for k in 0..self.groups.elements.len() {
                let ei = self.groups.elements[k] as usize;
                let el = sys.elements.get(ei);
                match hessians {
                    Hessians::Projected => el.eval(x, true, &mut local),
                    Hessians::First if ei < self.carried.len() => {
                        sys.elements.membranes[ei].eval_carried(x, &self.carried[ei], &mut local)
                    }
                    Hessians::First => el.eval_first(x, &mut local),
                    Hessians::Contact if ei < self.carried.len() => sys.elements.membranes[ei]
                        .eval_contact_carried(x, self.budget[ei], &self.carried[ei], &mut local),
                    Hessians::Contact => el.eval_contact(x, self.budget[ei], &mut local),
                }
                let k3 = 3 * el.vertices().len();
                self.work.per_element.borrow_mut()[ei] =
                    local.grad[..k3].iter().map(|g| g.abs()).sum::<f64>();
                self.add_element_through_groups(el.vertices(), &local);
            }
            self.groups.local = Some(local);
            self.finish_groups(hessians);
        }
        let per = self.work.per_element.borrow();
        self.force_scale = per.iter().fold(self.force_scale, |a, b| a + b);
        drop(per);
        self.filter_sliders(sys, x, x0, mode);
    }

    /// The rigid groups' members' own terms (inertia, damping, drag, or the static loads),
    /// through their groups' Jacobians at `x` (`rigid.rs`).
    fn assemble_members(
        &mut self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        x0: &[Vector3<f64>],
        mode: Mode,
    ) {
        self.groups.centers(sys, x);
        for g in 0..self.groups.members.len() {
            for k in 0..self.groups.members[g].len() {
                let i = self.groups.members[g][k] as usize;
                let m = sys.mass[i];
                let (g, hess) = match mode {
                    Mode::Dynamic { h } => self.vertex_terms(sys, x, x0, h, i),
                    Mode::Static => (-(m * sys.gravity + sys.force(i)), Matrix3::zeros()),
                };
                self.force_scale += g.abs().sum();
                self.add_member_terms(i, &g, &hess);
            }
        }
    }

    fn shift_diagonal(&mut self, mu: f64) {
        // Adding zero changes no entry: skip the pass (every factorization asks for it).
        if mu != 0.0 {
            self.add_to_diagonal(|_| mu);
        }
    }

    /// Adds `mu(i)` to the three diagonal entries of every free vertex i (and through J to
    /// the rigid groups' nodes).
    fn add_to_diagonal(&mut self, mu: impl Fn(usize) -> f64) {
        if !self.groups.is_empty() {
            self.add_to_group_diagonals(&mu);
        }
        for i in 0..self.lin.n {
            let f = self.lin.free_of[i];
            if f == NONE {
                continue;
            }
            let mu = mu(i);
            for c in 0..3 {
                let k = self.lin.diagonal_entry(f as usize, c);
                self.lin.values[k] += mu;
            }
        }
    }

    /// `dir` ← −H⁻¹ `grad` with the last factor, or by conjugate gradients preconditioned
    /// with the one-ring factor while `pcg` is set: false when they met a direction of
    /// non-positive curvature (H is not positive definite). Should they not converge, the
    /// rest of the step factors H itself, starting with this direction.
    fn solve_direction(&mut self, stats: &mut StepStats) -> bool {
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
                    self.dirs.pcg = false;
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
    fn direction_size(&self, scale: f64) -> f64 {
        self.step_size(&self.work.dir) * scale
    }

    /// The largest displacement of a vertex by the step `d` (over the nodes): a group's
    /// rotation node is in radians, so its members' displacements count instead.
    /// NaN when any entry of `d` is not finite: `f64::max` skips a NaN, so without the check a
    /// direction with non-finite entries would pass as a short one (and end a contact step
    /// "converged" with non-finite positions, reported only at the next step).
    fn step_size(&self, d: &[f64]) -> f64 {
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
    fn newton_direction(&mut self, stats: &mut StepStats, shift: f64) -> Result<(), StepError> {
        self.factor(stats, shift)?;
        if !self.solve_direction(stats) {
            // Conjugate gradients met non-positive curvature in a matrix meant to be
            // positive definite (projected): H's own factor decides, its shift grown as needed.
            self.dirs.pcg = false;
            self.factor(stats, 0.0)?;
            self.solve_direction(stats);
        }
        Ok(())
    }

    /// Factorizes `values` + `shift`·I (growing the shift as [`Self::newton_direction`] says).
    fn factor(&mut self, stats: &mut StepStats, shift: f64) -> Result<(), StepError> {
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
    fn try_factor(&mut self, stats: &mut StepStats) -> bool {
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

    /// While `pcg` is set, factors the one-ring preconditioner from `values`: whether it
    /// was positive definite, or `None` when H is to be factored instead (no preconditioner,
    /// or it declined: then the rest of the step factors H).
    fn factor_preconditioner(&mut self, certify: bool) -> Option<bool> {
        let pre: Option<&mut one_ring::OneRing> = self.dirs.preconditioner();
        match pre?.factor(&self.lin.values, certify) {
            one_ring::Factored::Positive => Some(true),
            one_ring::Factored::NotPositive => Some(false),
            one_ring::Factored::Declined if !self.dirs.pcg_single && self.dirs.single.is_some() => {
                self.dirs.pcg_single = true;
                self.factor_preconditioner(certify)
            }
            one_ring::Factored::Declined => {
                self.dirs.pcg = false;
                None
            }
        }
    }

    /// One numeric Cholesky factorization of `values`.
    fn factor_once(&mut self) -> Result<(), faer::linalg::solvers::LltError> {
        self.dirs.factor.factor(&self.lin.values)
    }

    /// Fills `budget` for [`Hessians::Contact`]: element e may keep negative curvature down
    /// to −α minᵢ (mᵢ/h²)/nᵢ over its vertices i, nᵢ the number of elements at i that
    /// spend a budget. Their sum is then at least −α M/h² and, every other element's
    /// Hessian being PSD (rods aside: their exact Hessians are not bounded), the contact
    /// step's matrix at least (1 − α) M/h² plus the contacts' terms: positive definite
    /// without a factorization to prove it, and the step's elastic model convex, which
    /// ADMM needs (on the exact, indefinite one it diverged). Filled again only when h or α
    /// changes.
    fn fill_budget(&mut self, sys: &SolidSystem, h: f64, alpha: f64) {
        let n = sys.elements.len();
        if self.budget_for == (h, alpha) && self.budget.len() == n {
            return;
        }
        let mut count = vec![0u32; sys.mass.len()];
        for ei in 0..n {
            let el = sys.elements.get(ei);
            if el.spends_budget() {
                for &v in el.vertices() {
                    count[v as usize] += 1;
                }
            }
        }
        self.budget.clear();
        self.budget.resize(n, 0.0);
        for (ei, b) in self.budget.iter_mut().enumerate() {
            let el = sys.elements.get(ei);
            if el.spends_budget() {
                *b = el
                    .vertices()
                    .iter()
                    .map(|&v| alpha * sys.mass[v as usize] / (h * h * count[v as usize] as f64))
                    .fold(f64::INFINITY, f64::min);
            }
        }
        self.budget_for = (h, alpha);
    }

    /// Adds `kappa` · mᵢ/h² to every free vertex's diagonal block.
    fn shift_inertia(&mut self, sys: &SolidSystem, h: f64, kappa: f64) {
        self.add_to_diagonal(|i| kappa * sys.mass[i] / (h * h));
    }

    /// Factorizes `values` (assembled with [`Hessians::First`]) and solves for the direction,
    /// adding inertia ([`shift_ladder`]'s tries) while it is not positive definite (its
    /// factorization fails, or conjugate gradients meet non-positive curvature).
    /// Returns `Some(shifted)` (whether inertia was added) on success. `last_shift` is the
    /// inertia that succeeded last in this step (0: none yet); a success updates it.
    fn factor_first(
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
    fn first_direction(
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

    /// Starts the membranes' carried stresses at the stresses at `x0` (the last step's
    /// converged state: its stress is the mixed form's warm start, where the first guess's
    /// is an overshoot), or clears them where the step does not carry any.
    pub(super) fn start_carried(&mut self, sys: &SolidSystem, x0: &[Vector3<f64>], carry: bool) {
        self.carried.clear();
        if carry {
            let ms = &sys.elements.membranes;
            self.carried.extend(ms.iter().map(|m| m.stress_at(x0)));
        }
    }

    /// Moves the carried stresses by the step just taken from `from` to `to` at the fraction
    /// `alpha` of its direction (`Membrane::predict_stress`).
    fn carry_stress(
        &mut self,
        sys: &SolidSystem,
        from: &[Vector3<f64>],
        to: &[Vector3<f64>],
        alpha: f64,
    ) {
        let ms = &sys.elements.membranes;
        let update = |(s, m): (&mut Matrix2<f64>, &crate::energy::Membrane)| {
            *s = m.predict_stress(from, to, s, alpha);
        };
        // Each stress on its own: the same bits at any thread count.
        if ms.len() >= PARALLEL_MIN && rayon::current_num_threads() > 1 {
            self.carried
                .par_iter_mut()
                .zip(ms.par_iter())
                .for_each(update);
        } else {
            self.carried.iter_mut().zip(ms.iter()).for_each(update);
        }
    }

    /// `trial` ← x + α·dir for the free vertices (held ones stay at x), rigid groups' members
    /// moved with their frames and sliders retracted to their curves: every trial point of
    /// the line searches and of the moves along negative curvature.
    fn place(
        &self,
        sys: &SolidSystem,
        x: &[Vector3<f64>],
        dir: &[f64],
        alpha: f64,
        trial: &mut [Vector3<f64>],
    ) {
        for ((t, p), &f) in trial.iter_mut().zip(x).zip(&self.lin.free_of) {
            *t = if f == NONE {
                *p
            } else {
                let f = 3 * f as usize;
                p + alpha * Vector3::new(dir[f], dir[f + 1], dir[f + 2])
            };
        }
        self.move_members(dir, alpha, trial);
        self.retract(sys, trial);
    }

    /// `b` ← A⁻¹ `b` with the factor the last direction was found with: the
    /// preconditioner's while conjugate gradients are on, else H's.
    fn solve_with_last(&mut self, b: &mut [f64]) {
        match self.dirs.preconditioner() {
            Some(pre) => pre.apply(b),
            None => self.dirs.factor.solve_in_place(b),
        }
    }

    /// Solves with the last factor in place (`b` ← H⁻¹ b, 3 entries per free vertex).
    fn solve_in_place(&mut self, stats: &mut StepStats, b: &mut [f64]) {
        let t = Instant::now();
        self.dirs.factor.solve_in_place(b);
        stats.solve_seconds += t.elapsed().as_secs_f64();
    }

    /// Advances `state` by `h`. Pinned vertices move to `pinned_to` (all vertices' targets;
    /// only pinned entries are read) or stay where they are. On error `state` is unchanged.
    pub fn step(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        pinned_to: Option<&[Vector3<f64>]>,
        h: f64,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        self.step_from(sys, state, None, pinned_to, h, settings)
    }

    /// Advances `state` by `h` with the second-order backward differentiation formula
    /// (BDF2), `prev` being the state one step of the same `h` before `state`:
    /// xₙ₊₁ − x̄ = (2h/3) vₙ₊₁ and vₙ₊₁ − v̄ = (2h/3) M⁻¹ f(xₙ₊₁), with x̄ = (4xₙ − xₙ₋₁)/3 and
    /// v̄ = (4vₙ − vₙ₋₁)/3. That is implicit Euler's minimization with step h̃ = 2h/3 from the
    /// state (x̄, v̄) (inertia ½‖x − x̄ − h̃v̄ − h̃²g‖²_M/h̃², damping and drag measured from x̄),
    /// so it is one: the same Newton, line search and statistics. Implicit Euler damps a swing
    /// at first order in h (a 0.3 rad pendulum at h = 1/48 s: 3.1e-2 rad off after 1 s,
    /// `tests/time_integration.rs`); BDF2's error is second order (1.1e-3 rad there) and it stays L-stable (stiff modes
    /// are still damped). Pinned vertices go to `pinned_to` as in [`Self::step`]. On error
    /// `state` is unchanged.
    pub fn step_bdf2(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        prev: &State,
        pinned_to: Option<&[Vector3<f64>]>,
        h: f64,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        if matches!(settings.method, Method::Explicit | Method::Static) {
            // Not implicit steps: nothing to blend.
            return self.step(sys, state, pinned_to, h, settings);
        }
        sys.check(prev)?;
        let blend = |a: &[Vector3<f64>], b: &[Vector3<f64>]| -> Vec<Vector3<f64>> {
            a.iter().zip(b).map(|(a, b)| (4.0 * a - b) / 3.0).collect()
        };
        let mut bar = State {
            x: blend(&state.x, &prev.x),
            v: blend(&state.v, &prev.v),
        };
        // Held vertices without targets stay where they are (not at x̄).
        let held: Vec<Vector3<f64>>;
        let pinned_to = match pinned_to {
            Some(p) => Some(p),
            None => {
                held = state.x.clone();
                Some(&held[..])
            }
        };
        let stats = self.step(sys, &mut bar, pinned_to, 2.0 * h / 3.0, settings)?;
        *state = bar;
        Ok(stats)
    }

    /// [`Self::step`] with Newton starting from `guess` (end-of-step positions, e.g. the
    /// last coupling iteration's) instead of x⁰ + h v⁰. The answer is the same minimizer to
    /// the tolerance; a good guess needs fewer iterations. Pinned vertices still go to their
    /// targets; a guess of the wrong length, or not finite, is ignored.
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
        if settings.method == Method::Explicit {
            if !sys.rigid.is_empty() {
                return Err(StepError::System(SystemError::BadRigid {
                    group: 0,
                    reason: "explicit steps cannot keep a group rigid: use method newton, linearized or static".into(),
                }));
            }
            return self.explicit(sys, state, &x0, &target, h);
        }
        let mut x = state.x.clone();
        if settings.method == Method::Static {
            for i in (0..self.lin.n).filter(|&i| self.held(i)) {
                x[i] = target(i);
            }
            if let Some(g) = guess {
                for i in (0..self.lin.n).filter(|&i| !self.held(i)) {
                    x[i] = g[i];
                }
            }
            self.retract(sys, &mut x);
            let stats = in_pool(self.threaded(), || {
                self.minimize(sys, &mut x, &x0, Mode::Static, settings)
            })?;
            state.x = x;
            state.v.iter_mut().for_each(|v| *v = Vector3::zeros());
            return Ok(stats);
        }
        self.predict(sys, state, &mut x, &target, guess, h);
        let stats = in_pool(self.threaded(), || {
            self.minimize(sys, &mut x, &x0, Mode::Dynamic { h }, settings)
        })?;
        for i in 0..self.lin.n {
            state.v[i] = (x[i] - x0[i]) / h;
        }
        state.x = x;
        Ok(stats)
    }

    /// The start of an implicit step from `state` (x⁰): held vertices at their targets, x̂ for
    /// every vertex, and the first iterate `x` (the guess, else x⁰ + h v⁰).
    fn predict(
        &mut self,
        sys: &SolidSystem,
        state: &State,
        x: &mut [Vector3<f64>],
        target: &dyn Fn(usize) -> Vector3<f64>,
        guess: Option<&[Vector3<f64>]>,
        h: f64,
    ) {
        let x0 = &state.x;
        for i in 0..self.lin.n {
            if self.held(i) {
                x[i] = target(i);
                self.work.x_hat[i] = x[i];
            } else {
                // x̂ = x⁰ + h v⁰ + h² (g + f/m): constant forces act like gravity.
                self.work.x_hat[i] =
                    x0[i] + h * state.v[i] + h * h * (sys.gravity + sys.force(i) / sys.mass[i]);
                x[i] = guess.map_or(x0[i] + h * state.v[i], |g| g[i]);
            }
        }
        if guess.is_none() {
            // A rigid group's first guess moves it rigidly: by its centroid's velocity.
            for g in &sys.rigid {
                let (mut p, mut w) = (Vector3::zeros(), 0.0);
                for &v in &g.vertices {
                    p += sys.mass[v as usize] * state.v[v as usize];
                    w += sys.mass[v as usize];
                }
                let vc = p / w;
                for &v in &g.vertices {
                    x[v as usize] = x0[v as usize] + h * vc;
                }
            }
        }
        self.retract(sys, x);
    }

    /// Moves `state` to static equilibrium under gravity, the constant forces and the elastic
    /// energies (pinned vertices stay put; velocities are set to zero). Newton with a
    /// proximal term μ/2‖x − xₖ‖², μ = 1e-9 of the largest stiffness scaled by the gradient's
    /// relative decrease: it converges to the true minimizer while keeping the Hessian SPD for
    /// bodies with rigid or otherwise free modes.
    /// The residual is ‖Δx‖∞ in metres.
    pub fn solve_static(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        sys.check(state)?;
        let x0 = state.x.clone();
        let mut x = x0.clone();
        self.retract(sys, &mut x);
        let stats = in_pool(self.threaded(), || {
            self.minimize(sys, &mut x, &x0, Mode::Static, settings)
        })?;
        state.x = x;
        state.v.iter_mut().for_each(|v| *v = Vector3::zeros());
        Ok(stats)
    }

    /// Whether this system has work for more than one thread (an assembly tree with a split,
    /// or a split factorization): its steps then run on a pool worker ([`in_pool`]).
    fn threaded(&self) -> bool {
        self.dirs.factor.split.is_some()
            || self.dirs.one_ring.as_ref().is_some_and(|o| o.is_split())
            || self.dirs.single.is_some()
            || matches!(self.lin.parts, partition::Part::Split { .. })
    }

    /// Each free node's block neighbours in H's pattern (itself included, sorted).
    fn vertex_graph(&self) -> Vec<Vec<u32>> {
        (0..self.lin.n_free)
            .map(|v| {
                (self.lin.col_ptr[3 * v]..self.lin.col_ptr[3 * v + 1])
                    .step_by(3)
                    .map(|k| (self.lin.row_idx[k] / 3) as u32)
                    .collect()
            })
            .collect()
    }

    /// H's own pattern factored in single precision as CG's preconditioner
    /// (`OneRing::single`), where H's factorization costs at least
    /// [`one_ring::SINGLE_MIN_FLOPS`] and may be split (no rigid groups), within `max_bytes`.
    fn build_single(
        &self,
        sys: &SolidSystem,
        max_bytes: Option<u64>,
    ) -> Result<Option<one_ring::OneRing>, StepError> {
        if self.dirs.factor.flops() < one_ring::SINGLE_MIN_FLOPS
            || !sys.rigid.is_empty()
            || self.modes.whole_only
        {
            return Ok(None);
        }
        one_ring::OneRing::single(
            &self.dirs.factor,
            &self.lin.col_ptr,
            &self.lin.row_idx,
            max_bytes,
        )
    }

    /// The one-ring preconditioner for this pattern (`one_ring.rs`), where it pays: its
    /// pattern keeps the pairs some element of at most three vertices couples (membrane
    /// triangles, rods, springs), every pair with a rigid group's node, and the contacts'
    /// extra blocks; the wide elements' (shell bending's) other pairs are dropped. Within
    /// `max_bytes`.
    fn build_one_ring(
        &self,
        sys: &SolidSystem,
        max_bytes: Option<u64>,
    ) -> Result<Option<one_ring::OneRing>, StepError> {
        let first = self.groups.first;
        let nbrs = self.vertex_graph();
        let mut keep: Vec<Vec<u32>> = (0..self.lin.n_free as u32).map(|j| vec![j]).collect();
        for (v, l) in nbrs.iter().enumerate() {
            if v >= first {
                keep[v].clone_from(l);
            } else {
                keep[v].extend(l.iter().filter(|&&r| r as usize >= first));
            }
        }
        for &(a, b) in &self.lin.extra {
            if let (Some(la), true) = (keep.get_mut(a as usize), (b as usize) < self.lin.n_free) {
                la.push(b);
                keep[b as usize].push(a);
            }
        }
        let node = |v: u32| self.lin.free_of.get(v as usize).copied().unwrap_or(NONE);
        sys.elements.for_each(|e| {
            if e.vertices().len() <= 3 {
                for &a in e.vertices() {
                    for &b in e.vertices() {
                        let (fa, fb) = (node(a), node(b));
                        if fa != NONE && fb != NONE && (fb as usize) < first {
                            keep[fb as usize].push(fa);
                        }
                    }
                }
            }
        });
        for l in &mut keep {
            l.sort_unstable();
            l.dedup();
        }
        let at = free_layout(sys, &self.lin.free_of, first);
        one_ring::OneRing::new(
            &nbrs,
            &self.lin.col_ptr,
            &keep,
            self.dirs.factor.flops(),
            &at,
            sys.rigid.is_empty() && !self.modes.whole_only,
            max_bytes,
        )
    }

    /// Newton (exact Hessians first for [`Method::Newton`] in dynamic steps, projected ones
    /// otherwise) with backtracking line search on the mode's objective. Callers run it on a
    /// worker of the thread pool ([`in_pool`]). A dynamic step's Newton directions go through
    /// the one-ring preconditioner where the system has one (a static solve's matrix may be
    /// singular, and a linearized step's one direction is the answer: both factor H).
    fn minimize(
        &mut self,
        sys: &SolidSystem,
        x: &mut Vec<Vector3<f64>>,
        x0: &[Vector3<f64>],
        mode: Mode,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        self.dirs.pcg = matches!(mode, Mode::Dynamic { .. }) && settings.method == Method::Newton;
        if self.dirs.pcg && !self.dirs.one_ring_tried {
            self.dirs.one_ring_tried = true;
            // Not paying, or too large for the memory limit: H's factor serves as before. The
            // limit holds for all the factors together: each preconditioner gets half of what
            // H's factor and the one built before it left. Half: they are optional, and the
            // rest of the run (its output nodes, a rebuild for contacts) needs room too
            // (measured under `ulimit -v` 400 MiB on a 100² sheet, a twin that took all of
            // it left a 600 KiB preview refused).
            let max = self.hooks.max_bytes;
            let left = |used: u64| max.map(|m| m.saturating_sub(used) / 2);
            self.dirs.one_ring = self
                .build_one_ring(sys, left(self.dirs.factor.bytes()))
                .ok()
                .flatten();
            let used =
                self.dirs.factor.bytes() + self.dirs.one_ring.as_ref().map_or(0, |o| o.bytes());
            self.dirs.single = self.build_single(sys, left(used)).ok().flatten();
        }
        if let Mode::Dynamic { h } = mode {
            for pre in [self.dirs.one_ring.as_mut(), self.dirs.single.as_mut()]
                .into_iter()
                .flatten()
            {
                pre.set_inertia(&self.lin.free_of, &sys.mass, h);
            }
        }
        // The one-ring's factor first (the cheaper one); the single-precision one where
        // there is no one-ring, or from where it declines.
        self.dirs.pcg_single = self.dirs.one_ring.is_none();
        let out = self.newton(sys, x, x0, mode, settings);
        self.dirs.pcg = false;
        // Carried stresses belong to this step's iteration only.
        self.carried.clear();
        out
    }

    /// [`Self::minimize`]'s iteration.
    fn newton(
        &mut self,
        sys: &SolidSystem,
        x: &mut Vec<Vector3<f64>>,
        x0: &[Vector3<f64>],
        mode: Mode,
        settings: &Settings,
    ) -> Result<StepStats, StepError> {
        let mut stats = StepStats::default();
        let linearized = settings.method == Method::Linearized;
        let max_it = if linearized {
            1
        } else {
            settings.max_iterations.max(1)
        };
        let scale = match mode {
            Mode::Dynamic { h } => 1.0 / h,
            Mode::Static => 1.0,
        };
        let mut g0 = 0.0f64;
        // The objective at the current iterate, when the last line search computed it (the
        // accepted trial's): the next line search starts from it instead of evaluating
        // every element's energy again. Same function, same bits.
        let mut e_at_x: Option<f64> = None;
        // The inertia that last made the exact Hessian positive definite in this step.
        let mut last_shift = 0.0;
        let mut rate = rate::RateStop::default();
        let mut friction_rate = rate::RateStop::default();
        // Whether a step of this loop stopped at a slider's stick point (`stick_cap`).
        let mut stuck = false;
        // Membranes carry their stress (the mixed form) where the first tries are exact.
        let carry = matches!(mode, Mode::Dynamic { .. }) && settings.method == Method::Newton;
        self.start_carried(sys, x0, carry);
        self.start_slide_forces(sys, !linearized);
        for it in 0..max_it {
            if self.should_stop() {
                return Err(StepError::Interrupted { iteration: it });
            }
            // Newton with the exact Hessian where it is positive definite (quadratic
            // convergence), else the projected one (always a descent direction; linear
            // convergence where the cloth buckles, since projection drops the membrane's
            // negative compressive stiffness that bending balances).
            let first = match mode {
                Mode::Dynamic { h } if settings.method == Method::Newton => {
                    self.first_direction(sys, x, x0, h, &mut last_shift, &mut stats)
                }
                _ => None,
            };
            if first.is_none() {
                let t = Instant::now();
                self.assemble(sys, x, x0, mode);
                stats.assembly_seconds += t.elapsed().as_secs_f64();
                if matches!(mode, Mode::Dynamic { .. }) && settings.method == Method::Newton {
                    stats.projected += 1;
                }
            }
            if !self.work.grad.iter().all(|g| g.is_finite()) {
                return Err(StepError::NonFinite { iteration: it });
            }
            let gnorm = self.work.grad.iter().fold(0.0f64, |m, g| m.max(g.abs()));
            if it == 0 {
                g0 = gnorm.max(f64::MIN_POSITIVE);
            }
            // Static: a proximal shift μ that shrinks with the gradient (Levenberg–Marquardt),
            // so free modes stay regular while convergence stays superlinear.
            let shift = match mode {
                Mode::Static => {
                    1e-9 * self.lin.values.iter().fold(0.0f64, |m, v| m.max(v.abs()))
                        * (gnorm / g0).clamp(1e-4, 1.0)
                }
                Mode::Dynamic { .. } => 0.0,
            };
            if first.is_none() {
                self.newton_direction(&mut stats, shift)?;
            }
            let mut res = self.direction_size(scale);
            // A direction computed with added inertia is shorter than Newton's: below the
            // tolerance it proves nothing, so the projected Hessians' direction decides.
            let reassembled = first == Some(true) && res < settings.tolerance;
            if reassembled {
                let t = Instant::now();
                self.assemble(sys, x, x0, mode);
                stats.assembly_seconds += t.elapsed().as_secs_f64();
                stats.projected += 1;
                self.newton_direction(&mut stats, shift)?;
                res = self.direction_size(scale);
            }
            if !res.is_finite() {
                return Err(StepError::NonFinite { iteration: it });
            }
            stats.iterations = it + 1;
            stats.residuals.push(res);
            self.report_newton(it + 1, res);
            // Converged: the step still takes this last (small) Newton correction, whole.
            // Stopping before it would leave a step that starts below the tolerance (a
            // body at rest whose first velocity change g·h is below it) where it started.
            // (Not an iteration that left a slider's friction out: `SlideForces`.)
            let done =
                !linearized && res < settings.tolerance && !self.sliders.slide_forces.frictionless;
            // Backtracking line search on the objective (Armijo, c = 1e-4).
            // (Not needed when the whole step is taken.)
            // Sliders' friction depends on this iteration's normal forces: a new objective.
            if Self::slide_friction(sys) {
                e_at_x = None;
            }
            let (e0, slope, xmax) = if linearized || done {
                (0.0, 0.0, 0.0)
            } else {
                (
                    e_at_x.unwrap_or_else(|| self.objective(sys, x, x0, mode)),
                    self.work
                        .grad
                        .iter()
                        .zip(&self.work.dir)
                        .map(|(g, d)| g * d)
                        .sum(),
                    x.iter().fold(0.0f64, |m, p| m.max(p.amax())),
                )
            };
            // Stopped at a frictional slider's stick point, where friction's potential has
            // its kink (`stick_cap`), once a step: several sliders reversing at different
            // fractions are then left to the line search rather than taking a cut each.
            let mut alpha = match mode {
                Mode::Dynamic { h }
                    if !linearized && !done && !stuck && Self::slide_friction(sys) =>
                {
                    self.stick_cap(sys, x, x0, &self.work.dir, h, 1.0)
                }
                _ => 1.0,
            };
            stuck |= alpha < 1.0;
            e_at_x = None;
            let corrections = stats.corrections;
            loop {
                let mut trial = std::mem::take(&mut self.work.x_trial);
                self.place(sys, x, &self.work.dir, alpha, &mut trial);
                self.work.x_trial = trial;
                if linearized || done {
                    break;
                }
                let e1 = self.objective(sys, &self.work.x_trial, x0, mode);
                e_at_x = Some(e1);
                // When the predicted decrease is below a bound on the objective's floating-point
                // resolution (≈ ε · |forces| · |positions|: terms like ½kL(l/L − 1)² are small
                // numbers made from large ones) the comparison may be noise: take the Newton
                // step, which descends locally. The bound is loose (on a buckling sheet the
                // objective resolved changes 1e4× smaller), and that helps: tighter ones cut
                // the nearly singular steps that cross flat buckling modes, 949 → 955 and
                // 1,096 Newton iterations over ten cases (BENCHMARKS.md, thirty-ninth session).
                let unresolvable = -slope * alpha <= 64.0 * f64::EPSILON * self.force_scale * xmax;
                if e1 <= e0 + 1e-4 * alpha * slope || unresolvable || alpha < 1e-10 {
                    break;
                }
                // A full step that stretches rods more than the Newton model predicted (the
                // model is linear in each segment's length, the length is not: a strand
                // swinging by d lengthens its segments by ~d²/2L) is rejected here, and
                // halving it converges slowly (the Maratos effect). A second-order
                // correction restores the lengths the model predicted, then the step is
                // tested again.
                if alpha == 1.0 && !self.correction.is_empty() {
                    stats.correction_sweeps += self.correction.apply(
                        &self.lin.free_of,
                        &sys.mass,
                        x,
                        &self.work.dir,
                        &self.work.x_trial,
                        &mut self.work.x_soc,
                    );
                    let mut soc = std::mem::take(&mut self.work.x_soc);
                    self.retract(sys, &mut soc);
                    self.work.x_soc = soc;
                    let e2 = self.objective(sys, &self.work.x_soc, x0, mode);
                    if e2 <= e0 + 1e-4 * slope {
                        std::mem::swap(&mut self.work.x_trial, &mut self.work.x_soc);
                        stats.corrections += 1;
                        e_at_x = Some(e2);
                        break;
                    }
                }
                alpha *= 0.5;
                stats.halvings += 1;
            }
            std::mem::swap(x, &mut self.work.x_trial);
            if !sys.sliders.is_empty() {
                let dir = std::mem::take(&mut self.work.dir);
                self.predict_slide_forces(&dir, alpha);
                self.work.dir = dir;
            }
            if linearized || done {
                stats.converged = true;
                break;
            }
            if !self.carried.is_empty() {
                let from = std::mem::take(&mut self.work.x_trial);
                self.carry_stress(sys, &from, x, alpha);
                self.work.x_trial = from;
            }
            // After a shifted direction, a move along the negative curvature its inertia
            // hid (`curvature.rs`). (The rate's test below counts unshifted steps only.)
            if let (Mode::Dynamic { h }, Some(true), false) = (mode, first, reassembled)
                && self.curvature_moves(sys)
            {
                let t = Instant::now();
                let lambda = self.negative_curvature(sys, h, last_shift);
                stats.solve_seconds += t.elapsed().as_secs_f64();
                if lambda < 0.0 {
                    let base = alpha * self.step_size(&self.work.dir);
                    let moved = self.curvature_search(sys, x, x0, mode, base, &mut e_at_x);
                    stats.curvature_moves += usize::from(moved);
                }
            }
            // Then the few vertices whose steps lag the rest solved locally, each patch
            // around one of them by its own Newton iterations (`elimination.rs`). Where
            // they end the step's last iterations, the rate's test below reads the
            // contraction of Newton and this together, the iteration that is repeated.
            if let (Mode::Dynamic { h }, true) = (mode, carry && self.eliminates(sys)) {
                let mut before = std::mem::take(&mut self.work.x_trial);
                before.copy_from_slice(x);
                let moved = self.eliminate(sys, x, x0, h, alpha, scale, settings.tolerance);
                if moved > 0 {
                    stats.eliminations += moved;
                    e_at_x = None;
                    // The moved membranes' carried stress follows by their linearized strain,
                    // as after a move along negative curvature.
                    self.carry_stress(sys, &before, x, 0.0);
                }
                self.work.x_trial = before;
            }
            // Or the corrections still to come, estimated from the contraction of the full
            // steps (`rate.rs`), are below the tolerance: with the first Hessians only
            // (exact where cheap, membranes' tension carried — the mixed form's Newton —,
            // midedge bending's Gauss–Newton term; unshifted), whose
            // convergence is superlinear. A shifted direction is not Newton's, and projected
            // Hessians converge linearly at a rate that can worsen as the fast modes die
            // out (projected Newton on cloth_hang: 13.42 → 10.56 iterations a step with
            // them, 1.9 → 2.9 cm off the converged run where it buckles). Sliders'
            // friction, lagged a normal force behind, is a fixed-point iteration of its own:
            // its normal forces' changes must contract too (`friction_rate`).
            let full = alpha == 1.0 && stats.corrections == corrections && first == Some(false);
            let budget = self.friction_budget(sys, &mut friction_rate, full, settings);
            if matches!(mode, Mode::Dynamic { .. })
                && rate.ends_within(budget, &mut stats, res, full)
            {
                break;
            }
        }
        if !stats.converged {
            return Err(stats.not_converged(settings.tolerance));
        }
        if !x.iter().all(|p| p.iter().all(|c| c.is_finite())) {
            return Err(StepError::NonFinite {
                iteration: stats.iterations,
            });
        }
        Ok(stats)
    }

    fn explicit(
        &mut self,
        sys: &SolidSystem,
        state: &mut State,
        x0: &[Vector3<f64>],
        target: &dyn Fn(usize) -> Vector3<f64>,
        h: f64,
    ) -> Result<StepStats, StepError> {
        if self.should_stop() {
            return Err(StepError::Interrupted { iteration: 0 });
        }
        // Forces at x⁰: f = −∇E + m g − c m v.
        let mut force = vec![Vector3::zeros(); self.lin.n];
        let local = &mut self.work.local;
        sys.elements.for_each(|el| {
            el.eval(x0, false, local);
            for (a, &v) in el.vertices().iter().enumerate() {
                force[v as usize] -= Vector3::new(
                    local.grad[3 * a],
                    local.grad[3 * a + 1],
                    local.grad[3 * a + 2],
                );
            }
        });
        let mut v = state.v.clone();
        let mut x = x0.to_vec();
        for i in 0..self.lin.n {
            if self.lin.free_of[i] == NONE {
                x[i] = target(i);
                v[i] = (x[i] - x0[i]) / h;
            } else {
                let m = sys.mass[i];
                let drag = sys
                    .drag(i)
                    .map_or_else(Vector3::zeros, |d| -(d.matrix * (state.v[i] - d.flow)));
                v[i] += h
                    * ((force[i] + sys.force(i) + drag) / m + sys.gravity
                        - sys.damping(i) * state.v[i]);
                x[i] = x0[i] + h * v[i];
            }
        }
        if !sys.sliders.is_empty() {
            // On its rail at the end of the step, with the velocity that took it there.
            self.retract(sys, &mut x);
            for sl in &sys.sliders {
                let i = sl.vertex as usize;
                v[i] = (x[i] - x0[i]) / h;
            }
        }
        if !x.iter().chain(&v).all(|p| p.iter().all(|c| c.is_finite())) {
            return Err(StepError::NonFinite { iteration: 0 });
        }
        state.x = x;
        state.v = v;
        Ok(StepStats {
            converged: true,
            ..Default::default()
        })
    }
}

/// The hinge table's angles (and gradients where `with_grad`) at `x`, over the pool from
/// [`PARALLEL_MIN`] hinges.
fn refresh_hinges(h: &mut SharedHinges, x: &[Vector3<f64>], with_grad: bool) {
    let parallel = rayon::current_num_threads() > 1 && h.len() >= PARALLEL_MIN;
    h.update(x, with_grad, parallel);
}

/// Adds one element's gradient and Hessian, evaluated into `local` on the stencil `v`, into
/// the shared arrays; `scale` receives Σ|gradient entries|.
///
/// # Safety
/// No other thread may write the entries this element touches while it runs (the assembly
/// tree guarantees it), and the pointers must cover the integrator's arrays.
#[allow(clippy::too_many_arguments)]
unsafe fn scatter(
    v: &[u32],
    local: &Local,
    free_of: &[u32],
    col_ptr: &[usize],
    slots: &[u32],
    values: Shared,
    grad: Shared,
    scale: *mut f64,
) {
    let k = v.len();
    unsafe {
        *scale = local.grad[..3 * k].iter().map(|g| g.abs()).sum::<f64>();
        for (a, &va) in v.iter().enumerate() {
            let fa = free_of[va as usize];
            if fa != NONE {
                for r in 0..3 {
                    *grad.at(3 * fa as usize + r) += local.grad[3 * a + r];
                }
            }
        }
        for (b, &vb) in v.iter().enumerate() {
            let fb = free_of[vb as usize];
            for a in 0..k {
                let s = slots[b * k + a];
                if s == NONE {
                    continue;
                }
                let base = block_entry(col_ptr, fb as usize, s as usize, 0, 0);
                for cc in 0..3 {
                    for rr in 0..3 {
                        *values.at(base + 3 * cc + rr) += local.hess[3 * b + cc][3 * a + rr];
                    }
                }
            }
        }
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

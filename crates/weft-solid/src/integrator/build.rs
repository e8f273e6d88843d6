//! Building an [`Integrator`] for a system: its free nodes (rigid groups' two each), the
//! sparsity pattern of 3×3 blocks between nodes that share an element, the element slots
//! into it, the assembly's partition, the factorization's symbolic analysis, and the
//! preconditioners built on first use (the one-ring's and the single-precision one,
//! `one_ring.rs`). Everything a step needs is sized here, so a step allocates nothing.

use super::factor::Factor;
use super::linear::LinearSystem;
use super::{Directions, Hooks, Modes, Route, Sliders, Work};
use super::{Integrator, LOCAL, NONE, admm, correction, elimination, one_ring, rigid, sliding};
use crate::energy::{Local, SharedHinges};
use crate::settings::StepError;
use crate::system::SolidSystem;
use nalgebra::Vector3;
use std::cell::RefCell;

impl Integrator {
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
    pub(super) fn ensure_extra(
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
    pub(super) fn held_bytes(&self) -> u64 {
        let pre = [self.dirs.one_ring.as_ref(), self.dirs.single.as_ref()];
        pre.into_iter()
            .flatten()
            .fold(self.dirs.factor.bytes(), |b, o| b.saturating_add(o.bytes()))
    }

    /// The integrator for `sys` with the pattern's `extra` blocks: `max_bytes` the limit it
    /// keeps for the factors it builds later, `room` what this build may take.
    pub(super) fn build(
        sys: &SolidSystem,
        (max_bytes, room): (Option<u64>, Option<u64>),
        extra: Vec<(u32, u32)>,
        whole_only: bool,
    ) -> Result<Self, StepError> {
        // What the steps run on, made here (a solver node's setup frame) rather than in the
        // first step: rayon's global pool starts its workers on first use, and this thread's
        // element scratch is zeroed page by page on first touch, costs that would otherwise
        // make a small system's first step several times its later ones (`bench/peers`' 4²
        // square measures it; figures in docs/history/issue-71-comments.md).
        let _ = rayon::current_num_threads();
        LOCAL.with(|_| ());
        if let Some(limit) = room {
            check_pattern_room(sys, &extra, limit)?;
        }
        let n = sys.mass.len();
        let (mut free_of, n_vertices) = number_free(sys);
        // Rigid groups: two nodes each after the free vertices (`rigid.rs`).
        let mut groups = rigid::Groups::new(sys, &mut free_of, n_vertices);
        let n_free = n_vertices + 2 * sys.rigid.len();
        let (lin, nbrs) = LinearSystem::new(sys, free_of, n_free, &mut groups, extra);
        let at = free_layout(sys, &lin.free_of, n_vertices);
        // Not split with rigid groups (their nodes couple every member).
        let may_split = sys.rigid.is_empty() && !whole_only;
        let held = lin.held_bytes(&nbrs, sys.elements.len());
        let factor = Factor::new(
            &nbrs,
            &lin.col_ptr,
            &lin.row_idx,
            &at,
            may_split,
            (room, held),
        )?;
        let dofs = 3 * n_free;
        let per_element = RefCell::new(vec![0.0; lin.slot_offset.len()]);
        Ok(Integrator {
            lin,
            dirs: Directions {
                factor,
                one_ring: None,
                single: None,
                one_ring_tried: false,
                route: Route::Factor,
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
                joined_max: admm::JOINED_MAX,
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
    pub(super) fn held(&self, i: usize) -> bool {
        self.lin.free_of[i] == NONE && self.groups.of.get(i).is_none_or(|&g| g == NONE)
    }

    /// Free (unpinned) vertices.
    pub fn free_vertices(&self) -> usize {
        self.lin.n_free
    }

    /// Each free node's block neighbours in H's pattern (itself included, sorted).
    pub(super) fn vertex_graph(&self) -> Vec<Vec<u32>> {
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
    pub(super) fn build_single(
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
    pub(super) fn build_one_ring(
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
}

/// Refuses, before allocating it, a pattern larger than `limit` bytes: bounded by the
/// elements' stencils squared and the contacts' blocks between solids.
fn check_pattern_room(
    sys: &SolidSystem,
    extra: &[(u32, u32)],
    limit: u64,
) -> Result<(), StepError> {
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
    Ok(())
}

/// Each vertex's free node (`NONE` for a pinned vertex or a rigid group's member), in
/// vertex order, and how many free vertices there are.
fn number_free(sys: &SolidSystem) -> (Vec<u32>, usize) {
    let n = sys.mass.len();
    let mut free_of = vec![NONE; n];
    let mut member = vec![false; n];
    for g in &sys.rigid {
        for &v in &g.vertices {
            if let Some(s) = member.get_mut(v as usize) {
                *s = true;
            }
        }
    }
    let mut n_free = 0usize;
    for (i, f) in free_of.iter_mut().enumerate() {
        if !sys.pinned.get(i).copied().unwrap_or(false) && !member[i] {
            *f = n_free as u32;
            n_free += 1;
        }
    }
    (free_of, n_free)
}

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

//! Building an [`Integrator`] for a system: its free nodes (rigid groups' two each), the
//! sparsity pattern of 3×3 blocks between nodes that share an element, the element slots
//! into it, the assembly's partition, the factorization's symbolic analysis, and the
//! preconditioners built on first use (the one-ring's and the single-precision one,
//! `one_ring.rs`). Everything a step needs is sized here, so a step allocates nothing.

use super::factor::Factor;
use super::linear::LinearSystem;
use super::{Directions, Hooks, Modes, Sliders, Work};
use super::{
    Integrator, LOCAL, NONE, admm, correction, elimination, one_ring, partition, rigid, sliding,
};
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

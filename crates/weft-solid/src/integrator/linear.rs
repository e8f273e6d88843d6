//! The linear system's room: the sparsity pattern of H over the free vertices (both
//! triangles, 3×3 blocks stored whole), each element's slots in it, the assembled values,
//! and the helpers that address them. Built with the integrator (`Integrator::build`) and
//! rebuilt only when the structure or the contacts' extra blocks change; assembly scatters
//! into it, the direction solver (`factor.rs`, `one_ring.rs`) reads it.

use super::{NONE, partition, rigid};
use crate::system::SolidSystem;
use rayon::prelude::*;

/// A pointer shared by assembly threads. Sound because the assembly tree (`partition.rs`)
/// runs concurrently only its splits' two halves, which touch disjoint free vertices, hence
/// disjoint gradient entries and matrix blocks; a split's interface runs after both.
#[derive(Clone, Copy)]
pub(super) struct Shared(pub(super) *mut f64);
unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}

impl Shared {
    /// The pointer to entry `i` (a method, so closures capture the whole `Shared`).
    pub(super) fn at(self, i: usize) -> *mut f64 {
        self.0.wrapping_add(i)
    }
}

/// Where entry `k` of column `c` of the pattern (`col_ptr`/`row_idx`: 3×3 blocks, each
/// vertex's three columns with the same rows) sits in `values`. The values are stored by
/// whole blocks: block (slot s, column vertex v) at `col_ptr[3v] + 9s`, column-major within
/// (see [`block_entry`]). An element's block is then one or two cache lines, not three
/// columns apart: the scatter's time is its loads of `values`.
pub(super) fn value_index(col_ptr: &[usize], k: usize, c: usize) -> usize {
    let off = k - col_ptr[c];
    col_ptr[c - c % 3] + 9 * (off / 3) + 3 * (c % 3) + off % 3
}

/// The index in `values` of entry (`rr`, `cc`) of block (slot `s`, column vertex `v`).
#[inline]
pub(super) fn block_entry(col_ptr: &[usize], v: usize, s: usize, rr: usize, cc: usize) -> usize {
    col_ptr[3 * v] + 9 * s + 3 * cc + rr
}

/// The linear system's room: the sparsity pattern over the free vertices, each element's
/// slots in it (assembly scatters into `values` through them), and the assembly's partition.
/// Built once per structure (and per contacts' extra blocks), never per iteration.
pub(super) struct LinearSystem {
    pub(super) n: usize,
    pub(super) free_of: Vec<u32>,
    pub(super) n_free: usize,
    pub(super) col_ptr: Vec<usize>,
    pub(super) row_idx: Vec<usize>,
    pub(super) values: Vec<f64>,
    /// Per element, per (a, b) stencil pair: the block's slot in column block v[b], for
    /// blocks on or below the diagonal only (`NONE` above it: see `upper_src`).
    pub(super) slots: Vec<u32>,
    pub(super) diag_slot: Vec<u32>,
    /// Per block above the diagonal (column by column, its slots below `diag_slot`): the
    /// slot of its transpose in the column of its row. Elements scatter the lower triangle
    /// only (half the scatter's loads and stores) and [`LinearSystem::mirror_upper`] copies it up.
    pub(super) upper_src: Vec<u32>,
    /// Per free node: where its column's entries start in `upper_src`.
    pub(super) upper_start: Vec<usize>,
    /// Per element: where its blocks start in `slots`.
    pub(super) slot_offset: Vec<usize>,
    /// The assembly tree: which elements may be assembled concurrently.
    pub(super) parts: partition::Part,
    /// Blocks beyond the elements' (free index pairs, sorted, lower first): the last
    /// contacts' between vertices that share no element.
    pub(super) extra: Vec<(u32, u32)>,
}

impl LinearSystem {
    /// The pattern for `sys` over its `n_free` nodes (`free_of`: each vertex's free node;
    /// `groups`' nodes after them), with the blocks of `extra` besides the elements': its
    /// block neighbour lists (each node's, sorted, itself included), the compressed columns,
    /// the elements' slots, the upper triangle's mirror map and the assembly's partition.
    /// Notes in `groups` the elements that touch a member. Returns the neighbour lists too,
    /// which the symbolic analysis reads.
    pub(super) fn new(
        sys: &SolidSystem,
        free_of: Vec<u32>,
        n_free: usize,
        groups: &mut rigid::Groups,
        extra: Vec<(u32, u32)>,
    ) -> (Self, Vec<Vec<u32>>) {
        let nbrs = block_neighbours(sys, &free_of, n_free, groups, &extra);
        let (col_ptr, row_idx) = compressed_columns(&nbrs);
        let (slots, slot_offset) = element_slots(sys, &free_of, groups, &nbrs);
        let (diag_slot, upper_start, upper_src) = mirror_map(&nbrs);
        let parts = assembly_parts(sys, &free_of, groups);
        let values = vec![0.0; row_idx.len()];
        let lin = LinearSystem {
            n: sys.mass.len(),
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
        };
        (lin, nbrs)
    }

    /// What the pattern holds beside the factor, as the memory limit counts it: its indices
    /// and values (16 bytes an entry), its slots and neighbour lists (`nbrs`), and per vertex
    /// and per element the work buffers built after it (trial positions, the assembly's
    /// partition, the shared hinges, the length correction: 512 bytes each bounds them; left
    /// out, a tight `ulimit -v` is met by the hinges' table after the check has passed).
    pub(super) fn held_bytes(&self, nbrs: &[Vec<u32>], elements: usize) -> u64 {
        let dofs = 3 * self.n_free;
        (16 * self.row_idx.len() + 8 * self.col_ptr.len() + 4 * (self.slots.len() + dofs)) as u64
            + nbrs.iter().map(|l| 24 + 4 * l.len() as u64).sum::<u64>()
            + 512 * (self.n + elements) as u64
    }

    /// Copies every block below the diagonal onto its transpose above it, which the
    /// elements did not write. Whatever was added above the diagonal before (the rigid
    /// groups' members' terms, added to both triangles alike) is overwritten by its mirror
    /// image, so the matrix is exactly symmetric.
    pub(super) fn mirror_upper(&mut self) {
        let values = Shared(self.values.as_mut_ptr());
        let (col_ptr, row_idx, diag_slot) = (&self.col_ptr, &self.row_idx, &self.diag_slot);
        let (upper_src, upper_start) = (&self.upper_src, &self.upper_start);
        // Columns `range`'s blocks above the diagonal, from their transposes below it.
        // SAFETY: a column's upper blocks are written by its own chunk only, and the blocks
        // read (below the diagonal) are never written here; the pointers cover `values`.
        let mirror = |range: std::ops::Range<usize>| unsafe {
            for j in range {
                let base = col_ptr[3 * j];
                for s in 0..diag_slot[j] as usize {
                    let i = row_idx[base + 3 * s] / 3;
                    let src = col_ptr[3 * i] + 9 * upper_src[upper_start[j] + s] as usize;
                    let dst = base + 9 * s;
                    for cc in 0..3 {
                        for rr in 0..3 {
                            *values.at(dst + 3 * cc + rr) = *values.at(src + 3 * rr + cc);
                        }
                    }
                }
            }
        };
        // Copies only: the same bits on any number of threads. (Small chunks in tests, so
        // their small systems take the parallel path.)
        const CHUNK: usize = if cfg!(test) { 8 } else { 2048 };
        if self.n_free >= 2 * CHUNK && rayon::current_num_threads() > 1 {
            (0..self.n_free.div_ceil(CHUNK))
                .into_par_iter()
                .for_each(|c| mirror(c * CHUNK..((c + 1) * CHUNK).min(self.n_free)));
        } else {
            mirror(0..self.n_free);
        }
    }

    /// The slot of block (row vertex `r`, column vertex `c`, free indices or group nodes)
    /// among column vertex c's blocks, when the pattern holds it (a column's rows are
    /// sorted, three to a block).
    pub(super) fn block_slot(&self, r: usize, c: usize) -> Option<usize> {
        let (lo, hi) = (self.col_ptr[3 * c], self.col_ptr[3 * c + 1]);
        self.row_idx[lo..hi]
            .binary_search(&(3 * r))
            .ok()
            .map(|k| k / 3)
    }

    /// The nine values of block (slot `s`, column vertex `c`), column-major (as nalgebra's
    /// `Matrix3::as_slice`).
    pub(super) fn block_mut(&mut self, c: usize, s: usize) -> &mut [f64] {
        let k = block_entry(&self.col_ptr, c, s, 0, 0);
        &mut self.values[k..k + 9]
    }

    /// The index in `values` of DOF c's diagonal entry of free vertex f.
    pub(super) fn diagonal_entry(&self, f: usize, c: usize) -> usize {
        block_entry(&self.col_ptr, f, self.diag_slot[f] as usize, c, c)
    }
}

/// The nodes vertex `v` moves with: its own free node, its rigid group's two, or none.
fn nodes_of(free_of: &[u32], groups: &rigid::Groups, v: u32) -> ([u32; 2], usize) {
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
}

/// Block neighbours of each node (itself included), sorted: nodes that share an element,
/// a group's two nodes, and the pairs of `extra`.
fn block_neighbours(
    sys: &SolidSystem,
    free_of: &[u32],
    n_free: usize,
    groups: &rigid::Groups,
    extra: &[(u32, u32)],
) -> Vec<Vec<u32>> {
    let mut nbrs: Vec<Vec<u32>> = (0..n_free as u32).map(|j| vec![j]).collect();
    for &t in &groups.node {
        nbrs[t as usize].push(t + 1);
        nbrs[t as usize + 1].push(t);
    }
    sys.elements.for_each(|e| {
        for &a in e.vertices() {
            let (na, ka) = nodes_of(free_of, groups, a);
            for &b in e.vertices() {
                let (nb, kb) = nodes_of(free_of, groups, b);
                for &fa in &na[..ka] {
                    for &fb in &nb[..kb] {
                        nbrs[fb as usize].push(fa);
                    }
                }
            }
        }
    });
    for &(a, b) in extra {
        if let (Some(la), true) = (nbrs.get_mut(a as usize), (b as usize) < n_free) {
            la.push(b);
            nbrs[b as usize].push(a);
        }
    }
    for l in &mut nbrs {
        l.sort_unstable();
        l.dedup();
    }
    nbrs
}

/// The pattern's compressed columns (`col_ptr`, `row_idx`): each node's three columns hold
/// the same rows, three per neighbour block.
fn compressed_columns(nbrs: &[Vec<u32>]) -> (Vec<usize>, Vec<usize>) {
    let mut col_ptr = Vec::with_capacity(3 * nbrs.len() + 1);
    let mut row_idx = Vec::new();
    col_ptr.push(0);
    for l in nbrs {
        for _cc in 0..3 {
            for &i in l {
                for rr in 0..3 {
                    row_idx.push(3 * i as usize + rr);
                }
            }
            col_ptr.push(row_idx.len());
        }
    }
    (col_ptr, row_idx)
}

/// Per element, per (a, b) stencil pair, the block's slot in column node b's list (lower
/// triangle only; `NONE` above it, for held vertices and for elements that touch a rigid
/// group, which scatter through its Jacobian: noted in `groups.elements`), and where each
/// element's slots start.
fn element_slots(
    sys: &SolidSystem,
    free_of: &[u32],
    groups: &mut rigid::Groups,
    nbrs: &[Vec<u32>],
) -> (Vec<u32>, Vec<usize>) {
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
    (slots, slot_offset)
}

/// Each node's diagonal slot, and the map [`LinearSystem::mirror_upper`] copies the lower
/// triangle up by: per column, where its entries start, and per block above the diagonal
/// the slot of its transpose in the column of its row.
fn mirror_map(nbrs: &[Vec<u32>]) -> (Vec<u32>, Vec<usize>, Vec<u32>) {
    let n_free = nbrs.len();
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
            nbrs[j][..diag_slot[j] as usize].iter().map(move |&i| {
                nbrs[i as usize]
                    .binary_search(&(j as u32))
                    .expect("symmetric pattern") as u32
            })
        })
        .collect();
    (diag_slot, upper_start, upper_src)
}

/// Which elements may be assembled concurrently (`partition.rs`), by their free vertices
/// only (held ones are never written); elements that touch a rigid group are assembled
/// apart (`groups.elements`).
fn assembly_parts(sys: &SolidSystem, free_of: &[u32], groups: &rigid::Groups) -> partition::Part {
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
    partition::partition(stencils, sys.mass.len(), &sys.layout)
}

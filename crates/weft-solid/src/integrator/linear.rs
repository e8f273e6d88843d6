//! The linear system's room: the sparsity pattern of H over the free vertices (both
//! triangles, 3×3 blocks stored whole), each element's slots in it, the assembled values,
//! and the helpers that address them. Built with the integrator (`Integrator::build`) and
//! rebuilt only when the structure or the contacts' extra blocks change; assembly scatters
//! into it, the direction solver (`factor.rs`, `one_ring.rs`) reads it.

use super::partition;
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
    /// only (half the scatter's loads and stores) and [`Integrator::mirror_upper`] copies it up.
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

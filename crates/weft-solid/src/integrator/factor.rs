//! The Newton system's sparse Cholesky factorization: a fill-reducing ordering chosen for
//! the pattern (`order.rs`), its symbolic analysis, and the numeric factorization and solve,
//! whole or as two halves at once (`split.rs`). The integrator holds one for the system
//! matrix, another for the one-ring preconditioner where it has one (`one_ring.rs`), and
//! where H's is large a single-precision twin of H's, sharing its analyses
//! ([`Factor::single_twin`]).
//!
//! Each factorization is sequential (`Par::Seq` throughout): faer's parallel supernodal
//! Cholesky changes its reduction order with the thread count (a cloth's factor then
//! differs in the last bits between 1 and 2 threads), and results must be bit-identical at
//! any count; on large sheets it is also slower here (`weft bench solid` measures it;
//! figures in docs/history/issue-71-comments.md). Threads go to assembly and to the split's
//! two halves.

use super::analysis::Analysis;
use super::{order, solve, split, value_index};
use crate::settings::StepError;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
use faer::{Conj, MatMut, Par};
use nalgebra::Vector3;
use std::sync::Arc;

/// Factors cheaper than this keep minimum degree without trying nested dissection: there the
/// flop count does not predict the time (dissection's leaves make many small supernodes),
/// and hair, whose chains minimum degree orders without fill, stays as it was. On the
/// hanging cloth, dissection's factorization is slower than minimum degree's below about
/// this count and ever faster above it (`weft bench solid` measures it; figures in
/// docs/history/issue-71-comments.md).
pub(super) const DISSECTION_MIN_FLOPS: f64 = 5e8;

/// Factorizations from this many flops are tried split in two halves factored concurrently
/// (`split.rs`), and kept when the larger half and the separator cost less than
/// [`SPLIT_GAIN`] of the whole. On the hanging cloth with 2 threads, below this count a
/// split factorization can still be faster on its own while the run as a whole is not;
/// from it up the split pays at every size (`weft bench solid` and `graphs/cloth_hang.json`
/// measure it; figures in docs/history/issue-71-comments.md).
const SPLIT_MIN_FLOPS: f64 = 1e7;
const SPLIT_GAIN: f64 = 0.75;

/// Nested dissection replaces minimum degree only with at most this fraction of its flops.
pub(super) const DISSECTION_GAIN: f64 = 0.8;

/// A factorization of one pattern (`col_ptr`/`row_idx`: both triangles, 3×3 blocks, values
/// stored by whole blocks): its analysis, and either its factor or its split's.
pub(super) struct Factor {
    /// The fill-reducing permutation (DOF `analysis.fwd[i]` is unknown i of the factor), the
    /// lower triangle of P A Pᵀ with each entry's index in `values`, and its symbolic
    /// factorization (whose own ordering is the identity: the permutation is applied by
    /// gathering). Shared with the single-precision twin ([`Self::single_twin`]): it never
    /// changes after `new`.
    pub(super) analysis: Arc<Analysis>,
    l_values: Vec<f64>,
    /// The gathered lower triangle's values.
    lower_values: Vec<f64>,
    /// A right-hand side in the factor's order.
    permuted: Vec<f64>,
    /// Scratch of the own one-right-hand-side solve (`solve.rs`), as long as the longest
    /// pattern below a supernode's diagonal block; `None` when the factor has wide
    /// supernodes and faer's solve is used.
    narrow_tmp: Option<Vec<f64>>,
    mem: MemBuffer,
    /// Where set, factorizations and solves go through the two-halves split (`split.rs`).
    pub(super) split: Option<split::Split>,
    /// Where set, the factor is nearly dense and small: factored as a dense matrix.
    dense: Option<Dense>,
    /// Where set, the split's halves are factored in single precision (a preconditioner's
    /// factor, [`Self::single_twin`]).
    single: Option<Single>,
    /// The bytes this factor was checked for against the memory limit ([`Self::bytes`]).
    bytes: u64,
}

/// Refuses `need` bytes for `what` beyond the memory limit `max_bytes`, if any.
fn within(need: u64, max_bytes: Option<u64>, what: &'static str) -> Result<(), StepError> {
    match max_bytes {
        Some(limit) if need > limit => Err(crate::settings::too_large(
            what,
            need,
            limit,
            crate::settings::FEWER_VERTICES,
        )),
        _ => Ok(()),
    }
}

/// A single-precision factor's diagonal scaling: the matrix factored is D A D with
/// D = diag(1/√A_dd), so its diagonal is one and f32's range holds its entries.
struct Single {
    /// Per DOF: its diagonal entry's index in `values`.
    diag: Vec<usize>,
    /// Per DOF: 1/√A_dd at the last factorization.
    scale: Vec<f64>,
}

/// Systems of at most [`DENSE_MAX`] unknowns whose dense factorization (n³/3 flops) costs at
/// most [`DENSE_FLOPS`] times the sparse one's flops are factored dense: on a small sheet
/// with shell bending (every vertex coupled to its two-ring, so a 5 × 5 grid's matrix is
/// nearly full) the supernodal factorization's updates between its many small supernodes
/// cost more than the fill they skip. The 4² square of `bench/peers` (dense under twice the
/// sparse flops) factors faster dense; the 10-segment ribbon and cantilever and the 6²
/// square, at several times the sparse flops, do not, and stay sparse (figures in
/// docs/history/issue-71-comments.md).
const DENSE_MAX: usize = 192;
const DENSE_FLOPS: f64 = 2.5;

/// A small, nearly dense factor: the permuted lower triangle scattered into a dense matrix
/// (column-major), factored in place.
struct Dense {
    /// Per entry of the analysis' lower pattern: its index in `a`.
    at: Vec<usize>,
    /// The lower triangle's other entries (the factor's fill), zeroed before each
    /// factorization (the upper triangle is never read).
    fill: Vec<usize>,
    a: Vec<f64>,
}

impl Factor {
    /// Orders and analyses the pattern of the vertex graph `nbrs` (block neighbours of each
    /// node, itself included, sorted; `col_ptr`/`row_idx` its DOF pattern): minimum degree,
    /// and where `at` says where the first nodes sit, nested dissection too, the one whose
    /// factor costs fewer flops kept (`order.rs`); split in two halves where `may_split` and
    /// it pays. `held`: the bytes the caller holds for this pattern (its indices, values and
    /// the like). Refuses, beside those, analyses whose arrays and temporaries would take
    /// more than `max_bytes` before computing them, and a factor that would before
    /// allocating it.
    pub(super) fn new(
        nbrs: &[Vec<u32>],
        col_ptr: &[usize],
        row_idx: &[usize],
        at: &[Vector3<f64>],
        may_split: bool,
        (max_bytes, held): (Option<u64>, u64),
    ) -> Result<Self, StepError> {
        // The analyses' peak, bounded before any: the ordering's copy of the vertex graph and
        // its scratch, and per entry of the lower triangle (at most half the pattern's
        // entries and the diagonal) 64 bytes: the kept analysis' row and gather indices
        // (16), its transpose for faer's symbolic analysis (8) and the symbolic structure
        // (at most 8, well above what a sheet's structure takes), and as much again for the
        // second analysis alive beside it (nested dissection's, or the split's two halves).
        let dofs = col_ptr.len() - 1;
        let lower = (row_idx.len() / 2 + dofs) as u64;
        let graph: u64 = nbrs.iter().map(|l| 24 + 4 * l.len() as u64).sum();
        let analyses = 64u64
            .saturating_mul(lower)
            .saturating_add(graph.saturating_mul(4))
            .saturating_add(64 * dofs as u64);
        within(
            held.saturating_add(analyses),
            max_bytes,
            "the Cholesky factor's analysis",
        )?;
        // Fill-reducing ordering on the vertex graph (a third of the size, a ninth of the
        // nonzeros of the DOF graph), expanded to keep each vertex's three DOFs together: the
        // factor's supernodes then align with the 3×3 blocks.
        let mut analysis = Analysis::new(
            &order::minimum_degree(nbrs).map_err(StepError::Factorization)?,
            col_ptr,
            row_idx,
        )?;
        if !at.is_empty()
            && analysis.flops >= DISSECTION_MIN_FLOPS
            && let Some(nd) = order::nested_dissection(nbrs, at)
        {
            let other = Analysis::new(&nd, col_ptr, row_idx)?;
            if other.flops < DISSECTION_GAIN * analysis.flops {
                analysis = other;
            }
        }
        // Held whatever the factorization: the caller's, the analysis kept, the right-hand
        // side.
        let held = held
            .saturating_add(analysis.bytes())
            .saturating_add(8 * dofs as u64);
        // Two halves factored at once (`split.rs`) where the factor is large enough to pay
        // for the separator's dense work, and they fit beside what is held.
        let split = if may_split && analysis.flops >= SPLIT_MIN_FLOPS {
            let order: Vec<usize> = analysis.fwd.iter().step_by(3).map(|&d| d / 3).collect();
            split::Split::new(
                nbrs,
                &order,
                (col_ptr, row_idx),
                at,
                SPLIT_GAIN * analysis.flops,
                max_bytes.map(|m| m.saturating_sub(held)),
            )?
        } else {
            None
        };
        let par = Par::Seq;
        let symbolic = &analysis.symbolic;
        let scratch = symbolic
            .factorize_numeric_llt_scratch::<f64>(par, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, par))
            .or(
                faer::linalg::cholesky::llt::factor::cholesky_in_place_scratch::<f64>(
                    dofs,
                    par,
                    Default::default(),
                ),
            );
        // Then the split's buffers (checked in `Split::new`) or the whole factor's and its
        // scratch.
        let need = match &split {
            Some(sp) => held.saturating_add(sp.bytes),
            None => held
                .saturating_add(8 * (symbolic.len_val() + analysis.lower_row.len()) as u64)
                .saturating_add(scratch.size_bytes() as u64),
        };
        within(need, max_bytes, "the Cholesky factor")?;
        let dense = (split.is_none()
            && dofs <= DENSE_MAX
            && (dofs as f64).powi(3) / 3.0 <= DENSE_FLOPS * analysis.flops)
            .then(|| {
                let at: Vec<usize> = (0..dofs)
                    .flat_map(|c| {
                        let rows =
                            &analysis.lower_row[analysis.lower_ptr[c]..analysis.lower_ptr[c + 1]];
                        rows.iter().map(move |&r| r + c * dofs)
                    })
                    .collect();
                let mut lower = vec![false; dofs * dofs];
                at.iter().for_each(|&k| lower[k] = true);
                let fill = (0..dofs)
                    .flat_map(|c| (c..dofs).map(move |r| r + c * dofs))
                    .filter(|&k| !lower[k])
                    .collect();
                Dense {
                    at,
                    fill,
                    a: vec![0.0; dofs * dofs],
                }
            });
        // A split system factors its halves (`split.rs`): no whole factor to hold.
        let whole = if split.is_some() || dense.is_some() {
            0
        } else {
            1
        };
        let narrow_tmp = match symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(sn) => solve::narrow(sn).map(|m| vec![0.0; m]),
            SymbolicCholeskyRaw::Simplicial(_) => None,
        };
        Ok(Factor {
            l_values: vec![0.0; whole * symbolic.len_val()],
            lower_values: vec![0.0; whole * analysis.lower_row.len()],
            permuted: vec![0.0; dofs],
            narrow_tmp,
            mem: MemBuffer::new(if split.is_none() {
                scratch
            } else {
                faer::dyn_stack::StackReq::EMPTY
            }),
            analysis: Arc::new(analysis),
            split,
            dense,
            single: None,
            bytes: need,
        })
    }

    /// A twin of this factor, approximate: the same analyses (shared, not redone: ordering
    /// and symbolic analysis are costly at the largest sizes), its split's halves factored
    /// in single precision, of the matrix scaled to a unit diagonal, so a solve with it is
    /// A⁻¹'s to about f32's precision times A's conditioning — a preconditioner for conjugate
    /// gradients on A in f64 (`one_ring.rs`), not an answer. f32's supernodal factorization
    /// takes clearly less than f64's time on large sheets (`weft bench solid` measures it;
    /// figures in docs/history/issue-71-comments.md). `None` where the factor is not split or
    /// its halves are hair-like (the own narrow solve is f64 only). `col_ptr`/`row_idx`: the
    /// pattern it was built for. Refuses a twin larger than `max_bytes` (its own buffers)
    /// before allocating it.
    pub(super) fn single_twin(
        &self,
        col_ptr: &[usize],
        row_idx: &[usize],
        max_bytes: Option<u64>,
    ) -> Result<Option<Self>, StepError> {
        let Some(split) = self.split.as_ref() else {
            return Ok(None);
        };
        let dofs = col_ptr.len() - 1;
        // The split's f32 buffers, and the scaling's diagonal indices, scale and the
        // right-hand side.
        let bytes = split.single_bytes().saturating_add(24 * dofs as u64);
        within(bytes, max_bytes, "the single-precision Cholesky factor")?;
        let Some(split) = split.single_twin() else {
            return Ok(None);
        };
        let Some(diag) = (0..dofs)
            .map(|c| {
                (col_ptr[c]..col_ptr[c + 1])
                    .find(|&k| row_idx[k] == c)
                    .map(|k| value_index(col_ptr, k, c))
            })
            .collect::<Option<Vec<usize>>>()
        else {
            return Ok(None);
        };
        Ok(Some(Factor {
            analysis: Arc::clone(&self.analysis),
            l_values: Vec::new(),
            lower_values: Vec::new(),
            permuted: vec![0.0; dofs],
            narrow_tmp: None,
            mem: MemBuffer::new(faer::dyn_stack::StackReq::EMPTY),
            split: Some(split),
            dense: None,
            single: Some(Single {
                diag,
                scale: vec![1.0; dofs],
            }),
            bytes,
        }))
    }

    /// The memory this factor holds, as estimated against the limit before allocating it (for
    /// a system's factor, with the caller's pattern and values counted too): what is left of
    /// the limit for the next factor ([`StepError::TooLarge`] otherwise).
    pub(super) fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Floating-point operations of one numeric factorization (the split's where split).
    pub(super) fn flops(&self) -> f64 {
        self.split
            .as_ref()
            .map_or(self.analysis.flops, |sp| sp.flops)
    }

    /// One numeric Cholesky factorization of `values`: into the factor, or the split's
    /// halves. An error means a non-positive pivot: the matrix is not positive definite.
    pub(super) fn factor(&mut self, values: &[f64]) -> Result<(), faer::linalg::solvers::LltError> {
        let scale = match self.single.as_mut() {
            Some(single) => {
                for (s, &k) in single.scale.iter_mut().zip(&single.diag) {
                    let d = values[k];
                    // Not a positive diagonal (or not finite): not positive definite.
                    if !(d > 0.0 && d.is_finite()) {
                        return Err(faer::linalg::solvers::LltError::NonPositivePivot { index: 0 });
                    }
                    *s = 1.0 / d.sqrt();
                }
                Some(single.scale.as_slice())
            }
            None => None,
        };
        if let Some(sp) = self.split.as_mut() {
            return if sp.factor(values, scale) {
                Ok(())
            } else {
                Err(faer::linalg::solvers::LltError::NonPositivePivot { index: 0 })
            };
        }
        if let Some(d) = self.dense.as_mut() {
            let n = self.analysis.fwd.len();
            d.fill.iter().for_each(|&k| d.a[k] = 0.0);
            for (&at, &k) in d.at.iter().zip(&self.analysis.lower_src) {
                d.a[at] = values[k];
            }
            let a = MatMut::from_column_major_slice_mut(&mut d.a, n, n);
            return faer::linalg::cholesky::llt::factor::cholesky_in_place(
                a,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut self.mem),
                Default::default(),
            )
            .map(|_| ());
        }
        self.analysis.factor(
            values,
            &mut self.lower_values,
            &mut self.l_values,
            &mut self.mem,
        )
    }

    /// Solves with the last factor in place (`b` ← A⁻¹ b).
    pub(super) fn solve_in_place(&mut self, b: &mut [f64]) {
        if let Some(sp) = self.split.as_mut() {
            match self.single.as_ref() {
                // (D A D)⁻¹ = D⁻¹ A⁻¹ D⁻¹, so A⁻¹ b = D (D A D)⁻¹ D b.
                Some(single) => {
                    b.iter_mut().zip(&single.scale).for_each(|(v, s)| *v *= s);
                    sp.solve_in_place(b);
                    b.iter_mut().zip(&single.scale).for_each(|(v, s)| *v *= s);
                }
                None => sp.solve_in_place(b),
            }
            return;
        }
        let dofs = self.analysis.fwd.len();
        for (p, &i) in self.permuted.iter_mut().zip(&self.analysis.fwd) {
            *p = b[i];
        }
        if let Some(d) = self.dense.as_ref() {
            let l = faer::MatRef::from_column_major_slice(&d.a, dofs, dofs);
            let rhs = MatMut::from_column_major_slice_mut(&mut self.permuted, dofs, 1);
            faer::linalg::cholesky::llt::solve::solve_in_place_with_conj(
                l,
                Conj::No,
                rhs,
                Par::Seq,
                MemStack::new(&mut self.mem),
            );
        } else {
            match (self.analysis.symbolic.raw(), self.narrow_tmp.as_mut()) {
                // Hair-like factors (every supernode narrow): see `solve.rs` for why not faer's.
                (SymbolicCholeskyRaw::Supernodal(sn), Some(tmp)) => {
                    solve::supernodal_solve(sn, &self.l_values, &mut self.permuted, tmp);
                }
                _ => {
                    let llt = faer::sparse::linalg::cholesky::LltRef::new(
                        &self.analysis.symbolic,
                        &self.l_values,
                    );
                    let rhs = MatMut::from_column_major_slice_mut(&mut self.permuted, dofs, 1);
                    llt.solve_in_place_with_conj(
                        Conj::No,
                        rhs,
                        Par::Seq,
                        MemStack::new(&mut self.mem),
                    );
                }
            }
        }
        for (&p, &i) in self.permuted.iter().zip(&self.analysis.fwd) {
            b[i] = p;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    impl Factor {
        /// The same factor without its dense form (the supernodal one), for comparison.
        fn sparse_only(mut self) -> Self {
            self.dense = None;
            self.l_values = vec![0.0; self.analysis.symbolic.len_val()];
            self.lower_values = vec![0.0; self.analysis.lower_row.len()];
            self
        }
    }

    /// A 4 × 4 two-ring grid (48 unknowns, nearly full; `split.rs`'s test grid and SPD
    /// matrix) is factored dense; its solve agrees with the supernodal factor's to rounding,
    /// and both refuse an indefinite matrix.
    #[test]
    fn a_small_nearly_full_system_is_factored_dense_with_the_sparse_answer() {
        use super::super::split::tests::{grid, spd};
        let (nbrs, _, col_ptr, row_idx) = grid(4);
        let values = spd(&col_ptr, &row_idx);
        let mut dense = Factor::new(&nbrs, &col_ptr, &row_idx, &[], false, (None, 0)).unwrap();
        assert!(dense.dense.is_some());
        let mut sparse = Factor::new(&nbrs, &col_ptr, &row_idx, &[], false, (None, 0))
            .unwrap()
            .sparse_only();
        dense.factor(&values).unwrap();
        sparse.factor(&values).unwrap();
        let b: Vec<f64> = (0..48).map(|i| (i as f64 * 0.37).sin()).collect();
        let (mut x, mut y) = (b.clone(), b.clone());
        dense.solve_in_place(&mut x);
        sparse.solve_in_place(&mut y);
        for (p, q) in x.iter().zip(&y) {
            // Both are backward stable on a well-conditioned (diagonally dominant) matrix.
            assert!((p - q).abs() <= 1e-13 * q.abs().max(1e-2), "{p} {q}");
        }
        // A's residual: the dense solve answers the system itself.
        let mut ax = vec![0.0; 48];
        for c in 0..48 {
            for p in col_ptr[c]..col_ptr[c + 1] {
                ax[row_idx[p]] += values[value_index(&col_ptr, p, c)] * x[c];
            }
        }
        for (r, bi) in ax.iter().zip(&b) {
            assert!((r - bi).abs() < 1e-12, "{r} {bi}");
        }
        // The diagonal made negative: both refuse it.
        let mut indefinite = values.clone();
        for c in 0..48 {
            for p in col_ptr[c]..col_ptr[c + 1] {
                if row_idx[p] == c {
                    indefinite[value_index(&col_ptr, p, c)] = -1.0;
                }
            }
        }
        assert!(dense.factor(&indefinite).is_err());
        assert!(sparse.factor(&indefinite).is_err());
        // A 6 × 6 grid's sparse factor costs well under the dense one: kept sparse.
        let (nbrs, _, col_ptr, row_idx) = grid(6);
        let six = Factor::new(&nbrs, &col_ptr, &row_idx, &[], false, (None, 0)).unwrap();
        assert!(six.dense.is_none());
    }
}

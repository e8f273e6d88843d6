//! A fill-reducing ordering applied to a pattern: the permuted lower triangle and its
//! symbolic Cholesky factorization (`Analysis`), shared by the whole factor (`factor.rs`) and
//! the split's halves (`split.rs`), and the subnormal flush their single-precision numeric
//! factorizations run under.

use super::{block_entry, order};
use crate::settings::StepError;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Par, Side};

/// Scaled entries (the diagonal is one) below this are left out of the single-precision
/// factor: the assembly leaves entries of 1e-108 and less where terms cancel, and in f32 they
/// and the fill they make are subnormal, whose arithmetic runs 5–10× slower.
const SINGLE_FLUSH: f64 = 1e-30;

/// Runs `f` with the SSE unit flushing subnormal results and inputs to zero (MXCSR's FTZ and
/// DAZ), as the single-precision factor's entries decay along a separator's fill and would
/// otherwise turn subnormal: without the flags the f32 factorization is no faster than
/// f64's, with them clearly faster (`weft bench solid` at 128² measures it; figures in
/// docs/history/issue-71-comments.md). The flags are the calling thread's and are restored
/// after; f64 arithmetic elsewhere is untouched.
#[allow(deprecated)]
pub(super) fn flushing<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_getcsr, _mm_setcsr};
        // SAFETY: reading and writing MXCSR's rounding-independent flush bits (FTZ 0x8000,
        // DAZ 0x0040) changes how subnormals are produced, nothing Rust relies on; the old
        // value is restored before returning.
        let old = unsafe { _mm_getcsr() };
        unsafe { _mm_setcsr(old | 0x8040) };
        let r = f();
        unsafe { _mm_setcsr(old) };
        r
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        f()
    }
}

/// A fill-reducing ordering applied: the permuted lower triangle's pattern and its symbolic
/// Cholesky factorization, and what a numeric factorization then costs.
pub(super) struct Analysis {
    /// DOF `fwd[i]` is unknown i of the factor.
    pub(super) fwd: Vec<usize>,
    pub(super) lower_ptr: Vec<usize>,
    pub(super) lower_row: Vec<usize>,
    pub(super) lower_src: Vec<usize>,
    pub(super) symbolic: SymbolicCholesky<usize>,
    /// Floating-point operations of one numeric factorization.
    pub(super) flops: f64,
}

impl Analysis {
    /// The bytes it holds: the permutation, the lower triangle's pattern and gather indices,
    /// and the symbolic factorization's structure.
    pub(super) fn bytes(&self) -> u64 {
        let own =
            self.fwd.len() + self.lower_ptr.len() + self.lower_row.len() + self.lower_src.len();
        let symbolic = match self.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(sn) => {
                sn.row_idx().len() + 4 * (sn.supernode_begin().len() + 1)
            }
            SymbolicCholeskyRaw::Simplicial(_) => self.lower_row.len() + self.fwd.len(),
        };
        8 * (own + symbolic) as u64
    }

    /// The permuted lower triangle's pattern, as faer's view.
    fn lower_pattern(&self) -> SymbolicSparseColMatRef<'_, usize> {
        let dofs = self.fwd.len();
        // SAFETY: `new` checked this pattern with `new_checked`; it never changes after.
        unsafe {
            SymbolicSparseColMatRef::new_unchecked(
                dofs,
                dofs,
                &self.lower_ptr,
                None,
                &self.lower_row,
            )
        }
    }

    /// One numeric Cholesky factorization of the permuted lower triangle gathered from
    /// `values` (the whole pattern's) into `lower_values`, its factor into `l_values`.
    pub(super) fn factor(
        &self,
        values: &[f64],
        lower_values: &mut [f64],
        l_values: &mut [f64],
        mem: &mut MemBuffer,
    ) -> Result<(), faer::linalg::solvers::LltError> {
        for (v, &k) in lower_values.iter_mut().zip(&self.lower_src) {
            *v = values[k];
        }
        self.numeric(lower_values, l_values, mem)
    }

    /// The numeric factorization of the gathered lower triangle, in f64 or f32.
    fn numeric<T: faer::traits::ComplexField>(
        &self,
        lower_values: &[T],
        l_values: &mut [T],
        mem: &mut MemBuffer,
    ) -> Result<(), faer::linalg::solvers::LltError> {
        self.symbolic
            .factorize_numeric_llt(
                l_values,
                SparseColMatRef::new(self.lower_pattern(), lower_values),
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(mem),
                Default::default(),
            )
            .map(|_| ())
    }

    /// [`Self::factor`] in single precision, of the matrix scaled to a unit diagonal
    /// (`scale[d]` = 1/√A_dd for DOF d): entries below [`SINGLE_FLUSH`] are dropped, and the
    /// factorization runs with subnormals flushed to zero (see [`flushing`]).
    pub(super) fn factor_single(
        &self,
        values: &[f64],
        scale: &[f64],
        lower_values: &mut [f32],
        l_values: &mut [f32],
        mem: &mut MemBuffer,
    ) -> Result<(), faer::linalg::solvers::LltError> {
        let dofs = self.fwd.len();
        for j in 0..dofs {
            let sj = scale[self.fwd[j]];
            for k in self.lower_ptr[j]..self.lower_ptr[j + 1] {
                let v = values[self.lower_src[k]] * sj * scale[self.fwd[self.lower_row[k]]];
                lower_values[k] = if v.abs() < SINGLE_FLUSH {
                    0.0
                } else {
                    v as f32
                };
            }
        }
        flushing(|| self.numeric(lower_values, l_values, mem))
    }

    /// The analysis of the pattern (`col_ptr`, `row_idx`: both triangles, 3×3 blocks) with
    /// its vertices eliminated in the order `order` (`order[i]`: the vertex eliminated i-th).
    /// `order` may list some of the vertices only: the analysis is then of the submatrix of
    /// those (rows of other vertices are left out).
    pub(super) fn new(
        order: &[usize],
        col_ptr: &[usize],
        row_idx: &[usize],
    ) -> Result<Self, StepError> {
        let dofs = 3 * order.len();
        let fwd: Vec<usize> = order
            .iter()
            .flat_map(|&v| [3 * v, 3 * v + 1, 3 * v + 2])
            .collect();
        // Per vertex, its place in `order`.
        let mut inv = vec![usize::MAX; (col_ptr.len() - 1) / 3];
        for (i, &v) in order.iter().enumerate() {
            inv[v] = i;
        }
        // The lower triangle of the permuted matrix P A Pᵀ, (P A Pᵀ)ᵢⱼ = A(fwd i, fwd j), as a
        // pattern of its own with, per entry, where its value sits in `values`: each
        // factorization gathers it in one pass (faer permuting A itself at every
        // factorization would be a noticeable share of the hanging cloth's time). Built a
        // vertex (three columns with the same block rows) at a time, its blocks sorted once:
        // entry by entry the build would be a large share of the analysis at the largest
        // sizes (`weft bench solid` measures both; figures in
        // docs/history/issue-71-comments.md).
        let (mut lower_ptr, mut lower_row, mut lower_src) = (
            Vec::with_capacity(dofs + 1),
            Vec::with_capacity(row_idx.len() / 2 + dofs),
            Vec::with_capacity(row_idx.len() / 2 + dofs),
        );
        lower_ptr.push(0);
        // (place of the row's vertex, block slot) of the blocks on or below the diagonal.
        let mut blocks: Vec<(usize, usize)> = Vec::new();
        for (j, &v) in order.iter().enumerate() {
            blocks.clear();
            let rows = &row_idx[col_ptr[3 * v]..col_ptr[3 * v + 1]];
            for (s, &r) in rows.iter().step_by(3).enumerate() {
                let i = inv[r / 3];
                if i != usize::MAX && i >= j {
                    blocks.push((i, s));
                }
            }
            blocks.sort_unstable();
            for cc in 0..3 {
                for &(i, s) in &blocks {
                    // The diagonal block's lower triangle only.
                    let first = if i == j { cc } else { 0 };
                    for rr in first..3 {
                        lower_row.push(3 * i + rr);
                        lower_src.push(block_entry(col_ptr, v, s, rr, cc));
                    }
                }
                lower_ptr.push(lower_row.len());
            }
        }
        // faer's symbolic analysis reads the upper triangle whatever the side when given no
        // ordering (the numeric factorization then takes the lower one): its transpose.
        let mut upper_ptr = vec![0usize; dofs + 1];
        for &r in &lower_row {
            upper_ptr[r + 1] += 1;
        }
        for j in 0..dofs {
            upper_ptr[j + 1] += upper_ptr[j];
        }
        let mut upper_row = vec![0usize; lower_row.len()];
        let mut next = upper_ptr.clone();
        for c in 0..dofs {
            for &r in &lower_row[lower_ptr[c]..lower_ptr[c + 1]] {
                upper_row[next[r]] = c;
                next[r] += 1;
            }
        }
        let sym = SymbolicSparseColMatRef::new_checked(dofs, dofs, &upper_ptr, None, &upper_row);
        // Checked once here: `factor_once` builds its view of the lower pattern unchecked.
        SymbolicSparseColMatRef::new_checked(dofs, dofs, &lower_ptr, None, &lower_row);
        let symbolic = factorize_symbolic_cholesky(
            sym,
            Side::Upper,
            SymmetricOrdering::Identity,
            // Supernodal always: it takes the lower triangle as given (the simplicial one
            // wants the upper and would transpose it each time), and on the hanging cloth
            // the simplicial factorization is several times slower (`weft bench solid`).
            CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
                ..Default::default()
            },
        )
        .map_err(|e| StepError::Factorization(format!("{e:?}")))?;
        let flops = order::supernodal_flops(symbolic.raw());
        Ok(Analysis {
            fwd,
            lower_ptr,
            lower_row,
            lower_src,
            symbolic,
            flops,
        })
    }
}

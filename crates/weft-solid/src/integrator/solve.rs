//! Triangular solves with faer's supernodal Cholesky factor, written for one right-hand side
//! and factors made of small supernodes (hair: chains of a few vertices).
//!
//! faer's own solve hands every supernode to its general dense kernels (a triangular solve
//! and a matrix product, each dispatched through its SIMD layer, with the product gathered in
//! a scratch matrix). A hair factor has thousands of supernodes of 3 to a dozen columns with
//! a few rows below them, where that dispatch costs more than the arithmetic: on
//! hair_on_head, whose contact step's ADMM solves tens of thousands of times a run, these
//! loops are markedly faster than faer's solves. Cloth factors have wide separators where
//! faer's kernels pay (these loops make cloth_pile's solves slower), so the integrator
//! takes this solve only for factors whose every supernode is [`narrow`]. The contact
//! examples' `--stats-json` measure it; figures in docs/history/issue-71-comments.md.
//!
//! The factor's layout (faer 0.24, `SupernodalLltRef::supernode`): supernode s spans columns
//! `begin[s]..end[s]` (w of them); its values, from `col_ptr_for_val[s]`, are a column-major
//! (w + m) × w block: the w × w lower-triangular diagonal block on top, then the m rows
//! listed from `row_idx[col_ptr_for_row_idx[s]]`. Every operation runs in a fixed order on
//! one thread: the same bits at any thread count.

use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;

/// Whether plain loops beat faer's dense kernels on every supernode of the factor (none has
/// 4 columns or more with 24 rows or more below them), and the longest pattern below a
/// diagonal block (the solve's scratch).
pub(super) fn narrow(symbolic: &SymbolicSupernodalCholesky<usize>) -> Option<usize> {
    let (begin, end) = (symbolic.supernode_begin(), symbolic.supernode_end());
    let val_ptr = symbolic.col_ptr_for_val();
    let mut longest = 0;
    for s in 0..begin.len() {
        let w = end[s] - begin[s];
        let m = (val_ptr[s + 1] - val_ptr[s]) / w - w;
        if w >= 4 && m >= 24 {
            return None;
        }
        longest = longest.max(m);
    }
    Some(longest)
}

/// x ← (L Lᵀ)⁻¹ x for the supernodal factor `values` of `symbolic`; `tmp` is scratch of at
/// least the longest supernode pattern ([`narrow`]'s answer).
pub(super) fn supernodal_solve(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    x: &mut [f64],
    tmp: &mut [f64],
) {
    forward(symbolic, values, x, tmp);
    backward(symbolic, values, x, tmp);
}

/// The pieces of one supernode: (first column, width, leading dimension, values, rows below).
fn block<'a>(
    symbolic: &'a SymbolicSupernodalCholesky<usize>,
    values: &'a [f64],
    s: usize,
) -> (usize, usize, usize, &'a [f64], &'a [usize]) {
    let (begin, end) = (symbolic.supernode_begin(), symbolic.supernode_end());
    let (val_ptr, row_ptr, rows) = (
        symbolic.col_ptr_for_val(),
        symbolic.col_ptr_for_row_idx(),
        symbolic.row_idx(),
    );
    let w = end[s] - begin[s];
    let vals = &values[val_ptr[s]..val_ptr[s + 1]];
    let lda = vals.len() / w;
    let pattern = &rows[row_ptr[s]..row_ptr[s] + (lda - w)];
    (begin[s], w, lda, vals, pattern)
}

/// x ← L⁻¹ x (see [`supernodal_solve`]).
pub(super) fn forward(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    x: &mut [f64],
    tmp: &mut [f64],
) {
    let block = |s: usize| block(symbolic, values, s);
    let n_supernodes = symbolic.supernode_begin().len();
    // Forward: L y = x, supernode by supernode. The rows below a supernode's diagonal block
    // gather L_bot · x_top column by column into `tmp` (contiguous, vectorized), then leave
    // it in x in one scatter.
    for s in 0..n_supernodes {
        let (start, w, lda, vals, pattern) = block(s);
        let m = lda - w;
        let t = &mut tmp[..m];
        t.iter_mut().for_each(|v| *v = 0.0);
        for j in 0..w {
            let col = &vals[j * lda..(j + 1) * lda];
            let xj = x[start + j] / col[j];
            x[start + j] = xj;
            for i in j + 1..w {
                x[start + i] -= col[i] * xj;
            }
            for (t, &l) in t.iter_mut().zip(&col[w..]) {
                *t += l * xj;
            }
        }
        for (&r, &t) in pattern.iter().zip(t.iter()) {
            x[r] -= t;
        }
    }
}

/// x ← L⁻ᵀ x (see [`supernodal_solve`]).
pub(super) fn backward(
    symbolic: &SymbolicSupernodalCholesky<usize>,
    values: &[f64],
    x: &mut [f64],
    tmp: &mut [f64],
) {
    let block = |s: usize| block(symbolic, values, s);
    let n_supernodes = symbolic.supernode_begin().len();
    // Backward: Lᵀ x = y, supernodes in reverse; the rows below are gathered once, and each
    // column's dot product with them runs in four lanes (a fixed order: same bits always).
    for s in (0..n_supernodes).rev() {
        let (start, w, lda, vals, pattern) = block(s);
        let m = lda - w;
        let t = &mut tmp[..m];
        for (t, &r) in t.iter_mut().zip(pattern) {
            *t = x[r];
        }
        for j in (0..w).rev() {
            let col = &vals[j * lda..(j + 1) * lda];
            let mut acc = x[start + j] - dot4(&col[w..], t);
            for i in j + 1..w {
                acc -= col[i] * x[start + i];
            }
            x[start + j] = acc / col[j];
        }
    }
}

/// Σ aᵢbᵢ in four interleaved partial sums, added in a fixed order.
fn dot4(a: &[f64], b: &[f64]) -> f64 {
    let mut s = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (a, b) in ca.zip(cb) {
        for k in 0..4 {
            s[k] += a[k] * b[k];
        }
    }
    let mut tail = 0.0;
    for (a, b) in ra.iter().zip(rb) {
        tail += a * b;
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::sparse::linalg::SupernodalThreshold;
    use faer::sparse::linalg::cholesky::{
        CholeskySymbolicParams, LltRef, SymbolicCholeskyRaw, SymmetricOrdering,
        factorize_symbolic_cholesky,
    };
    use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
    use faer::{Conj, MatMut, Par, Side};

    /// A 2-D grid Laplacian plus a diagonal (SPD, fill and supernodes of several widths),
    /// factored by faer: this solve and faer's agree to rounding.
    #[test]
    fn agrees_with_faers_solve_on_a_grid() {
        let k = 12;
        let n = k * k;
        let (mut ptr, mut row, mut val) = (vec![0usize], Vec::new(), Vec::new());
        for j in 0..n {
            let (a, b) = (j / k, j % k);
            // Lower triangle, rows ascending: the diagonal, then the +1 and +k neighbours.
            row.push(j);
            val.push(4.5 + (j % 7) as f64 * 0.1);
            if b + 1 < k {
                row.push(j + 1);
                val.push(-1.0);
            }
            if a + 1 < k {
                row.push(j + k);
                val.push(-1.0);
            }
            ptr.push(row.len());
        }
        // The symbolic analysis reads the upper triangle: the transpose's pattern.
        let mut up: Vec<Vec<usize>> = vec![Vec::new(); n];
        for c in 0..n {
            for &r in &row[ptr[c]..ptr[c + 1]] {
                up[r].push(c);
            }
        }
        let up_ptr: Vec<usize> = std::iter::once(0)
            .chain(up.iter().scan(0, |t, c| {
                *t += c.len();
                Some(*t)
            }))
            .collect();
        let up_row: Vec<usize> = up.concat();
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &up_ptr, None, &up_row);
        let symbolic = factorize_symbolic_cholesky(
            sym,
            Side::Upper,
            SymmetricOrdering::Amd,
            CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
                ..Default::default()
            },
        )
        .unwrap();
        let mut l = vec![0.0; symbolic.len_val()];
        let scratch = symbolic
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        let mut mem = MemBuffer::new(scratch);
        let lower = SymbolicSparseColMatRef::new_checked(n, n, &ptr, None, &row);
        symbolic
            .factorize_numeric_llt(
                &mut l,
                SparseColMatRef::new(lower, &val),
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .unwrap();
        let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
            panic!("forced supernodal");
        };
        assert!(
            (0..sn.n_supernodes()).any(|s| sn.supernode_end()[s] - sn.supernode_begin()[s] > 1),
            "the case must have supernodes wider than a column"
        );
        let b: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 - 5.0).collect();
        let mut ours = b.clone();
        // The factor is of P A Pᵀ: permute in, solve, permute out, as the integrator does.
        let perm = symbolic.perm().unwrap();
        let (fwd, inv) = perm.arrays();
        let mut pb: Vec<f64> = fwd.iter().map(|&i| ours[i]).collect();
        supernodal_solve(sn, &l, &mut pb, &mut vec![0.0; n]);
        for (k, &i) in fwd.iter().enumerate() {
            ours[i] = pb[k];
        }
        let mut theirs = b.clone();
        LltRef::new(&symbolic, &l).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut theirs, n, 1),
            Par::Seq,
            MemStack::new(&mut mem),
        );
        let _ = inv;
        let scale = theirs.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (a, b) in ours.iter().zip(&theirs) {
            // Both are backward stable; the summation orders differ.
            assert!((a - b).abs() <= 1e-13 * scale, "{a} vs {b}");
        }
        // And it solves the system: A x = b to rounding.
        let mut ax = vec![0.0; n];
        for c in 0..n {
            for k in ptr[c]..ptr[c + 1] {
                let r = row[k];
                ax[r] += val[k] * ours[c];
                if r != c {
                    ax[c] += val[k] * ours[r];
                }
            }
        }
        for (a, b) in ax.iter().zip(&b) {
            assert!((a - b).abs() <= 1e-12 * 5.0, "{a} vs {b}");
        }
    }
}

//! The Newton system factored as two halves at once: a Schur complement on a separator.
//!
//! The numeric Cholesky factorization is most of a cloth iteration's time, and faer's runs on
//! one thread (its parallel one changes its sums with the thread count). This splits the
//! system's vertices at the median of their layout (else of their indices) into halves A and
//! B, and takes as separator S the vertices of A that touch B. With A' = A \ S the matrix is
//!
//! `K = [[K_A'A', 0, K_A'S], [0, K_BB, K_BS], [K_SA', K_SB, K_SS]]`.
//!
//! Each half is factored with the separator bordering it, `M_A = [[K_A'A', K_A'S], [K_SA',
//! K_SS]] = F_A F_Aᵀ` (faer's supernodal Cholesky, the two halves concurrently, each
//! sequential). The trailing block of F_A is L_A with `L_A L_Aᵀ = K_SS − U_A`, U_A =
//! K_SA' K_A'A'⁻¹ K_A'S, so the separator's Schur complement is
//! `S̃ = K_SS − U_A − U_B = L_A L_Aᵀ + L_B L_Bᵀ − K_SS`, factored dense. K is positive
//! definite exactly when M_A, M_B and S̃ are (if K is, K_SS − U_A ⪰ S̃ ≻ 0), so a failed
//! factorization still means "not positive definite", as the whole one does.
//!
//! Solve K x = b: forward through F_A with [b_A'; 0] gives y_A' and t_A = −L_A⁻¹ W_Aᵀ y_A'
//! (W_Aᵀ the bordering rows of F_A), likewise B; then S̃ x_S = b_S + L_A t_A + L_B t_B; then
//! backward through F_Aᵀ with [y_A'; L_Aᵀ x_S] gives x_A' (and x_S again), likewise B.
//!
//! Every operation runs in a fixed order and the split depends on the system only (never on
//! the thread count), so the results are the same bits at any thread count; with one thread
//! the halves run one after the other.

use super::analysis::Analysis;
use super::{StepError, solve};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{LltRegularization, cholesky_in_place};
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::reborrow::ReborrowMut;
use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
use faer::sparse::linalg::cholesky::supernodal::{SupernodalLltRef, SymbolicSupernodalCholesky};
use faer::{Accum, Conj, MatMut, MatRef, Par};
use nalgebra::Vector3;
use std::sync::Arc;

/// One half, bordered by the separator.
struct Half {
    /// DOFs before the separator's.
    own: usize,
    /// Unknown i of this half's factor is DOF `analysis.fwd[i]`; the separator's DOFs are the
    /// last `3 · n_sep`, in the separator's order. Shared with a single-precision twin.
    analysis: Arc<Analysis>,
    lower_values: Vec<f64>,
    l_values: Vec<f64>,
    /// The factorization's scratch, and faer's solve's.
    mem: MemBuffer,
    /// The solve's vector in this half's order.
    x: Vec<f64>,
    /// The own solve's scratch where every supernode is narrow (hair-like), else `None`:
    /// faer's solve, as for the whole system (`solve.rs`: faer's kernels pay on cloth, as
    /// cloth_drape's contact solves show; figures in docs/history/issue-71-comments.md).
    narrow_tmp: Option<Vec<f64>>,
    /// The trailing block L of the factor (dense, column-major, lower).
    tail: Vec<f64>,
    /// Where this half is factored in single precision ([`Split::single_twin`]): its lower
    /// triangle, factor and solve vector in f32 (`lower_values` and `l_values` then empty).
    single: Option<HalfSingle>,
}

struct HalfSingle {
    lower_values: Vec<f32>,
    l_values: Vec<f32>,
    x: Vec<f32>,
    /// L Lᵀ of this half's trailing block (its lower triangle), computed as soon as the half
    /// is factored, concurrently with the other half's: run after both halves, the
    /// separator's products are a sizeable share of a large factorization (`weft bench
    /// solid` at 317² measures it; figures in docs/history/issue-71-comments.md).
    gram: Vec<f64>,
}

impl Half {
    /// The half's numeric buffers for its `analysis` (vertices in its order, the separator's
    /// last), `own_vertices` of them before the separator's.
    fn new(analysis: Analysis, own_vertices: usize) -> Self {
        let narrow_tmp = solve::narrow(supernodal(&analysis)).map(|m| vec![0.0; m]);
        let mem = MemBuffer::new(Self::scratch(&analysis));
        let dofs = analysis.fwd.len();
        let sep = dofs - 3 * own_vertices;
        Half {
            own: 3 * own_vertices,
            lower_values: vec![0.0; analysis.lower_row.len()],
            l_values: vec![0.0; analysis.symbolic.len_val()],
            mem,
            x: vec![0.0; dofs],
            narrow_tmp,
            tail: vec![0.0; sep * sep],
            analysis: Arc::new(analysis),
            single: None,
        }
    }

    /// The factorization's and the solve's scratch for `analysis`.
    fn scratch(analysis: &Analysis) -> StackReq {
        analysis
            .symbolic
            .factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default())
            .or(analysis.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq))
    }

    /// The bytes a half holds with `analysis` and a separator of `m` DOFs: the analysis, and
    /// what [`Self::new`] allocates (the gathered lower triangle and the factor, the scratch,
    /// the solve's vectors, the tail).
    fn bytes(analysis: &Analysis, m: usize) -> u64 {
        let narrow = solve::narrow(supernodal(analysis)).unwrap_or(0);
        let entries = analysis.lower_row.len() + analysis.symbolic.len_val();
        let vectors = analysis.fwd.len() + narrow;
        (8 * (entries + vectors) as u64)
            .saturating_add(analysis.bytes())
            .saturating_add(Self::scratch(analysis).size_bytes() as u64)
            .saturating_add(8u64.saturating_mul(m as u64).saturating_mul(m as u64))
    }

    /// This half's single-precision twin (see [`Split::single_twin`]): the same analysis,
    /// f32 buffers.
    fn single_twin(&self) -> Self {
        let symbolic = &self.analysis.symbolic;
        let scratch = symbolic
            .factorize_numeric_llt_scratch::<f32>(Par::Seq, Default::default())
            .or(symbolic.solve_in_place_scratch::<f32>(1, Par::Seq));
        Half {
            own: self.own,
            analysis: Arc::clone(&self.analysis),
            lower_values: Vec::new(),
            l_values: Vec::new(),
            mem: MemBuffer::new(scratch),
            x: vec![0.0; self.x.len()],
            narrow_tmp: None,
            tail: vec![0.0; self.tail.len()],
            single: Some(HalfSingle {
                lower_values: vec![0.0; self.analysis.lower_row.len()],
                l_values: vec![0.0; symbolic.len_val()],
                x: vec![0.0; self.x.len()],
                gram: vec![0.0; self.tail.len()],
            }),
        }
    }

    /// Factors this half's bordered matrix from `values`, and copies the factor's trailing
    /// block into `tail`: whether it was positive definite.
    /// `scale`: where the half is single precision, the whole system's diagonal scaling
    /// (the factor is then of D M D, see `Factor::single_twin`).
    fn factor(&mut self, values: &[f64], scale: Option<&[f64]>) -> bool {
        match (self.single.as_mut(), scale) {
            (Some(single), Some(scale)) => {
                let ok = self
                    .analysis
                    .factor_single(
                        values,
                        scale,
                        &mut single.lower_values,
                        &mut single.l_values,
                        &mut self.mem,
                    )
                    .is_ok();
                if ok {
                    copy_tail(&self.analysis, self.own, &single.l_values, &mut self.tail);
                    let m = self.analysis.fwd.len() - self.own;
                    lower_gram(&self.tail, m, &mut single.gram, Accum::Replace);
                }
                ok
            }
            _ => {
                let ok = self
                    .analysis
                    .factor(
                        values,
                        &mut self.lower_values,
                        &mut self.l_values,
                        &mut self.mem,
                    )
                    .is_ok();
                if ok {
                    copy_tail(&self.analysis, self.own, &self.l_values, &mut self.tail);
                }
                ok
            }
        }
    }

    /// x ← F⁻¹ [b_own; 0]: this half's own DOFs of `b`, the separator's zero (`x`'s tail is
    /// then t = −L⁻¹ Wᵀ y).
    fn forward(&mut self, b: &[f64]) {
        for (x, &d) in self.x[..self.own].iter_mut().zip(&self.analysis.fwd) {
            *x = b[d];
        }
        self.x[self.own..].iter_mut().for_each(|v| *v = 0.0);
        self.triangular_solve(false);
    }

    /// x ← F⁻ᵀ [y; Lᵀ x_S], given the separator's solution `xs`.
    fn backward(&mut self, xs: &[f64]) {
        let m = xs.len();
        let l = MatRef::from_column_major_slice(&self.tail, m, m);
        let xs = MatRef::from_column_major_slice(xs, m, 1);
        let top = MatMut::from_column_major_slice_mut(&mut self.x[self.own..], m, 1);
        matmul(top, Accum::Replace, l.transpose(), xs, 1.0, Par::Seq);
        self.triangular_solve(true);
    }

    /// x ← F⁻¹ x, or F⁻ᵀ x when `transposed`: the own solve where every supernode is narrow,
    /// else faer's.
    fn triangular_solve(&mut self, transposed: bool) {
        let sn = supernodal(&self.analysis);
        let n = self.x.len();
        if let Some(single) = self.single.as_mut() {
            for (y, &v) in single.x.iter_mut().zip(&self.x) {
                *y = v as f32;
            }
            let llt = SupernodalLltRef::new(sn, &single.l_values);
            let x = MatMut::from_column_major_slice_mut(&mut single.x, n, 1);
            let stack = MemStack::new(&mut self.mem);
            super::analysis::flushing(|| {
                if transposed {
                    llt.l_transpose_solve_with_conj(Conj::No, x, Par::Seq, stack);
                } else {
                    llt.l_solve_with_conj(Conj::No, x, Par::Seq, stack);
                }
            });
            for (v, &y) in self.x.iter_mut().zip(&single.x) {
                *v = y.into();
            }
            return;
        }
        match (self.narrow_tmp.as_mut(), transposed) {
            (Some(tmp), false) => solve::forward(sn, &self.l_values, &mut self.x, tmp),
            (Some(tmp), true) => solve::backward(sn, &self.l_values, &mut self.x, tmp),
            (None, _) => {
                let llt = SupernodalLltRef::new(sn, &self.l_values);
                let x = MatMut::from_column_major_slice_mut(&mut self.x, n, 1);
                let stack = MemStack::new(&mut self.mem);
                if transposed {
                    llt.l_transpose_solve_with_conj(Conj::No, x, Par::Seq, stack);
                } else {
                    llt.l_solve_with_conj(Conj::No, x, Par::Seq, stack);
                }
            }
        }
    }
}

/// `tail` ← the rows and columns from `own` on of a half's factor `l_values`.
fn copy_tail<T: Copy + Into<f64>>(
    analysis: &Analysis,
    own: usize,
    l_values: &[T],
    tail: &mut [f64],
) {
    let n = analysis.fwd.len() - own;
    tail.iter_mut().for_each(|v| *v = 0.0);
    let sn = supernodal(analysis);
    let (begin, end) = (sn.supernode_begin(), sn.supernode_end());
    let (val_ptr, row_ptr, rows) = (sn.col_ptr_for_val(), sn.col_ptr_for_row_idx(), sn.row_idx());
    for s in 0..begin.len() {
        if end[s] <= own {
            continue;
        }
        let w = end[s] - begin[s];
        let vals = &l_values[val_ptr[s]..val_ptr[s + 1]];
        let lda = vals.len() / w;
        let pattern = &rows[row_ptr[s]..row_ptr[s] + (lda - w)];
        for c in begin[s].max(own)..end[s] {
            let col = &vals[(c - begin[s]) * lda..(c - begin[s] + 1) * lda];
            let j = c - own;
            for r in c..end[s] {
                tail[(r - own) + j * n] = col[r - begin[s]].into();
            }
            for (k, &r) in pattern.iter().enumerate() {
                tail[(r - own) + j * n] = col[w + k].into();
            }
        }
    }
}

/// The supernodal symbolic factorization of a half (checked in `Split::new`).
fn supernodal(analysis: &Analysis) -> &SymbolicSupernodalCholesky<usize> {
    match analysis.symbolic.raw() {
        SymbolicCholeskyRaw::Supernodal(sn) => sn,
        SymbolicCholeskyRaw::Simplicial(_) => unreachable!("checked in Split::new"),
    }
}

/// The split factorization (see the module's doc).
pub(super) struct Split {
    halves: [Half; 2],
    /// The separator's DOFs, in the halves' trailing order.
    sep: Vec<usize>,
    /// K_SS's lower triangle: (row, column, index in `values`), in the separator's order.
    kss: Vec<(usize, usize, usize)>,
    /// S̃, then its dense Cholesky factor (column-major, lower).
    schur: Vec<f64>,
    /// The separator's right-hand side and solution.
    xs: Vec<f64>,
    mem: MemBuffer,
    /// Flops of the larger half's factorization plus the separator's dense work.
    pub(super) flops: f64,
    /// The bytes its buffers take, as estimated before allocating them.
    pub(super) bytes: u64,
}

impl Split {
    /// The split of the system whose vertex graph is `nbrs` (sorted, itself included) and
    /// whose value pattern is `col_ptr`/`row_idx` (3×3 blocks), with vertices eliminated
    /// within each half in the order they have in `order` (the whole system's ordering).
    /// `at`: the vertices' positions, or empty. None when the split is degenerate, when one
    /// factorization of it would cost `max_flops` or more, or when its buffers would take
    /// more than `max_bytes`: all three are known from the halves' symbolic analyses, before
    /// any numeric buffer is allocated (a separator of m DOFs holds three dense m × m
    /// matrices, 3.4 GB at m = 20k: a 24 × 2424 sheet cut across its length).
    pub(super) fn new(
        nbrs: &[Vec<u32>],
        order: &[usize],
        (col_ptr, row_idx): (&[usize], &[usize]),
        at: &[Vector3<f64>],
        max_flops: f64,
        max_bytes: Option<u64>,
    ) -> Result<Option<Self>, StepError> {
        let n = nbrs.len();
        if n < 8 {
            return Ok(None);
        }
        let mut verts: Vec<u32> = (0..n as u32).collect();
        let mid = n / 2;
        if at.len() == n && at.iter().all(|p| p.iter().all(|c| c.is_finite())) {
            let (mut lo, mut hi) = (at[0], at[0]);
            for p in at {
                lo = lo.inf(p);
                hi = hi.sup(p);
            }
            let axis = (hi - lo).imax();
            verts.sort_by(|&a, &b| {
                at[a as usize][axis]
                    .total_cmp(&at[b as usize][axis])
                    .then(a.cmp(&b))
            });
        }
        // side: 0 = A', 1 = B, 2 = separator (vertices of A touching B). The cut moves once
        // by half the first separator, so that A' and B get about as many vertices.
        let mut side = vec![1u8; n];
        let cut = |mid: usize, side: &mut Vec<u8>| {
            side.iter_mut().for_each(|s| *s = 1);
            for &v in &verts[..mid] {
                side[v as usize] = 0;
            }
            for &v in &verts[..mid] {
                if nbrs[v as usize].iter().any(|&u| side[u as usize] == 1) {
                    side[v as usize] = 2;
                }
            }
            side.iter().filter(|&&s| s == 2).count()
        };
        let first = cut(mid, &mut side);
        cut((mid + first / 2).min(n - 1), &mut side);
        let sep_vertices: Vec<usize> = (0..n).filter(|&v| side[v] == 2).collect();
        let count = |k: u8| side.iter().filter(|&&s| s == k).count();
        let (na, nb, ns) = (count(0), count(1), sep_vertices.len());
        // A separator as large as a half gains nothing.
        if na == 0 || nb == 0 || 4 * ns > n {
            return Ok(None);
        }
        // The separator's dense work alone (m³ flops, below) already too dear: no analyses.
        let mf = (3 * ns) as f64;
        if mf * mf * mf >= max_flops {
            return Ok(None);
        }
        let half_order = |k: u8| -> Vec<usize> {
            let mut o: Vec<usize> = order.iter().copied().filter(|&v| side[v] == k).collect();
            o.extend(&sep_vertices);
            o
        };
        // The halves' analyses are independent: concurrently (each is costly on large sheets).
        let (a, b) = rayon::join(
            || Analysis::new(&half_order(0), col_ptr, row_idx),
            || Analysis::new(&half_order(1), col_ptr, row_idx),
        );
        let (a, b) = (a?, b?);
        for h in [&a, &b] {
            if !matches!(h.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_)) {
                return Err(StepError::Factorization(
                    "expected a supernodal analysis".into(),
                ));
            }
        }
        // Two triangular products (m³/3 flops each) and a dense Cholesky (m³/3).
        let flops = a.flops.max(b.flops) + mf * mf * mf;
        let sep: Vec<usize> = sep_vertices
            .iter()
            .flat_map(|&v| [3 * v, 3 * v + 1, 3 * v + 2])
            .collect();
        let m = sep.len();
        let mut pos = vec![usize::MAX; col_ptr.len() - 1];
        for (i, &d) in sep.iter().enumerate() {
            pos[d] = i;
        }
        let mut kss = Vec::new();
        for (j, &d) in sep.iter().enumerate() {
            for k in col_ptr[d]..col_ptr[d + 1] {
                let i = pos[row_idx[k]];
                if i != usize::MAX && i >= j {
                    kss.push((i, j, super::value_index(col_ptr, k, d)));
                }
            }
        }
        let scratch = faer::linalg::cholesky::llt::factor::cholesky_in_place_scratch::<f64>(
            m,
            Par::Seq,
            Default::default(),
        );
        if flops >= max_flops {
            return Ok(None);
        }
        let mm = 8u64.saturating_mul(m as u64).saturating_mul(m as u64);
        let bytes = Half::bytes(&a, m)
            .saturating_add(Half::bytes(&b, m))
            .saturating_add(mm)
            .saturating_add(8 * 2 * m as u64)
            .saturating_add((std::mem::size_of::<(usize, usize, usize)>() * kss.len()) as u64)
            .saturating_add(scratch.size_bytes() as u64);
        // Too large to hold: the whole factor may still fit (the caller checks it).
        if max_bytes.is_some_and(|limit| bytes > limit) {
            return Ok(None);
        }
        Ok(Some(Split {
            halves: [Half::new(a, na), Half::new(b, nb)],
            sep,
            kss,
            schur: vec![0.0; m * m],
            xs: vec![0.0; m],
            mem: MemBuffer::new(scratch),
            flops,
            bytes,
        }))
    }

    /// The twin of this split factored in single precision (`Factor::single_twin`): the
    /// same halves, separator and analyses, with f32 buffers. `None` where a half is
    /// hair-like (its own narrow solve is f64 only).
    pub(super) fn single_twin(&self) -> Option<Self> {
        if self.halves.iter().any(|h| h.narrow_tmp.is_some()) {
            return None;
        }
        let m = self.sep.len();
        Some(Split {
            halves: [self.halves[0].single_twin(), self.halves[1].single_twin()],
            sep: self.sep.clone(),
            kss: self.kss.clone(),
            schur: vec![0.0; m * m],
            xs: vec![0.0; m],
            mem: MemBuffer::new(
                faer::linalg::cholesky::llt::factor::cholesky_in_place_scratch::<f64>(
                    m,
                    Par::Seq,
                    Default::default(),
                ),
            ),
            flops: self.flops,
            bytes: self.single_bytes(),
        })
    }

    /// The bytes [`Self::single_twin`] allocates: each half's f32 lower triangle and factor
    /// (4 bytes an entry), its tail and gram (f64, m² each), its vectors and f32 scratch, and
    /// the separator's dense matrix, vectors and copy of K_SS's entries.
    pub(super) fn single_bytes(&self) -> u64 {
        let m = self.sep.len() as u64;
        let halves: u64 = self
            .halves
            .iter()
            .map(|h| {
                let symbolic = &h.analysis.symbolic;
                let entries = (h.analysis.lower_row.len() + symbolic.len_val()) as u64;
                let scratch = symbolic
                    .factorize_numeric_llt_scratch::<f32>(Par::Seq, Default::default())
                    .or(symbolic.solve_in_place_scratch::<f32>(1, Par::Seq));
                4 * entries + 16 * m * m + 12 * h.x.len() as u64 + scratch.size_bytes() as u64
            })
            .sum();
        let kss = std::mem::size_of::<(usize, usize, usize)>() * self.kss.len();
        let dense = faer::linalg::cholesky::llt::factor::cholesky_in_place_scratch::<f64>(
            m as usize,
            Par::Seq,
            Default::default(),
        );
        halves + 8 * m * m + 16 * m + kss as u64 + dense.size_bytes() as u64
    }

    /// Factors `values` (the whole pattern's): whether the matrix is positive definite.
    /// `scale`: for single-precision halves, the diagonal scaling D of the matrix factored,
    /// D A D (`Factor::single_twin`).
    pub(super) fn factor(&mut self, values: &[f64], scale: Option<&[f64]>) -> bool {
        let [a, b] = &mut self.halves;
        let (ok_a, ok_b) = rayon::join(|| a.factor(values, scale), || b.factor(values, scale));
        if !(ok_a && ok_b) {
            return false;
        }
        let m = self.sep.len();
        // S̃ = L_A L_Aᵀ + L_B L_Bᵀ − K_SS (only the lower half is read).
        match (&self.halves[0].single, &self.halves[1].single) {
            (Some(a), Some(b)) => {
                for j in 0..m {
                    for i in j..m {
                        let k = i + j * m;
                        self.schur[k] = a.gram[k] + b.gram[k];
                    }
                }
            }
            _ => {
                lower_gram(&self.halves[0].tail, m, &mut self.schur, Accum::Replace);
                lower_gram(&self.halves[1].tail, m, &mut self.schur, Accum::Add);
            }
        }
        let mut s = MatMut::from_column_major_slice_mut(&mut self.schur, m, m);
        match scale {
            Some(d) => {
                for &(i, j, k) in &self.kss {
                    s[(i, j)] -= values[k] * d[self.sep[i]] * d[self.sep[j]];
                }
            }
            None => {
                for &(i, j, k) in &self.kss {
                    s[(i, j)] -= values[k];
                }
            }
        }
        cholesky_in_place(
            s,
            LltRegularization {
                dynamic_regularization_delta: 0.0,
                dynamic_regularization_epsilon: 0.0,
            },
            Par::Seq,
            MemStack::new(&mut self.mem),
            Default::default(),
        )
        .is_ok()
    }

    /// b ← K⁻¹ b with the last factorization (`b` in the whole system's DOF order). The
    /// halves' triangular solves run concurrently, as their factorizations do: they are
    /// most of the solve, and one after the other the split's solve would be slower than
    /// the whole factor's (`weft bench solid` measures it; figures in
    /// docs/history/issue-71-comments.md).
    pub(super) fn solve_in_place(&mut self, b: &mut [f64]) {
        let m = self.sep.len();
        // Forward through each half with the separator's entries zero.
        let [ha, hb] = &mut self.halves;
        let rhs: &[f64] = b;
        rayon::join(|| ha.forward(rhs), || hb.forward(rhs));
        // The separator: S̃ x_S = b_S + L_A t_A + L_B t_B (L lower-triangular, dense).
        for (x, &d) in self.xs.iter_mut().zip(&self.sep) {
            *x = b[d];
        }
        // faer's dense kernels: as plain loops these products are a sizeable share of the
        // split's solve even at small separators (figures in docs/history/issue-71-comments.md).
        for h in &self.halves {
            let l = MatRef::from_column_major_slice(&h.tail, m, m);
            let t = MatRef::from_column_major_slice(&h.x[h.own..], m, 1);
            let xs = MatMut::from_column_major_slice_mut(&mut self.xs, m, 1);
            matmul(xs, Accum::Add, l, t, 1.0, Par::Seq);
        }
        dense_solve(&self.schur, m, &mut self.xs);
        // Backward through each half from [y; Lᵀ x_S].
        let [ha, hb] = &mut self.halves;
        let xs: &[f64] = &self.xs;
        rayon::join(|| ha.backward(xs), || hb.backward(xs));
        for h in &self.halves {
            for (&x, &d) in h.x[..h.own].iter().zip(&h.analysis.fwd) {
                b[d] = x;
            }
        }
        for (&x, &d) in self.xs.iter().zip(&self.sep) {
            b[d] = x;
        }
    }
}

/// `out` ← (or +=, by `acc`) L Lᵀ's lower triangle, for a dense lower-triangular L
/// (column-major, m × m; only its lower triangle is read).
fn lower_gram(l: &[f64], m: usize, out: &mut [f64], acc: Accum) {
    use faer::linalg::matmul::triangular::{BlockStructure, matmul};
    let l = MatRef::from_column_major_slice(l, m, m);
    matmul(
        MatMut::from_column_major_slice_mut(out, m, m),
        BlockStructure::TriangularLower,
        acc,
        l,
        BlockStructure::TriangularLower,
        l.transpose(),
        BlockStructure::TriangularUpper,
        1.0,
        Par::Seq,
    );
}

/// x ← (L Lᵀ)⁻¹ x for a dense lower-triangular L (column-major, m × m; only its lower
/// triangle is read).
fn dense_solve(l: &[f64], m: usize, x: &mut [f64]) {
    let l = MatRef::from_column_major_slice(l, m, m);
    let mut x = MatMut::from_column_major_slice_mut(x, m, 1);
    solve_lower_triangular_in_place(l, x.rb_mut(), Par::Seq);
    solve_upper_triangular_in_place(l.transpose(), x, Par::Seq);
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::integrator::value_index;
    use nalgebra::{DMatrix, DVector};

    /// A k × k grid whose vertices couple their two-ring (a shell's pattern), its positions,
    /// and the 3×3-block pattern of the integrator (both triangles, rows sorted).
    /// (vertex graph, positions, column pointers, row indices).
    pub(in crate::integrator) type Grid =
        (Vec<Vec<u32>>, Vec<Vector3<f64>>, Vec<usize>, Vec<usize>);

    pub(in crate::integrator) fn grid(k: usize) -> Grid {
        let mut nbrs = vec![Vec::new(); k * k];
        for j in 0..k {
            for i in 0..k {
                for dj in -2i64..=2 {
                    for di in -2i64..=2 {
                        let (a, b) = (i as i64 + di, j as i64 + dj);
                        if (0..k as i64).contains(&a) && (0..k as i64).contains(&b) {
                            nbrs[j * k + i].push((b as usize * k + a as usize) as u32);
                        }
                    }
                }
            }
        }
        for l in &mut nbrs {
            l.sort_unstable();
        }
        let at = (0..k * k)
            .map(|v| Vector3::new((v % k) as f64, 0.0, (v / k) as f64))
            .collect();
        let (col_ptr, row_idx) = pattern(&nbrs);
        (nbrs, at, col_ptr, row_idx)
    }

    /// The integrator's 3×3-block pattern of a vertex graph (both triangles, rows sorted).
    pub(in crate::integrator) fn pattern(nbrs: &[Vec<u32>]) -> (Vec<usize>, Vec<usize>) {
        let (mut col_ptr, mut row_idx) = (vec![0], Vec::new());
        for l in nbrs {
            for _ in 0..3 {
                for &i in l {
                    row_idx.extend((0..3).map(|r| 3 * i as usize + r));
                }
                col_ptr.push(row_idx.len());
            }
        }
        (col_ptr, row_idx)
    }

    /// Values of an SPD matrix on that pattern: off-diagonal entries from a smooth function
    /// of (row, column), symmetric, and a dominant diagonal.
    pub(in crate::integrator) fn spd(col_ptr: &[usize], row_idx: &[usize]) -> Vec<f64> {
        let mut v = vec![0.0; row_idx.len()];
        for c in 0..col_ptr.len() - 1 {
            for k in col_ptr[c]..col_ptr[c + 1] {
                let r = row_idx[k];
                v[value_index(col_ptr, k, c)] = if r == c {
                    40.0 + (c % 7) as f64
                } else {
                    -0.3 * (((r + c) % 5) as f64 / 5.0 + 0.1)
                };
            }
        }
        v
    }

    fn dense(col_ptr: &[usize], row_idx: &[usize], v: &[f64]) -> DMatrix<f64> {
        let n = col_ptr.len() - 1;
        let mut m = DMatrix::zeros(n, n);
        for c in 0..n {
            for k in col_ptr[c]..col_ptr[c + 1] {
                m[(row_idx[k], c)] = v[value_index(col_ptr, k, c)];
            }
        }
        m
    }

    #[test]
    fn the_split_solves_like_a_dense_cholesky_and_finds_indefinite_matrices() {
        let k = 20;
        let (nbrs, at, col_ptr, row_idx) = grid(k);
        let order: Vec<usize> = (0..k * k).collect();
        for layout in [&at[..], &[]] {
            let mut sp = Split::new(
                &nbrs,
                &order,
                (&col_ptr, &row_idx),
                layout,
                f64::INFINITY,
                None,
            )
            .unwrap()
            .expect("a 20 × 20 grid splits");
            // The separator: two grid lines (the two-ring), 40 vertices.
            assert_eq!(sp.sep.len(), 3 * 2 * k);
            let values = spd(&col_ptr, &row_idx);
            assert!(sp.factor(&values, None));
            let b: Vec<f64> = (0..3 * k * k)
                .map(|i| ((i * 37) % 11) as f64 - 5.0)
                .collect();
            let mut x = b.clone();
            sp.solve_in_place(&mut x);
            let a = dense(&col_ptr, &row_idx, &values);
            let want = a.clone().cholesky().unwrap().solve(&DVector::from_vec(b));
            // 1e-12 relative: both are a few roundings from the exact solution of a
            // well-conditioned (diagonally dominant) system.
            let err = (DVector::from_vec(x) - &want).amax() / want.amax();
            assert!(err < 1e-12, "{err:e}");
            // A negative diagonal entry in either half or on the separator: not SPD.
            for v in [3 * 5 * k + 3, 3 * (k * k - 7), sp.sep[4]] {
                let mut bad = values.clone();
                let diag = (col_ptr[v]..col_ptr[v + 1])
                    .find(|&j| row_idx[j] == v)
                    .map(|j| value_index(&col_ptr, j, v))
                    .unwrap();
                bad[diag] = -5.0;
                assert!(!sp.factor(&bad, None), "DOF {v}");
            }
        }
    }

    /// A hanging 48 × 48 sheet whose vertices couple their two-ring (weak springs two rows
    /// or columns away, as shell bending couples them): the integrator splits it, and a step
    /// with the split reaches the same minimizer as one with the whole factorization.
    #[test]
    fn a_split_sheet_steps_to_the_same_answer_as_a_whole_one() {
        use crate::integrator::order::tests::{farthest, two_ring_sheet};
        use crate::integrator::{Integrator, Settings};
        let (mut sys, state) = two_ring_sheet(48);
        sys.layout = state.x.clone();
        let mut split = Integrator::new(&sys).unwrap();
        let mut whole = Integrator::new_whole(&sys).unwrap();
        assert!(split.dirs.factor.split.is_some() && whole.dirs.factor.split.is_none());
        let settings = Settings::default();
        let h = 1.0 / 48.0;
        let (mut a, mut b) = (state.clone(), state.clone());
        for _ in 0..2 {
            split.step(&sys, &mut a, None, h, &settings).unwrap();
            whole.step(&sys, &mut b, None, h, &settings).unwrap();
        }
        // The same minimizer to well within the tolerance's scale (1e-4 m/s · h ≈ 2e-6 m):
        // the two factorizations differ by rounding only.
        let far = farthest(&a, &b);
        assert!(far < 1e-9, "the split's steps differ by {far:e} m");
    }

    /// The split's buffers (three dense m × m blocks of its separator among them) are known
    /// from its analyses before any is allocated: within a limit below them it is not built,
    /// and the whole factor, which needs less, serves; a split that costs more flops than
    /// allowed is not built either.
    #[test]
    fn a_split_that_would_not_fit_or_pay_is_not_built() {
        let k = 20;
        let (nbrs, at, col_ptr, row_idx) = grid(k);
        let order: Vec<usize> = (0..k * k).collect();
        let new = |flops: f64, bytes: Option<u64>| {
            Split::new(&nbrs, &order, (&col_ptr, &row_idx), &at, flops, bytes).unwrap()
        };
        let sp = new(f64::INFINITY, None).expect("a 20 × 20 grid splits");
        // The separator's three m × m blocks alone (m = 120 DOFs).
        let m = sp.sep.len() as u64;
        assert!(sp.bytes > 24 * m * m, "{} bytes", sp.bytes);
        assert!(new(f64::INFINITY, Some(sp.bytes)).is_some());
        assert!(new(f64::INFINITY, Some(sp.bytes - 1)).is_none());
        assert!(new(sp.flops, None).is_none());
        // The integrator's factor within a limit: split or whole, its estimate within it.
        use crate::integrator::factor::Factor;
        let whole = Factor::new(&nbrs, &col_ptr, &row_idx, &at, false, (None, 0)).unwrap();
        for limit in [whole.bytes(), 3 * sp.bytes, u64::MAX] {
            let f = Factor::new(&nbrs, &col_ptr, &row_idx, &at, true, (Some(limit), 0)).unwrap();
            assert!(f.bytes() <= limit, "{} > {limit}", f.bytes());
        }
        // Below the whole factor too: refused (its analysis' bound, or the factor itself),
        // with the numbers.
        match Factor::new(
            &nbrs,
            &col_ptr,
            &row_idx,
            &at,
            true,
            (Some(whole.bytes() / 2), 0),
        ) {
            Err(StepError::TooLarge { what, .. }) => {
                assert!(what.starts_with("the Cholesky factor"), "{what}")
            }
            Err(e) => panic!("{e}"),
            Ok(_) => panic!("a factor over its limit was built"),
        }
    }

    #[test]
    fn small_or_unseparable_systems_are_not_split() {
        let (nbrs, at, col_ptr, row_idx) = grid(2);
        let order: Vec<usize> = (0..4).collect();
        assert!(
            Split::new(
                &nbrs,
                &order,
                (&col_ptr, &row_idx),
                &at,
                f64::INFINITY,
                None
            )
            .unwrap()
            .is_none()
        );
        // Every vertex coupled to every other: the separator would be a whole half.
        let n = 16;
        let all: Vec<u32> = (0..n as u32).collect();
        let nbrs = vec![all; n];
        let (col_ptr, row_idx) = pattern(&nbrs);
        let order: Vec<usize> = (0..n).collect();
        assert!(
            Split::new(
                &nbrs,
                &order,
                (&col_ptr, &row_idx),
                &[],
                f64::INFINITY,
                None
            )
            .unwrap()
            .is_none()
        );
    }
}

//! The one-ring preconditioner: Newton directions by conjugate gradients on the system
//! matrix H, preconditioned by a Cholesky factor of a sparser matrix M.
//!
//! Shell bending couples each vertex with its two-ring (a hinge's two wing tips, a midedge
//! triangle's flaps, a vertex's one-ring through its Laplacian), and the two-ring pattern's
//! Cholesky factor costs 5–8× the flops of the one-ring's on grids, with nested dissection
//! or minimum degree, and holds 2.5–3× the entries (figures in
//! docs/history/issue-71-comments.md). The blocks only the wide elements (four vertices or
//! more) touch are dropped from M, each dropped block B between vertices a and b replaced
//! by ‖B‖_F I on both diagonals:
//!
//! `M₊ = H − Σ [[0, B], [Bᵀ, 0]] + Σ [[‖B‖ I, 0], [0, ‖B‖ I]]`,
//!
//! and since [[s I, −B], [−Bᵀ, s I]] ⪰ 0 whenever s ≥ ‖B‖₂ (≤ ‖B‖_F), M₊ ⪰ H for any
//! symmetric H. The preconditioned CG then converges at a rate set by how much of H's
//! stiffness the dropped blocks carry: the bending's, small against the membrane and the
//! inertia on the hanging cloth (the lumps are about 1e-2 of m/h² there, so CG takes one or
//! two iterations a direction).
//!
//! The exact Hessian's try needs more than a descent direction: H's own Cholesky factorization
//! proved H positive definite, and a Newton iteration that skipped that proof could end at a
//! saddle of the step's objective (CG sees H only along its Krylov space, and the gradient
//! may have no part along a buckling mode). So that try factors M₋, the kept blocks with the
//! lumps subtracted from the diagonals instead (M₋ ⪯ H: the same inequality with B's sign
//! flipped): its success proves H ⪰ M₋ ≻ 0, and it preconditions as well (M₋⁻¹H has its
//! eigenvalues from 1 up to about 1 + 2·ratio). Its failure, or a direction of
//! non-positive curvature in CG, counts as "not positive definite", and the caller adds
//! inertia as it would after a failed factorization of H; it is more cautious than H's own
//! test only where H's lowest curvature is below the lumps (a few percent of the inertia on
//! the hanging cloth). Projected Hessians, positive definite by construction, take M₊ (the
//! lumps added: M₊ ⪰ H, eigenvalues of M₊⁻¹H in (0, 1]).
//!
//! Where the dropped stiffness is large against a vertex's inertia m/h² (bending that
//! dominates at the grid's scale: the hanging cloth at 64² with one step a frame), CG's
//! iterations grow as √(1 + 2·ratio) and the preconditioner declines: H is factored.
//!
//! Everything runs in a fixed order (the product by H row by row, each row's sum in one
//! order; the dot products sequential), so results are the same bits at any thread count.

use super::factor::Factor;
use crate::settings::StepError;
use nalgebra::Vector3;
use rayon::prelude::*;

/// The preconditioner is built where M's factor costs at most this fraction of H's flops:
/// the conjugate gradients' products and solves must be paid from the difference. No size
/// is too small: the hanging cloth resized down to 6² (and cloth_release) runs its solver
/// faster with it, with the same Newton iterations (`weft bench solid` and the examples'
/// `--stats-json` measure it; figures in docs/history/issue-71-comments.md).
pub(super) const ONE_RING_GAIN: f64 = 0.4;

/// CG stops when the residual's M⁻¹-norm has fallen by this factor (an inexact Newton
/// method's forcing term, Dembo, Eisenstat & Steihaug 1982: convergence stays fast while the
/// error left is a thousandth of the step). On cloth_hang a tighter forcing costs many more
/// CG iterations and no fewer Newton iterations (`--stats-json` counts both; figures in
/// docs/history/issue-71-comments.md). Where the cloth starts to buckle a step's objective
/// has nearby minima, and which one Newton ends in depends on its path at any forcing: the
/// same solver with exact directions ends in different ones at different tolerances.
const RELATIVE: f64 = 1e-3;

/// From this many flops of H's (split) factorization, a preconditioner of H's own pattern in
/// single precision is built too (`OneRing::single`), for the steps where the one-ring's
/// declines or where there is none. On `weft bench solid`'s hanging cloth as a graph
/// (`bench/sheet_graph.py`, one step a frame: the one-ring's declines in every step) it
/// gains nothing at 32², just below this count, and cuts the solver's time from 40² up, the
/// more the larger the sheet, with one or two CG iterations a direction and about the
/// Newton iterations of the f64 path (figures in docs/history/issue-71-comments.md).
pub(super) const SINGLE_MIN_FLOPS: f64 = 1e8;

/// Products by H over fewer nodes run on the calling thread (a fork–join costs more).
const PARALLEL_PRODUCT: usize = 8192;

/// Most CG iterations for one direction; beyond them the caller factors H itself.
pub(super) const MAX_ITERATIONS: usize = 30;

/// Past this max over vertices of (dropped stiffness) / (inertia m/h²) the preconditioner
/// declines a factorization and H is factored instead: M₊ ⪯ H + 2 diag(lump) ⪯ (1 + 2 ratio)
/// H where H ⪰ inertia, so CG's iterations grow as √(1 + 2 ratio).
pub(super) const RATIO_MAX: f64 = 10.0;

/// The same bound for M₋ (the lump subtracted), whose factorization certifies H: past half
/// the inertia, the lump alone may make M₋ indefinite where H is not.
pub(super) const CERTIFY_MAX: f64 = 0.5;

/// What a factorization of M gave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Factored {
    /// M is positive definite: its factor is ready.
    Positive,
    /// M is not positive definite: for M₊ ⪰ H, neither is H; for M₋ nothing is proved, and
    /// the caller adds inertia as if H were not.
    NotPositive,
    /// The dropped blocks are too stiff against the inertia for CG to pay: factor H.
    Declined,
}

/// What a preconditioned solve ended with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Outcome {
    /// The direction is in `dir`.
    Converged,
    /// H showed a direction of non-positive curvature: not positive definite.
    Indefinite,
    /// The iterations ran out (or a value was not finite): the caller factors H.
    Failed,
}

/// The sparser matrix M, its factor, and the conjugate gradients' vectors.
pub(super) struct OneRing {
    /// M's pattern (both triangles, 3×3 blocks stored whole, as H's) and values.
    values: Vec<f64>,
    /// Per block of M (in `values` order): where the same block starts in H's values.
    src: Vec<usize>,
    /// H's dropped blocks, each pair once: (where it starts in H's values, its two nodes).
    dropped: Vec<(usize, u32, u32)>,
    /// Per node: where its diagonal block starts in M's values.
    diag: Vec<usize>,
    /// Per node: Σ ‖B‖_F over its dropped blocks.
    lump: Vec<f64>,
    /// Per node: its inertia m/h² in this step (0 for a rigid group's nodes).
    inertia: Vec<f64>,
    /// max over nodes of lump / inertia at the last factorization.
    ratio: f64,
    /// M's factorization.
    factor: Factor,
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
}

impl OneRing {
    /// Builds M for H's pattern (`nbrs`: block neighbours of each node, sorted; `col_ptr`
    /// its DOF pattern), keeping the pairs `keep` says (sorted block neighbours, a subset of
    /// `nbrs`, each node's diagonal included). `None` where it does not pay (see
    /// [`ONE_RING_GAIN`]).
    pub(super) fn new(
        nbrs: &[Vec<u32>],
        col_ptr: &[usize],
        keep: &[Vec<u32>],
        h_flops: f64,
        at: &[Vector3<f64>],
        may_split: bool,
        max_bytes: Option<u64>,
    ) -> Result<Option<Self>, StepError> {
        let kept: usize = keep.iter().map(Vec::len).sum();
        let all: usize = nbrs.iter().map(Vec::len).sum();
        if kept == all {
            return Ok(None);
        }
        let dofs = 3 * nbrs.len();
        let mut m_ptr = Vec::with_capacity(dofs + 1);
        let mut m_row = Vec::with_capacity(9 * kept);
        m_ptr.push(0);
        for l in keep {
            for _ in 0..3 {
                for &i in l {
                    m_row.extend((0..3).map(|rr| 3 * i as usize + rr));
                }
                m_ptr.push(m_row.len());
            }
        }
        // Held beside its factor: M's pattern and values, and its sources (`src`, `dropped`,
        // `diag`: at most 24 bytes a kept block).
        let held = 8 * (2 * m_row.len() + m_ptr.len()) as u64 + 24 * kept as u64;
        let factor = Factor::new(keep, &m_ptr, &m_row, at, may_split, (max_bytes, held))?;
        if factor.flops() > ONE_RING_GAIN * h_flops {
            return Ok(None);
        }
        let (mut src, mut dropped, mut diag) = (Vec::with_capacity(kept), Vec::new(), Vec::new());
        for (v, (all_v, keep_v)) in nbrs.iter().zip(keep).enumerate() {
            let mut k = 0;
            for (s, &r) in all_v.iter().enumerate() {
                let base = col_ptr[3 * v] + 9 * s;
                if keep_v.get(k) == Some(&r) {
                    if r as usize == v {
                        diag.push(m_ptr[3 * v] + 9 * k);
                    }
                    src.push(base);
                    k += 1;
                } else if (r as usize) < v {
                    dropped.push((base, r, v as u32));
                }
            }
            debug_assert_eq!(k, keep_v.len(), "keep is a subset of nbrs");
        }
        Ok(Some(Self::with(
            factor,
            vec![0.0; m_row.len()],
            src,
            dropped,
            diag,
            nbrs.len(),
        )))
    }

    /// A preconditioner of `nodes` nodes around its factor, M's values and their sources.
    fn with(
        factor: Factor,
        values: Vec<f64>,
        src: Vec<usize>,
        dropped: Vec<(usize, u32, u32)>,
        diag: Vec<usize>,
        nodes: usize,
    ) -> Self {
        let dofs = 3 * nodes;
        OneRing {
            values,
            src,
            dropped,
            diag,
            lump: vec![0.0; nodes],
            inertia: vec![0.0; nodes],
            ratio: 0.0,
            factor,
            r: vec![0.0; dofs],
            z: vec![0.0; dofs],
            p: vec![0.0; dofs],
            q: vec![0.0; dofs],
        }
    }

    /// Sets each node's inertia m/h² for this step's factorizations (`free_of`: each
    /// vertex's node or `u32::MAX`; a rigid group's nodes get none).
    pub(super) fn set_inertia(&mut self, free_of: &[u32], mass: &[f64], h: f64) {
        self.inertia.fill(0.0);
        for (&f, &m) in free_of.iter().zip(mass) {
            if let Some(i) = self.inertia.get_mut(f as usize) {
                *i = m / (h * h);
            }
        }
    }

    /// H's own pattern as M, factored in single precision (`Factor::single_twin` of H's
    /// factor `h`, sharing its analyses): nothing is dropped, so M₊ = M₋ = H to f32's
    /// precision and CG converges in a few iterations; the factorization is what is cheaper
    /// (f32's supernodal kernels). `None` where H's factor is not split (see
    /// `Factor::single_twin`).
    pub(super) fn single(
        h: &Factor,
        col_ptr: &[usize],
        row_idx: &[usize],
        max_bytes: Option<u64>,
    ) -> Result<Option<Self>, StepError> {
        let Some(factor) = h.single_twin(col_ptr, row_idx, max_bytes)? else {
            return Ok(None);
        };
        let nodes = (col_ptr.len() - 1) / 3;
        Ok(Some(Self::with(
            factor,
            Vec::new(),
            Vec::new(),
            Vec::new(),
            Vec::new(),
            nodes,
        )))
    }

    /// Gathers M from H's values `h` and factors it: M₊ (the lump added: M₊ ⪰ H), or where
    /// `certify`, M₋ (the lump subtracted: M₋ ⪯ H), whose success proves H positive definite.
    pub(super) fn factor(&mut self, h: &[f64], certify: bool) -> Factored {
        if self.src.is_empty() {
            // H itself, in single precision.
            return if self.factor.factor(h).is_ok() {
                Factored::Positive
            } else {
                Factored::NotPositive
            };
        }
        self.lump.fill(0.0);
        for &(base, a, b) in &self.dropped {
            let f = h[base..base + 9].iter().map(|v| v * v).sum::<f64>().sqrt();
            self.lump[a as usize] += f;
            self.lump[b as usize] += f;
        }
        self.ratio = self
            .lump
            .iter()
            .zip(&self.inertia)
            .filter(|&(_, &m)| m > 0.0)
            .map(|(l, m)| l / m)
            .fold(0.0, f64::max);
        if self.ratio > if certify { CERTIFY_MAX } else { RATIO_MAX } {
            return Factored::Declined;
        }
        let sign = if certify { -1.0 } else { 1.0 };
        for (block, &s) in self.values.chunks_exact_mut(9).zip(&self.src) {
            block.copy_from_slice(&h[s..s + 9]);
        }
        for (&d, &l) in self.diag.iter().zip(&self.lump) {
            for c in 0..3 {
                self.values[d + 4 * c] += sign * l;
            }
        }
        if self.factor.factor(&self.values).is_ok() {
            Factored::Positive
        } else {
            Factored::NotPositive
        }
    }

    /// `dir` ← −H⁻¹ `grad` by CG preconditioned with the last factor of M; H is `h` on the
    /// pattern `col_ptr`/`row_idx`. Returns the outcome and the iterations taken.
    pub(super) fn solve(
        &mut self,
        h: &[f64],
        col_ptr: &[usize],
        row_idx: &[usize],
        grad: &[f64],
        dir: &mut [f64],
    ) -> (Outcome, usize) {
        dir.fill(0.0);
        for (r, g) in self.r.iter_mut().zip(grad) {
            *r = -g;
        }
        self.z.copy_from_slice(&self.r);
        self.factor.solve_in_place(&mut self.z);
        self.p.copy_from_slice(&self.z);
        let mut rz = dot(&self.r, &self.z);
        let goal = RELATIVE * RELATIVE * rz;
        if !rz.is_finite() {
            return (Outcome::Failed, 0);
        }
        if rz <= 0.0 {
            // A zero gradient: the zero direction is exact.
            return (Outcome::Converged, 0);
        }
        for it in 1..=MAX_ITERATIONS {
            product(h, col_ptr, row_idx, &self.p, &mut self.q);
            let pq = dot(&self.p, &self.q);
            if !pq.is_finite() {
                return (Outcome::Failed, it);
            }
            if pq <= 0.0 {
                return (Outcome::Indefinite, it);
            }
            let alpha = rz / pq;
            for ((d, r), (p, q)) in dir
                .iter_mut()
                .zip(self.r.iter_mut())
                .zip(self.p.iter().zip(&self.q))
            {
                *d += alpha * p;
                *r -= alpha * q;
            }
            self.z.copy_from_slice(&self.r);
            self.factor.solve_in_place(&mut self.z);
            let next = dot(&self.r, &self.z);
            if !next.is_finite() {
                return (Outcome::Failed, it);
            }
            if next <= goal {
                return (Outcome::Converged, it);
            }
            let beta = next / rz;
            rz = next;
            for (p, z) in self.p.iter_mut().zip(&self.z) {
                *p = z + beta * *p;
            }
        }
        (Outcome::Failed, MAX_ITERATIONS)
    }

    /// The memory this preconditioner holds (its factor's estimate, which counts M's
    /// pattern and values where it has them, and CG's vectors), for the memory limit the
    /// integrator shares among its factors.
    pub(super) fn bytes(&self) -> u64 {
        let vectors = self.r.len() * 4 + self.lump.len() * 2;
        self.factor.bytes() + 8 * vectors as u64
    }

    /// `b` ← M⁻¹ `b` with the last factor of M.
    pub(super) fn apply(&mut self, b: &mut [f64]) {
        self.factor.solve_in_place(b);
    }

    /// Whether M's factor is split in two halves (then steps run on a pool worker).
    pub(super) fn is_split(&self) -> bool {
        self.factor.split.is_some()
    }
}

/// Σ aᵢ bᵢ in index order.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `q` ← H `p` for H on the pattern `col_ptr`/`row_idx` (both triangles, 3×3 blocks stored
/// whole, column-major). H is symmetric, so node v's rows are its column's blocks
/// transposed: each node's three entries are summed from its own column alone, in the
/// column's order, concurrently over nodes and the same bits at any thread count.
pub(super) fn product(h: &[f64], col_ptr: &[usize], row_idx: &[usize], p: &[f64], q: &mut [f64]) {
    let row = |v: usize, qv: &mut [f64]| {
        let (start, end) = (col_ptr[3 * v], col_ptr[3 * v + 1]);
        let blocks = h[start..start + 3 * (end - start)].chunks_exact(9);
        let mut acc = [0.0f64; 3];
        for (b, &r) in blocks.zip(row_idx[start..end].iter().step_by(3)) {
            let pr = &p[r..r + 3];
            // Block (r, v) column-major: entry (rr, cc) at 3cc + rr. Row v of H is column
            // cc of this block: (Hp)_v,cc += Σ_rr B[rr, cc] p_r,rr.
            for (cc, a) in acc.iter_mut().enumerate() {
                *a += b[3 * cc] * pr[0] + b[3 * cc + 1] * pr[1] + b[3 * cc + 2] * pr[2];
            }
        }
        qv.copy_from_slice(&acc);
    };
    if q.len() < 3 * PARALLEL_PRODUCT {
        q.chunks_exact_mut(3)
            .enumerate()
            .for_each(|(v, qv)| row(v, qv));
    } else {
        q.par_chunks_mut(3)
            .with_min_len(PARALLEL_PRODUCT / 4)
            .enumerate()
            .for_each(|(v, qv)| row(v, qv));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::split::tests::pattern;

    /// The block graph of a chain of `n` nodes, each neighbouring those within `reach`.
    fn chain(n: usize, reach: usize) -> Vec<Vec<u32>> {
        (0..n)
            .map(|j| {
                (j.saturating_sub(reach)..(j + reach + 1).min(n))
                    .map(|i| i as u32)
                    .collect()
            })
            .collect()
    }

    /// A random symmetric positive definite matrix on a 1D chain with reach 2 (two-ring),
    /// kept at reach 1: CG with M converges to H's solution, and M ⪰ H.
    #[test]
    fn converges_to_the_solution_of_the_full_system() {
        let n = 40;
        let nbrs = chain(n, 2);
        let keep = chain(n, 1);
        let (col_ptr, row_idx) = pattern(&nbrs);
        // H = diag 10 + small symmetric couplings (a deterministic pseudo-random fill).
        let mut h = vec![0.0; row_idx.len()];
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        for v in 0..n {
            for (s, &r) in nbrs[v].iter().enumerate() {
                let r = r as usize;
                if r > v {
                    continue;
                }
                let base = col_ptr[3 * v] + 9 * s;
                let mirror = col_ptr[3 * r] + 9 * nbrs[r].binary_search(&(v as u32)).unwrap();
                for cc in 0..3 {
                    for rr in 0..3 {
                        let x = if r == v {
                            if rr == cc { 10.0 } else { 0.0 }
                        } else {
                            rnd()
                        };
                        if r == v && rr < cc {
                            continue;
                        }
                        h[base + 3 * cc + rr] = x;
                        h[mirror + 3 * rr + cc] = x;
                    }
                }
            }
        }
        let mut pre = OneRing::new(&nbrs, &col_ptr, &keep, f64::INFINITY, &[], false, None)
            .unwrap()
            .expect("pays");
        assert_eq!(pre.factor(&h, false), Factored::Positive);
        let grad: Vec<f64> = (0..3 * n).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut dir = vec![0.0; 3 * n];
        let (outcome, its) = pre.solve(&h, &col_ptr, &row_idx, &grad, &mut dir);
        assert_eq!(outcome, Outcome::Converged);
        assert!(its < 20, "{its} iterations");
        // CG stops on the residual's M⁻¹-norm (a fall by RELATIVE); M's diagonal here is
        // within 10 ± 6 per entry, so the Euclidean norm's fall is within a few times that.
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let mut hd = vec![0.0; 3 * n];
        product(&h, &col_ptr, &row_idx, &dir, &mut hd);
        let r: Vec<f64> = hd.iter().zip(&grad).map(|(a, g)| a + g).collect();
        let fall = norm(&r) / norm(&grad);
        assert!(fall < 5.0 * RELATIVE, "residual fell by {fall:e}");
        // M ⪰ H: xᵀ(M − H)x ≥ 0 for any x (M's values are H's kept blocks plus the lump).
        for k in 0..20 {
            let x: Vec<f64> = (0..3 * n)
                .map(|i| ((i * (k + 3)) as f64 * 0.71).cos())
                .collect();
            let (mut hx, mut mx) = (vec![0.0; 3 * n], vec![0.0; 3 * n]);
            product(&h, &col_ptr, &row_idx, &x, &mut hx);
            let (m_ptr, m_row) = pattern(&keep);
            product(&pre.values, &m_ptr, &m_row, &x, &mut mx);
            let gap = dot(&x, &mx) - dot(&x, &hx);
            assert!(gap >= -1e-12 * dot(&x, &mx), "xᵀMx − xᵀHx = {gap:e}");
        }
    }

    /// The product by H splits its rows over threads from `PARALLEL_PRODUCT` nodes; each row
    /// is summed on one thread in one order, so 1 and 3 threads give the same bits.
    #[test]
    fn the_product_is_the_same_bits_at_any_thread_count() {
        let n = PARALLEL_PRODUCT + 500;
        let nbrs = chain(n, 2);
        let (col_ptr, row_idx) = pattern(&nbrs);
        let h: Vec<f64> = (0..row_idx.len())
            .map(|i| (i as f64 * 0.013).sin())
            .collect();
        let p: Vec<f64> = (0..3 * n).map(|i| (i as f64 * 0.7).cos()).collect();
        let run = |threads| {
            let mut q = vec![0.0; 3 * n];
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| product(&h, &col_ptr, &row_idx, &p, &mut q));
            q
        };
        let one = run(1);
        assert!(
            one.iter()
                .zip(run(3))
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
    }

    /// A hanging sheet with shell bending (its pattern is the two-ring): the integrator builds
    /// the preconditioner, its steps take CG directions, and they end where steps that factor
    /// H end, to the tolerance's scale (each step solved to 1e-6 m/s: positions within
    /// 1e-6 · h a step; the first steps, before any buckling).
    #[test]
    fn a_shell_steps_to_the_same_answer_as_with_the_factor_of_h() {
        use crate::integrator::{Integrator, Settings};
        let (sys, state) = crate::integrator::order::tests::shell_sheet(16, 1e-6);
        let settings = Settings {
            tolerance: 1e-6,
            ..Settings::default()
        };
        let h = 1.0 / 48.0;
        let (mut with, mut without) = (
            Integrator::new(&sys).unwrap(),
            Integrator::new(&sys).unwrap(),
        );
        without.dirs.one_ring_tried = true;
        let (mut a, mut b) = (state.clone(), state.clone());
        let steps = 4;
        let mut cg = 0;
        for _ in 0..steps {
            cg += with
                .step(&sys, &mut a, None, h, &settings)
                .unwrap()
                .cg_iterations;
            without.step(&sys, &mut b, None, h, &settings).unwrap();
        }
        assert!(with.dirs.one_ring.is_some() && without.dirs.one_ring.is_none());
        assert!(cg > 0, "no CG iterations");
        let far = crate::integrator::order::tests::farthest(&a, &b);
        assert!(far < 1e-6 * h * steps as f64, "{far:e} m apart");
    }
}

#[cfg(test)]
mod single_tests {
    use super::*;
    use crate::integrator::split::tests::{grid, spd};
    use crate::integrator::value_index;

    /// H's own pattern factored in single precision (a 20 × 20 two-ring grid, split): a
    /// solve with the factor alone is H⁻¹'s to about f32's precision, CG with it reaches the
    /// f64 solution in a few iterations, and a matrix with a negative diagonal entry is
    /// refused as H's own factorization refuses it.
    #[test]
    fn the_single_precision_factor_preconditions_h_itself() {
        let k = 20;
        let (nbrs, at, col_ptr, row_idx) = grid(k);
        let mut values = spd(&col_ptr, &row_idx);
        // Scaled rows (1e-3 … 1e3 on the diagonal, as masses and stiffnesses differ): the
        // factor scales the matrix to a unit diagonal before rounding it to f32.
        let s: Vec<f64> = (0..3 * k * k)
            .map(|d| 10f64.powi((d % 7) as i32 - 3))
            .collect();
        for c in 0..3 * k * k {
            for p in col_ptr[c]..col_ptr[c + 1] {
                values[value_index(&col_ptr, p, c)] *= (s[c] * s[row_idx[p]]).sqrt();
            }
        }
        // The exact solution from H's f64 factor, and its single-precision twin.
        let mut exact = Factor::new(&nbrs, &col_ptr, &row_idx, &at, true, (None, 0)).unwrap();
        let mut pre = OneRing::single(&exact, &col_ptr, &row_idx, None)
            .unwrap()
            .expect("a 20 × 20 grid splits");
        assert_eq!(pre.factor(&values, true), Factored::Positive);
        let grad: Vec<f64> = (0..3 * k * k).map(|i| (i as f64 * 0.37).sin()).collect();
        exact.factor(&values).unwrap();
        let mut want: Vec<f64> = grad.iter().map(|g| -g).collect();
        exact.solve_in_place(&mut want);
        let err = |x: &[f64]| {
            let num = x
                .iter()
                .zip(&want)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>();
            (num / want.iter().map(|b| b * b).sum::<f64>()).sqrt()
        };
        // The factor alone: f32's unit roundoff (6e-8) times the scaled system's condition
        // number (diagonally dominant: a few) and the factor's growth, well below 1e-5.
        let mut z: Vec<f64> = grad.iter().map(|g| -g).collect();
        pre.factor.solve_in_place(&mut z);
        let e0 = err(&z);
        // Bounded below too: an f64 factor (errors near 1e-15) would fail here, so a silent
        // fallback to double precision cannot pass as single (measured 1.7e-7).
        assert!(e0 > 1e-10 && e0 < 1e-5, "{e0:e}");
        let mut dir = vec![0.0; 3 * k * k];
        let (outcome, its) = pre.solve(&values, &col_ptr, &row_idx, &grad, &mut dir);
        assert_eq!(outcome, Outcome::Converged);
        // The first iteration meets RELATIVE (1e-3) already: the direction is the factor's,
        // corrected along one Krylov vector, to its precision or better.
        assert!(its <= 2, "{its} iterations");
        assert!(err(&dir) <= 1.01 * e0, "{:e} {e0:e}", err(&dir));
        // A negative diagonal entry: not positive definite.
        let mut bad = values.clone();
        let v = 3 * 5 * k + 3;
        let d = (col_ptr[v]..col_ptr[v + 1])
            .find(|&j| row_idx[j] == v)
            .map(|j| value_index(&col_ptr, j, v))
            .unwrap();
        bad[d] = -5.0;
        assert_eq!(pre.factor(&bad, true), Factored::NotPositive);
    }
}

//! The porous pressure projection (DESIGN §6).
//!
//! On every face the fluid velocity after the step is
//! `u = ũ − h β ∇p`, `ũ = (ρα u* + hK v)/(ρα + hK)`, `β = α/(ρα + hK)`,
//! the implicit solution of `ρα (u − u*)/h = −α∇p − K(u − v)`: momentum with the pressure
//! force on the fluid's share α of the face and drag K towards the solid velocity v. The
//! pressure makes the mixture flux `F = α u + (1 − α) v` divergence-free, which per cell is
//!
//! `Σ_f α β h/Δx² (p_c − p_n) = −(1/Δx) Σ_f s_f (α ũ + (1 − α) v)`,
//!
//! (s_f = ±1 for faces on the cell's ± side): a 7-point system, symmetric, with positive
//! diagonal and non-positive off-diagonals, diagonally dominant, so SPD once one pressure is
//! fixed (an open side does that; a closed or periodic domain pins one cell, which only
//! removes the constant). With K = 0 and α = 1 it is the classic projection.
//!
//! It is solved by conjugate gradients preconditioned with a modified incomplete Cholesky
//! factor MIC(0) (the matrix's own lower pattern), warm-started from the last pressure. The residual
//! of this system is exactly the divergence of the mixture flux after the velocity update
//! (in 1/s), so the stopping test `max |r| ≤ tolerance` is a bound on the divergence left.
//! Sequential and in fixed order: bit-identical results on any machine thread count.

use crate::grid::{Boundary, FluidError, MacGrid};
use std::time::Instant;

const NONE: u32 = u32::MAX;

/// Pressure solve settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PressureSolve {
    /// Largest divergence of the mixture flux allowed after the solve [1/s].
    pub tolerance: f64,
    /// CG iteration limit.
    pub max_iterations: usize,
}

impl Default for PressureSolve {
    fn default() -> Self {
        PressureSolve {
            tolerance: 1e-8,
            max_iterations: 2000,
        }
    }
}

/// What a projection did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PressureStats {
    /// CG iterations.
    pub iterations: usize,
    /// Largest |divergence| of the mixture flux after the update [1/s].
    pub divergence: f64,
    /// Seconds building the system and its preconditioner.
    pub setup_seconds: f64,
    /// Seconds in CG.
    pub solve_seconds: f64,
}

/// Why a projection failed. The grid is left as it was.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ProjectionError {
    /// CG hit its iteration limit.
    #[error(
        "pressure solve did not converge in {iterations} iterations (divergence {residual:e} 1/s, tolerance {tolerance:e})"
    )]
    NotConverged {
        /// Iterations done.
        iterations: usize,
        /// max |r| reached [1/s].
        residual: f64,
        /// The tolerance asked for.
        tolerance: f64,
    },
    /// Bad settings or a bad field (negative drag, fluid fraction outside [0, 1]).
    #[error(transparent)]
    Fluid(#[from] FluidError),
    /// The stop check ([`Projection::set_stop`]) asked the solve to end.
    #[error("pressure solve stopped at CG iteration {iteration}")]
    Interrupted {
        /// CG iteration at which it stopped.
        iteration: usize,
    },
}

/// Asked once per CG iteration: true when the solve should end with
/// [`ProjectionError::Interrupted`] (Ctrl-C, a time limit, a host's cancel).
pub type StopCheck = std::sync::Arc<dyn Fn() -> bool + Send + Sync>;

/// Where a face's flux goes.
#[derive(Clone, Copy)]
enum Side {
    /// The face joins two cells (minus side, plus side).
    Interior(u32, u32),
    /// A boundary face with prescribed flux, next to one cell; `plus` when the cell is on
    /// the face's plus side.
    Fixed { cell: u32, plus: bool },
    /// An open boundary face (pressure 0 outside).
    Open { cell: u32, plus: bool },
}

/// The pressure system's pattern, preconditioner storage and CG vectors for one domain,
/// built once and reused by every projection.
pub struct Projection {
    n: usize,
    row_ptr: Vec<usize>,
    col: Vec<u32>,
    val: Vec<f64>,
    diag: Vec<u32>,
    /// Per distinct face (all axes, in order): its cells, and for interior faces the two
    /// off-diagonal slots.
    faces: Vec<(usize, usize, Side, [u32; 2])>,
    /// Cell pinned to zero pressure when no side is open.
    pin: Option<usize>,
    /// IC(0) factor: the lower triangle of the pattern (diagonal last in each row).
    l_ptr: Vec<usize>,
    l_col: Vec<u32>,
    l_val: Vec<f64>,
    /// Per lower entry: its slot in `val`.
    l_src: Vec<u32>,
    b: Vec<f64>,
    r: Vec<f64>,
    z: Vec<f64>,
    s: Vec<f64>,
    q: Vec<f64>,
    stop: Option<StopCheck>,
}

impl Projection {
    /// Sets (or clears) the check asked once per CG iteration; when it answers true the
    /// solve ends with [`ProjectionError::Interrupted`] and the grid is left as it was.
    pub fn set_stop(&mut self, stop: Option<StopCheck>) {
        self.stop = stop;
    }

    /// Builds the pattern for `grid`'s domain and boundaries.
    pub fn new(grid: &MacGrid) -> Self {
        let dom = &grid.domain;
        let n = dom.cell_count();
        let mut faces = Vec::new();
        let mut rows: Vec<Vec<u32>> = (0..n as u32).map(|c| vec![c]).collect();
        let mut any_open = false;
        for a in 0..3 {
            let d = dom.face_dims(a);
            let na = dom.cells[a];
            let periodic = dom.boundaries.is_periodic(a);
            for k in 0..d[2] {
                for j in 0..d[1] {
                    for i in 0..d[0] {
                        let idx = [i, j, k];
                        let m = idx[a];
                        if periodic && m == na {
                            continue; // the copy of face 0
                        }
                        let cell_at = |along: usize| {
                            let mut c = idx;
                            c[a] = along;
                            dom.cell(c[0], c[1], c[2]) as u32
                        };
                        let side = if m > 0 && m < na {
                            Side::Interior(cell_at(m - 1), cell_at(m))
                        } else if periodic {
                            Side::Interior(cell_at(na - 1), cell_at(0))
                        } else {
                            let (cell, plus, b) = if m == 0 {
                                (cell_at(0), true, dom.boundaries.lo[a])
                            } else {
                                (cell_at(na - 1), false, dom.boundaries.hi[a])
                            };
                            if b == Boundary::Open {
                                any_open = true;
                                Side::Open { cell, plus }
                            } else {
                                Side::Fixed { cell, plus }
                            }
                        };
                        if let Side::Interior(c0, c1) = side
                            && c0 != c1
                        {
                            rows[c0 as usize].push(c1);
                            rows[c1 as usize].push(c0);
                        }
                        faces.push((a, dom.face(a, i, j, k), side, [NONE; 2]));
                    }
                }
            }
        }
        let mut row_ptr = vec![0];
        let mut col = Vec::new();
        for r in &mut rows {
            r.sort_unstable();
            r.dedup();
            col.extend_from_slice(r);
            row_ptr.push(col.len());
        }
        let slot = |r: u32, c: u32| {
            let (lo, hi) = (row_ptr[r as usize], row_ptr[r as usize + 1]);
            (lo + col[lo..hi].binary_search(&c).expect("in pattern")) as u32
        };
        let diag: Vec<u32> = (0..n as u32).map(|c| slot(c, c)).collect();
        for f in &mut faces {
            if let Side::Interior(c0, c1) = f.2
                && c0 != c1
            {
                f.3 = [slot(c0, c1), slot(c1, c0)];
            }
        }
        let mut l_ptr = vec![0];
        let mut l_col = Vec::new();
        let mut l_src = Vec::new();
        for r in 0..n {
            for (s, &c) in col.iter().enumerate().take(row_ptr[r + 1]).skip(row_ptr[r]) {
                if c as usize <= r {
                    l_col.push(c);
                    l_src.push(s as u32);
                }
            }
            l_ptr.push(l_col.len());
        }
        Projection {
            n,
            val: vec![0.0; col.len()],
            row_ptr,
            col,
            diag,
            faces,
            pin: (!any_open).then_some(0),
            l_val: vec![0.0; l_col.len()],
            l_ptr,
            l_col,
            l_src,
            b: vec![0.0; n],
            r: vec![0.0; n],
            z: vec![0.0; n],
            s: vec![0.0; n],
            q: vec![0.0; n],
            stop: None,
        }
    }

    /// Projects `grid`'s velocity (the intermediate u*) with density `rho` [kg/m³] over a
    /// step `h` [s]: solves for the pressure and updates the face velocities. On error the
    /// grid is unchanged.
    pub fn project(
        &mut self,
        grid: &mut MacGrid,
        rho: f64,
        h: f64,
        settings: &PressureSolve,
    ) -> Result<PressureStats, ProjectionError> {
        if !(rho.is_finite() && rho > 0.0) {
            return Err(FluidError::Parameter {
                name: "fluid density",
                message: format!("must be > 0 kg/m³, got {rho}"),
            }
            .into());
        }
        if !(h.is_finite() && h > 0.0) {
            return Err(FluidError::Parameter {
                name: "time step",
                message: format!("must be > 0 s, got {h}"),
            }
            .into());
        }
        for a in 0..3 {
            if let Some(x) = grid.alpha[a].iter().find(|x| !(**x >= 0.0 && **x <= 1.0)) {
                return Err(FluidError::Parameter {
                    name: "fluid fraction",
                    message: format!("must be in [0, 1], got {x}"),
                }
                .into());
            }
            if let Some(x) = grid.drag[a].iter().find(|x| !(**x >= 0.0 && x.is_finite())) {
                return Err(FluidError::Parameter {
                    name: "drag coefficient",
                    message: format!("must be finite and >= 0, got {x}"),
                }
                .into());
            }
        }
        let t = Instant::now();
        let dx = grid.domain.dx;
        let mut stats = PressureStats::default();
        self.val.iter_mut().for_each(|v| *v = 0.0);
        self.b.iter_mut().for_each(|v| *v = 0.0);
        // Face quantities: ũ, the coefficient αβh/Δx², and the flux F̃ = αũ + (1 − α)v.
        let face = |g: &MacGrid, a: usize, f: usize| {
            let (al, k, v, u) = (g.alpha[a][f], g.drag[a][f], g.solid_vel[a][f], g.vel[a][f]);
            if al == 0.0 {
                // An obstacle face: no fluid, the flux is the obstacle's, the pressure has no
                // hold on it (and what velocity the face shows is the obstacle's).
                return (v, 0.0, v);
            }
            let den = rho * al + h * k;
            let ut = (rho * al * u + h * k * v) / den;
            let beta = al / den;
            (ut, beta, al * ut + (1.0 - al) * v)
        };
        let coef =
            |g: &MacGrid, a: usize, f: usize, beta: f64| g.alpha[a][f] * beta * h / (dx * dx);
        for &(a, f, side, slots) in &self.faces {
            match side {
                Side::Interior(c0, c1) => {
                    if c0 == c1 {
                        continue;
                    }
                    let (_, beta, flux) = face(grid, a, f);
                    let coef = coef(grid, a, f, beta);
                    let (c0, c1) = (c0 as usize, c1 as usize);
                    self.val[self.diag[c0] as usize] += coef;
                    self.val[self.diag[c1] as usize] += coef;
                    self.val[slots[0] as usize] -= coef;
                    self.val[slots[1] as usize] -= coef;
                    // The face is on c0's plus side and c1's minus side.
                    self.b[c0] -= flux / dx;
                    self.b[c1] += flux / dx;
                }
                Side::Fixed { cell, plus } => {
                    let al = grid.alpha[a][f];
                    let flux = al * grid.vel[a][f] + (1.0 - al) * grid.solid_vel[a][f];
                    // `plus`: the cell is on the face's plus side, so this is its minus face.
                    self.b[cell as usize] += if plus { flux / dx } else { -flux / dx };
                }
                Side::Open { cell, plus } => {
                    let (_, beta, flux) = face(grid, a, f);
                    let coef = coef(grid, a, f, beta);
                    self.val[self.diag[cell as usize] as usize] += coef;
                    self.b[cell as usize] += if plus { flux / dx } else { -flux / dx };
                }
            }
        }
        // Cells with no coupling at all (enclosed by solid) keep zero pressure.
        for c in 0..self.n {
            let d = self.diag[c] as usize;
            if self.val[d] == 0.0 {
                self.val[d] = 1.0;
                self.b[c] = 0.0;
            }
        }
        if let Some(pc) = self.pin {
            for s in self.row_ptr[pc]..self.row_ptr[pc + 1] {
                let c = self.col[s] as usize;
                if c != pc {
                    self.val[s] = 0.0;
                    // The symmetric entry in row c.
                    let (lo, hi) = (self.row_ptr[c], self.row_ptr[c + 1]);
                    let k = lo
                        + self.col[lo..hi]
                            .binary_search(&(pc as u32))
                            .expect("symmetric");
                    self.val[k] = 0.0;
                }
            }
            self.val[self.diag[pc] as usize] = 1.0;
            self.b[pc] = 0.0;
        }
        self.factor_ic0();
        stats.setup_seconds = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let mut p = grid.pressure.clone();
        if let Some(pc) = self.pin {
            // Warm start relative to the pinned cell (the constant is free).
            let p0 = p[pc];
            p.iter_mut().for_each(|x| *x -= p0);
        }
        let (iterations, residual, stopped) = self.pcg(&mut p, settings);
        if stopped {
            return Err(ProjectionError::Interrupted {
                iteration: iterations,
            });
        }
        stats.iterations = iterations;
        stats.solve_seconds = t.elapsed().as_secs_f64();
        if residual > settings.tolerance {
            return Err(ProjectionError::NotConverged {
                iterations,
                residual,
                tolerance: settings.tolerance,
            });
        }
        // Velocity update u = ũ − hβ∇p on every face whose flux the pressure controls.
        for &(a, f, side, _) in &self.faces {
            let (ut, beta, _) = face(grid, a, f);
            // u = ũ − hβ ∇p, ∇p = (p_plus − p_minus)/Δx.
            let hb = h * beta / dx;
            let new = match side {
                Side::Interior(c0, c1) if c0 != c1 => ut - hb * (p[c1 as usize] - p[c0 as usize]),
                Side::Interior(..) => ut,
                Side::Open { cell, plus } => {
                    // Outside the open side the pressure is 0.
                    let pc = p[cell as usize];
                    ut - hb * (if plus { pc } else { -pc })
                }
                Side::Fixed { .. } => continue,
            };
            grid.vel[a][f] = new;
        }
        grid.pressure.copy_from_slice(&p);
        grid.apply_boundaries();
        stats.divergence = max_divergence(grid);
        Ok(stats)
    }

    /// Cells (unknowns) of the system.
    pub fn unknowns(&self) -> usize {
        self.n
    }

    /// Bytes one CG iteration must move through memory at least, counting each array pass
    /// once: the matrix–vector product (values and column indices, the vector, the result),
    /// both triangular sweeps of the preconditioner (factor values, indices, vectors), and the
    /// vector updates and dot products (14 vector passes). For the bandwidth fraction that
    /// `weft bench fluid` reports.
    pub fn bytes_per_iteration(&self) -> f64 {
        let (n, nnz, lnz) = (
            self.n as f64,
            self.col.len() as f64,
            self.l_col.len() as f64,
        );
        let matvec = nnz * 12.0 + n * 16.0;
        let precondition = 2.0 * (lnz * 12.0) + n * 8.0 * 4.0;
        let vectors = n * 8.0 * 14.0;
        matvec + precondition + vectors
    }

    /// Modified incomplete Cholesky, MIC(0), on A's lower pattern (Gustafsson 1978; the
    /// form in Bridson's *Fluid Simulation for Computer Graphics*): IC(0) drops the fill
    /// L_rk L_qk that would join row r to the other neighbours q of an earlier row k; MIC
    /// subtracts τ = 0.97 of it from the diagonal instead, so L Lᵀ keeps A's row sums and the
    /// smooth error modes that make IC(0)'s iteration count grow like Δx⁻¹ are caught (the
    /// count grows like Δx^(−1/2)). For the 7-point stencil L_qk = A_qk / L_kk, so the dropped
    /// sum of row r is Σ_k L_rk (S_k − A_kr)/L_kk with S_k the sum of row k's entries right of
    /// its diagonal. A pivot that falls below σ = 1/4 of A_rr falls back to A_rr (safety).
    fn factor_ic0(&mut self) {
        const TAU: f64 = 0.97;
        const SIGMA: f64 = 0.25;
        // S_k and the diagonal of A, per row.
        for r in 0..self.n {
            self.s[r] = (self.row_ptr[r]..self.row_ptr[r + 1])
                .filter(|&e| self.col[e] as usize > r)
                .map(|e| self.val[e])
                .sum();
        }
        for r in 0..self.n {
            let (lo, hi) = (self.l_ptr[r], self.l_ptr[r + 1]);
            let mut dropped = 0.0;
            for e in lo..hi {
                let c = self.l_col[e] as usize;
                let a = self.val[self.l_src[e] as usize];
                let mut v = a;
                // Σ L_rj L_cj over j < c in both rows (sorted merge).
                let (mut p, mut q) = (lo, self.l_ptr[c]);
                let qend = self.l_ptr[c + 1] - if c == r { 0 } else { 1 };
                while p < e && q < qend {
                    let (cp, cq) = (self.l_col[p], self.l_col[q]);
                    if cp == cq {
                        v -= self.l_val[p] * self.l_val[q];
                        p += 1;
                        q += 1;
                    } else if cp < cq {
                        p += 1;
                    } else {
                        q += 1;
                    }
                }
                if c == r {
                    let d = v - TAU * dropped;
                    self.l_val[e] = if d >= SIGMA * a { d.sqrt() } else { a.sqrt() };
                } else {
                    let lkk = self.l_val[self.l_ptr[c + 1] - 1];
                    let l = v / lkk;
                    self.l_val[e] = l;
                    // Fill towards row c's other right neighbours: (S_c − A_cr)/L_cc each.
                    dropped += l * (self.s[c] - a) / lkk;
                }
            }
        }
    }

    /// z = (L Lᵀ)⁻¹ r.
    fn precondition(&mut self) {
        let n = self.n;
        // Forward: L y = r (y in z).
        for r in 0..n {
            let (lo, hi) = (self.l_ptr[r], self.l_ptr[r + 1]);
            let mut v = self.r[r];
            for e in lo..hi - 1 {
                v -= self.l_val[e] * self.z[self.l_col[e] as usize];
            }
            self.z[r] = v / self.l_val[hi - 1];
        }
        // Backward: Lᵀ z = y, column sweep.
        for r in (0..n).rev() {
            let (lo, hi) = (self.l_ptr[r], self.l_ptr[r + 1]);
            let zr = self.z[r] / self.l_val[hi - 1];
            self.z[r] = zr;
            for e in lo..hi - 1 {
                self.z[self.l_col[e] as usize] -= self.l_val[e] * zr;
            }
        }
    }

    fn matvec(&self, x: &[f64], out: &mut [f64]) {
        for (r, o) in out.iter_mut().enumerate() {
            *o = (self.row_ptr[r]..self.row_ptr[r + 1])
                .map(|s| self.val[s] * x[self.col[s] as usize])
                .sum();
        }
    }

    /// Preconditioned CG from `p`; returns (iterations, residual).
    ///
    /// The residual is max |rᵢ|, and when a cell is pinned also |Σᵢ rᵢ|: the pinned cell's
    /// own equation was dropped, and (the system being compatible) its divergence is minus
    /// the sum of the others', so both bounds together bound every cell's divergence.
    /// CG from `p`: (iterations, final residual, stopped by the stop check).
    fn pcg(&mut self, p: &mut [f64], settings: &PressureSolve) -> (usize, f64, bool) {
        let mut ap = std::mem::take(&mut self.q);
        self.matvec(p, &mut ap);
        for ((r, b), a) in self.r.iter_mut().zip(&self.b).zip(&ap) {
            *r = b - a;
        }
        self.q = ap;
        let pinned = self.pin.is_some();
        let norm = |v: &[f64]| {
            let m = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            if pinned {
                m.max(v.iter().sum::<f64>().abs())
            } else {
                m
            }
        };
        let mut res = norm(&self.r);
        if res <= settings.tolerance {
            return (0, res, false);
        }
        self.precondition();
        self.s.copy_from_slice(&self.z);
        let mut rz: f64 = self.r.iter().zip(&self.z).map(|(a, b)| a * b).sum();
        for it in 1..=settings.max_iterations {
            if self.stop.as_ref().is_some_and(|s| s()) {
                return (it - 1, res, true);
            }
            let mut q = std::mem::take(&mut self.q);
            self.matvec(&self.s, &mut q);
            let sq: f64 = self.s.iter().zip(&q).map(|(a, b)| a * b).sum();
            if sq.is_nan() || sq <= 0.0 {
                self.q = q;
                return (it, res, false);
            }
            let alpha = rz / sq;
            for i in 0..self.n {
                p[i] += alpha * self.s[i];
                self.r[i] -= alpha * q[i];
            }
            self.q = q;
            res = norm(&self.r);
            if res <= settings.tolerance {
                return (it, res, false);
            }
            self.precondition();
            let rz_new: f64 = self.r.iter().zip(&self.z).map(|(a, b)| a * b).sum();
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..self.n {
                self.s[i] = self.z[i] + beta * self.s[i];
            }
        }
        (settings.max_iterations, res, false)
    }
}

/// Largest |divergence| of the mixture flux α u + (1 − α) v over the cells [1/s].
pub fn max_divergence(grid: &MacGrid) -> f64 {
    let dom = &grid.domain;
    let mut worst = 0.0f64;
    for k in 0..dom.cells[2] {
        for j in 0..dom.cells[1] {
            for i in 0..dom.cells[0] {
                let mut div = 0.0;
                for a in 0..3 {
                    let lo = [i, j, k];
                    let mut hi = lo;
                    hi[a] += 1;
                    let flux = |idx: [usize; 3]| {
                        let f = dom.face(a, idx[0], idx[1], idx[2]);
                        let al = grid.alpha[a][f];
                        al * grid.vel[a][f] + (1.0 - al) * grid.solid_vel[a][f]
                    };
                    div += flux(hi) - flux(lo);
                }
                worst = worst.max((div / dom.dx).abs());
            }
        }
    }
    worst
}

//! Optional viscosity: implicit diffusion of the velocity.
//!
//! Each velocity component is diffused by one backward-Euler step,
//! `(I − hν∇²) u = u*`, ν = μ/ρ, with the 7-point Laplacian on that component's faces.
//! Backward Euler is unconditionally stable, so a viscous fluid (honey, or a coarse grid
//! with a large step) never limits the step; for water and air at cloth and hair scales the
//! term is small (hν/Δx² ≈ 10⁻⁷ for water at 2 cm and 40 ms), which is why it is optional.
//!
//! Boundaries, per side and per component:
//! - the face component normal to a wall or inflow side is prescribed there (a Dirichlet
//!   value, taken from the grid);
//! - a component tangential to a wall is no-slip (ghost value −u, the wall half a cell away);
//!   at an inflow side it takes the inflow's value (ghost 2u_in − u);
//! - at an open side every component has zero normal gradient;
//! - periodic sides wrap.
//!
//! The matrix is symmetric, diagonally dominant with unit-plus diagonal, so Jacobi-
//! preconditioned CG converges in a handful of iterations when hν/Δx² is small. Sequential
//! and in a fixed order: bit-identical on any thread count.

use crate::grid::{Boundary, Domain, MacGrid};
use crate::pressure::{PressureSolve, ProjectionError};

const NONE: u32 = u32::MAX;

/// The diffusion system's structure for one domain (built once, reused by every step).
pub struct Diffusion {
    domain: Domain,
    axes: [Component; 3],
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
    u: Vec<f64>,
    b: Vec<f64>,
    /// Each component's solution until all three are solved (the grid is left unchanged on
    /// error).
    solved: [Vec<f64>; 3],
    stop: Option<crate::pressure::StopCheck>,
}

/// One velocity component's unknowns.
struct Component {
    /// Face index of each unknown.
    face: Vec<u32>,
    /// Per unknown: its neighbours' unknown indices (NONE: no neighbour on that side).
    nbr: Vec<[u32; 6]>,
    /// Per unknown: neighbours counted on the diagonal (unknown neighbours and ghosts).
    weight: Vec<f64>,
    /// Prescribed neighbour values, added to the right side at solve time: (unknown, face
    /// whose grid value is prescribed, or NONE for the constant) — Dirichlet faces at walls
    /// and inflows, and inflow ghosts (constant 2u_in).
    known: Vec<(u32, u32, f64)>,
    /// Periodic copies: (copy face, original face).
    copies: Vec<(u32, u32)>,
}

/// What a diffusion step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DiffusionStats {
    /// CG iterations, summed over the three components.
    pub iterations: usize,
    /// Largest residual left [m/s].
    pub residual: f64,
}

impl Diffusion {
    /// Builds the three systems' structure for `grid`'s domain and boundaries.
    pub fn new(grid: &MacGrid) -> Self {
        let dom = &grid.domain;
        let bnd = dom.boundaries;
        let axes = [0, 1, 2].map(|a| {
            let d = dom.face_dims(a);
            let na = dom.cells[a];
            // Which faces are unknown, and their unknown index.
            let mut index = vec![NONE; dom.face_count(a)];
            let mut face = Vec::new();
            let mut copies = Vec::new();
            let fixed_side = |b: Boundary| matches!(b, Boundary::Wall | Boundary::Inflow(_));
            for k in 0..d[2] {
                for j in 0..d[1] {
                    for i in 0..d[0] {
                        let idx = [i, j, k];
                        let f = dom.face(a, i, j, k);
                        let m = idx[a];
                        if bnd.is_periodic(a) && m == na {
                            let mut o = idx;
                            o[a] = 0;
                            copies.push((f as u32, dom.face(a, o[0], o[1], o[2]) as u32));
                            continue;
                        }
                        if (m == 0 && fixed_side(bnd.lo[a])) || (m == na && fixed_side(bnd.hi[a])) {
                            continue; // prescribed normal velocity
                        }
                        index[f] = face.len() as u32;
                        face.push(f as u32);
                    }
                }
            }
            let mut nbr = Vec::with_capacity(face.len());
            let mut weight = Vec::with_capacity(face.len());
            let mut known = Vec::new();
            for (row, &f) in face.iter().enumerate() {
                let f = f as usize;
                // Face (i, j, k) from its index.
                let idx = [f % d[0], (f / d[0]) % d[1], f / (d[0] * d[1])];
                let mut nb = [NONE; 6];
                let mut w = 0.0;
                for b in 0..3 {
                    let len = d[b]; // faces along b in this array
                    let periodic = bnd.is_periodic(b);
                    // Along b, the last index on a periodic axis: for b == a the copy face
                    // n is not an unknown, so wrap over 0..n; across, 0..n_b.
                    let count = if b == a && periodic { na } else { len };
                    for (s, side) in [(0usize, bnd.lo[b]), (1, bnd.hi[b])] {
                        let m = idx[b];
                        let next = if s == 0 {
                            if m > 0 {
                                Some(m - 1)
                            } else if periodic {
                                Some(count - 1)
                            } else {
                                None
                            }
                        } else if m + 1 < count {
                            Some(m + 1)
                        } else if periodic {
                            Some(0)
                        } else {
                            None
                        };
                        match next {
                            Some(n2) => {
                                let mut o = idx;
                                o[b] = n2;
                                let g = dom.face(a, o[0], o[1], o[2]);
                                if index[g] != NONE {
                                    nb[2 * b + s] = index[g];
                                    w += 1.0;
                                } else if g != f {
                                    // A prescribed face (normal component at a wall or
                                    // inflow): Dirichlet, read from the grid at solve time.
                                    known.push((row as u32, g as u32, 0.0));
                                    w += 1.0;
                                }
                            }
                            None if b == a => {} // an open face: zero gradient
                            None => match side {
                                // Tangential at a wall: no-slip, ghost −u.
                                Boundary::Wall => w += 2.0,
                                Boundary::Inflow(v) => {
                                    w += 2.0;
                                    known.push((row as u32, NONE, 2.0 * v[a]));
                                }
                                Boundary::Open | Boundary::Periodic => {}
                            },
                        }
                    }
                }
                nbr.push(nb);
                weight.push(w);
            }
            Component {
                face,
                nbr,
                weight,
                known,
                copies,
            }
        });
        let n = axes.iter().map(|c| c.face.len()).max().unwrap_or(0);
        Diffusion {
            domain: dom.clone(),
            r: vec![0.0; n],
            z: vec![0.0; n],
            p: vec![0.0; n],
            q: vec![0.0; n],
            u: vec![0.0; n],
            b: vec![0.0; n],
            solved: [0, 1, 2].map(|a| vec![0.0; axes[a].face.len()]),
            stop: None,
            axes,
        }
    }

    /// Sets (or clears) the check asked once per CG iteration; when it answers true the
    /// solve ends with [`ProjectionError::Interrupted`] and the grid is left as it was.
    pub fn set_stop(&mut self, stop: Option<crate::pressure::StopCheck>) {
        self.stop = stop;
    }

    /// True when this structure was built for `grid`'s domain.
    pub fn fits(&self, grid: &MacGrid) -> bool {
        self.domain == grid.domain
    }

    /// Diffuses `grid`'s velocity with kinematic viscosity `nu` [m²/s] over `h` [s], each
    /// component's CG stopping at a residual of `settings.tolerance` [m/s]. On error the grid
    /// is unchanged.
    pub fn diffuse(
        &mut self,
        grid: &mut MacGrid,
        nu: f64,
        h: f64,
        settings: &PressureSolve,
    ) -> Result<DiffusionStats, ProjectionError> {
        if !(nu.is_finite() && nu >= 0.0) {
            return Err(crate::FluidError::Parameter {
                name: "kinematic viscosity",
                message: format!("must be finite and >= 0 m²/s, got {nu}"),
            }
            .into());
        }
        if !self.fits(grid) {
            return Err(crate::FluidError::Parameter {
                name: "grid",
                message: "the diffusion structure was built for another domain".into(),
            }
            .into());
        }
        let mut stats = DiffusionStats::default();
        if nu == 0.0 {
            return Ok(stats);
        }
        let c = h * nu / (grid.domain.dx * grid.domain.dx);
        for (a, comp) in self.axes.iter().enumerate() {
            let n = comp.face.len();
            let vel = &grid.vel[a];
            let (r, z, p, q, u, b) = (
                &mut self.r[..n],
                &mut self.z[..n],
                &mut self.p[..n],
                &mut self.q[..n],
                &mut self.u[..n],
                &mut self.b[..n],
            );
            for (row, &f) in comp.face.iter().enumerate() {
                b[row] = vel[f as usize];
                u[row] = vel[f as usize];
            }
            for &(row, f, k) in &comp.known {
                let val = if f == NONE { k } else { vel[f as usize] };
                b[row as usize] += c * val;
            }
            let apply = |x: &[f64], out: &mut [f64]| {
                for row in 0..n {
                    let mut s = (1.0 + c * comp.weight[row]) * x[row];
                    for &m in &comp.nbr[row] {
                        if m != NONE {
                            s -= c * x[m as usize];
                        }
                    }
                    out[row] = s;
                }
            };
            apply(u, q);
            let mut res = 0.0f64;
            for row in 0..n {
                r[row] = b[row] - q[row];
                res = res.max(r[row].abs());
            }
            let mut it = 0;
            let mut rz = 0.0;
            while res > settings.tolerance {
                if self.stop.as_ref().is_some_and(|s| s()) {
                    return Err(ProjectionError::Interrupted {
                        iteration: stats.iterations + it,
                    });
                }
                if it == settings.max_iterations {
                    return Err(ProjectionError::NotConverged {
                        iterations: stats.iterations + it,
                        residual: res,
                        tolerance: settings.tolerance,
                    });
                }
                let mut rz_new = 0.0;
                for row in 0..n {
                    z[row] = r[row] / (1.0 + c * comp.weight[row]);
                    rz_new += r[row] * z[row];
                }
                if it == 0 {
                    p.copy_from_slice(z);
                } else {
                    let beta = rz_new / rz;
                    for row in 0..n {
                        p[row] = z[row] + beta * p[row];
                    }
                }
                rz = rz_new;
                apply(p, q);
                let pq: f64 = p.iter().zip(q.iter()).map(|(x, y)| x * y).sum();
                let alpha = rz / pq;
                res = 0.0;
                for row in 0..n {
                    u[row] += alpha * p[row];
                    r[row] -= alpha * q[row];
                    res = res.max(r[row].abs());
                }
                it += 1;
            }
            stats.iterations += it;
            stats.residual = stats.residual.max(res);
            self.solved[a].copy_from_slice(u);
        }
        for (a, comp) in self.axes.iter().enumerate() {
            for (row, &f) in comp.face.iter().enumerate() {
                grid.vel[a][f as usize] = self.solved[a][row];
            }
            for &(copy, orig) in &comp.copies {
                grid.vel[a][copy as usize] = grid.vel[a][orig as usize];
            }
        }
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{Axis, Boundaries, Domain};

    /// A shear wave u_x = sin(2πy/L) in a periodic box decays by exactly
    /// 1/(1 + hν λ) per backward-Euler step, λ = (4/Δx²) sin²(πΔx/L) the discrete
    /// Laplacian's eigenvalue for that wave. Tolerance 1e-12: the CG tolerance.
    #[test]
    fn a_shear_wave_decays_by_the_discrete_factor() {
        let b = Boundaries::periodic(&[Axis::X, Axis::Y, Axis::Z]);
        let d = Domain::new([0.0; 3], [1.0, 1.0, 0.25], 1.0 / 16.0, b, None).unwrap();
        let mut g = MacGrid::new(d);
        let tau = std::f64::consts::TAU;
        g.set_velocity(|p| [(tau * p[1]).sin(), 0.0, 0.0]);
        let before = g.vel[0].clone();
        let (nu, h, dx) = (1e-2, 0.5, 1.0 / 16.0);
        let mut diff = Diffusion::new(&g);
        let s = diff
            .diffuse(
                &mut g,
                nu,
                h,
                &PressureSolve {
                    tolerance: 1e-14,
                    max_iterations: 200,
                },
            )
            .unwrap();
        let lambda = 4.0 / (dx * dx) * (std::f64::consts::PI * dx).sin().powi(2);
        let factor = 1.0 / (1.0 + h * nu * lambda);
        for (u, u0) in g.vel[0].iter().zip(&before) {
            assert!((u - factor * u0).abs() < 1e-12, "{u} vs {}", factor * u0);
        }
        assert!(g.vel[1].iter().all(|v| v.abs() < 1e-14));
        assert!(s.iterations > 0);
    }

    /// A uniform flow along a channel is untouched by viscosity away from walls, and stays
    /// uniform with open and periodic sides (zero gradient, wrap).
    #[test]
    fn uniform_flow_with_open_and_periodic_sides_is_unchanged() {
        let mut b = Boundaries::periodic(&[Axis::X, Axis::Z]);
        b.lo[1] = Boundary::Inflow([0.3, 0.2, -0.1]);
        b.hi[1] = Boundary::Open;
        let d = Domain::new([0.0; 3], [0.5, 0.5, 0.5], 0.1, b, None).unwrap();
        let mut g = MacGrid::new(d);
        g.set_velocity(|_| [0.3, 0.2, -0.1]);
        g.apply_boundaries();
        let before = g.vel.clone();
        Diffusion::new(&g)
            .diffuse(&mut g, 0.05, 1.0, &PressureSolve::default())
            .unwrap();
        for (a, before) in before.iter().enumerate() {
            for (u, u0) in g.vel[a].iter().zip(before) {
                assert!((u - u0).abs() < 1e-9, "axis {a}: {u} vs {u0}");
            }
        }
    }

    /// Bad viscosity is refused by name and leaves the grid unchanged.
    #[test]
    fn negative_viscosity_is_refused() {
        let d = Domain::new([0.0; 3], [1.0; 3], 0.25, Boundaries::closed(), None).unwrap();
        let mut g = MacGrid::new(d);
        g.set_velocity(|p| [p[1], 0.0, 0.0]);
        let before = g.vel.clone();
        let e = Diffusion::new(&g)
            .diffuse(&mut g, -1.0, 0.1, &PressureSolve::default())
            .unwrap_err();
        assert!(e.to_string().contains("kinematic viscosity"), "{e}");
        assert_eq!(g.vel, before);
    }
}

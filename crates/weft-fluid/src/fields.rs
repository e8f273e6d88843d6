//! What a grid holds, read out for probes, diagnostics and field files: cell-centred
//! velocity and solid fraction, vorticity, the hydrostatic pressure, the fluid's volume and
//! energy, and the impulse the domain's walls and obstacles give the fluid through the
//! pressure.
//!
//! Cell-centred values average the staggered faces: a cell's velocity component along axis a
//! is the mean of its two axis-a faces (second order at the centre), its solid fraction
//! 1 − the mean fluid fraction of its six faces.

use crate::grid::{Boundary, MacGrid};

impl MacGrid {
    /// Index (i, j, k) of the cell that holds `p` (clamped into the domain, wrapped on
    /// periodic axes).
    pub fn cell_holding(&self, p: [f64; 3]) -> [usize; 3] {
        let dom = &self.domain;
        std::array::from_fn(|b| {
            let x = ((p[b] - dom.origin[b]) / dom.dx).floor();
            let n = dom.cells[b] as f64;
            let x = if dom.boundaries.is_periodic(b) {
                x.rem_euclid(n)
            } else {
                x.clamp(0.0, n - 1.0)
            };
            if x.is_finite() { x as usize } else { 0 }.min(dom.cells[b] - 1)
        })
    }

    /// The two axis-`a` faces of cell `c` (its − and + side).
    fn cell_faces(&self, a: usize, c: [usize; 3]) -> (usize, usize) {
        let mut hi = c;
        hi[a] += 1;
        (
            self.domain.face(a, c[0], c[1], c[2]),
            self.domain.face(a, hi[0], hi[1], hi[2]),
        )
    }

    /// The velocity at the centre of cell `c` [m/s]: per axis the mean of its two faces.
    pub fn cell_velocity(&self, c: [usize; 3]) -> [f64; 3] {
        std::array::from_fn(|a| {
            let (lo, hi) = self.cell_faces(a, c);
            0.5 * (self.vel[a][lo] + self.vel[a][hi])
        })
    }

    /// The solid fraction of cell `c`: 1 − the mean fluid fraction α of its six faces.
    pub fn cell_solid_fraction(&self, c: [usize; 3]) -> f64 {
        let mut alpha = 0.0;
        for a in 0..3 {
            let (lo, hi) = self.cell_faces(a, c);
            alpha += self.alpha[a][lo] + self.alpha[a][hi];
        }
        1.0 - alpha / 6.0
    }

    /// Calls `f(cell index, (i, j, k))` for every cell, x fastest (the cell index order).
    pub fn for_each_cell(&self, mut f: impl FnMut(usize, [usize; 3])) {
        let [nx, ny, nz] = self.domain.cells;
        let mut n = 0;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    f(n, [i, j, k]);
                    n += 1;
                }
            }
        }
    }

    /// The solid fraction of the cell that holds `p`.
    pub fn solid_fraction_at(&self, p: [f64; 3]) -> f64 {
        self.cell_solid_fraction(self.cell_holding(p))
    }

    /// The vorticity ∇ × u at `p` [1/s]: central differences, half a cell either side, of the
    /// trilinearly sampled velocity (exact for velocity fields linear in space).
    pub fn vorticity_at(&self, p: [f64; 3]) -> [f64; 3] {
        let e = 0.5 * self.domain.dx;
        // ∂u_a/∂x_b
        let d = |a: usize, b: usize| {
            let (mut lo, mut hi) = (p, p);
            lo[b] -= e;
            hi[b] += e;
            (self.sample(a, hi) - self.sample(a, lo)) / (2.0 * e)
        };
        [d(2, 1) - d(1, 2), d(0, 2) - d(2, 0), d(1, 0) - d(0, 1)]
    }

    /// The point the hydrostatic pressure is measured from for gravity `g`: the domain's
    /// highest corner (along −g), so that ρ g·(x − x_top) ≥ 0 inside is the pressure under a
    /// free surface at the domain's top.
    pub fn hydrostatic_reference(&self, g: [f64; 3]) -> [f64; 3] {
        let size = self.domain.size();
        std::array::from_fn(|a| self.domain.origin[a] + if g[a] < 0.0 { size[a] } else { 0.0 })
    }

    /// The hydrostatic pressure ρ g·(x − x_top) at `x` [Pa] for density `rho` and gravity `g`,
    /// x_top from [`MacGrid::hydrostatic_reference`]: what the reduced pressure the grid
    /// solves for leaves out.
    pub fn hydrostatic_pressure(&self, x: [f64; 3], g: [f64; 3], rho: f64) -> f64 {
        let top = self.hydrostatic_reference(g);
        rho * (0..3).map(|a| g[a] * (x[a] - top[a])).sum::<f64>()
    }

    /// The fluid's volume [m³]: Σ over cells of (1 − solid fraction) Δx³.
    pub fn fluid_volume(&self) -> f64 {
        let mut v = 0.0;
        self.for_each_cell(|_, c| v += 1.0 - self.cell_solid_fraction(c));
        v * self.domain.dx.powi(3)
    }

    /// The fluid's kinetic energy ½ Σ ρ α u² Δx³ over distinct faces [J] for density `rho`.
    pub fn fluid_kinetic_energy(&self, rho: f64) -> f64 {
        let mut e = 0.0;
        self.for_distinct_faces(|a, f| e += 0.5 * self.alpha[a][f] * self.vel[a][f].powi(2));
        rho * e * self.domain.dx.powi(3)
    }

    /// The impulse the pressure `self.pressure` gives the fluid and the solids in it through
    /// the domain's closed sides and its obstacles over a step of `h` seconds [N·s].
    ///
    /// The porous projection applies −h ∇p Δx³ on each face, the fluid's share α and the
    /// solids' 1 − α. Summed over the faces that carry velocity, the pressure differences
    /// telescope along each row of faces to what the faces that do not carry it would have
    /// had: at a wall (or an inflow, whose velocity is prescribed) on the − side the cell's
    /// pressure pushes +p Δx² h, on the + side −p Δx² h, and a face inside an obstacle
    /// (fluid fraction 0) between cells L and R gives (p_R − p_L) Δx² h. So this is what the
    /// walls and obstacles gave fluid + solids, and in a closed box the change of their total
    /// momentum is this plus the body forces. Open sides are not walls (fluid and momentum
    /// cross them) and periodic ones have none.
    pub fn boundary_impulse(&self, h: f64) -> [f64; 3] {
        let dom = &self.domain;
        let p = &self.pressure;
        let area = dom.dx * dom.dx;
        let mut j = [0.0; 3];
        for a in 0..3 {
            let n = dom.cells[a];
            let closed = |b: Boundary| matches!(b, Boundary::Wall | Boundary::Inflow(_));
            let (lo_closed, hi_closed) =
                (closed(dom.boundaries.lo[a]), closed(dom.boundaries.hi[a]));
            let periodic = dom.boundaries.is_periodic(a);
            let d = dom.face_dims(a);
            for k in 0..d[2] {
                for jj in 0..d[1] {
                    for i in 0..d[0] {
                        let idx = [i, jj, k];
                        let along = idx[a];
                        let cell = |m: usize| {
                            let mut c = idx;
                            c[a] = m;
                            p[dom.cell(c[0], c[1], c[2])]
                        };
                        if along == 0 {
                            if lo_closed {
                                j[a] += cell(0) * area;
                            } else if periodic && self.alpha[a][dom.face(a, i, jj, k)] == 0.0 {
                                // The seam's face, between cell n − 1 and cell 0 (face n is
                                // its copy, which the periodic side skips below).
                                j[a] += (cell(0) - cell(n - 1)) * area;
                            }
                        } else if along == n {
                            if hi_closed {
                                j[a] -= cell(n - 1) * area;
                            }
                        } else if self.alpha[a][dom.face(a, i, jj, k)] == 0.0 {
                            j[a] += (cell(along) - cell(along - 1)) * area;
                        }
                    }
                }
            }
        }
        j.map(|x| x * h)
    }
}

#[cfg(test)]
mod tests {
    use crate::grid::{Boundaries, Domain, MacGrid};

    fn grid() -> MacGrid {
        let d = Domain::new(
            [0.1, -0.2, 0.0],
            [0.4, 0.3, 0.5],
            0.05,
            Boundaries::closed(),
            None,
        )
        .unwrap();
        MacGrid::new(d)
    }

    #[test]
    fn vorticity_of_a_rigid_rotation_is_twice_its_rate() {
        // u = Ω × (x − c): linear, so the sampled differences are exact: ω = 2Ω.
        let mut g = grid();
        let (om, c) = ([0.3, -1.1, 0.7], [0.3, -0.05, 0.25]);
        g.vel = [0, 1, 2].map(|a| vec![0.0; g.domain.face_count(a)]);
        for a in 0..3 {
            let d = g.domain.face_dims(a);
            for k in 0..d[2] {
                for j in 0..d[1] {
                    for i in 0..d[0] {
                        let x = g.domain.face_position(a, [i, j, k]);
                        let r = [x[0] - c[0], x[1] - c[1], x[2] - c[2]];
                        let u = [
                            om[1] * r[2] - om[2] * r[1],
                            om[2] * r[0] - om[0] * r[2],
                            om[0] * r[1] - om[1] * r[0],
                        ];
                        let f = g.domain.face(a, i, j, k);
                        g.vel[a][f] = u[a];
                    }
                }
            }
        }
        let w = g.vorticity_at([0.27, -0.01, 0.21]);
        for a in 0..3 {
            assert!((w[a] - 2.0 * om[a]).abs() < 1e-12, "{w:?}");
        }
        // The cell centre's velocity is the field's value there (linear field).
        let cc = g.domain.cell_center([2, 3, 4]);
        let v = g.cell_velocity([2, 3, 4]);
        let want = g.velocity_at(cc);
        for a in 0..3 {
            assert!((v[a] - want[a]).abs() < 1e-14);
        }
    }

    #[test]
    fn fractions_volume_and_the_hydrostatic_reference() {
        let mut g = grid();
        let full = 0.4 * 0.3 * 0.5;
        assert!((g.fluid_volume() - full).abs() < 1e-15);
        // One cell's six faces half solid: that cell is half solid.
        let c = [3, 2, 5];
        for a in 0..3 {
            let mut hi = c;
            hi[a] += 1;
            for idx in [c, hi] {
                let f = g.domain.face(a, idx[0], idx[1], idx[2]);
                g.alpha[a][f] = 0.5;
            }
        }
        assert_eq!(g.cell_solid_fraction(c), 0.5);
        let p = g.domain.cell_center(c);
        assert_eq!(g.solid_fraction_at(p), 0.5);
        // Its six neighbours share one half-solid face each (φ = 1/12 each): one cell's
        // volume in all, as the six faces hold (each face's solid volume is split between
        // the two cells it bounds).
        assert!((g.fluid_volume() - (full - 0.05f64.powi(3))).abs() < 1e-15);
        let top = g.hydrostatic_reference([0.0, -9.81, 0.0]);
        assert!(
            (top[0] - 0.1).abs() + (top[1] - 0.1).abs() + top[2].abs() < 1e-15,
            "{top:?}"
        );
        assert_eq!(g.cell_holding([9.0, -9.0, 0.26]), [7, 0, 5]);
    }

    #[test]
    fn a_pressure_gradient_in_a_closed_box_pushes_on_its_walls() {
        // p = 2x + 3: the walls give the fluid (p(x_first) − p(x_last)) Δx² h per row.
        let mut g = grid();
        let dom = g.domain.clone();
        let mut p = vec![0.0; dom.cell_count()];
        g.for_each_cell(|n, c| p[n] = 2.0 * dom.cell_center(c)[0] + 3.0);
        g.pressure = p;
        let h = 0.01;
        let j = g.boundary_impulse(h);
        let rows = (dom.cells[1] * dom.cells[2]) as f64;
        let want = (2.0 * dom.cell_center([0, 0, 0])[0] - 2.0 * dom.cell_center([7, 0, 0])[0])
            * rows
            * dom.dx
            * dom.dx
            * h;
        assert!((j[0] - want).abs() < 1e-15, "{j:?} vs {want}");
        assert!(j[1].abs() < 1e-15 && j[2].abs() < 1e-15, "{j:?}");
        // It is minus the sum of −h ∇p Δx³ over the interior faces.
        let mut interior = 0.0;
        for k in 0..dom.cells[2] {
            for jj in 0..dom.cells[1] {
                for i in 1..dom.cells[0] {
                    let (pl, pr) = (
                        g.pressure[dom.cell(i - 1, jj, k)],
                        g.pressure[dom.cell(i, jj, k)],
                    );
                    interior -= (pr - pl) / dom.dx * dom.dx.powi(3) * h;
                }
            }
        }
        assert!((interior - want).abs() < 1e-15);
    }

    #[test]
    fn an_obstacle_face_on_a_periodic_seam_counts() {
        use crate::grid::Axis;
        let d = Domain::new(
            [0.0; 3],
            [0.4, 0.2, 0.2],
            0.1,
            Boundaries::periodic(&[Axis::X]),
            None,
        )
        .unwrap();
        let mut g = MacGrid::new(d);
        let dom = g.domain.clone();
        let mut p = vec![0.0; dom.cell_count()];
        g.for_each_cell(|n, c| p[n] = 1.0 + c[0] as f64);
        g.pressure = p;
        // No obstacle: a periodic axis has no walls, whatever the pressure.
        assert_eq!(g.boundary_impulse(1.0)[0], 0.0);
        // The seam's faces (x = 0, and their copies at x = 0.4) inside an obstacle: each
        // gives (p(cell 0) − p(cell 3)) Δx², as an interior obstacle face would.
        for k in 0..2 {
            for j in 0..2 {
                for i in [0, 4] {
                    let f = dom.face(0, i, j, k);
                    g.alpha[0][f] = 0.0;
                }
            }
        }
        let want = 4.0 * (1.0 - 4.0) * 0.01;
        assert!((g.boundary_impulse(1.0)[0] - want).abs() < 1e-15);
        // The same as what the faces that carry velocity (1..3) get, Σ −∇p Δx³.
        let open_faces = -4.0 * 3.0 * 0.01;
        assert!((g.boundary_impulse(1.0)[0] - open_faces).abs() < 1e-15);
    }
}

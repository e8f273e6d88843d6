//! The domain, its boundaries, and the staggered grid's fields.
//!
//! Cell (i, j, k) spans `origin + [i, i+1] × [j, j+1] × [k, k+1] · dx`. The x-velocity lives
//! on the faces normal to x, at `origin + (i, j + ½, k + ½) · dx` for i in 0..=nx, and so on
//! for y and z. On a periodic axis faces 0 and n are the same face; both entries are kept and
//! kept equal.

/// A coordinate axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    /// x
    X = 0,
    /// y
    Y = 1,
    /// z
    Z = 2,
}

/// What happens at one side of the domain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Boundary {
    /// A closed, fixed wall: no flow through it.
    Wall,
    /// The opposite side's flow re-enters here (both sides of the axis must say so).
    Periodic,
    /// Prescribed velocity [m/s] (a current or a wind), entering or leaving.
    Inflow([f64; 3]),
    /// Open to still fluid at zero (gauge) pressure: flow leaves or enters freely.
    Open,
}

/// The six sides: `lo[a]` at the axis' minimum, `hi[a]` at its maximum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Boundaries {
    /// Minimum sides (x, y, z).
    pub lo: [Boundary; 3],
    /// Maximum sides (x, y, z).
    pub hi: [Boundary; 3],
}

impl Boundaries {
    /// A closed box.
    pub fn closed() -> Self {
        Boundaries {
            lo: [Boundary::Wall; 3],
            hi: [Boundary::Wall; 3],
        }
    }
    /// Periodic on the given axes, walls elsewhere.
    pub fn periodic(axes: &[Axis]) -> Self {
        let mut b = Self::closed();
        for &a in axes {
            b.lo[a as usize] = Boundary::Periodic;
            b.hi[a as usize] = Boundary::Periodic;
        }
        b
    }
    /// True when axis `a` is periodic.
    pub fn is_periodic(&self, a: usize) -> bool {
        self.lo[a] == Boundary::Periodic
    }
}

/// Why a fluid cannot be set up or solved.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FluidError {
    /// The cell size is not a positive number.
    ///
    /// `cell_size = 0`.
    #[error("cell size must be > 0 m, got {0}")]
    CellSize(f64),
    /// The domain has no extent along an axis, or is not finite.
    #[error("domain size must be positive and finite on every axis, got {0:?} m")]
    Size([f64; 3]),
    /// One side of an axis is periodic and the other is not.
    #[error("axis {axis} is periodic on one side only (both sides must be Periodic)")]
    HalfPeriodic {
        /// 0, 1, 2 for x, y, z.
        axis: usize,
    },
    /// The grid would not fit in the memory allowed; nothing was allocated.
    ///
    /// A 4096³ grid at 1 mm cells.
    #[error(
        "a {cells:?}-cell grid needs about {need_gib:.1} GiB, more than the {limit_gib:.1} GiB available; use larger cells or a smaller domain"
    )]
    TooLarge {
        /// Cells per axis.
        cells: [usize; 3],
        /// Estimated need [GiB].
        need_gib: f64,
        /// The limit [GiB].
        limit_gib: f64,
    },
    /// A parameter is out of its range.
    #[error("{name} {message}")]
    Parameter {
        /// Which parameter.
        name: &'static str,
        /// What is wrong.
        message: String,
    },
}

/// The region the fluid fills and how it is discretized.
#[derive(Clone, Debug, PartialEq)]
pub struct Domain {
    /// Minimum corner [m].
    pub origin: [f64; 3],
    /// Cells per axis.
    pub cells: [usize; 3],
    /// Cell size [m].
    pub dx: f64,
    /// The six sides.
    pub boundaries: Boundaries,
}

/// Bytes per cell a coupled step holds at most. A grid is 12 face arrays (velocity, fluid
/// fraction, drag, solid velocity) and the pressure, 104 bytes a cell; a coupled step keeps
/// about eight at once (the state, u*, the rasterized and projected iterates, the pressure
/// gradient, the advection scratch, the loop's feedback and the frame's checkpoint), and the
/// projection adds ten cell arrays (right side, CG vectors) and the 7-point matrix with its
/// incomplete factor and their indices (about 190 bytes).
pub const BYTES_PER_CELL: u64 = 8 * 104 + 8 * 10 + 12 * 7 + 12 * 4 + 8 * 7;

impl Domain {
    /// A domain from its minimum corner, size and cell size; the size is rounded up to whole
    /// cells. Refuses (before allocating anything) a grid whose estimated memory
    /// ([`BYTES_PER_CELL`]) exceeds `max_bytes`; `None`: no limit (a graph passes what the
    /// process may still allocate).
    pub fn new(
        origin: [f64; 3],
        size: [f64; 3],
        dx: f64,
        boundaries: Boundaries,
        max_bytes: Option<u64>,
    ) -> Result<Self, FluidError> {
        if !(dx.is_finite() && dx > 0.0) {
            return Err(FluidError::CellSize(dx));
        }
        if !size.iter().all(|s| s.is_finite() && *s > 0.0) || !origin.iter().all(|o| o.is_finite())
        {
            return Err(FluidError::Size(size));
        }
        for a in 0..3 {
            if (boundaries.lo[a] == Boundary::Periodic) != (boundaries.hi[a] == Boundary::Periodic)
            {
                return Err(FluidError::HalfPeriodic { axis: a });
            }
        }
        let per_axis = size.map(|s| (s / dx - 1e-9).ceil().max(1.0));
        let total: f64 = per_axis.iter().product();
        let need = total * BYTES_PER_CELL as f64;
        let limit = max_bytes.map_or(f64::INFINITY, |b| b as f64);
        // Cells and faces are indexed with u32 (u32::MAX marks "none").
        if need > limit || total >= (u32::MAX / 4) as f64 {
            const GIB: f64 = (1u64 << 30) as f64;
            return Err(FluidError::TooLarge {
                cells: per_axis.map(|c| c.min(usize::MAX as f64) as usize),
                need_gib: need / GIB,
                limit_gib: limit / GIB,
            });
        }
        Ok(Domain {
            origin,
            cells: per_axis.map(|c| c as usize),
            dx,
            boundaries,
        })
    }

    /// True when `p` lies in the domain's box (boundary included).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        let size = self.size();
        (0..3).all(|b| (0.0..=size[b]).contains(&(p[b] - self.origin[b])))
    }

    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        self.cells.iter().product()
    }

    /// Index of cell (i, j, k).
    #[inline]
    pub fn cell(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.cells[0] * (j + self.cells[1] * k)
    }

    /// Faces per axis-`a` array: one more than the cells along `a`.
    pub fn face_dims(&self, a: usize) -> [usize; 3] {
        let mut d = self.cells;
        d[a] += 1;
        d
    }

    /// Index of the axis-`a` face (i, j, k) (i along x etc., with the `a` index in 0..=n).
    #[inline]
    pub fn face(&self, a: usize, i: usize, j: usize, k: usize) -> usize {
        let d = self.face_dims(a);
        i + d[0] * (j + d[1] * k)
    }

    /// Number of axis-`a` faces.
    pub fn face_count(&self, a: usize) -> usize {
        self.face_dims(a).iter().product()
    }

    /// Position of the axis-`a` face (i, j, k) [m].
    pub fn face_position(&self, a: usize, idx: [usize; 3]) -> [f64; 3] {
        let mut p = [0.0; 3];
        for b in 0..3 {
            let off = if b == a { 0.0 } else { 0.5 };
            p[b] = self.origin[b] + (idx[b] as f64 + off) * self.dx;
        }
        p
    }

    /// Centre of cell (i, j, k) [m].
    pub fn cell_center(&self, idx: [usize; 3]) -> [f64; 3] {
        [0, 1, 2].map(|b| self.origin[b] + (idx[b] as f64 + 0.5) * self.dx)
    }

    /// The boundary face pairs of axis `a`: for every row of faces across the axis, the
    /// indices of its first (at the axis' minimum) and last (at its maximum) face. On a
    /// periodic axis these are the two copies of one face.
    pub fn boundary_face_pairs(&self, a: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        let d = self.face_dims(a);
        let n = self.cells[a];
        let (b1, b2) = ((a + 1) % 3, (a + 2) % 3);
        (0..d[b2]).flat_map(move |s| {
            (0..d[b1]).map(move |t| {
                let at = |along: usize| {
                    let mut idx = [0; 3];
                    idx[a] = along;
                    idx[b1] = t;
                    idx[b2] = s;
                    self.face(a, idx[0], idx[1], idx[2])
                };
                (at(0), at(n))
            })
        })
    }

    /// Size of the domain [m].
    pub fn size(&self) -> [f64; 3] {
        [0, 1, 2].map(|a| self.cells[a] as f64 * self.dx)
    }
}

/// The fluid's state and the solids' imprint on it.
#[derive(Clone, Debug)]
pub struct MacGrid {
    /// The domain.
    pub domain: Domain,
    /// Face velocities per axis [m/s].
    pub vel: [Vec<f64>; 3],
    /// Cell pressures [Pa] (gauge).
    pub pressure: Vec<f64>,
    /// Fluid fraction α = 1 − φ_s per face (1 where no solid).
    pub alpha: [Vec<f64>; 3],
    /// Drag coefficient per unit volume K [kg/(m³·s)] per face: the fluid feels −K(u − v).
    pub drag: [Vec<f64>; 3],
    /// Solid velocity per face [m/s] (the normal component for that face's axis).
    pub solid_vel: [Vec<f64>; 3],
}

impl MacGrid {
    /// A fluid at rest with no solids.
    pub fn new(domain: Domain) -> Self {
        let faces = |v: f64| [0, 1, 2].map(|a| vec![v; domain.face_count(a)]);
        MacGrid {
            vel: faces(0.0),
            pressure: vec![0.0; domain.cell_count()],
            alpha: faces(1.0),
            drag: faces(0.0),
            solid_vel: faces(0.0),
            domain,
        }
    }

    /// Makes `self` a copy of `other`, reusing `self`'s buffers (no allocation when the
    /// domains have the same size).
    pub fn copy_from(&mut self, other: &MacGrid) {
        self.domain.clone_from(&other.domain);
        for a in 0..3 {
            self.vel[a].clone_from(&other.vel[a]);
            self.alpha[a].clone_from(&other.alpha[a]);
            self.drag[a].clone_from(&other.drag[a]);
            self.solid_vel[a].clone_from(&other.solid_vel[a]);
        }
        self.pressure.clone_from(&other.pressure);
    }

    /// Sets the velocity of every face from a field `f(position) → [u, v, w]`.
    pub fn set_velocity(&mut self, f: impl Fn([f64; 3]) -> [f64; 3]) {
        for a in 0..3 {
            let d = self.domain.face_dims(a);
            for k in 0..d[2] {
                for j in 0..d[1] {
                    for i in 0..d[0] {
                        let p = self.domain.face_position(a, [i, j, k]);
                        let idx = self.domain.face(a, i, j, k);
                        self.vel[a][idx] = f(p)[a];
                    }
                }
            }
        }
        self.apply_boundaries();
    }

    /// Imposes the boundary conditions on the boundary faces: no flow through walls, the
    /// prescribed flow at inflows, and equal values on the two copies of a periodic face.
    pub fn apply_boundaries(&mut self) {
        for a in 0..3 {
            let b = self.domain.boundaries;
            for (lo, hi) in self.domain.boundary_face_pairs(a) {
                if b.is_periodic(a) {
                    self.vel[a][hi] = self.vel[a][lo];
                    continue;
                }
                for (face, side) in [(lo, b.lo[a]), (hi, b.hi[a])] {
                    match side {
                        Boundary::Wall => self.vel[a][face] = 0.0,
                        Boundary::Inflow(v) => self.vel[a][face] = v[a],
                        Boundary::Open | Boundary::Periodic => {}
                    }
                }
            }
        }
    }

    /// Adds a uniform acceleration `g` [m/s²] over `h` seconds to every face (body forces
    /// such as gravity), then re-imposes the boundaries.
    pub fn accelerate(&mut self, g: [f64; 3], h: f64) {
        for (a, v) in self.vel.iter_mut().enumerate() {
            v.iter_mut().for_each(|u| *u += h * g[a]);
        }
        self.apply_boundaries();
    }

    /// The trilinear stencil of point `p` on the axis-`a` faces: eight (face index, weight)
    /// pairs, weights summing to one. Outside the domain the nearest faces are used
    /// (clamped), or the stencil wraps on periodic axes (where only faces 0..n−1 are
    /// addressed: face n is face 0's copy). Sampling and rasterization share it, so what the
    /// grid gives a solid and what the solid gives the grid use the same weights.
    pub fn face_stencil(&self, a: usize, p: [f64; 3]) -> [(usize, f64); 8] {
        let dom = &self.domain;
        let d = dom.face_dims(a);
        let mut base = [0usize; 3];
        let mut frac = [0.0; 3];
        let mut next = [0usize; 3];
        for b in 0..3 {
            let off = if b == a { 0.0 } else { 0.5 };
            let x = (p[b] - dom.origin[b]) / dom.dx - off;
            if dom.boundaries.is_periodic(b) {
                // Distinct positions along a periodic axis: n faces (a) or n cells (others).
                let n = dom.cells[b] as f64;
                let xw = x.rem_euclid(n);
                let i0 = (xw.floor() as usize).min(dom.cells[b] - 1);
                base[b] = i0;
                frac[b] = xw - i0 as f64;
                next[b] = (i0 + 1) % dom.cells[b];
            } else {
                let max = (d[b] - 1) as f64;
                let xc = x.clamp(0.0, max);
                let i0 = (xc.floor() as usize).min(d[b].saturating_sub(2));
                base[b] = i0;
                frac[b] = if d[b] > 1 { xc - i0 as f64 } else { 0.0 };
                next[b] = (i0 + 1).min(d[b] - 1);
            }
        }
        std::array::from_fn(|corner| {
            let mut idx = [0usize; 3];
            let mut w = 1.0;
            for b in 0..3 {
                let hi = (corner >> b) & 1 == 1;
                idx[b] = if hi { next[b] } else { base[b] };
                w *= if hi { frac[b] } else { 1.0 - frac[b] };
            }
            (dom.face(a, idx[0], idx[1], idx[2]), w)
        })
    }

    /// The axis-`a` velocity component at point `p`, trilinear in that component's faces
    /// (see [`MacGrid::face_stencil`]).
    pub fn sample(&self, a: usize, p: [f64; 3]) -> f64 {
        self.face_stencil(a, p)
            .iter()
            .filter(|(_, w)| *w != 0.0)
            .map(|&(f, w)| w * self.vel[a][f])
            .sum()
    }

    /// The velocity vector at `p`.
    pub fn velocity_at(&self, p: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| self.sample(a, p))
    }

    /// The pressure [Pa] of the cell that holds `p` (clamped into the domain, wrapped on
    /// periodic axes): pressures live at cell centres, so a probe at a centre reads its cell.
    pub fn pressure_at(&self, p: [f64; 3]) -> f64 {
        let [i, j, k] = self.cell_holding(p);
        self.pressure[self.domain.cell(i, j, k)]
    }

    /// Kinetic energy per unit density, ½ Σ u² dx³ over distinct faces [m⁵/s²].
    pub fn kinetic_energy(&self) -> f64 {
        let mut e = 0.0;
        self.for_distinct_faces(|a, f| e += 0.5 * self.vel[a][f] * self.vel[a][f]);
        e * self.domain.dx.powi(3)
    }

    /// Calls `f(axis, face)` once for every distinct face (a periodic axis's last face is
    /// its first face's copy and is skipped).
    pub(crate) fn for_distinct_faces(&self, mut f: impl FnMut(usize, usize)) {
        let dom = &self.domain;
        for a in 0..3 {
            let d = dom.face_dims(a);
            let last = if dom.boundaries.is_periodic(a) {
                d[a] - 1
            } else {
                d[a]
            };
            for k in 0..d[2] {
                for j in 0..d[1] {
                    for i in 0..d[0] {
                        if [i, j, k][a] < last {
                            f(a, dom.face(a, i, j, k));
                        }
                    }
                }
            }
        }
    }

    /// The fluid's momentum Σ ρ α u Δx³ over distinct faces [kg·m/s] for density `rho`.
    pub fn momentum(&self, rho: f64) -> [f64; 3] {
        let mut m = [0.0; 3];
        self.for_distinct_faces(|a, f| m[a] += self.alpha[a][f] * self.vel[a][f]);
        m.map(|x| rho * x * self.domain.dx.powi(3))
    }

    /// The momentum the fluid gained from `before` to `self` with `self`'s fluid fractions,
    /// Σ ρ α (u − u_before) Δx³ [kg·m/s]: with `before` a step's advected velocity u*, what
    /// the coupling (drag, pressure) gave the fluid, which the solids' momentum change must
    /// balance. Zero unless both grids share a domain.
    pub fn momentum_gain(&self, before: &MacGrid, rho: f64) -> [f64; 3] {
        let mut m = [0.0; 3];
        if before.domain != self.domain {
            return m;
        }
        self.for_distinct_faces(|a, f| {
            m[a] += self.alpha[a][f] * (self.vel[a][f] - before.vel[a][f]);
        });
        m.map(|x| rho * x * self.domain.dx.powi(3))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_domains_are_refused_before_allocating() {
        let b = Boundaries::closed();
        assert_eq!(
            Domain::new([0.0; 3], [1.0; 3], 0.0, b, None).unwrap_err(),
            FluidError::CellSize(0.0)
        );
        assert!(matches!(
            Domain::new([0.0; 3], [1.0; 3], -1.0, b, None),
            Err(FluidError::CellSize(_))
        ));
        assert!(matches!(
            Domain::new([0.0; 3], [1.0, 0.0, 1.0], 0.1, b, None),
            Err(FluidError::Size(_))
        ));
        // 4 m at 1 mm: 6.4e10 cells, about 12 TiB: refused with the estimate.
        let err = Domain::new([0.0; 3], [4.0; 3], 1e-3, b, None).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("GiB") && msg.contains("4000"), "{msg}");
        let mut half = Boundaries::closed();
        half.lo[1] = Boundary::Periodic;
        assert_eq!(
            Domain::new([0.0; 3], [1.0; 3], 0.1, half, None).unwrap_err(),
            FluidError::HalfPeriodic { axis: 1 }
        );
    }

    #[test]
    fn sampling_reproduces_linear_fields_and_wraps_periodic_axes() {
        let d = Domain::new(
            [0.0; 3],
            [1.0, 1.0, 1.0],
            0.1,
            Boundaries::periodic(&[Axis::X]),
            None,
        )
        .unwrap();
        let mut g = MacGrid::new(d);
        // A field linear in y and z (x periodic): trilinear sampling is exact inside.
        g.set_velocity(|p| [1.0 + 2.0 * p[1] - p[2], 0.0, 0.0]);
        for p in [[0.33, 0.41, 0.52], [0.97, 0.2, 0.7], [1.5, 0.3, 0.3]] {
            let want = 1.0 + 2.0 * p[1] - p[2];
            assert!((g.sample(0, p) - want).abs() < 1e-12, "{p:?}");
        }
        // Periodic in x: sin(2πx) sampled between faces wraps across x = 1.
        g.set_velocity(|p| [(std::f64::consts::TAU * p[0]).sin(), 0.0, 0.0]);
        let a = g.sample(0, [0.05, 0.5, 0.5]);
        let b = g.sample(0, [1.05, 0.5, 0.5]);
        assert_eq!(a, b);
    }
}

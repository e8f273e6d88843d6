//! Verification scenes with known answers (VERIFY.md, Fluid), shared by the tests, which
//! assert them, and `weft bench`, which sweeps them over resolution.

use crate::advect::advect_velocity;
use crate::{Axis, Boundaries, Boundary, Domain, MacGrid, PressureSolve, Projection};
use crate::{FluidError, ProjectionError};

/// Why a verification scene could not run.
#[derive(Debug, thiserror::Error)]
pub enum VerifyError {
    /// The domain was refused.
    #[error(transparent)]
    Domain(#[from] FluidError),
    /// A pressure solve failed.
    #[error(transparent)]
    Projection(#[from] ProjectionError),
}

/// What the Taylor–Green run measured.
#[derive(Clone, Copy, Debug)]
pub struct TaylorGreen {
    /// The largest face-velocity error at t = 1 (the peak speed is 1).
    pub max_error: f64,
    /// The kinetic energy lost, relative to the start.
    pub energy_loss: f64,
    /// The largest divergence any projection left [1/s].
    pub max_divergence: f64,
}

/// The inviscid Taylor–Green vortex u = sin x cos y, v = −cos x sin y (a steady solution of
/// the Euler equations on the periodic box [0, 2π]²) at `n` cells across, run to t = 1 at
/// CFL 0.64 (h = 4/n) with pressure solves to 10⁻¹⁰: what it loses is numerical error.
/// Panics unless `n` ≥ 4.
pub fn taylor_green(n: usize) -> Result<TaylorGreen, VerifyError> {
    assert!(n >= 4, "Taylor–Green needs 4 cells across");
    let tau = std::f64::consts::TAU;
    let exact = |p: [f64; 3]| [p[0].sin() * p[1].cos(), -p[0].cos() * p[1].sin(), 0.0];
    let dx = tau / n as f64;
    let b = Boundaries::periodic(&[Axis::X, Axis::Y, Axis::Z]);
    let d = Domain::new([0.0; 3], [tau, tau, dx], dx, b, None)?;
    let mut g = MacGrid::new(d);
    g.set_velocity(exact);
    let mut proj = Projection::new(&g);
    let settings = PressureSolve {
        tolerance: 1e-10,
        max_iterations: 4000,
    };
    // Start exactly discretely divergence-free.
    proj.project(&mut g, 1.0, 1.0, &settings)?;
    let e0 = g.kinetic_energy();
    let steps = (n / 4).max(1);
    let h = 1.0 / steps as f64;
    let mut scratch = None;
    let mut max_divergence = 0.0f64;
    for _ in 0..steps {
        advect_velocity(&mut g, h, &mut scratch);
        let s = proj.project(&mut g, 1.0, h, &settings)?;
        max_divergence = max_divergence.max(s.divergence);
    }
    let mut max_error = 0.0f64;
    for a in 0..2 {
        let dims = g.domain.face_dims(a);
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = g.domain.face_position(a, [i, j, 0]);
                let u = g.vel[a][g.domain.face(a, i, j, 0)];
                max_error = max_error.max((u - exact(p)[a]).abs());
            }
        }
    }
    Ok(TaylorGreen {
        max_error,
        energy_loss: 1.0 - g.kinetic_energy() / e0,
        max_divergence,
    })
}

/// What the Darcy slab measured.
#[derive(Clone, Copy, Debug)]
pub struct DarcySlab {
    /// The pressure drop across the slab [Pa].
    pub drop: f64,
    /// Its reference K q L/α² [Pa].
    pub reference: f64,
    /// The superficial velocity α u inside the slab [m/s] (q = 0.02 m/s everywhere).
    pub superficial: f64,
    /// The largest divergence any projection left [1/s].
    pub max_divergence: f64,
}

/// Darcy slab: flow q = 2 cm/s through a fixed porous slab (x = 0.3 to 0.6 m of a 1 m
/// channel; fluid fraction α = 0.7, drag K = 3000 N s/m⁴ per unit volume), inflow at x = 0,
/// open at the far end, at cell size `dx` (dividing 0.3 and 0.25). At steady state the
/// mixture flux α u = q everywhere and inside the slab α∇p = −K u, so the pressure falls by
/// K q L/α² over the slab's length L (with Darcy's Δp/L = μq/k: K = μα²/k). Exact for the
/// discrete system at steady state. Panics unless 0 < `dx` ≤ 0.1 m (a cell before the slab).
pub fn darcy_slab(dx: f64) -> Result<DarcySlab, VerifyError> {
    assert!(
        dx > 0.0 && dx <= 0.1,
        "the slab needs cells of at most 0.1 m"
    );
    let (q, alpha, k) = (0.02, 0.7, 3.0e3);
    let mut b = Boundaries::periodic(&[Axis::Z]);
    b.lo[0] = Boundary::Inflow([q, 0.0, 0.0]);
    b.hi[0] = Boundary::Open;
    let d = Domain::new([0.0; 3], [1.0, 0.25, dx], dx, b, None)?;
    let mut g = MacGrid::new(d);
    g.set_velocity(|_| [q, 0.0, 0.0]);
    let dom = g.domain.clone();
    // The slab: x-faces i0..=i1 and the other faces of the cells between.
    let (i0, i1) = ((0.3 / dx).round() as usize, (0.6 / dx).round() as usize);
    for a in 0..3 {
        let dims = dom.face_dims(a);
        for kk in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let inside = if a == 0 {
                        (i0..=i1).contains(&i)
                    } else {
                        (i0..i1).contains(&i)
                    };
                    if inside {
                        let f = dom.face(a, i, j, kk);
                        g.alpha[a][f] = alpha;
                        g.drag[a][f] = k;
                    }
                }
            }
        }
    }
    let mut proj = Projection::new(&g);
    let settings = PressureSolve {
        tolerance: 1e-11,
        max_iterations: 20000,
    };
    // Steady state: no advection (the flow is uniform along x); after the first step u* is
    // already the steady u, so the inertial term ρα(u − u*)/h vanishes.
    let mut max_divergence = 0.0f64;
    for _ in 0..3 {
        let s = proj.project(&mut g, 998.2, 10.0, &settings)?;
        max_divergence = max_divergence.max(s.divergence);
    }
    // From the centre of cell i0 − 1 to that of cell i1 the path crosses faces i0..=i1.
    let len = (i1 - i0 + 1) as f64 * dx;
    let j = dom.cells[1] / 2;
    let mid = (i0 + i1) / 2;
    Ok(DarcySlab {
        drop: g.pressure[dom.cell(i0 - 1, j, 0)] - g.pressure[dom.cell(i1, j, 0)],
        reference: k * q * len / (alpha * alpha),
        superficial: g.vel[0][dom.face(0, mid, j, 0)] * alpha,
        max_divergence,
    })
}

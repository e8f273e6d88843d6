//! Verification scenes swept over resolution (`weft bench convergence`): each returns a
//! [`Run`] whose `dx` is its segment or cell size and whose error is relative to an
//! analytic reference (VERIFY.md):
//! - **cantilever**: the strand of [`crate::scenes_strand`] (0.1 m, clamped at its root by the
//!   attachment node), sagging under its own weight, solved statically; δ = qL⁴/(8EI) for
//!   the strand's own length. Expected order 2 (lumped masses, Voronoi curvature, the root
//!   clamp's half-segment term).
//! - **catenary**: a near-inextensible chain (EA = 10⁵ N, strain ~10⁻⁶) of length 1.2 m
//!   hung between x = ±0.5 m; its mid-point sag against c(cosh(a/c) − 1), 2c sinh(a/c) = L.
//!   Expected order 2 (straight segments on a smooth curve).
//! - **shell_strip**: a cloth strip (discrete shell, ν = 0) clamped along a short edge by
//!   the attachment node (`scenes/strip.json`), sagging under its own weight; tip deflection
//!   against the elastica of its length with EI = Ebt³/12. Square cells: the clamp converges
//!   at second order but the free long edges add an error that depends on the cells' shape,
//!   so the order is not clean (about 1.5).
//! - **membrane**: uniaxial tension of a square sheet; strain and Poisson contraction
//!   against the linear law at strain 10⁻⁴. Exact in resolution (uniform stress).
//! - **taylor_green**: the inviscid Taylor–Green vortex on [0, 2π]², t = 1 at CFL 0.64; the
//!   largest face-velocity error (relative to the peak speed 1). Expected order 1
//!   (semi-Lagrangian advection at fixed CFL).
//! - **darcy_slab**: flow q through a porous slab across a channel; the pressure drop
//!   against K q L/α². Exact at every resolution (to the solver's tolerance).

use crate::sweep::{Run, Status};
use std::time::Instant;
use weft_fluid::verify as fluid;
use weft_solid::verify as solid;

/// A run of `scene` at size `dx` with relative `error` (None: the solve failed), inaccurate
/// above `threshold`.
fn run(scene: &'static str, dx: f64, error: Option<f64>, seconds: f64, threshold: f64) -> Run {
    let error = error.unwrap_or(f64::NAN);
    Run {
        scene,
        method: scene,
        h: f64::NAN,
        dx,
        param: f64::NAN,
        param_name: "",
        error,
        error_unit: "relative",
        iterations: f64::NAN,
        seconds,
        steps: 1,
        status: Status::of(false, error, threshold),
    }
}

/// |measured − reference| / reference.
fn relative((measured, reference): (f64, f64)) -> f64 {
    (measured - reference).abs() / reference
}

/// The clamped strand with `n` segments ([`crate::scenes_strand::cantilever`]).
pub fn cantilever(n: usize) -> Run {
    let t = Instant::now();
    let error = crate::scenes_strand::cantilever(n, crate::scenes_strand::Root::Clamped)
        .ok()
        .map(relative);
    run(
        "cantilever",
        crate::scenes_strand::LENGTH / n as f64,
        error,
        t.elapsed().as_secs_f64(),
        1e-2,
    )
}

/// The strand cantilever with `n` segments held as `root`, for the before/after chart of
/// `weft bench accuracy`: the scene is named `cantilever`, the method the root's (`clamped`,
/// `two_pins`, the clamp before issue 20).
pub fn strand_cantilever(n: usize, root: crate::scenes_strand::Root) -> Run {
    use crate::scenes_strand::Root;
    let t = Instant::now();
    let error = crate::scenes_strand::cantilever(n, root).ok().map(relative);
    let mut r = run(
        "cantilever",
        crate::scenes_strand::LENGTH / n as f64,
        error,
        t.elapsed().as_secs_f64(),
        5e-3,
    );
    r.method = match root {
        Root::Clamped => "clamped",
        Root::TwoPins => "two_pins",
        Root::Pinned => "pinned",
    };
    r
}

/// The catenary with `n` segments, `n` even, EA = 10⁵ N ([`solid::catenary_sag`]).
pub fn catenary(n: usize) -> Run {
    let t = Instant::now();
    let error = solid::catenary_sag(n, 1e5).ok().map(relative);
    run(
        "catenary",
        1.2 / n as f64,
        error,
        t.elapsed().as_secs_f64(),
        1e-2,
    )
}

/// The clamped cloth strip with `nx` vertices along and (nx + 5)/4 across: 11 × 4, 21 × 6,
/// 41 × 11, 81 × 21 ([`crate::scenes_strand::strip_tip`]).
pub fn shell_strip(nx: usize) -> Run {
    let t = Instant::now();
    let error =
        crate::scenes_strand::strip_tip(nx, (nx + 5) / 4, crate::scenes_strand::Edge::Clamped)
            .ok()
            .map(relative);
    let dx = crate::scenes_strand::STRIP_LENGTH / (nx - 1) as f64;
    run("shell_strip", dx, error, t.elapsed().as_secs_f64(), 1e-2)
}

/// Uniaxial membrane tension on an `n × n` vertex sheet ([`solid::uniaxial`]) at strain
/// 10⁻⁴ (E = 1 MPa, ν = 0.3, t = 1 mm, N = 0.1 N/m): the larger relative error of ε_x and of
/// the Poisson contraction −ε_y/ε_x against the linear law. Linear triangles under uniform
/// stress are exact at any size; what is left is the StVK membrane's O(ε) departure.
pub fn membrane(n: usize) -> Run {
    let t = Instant::now();
    let (e, nu, th, tension) = (1e6, 0.3, 1e-3, 0.1);
    let mat = weft_solid::energy::MembraneMaterial::orthotropic(e, nu, th, 1.0, 1.0, 1.0);
    let error = solid::uniaxial(n, mat, nalgebra::Vector3::x(), tension)
        .ok()
        .map(|(ex, ey)| {
            let want = tension / (e * th);
            relative((ex, want)).max(relative((-ey / ex, nu)))
        });
    run(
        "membrane",
        1.0 / (n - 1) as f64,
        error,
        t.elapsed().as_secs_f64(),
        1e-2,
    )
}

/// Taylor–Green at `n` cells across ([`fluid::taylor_green`]): the largest velocity error
/// (the peak speed is 1).
pub fn taylor_green(n: usize) -> Run {
    let t = Instant::now();
    let error = fluid::taylor_green(n).ok().map(|tg| tg.max_error);
    let dx = std::f64::consts::TAU / n as f64;
    run("taylor_green", dx, error, t.elapsed().as_secs_f64(), 0.2)
}

/// The Darcy slab at cell size `dx` ([`fluid::darcy_slab`]).
pub fn darcy_slab(dx: f64) -> Run {
    let t = Instant::now();
    let error = fluid::darcy_slab(dx)
        .ok()
        .map(|s| relative((s.drop, s.reference)));
    run("darcy_slab", dx, error, t.elapsed().as_secs_f64(), 1e-6)
}

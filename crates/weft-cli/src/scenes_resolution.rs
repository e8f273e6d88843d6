//! Verification scenes swept over resolution (`weft bench convergence`): each returns a
//! [`Run`] whose `dx` is its segment or cell size and whose error is relative to an
//! analytic reference (VERIFY.md):
//! - **cantilever**: a steel rod (0.5 m, r = 1 mm) clamped at one end, sagging under its own
//!   weight, solved statically; δ = qL⁴/(8EI) with the clamp half a segment behind the
//!   second pinned vertex (L + l/2; see the weft-solid test). Expected order 2 (lumped
//!   masses, Voronoi curvature).
//! - **catenary**: a near-inextensible chain (EA = 10⁵ N, strain ~10⁻⁶) of length 1.2 m
//!   hung between x = ±0.5 m; its mid-point sag against c(cosh(a/c) − 1), 2c sinh(a/c) = L.
//!   Expected order 2 (straight segments on a smooth curve).
//! - **shell_strip**: a cloth strip (discrete shell, ν = 0) clamped along a short edge,
//!   sagging under its own weight; tip deflection against Euler–Bernoulli with EI = Ebt³/12.
//!   No clean order: what is left at 20 segments (< 0.1 %) is the clamp and the O((δ/L)²)
//!   geometric nonlinearity.
//! - **taylor_green**: the inviscid Taylor–Green vortex on [0, 2π]², t = 1 at CFL 0.64; the
//!   largest face-velocity error (relative to the peak speed 1). Expected order 1
//!   (semi-Lagrangian advection at fixed CFL).
//! - **darcy_slab**: flow q through a porous slab across a channel; the pressure drop
//!   against K q L/α². Exact at every resolution (to the solver's tolerance).

use crate::sweep::{Run, Status};
use nalgebra::Vector3;
use std::f64::consts::PI;
use std::time::Instant;
use weft_fluid::advect::advect_velocity;
use weft_fluid::{Axis, Boundaries, Boundary, Domain, MacGrid, PressureSolve, Projection};
use weft_solid::energy::{RodBend, RodStretch};
use weft_solid::{Integrator, Method, Settings, SolidSystem, State};

const G: f64 = 9.81;

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

/// Static equilibrium by projected Newton to 10⁻¹¹ m.
fn solve_static(sys: &SolidSystem, state: &mut State) -> Option<()> {
    let mut integ = Integrator::new(sys).ok()?;
    let settings = Settings {
        method: Method::Newton,
        tolerance: 1e-11,
        max_iterations: 200,
    };
    integ.solve_static(sys, state, &settings).ok().map(|_| ())
}

/// A rod along +x from `start`: `n` segments of `len / n`, line density `density`,
/// stretch stiffness `ea`, bending stiffness `ei` (none when 0).
fn rod(n: usize, len: f64, start: f64, density: f64, ea: f64, ei: f64) -> (SolidSystem, State) {
    let l = len / n as f64;
    let x: Vec<Vector3<f64>> = (0..=n)
        .map(|i| Vector3::new(start + i as f64 * l, 0.0, 0.0))
        .collect();
    let mut mass = vec![density * l; n + 1];
    mass[0] *= 0.5;
    mass[n] *= 0.5;
    let mut sys = SolidSystem::new(mass);
    sys.gravity = Vector3::new(0.0, -G, 0.0);
    for i in 0..n as u32 {
        sys.elements.stretches.push(RodStretch {
            v: [i, i + 1],
            rest_length: l,
            k: ea,
        });
    }
    if ei > 0.0 {
        for i in 1..n as u32 {
            sys.elements.bends.push(RodBend {
                v: [i - 1, i, i + 1],
                k: ei / (2.0 * l),
                rest: 0.0,
            });
        }
    }
    let v = vec![Vector3::zeros(); n + 1];
    (sys, State { x, v })
}

/// The rod cantilever with `n` segments.
pub fn cantilever(n: usize) -> Run {
    let t = Instant::now();
    let (len, r, e, rho) = (0.5, 1e-3, 2e11, 1000.0);
    let (area, i) = (PI * r * r, PI * r.powi(4) / 4.0);
    let l = len / n as f64;
    // One extra segment behind x = 0 carries the clamp.
    let (mut sys, mut s) = rod(n + 1, len + l, -l, rho * area, e * area, e * i);
    sys.pinned[0] = true;
    sys.pinned[1] = true;
    let error = solve_static(&sys, &mut s).map(|_| {
        let reference = rho * area * G * (len + 0.5 * l).powi(4) / (8.0 * e * i);
        (-s.x[n + 1].y - reference).abs() / reference
    });
    run("cantilever", l, error, t.elapsed().as_secs_f64(), 1e-2)
}

/// The catenary with `n` segments (`n` even, so a vertex sits at the middle).
pub fn catenary(n: usize) -> Run {
    let t = Instant::now();
    let (a, len) = (0.5, 1.2);
    let l = len / n as f64;
    let (mut sys, mut s) = rod(n, 2.0 * a, -a, 0.01, 1e5, 0.0);
    // Vertices start evenly across the span; rest lengths and masses are the chain's.
    for r in sys.elements.stretches.iter_mut() {
        r.rest_length = l;
    }
    for m in sys.mass.iter_mut() {
        *m *= l / (2.0 * a / n as f64);
    }
    // Start as a symmetric V of the right length; the solver finds the curve.
    let depth = ((len / 2.0).powi(2) - a * a).sqrt();
    for (i, p) in s.x.iter_mut().enumerate() {
        let u = 1.0 - (2.0 * i as f64 / n as f64 - 1.0).abs();
        p.y = -depth * u;
    }
    sys.pinned[0] = true;
    sys.pinned[n] = true;
    let error = solve_static(&sys, &mut s).map(|_| {
        // 2c sinh(a/c) = L by bisection.
        let (mut lo, mut hi) = (1e-3, 1e3);
        for _ in 0..200 {
            let c = 0.5 * (lo + hi);
            if 2.0 * c * (a / c).sinh() > len {
                lo = c
            } else {
                hi = c
            }
        }
        let c = 0.5 * (lo + hi);
        let sag = c * ((a / c).cosh() - 1.0);
        (-s.x[n / 2].y - sag).abs() / sag
    });
    run("catenary", l, error, t.elapsed().as_secs_f64(), 1e-2)
}

/// The shell strip with `nx` vertices along (and proportionally many across).
pub fn shell_strip(nx: usize) -> Run {
    use std::sync::Arc;
    use weft_scene::procedural::{Plane, grid};
    use weft_scene::{Density, DiscreteShell, ElementKind, Geometry, SceneElement};
    use weft_sim::{BehaviorTree, DiscreteShellMaterial, Gravity, compile};
    let t = Instant::now();
    let ny = (nx / 4).max(3);
    let (len, width, th, e, rho_a) = (0.4, 0.1, 1e-3, 2e9, 0.005);
    let dx = len / (nx - 1) as f64;
    // The grid spans x ∈ [−dx, L]: its first column sits behind the clamp line x = 0.
    let total = len + dx;
    let mesh = grid(
        [total, width],
        [nx + 1, ny],
        Plane::Xz,
        [0.5 * total - dx, 0.0, 0.0],
    );
    let mut el = SceneElement::new("strip", ElementKind::Cloth, Geometry::Mesh(mesh));
    el.secs.insert(DiscreteShell {
        youngs_modulus: e,
        poisson_ratio: 0.0,
        thickness: th,
        ..Default::default()
    });
    el.secs.insert(Density {
        area_density: rho_a,
        ..Default::default()
    });
    let tree = BehaviorTree {
        behaviors: vec![
            Arc::new(DiscreteShellMaterial),
            Arc::new(Gravity {
                acceleration: [0.0, -G, 0.0],
            }),
        ],
    };
    let error = compile(&[el], &tree).ok().and_then(|c| {
        let mut sys = c.system.clone();
        let cols = nx + 1;
        for j in 0..ny {
            sys.pinned[j * cols] = true;
            sys.pinned[j * cols + 1] = true;
        }
        let mut state = c.state.clone();
        solve_static(&sys, &mut state)?;
        let tip = (0..ny)
            .map(|j| -state.x[j * cols + cols - 1].y)
            .sum::<f64>()
            / ny as f64;
        let ei = e * width * th.powi(3) / 12.0;
        let reference = rho_a * G * width * (len + 0.5 * dx).powi(4) / (8.0 * ei);
        Some((tip - reference).abs() / reference)
    });
    run("shell_strip", dx, error, t.elapsed().as_secs_f64(), 1e-2)
}

/// Taylor–Green at `n` cells across.
pub fn taylor_green(n: usize) -> Run {
    let t = Instant::now();
    let tau = std::f64::consts::TAU;
    let exact = |p: [f64; 3]| [p[0].sin() * p[1].cos(), -p[0].cos() * p[1].sin(), 0.0];
    let dx = tau / n as f64;
    let b = Boundaries::periodic(&[Axis::X, Axis::Y, Axis::Z]);
    let error = Domain::new([0.0; 3], [tau, tau, dx], dx, b, None)
        .ok()
        .and_then(|d| {
            let mut g = MacGrid::new(d);
            g.set_velocity(exact);
            let mut proj = Projection::new(&g);
            let settings = PressureSolve {
                tolerance: 1e-10,
                max_iterations: 4000,
            };
            proj.project(&mut g, 1.0, 1.0, &settings).ok()?;
            // h = 4/n: CFL |u|max h/Δx = 4/(2π) at every resolution.
            let steps = (n / 4).max(1);
            let h = 1.0 / steps as f64;
            let mut scratch = None;
            for _ in 0..steps {
                advect_velocity(&mut g, h, &mut scratch);
                proj.project(&mut g, 1.0, h, &settings).ok()?;
            }
            let mut err = 0.0f64;
            for a in 0..2 {
                let dims = g.domain.face_dims(a);
                for j in 0..dims[1] {
                    for i in 0..dims[0] {
                        let p = g.domain.face_position(a, [i, j, 0]);
                        let u = g.vel[a][g.domain.face(a, i, j, 0)];
                        err = err.max((u - exact(p)[a]).abs());
                    }
                }
            }
            Some(err)
        });
    run("taylor_green", dx, error, t.elapsed().as_secs_f64(), 0.2)
}

/// The Darcy slab (0.3 m of a 1 m channel, α = 0.7, K = 3000 N s/m⁴, q = 2 cm/s) at cell
/// size `dx` (dividing 0.3 and 0.25).
pub fn darcy_slab(dx: f64) -> Run {
    let t = Instant::now();
    let (q, alpha, k) = (0.02, 0.7, 3.0e3);
    let mut b = Boundaries::periodic(&[Axis::Z]);
    b.lo[0] = Boundary::Inflow([q, 0.0, 0.0]);
    b.hi[0] = Boundary::Open;
    let error = Domain::new([0.0; 3], [1.0, 0.25, dx], dx, b, None)
        .ok()
        .and_then(|d| {
            let mut g = MacGrid::new(d);
            g.set_velocity(|_| [q, 0.0, 0.0]);
            let dom = g.domain.clone();
            // The slab: x-faces i0..=i1 (x = 0.3 to 0.6) and the other faces of the cells
            // between.
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
            // Steady: after the first step u* is already the steady flow.
            for _ in 0..3 {
                proj.project(&mut g, 998.2, 10.0, &settings).ok()?;
            }
            let len = (i1 - i0 + 1) as f64 * dx;
            let want = k * q * len / (alpha * alpha);
            let j = dom.cells[1] / 2;
            let dp = g.pressure[dom.cell(i0 - 1, j, 0)] - g.pressure[dom.cell(i1, j, 0)];
            Some((dp - want).abs() / want)
        });
    run("darcy_slab", dx, error, t.elapsed().as_secs_f64(), 1e-6)
}

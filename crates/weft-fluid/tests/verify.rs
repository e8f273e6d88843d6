//! Fluid verification (VERIFY.md, Fluid): hydrostatic rest, Taylor–Green, divergence after
//! every solve, and the Darcy slab through the porous pressure system.

use weft_fluid::verify;
use weft_fluid::*;

const RHO: f64 = 998.2;

/// A closed box of water at rest stays at rest under gravity, and its pressure is hydrostatic:
/// p_c − p_above = ρ g Δx between vertical neighbours. Tolerances: the solve stops at a
/// divergence of 1e-10 1/s, so velocities stay below 1e-10·Δx/… ≈ 1e-11 m/s and the
/// pressure steps match ρgΔx to 1e-9 relative.
#[test]
fn hydrostatic_rest() {
    let n = 12;
    let d = Domain::new(
        [0.0; 3],
        [1.0; 3],
        1.0 / n as f64,
        Boundaries::closed(),
        None,
    )
    .unwrap();
    let mut g = MacGrid::new(d);
    let mut proj = Projection::new(&g);
    let settings = PressureSolve {
        tolerance: 1e-10,
        max_iterations: 500,
    };
    let h = 0.01;
    for _ in 0..5 {
        g.accelerate([0.0, -9.81, 0.0], h);
        let s = proj.project(&mut g, RHO, h, &settings).unwrap();
        assert!(s.divergence <= 1e-10, "{}", s.divergence);
    }
    let umax = g.vel.iter().flatten().fold(0.0f64, |m, u| m.max(u.abs()));
    assert!(umax < 1e-9, "the water moved: {umax} m/s");
    let dom = &g.domain;
    let step = RHO * 9.81 * dom.dx;
    for k in 0..n {
        for j in 0..n - 1 {
            for i in 0..n {
                let dp = g.pressure[dom.cell(i, j, k)] - g.pressure[dom.cell(i, j + 1, k)];
                assert!(
                    (dp - step).abs() < 1e-9 * step,
                    "({i},{j},{k}): {dp} vs {step}"
                );
            }
        }
    }
}

/// The inviscid Taylor–Green vortex ([`verify::taylor_green`]): what the solver loses of
/// this steady Euler solution is its numerical error. At a fixed CFL number the velocity
/// error and the kinetic-energy loss at t = 1 must fall with resolution at the scheme's order
/// (semi-Lagrangian with trilinear interpolation at fixed CFL: first order). Every
/// projection must leave a divergence below its tolerance.
#[test]
fn taylor_green_converges_and_stays_divergence_free() {
    let mut errors = Vec::new();
    let mut losses = Vec::new();
    for n in [16usize, 32, 64] {
        let tg = verify::taylor_green(n).unwrap();
        assert!(
            tg.max_divergence <= 1e-10,
            "n = {n}: divergence {}",
            tg.max_divergence
        );
        errors.push(tg.max_error);
        losses.push(tg.energy_loss);
    }
    let order = |e: &[f64]| (e[1] / e[2]).log2();
    eprintln!(
        "Taylor–Green: max error {errors:?} (order {:.2}), KE loss {losses:?} (order {:.2})",
        order(&errors),
        order(&losses)
    );
    assert!(errors[2] < errors[1] && errors[1] < errors[0], "{errors:?}");
    assert!(
        order(&errors) > 0.8,
        "velocity error order {}",
        order(&errors)
    );
    assert!(order(&losses) > 0.8, "energy loss order {}", order(&losses));
}

/// Darcy slab ([`verify::darcy_slab`]): the pressure drop across a fixed porous slab is
/// K q L/α², and the superficial velocity α u is q inside it. Exact for the discrete system
/// at steady state: tolerance 1e-8 relative (and 1e-10 m/s).
#[test]
fn darcy_slab_pressure_drop() {
    let s = verify::darcy_slab(0.025).unwrap();
    assert!(s.max_divergence <= 1e-10, "{}", s.max_divergence);
    assert!(
        (s.drop - s.reference).abs() < 1e-8 * s.reference,
        "Δp {} Pa vs K q L/α² = {} Pa",
        s.drop,
        s.reference
    );
    assert!((s.superficial - 0.02).abs() < 1e-10, "{}", s.superficial);
}

/// Bad input: a pressure solve that cannot converge reports its residual and leaves the grid
/// untouched; out-of-range porous fields and parameters are refused by name.
#[test]
fn failed_and_refused_projections_leave_the_grid_unchanged() {
    let d = Domain::new([0.0; 3], [1.0; 3], 0.1, Boundaries::closed(), None).unwrap();
    let mut g = MacGrid::new(d);
    g.accelerate([0.0, -9.81, 0.0], 0.1);
    let before = g.vel.clone();
    let mut proj = Projection::new(&g);
    let tight = PressureSolve {
        tolerance: 1e-14,
        max_iterations: 2,
    };
    match proj.project(&mut g, RHO, 0.1, &tight) {
        Err(ProjectionError::NotConverged {
            iterations,
            residual,
            ..
        }) => {
            assert_eq!(iterations, 2);
            assert!(residual > 1e-14 && residual.is_finite());
        }
        other => panic!("expected NotConverged, got {other:?}"),
    }
    assert_eq!(g.vel, before);
    g.drag[0][5] = -1.0;
    let e = proj
        .project(&mut g, RHO, 0.1, &PressureSolve::default())
        .unwrap_err();
    assert!(e.to_string().contains("drag coefficient"), "{e}");
    g.drag[0][5] = 0.0;
    g.alpha[1][3] = -0.5;
    let e = proj
        .project(&mut g, RHO, 0.1, &PressureSolve::default())
        .unwrap_err();
    assert!(e.to_string().contains("fluid fraction"), "{e}");
    g.alpha[1][3] = 1.0;
    let e = proj
        .project(&mut g, -1.0, 0.1, &PressureSolve::default())
        .unwrap_err();
    assert!(e.to_string().contains("density"), "{e}");
    assert_eq!(g.vel, before);
}

/// Plane Poiseuille flow (optional viscosity): a channel between no-slip walls at x = 0 and
/// x = L, periodic along y and z, driven by a uniform body force g along y. The steady state
/// is u(x) = g x (L − x)/(2ν). Each step adds hg and diffuses implicitly, so with hν/L² ≫ 1 a
/// few steps reach the discrete steady state, whose error is the wall ghost's O(Δx²): the
/// largest error must fall by 4 × (order 2 ± 0.1) when the cells halve, and be below 1 % of
/// the peak at 16 cells.
#[test]
fn plane_poiseuille_flow_converges_at_second_order() {
    let (len, g, nu) = (0.1, 0.01, 1e-3);
    let solve = |cells: usize| {
        let b = Boundaries::periodic(&[Axis::Y, Axis::Z]);
        let dx = len / cells as f64;
        let d = Domain::new([0.0; 3], [len, 2.0 * dx, 2.0 * dx], dx, b, None).unwrap();
        let mut grid = MacGrid::new(d);
        let mut diff = weft_fluid::Diffusion::new(&grid);
        let h = 1e3 * len * len / nu;
        for _ in 0..6 {
            grid.accelerate([0.0, g, 0.0], h);
            diff.diffuse(
                &mut grid,
                nu,
                h,
                &PressureSolve {
                    tolerance: 1e-13,
                    max_iterations: 10_000,
                },
            )
            .unwrap();
        }
        let dom = &grid.domain;
        let mut err = 0.0f64;
        for i in 0..cells {
            let x = (i as f64 + 0.5) * dx;
            let want = g * x * (len - x) / (2.0 * nu);
            err = err.max((grid.vel[1][dom.face(1, i, 1, 1)] - want).abs());
        }
        err / (g * len * len / (8.0 * nu))
    };
    let (e16, e32) = (solve(16), solve(32));
    let order = (e16 / e32).log2();
    eprintln!("Poiseuille: relative error {e16:e} (16 cells), {e32:e} (32), order {order:.3}");
    assert!(e16 < 0.01, "{e16}");
    assert!((order - 2.0).abs() < 0.1, "order {order}");
}

/// A closed cube mesh [lo, hi]³ (12 triangles).
fn cube(lo: [f64; 3], hi: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let p = (0..8)
        .map(|c| [0, 1, 2].map(|b| if c >> b & 1 == 1 { hi[b] } else { lo[b] }))
        .collect();
    // Two triangles per side, outward (corner bits: x = 1, y = 2, z = 4).
    let t = vec![
        [0, 4, 6],
        [0, 6, 2],
        [1, 3, 7],
        [1, 7, 5], // x−, x+
        [0, 1, 5],
        [0, 5, 4],
        [2, 6, 7],
        [2, 7, 3], // y−, y+
        [0, 2, 3],
        [0, 3, 1],
        [4, 5, 7],
        [4, 7, 6], // z−, z+
    ];
    (p, t)
}

/// Fluid flux through the x-faces of cross-section `i` (fluid faces and obstacle faces
/// separately), times Δx².
fn section_flux(g: &MacGrid, i: usize) -> (f64, f64) {
    let dom = &g.domain;
    let (mut fluid, mut solid) = (0.0, 0.0);
    for k in 0..dom.cells[2] {
        for j in 0..dom.cells[1] {
            let f = dom.face(0, i, j, k);
            let al = g.alpha[0][f];
            fluid += al * g.vel[0][f] * dom.dx * dom.dx;
            solid += (1.0 - al) * g.solid_vel[0][f] * dom.dx * dom.dx;
        }
    }
    (fluid, solid)
}

/// Obstacles (colliders carved as α = 0 faces): a cube moving at V = 0.1 m/s along x through
/// a closed box of water. Mass conservation fixes every cross-section's net flux at zero: the
/// water flows back past the cube as fast as the cube pushes forward, Σ_fluid u Δx² =
/// −V A_cube, and the mixture is divergence-free. In an inflow channel (q = 0.05 m/s) with the
/// cube at rest, each section carries q A and none of it passes through the cube, so the gap
/// beside it carries it all. Tolerance: the CG stops at a divergence of 1e-10 1/s, so a section's
/// flux is exact to ~1e-10·Δx·A.
#[test]
fn obstacles_displace_and_divert_the_flow_conserving_mass() {
    use weft_fluid::obstacle::{carve, faces_inside_mesh};
    let solve = PressureSolve {
        tolerance: 1e-10,
        max_iterations: 5000,
    };
    let (lo, hi) = ([0.41, 0.31, 0.31], [0.59, 0.69, 0.69]);
    let (p, t) = cube(lo, hi);
    let carved = |g: &MacGrid, v: f64| {
        let mut faces = Vec::new();
        faces_inside_mesh(&g.domain, &p, &t, |a, f, _| {
            faces.push(SolidFace {
                axis: a as u8,
                face: f as u32,
                velocity: if a == 0 { v } else { 0.0 },
            })
        });
        faces
    };
    // Moving through a closed box.
    let d = Domain::new([0.0; 3], [1.0; 3], 0.05, Boundaries::closed(), None).unwrap();
    let mut g = MacGrid::new(d);
    let v = 0.1;
    let faces = carved(&g, v);
    carve(&mut g, &faces);
    let s = Projection::new(&g)
        .project(&mut g, RHO, 0.02, &solve)
        .unwrap();
    assert!(s.divergence <= 1e-10);
    // The cube spans x-face sections 9..=11 (x = 0.45, 0.5, 0.55).
    let section = 0.4 * 0.4; // the cube's cross-section on the grid: 8 × 8 faces inside
    for i in 1..20 {
        let (fluid, solid) = section_flux(&g, i);
        assert!(
            (fluid + solid).abs() < 1e-10,
            "section {i}: {fluid} + {solid}"
        );
        if (9..=11).contains(&i) {
            assert!((solid - v * section).abs() < 1e-12, "section {i}: {solid}");
        }
    }
    // At rest in an inflow channel.
    let q = 0.05;
    let mut b = Boundaries::periodic(&[Axis::Y, Axis::Z]);
    b.lo[0] = Boundary::Inflow([q, 0.0, 0.0]);
    b.hi[0] = Boundary::Open;
    let d = Domain::new([0.0; 3], [1.0; 3], 0.05, b, None).unwrap();
    let mut g = MacGrid::new(d);
    g.set_velocity(|_| [q, 0.0, 0.0]);
    let faces = carved(&g, 0.0);
    carve(&mut g, &faces);
    let s = Projection::new(&g)
        .project(&mut g, RHO, 0.02, &solve)
        .unwrap();
    assert!(s.divergence <= 1e-10);
    for i in 1..20 {
        let (fluid, solid) = section_flux(&g, i);
        assert!(
            (fluid - q).abs() < 1e-10 && solid == 0.0,
            "section {i}: {fluid}"
        );
    }
}

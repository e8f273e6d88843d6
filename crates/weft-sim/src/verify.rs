//! Verification scenes with known answers (VERIFY.md, Solids and Drag and coupling), shared
//! by the tests, which assert them, and `weft bench`, which sweeps them.

use crate::{BehaviorTree, DiscreteShellMaterial, DragElement, DragShape, Gravity, compile};
use nalgebra::Vector3;
use std::sync::Arc;
use weft_fluid::{Axis, Boundaries, Domain, DragParams, FluidProperties, MacGrid};
use weft_scene::procedural::{Plane, grid};
use weft_scene::{Density, DiscreteShell, ElementKind, Geometry, SceneElement};
use weft_solid::energy::RodStretch;
pub use weft_solid::verify::G;
use weft_solid::{SolidSystem, State};

/// A solid system, its state, its drag elements and the fluid they are in.
pub type CoupledScene = (SolidSystem, State, Vec<DragElement>, MacGrid);

/// Tip deflection of a shell strip (0.4 m × 0.1 m, 1 mm, E = 2 GPa, ν = 0, 5 g/m²; `nx`
/// vertices along, `ny` across) clamped along a short edge by pinning its first two columns
/// and sagging under its own weight, and the Euler–Bernoulli reference qL⁴/(8EI) with
/// EI = Ebt³/12 (ν = 0, so the narrow and wide plate formulas agree). The clamp sits half a
/// column behind the second pinned column, so the beam is L + Δx/2 long. Linear regime:
/// δ/L ≈ 2·10⁻³. Panics unless `nx` and `ny` are at least 2.
pub fn shell_strip_tip(nx: usize, ny: usize) -> Result<(f64, f64), String> {
    assert!(nx >= 2 && ny >= 2, "a strip needs two vertices each way");
    let (len, width, t, e, rho_a) = (0.4, 0.1, 1e-3, 2e9, 0.005);
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
        thickness: t,
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
    let c = compile(&[el], &tree).map_err(|e| e.to_string())?;
    let mut sys = c.system.clone();
    let cols = nx + 1;
    for j in 0..ny {
        sys.pinned[j * cols] = true;
        sys.pinned[j * cols + 1] = true;
    }
    let mut state = c.state.clone();
    weft_solid::verify::solve_static(&sys, &mut state).map_err(|e| e.to_string())?;
    let tip: f64 = (0..ny)
        .map(|j| -state.x[j * cols + cols - 1].y)
        .sum::<f64>()
        / ny as f64;
    let ei = e * width * t.powi(3) / 12.0;
    let q = rho_a * G * width;
    Ok((tip, q * (len + 0.5 * dx).powi(4) / (8.0 * ei)))
}

/// A straight free strand of `n` segments along x from `start`, moving at `v`, of `radius`
/// and `density` [kg/m³], stretch stiffness 10 N, each segment a drag element with `params`
/// (their diameter set to the strand's). No gravity (the caller sets it).
pub fn strand(
    n: usize,
    len: f64,
    start: [f64; 3],
    v: [f64; 3],
    radius: f64,
    density: f64,
    params: DragParams,
) -> (SolidSystem, State, Vec<DragElement>) {
    let area = std::f64::consts::PI * radius * radius;
    let l = len / n as f64;
    let mut mass = vec![density * area * l; n + 1];
    mass[0] *= 0.5;
    mass[n] *= 0.5;
    let mut sys = SolidSystem::new(mass);
    let params = DragParams {
        diameter: 2.0 * radius,
        ..params
    };
    let mut elements = Vec::new();
    for i in 0..n as u32 {
        sys.elements.stretches.push(RodStretch {
            v: [i, i + 1],
            rest_length: l,
            k: 10.0,
        });
        elements.push(DragElement {
            shape: DragShape::Segment([i, i + 1], area),
            params,
        });
    }
    let x = (0..=n)
        .map(|i| Vector3::new(start[0] + i as f64 * l, start[1], start[2]))
        .collect();
    let state = State {
        x,
        v: vec![Vector3::from(v); n + 1],
    };
    (sys, state, elements)
}

/// Drag per unit solid volume k [N s/m⁴] of the linear branch with ξ⊥ = 1 for a strand of
/// `radius` and drag scale `xi_d`: (μ/D²)·ξ_D/10⁴ in water.
pub fn strand_drag(radius: f64, xi_d: f64) -> f64 {
    let d = 2.0 * radius;
    FluidProperties::WATER.viscosity / (d * d) * xi_d / 1e4
}

/// A light strand (8 segments, 12 cm, `radius`, `density`, drag scale `xi_d`) at rest across
/// the middle of a closed 0.2 m box of still water (2 cm cells), under gravity: buoyancy
/// lifts it against its drag.
pub fn light_strand(radius: f64, density: f64, xi_d: f64) -> CoupledScene {
    let d = Domain::new([0.0; 3], [0.2; 3], 0.02, Boundaries::closed(), None).expect("a valid box");
    let params = DragParams {
        xi_d,
        ..Default::default()
    };
    let (mut sys, state, elements) =
        strand(8, 0.12, [0.04, 0.1, 0.1], [0.0; 3], radius, density, params);
    sys.gravity = Vector3::new(0.0, -G, 0.0);
    (sys, state, elements, MacGrid::new(d))
}

/// A flat 5 × 5 vertex sheet of `thickness` over the whole 0.1 m × 0.1 m x–z extent at
/// height `y`, of solid density `rho_s`: its vertex masses, positions and drag triangles.
pub fn porous_sheet(
    y: f64,
    thickness: f64,
    rho_s: f64,
    params: DragParams,
) -> (Vec<f64>, Vec<Vector3<f64>>, Vec<DragElement>) {
    let n = 5;
    let area_cell = (0.1 / (n - 1) as f64).powi(2);
    let mut x = Vec::new();
    for j in 0..n {
        for i in 0..n {
            x.push(Vector3::new(
                0.1 * i as f64 / (n - 1) as f64,
                y,
                0.1 * j as f64 / (n - 1) as f64,
            ));
        }
    }
    let mut mass = vec![0.0; n * n];
    let mut elements = Vec::new();
    let id = |a: usize, b: usize| (b * n + a) as u32;
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            for t in [
                [id(i, j), id(i, j + 1), id(i + 1, j)],
                [id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)],
            ] {
                for &v in &t {
                    mass[v as usize] += rho_s * thickness * 0.5 * area_cell / 3.0;
                }
                elements.push(DragElement {
                    shape: DragShape::Triangle(t, thickness),
                    params,
                });
            }
        }
    }
    (mass, x, elements)
}

/// The settling sheet's solid density [kg/m³] and its drag law (linear branch, ξ⊥ = 1,
/// D = 0.1 mm: k = μ/D² per unit solid volume).
pub const SHEET_DENSITY: f64 = 1500.0;
/// The settling sheet's drag law.
pub const SHEET_DRAG: DragParams = DragParams {
    xi_d: 1e4,
    xi_perp: 1.0,
    xi_par: 1.0,
    xi_n: 0.0,
    xi_l: 0.0,
    diameter: 1e-4,
    gamma: 0.1,
    degree: 1.0,
};

/// The settling sheet's Darcy terminal velocity Δρ g/k [m/s] (the porous model's α² ≈ 0.99
/// slows it by about 1 %).
pub fn sheet_terminal() -> f64 {
    let k = FluidProperties::WATER.viscosity / (SHEET_DRAG.diameter * SHEET_DRAG.diameter)
        * SHEET_DRAG.xi_d
        * SHEET_DRAG.xi_perp
        / 1e4;
    (SHEET_DENSITY - FluidProperties::WATER.density) * G / k
}

/// A heavy porous sheet of `thickness` spanning a 0.1 × 0.2 × 0.1 m box of still water
/// (periodic across, walls above and below, 2 cm cells) at mid-height, under gravity. No
/// elastic terms: every vertex feels the same forces per mass, so the sheet stays flat.
pub fn settling_sheet(thickness: f64) -> CoupledScene {
    let b = Boundaries::periodic(&[Axis::X, Axis::Z]);
    let d = Domain::new([0.0; 3], [0.1, 0.2, 0.1], 0.02, b, None).expect("a valid box");
    let (mass, x, elements) = porous_sheet(0.1, thickness, SHEET_DENSITY, SHEET_DRAG);
    let mut sys = SolidSystem::new(mass);
    sys.gravity = Vector3::new(0.0, -G, 0.0);
    let state = State {
        v: vec![Vector3::zeros(); x.len()],
        x,
    };
    (sys, state, elements, MacGrid::new(d))
}

//! Verification scenes with known answers (VERIFY.md, Solids and Drag and coupling), shared
//! by the tests, which assert them, and `weft bench`, which sweeps them. The coupled scenes
//! themselves are graph files run by `solver.coupled` (`crates/weft-bench/scenes/`); what
//! lives here is their analytic references.

use crate::{BehaviorTree, DiscreteShellMaterial, Gravity, compile};
use std::sync::Arc;
use weft_fluid::{DragParams, FluidProperties};
use weft_scene::procedural::{Plane, grid};
use weft_scene::{Density, DiscreteShell, ElementKind, Geometry, SceneElement};
pub use weft_solid::verify::G;

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

/// Drag per unit solid volume k [N s/m⁴] of the linear branch with ξ⊥ = 1 for a strand of
/// `radius` and drag scale `xi_d`: (μ/D²)·ξ_D/10⁴ in water.
pub fn strand_drag(radius: f64, xi_d: f64) -> f64 {
    let d = 2.0 * radius;
    FluidProperties::WATER.viscosity / (d * d) * xi_d / 1e4
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

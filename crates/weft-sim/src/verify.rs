//! Analytic references of the coupled verification scenes (VERIFY.md, Drag and coupling),
//! shared by the tests, which assert them, and `weft bench`, which sweeps them. The scenes
//! themselves are graph files run by `solver.coupled` (`crates/weft-bench/scenes/`), as are
//! the clamped strand and strip (`strand.json`, `strip.json`).

use weft_fluid::FluidProperties;
use weft_scene::Drag;
pub use weft_solid::verify::G;

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
pub const SHEET_DRAG: Drag = Drag {
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

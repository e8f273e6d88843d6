//! Shell-strip cantilever: calibrates the discrete bending stiffness against beam theory.
//!
//! A strip of length L, width b, thickness t (ν = 0, so the narrow and wide plate formulas
//! agree: EI = E b t³/12 = D b) is clamped along one short edge by pinning its first two rows
//! of vertices, and loaded by its own weight q = ρ_A g b. Tip deflection δ = qL⁴/(8EI); the
//! clamp sits half a row behind the second pinned row (see the rod cantilever in weft-solid).

use std::sync::Arc;
use weft_scene::procedural::{Plane, grid};
use weft_scene::{Density, DiscreteShell, ElementKind, Geometry, SceneElement};
use weft_sim::*;
use weft_solid::{Integrator, Method, Settings};

fn tip_deflection(nx: usize, ny: usize) -> (f64, f64) {
    let (len, width, t, e, rho_a) = (0.4, 0.1, 1e-3, 2e9, 0.5);
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
                acceleration: [0.0, -9.81, 0.0],
            }),
        ],
    };
    let c = compile(&[el], &tree).unwrap();
    let mut sys = c.system.clone();
    let cols = nx + 1;
    for j in 0..ny {
        sys.pinned[j * cols] = true;
        sys.pinned[j * cols + 1] = true;
    }
    let mut state = c.state.clone();
    let mut integ = Integrator::new(&sys).unwrap();
    integ
        .solve_static(
            &sys,
            &mut state,
            &Settings {
                method: Method::Newton,
                tolerance: 1e-12,
                max_iterations: 200,
            },
        )
        .unwrap();
    let tip: f64 = (0..ny)
        .map(|j| -state.x[j * cols + cols - 1].y)
        .sum::<f64>()
        / ny as f64;
    let ei = e * width * t.powi(3) / 12.0;
    let q = rho_a * 9.81 * width;
    // Clamp half a column behind the second pinned column: beam length L + dx/2.
    (tip, q * (len + 0.5 * dx).powi(4) / (8.0 * ei))
}

/// KNOWN CALIBRATION GAP (open, tracked in BENCHMARKS.md): the hinge weight |ē|²/Ā makes a
/// uniform cylinder cost ½Dκ² per area on equilateral meshes, but on this right-triangle grid
/// bending about a grid axis only the edges across the axis bend (θ = κa; the two triangles
/// across a diagonal stay coplanar), which doubles the energy for a wide strip. Measured:
/// the strip deflects 0.59 × beam theory (1.7× too stiff). This test pins that measured,
/// converged value so a calibration fix must update it deliberately; and it asserts
/// convergence under refinement, which holds either way.
#[test]
fn shell_strip_cantilever_converges_with_the_measured_calibration_factor() {
    // Linear regime: δ/L ≈ 2e-3.
    let mut rel = Vec::new();
    for (nx, ny) in [(11, 4), (21, 6), (41, 11)] {
        let (tip, reference) = tip_deflection(nx, ny);
        rel.push(tip / reference);
    }
    eprintln!("shell strip: tip deflection / beam theory at 10, 20, 40 segments: {rel:?}");
    // Converging: the last refinement changes the ratio by under 2 %.
    assert!((rel[2] - rel[1]).abs() / rel[2] < 0.02, "{rel:?}");
    // The converged ratio (0.591): within 3 % of the pinned value.
    assert!(
        (rel[2] - 0.591).abs() < 0.03 * 0.591,
        "calibration changed: {rel:?}"
    );
}

//! Verification scenes with known answers (VERIFY.md, Solids), shared by the tests, which
//! assert them, and `weft bench`, which sweeps them over resolution. Each returns the
//! measured value beside its analytic reference.

use crate::energy::{Membrane, MembraneMaterial, RodBend, RodStretch};
use crate::{Integrator, Method, Settings, SolidSystem, State, StepError};
use nalgebra::Vector3;

/// Gravity in every scene [m/s²].
pub const G: f64 = 9.81;

/// The pendulum equation θ″ = −(G/L) sin θ from θ₀ at rest: θ at time `t`, by classical RK4
/// at steps of at most 1e-5 s (its error ~1e-18 rad over a second): the reference the
/// integrators' time accuracy is measured against.
pub fn pendulum_angle(theta0: f64, len: f64, t: f64) -> f64 {
    let f = |u: [f64; 2]| [u[1], -G / len * u[0].sin()];
    let steps = (t / 1e-5).ceil().max(1.0) as usize;
    let h = t / steps as f64;
    let mut u = [theta0, 0.0];
    for _ in 0..steps {
        let k1 = f(u);
        let k2 = f([u[0] + 0.5 * h * k1[0], u[1] + 0.5 * h * k1[1]]);
        let k3 = f([u[0] + 0.5 * h * k2[0], u[1] + 0.5 * h * k2[1]]);
        let k4 = f([u[0] + h * k3[0], u[1] + h * k3[1]]);
        for j in 0..2 {
            u[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
        }
    }
    u[0]
}

/// A state at rest at positions `x`.
pub fn at_rest(x: Vec<Vector3<f64>>) -> State {
    let n = x.len();
    State {
        x,
        v: vec![Vector3::zeros(); n],
    }
}

/// Static equilibrium by projected Newton to 10⁻¹¹ m (positions are O(1) m; f64 resolves
/// ~10⁻¹⁶ of that, and the stiffest scenes here have condition numbers near 10⁵).
pub fn solve_static(sys: &SolidSystem, state: &mut State) -> Result<(), StepError> {
    let mut integ = Integrator::new(sys)?;
    let settings = Settings {
        method: Method::Newton,
        tolerance: 1e-11,
        max_iterations: 200,
    };
    integ.solve_static(sys, state, &settings).map(|_| ())
}

/// A straight rod along +x from `start` under gravity −y: `n` segments of `len / n`, line
/// density `density` [kg/m] lumped to vertices, stretch stiffness `ea` [N] and bending
/// stiffness `ei` [N m²] (no bending when 0). Panics unless `n` ≥ 1.
pub fn rod(
    n: usize,
    len: f64,
    start: Vector3<f64>,
    density: f64,
    ea: f64,
    ei: f64,
) -> (SolidSystem, State) {
    assert!(n >= 1, "a rod needs a segment");
    let l = len / n as f64;
    let x: Vec<_> = (0..=n)
        .map(|i| start + Vector3::new(i as f64 * l, 0.0, 0.0))
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
                dropoff: None,
            });
        }
    }
    (sys, at_rest(x))
}

/// The catenary parameter c with 2c sinh(a/c) = `len` (ends at ±`a`), by bisection.
pub fn catenary_parameter(a: f64, len: f64) -> f64 {
    let (mut lo, mut hi) = (1e-3, 1e3);
    for _ in 0..200 {
        let c = 0.5 * (lo + hi);
        if 2.0 * c * (a / c).sinh() > len {
            lo = c
        } else {
            hi = c
        }
    }
    0.5 * (lo + hi)
}

/// Mid-point sag of a chain (length 1.2 m, 0.01 kg/m, `n` segments, `n` even, stretch
/// stiffness `ea`, no bending) hung between x = ±0.5 m, and the catenary's c(cosh(a/c) − 1).
/// It starts as a symmetric V of the right length; the static solve finds the curve. Panics
/// unless `n` is even and at least 2.
pub fn catenary_sag(n: usize, ea: f64) -> Result<(f64, f64), StepError> {
    assert!(
        n >= 2 && n.is_multiple_of(2),
        "the catenary needs an even number of segments"
    );
    let (a, len) = (0.5, 1.2);
    let l = len / n as f64;
    let depth = ((len / 2.0).powi(2) - a * a).sqrt();
    let x: Vec<_> = (0..=n)
        .map(|i| {
            let u = 1.0 - (2.0 * i as f64 / n as f64 - 1.0).abs();
            Vector3::new(-a + 2.0 * a * i as f64 / n as f64, -depth * u, 0.0)
        })
        .collect();
    let mut mass = vec![0.01 * l; n + 1];
    mass[0] *= 0.5;
    mass[n] *= 0.5;
    let mut sys = SolidSystem::new(mass);
    sys.gravity = Vector3::new(0.0, -G, 0.0);
    sys.pinned[0] = true;
    sys.pinned[n] = true;
    for i in 0..n as u32 {
        sys.elements.stretches.push(RodStretch {
            v: [i, i + 1],
            rest_length: l,
            k: ea,
        });
    }
    let mut s = at_rest(x);
    solve_static(&sys, &mut s)?;
    let c = catenary_parameter(a, len);
    Ok((-s.x[n / 2].y, c * ((a / c).cosh() - 1.0)))
}

/// A flat sheet of `nx × ny` vertices spanning `w × hgt` in the xy-plane, two membrane
/// triangles per quad of material `mat` with warp direction `warp`, 1 g per vertex, no
/// gravity. Panics unless `nx` and `ny` are at least 2.
pub fn membrane_sheet(
    nx: usize,
    ny: usize,
    w: f64,
    hgt: f64,
    mat: MembraneMaterial,
    warp: Vector3<f64>,
) -> Result<(SolidSystem, State), String> {
    assert!(nx >= 2 && ny >= 2, "a sheet needs two vertices each way");
    let mut x = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            x.push(Vector3::new(
                w * i as f64 / (nx - 1) as f64,
                hgt * j as f64 / (ny - 1) as f64,
                0.0,
            ));
        }
    }
    let id = |i: usize, j: usize| (j * nx + i) as u32;
    let mut sys = SolidSystem::new(vec![1e-3; nx * ny]);
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            for t in [
                [id(i, j), id(i + 1, j), id(i + 1, j + 1)],
                [id(i, j), id(i + 1, j + 1), id(i, j + 1)],
            ] {
                let rest = [x[t[0] as usize], x[t[1] as usize], x[t[2] as usize]];
                sys.elements
                    .membranes
                    .push(Membrane::new(t, rest, warp, mat).map_err(|e| e.to_string())?);
            }
        }
    }
    Ok((sys, at_rest(x)))
}

/// Uniaxial membrane tension: a 1 m square sheet of `n × n` vertices (`n` odd) pulled with
/// line tension `tension` [N/m] on its left and right edges; returns the strains (ε_x, ε_y)
/// measured along its centre lines, for the linear law ε_x = N/(E t), ε_y = −ν ε_x (the
/// membrane is Green-strain StVK, so it departs from the linear law by O(ε)). Panics
/// unless `n` is odd and at least 3 (a centre vertex).
pub fn uniaxial(
    n: usize,
    mat: MembraneMaterial,
    warp: Vector3<f64>,
    tension: f64,
) -> Result<(f64, f64), String> {
    assert!(n >= 3 && n % 2 == 1, "the sheet needs a centre vertex");
    let (w, hgt) = (1.0, 1.0);
    let (mut sys, mut s) = membrane_sheet(n, n, w, hgt, mat, warp)?;
    // Pin the centre vertex: it removes rigid translation, and mesh and loads are point
    // symmetric about it, so it does not move in the exact solution either.
    sys.pinned[n / 2 * n + n / 2] = true;
    sys.forces = vec![Vector3::zeros(); n * n];
    let dy = hgt / (n - 1) as f64;
    for j in 0..n {
        // The edge nodes share the line load by their tributary length (half at the corners).
        let share = if j == 0 || j == n - 1 { 0.5 } else { 1.0 } * tension * dy;
        sys.forces[j * n] = Vector3::new(-share, 0.0, 0.0);
        sys.forces[j * n + n - 1] = Vector3::new(share, 0.0, 0.0);
    }
    solve_static(&sys, &mut s).map_err(|e| e.to_string())?;
    let (mx, my) = (n / 2 * n, n / 2);
    let ex = (s.x[mx + n - 1].x - s.x[mx].x) / w - 1.0;
    let ey = (s.x[my + (n - 1) * n].y - s.x[my].y) / hgt - 1.0;
    Ok((ex, ey))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bisection solves 2c sinh(a/c) = L to rounding.
    #[test]
    fn the_catenary_parameter_fits_the_length() {
        let c = catenary_parameter(0.5, 1.2);
        assert!((2.0 * c * (0.5 / c).sinh() - 1.2).abs() < 1e-12);
    }
}

//! The strand a user builds (`scenes/strand.json`: `geo.line` → `convert.hair` → a clamp by
//! `convert.attachment` → `solver.solid`), against the references for that object
//! (VERIFY.md, Solids). The strand is L long and held by the attachment node, so every
//! reference is for a beam of length L: no reference is moved to fit the discretization.
//! - **cantilever**: clamped, sagging under its own weight, solved statically; δ = qL⁴/(8EI)
//!   in the linear regime, the elastica's δ to converge against ([`elastica_tip`]).
//! - **tip load**: clamped, no gravity, a force P on the tip; δ = PL³/(3EI), and the
//!   elastica's.
//! - **Greenhill**: clamped at the bottom, standing up, tilted 10⁻³ rad: it stands below
//!   L_c = (7.837 EI/(ρgA))^{1/3} and falls over above it.
//! - **pendulum**: pinned by its root vertex alone (free to turn), a stiff strand swings as
//!   a rigid rod: T = 2π√(2L/(3g)) · 2K(sin(θ₀/2))/π.
//!
//! The defaults are the strand of issue 20: 0.1 m, E = 1 GPa, r = 0.5 mm, 1100 kg/m³
//! (qL³/EI = 0.17: a linear-regime cantilever).

pub use crate::graphs::{load, set};
use serde_json::json;
use std::f64::consts::PI;
use weft_graph::{Context, Graph};

/// The scene template.
pub const STRAND: &str = include_str!("../scenes/strand.json");
/// Length [m].
pub const LENGTH: f64 = 0.1;
/// Young's modulus [Pa].
pub const YOUNGS_MODULUS: f64 = 1e9;
/// Radius [m].
pub const RADIUS: f64 = 5e-4;
/// Density [kg/m³].
pub const DENSITY: f64 = 1100.0;
/// Gravity [m/s²].
pub const G: f64 = 9.81;

/// Bending stiffness EI = E πr⁴/4 [N m²] of a strand of Young's modulus `e`.
pub fn bending_stiffness(e: f64) -> f64 {
    e * PI * RADIUS.powi(4) / 4.0
}

/// Weight per length q = ρ g π r² [N/m].
pub fn weight_per_length() -> f64 {
    DENSITY * G * PI * RADIUS * RADIUS
}

/// How the strand's root is held.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Root {
    /// `select: curve_roots`, `root_vertices: 2`: the root vertex held, the strand clamped
    /// there.
    Clamped,
    /// `select: vertices`, `vertices: [0, 1]`: the first two vertices held (how a clamp was
    /// made before the clamp term: it clamps the tangent half a segment out).
    TwoPins,
    /// `select: curve_roots`, `root_vertices: 1`: the root vertex held, free to turn.
    Pinned,
}

/// The template with `n` segments from the origin to `end`, its root held as `root`.
pub fn strand(n: usize, end: [f64; 3], root: Root) -> Result<Graph, String> {
    let mut g = load(STRAND, "strand.json")?;
    set(&mut g, "line.segments", json!(n))?;
    set(&mut g, "line.end", json!(end))?;
    set(&mut g, "tip.index", json!(n))?;
    match root {
        Root::Clamped => {}
        Root::TwoPins => set(&mut g, "roots.select", json!("vertices"))?,
        Root::Pinned => set(&mut g, "roots.root_vertices", json!(1))?,
    }
    Ok(g)
}

/// The tip's position at `frame`.
pub fn tip(g: &mut Graph, frame: i64, fps: f64) -> Result<[f64; 3], String> {
    g.pull("tip", Context::at(frame, fps))
        .map_err(|e| e.to_string())?
        .get::<[f64; 3]>()
        .copied()
        .ok_or_else(|| "the tip is not a vec3".to_string())
}

/// Tip deflection of an inextensible elastica of length `len` and bending stiffness `ei`,
/// clamped horizontally at s = 0, under a weight `q` per length and a tip force `p`, both
/// downwards: the large-deflection reference the linear formulas qL⁴/(8EI) and PL³/(3EI)
/// approximate (they differ from it by O((qL³/EI)²): 3·10⁻⁴ for the default strand, above
/// what a converged discretization leaves, so convergence is measured against this).
///
/// With θ(s) the tangent's angle below horizontal, the moment balance EI θ′(s) =
/// ∫ₛᴸ q (x(σ) − x(s)) dσ + P (x(L) − x(s)) differentiates to EI θ″ = −(q (L − s) + P) cos θ,
/// with θ(0) = 0 and θ′(L) = 0 (a free tip carries no moment); δ = ∫₀ᴸ sin θ ds. Shooting
/// on θ′(0) by bisection, each shot integrated by classical RK4 over 4000 steps (error
/// O(h⁴) ≈ 10⁻¹⁴ relative).
pub fn elastica_tip(len: f64, ei: f64, q: f64, p: f64) -> f64 {
    let shoot = |k0: f64| -> (f64, f64) {
        let steps = 4000;
        let h = len / steps as f64;
        // State (θ, θ′, y).
        let f = |s: f64, u: [f64; 3]| [u[1], -(q * (len - s) + p) * u[0].cos() / ei, u[0].sin()];
        let mut u = [0.0, k0, 0.0];
        for i in 0..steps {
            let s = i as f64 * h;
            let add = |u: [f64; 3], k: [f64; 3], a: f64| [0, 1, 2].map(|j| u[j] + a * k[j]);
            let k1 = f(s, u);
            let k2 = f(s + 0.5 * h, add(u, k1, 0.5 * h));
            let k3 = f(s + 0.5 * h, add(u, k2, 0.5 * h));
            let k4 = f(s + h, add(u, k3, h));
            u = [0, 1, 2].map(|j| u[j] + h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]));
        }
        (u[1], u[2])
    };
    // θ′(L) grows with θ′(0); the linear theory's θ′(0) = (qL²/2 + PL)/EI brackets it
    // within a factor of two for any deflection short of the strand hanging down.
    let linear = (0.5 * q * len * len + p * len) / ei;
    let (mut lo, mut hi) = (0.0, 2.0 * linear);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if shoot(mid).0 > 0.0 {
            hi = mid
        } else {
            lo = mid
        }
    }
    shoot(0.5 * (lo + hi)).1
}

/// Static tip deflection of the horizontal strand under its own weight with `n` segments,
/// and the elastica's ([`elastica_tip`]; qL⁴/(8EI) to 3·10⁻⁴).
pub fn cantilever(n: usize, root: Root) -> Result<(f64, f64), String> {
    let mut g = strand(n, [LENGTH, 0.0, 0.0], root)?;
    let y = tip(&mut g, 1, 1.0)?[1];
    let ei = bending_stiffness(YOUNGS_MODULUS);
    Ok((-y, elastica_tip(LENGTH, ei, weight_per_length(), 0.0)))
}

/// Static tip deflection of the horizontal strand under a tip force `p` [N] (no gravity)
/// with `n` segments, and the elastica's ([`elastica_tip`]; PL³/(3EI) when PL²/EI ≪ 1).
pub fn tip_load(n: usize, p: f64) -> Result<(f64, f64), String> {
    let mut g = strand(n, [LENGTH, 0.0, 0.0], Root::Clamped)?;
    set(&mut g, "gravity.acceleration", json!([0.0, 0.0, 0.0]))?;
    set(&mut g, "load.force", json!([0.0, -p, 0.0]))?;
    let y = tip(&mut g, 1, 1.0)?[1];
    let ei = bending_stiffness(YOUNGS_MODULUS);
    Ok((-y, elastica_tip(LENGTH, ei, 0.0, p)))
}

/// Greenhill's critical length of a clamped vertical strand under its own weight [m]:
/// q L³/EI = 7.837.
pub fn greenhill_length() -> f64 {
    (7.837 * bending_stiffness(YOUNGS_MODULUS) / weight_per_length()).cbrt()
}

/// A vertical strand `factor` × [`greenhill_length`] long with `n` segments, clamped at the
/// bottom and tilted 10⁻³ rad, run for 8 s (implicit Euler, 24 fps × 4 substeps, damping
/// 1/s so it settles): the tip's largest sideways offset over the last second, relative to
/// the length. Below L_c the tilt is amplified by 1/(1 − (L/L_c)³) (17× at 0.98 L_c: an
/// offset near 0.02); above it the strand buckles over to its post-buckled shape (an offset
/// of several tenths at 1.02 L_c).
pub fn greenhill(factor: f64, n: usize) -> Result<f64, String> {
    let len = factor * greenhill_length();
    let tilt: f64 = 1e-3;
    let mut g = strand(n, [len * tilt.sin(), len * tilt.cos(), 0.0], Root::Clamped)?;
    set(&mut g, "rod.damping", json!(1.0))?;
    set(&mut g, "solve.method", json!("newton"))?;
    set(&mut g, "solve.substeps", json!(4))?;
    set(&mut g, "solve.tolerance", json!(1e-9))?;
    set(&mut g, "solve.max_retries", json!(4))?;
    let fps = 24.0;
    let mut offset = 0.0f64;
    for f in 1..=(8.0 * fps) as i64 {
        let x = tip(&mut g, f, fps)?[0];
        if f as f64 > 7.0 * fps {
            offset = offset.max(x.abs() / len);
        }
    }
    Ok(offset)
}

/// The complete elliptic integral of the first kind K(k), by the arithmetic–geometric mean.
pub fn elliptic_k(k: f64) -> f64 {
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    for _ in 0..32 {
        let (x, y) = (0.5 * (a + b), (a * b).sqrt());
        a = x;
        b = y;
    }
    PI / (2.0 * a)
}

/// A strand pinned by its root vertex alone, released `theta` [rad] from hanging straight
/// down, Young's modulus `e`, `n` segments, stepped at `fps` × 4 substeps for `seconds`: the
/// mean period of the tip's swing (from the times it crosses the vertical, interpolated
/// between frames), and a rigid rod's period 2π√(2L/(3g)) · 2K(sin(θ₀/2))/π.
pub fn pendulum_period(
    n: usize,
    e: f64,
    theta: f64,
    fps: f64,
    seconds: f64,
) -> Result<(f64, f64), String> {
    let mut g = strand(
        n,
        [LENGTH * theta.sin(), -LENGTH * theta.cos(), 0.0],
        Root::Pinned,
    )?;
    set(&mut g, "rod.youngs_modulus", json!(e))?;
    set(&mut g, "solve.method", json!("newton"))?;
    set(&mut g, "solve.substeps", json!(4))?;
    set(&mut g, "solve.tolerance", json!(1e-10))?;
    let mut crossings = Vec::new();
    let mut prev = tip(&mut g, 0, fps)?[0];
    for f in 1..=(seconds * fps).round() as i64 {
        let x = tip(&mut g, f, fps)?[0];
        if prev > 0.0 && x <= 0.0 {
            // Linear interpolation: the swing is nearly linear in time at the vertical
            // (its acceleration vanishes there), so the error is O(Δt³).
            crossings.push((f as f64 - 1.0 + prev / (prev - x)) / fps);
        }
        prev = x;
    }
    if crossings.len() < 2 {
        return Err(format!(
            "the strand crossed the vertical {} times",
            crossings.len()
        ));
    }
    let period = (crossings[crossings.len() - 1] - crossings[0]) / (crossings.len() - 1) as f64;
    let rigid = 2.0 * PI * (2.0 * LENGTH / (3.0 * G)).sqrt();
    Ok((period, rigid * 2.0 * elliptic_k((0.5 * theta).sin()) / PI))
}

/// The cloth strip template (`scenes/strip.json`): 0.4 m × 0.1 m, 1 mm, E = 2 GPa, ν = 0,
/// 5 g/m², clamped along its short edge at x = 0.
pub const STRIP: &str = include_str!("../scenes/strip.json");
/// The strip's length [m] (along x).
pub const STRIP_LENGTH: f64 = 0.4;

/// How the strip's edge is held.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Edge {
    /// The first column held with `clamp: true`: the clamp at x = 0.
    Clamped,
    /// The first two columns held, no clamp (the clamp before issue 20): rigid up to the
    /// second column, and clamped half a column behind it.
    TwoColumns,
}

/// Static tip deflection (mean of the tip's two corners) of the strip with `nx` × `ny`
/// vertices, held as `edge`, and the elastica's for a beam of the strip's length
/// (EI = E b t³/12: ν = 0, so the narrow and wide plate formulas agree).
pub fn strip_tip(nx: usize, ny: usize, edge: Edge) -> Result<(f64, f64), String> {
    let mut g = load(STRIP, "strip.json")?;
    set(&mut g, "sheet.nx", json!(nx))?;
    set(&mut g, "sheet.ny", json!(ny))?;
    let mut held: Vec<usize> = (0..ny).map(|j| j * nx).collect();
    if edge == Edge::TwoColumns {
        held.extend((0..ny).map(|j| j * nx + 1));
        set(&mut g, "edge.clamp", json!(false))?;
    }
    set(&mut g, "edge.vertices", json!(held))?;
    set(&mut g, "tip0.index", json!(nx - 1))?;
    set(&mut g, "tip1.index", json!(ny * nx - 1))?;
    let mut y = 0.0;
    for out in ["tip0", "tip1"] {
        y -= 0.5
            * g.pull(out, Context::at(1, 1.0))
                .map_err(|e| e.to_string())?
                .get::<[f64; 3]>()
                .ok_or("the tip is not a vec3")?[1];
    }
    let (e, t, b, rho_a) = (2e9, 1e-3, 0.1, 0.005);
    let ei = e * b * t * t * t / 12.0;
    Ok((y, elastica_tip(STRIP_LENGTH, ei, rho_a * G * b, 0.0)))
}

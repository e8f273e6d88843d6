//! A rough cost model: how long a frame will take, said before the first one starts.
//!
//! It exists so that a graph whose parameters imply hours of work says so at once, not to
//! predict times closely. Fitted to `weft bench solid` and `weft bench fluid` on the
//! project's 2-core machine (BENCHMARKS.md): a projected-Newton iteration costs 5.3 µs of
//! assembly per vertex plus a sparse factorization of 9.2 ms at 1024 cloth vertices growing
//! as n^1.5 (surfaces; 9.3 s at 100k), or about 0.6 µs per vertex for hair (chains factor
//! in linear time); cloth takes about 8 Newton iterations a step, hair up to 80; a pressure
//! solve costs 43 ns per cell per CG iteration with 75 iterations at 64³, growing as the
//! cube root of the cell count. Within a factor of a few of measured times, which is all a
//! warning needs.

use crate::Compiled;
use weft_solid::Method;

/// Estimated seconds for one solid step of `compiled` with `method`.
pub fn solid_step_seconds(compiled: &Compiled, method: Method) -> f64 {
    let term = |k: &str| compiled.terms.get(k).copied().unwrap_or(0) as f64;
    // A triangle mesh has about two triangles a vertex; a strand one segment a vertex.
    let cloth = 0.5 * term("membranes");
    let hair = term("rod_stretches");
    let n = cloth + hair;
    let assembly = 5.3e-6 * n;
    let factor = 9.2e-3 * (cloth / 1024.0).powf(1.5) + 0.6e-6 * hair;
    let iterations = if cloth >= hair { 8.0 } else { 40.0 };
    match method {
        Method::Explicit => 0.5 * assembly,
        Method::Linearized => assembly + factor,
        Method::Newton | Method::ProjectedNewton | Method::Static => {
            iterations * (assembly + factor)
        }
    }
}

/// Estimated seconds for one pressure solve on `cells` cells.
pub fn pressure_solve_seconds(cells: usize) -> f64 {
    let c = cells as f64;
    let iterations = 75.0 * (c / 262_144.0).cbrt();
    4.3e-8 * c * iterations.max(1.0)
}

/// `s` seconds for people: `40 s`, `12 min`, `3.2 h`, `2.5 days`.
pub fn human_seconds(s: f64) -> String {
    if s < 120.0 {
        format!("{s:.0} s")
    } else if s < 7200.0 {
        format!("{:.0} min", s / 60.0)
    } else if s < 172_800.0 {
        format!("{:.1} h", s / 3600.0)
    } else {
        format!("{:.1} days", s / 86_400.0)
    }
}

/// Above this many seconds a frame, solvers say what they estimate before starting.
pub const WARN_SECONDS_PER_FRAME: f64 = 600.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_well_and_the_model_grows() {
        assert_eq!(human_seconds(45.0), "45 s");
        assert_eq!(human_seconds(720.0), "12 min");
        assert_eq!(human_seconds(3.0 * 3600.0), "3.0 h");
        assert_eq!(human_seconds(3.0 * 86_400.0), "3.0 days");
        // Against BENCHMARKS.md (64³: 0.84 s a solve): within a factor of 1.5.
        let t = pressure_solve_seconds(64 * 64 * 64);
        assert!((0.84 / 1.5..0.84 * 1.5).contains(&t), "{t}");
        assert!(pressure_solve_seconds(128 * 128 * 128) > 8.0 * t);
    }
}

//! `weft bench fluid`: the pressure solve's cost against this machine's memory bandwidth.
//!
//! A closed box filled with a pseudo-random velocity field (deterministic) is projected to a
//! divergence of 1e-6 of its initial largest divergence, at several resolutions. Reported:
//! seconds per solve, CG iterations, seconds per iteration, the bytes an iteration must move
//! (counted from the arrays it streams), and the fraction of the measured single-thread
//! memory bandwidth (a STREAM-style triad over 3 × 128 MiB) that this amounts to.

use crate::row::Row;
use std::time::Instant;
use weft_fluid::pressure::max_divergence;
use weft_fluid::{Boundaries, Domain, MacGrid, PressureSolve, Projection};

/// Best-of-five triad a = b + s·c over 3 arrays of 16 Mi f64: bytes per second (24 per element,
/// write-allocate not counted, as STREAM reports).
fn triad_bandwidth() -> f64 {
    let n = 16 << 20;
    let b = vec![1.0f64; n];
    let c = vec![2.0f64; n];
    let mut a = vec![0.0f64; n];
    let mut best = f64::MAX;
    for rep in 0..5 {
        let s = 0.5 + rep as f64;
        let t = Instant::now();
        for ((x, y), z) in a.iter_mut().zip(&b).zip(&c) {
            *x = y + s * z;
        }
        best = best.min(t.elapsed().as_secs_f64());
        std::hint::black_box(&a);
    }
    24.0 * n as f64 / best
}

pub(crate) fn suite(quick: bool) -> Result<Vec<Row>, String> {
    let sizes: &[usize] = if quick { &[16, 32] } else { &[32, 64, 128] };
    let bw = triad_bandwidth();
    let mut rows = vec![Row {
        case: "memory bandwidth, triad, one thread".into(),
        nodes: 0,
        value: bw / 1e9,
        unit: "GB/s",
        target: "",
    }];
    for &n in sizes {
        let d = Domain::new(
            [0.0; 3],
            [1.0; 3],
            1.0 / n as f64,
            Boundaries::closed(),
            None,
        )
        .map_err(|e| e.to_string())?;
        let mut g = MacGrid::new(d);
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        for u in g.vel.iter_mut().flatten() {
            // xorshift64: a fixed pseudo-random field, the same on every run.
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            *u = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        }
        g.apply_boundaries();
        let div0 = max_divergence(&g);
        let mut proj = Projection::new(&g);
        let settings = PressureSolve {
            tolerance: 1e-6 * div0,
            max_iterations: 10_000,
        };
        let t = Instant::now();
        let s = proj
            .project(&mut g, 1000.0, 0.01, &settings)
            .map_err(|e| e.to_string())?;
        let total = t.elapsed().as_secs_f64();
        let per_it = s.solve_seconds / s.iterations.max(1) as f64;
        let bytes = proj.bytes_per_iteration();
        let cells = n * n * n;
        let name = format!("pressure solve {n}³");
        for (case, value, unit, target) in [
            (format!("{name}: seconds per solve"), total, "s", ""),
            (
                format!("{name}: CG iterations"),
                s.iterations as f64,
                "",
                "",
            ),
            (
                format!("{name}: ms per CG iteration"),
                per_it * 1e3,
                "ms",
                "",
            ),
            (
                format!("{name}: MB moved per iteration"),
                bytes / 1e6,
                "MB",
                "",
            ),
            (
                format!("{name}: fraction of triad bandwidth"),
                bytes / per_it / bw,
                "",
                "≥ 0.5",
            ),
        ] {
            rows.push(Row {
                case,
                nodes: cells,
                value,
                unit,
                target,
            });
        }
    }
    Ok(rows)
}

//! `weft bench convergence`: verification scenes against their analytic references under
//! refinement, with the observed orders of convergence (scenes and references in
//! [`crate::scenes_resolution`]).
//!
//! `--quick` asserts what the discretizations fix: the rod cantilever and the catenary
//! converge at second order (band 1.7–2.3), Taylor–Green at first order (0.8–1.3:
//! semi-Lagrangian advection at fixed CFL), the shell strip is within 0.5 % of beam theory at
//! every size, the membrane follows the linear law to 0.1 % at every size, and the Darcy
//! slab's pressure drop is exact (below 10⁻⁶) at every size.

use crate::scenes_resolution as scenes;
use crate::sweep::{self, Checks, Run};
use std::path::Path;

/// Runs the refinements, writes `convergence.csv`/`.json` and a chart into `out`, prints the
/// table and the checks, and returns the checks.
pub fn suite(quick: bool, out: &Path) -> Result<Checks, String> {
    let mut runs: Vec<Run> = Vec::new();
    let segments: &[usize] = if quick {
        &[10, 20, 40]
    } else {
        &[5, 10, 20, 40, 80]
    };
    for &n in segments {
        runs.push(scenes::cantilever(n));
        runs.push(scenes::catenary(2 * n));
    }
    let strips: &[usize] = if quick { &[21, 41] } else { &[11, 21, 41, 81] };
    for &nx in strips {
        runs.push(scenes::shell_strip(nx));
    }
    let sheets: &[usize] = if quick { &[5, 11] } else { &[5, 11, 21] };
    for &n in sheets {
        runs.push(scenes::membrane(n));
    }
    let cells: &[usize] = if quick { &[16, 32] } else { &[16, 32, 64, 128] };
    for &n in cells {
        runs.push(scenes::taylor_green(n));
    }
    let slab: &[f64] = if quick {
        &[0.05, 0.025]
    } else {
        &[0.05, 0.025, 0.0125]
    };
    for &dx in slab {
        runs.push(scenes::darcy_slab(dx));
    }
    // Orders where the discretization fixes one (the shell strip's error is the clamp and
    // the nonlinearity; the Darcy slab's is rounding).
    let names = ["cantilever", "catenary", "taylor_green"];
    let orders: Vec<(String, f64)> = names
        .iter()
        .map(|n| {
            let o = sweep::order_of(&runs, |r| r.dx, |r| r.scene == *n);
            (n.to_string(), o)
        })
        .collect();
    println!("relative error against the analytic reference, by segment or cell size");
    println!("| scene | size [m] | error | wall [s] |\n|---|---:|---:|---:|");
    for r in &runs {
        println!(
            "| {} | {:.4e} | {:.3e} | {:.3} |",
            r.scene, r.dx, r.error, r.seconds
        );
    }
    sweep::print_orders(&orders);
    let order = |n: &str| {
        orders
            .iter()
            .find(|(m, _)| m == n)
            .map_or(f64::NAN, |o| o.1)
    };
    let all =
        |n: &str, f: &dyn Fn(f64) -> bool| runs.iter().filter(|r| r.scene == n).all(|r| f(r.error));
    let mut checks: Checks = Vec::new();
    for (n, lo, hi) in [
        ("cantilever", 1.7, 2.3),
        ("catenary", 1.7, 2.3),
        ("taylor_green", 0.8, 1.3),
    ] {
        let o = order(n);
        checks.push((
            format!("{n}: order {o:.3} in band {lo}–{hi}"),
            (lo..=hi).contains(&o),
        ));
    }
    let strip: Vec<f64> = runs
        .iter()
        .filter(|r| r.scene == "shell_strip")
        .map(|r| r.error)
        .collect();
    checks.push((
        format!(
            "shell_strip within 0.5 % of beam theory from 20 segments, falling ({})",
            strip
                .iter()
                .map(|e| format!("{e:.2e}"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        runs.iter()
            .filter(|r| r.scene == "shell_strip" && r.dx <= 0.02 + 1e-12)
            .all(|r| r.error < 5e-3)
            && strip.windows(2).all(|w| w[1] < w[0]),
    ));
    checks.push((
        "membrane: the linear law to 0.1 % at every size (strain 1e-4)".into(),
        all("membrane", &|e| e < 1e-3),
    ));
    checks.push((
        "darcy_slab exact (below 1e-6) at every size".into(),
        all("darcy_slab", &|e| e < 1e-6),
    ));
    sweep::print_checks(&checks);
    sweep::write_runs(
        out,
        "convergence",
        &runs,
        serde_json::json!({"orders": orders, "checks": checks}),
    )?;
    crate::charts::error_vs(
        crate::charts::Across::Size,
        &runs,
        &orders,
        "Relative error against analytic references under refinement",
        &out.join("convergence_error_size"),
    )?;
    println!(
        "\nwrote {} runs and a chart (PNG, SVG) to {}",
        runs.len(),
        out.display()
    );
    Ok(checks)
}

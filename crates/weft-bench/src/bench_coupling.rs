//! `weft bench coupling`: where each coupling method holds (see [`crate::scenes_coupled`]
//! for the scene and its converged reference).
//!
//! A light strand (ρ_s = 100 kg/m³, a tenth of the water's density) rises in a closed box of
//! water. Swept: the step h and the drag scale ξ_D, so the drag-to-mass ratio K/m = k/ρ_s,
//! and the methods `one_way`, `staggered` and `newton`. The theory (VERIFY.md, "stability
//! where methods fail"): exchanging the forces once per step lags the fluid's reply, so
//! `staggered` goes wrong above some h·K/m; `newton` iterates the exchange to convergence and
//! holds; `one_way` ignores the reply and is wrong wherever the strand drags the water along.
//!
//! `--quick` asserts: `newton` never blows up and stays within 5 % at the strongest drag,
//! converging at first order in h there (band 0.8–1.2: backward Euler); `staggered` is off by
//! more than 5 % in every cell with h·K/m ≥ 200 while `newton` holds in each of them.

use crate::scenes_coupled::{self, COUPLINGS, Scene};
use crate::sweep::{self, Checks, Run, Status};
use std::path::Path;

/// The strand's density [kg/m³].
const DENSITY: f64 = 100.0;
/// h·K/m above which staggered exchange is asserted to fail.
const STAGGERED_LIMIT: f64 = 200.0;

/// Runs the sweep, writes `coupling.csv`/`.json` and the charts into `out`, prints the map
/// and the checks, and returns the checks.
pub fn suite(quick: bool, out: &Path) -> Result<Checks, String> {
    let (xis, ns): (&[f64], &[f64]) = if quick {
        (&[1e6, 1e8, 1e9], &[25.0, 100.0, 400.0])
    } else {
        (&[1e6, 1e7, 1e8, 1e9], &[25.0, 50.0, 100.0, 200.0, 400.0])
    };
    let hs: Vec<f64> = ns.iter().map(|n| 1.0 / n).collect();
    let mut runs: Vec<Run> = Vec::new();
    // Per run: the graph's own time per coupling iteration beyond its stages', and the
    // iteration's wall time.
    let mut overheads: Vec<(f64, f64)> = Vec::new();
    for &xi in xis {
        let scene = Scene::Strand {
            density: DENSITY,
            xi_d: xi,
        };
        let reference = scenes_coupled::reference(scene);
        if reference.is_none() {
            println!("warning: no converged reference at ξ_D = {xi:e}: only blow-ups are judged");
        }
        for m in COUPLINGS {
            for &h in &hs {
                let (run, overhead, per) =
                    scenes_coupled::coupled_run(scene, m, h, reference.as_deref());
                runs.push(run);
                overheads.push((overhead, per));
            }
        }
    }
    let strongest = scenes_coupled::strand_drag(*xis.last().unwrap_or(&1e9)) / DENSITY;
    println!(
        "light strand (ρ_s = {DENSITY} kg/m³) rising in water: largest velocity error against Newton at h = 1/1600 s"
    );
    println!("| K/m [1/s] | h [s] | h·K/m | one_way | staggered | newton |");
    println!("|---:|---:|---:|---:|---:|---:|");
    let find = |m: &str, p: f64, h: f64| {
        runs.iter()
            .find(|r| r.method == m && r.param == p && (r.h - h).abs() < 1e-12)
    };
    let mut params: Vec<f64> = runs.iter().map(|r| r.param).collect();
    params.sort_by(f64::total_cmp);
    params.dedup();
    for &p in &params {
        for &h in &hs {
            let cells: Vec<String> = COUPLINGS
                .iter()
                .map(|m| {
                    find(m, p, h).map_or("-".into(), |r| match r.status {
                        Status::BlownUp => "blown up".into(),
                        _ => format!("{:.2e} ({:.1} it)", r.error, r.iterations),
                    })
                })
                .collect();
            println!(
                "| {p:.2e} | 1/{:.0} | {:.0} | {} |",
                1.0 / h,
                h * p,
                cells.join(" | ")
            );
        }
    }
    let strongest_runs: Vec<Run> = runs
        .iter()
        .filter(|r| r.param == strongest)
        .cloned()
        .collect();
    let methods = COUPLINGS;
    let orders = sweep::orders_in_step(&strongest_runs, &methods);
    let newton_order = sweep::order_named(&orders, "newton");
    println!(
        "\nstability map (S within 5 %, I further, X blown up, F failed, ? no reference): rows K/m [1/s], columns h"
    );
    sweep::print_map(&runs, &methods, &params, &hs);
    let mut checks: Checks = Vec::new();
    checks.push((
        "newton never blows up".into(),
        runs.iter()
            .filter(|r| r.method == "newton")
            .all(|r| r.status != Status::BlownUp),
    ));
    checks.push((
        format!("newton within 5 % at the strongest drag (K/m = {strongest:.2e} 1/s)"),
        runs.iter()
            .filter(|r| r.method == "newton" && r.param == strongest)
            .all(|r| r.status == Status::Stable),
    ));
    checks.push((
        format!("newton first order in h at the strongest drag (observed {newton_order:.3}, band 0.8–1.2)"),
        (0.8..=1.2).contains(&newton_order),
    ));
    let beyond: Vec<&Run> = runs
        .iter()
        .filter(|r| r.method == "staggered" && r.h * r.param >= STAGGERED_LIMIT)
        .collect();
    let newton_there = beyond
        .iter()
        .all(|s| find("newton", s.param, s.h).is_some_and(|n| n.status == Status::Stable));
    checks.push((
        format!(
            "staggered fails where h·K/m ≥ {STAGGERED_LIMIT} ({} cells) and newton holds there",
            beyond.len()
        ),
        !beyond.is_empty() && beyond.iter().all(|r| r.status != Status::Stable) && newton_there,
    ));
    // The settling sheet: every method against the converged fall, and that fall against
    // Darcy's terminal velocity.
    let sheet_ref = scenes_coupled::reference(Scene::Sheet);
    let mut sheet: Vec<Run> = Vec::new();
    for m in COUPLINGS {
        for &h in &hs {
            let (run, overhead, per) =
                scenes_coupled::coupled_run(Scene::Sheet, m, h, sheet_ref.as_deref());
            sheet.push(run);
            overheads.push((overhead, per));
        }
    }
    // The engine's own cost per coupling iteration: the time an iteration takes beyond its
    // stages' kernels (scheduling, dirtiness, caching, feedback), against the iteration.
    let mut fractions: Vec<f64> = overheads
        .iter()
        .filter(|(o, p)| o.is_finite() && *p > 0.0)
        .map(|(o, p)| o / p)
        .collect();
    fractions.sort_by(f64::total_cmp);
    let mut micros: Vec<f64> = overheads
        .iter()
        .filter(|(o, _)| o.is_finite())
        .map(|(o, _)| o * 1e6)
        .collect();
    micros.sort_by(f64::total_cmp);
    let median = |v: &[f64]| v.get(v.len() / 2).copied().unwrap_or(f64::NAN);
    let (overhead_us, overhead_fraction) = (median(&micros), median(&fractions));
    println!(
        "\ngraph overhead per coupling iteration (beyond the stages' kernels): median {overhead_us:.1} µs, {:.3} % of an iteration (largest {:.3} %)",
        100.0 * overhead_fraction,
        100.0 * fractions.last().copied().unwrap_or(f64::NAN)
    );
    let terminal = weft_sim::verify::sheet_terminal();
    let fall = sheet_ref
        .as_ref()
        .and_then(|r| r.last())
        .map_or(f64::NAN, |v| -v);
    println!(
        "\nsettling sheet: converged fall {fall:.5} m/s at {:.2} s, Darcy Δρg/k = {terminal:.5} m/s (ratio {:.4})",
        Scene::Sheet.duration(),
        fall / terminal
    );
    println!("| h [s] | one_way | staggered | newton |\n|---:|---:|---:|---:|");
    for &h in &hs {
        let cells: Vec<String> = COUPLINGS
            .iter()
            .map(|m| {
                sheet
                    .iter()
                    .find(|r| r.method == *m && (r.h - h).abs() < 1e-12)
                    .map_or("-".into(), |r| {
                        format!("{:.2e} ({:.1} it)", r.error, r.iterations)
                    })
            })
            .collect();
        println!("| 1/{:.0} | {} |", 1.0 / h, cells.join(" | "));
    }
    let sheet_orders = sweep::orders_in_step(&sheet, &methods);
    // α² = (1 − φ)² with φ ≈ 0.5 % where the sheet is rasterized: 1 % slower than Darcy's
    // Δρg/k; 3 % allows the sheet's spread over two face layers.
    checks.push((
        format!(
            "settling sheet falls at Darcy's terminal velocity (ratio {:.4}, within 3 %)",
            fall / terminal
        ),
        (fall / terminal - 1.0).abs() < 0.03,
    ));
    let sheet_newton = sweep::order_named(&sheet_orders, "newton");
    checks.push((
        format!(
            "settling sheet: newton first order in h (observed {sheet_newton:.3}, band 0.8–1.2)"
        ),
        (0.8..=1.2).contains(&sheet_newton),
    ));
    sweep::print_checks(&checks);
    let mut all = runs.clone();
    all.extend(sheet.iter().cloned());
    sweep::write_runs(
        out,
        "coupling",
        &all,
        serde_json::json!({
            "density_kg_m3": DENSITY,
            "inaccurate_above": scenes_coupled::COUPLED_INACCURATE,
            "newton_order": newton_order,
            "graph_overhead_us_per_iteration": overhead_us,
            "graph_overhead_fraction_of_iteration": overhead_fraction,
            "checks": checks,
        }),
    )?;
    let title = format!("Light strand, K/m = {strongest:.1e} 1/s");
    crate::charts::error_vs_time(
        &strongest_runs,
        &format!("{title}: error against wall time"),
        &out.join("coupling_error_time"),
    )?;
    crate::charts::error_vs(
        crate::charts::Across::Step,
        &strongest_runs,
        &orders,
        &format!("{title}: error against step"),
        &out.join("coupling_error_step"),
    )?;
    crate::charts::error_vs(
        crate::charts::Across::Step,
        &sheet,
        &sheet_orders,
        "Settling sheet: error against step",
        &out.join("coupling_sheet_error_step"),
    )?;
    crate::charts::stability_map(
        &runs,
        |r| r.param,
        "drag-to-mass ratio K/m [1/s]",
        "Light strand coupling: green within 5 %, orange further, red blown up",
        &out.join("coupling_stability"),
    )?;
    println!(
        "\nwrote {} runs and charts (PNG, SVG) to {}",
        all.len(),
        out.display()
    );
    Ok(checks)
}

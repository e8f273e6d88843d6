//! `weft bench`: measurements that are not tests (no timing is ever asserted).
//!
//! Suite `graph` measures the engine's own overhead with trivial nodes: a clean re-pull of an
//! output (everything cached), a re-pull after dirtying the root of a chain (every node
//! re-runs) or one leaf of a fan-in (only the sum re-runs), and loading + validating a file.
//! The sweep suites (`accuracy`, `convergence`, `coupling`) are in their own modules.

use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;
use weft_graph::{Context, Graph, Registry, load_str};

/// Arguments of `weft bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Suite to run: `graph` (engine overhead), `solid` (cloth and hair solver), `contact`
    /// (a cloth draped on a sphere: detection, ADMM and Newton per step; and the incline
    /// sweep against Coulomb, charted into `--out`), `fluid`
    /// (pressure solve against memory bandwidth), or a sweep: `accuracy` (solid integrators
    /// over step, stiffness and Newton tolerance: error against step and wall time, stability
    /// maps), `convergence` (verification scenes under refinement, with fitted orders) or
    /// `coupling` (coupling methods over step and drag-to-mass ratio). Sweeps write CSV,
    /// JSON and charts (PNG, SVG) into `--out`.
    suite: String,
    /// Fewer repetitions or a smaller sweep (for CI); a sweep then also fails (exit 1) when
    /// a fact theory fixes does not hold.
    #[arg(long)]
    quick: bool,
    /// Directory for the sweep suites' outputs (CSV, JSON, charts).
    #[arg(long, value_name = "DIR", default_value = "bench-out")]
    out: std::path::PathBuf,
    /// Also write the results as JSON to this file.
    #[arg(long, value_name = "FILE")]
    json: Option<std::path::PathBuf>,
}

/// A chain `n0 → n1 → … → n{N−1}` of `math.add` nodes after one constant.
pub fn chain_graph(n: usize) -> String {
    let mut s = String::from("{\"format\": \"weft-graph\", \"version\": 1, \"nodes\": {\n");
    s += "\"n0\": {\"type\": \"value.float\", \"params\": {\"value\": 1.0}}";
    for i in 1..n {
        s += &format!(
            ",\n\"n{i}\": {{\"type\": \"math.add\", \"inputs\": {{\"a\": \"n{}.out\"}}, \"params\": {{}}}}",
            i - 1
        );
    }
    s + &format!("}},\n\"outputs\": {{\"out\": \"n{}.out\"}}}}\n", n - 1)
}

/// `N − 1` constants summed by one `math.sum`.
pub fn fan_in_graph(n: usize) -> String {
    let mut s = String::from("{\"format\": \"weft-graph\", \"version\": 1, \"nodes\": {\n");
    let mut terms = Vec::new();
    for i in 0..n - 1 {
        s += &format!(
            "\"l{i}\": {{\"type\": \"value.float\", \"params\": {{\"value\": {i}.0}}}},\n"
        );
        terms.push(format!("\"l{i}.out\""));
    }
    s += &format!(
        "\"sum\": {{\"type\": \"math.sum\", \"inputs\": {{\"terms\": [{}]}}}}",
        terms.join(", ")
    );
    s + "},\n\"outputs\": {\"out\": \"sum.out\"}}\n"
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[xs.len() / 2]
}

fn clean_pull_us(g: &mut Graph, reps: usize) -> f64 {
    let ctx = Context::new(0);
    g.pull("out", ctx).expect("bench graph evaluates");
    let t = Instant::now();
    for _ in 0..reps {
        std::hint::black_box(g.pull("out", ctx).expect("cached"));
    }
    t.elapsed().as_secs_f64() * 1e6 / reps as f64
}

fn dirty_pull_ms(g: &mut Graph, node: &str, reps: usize) -> f64 {
    let ctx = Context::new(0);
    let times = (0..reps)
        .map(|i| {
            let t = Instant::now();
            g.set_param(node, "value", serde_json::json!(i as f64))
                .expect("bench param");
            std::hint::black_box(g.pull("out", ctx).expect("bench graph evaluates"));
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    median(times)
}

use crate::row::Row;

fn graph_suite(reg: &Arc<Registry>, quick: bool) -> Vec<Row> {
    let sizes: &[usize] = if quick {
        &[1_000, 10_000]
    } else {
        &[100, 1_000, 10_000, 100_000]
    };
    let reps = if quick { 2_000 } else { 100_000 };
    let dirty_reps = if quick { 5 } else { 31 };
    let mut rows = Vec::new();
    for &n in sizes {
        let chain = chain_graph(n);
        let fan = fan_in_graph(n);
        let loads = (0..if quick { 2 } else { 7 })
            .map(|_| {
                let t = Instant::now();
                let g = load_str(reg, &chain, "chain").expect("bench graph loads");
                let ms = t.elapsed().as_secs_f64() * 1e3;
                drop(g); // freeing the graph is not part of loading it
                ms
            })
            .collect();
        rows.push(Row {
            case: "load + validate chain file".into(),
            nodes: n,
            value: median(loads),
            unit: "ms",
            target: "< 100 ms at 10k",
        });
        let mut g = load_str(reg, &chain, "chain").expect("loads");
        rows.push(Row {
            case: "clean re-pull, chain".into(),
            nodes: n,
            value: clean_pull_us(&mut g, reps),
            unit: "µs",
            target: "< 10 µs, flat in size",
        });
        let ms = dirty_pull_ms(&mut g, "n0", dirty_reps);
        rows.push(Row {
            case: "dirty root + re-pull, chain".into(),
            nodes: n,
            value: ms,
            unit: "ms",
            target: "",
        });
        rows.push(Row {
            case: "  per node".into(),
            nodes: n,
            value: ms * 1e3 / n as f64,
            unit: "µs",
            target: "≤ 1 µs",
        });
        let mut f = load_str(reg, &fan, "fan").expect("loads");
        rows.push(Row {
            case: "clean re-pull, fan-in".into(),
            nodes: n,
            value: clean_pull_us(&mut f, reps),
            unit: "µs",
            target: "< 10 µs, flat in size",
        });
        let ms = dirty_pull_ms(&mut f, "l0", dirty_reps);
        rows.push(Row {
            case: "dirty one leaf + re-pull, fan-in".into(),
            nodes: n,
            value: ms,
            unit: "ms",
            target: "",
        });
        rows.push(Row {
            case: "  per input read".into(),
            nodes: n,
            value: ms * 1e3 / n as f64,
            unit: "µs",
            target: "≤ 1 µs",
        });
    }
    rows
}

/// The exit code of a sweep suite: 1 when it failed, or (with `--quick`) when a fact theory
/// fixes did not hold.
fn checked(quick: bool, result: Result<crate::sweep::Checks, String>) -> ExitCode {
    match result {
        Ok(checks) if quick && checks.iter().any(|(_, ok)| !ok) => {
            eprintln!("error: a fact theory fixes did not hold (see FAIL above)");
            ExitCode::from(1)
        }
        Ok(_) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
    }
}

/// Runs `weft bench`.
pub fn run(reg: &Arc<Registry>, a: BenchArgs) -> ExitCode {
    let rows = match a.suite.as_str() {
        "graph" => graph_suite(reg, a.quick),
        "solid" => match crate::bench_solid::suite(a.quick) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(1);
            }
        },
        "contact" => match crate::bench_contact::suite(a.quick, &a.out) {
            Ok((r, checks)) => {
                crate::sweep::print_checks(&checks);
                if a.quick && checks.iter().any(|(_, ok)| !ok) {
                    eprintln!("error: a fact theory fixes did not hold (see FAIL above)");
                    return ExitCode::from(1);
                }
                r
            }
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(1);
            }
        },
        "fluid" => match crate::bench_fluid::suite(a.quick) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(1);
            }
        },
        "accuracy" => {
            return checked(
                a.quick,
                crate::bench_accuracy::suite(a.quick, &a.out).map(|s| s.checks),
            );
        }
        "convergence" => {
            return checked(a.quick, crate::bench_convergence::suite(a.quick, &a.out));
        }
        "coupling" => {
            return checked(a.quick, crate::bench_coupling::suite(a.quick, &a.out));
        }
        other => {
            eprintln!(
                "error: unknown bench suite '{other}' (suites: graph, solid, contact, fluid, accuracy, convergence, coupling)"
            );
            return ExitCode::from(2);
        }
    };
    println!("| case | size | value | unit | target |\n|---|---:|---:|---|---|");
    for r in &rows {
        println!(
            "| {} | {} | {:.3} | {} | {} |",
            r.case, r.nodes, r.value, r.unit, r.target
        );
    }
    if let Some(p) = &a.json {
        let text = serde_json::to_string_pretty(&rows).unwrap_or_default();
        if let Err(e) = weft_graph::atomic_write(p, text.as_bytes()) {
            eprintln!("error: cannot write {}: {e}", p.display());
            return ExitCode::from(1);
        }
    }
    ExitCode::SUCCESS
}

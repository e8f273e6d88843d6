//! Every file in `graphs/` loads and runs, and each example's numbers match its reference.

mod common;
use common::*;
use weft::graph::Context;

#[test]
fn every_graph_file_runs_to_finite_outputs() {
    let cache = tempfile::tempdir().unwrap();
    let mut count = 0;
    for entry in std::fs::read_dir(graphs_dir()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "json") {
            continue;
        }
        count += 1;
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        let mut g = example(&name);
        assert!(
            g.load_warnings().is_empty(),
            "{name}: {:?}",
            g.load_warnings()
        );
        // Disk caches write to a scratch directory, not the checkout.
        let ids: Vec<String> = g.node_ids().map(str::to_string).collect();
        for id in ids {
            if g.node_spec(&id).unwrap().name == "cache.disk" {
                let dir = cache.path().join(&name).join(&id);
                g.set_param(&id, "path", serde_json::json!(dir.to_str().unwrap()))
                    .unwrap();
            }
        }
        let outputs: Vec<String> = g.output_names().map(str::to_string).collect();
        for frame in 0..=24 {
            for o in &outputs {
                let v = g
                    .pull(o, Context::new(frame))
                    .unwrap_or_else(|e| panic!("{name}: {e}"));
                if let Some(p) = v.get::<String>() {
                    assert!(
                        std::path::Path::new(p).exists(),
                        "{name}: output {o} names {p}, which was not written"
                    );
                }
                let finite = match (v.get::<f64>(), v.get::<[f64; 3]>(), v.get::<Vec<f64>>()) {
                    (Some(x), _, _) => x.is_finite(),
                    (_, Some(a), _) => a.iter().all(|x| x.is_finite()),
                    (_, _, Some(l)) => l.iter().all(|x| x.is_finite()),
                    _ => true,
                };
                assert!(finite, "{name}: output {o} at frame {frame} is not finite");
            }
        }
    }
    assert!(count >= 6, "expected the example graphs, found {count}");
}

/// Implicit Euler for y' = -λy³ with the same Newton iteration and tolerance as the graph.
fn implicit_euler_reference(h: f64, lambda: f64, y0: f64, steps: usize) -> f64 {
    let mut y = y0;
    for _ in 0..steps {
        let prev = y;
        let mut x = prev;
        for _ in 0..100 {
            let r = x + h * lambda * x.powi(3) - prev;
            if r.abs() < 1e-14 {
                break;
            }
            x -= r / (1.0 + 3.0 * h * lambda * x * x);
        }
        y = x;
    }
    y
}

#[test]
fn stiff_newton_composite_matches_independent_solver_and_converges_first_order() {
    let exact = |t: f64| 1.0 / (1.0 + 2.0 * 50.0 * t).sqrt();
    let mut errors = Vec::new();
    for fps in [24.0, 48.0, 96.0] {
        let mut g = example("stiff_newton.json");
        let frames = fps as i64; // t = 1 s
        let y = f64_at_fps(&mut g, "y", frames, fps);
        // Both solve the same equation to a residual below 1e-12; the step map contracts
        // (dy_n+1/dy_n = 1/(1 + 3hλy²) < 1), so differences stay at the 1e-12 level.
        let reference = implicit_euler_reference(1.0 / fps, 50.0, 1.0, frames as usize);
        assert!(
            (y - reference).abs() < 1e-11,
            "fps {fps}: {y} vs {reference}"
        );
        let r = f64_at_fps(&mut g, "residual", frames, fps);
        assert!(r.abs() < 1e-12, "converged residual {r}");
        errors.push((y - exact(1.0)).abs());
    }
    // Implicit Euler is first order: halving h halves the error (asymptotically).
    for w in errors.windows(2) {
        let ratio = w[0] / w[1];
        assert!(
            (1.6..2.4).contains(&ratio),
            "error ratio {ratio} for halved h; errors {errors:?}"
        );
    }
}

#[test]
fn oscillator_rk4_is_fourth_order_and_symplectic_energy_stays_bounded() {
    let mut g = example("oscillator.json");
    // At a zero crossing (t = 0.25 s, frame 6) the error is the phase error, O(h⁴) for RK4.
    // (At a peak only the amplitude error shows: RK4's |R| = 1 − (ωh)⁶/144 per step gives
    // O(h⁵), a ratio of 32, which the second check confirms.)
    let e4 = f64_at(&mut g, "error_rk4", 6).abs();
    let p4 = f64_at(&mut g, "error_rk4", 24).abs();
    assert!(
        e4 < 1e-6 && p4 < 1e-6,
        "RK4 errors with h = 1/96 s: {e4}, {p4}"
    );
    g.set_param("rk4", "substeps", serde_json::json!(8))
        .unwrap();
    let e8 = f64_at(&mut g, "error_rk4", 6).abs();
    let p8 = f64_at(&mut g, "error_rk4", 24).abs();
    let ratio = e4 / e8;
    assert!(
        (13.0..19.0).contains(&ratio),
        "halving h should divide the RK4 phase error by 16, got {ratio}"
    );
    let ratio = p4 / p8;
    assert!(
        (26.0..38.0).contains(&ratio),
        "halving h should divide the RK4 amplitude error by 32, got {ratio}"
    );
    // Symplectic Euler has no energy drift: over 10 periods the energy error stays within
    // its O(ωh) oscillation (ωh = 2π/96 ≈ 0.065, relative amplitude ≈ 0.034).
    let e0 = f64_at(&mut g, "energy_symplectic", 0);
    let dev = |g: &mut weft::graph::Graph, frames: std::ops::Range<i64>| {
        frames
            .map(|f| (f64_at(g, "energy_symplectic", f) - e0).abs() / e0)
            .fold(0.0, f64::max)
    };
    let first = dev(&mut g, 0..24);
    let last = dev(&mut g, 216..240);
    assert!(
        first < 0.05 && last < 0.05,
        "energy deviation {first} then {last}"
    );
    assert!(
        last < 1.1 * first,
        "energy error grew from {first} to {last}"
    );
}

#[test]
fn static_hypot_graph_is_exact() {
    let mut g = example("hypot_static.json");
    assert_eq!(f64_at(&mut g, "hyp1", 0), 5.0);
    assert_eq!(f64_at(&mut g, "hyp2", 0), 13.0);
    let l = f64_at(&mut g, "length", 0);
    assert!((l - 194f64.sqrt()).abs() < 1e-15 * 14.0);
    assert!(g.is_static());
    // A static graph evaluates once, whatever frames are asked for.
    for f in 1..10 {
        f64_at(&mut g, "length", f);
    }
    assert_eq!(g.evaluations("len"), 1);
}

#[test]
fn decay_rk4_error_is_fourth_order() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = example("decay_disk_cache.json");
    g.set_param(
        "disk",
        "path",
        serde_json::json!(dir.path().to_str().unwrap()),
    )
    .unwrap();
    let exact = (-2.0f64).exp();
    let e1 = (f64_at(&mut g, "y", 24) - exact).abs();
    assert!(e1 / exact < 1e-6, "relative error {}", e1 / exact);
    g.set_param("decay", "substeps", serde_json::json!(2))
        .unwrap();
    let e2 = (f64_at(&mut g, "y", 24) - exact).abs();
    assert!((13.0..19.0).contains(&(e1 / e2)), "ratio {}", e1 / e2);
}

//! `weft bench solid`: the cloth and hair solver's cost.
//!
//! Hanging cloth (a horizontal square grid pinned at two corners, falling under gravity) at
//! several resolutions and a set of strands rooted on a sphere, each stepped for a fixed number
//! of frames (one step per frame, Newton to 1e-4 m/s as in the examples). Reports milliseconds
//! per step, Newton iterations per step, the split
//! between assembly, factorization and triangular solves (with the one-ring preconditioner's
//! conjugate gradients, counted per step), and the time per Newton iteration
//! against vertex count with the fitted exponent.

use crate::row::Row;
use std::sync::Arc;
use std::time::Instant;
use weft_scene::procedural::{Plane, grid, strands_on_sphere};
use weft_scene::{Attachment, AttachmentMode, ElementKind, Geometry, SceneElement};
use weft_sim::{
    AttachmentBehavior, BehaviorTree, DiscreteShellMaterial, Gravity, RodMaterial, SolidStepper,
    StepperSettings, compile,
};
use weft_solid::Settings;

struct Measured {
    vertices: usize,
    ms_per_step: f64,
    iterations_per_step: f64,
    assembly: f64,
    factor: f64,
    solve: f64,
    cg_per_step: f64,
}

fn run(scene: Vec<SceneElement>, frames: i64) -> Result<Measured, String> {
    let tree = BehaviorTree {
        behaviors: vec![
            Arc::new(DiscreteShellMaterial),
            Arc::new(RodMaterial),
            Arc::new(Gravity {
                acceleration: [0.0, -9.81, 0.0],
            }),
            Arc::new(AttachmentBehavior),
        ],
    };
    let compiled = Arc::new(compile(&scene, &tree).map_err(|e| e.to_string())?);
    let vertices = compiled.state.x.len();
    let mut stepper = SolidStepper::new(compiled, one_step_a_frame()).map_err(|e| e.to_string())?;
    let mut state = stepper.initial_state(&scene);
    let (mut steps, mut its, mut asm, mut fac, mut sol) = (0usize, 0usize, 0.0, 0.0, 0.0);
    let mut cg = 0usize;
    let t = Instant::now();
    for f in 1..=frames {
        let (next, s) = stepper
            .advance(&state, &scene, f, 1.0 / 24.0)
            .map_err(|e| e.to_string())?;
        state = next;
        steps += s.steps;
        its += s.newton_iterations;
        asm += s.linear.assembly_seconds;
        fac += s.linear.factor_seconds;
        sol += s.linear.solve_seconds;
        cg += s.linear.cg_iterations;
    }
    let total = t.elapsed().as_secs_f64();
    Ok(Measured {
        vertices,
        ms_per_step: total * 1e3 / steps as f64,
        iterations_per_step: its as f64 / steps as f64,
        assembly: asm * 1e3 / its as f64,
        factor: fac * 1e3 / its as f64,
        solve: sol * 1e3 / its as f64,
        cg_per_step: cg as f64 / steps as f64,
    })
}

/// The benchmarks' solver settings: one step a frame, Newton (and ADMM) to 1e-4 m/s as in
/// the examples, within the machine's memory.
pub(crate) fn one_step_a_frame() -> StepperSettings {
    StepperSettings {
        substeps: 1,
        max_retries: 4,
        max_bytes: Some(weft_graph::memory::available()),
        contact_iterations: 200,
        solver: Settings {
            tolerance: 1e-4,
            max_iterations: 200,
            ..Settings::default()
        },
        ..StepperSettings::default()
    }
}

fn cloth(n: usize) -> Vec<SceneElement> {
    let c = SceneElement::new(
        "cloth",
        ElementKind::Cloth,
        Geometry::Mesh(grid([1.0, 1.0], [n, n], Plane::Xz, [0.0, 1.0, 0.0])),
    );
    let mut pins = SceneElement::new("pins", ElementKind::Attachment, Geometry::None);
    pins.secs.insert(Attachment {
        target: "cloth".into(),
        vertices: vec![0, n as u32 - 1],
        mode: AttachmentMode::Hard,
        clamps: Vec::new(),
    });
    vec![c, pins]
}

fn hair(count: usize, vertices: usize) -> Vec<SceneElement> {
    let curves = strands_on_sphere([0.0, 1.6, 0.0], 0.1, count, vertices - 1, 0.3, 80.0);
    let roots = Attachment::curve_roots("hair", &curves, 2, AttachmentMode::Hard);
    let h = SceneElement::new("hair", ElementKind::Hair, Geometry::Curves(curves));
    let mut pins = SceneElement::new("roots", ElementKind::Attachment, Geometry::None);
    pins.secs.insert(roots);
    vec![h, pins]
}

pub(crate) fn suite(quick: bool) -> Result<Vec<Row>, String> {
    let sizes: &[usize] = if quick {
        &[16, 32]
    } else {
        &[32, 64, 128, 256, 317]
    };
    let frames = if quick { 2 } else { 6 };
    let mut rows = Vec::new();
    let mut fit = Vec::new();
    let push = |rows: &mut Vec<Row>, name: String, m: &Measured| {
        rows.push(Row {
            case: format!("{name}: ms per step"),
            nodes: m.vertices,
            value: m.ms_per_step,
            unit: "ms",
            target: "",
        });
        rows.push(Row {
            case: format!("{name}: Newton iterations per step"),
            nodes: m.vertices,
            value: m.iterations_per_step,
            unit: "",
            target: "",
        });
        rows.push(Row {
            case: format!("{name}: per iteration, assembly"),
            nodes: m.vertices,
            value: m.assembly,
            unit: "ms",
            target: "",
        });
        rows.push(Row {
            case: format!("{name}: per iteration, factorization"),
            nodes: m.vertices,
            value: m.factor,
            unit: "ms",
            target: "",
        });
        rows.push(Row {
            case: format!("{name}: per iteration, solve (and CG)"),
            nodes: m.vertices,
            value: m.solve,
            unit: "ms",
            target: "",
        });
        // The one-ring preconditioner's conjugate gradients (0 where H is factored: its
        // bound on the dropped stiffness against the inertia declined it, or no wide
        // elements).
        rows.push(Row {
            case: format!("{name}: CG iterations per step"),
            nodes: m.vertices,
            value: m.cg_per_step,
            unit: "",
            target: "",
        });
    };
    for &n in sizes {
        // The largest (317² ≈ 100k vertices) runs fewer frames: ~1 min per step.
        let m = run(cloth(n), if n > 256 { 2 } else { frames })?;
        fit.push((
            (m.vertices as f64).ln(),
            (m.assembly + m.factor + m.solve).ln(),
        ));
        push(&mut rows, format!("hanging cloth {n}×{n}"), &m);
    }
    // Thread scaling: the same cloth on 1 and 2 threads (bit-identical results; assembly and
    // the line search's energy sums run in parallel, the factorization does not).
    let n = if quick { 32 } else { 128 };
    let mut per_thread = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| e.to_string())?;
        let m = pool.install(|| run(cloth(n), frames))?;
        rows.push(Row {
            case: format!("hanging cloth {n}×{n} on {threads} thread(s): ms per step"),
            nodes: m.vertices,
            value: m.ms_per_step,
            unit: "ms",
            target: "",
        });
        rows.push(Row {
            case: format!("hanging cloth {n}×{n} on {threads} thread(s): assembly per iteration"),
            nodes: m.vertices,
            value: m.assembly,
            unit: "ms",
            target: "",
        });
        per_thread.push(m.ms_per_step);
    }
    rows.push(Row {
        case: format!("hanging cloth {n}×{n}: speedup 1 → 2 threads"),
        nodes: 0,
        value: per_thread[0] / per_thread[1],
        unit: "×",
        target: "",
    });
    let (count, len) = if quick { (100, 32) } else { (1000, 32) };
    let m = run(hair(count, len), frames)?;
    push(&mut rows, format!("hair {count} strands × {len}"), &m);
    // Least-squares slope of log(time per iteration) against log(vertices).
    let k = fit.len() as f64;
    let (sx, sy) = fit.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / k, sy / k);
    let (num, den) = fit.iter().fold((0.0, 0.0), |(a, b), (x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
    });
    rows.push(Row {
        case: "time per Newton iteration ∝ vertices^p, fitted p (cloth)".into(),
        nodes: 0,
        value: num / den,
        unit: "",
        target: "≤ 1.2", // issue 16's goal
    });
    Ok(rows)
}

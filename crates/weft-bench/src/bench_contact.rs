//! `weft bench contact`: what contacts with colliders cost (issue 13's benchmark).
//!
//! The drape: a 1 m square cloth (n × n vertices, 0.15 kg/m²) falling at 0.5 m/s onto a
//! sphere of radius 0.3 m (48 × 96 facets) from 5 mm above its top, μ 0.4, 1 mm thickness
//! each side, one step a frame at 24 fps, Newton and ADMM to 1e-4 m/s (the examples'
//! tolerance). Per step: wall time split into detection (finding contacts and the exact
//! checks), the ADMM loops (their triangular solves, contact projections and refactorizations)
//! and the rest of Newton (assembly, factorization, line search); contacts, ADMM and Newton
//! iterations per step. The goal is contact handling (detection + ADMM) at most half of a step.
//!
//! The incline sweep (VERIFY's incline as a chart): a 0.1 m cloth patch on a plane with
//! friction μ = 0.5 under gravity tilted by θ from 10° to 40° (finer around atan μ =
//! 26.57°), 4 steps a frame for 1 s, Newton and ADMM to 1e-11 m/s. Implicit Euler's velocity
//! under a constant net force is exactly a t, so the patch's velocity after 1 s is its
//! acceleration, charted against Coulomb's a = g max(0, sin θ − μ cos θ) into
//! `OUT/contact_incline.{png,svg,csv}`. Checked (exit 1 with `--quick` when one fails):
//! stuck angles creep below 1e-9 m, sliding ones are within 1 % of Coulomb, and the first
//! sliding angle is within 0.5° of atan μ.

use crate::row::Row;
use crate::sweep::Checks;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;
use weft_scene::procedural::{Plane, grid, sphere};
use weft_scene::{Channel, Collider, CollisionGroup, ElementKind, Geometry, SceneElement};
use weft_sim::{
    BehaviorTree, Collision, DiscreteShellMaterial, Gravity, SolidStepper, StepperSettings, compile,
};
use weft_solid::Settings;

/// Every side of the drape and the rotating sphere: μ 0.4, 1 mm thickness.
const SIDE: Collider = Collider {
    friction: 0.4,
    thickness: 1e-3,
    cohesion: 0.0,
};

fn drape(n: usize) -> Vec<SceneElement> {
    let mut cloth = SceneElement::new(
        "cloth",
        ElementKind::Cloth,
        Geometry::Mesh(grid([1.0, 1.0], [n, n], Plane::Xz, [0.0, 0.307, 0.0])),
    );
    cloth.secs.insert(SIDE);
    let count = cloth.vertex_count();
    cloth.set_channel(
        "velocity",
        Channel::Vec3(vec![[0.0, -0.5, 0.0]; count].into()),
    );
    let mut ball = SceneElement::new(
        "ball",
        ElementKind::Collider,
        Geometry::Mesh(sphere([0.0; 3], 0.3, 48, 96)),
    );
    ball.secs.insert(SIDE);
    let mut group = SceneElement::new("contacts", ElementKind::Collision, Geometry::None);
    group.secs.insert(CollisionGroup::default());
    vec![cloth, ball, group]
}

/// The rotating sphere (the contact literature's standard self-collision scene): a 1 m
/// square cloth (n × n vertices) 5 mm above a sphere of radius 0.3 m (48 × 96 facets)
/// resting on a floor, μ 0.4 on every side, 1 mm thickness each side, self-collision on. The
/// sphere turns about the vertical at 180°/s (`spin`), so friction winds the cloth around it
/// and its folds land on each other and on the floor.
fn twist(n: usize) -> Vec<SceneElement> {
    let mut scene = drape(n);
    scene[2].secs.insert(CollisionGroup {
        self_collision: true,
        ..CollisionGroup::default()
    });
    let mut floor = SceneElement::new(
        "floor",
        ElementKind::Collider,
        Geometry::Mesh(grid([3.0, 3.0], [2, 2], Plane::Xz, [0.0, -0.3, 0.0])),
    );
    floor.secs.insert(SIDE);
    scene.insert(2, floor);
    scene
}

/// The sphere's turn at `frame` (24 fps, 180°/s about y).
fn spin(frame: i64) -> weft_scene::Transform {
    let angle = std::f64::consts::PI * frame as f64 / 24.0;
    nalgebra::Isometry3::rotation(nalgebra::Vector3::y() * angle)
}

#[derive(Default)]
struct Measured {
    vertices: usize,
    steps: usize,
    seconds: f64,
    detection: f64,
    /// Of `detection`, between solids: broad phase, narrow phase, continuous detection.
    broad: f64,
    narrow: f64,
    ccd: f64,
    admm: f64,
    contacts: usize,
    max_contacts: usize,
    admm_iterations: usize,
    newton_iterations: usize,
    crossing_retries: usize,
    cut_backs: usize,
    max_penetration: f64,
}

/// Cloth material, `gravity` and collisions.
fn tree(gravity: [f64; 3]) -> BehaviorTree {
    BehaviorTree {
        behaviors: vec![
            Arc::new(DiscreteShellMaterial),
            Arc::new(Gravity {
                acceleration: gravity,
            }),
            Arc::new(Collision),
        ],
    }
}

/// `frames` frames of `scene` (`label` for progress), one step a frame at 24 fps; with
/// `turning`, that element turns as [`spin`] says.
fn run(
    label: &str,
    mut scene: Vec<SceneElement>,
    frames: i64,
    turning: Option<usize>,
) -> Result<Measured, String> {
    let compiled = Arc::new(compile(&scene, &tree([0.0, -9.81, 0.0])).map_err(|e| e.to_string())?);
    let settings = crate::bench_solid::one_step_a_frame();
    let mut stepper = SolidStepper::new(compiled.clone(), settings).map_err(|e| e.to_string())?;
    let mut state = stepper.initial_state(&scene);
    let mut m = Measured {
        vertices: compiled.state.x.len(),
        ..Measured::default()
    };
    let t = Instant::now();
    for f in 1..=frames {
        if let Some(k) = turning {
            scene[k].transform = Some(spin(f));
        }
        let (next, s) = stepper
            .advance(&state, &scene, f, 1.0 / 24.0)
            .map_err(|e| format!("{label}: {e}"))?;
        state = next;
        m.steps += s.steps;
        m.newton_iterations += s.newton_iterations;
        let c = s.contacts.unwrap_or_default();
        // Progress (stderr): the largest scenes take minutes a step.
        eprintln!(
            "{label} frame {f}: {:.1} s so far; {} steps, {} contacts (at most {}), {} Newton and {} ADMM iterations, ADMM {:.1} s, detection {:.2} s (broad {:.2}, narrow {:.2}, CCD {:.2}), {} crossing retries, {} cut-backs",
            t.elapsed().as_secs_f64(),
            s.steps,
            c.contacts,
            c.max_contacts,
            s.newton_iterations,
            c.admm_iterations,
            c.admm_seconds,
            c.detection_seconds,
            c.broad_seconds,
            c.narrow_seconds,
            c.ccd_seconds,
            c.crossing_retries,
            c.cut_backs,
        );
        m.detection += c.detection_seconds;
        m.broad += c.broad_seconds;
        m.narrow += c.narrow_seconds;
        m.ccd += c.ccd_seconds;
        m.admm += c.admm_seconds;
        m.contacts += c.contacts;
        m.max_contacts = m.max_contacts.max(c.max_contacts);
        m.admm_iterations += c.admm_iterations;
        m.crossing_retries += c.crossing_retries;
        m.cut_backs += c.cut_backs;
        m.max_penetration = m.max_penetration.max(c.max_penetration);
    }
    m.seconds = t.elapsed().as_secs_f64();
    Ok(m)
}

/// The patch on the incline at θ [°] with friction `mu`: (its velocity along the slope after
/// 1 s [m/s], the largest displacement along it [m]). Gravity tilted by θ about z is the
/// plane y = 0 tilted by θ; the patch lies on it, both thicknesses (2 mm) up.
fn incline(theta_deg: f64, mu: f64) -> Result<(f64, f64), String> {
    let side = Collider {
        friction: mu,
        thickness: 1e-3,
        cohesion: 0.0,
    };
    let mut patch = SceneElement::new(
        "patch",
        ElementKind::Cloth,
        Geometry::Mesh(grid([0.1, 0.1], [3, 3], Plane::Xz, [0.0, 2e-3, 0.0])),
    );
    patch.secs.insert(side.clone());
    let mut plane = SceneElement::new(
        "plane",
        ElementKind::Collider,
        Geometry::Mesh(grid([4.0, 4.0], [2, 2], Plane::Xz, [0.0; 3])),
    );
    plane.secs.insert(side);
    let mut group = SceneElement::new("contacts", ElementKind::Collision, Geometry::None);
    group.secs.insert(CollisionGroup::default());
    let scene = vec![patch, plane, group];
    let th = theta_deg.to_radians();
    let gravity = [9.81 * th.sin(), -9.81 * th.cos(), 0.0];
    let compiled = Arc::new(compile(&scene, &tree(gravity)).map_err(|e| e.to_string())?);
    let settings = StepperSettings {
        substeps: 4,
        contact_iterations: 2000,
        solver: Settings {
            tolerance: 1e-11,
            max_iterations: 50,
            ..Settings::default()
        },
        ..StepperSettings::default()
    };
    let mut stepper = SolidStepper::new(compiled, settings).map_err(|e| e.to_string())?;
    let mut state = stepper.initial_state(&scene);
    let x0 = state.solid.x.clone();
    for f in 1..=24 {
        state = stepper
            .advance(&state, &scene, f, 1.0 / 24.0)
            .map_err(|e| format!("incline {theta_deg}°: {e}"))?
            .0;
    }
    let n = state.solid.v.len() as f64;
    let v = state.solid.v.iter().map(|v| v.x).sum::<f64>() / n;
    let slide = state
        .solid
        .x
        .iter()
        .zip(&x0)
        .fold(0.0f64, |m, (a, b)| m.max((a.x - b.x).abs()));
    Ok((v, slide))
}

/// The incline sweep (module doc): its rows, its checks, and its chart and CSV in `out`.
fn incline_sweep(quick: bool, out: &Path) -> Result<(Vec<Row>, Checks), String> {
    let mu: f64 = 0.5;
    let threshold = mu.atan().to_degrees();
    let angles: Vec<f64> = if quick {
        vec![20.0, 26.1, 27.0, 35.0]
    } else {
        let mut a: Vec<f64> = (0..=12).map(|k| 10.0 + 2.5 * k as f64).collect();
        a.extend([26.0, 26.25, 26.5, 26.75, 27.0]);
        a.sort_by(f64::total_cmp);
        a
    };
    let coulomb = |theta: f64| {
        let th = theta.to_radians();
        (9.81 * (th.sin() - mu * th.cos())).max(0.0)
    };
    let mut measured = Vec::new();
    let mut csv = String::from("theta_deg,acceleration_m_s2,coulomb_m_s2,slide_m\n");
    let (mut creep, mut slip_error) = (0.0f64, 0.0f64);
    let mut first_slide = f64::INFINITY;
    for &theta in &angles {
        let (a, slide) = incline(theta, mu)?;
        let want = coulomb(theta);
        csv += &format!("{theta},{a:e},{want:e},{slide:e}\n");
        if want == 0.0 {
            creep = creep.max(slide);
        } else {
            slip_error = slip_error.max((a / want - 1.0).abs());
        }
        if slide > 1e-6 {
            first_slide = first_slide.min(theta);
        }
        measured.push((theta, a));
    }
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    weft_graph::atomic_write(&out.join("contact_incline.csv"), csv.as_bytes())
        .map_err(|e| e.to_string())?;
    let curve: Vec<(f64, f64)> = (0..=300)
        .map(|k| 10.0 + 30.0 * k as f64 / 300.0)
        .map(|t| (t, coulomb(t)))
        .collect();
    crate::charts::incline(&measured, &curve, mu, &out.join("contact_incline"))?;
    let checks = vec![
        (
            format!("incline: stuck angles creep {creep:.1e} m < 1e-9 m"),
            creep < 1e-9,
        ),
        (
            format!(
                "incline: sliding within {:.3} % of Coulomb (< 1 %)",
                100.0 * slip_error
            ),
            slip_error < 0.01,
        ),
        (
            format!(
                "incline: first sliding angle {first_slide}° vs atan μ = {threshold:.2}° (within 0.5°)"
            ),
            (first_slide - threshold).abs() < 0.5,
        ),
    ];
    let rows = vec![
        Row {
            case: "incline μ 0.5: largest creep where Coulomb sticks".into(),
            nodes: angles.len(),
            value: creep * 1e9,
            unit: "nm",
            target: "< 1 nm",
        },
        Row {
            case: "incline μ 0.5: largest sliding error against Coulomb".into(),
            nodes: angles.len(),
            value: 100.0 * slip_error,
            unit: "%",
            target: "< 1 %",
        },
        Row {
            case: "incline μ 0.5: first sliding angle − atan μ".into(),
            nodes: angles.len(),
            value: first_slide - threshold,
            unit: "°",
            target: "|·| < 0.5°",
        },
    ];
    Ok((rows, checks))
}

/// The suite: the incline sweep (rows, checks, chart in `out`), the drape's and the rotating
/// sphere's costs.
pub(crate) fn suite(quick: bool, out: &Path) -> Result<(Vec<Row>, Checks), String> {
    let (mut rows, checks) = incline_sweep(quick, out)?;
    // (n, frames): the larger scenes take minutes a step, so they run fewer frames.
    let drapes: &[(usize, i64)] = if quick {
        &[(16, 2), (32, 2)]
    } else {
        &[(64, 4), (128, 2), (256, 1)]
    };
    for &(n, frames) in drapes {
        let label = format!("drape {n}×{n}");
        rows.extend(cost_rows(&label, &run(&label, drape(n), frames, None)?));
    }
    // `WEFT_TWIST="n:frames,…"` picks the rotating sphere's sizes. The default is what this
    // machine can run in an hour (the 100 frames at 10k, 40k and 85k vertices take
    // days today: a 10k frame takes 9 min).
    let twists: Vec<(usize, i64)> = match std::env::var("WEFT_TWIST") {
        Ok(list) => list
            .split(',')
            .map(|p| {
                let (n, f) = p.split_once(':').unwrap_or((p, "100"));
                Ok((
                    n.trim()
                        .parse()
                        .map_err(|_| format!("WEFT_TWIST: bad size in '{p}'"))?,
                    f.trim()
                        .parse()
                        .map_err(|_| format!("WEFT_TWIST: bad frame count in '{p}'"))?,
                ))
            })
            .collect::<Result<_, String>>()?,
        Err(_) if quick => vec![(16, 6)],
        Err(_) => vec![(32, 100), (100, 2)],
    };
    for (n, frames) in twists {
        let label = format!("rotating sphere {n}×{n}");
        // The sphere is the scene's second element.
        rows.extend(cost_rows(&label, &run(&label, twist(n), frames, Some(1))?));
    }
    Ok((rows, checks))
}

/// A measured run's rows: time per step and its split, contacts and iterations per step.
fn cost_rows(name: &str, m: &Measured) -> Vec<Row> {
    let steps = m.steps.max(1) as f64;
    let ms = |s: f64| s * 1e3 / steps;
    let mut rows = Vec::new();
    let mut push = |what: &str, value: f64, unit: &'static str, target: &'static str| {
        rows.push(Row {
            case: format!("{name}: {what}"),
            nodes: m.vertices,
            value,
            unit,
            target,
        })
    };
    push("steps", m.steps as f64, "", "");
    push("ms per step", ms(m.seconds), "ms", "");
    push("  detection", ms(m.detection), "ms", "");
    push("    solids: broad phase", ms(m.broad), "ms", "");
    push("    solids: narrow phase", ms(m.narrow), "ms", "");
    push("    solids: CCD", ms(m.ccd), "ms", "");
    push("  ADMM", ms(m.admm), "ms", "");
    push(
        "  rest of Newton",
        ms(m.seconds - m.detection - m.admm),
        "ms",
        "",
    );
    push(
        "contact share of step",
        100.0 * (m.detection + m.admm) / m.seconds,
        "%",
        "≤ 50 %",
    );
    push(
        "solid-solid detection share of step",
        100.0 * (m.broad + m.narrow + m.ccd) / m.seconds,
        "%",
        "< 20 %",
    );
    push("contacts per step", m.contacts as f64 / steps, "", "");
    push("most contacts in a step", m.max_contacts as f64, "", "");
    push(
        "Newton iterations per step",
        m.newton_iterations as f64 / steps,
        "",
        "",
    );
    push(
        "ADMM iterations per step",
        m.admm_iterations as f64 / steps,
        "",
        "",
    );
    push("crossing retries", m.crossing_retries as f64, "", "");
    push("cut-backs", m.cut_backs as f64, "", "");
    push("largest penetration", m.max_penetration * 1e3, "mm", "");
    // Each run's rows as soon as they are measured (stderr), before the table.
    for r in &rows {
        eprintln!(
            "| {} | {} | {:.3} | {} | {} |",
            r.case, r.nodes, r.value, r.unit, r.target
        );
    }
    rows
}

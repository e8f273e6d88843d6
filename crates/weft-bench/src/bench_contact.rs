//! `weft bench contact`: what contacts with colliders cost (issue 13's benchmark).
//!
//! The drape: a 1 m square cloth (n × n vertices, 0.15 kg/m²) falling at 0.5 m/s onto a
//! sphere of radius 0.3 m (48 × 96 facets) from 5 mm above its top, μ 0.4, 1 mm thickness
//! each side, one step a frame at 24 fps, Newton and ADMM to 1e-4 m/s (the examples'
//! tolerance). Per step: wall time split into detection (finding contacts and the exact
//! checks), the ADMM loops (their triangular solves, contact projections and refactorizations)
//! and the rest of Newton (assembly, factorization, line search); contacts, ADMM and Newton
//! iterations per step. The goal is contact handling (detection + ADMM) at most half of a step.

use crate::row::Row;
use std::sync::Arc;
use std::time::Instant;
use weft_scene::procedural::{Plane, grid, sphere};
use weft_scene::{Channel, Collider, CollisionGroup, ElementKind, Geometry, SceneElement};
use weft_sim::{BehaviorTree, Collision, DiscreteShellMaterial, Gravity, SolidStepper, compile};

fn drape(n: usize) -> Vec<SceneElement> {
    let friction = Collider {
        friction: 0.4,
        thickness: 1e-3,
        cohesion: 0.0,
    };
    let mut cloth = SceneElement::new(
        "cloth",
        ElementKind::Cloth,
        Geometry::Mesh(grid([1.0, 1.0], [n, n], Plane::Xz, [0.0, 0.307, 0.0])),
    );
    cloth.secs.insert(friction.clone());
    let count = cloth.vertex_count();
    cloth.set_channel("velocity", Channel::Vec3(vec![[0.0, -0.5, 0.0]; count]));
    let mut ball = SceneElement::new(
        "ball",
        ElementKind::Collider,
        Geometry::Mesh(sphere([0.0; 3], 0.3, 48, 96)),
    );
    ball.secs.insert(friction);
    let mut group = SceneElement::new("contacts", ElementKind::Collision, Geometry::None);
    group.secs.insert(CollisionGroup::default());
    vec![cloth, ball, group]
}

struct Measured {
    vertices: usize,
    steps: usize,
    seconds: f64,
    detection: f64,
    admm: f64,
    contacts: usize,
    admm_iterations: usize,
    newton_iterations: usize,
}

fn run(n: usize, frames: i64) -> Result<Measured, String> {
    let scene = drape(n);
    let tree = BehaviorTree {
        behaviors: vec![
            Arc::new(DiscreteShellMaterial),
            Arc::new(Gravity {
                acceleration: [0.0, -9.81, 0.0],
            }),
            Arc::new(Collision),
        ],
    };
    let compiled = Arc::new(compile(&scene, &tree).map_err(|e| e.to_string())?);
    let vertices = compiled.state.x.len();
    let settings = crate::bench_solid::one_step_a_frame();
    let mut stepper = SolidStepper::new(compiled, settings).map_err(|e| e.to_string())?;
    let mut state = stepper.initial_state(&scene);
    let mut m = Measured {
        vertices,
        steps: 0,
        seconds: 0.0,
        detection: 0.0,
        admm: 0.0,
        contacts: 0,
        admm_iterations: 0,
        newton_iterations: 0,
    };
    let t = Instant::now();
    for f in 1..=frames {
        let (next, s) = stepper
            .advance(&state, &scene, f, 1.0 / 24.0)
            .map_err(|e| format!("{n}×{n}: {e}"))?;
        state = next;
        m.steps += s.steps;
        m.newton_iterations += s.newton_iterations;
        let c = s.contacts.unwrap_or_default();
        m.detection += c.detection_seconds;
        m.admm += c.admm_seconds;
        m.contacts += c.contacts;
        m.admm_iterations += c.admm_iterations;
    }
    m.seconds = t.elapsed().as_secs_f64();
    Ok(m)
}

pub(crate) fn suite(quick: bool) -> Result<Vec<Row>, String> {
    let sizes: &[usize] = if quick { &[16, 32] } else { &[64, 128, 256] };
    let frames = if quick { 2 } else { 4 };
    let mut rows = Vec::new();
    for &n in sizes {
        let m = run(n, frames)?;
        let steps = m.steps as f64;
        let ms = |s: f64| s * 1e3 / steps;
        let name = format!("drape {n}×{n}");
        let mut push = |what: &str, value: f64, unit: &'static str, target: &'static str| {
            rows.push(Row {
                case: format!("{name}: {what}"),
                nodes: m.vertices,
                value,
                unit,
                target,
            })
        };
        push("ms per step", ms(m.seconds), "ms", "");
        push("  detection", ms(m.detection), "ms", "");
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
        push("contacts per step", m.contacts as f64 / steps, "", "");
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
    }
    Ok(rows)
}

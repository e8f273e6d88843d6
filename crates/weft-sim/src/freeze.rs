//! Freeze: vertices blended between simulated and their animated input (Nucleus's input
//! attract and "freeze", Vellum's pin to animation).
//!
//! A freeze attachment (`AttachmentMode::Freeze`) lists vertices of a simulated element; the
//! element's *input* (its geometry in the scene the solver reads at each frame, animated
//! upstream) is where they are drawn to. Its weight w (read at every frame, so it can be
//! keyed) times a per-vertex factor ([`weft_scene::FreezeWeights`]) decides how:
//! - **w ≥ 1**: the vertex is held exactly at its input (a point target of the sliders'
//!   machinery, `weft_solid::SlideOn::Point`: its rows are filtered out and every trial point
//!   retracted onto it, so holding and releasing never changes the matrix's pattern);
//! - **0 < w < 1**: a zero-length spring of stiffness k = w/(1 − w)·m/Δt² (m the vertex's
//!   mass, Δt the frame time) pulls it to its input: a property of the physical system, not of
//!   the substeps, and proportional to mass, so the same weight does the same on a fine or a
//!   coarse mesh (a vertex hanging from it sits g Δt² (1 − w)/w below its input);
//! - **w = 0**: free.
//!
//! Within a frame the inputs are interpolated linearly from their positions at the frame's
//! start (kept in [`crate::SimState::inputs`]) to the frame's, at each substep's end time, so
//! a held vertex moves with the input's velocity and, released, keeps it.

use crate::error::SimError;
use nalgebra::Vector3;
use weft_scene::{Attachment, AttachmentMode, SceneElement};
use weft_solid::{SlideOn, Slider, SolidSystem};

/// A frozen vertex and where its input and weight come from.
#[derive(Clone, Debug, PartialEq)]
pub struct FreezePin {
    /// Global vertex index.
    pub vertex: usize,
    /// Scene index of the element whose input it follows (the element it belongs to).
    pub element: usize,
    /// Its index within that element.
    pub index: usize,
    /// Scene index of the freeze attachment element (its weight, read at every frame).
    pub attachment: usize,
    /// The per-vertex factor on the attachment's weight (≥ 0).
    pub factor: f64,
    /// Index of its spring in `system.elements.springs` (stiffness 0 unless 0 < w < 1).
    pub spring: usize,
}

/// One frame of the frozen vertices: their inputs at the frame's start and end, and weights.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FreezeFrame {
    /// Input positions at the frame's start (one per [`FreezePin`]).
    pub start: Vec<Vector3<f64>>,
    /// Input positions at the frame.
    pub end: Vec<Vector3<f64>>,
    /// Weights w · factor over the frame (≥ 0).
    pub weight: Vec<f64>,
    /// The frame's length [s].
    pub frame_dt: f64,
}

/// Each frozen vertex's input position in `scene` (checked by `Compiled::check_scene` first:
/// the elements have the vertex counts they were compiled with).
pub fn inputs(freezes: &[FreezePin], scene: &[SceneElement]) -> Vec<Vector3<f64>> {
    freezes
        .iter()
        .map(|f| {
            let p = scene
                .get(f.element)
                .and_then(|e| e.geometry.positions().get(f.index).copied())
                .unwrap_or([f64::NAN; 3]);
            Vector3::from(p)
        })
        .collect()
}

/// The frozen vertices' frame to `scene` (the scene at `frame`) from their inputs at the
/// previous frame, `start`; refuses a weight that is not a number ≥ 0 and an input that
/// is not finite, naming the attachment and the frame.
pub fn frame(
    freezes: &[FreezePin],
    scene: &[SceneElement],
    start: &[Vector3<f64>],
    frame: i64,
    frame_dt: f64,
) -> Result<FreezeFrame, SimError> {
    if freezes.is_empty() {
        return Ok(FreezeFrame {
            frame_dt,
            ..Default::default()
        });
    }
    if start.len() != freezes.len() {
        return Err(SimError::SceneChanged(format!(
            "frame {frame}: the state holds {} frozen inputs but the scene has {} frozen vertices",
            start.len(),
            freezes.len()
        )));
    }
    let end = inputs(freezes, scene);
    let mut weight = Vec::with_capacity(end.len());
    let mut last: Option<(usize, f64)> = None;
    for (f, p) in freezes.iter().zip(&end) {
        let a = &scene[f.attachment];
        let fail = |message: String| SimError::BadAttachment {
            attachment: a.name.clone(),
            message: format!("frame {frame}: {message}"),
        };
        let w = match last {
            Some((ai, w)) if ai == f.attachment => w,
            _ => {
                let w = match a.secs.get::<Attachment>().map(|s| s.mode) {
                    Some(AttachmentMode::Freeze { weight }) => weight,
                    _ => {
                        return Err(fail(
                            "it is no longer a freeze attachment (its mode changed during the run)"
                                .into(),
                        ));
                    }
                };
                if !(w >= 0.0 && w.is_finite()) {
                    return Err(fail(format!("the freeze weight must be ≥ 0, got {w}")));
                }
                last = Some((f.attachment, w));
                w
            }
        };
        if !p.iter().all(|c| c.is_finite()) {
            return Err(fail(format!(
                "the input of vertex {} of '{}' is not finite: {p:?}",
                f.index, scene[f.element].name
            )));
        }
        weight.push(w * f.factor);
    }
    Ok(FreezeFrame {
        start: start.to_vec(),
        end,
        weight,
        frame_dt,
    })
}

/// Sets the frozen vertices' targets at fraction `s` of `frame`: held vertices (w ≥ 1)
/// become point sliders after the compiled ones, springs get their stiffness and target.
pub fn set(
    freezes: &[FreezePin],
    base_sliders: usize,
    frame: &FreezeFrame,
    s: f64,
    system: &mut SolidSystem,
) {
    system.sliders.truncate(base_sliders);
    let dt2 = frame.frame_dt * frame.frame_dt;
    for (k, f) in freezes.iter().enumerate() {
        let (a, b, w) = (frame.start[k], frame.end[k], frame.weight[k]);
        // Exact at both ends of the frame: at s = 1 the input's own bits.
        let target = (1.0 - s) * a + s * b;
        let spring = &mut system.elements.springs[f.spring];
        spring.target = target;
        spring.k = if w > 0.0 && w < 1.0 {
            w / (1.0 - w) * system.mass[f.vertex] / dt2
        } else {
            0.0
        };
        if w >= 1.0 {
            system.sliders.push(Slider {
                vertex: f.vertex as u32,
                on: SlideOn::Point(target),
                friction: 0.0,
            });
        }
    }
}

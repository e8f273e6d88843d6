//! Clamped cloth edges: the ghost vertices that hold a cloth's tangent plane along a held
//! boundary edge. A ghost mirrors the edge's triangle across the edge (flat continuation, as
//! the cloth starts); it is a held, massless system vertex outside every element, moved by
//! its attachment's transform like the held vertices, and the shell bending of the triangle
//! and of the held vertices measures the cloth against it
//! (`weft_solid::energy::shell_bending_clamped`). Rods clamp without ghosts (`RodClamp`).

use crate::error::SimError;
use nalgebra::Vector3;
use std::ops::Range;
use weft_scene::{Attachment, ElementKind, Geometry, SceneElement};

/// A ghost vertex behind a clamped cloth edge.
#[derive(Clone, Debug, PartialEq)]
pub struct Ghost {
    /// Scene index of the cloth.
    pub element: usize,
    /// Scene index of the attachment that clamps it.
    pub attachment: usize,
    /// The clamped edge, in the cloth's vertex indices.
    pub edge: [u32; 2],
    /// The edge's triangle's third vertex (the ghost mirrors it), in the cloth's indices.
    pub apex: u32,
    /// The ghost's global vertex index.
    pub vertex: usize,
}

/// `c` mirrored across the line through `a` and `b`.
pub fn mirror(a: Vector3<f64>, b: Vector3<f64>, c: Vector3<f64>) -> Vector3<f64> {
    let d = b - a;
    let foot = a + d * ((c - a).dot(&d) / d.norm_squared());
    2.0 * foot - c
}

/// The ghosts of every attachment's clamps on cloth, numbered from `first` (global), with
/// their start positions (from `x`, the global start positions, and `ranges`). A clamp on
/// cloth names a boundary edge whose two vertices the attachment holds.
pub(crate) fn cloth_ghosts(
    scene: &[SceneElement],
    ranges: &[Option<Range<usize>>],
    x: &[Vector3<f64>],
) -> Result<Vec<(Ghost, Vector3<f64>)>, SimError> {
    let mut out = Vec::new();
    for (ai, a) in scene.iter().enumerate() {
        let Some(att) = a.secs.get::<Attachment>() else {
            continue;
        };
        if att.clamps.is_empty() {
            continue;
        }
        let Some(ti) = scene.iter().position(|e| e.name == att.target) else {
            continue; // the attachment Behavior reports it
        };
        let (ElementKind::Cloth, Geometry::Mesh(mesh), Some(r)) =
            (scene[ti].kind, &*scene[ti].geometry, &ranges[ti])
        else {
            continue;
        };
        let fail = |m: String| SimError::BadAttachment {
            attachment: a.name.clone(),
            message: m,
        };
        let n = scene[ti].vertex_count();
        for &[p, q] in &att.clamps {
            if p == q || p as usize >= n || q as usize >= n {
                return Err(fail(format!(
                    "clamp edge ({p}, {q}) is not an edge of '{}' ({n} vertices)",
                    att.target
                )));
            }
            if !(att.vertices.contains(&p) && att.vertices.contains(&q)) {
                return Err(fail(format!(
                    "clamp edge ({p}, {q}): both its vertices must be attached"
                )));
            }
            let mut tris = mesh
                .triangles
                .iter()
                .filter(|t| t.contains(&p) && t.contains(&q));
            let (Some(t), None) = (tris.next(), tris.next()) else {
                return Err(fail(format!(
                    "clamp edge ({p}, {q}) is not a boundary edge of '{}' (a clamp holds the cloth along its border)",
                    att.target
                )));
            };
            let Some(&apex) = t.iter().find(|&&v| v != p && v != q && (v as usize) < n) else {
                return Err(fail(format!(
                    "clamp edge ({p}, {q}): its triangle {t:?} has no third vertex in '{}'",
                    att.target
                )));
            };
            let g = |v: u32| x[r.start + v as usize];
            let position = mirror(g(p), g(q), g(apex));
            out.push((
                Ghost {
                    element: ti,
                    attachment: ai,
                    edge: [p, q],
                    apex,
                    vertex: 0,
                },
                position,
            ));
        }
    }
    Ok(out)
}

//! The attachment Behavior: every attachment element's vertices follow their target
//! (held, pulled by a spring, sliding on rails or surfaces, frozen, or moved as one rigid
//! group), and its clamps hold a strand's root direction. A vertex is held by at most one
//! attachment; two that list it are refused by name.

use super::Behavior;
use super::params::{checked, rest_positions, rod_section, v3};
use crate::builder::SystemBuilder;
use crate::error::SimError;
use std::collections::BTreeSet;
use weft_scene::{Attachment, AttachmentMode, ElementKind, Geometry, Rod, SceneElement};
use weft_solid::energy::{RodClamp, Spring};

/// Attachments: for every attachment element, its vertices follow their targets (hard: their
/// DOFs are eliminated; spring: a zero-length spring pulls them; slide: they stay on the
/// element's rails, free along them, exactly: see `weft_solid::slide`).
#[derive(Clone, Debug, Default)]
pub struct AttachmentBehavior;

impl Behavior for AttachmentBehavior {
    fn name(&self) -> &'static str {
        "attachment"
    }
    fn reads(&self) -> &'static [&'static str] {
        &[
            "attachment",
            "slide_rail",
            "slide_surface",
            "freeze_weights",
        ]
    }
    fn apply(&self, scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        // Rigid groups first: a sliding attachment listing a group's vertex slides the group.
        for rigid_pass in [true, false] {
            self.apply_pass(scene, b, rigid_pass)?;
        }
        Ok(())
    }
}

impl AttachmentBehavior {
    /// The rigid attachments (`rigid`), or every other one.
    fn apply_pass(
        &self,
        scene: &[SceneElement],
        b: &mut SystemBuilder,
        rigid_pass: bool,
    ) -> Result<(), SimError> {
        // Per vertex, its rigid group (made in the first pass).
        let mut group_of: std::collections::HashMap<usize, usize> = Default::default();
        if !rigid_pass {
            for (k, g) in b.system.rigid.iter().enumerate() {
                for &v in &g.vertices {
                    group_of.insert(v as usize, k);
                }
            }
        }
        let mut sliding_groups = std::collections::BTreeSet::new();
        for (ai, a) in scene.iter().enumerate() {
            let Some(att) = a.secs.get::<Attachment>() else {
                continue;
            };
            if matches!(att.mode, AttachmentMode::Rigid { .. }) != rigid_pass {
                continue;
            }
            b.read(ai, "attachment");
            let fail = |m: String| SimError::BadAttachment {
                attachment: a.name.clone(),
                message: m,
            };
            let Some(ti) = scene.iter().position(|e| e.name == att.target) else {
                return Err(fail(format!(
                    "no element named '{}' in the scene",
                    att.target
                )));
            };
            let Some(off) = b.offset(ti) else {
                return Err(fail(format!(
                    "element '{}' is not simulated (a {})",
                    att.target,
                    scene[ti].kind.name()
                )));
            };
            let n = scene[ti].vertex_count();
            if let AttachmentMode::Rigid { mass } = att.mode {
                rigid(scene, b, a, att, off, n, mass).map_err(fail)?;
                continue;
            }
            if let AttachmentMode::Freeze { weight } = att.mode {
                b.read(ai, "freeze_weights");
                freeze(b, a, att, ai, ti, off, n, weight).map_err(fail)?;
                continue;
            }
            let targets = if let AttachmentMode::Slide { friction } = att.mode {
                if !(friction >= 0.0 && friction.is_finite()) {
                    return Err(fail(format!("friction must be ≥ 0, got {friction}")));
                }
                b.read(ai, "slide_rail");
                b.read(ai, "slide_surface");
                crate::slide::targets(a, ai, b).map_err(fail)?
            } else {
                (0..0, 0..0)
            };
            if let AttachmentMode::Spring(k) = att.mode
                && !(k > 0.0 && k.is_finite())
            {
                return Err(fail(format!("spring stiffness must be > 0, got {k}")));
            }
            // A vertex listed twice is attached once (a second spring would double it).
            let mut vertices = att.vertices.clone();
            vertices.sort_unstable();
            vertices.dedup();
            for &v in &vertices {
                if v as usize >= n {
                    return Err(fail(format!(
                        "vertex {v} is out of range (element '{}' has {n} vertices)",
                        att.target
                    )));
                }
                let g = (v + off) as usize;
                let spring = match att.mode {
                    AttachmentMode::Slide { friction } if group_of.contains_key(&g) => {
                        // A ring: the group's centroid slides, once however many of its
                        // vertices are listed.
                        let k = group_of[&g];
                        if sliding_groups.insert(k) {
                            let members = b.system.rigid[k].vertices.clone();
                            crate::slide::slide(
                                b,
                                g,
                                Some(&members),
                                targets.clone(),
                                friction,
                                &att.target,
                                v,
                            );
                        }
                        continue;
                    }
                    AttachmentMode::Slide { friction } => {
                        // Two attachments on one vertex: said here, with their names.
                        if b.system.pinned[g] || constrained(b, g) {
                            return Err(fail(format!(
                                "vertex {v} of '{}' is already held, sliding, frozen or in a rigid group (another attachment lists it)",
                                att.target
                            )));
                        }
                        crate::slide::slide(b, g, None, targets.clone(), friction, &att.target, v);
                        continue;
                    }
                    AttachmentMode::Rigid { .. } | AttachmentMode::Freeze { .. } => continue,
                    AttachmentMode::Hard if constrained(b, g) => {
                        return Err(fail(format!(
                            "vertex {v} of '{}' already slides, is frozen or is in a rigid group (another attachment lists it)",
                            att.target
                        )));
                    }
                    AttachmentMode::Hard => {
                        b.system.pinned[g] = true;
                        None
                    }
                    AttachmentMode::Spring(k) => {
                        b.system.elements.springs.push(Spring {
                            v: [g as u32],
                            target: b.x[g],
                            k,
                        });
                        Some(b.system.elements.springs.len() - 1)
                    }
                };
                b.pin(ai, g, spring, scene[ai].transform);
            }
            if !att.clamps.is_empty() {
                clamps(scene, b, ai, ti, off).map_err(fail)?;
            }
        }
        Ok(())
    }
}

/// Whether global vertex `g` already slides or is in a rigid group.
fn constrained(b: &SystemBuilder, g: usize) -> bool {
    b.constrained[g]
}

/// Freeze attachment `a` (scene index `ai`) on element `ti` (first global vertex `off`, `n`
/// vertices): a [`crate::FreezePin`] and a spring (stiffness 0 until a weight sets it) per
/// listed vertex, with its factor from a Freeze Weights SEC (1 without one).
#[allow(clippy::too_many_arguments)]
fn freeze(
    b: &mut SystemBuilder,
    a: &SceneElement,
    att: &Attachment,
    ai: usize,
    ti: usize,
    off: u32,
    n: usize,
    weight: f64,
) -> Result<(), String> {
    if !(weight >= 0.0 && weight.is_finite()) {
        return Err(format!("the freeze weight must be ≥ 0, got {weight}"));
    }
    let factors = a.secs.get::<weft_scene::FreezeWeights>();
    if let Some(f) = factors
        && f.weights.len() != att.vertices.len()
    {
        return Err(format!(
            "{} vertex weights for {} listed vertices (one each, in the same order)",
            f.weights.len(),
            att.vertices.len()
        ));
    }
    // Sorted by vertex, a vertex listed twice frozen once (its first factor).
    let mut listed: Vec<(u32, f64)> = att
        .vertices
        .iter()
        .enumerate()
        .map(|(k, &v)| (v, factors.map_or(1.0, |f| f.weights[k])))
        .collect();
    listed.sort_by_key(|&(v, _)| v);
    listed.dedup_by_key(|&mut (v, _)| v);
    for (v, factor) in listed {
        if v as usize >= n {
            return Err(format!(
                "vertex {v} is out of range (element '{}' has {n} vertices)",
                att.target
            ));
        }
        if !(factor >= 0.0 && factor.is_finite()) {
            return Err(format!(
                "the weight of vertex {v} must be ≥ 0, got {factor}"
            ));
        }
        let g = (v + off) as usize;
        if b.system.pinned[g] || constrained(b, g) {
            return Err(format!(
                "vertex {v} of '{}' is already held, sliding, frozen or in a rigid group (another attachment lists it)",
                att.target
            ));
        }
        b.constrained[g] = true;
        b.system.elements.springs.push(Spring {
            v: [g as u32],
            target: b.x[g],
            k: 0.0,
        });
        let spring = b.system.elements.springs.len() - 1;
        b.freezes.push(crate::FreezePin {
            vertex: g,
            element: ti,
            index: v as usize,
            attachment: ai,
            factor,
            spring,
        });
    }
    Ok(())
}

/// Rigid attachment `a`: its vertices of the target (first global vertex `off`, `n`
/// vertices) become one rigid group, with `mass` added among them.
fn rigid(
    scene: &[SceneElement],
    b: &mut SystemBuilder,
    a: &SceneElement,
    att: &Attachment,
    off: u32,
    n: usize,
    mass: f64,
) -> Result<(), String> {
    if !(mass >= 0.0 && mass.is_finite()) {
        return Err(format!("mass must be ≥ 0, got {mass}"));
    }
    let mut vertices = att.vertices.clone();
    vertices.sort_unstable();
    vertices.dedup();
    if vertices.len() < 2 {
        return Err(format!(
            "a rigid group needs two or more vertices, got {}",
            vertices.len()
        ));
    }
    let mut group = Vec::with_capacity(vertices.len());
    for &v in &vertices {
        if v as usize >= n {
            return Err(format!(
                "vertex {v} is out of range (element '{}' has {n} vertices)",
                att.target
            ));
        }
        let g = v + off;
        if b.system.pinned[g as usize] || constrained(b, g as usize) {
            return Err(format!(
                "vertex {v} of '{}' is already held, sliding, frozen or in a rigid group (another attachment lists it)",
                att.target
            ));
        }
        group.push(g);
    }
    for &g in &group {
        b.add_mass(g as usize, mass / group.len() as f64);
        b.constrained[g as usize] = true;
    }
    b.system
        .rigid
        .push(weft_solid::RigidGroup { vertices: group });
    if scene.iter().any(|e| e.kind == ElementKind::Collision) {
        b.warn(format!(
            "rigid attachment '{}': its vertices take no contacts yet (they pass through colliders and other solids)",
            a.name
        ));
    }
    Ok(())
}

/// The clamps of attachment `ai` on element `ti` (first global vertex `off`): a
/// [`RodClamp`] each, along the strand's direction at the start, stiffness bend_scale·EI
/// over the first free segment's rest length (see `RodClamp` for why).
fn clamps(
    scene: &[SceneElement],
    b: &mut SystemBuilder,
    ai: usize,
    ti: usize,
    off: u32,
) -> Result<(), String> {
    let (a, e) = (&scene[ai], &scene[ti]);
    let Some(att) = a.secs.get::<Attachment>() else {
        return Ok(());
    };
    let Geometry::Curves(curves) = &*e.geometry else {
        // Cloth clamps are ghosts, made (and checked) before any Behavior applies.
        return Ok(());
    };
    let rod = e.secs.get::<Rod>().cloned().unwrap_or_default();
    checked(&e.name, &rod).map_err(|err| err.to_string())?;
    let ei = rod_section(&rod).bending;
    if ei == 0.0 {
        // A strand without bending stiffness has nothing to clamp: it hangs from its pins.
        return Ok(());
    }
    let rest = rest_positions(e, &rod.rest_channel).map_err(|err| err.to_string())?;
    let n = e.vertex_count();
    let mut seen = BTreeSet::new();
    for &[root, next] in &att.clamps {
        let (r, x) = (root as usize, next as usize);
        if r >= n || x >= n {
            return Err(format!(
                "clamp ({root}, {next}) is out of range (element '{}' has {n} vertices)",
                e.name
            ));
        }
        let same_curve = (0..curves.len()).any(|k| {
            let c = curves.range(k);
            c.contains(&r) && c.contains(&x)
        });
        if x != r + 1 || !same_curve {
            return Err(format!(
                "clamp ({root}, {next}): the second vertex must follow the first on the same strand"
            ));
        }
        if !seen.insert(r) {
            continue;
        }
        let l = (v3(rest[x]) - v3(rest[r])).norm();
        let (g, gn) = (r + off as usize, x + off as usize);
        let dir = b.x[gn] - b.x[g];
        if !(l > 1e-12 && dir.norm() > 1e-12) {
            return Err(format!(
                "clamp ({root}, {next}): the strand's first segment has zero length"
            ));
        }
        let tangent = dir.normalize();
        b.system.elements.clamps.push(RodClamp {
            v: [g as u32, gn as u32],
            tangent,
            k: ei / l,
        });
        let index = b.system.elements.clamps.len() - 1;
        b.clamp(ai, index, tangent, a.transform);
    }
    Ok(())
}

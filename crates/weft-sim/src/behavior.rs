//! Behaviors: reusable simulation logic applied to every element that carries (or defaults)
//! the SEC it reads.

use crate::builder::SystemBuilder;
use crate::error::SimError;
use nalgebra::Vector3;
use std::collections::BTreeSet;
use std::fmt::Debug;
use std::sync::Arc;
use weft_scene::fields::SecFields;
use weft_scene::{
    Attachment, AttachmentMode, Density, DiscreteShell, ElementKind, Geometry, Rod, SceneElement,
};
use weft_solid::energy::{
    ClampedEdge, Membrane, MembraneMaterial, RodBend, RodClamp, RodSection, RodStretch, Spring,
    plate_bending_stiffness, shell_bending_clamped,
};

/// Simulation logic for the elements a Behavior applies to.
pub trait Behavior: Send + Sync + Debug {
    /// Name shown in reports (`discrete_shell_material`).
    fn name(&self) -> &'static str;
    /// SEC types this Behavior reads (documentation; the builder records what it actually read
    /// for each element, and SECs nobody read for their element are reported).
    fn reads(&self) -> &'static [&'static str];
    /// Adds this Behavior's terms for `scene` to the builder.
    fn apply(&self, scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError>;
}

/// The Behaviors a solver applies, in order.
#[derive(Clone, Debug, Default)]
pub struct BehaviorTree {
    /// The Behaviors.
    pub behaviors: Vec<Arc<dyn Behavior>>,
}

pub(crate) fn bad(element: &str, field: &str, message: String) -> SimError {
    SimError::BadParameter {
        element: element.into(),
        field: field.into(),
        message,
    }
}

pub(crate) fn non_negative(element: &str, field: &str, x: f64) -> Result<(), SimError> {
    if x >= 0.0 && x.is_finite() {
        Ok(())
    } else {
        Err(bad(element, field, format!("must be >= 0, got {x}")))
    }
}

/// Checks an SEC against its table's ranges (`weft_scene::fields`): the node that attached
/// it checked the same ranges, but a host or plugin may build the struct itself.
pub(crate) fn checked<S: SecFields>(element: &str, sec: &S) -> Result<(), SimError> {
    sec.check()
        .map_err(|err| bad(element, &err.field, err.message))
}

fn v3(p: [f64; 3]) -> Vector3<f64> {
    Vector3::new(p[0], p[1], p[2])
}

/// Rest positions: the named channel if present (its length must match), else the current
/// positions.
fn rest_positions<'a>(e: &'a SceneElement, channel: &str) -> Result<&'a [[f64; 3]], SimError> {
    let n = e.vertex_count();
    match e.vec3_channel(channel) {
        Some(r) if r.len() == n => Ok(r),
        Some(r) => Err(SimError::BadGeometry {
            element: e.name.clone(),
            message: format!(
                "rest channel '{channel}' has {} entries but the element has {n} vertices",
                r.len()
            ),
        }),
        None => Ok(e.geometry.positions()),
    }
}

/// Discrete-shell cloth: StVK membrane (orthotropic by the SEC's warp/weft/shear scales) on every
/// triangle and mean-curvature bending at every vertex (`weft_solid::energy::ShellBend`:
/// D/2 (2H − 2H̄)² per area, cotangent weights, so a bend costs the plate energy on any mesh
/// and in any direction), with lumped masses from the Density SEC.
/// D = bend_scale · E t³/(12(1 − ν²)).
#[derive(Clone, Debug, Default)]
pub struct DiscreteShellMaterial;

impl Behavior for DiscreteShellMaterial {
    fn name(&self) -> &'static str {
        "discrete_shell_material"
    }
    fn reads(&self) -> &'static [&'static str] {
        &["discrete_shell", "density"]
    }
    fn apply(&self, scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        for (ei, e) in scene.iter().enumerate() {
            let (ElementKind::Cloth, Geometry::Mesh(mesh)) = (e.kind, &*e.geometry) else {
                continue;
            };
            b.read(ei, "discrete_shell");
            b.read(ei, "density");
            let shell = e.secs.get::<DiscreteShell>().cloned().unwrap_or_default();
            let density = e.secs.get::<Density>().cloned().unwrap_or_default();
            let name = e.name.as_str();
            checked(name, &shell)?;
            checked(name, &density)?;
            let rest = rest_positions(e, &shell.rest_channel)?;
            let off = b.offset(ei).expect("cloth elements have a vertex range");
            // A face listed twice (double-sided exports) would double mass and stiffness and
            // make hinges whose two wings are one vertex: refuse it by name.
            let mut seen = std::collections::HashMap::new();
            for (ti, t) in mesh.triangles.iter().enumerate() {
                let mut key = *t;
                key.sort_unstable();
                if let Some(first) = seen.insert(key, ti) {
                    return Err(SimError::BadGeometry {
                        element: name.into(),
                        message: format!(
                            "triangles {first} and {ti} use the same vertices {key:?} (a duplicated face, e.g. from a double-sided export)"
                        ),
                    });
                }
            }
            let mat = MembraneMaterial::orthotropic(
                shell.youngs_modulus,
                shell.poisson_ratio,
                shell.thickness,
                shell.warp_scale,
                shell.weft_scale,
                shell.shear_scale,
            );
            let warp = v3(shell.warp_direction);
            let n = rest.len() as u32;
            for (ti, t) in mesh.triangles.iter().enumerate() {
                if t.iter().any(|&v| v >= n) {
                    return Err(SimError::BadGeometry {
                        element: name.into(),
                        message: format!(
                            "triangle {ti} {t:?} uses a vertex beyond the {n} the element has"
                        ),
                    });
                }
                let r = [
                    v3(rest[t[0] as usize]),
                    v3(rest[t[1] as usize]),
                    v3(rest[t[2] as usize]),
                ];
                let gv = [t[0] + off, t[1] + off, t[2] + off];
                let m = Membrane::new(gv, r, warp, mat).map_err(|err| SimError::BadGeometry {
                    element: name.into(),
                    message: format!("triangle {ti} {t:?} {}", err.reason()),
                })?;
                for &v in &gv {
                    b.add_mass(v as usize, m.area * density.area_density / 3.0);
                }
                b.system.elements.membranes.push(m);
            }
            for v in 0..n {
                b.add_damping((v + off) as usize, shell.damping);
            }
            if shell.bend_scale > 0.0 {
                let d = plate_bending_stiffness(
                    shell.youngs_modulus,
                    shell.poisson_ratio,
                    shell.thickness,
                    shell.bend_scale,
                );
                let mut rest: Vec<Vector3<f64>> = rest.iter().map(|&p| v3(p)).collect();
                // Clamped edges: their ghosts' rest positions follow the element's rest
                // positions after its own (crate::clamp).
                let ghosts: Vec<crate::Ghost> = b
                    .ghosts
                    .iter()
                    .filter(|g| g.element == ei)
                    .cloned()
                    .collect();
                let mut clamped = Vec::with_capacity(ghosts.len());
                for g in &ghosts {
                    let [p, q] = g.edge.map(|v| rest[v as usize]);
                    clamped.push(ClampedEdge {
                        edge: g.edge,
                        ghost: rest.len() as u32,
                    });
                    rest.push(crate::clamp::mirror(p, q, rest[g.apex as usize]));
                }
                let bending =
                    shell_bending_clamped(&rest, &mesh.triangles, d, shell.poisson_ratio, &clamped)
                        .map_err(|err| SimError::BadGeometry {
                            element: name.into(),
                            message: err.to_string(),
                        })?;
                let global = |v: u32| {
                    if v < n {
                        v + off
                    } else {
                        ghosts[(v - n) as usize].vertex as u32
                    }
                };
                if bending.non_manifold_edges > 0 {
                    b.warn(format!(
                        "element '{name}': {} non-manifold edge(s) (shared by more than two triangles); their vertices get no bending",
                        bending.non_manifold_edges
                    ));
                }
                let (dropoff, kappa0) = (shell.bend_dropoff, shell.dropoff_curvature);
                for mut el in bending.vertices {
                    el.map_vertices(global);
                    el.set_dropoff(dropoff, kappa0);
                    b.system.elements.shells.push(el);
                }
                for mut el in bending.triangles {
                    el.map_vertices(global);
                    el.set_dropoff(dropoff, kappa0);
                    b.system.elements.midedges.push(el);
                }
                for mut el in bending.clamped_vertices {
                    el.map_vertices(global);
                    el.set_dropoff(dropoff, kappa0);
                    b.system.elements.shell_clamps.push(el);
                }
            }
        }
        Ok(())
    }
}

/// Rods (hair): stretch on every segment and bending at every interior vertex of each curve,
/// with lumped masses from the Density SEC. Axial stiffness k = stretch_scale·E·πr²; bending
/// EI = bend_scale·E·πr⁴/4 over the Voronoi length (see `weft_solid::energy::RodBend`).
#[derive(Clone, Debug, Default)]
pub struct RodMaterial;

impl Behavior for RodMaterial {
    fn name(&self) -> &'static str {
        "rod_material"
    }
    fn reads(&self) -> &'static [&'static str] {
        &["rod", "density"]
    }
    fn apply(&self, scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        for (ei, e) in scene.iter().enumerate() {
            let (ElementKind::Hair, Geometry::Curves(curves)) = (e.kind, &*e.geometry) else {
                continue;
            };
            b.read(ei, "rod");
            b.read(ei, "density");
            let rod = e.secs.get::<Rod>().cloned().unwrap_or_default();
            let density = e.secs.get::<Density>().cloned().unwrap_or_default();
            let name = e.name.as_str();
            checked(name, &rod)?;
            checked(name, &density)?;
            let section = rod_section(&rod);
            let (ea, ei_bend) = (section.axial, section.bending);
            let rest = rest_positions(e, &rod.rest_channel)?;
            let off = b.offset(ei).expect("hair elements have a vertex range");
            for k in 0..curves.len() {
                let r = curves.range(k);
                let pts: Vec<Vector3<f64>> = rest[r.clone()].iter().map(|&p| v3(p)).collect();
                for s in 0..pts.len().saturating_sub(1) {
                    let l = (pts[s + 1] - pts[s]).norm();
                    if l.is_nan() || l <= 1e-12 {
                        return Err(SimError::BadGeometry {
                            element: name.into(),
                            message: format!("curve {k}, segment {s} has zero rest length"),
                        });
                    }
                    let (a, c) = ((r.start + s) as u32 + off, (r.start + s + 1) as u32 + off);
                    b.system.elements.stretches.push(RodStretch {
                        v: [a, c],
                        rest_length: l,
                        k: ea,
                    });
                    b.add_mass(a as usize, 0.5 * l * density.line_density);
                    b.add_mass(c as usize, 0.5 * l * density.line_density);
                }
                if ei_bend > 0.0 {
                    for s in 1..pts.len().saturating_sub(1) {
                        let (e0, e1) = (pts[s] - pts[s - 1], pts[s + 1] - pts[s]);
                        let vor = 0.5 * (e0.norm() + e1.norm());
                        let kb = 2.0 * e0.cross(&e1).norm() / (e0.norm() * e1.norm() + e0.dot(&e1));
                        let v = (r.start + s) as u32 + off;
                        let mut bend = RodBend {
                            v: [v - 1, v, v + 1],
                            k: ei_bend / (2.0 * vor),
                            rest: kb,
                            dropoff: None,
                        };
                        bend.set_dropoff(rod.bend_dropoff, rod.dropoff_curvature, vor);
                        b.system.elements.bends.push(bend);
                    }
                }
            }
            for v in 0..rest.len() as u32 {
                b.add_damping((v + off) as usize, rod.damping);
            }
        }
        Ok(())
    }
}

/// A rod's axial and bending stiffnesses from its SEC (`weft_solid::energy::RodSection`).
fn rod_section(rod: &Rod) -> RodSection {
    RodSection::round(
        rod.youngs_modulus,
        rod.radius,
        rod.stretch_scale,
        rod.bend_stiffness,
        rod.bend_scale,
    )
}

/// Uniform gravity on every simulated vertex.
#[derive(Clone, Debug)]
pub struct Gravity {
    /// Acceleration [m/s²] (default (0, −9.81, 0)).
    pub acceleration: [f64; 3],
}

impl Behavior for Gravity {
    fn name(&self) -> &'static str {
        "gravity"
    }
    fn reads(&self) -> &'static [&'static str] {
        &[]
    }
    fn apply(&self, _scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        b.system.gravity += v3(self.acceleration);
        Ok(())
    }
}

/// Which vertices of an element a [`Load`] pushes.
#[derive(Clone, Debug, PartialEq)]
pub enum LoadVertices {
    /// Every vertex.
    All,
    /// The last vertex of every curve (a tip load on each strand).
    CurveTips,
    /// These indices.
    Listed(Vec<u32>),
}

/// A constant force on chosen vertices of one element: a tip load, a weight hung on a
/// point, a steady push.
#[derive(Clone, Debug)]
pub struct Load {
    /// Name of the loaded element.
    pub element: String,
    /// Which of its vertices.
    pub vertices: LoadVertices,
    /// Force on each of them [N].
    pub force: [f64; 3],
}

impl Behavior for Load {
    fn name(&self) -> &'static str {
        "load"
    }
    fn reads(&self) -> &'static [&'static str] {
        &[]
    }
    fn apply(&self, scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        let f = v3(self.force);
        if !f.iter().all(|c| c.is_finite()) {
            return Err(bad(
                "(tree)",
                "load.force",
                format!("must be finite, got {:?}", self.force),
            ));
        }
        let Some(ei) = scene.iter().position(|e| e.name == self.element) else {
            return Err(bad(
                "(tree)",
                "load.element",
                format!("no element named '{}' in the scene", self.element),
            ));
        };
        let e = &scene[ei];
        let Some(off) = b.offset(ei) else {
            return Err(bad(
                &e.name,
                "load.element",
                format!("'{}' is not simulated (a {})", e.name, e.kind.name()),
            ));
        };
        let n = e.vertex_count();
        let vertices: Vec<u32> = match (&self.vertices, &*e.geometry) {
            (LoadVertices::All, _) => (0..n as u32).collect(),
            (LoadVertices::CurveTips, Geometry::Curves(c)) => (0..c.len())
                .filter(|&k| !c.range(k).is_empty())
                .map(|k| c.range(k).end as u32 - 1)
                .collect(),
            (LoadVertices::CurveTips, _) => {
                return Err(bad(
                    &e.name,
                    "load.select",
                    format!("'{}' has no curves to take tips from", e.name),
                ));
            }
            (LoadVertices::Listed(v), _) => {
                // A vertex listed twice is loaded once.
                let mut v = v.clone();
                v.sort_unstable();
                v.dedup();
                v
            }
        };
        if let Some(v) = vertices.iter().find(|&&v| v as usize >= n) {
            return Err(bad(
                &e.name,
                "load.vertices",
                format!("vertex {v} is out of range ('{}' has {n} vertices)", e.name),
            ));
        }
        if b.system.forces.is_empty() {
            b.system.forces = vec![Vector3::zeros(); b.system.mass.len()];
        }
        for v in vertices {
            b.system.forces[(v + off) as usize] += f;
        }
        Ok(())
    }
}

/// Mass-proportional damping on every simulated vertex, added to the SECs' own.
#[derive(Clone, Debug)]
pub struct Damping {
    /// Coefficient [1/s]: a force −c m v.
    pub coefficient: f64,
}

impl Behavior for Damping {
    fn name(&self) -> &'static str {
        "damping"
    }
    fn reads(&self) -> &'static [&'static str] {
        &[]
    }
    fn apply(&self, _scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        non_negative("(tree)", "damping.coefficient", self.coefficient)?;
        for v in 0..b.system.mass.len() {
            b.add_damping(v, self.coefficient);
        }
        Ok(())
    }
}

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

/// Fluid drag: every hair segment (cross-section from its Rod SEC's radius) and cloth triangle
/// (thickness from its Discrete Shell SEC) becomes a drag element with its Drag SEC's law, or
/// the documented defaults. The elements reach the coupled stepper through
/// [`crate::Compiled::drag_elements`]; a scene without a fluid simply never uses them.
#[derive(Clone, Debug, Default)]
pub struct FluidDrag;

impl Behavior for FluidDrag {
    fn name(&self) -> &'static str {
        "fluid_drag"
    }
    fn reads(&self) -> &'static [&'static str] {
        &["drag", "rod", "discrete_shell"]
    }
    fn apply(&self, scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        for (ei, e) in scene.iter().enumerate() {
            let Some(off) = b.offset(ei) else { continue };
            let params = match e.kind {
                ElementKind::Cloth | ElementKind::Hair => {
                    b.read(ei, "drag");
                    e.secs
                        .get::<weft_scene::Drag>()
                        .cloned()
                        .unwrap_or_default()
                }
                _ => continue,
            };
            checked(&e.name, &params)?;
            match (&*e.geometry, e.kind) {
                (Geometry::Curves(c), ElementKind::Hair) => {
                    b.read(ei, "rod");
                    let r = e.secs.get::<Rod>().cloned().unwrap_or_default().radius;
                    let area = std::f64::consts::PI * r * r;
                    for w in c.offsets.windows(2) {
                        for v in w[0]..w[1].saturating_sub(1) {
                            b.drag_elements.push(crate::DragElement {
                                shape: crate::DragShape::Segment([v + off, v + 1 + off], area),
                                params,
                            });
                        }
                    }
                }
                (Geometry::Mesh(m), ElementKind::Cloth) => {
                    b.read(ei, "discrete_shell");
                    let t = e
                        .secs
                        .get::<DiscreteShell>()
                        .cloned()
                        .unwrap_or_default()
                        .thickness;
                    for tri in &m.triangles {
                        b.drag_elements.push(crate::DragElement {
                            shape: crate::DragShape::Triangle(tri.map(|v| v + off), t),
                            params,
                        });
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }
}

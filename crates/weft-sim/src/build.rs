//! Compiling (scene, Behavior tree) into a solid system with exactly the terms the scene needs.

use crate::behavior::BehaviorTree;
pub use crate::builder::{ClampPin, Pin, SystemBuilder};
use crate::error::SimError;
use nalgebra::Vector3;
use std::collections::{BTreeMap, BTreeSet};
use std::ops::Range;
use weft_scene::{Channel, ElementKind, SceneElement, Transform};
use weft_solid::{SolidSystem, State};

/// A scene compiled for the solid solver.
#[derive(Clone, Debug)]
pub struct Compiled {
    /// The system.
    pub system: SolidSystem,
    /// Initial state (positions from geometry, velocities from the `velocity` channel).
    pub state: State,
    /// Global vertex range of each scene element (None for elements that are not simulated).
    pub ranges: Vec<Option<Range<usize>>>,
    /// Attached vertices.
    pub pins: Vec<Pin>,
    /// Clamped roots (their directions follow the attachments' rotations).
    pub clamps: Vec<ClampPin>,
    /// Rails and surfaces of sliding attachments (they move with the attachments'
    /// transforms).
    pub targets: Vec<crate::slide::TargetPin>,
    /// Frozen vertices (freeze attachments), in attachment order.
    pub freezes: Vec<crate::freeze::FreezePin>,
    /// Sliders of sliding attachments: `system.sliders`' first entries (frozen vertices held
    /// in a step are point sliders after them).
    pub base_sliders: usize,
    /// Problems that do not stop the simulation (unread SECs, non-manifold edges).
    pub warnings: Vec<String>,
    /// Terms in the system, by kind: what the scene asked for and nothing else.
    pub terms: BTreeMap<&'static str, usize>,
    /// Elements that exchange momentum with a fluid (empty when no Behavior asked for drag).
    pub drag_elements: Vec<crate::DragElement>,
    /// The scene's fluid (None without a fluid-domain element: no grid is made).
    pub fluid: Option<crate::FluidSpec>,
    /// Contacts with colliders (None without `behavior.collision` and a collision element:
    /// no contact machinery is built).
    pub collisions: Option<crate::CollisionSetup>,
    /// The scene it was compiled from: the start frame's geometry, with the SECs whose values
    /// it holds (a later frame's SECs are compared with these: [`Compiled::with_params`]).
    pub source: std::sync::Arc<Vec<SceneElement>>,
    /// The Behavior tree it was compiled with.
    pub tree: BehaviorTree,
}

/// Whether two elements' SECs differ only in a freeze attachment's weight, which the stepper
/// reads at every frame itself (`Compiled::freeze_frame`): nothing to compile again.
fn only_freeze_weight_differs(a: &SceneElement, b: &SceneElement) -> bool {
    use weft_scene::{Attachment, AttachmentMode};
    let weightless = |e: &SceneElement| {
        e.secs.get::<Attachment>().map(|att| {
            let mut att = att.clone();
            if let AttachmentMode::Freeze { weight } = &mut att.mode {
                *weight = 0.0;
            }
            att
        })
    };
    let (Some(x), Some(y)) = (weightless(a), weightless(b)) else {
        return false;
    };
    x == y
        && a.secs.types().eq(b.secs.types())
        && a.secs.iter().zip(b.secs.iter()).all(|(p, q)| {
            p.sec_type() == "attachment" || std::sync::Arc::ptr_eq(p, q) || p.same(&**q)
        })
}

/// Whether two trees hold the same Behaviors with the same parameters.
fn same_tree(a: &BehaviorTree, b: &BehaviorTree) -> bool {
    a.behaviors.len() == b.behaviors.len()
        && a.behaviors
            .iter()
            .zip(&b.behaviors)
            .all(|(x, y)| std::sync::Arc::ptr_eq(x, y) || format!("{x:?}") == format!("{y:?}"))
}

pub(crate) fn lerp(a: Option<Transform>, b: Option<Transform>, s: f64) -> Option<Transform> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.lerp_slerp(&b, s)),
        (a, b) => b.or(a),
    }
}

impl Compiled {
    /// For animated parameters: the system compiled again when `scene` (the scene at
    /// `frame`) carries SECs whose values differ from the ones compiled, or `tree` (None: the
    /// one compiled) has Behaviors whose parameters do; `None` when nothing differs. Rest
    /// shapes, attachments' frames and everything else geometric stay the start frame's
    /// (the new system is compiled from the start scene with the frame's SECs), and a change
    /// that would change the vertices simulated is refused.
    pub fn with_params(
        &self,
        scene: &[SceneElement],
        tree: Option<&BehaviorTree>,
        frame: i64,
        max_bytes: Option<u64>,
    ) -> Result<Option<Compiled>, SimError> {
        let tree_same = tree.is_none_or(|t| same_tree(t, &self.tree));
        let secs_same = scene.len() == self.source.len()
            && scene
                .iter()
                .zip(self.source.iter())
                .all(|(a, b)| a.secs.same_as(&b.secs) || only_freeze_weight_differs(a, b));
        if tree_same && secs_same {
            return Ok(None);
        }
        self.check_scene(scene, frame)?;
        let next: Vec<SceneElement> = self
            .source
            .iter()
            .zip(scene)
            .map(|(s, e)| {
                let mut s = s.clone();
                s.secs = e.secs.clone();
                s
            })
            .collect();
        let c = compile_within(&next, tree.unwrap_or(&self.tree), max_bytes)?;
        if c.state.x.len() != self.state.x.len()
            || c.ranges != self.ranges
            || c.freezes.len() != self.freezes.len()
        {
            return Err(SimError::SceneChanged(format!(
                "frame {frame}: an animated parameter changed what is simulated ({} vertices, {} frozen, before: {}, {}); animate values, not structure",
                c.state.x.len(),
                c.freezes.len(),
                self.state.x.len(),
                self.freezes.len()
            )));
        }
        Ok(Some(c))
    }

    /// The scene with simulated elements moved to `state` (and a `velocity` channel set).
    pub fn scene_at<'a>(
        &self,
        scene: impl IntoIterator<Item = &'a SceneElement>,
        state: &State,
    ) -> Vec<SceneElement> {
        scene
            .into_iter()
            .zip(&self.ranges)
            .map(|(e, r)| {
                let mut e = e.clone();
                if let Some(r) = r {
                    for (p, x) in e
                        .geometry_mut()
                        .positions_mut()
                        .iter_mut()
                        .zip(&state.x[r.clone()])
                    {
                        *p = [x.x, x.y, x.z];
                    }
                    let vel = state.v[r.clone()].iter().map(|v| [v.x, v.y, v.z]).collect();
                    e.set_channel("velocity", Channel::Vec3(vel));
                }
                e
            })
            .collect()
    }

    /// Checks that `scene` (at `frame`) has the structure the system was compiled from: the
    /// same elements with the same vertex counts.
    pub fn check_scene(&self, scene: &[SceneElement], frame: i64) -> Result<(), SimError> {
        for (i, (e, r)) in scene.iter().zip(&self.ranges).enumerate() {
            if let Some(r) = r
                && e.vertex_count() != r.len()
            {
                return Err(SimError::SceneChanged(format!(
                    "element {i} '{}' has {} vertices at frame {frame} but had {} at the start",
                    e.name,
                    e.vertex_count(),
                    r.len()
                )));
            }
        }
        if scene.len() != self.ranges.len() {
            return Err(SimError::SceneChanged(format!(
                "the scene has {} elements at frame {frame} but had {} at the start",
                scene.len(),
                self.ranges.len()
            )));
        }
        Ok(())
    }

    /// Where attached vertices go at fraction `s` of the way from the transforms `from` to
    /// `to` (translation linearly, rotation by slerp): writes hard pins' targets into
    /// `targets` (one per vertex) and moves spring attachments' targets in `system`.
    pub fn set_targets(
        &self,
        from: &[Option<Transform>],
        to: &[Option<Transform>],
        s: f64,
        system: &mut SolidSystem,
        targets: &mut [Vector3<f64>],
    ) {
        for p in &self.pins {
            let t = lerp(
                from.get(p.attachment).copied().flatten(),
                to.get(p.attachment).copied().flatten(),
                s,
            );
            let x = match t {
                Some(t) => t.transform_point(&p.local.into()).coords,
                None => p.local,
            };
            targets[p.vertex] = x;
            if let Some(k) = p.spring {
                system.elements.springs[k].target = x;
            }
        }
        for r in &self.targets {
            let a = r.attachment();
            let t = lerp(
                from.get(a).copied().flatten(),
                to.get(a).copied().flatten(),
                s,
            );
            r.place(t, system);
        }
        for c in &self.clamps {
            let t = lerp(
                from.get(c.attachment).copied().flatten(),
                to.get(c.attachment).copied().flatten(),
                s,
            );
            system.elements.clamps[c.clamp].tangent = match t {
                Some(t) => t.transform_vector(&c.local),
                None => c.local,
            };
        }
    }
}

/// Compiles a scene: every cloth and hair element gets a range of global vertices; each
/// Behavior adds its terms; elements without mass, and SECs no Behavior reads, are reported.
pub fn compile(scene: &[SceneElement], tree: &BehaviorTree) -> Result<Compiled, SimError> {
    compile_within(scene, tree, None)
}

/// Bytes a simulated vertex costs in the compiled system at most: positions, velocities,
/// masses, its share of the energy terms' stencils and rest data (a cloth vertex is in six
/// triangles, each with a membrane, a bending and a midedge term).
pub const SYSTEM_BYTES_PER_VERTEX: u64 = 2048;

/// [`compile`], refusing (before building the system) a scene whose system, or whose fluid
/// grid, would take more than `max_bytes`; `None`: no limit.
pub fn compile_within(
    scene: &[SceneElement],
    tree: &BehaviorTree,
    max_bytes: Option<u64>,
) -> Result<Compiled, SimError> {
    check_size(scene, max_bytes)?;
    let (ranges, x, v) = gather_vertices(scene)?;
    let (mut b, v) = start_builder(scene, ranges, x, v)?;
    let n = b.x.len();
    apply_tree(scene, tree, &mut b)?;
    check_masses(scene, &b)?;
    check_bands(scene, &mut b)?;
    let fluid = crate::fluid::fluid_spec(scene, &b.x, max_bytes, |e, sec| {
        if let Some(r) = b.read.get_mut(e) {
            r.insert(sec);
        }
    })?;
    warn_fluid(fluid.as_ref(), &mut b);
    warn_unread(scene, &mut b);
    let terms = term_counts(&b, n);
    let base_sliders = b.system.sliders.len();
    b.system.layout = b.x.clone();
    Ok(Compiled {
        state: State { x: b.x, v },
        system: b.system,
        ranges: b.ranges,
        pins: b.pins,
        clamps: b.clamps,
        targets: b.targets,
        freezes: b.freezes,
        base_sliders,
        warnings: b.warnings,
        terms,
        drag_elements: b.drag_elements,
        fluid,
        collisions: b.collisions,
        source: std::sync::Arc::new(scene.to_vec()),
        tree: tree.clone(),
    })
}

/// Refuses a scene whose simulated vertices would take more than `max_bytes` in the system
/// ([`SYSTEM_BYTES_PER_VERTEX`] each), before anything is built.
fn check_size(scene: &[SceneElement], max_bytes: Option<u64>) -> Result<(), SimError> {
    if let Some(limit) = max_bytes {
        let n: u64 = scene
            .iter()
            .filter(|e| matches!(e.kind, ElementKind::Cloth | ElementKind::Hair))
            .map(|e| e.vertex_count() as u64)
            .sum();
        let need = n.saturating_mul(SYSTEM_BYTES_PER_VERTEX);
        if need > limit {
            const GIB: f64 = (1u64 << 30) as f64;
            return Err(SimError::TooLarge(format!(
                "the scene's {n} simulated vertices need about {:.2} GiB, more than the {:.2} GiB available; use coarser meshes, fewer strands or fewer segments",
                need as f64 / GIB,
                limit as f64 / GIB
            )));
        }
    }
    Ok(())
}

/// Per scene element, its range of global vertices; every global vertex's start position
/// and velocity.
type Vertices = (
    Vec<Option<Range<usize>>>,
    Vec<Vector3<f64>>,
    Vec<Vector3<f64>>,
);

/// The global vertices of the scene's cloth and hair elements, in scene order, with their
/// start velocities (the `velocity` channel, or zero). Element names must be unique and
/// positions finite.
fn gather_vertices(scene: &[SceneElement]) -> Result<Vertices, SimError> {
    let mut names = BTreeSet::new();
    let mut ranges = Vec::with_capacity(scene.len());
    let mut x = Vec::new();
    let mut v = Vec::new();
    for e in scene {
        if !names.insert(e.name.as_str()) {
            return Err(SimError::SceneChanged(format!(
                "two elements are named '{}': names must be unique",
                e.name
            )));
        }
        if !matches!(e.kind, ElementKind::Cloth | ElementKind::Hair) {
            ranges.push(None);
            continue;
        }
        let start = x.len();
        let vel = e
            .vec3_channel("velocity")
            .filter(|c| c.len() == e.vertex_count());
        for (i, p) in e.geometry.positions().iter().enumerate() {
            if !p.iter().all(|c| c.is_finite()) {
                return Err(SimError::BadGeometry {
                    element: e.name.clone(),
                    message: format!("vertex {i} has a non-finite position {p:?}"),
                });
            }
            x.push(Vector3::new(p[0], p[1], p[2]));
            v.push(vel.map_or_else(Vector3::zeros, |c| Vector3::new(c[i][0], c[i][1], c[i][2])));
        }
        ranges.push(Some(start..x.len()));
    }
    Ok((ranges, x, v))
}

/// The builder the Behaviors fill: the vertices `x` (velocities `v`) with the ghosts behind
/// clamped cloth edges appended (held, massless vertices after every element's), an empty
/// system over them, and the ghosts pinned to their attachments. Returns the velocities
/// with the ghosts' (zero) appended too.
fn start_builder(
    scene: &[SceneElement],
    ranges: Vec<Option<Range<usize>>>,
    mut x: Vec<Vector3<f64>>,
    mut v: Vec<Vector3<f64>>,
) -> Result<(SystemBuilder, Vec<Vector3<f64>>), SimError> {
    let mut ghosts = crate::clamp::cloth_ghosts(scene, &ranges, &x)?;
    for (g, p) in &mut ghosts {
        g.vertex = x.len();
        x.push(*p);
        v.push(Vector3::zeros());
    }
    let n = x.len();
    let mut system = SolidSystem::new(vec![0.0; n]);
    system.damping = vec![0.0; n];
    for (g, _) in &ghosts {
        system.pinned[g.vertex] = true;
    }
    let mut b = SystemBuilder {
        system,
        x,
        ranges,
        pins: Vec::new(),
        clamps: Vec::new(),
        targets: Vec::new(),
        freezes: Vec::new(),
        constrained: vec![false; n],
        ghosts: ghosts.into_iter().map(|(g, _)| g).collect(),
        warnings: Vec::new(),
        read: vec![BTreeSet::new(); scene.len()],
        drag_elements: Vec::new(),
        collisions: None,
    };
    for k in 0..b.ghosts.len() {
        let (a, vertex) = (b.ghosts[k].attachment, b.ghosts[k].vertex);
        b.pin(a, vertex, None, scene[a].transform);
    }
    Ok((b, v))
}

/// Every Behavior of `tree` applied in order (one listed twice is applied twice, and said).
fn apply_tree(
    scene: &[SceneElement],
    tree: &BehaviorTree,
    b: &mut SystemBuilder,
) -> Result<(), SimError> {
    for (k, beh) in tree.behaviors.iter().enumerate() {
        if tree.behaviors[..k].iter().any(|o| o.name() == beh.name()) {
            // Applying a Behavior twice doubles its terms (damping, stiffness, gravity).
            b.warn(format!(
                "the Behavior tree lists '{}' more than once: its terms are applied twice",
                beh.name()
            ));
        }
        beh.apply(scene, b)?;
    }
    Ok(())
}

/// Every simulated vertex needs mass (or to be pinned). If none of an element's vertices has
/// any, no material Behavior covered it; if only some lack it, they are in no triangle or
/// segment.
fn check_masses(scene: &[SceneElement], b: &SystemBuilder) -> Result<(), SimError> {
    for (e, r) in scene.iter().zip(&b.ranges) {
        let Some(r) = r else { continue };
        let massless = |i: usize| b.system.mass[i] <= 0.0 && !b.system.pinned[i];
        let Some(i) = r.clone().find(|&i| massless(i)) else {
            continue;
        };
        let message = if r.clone().all(|j| b.system.mass[j] <= 0.0) {
            let material = if e.kind == ElementKind::Cloth {
                "discrete shell"
            } else {
                "rod"
            };
            format!(
                "vertex {} has no mass: no material Behavior in the tree applies to this {} (add a {material} material)",
                i - r.start,
                e.kind.name()
            )
        } else {
            let what = if e.kind == ElementKind::Cloth {
                "triangle"
            } else {
                "segment"
            };
            format!(
                "vertex {} is in no {what}, so it has no mass (unused vertices cannot be simulated: remove or pin it)",
                i - r.start
            )
        };
        return Err(SimError::BadGeometry {
            element: e.name.clone(),
            message,
        });
    }
    Ok(())
}

/// Contact bands against the start state, now that every held vertex is known: refused, or
/// their warnings added.
fn check_bands(scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
    if let Some(setup) = &b.collisions {
        let start = crate::collide::band::Start {
            scene,
            x: &b.x,
            pinned: &b.system.pinned,
            ranges: &b.ranges,
        };
        let mut found = Vec::new();
        crate::collide::band::check(setup, &start, &mut |w| found.push(w))?;
        found.into_iter().for_each(|w| b.warn(w));
    }
    Ok(())
}

/// Drag elements without a fluid feel nothing, and a fluid without drag elements moves no
/// solid: either is said.
fn warn_fluid(fluid: Option<&crate::FluidSpec>, b: &mut SystemBuilder) {
    match (fluid, b.drag_elements.is_empty()) {
        (None, false) => b.warn(format!(
            "the Fluid Drag Behavior made {} drag elements but the scene has no fluid domain: they feel no fluid",
            b.drag_elements.len()
        )),
        (Some(f), true) => b.warn(format!(
            "the scene has the fluid domain '{}' but no Behavior couples a solid to it (add behavior.fluid_drag)",
            f.element
        )),
        _ => {}
    }
}

/// Every SEC that no Behavior read for its element is said, by element and type.
fn warn_unread(scene: &[SceneElement], b: &mut SystemBuilder) {
    for (ei, e) in scene.iter().enumerate() {
        for t in e.secs.types() {
            if !b.read[ei].contains(t) {
                let w = format!(
                    "element '{}' carries a '{t}' SEC that no Behavior in the tree reads for it",
                    e.name
                );
                b.warn(w);
            }
        }
    }
}

/// The terms in the built system, by kind (`n`: the vertices, ghosts included).
fn term_counts(b: &SystemBuilder, n: usize) -> BTreeMap<&'static str, usize> {
    let el = &b.system.elements;
    BTreeMap::from([
        ("membranes", el.membranes.len()),
        ("shell_bends", el.shells.len()),
        ("shell_midedges", el.midedges.len()),
        ("shell_clamps", el.shell_clamps.len()),
        ("rod_stretches", el.stretches.len()),
        ("rod_bends", el.bends.len()),
        ("rod_clamps", el.clamps.len()),
        ("cloth_clamp_ghosts", b.ghosts.len()),
        ("springs", el.springs.len()),
        ("frozen", b.freezes.len()),
        ("drag_elements", b.drag_elements.len()),
        (
            "contact_pairs",
            b.collisions.as_ref().map_or(0, |c| c.pairs.len()),
        ),
        ("pinned", b.system.pinned.iter().filter(|p| **p).count()),
        ("vertices", n),
    ])
}

impl Compiled {
    /// Each frozen vertex's input position in `scene` (checked by [`Compiled::check_scene`]
    /// first: the elements have the vertex counts they were compiled with).
    pub fn freeze_inputs(&self, scene: &[SceneElement]) -> Vec<Vector3<f64>> {
        crate::freeze::inputs(&self.freezes, scene)
    }

    /// The frozen vertices' frame to `scene` (the scene at `frame`) from their inputs at the
    /// previous frame, `start` (`freeze::frame`).
    pub fn freeze_frame(
        &self,
        scene: &[SceneElement],
        start: &[Vector3<f64>],
        frame: i64,
        frame_dt: f64,
    ) -> Result<crate::freeze::FreezeFrame, SimError> {
        crate::freeze::frame(&self.freezes, scene, start, frame, frame_dt)
    }

    /// Sets the frozen vertices' targets at fraction `s` of `frame` (`freeze::set`).
    pub fn set_freeze(&self, frame: &crate::freeze::FreezeFrame, s: f64, system: &mut SolidSystem) {
        crate::freeze::set(&self.freezes, self.base_sliders, frame, s, system)
    }
}

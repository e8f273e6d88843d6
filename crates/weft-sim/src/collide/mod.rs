//! Contacts with kinematic colliders: collision groups compiled from the scene, and the
//! detection that hands `weft_solid`'s contact step its contacts (issue 13; the plan and the
//! derivations are in `docs/contacts.md`).
//!
//! **Setup** ([`Collision`], the `behavior.collision` Behavior): every data-less collision
//! element (a Collision Group SEC and a Collision Response SEC) pairs its member cloth and hair
//! elements with its colliders; each pair gets its contact parameters from both sides' Collider
//! SECs. A scene without collision elements builds nothing.
//!
//! **Detection** ([`Detector`]), once per step and per collider, in the collider's own frame
//! (its mesh at the frame, placed by its transform interpolated over the frame as attachments
//! are): a rigidly moving collider's tree never changes, and a deforming one's is refit, not
//! rebuilt, when its shape changes. A vertex within reach of a triangle (the distance kept
//! plus its predicted travel) gets a contact whose plane separates it from that triangle:
//! normal from the closest point, the constraint n·(x_end − q_end) ≥ thickness on the end of
//! step. The triangle is convex, so a vertex that starts and ends on the plane's side never
//! crossed it. After the step, an exact check of every vertex's path against the triangles
//! near it adds a contact for any triangle the path crossed or ended too close to, and the
//! step is solved again (CCD by growing the active set: a vertex falling at 10 m/s onto a
//! thin plane is stopped whatever the step).

pub(crate) mod band;
pub(crate) mod bvh;
pub(crate) mod ccd;
pub(crate) mod geometry;
mod solids;
mod step;

pub use step::{ContactFrameStats, Contacts};

use crate::behavior::{bad, checked, non_negative};
use crate::builder::SystemBuilder;
use crate::error::SimError;
use bvh::TriangleTree;
use geometry::{closest_on_triangle, closest_segment_triangle, frame, segment_crosses_triangle};
use nalgebra::Vector3;
use std::collections::{BTreeMap, BTreeSet};
use std::ops::Range;
use weft_scene::{
    Collider, CollisionGroup, CollisionResponse, ElementKind, Geometry, Members, Rod, SceneElement,
    Transform,
};
use weft_solid::integrator::Contact;

type V = Vector3<f64>;

/// A collider element as compiled: its triangles and whether its mesh is closed.
#[derive(Clone, Debug, PartialEq)]
pub struct ColliderSetup {
    /// Scene index of the collider element.
    pub element: usize,
    /// Its triangles.
    pub triangles: Vec<[u32; 3]>,
    /// Every edge in exactly two triangles, oppositely oriented: inside and outside are
    /// defined, so a vertex found inside is pushed out through the nearest face. Otherwise
    /// only distance is (a vertex is kept on the side it comes from).
    pub closed: bool,
    /// Closed meshes: per triangle, the triangle across each edge k (from corner k to
    /// k + 1), for the edge's pseudo-normal (empty for open meshes).
    pub across: Vec<[u32; 3]>,
}

/// One simulated element against one collider, with the contact parameters of the pair.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactPair {
    /// Scene index of the simulated (cloth or hair) element.
    pub element: usize,
    /// Index into [`CollisionSetup::colliders`].
    pub collider: usize,
    /// Scene index of the collision element that made the pair.
    pub group: usize,
    /// Friction coefficient μ of the contact.
    pub friction: f64,
    /// Distance kept between the vertex and the collider's surface [m].
    pub distance: f64,
    /// Cohesion [Pa].
    pub cohesion: f64,
    /// Fraction of an existing penetration resolved per step.
    pub strength: f64,
    /// Damping of the normal relative velocity [1/s].
    pub damping: f64,
    /// Vertex–face detection on (the group's `vertex_face`).
    pub vertices: bool,
    /// Segment–face detection on (the group's `segment_face`; hair only).
    pub segments: bool,
}

/// Two simulated elements that collide (or one with itself), with the contact parameters of
/// the pair.
#[derive(Clone, Debug, PartialEq)]
pub struct SolidPair {
    /// Scene indices of the two elements, `a ≤ b` (equal: self-collision).
    pub a: usize,
    /// See `a`.
    pub b: usize,
    /// Scene index of the collision element that made the pair.
    pub group: usize,
    /// Friction coefficient μ (the geometric mean of both sides').
    pub friction: f64,
    /// Distance kept between the two surfaces [m] (both sides' thicknesses).
    pub distance: f64,
    /// Cohesion [Pa] (the larger side's).
    pub cohesion: f64,
    /// Fraction of an existing penetration resolved per step.
    pub strength: f64,
    /// Damping of the normal relative velocity [1/s].
    pub damping: f64,
    /// Vertex–face detection on (vertices against the other side's cloth triangles).
    pub vertices: bool,
    /// Edge–edge detection on (cloth edges and hair segments against the other side's).
    pub edges: bool,
}

/// Every collider and contact pair of a scene, and each simulated vertex's contact area.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CollisionSetup {
    /// The colliders that some pair uses.
    pub colliders: Vec<ColliderSetup>,
    /// The pairs, by collision element, then member, then collider.
    pub pairs: Vec<ContactPair>,
    /// The pairs of simulated elements that collide, by collision element, then members
    /// (a pair made by two collision elements is kept once, the first).
    pub solid_pairs: Vec<SolidPair>,
    /// Per scene element, its cloth triangles as global vertex indices (empty for the rest).
    pub triangles: Vec<Vec<[u32; 3]>>,
    /// Per scene element, its cloth edges (each once, lower vertex first) as global vertex
    /// indices (empty for the rest; hair's are its `segments`).
    pub edges: Vec<Vec<[u32; 2]>>,
    /// Contact area of each global vertex [m²] (cloth: a third of its triangles' areas; hair:
    /// half its segments' lengths × the fibre's diameter).
    pub areas: Vec<f64>,
    /// Per scene element, its hair segments as global vertex pairs (empty for the rest).
    pub segments: Vec<Vec<[u32; 2]>>,
}

/// Closed: every undirected edge in exactly two triangles, once in each direction.
fn is_closed(triangles: &[[u32; 3]]) -> bool {
    let mut directed: BTreeMap<(u32, u32), u32> = BTreeMap::new();
    for t in triangles {
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    directed
        .iter()
        .all(|(&(a, b), &n)| n == 1 && directed.get(&(b, a)) == Some(&1))
}

/// Contacts with colliders: pairs every collision element's member cloth and hair elements
/// with its colliders (Collision Group SEC), with the response of its Collision Response SEC
/// and both sides' Collider SECs (or their defaults). Without collision elements it builds
/// nothing (and says so).
#[derive(Clone, Debug, Default)]
pub struct Collision;

impl crate::Behavior for Collision {
    fn name(&self) -> &'static str {
        "collision"
    }
    fn reads(&self) -> &'static [&'static str] {
        &["collision_group", "collision_response", "collider"]
    }
    fn apply(&self, scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        let groups: Vec<usize> = (0..scene.len())
            .filter(|&i| scene[i].kind == ElementKind::Collision)
            .collect();
        if groups.is_empty() {
            b.warn("behavior.collision is in the tree but the scene has no collision element (convert.collision_group): nothing collides".into());
            return Ok(());
        }
        let simulated = |e: &SceneElement| matches!(e.kind, ElementKind::Cloth | ElementKind::Hair);
        let mut setup = CollisionSetup::default();
        let mut collider_index: BTreeMap<usize, usize> = BTreeMap::new();
        for &gi in &groups {
            let g = &scene[gi];
            b.read(gi, "collision_group");
            b.read(gi, "collision_response");
            let group = g.secs.get::<CollisionGroup>().cloned().unwrap_or_default();
            let response = g
                .secs
                .get::<CollisionResponse>()
                .cloned()
                .unwrap_or_default();
            if !(response.strength > 0.0 && response.strength <= 1.0) {
                return Err(bad(
                    &g.name,
                    "collision_response.strength",
                    format!("must be in (0, 1], got {}", response.strength),
                ));
            }
            non_negative(&g.name, "collision_response.damping", response.damping)?;
            for (field, members, want) in [
                ("collision_group.members", &group.members, "a cloth or hair"),
                ("collision_group.colliders", &group.colliders, "a collider"),
            ] {
                if let Members::Names(names) = members {
                    for n in names {
                        let Some(e) = scene.iter().find(|e| &e.name == n) else {
                            let known: Vec<&str> = scene.iter().map(|e| e.name.as_str()).collect();
                            return Err(bad(
                                &g.name,
                                field,
                                format!("'{n}' is not an element of the scene (it has {known:?})"),
                            ));
                        };
                        let ok = if want == "a collider" {
                            e.kind == ElementKind::Collider
                        } else {
                            simulated(e)
                        };
                        if !ok {
                            return Err(bad(
                                &g.name,
                                field,
                                format!("'{n}' is a {} element, not {want} element", e.kind.name()),
                            ));
                        }
                    }
                }
            }
            if !group.vertex_face && !group.segment_face && !group.edge_edge {
                b.warn(format!(
                    "collision element '{}' has no detection method on: it makes no contacts",
                    g.name
                ));
                continue;
            }
            let members: Vec<usize> = (0..scene.len())
                .filter(|&i| simulated(&scene[i]) && group.members.contains(&scene[i].name))
                .collect();
            let colliders: Vec<usize> = (0..scene.len())
                .filter(|&i| {
                    scene[i].kind == ElementKind::Collider
                        && group.colliders.contains(&scene[i].name)
                })
                .collect();
            let solids = group.self_collision || (group.between_members && members.len() > 1);
            if members.is_empty() || (colliders.is_empty() && !solids) {
                b.warn(format!(
                    "collision element '{}' has {} member(s) and {} collider(s), and its members collide neither with each other nor with themselves: it makes no contacts",
                    g.name,
                    members.len(),
                    colliders.len()
                ));
            }
            for (k, &ma) in members.iter().enumerate() {
                for &mb in &members[k..] {
                    let wanted = if ma == mb {
                        group.self_collision
                    } else {
                        group.between_members
                    };
                    if !wanted
                        || setup.solid_pairs.iter().any(|p| (p.a, p.b) == (ma, mb))
                        || !(group.vertex_face || group.edge_edge)
                    {
                        continue;
                    }
                    let sec = |m: usize| -> Result<Collider, SimError> {
                        let c = scene[m].secs.get::<Collider>().cloned().unwrap_or_default();
                        checked(&scene[m].name, &c)?;
                        Ok(c)
                    };
                    b.read(ma, "collider");
                    b.read(mb, "collider");
                    let (ca, cb) = (sec(ma)?, sec(mb)?);
                    setup.solid_pairs.push(SolidPair {
                        a: ma,
                        b: mb,
                        group: gi,
                        friction: (ca.friction * cb.friction).sqrt(),
                        distance: ca.thickness + cb.thickness,
                        cohesion: ca.cohesion.max(cb.cohesion),
                        strength: response.strength,
                        damping: response.damping,
                        vertices: group.vertex_face,
                        edges: group.edge_edge,
                    });
                }
            }
            for &m in &members {
                b.read(m, "collider");
                let ms = scene[m].secs.get::<Collider>().cloned().unwrap_or_default();
                checked(&scene[m].name, &ms)?;
                for &c in &colliders {
                    b.read(c, "collider");
                    let k = match collider_index.get(&c) {
                        Some(&k) => k,
                        None => {
                            let k = setup.colliders.len();
                            if let Some(cs) = scene[c].secs.get::<Collider>() {
                                checked(&scene[c].name, cs)?;
                            }
                            setup.colliders.push(collider_setup(&scene[c], c, b)?);
                            collider_index.insert(c, k);
                            k
                        }
                    };
                    let (friction, distance, cohesion) = match scene[c].secs.get::<Collider>() {
                        Some(cs) => (
                            (ms.friction * cs.friction).sqrt(),
                            ms.thickness + cs.thickness,
                            ms.cohesion.max(cs.cohesion),
                        ),
                        None => (ms.friction, ms.thickness, ms.cohesion),
                    };
                    setup.pairs.push(ContactPair {
                        element: m,
                        collider: k,
                        group: gi,
                        friction,
                        distance,
                        cohesion,
                        strength: response.strength,
                        damping: response.damping,
                        vertices: group.vertex_face,
                        segments: group.segment_face && scene[m].kind == ElementKind::Hair,
                    });
                }
            }
        }
        setup.areas = contact_areas(scene, b);
        setup.segments = hair_segments(scene, b);
        if !setup.solid_pairs.is_empty() {
            (setup.triangles, setup.edges) = cloth_surfaces(scene, b);
        }
        b.collisions = Some(setup);
        Ok(())
    }
}

fn collider_setup(
    e: &SceneElement,
    element: usize,
    b: &mut SystemBuilder,
) -> Result<ColliderSetup, SimError> {
    let Geometry::Mesh(m) = &*e.geometry else {
        return Err(SimError::BadGeometry {
            element: e.name.clone(),
            message: "a collider needs a triangle mesh".into(),
        });
    };
    if m.triangles.is_empty() {
        return Err(SimError::BadGeometry {
            element: e.name.clone(),
            message: "the collider has no triangles: there is nothing to collide with".into(),
        });
    }
    let n = m.positions.len() as u32;
    if let Some((ti, t)) = m
        .triangles
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&v| v >= n))
    {
        return Err(SimError::BadGeometry {
            element: e.name.clone(),
            message: format!("triangle {ti} {t:?} uses a vertex beyond the {n} the mesh has"),
        });
    }
    if let Some(i) = m
        .positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(SimError::BadGeometry {
            element: e.name.clone(),
            message: format!("vertex {i} has a non-finite position {:?}", m.positions[i]),
        });
    }
    let closed = is_closed(&m.triangles);
    let mut triangles = m.triangles.clone();
    if closed {
        // Inside is behind the faces: orient them outwards (positive enclosed volume).
        let p = |v: u32| V::from(m.positions[v as usize]);
        let volume: f64 = triangles
            .iter()
            .map(|t| p(t[0]).dot(&p(t[1]).cross(&p(t[2]))))
            .sum();
        if volume < 0.0 {
            for t in &mut triangles {
                t.swap(1, 2);
            }
        }
    }
    if !closed {
        b.warn(format!(
            "collider '{}' is not a closed, consistently oriented mesh: its inside is not defined, so contacts keep each vertex on the side it comes from (only distance is used)",
            e.name
        ));
    }
    let across = if closed {
        let mut by_edge: BTreeMap<(u32, u32), u32> = BTreeMap::new();
        for (ti, t) in triangles.iter().enumerate() {
            for k in 0..3 {
                by_edge.insert((t[k], t[(k + 1) % 3]), ti as u32);
            }
        }
        // Closed: every directed edge's reverse is in exactly one other triangle.
        triangles
            .iter()
            .map(|t| [0, 1, 2].map(|k| by_edge[&(t[(k + 1) % 3], t[k])]))
            .collect()
    } else {
        Vec::new()
    };
    Ok(ColliderSetup {
        element,
        triangles,
        closed,
        across,
    })
}

fn contact_areas(scene: &[SceneElement], b: &SystemBuilder) -> Vec<f64> {
    let mut areas = vec![0.0; b.x.len()];
    for (ei, e) in scene.iter().enumerate() {
        let Some(r) = b.ranges.get(ei).cloned().flatten() else {
            continue;
        };
        let p = |i: u32| b.x[r.start + i as usize];
        match &*e.geometry {
            Geometry::Mesh(m) => {
                for t in &m.triangles {
                    if t.iter().any(|&v| v as usize >= r.len()) {
                        continue; // the material Behavior reports it
                    }
                    let a = 0.5 * (p(t[1]) - p(t[0])).cross(&(p(t[2]) - p(t[0]))).norm();
                    for &v in t {
                        areas[r.start + v as usize] += a / 3.0;
                    }
                }
            }
            Geometry::Curves(c) => {
                let d = 2.0 * e.secs.get::<Rod>().cloned().unwrap_or_default().radius;
                for k in 0..c.len() {
                    let cr = c.range(k);
                    for v in cr.start..cr.end.saturating_sub(1) {
                        let l = (p(v as u32 + 1) - p(v as u32)).norm();
                        areas[r.start + v] += 0.5 * l * d;
                        areas[r.start + v + 1] += 0.5 * l * d;
                    }
                }
            }
            _ => {}
        }
    }
    areas
}

/// Per element, its cloth triangles and edges (each once) in global vertex indices.
type Surfaces = (Vec<Vec<[u32; 3]>>, Vec<Vec<[u32; 2]>>);

fn cloth_surfaces(scene: &[SceneElement], b: &SystemBuilder) -> Surfaces {
    let mut triangles = vec![Vec::new(); scene.len()];
    let mut edges = vec![Vec::new(); scene.len()];
    for (ei, e) in scene.iter().enumerate() {
        let (Some(r), Geometry::Mesh(m), ElementKind::Cloth) =
            (b.ranges.get(ei).cloned().flatten(), &*e.geometry, e.kind)
        else {
            continue;
        };
        let mut set = BTreeSet::new();
        for t in &m.triangles {
            if t.iter().any(|&v| v as usize >= r.len()) {
                continue; // the material Behavior reports it
            }
            let g = t.map(|v| (r.start + v as usize) as u32);
            triangles[ei].push(g);
            for k in 0..3 {
                let (p, q) = (g[k], g[(k + 1) % 3]);
                set.insert([p.min(q), p.max(q)]);
            }
        }
        edges[ei] = set.into_iter().collect();
    }
    (triangles, edges)
}

fn hair_segments(scene: &[SceneElement], b: &SystemBuilder) -> Vec<Vec<[u32; 2]>> {
    scene
        .iter()
        .enumerate()
        .map(|(ei, e)| {
            let (Some(r), Geometry::Curves(c)) =
                (b.ranges.get(ei).cloned().flatten(), &*e.geometry)
            else {
                return Vec::new();
            };
            (0..c.len())
                .flat_map(|k| {
                    let cr = c.range(k);
                    (cr.start..cr.end.saturating_sub(1))
                        .filter(|&v| v + 1 < r.len())
                        .map(|v| [(r.start + v) as u32, (r.start + v + 1) as u32])
                        .collect::<Vec<_>>()
                })
                .collect()
        })
        .collect()
}

/// A collider during a frame: its mesh in its own frame and the tree over it.
struct Live {
    local: Vec<V>,
    /// Closed meshes: each vertex's angle-weighted pseudo-normal (Bærentzen & Aanæs 2005),
    /// which decides inside and outside where the closest point is that vertex.
    vertex_normals: Vec<V>,
    tree: TriangleTree,
    from: Option<Transform>,
    to: Option<Transform>,
}

/// The angle-weighted pseudo-normal of every vertex of a closed mesh (empty for open ones).
fn vertex_normals(c: &ColliderSetup, p: &[V]) -> Vec<V> {
    if !c.closed {
        return Vec::new();
    }
    let mut n = vec![V::zeros(); p.len()];
    for t in &c.triangles {
        let x = t.map(|v| p[v as usize]);
        let face = face_normal(&x);
        for k in 0..3 {
            let (e1, e2) = (x[(k + 1) % 3] - x[k], x[(k + 2) % 3] - x[k]);
            let angle = e1.angle(&e2);
            if angle.is_finite() {
                n[t[k] as usize] += angle * face;
            }
        }
    }
    n
}

impl Live {
    /// Triangle `t` of collider `c` in the collider's own frame.
    fn triangle(&self, c: &ColliderSetup, t: u32) -> [V; 3] {
        c.triangles[t as usize].map(|v| self.local[v as usize])
    }

    fn at(&self, s: f64) -> Option<Transform> {
        crate::build::lerp(self.from, self.to, s)
    }
}

/// Where a contact came from: (vertex, collider, triangle, [`VERTEX`]) for a vertex's,
/// (its first vertex, collider, triangle, [`bin`] of the point) for a segment's.
type Key = (u32, u32, u32, u32);

/// The last field of a vertex contact's [`Key`].
const VERTEX: u32 = u32::MAX;

/// Which 1024th of a segment the point at `s` is in: a contact holds its own point, and a
/// point of the segment beside it can still end too close (the segment turns over the
/// step), so only a contact at nearly the same point counts as one already there.
fn bin(s: f64) -> u32 {
    (s * 1024.0).clamp(0.0, 1023.0) as u32
}

/// Finds contacts each step (see the module doc). Holds no simulation state: the colliders'
/// shapes and transforms come from the scene each frame.
pub struct Detector {
    live: Vec<Live>,
    candidates: Vec<u32>,
    keys: BTreeSet<Key>,
    /// The most contacts a step may hold ([`Room`]).
    room: usize,
    /// Whether this step's detection stopped at `room` (taken by [`Self::take_overflow`]).
    overflow: bool,
}

/// Bytes one contact takes at most over a step: the contact (176), its detection key, and
/// the contact step's state for it (its active entry, ADMM's vectors, the impulses kept for
/// the next round, the blocks it adds between solids): about 700 from the types' sizes,
/// rounded up.
pub const CONTACT_BYTES: u64 = 1024;

/// Bytes a candidate pair of primitives takes in the broad phase between solids (the trees'
/// pair, the filtered candidate and the narrow phase's entry: about 100), rounded up.
pub const PAIR_BYTES: u64 = 128;

/// How many contacts, and candidate pairs of primitives between solids, one step's detection
/// may hold: a quarter of the memory allowed each (a list may hold twice its length while it
/// grows). A contact band that takes in most of a scene (a thickness in metres where
/// millimetres were meant) would otherwise grow these lists as the product of the primitive
/// counts; detection stops at the room instead, and the step fails naming the band.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Room {
    /// Contacts.
    pub contacts: usize,
    /// Candidate pairs of primitives.
    pub pairs: usize,
}

impl Room {
    /// The room within `max_bytes` (`None`: unbounded).
    pub fn within(max_bytes: Option<u64>) -> Self {
        let of = |each: u64| {
            max_bytes.map_or(usize::MAX, |m| {
                usize::try_from(m / 4 / each).unwrap_or(usize::MAX)
            })
        };
        Room {
            contacts: of(CONTACT_BYTES),
            pairs: of(PAIR_BYTES),
        }
    }
}

/// Rounds of exact checking allowed per step before the step is accepted as it is (and its
/// penetration reported).
pub(crate) const MAX_ROUNDS: usize = 4;
/// Rounds allowed while the last check still added hair segment contacts. A segment sliding
/// over a faceted collider is linearized at one point a round, and the point that ends
/// deepest moves along the segment from round to round (hair_on_head, frame 12: 0.30, 0.32,
/// 0.22 mm at s = 0.36, 0.50, 0.62 of one segment); four rounds let a step end a segment
/// 0.1 mm inside the 2 mm kept whenever the solves' rounding changed. Eight rounds for every
/// contact cost the cloth pile 20 % for nothing; segments alone need them.
pub(crate) const MAX_SEGMENT_ROUNDS: usize = 8;

/// What an exact check found.
#[derive(Clone, Copy, Debug, Default)]
pub struct Checked {
    /// Contacts added.
    pub added: usize,
    /// Of those, contacts of hair segments (between their vertices).
    pub segments: usize,
    /// The largest penetration at the step's end [m].
    pub deepest: f64,
}

fn local_positions(e: &SceneElement, to: Option<Transform>) -> Vec<V> {
    e.geometry
        .positions()
        .iter()
        .map(|p| {
            let w = V::new(p[0], p[1], p[2]);
            match to {
                Some(t) => t.inverse_transform_point(&w.into()).coords,
                None => w,
            }
        })
        .collect()
}

impl Detector {
    /// A detector for `setup`'s colliders as they are in `scene`, holding at most `room`
    /// contacts a step.
    pub fn new(setup: &CollisionSetup, scene: &[SceneElement], room: usize) -> Self {
        let live = setup
            .colliders
            .iter()
            .map(|c| {
                let e = &scene[c.element];
                let local = local_positions(e, e.transform);
                let tree = TriangleTree::new(&local, &c.triangles);
                Live {
                    vertex_normals: vertex_normals(c, &local),
                    local,
                    tree,
                    from: e.transform,
                    to: e.transform,
                }
            })
            .collect();
        Detector {
            live,
            candidates: Vec::new(),
            keys: BTreeSet::new(),
            room,
            overflow: false,
        }
    }

    /// Holds at most `room` contacts a step from now on.
    pub fn set_room(&mut self, room: usize) {
        self.room = room;
    }

    /// Whether detection since the last call stopped at its room: the step's contacts are
    /// then incomplete.
    pub fn take_overflow(&mut self) -> bool {
        std::mem::take(&mut self.overflow)
    }

    /// Before stepping a frame: each collider's transforms at the frame's start and end and
    /// its shape at the end (the tree is refit when the shape changed).
    pub fn frame(
        &mut self,
        setup: &CollisionSetup,
        scene: &[SceneElement],
        from: &[Option<Transform>],
        to: &[Option<Transform>],
    ) -> Result<(), SimError> {
        for (c, live) in setup.colliders.iter().zip(&mut self.live) {
            let e = &scene[c.element];
            live.from = from.get(c.element).copied().flatten();
            live.to = to.get(c.element).copied().flatten();
            if e.vertex_count() != live.local.len() {
                return Err(SimError::SceneChanged(format!(
                    "collider '{}' has {} vertices but had {} at the start",
                    e.name,
                    e.vertex_count(),
                    live.local.len()
                )));
            }
            let local = local_positions(e, live.to);
            if local != live.local {
                if let Some(i) = local.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
                    return Err(SimError::BadGeometry {
                        element: e.name.clone(),
                        message: format!("vertex {i} has a non-finite position"),
                    });
                }
                live.local = local;
                live.tree.refit(&live.local, &c.triangles);
                live.vertex_normals = vertex_normals(c, &live.local);
            }
        }
        Ok(())
    }

    /// The contacts for a step of `h` from `x0`, `v0` between fractions `s0` and `s1` of the
    /// frame, replacing `out`. `pinned`: vertices that do not move (no contacts).
    #[allow(clippy::too_many_arguments)]
    pub fn detect(
        &mut self,
        setup: &CollisionSetup,
        ranges: &[Option<Range<usize>>],
        pinned: &[bool],
        x0: &[V],
        v0: &[V],
        (s0, s1, h): (f64, f64, f64),
        out: &mut Vec<Contact>,
    ) {
        out.clear();
        self.keys.clear();
        let (candidates, keys) = (&mut self.candidates, &mut self.keys);
        let (room, mut overflow) = (self.room, false);
        let pass = Pass {
            setup,
            ranges,
            pinned,
            live: &self.live,
            x0,
            s: (s0, s1),
        };
        let ends = |i: usize| x0[i] + h * v0[i];
        pass.vertices(ends, |at| {
            let (pair, c, live, i, a, b) = (at.pair, at.collider, at.live, at.vertex, at.a, at.b);
            let reach = 1.25 * pair.distance + (b - a).norm();
            let pad = V::repeat(reach);
            candidates.clear();
            live.tree.query(&(a - pad), &(a + pad), candidates);
            // The closest triangle within reach (ties: the lower index), only: a neighbour's
            // edge near the vertex would make a tilted plane through that edge (measured: a
            // patch sliding across a coplanar pair of triangles lost 40 % of a frame's
            // acceleration to them); the exact check adds the triangles a path really meets
            // (a concave corner's second face) instead.
            if let Some((d, t, w)) = nearest(c, live, candidates, &a)
                && d <= reach
            {
                if out.len() >= room {
                    overflow = true;
                    return;
                }
                keys.insert((i as u32, pair.collider as u32, t, VERTEX));
                out.push(contact(setup, &at, (t, w), x0, h, None));
            }
        });
        // Hair segments: the closest triangle within reach whose closest point is inside the
        // segment (between its vertices, whose own contacts hold the ends): a strand lying
        // over a curved collider touches it between its vertices (a 25 mm segment on a
        // 0.1 m head: hair_on_head's segments came to 0.68 mm of the 2 mm kept with vertex
        // contacts alone).
        pass.segments(ends, |sg| {
            let ([a0, a1], [b0, b1]) = (sg.a, sg.b);
            let travel = (b0 - a0).norm().max((b1 - a1).norm());
            let reach = 1.25 * sg.pair.distance + travel;
            let pad = V::repeat(reach);
            candidates.clear();
            sg.live
                .tree
                .query(&(a0.inf(&a1) - pad), &(a0.sup(&a1) + pad), candidates);
            if rooted(&sg, pinned, candidates) {
                return;
            }
            // Two points: the one closest to a triangle at the step's start and the one
            // closest at its predicted end (x₀ + h v₀). A strand sliding over a curved
            // collider touches it where it will be, not where it was: with the start's point
            // alone, hair_on_head's contact steps were solved again 58 times in 48 steps,
            // each check adding the points the segments sagged at (up to 1.05 mm inside the 2 mm
            // kept); with both, 37 times (Newton iterations a step 11.29 → 10.54). The end's
            // point only for a segment that has the start's (one closest at its ends at the
            // start is its vertices' to hold; adding theirs too: 44 times). More points along
            // each segment (fixed fractions) cut the rounds further but made the coupled
            // hair_underwater's stage C stall (redundant planes on one segment).
            let start = closest_inside(&sg, candidates, (&a0, &a1), reach);
            let end =
                start.and_then(|_| closest_inside(&sg, candidates, (&b0, &b1), f64::INFINITY));
            for s in [start, end].into_iter().flatten() {
                // The plane is the point's own, from its nearest triangle (as a vertex's
                // is): the segment's closest triangle need not be the point's, and its
                // face would misjudge inside and outside.
                let p = (1.0 - s) * a0 + s * a1;
                if let Some((d, tp, w)) = nearest(sg.collider, sg.live, candidates, &p)
                    && d <= reach
                {
                    let first = sg.vertices[0] as u32;
                    if out.len() >= room {
                        overflow = true;
                        return;
                    }
                    if keys.insert((first, sg.pair.collider as u32, tp, bin(s))) {
                        // `tp` is the point's nearest triangle: its pseudo-normal tells inside
                        // from outside (a point behind a face near a convex edge included).
                        out.push(segment_contact(&sg, (s, tp, w), x0, h, Side::Nearest));
                    }
                }
            }
        });
        self.overflow |= overflow;
    }

    /// The exact check after a step from `x0` to `x1`: every vertex's path (in each
    /// collider's frame) against the triangles near it. A triangle the path crossed, or that
    /// the end is closer to than the distance kept (less a thousandth of it), and that has no
    /// contact with the vertex yet, gets one (appended to `contacts`); hair segments too (below).
    #[allow(clippy::too_many_arguments)]
    pub fn check(
        &mut self,
        setup: &CollisionSetup,
        ranges: &[Option<Range<usize>>],
        pinned: &[bool],
        x0: &[V],
        x1: &[V],
        (s0, s1, h): (f64, f64, f64),
        contacts: &mut Vec<Contact>,
    ) -> Checked {
        let mut added = 0;
        let mut segments = 0;
        let mut deepest = 0.0f64;
        let (candidates, keys) = (&mut self.candidates, &mut self.keys);
        let (room, mut overflow) = (self.room, false);
        let pass = Pass {
            setup,
            ranges,
            pinned,
            live: &self.live,
            x0,
            s: (s0, s1),
        };
        pass.vertices(
            |i| x1[i],
            |at| {
                let (pair, c, live, i, a, b) =
                    (at.pair, at.collider, at.live, at.vertex, at.a, at.b);
                let pad = V::repeat(pair.distance);
                candidates.clear();
                live.tree
                    .query(&(a.inf(&b) - pad), &(a.sup(&b) + pad), candidates);
                candidates.sort_unstable();
                // Inside or outside is the nearest triangle's call, not each candidate's.
                let judged_b = judged_nearest(c, live, candidates, &b);
                let (inside_a, inside_b) = (
                    inside_closed(c, live, candidates, &a),
                    judged_b.map(|(inside, _)| inside),
                );
                // A vertex that ends inside (a start inside, leaving by `strength` of its
                // depth a step) is as deep as its nearest triangle says, and leaves through
                // it: another triangle's closest point is not on its way out, and a contact
                // there pushed it towards that point (measured: a strand 1.1 mm under a
                // notched block's top turned 14 mm sideways in one step).
                let nearest_b = judged_b.and_then(|(inside, t)| inside.then_some(t));
                // The path enters the collider through `tri`.
                let crosses = |tri: &[V; 3]| {
                    segment_crosses_triangle(&a, &b, &tri[0], &tri[1], &tri[2])
                        && (!c.closed || face_normal(tri).dot(&(b - a)) < 0.0)
                };
                for &t in candidates.iter() {
                    let tri = live.triangle(c, t);
                    // Tested here only where an inside end skips the triangle, and kept.
                    let crossed_here = nearest_b.is_some_and(|n| n != t).then(|| crosses(&tri));
                    if crossed_here == Some(false) {
                        continue;
                    }
                    let wb = closest_on_triangle(&b, &tri[0], &tri[1], &tri[2]);
                    let (_, signed) = side(c, live, t, &wb, (&b, &b), inside_b);
                    let clearance = signed - pair.distance;
                    if !keys.insert((i as u32, pair.collider as u32, t, VERTEX)) {
                        // Its contact holds it (to the solver's tolerance): measure only.
                        deepest = deepest.max(-clearance);
                        continue;
                    }
                    let crossed = crossed_here.unwrap_or_else(|| crosses(&tri));
                    if (crossed || clearance < -1e-3 * pair.distance) && contacts.len() >= room {
                        overflow = true;
                        keys.remove(&(i as u32, pair.collider as u32, t, VERTEX));
                        return;
                    }
                    if crossed || clearance < -1e-3 * pair.distance {
                        let wa = closest_on_triangle(&a, &tri[0], &tri[1], &tri[2]);
                        contacts.push(contact(setup, &at, (t, wa), x0, h, inside_a));
                        added += 1;
                        let depth = if crossed { pair.distance } else { -clearance };
                        deepest = deepest.max(depth);
                    } else {
                        keys.remove(&(i as u32, pair.collider as u32, t, VERTEX));
                    }
                }
            },
        );
        // Hair segments at the step's end against the triangles near their sweep: one that
        // ended closer than the distance kept (or through a triangle) at a point inside it
        // gets a contact there. A segment that swept across a collider's edge and ended
        // clear of it is not seen (edge–edge continuous detection is issue 14's).
        pass.segments(
            |i| x1[i],
            |sg| {
                let ([a0, a1], [b0, b1]) = (sg.a, sg.b);
                let pad = V::repeat(sg.pair.distance);
                let (lo, hi) = (a0.inf(&a1).inf(&b0).inf(&b1), a0.sup(&a1).sup(&b0).sup(&b1));
                candidates.clear();
                sg.live.tree.query(&(lo - pad), &(hi + pad), candidates);
                candidates.sort_unstable();
                if rooted(&sg, pinned, candidates) {
                    return;
                }
                // The segment's least clearance at the end, over the triangles near it.
                let mut worst: Option<(f64, u32, f64)> = None;
                for &t in candidates.iter() {
                    let tri = sg.live.triangle(sg.collider, t);
                    let (s, _, d) = closest_segment_triangle(&b0, &b1, &tri[0], &tri[1], &tri[2]);
                    let clearance = d - sg.pair.distance;
                    if worst.is_none_or(|(c, _, _)| clearance < c) {
                        worst = Some((clearance, t, s));
                    }
                }
                let Some((clearance, t, s)) = worst.filter(|&(_, _, s)| inside_segment(s)) else {
                    return; // clear, or closest at an end: the vertices' own check
                };
                deepest = deepest.max(-clearance);
                // A contact of the point that ended too close with that triangle (its plane
                // through the point's closest at the start), unless the segment has one there.
                let key = (sg.vertices[0] as u32, sg.pair.collider as u32, t, bin(s));
                if clearance < -1e-3 * sg.pair.distance && contacts.len() >= room {
                    overflow = true;
                    return;
                }
                if clearance < -1e-3 * sg.pair.distance && keys.insert(key) {
                    let tri = sg.live.triangle(sg.collider, t);
                    let start = (1.0 - s) * a0 + s * a1;
                    let w = closest_on_triangle(&start, &tri[0], &tri[1], &tri[2]);
                    // `t` is where the segment ended too close, not necessarily the start
                    // point's nearest triangle, whose face could misjudge the side: the point
                    // is taken as outside (the last step kept it out) unless one of the
                    // segment's vertices starts inside, then its nearest triangle decides.
                    let inside_at = |p: &V| inside_closed(sg.collider, sg.live, candidates, p);
                    let side = if sg.a.iter().any(|p| inside_at(p) == Some(true)) {
                        Side::Judged(inside_at(&start))
                    } else {
                        Side::Outside
                    };
                    contacts.push(segment_contact(&sg, (s, t, w), x0, h, side));
                    added += 1;
                    segments += 1;
                }
            },
        );
        self.overflow |= overflow;
        Checked {
            added,
            segments,
            deepest: deepest.max(0.0),
        }
    }
}

/// A vertex of a contact pair during a step: the pair, its collider, where the vertex is in
/// the collider's frame at the step's start (`a`) and end (`b`), and the step's fractions.
struct At<'a> {
    pair: &'a ContactPair,
    collider: &'a ColliderSetup,
    live: &'a Live,
    vertex: usize,
    a: V,
    b: V,
    s: (f64, f64),
}

/// What a detection pass walks: the setup, the elements' vertex ranges, which vertices are
/// held, the colliders during the frame, the step's start positions and its fractions.
struct Pass<'a> {
    setup: &'a CollisionSetup,
    ranges: &'a [Option<Range<usize>>],
    pinned: &'a [bool],
    live: &'a [Live],
    x0: &'a [V],
    s: (f64, f64),
}

impl Pass<'_> {
    /// Calls `f` for every free vertex of every pair with vertex–face detection, in pair then
    /// vertex order, with its start and its end `end(i)` in the collider's frame.
    fn vertices(&self, end: impl Fn(usize) -> V, mut f: impl FnMut(At<'_>)) {
        for pair in self.setup.pairs.iter().filter(|p| p.vertices) {
            let Some(r) = self.ranges.get(pair.element).cloned().flatten() else {
                continue;
            };
            let l = &self.live[pair.collider];
            let (t0, t1) = (l.at(self.s.0), l.at(self.s.1));
            for i in r.filter(|&i| !self.pinned[i]) {
                f(At {
                    pair,
                    collider: &self.setup.colliders[pair.collider],
                    live: l,
                    vertex: i,
                    a: inverse(t0, &self.x0[i]),
                    b: inverse(t1, &end(i)),
                    s: self.s,
                });
            }
        }
    }

    /// Calls `f` for every hair segment of every pair with segment–face detection whose
    /// vertices are not both held, in pair then segment order, as [`Pass::vertices`] does.
    fn segments(&self, end: impl Fn(usize) -> V, mut f: impl FnMut(SegmentAt<'_>)) {
        for pair in self.setup.pairs.iter().filter(|p| p.segments) {
            if self.ranges.get(pair.element).cloned().flatten().is_none() {
                continue;
            }
            let l = &self.live[pair.collider];
            let (t0, t1) = (l.at(self.s.0), l.at(self.s.1));
            for seg in self.setup.segments.get(pair.element).into_iter().flatten() {
                let [i, j] = seg.map(|v| v as usize);
                if self.pinned[i] && self.pinned[j] {
                    continue;
                }
                let (x0, e) = (self.x0, &end);
                f(SegmentAt {
                    pair,
                    collider: &self.setup.colliders[pair.collider],
                    live: l,
                    vertices: [i, j],
                    a: [inverse(t0, &x0[i]), inverse(t0, &x0[j])],
                    b: [inverse(t1, &e(i)), inverse(t1, &e(j))],
                    s: self.s,
                });
            }
        }
    }
}

fn inverse(t: Option<Transform>, p: &V) -> V {
    match t {
        Some(t) => t.inverse_transform_point(&(*p).into()).coords,
        None => *p,
    }
}

fn face_normal(tri: &[V; 3]) -> V {
    (tri[1] - tri[0])
        .cross(&(tri[2] - tri[0]))
        .try_normalize(0.0)
        .unwrap_or_else(V::zeros)
}

/// Whether `p` is inside closed collider `c`, by the pseudo-normal of its nearest triangle
/// of `candidates` (`None` for open meshes or no candidates). The candidates must include
/// every triangle nearer to `p` than the ones the caller judges.
fn inside_closed(c: &ColliderSetup, live: &Live, candidates: &[u32], p: &V) -> Option<bool> {
    judged_nearest(c, live, candidates, p).map(|(inside, _)| inside)
}

/// [`inside_closed`]'s answer with the nearest triangle that gave it.
fn judged_nearest(
    c: &ColliderSetup,
    live: &Live,
    candidates: &[u32],
    p: &V,
) -> Option<(bool, u32)> {
    if !c.closed {
        return None;
    }
    let (_, t, w) = nearest(c, live, candidates, p)?;
    Some((side(c, live, t, &w, (p, p), None).1 < 0.0, t))
}

/// The contact normal (local frame, unit) of the point `a` against triangle `t` at its closest
/// point (weights `w`), and `a`'s signed distance to the triangle. Closed meshes: a point
/// behind the face is inside (negative distance) and pushed out through it. Open meshes: the
/// normal points from the surface to the point; a point on the surface is kept on the side
/// it comes from (against its motion towards `b`). `inside`: whether `a` is inside a closed
/// mesh, decided by its nearest triangle ([`inside_closed`]) when `t` may not be that one (a
/// triangle's own side is only meaningful for the nearest).
fn side(
    c: &ColliderSetup,
    live: &Live,
    t: u32,
    w: &[f64; 3],
    (a, b): (&V, &V),
    inside: Option<bool>,
) -> (V, f64) {
    let tri = live.triangle(c, t);
    let q = w[0] * tri[0] + w[1] * tri[1] + w[2] * tri[2];
    let nf = face_normal(&tri);
    let diff = a - q;
    let d = diff.norm();
    let scale = tri.iter().fold(a.amax(), |m, p| m.max(p.amax()));
    let tiny = d <= 1e-12 * scale.max(1.0);
    if c.closed {
        // Inside is behind the pseudo-normal of the feature the closest point is on (face,
        // edge or vertex; Bærentzen & Aanæs 2005): behind a face's plane near a convex edge
        // is still outside (a vertex beside a box's side, below its top).
        let zero: Vec<usize> = (0..3).filter(|&k| w[k] <= 1e-12).collect();
        let pseudo = match zero[..] {
            [k] => {
                let j = (k + 1) % 3; // the edge opposite corner k
                nf + face_normal(&live.triangle(c, c.across[t as usize][j]))
            }
            [k0, k1] => live.vertex_normals[c.triangles[t as usize][3 - k0 - k1] as usize],
            _ => nf,
        };
        let inside = inside.unwrap_or(pseudo.dot(&diff) < 0.0);
        match (tiny, inside) {
            (true, _) => (nf, -d),
            (false, true) => (-diff / d, -d),
            (false, false) => (diff / d, d),
        }
    } else if tiny {
        (if nf.dot(&(b - a)) > 0.0 { -nf } else { nf }, d)
    } else {
        (diff / d, d)
    }
}

/// The contact of a vertex with triangle `t` (closest point weights `w` at the step's start
/// position, local): the plane through the closest point, carried by the collider.
fn contact(
    setup: &CollisionSetup,
    at: &At<'_>,
    (t, w): (u32, [f64; 3]),
    x0: &[V],
    h: f64,
    inside: Option<bool>,
) -> Contact {
    let i = at.vertex;
    let (pair, c, live) = (at.pair, at.collider, at.live);
    Contact {
        cohesion: pair.cohesion * setup.areas[i] * h,
        ..plane(
            pair,
            c,
            live,
            at.s,
            t,
            w,
            (&at.a, &at.b, &x0[i]),
            h,
            &[(i as u32, 1.0)],
            false,
            inside,
        )
    }
}

/// The contact of a point of the solid with triangle `t` (closest point weights `w` at the
/// step's start): the plane through the closest point, carried by the collider. The point is
/// at `a` (local) and `x0` (world) at the step's start, heading to `b` (local), and is
/// `points` (vertices and weights); no cohesion (the caller's). `outside`: the point is known
/// to start outside (a segment's, kept out by the last step), so the normal is from the
/// triangle to it even where it is behind the triangle's plane (around a convex edge).
#[allow(clippy::too_many_arguments)]
fn plane(
    pair: &ContactPair,
    c: &ColliderSetup,
    live: &Live,
    (s0, s1): (f64, f64),
    t: u32,
    w: [f64; 3],
    (a, b, x0): (&V, &V, &V),
    h: f64,
    points: &[(u32, f64)],
    outside: bool,
    inside: Option<bool>,
) -> Contact {
    let (n_local, _) = side(c, live, t, &w, (a, b), inside);
    let tri = live.triangle(c, t);
    let q = w[0] * tri[0] + w[1] * tri[1] + w[2] * tri[2];
    let n_local = match (a - q).try_normalize(1e-12 * a.amax().max(1.0)) {
        Some(n) if outside => n,
        _ => n_local,
    };
    let place = |s: f64, p: &V| match live.at(s) {
        Some(t) => t.transform_point(&(*p).into()).coords,
        None => *p,
    };
    let (q0, q1) = (place(s0, &q), place(s1, &q));
    let n = match live.at(s1) {
        Some(t) => t.rotation * n_local,
        None => n_local,
    };
    // n·(x_end − q_end) ≥ distance ⟺ n·(v − v_c) ≥ −gap/h with these (docs/contacts.md).
    let mut gap = n.dot(&(x0 - q0)) - pair.distance;
    if gap < 0.0 {
        gap *= pair.strength;
    }
    Contact {
        frame: frame(&n),
        gap,
        velocity: (q1 - q0) / h,
        friction: pair.friction,
        damping: pair.damping,
        ..Contact::points(points)
    }
}

/// A hair segment of a contact pair during a step: the pair, its collider, the segment's
/// vertices, where they are in the collider's frame at the step's start (`a`) and end (`b`),
/// and the step's fractions.
struct SegmentAt<'a> {
    pair: &'a ContactPair,
    collider: &'a ColliderSetup,
    live: &'a Live,
    vertices: [usize; 2],
    a: [V; 2],
    b: [V; 2],
    s: (f64, f64),
}

/// The triangle of `candidates` nearest to `p` (ties: the lower index): (distance, triangle,
/// closest point weights).
fn nearest(
    c: &ColliderSetup,
    live: &Live,
    candidates: &[u32],
    p: &V,
) -> Option<(f64, u32, [f64; 3])> {
    let mut best: Option<(f64, u32, [f64; 3])> = None;
    for &t in candidates {
        let tri = live.triangle(c, t);
        let w = closest_on_triangle(p, &tri[0], &tri[1], &tri[2]);
        let d = (p - (w[0] * tri[0] + w[1] * tri[1] + w[2] * tri[2])).norm();
        if best.is_none_or(|(bd, bt, _)| (d, t) < (bd, bt)) {
            best = Some((d, t, w));
        }
    }
    best
}

/// A segment with a held end that starts within the distance kept of a triangle of
/// `candidates`: a strand rooted in the collider's skin (a scalp). Its held end is where the
/// groom put it, and a point beside it cannot be moved out (it follows the held end), so the
/// segment gets no contact of its own, as held vertices get none; its free vertex's does.
fn rooted(sg: &SegmentAt<'_>, pinned: &[bool], candidates: &[u32]) -> bool {
    (0..2).any(|k| {
        pinned[sg.vertices[k]]
            && nearest(sg.collider, sg.live, candidates, &sg.a[k])
                .is_some_and(|(d, _, _)| d < sg.pair.distance)
    })
}

/// Where along segment `p0`–`p1` (in the collider's frame) it is closest to a triangle of
/// `candidates` no farther than `reach`, if that point is inside the segment (ties: the lower
/// triangle index).
fn closest_inside(
    sg: &SegmentAt<'_>,
    candidates: &[u32],
    (p0, p1): (&V, &V),
    reach: f64,
) -> Option<f64> {
    let mut best: Option<(f64, u32, f64)> = None;
    for &t in candidates {
        let tri = sg.live.triangle(sg.collider, t);
        let (s, _, d) = closest_segment_triangle(p0, p1, &tri[0], &tri[1], &tri[2]);
        if d <= reach && inside_segment(s) && best.is_none_or(|(bd, bt, _)| (d, t) < (bd, bt)) {
            best = Some((d, t, s));
        }
    }
    best.map(|(_, _, s)| s)
}

/// Where along a segment a contact of its own goes: away from its ends, which vertex–face
/// contacts hold (a thousandth of the segment).
fn inside_segment(s: f64) -> bool {
    (1e-3..=1.0 - 1e-3).contains(&s)
}

/// How a hair segment's contact point tells which side of a closed collider it starts on.
#[derive(Clone, Copy, Debug)]
enum Side {
    /// The triangle is the point's nearest: its pseudo-normal decides.
    Nearest,
    /// Outside (kept out by the last step): the normal is from the triangle to the point
    /// even behind the triangle's plane.
    Outside,
    /// As [`inside_closed`] judged it (`None`: open meshes, by distance alone).
    Judged(Option<bool>),
}

/// The contact of segment `sg` at `s` along it with triangle `t` (closest point weights `w`
/// of that point at the step's start), its side as `side` says. A point taken as outside
/// while a segment's vertex had been pushed inside (hair_pile, a rounding-level change of
/// gravity: a vertex 0.65 mm inside the head) got the normal into the collider, opposite its
/// vertex's contact: contacts no step can meet, ADMM 0.1–1.8 m/s off them at every halving of
/// the step, and the run failed at frame 10.
fn segment_contact(
    sg: &SegmentAt<'_>,
    (s, t, w): (f64, u32, [f64; 3]),
    x0: &[V],
    h: f64,
    side: Side,
) -> Contact {
    let [i, j] = sg.vertices;
    let at = |p: &[V; 2]| (1.0 - s) * p[0] + s * p[1];
    let (a, b, x) = (at(&sg.a), at(&sg.b), (1.0 - s) * x0[i] + s * x0[j]);
    let points = [(i as u32, 1.0 - s), (j as u32, s)];
    plane(
        sg.pair,
        sg.collider,
        sg.live,
        sg.s,
        t,
        w,
        (&a, &b, &x),
        h,
        &points,
        matches!(side, Side::Outside),
        match side {
            Side::Judged(inside) => inside,
            Side::Nearest | Side::Outside => None,
        },
    )
}

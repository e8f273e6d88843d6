//! The setup of contacts: the [`Collision`] Behavior pairs every collision element's member
//! cloth and hair elements with its colliders and with each other, each pair with its contact
//! parameters from both sides' Collider SECs and the group's Collision Response SEC, into the
//! [`CollisionSetup`] the detectors read.

use super::surfaces::{
    ColliderSetup, cloth_surfaces, collider_setup, contact_areas, hair_segments,
};
use crate::behavior::{bad, checked, non_negative};
use crate::builder::SystemBuilder;
use crate::error::SimError;
use std::collections::BTreeMap;
use weft_scene::{Collider, CollisionGroup, CollisionResponse, ElementKind, Members, SceneElement};

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
        let mut setup = CollisionSetup::default();
        let mut collider_index: BTreeMap<usize, usize> = BTreeMap::new();
        for &gi in &groups {
            let Some(g) = read_group(scene, gi, b)? else {
                continue;
            };
            push_solid_pairs(scene, &g, b, &mut setup.solid_pairs)?;
            push_collider_pairs(scene, &g, b, &mut setup, &mut collider_index)?;
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

/// The elements that collide: cloth and hair.
fn simulated(e: &SceneElement) -> bool {
    matches!(e.kind, ElementKind::Cloth | ElementKind::Hair)
}

/// A collision element as read: its SECs (or their defaults) and the scene indices of the
/// members and colliders it names.
struct Group {
    /// Scene index of the collision element.
    index: usize,
    group: CollisionGroup,
    response: CollisionResponse,
    members: Vec<usize>,
    colliders: Vec<usize>,
}

/// Collision element `gi` read and checked: its response's ranges and the names it lists.
/// `None` when it has no detection method on (it makes no contacts, and says so).
fn read_group(
    scene: &[SceneElement],
    gi: usize,
    b: &mut SystemBuilder,
) -> Result<Option<Group>, SimError> {
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
    check_names(scene, g, &group)?;
    if !group.vertex_face && !group.segment_face && !group.edge_edge {
        b.warn(format!(
            "collision element '{}' has no detection method on: it makes no contacts",
            g.name
        ));
        return Ok(None);
    }
    let members: Vec<usize> = (0..scene.len())
        .filter(|&i| simulated(&scene[i]) && group.members.contains(&scene[i].name))
        .collect();
    let colliders: Vec<usize> = (0..scene.len())
        .filter(|&i| {
            scene[i].kind == ElementKind::Collider && group.colliders.contains(&scene[i].name)
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
    Ok(Some(Group {
        index: gi,
        group,
        response,
        members,
        colliders,
    }))
}

/// Every name collision element `g` lists is an element of the scene of the kind its field
/// asks for (members: cloth or hair; colliders: a collider).
fn check_names(
    scene: &[SceneElement],
    g: &SceneElement,
    group: &CollisionGroup,
) -> Result<(), SimError> {
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
    Ok(())
}

/// The pairs of members of `g` that collide with each other (or themselves), appended to
/// `pairs` unless an earlier collision element made the pair already.
fn push_solid_pairs(
    scene: &[SceneElement],
    g: &Group,
    b: &mut SystemBuilder,
    pairs: &mut Vec<SolidPair>,
) -> Result<(), SimError> {
    let (group, response, members) = (&g.group, &g.response, &g.members);
    for (k, &ma) in members.iter().enumerate() {
        for &mb in &members[k..] {
            let wanted = if ma == mb {
                group.self_collision
            } else {
                group.between_members
            };
            if !wanted
                || pairs.iter().any(|p| (p.a, p.b) == (ma, mb))
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
            pairs.push(SolidPair {
                a: ma,
                b: mb,
                group: g.index,
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
    Ok(())
}

/// Each member of `g` against each of its colliders, appended to `setup.pairs`; a collider
/// first met is compiled into `setup.colliders` (`collider_index`: scene index to its place
/// there).
fn push_collider_pairs(
    scene: &[SceneElement],
    g: &Group,
    b: &mut SystemBuilder,
    setup: &mut CollisionSetup,
    collider_index: &mut BTreeMap<usize, usize>,
) -> Result<(), SimError> {
    let (group, response) = (&g.group, &g.response);
    for &m in &g.members {
        b.read(m, "collider");
        let ms = scene[m].secs.get::<Collider>().cloned().unwrap_or_default();
        checked(&scene[m].name, &ms)?;
        for &c in &g.colliders {
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
                group: g.index,
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
    Ok(())
}

//! The meshes contacts are made with, as the setup compiles them: each collider's triangles
//! (oriented outwards when the mesh is closed, with the triangle across each edge for the
//! pseudo-normals), and the simulated elements' contact surfaces (cloth triangles and edges,
//! hair segments, each vertex's contact area) in global vertex indices. Kept apart from the
//! pairing of [`super::setup`] because they read only geometry, never the collision SECs.

use crate::builder::SystemBuilder;
use crate::error::SimError;
use nalgebra::Vector3;
use std::collections::{BTreeMap, BTreeSet};
use weft_scene::{ElementKind, Geometry, Rod, SceneElement};

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

pub(super) fn collider_setup(
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

pub(super) fn contact_areas(scene: &[SceneElement], b: &SystemBuilder) -> Vec<f64> {
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
pub(super) type Surfaces = (Vec<Vec<[u32; 3]>>, Vec<Vec<[u32; 2]>>);

pub(super) fn cloth_surfaces(scene: &[SceneElement], b: &SystemBuilder) -> Surfaces {
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

pub(super) fn hair_segments(scene: &[SceneElement], b: &SystemBuilder) -> Vec<Vec<[u32; 2]>> {
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

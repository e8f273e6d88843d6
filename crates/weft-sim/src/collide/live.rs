//! A collider during a frame, and the walk over what a detection pass visits. [`Live`] holds a
//! collider's mesh in its own frame (placed by its transform interpolated over the frame),
//! its tree and, for closed meshes, its vertices' pseudo-normals; [`Pass`] hands every free
//! vertex and hair segment of every pair to the caller, already in the collider's frame at
//! the step's start and end (a rigidly moving collider is then at rest and its tree never
//! changes).

use super::bvh::TriangleTree;
use super::geometry::face_normal;
use super::setup::{CollisionSetup, ContactPair};
use super::surfaces::ColliderSetup;
use nalgebra::Vector3;
use std::ops::Range;
use weft_scene::{SceneElement, Transform};

type V = Vector3<f64>;

/// A collider during a frame: its mesh in its own frame and the tree over it.
pub(super) struct Live {
    pub(super) local: Vec<V>,
    /// Closed meshes: each vertex's angle-weighted pseudo-normal (Bærentzen & Aanæs 2005),
    /// which decides inside and outside where the closest point is that vertex.
    pub(super) vertex_normals: Vec<V>,
    pub(super) tree: TriangleTree,
    pub(super) from: Option<Transform>,
    pub(super) to: Option<Transform>,
}

/// The angle-weighted pseudo-normal of every vertex of a closed mesh (empty for open ones).
pub(super) fn vertex_normals(c: &ColliderSetup, p: &[V]) -> Vec<V> {
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
    pub(super) fn triangle(&self, c: &ColliderSetup, t: u32) -> [V; 3] {
        c.triangles[t as usize].map(|v| self.local[v as usize])
    }

    /// The collider's transform a fraction `s` through the step (translation linearly,
    /// rotation by slerp, as the stepper moves pins), or whichever end is given.
    pub(super) fn at(&self, s: f64) -> Option<Transform> {
        match (self.from, self.to) {
            (Some(a), Some(b)) => Some(a.lerp_slerp(&b, s)),
            (a, b) => b.or(a),
        }
    }
}

pub(super) fn local_positions(e: &SceneElement, to: Option<Transform>) -> Vec<V> {
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

/// A vertex of a contact pair during a step: the pair, its collider, where the vertex is in
/// the collider's frame at the step's start (`a`) and end (`b`), and the step's fractions.
pub(super) struct At<'a> {
    pub(super) pair: &'a ContactPair,
    pub(super) collider: &'a ColliderSetup,
    pub(super) live: &'a Live,
    pub(super) vertex: usize,
    pub(super) a: V,
    pub(super) b: V,
    pub(super) s: (f64, f64),
}

/// What a detection pass walks: the setup, the elements' vertex ranges, which vertices are
/// held, the colliders during the frame, the step's start positions and its fractions.
pub(super) struct Pass<'a> {
    pub(super) setup: &'a CollisionSetup,
    pub(super) ranges: &'a [Option<Range<usize>>],
    pub(super) pinned: &'a [bool],
    pub(super) live: &'a [Live],
    pub(super) x0: &'a [V],
    pub(super) s: (f64, f64),
}

impl Pass<'_> {
    /// Calls `f` for every free vertex of every pair with vertex–face detection, in pair then
    /// vertex order, with its start and its end `end(i)` in the collider's frame.
    pub(super) fn vertices(&self, end: impl Fn(usize) -> V, mut f: impl FnMut(At<'_>)) {
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
    pub(super) fn segments(&self, end: impl Fn(usize) -> V, mut f: impl FnMut(SegmentAt<'_>)) {
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

pub(super) fn inverse(t: Option<Transform>, p: &V) -> V {
    match t {
        Some(t) => t.inverse_transform_point(&(*p).into()).coords,
        None => *p,
    }
}

/// A hair segment of a contact pair during a step: the pair, its collider, the segment's
/// vertices, where they are in the collider's frame at the step's start (`a`) and end (`b`),
/// and the step's fractions.
pub(super) struct SegmentAt<'a> {
    pub(super) pair: &'a ContactPair,
    pub(super) collider: &'a ColliderSetup,
    pub(super) live: &'a Live,
    pub(super) vertices: [usize; 2],
    pub(super) a: [V; 2],
    pub(super) b: [V; 2],
    pub(super) s: (f64, f64),
}

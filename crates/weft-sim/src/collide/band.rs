//! Contact bands checked against the scene before the first step.
//!
//! A thickness is the distance a contact keeps from a surface, in metres; a band is what a
//! pair keeps between its surfaces (both sides' thicknesses). Typed a thousandfold too large
//! (a metre where a millimetre was meant), a band takes in most of the scene: every vertex
//! gets a contact with every triangle near it, and a frame that took a fraction of a second
//! runs for minutes or hours without a word. So, before a step:
//!
//! - a thickness wider than its own element (the largest side of its bounding box) cannot
//!   describe the scene, and is refused naming the element, the parameter and both sizes;
//! - a pair whose band already holds most of a member's free vertices at the start is
//!   reported with the numbers and what the steps will do about it: against a collider or
//!   another member, the first steps push them out (a jump of up to the band's depth);
//! - an element most of whose free vertices start within its own self-collision band of its
//!   other primitives is refused: no motion of a sheet (or of a strand) can take every
//!   vertex a band's width from primitives one edge away, so its contacts could never be met.

use super::bvh::BoxTree;
use super::ccd::{self, PairKind};
use super::detect::Detector;
use super::live::inverse;
use super::planes::{judged_nearest, nearest};
use super::setup::CollisionSetup;
use crate::behavior::bad;
use crate::error::SimError;
use nalgebra::Vector3;
use std::ops::Range;
use weft_scene::{Collider, SceneElement};

type V = Vector3<f64>;

/// Candidates looked at per vertex for its nearest primitive: enough for every mesh a sane
/// band sees near a vertex (a few dozen), and a bound on the work when the band takes in
/// everything (then the first candidates already answer).
const SCAN: usize = 256;

/// Vertices of a member looked at, at most (evenly spread; the counts are scaled up): the
/// checks run at every compile, and a wide band makes each vertex's look cost as much as the
/// collider's triangles.
const SAMPLE: usize = 4096;

/// Every `stride`-th of `n` vertices, for at most [`SAMPLE`] of them.
fn stride(n: usize) -> usize {
    n.div_ceil(SAMPLE).max(1)
}

/// The start state and positions the checks read.
pub(crate) struct Start<'a> {
    /// The scene.
    pub scene: &'a [SceneElement],
    /// Initial positions of the simulated vertices (global).
    pub x: &'a [V],
    /// Per global vertex: held (attached), so it gets no contacts.
    pub pinned: &'a [bool],
    /// Per scene element, its global vertices.
    pub ranges: &'a [Option<Range<usize>>],
}

impl Start<'_> {
    fn free(&self, e: usize) -> Vec<usize> {
        self.ranges
            .get(e)
            .cloned()
            .flatten()
            .into_iter()
            .flatten()
            .filter(|&i| !self.pinned[i])
            .collect()
    }

    fn name(&self, e: usize) -> &str {
        self.scene.get(e).map_or("?", |e| e.name.as_str())
    }
}

/// A number of metres for a message: `0.001`, `2`, `1e30`.
fn metres(x: f64) -> String {
    if x != 0.0 && !(1e-4..1e5).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        let r = format!("{x:.4}");
        r.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// The largest side of the bounding box of `p` (0 for none).
fn extent(p: impl IntoIterator<Item = V>) -> f64 {
    let mut it = p.into_iter();
    let Some(first) = it.next() else {
        return 0.0;
    };
    let (lo, hi) = it.fold((first, first), |(lo, hi), q| (lo.inf(&q), hi.sup(&q)));
    (hi - lo).max()
}

/// Refuses a thickness wider than its element, then checks where each pair's band starts
/// (see the module doc). Warnings go to `warn`.
pub(crate) fn check(
    setup: &CollisionSetup,
    start: &Start<'_>,
    warn: &mut impl FnMut(String),
) -> Result<(), SimError> {
    thickness_within_extent(setup, start)?;
    against_colliders(setup, start, warn);
    between_solids(setup, start, warn)
}

fn thickness_within_extent(setup: &CollisionSetup, start: &Start<'_>) -> Result<(), SimError> {
    let members = setup
        .pairs
        .iter()
        .map(|p| p.element)
        .chain(setup.solid_pairs.iter().flat_map(|p| [p.a, p.b]));
    let colliders = setup.colliders.iter().map(|c| c.element);
    for e in members.chain(colliders) {
        let el = &start.scene[e];
        let Some(c) = el.secs.get::<Collider>() else {
            continue;
        };
        let size = match start.ranges.get(e).cloned().flatten() {
            Some(r) => extent(start.x[r].iter().copied()),
            None => extent(el.geometry.positions().iter().map(|p| V::from(*p))),
        };
        if size > 0.0 && c.thickness > size {
            return Err(bad(
                &el.name,
                "collider.thickness",
                format!(
                    "is {} m, wider than the element itself (its bounding box's largest side \
                     is {} m): a contact band that wide cannot describe the scene (the \
                     thickness is the distance kept from the surface, in metres: 1 mm is 0.001)",
                    metres(c.thickness),
                    metres(size)
                ),
            ));
        }
    }
    Ok(())
}

/// How many of a group of vertices start in a band, how deep, and with how many primitives
/// in it: counted over every `stride`-th vertex, scaled to the whole group.
struct Inside {
    stride: usize,
    count: usize,
    deepest: f64,
    /// Primitives within the band of the vertices counted: each a contact of the first step.
    primitives: usize,
}

impl Inside {
    fn new(stride: usize) -> Self {
        Inside {
            stride,
            count: 0,
            deepest: 0.0,
            primitives: 0,
        }
    }
    fn add(&mut self, depth: f64, primitives: usize) {
        self.count += self.stride;
        self.deepest = self.deepest.max(depth);
        self.primitives += self.stride * primitives;
    }
    /// More than half of `of`.
    fn most(&self, of: usize) -> bool {
        2 * self.count > of
    }
    /// "576" or, counted over a sample, "about 576".
    fn count(&self) -> String {
        let about = if self.stride > 1 { "about " } else { "" };
        format!("{about}{}", self.count)
    }
    /// What the contacts will cost where they are many: ", about 150000 contacts in the
    /// first step (267 a vertex), each an ADMM unknown of every iteration".
    fn contacts(&self) -> String {
        let per = self.primitives / self.count.max(1);
        if per < 8 {
            return String::new();
        }
        format!(
            "; about {} contacts in the first step ({per} a vertex), each solved for in every \
             ADMM iteration: slow steps",
            self.primitives
        )
    }
}

fn against_colliders(setup: &CollisionSetup, start: &Start<'_>, warn: &mut impl FnMut(String)) {
    if setup.pairs.is_empty() {
        return;
    }
    let detector = Detector::new(setup, start.scene, usize::MAX);
    let mut candidates = Vec::new();
    for pair in setup.pairs.iter().filter(|p| p.vertices) {
        let (c, live) = (
            &setup.colliders[pair.collider],
            &detector.live[pair.collider],
        );
        let free = start.free(pair.element);
        let mut inside = Inside::new(stride(free.len()));
        let pad = V::repeat(pair.distance);
        for &i in free.iter().step_by(inside.stride) {
            let a = inverse(live.from, &start.x[i]);
            candidates.clear();
            live.tree.query(&(a - pad), &(a + pad), &mut candidates);
            let Some((d, _, _)) = nearest(c, live, &candidates, &a) else {
                continue;
            };
            let within = judged_nearest(c, live, &candidates, &a).is_some_and(|(inn, _)| inn);
            let signed = if within { -d } else { d };
            if signed < pair.distance {
                // The exact check gives the vertex a contact with each triangle this near.
                let near = candidates
                    .iter()
                    .filter(|&&t| {
                        let q = live.triangle(c, t);
                        ccd::distance(PairKind::PointTriangle, &[a, q[0], q[1], q[2]])
                            < pair.distance
                    })
                    .count();
                inside.add(pair.distance - signed, near.max(1));
            }
        }
        if inside.most(free.len()) {
            let strength = pair.strength;
            warn(format!(
                "'{}': {} of its {} free vertices start inside the {} m contact band of \
                 collider '{}' (up to {} m deep): the first step pushes them out by {} m at \
                 most (collision_response.strength {} of their depth each step){}; if that \
                 is not meant, collider.thickness is in metres (1 mm is 0.001)",
                start.name(pair.element),
                inside.count(),
                free.len(),
                metres(pair.distance),
                start.name(c.element),
                metres(inside.deepest),
                metres(strength * inside.deepest),
                strength,
                inside.contacts(),
            ));
        }
    }
}

/// A primitive of a simulated element: a cloth triangle, or a hair segment (hair has no
/// faces; its segments are what edge–edge detection keeps apart).
#[derive(Clone, Copy)]
enum Primitive {
    Triangle([u32; 3]),
    Segment([u32; 2]),
}

impl Primitive {
    fn has(&self, v: u32) -> bool {
        match self {
            Primitive::Triangle(t) => t.contains(&v),
            Primitive::Segment(s) => s.contains(&v),
        }
    }
    fn distance(&self, x: &[V], p: &V) -> f64 {
        let at = |k: u32| x[k as usize];
        match *self {
            Primitive::Triangle(t) => {
                ccd::distance(PairKind::PointTriangle, &[*p, at(t[0]), at(t[1]), at(t[2])])
            }
            Primitive::Segment(s) => {
                ccd::distance(PairKind::EdgeEdge, &[*p, *p, at(s[0]), at(s[1])])
            }
        }
    }
    fn bounds(&self, x: &[V], pad: f64) -> (V, V) {
        let vs: &[u32] = match self {
            Primitive::Triangle(t) => t,
            Primitive::Segment(s) => s,
        };
        let (mut lo, mut hi) = (x[vs[0] as usize], x[vs[0] as usize]);
        for &k in &vs[1..] {
            lo = lo.inf(&x[k as usize]);
            hi = hi.sup(&x[k as usize]);
        }
        (lo - V::repeat(pad), hi + V::repeat(pad))
    }
}

/// The primitives of element `e`: its cloth triangles, else its hair segments.
fn primitives(setup: &CollisionSetup, e: usize) -> Vec<Primitive> {
    let tris = setup.triangles.get(e).map_or(&[][..], |t| &t[..]);
    if !tris.is_empty() {
        return tris.iter().map(|&t| Primitive::Triangle(t)).collect();
    }
    let segs = setup.segments.get(e).map_or(&[][..], |s| &s[..]);
    segs.iter().map(|&s| Primitive::Segment(s)).collect()
}

/// How many of `verts` start within `distance` of a primitive of `prims` that does not hold
/// them, and how near the nearest such primitive is.
fn inside_band(x: &[V], verts: &[usize], prims: &[Primitive], distance: f64) -> (Inside, f64) {
    let mut inside = Inside::new(stride(verts.len()));
    let mut nearest = f64::INFINITY;
    if prims.is_empty() {
        return (inside, nearest);
    }
    let boxes: Vec<(V, V)> = prims.iter().map(|p| p.bounds(x, distance)).collect();
    let tree = BoxTree::new(&boxes);
    for &i in verts.iter().step_by(inside.stride) {
        let p = x[i];
        let (mut best, mut near) = (f64::INFINITY, 0);
        tree.scan(&p, &p, SCAN, |k| {
            let prim = &prims[k as usize];
            if !prim.has(i as u32) {
                let d = prim.distance(x, &p);
                best = best.min(d);
                near += usize::from(d < distance);
            }
        });
        nearest = nearest.min(best);
        if best < distance {
            inside.add(distance - best, near);
        }
    }
    (inside, nearest)
}

fn between_solids(
    setup: &CollisionSetup,
    start: &Start<'_>,
    warn: &mut impl FnMut(String),
) -> Result<(), SimError> {
    for pair in &setup.solid_pairs {
        let sides: &[(usize, usize)] = if pair.a == pair.b {
            &[(pair.a, pair.a)]
        } else {
            &[(pair.a, pair.b), (pair.b, pair.a)]
        };
        for &(e, other) in sides {
            let free = start.free(e);
            let (inside, nearest) =
                inside_band(start.x, &free, &primitives(setup, other), pair.distance);
            if !inside.most(free.len()) {
                continue;
            }
            if e == other {
                return Err(bad(
                    start.name(e),
                    "collider.thickness",
                    format!(
                        "gives a self-collision band of {} m (both sides' thickness), but {} \
                         of its {} free vertices start within that of its own other \
                         primitives (the nearest {} m away): no motion can take them all out \
                         of it, so its contacts could never be met; make the thickness \
                         smaller than {} m (half that spacing) or turn self_collision off",
                        metres(pair.distance),
                        inside.count(),
                        free.len(),
                        metres(nearest),
                        metres(0.5 * nearest),
                    ),
                ));
            }
            warn(format!(
                "'{}': {} of its {} free vertices start inside the {} m contact band it \
                 keeps from '{}' (up to {} m deep): the first steps push them apart{}; if \
                 that is not meant, collider.thickness is in metres (1 mm is 0.001)",
                start.name(e),
                inside.count(),
                free.len(),
                metres(pair.distance),
                start.name(other),
                metres(inside.deepest),
                inside.contacts(),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metres_read_well() {
        assert_eq!(metres(0.001), "0.001");
        assert_eq!(metres(2.0), "2");
        assert_eq!(metres(0.55), "0.55");
        assert_eq!(metres(2e30), "2e30");
        assert_eq!(metres(1e-6), "1e-6");
    }
}

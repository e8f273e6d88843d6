//! Detection against colliders ([`Detector`]), once per step and per collider, in the
//! collider's own frame: before the step each free vertex (and each hair segment, between its
//! vertices) within reach gets a contact with its nearest triangle; after the step the exact
//! check of every path adds a contact for any triangle a path crossed or ended too close to,
//! for the step to be solved again. Each contact is keyed by where it came from, so a round
//! never adds one twice.

use super::bvh::TriangleTree;
use super::geometry::{
    closest_on_triangle, closest_segment_triangle, face_normal, segment_crosses_triangle,
};
use super::live::{Live, Pass, local_positions, vertex_normals};
use super::planes::{
    Side, closest_inside, contact, inside_closed, inside_segment, judged_nearest, nearest, rooted,
    segment_contact, side,
};
use super::setup::CollisionSetup;
use crate::error::SimError;
use nalgebra::Vector3;
use std::collections::BTreeSet;
use std::ops::Range;
use weft_scene::{SceneElement, Transform};
use weft_solid::integrator::Contact;

type V = Vector3<f64>;

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

/// Finds contacts each step (see the module docs here and of [`super`]). Holds no simulation state: the colliders'
/// shapes and transforms come from the scene each frame.
pub struct Detector {
    /// Each collider during the frame (read by the band check at load, too).
    pub(super) live: Vec<Live>,
    candidates: Vec<u32>,
    keys: BTreeSet<Key>,
    /// The most contacts a step may hold ([`Room`](super::room::Room)).
    room: usize,
    /// Whether this step's detection stopped at `room` (taken by [`Self::take_overflow`]).
    overflow: bool,
}

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

//! Contacts between deforming solids (issue 14): cloth on cloth, hair on hair, hair on cloth,
//! and each with itself, as the Collision Group SEC asks.
//!
//! **Primitives.** Vertices against cloth triangles (vertex–face), and cloth edges and hair
//! segments against each other (edge–edge): every intersection of two such surfaces or
//! curves starts with one of these two touching. Primitives that share a vertex never
//! collide (a triangle and its own corner, two edges of one triangle, consecutive segments).
//!
//! **Broad phase.** Three parry3d-f64 trees (vertices, triangles, edges) over the
//! primitives' boxes swept over the step and padded by half the distance kept; built once,
//! refit every detection; pairs come from traversing two trees together (edges against
//! themselves).
//!
//! **Detection before the step**, from the start positions and the predicted ends
//! (x⁰ + h v⁰): each vertex within reach of a triangle of another solid (or a non-adjacent one
//! of its own) gets a contact with the nearest such triangle per element, and with any other
//! whose closest point is inside its face (a vertex between two layers of one skirt); each
//! hair segment and cloth edge gets one with the nearest edge or segment per strand or cloth
//! element within reach (hair has no faces; the cloth's own faces do not hold two sheets'
//! crossing edges apart). A contact's point is the difference of the two primitives'
//! closest points at the start, Σ wⱼ xⱼ with weights (1, −b₀, −b₁, −b₂) or (1 − s, s, −(1 − t),
//! −t), its normal from the second to the first, its constraint n·(p_a − p_b) ≥ distance at
//! the end of the step, linearized at the start; the solver shares each impulse between the
//! two sides by these weights.
//!
//! **Check after each solve**: every pair whose swept boxes meet is tested by continuous
//! detection ([`super::ccd`], conservative). A pair without a contact whose path comes within
//! the distance gets one and the step is solved again; so does an edge pair that another
//! held for it (the ownership at a hair joint is judged at the start) once the solve ends
//! inside its distance. An edge pair that holds a contact but ends inside its distance by
//! more than a thousandth of it and more than the solve's tolerance over the step (`tol`·h,
//! what a contact met to the tolerance may leave) gets a second contact linearized where the
//! solve ended (closest points and normal there: the distance's tangent plane), and the step
//! is solved again: a hair sliding millimetres over another in a step moves far from where
//! its first contact was linearized (hair_pile: up to 0.19 mm into the 0.4 mm kept, within
//! the tolerance's 1.1e-5 m with this). Any pair whose path comes within a
//! tenth of the distance (or half its starting clearance, if less) is **crossing**: the
//! caller then retries with a smaller step, and at the smallest cuts the step back to the
//! last time continuous detection proved safe. A pair that starts touching (closer than
//! 10⁻⁶ of the distance) cannot be judged and is counted as starting inside instead.

use super::bvh::BoxTree;
use super::ccd::{self, PairKind};
use super::geometry::{closest_on_triangle, closest_segment_segment, frame};
use super::room::Room;
use super::setup::{CollisionSetup, SolidPair};
use nalgebra::Vector3;
use std::collections::{BTreeMap, BTreeSet};
use std::ops::Range;
use std::time::Instant;
use weft_solid::integrator::Contact;

type V = Vector3<f64>;

const NONE: u32 = u32::MAX;

/// Key of a vertex–face contact: (vertex, triangle index).
const VT: u8 = 0;
/// Key of an edge–edge contact: (lower edge index, higher edge index).
const EE: u8 = 1;

/// What the check after a solve found.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Checked {
    /// Contacts added (their pairs' paths came within the distance).
    pub added: usize,
    /// Largest amount by which a pair ends closer than its distance [m].
    pub deepest: f64,
    /// Pairs whose paths come within a tenth of their distance: the step is not accepted.
    pub crossing: usize,
    /// The earliest conservative time of impact among them (fraction of the step).
    pub toi: f64,
    /// Pairs that start touching (cannot be judged).
    pub started_inside: usize,
}

/// Where detection between solids spent its time [s], summed until taken.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct SolidTimes {
    /// Refitting the trees and traversing them for pairs whose boxes meet.
    pub broad: f64,
    /// Distances and closest points of those pairs before a step (the contacts made).
    pub narrow: f64,
    /// Continuous detection of every path after a solve (the exact check).
    pub ccd: f64,
}

/// The contacts between deforming solids of a compiled scene (see the module doc). Holds no
/// simulation state: its trees and buffers are rebuilt from each step's positions.
pub(crate) struct Solids {
    /// Elements (lower, higher) → index into `CollisionSetup::solid_pairs`.
    pair_of: BTreeMap<(u32, u32), usize>,
    /// Per global vertex, its scene element (`NONE`: not simulated).
    element_of: Vec<u32>,
    /// Vertices that some pair detects against triangles.
    verts: Vec<u32>,
    tris: Vec<[u32; 3]>,
    edges: Vec<[u32; 2]>,
    /// Per edge: the group its nearest-per-group choice is made in (a hair strand's first
    /// segment, or a cloth element's first edge index offset past every segment).
    edge_group: Vec<u32>,
    /// Per edge: a hair segment (true) or a cloth edge.
    edge_hair: Vec<bool>,
    /// Per hair segment: the segment before and after it in its strand (`NONE` at its ends
    /// and for cloth edges).
    edge_prev: Vec<u32>,
    edge_next: Vec<u32>,
    /// Half the largest distance of any pair [m]: the boxes' padding.
    half: f64,
    trees: Option<[BoxTree; 3]>,
    found: Vec<(u32, u32)>,
    keys: BTreeSet<(u8, u32, u32)>,
    times: SolidTimes,
    /// The most candidate pairs of primitives, and contacts, a step may hold ([`Room`]).
    room: Room,
    /// Whether this step's detection stopped at `room` (taken by [`Self::take_overflow`]).
    overflow: bool,
}

impl Solids {
    /// The detection for `setup`'s solid pairs; `None` when it has none.
    pub(crate) fn new(
        setup: &CollisionSetup,
        ranges: &[Option<Range<usize>>],
        room: Room,
    ) -> Option<Self> {
        if setup.solid_pairs.is_empty() {
            return None;
        }
        let n = ranges.iter().flatten().map(|r| r.end).max().unwrap_or(0);
        let mut element_of = vec![NONE; n];
        for (e, r) in ranges.iter().enumerate() {
            for v in r.clone().into_iter().flatten() {
                element_of[v] = e as u32;
            }
        }
        let mut pair_of = BTreeMap::new();
        let (mut face_of, mut vert_of, mut edge_of) =
            (BTreeSet::new(), BTreeSet::new(), BTreeSet::new());
        for (k, p) in setup.solid_pairs.iter().enumerate() {
            pair_of.insert((p.a as u32, p.b as u32), k);
            for (x, y) in [(p.a, p.b), (p.b, p.a)] {
                let has_faces = setup.triangles.get(y).is_some_and(|t| !t.is_empty());
                if p.vertices && has_faces {
                    vert_of.insert(x);
                    face_of.insert(y);
                }
                if p.edges {
                    edge_of.insert(x);
                }
            }
        }
        let verts = vert_of
            .iter()
            .flat_map(|&e| ranges.get(e).cloned().flatten().into_iter().flatten())
            .map(|v| v as u32)
            .collect();
        let tris = face_of
            .iter()
            .flat_map(|&e| setup.triangles[e].iter().copied())
            .collect();
        let (mut edges, mut edge_group, mut edge_hair) = (Vec::new(), Vec::new(), Vec::new());
        for &e in &edge_of {
            let segments = setup.segments.get(e).map_or(&[][..], |s| &s[..]);
            let mut strand = NONE;
            for (k, s) in segments.iter().enumerate() {
                if k == 0 || segments[k - 1][1] != s[0] {
                    strand = edges.len() as u32;
                }
                edges.push(*s);
                edge_group.push(strand);
                edge_hair.push(true);
            }
            let cloth = setup.edges.get(e).map_or(&[][..], |s| &s[..]);
            let first = edges.len() as u32;
            for s in cloth {
                edges.push(*s);
                edge_group.push(first);
                edge_hair.push(false);
            }
        }
        let (mut edge_prev, mut edge_next) = (vec![NONE; edges.len()], vec![NONE; edges.len()]);
        for k in 1..edges.len() {
            if edge_hair[k] && edge_hair[k - 1] && edges[k - 1][1] == edges[k][0] {
                edge_prev[k] = (k - 1) as u32;
                edge_next[k - 1] = k as u32;
            }
        }
        let half = 0.5
            * setup
                .solid_pairs
                .iter()
                .fold(0.0f64, |m, p| m.max(p.distance));
        Some(Solids {
            pair_of,
            element_of,
            verts,
            tris,
            edges,
            edge_group,
            edge_hair,
            edge_prev,
            edge_next,
            half,
            trees: None,
            found: Vec::new(),
            keys: BTreeSet::new(),
            times: SolidTimes::default(),
            room,
            overflow: false,
        })
    }

    /// Holds at most `room` candidate pairs and contacts a step from now on.
    pub(crate) fn set_room(&mut self, room: Room) {
        self.room = room;
    }

    /// Whether detection since the last call stopped at its room (contacts or candidate
    /// pairs past what the memory allows): the step's contacts are then incomplete.
    pub(crate) fn take_overflow(&mut self) -> bool {
        std::mem::take(&mut self.overflow)
    }

    /// The time spent since the last call (see [`SolidTimes`]).
    pub(crate) fn take_times(&mut self) -> SolidTimes {
        std::mem::take(&mut self.times)
    }

    /// The pair of the elements of vertices `a` and `b`, if they collide.
    fn pair<'s>(&self, setup: &'s CollisionSetup, a: u32, b: u32) -> Option<&'s SolidPair> {
        let (ea, eb) = (self.element_of[a as usize], self.element_of[b as usize]);
        let k = self.pair_of.get(&(ea.min(eb), ea.max(eb)))?;
        setup.solid_pairs.get(*k)
    }

    /// The pairs of primitives whose boxes meet and that may collide (their elements pair up
    /// with that method, they share no vertex, not all their vertices are held), sorted, with
    /// their pair's index: vertex–triangle (`VT`: vertex, triangle index) or edge–edge (`EE`:
    /// lower edge index, higher).
    fn candidates(
        &mut self,
        setup: &CollisionSetup,
        pinned: &[bool],
        kind: u8,
    ) -> Vec<(u32, u32, usize)> {
        let Some(trees) = &self.trees else {
            return Vec::new();
        };
        self.found.clear();
        let max = self.room.pairs;
        let complete = if kind == VT {
            trees[0].pairs(&trees[1], &mut self.found, max)
        } else {
            // Each unordered pair comes twice.
            let complete = trees[2].pairs(&trees[2], &mut self.found, max.saturating_mul(2));
            self.found.retain(|&(i, j)| i < j);
            complete
        };
        if !complete {
            self.overflow = true;
            self.found.clear();
            return Vec::new();
        }
        self.found.sort_unstable();
        let held = |vs: &[u32]| vs.iter().all(|&k| pinned[k as usize]);
        let mut out = Vec::with_capacity(self.found.len());
        for &(i, j) in &self.found {
            let (ids, enabled): ([u32; 4], fn(&SolidPair) -> bool) = if kind == VT {
                let (v, t) = (self.verts[i as usize], self.tris[j as usize]);
                if t.contains(&v) {
                    continue;
                }
                ([v, t[0], t[1], t[2]], |p| p.vertices)
            } else {
                let (a, b) = (self.edges[i as usize], self.edges[j as usize]);
                if a.iter().any(|v| b.contains(v)) {
                    continue;
                }
                ([a[0], a[1], b[0], b[1]], |p| p.edges)
            };
            if held(&ids) {
                continue;
            }
            let side = if kind == VT { ids[1] } else { ids[2] };
            let (ea, eb) = (
                self.element_of[ids[0] as usize],
                self.element_of[side as usize],
            );
            if let Some(&k) = self.pair_of.get(&(ea.min(eb), ea.max(eb)))
                && enabled(&setup.solid_pairs[k])
            {
                out.push((i, j, k));
            }
        }
        out
    }

    /// Whether the pair of edges `i` and `j` should carry a contact of its own, from their
    /// closest points at `x0`. Two cloth edges: only when both points are inside them (a
    /// point at an end is a vertex, which vertex–face holds). A hair segment whose point is
    /// at a joint of its strand: only when the segment past the joint is farther (or as far
    /// and later): both are parts of one smooth capsule, and the farther one's end, seen
    /// from a point sliding over the joint, would give a plane tilted against the motion (a
    /// strand sliding across another lost 45 % of its speed at every joint it passed).
    fn edge_pair_owned(&self, i: u32, j: u32, x0: &[V]) -> bool {
        let at = |e: u32| self.edges[e as usize].map(|k| x0[k as usize]);
        let (a, b) = (at(i), at(j));
        let (s, t) = closest_segment_segment(&a[0], &a[1], &b[0], &b[1]);
        let clamped = |u: f64| !(1e-9..=1.0 - 1e-9).contains(&u);
        if !self.edge_hair[i as usize] && !self.edge_hair[j as usize] {
            return !clamped(s) && !clamped(t);
        }
        let dist =
            |p: &[V; 2], q: &[V; 2]| ccd::distance(PairKind::EdgeEdge, &[p[0], p[1], q[0], q[1]]);
        let d = dist(&a, &b);
        let scale = 1e-12 * a.iter().chain(&b).fold(1.0f64, |m, p| m.max(p.amax()));
        for (k, u, other) in [(i, s, &b), (j, t, &a)] {
            if !self.edge_hair[k as usize] || !clamped(u) {
                continue;
            }
            let past = if u < 0.5 {
                self.edge_prev[k as usize]
            } else {
                self.edge_next[k as usize]
            };
            if past == NONE {
                continue;
            }
            let dn = dist(&at(past), other);
            if dn < d - scale || (dn <= d + scale && past < k) {
                return false;
            }
        }
        true
    }

    /// Refits the trees (building them the first time) to the primitives' boxes over the
    /// positions `x0` and `x1(i)`, padded by `pad`.
    fn refit(&mut self, x0: &[V], x1: &impl Fn(usize) -> V, pad: f64) {
        let p = V::repeat(pad);
        let span = |vs: &[u32]| {
            let (mut lo, mut hi) = (V::repeat(f64::INFINITY), V::repeat(f64::NEG_INFINITY));
            for &v in vs {
                let (a, b) = (x0[v as usize], x1(v as usize));
                lo = lo.inf(&a).inf(&b);
                hi = hi.sup(&a).sup(&b);
            }
            (lo - p, hi + p)
        };
        let mut built = self.trees.take();
        let lists: [Vec<(V, V)>; 3] = [
            self.verts.iter().map(|v| span(&[*v])).collect(),
            self.tris.iter().map(|t| span(t)).collect(),
            self.edges.iter().map(|e| span(e)).collect(),
        ];
        match &mut built {
            Some(trees) => {
                for (t, b) in trees.iter_mut().zip(&lists) {
                    t.refit(b);
                }
            }
            None => built = Some(lists.each_ref().map(|b| BoxTree::new(b))),
        }
        self.trees = built;
    }

    /// Appends to `out` the contacts for a step of `h` from `x0`, `v0` (see the module doc),
    /// and forgets the last step's.
    pub(crate) fn detect(
        &mut self,
        setup: &CollisionSetup,
        pinned: &[bool],
        x0: &[V],
        v0: &[V],
        h: f64,
        out: &mut Vec<Contact>,
    ) {
        self.keys.clear();
        let clock = Instant::now();
        let end = |i: usize| x0[i] + h * v0[i];
        self.refit(x0, &end, 1.25 * self.half);
        let (vt, ee) = (
            self.candidates(setup, pinned, VT),
            self.candidates(setup, pinned, EE),
        );
        let clock = self.lap(clock, |t| &mut t.broad);
        let travel = |i: u32| (end(i as usize) - x0[i as usize]).norm();
        // Vertex–face: per vertex and element, the nearest triangle within reach, and any
        // other whose closest point is inside its face.
        let mut near: Vec<(u32, u32, f64, u32, [f64; 3])> = Vec::new();
        for (vi, ti, k) in vt {
            let (v, t, pair) = (
                self.verts[vi as usize],
                self.tris[ti as usize],
                &setup.solid_pairs[k],
            );
            let tri = t.map(|k| x0[k as usize]);
            let p = x0[v as usize];
            let w = closest_on_triangle(&p, &tri[0], &tri[1], &tri[2]);
            let d = (p - (w[0] * tri[0] + w[1] * tri[1] + w[2] * tri[2])).norm();
            let reach =
                1.25 * pair.distance + travel(v) + t.iter().map(|&k| travel(k)).fold(0.0, f64::max);
            if d <= reach {
                near.push((v, self.element_of[t[0] as usize], d, ti, w));
            }
        }
        near.sort_by(|a, b| {
            (a.0, a.1)
                .cmp(&(b.0, b.1))
                .then(a.2.total_cmp(&b.2))
                .then(a.3.cmp(&b.3))
        });
        for (k, &(v, e, _, ti, w)) in near.iter().enumerate() {
            let first = k == 0 || (near[k - 1].0, near[k - 1].1) != (v, e);
            if first || w.iter().all(|&b| b > 1e-9) {
                let t = self.tris[ti as usize];
                let pair = self.pair(setup, v, t[0]).expect("filtered above");
                if out.len() >= self.room.contacts {
                    self.overflow = true;
                    break;
                }
                self.keys.insert((VT, v, ti));
                out.push(vt_contact(setup, pair, v, t, w, x0, &end, h));
            }
        }
        // Edge–edge: per segment or cloth edge and strand (or cloth element) of the other
        // side, the nearest within reach. (Until the fifteenth session, hair only, cloth's
        // left to the check: then nearly every contact step of cloth_pile was solved twice,
        // its first solve's check adding some 80 edge pairs.)
        let mut near: Vec<(u32, u32, f64, u32)> = Vec::new();
        for (i, j, k) in ee {
            let (a, b, pair) = (
                self.edges[i as usize],
                self.edges[j as usize],
                &setup.solid_pairs[k],
            );
            let x = [a[0], a[1], b[0], b[1]].map(|k| x0[k as usize]);
            let d = ccd::distance(PairKind::EdgeEdge, &x);
            let reach = 1.25 * pair.distance
                + travel(a[0]).max(travel(a[1]))
                + travel(b[0]).max(travel(b[1]));
            if d <= reach {
                near.push((i, self.edge_group[j as usize], d, j));
                near.push((j, self.edge_group[i as usize], d, i));
            }
        }
        near.sort_by(|a, b| {
            (a.0, a.1)
                .cmp(&(b.0, b.1))
                .then(a.2.total_cmp(&b.2))
                .then(a.3.cmp(&b.3))
        });
        let mut chosen = BTreeSet::new();
        for (k, &(i, g, _, j)) in near.iter().enumerate() {
            if k == 0 || (near[k - 1].0, near[k - 1].1) != (i, g) {
                chosen.insert((i.min(j), i.max(j)));
            }
        }
        for (i, j) in chosen {
            if !self.edge_pair_owned(i, j, x0) {
                continue;
            }
            let (a, b) = (self.edges[i as usize], self.edges[j as usize]);
            let pair = self.pair(setup, a[0], b[0]).expect("filtered above");
            if out.len() >= self.room.contacts {
                self.overflow = true;
                break;
            }
            self.keys.insert((EE, i, j));
            out.push(ee_contact(setup, pair, a, b, x0, &end, h));
        }
        self.lap(clock, |t| &mut t.narrow);
    }

    /// Adds the time since `clock` to the field `of` picks; the new clock.
    fn lap(&mut self, clock: Instant, of: impl Fn(&mut SolidTimes) -> &mut f64) -> Instant {
        let now = Instant::now();
        *of(&mut self.times) += (now - clock).as_secs_f64();
        now
    }

    /// The check after a solve from `x0` to `x1` (see the module doc): appends the contacts
    /// the paths need to `contacts`. `slack` [m]: how far inside its distance the solve may
    /// leave a pair that has a contact (its tolerance over the step, `tol`·h).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn check(
        &mut self,
        setup: &CollisionSetup,
        pinned: &[bool],
        x0: &[V],
        x1: &[V],
        h: f64,
        slack: f64,
        contacts: &mut Vec<Contact>,
    ) -> Checked {
        let clock = Instant::now();
        let end = |i: usize| x1[i];
        self.refit(x0, &end, self.half);
        let (vt, ee) = (
            self.candidates(setup, pinned, VT),
            self.candidates(setup, pinned, EE),
        );
        let clock = self.lap(clock, |t| &mut t.broad);
        let mut out = Checked {
            toi: 1.0,
            ..Default::default()
        };
        let mut judge = |kind: PairKind,
                         key: (u8, u32, u32),
                         ids: [u32; 4],
                         pair: &SolidPair,
                         keys: &mut BTreeSet<(u8, u32, u32)>,
                         may_add: bool|
         -> Judged {
            let x = ids.map(|k| x0[k as usize]);
            let d = ids.map(|k| x1[k as usize] - x0[k as usize]);
            let dist = pair.distance;
            let end_gap = ccd::distance(kind, &positions_at_end(&x, &d)) - dist;
            let mut add = Judged::No;
            let inside = end_gap < -1e-3 * dist;
            if keys.contains(&key) {
                out.deepest = out.deepest.max(-end_gap);
                // Held, yet the solve ended inside the distance: its contact was linearized
                // at the step's start (closest points and normal fixed) and the pair slid
                // or turned far from there. A second contact, linearized where the solve
                // ended, holds it on the next round. Not where it ended within what the
                // solve promises (`slack`): a contact met to the tolerance ends up to
                // `tol`·h inside its plane, and on cloth_pile (tolerance 1 mm/s, 1/96 s
                // steps) half of these re-linearizations were less than 1.04e-5 m deep,
                // each costing the step another solve.
                if inside && end_gap < -slack && kind == PairKind::EdgeEdge {
                    add = Judged::AtEnd;
                }
            } else if ccd::time_of_impact(kind, &x, &d, dist * (1.0 - 1e-3)).is_some() {
                out.deepest = out.deepest.max(-end_gap);
                // A pair another holds (see `edge_pair_owned`) is still judged for crossing,
                // and takes a contact of its own once the step ends inside its distance:
                // ownership is judged at the step's start, and a strand sliding over a
                // joint of another during the step ends against the segment past it
                // (measured on hair_pile: such a pair 0.19 mm inside its 0.4 mm in every
                // detection round of a step, never added).
                if may_add || inside {
                    keys.insert(key);
                    add = Judged::AtStart;
                }
            } else {
                return Judged::No; // never within the distance: not crossing either
            }
            let d0 = ccd::distance(kind, &x);
            if d0 <= 1e-6 * dist {
                out.started_inside += 1;
            } else if let Some(t) = ccd::time_of_impact(kind, &x, &d, (0.1 * dist).min(0.5 * d0)) {
                out.crossing += 1;
                out.toi = out.toi.min(t);
            }
            add
        };
        let room = self.room.contacts;
        for (vi, ti, k) in vt {
            if contacts.len() >= room {
                self.overflow = true;
                break;
            }
            let (v, t, pair) = (
                self.verts[vi as usize],
                self.tris[ti as usize],
                &setup.solid_pairs[k],
            );
            if judge(
                PairKind::PointTriangle,
                (VT, v, ti),
                [v, t[0], t[1], t[2]],
                pair,
                &mut self.keys,
                true,
            ) != Judged::No
            {
                let tri = t.map(|k| x0[k as usize]);
                let w = closest_on_triangle(&x0[v as usize], &tri[0], &tri[1], &tri[2]);
                contacts.push(vt_contact(setup, pair, v, t, w, x0, &end, h));
                out.added += 1;
            }
        }
        for (i, j, k) in ee {
            if contacts.len() >= room {
                self.overflow = true;
                break;
            }
            let (a, b, pair) = (
                self.edges[i as usize],
                self.edges[j as usize],
                &setup.solid_pairs[k],
            );
            let owned = self.edge_pair_owned(i, j, x0);
            match judge(
                PairKind::EdgeEdge,
                (EE, i, j),
                [a[0], a[1], b[0], b[1]],
                pair,
                &mut self.keys,
                owned,
            ) {
                Judged::No => {}
                Judged::AtStart => {
                    contacts.push(ee_contact(setup, pair, a, b, x0, &end, h));
                    out.added += 1;
                }
                Judged::AtEnd => {
                    contacts.push(ee_contact_at_end(setup, pair, a, b, x0, x1, h));
                    out.added += 1;
                }
            }
        }
        self.lap(clock, |t| &mut t.ccd);
        out
    }
}

/// What the check does with a pair.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Judged {
    No,
    /// A contact linearized at the step's start.
    AtStart,
    /// A further contact for a held pair, linearized where the last solve ended.
    AtEnd,
}

fn positions_at_end(x: &[V; 4], d: &[V; 4]) -> [V; 4] {
    [x[0] + d[0], x[1] + d[1], x[2] + d[2], x[3] + d[3]]
}

/// The unit normal from `b` to `a` at the start; where they touch, `fallback` (unit, or zero)
/// turned against the relative motion `rel` of `a` (it comes from the side it moves away
/// from), else any direction across `rel`.
fn normal(a: &V, b: &V, fallback: V, rel: &V) -> V {
    let scale = a.amax().max(b.amax()).max(1.0);
    if let Some(n) = (a - b).try_normalize(1e-12 * scale) {
        return n;
    }
    if fallback != V::zeros() {
        return if fallback.dot(rel) > 0.0 {
            -fallback
        } else {
            fallback
        };
    }
    match (-rel).try_normalize(0.0) {
        Some(n) => n,
        None => V::z(),
    }
}

#[allow(clippy::too_many_arguments)]
fn vt_contact(
    setup: &CollisionSetup,
    pair: &SolidPair,
    v: u32,
    t: [u32; 3],
    w: [f64; 3],
    x0: &[V],
    end: &impl Fn(usize) -> V,
    h: f64,
) -> Contact {
    let tri = t.map(|k| x0[k as usize]);
    let q = w[0] * tri[0] + w[1] * tri[1] + w[2] * tri[2];
    let p = x0[v as usize];
    let face = (tri[1] - tri[0])
        .cross(&(tri[2] - tri[0]))
        .try_normalize(0.0)
        .unwrap_or_else(V::zeros);
    let moved = |k: u32| end(k as usize) - x0[k as usize];
    let rel = moved(v) - (w[0] * moved(t[0]) + w[1] * moved(t[1]) + w[2] * moved(t[2]));
    let n = normal(&p, &q, face, &rel);
    let cohesion = pair.cohesion * setup.areas.get(v as usize).copied().unwrap_or(0.0) * h;
    make(
        pair,
        n,
        (p - q).norm(),
        cohesion,
        &[(v, 1.0), (t[0], -w[0]), (t[1], -w[1]), (t[2], -w[2])],
    )
}

fn ee_contact(
    setup: &CollisionSetup,
    pair: &SolidPair,
    a: [u32; 2],
    b: [u32; 2],
    x0: &[V],
    end: &impl Fn(usize) -> V,
    h: f64,
) -> Contact {
    let [a0, a1, b0, b1] = [a[0], a[1], b[0], b[1]].map(|k| x0[k as usize]);
    let (s, t) = closest_segment_segment(&a0, &a1, &b0, &b1);
    let (pa, pb) = (a0 + s * (a1 - a0), b0 + t * (b1 - b0));
    let moved = |k: u32| end(k as usize) - x0[k as usize];
    let rel = (1.0 - s) * moved(a[0]) + s * moved(a[1]) - (1.0 - t) * moved(b[0]) - t * moved(b[1]);
    let n = normal(&pa, &pb, across(&a0, &a1, &b0, &b1), &rel);
    edge_make(setup, pair, (a, s), (b, t), n, (pa - pb).norm(), h)
}

/// The unit normal of the plane of two edges (zero where they are parallel).
fn across(a0: &V, a1: &V, b0: &V, b1: &V) -> V {
    (a1 - a0)
        .cross(&(b1 - b0))
        .try_normalize(0.0)
        .unwrap_or_else(V::zeros)
}

/// The edge–edge contact between the points at s along `a` and t along `b`, normal `n`,
/// start distance `d`; its cohesive impulse is the pair's cohesion over the smaller of the
/// areas the two points stand for (interpolated along each edge).
fn edge_make(
    setup: &CollisionSetup,
    pair: &SolidPair,
    (a, s): ([u32; 2], f64),
    (b, t): ([u32; 2], f64),
    n: V,
    d: f64,
    h: f64,
) -> Contact {
    let area = |e: [u32; 2], u: f64| {
        let ar = |k: u32| setup.areas.get(k as usize).copied().unwrap_or(0.0);
        (1.0 - u) * ar(e[0]) + u * ar(e[1])
    };
    let cohesion = pair.cohesion * area(a, s).min(area(b, t)) * h;
    make(
        pair,
        n,
        d,
        cohesion,
        &[(a[0], 1.0 - s), (a[1], s), (b[0], -(1.0 - t)), (b[1], -t)],
    )
}

/// The edge–edge contact linearized at the solve's end `x1`: closest points and normal
/// there, the same weights applied to the start positions `x0` for the start distance along
/// that normal. Its constraint n·(p_a − p_b) ≥ distance is the pair's distance function's
/// tangent plane at `x1`, exact to first order where the solve ended.
fn ee_contact_at_end(
    setup: &CollisionSetup,
    pair: &SolidPair,
    a: [u32; 2],
    b: [u32; 2],
    x0: &[V],
    x1: &[V],
    h: f64,
) -> Contact {
    let at = |x: &[V]| [a[0], a[1], b[0], b[1]].map(|k| x[k as usize]);
    let [e0, e1, f0, f1] = at(x1);
    let (s, t) = closest_segment_segment(&e0, &e1, &f0, &f1);
    let (pa, pb) = (e0 + s * (e1 - e0), f0 + t * (f1 - f0));
    let [a0, a1, b0, b1] = at(x0);
    let (qa, qb) = (a0 + s * (a1 - a0), b0 + t * (b1 - b0));
    let n = normal(
        &pa,
        &pb,
        across(&e0, &e1, &f0, &f1),
        &((pa - qa) - (pb - qb)),
    );
    edge_make(setup, pair, (a, s), (b, t), n, n.dot(&(qa - qb)), h)
}

/// A contact between two solids: its point Σ wⱼ xⱼ is the first side's closest point less
/// the second's, kept `pair.distance` apart along `n` (the second side's velocity is in the
/// weights, so the contact's own is zero); `d` the start distance.
fn make(pair: &SolidPair, n: V, d: f64, cohesion: f64, points: &[(u32, f64)]) -> Contact {
    let mut gap = d - pair.distance;
    if gap < 0.0 {
        gap *= pair.strength;
    }
    Contact {
        frame: frame(&n),
        gap,
        friction: pair.friction,
        cohesion,
        damping: pair.damping,
        ..Contact::points(points)
    }
}

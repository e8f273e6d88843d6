//! The contact plane of a point of a solid against a collider's triangle, and the queries it
//! needs: the nearest triangle, which side of a closed mesh a point is on (by the
//! pseudo-normal of the feature its closest point is on), and where along a hair segment its
//! own contact goes. The constraint is n·(x_end − q_end) ≥ distance, the plane carried by
//! the collider over the step (`docs/contacts.md`).

use super::geometry::{closest_on_triangle, closest_segment_triangle, face_normal, frame};
use super::live::{At, Live, SegmentAt};
use super::setup::{CollisionSetup, ContactPair};
use super::surfaces::ColliderSetup;
use nalgebra::Vector3;
use weft_solid::integrator::Contact;

type V = Vector3<f64>;

/// Whether `p` is inside closed collider `c`, by the pseudo-normal of its nearest triangle
/// of `candidates` (`None` for open meshes or no candidates). The candidates must include
/// every triangle nearer to `p` than the ones the caller judges.
pub(super) fn inside_closed(
    c: &ColliderSetup,
    live: &Live,
    candidates: &[u32],
    p: &V,
) -> Option<bool> {
    judged_nearest(c, live, candidates, p).map(|(inside, _)| inside)
}

/// [`inside_closed`]'s answer with the nearest triangle that gave it.
pub(super) fn judged_nearest(
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
pub(super) fn side(
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
pub(super) fn contact(
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

/// The triangle of `candidates` nearest to `p` (ties: the lower index): (distance, triangle,
/// closest point weights).
pub(super) fn nearest(
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
pub(super) fn rooted(sg: &SegmentAt<'_>, pinned: &[bool], candidates: &[u32]) -> bool {
    (0..2).any(|k| {
        pinned[sg.vertices[k]]
            && nearest(sg.collider, sg.live, candidates, &sg.a[k])
                .is_some_and(|(d, _, _)| d < sg.pair.distance)
    })
}

/// Where along segment `p0`–`p1` (in the collider's frame) it is closest to a triangle of
/// `candidates` no farther than `reach`, if that point is inside the segment (ties: the lower
/// triangle index).
pub(super) fn closest_inside(
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
pub(super) fn inside_segment(s: f64) -> bool {
    (1e-3..=1.0 - 1e-3).contains(&s)
}

/// How a hair segment's contact point tells which side of a closed collider it starts on.
#[derive(Clone, Copy, Debug)]
pub(super) enum Side {
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
pub(super) fn segment_contact(
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

//! Wrap: a high-resolution render mesh deformed by a simulated low-resolution one (the proxy).
//!
//! Binding, once, at rest: each render vertex takes the closest point of the proxy's rest
//! surface (a triangle and barycentric weights) and its offset from that point in the
//! triangle's frame (first edge, in-plane normal to it, face normal). Deformed: the same
//! weights on the triangle's current vertices, plus the offset in its current frame. A rigid
//! motion of the proxy turns every frame with it, so the render mesh moves rigidly (to
//! rounding); a render vertex on a proxy vertex has weights (1, 0, 0) and no offset, so a
//! render mesh equal to the proxy follows it exactly.

use nalgebra::{Matrix3, Vector3};

use crate::slide::SurfaceMesh;

/// What a binding stopped by its caller says.
pub const STOPPED: &str = "stopped before the binding was done";

/// Bytes a binding keeps per render vertex (a triangle or three guide places, weights,
/// offset), for memory checks before binding.
pub const BYTES_PER_BOUND_VERTEX: u64 = 80;

/// Each render vertex's place on the proxy.
#[derive(Clone, Debug, PartialEq)]
pub struct Wrap {
    /// The proxy triangle of each render vertex.
    tri: Vec<u32>,
    /// Its barycentric weights there.
    weights: Vec<[f64; 3]>,
    /// Its offset from that point, in the triangle's frame [m].
    offset: Vec<[f64; 3]>,
}

/// A triangle's frame: columns first edge (unit), in-plane normal to it, face normal; None
/// for a triangle without area.
fn frame(a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>) -> Option<Matrix3<f64>> {
    let e1 = (b - a).try_normalize(0.0)?;
    let n = (b - a).cross(&(c - a)).try_normalize(0.0)?;
    Some(Matrix3::from_columns(&[e1, n.cross(&e1), n]))
}

/// The point with weights `w` on the triangle `t` plus the offset `o` in its frame (none when
/// the triangle has collapsed). A zero offset adds nothing, so weights (1, 0, 0) give the
/// vertex itself, bit for bit.
fn placed(t: [Vector3<f64>; 3], w: &[f64; 3], o: &[f64; 3]) -> [f64; 3] {
    let q = w[0] * t[0] + w[1] * t[1] + w[2] * t[2];
    let o = Vector3::from(*o);
    let p = if o == Vector3::zeros() {
        q
    } else {
        frame(&t[0], &t[1], &t[2]).map_or(q, |f| q + f * o)
    };
    p.into()
}

impl Wrap {
    /// Binds `render` (positions at rest) to the proxy's rest surface (`rest`, `triangles`).
    /// Refused: a proxy that is no surface (no triangle, one without area, an index out of
    /// range, a non-finite point), or a non-finite render point.
    pub fn bind(
        rest: &[[f64; 3]],
        triangles: &[[u32; 3]],
        render: &[[f64; 3]],
        stop: &dyn Fn() -> bool,
    ) -> Result<Wrap, String> {
        let mesh = SurfaceMesh::new(rest, triangles)?;
        let mut w = Wrap {
            tri: Vec::with_capacity(render.len()),
            weights: Vec::with_capacity(render.len()),
            offset: Vec::with_capacity(render.len()),
        };
        for (i, p) in render.iter().enumerate() {
            if i % 4096 == 4095 && stop() {
                return Err(STOPPED.into());
            }
            let p = Vector3::from(*p);
            let Some((k, weights, q)) = mesh.closest(&p) else {
                return Err(format!("render vertex {i} is not finite"));
            };
            let [a, b, c] = triangles[k].map(|v| Vector3::from(rest[v as usize]));
            let f = frame(&a, &b, &c).ok_or("a proxy triangle has no area")?;
            w.tri.push(k as u32);
            w.weights.push(weights);
            w.offset.push((f.transpose() * (p - q)).into());
        }
        Ok(w)
    }

    /// The render positions for the proxy at `positions` (the bound triangles' vertices,
    /// indexed like the rest positions). A triangle that has collapsed to no area keeps the
    /// weights and drops the offset.
    pub fn apply(&self, positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Vec<[f64; 3]> {
        self.tri
            .iter()
            .zip(&self.weights)
            .zip(&self.offset)
            .map(|((&k, w), o)| {
                let [a, b, c] = triangles[k as usize].map(|v| Vector3::from(positions[v as usize]));
                placed([a, b, c], w, o)
            })
            .collect()
    }

    /// Render vertices bound.
    pub fn len(&self) -> usize {
        self.tri.len()
    }

    /// True when none are.
    pub fn is_empty(&self) -> bool {
        self.tri.is_empty()
    }
}

/// The points moved by one fixed rigid motion (the tests' check of rigid invariance).
#[cfg(test)]
fn rigidly_moved(ps: &[[f64; 3]]) -> Vec<[f64; 3]> {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    let m = Isometry3::from_parts(
        Translation3::new(0.3, -1.2, 2.0),
        UnitQuaternion::from_euler_angles(0.7, -0.4, 2.1),
    );
    ps.iter()
        .map(|p| m.transform_point(&(*p).into()).coords.into())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An n × n grid of spacing `a` in y = 0 (`weft_scene::procedural::grid`).
    fn grid(n: usize, a: f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let size = a * (n - 1) as f64;
        let m = weft_scene::procedural::grid(
            [size; 2],
            [n; 2],
            weft_scene::procedural::Plane::Xz,
            [0.0; 3],
        );
        (m.positions, m.triangles)
    }

    #[test]
    fn a_rigid_motion_of_the_proxy_moves_the_render_mesh_rigidly() {
        let (proxy, tris) = grid(5, 0.1);
        // A finer render mesh, lifted off the proxy and wavy (offsets of both signs).
        let (mut render, _) = grid(17, 0.025);
        for (k, p) in render.iter_mut().enumerate() {
            p[1] = 0.004 * ((k as f64) * 0.7).sin();
        }
        let w = Wrap::bind(&proxy, &tris, &render, &|| false).unwrap();
        let out = w.apply(&rigidly_moved(&proxy), &tris);
        for (got, want) in out.iter().zip(rigidly_moved(&render)) {
            let d = (Vector3::from(*got) - Vector3::from(want)).norm();
            assert!(d < 1e-12, "{got:?} vs {want:?}");
        }
        // At rest: the render mesh itself.
        for (got, want) in w.apply(&proxy, &tris).iter().zip(&render) {
            assert!((Vector3::from(*got) - Vector3::from(*want)).norm() < 1e-15);
        }
    }

    #[test]
    fn a_render_mesh_equal_to_the_proxy_follows_it_exactly() {
        let (proxy, tris) = grid(6, 0.1);
        let w = Wrap::bind(&proxy, &tris, &proxy, &|| false).unwrap();
        // Any deformation, however far from rigid.
        let bent: Vec<[f64; 3]> = proxy
            .iter()
            .enumerate()
            .map(|(k, p)| {
                [
                    p[0] * 1.3,
                    p[1] + 0.2 * p[0] * p[0],
                    (k as f64 * 0.37).cos(),
                ]
            })
            .collect();
        assert_eq!(w.apply(&bent, &tris), bent);
    }

    #[test]
    fn bad_proxies_are_refused() {
        let (proxy, tris) = grid(3, 0.1);
        assert!(Wrap::bind(&proxy, &[], &proxy, &|| false).is_err());
        assert!(Wrap::bind(&proxy, &[[0, 1, 99]], &proxy, &|| false).is_err());
        assert!(Wrap::bind(&proxy, &tris, &[[f64::NAN, 0.0, 0.0]], &|| false).is_err());
    }
}

/// Render hairs interpolated from simulated guide strands.
///
/// Binding, once, at rest: each render strand takes three guides whose roots are nearest to
/// its root and not on a line, and the barycentric weights of its root in their triangle (in
/// its plane; outside it they extrapolate). Each render vertex at arc-length fraction s of its
/// strand is bound to the three guides' points at the same fraction of theirs: the same weights
/// of those points, plus an offset in the frame of their triangle (as [`Wrap`] does with a
/// cloth's). A rigid motion of the guides moves every render hair rigidly; a render strand
/// equal to a guide follows it exactly.
#[derive(Clone, Debug, PartialEq)]
pub struct HairWrap {
    /// Per render vertex: for each of its three guides, (guide vertex i, fraction t along the
    /// segment i → i + 1; t = 0 on a guide's last vertex).
    at: Vec<[(u32, f64); 3]>,
    /// Per render vertex: its strand's weights on the three guides.
    weights: Vec<[f64; 3]>,
    /// Per render vertex: its offset in the three points' frame [m].
    offset: Vec<[f64; 3]>,
}

/// A curve's vertex range and the cumulative length at each of its vertices.
fn arc(positions: &[[f64; 3]], range: std::ops::Range<usize>) -> Vec<f64> {
    let mut l = vec![0.0];
    for i in range.start + 1..range.end {
        let d = Vector3::from(positions[i]) - Vector3::from(positions[i - 1]);
        l.push(l.last().copied().unwrap_or(0.0) + d.norm());
    }
    l
}

/// (global vertex, fraction) of the point at fraction `s` of a curve's length.
fn at_fraction(start: usize, lengths: &[f64], s: f64) -> (u32, f64) {
    let total = *lengths.last().unwrap_or(&0.0);
    let target = s.clamp(0.0, 1.0) * total;
    for i in 0..lengths.len().saturating_sub(1) {
        let (a, b) = (lengths[i], lengths[i + 1]);
        if target <= b && b > a {
            return ((start + i) as u32, ((target - a) / (b - a)).clamp(0.0, 1.0));
        }
    }
    ((start + lengths.len().saturating_sub(1)) as u32, 0.0)
}

fn point(p: &[[f64; 3]], (i, t): (u32, f64)) -> Vector3<f64> {
    let a = Vector3::from(p[i as usize]);
    if t == 0.0 {
        a
    } else {
        (1.0 - t) * a + t * Vector3::from(p[i as usize + 1])
    }
}

impl HairWrap {
    /// Binds the `render` curves (at rest) to the guide curves at rest. Refused: fewer than
    /// three guides, guide roots all on one line, or a non-finite point.
    pub fn bind(
        guides: &weft_scene::Curves,
        render: &weft_scene::Curves,
        stop: &dyn Fn() -> bool,
    ) -> Result<HairWrap, String> {
        let finite =
            |c: &weft_scene::Curves| c.positions.iter().all(|p| p.iter().all(|v| v.is_finite()));
        if !finite(guides) || !finite(render) {
            return Err("a guide or render point is not finite".into());
        }
        let valid = |c: &weft_scene::Curves, k: usize| {
            c.offsets
                .get(k + 1)
                .is_some_and(|&e| e as usize <= c.positions.len() && c.offsets[k] < e)
        };
        let gcount = guides.len();
        if gcount < 3 || (0..gcount).any(|k| !valid(guides, k)) {
            return Err(format!(
                "needs three or more guide strands with vertices, got {gcount}"
            ));
        }
        let roots: Vec<Vector3<f64>> = (0..gcount)
            .map(|k| Vector3::from(guides.positions[guides.range(k).start]))
            .collect();
        let lengths: Vec<Vec<f64>> = (0..gcount)
            .map(|k| arc(&guides.positions, guides.range(k)))
            .collect();
        let mut w = HairWrap {
            at: Vec::new(),
            weights: Vec::new(),
            offset: Vec::new(),
        };
        for r in 0..render.len() {
            if r % 1024 == 1023 && stop() {
                return Err(STOPPED.into());
            }
            if !valid(render, r) {
                continue;
            }
            let range = render.range(r);
            let root = Vector3::from(render.positions[range.start]);
            // Guides by root distance (ties by index): the nearest two, then the nearest
            // third off their line.
            let mut order: Vec<usize> = (0..gcount).collect();
            order.sort_by(|&a, &b| {
                (roots[a] - root)
                    .norm_squared()
                    .total_cmp(&(roots[b] - root).norm_squared())
                    .then(a.cmp(&b))
            });
            let (g0, g1) = (order[0], order[1]);
            let e = roots[g1] - roots[g0];
            let Some(g2) = order[2..].iter().copied().find(|&g| {
                e.cross(&(roots[g] - roots[g0])).norm()
                    > 1e-9 * e.norm_squared().max(f64::MIN_POSITIVE)
            }) else {
                return Err("the guide roots are all on one line".into());
            };
            let g = [g0, g1, g2];
            // Barycentric weights of the root's projection into the roots' plane.
            let (a, b, c) = (roots[g0], roots[g1], roots[g2]);
            let (v0, v1, v2) = (b - a, c - a, root - a);
            let (d00, d01, d11) = (v0.dot(&v0), v0.dot(&v1), v1.dot(&v1));
            let (d20, d21) = (v2.dot(&v0), v2.dot(&v1));
            let den = d00 * d11 - d01 * d01;
            let (wb, wc) = ((d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den);
            let weights = [1.0 - wb - wc, wb, wc];
            let rl = arc(&render.positions, range.clone());
            let total = *rl.last().unwrap_or(&0.0);
            for (j, i) in range.enumerate() {
                let s = if total > 0.0 { rl[j] / total } else { 0.0 };
                let at = g.map(|k| at_fraction(guides.range(k).start, &lengths[k], s));
                let [pa, pb, pc] = at.map(|x| point(&guides.positions, x));
                let q = weights[0] * pa + weights[1] * pb + weights[2] * pc;
                let p = Vector3::from(render.positions[i]);
                let offset = match frame(&pa, &pb, &pc) {
                    Some(f) if p != q => (f.transpose() * (p - q)).into(),
                    _ => [0.0; 3],
                };
                w.at.push(at);
                w.weights.push(weights);
                w.offset.push(offset);
            }
        }
        Ok(w)
    }

    /// The render hairs' positions for the guides at `positions`.
    pub fn apply(&self, positions: &[[f64; 3]]) -> Vec<[f64; 3]> {
        self.at
            .iter()
            .zip(&self.weights)
            .zip(&self.offset)
            .map(|((at, w), o)| {
                let [a, b, c] = at.map(|x| point(positions, x));
                placed([a, b, c], w, o)
            })
            .collect()
    }
}

#[cfg(test)]
mod hair_tests {
    use super::*;
    use weft_scene::Curves;

    /// Strands of 6 vertices rising from roots on a 3 × 3 patch, bent differently.
    fn guides() -> Curves {
        let mut c = Curves {
            positions: Vec::new(),
            offsets: vec![0],
        };
        for k in 0..9 {
            let (x, z) = ((k % 3) as f64 * 0.02, (k / 3) as f64 * 0.02);
            for j in 0..6 {
                let t = j as f64 * 0.01;
                c.positions
                    .push([x + 0.3 * t * t * (k as f64 * 0.3).sin(), t, z + 0.2 * t * t]);
            }
            c.offsets.push(c.positions.len() as u32);
        }
        c
    }

    #[test]
    fn render_hairs_move_rigidly_with_their_guides_and_a_guide_copy_follows_it_exactly() {
        let g = guides();
        // Render hairs: one on guide 4 (a copy), others between the guides, with more
        // vertices than the guides have.
        let mut render = Curves {
            positions: Vec::new(),
            offsets: vec![0],
        };
        for j in 0..6 {
            render.positions.push(g.positions[4 * 6 + j]);
        }
        render.offsets.push(6);
        for k in 0..5 {
            let (x, z) = (0.005 + 0.007 * k as f64, 0.013 + 0.003 * k as f64);
            for j in 0..11 {
                let t = j as f64 * 0.005;
                render
                    .positions
                    .push([x + 0.1 * t * t, t, z + 0.15 * t * t]);
            }
            render.offsets.push(render.positions.len() as u32);
        }
        let w = HairWrap::bind(&g, &render, &|| false).unwrap();
        // At rest: the render hairs themselves.
        for (got, want) in w.apply(&g.positions).iter().zip(&render.positions) {
            assert!((Vector3::from(*got) - Vector3::from(*want)).norm() < 1e-15);
        }
        let out = w.apply(&rigidly_moved(&g.positions));
        for (got, want) in out.iter().zip(rigidly_moved(&render.positions)) {
            assert!((Vector3::from(*got) - Vector3::from(want)).norm() < 1e-12);
        }
        // Any motion of the guides: the copy of guide 4 is guide 4.
        let bent: Vec<[f64; 3]> = g
            .positions
            .iter()
            .enumerate()
            .map(|(k, p)| {
                [
                    p[0] + 0.01 * (k as f64).sin(),
                    p[1] * 0.9,
                    p[2] - 0.02 * (k as f64).cos(),
                ]
            })
            .collect();
        assert_eq!(&w.apply(&bent)[..6], &bent[24..30]);
    }

    #[test]
    fn too_few_or_collinear_guides_are_refused() {
        let two = Curves {
            positions: vec![[0.0; 3], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]],
            offsets: vec![0, 2, 4],
        };
        assert!(HairWrap::bind(&two, &two, &|| false).is_err());
        let line = Curves {
            positions: (0..3)
                .flat_map(|k| [[k as f64, 0.0, 0.0], [k as f64, 1.0, 0.0]])
                .collect(),
            offsets: vec![0, 2, 4, 6],
        };
        assert!(HairWrap::bind(&line, &line, &|| false).is_err());
    }
}

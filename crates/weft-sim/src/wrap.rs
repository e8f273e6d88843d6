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

impl Wrap {
    /// Binds `render` (positions at rest) to the proxy's rest surface (`rest`, `triangles`).
    /// Refused: a proxy that is no surface (no triangle, one without area, an index out of
    /// range, a non-finite point), or a non-finite render point.
    pub fn bind(
        rest: &[[f64; 3]],
        triangles: &[[u32; 3]],
        render: &[[f64; 3]],
    ) -> Result<Wrap, String> {
        let mesh = SurfaceMesh::new(rest, triangles)?;
        let mut w = Wrap {
            tri: Vec::with_capacity(render.len()),
            weights: Vec::with_capacity(render.len()),
            offset: Vec::with_capacity(render.len()),
        };
        for (i, p) in render.iter().enumerate() {
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
                let q = w[0] * a + w[1] * b + w[2] * c;
                let o = Vector3::from(*o);
                let p = if o == Vector3::zeros() {
                    q
                } else {
                    frame(&a, &b, &c).map_or(q, |f| q + f * o)
                };
                p.into()
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

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};

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
        let w = Wrap::bind(&proxy, &tris, &render).unwrap();
        let m = Isometry3::from_parts(
            Translation3::new(0.3, -1.2, 2.0),
            UnitQuaternion::from_euler_angles(0.7, -0.4, 2.1),
        );
        let moved = |ps: &[[f64; 3]]| -> Vec<[f64; 3]> {
            ps.iter()
                .map(|p| m.transform_point(&(*p).into()).coords.into())
                .collect()
        };
        let out = w.apply(&moved(&proxy), &tris);
        for (got, want) in out.iter().zip(moved(&render)) {
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
        let w = Wrap::bind(&proxy, &tris, &proxy).unwrap();
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
        assert!(Wrap::bind(&proxy, &[], &proxy).is_err());
        assert!(Wrap::bind(&proxy, &[[0, 1, 99]], &proxy).is_err());
        assert!(Wrap::bind(&proxy, &tris, &[[f64::NAN, 0.0, 0.0]]).is_err());
    }
}

//! Sliding attachments' targets, from the scene to the solver: rails (Slide Rail SEC: curves)
//! and surfaces (Slide Surface SEC: a triangle mesh), placed by the attachment element's
//! transform and moved with it every substep. The constraint itself is `weft_solid::slide`.

use nalgebra::{Isometry3, Vector3};
use std::cell::RefCell;
use std::ops::Range;
use std::sync::Arc;

use crate::SystemBuilder;
use crate::collide::bvh::TriangleTree;
use crate::collide::geometry::closest_on_triangle;
use weft_scene::{SceneElement, SlideRail, SlideSurface, Transform};
use weft_solid::{OnSurface, Rail, SlideOn, Slider, Surface};

/// What the sliding attachments' targets move with: each rail or surface of the system, its
/// attachment element and its shape in that element's transform frame.
#[derive(Clone, Debug)]
pub enum TargetPin {
    /// Rail `rail` of the system: its points in the frame.
    Rail {
        /// Index in `system.rails`.
        rail: usize,
        /// Scene index of the attachment element.
        attachment: usize,
        /// The points in the attachment transform's frame.
        local: Vec<Vector3<f64>>,
    },
    /// Surface `surface` of the system: its mesh in the frame.
    Surface {
        /// Index in `system.surfaces`.
        surface: usize,
        /// Scene index of the attachment element.
        attachment: usize,
        /// The mesh in the attachment transform's frame, with its search tree.
        mesh: Arc<SurfaceMesh>,
    },
}

impl TargetPin {
    /// Scene index of the attachment element that moves it.
    pub fn attachment(&self) -> usize {
        match self {
            TargetPin::Rail { attachment, .. } | TargetPin::Surface { attachment, .. } => {
                *attachment
            }
        }
    }

    /// Moves the target to transform `t` (None: the frame is the world).
    pub fn place(&self, t: Option<Transform>, system: &mut weft_solid::SolidSystem) {
        match self {
            TargetPin::Rail { rail, local, .. } => {
                for (p, l) in system.rails[*rail].points.iter_mut().zip(local) {
                    *p = match t {
                        Some(t) => t.transform_point(&(*l).into()).coords,
                        None => *l,
                    };
                }
            }
            TargetPin::Surface { surface, mesh, .. } => {
                system.surfaces[*surface] = Arc::new(PlacedSurface {
                    mesh: mesh.clone(),
                    at: t.unwrap_or_else(Isometry3::identity),
                });
            }
        }
    }
}

/// A triangle mesh to slide on, in its own frame: positions, triangles, unit normals, which
/// edges are open borders, and a tree of triangle bounds for closest-point queries.
pub struct SurfaceMesh {
    points: Vec<Vector3<f64>>,
    triangles: Vec<[u32; 3]>,
    normals: Vec<Vector3<f64>>,
    /// Per triangle, edge k (vertices k, k + 1) is on no other triangle.
    border: Vec<[bool; 3]>,
    tree: TriangleTree,
    /// The mesh's bounding-box diagonal [m] (the search's largest radius).
    size: f64,
}

impl std::fmt::Debug for SurfaceMesh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "SurfaceMesh({} points, {} triangles)",
            self.points.len(),
            self.triangles.len()
        )
    }
}

impl SurfaceMesh {
    /// The mesh, refusing what a vertex cannot slide on (no triangle, an index out of range,
    /// a non-finite point, a triangle without area).
    pub fn new(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Result<Self, String> {
        if triangles.is_empty() {
            return Err("the surface has no triangles".into());
        }
        let points: Vec<Vector3<f64>> = positions.iter().map(|p| Vector3::from(*p)).collect();
        if let Some(i) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(format!("surface point {i} is not finite"));
        }
        let mut normals = Vec::with_capacity(triangles.len());
        let mut edges = std::collections::BTreeMap::new();
        for (k, t) in triangles.iter().enumerate() {
            if t.iter().any(|&i| i as usize >= points.len()) {
                return Err(format!(
                    "surface triangle {k} names a point out of range ({} points)",
                    points.len()
                ));
            }
            let [a, b, c] = t.map(|i| points[i as usize]);
            let n = (b - a).cross(&(c - a));
            let scale = (b - a).norm_squared().max((c - a).norm_squared());
            if n.norm() <= 1e-12 * scale || !n.norm().is_finite() {
                return Err(format!("surface triangle {k} has no area"));
            }
            normals.push(n.normalize());
            for e in 0..3 {
                let (i, j) = (t[e], t[(e + 1) % 3]);
                *edges.entry((i.min(j), i.max(j))).or_insert(0u32) += 1;
            }
        }
        let border = triangles
            .iter()
            .map(|t| {
                [0, 1, 2].map(|e| {
                    let (i, j) = (t[e], t[(e + 1) % 3]);
                    edges[&(i.min(j), i.max(j))] == 1
                })
            })
            .collect();
        let (lo, hi) = points.iter().fold(
            (
                Vector3::repeat(f64::INFINITY),
                Vector3::repeat(f64::NEG_INFINITY),
            ),
            |(lo, hi), p| (lo.inf(p), hi.sup(p)),
        );
        Ok(SurfaceMesh {
            tree: TriangleTree::new(&points, triangles),
            size: (hi - lo).norm(),
            points,
            triangles: triangles.to_vec(),
            normals,
            border,
        })
    }

    /// The closest point of the mesh to `p` (its own frame): triangle, barycentric weights,
    /// point. Searches boxes growing from a small one; the first triangle found bounds the
    /// distance, and one more search within that distance makes the answer exact. Ties go to
    /// the lowest triangle index (deterministic).
    pub(crate) fn closest(&self, p: &Vector3<f64>) -> Option<(usize, [f64; 3], Vector3<f64>)> {
        // A non-finite point has no closest point (and would never end the search).
        if !p.iter().all(|c| c.is_finite()) {
            return None;
        }
        thread_local! {
            static FOUND: RefCell<Vec<u32>> = const { RefCell::new(Vec::new()) };
        }
        FOUND.with(|found| {
            let found = &mut *found.borrow_mut();
            let best_of = |found: &mut Vec<u32>| {
                found.sort_unstable();
                let mut best: Option<(f64, usize, [f64; 3], Vector3<f64>)> = None;
                for &k in found.iter() {
                    let t = self.triangles[k as usize];
                    let [a, b, c] = t.map(|i| self.points[i as usize]);
                    let w = closest_on_triangle(p, &a, &b, &c);
                    let q = w[0] * a + w[1] * b + w[2] * c;
                    let d = (q - p).norm_squared();
                    if best.as_ref().is_none_or(|(bd, ..)| d < *bd) {
                        best = Some((d, k as usize, w, q));
                    }
                }
                best
            };
            let mut r = 1e-6 * self.size.max(1e-3) + p.amax() * f64::EPSILON * 16.0;
            loop {
                found.clear();
                let e = Vector3::repeat(r);
                self.tree.query(&(p - e), &(p + e), found);
                if let Some((d2, ..)) = best_of(found) {
                    // Every triangle closer than the best so far meets the box of that
                    // radius: search it once more (it is no larger than this one).
                    let d = d2.sqrt();
                    if d <= r {
                        found.clear();
                        let e = Vector3::repeat(d);
                        self.tree.query(&(p - e), &(p + e), found);
                    }
                    return best_of(found).map(|(_, k, w, q)| (k, w, q));
                }
                if r > 4.0 * (self.size + p.norm()) {
                    return None;
                }
                r *= 4.0;
            }
        })
    }
}

/// A [`SurfaceMesh`] placed by a rigid transform: the solver's view of it.
#[derive(Debug)]
struct PlacedSurface {
    mesh: Arc<SurfaceMesh>,
    at: Isometry3<f64>,
}

impl Surface for PlacedSurface {
    fn closest(&self, p: &Vector3<f64>) -> Option<OnSurface> {
        let local = self.at.inverse_transform_point(&(*p).into()).coords;
        let (k, w, q) = self.mesh.closest(&local)?;
        let t = self.mesh.triangles[k];
        let n = self.mesh.normals[k];
        // On an open border edge (its opposite weight zero): the edge and the way out.
        let border = (0..3).find_map(|e| {
            let opposite = (e + 2) % 3;
            (self.mesh.border[k][e] && w[opposite] == 0.0).then(|| {
                let (a, b) = (
                    self.mesh.points[t[e] as usize],
                    self.mesh.points[t[(e + 1) % 3] as usize],
                );
                let along = (b - a).normalize();
                // In the plane, away from the opposite vertex.
                let c = self.mesh.points[t[opposite] as usize];
                let mut out = n.cross(&along);
                if out.dot(&(c - a)) > 0.0 {
                    out = -out;
                }
                (
                    self.at.transform_vector(&along),
                    self.at.transform_vector(&out),
                )
            })
        });
        Some(OnSurface {
            point: self.at.transform_point(&q.into()).coords,
            normal: self.at.transform_vector(&n),
            border,
        })
    }
}

/// The targets of sliding attachment `a` (scene index `ai`) into the system, placed by its
/// transform: the rails' and the surfaces' index ranges.
pub(crate) fn targets(
    a: &SceneElement,
    ai: usize,
    b: &mut SystemBuilder,
) -> Result<(Range<usize>, Range<usize>), String> {
    let rail = a.secs.get::<SlideRail>();
    let surface = a.secs.get::<SlideSurface>();
    if rail.is_none() && surface.is_none() {
        return Err(
            "mode slide needs a rail or a surface (connect convert.attachment's 'along' or 'onto')"
                .into(),
        );
    }
    let rails_start = b.system.rails.len();
    if let Some(sec) = rail {
        let c = &sec.curves;
        if c.is_empty() {
            return Err("its rail has no curves".into());
        }
        for k in 0..c.len() {
            let local: Vec<Vector3<f64>> = c
                .positions
                .get(c.range(k))
                .unwrap_or_default()
                .iter()
                .map(|p| Vector3::from(*p))
                .collect();
            let pin = TargetPin::Rail {
                rail: b.system.rails.len(),
                attachment: ai,
                local: local.clone(),
            };
            b.system.rails.push(Rail { points: local });
            pin.place(a.transform, &mut b.system);
            if !b.system.rails[rails_start + k].is_usable() {
                return Err(format!(
                    "rail curve {k} needs two or more finite points with a segment of positive length"
                ));
            }
            b.targets.push(pin);
        }
    }
    let surfaces_start = b.system.surfaces.len();
    if let Some(sec) = surface {
        let mesh = Arc::new(SurfaceMesh::new(&sec.mesh.positions, &sec.mesh.triangles)?);
        b.system.surfaces.push(Arc::new(PlacedSurface {
            mesh: mesh.clone(),
            at: Isometry3::identity(),
        }));
        let pin = TargetPin::Surface {
            surface: b.system.surfaces.len() - 1,
            attachment: ai,
            mesh,
        };
        pin.place(a.transform, &mut b.system);
        b.targets.push(pin);
    }
    Ok((
        rails_start..b.system.rails.len(),
        surfaces_start..b.system.surfaces.len(),
    ))
}

/// Global vertex `g` (vertex `local` of element `name`) slides on the nearest of the given
/// rails and surfaces, with friction `mu`, moved onto it now (with a warning when that is
/// more than a micrometre). With `group` (the members of the rigid group `g` is in), the
/// group slides: its centroid is what is placed, and all its members move.
pub(crate) fn slide(
    b: &mut SystemBuilder,
    g: usize,
    group: Option<&[u32]>,
    (rails, surfaces): (Range<usize>, Range<usize>),
    mu: f64,
    name: &str,
    local: u32,
) {
    let x = match group {
        Some(members) => {
            // Mass-weighted as the solver's (a plain mean if no mass is known yet).
            let w: f64 = members.iter().map(|&m| b.system.mass[m as usize]).sum();
            let mut c = Vector3::zeros();
            for &m in members {
                let m = m as usize;
                c += if w > 0.0 {
                    b.system.mass[m] / w
                } else {
                    1.0 / members.len() as f64
                } * b.x[m];
            }
            c
        }
        None => b.x[g],
    };
    let on = rails
        .map(|k| SlideOn::Rail(k as u32))
        .chain(surfaces.map(|k| SlideOn::Surface(k as u32)));
    let mut best: Option<(f64, SlideOn, Vector3<f64>)> = None;
    for o in on {
        if let Some(p) = weft_solid::slide::place(&b.system.rails, &b.system.surfaces, o, &x) {
            let d = (p.point - x).norm();
            if best.is_none_or(|(bd, _, _)| d < bd) {
                best = Some((d, o, p.point));
            }
        }
    }
    let Some((d, on, p)) = best else { return };
    if d > 1e-6 {
        b.warn(format!(
            "vertex {local} of '{name}' (or its rigid group's centroid) starts {d:.3e} m from what it slides on: moved onto it"
        ));
    }
    match group {
        Some(members) => {
            for &m in members {
                b.x[m as usize] += p - x;
            }
        }
        None => {
            b.x[g] = p;
            b.constrained[g] = true;
        }
    }
    b.system.sliders.push(Slider {
        vertex: g as u32,
        on,
        friction: mu,
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles making the unit square in z = 0.
    fn square() -> SurfaceMesh {
        SurfaceMesh::new(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            &[[0, 1, 2], [0, 2, 3]],
        )
        .unwrap()
    }

    #[test]
    fn closest_points_normals_and_borders_on_a_placed_square() {
        let s = PlacedSurface {
            mesh: Arc::new(square()),
            at: Isometry3::translation(0.0, 0.0, 2.0),
        };
        let o = s.closest(&Vector3::new(0.75, 0.25, 5.0)).unwrap();
        assert_eq!(o.point, Vector3::new(0.75, 0.25, 2.0));
        assert_eq!(o.normal, Vector3::z());
        assert_eq!(o.border, None);
        // Beyond the x = 1 border: on it, with the edge along y and the way out along +x.
        let o = s.closest(&Vector3::new(3.0, 0.5, 2.5)).unwrap();
        assert_eq!(o.point, Vector3::new(1.0, 0.5, 2.0));
        let (along, out) = o.border.unwrap();
        assert!((along.cross(&Vector3::y())).norm() < 1e-15);
        assert!((out - Vector3::x()).norm() < 1e-15);
        // Far away: still found.
        let o = s.closest(&Vector3::new(-1e3, 0.5, 0.0)).unwrap();
        assert_eq!(o.point, Vector3::new(0.0, 0.5, 2.0));
    }

    #[test]
    fn bad_meshes_are_refused() {
        assert!(SurfaceMesh::new(&[[0.0; 3]], &[]).is_err());
        assert!(SurfaceMesh::new(&[[0.0; 3]; 3], &[[0, 1, 2]]).is_err());
        assert!(SurfaceMesh::new(&[[0.0; 3]; 2], &[[0, 1, 2]]).is_err());
        let nan = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [f64::NAN, 1.0, 0.0]];
        assert!(SurfaceMesh::new(&nan, &[[0, 1, 2]]).is_err());
    }
}

//! The camera: vector helpers, framing bounds ([`auto_camera`]), and the projection of world
//! points to pixels with its clip planes ([`View`]).

use super::{Camera, PreviewItem};

// ---------------------------------------------------------------------------------------------
// Vector helpers.

pub(super) type V3 = [f64; 3];

pub(super) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub(super) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
pub(super) fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
pub(super) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub(super) fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
pub(super) fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}
pub(super) fn finite(a: V3) -> bool {
    a.iter().all(|c| c.is_finite())
}
/// `a / |a|`, or `None` when `a` is (nearly) zero or not finite.
pub(super) fn normalize(a: V3) -> Option<V3> {
    let n = norm(a);
    (n.is_finite() && n > 1e-300).then(|| scale(a, 1.0 / n))
}

// ---------------------------------------------------------------------------------------------
// Camera framing.

/// Axis-aligned bounds of the finite vertices of `items`, or `None` if there are none.
pub fn scene_bounds(items: &[PreviewItem<'_>]) -> Option<([f64; 3], [f64; 3])> {
    let mut out: Option<(V3, V3)> = None;
    for item in items {
        let positions = match item {
            PreviewItem::Mesh(m, _) => &m.positions,
            PreviewItem::Curves(c, _) => &c.positions,
        };
        for &p in positions.iter().filter(|p| finite(**p)) {
            let (lo, hi) = out.get_or_insert((p, p));
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    out
}

/// Default vertical field of view of [`auto_camera`] [degrees].
pub(super) const AUTO_FOV_Y: f64 = 35.0;

/// A camera that frames `bounds` `(min, max)` from a three-quarter view: from +z, somewhat
/// above (+y, the up axis) and to the right (+x), looking at the centre of the bounds, far
/// enough that the bounding sphere fits the view with a 15 % margin for an image of the given
/// width / height `aspect`.
///
/// Deterministic. Bounds that are empty, degenerate or not finite use a 1 m extent (around the
/// origin if the centre is not finite); a non-finite or non-positive `aspect` is taken as 1.
pub fn auto_camera(bounds: ([f64; 3], [f64; 3]), aspect: f64) -> Camera {
    let (lo, hi) = bounds;
    let mut center = scale(add(lo, hi), 0.5);
    if !finite(center) {
        center = [0.0; 3];
    }
    let mut radius = 0.5 * norm(sub(hi, lo));
    if !(radius.is_finite() && radius > 1e-9) {
        radius = 0.5;
    }
    let aspect = if aspect.is_finite() && aspect > 0.0 {
        aspect
    } else {
        1.0
    };
    let half_v = (AUTO_FOV_Y * 0.5).to_radians();
    let half_h = (aspect * half_v.tan()).atan();
    let half = half_v.min(half_h);
    let distance = 1.15 * radius / half.sin();
    let dir = [0.45, 0.35, 1.0];
    let dir = scale(dir, 1.0 / norm(dir));
    Camera {
        eye: add(center, scale(dir, distance)),
        target: center,
        up: [0.0, 1.0, 0.0],
        fov_y_degrees: AUTO_FOV_Y,
    }
}

// ---------------------------------------------------------------------------------------------
// Rendering.

/// The camera as an orthonormal frame plus the pixel projection.
pub(super) struct View {
    pub(super) eye: V3,
    pub(super) right: V3,
    pub(super) up: V3,
    pub(super) fwd: V3,
    /// Focal length [pixels].
    pub(super) focal: f64,
    pub(super) cx: f64,
    pub(super) cy: f64,
    /// Near clipping distance [m].
    pub(super) near: f64,
    /// Unit direction towards the light (world space).
    pub(super) to_light: V3,
    /// Clip planes in camera space, `(n, d)` keeping `n·p + d >= 0`: the near plane and a
    /// guard band [`GUARD`] pixels around the image, so projected coordinates stay small
    /// enough for exact fixed-point rasterization.
    pub(super) planes: [[f64; 4]; 5],
}

/// Guard band around the image [pixels]: triangles are clipped this far outside it.
pub(super) const GUARD: f64 = 1024.0;
/// Sub-pixel resolution of the rasterizer: vertices snap to 1/256 pixel.
pub(super) const SUBPIXEL: f64 = 256.0;

impl View {
    pub(super) fn new(camera: &Camera, width: u32, height: u32) -> Option<View> {
        if !(finite(camera.eye) && finite(camera.target)) {
            return None;
        }
        let offset = sub(camera.target, camera.eye);
        let fwd = normalize(offset)?;
        let right = [camera.up, [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]
            .into_iter()
            .filter(|u| finite(*u))
            .find_map(|u| {
                let r = cross(fwd, u);
                // Reject an up direction (nearly) parallel to the view direction.
                (norm(u) > 0.0 && norm(r) > 1e-6 * norm(u)).then(|| normalize(r))?
            })?;
        let up = cross(right, fwd);
        let fov = if camera.fov_y_degrees.is_finite() {
            camera.fov_y_degrees.clamp(1.0, 170.0)
        } else {
            45.0
        };
        let focal = 0.5 * f64::from(height) / (0.5 * fov).to_radians().tan();
        let to_light = normalize(add(
            add(scale(right, -0.5), scale(up, 0.6)),
            scale(fwd, -0.6),
        ))?;
        let (w, h) = (f64::from(width), f64::from(height));
        let (cx, cy) = (0.5 * w, 0.5 * h);
        let near = (1e-4 * norm(offset)).max(1e-9);
        Some(View {
            eye: camera.eye,
            right,
            up,
            fwd,
            focal,
            cx,
            cy,
            near,
            to_light,
            planes: [
                [0.0, 0.0, 1.0, -near],
                [focal, 0.0, cx + GUARD, 0.0],
                [-focal, 0.0, w + GUARD - cx, 0.0],
                [0.0, -focal, cy + GUARD, 0.0],
                [0.0, focal, h + GUARD - cy, 0.0],
            ],
        })
    }

    /// Camera-space coordinates: x right, y up, z depth along the view direction.
    pub(super) fn to_camera(&self, p: V3) -> V3 {
        let d = sub(p, self.eye);
        [dot(d, self.right), dot(d, self.up), dot(d, self.fwd)]
    }

    /// Pixel coordinates and inverse depth of a camera-space point with `z >= near`.
    pub(super) fn project(&self, c: V3) -> V3 {
        let iz = 1.0 / c[2];
        [
            self.cx + self.focal * c[0] * iz,
            self.cy - self.focal * c[1] * iz,
            iz,
        ]
    }
}

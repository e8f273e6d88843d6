//! A small software renderer for looking at results without a 3-D package.
//!
//! [`render`] draws meshes (z-buffered, flat two-sided Lambert shading, lit from the camera's
//! upper left) and curves (depth-tested one- or two-pixel lines) over a light grey gradient;
//! [`auto_camera`] frames given bounds from a three-quarter view; [`write_png`] saves the
//! [`Image`] atomically.
//!
//! Bad input never panics: vertices that are NaN or infinite, triangles with an index out of
//! range, degenerate triangles and geometry behind the camera are skipped or clipped, curves
//! with invalid offsets are skipped, and an unusable camera gives a background-only image.
//!
//! ```
//! use weft_scene::{Mesh, preview::{PreviewItem, auto_camera, render, scene_bounds}};
//! let mesh = Mesh {
//!     positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
//!     triangles: vec![[0, 1, 2]],
//! };
//! let items = [PreviewItem::Mesh(&mesh, [200, 120, 80])];
//! let bounds = scene_bounds(&items).unwrap_or(([0.0; 3], [0.0; 3]));
//! let image = render(&items, &auto_camera(bounds, 4.0 / 3.0), 320, 240);
//! assert_eq!(image.rgb.len(), 320 * 240 * 3);
//! ```

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::geometry::{Curves, Mesh};

/// Largest width or height [`render`] produces; larger requests are clamped to it.
pub const MAX_DIMENSION: u32 = 8192;

/// A pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position [m].
    pub eye: [f64; 3],
    /// Point looked at [m].
    pub target: [f64; 3],
    /// Up direction (need not be orthogonal to the view direction).
    pub up: [f64; 3],
    /// Vertical field of view [degrees]; values outside 1–170 are clamped, non-finite ones
    /// replaced by 45.
    pub fov_y_degrees: f64,
}

/// An 8-bit RGB image, rows top to bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Width [pixels].
    pub width: u32,
    /// Height [pixels].
    pub height: u32,
    /// `width * height` RGB triples, row-major from the top-left pixel.
    pub rgb: Vec<u8>,
}

impl Image {
    /// The colour of pixel `(x, y)` (from the top left), or `None` outside the image.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y as usize * self.width as usize + x as usize) * 3;
        let p = self.rgb.get(i..i + 3)?;
        Some([p[0], p[1], p[2]])
    }
}

/// Something to draw, with its base colour.
#[derive(Clone, Copy, Debug)]
pub enum PreviewItem<'a> {
    /// A triangle mesh, shaded.
    Mesh(&'a Mesh, [u8; 3]),
    /// Curves, drawn as lines.
    Curves(&'a Curves, [u8; 3]),
}

/// Why a PNG could not be written.
#[derive(Debug, thiserror::Error)]
pub enum PreviewError {
    /// Creating, writing or renaming the file failed.
    #[error("cannot write PNG {}: {source}", .path.display())]
    Io {
        /// The file being written (the temporary file or the destination).
        path: PathBuf,
        /// The underlying error.
        source: io::Error,
    },
    /// The PNG encoder failed.
    #[error("cannot encode PNG {}: {source}", .path.display())]
    Png {
        /// The destination.
        path: PathBuf,
        /// The encoder error.
        source: png::EncodingError,
    },
    /// The image cannot be saved (zero size, or pixel data of the wrong length), or the path
    /// does not name a file.
    #[error("cannot write PNG {}: {message}", .path.display())]
    Invalid {
        /// The destination.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

// ---------------------------------------------------------------------------------------------
// Vector helpers.

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}
fn finite(a: V3) -> bool {
    a.iter().all(|c| c.is_finite())
}
/// `a / |a|`, or `None` when `a` is (nearly) zero or not finite.
fn normalize(a: V3) -> Option<V3> {
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
const AUTO_FOV_Y: f64 = 35.0;

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
struct View {
    eye: V3,
    right: V3,
    up: V3,
    fwd: V3,
    /// Focal length [pixels].
    focal: f64,
    cx: f64,
    cy: f64,
    /// Near clipping distance [m].
    near: f64,
    /// Unit direction towards the light (world space).
    to_light: V3,
    /// Clip planes in camera space, `(n, d)` keeping `n·p + d >= 0`: the near plane and a
    /// guard band [`GUARD`] pixels around the image, so projected coordinates stay small
    /// enough for exact fixed-point rasterization.
    planes: [[f64; 4]; 5],
}

/// Guard band around the image [pixels]: triangles are clipped this far outside it.
const GUARD: f64 = 1024.0;
/// Sub-pixel resolution of the rasterizer: vertices snap to 1/256 pixel.
const SUBPIXEL: f64 = 256.0;

impl View {
    fn new(camera: &Camera, width: u32, height: u32) -> Option<View> {
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
    fn to_camera(&self, p: V3) -> V3 {
        let d = sub(p, self.eye);
        [dot(d, self.right), dot(d, self.up), dot(d, self.fwd)]
    }

    /// Pixel coordinates and inverse depth of a camera-space point with `z >= near`.
    fn project(&self, c: V3) -> V3 {
        let iz = 1.0 / c[2];
        [
            self.cx + self.focal * c[0] * iz,
            self.cy - self.focal * c[1] * iz,
            iz,
        ]
    }
}

/// Colour and depth buffers. Depth is stored as inverse view depth (0 = nothing drawn), which
/// interpolates linearly in screen space.
struct Target {
    width: usize,
    height: usize,
    rgb: Vec<u8>,
    inv_depth: Vec<f32>,
}

impl Target {
    fn put(&mut self, x: usize, y: usize, iz: f32, color: [u8; 3], bias: f32) {
        let i = y * self.width + x;
        if iz * bias > self.inv_depth[i] {
            self.inv_depth[i] = self.inv_depth[i].max(iz);
            self.rgb[3 * i..3 * i + 3].copy_from_slice(&color);
        }
    }
}

/// Background colour of row `y`: a light grey vertical gradient.
fn background(y: u32, height: u32) -> [u8; 3] {
    let t = (f64::from(y) + 0.5) / f64::from(height.max(1));
    let top = [238.0, 240.0, 243.0];
    let bottom = [198.0, 201.0, 206.0];
    let mut out = [0; 3];
    for k in 0..3 {
        out[k] = (top[k] + (bottom[k] - top[k]) * t).round() as u8;
    }
    out
}

fn shade(color: [u8; 3], intensity: f64) -> [u8; 3] {
    color.map(|c| (f64::from(c) * intensity).round().clamp(0.0, 255.0) as u8)
}

/// Renders `items` seen by `camera` into a `width` × `height` image (each clamped to
/// [`MAX_DIMENSION`]).
///
/// Triangles are z-buffered and flat-shaded with two-sided Lambert lighting (ambient 0.2,
/// diffuse 0.8 × |n·l|, light from the camera's upper left); curves are depth-tested lines, one
/// pixel wide (two for images of 1000 pixels or more on the short side), shaded by their
/// tangent. Geometry is clipped at a near plane in front of the eye.
pub fn render(items: &[PreviewItem<'_>], camera: &Camera, width: u32, height: u32) -> Image {
    let (width, height) = (width.min(MAX_DIMENSION), height.min(MAX_DIMENSION));
    let (w, h) = (width as usize, height as usize);
    let mut rgb = Vec::with_capacity(w * h * 3);
    for y in 0..height {
        let c = background(y, height);
        for _ in 0..w {
            rgb.extend_from_slice(&c);
        }
    }
    let mut target = Target {
        width: w,
        height: h,
        rgb,
        inv_depth: vec![0.0; w * h],
    };
    if let (Some(view), true) = (View::new(camera, width, height), w > 0 && h > 0) {
        let thick = width.min(height) >= 1000;
        for item in items {
            match *item {
                PreviewItem::Mesh(mesh, color) => draw_mesh(&mut target, &view, mesh, color),
                PreviewItem::Curves(curves, color) => {
                    draw_curves(&mut target, &view, curves, color, thick)
                }
            }
        }
    }
    Image {
        width,
        height,
        rgb: target.rgb,
    }
}

fn draw_mesh(target: &mut Target, view: &View, mesh: &Mesh, color: [u8; 3]) {
    let n = mesh.positions.len();
    for t in &mesh.triangles {
        if t.iter().any(|&i| i as usize >= n) {
            continue;
        }
        let p = t.map(|i| mesh.positions[i as usize]);
        if !p.iter().all(|q| finite(*q)) {
            continue;
        }
        let Some(normal) = normalize(cross(sub(p[1], p[0]), sub(p[2], p[0]))) else {
            continue; // degenerate
        };
        let intensity = 0.2 + 0.8 * dot(normal, view.to_light).abs();
        let c = shade(color, intensity);

        // Clip (Sutherland–Hodgman) against the near plane and the guard band: each plane
        // adds at most one vertex to the convex polygon.
        let mut poly = [[0.0; 3]; 9];
        let mut next = [[0.0; 3]; 9];
        poly[..3].copy_from_slice(&p.map(|q| view.to_camera(q)));
        let mut len = 3;
        for plane in &view.planes {
            let dist = |v: V3| plane[0] * v[0] + plane[1] * v[1] + plane[2] * v[2] + plane[3];
            if poly[..len].iter().all(|&v| dist(v) >= 0.0) {
                continue; // entirely inside this plane: the usual case
            }
            let mut out = 0;
            for k in 0..len {
                let (a, b) = (poly[k], poly[(k + 1) % len]);
                let (da, db) = (dist(a), dist(b));
                if da >= 0.0 && out < next.len() {
                    next[out] = a;
                    out += 1;
                }
                if (da >= 0.0) != (db >= 0.0) && out < next.len() {
                    next[out] = intersect(a, b, dist);
                    out += 1;
                }
            }
            std::mem::swap(&mut poly, &mut next);
            len = out;
            if len < 3 {
                break;
            }
        }
        if len < 3 {
            continue;
        }
        let first = view.project(poly[0]);
        let mut prev = view.project(poly[1]);
        for q in &poly[2..len] {
            let cur = view.project(*q);
            raster_triangle(target, first, prev, cur, c);
            prev = cur;
        }
    }
}

/// Where segment `ab` crosses the plane `dist = 0`, computed the same way whichever way round
/// the segment is given, so triangles sharing an edge get the same point (no cracks).
fn intersect(a: V3, b: V3, dist: impl Fn(V3) -> f64) -> V3 {
    let (p, q) = if a < b { (a, b) } else { (b, a) };
    let (dp, dq) = (dist(p), dist(q));
    add(p, scale(sub(q, p), dp / (dp - dq)))
}

/// Fills a screen-space triangle (x, y in pixels, inverse depth) with z-test.
///
/// Vertices snap to 1/[`SUBPIXEL`] pixel and edge functions are exact integers with a
/// consistent tie rule, so triangles sharing an edge cover each pixel centre exactly once.
/// Coordinates must lie within the guard band (at most about 2^14 pixels), which keeps every
/// product well inside `i64`.
fn raster_triangle(target: &mut Target, a: V3, b: V3, c: V3, color: [u8; 3]) {
    const LIMIT: f64 = (MAX_DIMENSION as f64 + 2.0 * GUARD + 16.0) * SUBPIXEL;
    let snap = |v: V3| -> Option<(i64, i64, f64)> {
        let (x, y) = ((v[0] * SUBPIXEL).round(), (v[1] * SUBPIXEL).round());
        (x.abs() <= LIMIT && y.abs() <= LIMIT && v[2].is_finite())
            .then_some((x as i64, y as i64, v[2]))
    };
    let (Some(a), Some(mut b), Some(mut c)) = (snap(a), snap(b), snap(c)) else {
        return;
    };
    // Edge function of the directed edge p -> q at (x, y): positive on its left in
    // y-down screen space.
    let edge = |p: (i64, i64, f64), q: (i64, i64, f64), x: i64, y: i64| {
        (q.0 - p.0) * (y - p.1) - (q.1 - p.1) * (x - p.0)
    };
    let mut area = edge(a, b, c.0, c.1);
    if area < 0 {
        std::mem::swap(&mut b, &mut c);
        area = -area;
    }
    if area == 0 {
        return;
    }
    let sub = SUBPIXEL as i64;
    let half = sub / 2;
    let min_x = a.0.min(b.0).min(c.0);
    let max_x = a.0.max(b.0).max(c.0);
    let min_y = a.1.min(b.1).min(c.1);
    let max_y = a.1.max(b.1).max(c.1);
    // Pixels whose centre (x + 1/2) lies in the bounding box.
    let x0 = (min_x - half + sub - 1).div_euclid(sub).max(0);
    let x1 = (max_x - half).div_euclid(sub).min(target.width as i64 - 1);
    let y0 = (min_y - half + sub - 1).div_euclid(sub).max(0);
    let y1 = (max_y - half).div_euclid(sub).min(target.height as i64 - 1);
    if x1 < x0 || y1 < y0 {
        return;
    }
    // A pixel centre exactly on an edge belongs to the triangle for which that edge points
    // down (or left when horizontal): one of two triangles sharing the edge, never both.
    let bias = |p: (i64, i64, f64), q: (i64, i64, f64)| {
        let (dx, dy) = (q.0 - p.0, q.1 - p.1);
        if dy > 0 || (dy == 0 && dx < 0) { 0 } else { -1 }
    };
    let (bias_a, bias_b, bias_c) = (bias(b, c), bias(c, a), bias(a, b));
    let (step_a, step_b, step_c) = ((c.1 - b.1) * -sub, (a.1 - c.1) * -sub, (b.1 - a.1) * -sub);
    let inv_area = 1.0 / area as f64;
    let px0 = x0 * sub + half;
    for y in y0..=y1 {
        let py = y * sub + half;
        let mut wa = edge(b, c, px0, py);
        let mut wb = edge(c, a, px0, py);
        let mut wc = edge(a, b, px0, py);
        let row = y as usize * target.width;
        for x in x0 as usize..=x1 as usize {
            if wa + bias_a >= 0 && wb + bias_b >= 0 && wc + bias_c >= 0 {
                let iz = ((wa as f64 * a.2 + wb as f64 * b.2 + wc as f64 * c.2) * inv_area) as f32;
                let i = row + x;
                if iz > target.inv_depth[i] {
                    target.inv_depth[i] = iz;
                    target.rgb[3 * i..3 * i + 3].copy_from_slice(&color);
                }
            }
            wa += step_a;
            wb += step_b;
            wc += step_c;
        }
    }
}

fn draw_curves(target: &mut Target, view: &View, curves: &Curves, color: [u8; 3], thick: bool) {
    if crate::obj::check_offsets(curves).is_err() {
        return;
    }
    for range in curves.offsets.windows(2) {
        let strand = &curves.positions[range[0] as usize..range[1] as usize];
        for seg in strand.windows(2) {
            let (a, b) = (seg[0], seg[1]);
            if !(finite(a) && finite(b)) {
                continue;
            }
            // Hair-style shading: brightest when the strand is perpendicular to the light.
            let intensity = match normalize(sub(b, a)) {
                Some(t) => {
                    let d = dot(t, view.to_light);
                    0.35 + 0.65 * (1.0 - d * d).max(0.0).sqrt()
                }
                None => 0.35 + 0.65,
            };
            draw_segment(target, view, a, b, shade(color, intensity), thick);
        }
    }
}

/// Draws a depth-tested line segment (DDA), clipped to the near plane and the image.
fn draw_segment(target: &mut Target, view: &View, a: V3, b: V3, color: [u8; 3], thick: bool) {
    let (mut ca, mut cb) = (view.to_camera(a), view.to_camera(b));
    let (da, db) = (ca[2] - view.near, cb[2] - view.near);
    if da < 0.0 && db < 0.0 {
        return;
    }
    if da < 0.0 {
        ca = add(ca, scale(sub(cb, ca), da / (da - db)));
        ca[2] = view.near;
    } else if db < 0.0 {
        cb = add(cb, scale(sub(ca, cb), db / (db - da)));
        cb[2] = view.near;
    }
    let (p, q) = (view.project(ca), view.project(cb));
    let d = sub(q, p);
    if !(finite(p) && finite(q) && finite(d)) {
        return;
    }
    // Liang–Barsky clip of p + t d, t in [0, 1], to the image rectangle.
    let (w, h) = (target.width as f64, target.height as f64);
    let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
    for (delta, dist) in [
        (-d[0], p[0]),
        (d[0], w - p[0]),
        (-d[1], p[1]),
        (d[1], h - p[1]),
    ] {
        if delta == 0.0 {
            if dist < 0.0 {
                return;
            }
        } else {
            let t = dist / delta;
            if delta < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    if t0 > t1 {
        return;
    }
    let p0 = add(p, scale(d, t0));
    let span = scale(d, t1 - t0);
    // Lines drawn on a surface should show: let them win against slightly nearer depths.
    let bias = 1.0 + 1e-3;
    let size = [w, h];
    let mut plot = |q: V3, major: usize| {
        let (x, y) = (q[0].floor(), q[1].floor());
        if !(x >= 0.0 && y >= 0.0 && x < w && y < h) {
            return;
        }
        let (x, y) = (x as usize, y as usize);
        let iz = q[2] as f32;
        target.put(x, y, iz, color, bias);
        if thick {
            // Widen across the line.
            let (x2, y2) = if major == 1 { (x + 1, y) } else { (x, y + 1) };
            if x2 < target.width && y2 < target.height {
                target.put(x2, y2, iz, color, bias);
            }
        }
    };
    // One pixel per pixel centre crossed along the major axis: consecutive segments of a
    // curve share their end points, so a strand is drawn without gaps or double pixels.
    let major = if span[1].abs() > span[0].abs() { 1 } else { 0 };
    let (start, end) = (p0[major], p0[major] + span[major]);
    let (lo, hi) = (start.min(end), start.max(end));
    let first = (lo - 0.5).ceil().max(0.0);
    let last = (hi - 0.5).floor().min(size[major] - 1.0);
    if first > last {
        // Shorter than a pixel and crossing no pixel centre: mark the pixel under its middle.
        plot(add(p0, scale(span, 0.5)), major);
        return;
    }
    let mut i = first;
    while i <= last {
        let t = (i + 0.5 - start) / span[major];
        let mut q = add(p0, scale(span, t));
        q[major] = i + 0.5;
        plot(q, major);
        i += 1.0;
    }
}

// ---------------------------------------------------------------------------------------------
// PNG output.

/// Writes `image` as an 8-bit RGB PNG at `path`, atomically: the data goes to
/// `<path>.png.tmp`-style sibling file (`path.with_extension("png.tmp")`), which is synced and
/// then renamed over `path`, so readers never see a partial file.
///
/// # Errors
///
/// [`PreviewError::Invalid`] for a zero-sized image, pixel data whose length is not
/// `width * height * 3`, or a path without a file name; [`PreviewError::Io`] and
/// [`PreviewError::Png`] when writing fails (the temporary file is then removed).
pub fn write_png(image: &Image, path: &Path) -> Result<(), PreviewError> {
    if path.file_name().is_none() {
        return Err(PreviewError::Invalid {
            path: path.to_owned(),
            message: "the path does not name a file".into(),
        });
    }
    let tmp = path.with_extension("png.tmp");
    let result = write_png_to(image, path, &tmp).and_then(|()| {
        std::fs::rename(&tmp, path).map_err(|source| PreviewError::Io {
            path: path.to_owned(),
            source,
        })
    });
    if result.is_err() {
        // Best effort: the temporary file may not exist.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Encodes `image` as an 8-bit RGB PNG into `out` (for callers with their own atomic
/// writer); `path` only labels errors.
pub fn encode_png(image: &Image, path: &Path, out: &mut dyn Write) -> Result<(), PreviewError> {
    let invalid = |message: String| PreviewError::Invalid {
        path: path.to_owned(),
        message,
    };
    if image.width == 0 || image.height == 0 {
        return Err(invalid(format!(
            "image is {}x{}; PNG needs at least 1x1",
            image.width, image.height
        )));
    }
    let expected = image.width as usize * image.height as usize * 3;
    if image.rgb.len() != expected {
        return Err(invalid(format!(
            "image has {} bytes of pixel data; {}x{} RGB needs {expected}",
            image.rgb.len(),
            image.width,
            image.height
        )));
    }
    let png_err = |source| PreviewError::Png {
        path: path.to_owned(),
        source,
    };
    let mut encoder = png::Encoder::new(out, image.width, image.height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().map_err(png_err)?;
    writer.write_image_data(&image.rgb).map_err(png_err)?;
    writer.finish().map_err(png_err)
}

fn write_png_to(image: &Image, path: &Path, tmp: &Path) -> Result<(), PreviewError> {
    let io_err = |source| PreviewError::Io {
        path: tmp.to_owned(),
        source,
    };
    let file = File::create(tmp).map_err(io_err)?;
    let mut out = BufWriter::new(file);
    encode_png(image, path, &mut out)?;
    out.flush().map_err(io_err)?;
    let file = out.into_inner().map_err(|e| io_err(e.into_error()))?;
    file.sync_all().map_err(io_err)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square of side `size` in the plane z = `z`, centred on the z axis, facing +z.
    fn square(size: f64, z: f64) -> Mesh {
        let s = 0.5 * size;
        Mesh {
            positions: vec![[-s, -s, z], [s, -s, z], [s, s, z], [-s, s, z]],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    fn front_camera(distance: f64) -> Camera {
        Camera {
            eye: [0.0, 0.0, distance],
            target: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y_degrees: 60.0,
        }
    }

    /// Number of pixels that differ from the background.
    fn covered(image: &Image) -> usize {
        (0..image.height)
            .flat_map(|y| (0..image.width).map(move |x| (x, y)))
            .filter(|&(x, y)| image.pixel(x, y) != Some(background(y, image.height)))
            .count()
    }

    fn is_background(image: &Image) -> bool {
        covered(image) == 0
    }

    #[test]
    fn unit_quad_covers_expected_fraction() {
        let quad = square(1.0, 0.0);
        let color = [200, 100, 50];
        let image = render(
            &[PreviewItem::Mesh(&quad, color)],
            &front_camera(2.0),
            200,
            200,
        );
        assert_eq!(
            (image.width, image.height, image.rgb.len()),
            (200, 200, 120_000)
        );
        // Focal length 100 / tan(30°) px; the quad spans focal * 1 / 2 px.
        let side = 100.0 / 30f64.to_radians().tan() * 0.5;
        let expected = side * side;
        let count = covered(&image) as f64;
        assert!(
            (count - expected).abs() < 0.03 * expected,
            "covered {count}, expected {expected}"
        );
        // Centre: flat Lambert with |n·l| = 0.6 / |(-0.5, 0.6, 0.6)|.
        let intensity = 0.2 + 0.8 * 0.6 / (0.25_f64 + 0.36 + 0.36).sqrt();
        let shaded = color.map(|c| (f64::from(c) * intensity).round() as u8);
        assert_eq!(image.pixel(100, 100), Some(shaded));
        assert_eq!(image.pixel(60, 60), Some(shaded));
        // Corners and outside the quad: background.
        assert_eq!(image.pixel(0, 0), Some(background(0, 200)));
        assert_eq!(image.pixel(199, 199), Some(background(199, 200)));
        assert_eq!(image.pixel(100, 20), Some(background(20, 200)));
        // Seen from behind it looks the same (two-sided).
        let back = render(
            &[PreviewItem::Mesh(&quad, color)],
            &Camera {
                eye: [0.0, 0.0, -2.0],
                ..front_camera(2.0)
            },
            200,
            200,
        );
        assert_eq!(covered(&back), covered(&image));
    }

    #[test]
    fn z_buffer_keeps_the_nearest_surface() {
        let near = square(1.0, 0.5);
        let far = square(2.0, 0.0);
        let (red, blue) = ([255, 0, 0], [0, 0, 255]);
        for items in [
            [PreviewItem::Mesh(&near, red), PreviewItem::Mesh(&far, blue)],
            [PreviewItem::Mesh(&far, blue), PreviewItem::Mesh(&near, red)],
        ] {
            let image = render(&items, &front_camera(3.0), 100, 100);
            let centre = image.pixel(50, 50).expect("pixel");
            assert!(centre[0] > 0 && centre[2] == 0, "{centre:?}");
            // 25 px from the centre only the far square is visible (half-sizes 17 and 29 px).
            let edge = image.pixel(50, 25).expect("pixel");
            assert!(edge[0] == 0 && edge[2] > 0, "{edge:?}");
        }
    }

    #[test]
    fn empty_and_degenerate_scenes_are_background() {
        let camera = front_camera(2.0);
        assert!(is_background(&render(&[], &camera, 64, 48)));
        let empty = Mesh::default();
        let no_curves = Curves::default();
        let flat = Mesh {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
            triangles: vec![[0, 1, 2], [0, 0, 0]],
        };
        let bad_index = Mesh {
            positions: vec![[0.0; 3]],
            triangles: vec![[0, 5, 9]],
        };
        let bad_offsets = Curves {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0]],
            offsets: vec![0, 5],
        };
        let items = [
            PreviewItem::Mesh(&empty, [0; 3]),
            PreviewItem::Curves(&no_curves, [0; 3]),
            PreviewItem::Mesh(&flat, [0; 3]),
            PreviewItem::Mesh(&bad_index, [0; 3]),
            PreviewItem::Curves(&bad_offsets, [0; 3]),
        ];
        assert!(is_background(&render(&items, &camera, 64, 48)));
        // Zero-sized images and unusable cameras.
        assert_eq!(render(&items, &camera, 0, 10).rgb.len(), 0);
        let quad = square(1.0, 0.0);
        let one = [PreviewItem::Mesh(&quad, [0; 3])];
        for cam in [
            Camera {
                eye: [0.0; 3],
                ..camera
            },
            Camera {
                eye: [f64::NAN; 3],
                ..camera
            },
            Camera {
                up: [0.0, 0.0, 1.0],
                fov_y_degrees: f64::NAN,
                ..camera
            },
        ] {
            let image = render(&one, &cam, 32, 32);
            assert_eq!(image.rgb.len(), 32 * 32 * 3);
        }
    }

    #[test]
    fn nan_vertices_and_geometry_behind_the_camera_do_not_panic() {
        let mut quad = square(1.0, 0.0);
        quad.positions[1] = [f64::NAN, 0.0, f64::INFINITY];
        let curves = Curves {
            positions: vec![[f64::NAN, 0.0, 0.0], [0.0, 0.0, 0.0], [0.1, 0.1, 0.0]],
            offsets: vec![0, 3],
        };
        let items = [
            PreviewItem::Mesh(&quad, [255; 3]),
            PreviewItem::Curves(&curves, [0; 3]),
        ];
        let image = render(&items, &front_camera(2.0), 64, 64);
        // The triangle without the NaN vertex and the finite segment are drawn.
        assert!(covered(&image) > 100);

        // Entirely behind the camera: nothing.
        let behind = square(1.0, 5.0);
        let strand = Curves {
            positions: vec![[0.0, 0.0, 4.0], [0.0, 0.0, 6.0]],
            offsets: vec![0, 2],
        };
        let items = [
            PreviewItem::Mesh(&behind, [255; 3]),
            PreviewItem::Curves(&strand, [0; 3]),
        ];
        assert!(is_background(&render(&items, &front_camera(2.0), 64, 64)));

        // Through the camera plane: clipped, drawn in front, no panic.
        let big = square(100.0, 0.0);
        let through = Mesh {
            positions: vec![[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, -1.0, 10.0]],
            triangles: vec![[0, 1, 2]],
        };
        let long = Curves {
            positions: vec![[0.2, 0.1, -3.0], [0.2, 0.1, 1e9]],
            offsets: vec![0, 2],
        };
        let items = [
            PreviewItem::Mesh(&big, [255; 3]),
            PreviewItem::Mesh(&through, [0, 255, 0]),
            PreviewItem::Curves(&long, [0; 3]),
        ];
        let image = render(&items, &front_camera(2.0), 64, 64);
        assert_eq!(covered(&image), 64 * 64);
    }

    #[test]
    fn curves_draw_depth_tested_lines() {
        // A horizontal strand 1 m in front of the origin, spanning the view.
        let strand = Curves {
            positions: vec![[-10.0, 0.0, 1.0], [0.0, 0.0, 1.0], [10.0, 0.0, 1.0]],
            offsets: vec![0, 3],
        };
        let image = render(
            &[PreviewItem::Curves(&strand, [0, 0, 0])],
            &front_camera(2.0),
            120,
            80,
        );
        // One pixel per column, all on the middle rows.
        let count = covered(&image);
        assert_eq!(count, 120);
        let row = (0..80)
            .find(|&y| image.pixel(60, y) != Some(background(y, 80)))
            .expect("line");
        assert!((39..=40).contains(&row), "{row}");
        // Hidden behind a surface nearer to the eye.
        let wall = square(50.0, 1.5);
        let hidden = render(
            &[
                PreviewItem::Mesh(&wall, [255; 3]),
                PreviewItem::Curves(&strand, [0; 3]),
            ],
            &front_camera(2.0),
            120,
            80,
        );
        let wall_only = render(
            &[PreviewItem::Mesh(&wall, [255; 3])],
            &front_camera(2.0),
            120,
            80,
        );
        assert!(hidden.rgb == wall_only.rgb);
        // A line lying on a surface shows.
        let on = square(50.0, 1.0);
        let image = render(
            &[
                PreviewItem::Mesh(&on, [255; 3]),
                PreviewItem::Curves(&strand, [0; 3]),
            ],
            &front_camera(2.0),
            120,
            80,
        );
        let dark = image.rgb.chunks(3).filter(|p| p[0] < 10).count();
        assert_eq!(dark, 120);
        // A strand of many sub-pixel segments is drawn without gaps: a diagonal of 1000
        // segments across the image covers one pixel per column.
        let fine = Curves {
            positions: (0..=1000)
                .map(|k| {
                    let s = k as f64 / 1000.0;
                    [-0.9 + 1.8 * s, -0.3 + 0.6 * s, 1.0]
                })
                .collect(),
            offsets: vec![0, 1001],
        };
        let image = render(
            &[PreviewItem::Curves(&fine, [0; 3])],
            &front_camera(2.0),
            120,
            80,
        );
        for x in 0..120 {
            let n = (0..80)
                .filter(|&y| image.pixel(x, y) != Some(background(y, 80)))
                .count();
            assert_eq!(n, 1, "column {x}");
        }
    }

    #[test]
    fn auto_camera_frames_the_bounds() {
        let bounds = ([-1.0, 0.0, -1.0], [1.0, 2.0, 1.0]);
        let cam = auto_camera(bounds, 1.5);
        assert_eq!(cam, auto_camera(bounds, 1.5));
        assert_eq!(cam.target, [0.0, 1.0, 0.0]);
        let d = sub(cam.eye, cam.target);
        assert!(
            d[0] > 0.0 && d[1] > 0.0 && d[2] > d[0] && d[2] > d[1],
            "{d:?}"
        );
        // Bounding-sphere radius sqrt(3) fits the 35° vertical field with a 15 % margin.
        let distance = norm(d);
        let expected = 1.15 * 3f64.sqrt() / 17.5f64.to_radians().sin();
        assert!(
            (distance - expected).abs() < 1e-12,
            "{distance} vs {expected}"
        );
        // Every corner of the box projects inside the image.
        let view = View::new(&cam, 300, 200).expect("view");
        for k in 0..8 {
            let corner = [0, 1, 2].map(|a| {
                if k >> a & 1 == 1 {
                    bounds.1[a]
                } else {
                    bounds.0[a]
                }
            });
            let s = view.project(view.to_camera(corner));
            assert!(
                (0.0..300.0).contains(&s[0]) && (0.0..200.0).contains(&s[1]),
                "{s:?}"
            );
        }
        // Degenerate input gets a default 1 m extent.
        let point = auto_camera(([1.0; 3], [1.0; 3]), f64::NAN);
        let expected = 1.15 * 0.5 / 17.5f64.to_radians().sin();
        assert!((norm(sub(point.eye, point.target)) - expected).abs() < 1e-12);
        let nan = auto_camera(([f64::NAN; 3], [f64::INFINITY; 3]), 0.0);
        assert!(finite(nan.eye) && nan.target == [0.0; 3]);
    }

    #[test]
    fn scene_bounds_skip_non_finite_points() {
        let mut quad = square(2.0, 0.5);
        quad.positions.push([f64::NAN, 100.0, 0.0]);
        let strand = Curves {
            positions: vec![[0.0, 3.0, 0.0], [f64::INFINITY, 0.0, 0.0]],
            offsets: vec![0, 2],
        };
        let items = [
            PreviewItem::Mesh(&quad, [0; 3]),
            PreviewItem::Curves(&strand, [0; 3]),
        ];
        assert_eq!(
            scene_bounds(&items),
            Some(([-1.0, -1.0, 0.0], [1.0, 3.0, 0.5]))
        );
        assert_eq!(scene_bounds(&[]), None);
    }

    #[test]
    fn dense_grid_has_no_holes() {
        // A unit square as 128 x 128 quads = 32768 triangles covers the same pixels as the
        // same square made of two triangles: shared edges leave no gaps.
        let n = 129;
        let mut grid = Mesh::default();
        for j in 0..n {
            for i in 0..n {
                let (x, y) = (i as f64 / 128.0 - 0.5, j as f64 / 128.0 - 0.5);
                grid.positions.push([x, y, 0.0]);
            }
        }
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = (j * n + i) as u32;
                let n = n as u32;
                grid.triangles.push([v, v + 1, v + n + 1]);
                grid.triangles.push([v, v + n + 1, v + n]);
            }
        }
        assert_eq!(grid.triangles.len(), 32768);
        let camera = front_camera(2.0);
        let start = std::time::Instant::now();
        let image = render(&[PreviewItem::Mesh(&grid, [180; 3])], &camera, 512, 512);
        let elapsed = start.elapsed();
        let reference = render(
            &[PreviewItem::Mesh(&square(1.0, 0.0), [180; 3])],
            &camera,
            512,
            512,
        );
        let differing = image
            .rgb
            .iter()
            .zip(&reference.rgb)
            .filter(|(p, q)| p != q)
            .count();
        assert_eq!(differing, 0, "render took {elapsed:?}");
        // Half-size focal / 4 = 110.9 px: about 221.7^2 pixels.
        let count = covered(&image) as f64;
        assert!((count - 49_152.0).abs() < 0.02 * 49_152.0, "{count}");
    }

    #[test]
    fn png_has_signature_and_header() {
        let dir = tempfile::tempdir().expect("dir");
        let path = dir.path().join("preview.png");
        let quad = square(1.0, 0.0);
        let image = render(
            &[PreviewItem::Mesh(&quad, [10, 200, 30])],
            &front_camera(2.0),
            37,
            21,
        );
        write_png(&image, &path).expect("write");
        let bytes = std::fs::read(&path).expect("read");
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        assert_eq!(&bytes[8..16], b"\0\0\0\x0dIHDR");
        assert_eq!(u32::from_be_bytes(bytes[16..20].try_into().expect("4")), 37);
        assert_eq!(u32::from_be_bytes(bytes[20..24].try_into().expect("4")), 21);
        assert_eq!((bytes[24], bytes[25]), (8, 2)); // 8-bit RGB
        // Pixels survive, and no temporary file is left behind.
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().expect("info");
        let mut buf = vec![0; reader.output_buffer_size().expect("size")];
        let info = reader.next_frame(&mut buf).expect("frame");
        assert_eq!(&buf[..info.buffer_size()], &image.rgb[..]);
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .expect("list")
            .map(|e| e.expect("entry").file_name())
            .collect();
        assert_eq!(names, ["preview.png"]);

        // Overwrites atomically; bad images and paths are errors.
        write_png(&image, &path).expect("overwrite");
        let empty = Image {
            width: 0,
            height: 5,
            rgb: vec![],
        };
        assert!(matches!(
            write_png(&empty, &path),
            Err(PreviewError::Invalid { .. })
        ));
        let short = Image {
            width: 2,
            height: 2,
            rgb: vec![0; 5],
        };
        assert!(write_png(&short, &path).is_err());
        let missing = dir.path().join("no/such/dir/x.png");
        let err = write_png(&image, &missing).expect_err("missing dir");
        assert!(matches!(err, PreviewError::Io { .. }), "{err}");
        assert!(write_png(&image, Path::new("/")).is_err());
    }
}

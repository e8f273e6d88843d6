//! The rasterizer: z-buffered flat-shaded triangles, depth-tested lines, the background.

use super::camera::*;
use super::{Camera, Image, MAX_DIMENSION, PreviewItem};
use crate::geometry::{Curves, Mesh};

/// Colour and depth buffers. Depth is stored as inverse view depth (0 = nothing drawn), which
/// interpolates linearly in screen space.
pub(super) struct Target {
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) rgb: Vec<u8>,
    pub(super) inv_depth: Vec<f32>,
}

impl Target {
    pub(super) fn put(&mut self, x: usize, y: usize, iz: f32, color: [u8; 3], bias: f32) {
        let i = y * self.width + x;
        if iz * bias > self.inv_depth[i] {
            self.inv_depth[i] = self.inv_depth[i].max(iz);
            self.rgb[3 * i..3 * i + 3].copy_from_slice(&color);
        }
    }
}

/// Background colour of row `y`: a light grey vertical gradient.
pub(super) fn background(y: u32, height: u32) -> [u8; 3] {
    let t = (f64::from(y) + 0.5) / f64::from(height.max(1));
    let top = [238.0, 240.0, 243.0];
    let bottom = [198.0, 201.0, 206.0];
    let mut out = [0; 3];
    for k in 0..3 {
        out[k] = (top[k] + (bottom[k] - top[k]) * t).round() as u8;
    }
    out
}

pub(super) fn shade(color: [u8; 3], intensity: f64) -> [u8; 3] {
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

pub(super) fn draw_mesh(target: &mut Target, view: &View, mesh: &Mesh, color: [u8; 3]) {
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
pub(super) fn intersect(a: V3, b: V3, dist: impl Fn(V3) -> f64) -> V3 {
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
pub(super) fn raster_triangle(target: &mut Target, a: V3, b: V3, c: V3, color: [u8; 3]) {
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

pub(super) fn draw_curves(
    target: &mut Target,
    view: &View,
    curves: &Curves,
    color: [u8; 3],
    thick: bool,
) {
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
pub(super) fn draw_segment(
    target: &mut Target,
    view: &View,
    a: V3,
    b: V3,
    color: [u8; 3],
    thick: bool,
) {
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

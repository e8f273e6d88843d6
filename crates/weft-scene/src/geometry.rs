//! Geometry carried by Scene Elements: triangle meshes and curves (strands), in f64 metres.

/// A triangle mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions [m].
    pub positions: Vec<[f64; 3]>,
    /// Triangles as vertex indices, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
}

/// A set of curves (hair strands), each a polyline.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Curves {
    /// Vertex positions of all curves, curve after curve [m].
    pub positions: Vec<[f64; 3]>,
    /// Curve k is `positions[offsets[k] .. offsets[k + 1]]`; `offsets` starts with 0 and has
    /// one more entry than there are curves.
    pub offsets: Vec<u32>,
}

impl Curves {
    /// Number of curves.
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }
    /// True when there are no curves.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Vertex range of curve `k`.
    pub fn range(&self, k: usize) -> std::ops::Range<usize> {
        self.offsets[k] as usize..self.offsets[k + 1] as usize
    }
}

/// What an element's geometry is.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Geometry {
    /// A data-less element (an attachment instance, a collision group).
    #[default]
    None,
    /// A triangle mesh (cloth, colliders).
    Mesh(Mesh),
    /// Curves (hair).
    Curves(Curves),
    /// Bare points.
    Points(Vec<[f64; 3]>),
}

impl Geometry {
    /// Vertex positions, whatever the kind (empty for `None`).
    pub fn positions(&self) -> &[[f64; 3]] {
        match self {
            Geometry::None => &[],
            Geometry::Mesh(m) => &m.positions,
            Geometry::Curves(c) => &c.positions,
            Geometry::Points(p) => p,
        }
    }
    /// Mutable vertex positions.
    pub fn positions_mut(&mut self) -> &mut [[f64; 3]] {
        match self {
            Geometry::None => &mut [],
            Geometry::Mesh(m) => &mut m.positions,
            Geometry::Curves(c) => &mut c.positions,
            Geometry::Points(p) => p,
        }
    }
    /// Axis-aligned bounds `(min, max)`, or `None` without vertices.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        bounds(self.positions())
    }
}

/// Axis-aligned bounds of points.
pub fn bounds(points: &[[f64; 3]]) -> Option<([f64; 3], [f64; 3])> {
    let first = *points.first()?;
    Some(points.iter().fold((first, first), |(mut lo, mut hi), p| {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
        (lo, hi)
    }))
}

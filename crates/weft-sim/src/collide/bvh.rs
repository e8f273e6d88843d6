//! The one place where parry3d-f64's glam types meet Weft's nalgebra: a bounding-volume
//! hierarchy over a collider's triangles, in the collider's own frame.

use nalgebra::Vector3;
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector as GVec;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy, BvhWorkspace};

fn g(v: &Vector3<f64>) -> GVec {
    GVec::new(v.x, v.y, v.z)
}

fn triangle_box(p: &[Vector3<f64>], t: &[u32; 3]) -> Aabb {
    let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
    Aabb::new(g(&a.inf(&b).inf(&c)), g(&a.sup(&b).sup(&c)))
}

/// Triangles by their bounds; leaf k is triangle k.
pub(crate) struct TriangleTree {
    bvh: Bvh,
    workspace: BvhWorkspace,
}

impl TriangleTree {
    /// A tree over `triangles` of the points `p` (every index in range).
    pub(crate) fn new(p: &[Vector3<f64>], triangles: &[[u32; 3]]) -> Self {
        let leaves: Vec<Aabb> = triangles.iter().map(|t| triangle_box(p, t)).collect();
        TriangleTree {
            bvh: Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves),
            workspace: BvhWorkspace::default(),
        }
    }

    /// Moves the leaves to the triangles' bounds at the points `p` and refits the tree (its
    /// structure is kept: a deforming collider is not rebuilt each frame).
    pub(crate) fn refit(&mut self, p: &[Vector3<f64>], triangles: &[[u32; 3]]) {
        for (k, t) in triangles.iter().enumerate() {
            self.bvh
                .insert_or_update_partially(triangle_box(p, t), k as u32, 0.0);
        }
        self.bvh.refit(&mut self.workspace);
    }

    /// Appends to `out` the triangles whose bounds meet the box `lo..hi`.
    pub(crate) fn query(&self, lo: &Vector3<f64>, hi: &Vector3<f64>, out: &mut Vec<u32>) {
        let aabb = Aabb::new(g(lo), g(hi));
        out.extend(self.bvh.intersect_aabb(&aabb));
    }
}

/// Boxes of a deforming solid's primitives (vertices, edges, triangles); leaf k is box k.
/// Refit each step to the primitives' swept boxes; pairs of overlapping leaves are found by
/// traversing two trees (or one against itself) together.
pub(crate) struct BoxTree {
    bvh: Bvh,
    workspace: BvhWorkspace,
}

impl BoxTree {
    /// A tree over the boxes `lo[k]..hi[k]`.
    pub(crate) fn new(boxes: &[(Vector3<f64>, Vector3<f64>)]) -> Self {
        let leaves: Vec<Aabb> = boxes
            .iter()
            .map(|(lo, hi)| Aabb::new(g(lo), g(hi)))
            .collect();
        BoxTree {
            bvh: Bvh::from_leaves(BvhBuildStrategy::Binned, &leaves),
            workspace: BvhWorkspace::default(),
        }
    }

    /// Moves leaf k to box k and refits (the structure is kept).
    pub(crate) fn refit(&mut self, boxes: &[(Vector3<f64>, Vector3<f64>)]) {
        for (k, (lo, hi)) in boxes.iter().enumerate() {
            self.bvh
                .insert_or_update_partially(Aabb::new(g(lo), g(hi)), k as u32, 0.0);
        }
        self.bvh.refit(&mut self.workspace);
    }

    /// Calls `f` with the leaves whose boxes meet the box `lo..hi`, at most `max` of them.
    pub(crate) fn scan(
        &self,
        lo: &Vector3<f64>,
        hi: &Vector3<f64>,
        max: usize,
        f: impl FnMut(u32),
    ) {
        let aabb = Aabb::new(g(lo), g(hi));
        self.bvh.intersect_aabb(&aabb).take(max).for_each(f);
    }

    /// Appends to `out` every pair (leaf of `self`, leaf of `other`) whose boxes overlap, in
    /// traversal order (the same for the same trees), at most `max` of them: false when
    /// there were more (the rest are not collected). With `other` = `self` each unordered
    /// pair comes twice and each leaf with itself.
    pub(crate) fn pairs(&self, other: &BoxTree, out: &mut Vec<(u32, u32)>, max: usize) -> bool {
        let start = out.len();
        out.extend(
            self.bvh
                .leaf_pairs(&other.bvh, |a, b| a.intersects(b))
                .take(max.saturating_add(1)),
        );
        if out.len() - start > max {
            out.truncate(start + max);
            return false;
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Traversing a tree against itself yields every overlapping pair in both orders (the
    /// detection keeps i < j), checked against all pairs of 60 random boxes.
    #[test]
    fn self_pairs_are_every_overlap_in_both_orders() {
        let mut seed = 5u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let boxes: Vec<(Vector3<f64>, Vector3<f64>)> = (0..60)
            .map(|_| {
                let lo = Vector3::new(rnd(), rnd(), rnd());
                (lo, lo + Vector3::new(rnd(), rnd(), rnd()) * 0.2)
            })
            .collect();
        let tree = BoxTree::new(&boxes);
        let mut found = Vec::new();
        assert!(tree.pairs(&tree, &mut found, usize::MAX));
        found.sort_unstable();
        found.dedup();
        let mut want = Vec::new();
        for (i, a) in boxes.iter().enumerate() {
            for (j, b) in boxes.iter().enumerate() {
                if (0..3).all(|k| a.0[k] <= b.1[k] && b.0[k] <= a.1[k]) {
                    want.push((i as u32, j as u32));
                }
            }
        }
        assert_eq!(found, want);
        // Capped below the count: that many are kept, and the answer says some were not.
        let mut capped = Vec::new();
        assert!(!tree.pairs(&tree, &mut capped, 10));
        assert_eq!(capped.len(), 10);
    }
}

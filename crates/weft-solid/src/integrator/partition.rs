//! Which elements may be assembled at the same time: a fixed binary tree of element sets.
//!
//! Each split cuts the free vertices of its set in two halves (at the median of their longest
//! extent when the system has a layout, else at the median vertex index: a grid's rows, a
//! hair's strands). An element whose free vertices all lie in one half belongs to that half;
//! one that touches both is an interface element of the split. The halves write disjoint
//! gradient entries and matrix blocks, so they are assembled concurrently (`rayon::join`),
//! and the interface elements after both, on one thread. Splitting stops at [`LEAF`] elements
//! or where the interface would be more than [`MAX_INTERFACE`] of the set.
//!
//! Why a tree and not a colouring: colouring the shell's two-ring stencils gives the hanging
//! cloth dozens of colours of a hundred-odd elements each, and a fork–join per colour costs
//! more than the colour's work (the colours run in parallel make assembly slower, not
//! faster; figures in docs/history/issue-71-comments.md); a tree forks once per split.
//!
//! Determinism: the tree depends on the elements, the free vertices and the layout only, never
//! on the thread count; every matrix entry receives its terms in the same order (its leaf's
//! elements in element order, then the interfaces from the leaf up) however the halves are
//! scheduled. So results are bit-identical at any thread count.

use nalgebra::Vector3;

/// Sets with fewer elements than twice this are not split: a fork–join costs as much as
/// assembling some twenty elements when the workers are awake (more when they sleep), so
/// smaller leaves make a small system slower than one thread (`bench/peers`' hanging square
/// at 8² measures it; figures in docs/history/issue-71-comments.md).
const LEAF: usize = 512;

/// A split whose interface holds more than this fraction of its set is not made (its serial
/// part would eat the gain).
const MAX_INTERFACE: f64 = 0.25;

/// Deepest split (at most 2^DEPTH leaves).
const DEPTH: usize = 6;

/// Elements with their free vertices: (element index, stencil's free vertices).
pub(super) type Stencils = Vec<(u32, Vec<u32>)>;

/// A node of the assembly tree.
#[derive(Debug)]
pub(super) enum Part {
    /// Elements assembled one after another, in this order.
    Leaf(Vec<u32>),
    /// Two halves that touch disjoint vertices, then the elements touching both.
    Split {
        halves: Box<[Part; 2]>,
        interface: Vec<u32>,
    },
}

impl Part {
    /// Calls `work` on every element: the two halves of each split concurrently when
    /// `parallel`, the interface after them.
    pub(super) fn run<F: Fn(&u32) + Sync>(&self, work: &F, parallel: bool) {
        match self {
            Part::Leaf(e) => e.iter().for_each(work),
            Part::Split { halves, interface } => {
                if parallel {
                    rayon::join(|| halves[0].run(work, true), || halves[1].run(work, true));
                } else {
                    halves[0].run(work, false);
                    halves[1].run(work, false);
                }
                interface.iter().for_each(work);
            }
        }
    }

    /// Number of leaves (for tests and statistics).
    #[cfg(test)]
    pub(super) fn leaves(&self) -> usize {
        match self {
            Part::Leaf(_) => 1,
            Part::Split { halves, .. } => halves[0].leaves() + halves[1].leaves(),
        }
    }

    /// Every element once, in the order `run` without threads visits them.
    #[cfg(test)]
    pub(super) fn elements(&self) -> Vec<u32> {
        match self {
            Part::Leaf(e) => e.clone(),
            Part::Split { halves, interface } => {
                let mut v = halves[0].elements();
                v.extend(halves[1].elements());
                v.extend(interface);
                v
            }
        }
    }
}

/// The assembly tree of `elements` (each one's free vertices, ascending element index kept
/// with it), over `n` vertices with optional positions `at` (used when there is one per
/// vertex and all are finite).
pub(super) fn partition(elements: Stencils, n: usize, at: &[Vector3<f64>]) -> Part {
    let layout =
        (at.len() == n && at.iter().all(|p| p.iter().all(|c| c.is_finite()))).then_some(at);
    let mut verts: Vec<u32> = {
        let mut used = vec![false; n];
        for (_, vs) in &elements {
            for &v in vs {
                used[v as usize] = true;
            }
        }
        (0..n as u32).filter(|&v| used[v as usize]).collect()
    };
    // side[v]: which half of the current split vertex v is in (scratch, reused).
    let mut side = vec![0u8; n];
    split(elements, &mut verts, layout, &mut side, 0)
}

fn split(
    elements: Stencils,
    verts: &mut [u32],
    layout: Option<&[Vector3<f64>]>,
    side: &mut [u8],
    depth: usize,
) -> Part {
    let leaf = |e: Stencils| Part::Leaf(e.into_iter().map(|(i, _)| i).collect());
    if elements.len() < 2 * LEAF || depth >= DEPTH || verts.len() < 2 {
        return leaf(elements);
    }
    let mid = verts.len() / 2;
    match layout {
        Some(at) => {
            let (mut lo, mut hi) = (at[verts[0] as usize], at[verts[0] as usize]);
            for &v in verts.iter() {
                lo = lo.inf(&at[v as usize]);
                hi = hi.sup(&at[v as usize]);
            }
            let axis = (hi - lo).imax();
            // Ties broken by index: the same split for the same input.
            verts.select_nth_unstable_by(mid, |&a, &b| {
                at[a as usize][axis]
                    .total_cmp(&at[b as usize][axis])
                    .then(a.cmp(&b))
            });
        }
        None => {
            verts.select_nth_unstable(mid);
        }
    }
    for (k, &v) in verts.iter().enumerate() {
        side[v as usize] = u8::from(k >= mid);
    }
    let (mut a, mut b, mut interface) = (Vec::new(), Vec::new(), Vec::new());
    let total = elements.len();
    for (i, vs) in elements {
        let mut sides = vs.iter().map(|&v| side[v as usize]);
        match sides.next() {
            None => a.push((i, vs)),
            Some(s0) => {
                if sides.all(|s| s == s0) {
                    if s0 == 0 { &mut a } else { &mut b }.push((i, vs));
                } else {
                    interface.push(i);
                }
            }
        }
    }
    if interface.len() as f64 > MAX_INTERFACE * total as f64 {
        let mut all: Stencils = a;
        all.extend(b);
        // Back to element order (the halves' elements were taken apart, the interface's
        // stencils dropped): a leaf of every element, by index.
        let mut ids: Vec<u32> = all.iter().map(|(i, _)| *i).collect();
        ids.extend(interface);
        ids.sort_unstable();
        return Part::Leaf(ids);
    }
    let (va, vb) = verts.split_at_mut(mid);
    let pa = split(a, va, layout, side, depth + 1);
    let pb = split(b, vb, layout, side, depth + 1);
    Part::Split {
        halves: Box::new([pa, pb]),
        interface,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Triangles of an n × n vertex grid, each with its three vertices.
    fn grid(n: u32) -> (Stencils, Vec<Vector3<f64>>) {
        let mut e = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let v = j * n + i;
                e.push((e.len() as u32, vec![v, v + 1, v + n]));
                e.push((e.len() as u32, vec![v + 1, v + n + 1, v + n]));
            }
        }
        let at = (0..n * n)
            .map(|v| Vector3::new((v % n) as f64, 0.0, (v / n) as f64))
            .collect();
        (e, at)
    }

    /// Checks that a tree's halves never share a vertex, recursively; returns its vertices.
    fn disjoint(p: &Part, stencil: &dyn Fn(u32) -> Vec<u32>) -> Vec<u32> {
        match p {
            Part::Leaf(e) => e.iter().flat_map(|&i| stencil(i)).collect(),
            Part::Split { halves, interface } => {
                let mut a = disjoint(&halves[0], stencil);
                let mut b = disjoint(&halves[1], stencil);
                a.sort_unstable();
                a.dedup();
                b.sort_unstable();
                b.dedup();
                assert!(
                    a.iter().all(|v| b.binary_search(v).is_err()),
                    "halves share a vertex"
                );
                a.extend(b);
                a.extend(interface.iter().flat_map(|&i| stencil(i)));
                a
            }
        }
    }

    #[test]
    fn halves_touch_disjoint_vertices_and_every_element_is_kept_once() {
        let (e, at) = grid(48);
        let stencils = e.clone();
        let stencil = |i: u32| stencils[i as usize].1.clone();
        for layout in [&at[..], &[]] {
            let p = partition(e.clone(), at.len(), layout);
            // 4,418 triangles: split down to leaves of at least LEAF (but fewer than 2 LEAF).
            assert!(p.leaves() >= 8, "{} leaves", p.leaves());
            disjoint(&p, &stencil);
            let mut all = p.elements();
            all.sort_unstable();
            assert_eq!(all, (0..e.len() as u32).collect::<Vec<_>>());
        }
    }

    #[test]
    fn small_sets_and_bad_layouts_stay_whole() {
        let (e, mut at) = grid(8);
        assert_eq!(partition(e.clone(), at.len(), &at).leaves(), 1);
        let (e48, at48) = grid(48);
        // A layout with a NaN is ignored: the split falls back to vertex indices.
        at[3].x = f64::NAN;
        assert_eq!(partition(e, at.len(), &at).leaves(), 1);
        let with_nan: Vec<_> = at48.iter().map(|p| p * f64::NAN).collect();
        let by_index = partition(e48.clone(), at48.len(), &[]);
        let nan = partition(e48, at48.len(), &with_nan);
        assert_eq!(by_index.elements(), nan.elements());
    }

    #[test]
    fn an_element_joining_everything_goes_to_the_interface() {
        let (mut e, at) = grid(48);
        let all: Vec<u32> = (0..48 * 48).collect();
        e.push((e.len() as u32, all));
        let p = partition(e.clone(), at.len(), &at);
        let Part::Split { interface, .. } = &p else {
            panic!("not split");
        };
        assert!(interface.contains(&(e.len() as u32 - 1)));
    }
}

//! Fill-reducing orderings of the Newton system's vertex graph, and the choice between them.
//!
//! The Cholesky factor's cost depends on the order its unknowns are eliminated in. Two
//! orderings are built on the graph of vertices (3×3 blocks, expanded to DOFs afterwards):
//! - approximate minimum degree (AMD, faer's): greedy and local; ideal for chains (hair) and
//!   small sheets;
//! - nested dissection by coordinate bisection (George 1973; the geometric variant of
//!   Miller, Teng, Thurston & Vavasis 1998): cut the vertices at the median of their longest
//!   extent, take the vertices of one half that touch the other as the separator, order the
//!   two halves (recursively) before it. On a sheet its separators are straight, so the
//!   dense blocks at the top of the elimination tree are as small as the mesh allows.
//!   On the hanging cloth's pattern (shell bending couples a vertex's two-ring) AMD needs
//!   fewer flops up to about 24², dissection ever fewer above, about half of AMD's from
//!   64² (figures in docs/history/issue-71-comments.md).
//!
//! The integrator analyses minimum degree first; where the system has a layout and that
//! factor is large (see `DISSECTION_MIN_FLOPS` in `integrator.rs`), it analyses nested
//! dissection too and keeps it if it needs clearly fewer flops ([`supernodal_flops`]). Both
//! depend only on the graph and the layout, never on threads. Dissection's factorizations
//! are faster from 64² on, about twice as fast at the largest sizes (`weft bench solid`'s
//! hanging cloth measures it; figures in docs/history/issue-71-comments.md).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::SymbolicSparseColMatRef;
use faer::sparse::linalg::amd;
use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;
use nalgebra::Vector3;

/// Subgraphs this small are ordered as they are: inside them the order changes the flops by
/// little (other leaf sizes, or AMD inside the leaves, gain nothing worth the work; figures
/// in docs/history/issue-71-comments.md).
const LEAF: usize = 16;

/// AMD on the graph whose node j neighbours `nbrs[j]` (sorted, itself included): `order[i]`
/// is the node eliminated i-th.
pub(super) fn minimum_degree(nbrs: &[Vec<u32>]) -> Result<Vec<usize>, String> {
    let n = nbrs.len();
    let mut ptr = Vec::with_capacity(n + 1);
    let mut idx = Vec::new();
    ptr.push(0);
    for l in nbrs {
        idx.extend(l.iter().map(|&i| i as usize));
        ptr.push(idx.len());
    }
    let sym = SymbolicSparseColMatRef::new_checked(n, n, &ptr, None, &idx);
    let (mut perm, mut inv) = (vec![0usize; n], vec![0usize; n]);
    let mut mem = MemBuffer::new(amd::order_scratch::<usize>(n, idx.len()));
    amd::order(
        &mut perm,
        &mut inv,
        sym,
        amd::Control::default(),
        MemStack::new(&mut mem),
    )
    .map_err(|e| format!("{e:?}"))?;
    Ok(perm)
}

/// Nested dissection of the graph `nbrs` by the coordinates `at` of its first `at.len()`
/// nodes; the nodes after those (rigid groups' nodes, coupled to many vertices) come last.
/// `None` when a coordinate is not finite. `order[i]` is the node eliminated i-th.
pub(super) fn nested_dissection(nbrs: &[Vec<u32>], at: &[Vector3<f64>]) -> Option<Vec<usize>> {
    let n = at.len().min(nbrs.len());
    if at[..n].iter().any(|p| !p.iter().all(|c| c.is_finite())) {
        return None;
    }
    enum Task {
        Split(Vec<u32>),
        Emit(Vec<u32>),
    }
    let mut order = Vec::with_capacity(nbrs.len());
    // 1: in the half being cut away from (the right one), for the boundary test.
    let mut right = vec![false; nbrs.len()];
    // A stack, not recursion: a layout with many equal coordinates may split unevenly.
    let mut tasks = vec![Task::Split((0..n as u32).collect())];
    while let Some(task) = tasks.pop() {
        let mut set = match task {
            Task::Emit(sep) => {
                order.extend(sep.iter().map(|&v| v as usize));
                continue;
            }
            Task::Split(set) => set,
        };
        let (mut lo, mut hi) = (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(-f64::INFINITY),
        );
        for &v in &set {
            lo = lo.inf(&at[v as usize]);
            hi = hi.sup(&at[v as usize]);
        }
        let axis = (hi - lo).imax();
        if set.len() <= LEAF || hi[axis] <= lo[axis] {
            order.extend(set.iter().map(|&v| v as usize));
            continue;
        }
        set.sort_unstable_by(|&a, &b| {
            at[a as usize][axis]
                .total_cmp(&at[b as usize][axis])
                .then(a.cmp(&b))
        });
        // Cut at the median's coordinate, keeping equal coordinates on one side (a row of a
        // grid is not split, or the separator would take a third row). The extent is
        // positive, so both sides are non-empty.
        let cut = at[set[set.len() / 2] as usize][axis];
        let mut half = set.partition_point(|&v| at[v as usize][axis] < cut);
        if half == 0 {
            half = set.partition_point(|&v| at[v as usize][axis] <= cut);
        }
        let (left, rest) = set.split_at(half);
        for &v in rest {
            right[v as usize] = true;
        }
        let (mut inner, mut separator) = (Vec::new(), Vec::new());
        for &v in left {
            if nbrs[v as usize].iter().any(|&w| right[w as usize]) {
                separator.push(v);
            } else {
                inner.push(v);
            }
        }
        for &v in rest {
            right[v as usize] = false;
        }
        // Popped in reverse: the left half, the right half, then their separator.
        tasks.push(Task::Emit(separator));
        tasks.push(Task::Split(rest.to_vec()));
        tasks.push(Task::Split(inner));
    }
    order.extend(n..nbrs.len());
    Some(order)
}

/// Floating-point operations of a numeric factorization with this supernodal structure:
/// per supernode of w columns with m rows below, w³/3 for its diagonal block, w²m for the
/// panel below it and wm² for its update of the rest.
pub(super) fn supernodal_flops(symbolic: &SymbolicCholeskyRaw<usize>) -> f64 {
    match symbolic {
        SymbolicCholeskyRaw::Supernodal(sn) => flops(sn),
        // Never built (the integrator forces supernodal), but not a reason to fail.
        SymbolicCholeskyRaw::Simplicial(_) => f64::INFINITY,
    }
}

fn flops(sn: &SymbolicSupernodalCholesky<usize>) -> f64 {
    let (begin, end, val_ptr) = (
        sn.supernode_begin(),
        sn.supernode_end(),
        sn.col_ptr_for_val(),
    );
    (0..begin.len())
        .map(|s| {
            let w = (end[s] - begin[s]) as f64;
            let m = (val_ptr[s + 1] - val_ptr[s]) as f64 / w - w;
            w * w * w / 3.0 + w * w * m + w * m * m
        })
        .sum()
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::factor::{DISSECTION_GAIN, DISSECTION_MIN_FLOPS};
    use super::*;
    use crate::system::{SolidSystem, State};

    /// A k × k membrane sheet (1 m square, in the xy plane) whose membrane carries weak
    /// springs to every vertex two rows or columns away, which couple each vertex's two-ring
    /// as shell bending does; gravity along −z, held at two corners of its first row.
    pub(in crate::integrator) fn two_ring_sheet(k: usize) -> (SolidSystem, State) {
        use crate::energy::{MembraneMaterial, RodStretch};
        let mat = MembraneMaterial::orthotropic(1e6, 0.3, 1e-3, 1.0, 1.0, 1.0);
        let (mut sys, state) =
            crate::verify::membrane_sheet(k, k, 1.0, 1.0, mat, Vector3::x()).unwrap();
        // Every vertex two rows or columns away (a 5 × 5 stencil, as the shell's two-ring).
        let ring: Vec<(i64, i64)> = (-2i64..=2)
            .flat_map(|di| (0i64..=2).map(move |dj| (di, dj)))
            .filter(|&(di, dj)| (dj > 0 || di > 0) && di.abs().max(dj) == 2)
            .collect();
        for j in 0..k as i64 {
            for i in 0..k as i64 {
                for &(di, dj) in &ring {
                    let (ii, jj) = (i + di, j + dj);
                    if (0..k as i64).contains(&ii) && jj < k as i64 {
                        let (a, b) = ((j * k as i64 + i) as usize, (jj * k as i64 + ii) as usize);
                        sys.elements.stretches.push(RodStretch {
                            v: [a as u32, b as u32],
                            rest_length: (state.x[a] - state.x[b]).norm(),
                            k: 10.0,
                        });
                    }
                }
            }
        }
        sys.gravity = Vector3::new(0.0, 0.0, -9.81);
        sys.pinned[0] = true;
        sys.pinned[k - 1] = true;
        (sys, state)
    }

    /// A k × k sheet (1 m square, in the xy plane) with membranes (2 MPa, 0.5 mm) and shell
    /// bending of plate stiffness `d`, gravity along −z, held at two corners of its first
    /// row, its layout the rest shape.
    pub(in crate::integrator) fn shell_sheet(k: usize, d: f64) -> (SolidSystem, State) {
        use crate::energy::{MembraneMaterial, shell_bending};
        let mat = MembraneMaterial::orthotropic(2e6, 0.3, 5e-4, 1.0, 1.0, 1.0);
        let (mut sys, state) =
            crate::verify::membrane_sheet(k, k, 1.0, 1.0, mat, Vector3::x()).unwrap();
        let tris: Vec<[u32; 3]> = sys.elements.membranes.iter().map(|m| m.v).collect();
        let bending = shell_bending(&state.x, &tris, d, 0.3).unwrap();
        sys.elements.shells = bending.vertices;
        sys.elements.midedges = bending.triangles;
        sys.gravity = Vector3::new(0.0, 0.0, -9.81);
        sys.pinned[0] = true;
        sys.pinned[k - 1] = true;
        sys.layout = state.x.clone();
        (sys, state)
    }

    /// The largest distance between corresponding vertices of two states.
    pub(in crate::integrator) fn farthest(a: &State, b: &State) -> f64 {
        a.x.iter()
            .zip(&b.x)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max)
    }

    /// The vertex graph of a k × k grid where each vertex neighbours those within `reach`
    /// rows and columns (itself included), and the grid's coordinates.
    fn grid(k: usize, reach: usize) -> (Vec<Vec<u32>>, Vec<Vector3<f64>>) {
        let mut nbrs = vec![Vec::new(); k * k];
        let mut at = Vec::new();
        for j in 0..k {
            for i in 0..k {
                at.push(Vector3::new(i as f64 * 0.1, 0.0, j as f64 * 0.1));
                for jj in j.saturating_sub(reach)..(j + reach + 1).min(k) {
                    for ii in i.saturating_sub(reach)..(i + reach + 1).min(k) {
                        nbrs[j * k + i].push((jj * k + ii) as u32);
                    }
                }
            }
        }
        (nbrs, at)
    }

    fn is_permutation(order: &[usize], n: usize) -> bool {
        let mut seen = vec![false; n];
        order.len() == n
            && order
                .iter()
                .all(|&v| v < n && !std::mem::replace(&mut seen[v], true))
    }

    #[test]
    fn dissection_orders_every_node_once_and_separates_the_halves() {
        let (nbrs, at) = grid(20, 2);
        let order = nested_dissection(&nbrs, &at).unwrap();
        assert!(is_permutation(&order, nbrs.len()));
        // The cut halves the 20 columns; the last 40 nodes are the top separator, the two
        // columns (reach 2) of the first half next to the second. Before them come the
        // first half's other 160 nodes, then the second half's 200, and no node of those 160
        // neighbours one of those 200.
        let first: std::collections::HashSet<usize> = order[..160].iter().copied().collect();
        let second: std::collections::HashSet<usize> = order[160..360].iter().copied().collect();
        for &v in &first {
            assert!(nbrs[v].iter().all(|&w| !second.contains(&(w as usize))));
        }
    }

    #[test]
    fn extra_nodes_come_last_and_bad_layouts_are_refused() {
        let (mut nbrs, mut at) = grid(6, 1);
        // Two extra nodes (a rigid group's) coupled to everything.
        let n = nbrs.len() as u32;
        for l in &mut nbrs {
            l.extend([n, n + 1]);
        }
        nbrs.push((0..n + 2).collect());
        nbrs.push((0..n + 2).collect());
        let order = nested_dissection(&nbrs, &at).unwrap();
        assert!(is_permutation(&order, nbrs.len()));
        assert_eq!(&order[order.len() - 2..], &[36, 37]);
        at[7].y = f64::NAN;
        assert!(nested_dissection(&nbrs, &at).is_none());
    }

    /// A sheet large enough for dissection to be tried: with its layout the integrator takes
    /// nested dissection (fewer flops), and a step solves the same system to rounding. Its
    /// membrane carries weak springs to every vertex two rows or columns away, which couple
    /// each vertex's two-ring as shell bending does (with the membrane's one-ring alone,
    /// minimum degree does well: 9.6e8 flops at 120² against dissection's 8.2e8).
    #[test]
    fn a_large_sheet_with_a_layout_is_dissected_and_steps_to_the_same_answer() {
        use crate::integrator::{Integrator, Settings};
        let k = 100;
        let (mut sys, state) = two_ring_sheet(k);
        let plain = Integrator::new(&sys).unwrap();
        sys.layout = state.x.clone();
        let cut = Integrator::new(&sys).unwrap();
        let flops = |i: &Integrator| supernodal_flops(i.dirs.factor.analysis.symbolic.raw());
        assert!(
            plain.dirs.factor.analysis.fwd != cut.dirs.factor.analysis.fwd,
            "the layout changed nothing"
        );
        assert!(
            flops(&cut) < DISSECTION_GAIN * flops(&plain),
            "dissection {:.3e} flops, minimum degree {:.3e}",
            flops(&cut),
            flops(&plain)
        );
        assert!(flops(&plain) >= DISSECTION_MIN_FLOPS);
        // The last unknowns are the top separator: vertices of one straight band.
        let last: Vec<usize> = cut.dirs.factor.analysis.fwd
            [cut.dirs.factor.analysis.fwd.len() - 3 * k..]
            .iter()
            .step_by(3)
            .map(|&d| d / 3)
            .collect();
        // Free index f is vertex f + 1 before the second pin (vertex k − 1), f + 2 after.
        let vertex = |f: usize| if f + 1 < k - 1 { f + 1 } else { f + 2 };
        let span = |c: fn(&Vector3<f64>) -> f64| {
            let v: Vec<f64> = last.iter().map(|&f| c(&state.x[vertex(f)])).collect();
            v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min)
        };
        assert!(span(|p| p.x).min(span(|p| p.y)) <= 3.0 / (k - 1) as f64);
        // One step of each: the same minimizer, to the tolerance's scale (1e-6 m/s · h).
        let settings = Settings::default();
        let h = 1.0 / 48.0;
        let (mut a, mut b) = (state.clone(), state.clone());
        let (mut plain, mut cut) = (plain, cut);
        plain.step(&sys, &mut a, None, h, &settings).unwrap();
        cut.step(&sys, &mut b, None, h, &settings).unwrap();
        let far = farthest(&a, &b);
        assert!(far < 1e-8, "the orderings' steps differ by {far:e} m");
    }

    #[test]
    fn coincident_and_collinear_layouts_still_give_permutations() {
        let (nbrs, _) = grid(12, 2);
        // Every vertex at one point: one leaf in index order.
        let same = vec![Vector3::new(1.0, 2.0, 3.0); nbrs.len()];
        let order = nested_dissection(&nbrs, &same).unwrap();
        assert_eq!(order, (0..nbrs.len()).collect::<Vec<_>>());
        // Many vertices on few distinct coordinates: uneven splits, still a permutation.
        let lumpy: Vec<_> = (0..nbrs.len())
            .map(|i| Vector3::new((i % 3) as f64, 0.0, if i < 100 { 0.0 } else { i as f64 }))
            .collect();
        assert!(is_permutation(
            &nested_dissection(&nbrs, &lumpy).unwrap(),
            nbrs.len()
        ));
    }
}

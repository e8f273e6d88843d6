//! Rigid groups in the Newton solve: each group's vertices move as one rigid body.
//!
//! A group is two nodes of the system (three unknowns each, like a vertex): a translation T
//! and a small rotation Θ about the group's centroid c at the iterate, so a member at
//! x = c + q moves by J [T; Θ] = T + Θ × q = [I, −[q]×] [T; Θ]. Assembly maps every member's
//! gradient and Hessian blocks through J (reduced coordinates: JᵀHJ, Jᵀg), and adds the
//! rotation's own curvature, Σ_members sym(g qᵀ) − (g·q) I on the Θ block (the second-order
//! term of gᵀ exp([Θ]×) q; projected to PSD with the projected Hessians; on a group whose
//! members lie on a line, restricted to the turns that move the line: the turn about it is
//! a gauge, `gauge_free`). Trial points move
//! members exactly: x ← c + αT + exp(α[Θ]×) q, so distances within a group are kept to
//! rounding whatever the step. Members are not free vertices (their `free_of` is NONE):
//! elements that touch one are scattered through J serially, after the coloured ones.

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::{Hessians, Integrator, NONE};
use crate::energy::{Local, MAX_DOFS};

const MAX_STENCIL: usize = MAX_DOFS / 3;
use crate::spd::project_psd;
use crate::system::SolidSystem;

/// The rigid groups as the integrator sees them (built with the pattern).
#[derive(Default)]
pub(super) struct Groups {
    /// Per group: its translation node (the rotation node is the next one).
    pub(super) node: Vec<u32>,
    /// Per group: its member vertices.
    pub(super) members: Vec<Vec<u32>>,
    /// Per vertex: its group, or NONE.
    pub(super) of: Vec<u32>,
    /// Per group: the centroid (mass-weighted) at the last assembly.
    pub(super) center: Vec<Vector3<f64>>,
    /// Per vertex: a member's offset from its group's centroid at the last assembly.
    pub(super) offset: Vec<Vector3<f64>>,
    /// The first group node (every node before it is a free vertex).
    pub(super) first: usize,
    /// Per vertex: the gradient at a member from every term, at the last assembly (for the
    /// rotation's curvature term).
    pub(super) grad_at: Vec<Vector3<f64>>,
    /// Elements with a member in their stencil (scattered through J, in order).
    pub(super) elements: Vec<u32>,
    /// Their evaluation scratch.
    pub(super) local: Option<Box<Local>>,
}

/// For a group whose members' offsets span at most a line (`spread` = Σ q qᵀ of rank ≤ 1
/// to rounding: its second invariant, the sum of its principal 2×2 minors, below 1e-12 of
/// its trace squared), the projector onto the turns that move it: I − a aᵀ along the line
/// a, or zero where the members coincide. None for a group that spans a plane or more.
///
/// A group nearly but not exactly on a line (its width 1e-6 to 1e-2 of its length) keeps
/// the exact curvature: its turn about the line moves its members, by little, and its
/// Hessian may still need inertia added where a torque acts.
fn gauge_free(spread: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let tr = spread.trace();
    let minors = 0.5 * (tr * tr - (spread * spread).trace());
    if minors.is_nan() || minors > 1e-12 * tr * tr {
        return None;
    }
    // Rank one: every column is a multiple of a; the largest is the best conditioned.
    let col = (1..3).fold(spread.column(0).into_owned(), |best, k| {
        let c = spread.column(k).into_owned();
        if c.norm_squared() > best.norm_squared() {
            c
        } else {
            best
        }
    });
    let norm = col.norm();
    if norm == 0.0 || !norm.is_finite() {
        return Some(Matrix3::zeros());
    }
    let a = col / norm;
    Some(Matrix3::identity() - a * a.transpose())
}

fn skew(q: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -q.z, q.y, q.z, 0.0, -q.x, -q.y, q.x, 0.0)
}

impl Groups {
    /// The groups of `sys` with nodes from `first_node` on; `free_of` gets NONE for members.
    pub(super) fn new(sys: &SolidSystem, free_of: &mut [u32], first_node: usize) -> Self {
        let n = free_of.len();
        let mut of = vec![NONE; n];
        let mut node = Vec::with_capacity(sys.rigid.len());
        let mut members = Vec::with_capacity(sys.rigid.len());
        for (g, group) in sys.rigid.iter().enumerate() {
            node.push((first_node + 2 * g) as u32);
            members.push(group.vertices.clone());
            for &v in &group.vertices {
                if let Some(slot) = of.get_mut(v as usize) {
                    *slot = g as u32;
                    free_of[v as usize] = NONE;
                }
            }
        }
        let per_vertex = if node.is_empty() { 0 } else { n };
        Groups {
            center: vec![Vector3::zeros(); node.len()],
            offset: vec![Vector3::zeros(); per_vertex],
            first: first_node,
            grad_at: vec![Vector3::zeros(); per_vertex],
            node,
            members,
            of,
            elements: Vec::new(),
            local: None,
        }
    }

    /// Whether there are none.
    pub(super) fn is_empty(&self) -> bool {
        self.node.is_empty()
    }

    /// The nodes a vertex moves with and their Jacobian's columns: a free vertex its own
    /// (identity), a member its group's two ([I, −[q]×]), a held one none.
    pub(super) fn nodes_of(&self, free_of: &[u32], v: usize) -> ([(u32, Matrix3<f64>); 2], usize) {
        let f = free_of[v];
        if f != NONE {
            return ([(f, Matrix3::identity()), (NONE, Matrix3::zeros())], 1);
        }
        match self.of.get(v) {
            Some(&g) if g != NONE => {
                let t = self.node[g as usize];
                (
                    [(t, Matrix3::identity()), (t + 1, -skew(&self.offset[v]))],
                    2,
                )
            }
            _ => ([(NONE, Matrix3::zeros()); 2], 0),
        }
    }

    /// Every group's centroid at `x` (weighted by mass) and its members' offsets from it;
    /// clears the members' gradients.
    pub(super) fn centers(&mut self, sys: &SolidSystem, x: &[Vector3<f64>]) {
        for (c, m) in self.center.iter_mut().zip(&self.members) {
            let (mut s, mut w) = (Vector3::zeros(), 0.0);
            for &v in m {
                s += sys.mass[v as usize] * x[v as usize];
                w += sys.mass[v as usize];
            }
            *c = s / w;
            for &v in m {
                self.offset[v as usize] = x[v as usize] - *c;
                self.grad_at[v as usize] = Vector3::zeros();
            }
        }
    }
}

impl Integrator {
    /// Adds `b` to block (row node `r`, column node `c`) (in the pattern by construction).
    pub(super) fn add_block(&mut self, r: u32, c: u32, b: &Matrix3<f64>) {
        let Some(s) = self.lin.block_slot(r as usize, c as usize) else {
            debug_assert!(false, "block ({r}, {c}) is not in the pattern");
            return;
        };
        for (v, b) in self
            .lin
            .block_mut(c as usize, s)
            .iter_mut()
            .zip(b.as_slice())
        {
            *v += b;
        }
    }

    /// Adds a vertex's gradient `g` and Hessian block `h` (both from per-vertex terms:
    /// inertia, damping, drag) for member `v` through its group's Jacobian.
    pub(super) fn add_member_terms(&mut self, v: usize, g: &Vector3<f64>, h: &Matrix3<f64>) {
        let (nodes, k) = self.groups.nodes_of(&self.lin.free_of, v);
        self.groups.grad_at[v] += g;
        for &(na, ja) in &nodes[..k] {
            let gj = ja.transpose() * g;
            for c in 0..3 {
                self.work.grad[3 * na as usize + c] += gj[c];
            }
            for &(nb, jb) in &nodes[..k] {
                let b = ja.transpose() * h * jb;
                self.add_block(na, nb, &b);
            }
        }
    }

    /// Adds an element's `local` gradient and Hessian (stencil `verts`) through the nodes'
    /// Jacobians: for elements with a member in their stencil.
    pub(super) fn add_element_through_groups(&mut self, verts: &[u32], local: &Local) {
        // Each stencil vertex's nodes, once: (node, S) with J = I for S = None and
        // J = −S (S = [q]×) for a group's rotation node, so Jᵀ = S there.
        let mut nodes = [([(NONE, None::<Matrix3<f64>>); 2], 0usize); MAX_STENCIL];
        for (a, &va) in verts.iter().enumerate() {
            let (list, k) = self.groups.nodes_of(&self.lin.free_of, va as usize);
            nodes[a].1 = k;
            for (slot, &(n, j)) in nodes[a].0.iter_mut().zip(&list[..k]) {
                // nodes_of gives −S for a rotation node, the identity otherwise.
                *slot = (n, (j != Matrix3::identity()).then_some(-j));
            }
        }
        for (a, &va) in verts.iter().enumerate() {
            let ga = Vector3::new(
                local.grad[3 * a],
                local.grad[3 * a + 1],
                local.grad[3 * a + 2],
            );
            if self.groups.of.get(va as usize).is_some_and(|&g| g != NONE) {
                self.groups.grad_at[va as usize] += ga;
            }
            let (na_list, ka) = nodes[a];
            for &(na, sa) in &na_list[..ka] {
                let gj = sa.map_or(ga, |s| s * ga);
                for c in 0..3 {
                    self.work.grad[3 * na as usize + c] += gj[c];
                }
                for (b, &(nb_list, kb)) in nodes[..verts.len()].iter().enumerate() {
                    if kb == 0 {
                        continue;
                    }
                    let mut hab = Matrix3::zeros();
                    for cc in 0..3 {
                        for rr in 0..3 {
                            hab[(rr, cc)] = local.hess[3 * b + cc][3 * a + rr];
                        }
                    }
                    // Jaᵀ H Jb with Jᵀ = S and J = −S on rotation nodes.
                    let left = sa.map_or(hab, |s| s * hab);
                    for &(nb, sb) in &nb_list[..kb] {
                        let blk = sb.map_or(left, |s| -(left * s));
                        self.add_block(na, nb, &blk);
                    }
                }
            }
        }
    }

    /// The rotation's curvature on every group's Θ block, Σ sym(g qᵀ) − (g·q) I over its
    /// members (projected to PSD with the projected Hessians), and a regularization of
    /// 1e-12 of the block's scale so a group on a line (no inertia about it) stays
    /// factorizable (its gradient has no component about the line).
    ///
    /// On a line group (two vertices, or members on one line) a turn about the line moves no
    /// member: it is a gauge, not a degree of freedom. The curvature is then taken on the
    /// turns that move the line only, P m P with P = I − a aᵀ (a the line's direction):
    /// the Hessian of the energy restricted to them, exact there. Left in, the exponential
    /// map's second-order cross terms (a turn about a and one about b move a member along b
    /// by ½ θ_a θ_b |q|) couple the gauge, whose diagonal is zero, to the turns that carry a
    /// torque, so the Hessian is indefinite at every iterate off equilibrium (on
    /// `graphs/curtain_rail.json`'s two-vertex rings, more inertia shifts than Newton
    /// iterations; figures in docs/history/issue-71-comments.md).
    pub(super) fn finish_groups(&mut self, hessians: Hessians) {
        for g in 0..self.groups.node.len() {
            let mut m = Matrix3::zeros();
            let mut spread = Matrix3::zeros();
            for &v in &self.groups.members[g] {
                let v = v as usize;
                let (gv, q) = (self.groups.grad_at[v], self.groups.offset[v]);
                let gq = gv * q.transpose();
                m += 0.5 * (gq + gq.transpose()) - gv.dot(&q) * Matrix3::identity();
                spread += q * q.transpose();
            }
            if let Some(p) = gauge_free(&spread) {
                m = p * m * p;
            }
            if hessians == Hessians::Projected {
                project_psd(&mut m);
            }
            let r = self.groups.node[g] + 1;
            let Some(s) = self.lin.block_slot(r as usize, r as usize) else {
                continue;
            };
            let block = self.lin.block_mut(r as usize, s);
            let diag = [0, 4, 8]
                .map(|k| block[k].abs())
                .into_iter()
                .fold(0.0f64, f64::max);
            m += 1e-12 * diag * Matrix3::identity();
            self.add_block(r, r, &m);
        }
    }

    /// Moves every group's members of `x` by `alpha` times its nodes' step in `dir`, exactly
    /// rigidly (about the centroid of the last assembly), into `out`.
    pub(super) fn move_members(&self, dir: &[f64], alpha: f64, out: &mut [Vector3<f64>]) {
        for (g, members) in self.groups.members.iter().enumerate() {
            let t = 3 * self.groups.node[g] as usize;
            let step = alpha * Vector3::new(dir[t], dir[t + 1], dir[t + 2]);
            let turn = alpha * Vector3::new(dir[t + 3], dir[t + 4], dir[t + 5]);
            let r = Rotation3::new(turn);
            let c = self.groups.center[g];
            for &v in members {
                let v = v as usize;
                out[v] = c + step + r * self.groups.offset[v];
            }
        }
    }

    /// The largest of `size(T, Θ, q)` over every group's members (T, Θ the group's nodes
    /// in `dir`, q the member's offset), sequentially: the same bits at any thread count.
    fn largest_over_members(
        &self,
        dir: &[f64],
        size: impl Fn(&Vector3<f64>, &Vector3<f64>, &Vector3<f64>) -> f64,
    ) -> f64 {
        let mut m = 0.0f64;
        for (g, members) in self.groups.members.iter().enumerate() {
            let t = 3 * self.groups.node[g] as usize;
            let step = Vector3::new(dir[t], dir[t + 1], dir[t + 2]);
            let turn = Vector3::new(dir[t + 3], dir[t + 4], dir[t + 5]);
            for &v in members {
                m = m.max(size(&step, &turn, &self.groups.offset[v as usize]));
            }
        }
        m
    }

    /// The largest displacement of a member by the step `dir` (its linearization).
    pub(super) fn member_step_size(&self, dir: &[f64]) -> f64 {
        self.largest_over_members(dir, |step, turn, q| (step + turn.cross(q)).amax())
    }

    /// A bound on how far any point moves per unit of α along `dir` (Euclidean): a free
    /// vertex by its own |d|, a member by |T| + |Θ| |q|, since
    /// |exp(a[Θ]×)q − exp(b[Θ]×)q| ≤ |a − b| |Θ| |q| (the same axis, angles apart by
    /// |a − b| |Θ|). So placing the step at α = s instead of 1 moves no point more than
    /// (s − 1) times this beyond where α = 1 puts it. Sequential: the same bits at any
    /// thread count.
    pub(super) fn largest_move(&self, dir: &[f64]) -> f64 {
        let end = if self.groups.is_empty() {
            dir.len()
        } else {
            3 * self.groups.first
        };
        let free = dir[..end]
            .chunks_exact(3)
            .map(|d| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt())
            .fold(0.0f64, f64::max);
        free.max(
            self.largest_over_members(dir, |step, turn, q| step.norm() + turn.norm() * q.norm()),
        )
    }

    /// Adds `mu(v)` per member to its group's translation diagonal and `mu(v) |q|²` to its
    /// rotation diagonal (the isotropic part of the same shift, moved through J).
    pub(super) fn add_to_group_diagonals(&mut self, mu: &impl Fn(usize) -> f64) {
        for g in 0..self.groups.node.len() {
            let (mut t, mut r) = (0.0, 0.0);
            for &v in &self.groups.members[g] {
                let v = v as usize;
                t += mu(v);
                r += mu(v) * self.groups.offset[v].norm_squared();
            }
            let n = self.groups.node[g];
            self.add_block(n, n, &(t * Matrix3::identity()));
            self.add_block(n + 1, n + 1, &(r * Matrix3::identity()));
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::energy::RodStretch;
    use crate::system::RigidGroup;
    use crate::{Integrator, Method, Settings, SolidSystem, State};
    use nalgebra::Vector3;

    fn settings(method: Method) -> Settings {
        Settings {
            method,
            tolerance: 1e-11,
            max_iterations: 100,
        }
    }

    #[test]
    fn a_spinning_rigid_triangle_keeps_its_shape_and_its_centroid_falls_freely() {
        // Three vertices of unequal mass, spinning at ω about a tilted axis, thrown upwards.
        // Only gravity acts: the centroid follows implicit Euler's free fall exactly
        // (v_n = v₀ + n h g), and every distance is kept to rounding.
        let x = vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.1, 0.0, 0.02),
            Vector3::new(0.03, 0.07, -0.01),
        ];
        let mass = vec![0.01, 0.02, 0.015];
        let total: f64 = mass.iter().sum();
        // The mass-weighted mean of positions or velocities.
        let mean = |p: &[Vector3<f64>]| {
            p.iter()
                .zip(&mass)
                .map(|(p, m)| *m * p)
                .sum::<Vector3<f64>>()
                / total
        };
        let c0 = mean(&x);
        let (omega, vc0) = (Vector3::new(3.0, -5.0, 8.0), Vector3::new(0.2, 1.0, 0.0));
        let v0: Vec<_> = x.iter().map(|p| vc0 + omega.cross(&(p - c0))).collect();
        let v = v0.clone();
        let mut sys = SolidSystem::new(mass.clone());
        sys.gravity = Vector3::new(0.0, -9.81, 0.0);
        sys.rigid.push(RigidGroup {
            vertices: vec![0, 1, 2],
        });
        let mut s = State { x: x.clone(), v };
        let mut integ = Integrator::new(&sys).unwrap();
        let h = 0.01;
        let dist = |s: &State, a: usize, b: usize| (s.x[a] - s.x[b]).norm();
        let rest = [dist(&s, 0, 1), dist(&s, 1, 2), dist(&s, 0, 2)];
        for n in 1..=100 {
            integ
                .step(&sys, &mut s, None, h, &settings(Method::Newton))
                .unwrap();
            for (k, (a, b)) in [(0, 1), (1, 2), (0, 2)].into_iter().enumerate() {
                let d = dist(&s, a, b);
                assert!(
                    (d / rest[k] - 1.0).abs() < 1e-12,
                    "step {n}: {d} vs {}",
                    rest[k]
                );
            }
            let vc = mean(&s.v);
            let want = vc0 + n as f64 * h * sys.gravity;
            assert!((vc - want).norm() < 1e-9, "step {n}: {vc:?} vs {want:?}");
        }
        // Still spinning (implicit Euler damps a free rotation by ~(ωh)²/2 a step, here
        // ~0.5 %, so about 40 % is left after 100 steps; not to rest).
        let spin = |x: &[Vector3<f64>], v: &[Vector3<f64>]| {
            (v[1] - mean(v)).norm() / (x[1] - mean(x)).norm()
        };
        let (now, then) = (spin(&s.x, &s.v), spin(&x, &v0));
        assert!(
            now > 0.3 * then && now < then,
            "spin {now} rad/s from {then}"
        );
    }

    #[test]
    fn a_line_groups_curvature_is_exact_on_the_turns_that_move_it_and_drops_the_gauge() {
        // Two members on a line (a two-vertex ring) pulled unequally, so with a torque: the
        // curvature of Σ g·exp([Θ]×) q over the turns Θ. Along the line a the exact one has a
        // zero diagonal and cross terms to the torque's turns (indefinite); restricted, it
        // matches central differences on the plane ⊥ a and has a as a null vector.
        let q = [
            Vector3::new(-0.03, 0.01, 0.02),
            Vector3::new(0.06, -0.02, -0.04),
        ];
        let g = [Vector3::new(0.2, 0.9, -0.3), Vector3::new(-1.5, 2.6, -1.1)];
        let mut m = nalgebra::Matrix3::zeros();
        let mut spread = nalgebra::Matrix3::zeros();
        for (g, q) in g.iter().zip(&q) {
            let gq = g * q.transpose();
            m += 0.5 * (gq + gq.transpose()) - g.dot(q) * nalgebra::Matrix3::identity();
            spread += q * q.transpose();
        }
        let a = q[1].normalize();
        assert!(m.symmetric_eigen().eigenvalues.min() < -1e-3, "{m}");
        let p = super::gauge_free(&spread).expect("a line group");
        let r = p * m * p;
        assert!((r * a).norm() < 1e-15, "{}", r * a);
        // f(Θ) = Σ g·exp([Θ]×) q; its second differences along b, c ⊥ a, where the
        // restriction keeps m as it was (step 1e-4 rad: the error is O(step²) of the fourth
        // derivative, |g||q| ≈ 0.24, so ~1e-9).
        let f = |t: Vector3<f64>| -> f64 {
            let r = nalgebra::Rotation3::new(t);
            g.iter().zip(&q).map(|(g, q)| g.dot(&(r * q))).sum()
        };
        let b = a.cross(&Vector3::z()).normalize();
        let c = a.cross(&b);
        let s = 1e-4;
        for (u, w) in [(b, b), (c, c), (b, c)] {
            let fd = (f(s * (u + w)) - f(s * (u - w)) - f(s * (w - u)) + f(-s * (u + w)))
                / (4.0 * s * s);
            let exact = u.dot(&(r * w));
            assert!((fd - exact).abs() < 1e-7, "{fd} vs {exact}");
        }
        // A triangle spans a plane: every turn moves it, nothing is dropped.
        let tri = [Vector3::x(), Vector3::y(), -Vector3::x() - Vector3::y()];
        let spread: nalgebra::Matrix3<f64> = tri.iter().map(|q| q * q.transpose()).sum();
        assert!(super::gauge_free(&spread).is_none());
    }

    #[test]
    fn a_swinging_two_vertex_ring_takes_exact_newton_steps() {
        // A bar of two rigid members (a ring of two cloth vertices) hung by two springs from
        // pinned points, thrown sideways and turning: off equilibrium its turns carry a
        // torque. With the gauge (the turn about the bar) dropped, the exact Hessian is
        // positive definite: no inertia is added, and Newton converges quadratically.
        let x = vec![
            Vector3::new(0.0, 0.0, 0.0),
            Vector3::new(0.1, 0.0, 0.0),
            Vector3::new(-0.05, 0.2, 0.03),
            Vector3::new(0.2, 0.15, -0.02),
        ];
        let mut sys = SolidSystem::new(vec![0.01, 0.02, 1.0, 1.0]);
        sys.gravity = Vector3::new(0.0, -9.81, 0.0);
        sys.pinned[2] = true;
        sys.pinned[3] = true;
        for (v, rest) in [([0, 2], 0.15), ([1, 3], 0.12)] {
            sys.elements.stretches.push(RodStretch {
                v,
                rest_length: rest,
                k: 20.0,
            });
        }
        sys.rigid.push(RigidGroup {
            vertices: vec![0, 1],
        });
        let v = vec![
            Vector3::new(0.3, 0.1, 0.8),
            Vector3::new(0.3, -0.2, -0.4),
            Vector3::zeros(),
            Vector3::zeros(),
        ];
        let mut s = State { x, v };
        let mut integ = Integrator::new(&sys).unwrap();
        for n in 0..20 {
            let st = integ
                .step(&sys, &mut s, None, 0.01, &settings(Method::Newton))
                .unwrap();
            assert_eq!(st.shifted, 0, "step {n}: {:?}", st.residuals);
            // Superlinear at the end: the last correction at most 1e-3 of the one before
            // (linear convergence contracts by a fixed ratio; measured 5.0e-5 at most over 20 steps).
            let r = &st.residuals;
            let k = r.len() - 1;
            assert!(
                k >= 1 && r[k] <= 1e-3 * r[k - 1],
                "step {n}: residuals {r:?}"
            );
        }
    }

    /// A vertical chain of 7 vertices (mass 0.01 kg each) hanging from vertex 0 by stiff
    /// segments; with `rigid` the last three form a group. Static equilibrium's positions.
    fn hanging_chain(rigid: bool) -> Vec<Vector3<f64>> {
        let n = 7;
        let x: Vec<_> = (0..n)
            .map(|i| Vector3::new(0.0, -0.1 * i as f64, 0.0))
            .collect();
        let mut sys = SolidSystem::new(vec![0.01; n]);
        sys.gravity = Vector3::new(0.0, -9.81, 0.0);
        sys.pinned[0] = true;
        for i in 0..n - 1 {
            sys.elements.stretches.push(RodStretch {
                v: [i as u32, i as u32 + 1],
                rest_length: 0.1,
                k: 50.0,
            });
        }
        if rigid {
            sys.rigid.push(RigidGroup {
                vertices: vec![4, 5, 6],
            });
        }
        let mut s = State {
            x,
            v: vec![Vector3::zeros(); n],
        };
        let mut integ = Integrator::new(&sys).unwrap();
        integ
            .step(&sys, &mut s, None, 1.0, &settings(Method::Static))
            .unwrap();
        s.x
    }

    #[test]
    fn a_rigid_group_at_the_end_of_a_chain_carries_its_weight_like_point_masses() {
        // Above the group, every segment carries the weight below it whether the last three
        // vertices are rigid or free (a hanging chain is straight): the same positions.
        // Within the group the segments keep their rest length; free, they stretch by
        // m g k/EA.
        let (rigid, free) = (hanging_chain(true), hanging_chain(false));
        for i in 0..=4 {
            assert!(
                (rigid[i] - free[i]).norm() < 1e-10,
                "vertex {i}: {:?} vs {:?}",
                rigid[i],
                free[i]
            );
        }
        for i in 4..6 {
            let l = (rigid[i + 1] - rigid[i]).norm();
            assert!((l - 0.1).abs() < 1e-12, "rigid segment {i}: {l}");
        }
        let stretched = (free[6] - free[5]).norm();
        assert!(
            (stretched - (0.1 + 0.01 * 9.81 * 0.1 / 50.0)).abs() < 1e-10,
            "{stretched}"
        );
    }
}

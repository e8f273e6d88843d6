//! The rods' second-order correction: a rejected full Newton step has its segment lengths
//! restored to what the Newton model predicted, then is tested again (Nocedal & Wright,
//! Numerical Optimization, §15.6). The model is linear in each segment's length and the
//! length is not (a strand swinging by d lengthens a segment by ~d²/2L), so without it full
//! steps of swinging hair are rejected and halved (the Maratos effect).
//!
//! The restoration is a mass-weighted projection onto the lengths (Goldenthal et al. 2007,
//! "Efficient simulation of inextensible cloth", fast projection): with c(x) the segments'
//! length mismatches and C = ∂c/∂x, each iteration solves (C M⁻¹ Cᵀ) λ = c and moves
//! x ← x − M⁻¹ Cᵀ λ. Along a strand the segments (a, b), (b, c), … share one vertex with the
//! next, so C M⁻¹ Cᵀ is tridiagonal and one iteration costs a Thomas solve: Newton's method on
//! the constraints, converging quadratically where Gauss–Seidel sweeps (each segment in turn)
//! converged linearly and slowly on long strands. Where the segments are not chains (a vertex
//! shared by two segments that are not consecutive in the list, or a pivot that vanishes: a
//! free vertex between two held ones on a line), the Gauss–Seidel sweeps are kept.

use nalgebra::Vector3;

use super::NONE;

/// Projections (Newton iterations on the lengths) at most; two or three reach 1e-3 of the
/// first mismatch on strands.
const MAX_PROJECTIONS: usize = 16;
/// Gauss–Seidel sweeps at most, where the segments are not chains.
const MAX_SWEEPS: usize = 256;
/// Stop once the largest mismatch is below this fraction of the first.
const REDUCTION: f64 = 1e-3;

/// The rod segments the correction keeps at their predicted lengths, and its scratch (sized
/// once: no allocation per step).
#[derive(Default)]
pub(super) struct LengthCorrection {
    links: Vec<(u32, u32)>,
    /// Per segment: it shares its first vertex with the previous segment's second.
    chained: Vec<bool>,
    /// Every vertex two segments share is a `chained` pair: the tridiagonal system is all
    /// of C M⁻¹ Cᵀ.
    chains: bool,
    target: Vec<f64>,
    dir: Vec<Vector3<f64>>,
    miss: Vec<f64>,
    pivot: Vec<f64>,
    upper: Vec<f64>,
}

impl LengthCorrection {
    pub(super) fn new(links: Vec<(u32, u32)>, vertices: usize) -> Self {
        let m = links.len();
        let chained: Vec<bool> = (0..m)
            .map(|i| i > 0 && links[i - 1].1 == links[i].0)
            .collect();
        let mut uses = vec![0usize; vertices];
        for &(a, b) in &links {
            uses[a as usize] += 1;
            uses[b as usize] += 1;
        }
        let shared: usize = uses.iter().map(|&u| u.saturating_sub(1)).sum();
        let chains = shared == chained.iter().filter(|&&c| c).count();
        Self {
            links,
            chained,
            chains,
            target: vec![0.0; m],
            dir: vec![Vector3::zeros(); m],
            miss: vec![0.0; m],
            pivot: vec![0.0; m],
            upper: vec![0.0; m],
        }
    }

    pub(super) fn is_empty(&self) -> bool {
        self.links.is_empty()
    }

    /// Writes into `out` the positions `trial` (= x + the Newton step `dir`) moved so that
    /// every segment has the length the Newton model predicts, l + u·(d_b − d_a) (l and u
    /// its length and direction at x; at least a tenth of l). Held vertices (no free index)
    /// do not move. Returns the iterations (projections or sweeps).
    pub(super) fn apply(
        &mut self,
        free_of: &[u32],
        mass: &[f64],
        x: &[Vector3<f64>],
        dir: &[f64],
        trial: &[Vector3<f64>],
        out: &mut [Vector3<f64>],
    ) -> usize {
        out.copy_from_slice(trial);
        let step = |f: u32| {
            if f == NONE {
                Vector3::zeros()
            } else {
                let f = 3 * f as usize;
                Vector3::new(dir[f], dir[f + 1], dir[f + 2])
            }
        };
        for (t, &(a, b)) in self.target.iter_mut().zip(&self.links) {
            let (a, b) = (a as usize, b as usize);
            let e = x[b] - x[a];
            let l = e.norm();
            let moved = step(free_of[b]) - step(free_of[a]);
            // A step that shortens the segment by most of its length is no model to restore.
            *t = if l > 0.0 {
                (l + e.dot(&moved) / l).max(0.1 * l)
            } else {
                l
            };
        }
        let inverse = |v: usize| {
            if free_of[v] == NONE {
                0.0
            } else {
                1.0 / mass[v]
            }
        };
        if self.chains {
            if let Some(k) = self.project(&inverse, out) {
                return k;
            }
            // A vanishing pivot: start again from the trial with the sweeps.
            out.copy_from_slice(trial);
        }
        self.sweep(&inverse, out)
    }

    /// Newton's method on the lengths, one tridiagonal solve an iteration; None where a
    /// pivot vanishes (the lengths cannot all be met by moving the free vertices).
    fn project(
        &mut self,
        inverse: &dyn Fn(usize) -> f64,
        out: &mut [Vector3<f64>],
    ) -> Option<usize> {
        let mut first = None;
        for k in 1..=MAX_PROJECTIONS {
            let mut worst = 0.0f64;
            for (i, &(a, b)) in self.links.iter().enumerate() {
                let e = out[b as usize] - out[a as usize];
                let l = e.norm();
                self.dir[i] = if l > 0.0 { e / l } else { Vector3::zeros() };
                self.miss[i] = l - self.target[i];
                worst = worst.max(self.miss[i].abs());
            }
            let first = *first.get_or_insert(worst);
            if worst == 0.0 || (k > 1 && worst <= REDUCTION * first) {
                return Some(k - 1);
            }
            // Thomas's algorithm on C M⁻¹ Cᵀ: diagonal w_a + w_b, off-diagonal −w_b u_i·u_{i+1}
            // where segment i + 1 starts at segment i's end b; the right-hand side `miss`
            // becomes λ in place.
            for i in 0..self.links.len() {
                let (a, b) = (self.links[i].0 as usize, self.links[i].1 as usize);
                let mut diag = inverse(a) + inverse(b);
                if diag == 0.0 || self.dir[i] == Vector3::zeros() {
                    // Nothing can move this segment's length: no multiplier.
                    diag = 1.0;
                    self.miss[i] = 0.0;
                }
                // Zero where either segment cannot move (its weights or its direction vanish).
                self.upper[i] = if self.chained.get(i + 1).copied().unwrap_or(false) {
                    -inverse(b) * self.dir[i].dot(&self.dir[i + 1])
                } else {
                    0.0
                };
                if i > 0 && self.chained[i] {
                    let m = self.upper[i - 1] / self.pivot[i - 1];
                    diag -= m * self.upper[i - 1];
                    self.miss[i] -= m * self.miss[i - 1];
                }
                if diag <= 1e-9 * (inverse(a) + inverse(b)) {
                    return None;
                }
                self.pivot[i] = diag;
            }
            for i in (0..self.links.len()).rev() {
                let next = if self.chained.get(i + 1).copied().unwrap_or(false) {
                    self.upper[i] * self.miss[i + 1]
                } else {
                    0.0
                };
                self.miss[i] = (self.miss[i] - next) / self.pivot[i];
            }
            for (i, &(a, b)) in self.links.iter().enumerate() {
                let (a, b) = (a as usize, b as usize);
                let push = self.dir[i] * self.miss[i];
                out[a] += inverse(a) * push;
                out[b] -= inverse(b) * push;
            }
        }
        Some(MAX_PROJECTIONS)
    }

    /// Gauss–Seidel: each segment's mismatch removed along it in turn, split in inverse
    /// proportion to the masses.
    fn sweep(&self, inverse: &dyn Fn(usize) -> f64, out: &mut [Vector3<f64>]) -> usize {
        let mut first = None;
        for sweep in 1..=MAX_SWEEPS {
            let mut worst = 0.0f64;
            for (&(a, b), &target) in self.links.iter().zip(&self.target) {
                let (a, b) = (a as usize, b as usize);
                let (wa, wb) = (inverse(a), inverse(b));
                let e = out[b] - out[a];
                let l = e.norm();
                if wa + wb == 0.0 || l == 0.0 {
                    continue;
                }
                let miss = l - target;
                worst = worst.max(miss.abs());
                let push = e * (miss / (l * (wa + wb)));
                out[a] += wa * push;
                out[b] -= wb * push;
            }
            let first = *first.get_or_insert(worst);
            if worst <= REDUCTION * first {
                return sweep;
            }
        }
        MAX_SWEEPS
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A strand of `n` segments along x, 1 cm each, its first vertex held (no free index),
    /// and a step that swings it: every vertex moved sideways in proportion to its distance
    /// from the root (a rotation's linearization, which lengthens every segment).
    fn swung(n: usize) -> (Vec<Vector3<f64>>, Vec<u32>, Vec<f64>, Vec<f64>) {
        let x: Vec<_> = (0..=n)
            .map(|i| Vector3::new(0.01 * i as f64, 0.0, 0.0))
            .collect();
        let free_of: Vec<u32> = (0..=n)
            .map(|i| if i == 0 { NONE } else { i as u32 - 1 })
            .collect();
        let mass: Vec<f64> = (0..=n)
            .map(|i| 1e-4 * (1.0 + 0.3 * (i % 3) as f64))
            .collect();
        let mut dir = vec![0.0; 3 * n];
        for i in 1..=n {
            dir[3 * (i - 1) + 1] = 0.3 * x[i].x;
        }
        (x, free_of, mass, dir)
    }

    fn trial_of(x: &[Vector3<f64>], free_of: &[u32], dir: &[f64]) -> Vec<Vector3<f64>> {
        x.iter()
            .zip(free_of)
            .map(|(p, &f)| {
                if f == NONE {
                    *p
                } else {
                    let f = 3 * f as usize;
                    p + Vector3::new(dir[f], dir[f + 1], dir[f + 2])
                }
            })
            .collect()
    }

    /// On a strand (a chain of segments) the tridiagonal projection meets every predicted
    /// length to 1e-3 of the step's mismatch in a few iterations, where the Gauss–Seidel
    /// sweeps it replaced took hundreds on long strands; the held root does not move.
    #[test]
    fn a_strand_gets_its_lengths_back_in_a_few_projections() {
        let n = 31;
        let (x, free_of, mass, dir) = swung(n);
        let links: Vec<(u32, u32)> = (0..n as u32).map(|i| (i, i + 1)).collect();
        let trial = trial_of(&x, &free_of, &dir);
        let mut c = LengthCorrection::new(links.clone(), n + 1);
        assert!(c.chains);
        let mut out = vec![Vector3::zeros(); n + 1];
        let k = c.apply(&free_of, &mass, &x, &dir, &trial, &mut out);
        // The model predicts the rest length (the step is perpendicular to every segment).
        let first = (trial[n] - trial[n - 1]).norm() - 0.01;
        let worst = links
            .iter()
            .map(|&(a, b)| ((out[b as usize] - out[a as usize]).norm() - 0.01).abs())
            .fold(0.0f64, f64::max);
        assert!(k <= 4, "{k} projections");
        // Quadratic convergence: far below the stopping fraction once it stops.
        assert!(
            worst <= 1e-3 * first,
            "mismatch {worst:e} against {first:e}"
        );
        assert_eq!(out[0], x[0]);
        // The Gauss–Seidel sweeps on the same strand, for the record of what was replaced.
        let mut gs = LengthCorrection::new(links, n + 1);
        gs.chains = false;
        let sweeps = gs.apply(&free_of, &mass, &x, &dir, &trial, &mut out);
        assert!(
            sweeps > 10 * k.max(1),
            "{sweeps} sweeps against {k} projections"
        );
    }

    /// Segments that do not form chains (a vertex shared by non-consecutive segments: a
    /// star) keep the Gauss–Seidel sweeps, and held vertices stay where they are.
    #[test]
    fn a_star_falls_back_to_sweeps_and_held_vertices_stay() {
        let x = vec![
            Vector3::zeros(),
            Vector3::new(0.01, 0.0, 0.0),
            Vector3::new(0.0, 0.01, 0.0),
            Vector3::new(0.0, 0.0, 0.01),
        ];
        let free_of = vec![0, 1, 2, NONE];
        let mass = vec![1e-4; 4];
        let links = vec![(0, 1), (0, 2), (0, 3)];
        let mut c = LengthCorrection::new(links.clone(), 4);
        assert!(!c.chains);
        let dir = vec![0.0, 0.0, 0.0, 0.0, 0.004, 0.0, 0.0, 0.0, 0.004];
        let trial = trial_of(&x, &free_of, &dir);
        let mut out = vec![Vector3::zeros(); 4];
        c.apply(&free_of, &mass, &x, &dir, &trial, &mut out);
        assert_eq!(out[3], x[3]);
        for &(a, b) in &links {
            let l = (out[b as usize] - out[a as usize]).norm();
            assert!((l - 0.01).abs() < 1e-3 * 0.004, "segment ({a}, {b}): {l}");
        }
    }
}

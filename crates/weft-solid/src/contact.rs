//! The per-contact Signorini–Coulomb solve of the contact step (after Daviet 2020; the ADMM
//! in `integrator/contacts.rs` calls it once per contact and iteration).
//!
//! A contact has a local frame (n, t₁, t₂), n out of the collider. Its relative velocity u and
//! the impulse r the collider gives (both in that frame: normal component first) obey
//! Coulomb's law with friction μ: r ∈ K_μ = {|r_T| ≤ μ r_N}, and either r = 0 with u_N ≥ 0
//! (take off), or u = 0 with r ∈ K_μ (stick), or u_N = 0 and r_T = −μ r_N u_T/|u_T| (slide).
//! With De Saxcé's modified velocity ũ = u + μ|u_T| n this is the cone complementarity
//! K_μ ∋ r ⊥ ũ ∈ K_μ* (the dual cone {μ|ũ_T| ≤ ũ_N}).
//!
//! The ADMM's contact step asks, per contact, for the (u, r) that obeys the law with
//! u = w + r/ρ (w the velocity the primal step left, shifted by the scaled dual, ρ the
//! contact's weight). By cases, in closed form:
//! - take off when w_N ≥ 0: r = 0, u = w;
//! - stick when −w ∈ K_μ (|w_T| ≤ −μ w_N): u = 0, r = −ρ w (exact: no creep);
//! - otherwise slide: r_N = −ρ w_N, r_T = −μ r_N w_T/|w_T|, u = (0, w_T (1 − μ r_N/(ρ|w_T|))).
//!
//! Cohesion c [N·s, an impulse] lets the collider pull: r + c n ∈ K_μ, which is the same
//! problem for w − (c/ρ) n, the cone's apex moved to −c. A gap g [m] between a vertex and its
//! collider (its thickness subtracted) lets the step close it: u_N ≥ −g/h, the same problem
//! for w + (g/h) n; a penetration (g < 0) is resolved at the fraction of it the caller passes
//! in g (the Collision Response's strength).

/// Which case of Coulomb's law a contact is in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Regime {
    /// Separating: no impulse.
    TakeOff,
    /// No relative motion; the impulse is inside the friction cone.
    Stick,
    /// Sliding on the cone's boundary, opposite the tangential velocity.
    Slide,
}

/// The (u, r) of one contact that obeys Coulomb's law with friction `mu` (≥ 0), apex shift
/// `cohesion` (an impulse, ≥ 0) and u = w + r/ρ, `rho` > 0; vectors in the contact frame
/// (normal first). Returns (u, r, regime).
pub fn solve_local(w: [f64; 3], mu: f64, cohesion: f64, rho: f64) -> ([f64; 3], [f64; 3], Regime) {
    // Cohesion: r' = r + c n obeys the law without it, for w' = w − (c/ρ) n.
    let wn = w[0] - cohesion / rho;
    let wt = [w[1], w[2]];
    let wt_norm = wt[0].hypot(wt[1]);
    let (u, rp, regime) = if wn >= 0.0 {
        ([wn, wt[0], wt[1]], [0.0; 3], Regime::TakeOff)
    } else if wt_norm <= -mu * wn {
        (
            [0.0; 3],
            [-rho * wn, -rho * wt[0], -rho * wt[1]],
            Regime::Stick,
        )
    } else {
        let rn = -rho * wn;
        let scale = 1.0 - mu * rn / (rho * wt_norm);
        let d = [wt[0] / wt_norm, wt[1] / wt_norm];
        (
            [0.0, wt[0] * scale, wt[1] * scale],
            [rn, -mu * rn * d[0], -mu * rn * d[1]],
            Regime::Slide,
        )
    };
    // Back from the shifted problem: u is w + r/ρ with the true w and r = r' − c n.
    let r = [rp[0] - cohesion, rp[1], rp[2]];
    let u = [u[0], u[1], u[2]];
    (u, r, regime)
}

/// How far (u, r) is from Coulomb's law with friction `mu` and cohesion `cohesion`: the
/// largest of r's distance outside the shifted cone, ũ's outside the dual cone, and |r'·ũ|
/// (r' = r + c n), each made a velocity or impulse by nothing: callers compare it with their
/// own scale.
pub fn residual(u: [f64; 3], r: [f64; 3], mu: f64, cohesion: f64) -> f64 {
    let rp = [r[0] + cohesion, r[1], r[2]];
    let ut = u[1].hypot(u[2]);
    let ul = [u[0] + mu * ut, u[1], u[2]];
    let rt = rp[1].hypot(rp[2]);
    let outside_k = (rt - mu * rp[0]).max(-rp[0]).max(0.0);
    let outside_dual = (mu * ul[1].hypot(ul[2]) - ul[0]).max(0.0);
    let comp = (rp[0] * ul[0] + rp[1] * ul[1] + rp[2] * ul[2]).abs();
    outside_k.max(outside_dual).max(comp)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    /// Every case obeys the law to rounding, u = w + r/ρ holds, and the regimes are where
    /// the closed form puts them; over 10⁴ random (w, μ, c, ρ).
    #[test]
    fn the_local_solve_obeys_coulomb_and_the_step_relation() {
        let mut seed = 7u64;
        let mut seen = [0usize; 3];
        for _ in 0..10_000 {
            let w = [lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)];
            let mu = 1.0 + lcg(&mut seed); // 0..2
            let c = if lcg(&mut seed) > 0.0 {
                0.0
            } else {
                0.3 * (1.0 + lcg(&mut seed))
            };
            let rho = 10f64.powf(2.0 * lcg(&mut seed));
            let (u, r, regime) = solve_local(w, mu, c, rho);
            let scale = 1.0 + rho * (w[0].abs() + w[1].abs() + w[2].abs()) + c;
            assert!(
                residual(u, r, mu, c) <= 1e-12 * scale,
                "{w:?} {mu} {c} {rho}: {u:?} {r:?}"
            );
            for k in 0..3 {
                assert!(
                    (u[k] - (w[k] + r[k] / rho)).abs() <= 1e-12 * scale,
                    "{k}: {u:?} {r:?}"
                );
            }
            seen[regime as usize] += 1;
        }
        assert!(seen.iter().all(|&n| n > 500), "{seen:?}");
    }

    /// The three cases on simple numbers: a block pushed down and sideways on a floor.
    #[test]
    fn take_off_stick_and_slide() {
        // Moving away: nothing.
        assert_eq!(
            solve_local([0.2, 1.0, 0.0], 0.5, 0.0, 2.0).2,
            Regime::TakeOff
        );
        // Into the floor, tangential speed within μ × normal: held exactly.
        let (u, r, g) = solve_local([-1.0, 0.4, 0.0], 0.5, 0.0, 2.0);
        assert_eq!((u, g), ([0.0; 3], Regime::Stick));
        assert_eq!(r, [2.0, -0.8, 0.0]);
        // Beyond it: slides, the impulse on the cone against the motion.
        let (u, r, g) = solve_local([-1.0, 0.0, 0.8], 0.5, 0.0, 2.0);
        assert_eq!(g, Regime::Slide);
        assert_eq!(r, [2.0, 0.0, -1.0]);
        assert!((u[2] - 0.3).abs() < 1e-15 && u[0] == 0.0);
        // Cohesion: a small pull away is held (the collider pulls back up to c).
        let (u, r, g) = solve_local([0.1, 0.0, 0.0], 0.5, 0.5, 2.0);
        assert_eq!((u, g), ([0.0; 3], Regime::Stick));
        assert!((r[0] + 0.2).abs() < 1e-15);
        // A larger one tears off, the collider pulling with all of c.
        let (u, r, g) = solve_local([1.0, 0.0, 0.0], 0.5, 0.5, 2.0);
        assert_eq!(g, Regime::TakeOff);
        assert!((r[0] + 0.5).abs() < 1e-15 && (u[0] - 0.75).abs() < 1e-15);
    }
}

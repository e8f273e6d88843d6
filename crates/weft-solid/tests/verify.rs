//! Verification of the solver against cases with known answers (shared/VERIFY.md, Solids).
//! Each test states its reference and why its tolerance is right.

use nalgebra::Vector3;
use std::f64::consts::PI;
use weft_solid::energy::{MembraneMaterial, RodStretch};
use weft_solid::verify::{self, G, at_rest, rod};
use weft_solid::{Integrator, Method, Settings, SolidSystem, State, StepError};

/// A 1 kg point mass on a stiff (k = 1e7 N/m) rod of length `len` from a pinned pivot,
/// released `th0` from the vertical.
fn pendulum(len: f64, th0: f64) -> (SolidSystem, State) {
    let x = vec![
        Vector3::zeros(),
        Vector3::new(len * th0.sin(), -len * th0.cos(), 0.0),
    ];
    let mut sys = SolidSystem::new(vec![1.0, 1.0]);
    sys.pinned[0] = true;
    sys.gravity = Vector3::new(0.0, -G, 0.0);
    sys.elements.stretches.push(RodStretch {
        v: [0, 1],
        rest_length: len,
        k: 1e7,
    });
    (sys, at_rest(x))
}

#[test]
fn pendulum_period_matches_the_large_amplitude_series() {
    // A point mass on a stiff massless-ish rod (one segment), pivot pinned.
    let (len, th0) = (1.0, 0.3f64);
    let (sys, mut s) = pendulum(len, th0);
    let mut integ = Integrator::new(&sys).unwrap();
    let h = 5e-4;
    let settings = Settings {
        tolerance: 1e-9,
        ..Settings::default()
    };
    let (mut t, mut crossings) = (0.0, Vec::new());
    let mut prev = s.x[1].x;
    while crossings.len() < 5 {
        integ.step(&sys, &mut s, None, h, &settings).unwrap();
        t += h;
        let cur = s.x[1].x;
        if prev > 0.0 && cur <= 0.0 || prev < 0.0 && cur >= 0.0 {
            crossings.push(t - h * cur / (cur - prev)); // linear interpolation of the crossing
        }
        prev = cur;
    }
    let period = (crossings[4] - crossings[0]) / 2.0;
    let t0 = 2.0 * PI * (len / G).sqrt();
    let series = t0 * (1.0 + th0 * th0 / 16.0 + 11.0 * th0.powi(4) / 3072.0);
    // Implicit Euler's phase error is O((ωh)²) ≈ 1e-6 here; the crossing interpolation and the
    // amplitude lost to numerical damping over two periods (~1 %, which shifts the θ₀²/16
    // correction by ~1e-4 of itself) are far below 2e-4. The correction itself is 5.6e-3.
    let rel = (period - series).abs() / series;
    eprintln!("pendulum period {period} vs series {series} (rel {rel:e})");
    assert!(
        rel < 2e-4,
        "period {period} vs series {series} (rel {rel:e}); small-angle T₀ = {t0}"
    );
    assert!(
        (period - t0) / t0 > 5e-3,
        "the amplitude correction is resolved"
    );
}

#[test]
fn newton_is_stable_where_explicit_blows_up() {
    // A hanging chain of stiff springs: ω_max ≈ 2√(k/m) = 2000 rad/s, so symplectic Euler is
    // stable only for h < 2/ω_max = 1e-3 s. At h = 1e-2 it must blow up; implicit Euler must
    // not, and (being dissipative) must not gain energy.
    let (mut sys, s0) = rod(10, 1.0, Vector3::zeros(), 0.1, 1e4 * 0.1, 0.0);
    sys.pinned[0] = true;
    let energy = |s: &State| -> f64 {
        let mut e: f64 = (0..s.x.len())
            .map(|i| 0.5 * sys.mass[i] * s.v[i].norm_squared() + sys.mass[i] * G * s.x[i].y)
            .sum();
        for st in &sys.elements.stretches {
            let l = (s.x[st.v[1] as usize] - s.x[st.v[0] as usize]).norm();
            e += 0.5 * st.k * st.rest_length * (l / st.rest_length - 1.0).powi(2);
        }
        e
    };
    let h = 1e-2;
    let mut explicit = s0.clone();
    let mut integ = Integrator::new(&sys).unwrap();
    let settings = |method| Settings {
        method,
        ..Settings::default()
    };
    let mut blew_up = false;
    for _ in 0..200 {
        match integ.step(&sys, &mut explicit, None, h, &settings(Method::Explicit)) {
            Err(StepError::NonFinite { .. }) => {
                blew_up = true;
                break;
            }
            Ok(_) if energy(&explicit).abs() > 1e6 => {
                blew_up = true;
                break;
            }
            Ok(_) => {}
            Err(e) => panic!("{e}"),
        }
    }
    assert!(blew_up, "explicit should be unstable at h = 10× its limit");
    let mut implicit = s0.clone();
    let e0 = energy(&implicit);
    for _ in 0..200 {
        integ
            .step(&sys, &mut implicit, None, h, &settings(Method::Newton))
            .unwrap();
        assert!(
            energy(&implicit) <= e0 + 1e-9,
            "implicit Euler gained energy"
        );
    }
    // And explicit is fine below its limit.
    let mut small = s0.clone();
    for _ in 0..200 {
        integ
            .step(&sys, &mut small, None, 5e-4, &settings(Method::Explicit))
            .unwrap();
    }
    assert!(energy(&small).abs() < 10.0);
}

#[test]
fn catenary_sag_matches_the_analytic_curve() {
    // Ends at x = ±0.5 m, length 1.2 m, near-inextensible (EA = 1e3 N: strain ~1e-4), no
    // bending, 60 segments.
    let (mid, sag) = verify::catenary_sag(60, 1e3).unwrap();
    eprintln!(
        "catenary sag {mid} vs {sag} (rel {:e})",
        (mid - sag).abs() / sag
    );
    // 60 straight segments approximate the curve to O(1/n²) ≈ 3e-4 of the sag; the stretch
    // (tension/EA ≈ 1e-4) lengthens the chain slightly and deepens the sag by a similar amount.
    assert!(
        (mid - sag).abs() / sag < 2e-3,
        "sag {mid} vs catenary {sag}"
    );
}

/// [`verify::uniaxial`] on an 11 × 11 vertex sheet, or a panic saying why not.
fn uniaxial(mat: MembraneMaterial, warp: Vector3<f64>, tension: f64) -> (f64, f64) {
    verify::uniaxial(11, mat, warp, tension).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn uniaxial_membrane_tension_gives_the_strain_and_poisson_contraction() {
    let (e, nu, t) = (1e6, 0.3, 1e-3);
    let tension = 5.0; // N/m → ε = N/(E t) = 5e-3
    let (ex, ey) = uniaxial(
        MembraneMaterial::orthotropic(e, nu, t, 1.0, 1.0, 1.0),
        Vector3::x(),
        tension,
    );
    let want = tension / (e * t);
    eprintln!("uniaxial: ε_x {ex} vs {want}; ν measured {}", -ey / ex);
    // Green-strain StVK differs from the linear law by O(ε) = 0.5 %: allow 1 %.
    assert!(
        (ex - want).abs() / want < 1e-2,
        "ε_x = {ex}, linear theory {want}"
    );
    assert!(
        (-ey / ex - nu).abs() / nu < 2e-2,
        "ν measured {} vs {nu}",
        -ey / ex
    );
}

#[test]
fn anisotropic_cloth_has_the_set_warp_and_weft_stiffness() {
    // Warp along x three times stiffer than the weft: pulling along x strains 3× less than
    // the same pull rotated to y (the warp direction turned to y gives the weft response).
    let mat = MembraneMaterial::orthotropic(1e6, 0.0, 1e-3, 3.0, 1.0, 1.0);
    let (ex_warp, _) = uniaxial(mat, Vector3::x(), 5.0);
    let (ex_weft, _) = uniaxial(mat, Vector3::y(), 5.0);
    let want_warp = 5.0 / (3.0 * 1e6 * 1e-3);
    let want_weft = 5.0 / (1e6 * 1e-3);
    assert!(
        (ex_warp - want_warp).abs() / want_warp < 1e-2,
        "warp strain {ex_warp} vs {want_warp}"
    );
    assert!(
        (ex_weft - want_weft).abs() / want_weft < 1e-2,
        "weft strain {ex_weft} vs {want_weft}"
    );
}

#[test]
fn a_failed_step_leaves_the_state_unchanged_and_says_why() {
    let (sys, s0) = rod(4, 1.0, Vector3::zeros(), 0.1, 1e3, 0.0);
    let mut integ = Integrator::new(&sys).unwrap();
    let mut s = s0.clone();
    let tight = Settings {
        tolerance: 0.0,
        max_iterations: 3,
        ..Settings::default()
    };
    let e = integ.step(&sys, &mut s, None, 1e-2, &tight).unwrap_err();
    assert!(
        matches!(e, StepError::NotConverged { iterations: 3, .. }),
        "{e}"
    );
    assert_eq!(s, s0);
    let mut bad = s0.clone();
    bad.x[2].y = f64::NAN;
    let e = integ
        .step(&sys, &mut bad, None, 1e-2, &Settings::default())
        .unwrap_err();
    assert_eq!(e.to_string(), "vertex 2 has a non-finite position");
}

/// Settling fibre (VERIFY.md, Drag and coupling), the solid side: a slender rigid-ish fibre in
/// still fluid with the slender-body drag γ⊥ = 4πμL/(ln(L/d) + 0.84) and
/// γ∥ = 2πμL/(ln(L/d) − 0.20), lumped per vertex as D = (l_v/L)[γ⊥(I − eeᵀ) + γ∥ eeᵀ], falls at
/// W/γ⊥ when horizontal and W/γ∥ when vertical (W its net weight). Implicit Euler's steady
/// state is exact (v = v + h(g − Dv/m) ⇒ v = mg/D), so after 20 time constants the speeds
/// match to 1e-6 (measured: 2e-8) and their ratio γ⊥/γ∥ (1.73 here) with them.
#[test]
fn a_settling_fibre_falls_at_its_slender_body_speeds() {
    use weft_solid::VertexDrag;
    let (len, d, mu, n) = (0.01, 1e-5, 1.002e-3, 8usize);
    let (rho_s, rho_f) = (1300.0, 998.2);
    let area = PI * d * d / 4.0;
    let ln = (len / d).ln();
    let g_perp = 4.0 * PI * mu * len / (ln + 0.84);
    let g_par = 2.0 * PI * mu * len / (ln - 0.20);
    let weight = (rho_s - rho_f) * G * area * len;
    let mut speeds = Vec::new();
    for vertical in [false, true] {
        let (mut sys, mut state) = rod(n, len, Vector3::zeros(), rho_s * area, 1e3, 1e-9);
        // Net weight (buoyancy included) as the gravity on the solid's mass.
        sys.gravity = Vector3::new(0.0, -G * (rho_s - rho_f) / rho_s, 0.0);
        let e = if vertical {
            Vector3::new(0.0, 1.0, 0.0)
        } else {
            Vector3::new(1.0, 0.0, 0.0)
        };
        if vertical {
            for (i, p) in state.x.iter_mut().enumerate() {
                *p = Vector3::new(0.0, i as f64 * len / n as f64, 0.0);
            }
        }
        let lv = |i: usize| if i == 0 || i == n { 0.5 } else { 1.0 } * len / n as f64;
        let ee = e * e.transpose();
        sys.drag = (0..=n)
            .map(|i| VertexDrag {
                matrix: lv(i) / len * (g_perp * (nalgebra::Matrix3::identity() - ee) + g_par * ee),
                flow: Vector3::zeros(),
            })
            .collect();
        let m_total = rho_s * area * len;
        let tau = m_total / g_par.min(g_perp);
        let h = tau / 4.0;
        let mut integ = Integrator::new(&sys).unwrap();
        let settings = Settings {
            method: Method::Newton,
            tolerance: 1e-12,
            max_iterations: 50,
        };
        for _ in 0..80 {
            integ.step(&sys, &mut state, None, h, &settings).unwrap();
        }
        let vy: f64 = state.v.iter().map(|v| v.y).sum::<f64>() / (n + 1) as f64;
        speeds.push(-vy);
    }
    let (want_h, want_v) = (weight / g_perp, weight / g_par);
    eprintln!(
        "settling fibre: horizontal {:e} m/s (theory {want_h:e}), vertical {:e} (theory {want_v:e}), ratio {}",
        speeds[0],
        speeds[1],
        speeds[1] / speeds[0]
    );
    assert!((speeds[0] / want_h - 1.0).abs() < 1e-6, "{speeds:?}");
    assert!((speeds[1] / want_v - 1.0).abs() < 1e-6, "{speeds:?}");
    assert!(((speeds[1] / speeds[0]) / (g_perp / g_par) - 1.0).abs() < 1e-6);
}

/// A loose Newton tolerance still takes the step: a body at rest whose velocity change in a
/// step (g·h = 0.098 m/s) is below the tolerance (0.1 m/s) falls at −g·h after it, exactly
/// (free fall is linear: one Newton step is the implicit Euler answer to rounding). With the
/// converged test before the correction, the body would never move.
#[test]
fn a_tolerance_looser_than_the_step_still_moves_the_body() {
    let mut sys = SolidSystem::new(vec![1.0]);
    sys.gravity = Vector3::new(0.0, -G, 0.0);
    let mut state = at_rest(vec![Vector3::zeros()]);
    let mut integ = Integrator::new(&sys).unwrap();
    let settings = Settings {
        method: Method::Newton,
        tolerance: 0.1,
        max_iterations: 10,
    };
    let h = 0.01;
    let stats = integ.step(&sys, &mut state, None, h, &settings).unwrap();
    assert_eq!(stats.iterations, 1);
    assert!((state.v[0].y + G * h).abs() < 1e-12, "{}", state.v[0].y);
    assert!((state.x[0].y + G * h * h).abs() < 1e-12, "{}", state.x[0].y);
}

/// Warm start: a Newton step started from a good guess (here the answer of the same step
/// started cold) reaches the same positions to the tolerance in fewer iterations (one: the
/// guess is already converged), and a guess of the wrong length is ignored.
#[test]
fn a_warm_started_step_reaches_the_same_answer_in_fewer_iterations() {
    let (mut sys, s0) = rod(10, 1.0, Vector3::zeros(), 0.1, 1e4, 1e-3);
    sys.pinned[0] = true;
    let settings = Settings {
        method: Method::Newton,
        tolerance: 1e-9,
        max_iterations: 50,
    };
    let mut integ = Integrator::new(&sys).unwrap();
    let mut cold = s0.clone();
    let c = integ.step(&sys, &mut cold, None, 0.02, &settings).unwrap();
    let mut warm = s0.clone();
    let w = integ
        .step_from(&sys, &mut warm, Some(&cold.x), None, 0.02, &settings)
        .unwrap();
    let dx = cold
        .x
        .iter()
        .zip(&warm.x)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).amax()));
    assert!(c.iterations > 2 && w.iterations == 1, "{c:?} {w:?}");
    // The velocity tolerance 1e-9 m/s times h bounds the position difference.
    assert!(dx < 1e-9 * 0.02 * 10.0, "{dx}");
    let mut ignored = s0.clone();
    let i = integ
        .step_from(
            &sys,
            &mut ignored,
            Some(&cold.x[..3]),
            None,
            0.02,
            &settings,
        )
        .unwrap();
    assert_eq!(i.iterations, c.iterations);
    assert_eq!(ignored.x, cold.x);
}

/// The second-order correction: a stiff 10-segment strand (hair-like: E A = 24 N, 1e-4 kg/m,
/// held at one end) released horizontally swings under gravity for 24 steps of 1/24 s. Full
/// Newton steps lengthen its segments by ~d²/2L more than the Newton model predicts and were
/// halved by the line search: measured without the correction, 469 Newton iterations (19.5 a
/// step); with it, 117 (33 full steps corrected and accepted). Reference: the same steps solved
/// to a 1e-3 tighter tolerance; each step's positions agree to the tolerance times h (1e-4 m/s
/// × 1/24 s), so over 24 steps the tip stays within 24 × 4.2e-6 m of it (measured 2.2e-7 m).
#[test]
fn stiff_strands_swing_in_few_newton_iterations_to_the_same_answer() {
    let (mut sys, s0) = rod(10, 0.25, Vector3::zeros(), 1e-4, 24.0, 1e-9);
    sys.pinned[0] = true;
    let h = 1.0 / 24.0;
    let run = |tolerance: f64| {
        let settings = Settings {
            method: Method::Newton,
            tolerance,
            max_iterations: 200,
        };
        let mut integ = Integrator::new(&sys).unwrap();
        let mut state = s0.clone();
        let (mut iterations, mut corrections) = (0, 0);
        for _ in 0..24 {
            let s = integ.step(&sys, &mut state, None, h, &settings).unwrap();
            iterations += s.iterations;
            corrections += s.corrections;
        }
        (state.x[10], iterations, corrections)
    };
    let (tip, iterations, corrections) = run(1e-4);
    let (reference, _, _) = run(1e-7);
    assert!(corrections > 0, "no full step was corrected");
    assert!(
        (tip - reference).amax() < 24.0 * 1e-4 * h,
        "tip {tip:?} against {reference:?}"
    );
    // At most 6 a step on average (measured 4.9; 19.5 without the correction).
    assert!(
        iterations <= 6 * 24,
        "{iterations} Newton iterations in 24 steps"
    );
}

/// BDF2 against implicit Euler on the large-amplitude pendulum (θ₀ = 0.3): the angle after
/// 1 s against the pendulum equation θ″ = −(g/L) sin θ integrated by RK4 at 1e-5 s (its
/// error ~1e-18, far below both). Halving the step must divide BDF2's error by ~4 (second
/// order) and implicit Euler's by ~2 (first order), and BDF2 at h = 1/100 s must already be
/// far more accurate (implicit Euler's numerical damping is what it removes). The rod
/// (k = 1e7 N/m for 1 kg) stretches ~1e-6 m under the swing: below 1e-6 rad, well under the
/// errors compared (≥ 1e-4 rad).
#[test]
fn bdf2_is_second_order_where_implicit_euler_is_first() {
    let (len, th0) = (1.0, 0.3f64);
    let make = || pendulum(len, th0);
    let reference = verify::pendulum_angle(th0, len, 1.0);
    let run = |steps: usize, bdf2: bool| -> f64 {
        let (sys, mut s) = make();
        let mut integ = Integrator::new(&sys).unwrap();
        let settings = Settings {
            tolerance: 1e-10,
            ..Settings::default()
        };
        let h = 1.0 / steps as f64;
        let mut prev: Option<State> = None;
        for _ in 0..steps {
            let before = s.clone();
            match (&prev, bdf2) {
                // The first step has no history: implicit Euler (its O(h²) local error keeps
                // BDF2's global error second order).
                (Some(p), true) => integ.step_bdf2(&sys, &mut s, p, None, h, &settings),
                _ => integ.step(&sys, &mut s, None, h, &settings),
            }
            .unwrap();
            prev = Some(before);
        }
        (s.x[1].x.atan2(-s.x[1].y) - reference).abs()
    };
    let (euler, euler2) = (run(100, false), run(200, false));
    let (bdf2, bdf2_2) = (run(100, true), run(200, true));
    eprintln!("implicit Euler {euler:e} → {euler2:e}; BDF2 {bdf2:e} → {bdf2_2:e}");
    assert!(
        (1.6..2.4).contains(&(euler / euler2)),
        "implicit Euler's order: ratio {}",
        euler / euler2
    );
    assert!(
        (3.2..4.8).contains(&(bdf2 / bdf2_2)),
        "BDF2's order: ratio {}",
        bdf2 / bdf2_2
    );
    assert!(
        bdf2 < euler / 10.0,
        "BDF2 {bdf2:e} against implicit Euler {euler:e}"
    );
}

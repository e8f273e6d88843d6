//! Anisotropic drag and lift between fluid and fibres or cloth (the seed's eqs. 1–4, after
//! Fei et al. 2018).
//!
//! Drag coefficients per direction l ∈ {⊥, ∥} (eq. 1, the Ergun form):
//! `C_l = 1/k_l + ξ_N · 1.75/√(150 k_l) · (1 − γ)^(−3/2) · (ρ D |Δv| / μ)^c`,
//! with the user's scales standing for the permeabilities (eq. 2): `1/k_l = ξ_D/10⁴ · ξ_l`.
//! Force on the solid (eq. 3): `f = −(μV/D²) R C Rᵀ Δv`, Δv = v_solid − u_fluid, with
//! C = diag(C⊥, C⊥, C∥) in a rod's frame (∥ along the tangent) and diag(C⊥, C∥, C∥) in a
//! face's (⊥ along the normal). Lift (eq. 4): `f_L = −ξ_L (Q − (Q·Δv/|Δv|²) Δv)`,
//! `Q = e × (e × f_drag)`, e the rod's tangent (for faces we take the normal, the direction
//! the seed's e∥ plays for rods: lift then turns the part of the drag across the face).
//! Every function also returns the derivative the implicit solid solve needs.

use weft_scene::Drag;

/// Fluid material: density and dynamic viscosity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FluidProperties {
    /// Density ρ [kg/m³].
    pub density: f64,
    /// Dynamic viscosity μ [Pa·s].
    pub viscosity: f64,
}

impl FluidProperties {
    /// Fresh water at 20 °C.
    pub const WATER: FluidProperties = FluidProperties {
        density: 998.2,
        viscosity: 1.002e-3,
    };
    /// Dry air at 20 °C, sea level.
    pub const AIR: FluidProperties = FluidProperties {
        density: 1.204,
        viscosity: 1.81e-5,
    };
}

/// The drag law of eqs. 1–2 on the Drag SEC's parameters (`weft_scene::Drag`, declared
/// once there with its defaults and ranges; `SecFields::check` validates it).
pub trait DragLaw {
    /// 1/k_l (eq. 2) for ξ_l.
    fn inverse_permeability(&self, xi_l: f64) -> f64;
    /// C_l and dC_l/d|Δv| (eq. 1) for inverse permeability `kinv` at speed `speed`.
    fn coefficient(&self, fluid: &FluidProperties, kinv: f64, speed: f64) -> (f64, f64);
}

impl DragLaw for Drag {
    fn inverse_permeability(&self, xi_l: f64) -> f64 {
        self.xi_d / 1e4 * xi_l
    }

    fn coefficient(&self, fluid: &FluidProperties, kinv: f64, speed: f64) -> (f64, f64) {
        if kinv <= 0.0 {
            return (0.0, 0.0);
        }
        let lin = kinv;
        if self.xi_n == 0.0 || speed == 0.0 {
            // The nonlinear term vanishes at zero speed for c > 0 (and its slope too for
            // c > 1; for c = 1 the one-sided slope is the constant below).
            let slope = if self.xi_n > 0.0 && self.degree == 1.0 {
                nonlinear_prefactor(self, kinv) * fluid.density * self.diameter / fluid.viscosity
            } else {
                0.0
            };
            let at_zero = if self.xi_n > 0.0 && self.degree == 0.0 {
                nonlinear_prefactor(self, kinv)
            } else {
                0.0
            };
            return (lin + at_zero, slope);
        }
        let re = fluid.density * self.diameter * speed / fluid.viscosity;
        let pre = nonlinear_prefactor(self, kinv);
        let c = self.degree;
        let nl = pre * re.powf(c);
        // d(re^c)/d|Δv| = c re^(c−1) · ρD/μ.
        let dnl = pre * c * re.powf(c - 1.0) * fluid.density * self.diameter / fluid.viscosity;
        (lin + nl, dnl)
    }
}

fn nonlinear_prefactor(p: &Drag, kinv: f64) -> f64 {
    // ξ_N · 1.75/√(150 k) · (1 − γ)^(−3/2), with k = 1/kinv.
    p.xi_n * 1.75 * (kinv / 150.0).sqrt() * (1.0 - p.gamma).powf(-1.5)
}

/// The solid's shape for drag: a rod segment (unit tangent) or a cloth face (unit normal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// Rod with unit tangent e (∥ direction).
    Rod([f64; 3]),
    /// Face with unit normal n (⊥ direction).
    Face([f64; 3]),
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Drag on a solid of volume `volume` [m³] moving at `dv` = v_solid − u_fluid [m/s]
/// relative to the fluid (eq. 3): the force [N] and its derivative ∂f/∂(Δv) [N·s/m]
/// (row-major 3×3; symmetric negative semidefinite in the linear branch).
pub fn drag_force(
    params: &Drag,
    fluid: &FluidProperties,
    shape: Shape,
    volume: f64,
    dv: [f64; 3],
) -> ([f64; 3], [[f64; 3]; 3]) {
    let speed = dot(dv, dv).sqrt();
    let (kp, kq) = (
        params.inverse_permeability(params.xi_perp),
        params.inverse_permeability(params.xi_par),
    );
    let (cp, dcp) = params.coefficient(fluid, kp, speed);
    let (cq, dcq) = params.coefficient(fluid, kq, speed);
    // C = c_axis · e eᵀ + c_other · (I − e eᵀ).
    let (e, c_axis, dc_axis, c_other, dc_other) = match shape {
        Shape::Rod(t) => (t, cq, dcq, cp, dcp),
        Shape::Face(n) => (n, cp, dcp, cq, dcq),
    };
    let s = params.diameter;
    let scale = fluid.viscosity * volume / (s * s);
    let ed = dot(e, dv);
    let mut f = [0.0; 3];
    // (C Δv) and (dC/d|Δv| Δv).
    let mut cdv = [0.0; 3];
    let mut dcdv = [0.0; 3];
    for i in 0..3 {
        let along = e[i] * ed;
        cdv[i] = c_axis * along + c_other * (dv[i] - along);
        dcdv[i] = dc_axis * along + dc_other * (dv[i] - along);
        f[i] = -scale * cdv[i];
    }
    let mut jac = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let id = if i == j { 1.0 } else { 0.0 };
            let c_ij = c_axis * e[i] * e[j] + c_other * (id - e[i] * e[j]);
            // d|Δv|/dΔv = Δv/|Δv|.
            let nl = if speed > 0.0 {
                dcdv[i] * dv[j] / speed
            } else {
                0.0
            };
            jac[i][j] = -scale * (c_ij + nl);
        }
    }
    (f, jac)
}

/// Lift (eq. 4) from the drag `f_drag` at relative velocity `dv` with axis `e` (the rod's
/// tangent, or the face's normal). Zero when Δv = 0.
pub fn lift_force(xi_l: f64, e: [f64; 3], f_drag: [f64; 3], dv: [f64; 3]) -> [f64; 3] {
    let v2 = dot(dv, dv);
    if v2 == 0.0 || xi_l == 0.0 {
        return [0.0; 3];
    }
    let q = cross(e, cross(e, f_drag));
    let k = dot(q, dv) / v2;
    [0, 1, 2].map(|i| -xi_l * (q[i] - k * dv[i]))
}

#[cfg(test)]
mod tests {
    use super::*;

    const W: FluidProperties = FluidProperties::WATER;

    fn params(xi_n: f64, c: f64) -> Drag {
        Drag {
            xi_d: 2.0,
            xi_perp: 1.5,
            xi_par: 0.4,
            xi_n,
            xi_l: 0.3,
            diameter: 1e-4,
            gamma: 0.2,
            degree: c,
        }
    }

    #[test]
    fn coefficients_in_the_linear_and_nonlinear_branches() {
        // Linear branch: C = 1/k = ξ_D ξ_l / 10⁴ exactly.
        let p = params(0.0, 1.0);
        let (c, dc) = p.coefficient(&W, p.inverse_permeability(1.5), 0.3);
        assert!((c - 2.0 * 1.5 / 1e4).abs() < 1e-18, "{c}");
        assert_eq!(dc, 0.0);
        // Nonlinear: by hand, k = 1e4/(2·1.5), Re = ρ D |Δv|/μ.
        let p = params(0.7, 1.0);
        let k: f64 = 1e4 / 3.0;
        let re = 998.2 * 1e-4 * 0.3 / 1.002e-3;
        let want = 1.0 / k + 0.7 * 1.75 / (150.0 * k).sqrt() / 0.8f64.powf(1.5) * re;
        let (c, dc) = p.coefficient(&W, p.inverse_permeability(1.5), 0.3);
        assert!((c - want).abs() < 1e-15 * want, "{c} vs {want}");
        let h = 1e-7;
        let fd =
            (p.coefficient(&W, 3e-4, 0.3 + h).0 - p.coefficient(&W, 3e-4, 0.3 - h).0) / (2.0 * h);
        assert!((dc - fd).abs() < 1e-6 * dc.abs(), "{dc} vs {fd}");
        // Degree 2: quadratic in the Reynolds number.
        let p2 = params(0.7, 2.0);
        let (c2, _) = p2.coefficient(&W, p2.inverse_permeability(1.5), 0.3);
        assert!((c2 - (1.0 / k + (want - 1.0 / k) * re)).abs() < 1e-12 * c2);
    }

    #[test]
    fn drag_on_a_rod_and_a_face_has_the_right_direction_and_size() {
        let p = params(0.0, 1.0);
        let (v, s) = (2e-9, (1e-4f64).powi(2));
        let scale = W.viscosity * v / s;
        let (cperp, cpar) = (2.0 * 1.5 / 1e4, 2.0 * 0.4 / 1e4);
        // Rod along x moving along y: normal drag opposing the motion.
        let (f, _) = drag_force(&p, &W, Shape::Rod([1.0, 0.0, 0.0]), v, [0.0, 0.5, 0.0]);
        assert!((f[1] + scale * cperp * 0.5).abs() < 1e-15 * scale);
        assert!(f[0] == 0.0 && f[2] == 0.0);
        // ... and along x: tangential drag.
        let (f, _) = drag_force(&p, &W, Shape::Rod([1.0, 0.0, 0.0]), v, [0.5, 0.0, 0.0]);
        assert!((f[0] + scale * cpar * 0.5).abs() < 1e-15 * scale);
        // Face with normal z moving along z: the normal coefficient; along x: tangential.
        let (f, _) = drag_force(&p, &W, Shape::Face([0.0, 0.0, 1.0]), v, [0.0, 0.0, 0.5]);
        assert!((f[2] + scale * cperp * 0.5).abs() < 1e-15 * scale);
        let (f, _) = drag_force(&p, &W, Shape::Face([0.0, 0.0, 1.0]), v, [0.5, 0.0, 0.0]);
        assert!((f[0] + scale * cpar * 0.5).abs() < 1e-15 * scale);
    }

    #[test]
    fn the_drag_jacobian_matches_finite_differences() {
        let e = {
            let t = [0.3, -0.5, 0.8];
            let l = dot(t, t).sqrt();
            t.map(|x| x / l)
        };
        for (p, shape) in [
            (params(0.0, 1.0), Shape::Rod(e)),
            (params(0.9, 1.0), Shape::Rod(e)),
            (params(0.9, 1.6), Shape::Face(e)),
        ] {
            let dv = [0.2, 0.35, -0.1];
            let (_, jac) = drag_force(&p, &W, shape, 1e-9, dv);
            let h = 1e-7;
            for j in 0..3 {
                let (mut a, mut b) = (dv, dv);
                a[j] += h;
                b[j] -= h;
                let (fa, _) = drag_force(&p, &W, shape, 1e-9, a);
                let (fb, _) = drag_force(&p, &W, shape, 1e-9, b);
                for i in 0..3 {
                    let fd = (fa[i] - fb[i]) / (2.0 * h);
                    let sc = jac.iter().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
                    assert!((jac[i][j] - fd).abs() < 1e-6 * sc, "{shape:?} [{i}][{j}]");
                }
            }
        }
    }

    #[test]
    fn lift_is_perpendicular_to_the_flow_and_vanishes_where_it_should() {
        let p = params(0.0, 1.0);
        let e = [1.0, 0.0, 0.0];
        let dv = [0.3, 0.4, 0.0];
        let (f, _) = drag_force(&p, &W, Shape::Rod(e), 1e-9, dv);
        let l = lift_force(p.xi_l, e, f, dv);
        assert!(dot(l, dv).abs() < 1e-15 * dot(l, l).sqrt().max(1e-300));
        assert!(dot(l, l) > 0.0);
        // Zero for Δv = 0 and for Δv along the axis.
        assert_eq!(lift_force(p.xi_l, e, f, [0.0; 3]), [0.0; 3]);
        let along = [0.5, 0.0, 0.0];
        let (f, _) = drag_force(&p, &W, Shape::Rod(e), 1e-9, along);
        let l = lift_force(p.xi_l, e, f, along);
        assert!(l.iter().all(|x| x.abs() < 1e-30), "{l:?}");
    }

    #[test]
    fn out_of_range_parameters_are_named() {
        use weft_scene::fields::SecFields;
        let mut p = Drag::default();
        assert!(p.check().is_ok());
        p.gamma = 1.0;
        assert_eq!(p.check().unwrap_err().field, "drag.gamma");
        p = Drag {
            diameter: 0.0,
            ..Default::default()
        };
        assert_eq!(p.check().unwrap_err().field, "drag.diameter");
        p = Drag {
            xi_perp: -1.0,
            ..Default::default()
        };
        assert_eq!(p.check().unwrap_err().field, "drag.xi_perp");
    }
}

//! The coupled fluid–solid step (VERIFY.md, Drag and coupling).

use nalgebra::Vector3;
use weft_fluid::advect::advect_velocity;
use weft_fluid::{Axis, Boundaries, Domain, DragParams, FluidProperties, MacGrid};
use weft_sim::verify;
use weft_sim::*;
use weft_solid::{Settings, SolidSystem, State};

/// A straight free strand of `n` segments along x from `start`, moving at `v` (hair's
/// 1300 kg/m³, ξ_D = 10⁴).
fn strand(
    n: usize,
    len: f64,
    start: [f64; 3],
    v: [f64; 3],
    radius: f64,
) -> (SolidSystem, State, Vec<DragElement>) {
    let params = DragParams {
        xi_d: 1e4,
        ..Default::default()
    };
    verify::strand(n, len, start, v, radius, 1300.0, params)
}

/// Drag and pressure forces are internal to fluid + solids: in a periodic box without gravity
/// the momentum the coupling takes from the fluid, Σ_f ρα(u − u*)Δx³ (u* the advected
/// velocity the projection starts from), is the momentum the solids gain, Σ m(v − v⁰), once
/// the Newton coupling has converged. Tolerance: the coupling stops at a velocity change of
/// 1e-10 m/s; the imbalance must be below 1e-6 of the exchanged momentum.
#[test]
fn the_coupling_conserves_momentum_in_a_periodic_box() {
    let b = Boundaries::periodic(&[Axis::X, Axis::Y, Axis::Z]);
    let d = Domain::new([0.0; 3], [0.2, 0.2, 0.2], 0.02, b, None).unwrap();
    let mut grid = MacGrid::new(d);
    let (mut sys, mut state, elements) = strand(6, 0.1, [0.05, 0.1, 0.1], [0.2, 0.05, 0.0], 2e-3);
    let mut stepper = CoupledStepper::new(&sys, &grid).unwrap();
    let settings = CoupledSettings {
        tolerance: 1e-10,
        max_iterations: 60,
        solid: Settings {
            tolerance: 1e-12,
            ..Default::default()
        },
        pressure: weft_fluid::PressureSolve {
            tolerance: 1e-12,
            max_iterations: 5000,
        },
        fluid: FluidProperties::WATER,
        ..Default::default()
    };
    let h = 0.01;
    let mut exchanged = 0.0f64;
    for step in 0..5 {
        let mut predicted = grid.clone();
        advect_velocity(&mut predicted, h, &mut None);
        let v0 = state.v.clone();
        let stats = stepper
            .step(
                &mut sys, &elements, &mut state, &mut grid, None, h, &settings,
            )
            .unwrap();
        let dom = &grid.domain;
        let cell = dom.dx.powi(3);
        let mut fluid = Vector3::zeros();
        for a in 0..3 {
            let dims = dom.face_dims(a);
            for k in 0..dims[2] {
                for j in 0..dims[1] {
                    for i in 0..dims[0] {
                        if [i, j, k][a] == dom.cells[a] {
                            continue; // the periodic copy
                        }
                        let f = dom.face(a, i, j, k);
                        fluid[a] += 998.2
                            * grid.alpha[a][f]
                            * (grid.vel[a][f] - predicted.vel[a][f])
                            * cell;
                    }
                }
            }
        }
        let solid: Vector3<f64> = (0..state.v.len())
            .map(|i| sys.mass[i] * (state.v[i] - v0[i]))
            .sum();
        exchanged = exchanged.max(solid.norm());
        let imbalance = (fluid + solid).norm();
        eprintln!(
            "step {step}: {} coupling iterations, solid Δp {:?}, imbalance {imbalance:e}",
            stats.iterations,
            solid.as_slice()
        );
        assert!(
            imbalance <= 1e-6 * solid.norm(),
            "step {step}: {imbalance:e} vs {:e}",
            solid.norm()
        );
    }
    assert!(exchanged > 0.0);
}

/// The settling sheet of `thickness` ([`verify::settling_sheet`]) stepped 60 × 5 ms with
/// Newton coupling to 1e-9 m/s; its mean fall speed at the end and Darcy's Δρg/k.
fn settle_sheet(thickness: f64) -> (f64, f64) {
    let (mut sys, mut state, elements, mut grid) = verify::settling_sheet(thickness);
    let mut stepper = CoupledStepper::new(&sys, &grid).unwrap();
    let settings = CoupledSettings {
        tolerance: 1e-9,
        max_iterations: 100,
        gravity: [0.0, -9.81, 0.0],
        ..Default::default()
    };
    let mut v = 0.0;
    for _ in 0..60 {
        stepper
            .step(
                &mut sys, &elements, &mut state, &mut grid, None, 0.005, &settings,
            )
            .unwrap();
        v = -state.v.iter().map(|v| v.y).sum::<f64>() / state.v.len() as f64;
    }
    (v, verify::sheet_terminal())
}

/// Settling porous sheet (VERIFY.md): the sheet reaches the terminal velocity at which drag
/// balances its net weight. From the porous model at steady state (fluid at rest far away,
/// zero mixture flux through the sheet): U = α² Δρ g / k, k = (μ/D²) C⊥ the drag per unit
/// solid volume, α the fluid fraction where the sheet is rasterized — independent of the
/// thickness up to α² (here φ = 1 − α ≤ 1 %). Tolerances: 3 % against Δρg/k (the α² factor
/// and the sheet's spread over two face layers), and 2 % between thicknesses 0.2 and 0.4 mm.
/// Measured: 0.989 and 0.978 × Δρg/k, as α² with φ ≈ 0.55 % and 1.1 % predicts.
#[test]
fn a_settling_porous_sheet_reaches_the_darcy_terminal_velocity() {
    let (u1, want) = settle_sheet(2e-4);
    let (u2, _) = settle_sheet(4e-4);
    eprintln!("settling sheet: U = {u1} and {u2} m/s (t = 0.2, 0.4 mm), Δρg/k = {want}");
    assert!((u1 / want - 1.0).abs() < 0.03, "{u1} vs {want}");
    assert!((u2 / u1 - 1.0).abs() < 0.02, "{u1} vs {u2}");
}

/// A pinned porous sheet of `thickness` across a channel (periodic across, inflow of `q`
/// upward at y = 0, open at the top) with the nonlinear drag term on (ξ_N = 1, c = 1), stepped
/// with Newton coupling to steady state. Returns the pressure drop across the sheet [Pa]
/// between cell centres 0.07 m below and above it, and the coupling iterations of the last
/// step.
fn ergun_sheet(q: f64, thickness: f64, params: DragParams) -> (f64, usize) {
    let mut b = Boundaries::periodic(&[Axis::X, Axis::Z]);
    b.lo[1] = weft_fluid::Boundary::Inflow([0.0, q, 0.0]);
    b.hi[1] = weft_fluid::Boundary::Open;
    let d = Domain::new([0.0; 3], [0.1, 0.2, 0.1], 0.02, b, None).unwrap();
    let mut grid = MacGrid::new(d);
    grid.set_velocity(|_| [0.0, q, 0.0]);
    let (mass, x, elements) = verify::porous_sheet(0.1, thickness, 1000.0, params);
    let mut sys = SolidSystem::new(mass);
    sys.pinned = vec![true; x.len()];
    let mut state = State {
        v: vec![Vector3::zeros(); x.len()],
        x,
    };
    let mut stepper = CoupledStepper::new(&sys, &grid).unwrap();
    let settings = CoupledSettings {
        tolerance: 1e-12,
        max_iterations: 60,
        pressure: weft_fluid::PressureSolve {
            tolerance: 1e-12,
            max_iterations: 5000,
        },
        ..Default::default()
    };
    let mut iterations = 0;
    for _ in 0..4 {
        let stats = stepper
            .step(
                &mut sys, &elements, &mut state, &mut grid, None, 0.01, &settings,
            )
            .unwrap();
        assert!(stats.converged, "{stats:?}");
        iterations = stats.iterations;
    }
    let dom = &grid.domain;
    // Cells j = 1 (y = 0.03) and j = 8 (y = 0.17): no drag between them and the ends, so the
    // pressure is flat there at steady state and the difference is the sheet's drop.
    let dp = grid.pressure[dom.cell(2, 1, 2)] - grid.pressure[dom.cell(2, 8, 2)];
    (dp, iterations)
}

/// Ergun / Forchheimer (VERIFY.md): with the nonlinear term on and c = 1, the pressure drop
/// across a fixed porous layer of thickness L at superficial velocity q is
/// Δp/L = μq/k + 1.75/√150 · ρq²/(√k (1−γ)^{3/2}), k = k_l D² (eq. 2: 1/k_l = ξ_D ξ⊥/10⁴).
/// The sheet is a pinned cloth of thickness L = 20 µm rasterized into the grid; its drag is
/// evaluated at the fluid velocity sampled at its vertices, so the Newton coupling iterates
/// the nonlinear law to a fixed point (3 iterations per step). Speeds 2 and 8 cm/s put the
/// inertial term at 0.33 and 1.33 times the viscous one, so Darcy alone would miss by 25 % and
/// 57 %. Tolerance 0.5 %: the sheet takes a solid fraction φ = L/Δx = 0.1 % of the faces it
/// is spread over and the interstitial velocity there is q/α, so the law holds up to O(φ).
/// Measured: +0.21 % and +0.25 %; at L = 10 µm +0.10 % and +0.12 % (halving with φ).
#[test]
fn ergun_pressure_drop_across_a_pinned_porous_sheet() {
    let (rho, mu) = (998.2, 1.002e-3);
    let params = DragParams {
        xi_d: 1e4,
        xi_perp: 1.0,
        xi_par: 1.0,
        xi_n: 1.0,
        degree: 1.0,
        diameter: 1e-4,
        gamma: 0.1,
        ..Default::default()
    };
    let len = 2e-5;
    let k = params.diameter.powi(2) / (params.xi_d / 1e4 * params.xi_perp);
    for q in [0.02, 0.08] {
        let viscous = mu * q / k;
        let inertial =
            1.75 / 150f64.sqrt() * rho * q * q / (k.sqrt() * (1.0 - params.gamma).powf(1.5));
        let want = (viscous + inertial) * len;
        let (dp, iterations) = ergun_sheet(q, len, params);
        eprintln!(
            "Ergun: q = {q} m/s: Δp = {dp} Pa, law {want} Pa (inertial/viscous {:.2}), \
             {iterations} coupling iterations",
            inertial / viscous
        );
        assert!((dp / want - 1.0).abs() < 5e-3, "q = {q}: Δp {dp} vs {want}");
        // Darcy alone would be far off: the test sees the nonlinear term.
        assert!((dp / (viscous * len) - 1.0).abs() > 0.2);
    }
}

/// Scene side: the Fluid Drag Behavior turns every hair segment and cloth triangle into a
/// drag element with its Drag SEC (or the defaults), names bad drag parameters, and a Drag
/// SEC without the Behavior is reported as unread.
#[test]
fn fluid_drag_behavior_builds_elements_from_secs() {
    use std::sync::Arc;
    use weft_scene::procedural::{Plane, grid, strands_on_sphere};
    use weft_scene::{Drag, ElementKind, Geometry, SceneElement};
    let curves = strands_on_sphere([0.0, 1.0, 0.0], 0.1, 5, 4, 0.2, 60.0);
    let strands = curves.len();
    let mut hair = SceneElement::new("hair", ElementKind::Hair, Geometry::Curves(curves));
    hair.secs.insert(Drag {
        xi_d: 3.0,
        ..Default::default()
    });
    let cloth = SceneElement::new(
        "cloth",
        ElementKind::Cloth,
        Geometry::Mesh(grid([1.0, 1.0], [3, 3], Plane::Xz, [0.0; 3])),
    );
    let tree = |with_drag: bool| {
        let mut behaviors: Vec<Arc<dyn Behavior>> =
            vec![Arc::new(RodMaterial), Arc::new(DiscreteShellMaterial)];
        if with_drag {
            behaviors.push(Arc::new(FluidDrag));
        }
        BehaviorTree { behaviors }
    };
    let c = compile(&[hair.clone(), cloth.clone()], &tree(true)).unwrap();
    assert_eq!(c.drag_elements.len(), strands * 4 + 8);
    assert_eq!(c.terms["drag_elements"], strands * 4 + 8);
    assert_eq!(c.drag_elements[0].params.xi_d, 3.0);
    assert_eq!(
        c.drag_elements.last().unwrap().params.xi_d,
        1.0,
        "cloth: defaults"
    );
    // Without a fluid domain the drag elements feel nothing: said once, and no grid.
    assert_eq!(c.warnings.len(), 1, "{:?}", c.warnings);
    assert!(
        c.warnings[0].contains("no fluid domain"),
        "{:?}",
        c.warnings
    );
    assert!(c.fluid.is_none());
    let c = compile(&[hair.clone(), cloth.clone()], &tree(false)).unwrap();
    assert!(c.drag_elements.is_empty());
    assert!(
        c.warnings.iter().any(|w| w.contains("'drag'")),
        "{:?}",
        c.warnings
    );
    hair.secs.insert(Drag {
        gamma: 1.5,
        ..Default::default()
    });
    let e = compile(&[hair, cloth], &tree(true)).unwrap_err();
    assert!(e.to_string().contains("drag.gamma"), "{e}");
}

/// A fluid-domain element makes the scene's fluid: automatic bounds enclose the solids plus
/// the padding (rounded up to whole cells), the Fluid SEC's properties and the flow are kept,
/// and its SECs count as read. A second domain, and a grid too large for memory, are refused
/// naming the element and field.
#[test]
fn a_fluid_domain_element_makes_the_scenes_fluid() {
    use std::sync::Arc;
    use weft_scene::procedural::strands_on_sphere;
    use weft_scene::{DomainSide, ElementKind, Fluid, FluidDomain, Geometry, SceneElement};
    let curves = strands_on_sphere([0.0, 1.0, 0.0], 0.1, 5, 4, 0.2, 60.0);
    let hair = SceneElement::new("hair", ElementKind::Hair, Geometry::Curves(curves));
    let mut water = SceneElement::new("water", ElementKind::FluidDomain, Geometry::None);
    water.secs.insert(FluidDomain {
        padding: 0.05,
        cell_size: 0.01,
        lo: [DomainSide::Inflow, DomainSide::Wall, DomainSide::Periodic],
        hi: [DomainSide::Open, DomainSide::Wall, DomainSide::Periodic],
        flow: [0.3, 0.0, 0.0],
        ..Default::default()
    });
    water.secs.insert(Fluid::AIR);
    let tree = BehaviorTree {
        behaviors: vec![Arc::new(RodMaterial), Arc::new(FluidDrag)],
    };
    let c = compile(&[hair.clone(), water.clone()], &tree).unwrap();
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
    let f = c.fluid.as_ref().expect("a fluid");
    let (lo, hi) = weft_scene::bounds(
        &c.state
            .x
            .iter()
            .map(|p| [p.x, p.y, p.z])
            .collect::<Vec<_>>(),
    )
    .unwrap();
    for a in 0..3 {
        assert!((f.domain.origin[a] - (lo[a] - 0.05)).abs() < 1e-12);
        let top = f.domain.origin[a] + f.domain.cells[a] as f64 * 0.01;
        assert!(top >= hi[a] + 0.05 - 1e-9 && top < hi[a] + 0.06, "axis {a}");
    }
    assert_eq!(f.properties.density, Fluid::AIR.density);
    let g = f.initial_grid();
    assert_eq!(g.vel[0][g.domain.face(0, 3, 2, 2)], 0.3);
    assert_eq!(
        f.domain.boundaries.lo[0],
        weft_fluid::Boundary::Inflow([0.3, 0.0, 0.0])
    );
    let mut second = water.clone();
    second.name = "sea".into();
    let e = compile(&[hair.clone(), water.clone(), second], &tree).unwrap_err();
    assert!(e.to_string().contains("'sea'"), "{e}");
    let mut huge = water;
    huge.secs.insert(FluidDomain {
        cell_size: 1e-5,
        ..Default::default()
    });
    let e = compile(&[hair, huge], &tree).unwrap_err().to_string();
    assert!(
        e.contains("fluid_domain.cell_size") && e.contains("GiB"),
        "{e}"
    );
}

/// A light strand (radius 8 mm, ρ_s = `density`) in a closed water box under gravity
/// ([`verify::light_strand`]), stepped `steps` times with `method`; returns its mean vertical
/// velocity after each step (None once a step fails).
fn light_strand(method: Coupling, density: f64, xi_d: f64, steps: usize) -> Vec<Option<f64>> {
    let (mut sys, mut state, elements, mut grid) = verify::light_strand(8e-3, density, xi_d);
    let mut stepper = CoupledStepper::new(&sys, &grid).unwrap();
    let settings = CoupledSettings {
        method,
        tolerance: 1e-6,
        max_iterations: 100,
        gravity: [0.0, -9.81, 0.0],
        ..Default::default()
    };
    let mut out = Vec::new();
    for _ in 0..steps {
        let r = stepper.step(
            &mut sys, &elements, &mut state, &mut grid, None, 0.01, &settings,
        );
        out.push(
            r.ok()
                .map(|_| state.v.iter().map(|v| v.y).sum::<f64>() / state.v.len() as f64),
        );
        if out.last() == Some(&None) {
            break;
        }
    }
    out
}

/// A light strand in strong drag (VERIFY.md): ρ_s = 5 kg/m³ in water, ξ_D = 10⁸, so the
/// drag relaxation time m/(kV) ≈ 0.1 ms is far below the step (10 ms) and the fluid around
/// the strand is 200 times heavier than it. Its terminal rise speed is Δρg/k = 0.249 m/s
/// (k = (μ/D²)ξ_Dξ⊥/10⁴). `staggered` exchanges forces once per step, lagging the pressure's
/// reply to the strand's motion, and oscillates about it (measured: 0.246, 0.109, 0.290,
/// 0.189, 0.275, 0.239 m/s); `newton` iterates the exchange to 1e-6 m/s and rises smoothly
/// (0.161, 0.214, 0.237, 0.248, 0.251 m/s). Asserted: staggered's step-to-step changes
/// alternate in sign with swings above 0.03 m/s at least four times; newton's never swing by
/// more than 0.01 m/s against the trend, and it reaches the terminal speed within 3 %.
#[test]
fn a_light_strand_in_strong_drag_staggered_oscillates_newton_holds() {
    let terminal = (998.2 - 5.0) * 9.81 / (1.002e-3 / (0.016f64 * 0.016) * 1e8 / 1e4);
    let staggered: Vec<f64> = light_strand(Coupling::Staggered, 5.0, 1e8, 8)
        .into_iter()
        .map(|v| v.expect("staggered step"))
        .collect();
    let newton: Vec<f64> = light_strand(Coupling::Newton, 5.0, 1e8, 8)
        .into_iter()
        .map(|v| v.expect("newton step"))
        .collect();
    eprintln!("terminal {terminal:.4} m/s\nstaggered {staggered:.3?}\nnewton    {newton:.3?}");
    let swings = |v: &[f64], min: f64| {
        let d: Vec<f64> = v.windows(2).map(|w| w[1] - w[0]).collect();
        d.windows(2)
            .filter(|w| w[0] * w[1] < 0.0 && w[0].abs().min(w[1].abs()) > min)
            .count()
    };
    assert!(swings(&staggered, 0.03) >= 4, "staggered: {staggered:?}");
    assert_eq!(swings(&newton, 0.01), 0, "newton: {newton:?}");
    let peak = newton.iter().cloned().fold(0.0, f64::max);
    assert!((peak / terminal - 1.0).abs() < 0.03, "{peak} vs {terminal}");
}

/// Colliders are obstacles in the fluid: `FluidSpec::obstacles` finds the faces inside a
/// collider's closed mesh (those within the sphere's radius less the faceting, none beyond
/// it) and gives each the collider's rigid velocity at that face: for a turn by θ about the
/// y axis through the centre over h, (p − R(−θ)p)/h, which for small θ is ω × r. Tolerance:
/// exact rigid motion, to rounding (1e-12 m/s).
#[test]
fn colliders_are_obstacles_moving_with_their_transform() {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    use std::sync::Arc;
    use weft_scene::procedural::{sphere, strands_on_sphere};
    use weft_scene::{ElementKind, FluidDomain, Geometry, SceneElement};
    let centre = [0.0, 0.5, 0.0];
    let place = |angle: f64| {
        Isometry3::from_parts(
            Translation3::new(centre[0], centre[1], centre[2]),
            UnitQuaternion::from_axis_angle(&nalgebra::Vector3::y_axis(), angle),
        )
    };
    let (before, after, h) = (place(0.0), place(0.02), 0.04);
    let mut mesh = sphere([0.0; 3], 0.1, 16, 32);
    for p in &mut mesh.positions {
        let q = after.transform_point(&nalgebra::Point3::from(*p));
        *p = [q.x, q.y, q.z];
    }
    let mut head = SceneElement::new("head", ElementKind::Collider, Geometry::Mesh(mesh));
    head.transform = Some(after);
    let hair = SceneElement::new(
        "hair",
        ElementKind::Hair,
        Geometry::Curves(strands_on_sphere(centre, 0.1, 3, 3, 0.1, 60.0)),
    );
    let mut water = SceneElement::new("water", ElementKind::FluidDomain, Geometry::None);
    water.secs.insert(FluidDomain {
        padding: 0.05,
        cell_size: 0.02,
        ..Default::default()
    });
    let tree = BehaviorTree {
        behaviors: vec![Arc::new(RodMaterial)],
    };
    let scene = [hair, head, water];
    let c = compile(&scene, &tree).unwrap();
    let f = c.fluid.as_ref().unwrap();
    assert_eq!(f.colliders, [1]);
    let mut faces = Vec::new();
    f.obstacles(&scene, &[None, Some(before), None], h, &mut faces);
    assert!(faces.len() > 300, "{}", faces.len());
    let back = before * after.inverse();
    let from_centre = |p: [f64; 3]| {
        (0..3)
            .map(|b| (p[b] - centre[b]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    for s in &faces {
        let a = s.axis as usize;
        let d = &f.domain;
        let dims = d.face_dims(a);
        let fi = s.face as usize;
        let idx = [
            fi % dims[0],
            (fi / dims[0]) % dims[1],
            fi / (dims[0] * dims[1]),
        ];
        let p = d.face_position(a, idx);
        let r = from_centre(p);
        assert!(r < 0.1, "face at {p:?}, {r} from the centre");
        let p1 = nalgebra::Point3::from(p);
        let want = (p1 - back.transform_point(&p1))[a] / h;
        assert!(
            (s.velocity - want).abs() < 1e-12,
            "{} vs {want}",
            s.velocity
        );
    }
    // A collider at rest (no transform before): its faces do not move.
    f.obstacles(&scene, &[None, None, None], h, &mut faces);
    assert!(faces.iter().all(|s| s.velocity == 0.0));
    // Every face well inside (0.08 m, below the faceting's 0.1·cos(π/16)) is found.
    let inside = faces.len();
    let found: std::collections::HashSet<(u8, u32)> =
        faces.iter().map(|s| (s.axis, s.face)).collect();
    let d = &f.domain;
    let mut deep = 0;
    for a in 0..3 {
        let dims = d.face_dims(a);
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let p = d.face_position(a, [i, j, k]);
                    if from_centre(p) < 0.08 {
                        deep += 1;
                        assert!(
                            found.contains(&(a as u8, d.face(a, i, j, k) as u32)),
                            "{p:?}"
                        );
                    }
                }
            }
        }
    }
    assert!(
        deep > 0 && deep <= inside,
        "{deep} deep faces, {inside} found"
    );
    eprintln!("collider: {inside} faces inside, {deep} within 0.08 m");
}

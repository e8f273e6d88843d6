//! The coupled solver through the graph users run (`solver.coupled`), on the verification
//! scenes of VERIFY.md (Drag and coupling). Each scene is a graph file in `scenes/`, set as
//! `weft run --set` would set it; the benchmarks sweep the same files.

use weft_bench::scenes_coupled::{
    POROUS_CHANNEL, load, mean_velocity, set, sheet_graph, strand_graph,
};
use weft_graph::{Context, Graph};

fn vec3(g: &mut Graph, output: &str, frame: i64, fps: f64) -> [f64; 3] {
    *g.pull(output, Context::at(frame, fps))
        .unwrap_or_else(|e| panic!("{e}"))
        .get::<[f64; 3]>()
        .expect("a vec3")
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// Drag and pressure forces are internal to fluid + solids: in a periodic box without gravity
/// the momentum the coupling gives the fluid over a step, Σ_f ρα(u − u*)Δx³ (u* the
/// advected velocity the step starts from; `coupled.momentum`'s `exchange`), is the momentum
/// the solids lose, −Σ m(v − v⁰), once the Newton coupling has converged. A strand (6
/// segments, 10 cm, r = 2 mm, 1300 kg/m³, ξ_D = 10⁴) is thrown at (0.2, 0.05, 0) m/s through
/// still water. Tolerance: the coupling stops at a velocity change of 1e-10 m/s; the imbalance
/// must be below 1e-6 of the exchanged momentum.
#[test]
fn the_coupling_conserves_momentum_in_a_periodic_box() {
    let mut g = strand_graph(2e-3, 1300.0, 1e4).unwrap();
    for (what, v) in [
        ("line.start", serde_json::json!([0.05, 0.1, 0.1])),
        ("line.end", serde_json::json!([0.15, 0.1, 0.1])),
        ("line.segments", serde_json::json!(6)),
        ("hair.velocity", serde_json::json!([0.2, 0.05, 0.0])),
        ("gravity.acceleration", serde_json::json!([0.0, 0.0, 0.0])),
        ("solve.update.tolerance", serde_json::json!(1e-10)),
        ("solve.max_iterations", serde_json::json!(60)),
        ("solve.solid.tolerance", serde_json::json!(1e-12)),
        ("solve.pressure.tolerance", serde_json::json!(1e-12)),
        ("solve.pressure.max_iterations", serde_json::json!(5000)),
    ] {
        set(&mut g, what, v).unwrap();
    }
    let sides = ["x_min", "x_max", "y_min", "y_max", "z_min", "z_max"];
    let periodic: Vec<(&str, serde_json::Value)> =
        sides.iter().map(|s| (*s, "periodic".into())).collect();
    g.set_params("water", &periodic).unwrap();
    let fps = 100.0; // h = 0.01 s
    let mut before = vec3(&mut g, "solid_momentum", 0, fps);
    let mut exchanged = 0.0f64;
    for frame in 1..=5 {
        let solid = vec3(&mut g, "solid_momentum", frame, fps);
        let fluid = vec3(&mut g, "exchange", frame, fps);
        let gained = [0, 1, 2].map(|k| solid[k] - before[k]);
        let imbalance = norm([0, 1, 2].map(|k| fluid[k] + gained[k]));
        eprintln!("step {frame}: solid Δp {gained:?}, imbalance {imbalance:e}");
        assert!(
            imbalance <= 1e-6 * norm(gained),
            "step {frame}: {imbalance:e} vs {:e}",
            norm(gained)
        );
        exchanged = exchanged.max(norm(gained));
        before = solid;
    }
    // The strand (1.6 g at 0.2 m/s) gives the water about 1e-7 kg·m/s a step: not nothing.
    assert!(
        exchanged > 1e-8,
        "the strand exchanged {exchanged:e} kg m/s"
    );
}

/// The settling sheet of `thickness` stepped 60 × 5 ms with Newton coupling to 1e-9 m/s; its
/// mean fall speed at the end and Darcy's Δρg/k.
fn settle_sheet(thickness: f64) -> (f64, f64) {
    let mut g = sheet_graph(thickness).unwrap();
    set(&mut g, "solve.update.tolerance", 1e-9.into()).unwrap();
    let v = mean_velocity(&mut g, 60, 200.0).unwrap();
    (-v[1], weft_sim::verify::sheet_terminal())
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

/// Ergun / Forchheimer (VERIFY.md): with the nonlinear term on and c = 1, the pressure drop
/// across a fixed porous layer of thickness L at superficial velocity q is
/// Δp/L = μq/k + 1.75/√150 · ρq²/(√k (1−γ)^{3/2}), k = k_l D² (eq. 2: 1/k_l = ξ_D ξ⊥/10⁴).
/// The sheet is a pinned cloth of thickness L = 20 µm rasterized into the grid; its drag is
/// evaluated at the fluid velocity sampled at its vertices, so the Newton coupling iterates
/// the nonlinear law to a fixed point. Speeds 2 and 8 cm/s put the inertial term at 0.33 and
/// 1.33 times the viscous one, so Darcy alone would miss by 25 % and 57 %. Tolerance 0.5 %:
/// the sheet takes a solid fraction φ = L/Δx = 0.1 % of the faces it is spread over and the
/// interstitial velocity there is q/α, so the law holds up to O(φ). The drop is read by two
/// `coupled.probe`s at the cell centres 7 cm below and above the sheet after four 10 ms
/// steps. Measured: +0.21 % and +0.25 %.
#[test]
fn ergun_pressure_drop_across_a_pinned_porous_sheet() {
    let (rho, mu, diameter, gamma, len): (f64, f64, f64, f64, f64) =
        (998.2, 1.002e-3, 1e-4, 0.1, 2e-5);
    let k = diameter * diameter; // ξ_D ξ⊥ / 10⁴ = 1
    for q in [0.02, 0.08] {
        let mut g = load(POROUS_CHANNEL, "porous_channel.json").unwrap();
        set(&mut g, "water.flow", serde_json::json!([0.0, q, 0.0])).unwrap();
        let dp = *g
            .pull("pressure_drop", Context::at(4, 100.0))
            .unwrap()
            .get::<f64>()
            .unwrap();
        let viscous = mu * q / k;
        let inertial = 1.75 / 150f64.sqrt() * rho * q * q / (k.sqrt() * (1.0 - gamma).powf(1.5));
        let want = (viscous + inertial) * len;
        eprintln!(
            "Ergun: q = {q} m/s: Δp = {dp} Pa, law {want} Pa (inertial/viscous {:.2})",
            inertial / viscous
        );
        assert!((dp / want - 1.0).abs() < 5e-3, "q = {q}: Δp {dp} vs {want}");
        // Darcy alone would be far off: the test sees the nonlinear term.
        assert!((dp / (viscous * len) - 1.0).abs() > 0.2);
    }
}

/// A light strand (radius 8 mm, ρ_s = 5 kg/m³, ξ_D = 10⁸) in a closed water box under
/// gravity, stepped 8 × 10 ms with `method`: its mean vertical velocity after each step.
fn light_strand(method: &str) -> Vec<f64> {
    let mut g = strand_graph(8e-3, 5.0, 1e8).unwrap();
    set(&mut g, "solve.predict.method", method.into()).unwrap();
    (1..=8)
        .map(|f| mean_velocity(&mut g, f, 100.0).unwrap_or_else(|e| panic!("{method}: {e}"))[1])
        .collect()
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
    let staggered = light_strand("staggered");
    let newton = light_strand("newton");
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

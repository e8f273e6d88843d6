//! SEC nodes: each attaches one typed parameter bundle to an element. Parameter ranges are
//! checked when the graph loads, so a negative stiffness or ν ≥ 0.5 is a load error naming the
//! node and parameter. Defaults are the SEC types' documented defaults.

use weft_graph::{Kernel, NodeSpec, ParamError, ParamSpec, Params, Registry, RegistryError, Value};
use weft_scene::{Collider, Density, DiscreteShell, Drag, Fluid, Rod, SceneElement, Sec};

fn attach<S: Sec + Clone>(
    name: &str,
    doc: &str,
    params: Vec<ParamSpec>,
    build: fn(&Params) -> Result<S, ParamError>,
    r: &mut Registry,
) -> Result<(), RegistryError> {
    let mut spec = NodeSpec::new(name, doc)
        .input("element", "element", "the element to carry the SEC")
        .output(
            "element",
            "element",
            "the same element with the SEC attached (replacing one of the same type)",
        );
    for p in params {
        spec = spec.param(p);
    }
    r.register(spec, move |_| {
        Ok(Kernel::from_fn(move |cx| {
            let mut e = cx.input_as::<SceneElement>("element")?;
            e.secs.insert(build(cx.params())?);
            cx.set("element", Value::new(e));
            Ok(())
        }))
    })
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    let d = DiscreteShell::default();
    attach(
        "sec.discrete_shell",
        "Discrete Shell SEC: membrane (StVK, optionally orthotropic) and bending of cloth",
        vec![
            ParamSpec::float("youngs_modulus", d.youngs_modulus)
                .gt(0.0)
                .unit("Pa")
                .doc("Young's modulus E"),
            ParamSpec::float("poisson_ratio", d.poisson_ratio)
                .ge(0.0)
                .lt(0.5)
                .doc("Poisson's ratio ν"),
            ParamSpec::float("thickness", d.thickness)
                .gt(0.0)
                .unit("m")
                .doc("shell thickness t"),
            ParamSpec::float("bend_scale", d.bend_scale)
                .ge(0.0)
                .doc("multiplier on D = E t³/(12(1 − ν²)); 0 disables bending"),
            ParamSpec::float("damping", d.damping)
                .ge(0.0)
                .unit("1/s")
                .doc("mass-proportional damping"),
            ParamSpec::string("rest_channel", &d.rest_channel)
                .doc("channel with rest positions (initial positions when absent)"),
            ParamSpec::float("warp_scale", d.warp_scale)
                .gt(0.0)
                .doc("stiffness multiplier along the warp"),
            ParamSpec::float("weft_scale", d.weft_scale)
                .gt(0.0)
                .doc("stiffness multiplier along the weft"),
            ParamSpec::float("shear_scale", d.shear_scale)
                .gt(0.0)
                .doc("shear stiffness multiplier"),
            ParamSpec::vec3("warp_direction", d.warp_direction).doc("warp direction in rest space"),
        ]
        .into_iter()
        .chain(dropoff_params(d.bend_dropoff, d.dropoff_curvature))
        .collect(),
        |p| {
            Ok(DiscreteShell {
                youngs_modulus: p.f64("youngs_modulus")?,
                poisson_ratio: p.f64("poisson_ratio")?,
                thickness: p.f64("thickness")?,
                bend_scale: p.f64("bend_scale")?,
                damping: p.f64("damping")?,
                bend_dropoff: p.f64("bend_dropoff")?,
                dropoff_curvature: p.f64("dropoff_curvature")?,
                rest_channel: p.str("rest_channel")?.to_string(),
                warp_scale: p.f64("warp_scale")?,
                weft_scale: p.f64("weft_scale")?,
                shear_scale: p.f64("shear_scale")?,
                warp_direction: p.vec3("warp_direction")?,
            })
        },
        r,
    )?;
    let d = Rod::default();
    attach(
        "sec.rod",
        "Rod SEC: stretching and bending of hair",
        vec![
            ParamSpec::float("youngs_modulus", d.youngs_modulus)
                .gt(0.0)
                .unit("Pa")
                .doc("Young's modulus E"),
            ParamSpec::float("radius", d.radius)
                .gt(0.0)
                .unit("m")
                .doc("fibre radius r"),
            ParamSpec::float("stretch_scale", d.stretch_scale)
                .gt(0.0)
                .doc("multiplier on the axial stiffness E·πr²"),
            ParamSpec::float("bend_stiffness", d.bend_stiffness)
                .ge(0.0)
                .unit("N·m²")
                .doc("bending stiffness EI; 0 derives it as E·πr⁴/4"),
            ParamSpec::float("bend_scale", d.bend_scale)
                .ge(0.0)
                .doc("multiplier on the bending stiffness; 0 disables bending"),
            ParamSpec::float("damping", d.damping)
                .ge(0.0)
                .unit("1/s")
                .doc("mass-proportional damping"),
            ParamSpec::string("rest_channel", &d.rest_channel)
                .doc("channel with rest positions (initial positions when absent)"),
        ]
        .into_iter()
        .chain(dropoff_params(d.bend_dropoff, d.dropoff_curvature))
        .collect(),
        |p| {
            Ok(Rod {
                youngs_modulus: p.f64("youngs_modulus")?,
                radius: p.f64("radius")?,
                stretch_scale: p.f64("stretch_scale")?,
                bend_stiffness: p.f64("bend_stiffness")?,
                bend_scale: p.f64("bend_scale")?,
                damping: p.f64("damping")?,
                bend_dropoff: p.f64("bend_dropoff")?,
                dropoff_curvature: p.f64("dropoff_curvature")?,
                rest_channel: p.str("rest_channel")?.to_string(),
            })
        },
        r,
    )?;
    let d = Density::default();
    attach(
        "sec.density",
        "Density SEC: mass per area of cloth and per length of hair",
        vec![
            ParamSpec::float("area_density", d.area_density)
                .gt(0.0)
                .unit("kg/m²")
                .doc("cloth mass per rest area"),
            ParamSpec::float("line_density", d.line_density)
                .gt(0.0)
                .unit("kg/m")
                .doc("hair mass per rest length"),
        ],
        |p| {
            Ok(Density {
                area_density: p.f64("area_density")?,
                line_density: p.f64("line_density")?,
            })
        },
        r,
    )?;
    let d = Drag::default();
    attach(
        "sec.drag",
        "Drag SEC: how hair or cloth exchanges momentum with a fluid (the seed's anisotropic drag: C_l = 1/k_l + xi_N 1.75/sqrt(150 k_l) (1 - gamma)^-1.5 Re^c, 1/k_l = xi_D xi_l / 1e4; force -(mu V/D^2) R C R^T dv; lift xi_L)",
        vec![
            ParamSpec::float("xi_d", d.xi_d)
                .ge(0.0)
                .doc("global drag scale ξ_D"),
            ParamSpec::float("xi_perp", d.xi_perp)
                .ge(0.0)
                .doc("normal drag scale ξ⊥"),
            ParamSpec::float("xi_par", d.xi_par)
                .ge(0.0)
                .doc("tangential drag scale ξ∥"),
            ParamSpec::float("xi_n", d.xi_n)
                .ge(0.0)
                .doc("nonlinear (inertial) term scale ξ_N; 0: linear drag"),
            ParamSpec::float("xi_l", d.xi_l)
                .ge(0.0)
                .doc("lift scale ξ_L; 0: no lift"),
            ParamSpec::float("diameter", d.diameter)
                .gt(0.0)
                .unit("m")
                .doc("fibre diameter D"),
            ParamSpec::float("gamma", d.gamma)
                .ge(0.0)
                .lt(1.0)
                .doc("material fraction γ"),
            ParamSpec::float("degree", d.degree)
                .ge(0.0)
                .doc("drag degree c: the exponent of the Reynolds number"),
        ],
        |p| {
            Ok(Drag {
                xi_d: p.f64("xi_d")?,
                xi_perp: p.f64("xi_perp")?,
                xi_par: p.f64("xi_par")?,
                xi_n: p.f64("xi_n")?,
                xi_l: p.f64("xi_l")?,
                diameter: p.f64("diameter")?,
                gamma: p.f64("gamma")?,
                degree: p.f64("degree")?,
            })
        },
        r,
    )?;
    let d = Collider::default();
    attach(
        "sec.collider",
        "Collider SEC: how a cloth, hair or collider element meets others in contact (with behavior.collision and a collision group); a contact keeps the sum of both sides' thicknesses, uses the geometric mean of their friction coefficients and the larger cohesion; a collider without it takes the other side's friction and cohesion",
        vec![
            ParamSpec::float("friction", d.friction)
                .ge(0.0)
                .doc("Coulomb friction coefficient μ"),
            ParamSpec::float("thickness", d.thickness)
                .gt(0.0)
                .unit("m")
                .doc("distance kept from the surface"),
            ParamSpec::float("cohesion", d.cohesion)
                .ge(0.0)
                .unit("Pa")
                .doc("the most a contact may pull per m² of contact area (cloth: a third of a vertex's triangles; hair: its segments' length × diameter)"),
        ],
        |p| {
            Ok(Collider {
                friction: p.f64("friction")?,
                thickness: p.f64("thickness")?,
                cohesion: p.f64("cohesion")?,
            })
        },
        r,
    )?;
    attach(
        "sec.fluid",
        "Fluid SEC: the material filling a fluid domain (SI): a preset (water or air at 20 °C) or custom density and viscosity",
        vec![
            ParamSpec::choice("preset", &["water", "air", "custom"], "water")
                .doc("water: 998.2 kg/m³, 1.002e-3 Pa·s; air: 1.204 kg/m³, 1.81e-5 Pa·s; custom: the two parameters below"),
            ParamSpec::float("density", Fluid::WATER.density)
                .gt(0.0)
                .unit("kg/m³")
                .doc("density ρ (preset custom only)"),
            ParamSpec::float("viscosity", Fluid::WATER.viscosity)
                .gt(0.0)
                .unit("Pa·s")
                .doc("dynamic viscosity μ (preset custom only)"),
        ],
        |p| {
            Ok(match p.str("preset")? {
                "air" => Fluid::AIR,
                "custom" => Fluid {
                    density: p.f64("density")?,
                    viscosity: p.f64("viscosity")?,
                },
                _ => Fluid::WATER,
            })
        },
        r,
    )
}

/// The bend angle dropoff's two parameters (Discrete Shell and Rod SECs alike).
fn dropoff_params(d: f64, kappa0: f64) -> [ParamSpec; 2] {
    [
        ParamSpec::float("bend_dropoff", d)
            .ge(0.0)
            .le(1.0)
            .doc("bend angle dropoff d: bending stiffness × (1 − d + d (κ/κ₀)²) at curvature κ (soft for small bends, stiffer for large; 0: none)"),
        ParamSpec::float("dropoff_curvature", kappa0)
            .gt(0.0)
            .unit("1/m")
            .doc("κ₀ of the dropoff: the curvature (1/radius) at which the plain stiffness holds"),
    ]
}

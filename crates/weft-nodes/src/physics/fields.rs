//! Reading the fluid of a coupled state out of Weft: `coupled.probe` (everything the grid
//! holds at a point), `coupled.line_probe` (a profile along a segment), `coupled.diagnostics`
//! (momentum, energy, impulses, divergence, volume per frame) and `output.vdb` (the fields
//! as OpenVDB files, written by `weft_scene::vdb`).
//!
//! Pressures: the grid solves for the reduced pressure p − ρ g·x (gravity lives in the
//! hydrostatic part, DESIGN §6). Probes give it as `pressure` and, as `pressure_absolute`,
//! with the hydrostatic part ρ g·(x − x_top) added, x_top the domain's highest corner along
//! gravity: the gauge pressure under a free surface at the domain's top.

use super::coupled::{CoupledState, get, settings};
use super::output::fail;
use weft_fluid::MacGrid;
use weft_graph::{EvalCx, Kernel, NodeError, NodeSpec, ParamSpec, Registry, RegistryError};
use weft_scene::vdb::{self, DenseGrid, GridClass, Values, VectorType};

/// The state's fluid, or an error naming what is missing.
fn fluid_of<'a>(s: &'a CoupledState, what: &str) -> Result<&'a MacGrid, NodeError> {
    s.fluid.as_deref().ok_or_else(|| {
        NodeError::Failed(format!(
            "{what}: the scene has no fluid (add a convert.fluid_domain element with a sec.fluid); nothing was read or written"
        ))
    })
}

/// Refuses a point outside the fluid's box.
fn inside(g: &MacGrid, p: [f64; 3], what: &str) -> Result<(), NodeError> {
    let dom = &g.domain;
    if !dom.contains(p) {
        let size = dom.size();
        let hi: Vec<f64> = (0..3).map(|a| dom.origin[a] + size[a]).collect();
        return Err(NodeError::Failed(format!(
            "{what} {p:?} m is outside the fluid domain {:?} .. {hi:?} m",
            dom.origin
        )));
    }
    Ok(())
}

/// The quantities a probe reads at a point.
struct Reading {
    velocity: [f64; 3],
    pressure: f64,
    pressure_absolute: f64,
    solid_fraction: f64,
    vorticity: [f64; 3],
}

/// Reads the grid at `p`; `gravity` and `rho` (the state's) give the hydrostatic part, taken at
/// the centre of the cell whose pressure is read.
fn read(g: &MacGrid, p: [f64; 3], gravity: [f64; 3], rho: f64) -> Reading {
    let pressure = g.pressure_at(p);
    let centre = g.domain.cell_center(g.cell_holding(p));
    Reading {
        velocity: g.velocity_at(p),
        pressure,
        pressure_absolute: pressure + g.hydrostatic_pressure(centre, gravity, rho),
        solid_fraction: g.solid_fraction_at(p),
        vorticity: g.vorticity_at(p),
    }
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn probe(cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let v = cx.input("state")?;
    let s = get::<CoupledState>(&v, "state")?;
    let p = cx.params().vec3("point")?;
    let (r, max) = match &s.fluid {
        Some(g) => {
            inside(g, p, "param 'point':")?;
            let max = g.vel.iter().flatten().fold(0.0f64, |m, u| m.max(u.abs()));
            let set = settings(&s.compiled);
            (read(g, p, set.gravity, set.fluid.density), max)
        }
        None => (
            Reading {
                velocity: [0.0; 3],
                pressure: 0.0,
                pressure_absolute: 0.0,
                solid_fraction: 0.0,
                vorticity: [0.0; 3],
            },
            0.0,
        ),
    };
    cx.set("velocity", r.velocity);
    cx.set("pressure", r.pressure);
    cx.set("pressure_absolute", r.pressure_absolute);
    cx.set("solid_fraction", r.solid_fraction);
    cx.set("vorticity", r.vorticity);
    cx.set("max_speed", max);
    Ok(())
}

const QUANTITIES: &[&str] = &[
    "speed",
    "velocity_x",
    "velocity_y",
    "velocity_z",
    "pressure",
    "pressure_absolute",
    "solid_fraction",
    "vorticity_magnitude",
];

fn line_probe(cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let v = cx.input("state")?;
    let s = get::<CoupledState>(&v, "state")?;
    let params = cx.params();
    let (a, b) = (params.vec3("start")?, params.vec3("end")?);
    let n = params.usize("samples")?;
    let quantity = params.str("quantity")?.to_string();
    let g = fluid_of(s, "a line probe needs a fluid")?;
    inside(g, a, "param 'start':")?;
    inside(g, b, "param 'end':")?;
    let length = norm([0, 1, 2].map(|k| b[k] - a[k]));
    let set = settings(&s.compiled);
    let mut values = Vec::with_capacity(n);
    let mut distance = Vec::with_capacity(n);
    for k in 0..n {
        let t = if n > 1 {
            k as f64 / (n - 1) as f64
        } else {
            0.0
        };
        let p = [0, 1, 2].map(|c| a[c] + t * (b[c] - a[c]));
        let r = read(g, p, set.gravity, set.fluid.density);
        values.push(match quantity.as_str() {
            "speed" => norm(r.velocity),
            "velocity_x" => r.velocity[0],
            "velocity_y" => r.velocity[1],
            "velocity_z" => r.velocity[2],
            "pressure" => r.pressure,
            "pressure_absolute" => r.pressure_absolute,
            "solid_fraction" => r.solid_fraction,
            _ => norm(r.vorticity),
        });
        distance.push(t * length);
    }
    cx.set("values", values);
    cx.set("distance", distance);
    Ok(())
}

fn diagnostics(cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let v = cx.input("state")?;
    let s = get::<CoupledState>(&v, "state")?;
    let h = 1.0 / cx.context().fps;
    let set = settings(&s.compiled);
    let sys = &s.compiled.system;
    let (mut solid, mut solid_ke, mut mass) = ([0.0; 3], 0.0, 0.0);
    for (m, v) in sys.mass.iter().zip(&s.sim.solid.v) {
        for k in 0..3 {
            solid[k] += m * v[k];
        }
        solid_ke += 0.5 * m * v.norm_squared();
        mass += m;
    }
    let rho = set.fluid.density;
    let (fluid, fluid_ke, walls, divergence, volume) = match &s.fluid {
        Some(g) => (
            g.momentum(rho),
            g.fluid_kinetic_energy(rho),
            g.boundary_impulse(h),
            weft_fluid::max_divergence(g),
            g.fluid_volume(),
        ),
        None => ([0.0; 3], 0.0, [0.0; 3], 0.0, 0.0),
    };
    // Gravity with the hydrostatic pressure: the solids' weight less their buoyancy (the
    // reduced pressure carries no hydrostatic part, so the walls' impulse above excludes it).
    let solid_volume = if s.fluid.is_some() {
        weft_sim::solid_volume(&s.compiled.drag_elements, &s.sim.solid.x)
    } else {
        0.0
    };
    let weight = mass - rho * solid_volume;
    let gravity = set.gravity.map(|g| h * g * weight);
    cx.set("solid_momentum", solid);
    cx.set("fluid_momentum", fluid);
    cx.set("total_momentum", [0, 1, 2].map(|k| solid[k] + fluid[k]));
    cx.set("solid_kinetic_energy", solid_ke);
    cx.set("fluid_kinetic_energy", fluid_ke);
    cx.set("exchange", s.exchange);
    cx.set("transport", s.transport);
    cx.set("wall_impulse", walls);
    cx.set("gravity_impulse", gravity);
    cx.set("max_divergence", divergence);
    cx.set("fluid_volume", volume);
    Ok(())
}

const GRIDS: &[&str] = &[
    "velocity",
    "pressure",
    "pressure_absolute",
    "speed",
    "solid_fraction",
];

fn output_vdb(cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
    let v = cx.input("state")?;
    let s = get::<CoupledState>(&v, "state")?;
    let params = cx.params().clone();
    let prefix = super::output::file_prefix(params.str("prefix")?)?;
    let mut wanted = Vec::new();
    for name in params
        .str("grids")?
        .split(',')
        .map(str::trim)
        .filter(|n| !n.is_empty())
    {
        if !GRIDS.contains(&name) {
            return Err(NodeError::Failed(format!(
                "param 'grids': unknown grid {name:?}; choose from {}",
                GRIDS.join(", ")
            )));
        }
        if !wanted.contains(&name) {
            wanted.push(name);
        }
    }
    if wanted.is_empty() {
        return Err(NodeError::Failed(format!(
            "param 'grids': empty; choose from {}",
            GRIDS.join(", ")
        )));
    }
    let g = fluid_of(s, "output.vdb writes the fluid's fields")?;
    let cells = g.domain.cell_count() as u64;
    // The f32 grids and the file (at most their raw size), 4 bytes a component each, and a
    // margin for the nodes' masks and the compressor's buffers.
    let components: u64 = wanted
        .iter()
        .map(|&w| if w == "velocity" { 3 } else { 1 })
        .sum();
    weft_graph::memory::check_within(
        weft_graph::memory::product(&[cells, 8 * components + 64]),
        cx.memory_budget(),
        || format!("the fields of a {:?}-cell grid", g.domain.cells),
        "use larger cells or fewer grids",
    )?;
    let set = settings(&s.compiled);
    let dom = &g.domain;
    let n = dom.cell_count();
    // One scalar per cell, x fastest (the grid's cell order, which the VDB writer takes).
    let scalars = |f: &dyn Fn(usize, [usize; 3]) -> f64| {
        let mut v = Vec::with_capacity(n);
        g.for_each_cell(|i, c| v.push(f(i, c) as f32));
        Values::Float(v)
    };
    let half = params.str("precision")? == "half";
    let mut grids = Vec::new();
    for name in wanted {
        let (class, values) = match name {
            "velocity" => {
                let mut v = Vec::with_capacity(n);
                g.for_each_cell(|_, c| v.push(g.cell_velocity(c).map(|x| x as f32)));
                (GridClass::Unknown, Values::Vec3(v))
            }
            "speed" => (
                GridClass::Unknown,
                scalars(&|_, c| norm(g.cell_velocity(c))),
            ),
            "pressure" => (GridClass::Unknown, scalars(&|i, _| g.pressure[i])),
            "pressure_absolute" => (
                GridClass::Unknown,
                scalars(&|i, c| {
                    let x = dom.cell_center(c);
                    g.pressure[i] + g.hydrostatic_pressure(x, set.gravity, set.fluid.density)
                }),
            ),
            _ => (
                GridClass::FogVolume,
                scalars(&|_, c| g.cell_solid_fraction(c)),
            ),
        };
        grids.push(DenseGrid {
            name: name.to_string(),
            class,
            vector_type: VectorType::ContravariantRelative,
            dims: dom.cells,
            voxel_size: dom.dx,
            origin: dom.cell_center([0, 0, 0]),
            values,
            half,
        });
    }
    let compression = match params.str("compression")? {
        "none" => vdb::Compression::None,
        _ => vdb::Compression::Zip,
    };
    let path = cx
        .output_path("directory")?
        .join(format!("{prefix}.{:04}.vdb", cx.frame()));
    let bytes = vdb::to_bytes(&grids, compression).map_err(|e| fail(&path, e))?;
    weft_graph::atomic_write(&path, &bytes).map_err(|e| fail(&path, e))?;
    cx.set("path", path.display().to_string());
    Ok(())
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new(
            "coupled.probe",
            "reads the fluid of a coupled state at a point: velocity, pressure (reduced and absolute), solid fraction, vorticity, and the largest speed (zeros without fluid; a point outside the domain is an error)",
        )
        .input("state", "coupled", "the coupled state")
        .output("velocity", "vec3", "fluid velocity at the point, trilinear in the faces [m/s]")
        .output("pressure", "float", "reduced pressure p − ρ g·x of the cell holding the point [Pa] (what the grid solves for: gravity is in the hydrostatic part)")
        .output("pressure_absolute", "float", "the reduced pressure plus the hydrostatic ρ g·(x − x_top) at the cell's centre, x_top the domain's highest corner along gravity [Pa]: gauge pressure under a free surface at the domain's top")
        .output("solid_fraction", "float", "solid fraction of the cell holding the point: 1 − the mean fluid fraction of its six faces")
        .output("vorticity", "vec3", "∇ × u at the point [1/s] (central differences of the sampled velocity, half a cell either side)")
        .output("max_speed", "float", "largest face speed [m/s]")
        .param(ParamSpec::vec3("point", [0.0; 3]).unit("m").doc("where to sample (inside the fluid domain)")),
        |_| Ok(Kernel::from_fn(probe)),
    )?;
    r.register(
        NodeSpec::new(
            "coupled.line_probe",
            "a profile of the fluid along a segment: N samples from start to end (outputs.csv writes them as columns NAME.0 … NAME.N−1)",
        )
        .input("state", "coupled", "the coupled state")
        .output("values", "floats", "the quantity at each sample, start to end")
        .output("distance", "floats", "each sample's distance from start [m]")
        .param(ParamSpec::vec3("start", [0.0; 3]).unit("m").doc("first sample (inside the fluid domain)"))
        .param(ParamSpec::vec3("end", [0.0; 3]).unit("m").doc("last sample (inside the fluid domain)"))
        .param(ParamSpec::int("samples", 16).ge(1.0).le(100_000.0).doc("number of samples, evenly spaced with both ends included (1: the start alone)"))
        .param(ParamSpec::choice("quantity", QUANTITIES, "speed").doc("what to sample: speed, a velocity component [m/s], pressure or pressure_absolute [Pa] (see coupled.probe), solid_fraction, vorticity_magnitude [1/s]")),
        |_| Ok(Kernel::from_fn(line_probe)),
    )?;
    r.register(
        NodeSpec::new(
            "coupled.diagnostics",
            "conservation diagnostics of a coupled state, per frame: momentum and kinetic energy of solids and fluid, the impulses of the last step (coupling, walls and obstacles, gravity), the largest divergence and the fluid's volume. In a closed box with free solids (attachments' forces are in no term), solid_momentum(f) − solid_momentum(f−1) + exchange = wall_impulse + gravity_impulse to the coupling tolerance, and the fluid's momentum changes by exchange + transport",
        )
        .input("state", "coupled", "the coupled state")
        .output("solid_momentum", "vec3", "Σ m v over the simulated vertices [kg·m/s]")
        .output("fluid_momentum", "vec3", "Σ ρ α u Δx³ over the grid's distinct faces [kg·m/s] (zero without fluid)")
        .output("total_momentum", "vec3", "solid_momentum + fluid_momentum [kg·m/s]")
        .output("solid_kinetic_energy", "float", "½ Σ m |v|² [J]")
        .output("fluid_kinetic_energy", "float", "½ Σ ρ α u² Δx³ over distinct faces [J]")
        .output("exchange", "vec3", "what the coupling (drag and pressure) gave the fluid over the last step, Σ ρ α (u − u*) Δx³ [kg·m/s], u* the advected velocity")
        .output("transport", "vec3", "the rest of the fluid's momentum change over the last step, Σ ρα u − (Σ ρα u at the step's start) − exchange [kg·m/s]: what advection (semi-Lagrangian, not conservative) and the solids' moving fractions created; fluid_momentum changes by exchange + transport")
        .output("wall_impulse", "vec3", "what the domain's walls and inflow sides and the obstacles in it gave fluid and solids through the (reduced) pressure over the last step [N·s]; open and periodic sides give none")
        .output("gravity_impulse", "vec3", "h g (M − ρ_f V): the solids' weight less their buoyancy over the last step [N·s] (with the reduced pressure, the fluid's own weight is balanced hydrostatically and appears in neither term)")
        .output("max_divergence", "float", "largest |∇·(α u + (1 − α) v)| over the cells [1/s]")
        .output("fluid_volume", "float", "Σ (1 − solid fraction) Δx³ over the cells [m³]"),
        |_| Ok(Kernel::from_fn(diagnostics)),
    )?;
    r.register(
        NodeSpec::new(
            "output.vdb",
            "writes the fluid of a coupled state at each frame as DIRECTORY/PREFIX.FRAME.vdb (OpenVDB, file format 224): cell-centred grids in metres, voxel (i, j, k) at the centre of cell (i, j, k)",
        )
        .input("state", "coupled", "the coupled state (its scene must have a fluid)")
        .output("path", "string", "the file written")
        .param(ParamSpec::string("directory", "out/fields").doc("output directory (under --out when given, else the working directory)"))
        .param(ParamSpec::string("prefix", "fields").doc("file name prefix"))
        .param(ParamSpec::string("grids", "velocity,pressure,speed,solid_fraction").doc("comma-separated grids to write: velocity (vec3s, the faces averaged to cell centres, vector type contravariant relative), pressure (reduced, Pa), pressure_absolute (with the hydrostatic part, Pa), speed (|velocity|, m/s), solid_fraction (fog volume, 0 to 1)"))
        .param(ParamSpec::choice("compression", &["zip", "none"], "zip").doc("zip: each node's values zlib-compressed (OpenVDB's COMPRESS_ZIP); none: raw"))
        .param(ParamSpec::choice("precision", &["float", "half"], "float").doc("float: 32-bit values; half: 16-bit (OpenVDB's _HalfFloat grids: about half the file, 3 significant digits, magnitudes up to 65504 — a larger value is an error naming the grid)")),
        |_| Ok(Kernel::from_fn(output_vdb)),
    )
}

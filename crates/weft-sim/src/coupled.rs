//! Two-way coupling of solids with the Eulerian fluid (DESIGN §6): one time step.
//!
//! Gravity on the fluid is balanced by its hydrostatic pressure, so the grid solves for the
//! pressure *relative to hydrostatic* (Boussinesq-free reduced pressure, exact for a fluid of
//! uniform density): the fluid feels no gravity, an open side sits at hydrostatic pressure
//! (still water deep below it, not a waterfall), and the solids get the hydrostatic part as
//! the explicit buoyancy −ρ_f V g. Otherwise:
//!
//! The stages of a step (DESIGN §6's numbers; ARCHITECTURE.md's table), each a method of
//! [`CoupledStepper`] named as the `solver.coupled` node that calls it (the composite is
//! the loop; there is no other): **4** `predict` advects the fluid → u* (at the start of
//! the step it serves), and with **1** carves the obstacles; **3** the composite's Newton
//! iterations k, each: **B** `forces` samples every drag element at the current solid
//! iterate; per sample, the drag tensor's diagonal k (per unit solid volume, from the seed's
//! law at the current relative speed), the fluid velocity u^k and pressure gradient ∇p^k
//! interpolated with the same trilinear weights the rasterization uses; lumped to vertices
//! as a linear drag −D(v − u) and a pressure (buoyancy) force −V∇p. **C** `solid`: the
//! implicit solid solve → v^{k+1} (its first iterate is **2**, its assembly **A**). **D**
//! `rasterize` puts the samples (volume, drag, solid velocity v^{k+1}) onto the faces.
//! **E/F** `pressure`: the porous pressure solve from u* with the solid prescribed →
//! u^{k+1}, p^{k+1}. **G** `update` stops when neither velocity changed by more than the
//! tolerance. Methods: `Newton` iterates to tolerance, `Staggered` makes one pass, `OneWay`
//! projects the fluid without solids and lets it drive them.
//!
//! Momentum: the fluid loses Σ_f K(u − v)dx³ + Σ_f α∇p dx³ and the solids gain
//! Σ_s V k(u_s − v_s) − Σ_s V (∇p)_s; with the same interpolation weights on both sides
//! (and on a periodic domain, where Σ_f ∇p = 0) these cancel exactly once the iterations have
//! converged, so total momentum is conserved to the coupling tolerance. That is why only the
//! drag tensor's diagonal is used on both sides: the grid holds one coefficient per face.

use crate::collide::{ContactFrameStats, Contacts};
use crate::relaxation::RelaxationMethod;
use nalgebra::Vector3;
use weft_fluid::advect::advect_velocity;
use weft_fluid::obstacle::carve;
use weft_fluid::raster::{
    RasterStats, Sample, add_impulse, rasterize, segment_lattice, segment_samples,
    triangle_lattice, triangle_samples,
};
use weft_fluid::{
    Diffusion, DragLaw, FluidProperties, MacGrid, PressureSolve, PressureStats, Projection,
    SolidFace, lift_force,
};
use weft_solid::{Integrator, Settings, SolidSystem, State, StepError, StepStats, VertexDrag};

/// The solid part a drag element covers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DragShape {
    /// A rod segment between two vertices, with its cross-section area [m²].
    Segment([u32; 2], f64),
    /// A cloth triangle, with its thickness [m].
    Triangle([u32; 3], f64),
}

/// One element that exchanges momentum with the fluid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DragElement {
    /// Its shape.
    pub shape: DragShape,
    /// Its drag law.
    pub params: weft_scene::Drag,
}

/// How solids and fluid are coupled within a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coupling {
    /// The fluid drives the solids and feels nothing back.
    OneWay,
    /// One pass of the stages (explicit in the exchange).
    Staggered,
    /// The stages iterated until the velocities stop changing.
    Newton,
}

impl Coupling {
    /// Whether coupling iteration `iteration` (from 0), which changed the velocities by at
    /// most `change` [m/s], ends the step: `Newton` needs a second iteration (the first has
    /// nothing to compare against but the last step) and a change below `tolerance`; the
    /// one-pass methods stop at once.
    pub fn converged(self, iteration: usize, change: f64, tolerance: f64) -> bool {
        match self {
            Coupling::Newton => iteration > 0 && change < tolerance,
            Coupling::Staggered | Coupling::OneWay => true,
        }
    }
}

/// Coupled step settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoupledSettings {
    /// Coupling method.
    pub method: Coupling,
    /// Newton stops when solid and fluid velocities change by less than this [m/s].
    pub tolerance: f64,
    /// Newton iteration limit.
    pub max_iterations: usize,
    /// How Newton relaxes the solid iterate between coupling iterations.
    pub relaxation: RelaxationMethod,
    /// The solid solve.
    pub solid: Settings,
    /// The pressure solve.
    pub pressure: PressureSolve,
    /// The fluid.
    pub fluid: FluidProperties,
    /// Gravity [m/s²]: the hydrostatic pressure's gradient ρ_f g, felt by the solids as
    /// buoyancy (the solids take their own weight from their system).
    pub gravity: [f64; 3],
    /// Cap on a face's solid fraction.
    pub max_solid_fraction: f64,
    /// Viscous diffusion of the fluid (implicit, [`Diffusion`]) after advection, with
    /// ν = μ/ρ from `fluid`. Off by default: for water and air at hair and cloth scales it
    /// changes a step by hν/Δx² ≈ 10⁻⁷ of the velocity's curvature.
    pub viscosity: bool,
    /// The most the drag samples may take [bytes] ([`CoupledError::TooManySamples`]);
    /// `None`: no limit.
    pub max_bytes: Option<u64>,
}

impl Default for CoupledSettings {
    fn default() -> Self {
        CoupledSettings {
            method: Coupling::Newton,
            tolerance: 1e-6,
            max_iterations: 30,
            relaxation: RelaxationMethod::Aitken,
            solid: Settings::default(),
            pressure: PressureSolve::default(),
            fluid: FluidProperties::WATER,
            gravity: [0.0; 3],
            max_solid_fraction: 0.9,
            viscosity: false,
            max_bytes: None,
        }
    }
}

/// The viscous diffusion's CG: converged to 1e-12 m/s (its matrix is the identity plus
/// hν/Δx² times a Laplacian, so this takes a few iterations for water and air).
const VISCOUS_SOLVE: PressureSolve = PressureSolve {
    tolerance: 1e-12,
    max_iterations: 1000,
};

/// What the predict stage did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Predicted {
    /// CG iterations of the one-way projection (0 for the other methods).
    pub projection_iterations: usize,
    /// CG iterations of the viscous diffusion, all three components (0 when off).
    pub viscosity_iterations: usize,
}

/// Why a coupled step failed; the states are left as they were.
#[derive(Debug, thiserror::Error)]
pub enum CoupledError {
    /// The solid solve failed.
    #[error("solid solve at coupling iteration {iteration}: {source}")]
    Solid {
        /// Coupling iteration.
        iteration: usize,
        /// The solver's error.
        source: StepError,
    },
    /// The pressure solve failed.
    #[error("pressure solve at coupling iteration {iteration}: {source}")]
    Pressure {
        /// Coupling iteration.
        iteration: usize,
        /// The solver's error.
        source: weft_fluid::ProjectionError,
    },
    /// The viscous diffusion failed.
    #[error("viscous diffusion: {0}")]
    Viscosity(weft_fluid::ProjectionError),
    /// A coupling iterate became non-finite (the iterations diverged).
    #[error(
        "the coupling iterate became non-finite at coupling iteration {iteration} (the iterations diverged: reduce the step; staggered coupling diverges where newton holds)"
    )]
    NonFinite {
        /// Coupling iteration.
        iteration: usize,
    },
    /// Newton coupling hit its iteration limit.
    #[error(
        "coupling did not converge in {iterations} iterations (velocity change {residual:e} m/s, tolerance {tolerance:e})"
    )]
    NotConverged {
        /// Iterations done.
        iterations: usize,
        /// Last change.
        residual: f64,
        /// Tolerance asked for.
        tolerance: f64,
    },
    /// A drag element's parameters are out of range.
    #[error(transparent)]
    Parameters(#[from] weft_fluid::FluidError),
    /// The drag elements would make more samples than memory holds (elements much larger
    /// than the cells); nothing was allocated.
    ///
    /// A 4 km flag in 2 cm cells.
    #[error(
        "the drag elements make {samples} samples at this cell size ({dx} m), needing about {need_gib:.1} GiB, more than the {limit_gib:.1} GiB available; use larger cells (the fluid domain's cell_size) or smaller elements"
    )]
    TooManySamples {
        /// Samples the lattices would make.
        samples: u64,
        /// Cell size [m].
        dx: f64,
        /// Estimated need [GiB].
        need_gib: f64,
        /// The limit [GiB].
        limit_gib: f64,
    },
}

/// Bytes a drag sample costs over a coupling iteration: its point, its sample, its lift and
/// the rasterizer's copy.
const SAMPLE_BYTES: u64 = 256;

impl CoupledError {
    /// True when a stop check ([`CoupledStepper::set_stop`]) ended the step, not a failure.
    pub fn is_interrupted(&self) -> bool {
        matches!(
            self,
            CoupledError::Solid {
                source: StepError::Interrupted { .. },
                ..
            } | CoupledError::Pressure {
                source: weft_fluid::ProjectionError::Interrupted { .. },
                ..
            } | CoupledError::Viscosity(weft_fluid::ProjectionError::Interrupted { .. })
        )
    }
}

/// A sample of a drag element: which vertices it interpolates, with what weights, its
/// volume, and its element.
#[derive(Clone, Copy, Debug)]
struct Point {
    verts: [u32; 3],
    weights: [f64; 3],
    volume: f64,
    element: u32,
}

/// What solids and fluid exchange in one coupling iteration, gathered at the solid and fluid
/// iterates: the samples (with their drag diagonals, to be rasterized), the linear drag
/// −D(v − u) per vertex, and the explicit fluid forces per vertex (pressure −V∇p and lift).
#[derive(Clone, Debug, Default)]
pub struct Exchange {
    points: Vec<Point>,
    /// One per sample; velocities are filled when rasterizing.
    pub samples: Vec<Sample>,
    /// Linear drag per vertex (D in `matrix`, the flow velocity in `flow`).
    pub drag: Vec<VertexDrag>,
    /// Explicit force per vertex [N]: pressure (buoyancy) and lift.
    pub forces: Vec<Vector3<f64>>,
    /// Lift on each sample [N]; the fluid takes the reaction.
    lift: Vec<[f64; 3]>,
    /// Samples outside the fluid domain (they feel the nearest fluid and give nothing back).
    pub outside: usize,
}

/// The coupled stepper's reusable parts (built on first use, or by [`CoupledStepper::new`]):
/// the solid integrator (its pattern and symbolic
/// factorization), the pressure projection (its matrix pattern and preconditioner), and
/// scratch buffers. The stages are public; the loop that runs them is the graph's
/// (`solver.coupled`, an iterating composite of stage nodes in weft-nodes), the only one.
#[derive(Default)]
pub struct CoupledStepper {
    integrator: Option<Integrator>,
    projection: Option<Projection>,
    advect_scratch: Option<MacGrid>,
    diffusion: Option<Diffusion>,
    /// Faces inside kinematic obstacles for the coming step ([`Self::set_obstacles`]).
    obstacles: Vec<SolidFace>,
    /// The pressure gradient on the faces (sampled like a velocity).
    gradient: Option<MacGrid>,
    samples: Vec<Sample>,
    stop: Option<weft_solid::StopCheck>,
    progress: Option<std::sync::Arc<weft_solid::Progress>>,
}

impl CoupledStepper {
    /// Sets (or clears) the check the solid and pressure solvers ask once per iteration;
    /// when it answers true the stage fails with an error for which
    /// [`CoupledError::is_interrupted`] holds.
    pub fn set_stop(&mut self, stop: Option<weft_solid::StopCheck>) {
        if let Some(i) = &mut self.integrator {
            i.set_stop(stop.clone());
        }
        if let Some(p) = &mut self.projection {
            p.set_stop(stop.clone());
        }
        if let Some(d) = &mut self.diffusion {
            d.set_stop(stop.clone());
        }
        self.stop = stop;
    }

    /// Sets (or clears) where the solid solve stores its progress for a progress line.
    pub fn set_progress(&mut self, progress: Option<std::sync::Arc<weft_solid::Progress>>) {
        if let Some(i) = &mut self.integrator {
            i.set_progress(progress.clone());
        }
        self.progress = progress;
    }

    /// Builds the solver structures for a solid system and a fluid domain.
    pub fn new(sys: &SolidSystem, grid: &MacGrid) -> Result<Self, StepError> {
        Ok(CoupledStepper {
            integrator: Some(Integrator::new(sys)?),
            projection: Some(Projection::new(grid)),
            advect_scratch: None,
            diffusion: None,
            obstacles: Vec::new(),
            gradient: None,
            samples: Vec::new(),
            stop: None,
            progress: None,
        })
    }

    /// Sets the faces inside kinematic obstacles (colliders) for the coming steps
    /// ([`crate::FluidSpec::obstacles`]); [`Self::predict`] carves them into u*, and every
    /// later stage keeps them.
    pub fn set_obstacles(&mut self, faces: &[SolidFace]) {
        self.obstacles.clear();
        self.obstacles.extend_from_slice(faces);
    }

    /// **Predict** the fluid: `out` becomes `grid` advected over `h` (u*; gravity is in the
    /// hydrostatic pressure, see the module doc), then diffused when `settings.viscosity`;
    /// the solids' imprint is cleared and the obstacles are carved in. For
    /// [`Coupling::OneWay`] it is then projected as if no hair or cloth were there, and is
    /// the fluid the solids see.
    pub fn predict(
        &mut self,
        grid: &MacGrid,
        h: f64,
        settings: &CoupledSettings,
        out: &mut MacGrid,
    ) -> Result<Predicted, CoupledError> {
        let mut done = Predicted::default();
        out.copy_from(grid);
        advect_velocity(out, h, &mut self.advect_scratch);
        out.apply_boundaries();
        if settings.viscosity {
            let diffusion = match &mut self.diffusion {
                Some(d) if d.fits(out) => d,
                slot => {
                    let mut d = Diffusion::new(out);
                    d.set_stop(self.stop.clone());
                    slot.insert(d)
                }
            };
            let nu = settings.fluid.viscosity / settings.fluid.density;
            let s = diffusion
                .diffuse(out, nu, h, &VISCOUS_SOLVE)
                .map_err(CoupledError::Viscosity)?;
            done.viscosity_iterations = s.iterations;
        }
        for a in 0..3 {
            out.alpha[a].iter_mut().for_each(|x| *x = 1.0);
            out.drag[a].iter_mut().for_each(|x| *x = 0.0);
            out.solid_vel[a].iter_mut().for_each(|x| *x = 0.0);
        }
        carve(out, &self.obstacles);
        if settings.method != Coupling::OneWay {
            return Ok(done);
        }
        done.projection_iterations = self.pressure(out, h, settings, 0)?.iterations;
        Ok(done)
    }

    /// **Forces** (stage B): samples every drag element at positions `x` on the lattices
    /// rasterization uses ([`segment_lattice`], [`triangle_lattice`]). The lattices (sample
    /// counts, weights and volumes) come from the step's start positions `x0`, so that they do
    /// not jump between coupling iterations when an element's size crosses a lattice step (a
    /// discontinuous fixed-point map can cycle instead of converging; measured on the
    /// flag_wind example, a 5-iteration cycle). Per sample, the drag
    /// diagonal at the relative speed against the fluid `seen`, its velocity, pressure
    /// gradient and lift, all interpolated with the trilinear weights rasterization uses;
    /// lumped to vertices as linear drag and explicit forces.
    #[allow(clippy::too_many_arguments)]
    pub fn forces(
        &mut self,
        elements: &[DragElement],
        x0: &[Vector3<f64>],
        x: &[Vector3<f64>],
        v: &[Vector3<f64>],
        seen: &MacGrid,
        settings: &CoupledSettings,
        out: &mut Exchange,
    ) -> Result<(), CoupledError> {
        let dx = seen.domain.dx;
        let mu = settings.fluid.viscosity;
        if let Some(limit) = settings.max_bytes {
            let samples = sample_count(elements, x0, dx);
            let need = samples.saturating_mul(SAMPLE_BYTES);
            // Only the growth counts: last step's samples are reused in place.
            let have = (out.points.capacity() as u64).saturating_mul(SAMPLE_BYTES);
            if need > limit.saturating_add(have) {
                const GIB: f64 = (1u64 << 30) as f64;
                return Err(CoupledError::TooManySamples {
                    samples,
                    dx,
                    need_gib: need as f64 / GIB,
                    limit_gib: limit as f64 / GIB,
                });
            }
        }
        sample_points(elements, x0, dx, &mut out.points);
        let grad = self
            .gradient
            .get_or_insert_with(|| MacGrid::new(seen.domain.clone()));
        if grad.domain != seen.domain {
            *grad = MacGrid::new(seen.domain.clone());
        }
        pressure_gradient(seen, grad);
        let n = x.len();
        // Accumulated in place: D in `drag.matrix`, D·u in `drag.flow` (divided below).
        out.drag.clear();
        out.drag.resize(n, VertexDrag::default());
        out.forces.clear();
        out.forces.resize(n, Vector3::zeros());
        out.samples.clear();
        out.lift.clear();
        out.outside = 0;
        let g = Vector3::from(settings.gravity);
        for pt in &out.points {
            let e = &elements[pt.element as usize];
            let pos: Vector3<f64> = (0..3)
                .map(|j| pt.weights[j] * x[pt.verts[j] as usize])
                .sum();
            let vel: Vector3<f64> = (0..3)
                .map(|j| pt.weights[j] * v[pt.verts[j] as usize])
                .sum();
            let p = [pos.x, pos.y, pos.z];
            if !seen.domain.contains(p) {
                out.outside += 1;
            }
            let u = Vector3::from(seen.velocity_at(p));
            let gp = Vector3::from(grad.velocity_at(p));
            let dv = vel - u;
            let (k, axis) = drag_diagonal(e, x, &settings.fluid, mu, dv.norm());
            let lift = if e.params.xi_l > 0.0 {
                let f_drag = [0, 1, 2].map(|a| -pt.volume * k[a] * dv[a]);
                lift_force(e.params.xi_l, axis.into(), f_drag, dv.into())
            } else {
                [0.0; 3]
            };
            // Pressure: the dynamic part −V∇p from the grid, the hydrostatic part −ρ_f V g.
            let f = -pt.volume * (gp + settings.fluid.density * g) + Vector3::from(lift);
            for j in 0..3 {
                let (w, vi) = (pt.weights[j], pt.verts[j] as usize);
                if w == 0.0 {
                    continue;
                }
                for a in 0..3 {
                    out.drag[vi].matrix[(a, a)] += w * pt.volume * k[a];
                    out.drag[vi].flow[a] += w * pt.volume * k[a] * u[a];
                }
                out.forces[vi] += w * f;
            }
            out.samples.push(Sample {
                position: p,
                velocity: [0.0; 3], // filled when rasterizing
                volume: pt.volume,
                drag: k,
            });
            out.lift.push(lift);
        }
        for d in &mut out.drag {
            for a in 0..3 {
                let m = d.matrix[(a, a)];
                d.flow[a] = if m > 0.0 { d.flow[a] / m } else { 0.0 };
            }
        }
        Ok(())
    }

    /// **Solid** (stage C, with 2 and A): one implicit step of `h` from `start` with the exchange's
    /// drag and forces (written into `sys`), attached vertices at `targets`. Newton starts
    /// from `guess` when given (the last coupling iterate's positions: the forces change
    /// little between iterations, so it is close), else from x⁰ + h v⁰. With `contacts` (the
    /// scene's contact machinery, its `frame` already set, and the stats to add to), the step
    /// is the hard-contact solve `solver.solid` uses, with the same detection and checks.
    #[allow(clippy::too_many_arguments)]
    pub fn solid(
        &mut self,
        sys: &mut SolidSystem,
        exchange: &Exchange,
        start: &State,
        guess: Option<&[Vector3<f64>]>,
        targets: Option<&[Vector3<f64>]>,
        h: f64,
        settings: &CoupledSettings,
        iteration: usize,
        contacts: Option<(&mut Contacts, &mut ContactFrameStats)>,
        out: &mut State,
    ) -> Result<StepStats, CoupledError> {
        sys.drag.clone_from(&exchange.drag);
        sys.forces.clone_from(&exchange.forces);
        out.x.clone_from(&start.x);
        out.v.clone_from(&start.v);
        let fail = |source| CoupledError::Solid { iteration, source };
        let integrator = match &mut self.integrator {
            Some(i) => {
                // What the process may take now, not when the integrator was built.
                if let Some(a) = settings.max_bytes {
                    i.set_available(a);
                }
                i
            }
            None => {
                let mut i = Integrator::new_within(sys, settings.max_bytes).map_err(fail)?;
                i.set_stop(self.stop.clone());
                i.set_progress(self.progress.clone());
                self.integrator.insert(i)
            }
        };
        let contacts = contacts.map(|(c, stats)| {
            if let Some(a) = settings.max_bytes {
                c.set_available(a);
            }
            (c, stats)
        });
        match contacts {
            Some((c, stats)) => c
                .step(
                    integrator,
                    sys,
                    out,
                    targets,
                    guess,
                    (0.0, 1.0, h),
                    &settings.solid,
                    // A coupling iteration is not retried smaller: cut back instead.
                    true,
                    stats,
                )
                .map_err(fail),
            None => integrator
                .step_from(sys, out, guess, targets, h, &settings.solid)
                .map_err(fail),
        }
    }

    /// **Rasterize** (stage D): `out` becomes the predicted fluid `u_star` with the
    /// exchange's samples, moving with the solid velocities `v`, rasterized into solid
    /// fractions, drag and solid velocities, and the lift's reaction added.
    pub fn rasterize(
        &mut self,
        exchange: &Exchange,
        v: &[Vector3<f64>],
        u_star: &MacGrid,
        h: f64,
        settings: &CoupledSettings,
        out: &mut MacGrid,
    ) -> RasterStats {
        out.copy_from(u_star);
        self.samples.clone_from(&exchange.samples);
        for (s, pt) in self.samples.iter_mut().zip(&exchange.points) {
            let w: Vector3<f64> = (0..3)
                .map(|j| pt.weights[j] * v[pt.verts[j] as usize])
                .sum();
            s.velocity = [w.x, w.y, w.z];
        }
        let stats = rasterize(out, &self.samples, settings.max_solid_fraction);
        for (s, l) in self.samples.iter().zip(&exchange.lift) {
            if l.iter().any(|c| *c != 0.0) {
                add_impulse(out, s.position, l.map(|c| -c * h), settings.fluid.density);
            }
        }
        stats
    }

    /// **Pressure** (stages E/F): projects `fluid` (u* with the solids rasterized)
    /// onto the mixture's divergence-free fields; velocities and pressure are updated.
    pub fn pressure(
        &mut self,
        fluid: &mut MacGrid,
        h: f64,
        settings: &CoupledSettings,
        iteration: usize,
    ) -> Result<PressureStats, CoupledError> {
        let projection = match &mut self.projection {
            Some(p) if p.unknowns() == fluid.domain.cell_count() => p,
            _ => {
                let mut p = Projection::new(fluid);
                p.set_stop(self.stop.clone());
                self.projection.insert(p)
            }
        };
        projection
            .project(fluid, settings.fluid.density, h, &settings.pressure)
            .map_err(|source| CoupledError::Pressure { iteration, source })
    }
}

/// The solids' volume as the drag samples carry it [m³] at positions `x`: Σ area × length
/// over segments and area × thickness over triangles (what buoyancy −ρ V g acts on).
pub fn solid_volume(elements: &[DragElement], x: &[Vector3<f64>]) -> f64 {
    elements
        .iter()
        .map(|e| match e.shape {
            DragShape::Segment([a, b], area) => area * (x[b as usize] - x[a as usize]).norm(),
            DragShape::Triangle([a, b, c], thickness) => {
                let (pa, pb, pc) = (x[a as usize], x[b as usize], x[c as usize]);
                0.5 * (pb - pa).cross(&(pc - pa)).norm() * thickness
            }
        })
        .sum()
}

/// How many points [`sample_points`] makes, without making them (saturating).
fn sample_count(elements: &[DragElement], x: &[Vector3<f64>], dx: f64) -> u64 {
    let mut total = 0u64;
    for e in elements {
        let n = match e.shape {
            DragShape::Segment([a, b], _) => {
                segment_samples((x[b as usize] - x[a as usize]).norm(), dx)
            }
            DragShape::Triangle([a, b, c], _) => {
                let (pa, pb, pc) = (x[a as usize], x[b as usize], x[c as usize]);
                let longest = (pb - pa).norm().max((pc - pb).norm()).max((pa - pc).norm());
                triangle_samples(longest, dx)
            }
        };
        total = total.saturating_add(n as u64);
    }
    total
}

/// Samples every element at positions `x` on the lattices rasterization uses, keeping each
/// sample's vertex weights.
fn sample_points(elements: &[DragElement], x: &[Vector3<f64>], dx: f64, out: &mut Vec<Point>) {
    out.clear();
    for (ei, e) in elements.iter().enumerate() {
        match e.shape {
            DragShape::Segment([a, b], area) => {
                let len = (x[b as usize] - x[a as usize]).norm();
                let (n, lattice) = segment_lattice(len, dx);
                for [wa, wb] in lattice {
                    out.push(Point {
                        verts: [a, b, b],
                        weights: [wa, wb, 0.0],
                        volume: area * len / n as f64,
                        element: ei as u32,
                    });
                }
            }
            DragShape::Triangle([a, b, c], thickness) => {
                let (pa, pb, pc) = (x[a as usize], x[b as usize], x[c as usize]);
                let area = 0.5 * (pb - pa).cross(&(pc - pa)).norm();
                let longest = (pb - pa).norm().max((pc - pb).norm()).max((pa - pc).norm());
                let (count, lattice) = triangle_lattice(longest, dx);
                for weights in lattice {
                    out.push(Point {
                        verts: [a, b, c],
                        weights,
                        volume: area * thickness / count as f64,
                        element: ei as u32,
                    });
                }
            }
        }
    }
}

/// The drag tensor's diagonal per unit solid volume, k = (μ/D²) R C Rᵀ, for element `e` at
/// relative speed `speed` (eq. 1–3 of the seed).
fn drag_diagonal(
    e: &DragElement,
    x: &[Vector3<f64>],
    fluid: &FluidProperties,
    mu: f64,
    speed: f64,
) -> ([f64; 3], Vector3<f64>) {
    let p = &e.params;
    let (cp, _) = p.coefficient(fluid, p.inverse_permeability(p.xi_perp), speed);
    let (cq, _) = p.coefficient(fluid, p.inverse_permeability(p.xi_par), speed);
    let (axis, c_axis, c_other) = match e.shape {
        DragShape::Segment([a, b], _) => ((x[b as usize] - x[a as usize]).normalize(), cq, cp),
        DragShape::Triangle([a, b, c], _) => {
            let (pa, pb, pc) = (x[a as usize], x[b as usize], x[c as usize]);
            ((pb - pa).cross(&(pc - pa)).normalize(), cp, cq)
        }
    };
    let s = mu / (p.diameter * p.diameter);
    let k =
        [0, 1, 2].map(|a| s * (c_axis * axis[a] * axis[a] + c_other * (1.0 - axis[a] * axis[a])));
    (k, axis)
}

/// Fills `out`'s face velocities with the pressure gradient (p_plus − p_minus)/Δx of `grid`
/// (zero on boundary faces without a neighbour), so that it can be sampled like a velocity.
fn pressure_gradient(grid: &MacGrid, out: &mut MacGrid) {
    let dom = &grid.domain;
    for a in 0..3 {
        let d = dom.face_dims(a);
        let na = dom.cells[a];
        for k in 0..d[2] {
            for j in 0..d[1] {
                for i in 0..d[0] {
                    let idx = [i, j, k];
                    let m = idx[a];
                    let cell = |along: usize| {
                        let mut c = idx;
                        c[a] = along;
                        grid.pressure[dom.cell(c[0], c[1], c[2])]
                    };
                    let val = if grid.alpha[a][dom.face(a, i, j, k)] == 0.0 {
                        0.0 // inside an obstacle: no fluid, no pressure force
                    } else if m > 0 && m < na {
                        (cell(m) - cell(m - 1)) / dom.dx
                    } else if dom.boundaries.is_periodic(a) {
                        (cell(0) - cell(na - 1)) / dom.dx
                    } else {
                        0.0
                    };
                    out.vel[a][dom.face(a, i, j, k)] = val;
                }
            }
        }
    }
}

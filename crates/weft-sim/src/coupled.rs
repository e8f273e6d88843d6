//! Two-way coupling of solids with the Eulerian fluid (DESIGN §6): one time step.
//!
//! (1) Predict the fluid: advect, add gravity → u*. (2) Newton iterations k:
//! **A/B** sample every drag element at the current solid iterate; per sample, the drag
//! tensor's diagonal k (per unit solid volume, from the seed's law at the current relative
//! speed), the fluid velocity u^k and pressure gradient ∇p^k interpolated with the same
//! trilinear weights the rasterization uses; lump them to vertices as a linear drag
//! −D(v − u) and a pressure (buoyancy) force −V∇p. **C** implicit solid solve → v^{k+1}.
//! **D** rasterize the samples (volume, drag, solid velocity v^{k+1}) onto the faces. **E/F**
//! porous pressure solve from u* with the solid prescribed → u^{k+1}, p^{k+1}. **G** stop
//! when neither velocity changed by more than the tolerance. Methods: `Newton` iterates to
//! tolerance, `Staggered` makes one pass, `OneWay` projects the fluid without solids and
//! lets it drive them.
//!
//! Momentum: the fluid loses Σ_f K(u − v)dx³ + Σ_f α∇p dx³ and the solids gain
//! Σ_s V k(u_s − v_s) − Σ_s V (∇p)_s; with the same interpolation weights on both sides
//! (and on a periodic domain, where Σ_f ∇p = 0) these cancel exactly once the iterations have
//! converged, so total momentum is conserved to the coupling tolerance. That is why only the
//! drag tensor's diagonal is used on both sides: the grid holds one coefficient per face.

use nalgebra::Vector3;
use std::time::Instant;
use weft_fluid::advect::advect_velocity;
use weft_fluid::raster::{Sample, rasterize, segment_lattice, triangle_lattice};
use weft_fluid::{DragParams, FluidProperties, MacGrid, PressureSolve, Projection};
use weft_solid::{Integrator, Settings, SolidSystem, State, StepError, VertexDrag};

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
    pub params: DragParams,
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

/// Coupled step settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoupledSettings {
    /// Coupling method.
    pub method: Coupling,
    /// Newton stops when solid and fluid velocities change by less than this [m/s].
    pub tolerance: f64,
    /// Newton iteration limit.
    pub max_iterations: usize,
    /// The solid solve.
    pub solid: Settings,
    /// The pressure solve.
    pub pressure: PressureSolve,
    /// The fluid.
    pub fluid: FluidProperties,
    /// Gravity on the fluid [m/s²] (the solids take theirs from their system).
    pub gravity: [f64; 3],
    /// Cap on a face's solid fraction.
    pub max_solid_fraction: f64,
}

impl Default for CoupledSettings {
    fn default() -> Self {
        CoupledSettings {
            method: Coupling::Newton,
            tolerance: 1e-6,
            max_iterations: 30,
            solid: Settings::default(),
            pressure: PressureSolve::default(),
            fluid: FluidProperties::WATER,
            gravity: [0.0; 3],
            max_solid_fraction: 0.9,
        }
    }
}

/// What a coupled step did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CoupledStats {
    /// Coupling iterations.
    pub iterations: usize,
    /// Per iteration: largest change of solid and of fluid velocity [m/s].
    pub residuals: Vec<[f64; 2]>,
    /// Whether the tolerance was met (always for one-way and staggered).
    pub converged: bool,
    /// Newton iterations of the solid solves, summed.
    pub solid_iterations: usize,
    /// CG iterations of the pressure solves, summed.
    pub pressure_iterations: usize,
    /// Seconds per stage: advection, sampling, solid solve, rasterization, pressure.
    pub seconds: [f64; 5],
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
}

/// A sample of a drag element: where it is, which vertices it interpolates, its volume and
/// the drag diagonal per unit volume.
#[derive(Clone, Copy, Debug)]
struct Point {
    verts: [u32; 3],
    weights: [f64; 3],
    volume: f64,
    element: u32,
}

/// The coupled stepper's reusable parts.
pub struct CoupledStepper {
    integrator: Integrator,
    projection: Projection,
    advect_scratch: Option<MacGrid>,
    /// The pressure gradient on the faces (sampled like a velocity).
    gradient: Option<MacGrid>,
    points: Vec<Point>,
    samples: Vec<Sample>,
}

impl CoupledStepper {
    /// Builds the solver structures for a solid system and a fluid domain.
    pub fn new(sys: &SolidSystem, grid: &MacGrid) -> Result<Self, StepError> {
        Ok(CoupledStepper {
            integrator: Integrator::new(sys)?,
            projection: Projection::new(grid),
            advect_scratch: None,
            gradient: None,
            points: Vec::new(),
            samples: Vec::new(),
        })
    }

    /// Samples every element at positions `x` on the lattices rasterization uses
    /// ([`segment_lattice`], [`triangle_lattice`]), keeping each sample's vertex weights.
    fn sample_points(&mut self, elements: &[DragElement], x: &[Vector3<f64>], dx: f64) {
        self.points.clear();
        for (ei, e) in elements.iter().enumerate() {
            match e.shape {
                DragShape::Segment([a, b], area) => {
                    let len = (x[b as usize] - x[a as usize]).norm();
                    let (n, lattice) = segment_lattice(len, dx);
                    for [wa, wb] in lattice {
                        self.points.push(Point {
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
                        self.points.push(Point {
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

    /// One coupled step of `h` seconds. `sys` is the solid system (its `drag` and `forces`
    /// are overwritten with the fluid's); on error `state` and `grid` are unchanged.
    pub fn step(
        &mut self,
        sys: &mut SolidSystem,
        elements: &[DragElement],
        state: &mut State,
        grid: &mut MacGrid,
        h: f64,
        settings: &CoupledSettings,
    ) -> Result<CoupledStats, CoupledError> {
        for e in elements {
            e.params.validate()?;
        }
        let mut stats = CoupledStats::default();
        let n = state.x.len();
        let dx = grid.domain.dx;
        let rho = settings.fluid.density;
        let mu = settings.fluid.viscosity;
        // (1) Fluid predictor u*.
        let t = Instant::now();
        let mut fluid = grid.clone();
        advect_velocity(&mut fluid, h, &mut self.advect_scratch);
        fluid.accelerate(settings.gravity, h);
        let u_star = fluid.vel.clone();
        stats.seconds[0] += t.elapsed().as_secs_f64();
        if settings.method == Coupling::OneWay {
            // The fluid as if no solid were there; then the solids in it.
            for a in 0..3 {
                fluid.alpha[a].iter_mut().for_each(|x| *x = 1.0);
                fluid.drag[a].iter_mut().for_each(|x| *x = 0.0);
            }
            let t = Instant::now();
            let ps = self
                .projection
                .project(&mut fluid, rho, h, &settings.pressure)
                .map_err(|source| CoupledError::Pressure {
                    iteration: 0,
                    source,
                })?;
            stats.pressure_iterations += ps.iterations;
            stats.seconds[4] += t.elapsed().as_secs_f64();
        }
        let mut solid = state.clone();
        let (mut v_prev, mut u_prev) = (state.v.clone(), fluid.vel.clone());
        let mut omega = 0.5;
        let mut r_prev: Option<Vec<Vector3<f64>>> = None;
        let max_it = match settings.method {
            Coupling::Newton => settings.max_iterations.max(1),
            _ => 1,
        };
        for it in 0..max_it {
            // A/B: drag and pressure forces from the fluid iterate, at the solid iterate.
            let t = Instant::now();
            let xk = if it == 0 { &state.x } else { &solid.x };
            self.sample_points(elements, xk, dx);
            let grad = self
                .gradient
                .get_or_insert_with(|| MacGrid::new(fluid.domain.clone()));
            // The first iteration sees the fluid as the last step left it (divergence-free,
            // with its pressure); later ones the latest projection. Not u*: it still holds
            // this step's gravity, which the pressure has yet to balance.
            let seen = if it == 0 && settings.method != Coupling::OneWay {
                &*grid
            } else {
                &fluid
            };
            pressure_gradient(seen, grad);
            // Accumulated in place: D in `drag.matrix`, D·u in `drag.flow` (divided below),
            // the pressure force in `forces` (no allocation after the first step).
            sys.drag.clear();
            sys.drag.resize(n, VertexDrag::default());
            sys.forces.clear();
            sys.forces.resize(n, Vector3::zeros());
            let vk = if it == 0 { &state.v } else { &solid.v };
            self.samples.clear();
            for pt in &self.points {
                let e = &elements[pt.element as usize];
                let pos: Vector3<f64> = (0..3)
                    .map(|j| pt.weights[j] * xk[pt.verts[j] as usize])
                    .sum();
                let vel: Vector3<f64> = (0..3)
                    .map(|j| pt.weights[j] * vk[pt.verts[j] as usize])
                    .sum();
                let p = [pos.x, pos.y, pos.z];
                let u = Vector3::from(seen.velocity_at(p));
                let gp = Vector3::from(grad.velocity_at(p));
                let k = drag_diagonal(e, xk, &settings.fluid, mu, (vel - u).norm());
                for j in 0..3 {
                    let (w, vi) = (pt.weights[j], pt.verts[j] as usize);
                    if w == 0.0 {
                        continue;
                    }
                    for a in 0..3 {
                        sys.drag[vi].matrix[(a, a)] += w * pt.volume * k[a];
                        sys.drag[vi].flow[a] += w * pt.volume * k[a] * u[a];
                    }
                    if settings.method != Coupling::OneWay {
                        sys.forces[vi] -= w * pt.volume * gp;
                    }
                }
                self.samples.push(Sample {
                    position: p,
                    velocity: [0.0; 3], // filled after the solid solve
                    volume: pt.volume,
                    drag: k,
                });
            }
            for d in &mut sys.drag {
                for a in 0..3 {
                    let m = d.matrix[(a, a)];
                    d.flow[a] = if m > 0.0 { d.flow[a] / m } else { 0.0 };
                }
            }
            stats.seconds[1] += t.elapsed().as_secs_f64();
            // C: implicit solid solve from the step's start.
            let t = Instant::now();
            let mut next = state.clone();
            let ss = self
                .integrator
                .step(sys, &mut next, None, h, &settings.solid)
                .map_err(|source| CoupledError::Solid {
                    iteration: it,
                    source,
                })?;
            stats.solid_iterations += ss.iterations;
            stats.seconds[2] += t.elapsed().as_secs_f64();
            stats.iterations = it + 1;
            let dv = next
                .v
                .iter()
                .zip(&v_prev)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).amax()));
            if settings.method == Coupling::Newton && it > 0 {
                // Aitken Δ² relaxation of the solid velocity (Irons & Tuck 1969; Küttler &
                // Wall 2008): the plain fixed point diverges when the fluid around a light
                // solid is heavier than it (the added-mass effect: the pressure's reply to the
                // solid's motion is lagged), so the update is scaled by ω, re-estimated from
                // the last two residuals r = ṽ − v.
                let r: Vec<Vector3<f64>> =
                    next.v.iter().zip(&solid.v).map(|(a, b)| a - b).collect();
                if let Some(rp) = &r_prev {
                    let (mut num, mut den) = (0.0, 0.0);
                    for (a, b) in r.iter().zip(rp) {
                        let d = a - b;
                        num += b.dot(&d);
                        den += d.dot(&d);
                    }
                    if den > 0.0 {
                        omega = (-omega * num / den).clamp(1e-4, 1.0);
                    }
                }
                for (i, ri) in r.iter().enumerate() {
                    next.v[i] = solid.v[i] + omega * ri;
                    next.x[i] = state.x[i] + h * next.v[i];
                }
                r_prev = Some(r);
            }
            solid = next;
            if settings.method == Coupling::OneWay {
                stats.residuals.push([dv, 0.0]);
                stats.converged = true;
                break;
            }
            // D: rasterize with the new solid velocities.
            let t = Instant::now();
            for (s, pt) in self.samples.iter_mut().zip(&self.points) {
                let v: Vector3<f64> = (0..3)
                    .map(|j| pt.weights[j] * solid.v[pt.verts[j] as usize])
                    .sum();
                s.velocity = [v.x, v.y, v.z];
            }
            rasterize(&mut fluid, &self.samples, settings.max_solid_fraction);
            stats.seconds[3] += t.elapsed().as_secs_f64();
            // E/F: pressure solve from u* with the solid prescribed.
            let t = Instant::now();
            fluid.vel.clone_from(&u_star);
            let ps = self
                .projection
                .project(&mut fluid, rho, h, &settings.pressure)
                .map_err(|source| CoupledError::Pressure {
                    iteration: it,
                    source,
                })?;
            stats.pressure_iterations += ps.iterations;
            stats.seconds[4] += t.elapsed().as_secs_f64();
            let du = fluid
                .vel
                .iter()
                .zip(&u_prev)
                .flat_map(|(a, b)| a.iter().zip(b))
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            stats.residuals.push([dv, du]);
            // G: convergence.
            if settings.method == Coupling::Staggered || (it > 0 && dv.max(du) < settings.tolerance)
            {
                stats.converged = true;
                break;
            }
            v_prev.clone_from(&solid.v);
            u_prev.clone_from(&fluid.vel);
        }
        if !stats.converged {
            let last = stats.residuals.last().copied().unwrap_or([f64::NAN; 2]);
            return Err(CoupledError::NotConverged {
                iterations: stats.iterations,
                residual: last[0].max(last[1]),
                tolerance: settings.tolerance,
            });
        }
        *state = solid;
        *grid = fluid;
        Ok(stats)
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
) -> [f64; 3] {
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
    [0, 1, 2].map(|a| s * (c_axis * axis[a] * axis[a] + c_other * (1.0 - axis[a] * axis[a])))
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
                    let val = if m > 0 && m < na {
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

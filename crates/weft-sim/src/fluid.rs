//! The fluid a scene asks for: its domain element's Fluid Domain and Fluid SECs turned into a
//! discretized domain, fluid properties and the current or wind. A scene without a domain
//! element has no fluid, and nothing is allocated for one.

use crate::error::SimError;
use nalgebra::Point3;
use nalgebra::Vector3;
use weft_fluid::obstacle::faces_inside_mesh;
use weft_fluid::{Boundaries, Boundary, Domain, FluidError, FluidProperties, MacGrid, SolidFace};
use weft_scene::{DomainSide, ElementKind, Fluid, FluidDomain, Geometry, SceneElement, Transform};

/// A scene's fluid, before its grid is allocated.
#[derive(Clone, Debug, PartialEq)]
pub struct FluidSpec {
    /// Name of the domain element.
    pub element: String,
    /// The discretized domain.
    pub domain: Domain,
    /// Density and viscosity.
    pub properties: FluidProperties,
    /// The current or wind [m/s]: the initial velocity and the inflow sides' velocity.
    pub flow: [f64; 3],
    /// Scene indices of the colliders: obstacles in the fluid (their closed meshes).
    pub colliders: Vec<usize>,
}

impl FluidSpec {
    /// The fluid at the start: the flow everywhere (the boundaries imposed), zero pressure.
    pub fn initial_grid(&self) -> MacGrid {
        let mut g = MacGrid::new(self.domain.clone());
        let flow = self.flow;
        g.set_velocity(|_| flow);
        g.apply_boundaries();
        g
    }

    /// The faces inside the scene's colliders at the end of a step of `h` seconds (`scene`
    /// holds them placed there), each with its collider's velocity: the rigid motion from
    /// `before` (the transforms at the step's start) to the current transform, or at rest for
    /// a collider without transforms. Cleared and refilled into `out`.
    pub fn obstacles(
        &self,
        scene: &[SceneElement],
        before: &[Option<Transform>],
        h: f64,
        out: &mut Vec<SolidFace>,
    ) {
        out.clear();
        for &c in &self.colliders {
            let Some(e) = scene.get(c) else { continue };
            let Geometry::Mesh(m) = &*e.geometry else {
                continue;
            };
            // x(t) = T(t)·X: the face at world p came from T₀T₁⁻¹p at the step's start.
            let motion = match (before.get(c).copied().flatten(), e.transform) {
                (Some(t0), Some(t1)) if h > 0.0 => Some(t0 * t1.inverse()),
                _ => None,
            };
            faces_inside_mesh(&self.domain, &m.positions, &m.triangles, |a, f, p| {
                let velocity = motion.map_or(0.0, |back| {
                    let p1 = Point3::from(p);
                    (p1 - back.transform_point(&p1))[a] / h
                });
                out.push(SolidFace {
                    axis: a as u8,
                    face: f as u32,
                    velocity,
                });
            });
        }
    }
}

fn side(s: DomainSide, flow: [f64; 3]) -> Boundary {
    match s {
        DomainSide::Wall => Boundary::Wall,
        DomainSide::Periodic => Boundary::Periodic,
        DomainSide::Inflow => Boundary::Inflow(flow),
        DomainSide::Open => Boundary::Open,
    }
}

/// Finds the scene's fluid domain (at most one) and discretizes it. Automatic bounds enclose
/// the simulated vertices `x` and every collider plus the padding. The
/// domain element's SECs are marked read through `read`.
pub(crate) fn fluid_spec(
    scene: &[SceneElement],
    x: &[Vector3<f64>],
    max_bytes: Option<u64>,
    mut read: impl FnMut(usize, &'static str),
) -> Result<Option<FluidSpec>, SimError> {
    let mut domains = scene
        .iter()
        .enumerate()
        .filter(|(_, e)| e.kind == ElementKind::FluidDomain);
    let Some((ei, e)) = domains.next() else {
        return Ok(None);
    };
    if let Some((_, other)) = domains.next() {
        return Err(SimError::BadParameter {
            element: other.name.clone(),
            field: "fluid_domain".into(),
            message: format!(
                "is a second fluid domain (the scene already has '{}'); one grid per scene",
                e.name
            ),
        });
    }
    read(ei, "fluid_domain");
    read(ei, "fluid");
    let sec = e.secs.get::<FluidDomain>().cloned().unwrap_or_default();
    let fluid = e.secs.get::<Fluid>().copied().unwrap_or_default();
    let bad = |field: &str, message: String| SimError::BadParameter {
        element: e.name.clone(),
        field: field.into(),
        message,
    };
    if !(fluid.density > 0.0 && fluid.density.is_finite()) {
        return Err(bad(
            "fluid.density",
            format!("must be > 0 kg/m³, got {}", fluid.density),
        ));
    }
    if !(fluid.viscosity > 0.0 && fluid.viscosity.is_finite()) {
        return Err(bad(
            "fluid.viscosity",
            format!("must be > 0 Pa·s, got {}", fluid.viscosity),
        ));
    }
    if !sec.flow.iter().all(|c| c.is_finite()) {
        return Err(bad(
            "fluid_domain.flow",
            format!("must be finite, got {:?}", sec.flow),
        ));
    }
    let (lo, hi) = match sec.bounds {
        Some(b) => b,
        None => {
            if !(sec.padding >= 0.0 && sec.padding.is_finite()) {
                return Err(bad(
                    "fluid_domain.padding",
                    format!("must be ≥ 0 m, got {}", sec.padding),
                ));
            }
            let mut pts: Vec<[f64; 3]> = x.iter().map(|p| [p.x, p.y, p.z]).collect();
            for c in scene.iter().filter(|c| c.kind == ElementKind::Collider) {
                // Collider positions are already placed at their transform.
                pts.extend_from_slice(c.geometry.positions());
            }
            let Some((lo, hi)) = weft_scene::bounds(&pts) else {
                return Err(bad(
                    "fluid_domain.bounds",
                    "are automatic, but the scene has no solids to enclose: give bounds".into(),
                ));
            };
            (lo.map(|c| c - sec.padding), hi.map(|c| c + sec.padding))
        }
    };
    let size = [0, 1, 2].map(|a| hi[a] - lo[a]);
    let boundaries = Boundaries {
        lo: sec.lo.map(|s| side(s, sec.flow)),
        hi: sec.hi.map(|s| side(s, sec.flow)),
    };
    let domain = Domain::new(lo, size, sec.cell_size, boundaries, max_bytes).map_err(|err| {
        let field = match err {
            FluidError::CellSize(_) | FluidError::TooLarge { .. } => "fluid_domain.cell_size",
            FluidError::Size(_) => "fluid_domain.bounds",
            _ => "fluid_domain.sides",
        };
        bad(field, err.to_string())
    })?;
    Ok(Some(FluidSpec {
        element: e.name.clone(),
        domain,
        properties: FluidProperties {
            density: fluid.density,
            viscosity: fluid.viscosity,
        },
        flow: sec.flow,
        colliders: scene
            .iter()
            .enumerate()
            .filter(|(_, c)| c.kind == ElementKind::Collider)
            .map(|(i, _)| i)
            .collect(),
    }))
}

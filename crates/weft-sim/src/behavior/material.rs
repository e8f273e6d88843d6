//! The material Behaviors: discrete-shell cloth and rod hair. Each turns its element's
//! geometry and SECs into energy terms and lumped masses (and per-vertex damping) on the
//! element's global vertices, refusing geometry the terms cannot be built on by name.

use super::Behavior;
use super::params::{checked, rest_positions, rod_section, v3};
use crate::builder::SystemBuilder;
use crate::error::SimError;
use nalgebra::Vector3;
use weft_scene::{Density, DiscreteShell, ElementKind, Geometry, Rod, SceneElement};
use weft_solid::energy::{
    ClampedEdge, Membrane, MembraneMaterial, RodBend, RodStretch, plate_bending_stiffness,
    shell_bending_clamped,
};

/// Discrete-shell cloth: StVK membrane (orthotropic by the SEC's warp/weft/shear scales) on every
/// triangle and mean-curvature bending at every vertex (`weft_solid::energy::ShellBend`:
/// D/2 (2H − 2H̄)² per area, cotangent weights, so a bend costs the plate energy on any mesh
/// and in any direction), with lumped masses from the Density SEC.
/// D = bend_scale · E t³/(12(1 − ν²)).
#[derive(Clone, Debug, Default)]
pub struct DiscreteShellMaterial;

impl Behavior for DiscreteShellMaterial {
    fn name(&self) -> &'static str {
        "discrete_shell_material"
    }
    fn reads(&self) -> &'static [&'static str] {
        &["discrete_shell", "density"]
    }
    fn apply(&self, scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        for (ei, e) in scene.iter().enumerate() {
            let (ElementKind::Cloth, Geometry::Mesh(mesh)) = (e.kind, &*e.geometry) else {
                continue;
            };
            b.read(ei, "discrete_shell");
            b.read(ei, "density");
            let shell = e.secs.get::<DiscreteShell>().cloned().unwrap_or_default();
            let density = e.secs.get::<Density>().cloned().unwrap_or_default();
            let name = e.name.as_str();
            checked(name, &shell)?;
            checked(name, &density)?;
            let rest = rest_positions(e, &shell.rest_channel)?;
            let off = b.offset(ei).expect("cloth elements have a vertex range");
            // A face listed twice (double-sided exports) would double mass and stiffness and
            // make hinges whose two wings are one vertex: refuse it by name.
            let mut seen = std::collections::HashMap::new();
            for (ti, t) in mesh.triangles.iter().enumerate() {
                let mut key = *t;
                key.sort_unstable();
                if let Some(first) = seen.insert(key, ti) {
                    return Err(SimError::BadGeometry {
                        element: name.into(),
                        message: format!(
                            "triangles {first} and {ti} use the same vertices {key:?} (a duplicated face, e.g. from a double-sided export)"
                        ),
                    });
                }
            }
            let mat = MembraneMaterial::orthotropic(
                shell.youngs_modulus,
                shell.poisson_ratio,
                shell.thickness,
                shell.warp_scale,
                shell.weft_scale,
                shell.shear_scale,
            );
            let warp = v3(shell.warp_direction);
            let n = rest.len() as u32;
            for (ti, t) in mesh.triangles.iter().enumerate() {
                if t.iter().any(|&v| v >= n) {
                    return Err(SimError::BadGeometry {
                        element: name.into(),
                        message: format!(
                            "triangle {ti} {t:?} uses a vertex beyond the {n} the element has"
                        ),
                    });
                }
                let r = [
                    v3(rest[t[0] as usize]),
                    v3(rest[t[1] as usize]),
                    v3(rest[t[2] as usize]),
                ];
                let gv = [t[0] + off, t[1] + off, t[2] + off];
                let m = Membrane::new(gv, r, warp, mat).map_err(|err| SimError::BadGeometry {
                    element: name.into(),
                    message: format!("triangle {ti} {t:?} {}", err.reason()),
                })?;
                for &v in &gv {
                    b.add_mass(v as usize, m.area * density.area_density / 3.0);
                }
                b.system.elements.membranes.push(m);
            }
            for v in 0..n {
                b.add_damping((v + off) as usize, shell.damping);
            }
            if shell.bend_scale > 0.0 {
                let d = plate_bending_stiffness(
                    shell.youngs_modulus,
                    shell.poisson_ratio,
                    shell.thickness,
                    shell.bend_scale,
                );
                let mut rest: Vec<Vector3<f64>> = rest.iter().map(|&p| v3(p)).collect();
                // Clamped edges: their ghosts' rest positions follow the element's rest
                // positions after its own (crate::clamp).
                let ghosts: Vec<crate::Ghost> = b
                    .ghosts
                    .iter()
                    .filter(|g| g.element == ei)
                    .cloned()
                    .collect();
                let mut clamped = Vec::with_capacity(ghosts.len());
                for g in &ghosts {
                    let [p, q] = g.edge.map(|v| rest[v as usize]);
                    clamped.push(ClampedEdge {
                        edge: g.edge,
                        ghost: rest.len() as u32,
                    });
                    rest.push(crate::clamp::mirror(p, q, rest[g.apex as usize]));
                }
                let bending =
                    shell_bending_clamped(&rest, &mesh.triangles, d, shell.poisson_ratio, &clamped)
                        .map_err(|err| SimError::BadGeometry {
                            element: name.into(),
                            message: err.to_string(),
                        })?;
                let global = |v: u32| {
                    if v < n {
                        v + off
                    } else {
                        ghosts[(v - n) as usize].vertex as u32
                    }
                };
                if bending.non_manifold_edges > 0 {
                    b.warn(format!(
                        "element '{name}': {} non-manifold edge(s) (shared by more than two triangles); their vertices get no bending",
                        bending.non_manifold_edges
                    ));
                }
                let (dropoff, kappa0) = (shell.bend_dropoff, shell.dropoff_curvature);
                for mut el in bending.vertices {
                    el.map_vertices(global);
                    el.set_dropoff(dropoff, kappa0);
                    b.system.elements.shells.push(el);
                }
                for mut el in bending.triangles {
                    el.map_vertices(global);
                    el.set_dropoff(dropoff, kappa0);
                    b.system.elements.midedges.push(el);
                }
                for mut el in bending.clamped_vertices {
                    el.map_vertices(global);
                    el.set_dropoff(dropoff, kappa0);
                    b.system.elements.shell_clamps.push(el);
                }
            }
        }
        Ok(())
    }
}

/// Rods (hair): stretch on every segment and bending at every interior vertex of each curve,
/// with lumped masses from the Density SEC. Axial stiffness k = stretch_scale·E·πr²; bending
/// EI = bend_scale·E·πr⁴/4 over the Voronoi length (see `weft_solid::energy::RodBend`).
#[derive(Clone, Debug, Default)]
pub struct RodMaterial;

impl Behavior for RodMaterial {
    fn name(&self) -> &'static str {
        "rod_material"
    }
    fn reads(&self) -> &'static [&'static str] {
        &["rod", "density"]
    }
    fn apply(&self, scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        for (ei, e) in scene.iter().enumerate() {
            let (ElementKind::Hair, Geometry::Curves(curves)) = (e.kind, &*e.geometry) else {
                continue;
            };
            b.read(ei, "rod");
            b.read(ei, "density");
            let rod = e.secs.get::<Rod>().cloned().unwrap_or_default();
            let density = e.secs.get::<Density>().cloned().unwrap_or_default();
            let name = e.name.as_str();
            checked(name, &rod)?;
            checked(name, &density)?;
            let section = rod_section(&rod);
            let (ea, ei_bend) = (section.axial, section.bending);
            let rest = rest_positions(e, &rod.rest_channel)?;
            let off = b.offset(ei).expect("hair elements have a vertex range");
            for k in 0..curves.len() {
                let r = curves.range(k);
                let pts: Vec<Vector3<f64>> = rest[r.clone()].iter().map(|&p| v3(p)).collect();
                for s in 0..pts.len().saturating_sub(1) {
                    let l = (pts[s + 1] - pts[s]).norm();
                    if l.is_nan() || l <= 1e-12 {
                        return Err(SimError::BadGeometry {
                            element: name.into(),
                            message: format!("curve {k}, segment {s} has zero rest length"),
                        });
                    }
                    let (a, c) = ((r.start + s) as u32 + off, (r.start + s + 1) as u32 + off);
                    b.system.elements.stretches.push(RodStretch {
                        v: [a, c],
                        rest_length: l,
                        k: ea,
                    });
                    b.add_mass(a as usize, 0.5 * l * density.line_density);
                    b.add_mass(c as usize, 0.5 * l * density.line_density);
                }
                if ei_bend > 0.0 {
                    for s in 1..pts.len().saturating_sub(1) {
                        let (e0, e1) = (pts[s] - pts[s - 1], pts[s + 1] - pts[s]);
                        let vor = 0.5 * (e0.norm() + e1.norm());
                        let kb = 2.0 * e0.cross(&e1).norm() / (e0.norm() * e1.norm() + e0.dot(&e1));
                        let v = (r.start + s) as u32 + off;
                        let mut bend = RodBend {
                            v: [v - 1, v, v + 1],
                            k: ei_bend / (2.0 * vor),
                            rest: kb,
                            dropoff: None,
                        };
                        bend.set_dropoff(rod.bend_dropoff, rod.dropoff_curvature, vor);
                        b.system.elements.bends.push(bend);
                    }
                }
            }
            for v in 0..rest.len() as u32 {
                b.add_damping((v + off) as usize, rod.damping);
            }
        }
        Ok(())
    }
}

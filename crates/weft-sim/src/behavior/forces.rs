//! The Behaviors that add forces rather than structure: uniform gravity, constant loads on
//! chosen vertices, mass-proportional damping, and the drag elements through which a fluid
//! pushes the solids.

use super::Behavior;
use super::params::{bad, checked, non_negative, v3};
use crate::builder::SystemBuilder;
use crate::error::SimError;
use nalgebra::Vector3;
use weft_scene::{DiscreteShell, ElementKind, Geometry, Rod, SceneElement};

/// Uniform gravity on every simulated vertex.
#[derive(Clone, Debug)]
pub struct Gravity {
    /// Acceleration [m/s²] (default (0, −9.81, 0)).
    pub acceleration: [f64; 3],
}

impl Behavior for Gravity {
    fn name(&self) -> &'static str {
        "gravity"
    }
    fn reads(&self) -> &'static [&'static str] {
        &[]
    }
    fn apply(&self, _scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        b.system.gravity += v3(self.acceleration);
        Ok(())
    }
}

/// Which vertices of an element a [`Load`] pushes.
#[derive(Clone, Debug, PartialEq)]
pub enum LoadVertices {
    /// Every vertex.
    All,
    /// The last vertex of every curve (a tip load on each strand).
    CurveTips,
    /// These indices.
    Listed(Vec<u32>),
}

/// A constant force on chosen vertices of one element: a tip load, a weight hung on a
/// point, a steady push.
#[derive(Clone, Debug)]
pub struct Load {
    /// Name of the loaded element.
    pub element: String,
    /// Which of its vertices.
    pub vertices: LoadVertices,
    /// Force on each of them [N].
    pub force: [f64; 3],
}

impl Behavior for Load {
    fn name(&self) -> &'static str {
        "load"
    }
    fn reads(&self) -> &'static [&'static str] {
        &[]
    }
    fn apply(&self, scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        let f = v3(self.force);
        if !f.iter().all(|c| c.is_finite()) {
            return Err(bad(
                "(tree)",
                "load.force",
                format!("must be finite, got {:?}", self.force),
            ));
        }
        let Some(ei) = scene.iter().position(|e| e.name == self.element) else {
            return Err(bad(
                "(tree)",
                "load.element",
                format!("no element named '{}' in the scene", self.element),
            ));
        };
        let e = &scene[ei];
        let Some(off) = b.offset(ei) else {
            return Err(bad(
                &e.name,
                "load.element",
                format!("'{}' is not simulated (a {})", e.name, e.kind.name()),
            ));
        };
        let n = e.vertex_count();
        let vertices: Vec<u32> = match (&self.vertices, &*e.geometry) {
            (LoadVertices::All, _) => (0..n as u32).collect(),
            (LoadVertices::CurveTips, Geometry::Curves(c)) => (0..c.len())
                .filter(|&k| !c.range(k).is_empty())
                .map(|k| c.range(k).end as u32 - 1)
                .collect(),
            (LoadVertices::CurveTips, _) => {
                return Err(bad(
                    &e.name,
                    "load.select",
                    format!("'{}' has no curves to take tips from", e.name),
                ));
            }
            (LoadVertices::Listed(v), _) => {
                // A vertex listed twice is loaded once.
                let mut v = v.clone();
                v.sort_unstable();
                v.dedup();
                v
            }
        };
        if let Some(v) = vertices.iter().find(|&&v| v as usize >= n) {
            return Err(bad(
                &e.name,
                "load.vertices",
                format!("vertex {v} is out of range ('{}' has {n} vertices)", e.name),
            ));
        }
        if b.system.forces.is_empty() {
            b.system.forces = vec![Vector3::zeros(); b.system.mass.len()];
        }
        for v in vertices {
            b.system.forces[(v + off) as usize] += f;
        }
        Ok(())
    }
}

/// Mass-proportional damping on every simulated vertex, added to the SECs' own.
#[derive(Clone, Debug)]
pub struct Damping {
    /// Coefficient [1/s]: a force −c m v.
    pub coefficient: f64,
}

impl Behavior for Damping {
    fn name(&self) -> &'static str {
        "damping"
    }
    fn reads(&self) -> &'static [&'static str] {
        &[]
    }
    fn apply(&self, _scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        non_negative("(tree)", "damping.coefficient", self.coefficient)?;
        for v in 0..b.system.mass.len() {
            b.add_damping(v, self.coefficient);
        }
        Ok(())
    }
}

/// Fluid drag: every hair segment (cross-section from its Rod SEC's radius) and cloth triangle
/// (thickness from its Discrete Shell SEC) becomes a drag element with its Drag SEC's law, or
/// the documented defaults. The elements reach the coupled stepper through
/// [`crate::Compiled::drag_elements`]; a scene without a fluid simply never uses them.
#[derive(Clone, Debug, Default)]
pub struct FluidDrag;

impl Behavior for FluidDrag {
    fn name(&self) -> &'static str {
        "fluid_drag"
    }
    fn reads(&self) -> &'static [&'static str] {
        &["drag", "rod", "discrete_shell"]
    }
    fn apply(&self, scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError> {
        for (ei, e) in scene.iter().enumerate() {
            let Some(off) = b.offset(ei) else { continue };
            let params = match e.kind {
                ElementKind::Cloth | ElementKind::Hair => {
                    b.read(ei, "drag");
                    e.secs
                        .get::<weft_scene::Drag>()
                        .cloned()
                        .unwrap_or_default()
                }
                _ => continue,
            };
            checked(&e.name, &params)?;
            match (&*e.geometry, e.kind) {
                (Geometry::Curves(c), ElementKind::Hair) => {
                    b.read(ei, "rod");
                    let r = e.secs.get::<Rod>().cloned().unwrap_or_default().radius;
                    let area = std::f64::consts::PI * r * r;
                    for w in c.offsets.windows(2) {
                        for v in w[0]..w[1].saturating_sub(1) {
                            b.drag_elements.push(crate::DragElement {
                                shape: crate::DragShape::Segment([v + off, v + 1 + off], area),
                                params,
                            });
                        }
                    }
                }
                (Geometry::Mesh(m), ElementKind::Cloth) => {
                    b.read(ei, "discrete_shell");
                    let t = e
                        .secs
                        .get::<DiscreteShell>()
                        .cloned()
                        .unwrap_or_default()
                        .thickness;
                    for tri in &m.triangles {
                        b.drag_elements.push(crate::DragElement {
                            shape: crate::DragShape::Triangle(tri.map(|v| v + off), t),
                            params,
                        });
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }
}

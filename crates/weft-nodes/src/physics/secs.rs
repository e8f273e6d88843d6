//! SEC nodes: each attaches one typed parameter bundle to an element. An SEC's parameters,
//! their defaults, ranges, units and docs are its table's (`weft_scene::fields`): checked
//! when the graph loads, so a negative stiffness or ν ≥ 0.5 is a load error naming the node
//! and parameter, and read back field by field.

use std::ops::Bound;
use weft_graph::{Kernel, NodeSpec, ParamError, ParamSpec, Params, Registry, RegistryError, Value};
use weft_scene::fields::{FieldKind, FieldValue, SecFields};
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

/// A node's parameter for field `f` of SEC `S`, its default `S::default()`'s.
fn param<S: SecFields>(f: &weft_scene::fields::Field) -> ParamSpec {
    let p = match (f.kind, S::default().get(f.name)) {
        (FieldKind::Float { min, max }, Some(FieldValue::Float(d))) => {
            let mut p = ParamSpec::float(f.name, d);
            p = match min {
                Bound::Included(x) => p.ge(x),
                Bound::Excluded(x) => p.gt(x),
                Bound::Unbounded => p,
            };
            match max {
                Bound::Included(x) => p.le(x),
                Bound::Excluded(x) => p.lt(x),
                Bound::Unbounded => p,
            }
        }
        (_, Some(FieldValue::Text(d))) => ParamSpec::string(f.name, &d),
        (_, Some(FieldValue::Vec3(d))) => ParamSpec::vec3(f.name, d),
        _ => unreachable!("an SEC table's field has a default of its kind"),
    };
    let p = if f.unit.is_empty() { p } else { p.unit(f.unit) };
    p.doc(f.doc)
}

/// SEC `S` from the node's parameters, field by field.
fn read_back<S: SecFields>(p: &Params) -> Result<S, ParamError> {
    let mut sec = S::default();
    for f in S::fields() {
        let v = match f.kind {
            FieldKind::Float { .. } => FieldValue::Float(p.f64(f.name)?),
            FieldKind::Text => FieldValue::Text(p.str(f.name)?.to_string()),
            FieldKind::Vec3 => FieldValue::Vec3(p.vec3(f.name)?),
        };
        sec.set(f.name, v);
    }
    Ok(sec)
}

/// Registers `sec.NAME`, the node attaching SEC `S` with its table's parameters.
fn attach_table<S: SecFields + Sec>(r: &mut Registry) -> Result<(), RegistryError> {
    let params = S::fields().iter().map(param::<S>).collect();
    attach(
        &format!("sec.{}", S::TYPE),
        S::DOC,
        params,
        read_back::<S>,
        r,
    )
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    attach_table::<DiscreteShell>(r)?;
    attach_table::<Rod>(r)?;
    attach_table::<Density>(r)?;
    attach_table::<Drag>(r)?;
    attach_table::<Collider>(r)?;
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

//! Byte encodings of the solvers' states for disk checkpoints (`weft run --out`): what a
//! killed run resumes from. Everything a state holds that the start frame cannot rebuild is
//! written bit for bit (positions, velocities, transforms, the fluid's fields); the rest (the
//! compiled scene, the fluid's domain) comes from the start frame's state on restore, and is
//! checked against what the bytes say.

use super::coupled::CoupledState;
use super::types::Scene;
use std::sync::Arc;
use weft_fluid::MacGrid;
use weft_graph::Value;
use weft_graph::codec::{Reader, Writer};
use weft_scene::Transform;
use weft_sim::Relaxation;
use weft_sim::SimState;
use weft_solid::State;

fn vecs(v: &[nalgebra::Vector3<f64>]) -> Vec<[f64; 3]> {
    v.iter().map(|p| [p.x, p.y, p.z]).collect()
}

fn unvecs(v: Vec<[f64; 3]>) -> Vec<nalgebra::Vector3<f64>> {
    v.into_iter().map(nalgebra::Vector3::from).collect()
}

/// Writes a solid state and its frame's transforms.
pub(crate) fn write_sim(w: &mut Writer, s: &SimState) {
    w.vec3s(&vecs(&s.solid.x)).vec3s(&vecs(&s.solid.v));
    w.u64(s.transforms.len() as u64);
    for t in &s.transforms {
        match t {
            None => {
                w.u64(0);
            }
            Some(t) => {
                let q = t.rotation.quaternion().coords;
                let p = t.translation.vector;
                w.u64(1).f64s(&[q.x, q.y, q.z, q.w, p.x, p.y, p.z]);
            }
        }
    }
}

/// Reads what [`write_sim`] wrote; `vertices` and `elements` must match the template.
pub(crate) fn read_sim(r: &mut Reader<'_>, template: &SimState) -> Result<SimState, String> {
    let x = unvecs(r.vec3s()?);
    let v = unvecs(r.vec3s()?);
    let n = template.solid.x.len();
    if x.len() != n || v.len() != n {
        return Err(format!(
            "{} positions and {} velocities for {n} vertices",
            x.len(),
            v.len()
        ));
    }
    let count = r.u64()?;
    if count != template.transforms.len() as u64 {
        return Err(format!(
            "{count} transforms for {} elements",
            template.transforms.len()
        ));
    }
    let mut transforms = Vec::with_capacity(template.transforms.len());
    for _ in 0..count {
        transforms.push(match r.u64()? {
            0 => None,
            1 => {
                let c = r.f64s()?;
                let [qx, qy, qz, qw, tx, ty, tz] = c[..] else {
                    return Err(format!("a transform of {} numbers", c.len()));
                };
                // Bit for bit: no renormalization of the stored unit quaternion.
                let q = nalgebra::UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(
                    qw, qx, qy, qz,
                ));
                Some(Transform::from_parts(
                    nalgebra::Translation3::new(tx, ty, tz),
                    q,
                ))
            }
            k => return Err(format!("transform tag {k}")),
        });
    }
    Ok(SimState {
        solid: State { x, v },
        transforms,
        history: None,
        inputs: Vec::new(),
    })
}

/// Writes a state's frozen inputs (after everything else: a checkpoint from before freeze
/// attachments ends without them).
fn write_inputs(w: &mut Writer, s: &SimState) {
    w.vec3s(&vecs(&s.inputs));
}

/// Reads what [`write_inputs`] wrote into `s`, which must have as many as `template`.
fn read_inputs(
    r: &mut Reader<'_>,
    mut s: SimState,
    template: &SimState,
) -> Result<SimState, String> {
    if r.end().is_ok() {
        s.inputs = Vec::new();
    } else {
        s.inputs = unvecs(r.vec3s()?);
    }
    if s.inputs.len() != template.inputs.len() {
        return Err(format!(
            "{} frozen inputs for {} frozen vertices",
            s.inputs.len(),
            template.inputs.len()
        ));
    }
    Ok(s)
}

/// Writes the BDF2 history of a solid state (the state one step before and that step's
/// length), after [`write_sim`]: a flag, then positions, velocities and the step. Only
/// `solver.solid` keeps one.
fn write_history(w: &mut Writer, s: &SimState) {
    match &s.history {
        None => {
            w.u64(0);
        }
        Some((prev, h)) => {
            w.u64(1).vec3s(&vecs(&prev.x)).vec3s(&vecs(&prev.v)).f64(*h);
        }
    }
}

/// Reads what [`write_history`] wrote into `s`. A checkpoint written before BDF2 existed
/// ends after the state: no history (its run was implicit Euler).
fn read_history(r: &mut Reader<'_>, mut s: SimState) -> Result<SimState, String> {
    if r.end().is_ok() {
        return Ok(s);
    }
    s.history = match r.u64()? {
        0 => None,
        1 => {
            let x = unvecs(r.vec3s()?);
            let v = unvecs(r.vec3s()?);
            let h = r.f64()?;
            let n = s.solid.x.len();
            if x.len() != n || v.len() != n || !h.is_finite() || h <= 0.0 {
                return Err(format!(
                    "a history of {} positions and {} velocities for {n} vertices, step {h}",
                    x.len(),
                    v.len()
                ));
            }
            Some((State { x, v }, h))
        }
        k => return Err(format!("history tag {k}")),
    };
    Ok(s)
}

/// Writes `solver.solid`'s state: the solid state, its BDF2 history, its frozen inputs.
pub(crate) fn write_solid(w: &mut Writer, s: &SimState) {
    write_sim(w, s);
    write_history(w, s);
    write_inputs(w, s);
}

/// Reads what [`write_solid`] wrote (or, from before BDF2, [`write_sim`] alone).
pub(crate) fn read_solid(r: &mut Reader<'_>, template: &SimState) -> Result<SimState, String> {
    let s = read_sim(r, template).and_then(|s| read_history(r, s))?;
    read_inputs(r, s, template)
}

/// Writes a fluid's fields (the domain is the compiled scene's, not stored).
pub(crate) fn write_grid(w: &mut Writer, g: &MacGrid) {
    for a in 0..3 {
        w.f64s(&g.vel[a])
            .f64s(&g.alpha[a])
            .f64s(&g.drag[a])
            .f64s(&g.solid_vel[a]);
    }
    w.f64s(&g.pressure);
}

/// Reads what [`write_grid`] wrote into a grid on `template`'s domain.
pub(crate) fn read_grid(r: &mut Reader<'_>, template: &MacGrid) -> Result<MacGrid, String> {
    let mut g = MacGrid::new(template.domain.clone());
    for a in 0..3 {
        for field in [
            &mut g.vel[a],
            &mut g.alpha[a],
            &mut g.drag[a],
            &mut g.solid_vel[a],
        ] {
            let v = r.f64s()?;
            if v.len() != field.len() {
                return Err(format!("{} face values for {} faces", v.len(), field.len()));
            }
            *field = v;
        }
    }
    let p = r.f64s()?;
    if p.len() != g.pressure.len() {
        return Err(format!(
            "{} pressures for {} cells",
            p.len(),
            g.pressure.len()
        ));
    }
    g.pressure = p;
    Ok(g)
}

/// A frame's coupled state for a disk checkpoint: solids, fluid fields, last residuals
/// (the compiled scene and the domain come back from the start frame's state).
pub(crate) fn encode_state(v: &Value) -> Option<Vec<u8>> {
    let s = v.get::<CoupledState>()?;
    let mut w = weft_graph::codec::Writer::new();
    write_sim(&mut w, &s.sim);
    match &s.fluid {
        Some(g) => {
            w.u64(1);
            write_grid(&mut w, g);
        }
        None => {
            w.u64(0);
        }
    }
    w.u64(s.iteration as u64)
        .f64s(&s.residual)
        .f64s(&[s.exchange, s.transport].concat());
    write_inputs(&mut w, &s.sim);
    Some(w.finish())
}

/// Rebuilds a coupled state from [`encode_state`]'s bytes, the start frame's state and the
/// solver's inputs at the restored frame (its scene).
pub(crate) fn restore_state(
    b: &[u8],
    template: &Value,
    inputs: &[(String, Value)],
) -> Result<Value, String> {
    let t = template
        .get::<CoupledState>()
        .ok_or("the start state is not a coupled state")?;
    let mut r = weft_graph::codec::Reader::new(b);
    let sim = read_sim(&mut r, &t.sim)?;
    let fluid = match (r.u64()?, &t.fluid) {
        (0, None) => None,
        (1, Some(g)) => Some(Arc::new(read_grid(&mut r, g)?)),
        _ => return Err("the fluid does not match the scene's".into()),
    };
    let iteration = r.u64()? as usize;
    let residual = match r.f64s()?[..] {
        [a, b] => [a, b],
        _ => return Err("expected two residuals".into()),
    };
    // Exchange and transport (checkpoints written before transport was kept hold the
    // exchange alone).
    let (exchange, transport) = match r.f64s()?[..] {
        [a, b, c] => ([a, b, c], [0.0; 3]),
        [a, b, c, d, e, f] => ([a, b, c], [d, e, f]),
        _ => return Err("expected two momenta".into()),
    };
    let sim = read_inputs(&mut r, sim, &t.sim)?;
    r.end()?;
    let scene = inputs
        .iter()
        .find(|(k, _)| k == "scene")
        .and_then(|(_, v)| v.get::<Scene>())
        .map_or_else(|| t.scene.clone(), |s| Arc::new(s.clone()));
    Ok(Value::new(CoupledState {
        compiled: t.compiled.clone(),
        sim,
        fluid,
        scene,
        iteration,
        relaxation: Relaxation::default(),
        residual,
        exchange,
        transport,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sim_states_round_trip_bit_for_bit() {
        let rot = nalgebra::UnitQuaternion::from_euler_angles(0.1, -0.7, 2.3);
        let s = SimState {
            solid: State {
                x: vec![nalgebra::Vector3::new(0.1, -0.0, 1e-300); 3],
                v: vec![nalgebra::Vector3::new(f64::MIN_POSITIVE, 2.0, -3.5); 3],
            },
            transforms: vec![
                None,
                Some(Transform::from_parts(
                    nalgebra::Translation3::new(1.0, 2.0, 3.0),
                    rot,
                )),
            ],
            history: None,
            inputs: Vec::new(),
        };
        let mut w = Writer::new();
        write_sim(&mut w, &s);
        let b = w.finish();
        let back = read_sim(&mut Reader::new(&b), &s).unwrap();
        assert_eq!(back, s);
        let mut w2 = Writer::new();
        write_sim(&mut w2, &back);
        assert_eq!(w2.finish(), b);
        for cut in 0..b.len() {
            assert!(read_sim(&mut Reader::new(&b[..cut]), &s).is_err());
        }
    }

    /// The BDF2 history and the frozen inputs round-trip bit for bit after the state; a
    /// checkpoint that ends after the state (written before BDF2 and freeze) reads as no
    /// history and no inputs; a damaged one is refused.
    #[test]
    fn histories_round_trip_and_old_checkpoints_read_as_none() {
        let state = |a: f64| State {
            x: vec![nalgebra::Vector3::new(a, -0.0, 1e-300); 2],
            v: vec![nalgebra::Vector3::new(f64::MIN_POSITIVE, 2.0, a); 2],
        };
        let s = SimState {
            solid: state(0.5),
            transforms: vec![None],
            history: Some((state(0.25), 1.0 / 96.0)),
            inputs: vec![nalgebra::Vector3::new(0.3, -1e-310, 7.0); 2],
        };
        let mut w = Writer::new();
        write_solid(&mut w, &s);
        let b = w.finish();
        let mut r = Reader::new(&b);
        let back = read_solid(&mut r, &s).unwrap();
        r.end().unwrap();
        assert_eq!(back, s);
        let mut old = Writer::new();
        write_sim(&mut old, &s);
        let old = old.finish();
        let unfrozen = SimState {
            inputs: Vec::new(),
            ..s.clone()
        };
        let back = read_solid(&mut Reader::new(&old), &unfrozen).unwrap();
        assert_eq!((back.history, back.inputs.len()), (None, 0));
        // A scene with frozen vertices needs their inputs.
        assert!(read_solid(&mut Reader::new(&old), &s).is_err());
        for cut in old.len() + 1..b.len() {
            assert!(read_solid(&mut Reader::new(&b[..cut]), &s).is_err());
        }
    }
}

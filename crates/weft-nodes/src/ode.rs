//! Stateful integrators of ODEs with known solutions, for testing the engine's time handling
//! (checkpoints, resume, invalidation) against analytic answers.

use serde_json::json;
use weft_graph::{
    EvalCx, Kernel, NodeError, NodeSpec, ParamSpec, Registry, RegistryError, Step, TimeClass, Value,
};

/// y(t) = y0 e^{−k t}, the solution of y' = −k y.
pub fn decay_exact(y0: f64, k: f64, t: f64) -> f64 {
    y0 * (-k * t).exp()
}

/// x(t) = x0 cos ωt + (v0/ω) sin ωt, the solution of x'' = −ω² x.
pub fn oscillator_exact(x0: f64, v0: f64, omega: f64, t: f64) -> f64 {
    x0 * (omega * t).cos() + v0 / omega * (omega * t).sin()
}

/// Every this many substeps an integrator asks whether to stop (a frame of 10⁹ substeps is
/// a valid request that must still answer Ctrl-C).
const CHECK_EVERY: usize = 1 << 16;

fn stop_check(cx: &EvalCx<'_>, k: usize) -> Result<(), NodeError> {
    if k % CHECK_EVERY == CHECK_EVERY - 1 && cx.interrupt().is_set() {
        return Err(NodeError::Interrupted(format!(
            "{} at substep {}",
            cx.interrupt().reason(),
            k + 1
        )));
    }
    Ok(())
}

fn substep(cx: &EvalCx<'_>) -> Result<(usize, f64), NodeError> {
    let n = cx.params().usize("substeps")?.max(1);
    Ok((n, 1.0 / (cx.context().fps * n as f64)))
}

struct Decay;

impl Step for Decay {
    fn init(&mut self, cx: &mut EvalCx<'_>) -> Result<Value, NodeError> {
        Ok(Value::from(cx.params().f64("y0")?))
    }
    fn step(&mut self, state: &Value, cx: &mut EvalCx<'_>) -> Result<Value, NodeError> {
        let mut y = *state
            .get::<f64>()
            .ok_or_else(|| NodeError::Failed("the state is not a number".into()))?;
        let k = cx.params().f64("rate")?;
        let (n, h) = substep(cx)?;
        let f = |y: f64| -k * y;
        let method = cx.params().str("method")?.to_string();
        for i in 0..n {
            stop_check(cx, i)?;
            y = match method.as_str() {
                "explicit_euler" => y + h * f(y),
                "implicit_euler" => y / (1.0 + h * k),
                "exact" => y * (-k * h).exp(),
                _ => {
                    let k1 = f(y);
                    let k2 = f(y + 0.5 * h * k1);
                    let k3 = f(y + 0.5 * h * k2);
                    let k4 = f(y + h * k3);
                    y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
                }
            };
        }
        if !y.is_finite() {
            return Err(NodeError::Failed(format!(
                "y became {y}: the step h·k = {} is unstable for this method",
                h * k
            )));
        }
        Ok(Value::from(y))
    }
    fn outputs(&mut self, state: &Value, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        cx.set("y", state.clone());
        Ok(())
    }
    fn save_state(&self, state: &Value, _: &weft_graph::Registry) -> Option<Vec<u8>> {
        state.get::<f64>().map(|y| y.to_le_bytes().to_vec())
    }
    fn load_state(&mut self, b: &[u8], _: &Value, _: &mut EvalCx<'_>) -> Result<Value, NodeError> {
        let b: [u8; 8] = b.try_into().map_err(|_| {
            NodeError::Failed(format!("checkpoint of {} bytes, expected 8", b.len()))
        })?;
        Ok(Value::from(f64::from_le_bytes(b)))
    }
}

struct Oscillator;

impl Step for Oscillator {
    fn init(&mut self, cx: &mut EvalCx<'_>) -> Result<Value, NodeError> {
        Ok(Value::from([
            cx.params().f64("x0")?,
            cx.params().f64("v0")?,
            0.0,
        ]))
    }
    fn step(&mut self, state: &Value, cx: &mut EvalCx<'_>) -> Result<Value, NodeError> {
        let s = *state
            .get::<[f64; 3]>()
            .ok_or_else(|| NodeError::Failed("the state is not [x, v, 0]".into()))?;
        let (mut x, mut v) = (s[0], s[1]);
        let w = cx.params().f64("omega")?;
        let c = 2.0 * cx.params().f64("zeta")? * w;
        // The drive is sampled at the frame being stepped to and held over its substeps.
        let a = cx.f64_input("drive")?;
        let (n, h) = substep(cx)?;
        let acc = |x: f64, v: f64| -w * w * x - c * v + a;
        let method = cx.params().str("method")?.to_string();
        for i in 0..n {
            stop_check(cx, i)?;
            match method.as_str() {
                "symplectic_euler" => {
                    v += h * acc(x, v);
                    x += h * v;
                }
                "implicit_euler" => {
                    // x1 = x + h v1, v1 = v + h acc(x1, v1): linear, solved in closed form.
                    v = (v + h * (a - w * w * x)) / (1.0 + c * h + w * w * h * h);
                    x += h * v;
                }
                _ => {
                    let (k1x, k1v) = (v, acc(x, v));
                    let (k2x, k2v) = (v + 0.5 * h * k1v, acc(x + 0.5 * h * k1x, v + 0.5 * h * k1v));
                    let (k3x, k3v) = (v + 0.5 * h * k2v, acc(x + 0.5 * h * k2x, v + 0.5 * h * k2v));
                    let (k4x, k4v) = (v + h * k3v, acc(x + h * k3x, v + h * k3v));
                    x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
                    v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
                }
            }
        }
        if !(x.is_finite() && v.is_finite()) {
            return Err(NodeError::Failed(format!(
                "state became ({x}, {v}): ω·h = {} is unstable for {method}",
                w * h
            )));
        }
        Ok(Value::from([x, v, 0.0]))
    }
    fn outputs(&mut self, state: &Value, cx: &mut EvalCx<'_>) -> Result<(), NodeError> {
        let s = *state
            .get::<[f64; 3]>()
            .ok_or_else(|| NodeError::Failed("the state is not [x, v, 0]".into()))?;
        let w = cx.params().f64("omega")?;
        cx.set("x", s[0]);
        cx.set("v", s[1]);
        cx.set("energy", 0.5 * s[1] * s[1] + 0.5 * w * w * s[0] * s[0]);
        Ok(())
    }
    fn save_state(&self, state: &Value, _: &weft_graph::Registry) -> Option<Vec<u8>> {
        let mut w = weft_graph::codec::Writer::new();
        w.f64s(state.get::<[f64; 3]>()?);
        Some(w.finish())
    }
    fn load_state(&mut self, b: &[u8], _: &Value, _: &mut EvalCx<'_>) -> Result<Value, NodeError> {
        let mut r = weft_graph::codec::Reader::new(b);
        match (r.f64s(), r.end()) {
            (Ok(v), Ok(())) if v.len() == 3 => Ok(Value::from([v[0], v[1], v[2]])),
            _ => Err(NodeError::Failed(
                "checkpoint: not an oscillator state".into(),
            )),
        }
    }
}

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new(
            "ode.decay",
            "integrates y' = −k y from y0 (exact: y0 e^{−kt})",
        )
        .time(TimeClass::Stateful)
        .output("y", "float", "y at the frame's time")
        .param(
            ParamSpec::float("rate", 1.0)
                .gt(0.0)
                .unit("1/s")
                .doc("decay rate k"),
        )
        .param(ParamSpec::float("y0", 1.0).doc("value at the start frame"))
        .param(
            ParamSpec::choice(
                "method",
                &["explicit_euler", "implicit_euler", "rk4", "exact"],
                "rk4",
            )
            .doc("integrator"),
        )
        .param(ParamSpec::int("substeps", 1).ge(1.0).doc("steps per frame")),
        |_| Ok(Kernel::Step(Box::new(Decay))),
    )?;
    r.register(
        NodeSpec::new(
            "ode.oscillator",
            "integrates x'' = −ω² x − 2ζω x' + drive (undamped exact: x0 cos ωt + v0/ω sin ωt)",
        )
        .time(TimeClass::Stateful)
        .input_default(
            "drive",
            "float",
            json!(0.0),
            "external acceleration, read at every frame",
        )
        .output("x", "float", "position")
        .output("v", "float", "velocity")
        .output("energy", "float", "½v² + ½ω²x² (per unit mass)")
        .param(
            ParamSpec::float("omega", 1.0)
                .gt(0.0)
                .unit("rad/s")
                .doc("angular frequency ω"),
        )
        .param(ParamSpec::float("zeta", 0.0).ge(0.0).doc("damping ratio ζ"))
        .param(
            ParamSpec::float("x0", 1.0)
                .unit("m")
                .doc("initial position"),
        )
        .param(
            ParamSpec::float("v0", 0.0)
                .unit("m/s")
                .doc("initial velocity"),
        )
        .param(
            ParamSpec::choice(
                "method",
                &["symplectic_euler", "implicit_euler", "rk4"],
                "rk4",
            )
            .doc("integrator"),
        )
        .param(ParamSpec::int("substeps", 1).ge(1.0).doc("steps per frame")),
        |_| Ok(Kernel::Step(Box::new(Oscillator))),
    )
}

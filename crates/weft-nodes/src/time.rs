//! Frame and time, and keyed curves (an animated weight, stiffness or friction).

use weft_graph::{Kernel, NodeSpec, ParamSpec, Params, Registry, RegistryError, TimeClass};

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    r.register(
        NodeSpec::new(
            "time.frame",
            "the frame being evaluated, its time and the frame step",
        )
        .time(TimeClass::Animated)
        .output("frame", "int", "frame number")
        .output("time", "float", "time in seconds (frame / fps)")
        .output("dt", "float", "seconds per frame (1 / fps)"),
        |_| {
            Ok(Kernel::from_fn(|cx| {
                let c = cx.context();
                cx.set("frame", c.frame);
                cx.set("time", c.time());
                cx.set("dt", 1.0 / c.fps);
                Ok(())
            }))
        },
    )?;
    r.register(
        NodeSpec::new(
            "anim.curve",
            "a keyed curve: its value at the frame being evaluated, interpolated between keys (the first key's value before it, the last's after)",
        )
        .time(TimeClass::Animated)
        .output("out", "float", "the curve's value at the frame")
        .param(ParamSpec::floats("frames", &[1.0]).doc("key frames, increasing"))
        .param(ParamSpec::floats("values", &[0.0]).doc("the value at each key frame"))
        .param(
            ParamSpec::choice("interpolation", &["linear", "step", "smooth"], "linear").doc(
                "linear: straight between keys; step: each key's value until the next key; smooth: eased (3s² − 2s³, flat at every key)",
            ),
        ),
        |p| {
            keys(p)?;
            Ok(Kernel::from_fn(|cx| {
                let (frames, values) = keys(cx.params()).map_err(weft_graph::NodeError::Failed)?;
                let v = curve_at(
                    &frames,
                    &values,
                    cx.params().str("interpolation")?,
                    cx.frame() as f64,
                );
                cx.set("out", v);
                Ok(())
            }))
        },
    )
}

/// The keys of `anim.curve`, checked: as many values as frames (at least one), all finite,
/// frames increasing.
fn keys(p: &Params) -> Result<(Vec<f64>, Vec<f64>), String> {
    let (f, v) = (p.floats("frames")?, p.floats("values")?);
    if f.is_empty() || f.len() != v.len() {
        return Err(format!(
            "param 'values': {} values for {} key frames (one each, at least one key)",
            v.len(),
            f.len()
        ));
    }
    if let Some(x) = f.iter().chain(&v).find(|x| !x.is_finite()) {
        return Err(format!("param 'frames' or 'values': {x} is not a number"));
    }
    if let Some(w) = f.windows(2).find(|w| w[1] <= w[0]) {
        return Err(format!(
            "param 'frames': key frames must increase ({} then {})",
            w[0], w[1]
        ));
    }
    Ok((f, v))
}

/// The curve through (`frames`, `values`) at `t` (keys checked by [`keys`]).
fn curve_at(frames: &[f64], values: &[f64], interpolation: &str, t: f64) -> f64 {
    let k = frames.partition_point(|&f| f <= t);
    if k == 0 {
        return values[0];
    }
    if k == frames.len() {
        return values[k - 1];
    }
    let (f0, f1, v0, v1) = (frames[k - 1], frames[k], values[k - 1], values[k]);
    let s = (t - f0) / (f1 - f0);
    let s = match interpolation {
        "step" => 0.0,
        "smooth" => s * s * (3.0 - 2.0 * s),
        _ => s,
    };
    // Exact at the keys: v0 at s = 0, v1 at s = 1.
    (1.0 - s) * v0 + s * v1
}

#[cfg(test)]
mod tests {
    use super::curve_at;

    #[test]
    fn a_curve_holds_its_ends_and_interpolates_between_keys() {
        let (f, v) = ([1.0, 11.0, 21.0], [0.0, 1.0, 0.5]);
        assert_eq!(curve_at(&f, &v, "linear", -5.0), 0.0);
        assert_eq!(curve_at(&f, &v, "linear", 30.0), 0.5);
        assert_eq!(curve_at(&f, &v, "linear", 11.0), 1.0);
        assert!((curve_at(&f, &v, "linear", 6.0) - 0.5).abs() < 1e-15);
        assert_eq!(curve_at(&f, &v, "step", 10.0), 0.0);
        assert_eq!(curve_at(&f, &v, "step", 11.0), 1.0);
        // Smooth: 3s² − 2s³ at s = 1/4 is 0.15625; symmetric about the middle.
        assert!((curve_at(&f, &v, "smooth", 3.5) - 0.15625).abs() < 1e-15);
        assert!((curve_at(&f, &v, "smooth", 6.0) - 0.5).abs() < 1e-15);
    }
}

//! Frame and time.

use weft_graph::{Kernel, NodeSpec, Registry, RegistryError, TimeClass};

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
    )
}

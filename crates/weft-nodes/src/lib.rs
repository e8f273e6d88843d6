//! `weft-nodes`: Weft's standard node library.
//!
//! [`registry`] returns a [`Registry`] with every standard node type registered. Today these
//! are the generic nodes that let graphs be built and tested without physics: constants,
//! scalar and vector arithmetic, expressions, frame/time, and stateful ODE integrators with
//! known solutions. Physics crates register their nodes here as they land.
//!
//! Node kernels read their parameters from the evaluation context at compute time, so a
//! parameter change never needs a rebuilt kernel unless the factory pre-parses it (`math.expr`).
#![warn(missing_docs)]

mod expr;
mod math;
mod ode;
pub mod physics;
mod time;
mod values;
mod vec3;

use std::sync::Arc;
use weft_graph::{Registry, RegistryError};

pub use ode::{decay_exact, oscillator_exact};

/// Registers every standard node type into `r`.
pub fn register_all(r: &mut Registry) -> Result<(), RegistryError> {
    values::register(r)?;
    math::register(r)?;
    expr::register(r)?;
    vec3::register(r)?;
    time::register(r)?;
    ode::register(r)?;
    physics::register(r)?;
    Ok(())
}

/// A shared registry with the built-in and standard node types.
pub fn registry() -> Arc<Registry> {
    let mut r = Registry::new();
    register_all(&mut r).expect("standard node specs are consistent");
    Arc::new(r)
}

#[cfg(test)]
mod tests {
    #[test]
    fn registry_builds() {
        let r = super::registry();
        assert!(r.node_type("math.add").is_some());
        assert!(
            r.specs().all(|s| !s.doc.is_empty()),
            "every node type has a doc line"
        );
    }
}

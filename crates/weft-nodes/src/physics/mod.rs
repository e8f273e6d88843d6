//! Physics nodes: geometry, Scene Element conversion, SECs, Behaviors, the solid solver and
//! outputs. Port types for scene data are registered here too.

mod behaviors;
mod checkpoint;
mod convert;
mod coupled;
mod coupled_nodes;
mod fields;
mod geo;
mod measure;
mod output;
mod secs;
mod solver;
mod types;
mod wrap;
mod xform;

pub use coupled::CoupledState;
pub use types::{BehaviorValue, Scene};

use weft_graph::{Registry, RegistryError};

pub(crate) fn register(r: &mut Registry) -> Result<(), RegistryError> {
    types::register(r)?;
    geo::register(r)?;
    convert::register(r)?;
    secs::register(r)?;
    behaviors::register(r)?;
    xform::register(r)?;
    measure::register(r)?;
    wrap::register(r)?;
    coupled_nodes::register(r)?;
    fields::register(r)?;
    output::register(r)?;
    solver::register(r)
}

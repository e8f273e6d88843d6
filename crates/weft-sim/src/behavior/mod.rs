//! Behaviors: reusable simulation logic applied to every element that carries (or defaults)
//! the SEC it reads.
//!
//! This module holds the [`Behavior`] trait and the [`BehaviorTree`] that lists them; the
//! Behaviors themselves are grouped by what they add: [`material`] (cloth and hair energies
//! and masses), [`forces`] (gravity, loads, damping, fluid drag) and [`attachment`] (held,
//! spring, sliding, frozen and rigid vertices, and clamps), with [`params`] the checks and
//! readings of SECs they share. The Collision Behavior is `crate::collide`'s.

mod attachment;
mod forces;
mod material;
mod params;

pub use attachment::AttachmentBehavior;
pub use forces::{Damping, FluidDrag, Gravity, Load, LoadVertices};
pub use material::{DiscreteShellMaterial, RodMaterial};
pub(crate) use params::{bad, checked, non_negative};

use crate::builder::SystemBuilder;
use crate::error::SimError;
use std::fmt::Debug;
use std::sync::Arc;
use weft_scene::SceneElement;

/// Simulation logic for the elements a Behavior applies to.
pub trait Behavior: Send + Sync + Debug {
    /// Name shown in reports (`discrete_shell_material`).
    fn name(&self) -> &'static str;
    /// SEC types this Behavior reads (documentation; the builder records what it actually read
    /// for each element, and SECs nobody read for their element are reported).
    fn reads(&self) -> &'static [&'static str];
    /// Adds this Behavior's terms for `scene` to the builder.
    fn apply(&self, scene: &[SceneElement], b: &mut SystemBuilder) -> Result<(), SimError>;
}

/// The Behaviors a solver applies, in order.
#[derive(Clone, Debug, Default)]
pub struct BehaviorTree {
    /// The Behaviors.
    pub behaviors: Vec<Arc<dyn Behavior>>,
}

//! `weft-sim`: Behaviors and the steppers that turn a scene into a simulation.
//!
//! A [`Behavior`] is reusable simulation logic ("every cloth gets discrete-shell membrane and
//! bending energies, from its Discrete Shell SEC or the documented defaults"). A
//! [`BehaviorTree`] groups the Behaviors a solver applies. [`compile`] turns (scene, tree) into
//! a `weft_solid::SolidSystem` holding exactly the terms the scene asks for, and
//! [`SolidStepper`] advances it frame by frame with substeps, attachments that follow animated
//! transforms, and automatic retries with smaller steps when a step fails.
//!
//! Functions take the data they read and write as arguments; nothing here prints or touches
//! files.
#![warn(missing_docs)]

mod behavior;
mod build;
mod builder;
mod clamp;
mod collide;
mod coupled;
mod error;
pub mod estimate;
mod fluid;
mod freeze;
mod relaxation;
mod slide;
mod stepper;
pub mod verify;
mod wrap;

pub use behavior::{
    AttachmentBehavior, Behavior, BehaviorTree, Damping, DiscreteShellMaterial, FluidDrag, Gravity,
    Load, LoadVertices, RodMaterial,
};
pub use build::{
    ClampPin, Compiled, Pin, SYSTEM_BYTES_PER_VERTEX, SystemBuilder, compile, compile_within,
};
pub use clamp::Ghost;
pub use collide::{
    ColliderSetup, Collision, CollisionSetup, ContactFrameStats, ContactPair, Contacts, Detector,
};
pub use coupled::{
    CoupledError, CoupledSettings, CoupledStepper, Coupling, DragElement, DragShape, Exchange,
    Predicted, solid_volume,
};
pub use error::SimError;
pub use fluid::FluidSpec;
pub use freeze::{FreezeFrame, FreezePin};
pub use relaxation::{Relaxation, RelaxationMethod, fluid_change, relax, velocity_change};
pub use slide::{SurfaceMesh, TargetPin};
pub use stepper::{
    FrameStats, LinearFrameStats, NewtonFrameStats, Scheme, SimState, SolidStepper, StepperSettings,
};
pub use wrap::{BYTES_PER_BOUND_VERTEX, HairWrap, STOPPED as WRAP_STOPPED, Wrap};

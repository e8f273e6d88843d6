//! `weft-fluid`: an Eulerian fluid on a staggered (MAC) grid, in f64, and the porous model
//! through which hair and cloth exchange momentum with it.
//!
//! Velocities live on cell faces, pressure at cell centres. A step is: advect the velocity
//! (semi-Lagrangian, [`advect`]); optionally diffuse it (implicit viscosity, [`viscosity`]);
//! add body forces; project with the porous pressure system of
//! DESIGN §6 ([`pressure`]): per face a fluid fraction α = 1 − φ_s, a drag coefficient K per
//! unit volume and a solid velocity v, which turn the usual projection (K = 0, α = 1: Batty et
//! al. 2007) into one where the fluid is dragged towards the solid and the mixture flux
//! α u + (1 − α) v is divergence-free. [`drag`] holds the anisotropic drag and lift laws of
//! the seed (Fei et al. 2018 drag, eqs. 1–4) with the derivatives an implicit solid solve needs.
//!
//! Like `weft-solid`, this crate knows nothing of graphs, files or scene elements.
#![warn(missing_docs)]

pub mod advect;
pub mod drag;
pub mod fields;
pub mod grid;
pub mod obstacle;
pub mod pressure;
pub mod raster;
pub mod verify;
pub mod viscosity;

pub use drag::{DragLaw, FluidProperties, Shape, drag_force, lift_force};
pub use grid::{Axis, Boundaries, Boundary, Domain, FluidError, MacGrid};
pub use obstacle::SolidFace;
pub use pressure::{
    PressureSolve, PressureStats, Projection, ProjectionError, StopCheck, max_divergence,
};
pub use viscosity::{Diffusion, DiffusionStats};

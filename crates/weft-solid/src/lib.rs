//! `weft-solid`: Lagrangian mechanics of cloth (discrete shells) and hair (rods).
//!
//! Unknowns are node positions and velocities in f64. A time step is implicit Euler written as
//! the minimization of the incremental potential
//! `E(x) = 1/(2h²) ‖x − x̂‖²_M + Σ potentials(x)`, `x̂ = x⁰ + h v⁰ + h² g`, solved by projected
//! Newton: element Hessians projected to PSD, a sparse Cholesky factorization (faer) whose
//! symbolic analysis is computed once per sparsity pattern, and a backtracking line search.
//! Energies live in [`energy`], each with finite-difference tests of its gradient and Hessian.
//!
//! This crate knows nothing about graphs, files or scene elements: functions take the data they
//! read and write as arguments, print nothing and touch no files.
#![warn(missing_docs)]

pub mod contact;
pub mod energy;
pub mod integrator;
pub mod progress;
mod settings;
pub mod slide;
pub mod spd;
pub mod system;
pub mod verify;

pub use integrator::{Integrator, Method, Settings, StepError, StepStats, StopCheck};
pub use progress::Progress;
pub use settings::{FEWER_VERTICES, Next, too_large};
pub use slide::{OnSurface, Rail, SlideOn, Slider, Surface};
pub use system::{Elements, RigidGroup, SolidSystem, State, SystemError, VertexDrag};

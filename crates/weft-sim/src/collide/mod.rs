//! Contacts with kinematic colliders: collision groups compiled from the scene, and the
//! detection that hands `weft_solid`'s contact step its contacts (issue 13; the plan and the
//! derivations are in `docs/contacts.md`).
//!
//! **Setup** ([`Collision`], the `behavior.collision` Behavior): every data-less collision
//! element (a Collision Group SEC and a Collision Response SEC) pairs its member cloth and hair
//! elements with its colliders; each pair gets its contact parameters from both sides' Collider
//! SECs. A scene without collision elements builds nothing.
//!
//! **Detection** ([`Detector`]), once per step and per collider, in the collider's own frame
//! (its mesh at the frame, placed by its transform interpolated over the frame as attachments
//! are): a rigidly moving collider's tree never changes, and a deforming one's is refit, not
//! rebuilt, when its shape changes. A vertex within reach of a triangle (the distance kept
//! plus its predicted travel) gets a contact whose plane separates it from that triangle:
//! normal from the closest point, the constraint n·(x_end − q_end) ≥ thickness on the end of
//! step. The triangle is convex, so a vertex that starts and ends on the plane's side never
//! crossed it. After the step, an exact check of every vertex's path against the triangles
//! near it adds a contact for any triangle the path crossed or ended too close to, and the
//! step is solved again (CCD by growing the active set: a vertex falling at 10 m/s onto a
//! thin plane is stopped whatever the step).
//!
//! The parts, each a module of its own: [`setup`] (the Behavior and the pairs), [`surfaces`]
//! (the meshes it compiles), [`room`] (what a step's detection may hold), [`live`] (a
//! collider during a frame and the walk over a pass), [`planes`] (a point's contact plane
//! against a triangle), [`detect`] (the [`Detector`]), [`solids`] (between deforming solids),
//! [`band`] (bands checked at load) and [`step`] (the contact step both solvers call).

pub(crate) mod band;
pub(crate) mod bvh;
pub(crate) mod ccd;
mod detect;
pub(crate) mod geometry;
mod live;
mod planes;
mod room;
mod setup;
mod solids;
mod step;
mod surfaces;

pub use detect::Detector;
pub use setup::{Collision, CollisionSetup, ContactPair};
pub use step::{ContactFrameStats, Contacts};
pub use surfaces::ColliderSetup;

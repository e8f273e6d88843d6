//! `weft-scene`: what a scene is made of.
//!
//! A [`SceneElement`] is one object (a cloth, a fur set, a collider) or a data-less element
//! standing for an interaction (an attachment). It holds optional [`Geometry`], named
//! per-vertex [`Channel`]s (`rest`, `velocity`, pin weights…) and a set of SECs (Scene Element
//! Components): typed, documented per-object parameter bundles that Behaviors read. This crate
//! also reads and writes meshes and curves (OBJ, USD) and renders preview images.
//!
//! It knows nothing about solvers or graphs: data and I/O only.
#![warn(missing_docs)]

pub mod element;
pub mod fields;
pub mod geometry;
pub mod obj;
pub mod preview;
pub mod procedural;
pub mod sec;
pub mod usd;
pub mod vdb;

pub use element::{Channel, ElementKind, SceneElement, Transform};
pub use geometry::{Curves, Geometry, Mesh, bounds};
pub use obj::{ObjError, read_obj, write_obj_curves, write_obj_mesh};
pub use preview::{Camera, Image, PreviewError, PreviewItem, auto_camera, render, write_png};
pub use sec::{
    Attachment, AttachmentMode, Collider, CollisionGroup, CollisionResponse, Density,
    DiscreteShell, DomainSide, Drag, Fluid, FluidDomain, FreezeWeights, Members, Rod, Sec, SecSet,
    SlideRail, SlideSurface,
};
pub use usd::{UsdError, UsdaScene, VolumeField};

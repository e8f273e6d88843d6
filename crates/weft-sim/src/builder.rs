//! What Behaviors build into: the solid system under construction, with the scene's vertex
//! ranges, attachments, warnings and which SECs were read.

use nalgebra::Vector3;
use std::collections::BTreeSet;
use std::ops::Range;
use weft_scene::Transform;
use weft_solid::SolidSystem;

/// An attached vertex and where its target comes from.
#[derive(Clone, Debug, PartialEq)]
pub struct Pin {
    /// Global vertex index.
    pub vertex: usize,
    /// Scene index of the attachment element (whose transform, if any, moves the target).
    pub attachment: usize,
    /// Target in the attachment transform's frame at the start (world when it has none).
    pub local: Vector3<f64>,
    /// Index of the spring in `system.elements.springs` for spring attachments.
    pub spring: Option<usize>,
}

/// A clamped root and where its direction comes from.
#[derive(Clone, Debug, PartialEq)]
pub struct ClampPin {
    /// Index of the clamp in `system.elements.clamps`.
    pub clamp: usize,
    /// Scene index of the attachment element (whose transform, if any, turns the direction).
    pub attachment: usize,
    /// The clamp's direction in the attachment transform's frame at the start (world when
    /// it has none), unit.
    pub local: Vector3<f64>,
}

/// Builds a system while Behaviors apply.
pub struct SystemBuilder {
    /// The system so far.
    pub system: SolidSystem,
    /// Initial positions (global).
    pub x: Vec<Vector3<f64>>,
    pub(crate) ranges: Vec<Option<Range<usize>>>,
    pub(crate) pins: Vec<Pin>,
    pub(crate) clamps: Vec<ClampPin>,
    pub(crate) targets: Vec<crate::slide::TargetPin>,
    pub(crate) freezes: Vec<crate::freeze::FreezePin>,
    /// Per vertex: it already slides, is frozen or is in a rigid group (so a second attachment listing
    /// it is refused without searching the lists).
    pub(crate) constrained: Vec<bool>,
    /// Ghost vertices behind clamped cloth edges (made before any Behavior applies).
    pub ghosts: Vec<crate::Ghost>,
    pub(crate) warnings: Vec<String>,
    pub(crate) read: Vec<BTreeSet<&'static str>>,
    /// Elements that exchange momentum with a fluid (filled by [`crate::FluidDrag`]).
    pub drag_elements: Vec<crate::DragElement>,
    /// Contacts with colliders (made by [`crate::Collision`]; `None`: no contact machinery).
    pub collisions: Option<crate::CollisionSetup>,
}

impl SystemBuilder {
    /// Records that a Behavior read (or defaulted) SEC type `sec` of scene element `e`: SECs
    /// that no Behavior reads for their element are reported.
    pub fn read(&mut self, e: usize, sec: &'static str) {
        if let Some(r) = self.read.get_mut(e) {
            r.insert(sec);
        }
    }
    /// First global vertex of scene element `e`, if it is simulated.
    pub fn offset(&self, e: usize) -> Option<u32> {
        self.ranges.get(e)?.as_ref().map(|r| r.start as u32)
    }
    /// Adds lumped mass to a vertex.
    pub fn add_mass(&mut self, v: usize, m: f64) {
        self.system.mass[v] += m;
    }
    /// Adds damping [1/s] to a vertex.
    pub fn add_damping(&mut self, v: usize, c: f64) {
        self.system.damping[v] += c;
    }
    /// Records an attached vertex.
    pub fn pin(
        &mut self,
        attachment: usize,
        vertex: usize,
        spring: Option<usize>,
        transform: Option<Transform>,
    ) {
        let x = self.x[vertex];
        let local = match transform {
            Some(t) => t.inverse_transform_point(&x.into()).coords,
            None => x,
        };
        self.pins.push(Pin {
            vertex,
            attachment,
            local,
            spring,
        });
    }
    /// Records a clamp whose direction follows `transform`'s rotation; `tangent` is its
    /// world direction at the start (unit).
    pub fn clamp(
        &mut self,
        attachment: usize,
        clamp: usize,
        tangent: Vector3<f64>,
        transform: Option<Transform>,
    ) {
        let local = match transform {
            Some(t) => t.inverse_transform_vector(&tangent),
            None => tangent,
        };
        self.clamps.push(ClampPin {
            clamp,
            attachment,
            local,
        });
    }
    /// Records a warning for the run's report.
    pub fn warn(&mut self, w: String) {
        if !self.warnings.contains(&w) {
            self.warnings.push(w);
        }
    }
}

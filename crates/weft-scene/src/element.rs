//! Scene Elements and their per-vertex channels.

use crate::geometry::Geometry;
use crate::sec::SecSet;
use std::collections::BTreeMap;
use std::sync::Arc;

/// A rigid transform (rotation and translation), f64.
pub type Transform = nalgebra::Isometry3<f64>;

/// What an element is, which decides which Behaviors apply to it by default.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum ElementKind {
    /// A triangle mesh simulated as a shell.
    Cloth,
    /// Curves simulated as rods.
    Hair,
    /// A data-less element standing for an attachment instance.
    Attachment,
    /// A kinematic object (shown, collided with, carved out of fluids; never simulated).
    Collider,
    /// The region a fluid fills (a data-less element carrying a Fluid Domain SEC).
    FluidDomain,
    /// A data-less element carrying Collision Group and Collision Response SECs.
    Collision,
    /// Geometry made from simulated elements for output (a wrapped render mesh): written and
    /// shown, never simulated.
    Render,
}

impl ElementKind {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            ElementKind::Cloth => "cloth",
            ElementKind::Hair => "hair",
            ElementKind::Attachment => "attachment",
            ElementKind::Collider => "collider",
            ElementKind::FluidDomain => "fluid_domain",
            ElementKind::Collision => "collision",
            ElementKind::Render => "render",
        }
    }
}

/// A named per-vertex channel. Its values are shared (never changed in place: a new channel
/// replaces one), so copying an element's channels to set one of them, as a solver does with
/// `velocity` every frame, copies none of the others' values.
#[derive(Clone, Debug, PartialEq)]
pub enum Channel {
    /// One number per vertex (pin weights, masses).
    Float(Arc<[f64]>),
    /// One vector per vertex (rest positions, velocities).
    Vec3(Arc<[[f64; 3]]>),
}

impl Channel {
    /// Entries in the channel.
    pub fn len(&self) -> usize {
        match self {
            Channel::Float(v) => v.len(),
            Channel::Vec3(v) => v.len(),
        }
    }
    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One object of a scene, or a data-less element standing for an interaction.
///
/// Geometry and channels are shared (`Arc`): attaching an SEC or renaming an element copies
/// pointers, not vertices; [`SceneElement::geometry_mut`] copies on write.
#[derive(Clone, Debug)]
pub struct SceneElement {
    /// Name, unique in a scene (used in outputs and messages).
    pub name: String,
    /// What it is.
    pub kind: ElementKind,
    /// Its geometry.
    pub geometry: Arc<Geometry>,
    /// Named per-vertex channels (`rest`, `velocity`, …).
    pub channels: Arc<BTreeMap<String, Channel>>,
    /// Its Scene Element Components.
    pub secs: SecSet,
    /// Kinematic transform at the current frame (colliders and attachment targets).
    pub transform: Option<Transform>,
}

impl SceneElement {
    /// About how many bytes the element's geometry and channels hold (for memory budgets;
    /// data shared with other elements is counted in each).
    pub fn heap_bytes(&self) -> usize {
        let geometry = match &*self.geometry {
            Geometry::None => 0,
            Geometry::Mesh(m) => 24 * m.positions.len() + 12 * m.triangles.len(),
            Geometry::Curves(c) => 24 * c.positions.len() + 4 * c.offsets.len(),
            Geometry::Points(p) => 24 * p.len(),
        };
        let channels: usize = self
            .channels
            .values()
            .map(|c| match c {
                Channel::Float(v) => 8 * v.len(),
                Channel::Vec3(v) => 24 * v.len(),
            })
            .sum();
        geometry + channels + 256
    }

    /// A new element with geometry, no channels and no SECs.
    pub fn new(name: &str, kind: ElementKind, geometry: Geometry) -> Self {
        SceneElement {
            name: name.to_string(),
            kind,
            geometry: Arc::new(geometry),
            channels: Arc::new(BTreeMap::new()),
            secs: SecSet::default(),
            transform: None,
        }
    }
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.geometry.positions().len()
    }
    /// Mutable geometry, copied first if shared.
    pub fn geometry_mut(&mut self) -> &mut Geometry {
        Arc::make_mut(&mut self.geometry)
    }
    /// Sets a channel (copying the channel map if shared).
    pub fn set_channel(&mut self, name: &str, c: Channel) {
        Arc::make_mut(&mut self.channels).insert(name.to_string(), c);
    }
    /// A vec3 channel, if present with that type.
    pub fn vec3_channel(&self, name: &str) -> Option<&[[f64; 3]]> {
        match self.channels.get(name) {
            Some(Channel::Vec3(v)) => Some(v),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Mesh;

    /// Setting a channel on a copy of an element (as a solver sets `velocity` on its output
    /// every frame) leaves the original as it was and shares the other channels' values.
    #[test]
    fn setting_a_channel_on_a_copy_shares_the_other_channels() {
        let mesh = Mesh {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2]],
        };
        let mut e = SceneElement::new("sheet", ElementKind::Cloth, Geometry::Mesh(mesh));
        e.set_channel("rest", Channel::Vec3(vec![[0.5; 3]; 3].into()));
        let mut f = e.clone();
        f.set_channel("velocity", Channel::Vec3(vec![[0.0, -1.0, 0.0]; 3].into()));
        let (Some(Channel::Vec3(a)), Some(Channel::Vec3(b))) =
            (e.channels.get("rest"), f.channels.get("rest"))
        else {
            panic!("both have the rest channel");
        };
        assert!(Arc::ptr_eq(a, b));
        assert!(e.channels.get("velocity").is_none());
        assert_eq!(f.vec3_channel("velocity"), Some(&[[0.0, -1.0, 0.0]; 3][..]));
        assert_eq!(e.vec3_channel("rest"), Some(&[[0.5; 3]; 3][..]));
    }
}

//! The mechanical system: lumped masses, pinned vertices, energy elements, and its state.

use crate::energy::{
    Element, Hinge, Membrane, MidedgeBend, RodBend, RodClamp, RodStretch, ShellBend, ShellClamp,
    Spring,
};
use crate::slide::{Rail, SlideOn, Slider, Surface};
use nalgebra::{Matrix3, Vector3};
use std::sync::Arc;

/// Every energy element of a system, grouped by type (no dynamic dispatch in storage).
#[derive(Clone, Debug, Default)]
pub struct Elements {
    /// Cloth membrane triangles.
    pub membranes: Vec<Membrane>,
    /// Cloth bending hinges (the classic discrete-shell energy).
    pub hinges: Vec<Hinge>,
    /// Cloth bending, trace part (per vertex).
    pub shells: Vec<ShellBend>,
    /// Cloth bending, deviatoric part (per triangle).
    pub midedges: Vec<MidedgeBend>,
    /// Cloth bending, trace part at held vertices on clamped edges.
    pub shell_clamps: Vec<ShellClamp>,
    /// Rod segments.
    pub stretches: Vec<RodStretch>,
    /// Rod bending at interior vertices.
    pub bends: Vec<RodBend>,
    /// Rod bending at clamped roots.
    pub clamps: Vec<RodClamp>,
    /// Soft attachments.
    pub springs: Vec<Spring>,
}

impl Elements {
    /// Calls `f` on every element in a fixed order (membranes, hinges, shells,
    /// midedges, shell clamps, stretches, bends, clamps, springs): assembly order is part of
    /// determinism.
    pub fn for_each(&self, mut f: impl FnMut(&dyn Element)) {
        self.membranes.iter().for_each(|e| f(e));
        self.hinges.iter().for_each(|e| f(e));
        self.shells.iter().for_each(|e| f(e));
        self.midedges.iter().for_each(|e| f(e));
        self.shell_clamps.iter().for_each(|e| f(e));
        self.stretches.iter().for_each(|e| f(e));
        self.bends.iter().for_each(|e| f(e));
        self.clamps.iter().for_each(|e| f(e));
        self.springs.iter().for_each(|e| f(e));
    }
    /// The `i`-th element in [`Elements::for_each`] order.
    pub fn get(&self, mut i: usize) -> &dyn Element {
        macro_rules! pick {
            ($($v:ident),*) => {$(
                if i < self.$v.len() {
                    return &self.$v[i];
                }
                i -= self.$v.len();
            )*};
        }
        pick!(
            membranes,
            hinges,
            shells,
            midedges,
            shell_clamps,
            stretches,
            bends,
            clamps,
            springs
        );
        panic!("element index out of range")
    }
    /// The indices [`Self::get`] gives the midedge elements.
    pub fn midedge_range(&self) -> std::ops::Range<usize> {
        let start = self.membranes.len() + self.hinges.len() + self.shells.len();
        start..start + self.midedges.len()
    }
    /// Number of elements.
    pub fn len(&self) -> usize {
        self.membranes.len()
            + self.hinges.len()
            + self.shells.len()
            + self.midedges.len()
            + self.shell_clamps.len()
            + self.stretches.len()
            + self.bends.len()
            + self.clamps.len()
            + self.springs.len()
    }
    /// True when there are none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A solid system: what does not change from step to step.
#[derive(Clone, Debug)]
pub struct SolidSystem {
    /// Lumped mass per vertex [kg]; must be positive for every free vertex.
    pub mass: Vec<f64>,
    /// Pinned vertices follow prescribed positions (hard attachments: their DOFs are
    /// eliminated from the solve).
    pub pinned: Vec<bool>,
    /// Energy elements.
    pub elements: Elements,
    /// Gravity [m/s²].
    pub gravity: Vector3<f64>,
    /// Mass-proportional damping per vertex [1/s]: a force −c m v (empty for none).
    pub damping: Vec<f64>,
    /// Constant external force per vertex [N] (empty for none).
    pub forces: Vec<Vector3<f64>>,
    /// Drag towards a flow, per vertex (empty for none): the force −D (v − u) with D a
    /// symmetric positive semidefinite matrix [kg/s] and u the flow's velocity [m/s]. Linear
    /// in v, so implicit Euler treats it exactly (the fluid coupling lags D and u between its
    /// Newton stages).
    pub drag: Vec<VertexDrag>,
    /// Rails that sliding vertices stay on (moved between steps by the caller).
    pub rails: Vec<Rail>,
    /// Surfaces that sliding vertices stay on (replaced between steps by the caller).
    pub surfaces: Vec<Arc<dyn Surface>>,
    /// Sliding vertices ([`crate::slide`]): each stays on its rail, free along it.
    pub sliders: Vec<Slider>,
    /// Rigid groups: each group's vertices move as one rigid body (six degrees of freedom in
    /// the Newton system, `integrator/rigid.rs`).
    pub rigid: Vec<RigidGroup>,
    /// Where the vertices sit (any one configuration, e.g. the start frame's; empty for
    /// unknown): the Newton solve's fill-reducing ordering may cut the mesh by these
    /// coordinates (nested dissection, `integrator/order.rs`). It changes only the factor's
    /// cost and rounding, never what is solved.
    pub layout: Vec<Vector3<f64>>,
}

/// Vertices that move as one rigid body (a button, a clasp, a bead): their distances stay
/// those they start with.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RigidGroup {
    /// The vertices (global indices), two or more, none held, sliding or in another group.
    pub vertices: Vec<u32>,
}

/// Linear drag on one vertex: force −D (v − u).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexDrag {
    /// Drag matrix D [kg/s], symmetric positive semidefinite.
    pub matrix: Matrix3<f64>,
    /// The flow velocity u at the vertex [m/s].
    pub flow: Vector3<f64>,
}

impl Default for VertexDrag {
    fn default() -> Self {
        VertexDrag {
            matrix: Matrix3::zeros(),
            flow: Vector3::zeros(),
        }
    }
}

impl SolidSystem {
    /// A system of `n` free vertices with the given masses and no elements.
    pub fn new(mass: Vec<f64>) -> Self {
        let n = mass.len();
        SolidSystem {
            mass,
            pinned: vec![false; n],
            elements: Elements::default(),
            gravity: Vector3::zeros(),
            damping: Vec::new(),
            forces: Vec::new(),
            drag: Vec::new(),
            rails: Vec::new(),
            surfaces: Vec::new(),
            sliders: Vec::new(),
            rigid: Vec::new(),
            layout: Vec::new(),
        }
    }
    /// Damping coefficient of vertex `i` [1/s] (zero when none are set).
    pub fn damping(&self, i: usize) -> f64 {
        self.damping.get(i).copied().unwrap_or(0.0)
    }
    /// External force on vertex `i` (zero when none are set).
    pub fn force(&self, i: usize) -> Vector3<f64> {
        self.forces.get(i).copied().unwrap_or_else(Vector3::zeros)
    }
    /// Drag on vertex `i` (none when none are set).
    pub fn drag(&self, i: usize) -> Option<&VertexDrag> {
        self.drag.get(i)
    }
}

/// Positions and velocities.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Positions [m].
    pub x: Vec<Vector3<f64>>,
    /// Velocities [m/s].
    pub v: Vec<Vector3<f64>>,
}

/// Why a system cannot be simulated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SystemError {
    /// Arrays disagree in length.
    ///
    /// `mass` has 10 entries but the state has 12 vertices.
    #[error("{what} has {got} entries, expected {want}")]
    Length {
        /// Which array.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The vertex count.
        want: usize,
    },
    /// A free vertex has no mass (it would have infinite acceleration).
    ///
    /// Vertex 3 is free with mass 0.
    #[error("vertex {vertex} is free but has mass {mass} (must be > 0)")]
    Massless {
        /// The vertex.
        vertex: usize,
        /// Its mass.
        mass: f64,
    },
    /// An element names a vertex that does not exist.
    ///
    /// A hinge on vertex 99 of a 50-vertex system.
    #[error("an element uses vertex {vertex}, but there are {n} vertices")]
    VertexOutOfRange {
        /// The index.
        vertex: usize,
        /// Vertex count.
        n: usize,
    },
    /// A sliding vertex that cannot slide: out of range, held, in a rigid group, listed twice,
    /// with a negative
    /// or non-finite friction, or on a rail that does not exist or has no segment of positive,
    /// finite length (or a surface that does not exist).
    ///
    /// Vertex 4 slides on rail 2, but there are 2 rails.
    #[error("sliding vertex {vertex}: {reason}")]
    BadSlider {
        /// The vertex.
        vertex: usize,
        /// What is wrong.
        reason: String,
    },
    /// A rigid group that cannot move as one: too few vertices, one out of range, held or in
    /// two groups; or a step method that cannot keep it rigid.
    ///
    /// Rigid group 1: vertex 8 is also held in place.
    #[error("rigid group {group}: {reason}")]
    BadRigid {
        /// The group's index.
        group: usize,
        /// What is wrong.
        reason: String,
    },
    /// A position or velocity is NaN or infinite.
    ///
    /// Vertex 7's rest position is NaN.
    #[error("vertex {vertex} has a non-finite {what}")]
    NonFinite {
        /// The vertex.
        vertex: usize,
        /// `position` or `velocity`.
        what: &'static str,
    },
}

impl SolidSystem {
    /// Checks the system against a state before simulating.
    pub fn check(&self, state: &State) -> Result<(), SystemError> {
        let n = state.x.len();
        for (what, got) in [
            ("velocity", state.v.len()),
            ("mass", self.mass.len()),
            ("pinned", self.pinned.len()),
            ("forces", self.forces.len()),
            ("drag", self.drag.len()),
        ] {
            if got != n && !((what == "forces" || what == "drag") && got == 0) {
                return Err(SystemError::Length { what, got, want: n });
            }
        }
        for i in 0..n {
            if !self.pinned[i]
                && (self.mass[i].is_nan() || self.mass[i] <= 0.0 || self.mass[i].is_infinite())
            {
                return Err(SystemError::Massless {
                    vertex: i,
                    mass: self.mass[i],
                });
            }
            if !state.x[i].iter().all(|c| c.is_finite()) {
                return Err(SystemError::NonFinite {
                    vertex: i,
                    what: "position",
                });
            }
            if let Some(d) = self.drag.get(i)
                && !(d.matrix.iter().chain(d.flow.iter()).all(|c| c.is_finite())
                    && d.matrix == d.matrix.transpose())
            {
                return Err(SystemError::NonFinite {
                    vertex: i,
                    what: "drag (or an asymmetric drag matrix)",
                });
            }
            if !state.v[i].iter().all(|c| c.is_finite()) {
                return Err(SystemError::NonFinite {
                    vertex: i,
                    what: "velocity",
                });
            }
        }
        let mut bad = None;
        self.elements.for_each(|e| {
            if let Some(&v) = e.vertices().iter().find(|&&v| v as usize >= n) {
                bad.get_or_insert(v as usize);
            }
        });
        if let Some(vertex) = bad {
            return Err(SystemError::VertexOutOfRange { vertex, n });
        }
        // Per-vertex flags only when there is something to flag (this runs every step).
        let flags = |k: usize| vec![false; if k == 0 { 0 } else { n }];
        let mut grouped = flags(self.rigid.len());
        // Per vertex, its group (when there are groups and sliders: a slider on a member
        // slides the whole group, one slider a group).
        let mut group_of = vec![
            u32::MAX;
            if self.sliders.is_empty() {
                0
            } else {
                grouped.len()
            }
        ];
        for (group, g) in self.rigid.iter().enumerate() {
            let fail = |reason: String| Err(SystemError::BadRigid { group, reason });
            if g.vertices.len() < 2 {
                return fail(format!(
                    "it has {} vertices; a rigid group needs two or more",
                    g.vertices.len()
                ));
            }
            for &v in &g.vertices {
                let v = v as usize;
                if v >= n {
                    return fail(format!("vertex {v} is out of range ({n} vertices)"));
                }
                if self.pinned[v] {
                    return fail(format!("vertex {v} is also held in place"));
                }
                if std::mem::replace(&mut grouped[v], true) {
                    return fail(format!("vertex {v} is in it twice, or in another group"));
                }
                if let Some(s) = group_of.get_mut(v) {
                    *s = group as u32;
                }
            }
        }
        let mut sliding = flags(self.sliders.len());
        let mut group_slides = vec![false; self.rigid.len()];
        for sl in &self.sliders {
            let vertex = sl.vertex as usize;
            let fail = |reason: String| Err(SystemError::BadSlider { vertex, reason });
            if vertex >= n {
                return fail(format!("there are {n} vertices"));
            }
            if self.pinned[vertex] {
                return fail("it is also held in place".into());
            }
            if std::mem::replace(&mut sliding[vertex], true) {
                return fail("it is listed twice".into());
            }
            if let Some(&g) = group_of.get(vertex).filter(|&&g| g != u32::MAX)
                && std::mem::replace(&mut group_slides[g as usize], true)
            {
                return fail(format!(
                    "rigid group {g} already slides (one slider a group: its centroid slides)"
                ));
            }
            if !(sl.friction >= 0.0 && sl.friction.is_finite()) {
                return fail(format!(
                    "friction must be ≥ 0 and finite, got {}",
                    sl.friction
                ));
            }
            match sl.on {
                SlideOn::Rail(k) => match self.rails.get(k as usize) {
                    None => {
                        return fail(format!(
                            "it slides on rail {k}, but there are {} rails",
                            self.rails.len()
                        ));
                    }
                    Some(r) if !r.is_usable() => {
                        return fail(format!(
                            "rail {k} has no segment of positive, finite length"
                        ));
                    }
                    Some(_) => {}
                },
                SlideOn::Surface(k) => {
                    if self.surfaces.get(k as usize).is_none() {
                        return fail(format!(
                            "it slides on surface {k}, but there are {} surfaces",
                            self.surfaces.len()
                        ));
                    }
                }
                SlideOn::Point(p) => {
                    if !p.iter().all(|c| c.is_finite()) {
                        return fail(format!("it is held at a non-finite point {p:?}"));
                    }
                }
            }
        }
        Ok(())
    }
}

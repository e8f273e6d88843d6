//! Scene Element Components: typed per-object parameter bundles that Behaviors read.
//!
//! An SEC type is any type implementing [`Sec`]; a plugin adds one without touching this crate
//! (and exposes it in graphs by registering a node that attaches it). A Behavior that finds no
//! SEC of its kind on an element uses the type's documented `Default`.

use crate::fields::{ge, ge_le, ge_lt, gt, text, vec3};
use std::any::Any;
use std::collections::BTreeMap;
use std::fmt::Debug;
use std::sync::Arc;

/// A Scene Element Component.
pub trait Sec: Any + Send + Sync + Debug {
    /// Type name (`"discrete_shell"`), unique among SEC types.
    fn sec_type(&self) -> &'static str;
    /// The parameters as JSON, for reports and `--stats`.
    fn describe(&self) -> serde_json::Value;
    /// Upcast for typed access.
    fn as_any(&self) -> &dyn Any;
    /// Whether `other` is an SEC of the same type with the same values (solvers re-read SECs
    /// whose values an animated parameter changed). The default answers false: a solver
    /// then rebuilds from it whenever it is a new value.
    fn same(&self, _other: &dyn Sec) -> bool {
        false
    }
}

/// The SECs of one element: at most one per type, shared (`Arc`) so copying an element is cheap.
#[derive(Clone, Debug, Default)]
pub struct SecSet {
    map: BTreeMap<&'static str, Arc<dyn Sec>>,
}

impl SecSet {
    /// Adds or replaces the SEC of this type.
    pub fn insert(&mut self, sec: impl Sec) {
        self.map.insert(sec.sec_type(), Arc::new(sec));
    }
    /// The SEC of type `T`, if attached.
    pub fn get<T: Sec>(&self) -> Option<&T> {
        self.map
            .values()
            .find_map(|s| s.as_any().downcast_ref::<T>())
    }
    /// Names of the attached SEC types, sorted.
    pub fn types(&self) -> impl Iterator<Item = &'static str> + '_ {
        self.map.keys().copied()
    }
    /// Every SEC.
    pub fn iter(&self) -> impl Iterator<Item = &Arc<dyn Sec>> {
        self.map.values()
    }
    /// Whether both sets hold the same SEC types with the same values (shared ones are not
    /// compared further).
    pub fn same_as(&self, other: &SecSet) -> bool {
        self.map.len() == other.map.len()
            && self
                .map
                .iter()
                .zip(&other.map)
                .all(|((ka, a), (kb, b))| ka == kb && (Arc::ptr_eq(a, b) || a.same(&**b)))
    }
    /// Number of SECs.
    pub fn len(&self) -> usize {
        self.map.len()
    }
    /// True when none.
    pub fn is_empty(&self) -> bool {
        self.map.is_empty()
    }
}

macro_rules! sec_impl {
    ($t:ty, $name:literal) => {
        impl Sec for $t {
            fn sec_type(&self) -> &'static str {
                $name
            }
            fn describe(&self) -> serde_json::Value {
                serde_json::json!(format!("{self:?}"))
            }
            fn as_any(&self) -> &dyn Any {
                self
            }
            fn same(&self, other: &dyn Sec) -> bool {
                other.as_any().downcast_ref::<Self>() == Some(self)
            }
        }
    };
}

/// The bend angle dropoff's doc (Discrete Shell and Rod SECs alike).
macro_rules! dropoff_doc {
    () => {
        "bend angle dropoff d: bending stiffness × (1 − d + d (κ/κ₀)²) at curvature κ (soft for small bends, stiffer for large; 0: none; `weft_solid::energy::Dropoff`)"
    };
}

crate::sec_fields! {
    /// Discrete Shell: membrane and bending of cloth (SI units).
    pub struct DiscreteShell: "discrete_shell",
        "Discrete Shell SEC: membrane (StVK, optionally orthotropic) and bending of cloth" {
        youngs_modulus: f64 = 1e6, gt(0.0), "Pa", "Young's modulus E";
        poisson_ratio: f64 = 0.3, ge_lt(0.0, 0.5), "", "Poisson's ratio ν";
        thickness: f64 = 1e-3, gt(0.0), "m", "shell thickness t";
        bend_scale: f64 = 1.0, ge(0.0), "", "multiplier on D = E t³/(12(1 − ν²)); 0 disables bending";
        damping: f64 = 0.0, ge(0.0), "1/s", "mass-proportional damping";
        rest_channel: String = "rest", text(), "", "channel with rest positions (initial positions when absent)";
        warp_scale: f64 = 1.0, gt(0.0), "", "stiffness multiplier along the warp";
        weft_scale: f64 = 1.0, gt(0.0), "", "stiffness multiplier along the weft";
        shear_scale: f64 = 1.0, gt(0.0), "", "shear stiffness multiplier";
        warp_direction: [f64; 3] = [1.0, 0.0, 0.0], vec3(), "", "warp direction in rest space (projected into each triangle)";
        bend_dropoff: f64 = 0.0, ge_le(0.0, 1.0), "", dropoff_doc!();
        dropoff_curvature: f64 = 20.0, gt(0.0), "1/m", "κ₀ of the dropoff: the curvature (1/radius) at which the plain stiffness holds";
    }
}

crate::sec_fields! {
    /// Rod: stretching and bending of hair (SI units).
    pub struct Rod: "rod", "Rod SEC: stretching and bending of hair" {
        youngs_modulus: f64 = 3e9, gt(0.0), "Pa", "Young's modulus E (3e9: keratin)";
        radius: f64 = 5e-5, gt(0.0), "m", "fibre radius r";
        stretch_scale: f64 = 1.0, gt(0.0), "", "multiplier on the axial stiffness E·πr² (lower it for stretchy strands)";
        bend_stiffness: f64 = 0.0, ge(0.0), "N·m²", "bending stiffness EI; 0 derives it as E·πr⁴/4";
        bend_scale: f64 = 1.0, ge(0.0), "", "multiplier on the bending stiffness; 0 disables bending";
        damping: f64 = 0.0, ge(0.0), "1/s", "mass-proportional damping";
        rest_channel: String = "rest", text(), "", "channel with rest positions (initial positions when absent)";
        bend_dropoff: f64 = 0.0, ge_le(0.0, 1.0), "", dropoff_doc!();
        dropoff_curvature: f64 = 20.0, gt(0.0), "1/m", "κ₀ of the dropoff: the curvature (1/radius) at which the plain stiffness holds";
    }
}

crate::sec_fields! {
    /// Density: mass per area of cloth and per length of hair.
    pub struct Density: "density", "Density SEC: mass per area of cloth and per length of hair" {
        area_density: f64 = 0.2, gt(0.0), "kg/m²", "cloth mass per rest area";
        line_density: f64 = 1e-5, gt(0.0), "kg/m", "hair mass per rest length (1e-5: a 50 µm keratin fibre)";
    }
}

crate::sec_fields! {
    /// Drag: how hair or cloth exchanges momentum with a surrounding fluid (the seed's
    /// anisotropic drag, Fei et al. 2018). Coefficients C_l = 1/k_l + ξ_N·1.75/√(150 k_l)·(1 −
    /// γ)^(−3/2)·Re^c with 1/k_l = ξ_D ξ_l / 10⁴; force −(μV/D²) R C Rᵀ Δv; lift ξ_L. The
    /// law itself is `weft_fluid::DragLaw`.
    #[derive(Copy)]
    pub struct Drag: "drag",
        "Drag SEC: how hair or cloth exchanges momentum with a fluid (the seed's anisotropic drag: C_l = 1/k_l + xi_N 1.75/sqrt(150 k_l) (1 - gamma)^-1.5 Re^c, 1/k_l = xi_D xi_l / 1e4; force -(mu V/D^2) R C R^T dv; lift xi_L)" {
        xi_d: f64 = 1.0, ge(0.0), "", "global drag scale ξ_D";
        xi_perp: f64 = 1.0, ge(0.0), "", "normal drag scale ξ⊥";
        xi_par: f64 = 0.5, ge(0.0), "", "tangential drag scale ξ∥";
        xi_n: f64 = 0.0, ge(0.0), "", "nonlinear (inertial) term scale ξ_N; 0: linear drag";
        xi_l: f64 = 0.0, ge(0.0), "", "lift scale ξ_L; 0: no lift";
        diameter: f64 = 1e-4, gt(0.0), "m", "fibre diameter D";
        gamma: f64 = 0.1, ge_lt(0.0, 1.0), "", "material fraction γ";
        degree: f64 = 1.0, ge(0.0), "", "drag degree c: the exponent of the Reynolds number";
    }
}

/// What one side of a fluid domain does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DomainSide {
    /// A fixed wall: no flow through it.
    Wall,
    /// Flow leaving through the opposite side re-enters here (both sides of the axis).
    Periodic,
    /// The domain's `flow` velocity is prescribed here (a current or a wind).
    Inflow,
    /// Open to still fluid at zero gauge pressure.
    Open,
}

/// Fluid Domain: the box a fluid fills, how finely it is resolved, and its sides. Carried by
/// a data-less fluid-domain element; a scene without one has no fluid (and no grid).
#[derive(Clone, Debug, PartialEq)]
pub struct FluidDomain {
    /// Explicit bounds (minimum, maximum corner) [m]; `None`: the solids' bounds plus
    /// `padding` (default `None`).
    pub bounds: Option<([f64; 3], [f64; 3])>,
    /// Margin around the solids for automatic bounds [m] (default 0.1).
    pub padding: f64,
    /// Cell size Δx [m] (default 0.02).
    pub cell_size: f64,
    /// Sides at the minimum of x, y, z (default walls).
    pub lo: [DomainSide; 3],
    /// Sides at the maximum of x, y, z (default walls).
    pub hi: [DomainSide; 3],
    /// The current or wind [m/s]: the velocity at inflow sides and the fluid's initial
    /// velocity (default 0).
    pub flow: [f64; 3],
}

impl Default for FluidDomain {
    fn default() -> Self {
        FluidDomain {
            bounds: None,
            padding: 0.1,
            cell_size: 0.02,
            lo: [DomainSide::Wall; 3],
            hi: [DomainSide::Wall; 3],
            flow: [0.0; 3],
        }
    }
}
sec_impl!(FluidDomain, "fluid_domain");

/// Fluid: the material filling a fluid domain (SI units). Presets: [`Fluid::WATER`] (the
/// default) and [`Fluid::AIR`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fluid {
    /// Density ρ [kg/m³].
    pub density: f64,
    /// Dynamic viscosity μ [Pa·s].
    pub viscosity: f64,
}

impl Fluid {
    /// Water at 20 °C.
    pub const WATER: Fluid = Fluid {
        density: 998.2,
        viscosity: 1.002e-3,
    };
    /// Air at 20 °C, sea level.
    pub const AIR: Fluid = Fluid {
        density: 1.204,
        viscosity: 1.81e-5,
    };
}

impl Default for Fluid {
    fn default() -> Self {
        Fluid::WATER
    }
}
sec_impl!(Fluid, "fluid");

/// How attached vertices follow their target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AttachmentMode {
    /// Exactly (the vertices' degrees of freedom are eliminated).
    Hard,
    /// Through a zero-length spring of this stiffness [N/m].
    Spring(f64),
    /// On a rail or a surface, free along it (exactly: the [`SlideRail`] and
    /// [`SlideSurface`] SECs on the same attachment element give them), with this Coulomb
    /// friction coefficient along it.
    Slide {
        /// μ ≥ 0.
        friction: f64,
    },
    /// As one rigid body (free: to hold it as well, attach it hard), with this much mass
    /// [kg] added, shared equally among the vertices (a button's, a bead's).
    Rigid {
        /// Added mass ≥ 0 [kg].
        mass: f64,
    },
    /// Frozen to the target element's animated input, by `weight` (times the per-vertex
    /// factors of a [`FreezeWeights`] SEC on the same element): at w ≥ 1 each vertex is
    /// exactly at its input position; at 0 < w < 1 a zero-length spring of stiffness
    /// w/(1 − w)·m/Δt² (m the vertex's mass, Δt the frame time) pulls it there; at 0 it is
    /// free. Read at every frame, so an animated weight locks and releases regions.
    Freeze {
        /// w ≥ 0 (values above 1 hold as 1 does).
        weight: f64,
    },
}

/// Freeze Weights: per listed vertex of a freeze attachment (in the order of its
/// [`Attachment::vertices`]), a factor ≥ 0 on the attachment's weight.
#[derive(Clone, Debug, PartialEq)]
pub struct FreezeWeights {
    /// One factor per listed vertex.
    pub weights: Vec<f64>,
}
sec_impl!(FreezeWeights, "freeze_weights");

/// Slide Rail: the curves a sliding attachment's vertices stay on (polylines, in the frame
/// of the attachment element's transform; world when it has none). Each vertex slides on
/// the curve nearest to it at the start, and is moved onto it there.
#[derive(Clone, Debug, PartialEq)]
pub struct SlideRail {
    /// The rails.
    pub curves: crate::Curves,
}
sec_impl!(SlideRail, "slide_rail");

/// Slide Surface: a triangle mesh a sliding attachment's vertices stay on (in the frame of the
/// attachment element's transform; world when it has none). With a Slide Rail as well, each
/// vertex takes whichever is nearest to it at the start.
#[derive(Clone, Debug, PartialEq)]
pub struct SlideSurface {
    /// The surface.
    pub mesh: crate::Mesh,
}
sec_impl!(SlideSurface, "slide_surface");

/// Attachment: vertices of a target element that follow a fixed point or an animated
/// transform. Carried by a data-less attachment element.
#[derive(Clone, Debug, PartialEq)]
pub struct Attachment {
    /// Name of the element whose vertices are attached.
    pub target: String,
    /// Attached vertex indices, within the target element.
    pub vertices: Vec<u32>,
    /// Hard or spring.
    pub mode: AttachmentMode,
    /// Clamps, each (root, next) in the target's indices: the strand leaves `root` along the
    /// direction it has towards `next` at the start, turned with the transform. The root is
    /// normally also in `vertices`; `next` stays free (hair only: see
    /// `weft_solid::energy::RodClamp`).
    pub clamps: Vec<[u32; 2]>,
}
sec_impl!(Attachment, "attachment");

impl Attachment {
    /// The roots of every curve, `root_vertices` (k ≥ 1) vertices a root. k = 1: the first
    /// vertex is held and the strand turns freely about it (a pin joint). k ≥ 2: the first
    /// k − 1 vertices are held and the strand is clamped at the last of them, leaving it along
    /// the direction it starts with; the next vertex is free, so a strand clamped with
    /// k = 2 bends over its whole length. (Holding k vertices without a clamp would clamp the
    /// tangent half a segment further out: a strand too stiff by an amount that changes with
    /// its resolution.) Curves too short for a clamp are held without one.
    pub fn curve_roots(
        target: &str,
        curves: &crate::Curves,
        root_vertices: u32,
        mode: AttachmentMode,
    ) -> Attachment {
        let k = root_vertices.max(1);
        let held = if k == 1 { 1 } else { k - 1 };
        let mut vertices = Vec::new();
        let mut clamps = Vec::new();
        for c in 0..curves.len() {
            let r = curves.range(c);
            let (start, end) = (r.start as u32, r.end as u32);
            vertices.extend(start..(start + held).min(end));
            let root = start + held - 1;
            if k >= 2 && root + 1 < end {
                clamps.push([root, root + 1]);
            }
        }
        Attachment {
            target: target.into(),
            vertices,
            mode,
            clamps,
        }
    }

    /// The clamps of held `vertices` on `geometry`. Cloth: every boundary edge (in one
    /// triangle) whose two vertices are held, so the cloth's tangent plane is held along its
    /// held border. Strands: every held vertex whose next vertex on the strand is not held
    /// (where the free strand leaves what is held). In ascending order.
    pub fn clamps_of(geometry: &crate::Geometry, vertices: &[u32]) -> Vec<[u32; 2]> {
        let held: std::collections::BTreeSet<u32> = vertices.iter().copied().collect();
        match geometry {
            crate::Geometry::Mesh(m) => {
                let mut count: BTreeMap<[u32; 2], u32> = BTreeMap::new();
                for t in &m.triangles {
                    for k in 0..3 {
                        let (a, b) = (t[k], t[(k + 1) % 3]);
                        *count.entry([a.min(b), a.max(b)]).or_default() += 1;
                    }
                }
                count
                    .into_iter()
                    .filter(|(e, c)| *c == 1 && held.contains(&e[0]) && held.contains(&e[1]))
                    .map(|(e, _)| e)
                    .collect()
            }
            crate::Geometry::Curves(c) => (0..c.len())
                .flat_map(|k| {
                    let r = c.range(k);
                    let held = &held;
                    r.clone().filter_map(move |v| {
                        let v = v as u32;
                        (held.contains(&v)
                            && ((v + 1) as usize) < r.end
                            && !held.contains(&(v + 1)))
                        .then_some([v, v + 1])
                    })
                })
                .collect(),
            _ => Vec::new(),
        }
    }
}

crate::sec_fields! {
    /// Collider: how a cloth, hair or collider element meets others in contact (with
    /// `behavior.collision` and a collision group). A contact keeps the sum of both sides'
    /// thicknesses, uses the geometric mean of their friction coefficients and the larger
    /// cohesion; a collider without it takes the simulated element's friction and cohesion
    /// and adds no thickness; a simulated element without it uses the defaults.
    pub struct Collider: "collider",
        "Collider SEC: how a cloth, hair or collider element meets others in contact (with behavior.collision and a collision group); a contact keeps the sum of both sides' thicknesses, uses the geometric mean of their friction coefficients and the larger cohesion; a collider without it takes the other side's friction and cohesion" {
        friction: f64 = 0.3, ge(0.0), "", "Coulomb friction coefficient μ (0.3: cotton on skin)";
        thickness: f64 = 1e-3, gt(0.0), "m", "distance kept from the surface";
        cohesion: f64 = 0.0, ge(0.0), "Pa", "the most a contact may pull per m² of contact area (cloth: a third of a vertex's triangles; hair: its segments' length × diameter)";
    }
}

/// Which elements a collision group names.
#[derive(Clone, Debug, PartialEq)]
pub enum Members {
    /// Every element of the right kind.
    All,
    /// These element names.
    Names(Vec<String>),
}

impl Members {
    /// Parses `"all"` or a comma-separated list of names (blanks around names ignored).
    pub fn parse(s: &str) -> Members {
        if s.trim() == "all" {
            return Members::All;
        }
        Members::Names(
            s.split(',')
                .map(|n| n.trim().to_string())
                .filter(|n| !n.is_empty())
                .collect(),
        )
    }
    /// True when `name` is a member.
    pub fn contains(&self, name: &str) -> bool {
        match self {
            Members::All => true,
            Members::Names(n) => n.iter().any(|m| m == name),
        }
    }
}

/// Collision Group: which simulated elements collide with which colliders and with each other
/// (and themselves), and how contacts are detected. Carried by a data-less collision element; several may coexist, each with its
/// own members and methods.
#[derive(Clone, Debug, PartialEq)]
pub struct CollisionGroup {
    /// Simulated elements (cloth, hair) that collide (default all).
    pub members: Members,
    /// Collider elements they collide with (default all).
    pub colliders: Members,
    /// Vertex–face: every vertex of a member against the colliders' triangles (default on).
    pub vertex_face: bool,
    /// Segment–face: every hair segment against the colliders' triangles, so a strand
    /// touches between its vertices too (default on; cloth has no segments).
    pub segment_face: bool,
    /// Edge–edge: between members, every cloth edge and hair segment against the others'
    /// (default on): crossing edges touch between their vertices, and hair on hair has no
    /// faces.
    pub edge_edge: bool,
    /// Members collide with each other (default on): layers of clothing, hair on a collar.
    pub between_members: bool,
    /// Each member collides with itself (default off): a skirt folding onto itself, strands
    /// of one groom on each other. Primitives that share a vertex never collide.
    pub self_collision: bool,
}

impl Default for CollisionGroup {
    fn default() -> Self {
        CollisionGroup {
            members: Members::All,
            colliders: Members::All,
            vertex_face: true,
            segment_face: true,
            edge_edge: true,
            between_members: true,
            self_collision: false,
        }
    }
}
sec_impl!(CollisionGroup, "collision_group");

/// Collision Response: how hard a collision group's contacts act.
#[derive(Clone, Debug, PartialEq)]
pub struct CollisionResponse {
    /// Fraction of an existing penetration resolved per step, in (0, 1] (default 0.5): a
    /// start that is already inside a collider separates over a few steps instead of at
    /// once.
    pub strength: f64,
    /// Damping of the normal relative velocity at a contact [1/s], ≥ 0 (default 0): a force
    /// −c m (n·(v − v_collider)) n on each touching vertex.
    pub damping: f64,
}

impl Default for CollisionResponse {
    fn default() -> Self {
        CollisionResponse {
            strength: 0.5,
            damping: 0.0,
        }
    }
}
sec_impl!(CollisionResponse, "collision_response");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_sec_per_type_typed_access() {
        let mut s = SecSet::default();
        s.insert(DiscreteShell::default());
        s.insert(DiscreteShell {
            thickness: 2e-3,
            ..Default::default()
        });
        s.insert(Density::default());
        assert_eq!(s.len(), 2);
        assert_eq!(s.get::<DiscreteShell>().unwrap().thickness, 2e-3);
        assert!(s.get::<Rod>().is_none());
        assert_eq!(
            s.types().collect::<Vec<_>>(),
            vec!["density", "discrete_shell"]
        );
    }

    #[test]
    fn sets_compare_by_value_not_by_sharing() {
        let make = |t: f64| {
            let mut s = SecSet::default();
            s.insert(DiscreteShell {
                thickness: t,
                ..Default::default()
            });
            s.insert(Density::default());
            s
        };
        let a = make(1e-3);
        assert!(a.same_as(&a.clone()), "shared");
        assert!(a.same_as(&make(1e-3)), "equal values, separate SECs");
        assert!(!a.same_as(&make(2e-3)), "a value differs");
        let mut fewer = SecSet::default();
        fewer.insert(DiscreteShell::default());
        assert!(!a.same_as(&fewer), "a type is missing");
    }
}

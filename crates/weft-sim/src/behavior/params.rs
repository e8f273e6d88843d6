//! What the Behaviors share in reading their SECs: the errors naming a bad parameter, the
//! range checks of an SEC's table, rest positions from a channel, and a rod's section. Kept
//! apart so that the materials and the attachments (which clamp rods) read them alike.

use crate::error::SimError;
use nalgebra::Vector3;
use weft_scene::fields::SecFields;
use weft_scene::{Rod, SceneElement};
use weft_solid::energy::RodSection;

pub(crate) fn bad(element: &str, field: &str, message: String) -> SimError {
    SimError::BadParameter {
        element: element.into(),
        field: field.into(),
        message,
    }
}

pub(crate) fn non_negative(element: &str, field: &str, x: f64) -> Result<(), SimError> {
    if x >= 0.0 && x.is_finite() {
        Ok(())
    } else {
        Err(bad(element, field, format!("must be >= 0, got {x}")))
    }
}

/// Checks an SEC against its table's ranges (`weft_scene::fields`): the node that attached
/// it checked the same ranges, but a host or plugin may build the struct itself.
pub(crate) fn checked<S: SecFields>(element: &str, sec: &S) -> Result<(), SimError> {
    sec.check()
        .map_err(|err| bad(element, &err.field, err.message))
}

pub(super) fn v3(p: [f64; 3]) -> Vector3<f64> {
    Vector3::new(p[0], p[1], p[2])
}

/// Rest positions: the named channel if present (its length must match), else the current
/// positions.
pub(super) fn rest_positions<'a>(
    e: &'a SceneElement,
    channel: &str,
) -> Result<&'a [[f64; 3]], SimError> {
    let n = e.vertex_count();
    match e.vec3_channel(channel) {
        Some(r) if r.len() == n => Ok(r),
        Some(r) => Err(SimError::BadGeometry {
            element: e.name.clone(),
            message: format!(
                "rest channel '{channel}' has {} entries but the element has {n} vertices",
                r.len()
            ),
        }),
        None => Ok(e.geometry.positions()),
    }
}

/// A rod's axial and bending stiffnesses from its SEC (`weft_solid::energy::RodSection`).
pub(super) fn rod_section(rod: &Rod) -> RodSection {
    RodSection::round(
        rod.youngs_modulus,
        rod.radius,
        rod.stretch_scale,
        rod.bend_stiffness,
        rod.bend_scale,
    )
}

//! SECs declared once: each field's name, type, default, range, unit and doc in one table
//! ([`sec_fields!`]), from which the struct, its `Default`, the node that attaches it
//! (weft-nodes builds its parameters and reads them back generically) and the range check
//! that every reader runs ([`SecFields::check`]) all come.
//!
//! An SEC reaches a solver from a graph's node (whose parameters the loader has checked), or
//! from a host or plugin that builds the struct itself: the Behaviors check it again, from
//! the same table, so both ways refuse the same values with the same message.

use std::ops::Bound;

/// What values a field takes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FieldKind {
    /// A float in a range (not NaN; infinite only where the range is unbounded that way).
    Float {
        /// Lower bound.
        min: Bound<f64>,
        /// Upper bound.
        max: Bound<f64>,
    },
    /// Text (a channel's name).
    Text,
    /// `[x, y, z]`.
    Vec3,
}

/// A float field greater than `x`.
pub const fn gt(x: f64) -> FieldKind {
    FieldKind::Float {
        min: Bound::Excluded(x),
        max: Bound::Unbounded,
    }
}

/// A float field at least `x`.
pub const fn ge(x: f64) -> FieldKind {
    FieldKind::Float {
        min: Bound::Included(x),
        max: Bound::Unbounded,
    }
}

/// A float field in `[lo, hi)`.
pub const fn ge_lt(lo: f64, hi: f64) -> FieldKind {
    FieldKind::Float {
        min: Bound::Included(lo),
        max: Bound::Excluded(hi),
    }
}

/// A float field in `[lo, hi]`.
pub const fn ge_le(lo: f64, hi: f64) -> FieldKind {
    FieldKind::Float {
        min: Bound::Included(lo),
        max: Bound::Included(hi),
    }
}

/// A text field.
pub const fn text() -> FieldKind {
    FieldKind::Text
}

/// A three-vector field.
pub const fn vec3() -> FieldKind {
    FieldKind::Vec3
}

/// One field of an SEC.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Field {
    /// Name, as the field and the node's parameter.
    pub name: &'static str,
    /// Values it takes.
    pub kind: FieldKind,
    /// SI unit (`"Pa"`, `"m"`), empty for dimensionless.
    pub unit: &'static str,
    /// One line: what it is.
    pub doc: &'static str,
}

/// A field's value.
#[derive(Clone, Debug, PartialEq)]
pub enum FieldValue {
    /// A float.
    Float(f64),
    /// Text.
    Text(String),
    /// A three-vector.
    Vec3([f64; 3]),
}

/// The Rust types an SEC's fields have.
pub trait FieldType: Sized {
    /// As a value.
    fn to_value(&self) -> FieldValue;
    /// From a value of the right kind.
    fn from_value(v: FieldValue) -> Option<Self>;
}

impl FieldType for f64 {
    fn to_value(&self) -> FieldValue {
        FieldValue::Float(*self)
    }
    fn from_value(v: FieldValue) -> Option<Self> {
        match v {
            FieldValue::Float(x) => Some(x),
            _ => None,
        }
    }
}

impl FieldType for String {
    fn to_value(&self) -> FieldValue {
        FieldValue::Text(self.clone())
    }
    fn from_value(v: FieldValue) -> Option<Self> {
        match v {
            FieldValue::Text(s) => Some(s),
            _ => None,
        }
    }
}

impl FieldType for [f64; 3] {
    fn to_value(&self) -> FieldValue {
        FieldValue::Vec3(*self)
    }
    fn from_value(v: FieldValue) -> Option<Self> {
        match v {
            FieldValue::Vec3(a) => Some(a),
            _ => None,
        }
    }
}

/// A field whose value is out of its range: `poisson_ratio must be in [0, 0.5), got 0.5`.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldError {
    /// `sec.field` (`discrete_shell.poisson_ratio`).
    pub field: String,
    /// What is wrong (`must be in [0, 0.5), got 0.5`).
    pub message: String,
}

/// The range of `kind` in words: `> 0`, `>= 0`, `in [0, 0.5)`; empty when unbounded.
pub fn range_text(kind: &FieldKind) -> String {
    let FieldKind::Float { min, max } = kind else {
        return String::new();
    };
    match (min, max) {
        (Bound::Unbounded, Bound::Unbounded) => String::new(),
        (Bound::Excluded(a), Bound::Unbounded) => format!("> {a}"),
        (Bound::Included(a), Bound::Unbounded) => format!(">= {a}"),
        (Bound::Unbounded, Bound::Excluded(b)) => format!("< {b}"),
        (Bound::Unbounded, Bound::Included(b)) => format!("<= {b}"),
        (lo, hi) => {
            let (l, a) = match lo {
                Bound::Included(a) => ('[', a),
                Bound::Excluded(a) => ('(', a),
                Bound::Unbounded => unreachable!("matched above"),
            };
            let (h, b) = match hi {
                Bound::Included(b) => (']', b),
                Bound::Excluded(b) => (')', b),
                Bound::Unbounded => unreachable!("matched above"),
            };
            format!("in {l}{a}, {b}{h}")
        }
    }
}

/// Whether `x` is in `kind`'s range (NaN never is; an infinity only past an unbounded end).
pub fn in_range(kind: &FieldKind, x: f64) -> bool {
    let FieldKind::Float { min, max } = kind else {
        return true;
    };
    let lo = match min {
        Bound::Included(a) => x >= *a && x.is_finite(),
        Bound::Excluded(a) => x > *a && x.is_finite(),
        Bound::Unbounded => !x.is_nan(),
    };
    let hi = match max {
        Bound::Included(b) => x <= *b,
        Bound::Excluded(b) => x < *b,
        Bound::Unbounded => true,
    };
    lo && hi
}

/// An SEC declared by a table ([`sec_fields!`]).
pub trait SecFields: Default + Clone {
    /// The SEC type's name (`"discrete_shell"`).
    const TYPE: &'static str;
    /// One line: what it is for.
    const DOC: &'static str;
    /// Its fields, in order.
    fn fields() -> &'static [Field];
    /// Field `name`'s value.
    fn get(&self, name: &str) -> Option<FieldValue>;
    /// Sets field `name`; false when there is no such field or the value is of another kind.
    fn set(&mut self, name: &str, v: FieldValue) -> bool;
    /// The first field out of its range, in table order.
    fn check(&self) -> Result<(), FieldError> {
        for f in Self::fields() {
            if let Some(FieldValue::Float(x)) = self.get(f.name)
                && !in_range(&f.kind, x)
            {
                return Err(FieldError {
                    field: format!("{}.{}", Self::TYPE, f.name),
                    message: format!("must be {}, got {x}", range_text(&f.kind)),
                });
            }
        }
        Ok(())
    }
}

/// Declares an SEC from its table: the struct (its fields documented by the table), its
/// `Default`, [`crate::Sec`] and [`SecFields`].
///
/// ```ignore
/// sec_fields! {
///     /// Density: mass per area of cloth and per length of hair.
///     pub struct Density: "density", "Density SEC: mass per area of cloth and per length of hair" {
///         area_density: f64 = 0.2, gt(0.0), "kg/m²", "cloth mass per rest area";
///         line_density: f64 = 1e-5, gt(0.0), "kg/m", "hair mass per rest length";
///     }
/// }
/// ```
#[macro_export]
macro_rules! sec_fields {
    (
        $(#[$meta:meta])*
        pub struct $name:ident : $ty:literal, $doc:literal {
            $($field:ident : $ft:ty = $default:expr, $kind:expr, $unit:literal, $fdoc:expr;)*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Debug, PartialEq)]
        pub struct $name {
            $(
                #[doc = $fdoc]
                #[doc = ""]
                #[doc = concat!("Default `", stringify!($default), "`.")]
                pub $field: $ft,
            )*
        }

        impl Default for $name {
            fn default() -> Self {
                $name { $($field: ($default).into(),)* }
            }
        }

        impl $crate::Sec for $name {
            fn sec_type(&self) -> &'static str {
                $ty
            }
            fn describe(&self) -> serde_json::Value {
                serde_json::json!(format!("{self:?}"))
            }
            fn as_any(&self) -> &dyn std::any::Any {
                self
            }
            fn same(&self, other: &dyn $crate::Sec) -> bool {
                other.as_any().downcast_ref::<Self>() == Some(self)
            }
        }

        impl $crate::fields::SecFields for $name {
            const TYPE: &'static str = $ty;
            const DOC: &'static str = $doc;
            fn fields() -> &'static [$crate::fields::Field] {
                const FIELDS: &[$crate::fields::Field] = &[$(
                    $crate::fields::Field {
                        name: stringify!($field),
                        kind: $kind,
                        unit: $unit,
                        doc: $fdoc,
                    },
                )*];
                FIELDS
            }
            fn get(&self, name: &str) -> Option<$crate::fields::FieldValue> {
                match name {
                    $(stringify!($field) => Some($crate::fields::FieldType::to_value(&self.$field)),)*
                    _ => None,
                }
            }
            fn set(&mut self, name: &str, v: $crate::fields::FieldValue) -> bool {
                match name {
                    $(stringify!($field) => match <$ft as $crate::fields::FieldType>::from_value(v) {
                        Some(x) => {
                            self.$field = x;
                            true
                        }
                        None => false,
                    },)*
                    _ => false,
                }
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_read_as_the_loader_writes_them() {
        assert_eq!(range_text(&gt(0.0)), "> 0");
        assert_eq!(range_text(&ge(0.0)), ">= 0");
        assert_eq!(range_text(&ge_lt(0.0, 0.5)), "in [0, 0.5)");
        assert_eq!(range_text(&ge_le(0.0, 1.0)), "in [0, 1]");
        assert!(in_range(&ge_lt(0.0, 0.5), 0.0) && !in_range(&ge_lt(0.0, 0.5), 0.5));
        assert!(!in_range(&gt(0.0), f64::NAN) && !in_range(&gt(0.0), f64::INFINITY));
        assert!(in_range(&text(), 0.0));
    }
}

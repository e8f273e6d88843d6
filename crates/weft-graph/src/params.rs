//! Validated parameter sets.

use crate::spec::{ParamKind, ParamSpec};
use std::collections::BTreeMap;
use std::ops::Bound;

/// A node's parameters after validation: every declared parameter present (defaults filled),
/// every value of the declared kind and in range. The engine runs a node's factory and kernel
/// only on a set that validated completely, so a getter fails only when a node reads a name
/// its own spec does not declare, or as another kind: a programming error, which still comes
/// back as a [`ParamError`] (and from there a node error naming the node), never as a panic.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Params {
    values: BTreeMap<String, serde_json::Value>,
}

/// A parameter read that the validated set cannot answer.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("parameter '{name}': {problem}")]
pub struct ParamError {
    /// The parameter.
    pub name: String,
    /// What is wrong: not declared, or not of the kind asked for.
    pub problem: &'static str,
}

impl From<ParamError> for String {
    fn from(e: ParamError) -> String {
        e.to_string()
    }
}

impl Params {
    /// Builds a parameter set from already validated values.
    pub(crate) fn from_map(values: BTreeMap<String, serde_json::Value>) -> Self {
        Params { values }
    }

    /// The raw JSON value.
    pub fn get(&self, name: &str) -> Option<&serde_json::Value> {
        self.values.get(name)
    }

    fn read<'a, T>(
        &'a self,
        name: &str,
        kind: &'static str,
        f: impl FnOnce(&'a serde_json::Value) -> Option<T>,
    ) -> Result<T, ParamError> {
        let v = self.values.get(name).ok_or_else(|| ParamError {
            name: name.to_string(),
            problem: "not declared by the node's spec",
        })?;
        f(v).ok_or(ParamError {
            name: name.to_string(),
            problem: kind,
        })
    }

    /// A float parameter.
    pub fn f64(&self, name: &str) -> Result<f64, ParamError> {
        self.read(name, "is not a number", serde_json::Value::as_f64)
    }
    /// An integer parameter.
    pub fn i64(&self, name: &str) -> Result<i64, ParamError> {
        self.read(name, "is not an integer", serde_json::Value::as_i64)
    }
    /// An integer parameter as a count or size (validated ranges keep counts non-negative).
    pub fn usize(&self, name: &str) -> Result<usize, ParamError> {
        self.read(name, "is not a non-negative integer", |v| {
            v.as_u64().and_then(|x| usize::try_from(x).ok())
        })
    }
    /// A boolean parameter.
    pub fn bool(&self, name: &str) -> Result<bool, ParamError> {
        self.read(name, "is not true or false", serde_json::Value::as_bool)
    }
    /// A string or enum parameter.
    pub fn str(&self, name: &str) -> Result<&str, ParamError> {
        self.read(name, "is not a string", serde_json::Value::as_str)
    }
    /// A vec3 parameter.
    pub fn vec3(&self, name: &str) -> Result<[f64; 3], ParamError> {
        self.read(name, "is not [x, y, z]", |v| {
            let a = v.as_array().filter(|a| a.len() == 3)?;
            Some([a[0].as_f64()?, a[1].as_f64()?, a[2].as_f64()?])
        })
    }
    /// A float-list parameter.
    pub fn floats(&self, name: &str) -> Result<Vec<f64>, ParamError> {
        self.read(name, "is not a list of numbers", |v| {
            v.as_array()?.iter().map(|x| x.as_f64()).collect()
        })
    }
    /// All parameters, sorted by name.
    pub fn iter(&self) -> impl Iterator<Item = (&String, &serde_json::Value)> {
        self.values.iter()
    }
    /// Replaces one value (already validated by [`check_param`]).
    pub(crate) fn set(&mut self, name: &str, v: serde_json::Value) {
        self.values.insert(name.to_string(), v);
    }
    /// Canonical JSON text, for hashing.
    pub fn canonical(&self) -> String {
        serde_json::to_string(&self.values).unwrap_or_default()
    }
}

fn bound_ok(x: f64, min: &Bound<f64>, max: &Bound<f64>) -> bool {
    let lo = match min {
        Bound::Included(m) => x >= *m,
        Bound::Excluded(m) => x > *m,
        Bound::Unbounded => true,
    };
    let hi = match max {
        Bound::Included(m) => x <= *m,
        Bound::Excluded(m) => x < *m,
        Bound::Unbounded => true,
    };
    lo && hi
}

fn range_text(min: &Bound<f64>, max: &Bound<f64>) -> String {
    let lo = match min {
        Bound::Included(m) => format!(">= {m}"),
        Bound::Excluded(m) => format!("> {m}"),
        Bound::Unbounded => String::new(),
    };
    let hi = match max {
        Bound::Included(m) => format!("<= {m}"),
        Bound::Excluded(m) => format!("< {m}"),
        Bound::Unbounded => String::new(),
    };
    match (lo.is_empty(), hi.is_empty()) {
        (false, false) => format!("{lo} and {hi}"),
        (false, true) => lo,
        (true, false) => hi,
        (true, true) => "finite".into(),
    }
}

/// Checks one value against its spec; returns the value to store (ints given for floats are
/// widened) or a message saying what was expected and what was given.
pub fn check_param(spec: &ParamSpec, v: &serde_json::Value) -> Result<serde_json::Value, String> {
    let got = || {
        let s = v.to_string();
        if s.chars().count() > 60 {
            format!("{}…", s.chars().take(57).collect::<String>())
        } else {
            s
        }
    };
    match &spec.kind {
        ParamKind::Float { min, max } => {
            let x = v
                .as_f64()
                .ok_or_else(|| format!("expected a number, got {}", got()))?;
            if !x.is_finite() {
                return Err(format!("expected a finite number, got {}", got()));
            }
            if !bound_ok(x, min, max) {
                return Err(format!("must be {}, got {x}", range_text(min, max)));
            }
            Ok(serde_json::Number::from_f64(x)
                .map(Into::into)
                .unwrap_or(serde_json::Value::Null))
        }
        ParamKind::Int { min, max } => {
            let x = v
                .as_i64()
                .or_else(|| {
                    v.as_f64()
                        .filter(|f| f.fract() == 0.0 && f.abs() < 9e15)
                        .map(|f| f as i64)
                })
                .ok_or_else(|| format!("expected an integer, got {}", got()))?;
            if min.is_some_and(|m| x < m) || max.is_some_and(|m| x > m) {
                let lo = min.map(|m| format!(">= {m}")).unwrap_or_default();
                let hi = max.map(|m| format!("<= {m}")).unwrap_or_default();
                let sep = if lo.is_empty() || hi.is_empty() {
                    ""
                } else {
                    " and "
                };
                return Err(format!("must be {lo}{sep}{hi}, got {x}"));
            }
            Ok(x.into())
        }
        ParamKind::Bool => v
            .as_bool()
            .map(Into::into)
            .ok_or_else(|| format!("expected true or false, got {}", got())),
        ParamKind::String => v
            .as_str()
            .map(Into::into)
            .ok_or_else(|| format!("expected a string, got {}", got())),
        ParamKind::Enum(choices) => {
            let s = v
                .as_str()
                .ok_or_else(|| format!("expected one of {choices:?}, got {}", got()))?;
            if choices.iter().any(|c| c == s) {
                Ok(s.into())
            } else {
                Err(format!("expected one of {choices:?}, got {s:?}"))
            }
        }
        ParamKind::Vec3 => {
            let a = v
                .as_array()
                .filter(|a| {
                    a.len() == 3 && a.iter().all(|x| x.as_f64().is_some_and(f64::is_finite))
                })
                .ok_or_else(|| format!("expected [x, y, z] of finite numbers, got {}", got()))?;
            Ok(serde_json::json!(
                a.iter().filter_map(|x| x.as_f64()).collect::<Vec<_>>()
            ))
        }
        ParamKind::FloatList => {
            let a = v
                .as_array()
                .filter(|a| a.iter().all(|x| x.as_f64().is_some_and(f64::is_finite)))
                .ok_or_else(|| format!("expected a list of finite numbers, got {}", got()))?;
            Ok(serde_json::json!(
                a.iter().filter_map(|x| x.as_f64()).collect::<Vec<_>>()
            ))
        }
        ParamKind::Json => Ok(v.clone()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_and_kinds() {
        let dt = ParamSpec::float("dt", 0.01).gt(0.0);
        assert!(check_param(&dt, &serde_json::json!(0.5)).is_ok());
        assert_eq!(
            check_param(&dt, &serde_json::json!(0)).unwrap_err(),
            "must be > 0, got 0"
        );
        assert_eq!(
            check_param(&dt, &serde_json::json!("x")).unwrap_err(),
            "expected a number, got \"x\""
        );
        // An integer literal is accepted for a float and stored as a float.
        assert_eq!(
            check_param(&dt, &serde_json::json!(2)).unwrap().as_f64(),
            Some(2.0)
        );
        let n = ParamSpec::int("n", 3).ge(1.0).le(10.0);
        assert_eq!(
            check_param(&n, &serde_json::json!(11)).unwrap_err(),
            "must be >= 1 and <= 10, got 11"
        );
        let m = ParamSpec::choice("method", &["a", "b"], "a");
        assert!(
            check_param(&m, &serde_json::json!("c"))
                .unwrap_err()
                .contains("one of")
        );
    }
}

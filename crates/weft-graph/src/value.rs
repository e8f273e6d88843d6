//! Values on edges and the port types that name them.
//!
//! A [`Value`] is a reference-counted, type-erased payload: cloning it is an `Arc` clone, so
//! large data (meshes, grids) is shared between the cache of the node that made it and every
//! reader. Writers call [`Value::make_mut`], which copies only when the payload is shared
//! (copy on write). A [`PortType`] gives a value type a name for graph files, and optionally a
//! JSON form (for parameters, defaults and printing) and a byte codec (for disk caches).

use std::any::{Any, TypeId};
use std::fmt;
use std::sync::Arc;

/// A type-erased, shared value flowing on an edge.
#[derive(Clone)]
pub struct Value(Arc<dyn Any + Send + Sync>);

impl Value {
    /// Wraps a payload.
    pub fn new<T: Any + Send + Sync>(v: T) -> Self {
        Value(Arc::new(v))
    }

    /// Borrows the payload if it is a `T`.
    pub fn get<T: Any>(&self) -> Option<&T> {
        self.0.downcast_ref::<T>()
    }

    /// Mutable access to the payload, cloning it first if another reader shares it.
    pub fn make_mut<T: Any + Clone + Send + Sync>(&mut self) -> Option<&mut T> {
        if !self.0.is::<T>() {
            return None;
        }
        if Arc::get_mut(&mut self.0).is_none() {
            let copy: T = self.0.downcast_ref::<T>()?.clone();
            self.0 = Arc::new(copy);
        }
        Arc::get_mut(&mut self.0)?.downcast_mut::<T>()
    }

    /// The `TypeId` of the payload.
    pub fn payload_type_id(&self) -> TypeId {
        (*self.0).type_id()
    }

    /// True when both values share one allocation (no copy was made).
    pub fn ptr_eq(&self, other: &Value) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }

    /// Number of holders of the payload (for copy-on-write tests).
    pub fn share_count(&self) -> usize {
        Arc::strong_count(&self.0)
    }
}

impl fmt::Debug for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(v) = self.get::<f64>() {
            write!(f, "Value({v})")
        } else if let Some(v) = self.get::<i64>() {
            write!(f, "Value({v})")
        } else if let Some(v) = self.get::<bool>() {
            write!(f, "Value({v})")
        } else if let Some(v) = self.get::<[f64; 3]>() {
            write!(f, "Value({v:?})")
        } else if let Some(v) = self.get::<String>() {
            write!(f, "Value({v:?})")
        } else {
            write!(f, "Value(..)")
        }
    }
}

impl From<f64> for Value {
    fn from(v: f64) -> Self {
        Value::new(v)
    }
}
impl From<i64> for Value {
    fn from(v: i64) -> Self {
        Value::new(v)
    }
}
impl From<bool> for Value {
    fn from(v: bool) -> Self {
        Value::new(v)
    }
}
impl From<[f64; 3]> for Value {
    fn from(v: [f64; 3]) -> Self {
        Value::new(v)
    }
}
impl From<String> for Value {
    fn from(v: String) -> Self {
        Value::new(v)
    }
}
impl From<Vec<f64>> for Value {
    fn from(v: Vec<f64>) -> Self {
        Value::new(v)
    }
}

/// Converts a JSON value into a payload of this port type.
pub type FromJson = fn(&serde_json::Value) -> Result<Value, String>;
/// Converts a payload into JSON (for printing and output files).
pub type ToJson = fn(&Value) -> Option<serde_json::Value>;
/// Encodes a payload to bytes (disk caches); must round-trip bit-exactly through `Decode`.
pub type Encode = fn(&Value) -> Option<Vec<u8>>;
/// Decodes bytes written by the matching `Encode`.
pub type Decode = fn(&[u8]) -> Result<Value, String>;
/// About how many bytes a payload holds (memory budgets of caches and checkpoints).
pub type Size = fn(&Value) -> usize;
/// Decodes bytes written by the matching `Encode` for a payload that shares parts it does
/// not store (a compiled scene behind an `Arc`): `template` is the same node's value at its
/// start frame, `inputs` its inputs (by port name) at the frame being restored.
pub type Restore = fn(&[u8], &Value, &[(String, Value)]) -> Result<Value, String>;

/// A named value type that ports can carry.
#[derive(Clone)]
pub struct PortType {
    /// Name used in specs and graph files (`"float"`, `"mesh"`).
    pub name: String,
    /// One-line description.
    pub doc: String,
    /// The Rust type of the payload.
    pub type_id: TypeId,
    /// Rust type name, for error messages.
    pub rust_name: &'static str,
    /// JSON → value (parameters, defaults, `--set`).
    pub from_json: Option<FromJson>,
    /// Value → JSON (printing, `--out`).
    pub to_json: Option<ToJson>,
    /// Value → bytes (disk caches).
    pub encode: Option<Encode>,
    /// Bytes → value (disk caches).
    pub decode: Option<Decode>,
    /// Bytes + the start frame's value → value (disk checkpoints of stateful composites,
    /// for payloads that `decode` alone cannot rebuild).
    pub restore: Option<Restore>,
    /// About how many bytes a payload holds; `None`: small (the payload's own size).
    pub size: Option<Size>,
}

impl PortType {
    /// A port type for payload `T` with no JSON form and no codec.
    pub fn of<T: Any + Send + Sync>(name: &str, doc: &str) -> Self {
        PortType {
            name: name.to_string(),
            doc: doc.to_string(),
            type_id: TypeId::of::<T>(),
            rust_name: std::any::type_name::<T>(),
            from_json: None,
            to_json: None,
            encode: None,
            decode: None,
            restore: None,
            size: None,
        }
    }

    /// Adds a size estimate, which caches and checkpoints count against memory.
    pub fn with_size(mut self, size: Size) -> Self {
        self.size = Some(size);
        self
    }

    /// Adds a JSON form.
    pub fn with_json(mut self, from: FromJson, to: ToJson) -> Self {
        self.from_json = Some(from);
        self.to_json = Some(to);
        self
    }

    /// Adds a byte codec, which makes the type storable in disk caches.
    pub fn with_codec(mut self, encode: Encode, decode: Decode) -> Self {
        self.encode = Some(encode);
        self.decode = Some(decode);
        self
    }

    /// Adds an encoding restored against the start frame's value (see [`Restore`]): enough
    /// for disk checkpoints, not for disk caches.
    pub fn with_restore(mut self, encode: Encode, restore: Restore) -> Self {
        self.encode = Some(encode);
        self.restore = Some(restore);
        self
    }
}

fn f64s_to_bytes(xs: &[f64]) -> Vec<u8> {
    xs.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn bytes_to_f64s(b: &[u8]) -> Result<Vec<f64>, String> {
    if !b.len().is_multiple_of(8) {
        return Err(format!("{} bytes is not a whole number of f64", b.len()));
    }
    Ok(b.chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("chunk of 8")))
        .collect())
}

fn json_f64(j: &serde_json::Value) -> Result<f64, String> {
    j.as_f64()
        .ok_or_else(|| format!("expected a number, got {j}"))
}

/// The port types every registry starts with.
pub fn builtin_port_types() -> Vec<PortType> {
    vec![
        PortType::of::<f64>("float", "a 64-bit floating-point number")
            .with_json(
                |j| json_f64(j).map(Value::from),
                |v| {
                    v.get::<f64>()
                        .and_then(|x| serde_json::Number::from_f64(*x))
                        .map(Into::into)
                },
            )
            .with_codec(
                |v| v.get::<f64>().map(|x| x.to_le_bytes().to_vec()),
                |b| {
                    let xs = bytes_to_f64s(b)?;
                    match xs.as_slice() {
                        [x] => Ok(Value::from(*x)),
                        _ => Err("expected one f64".into()),
                    }
                },
            ),
        PortType::of::<i64>("int", "a 64-bit signed integer")
            .with_json(
                |j| {
                    j.as_i64()
                        .map(Value::from)
                        .ok_or_else(|| format!("expected an integer, got {j}"))
                },
                |v| v.get::<i64>().map(|x| (*x).into()),
            )
            .with_codec(
                |v| v.get::<i64>().map(|x| x.to_le_bytes().to_vec()),
                |b| {
                    let a: [u8; 8] = b.try_into().map_err(|_| "expected 8 bytes".to_string())?;
                    Ok(Value::from(i64::from_le_bytes(a)))
                },
            ),
        PortType::of::<bool>("bool", "true or false")
            .with_json(
                |j| {
                    j.as_bool()
                        .map(Value::from)
                        .ok_or_else(|| format!("expected true or false, got {j}"))
                },
                |v| v.get::<bool>().map(|x| (*x).into()),
            )
            .with_codec(
                |v| v.get::<bool>().map(|x| vec![*x as u8]),
                |b| match b {
                    [0] => Ok(Value::from(false)),
                    [1] => Ok(Value::from(true)),
                    _ => Err("expected one byte 0 or 1".into()),
                },
            ),
        PortType::of::<String>("string", "UTF-8 text")
            .with_json(
                |j| {
                    j.as_str()
                        .map(|s| Value::from(s.to_string()))
                        .ok_or_else(|| format!("expected a string, got {j}"))
                },
                |v| v.get::<String>().map(|s| s.clone().into()),
            )
            .with_codec(
                |v| v.get::<String>().map(|s| s.as_bytes().to_vec()),
                |b| {
                    String::from_utf8(b.to_vec())
                        .map(Value::from)
                        .map_err(|e| e.to_string())
                },
            ),
        PortType::of::<[f64; 3]>("vec3", "a 3-vector of f64 (x, y, z)")
            .with_json(
                |j| {
                    let a = j
                        .as_array()
                        .filter(|a| a.len() == 3)
                        .ok_or_else(|| format!("expected [x, y, z], got {j}"))?;
                    Ok(Value::from([
                        json_f64(&a[0])?,
                        json_f64(&a[1])?,
                        json_f64(&a[2])?,
                    ]))
                },
                |v| v.get::<[f64; 3]>().map(|a| serde_json::json!(a)),
            )
            .with_codec(
                |v| v.get::<[f64; 3]>().map(|a| f64s_to_bytes(a)),
                |b| {
                    let xs = bytes_to_f64s(b)?;
                    match xs.as_slice() {
                        [x, y, z] => Ok(Value::from([*x, *y, *z])),
                        _ => Err("expected three f64".into()),
                    }
                },
            ),
        PortType::of::<Vec<f64>>("floats", "a list of f64")
            .with_json(
                |j| {
                    let a = j
                        .as_array()
                        .ok_or_else(|| format!("expected a list of numbers, got {j}"))?;
                    a.iter()
                        .map(json_f64)
                        .collect::<Result<Vec<_>, _>>()
                        .map(Value::from)
                },
                |v| v.get::<Vec<f64>>().map(|a| serde_json::json!(a)),
            )
            .with_codec(
                |v| v.get::<Vec<f64>>().map(|a| f64s_to_bytes(a)),
                |b| bytes_to_f64s(b).map(Value::from),
            ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn make_mut_copies_only_when_shared() {
        let mut a = Value::from(vec![1.0, 2.0]);
        let before = a.clone();
        assert!(a.ptr_eq(&before));
        a.make_mut::<Vec<f64>>().unwrap()[0] = 5.0;
        // The writer got a private copy; the other holder still sees the old data.
        assert!(!a.ptr_eq(&before));
        assert_eq!(before.get::<Vec<f64>>().unwrap()[0], 1.0);
        assert_eq!(a.get::<Vec<f64>>().unwrap()[0], 5.0);
        // Unshared: no copy.
        let p = a.get::<Vec<f64>>().unwrap().as_ptr();
        a.make_mut::<Vec<f64>>().unwrap()[1] = 7.0;
        assert_eq!(a.get::<Vec<f64>>().unwrap().as_ptr(), p);
    }

    #[test]
    fn codecs_round_trip_bit_exactly() {
        for t in builtin_port_types() {
            let sample = match t.name.as_str() {
                "float" => Value::from(0.1f64 + 0.2),
                "int" => Value::from(-7i64),
                "bool" => Value::from(true),
                "string" => Value::from("héllo".to_string()),
                "vec3" => Value::from([1e-300, -0.0, f64::MAX]),
                "floats" => Value::from(vec![std::f64::consts::PI; 5]),
                _ => unreachable!(),
            };
            let bytes = (t.encode.unwrap())(&sample).unwrap();
            let back = (t.decode.unwrap())(&bytes).unwrap();
            assert_eq!((t.encode.unwrap())(&back).unwrap(), bytes, "{}", t.name);
        }
    }
}

//! Node specifications: the static description of a node type.
//!
//! A spec lists typed input and output ports and parameters with their types, defaults, units
//! and one-line docs. Validation of graph files, `weft nodes`, and the C API's introspection all
//! read specs, so a node documents itself by being registered.

use serde::Serialize;
use std::ops::Bound;

/// How a node's outputs depend on time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TimeClass {
    /// Independent of the frame: evaluated once, cached until an input changes.
    Static,
    /// A function of the frame with no history (an animated collider).
    Animated,
    /// Frame f is a step from frame f − 1 (every solver); keeps per-frame checkpoints.
    Stateful,
}

/// The type a port carries.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TypeRef {
    /// A registered port type, by name.
    Named(String),
    /// Accepts any type (inputs only, or outputs resolved below).
    Any,
    /// An output with the same type as the value connected to the named input.
    SameAs(String),
    /// An output whose type is named by a string parameter.
    FromParam(String),
}

impl TypeRef {
    /// Display form used in errors and `weft nodes`.
    pub fn describe(&self) -> String {
        match self {
            TypeRef::Named(n) => n.clone(),
            TypeRef::Any => "any".into(),
            TypeRef::SameAs(p) => format!("same as input '{p}'"),
            TypeRef::FromParam(p) => format!("type named by param '{p}'"),
        }
    }
}

/// One input or output port.
#[derive(Clone, Debug, Serialize)]
pub struct PortSpec {
    /// Port name, unique among the node's inputs (or outputs).
    pub name: String,
    /// What it carries.
    #[serde(rename = "type")]
    pub ty: TypeRef,
    /// One-line doc.
    pub doc: String,
    /// Inputs: a connection (or a default) is required.
    pub required: bool,
    /// Inputs: accepts a list of connections (`["a.out", "b.out"]`).
    pub multi: bool,
    /// Inputs: JSON default used when unconnected.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub default: Option<serde_json::Value>,
}

/// What values a parameter accepts.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ParamKind {
    /// A float within a range.
    Float {
        /// Lower bound.
        #[serde(serialize_with = "ser_bound")]
        min: Bound<f64>,
        /// Upper bound.
        #[serde(serialize_with = "ser_bound")]
        max: Bound<f64>,
    },
    /// An integer within a range (inclusive).
    Int {
        /// Smallest accepted value.
        min: Option<i64>,
        /// Largest accepted value.
        max: Option<i64>,
    },
    /// `true` or `false`.
    Bool,
    /// Free text.
    String,
    /// One of a fixed set of strings.
    Enum(Vec<String>),
    /// `[x, y, z]`.
    Vec3,
    /// A list of numbers.
    FloatList,
    /// Any JSON value (the node validates it).
    Json,
}

fn ser_bound<S: serde::Serializer>(b: &Bound<f64>, s: S) -> Result<S::Ok, S::Error> {
    match b {
        Bound::Included(x) => s.serialize_str(&format!(">= {x}")),
        Bound::Excluded(x) => s.serialize_str(&format!("> {x}")),
        Bound::Unbounded => s.serialize_none(),
    }
}

/// One parameter.
#[derive(Clone, Debug, Serialize)]
pub struct ParamSpec {
    /// Name, unique within the node.
    pub name: String,
    /// Accepted values.
    pub kind: ParamKind,
    /// Default; `None` makes the parameter required.
    pub default: Option<serde_json::Value>,
    /// SI unit (`"m"`, `"Pa"`, `"1/s"`), empty for dimensionless.
    pub unit: String,
    /// One-line doc.
    pub doc: String,
}

impl ParamSpec {
    fn new(name: &str, kind: ParamKind, default: Option<serde_json::Value>) -> Self {
        ParamSpec {
            name: name.into(),
            kind,
            default,
            unit: String::new(),
            doc: String::new(),
        }
    }
    /// A float parameter with a default and no range limit.
    pub fn float(name: &str, default: f64) -> Self {
        Self::new(
            name,
            ParamKind::Float {
                min: Bound::Unbounded,
                max: Bound::Unbounded,
            },
            Some(default.into()),
        )
    }
    /// An integer parameter with a default.
    pub fn int(name: &str, default: i64) -> Self {
        Self::new(
            name,
            ParamKind::Int {
                min: None,
                max: None,
            },
            Some(default.into()),
        )
    }
    /// A boolean parameter.
    pub fn bool(name: &str, default: bool) -> Self {
        Self::new(name, ParamKind::Bool, Some(default.into()))
    }
    /// A string parameter.
    pub fn string(name: &str, default: &str) -> Self {
        Self::new(name, ParamKind::String, Some(default.into()))
    }
    /// One of `choices`; the default must be one of them.
    pub fn choice(name: &str, choices: &[&str], default: &str) -> Self {
        Self::new(
            name,
            ParamKind::Enum(choices.iter().map(|s| s.to_string()).collect()),
            Some(default.into()),
        )
    }
    /// A 3-vector parameter.
    pub fn vec3(name: &str, default: [f64; 3]) -> Self {
        Self::new(name, ParamKind::Vec3, Some(serde_json::json!(default)))
    }
    /// A list of numbers.
    pub fn floats(name: &str, default: &[f64]) -> Self {
        Self::new(name, ParamKind::FloatList, Some(serde_json::json!(default)))
    }
    /// Free JSON.
    pub fn json(name: &str, default: serde_json::Value) -> Self {
        Self::new(name, ParamKind::Json, Some(default))
    }
    /// Makes the parameter required (no default).
    pub fn required(mut self) -> Self {
        self.default = None;
        self
    }
    /// Sets the unit.
    pub fn unit(mut self, unit: &str) -> Self {
        self.unit = unit.into();
        self
    }
    /// Sets the doc line.
    pub fn doc(mut self, doc: &str) -> Self {
        self.doc = doc.into();
        self
    }
    /// Float: value must be `> x`.
    pub fn gt(mut self, x: f64) -> Self {
        if let ParamKind::Float { min, .. } = &mut self.kind {
            *min = Bound::Excluded(x);
        }
        self
    }
    /// Float: value must be `>= x`; Int: `>= x`.
    pub fn ge(mut self, x: f64) -> Self {
        match &mut self.kind {
            ParamKind::Float { min, .. } => *min = Bound::Included(x),
            ParamKind::Int { min, .. } => *min = Some(x as i64),
            _ => {}
        }
        self
    }
    /// Float: value must be `< x`.
    pub fn lt(mut self, x: f64) -> Self {
        if let ParamKind::Float { max, .. } = &mut self.kind {
            *max = Bound::Excluded(x);
        }
        self
    }
    /// Float: value must be `<= x`; Int: `<= x`.
    pub fn le(mut self, x: f64) -> Self {
        match &mut self.kind {
            ParamKind::Float { max, .. } => *max = Bound::Included(x),
            ParamKind::Int { max, .. } => *max = Some(x as i64),
            _ => {}
        }
        self
    }
}

/// The static description of a node type.
#[derive(Clone, Debug, Serialize)]
pub struct NodeSpec {
    /// Registered name (`"math.add"`).
    pub name: String,
    /// One-line doc.
    pub doc: String,
    /// Time dependence.
    pub time: TimeClass,
    /// Input ports.
    pub inputs: Vec<PortSpec>,
    /// Output ports.
    pub outputs: Vec<PortSpec>,
    /// Parameters.
    pub params: Vec<ParamSpec>,
    /// The node pulls its inputs itself, on demand (caches, switches); the engine does not
    /// evaluate them before calling it.
    pub lazy_inputs: bool,
}

impl NodeSpec {
    /// A static node with no ports.
    pub fn new(name: &str, doc: &str) -> Self {
        NodeSpec {
            name: name.into(),
            doc: doc.into(),
            time: TimeClass::Static,
            inputs: vec![],
            outputs: vec![],
            params: vec![],
            lazy_inputs: false,
        }
    }
    /// Sets the time class. Stateful nodes get a `start_frame` parameter.
    pub fn time(mut self, t: TimeClass) -> Self {
        self.time = t;
        if t == TimeClass::Stateful && self.param_spec("start_frame").is_none() {
            self.params.push(
                ParamSpec::int("start_frame", 0)
                    .ge(-1e9)
                    .le(1e9)
                    .doc("frame holding the initial state; earlier frames hold it too"),
            );
        }
        self
    }
    /// Adds a required input.
    pub fn input(mut self, name: &str, ty: &str, doc: &str) -> Self {
        self.inputs.push(PortSpec {
            name: name.into(),
            ty: type_ref(ty),
            doc: doc.into(),
            required: true,
            multi: false,
            default: None,
        });
        self
    }
    /// Adds an optional input with a default used when unconnected (`Null` for none).
    pub fn input_default(
        mut self,
        name: &str,
        ty: &str,
        default: serde_json::Value,
        doc: &str,
    ) -> Self {
        self.inputs.push(PortSpec {
            name: name.into(),
            ty: type_ref(ty),
            doc: doc.into(),
            required: false,
            multi: false,
            default: (!default.is_null()).then_some(default),
        });
        self
    }
    /// Adds a multi-input (a list of connections, possibly empty).
    pub fn input_multi(mut self, name: &str, ty: &str, doc: &str) -> Self {
        self.inputs.push(PortSpec {
            name: name.into(),
            ty: type_ref(ty),
            doc: doc.into(),
            required: false,
            multi: true,
            default: None,
        });
        self
    }
    /// Adds an output.
    pub fn output(mut self, name: &str, ty: &str, doc: &str) -> Self {
        self.outputs.push(PortSpec {
            name: name.into(),
            ty: type_ref(ty),
            doc: doc.into(),
            required: false,
            multi: false,
            default: None,
        });
        self
    }
    /// Adds a parameter.
    pub fn param(mut self, p: ParamSpec) -> Self {
        self.params.push(p);
        self
    }
    /// Marks inputs as pulled on demand by the node.
    pub fn lazy(mut self) -> Self {
        self.lazy_inputs = true;
        self
    }
    /// Looks up a parameter.
    pub fn param_spec(&self, name: &str) -> Option<&ParamSpec> {
        self.params.iter().find(|p| p.name == name)
    }
    /// Index of an input port.
    pub fn input_index(&self, name: &str) -> Option<usize> {
        self.inputs.iter().position(|p| p.name == name)
    }
    /// Index of an output port.
    pub fn output_index(&self, name: &str) -> Option<usize> {
        self.outputs.iter().position(|p| p.name == name)
    }
}

/// `"float"` → Named, `"any"` → Any, `"same:in"` → SameAs, `"param:type"` → FromParam.
fn type_ref(s: &str) -> TypeRef {
    if s == "any" {
        TypeRef::Any
    } else if let Some(p) = s.strip_prefix("same:") {
        TypeRef::SameAs(p.into())
    } else if let Some(p) = s.strip_prefix("param:") {
        TypeRef::FromParam(p.into())
    } else {
        TypeRef::Named(s.into())
    }
}

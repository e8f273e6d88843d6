//! The registry of node types and port types, by name.

use crate::diag::nearest;
use crate::node::{Factory, Kernel};
use crate::params::{Params, check_param};
use crate::spec::{NodeSpec, TypeRef};
use crate::value::{PortType, builtin_port_types};
use std::collections::BTreeMap;
use std::sync::Arc;

/// A registered node type.
#[derive(Clone)]
pub struct NodeType {
    /// Its spec.
    pub spec: Arc<NodeSpec>,
    pub(crate) factory: Factory,
}

/// Why a registration was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RegistryError {
    /// The name is taken.
    ///
    /// Registering `"math.add"` twice.
    #[error("'{0}' is already registered")]
    Duplicate(String),
    /// The spec names a port type nobody registered.
    ///
    /// An input of type `"mesh"` before the `mesh` port type is registered.
    #[error("node type '{node}': port '{port}' has unknown type '{ty}'")]
    UnknownPortType {
        /// Node type.
        node: String,
        /// Port.
        port: String,
        /// The unknown type name.
        ty: String,
    },
    /// A default does not satisfy its own spec, or a name is repeated.
    ///
    /// A float parameter `dt` with `.gt(0.0)` and default `0.0`.
    #[error("node type '{node}': {message}")]
    BadSpec {
        /// Node type.
        node: String,
        /// What is inconsistent.
        message: String,
    },
}

/// Node types and port types by name. Crates outside `weft-graph` register their own (the Rust
/// side of the plugin API); the registry is then shared read-only by every graph.
#[derive(Clone)]
pub struct Registry {
    types: BTreeMap<String, NodeType>,
    port_types: BTreeMap<String, PortType>,
    /// Library subgraphs: composite node types written in the graph format, available to
    /// every file as if it declared them (see [`Registry::register_subgraph`]).
    library: BTreeMap<String, crate::file::SubgraphDecl>,
}

impl Default for Registry {
    fn default() -> Self {
        Self::new()
    }
}

impl Registry {
    /// A registry with the built-in port types and the built-in cache nodes.
    pub fn new() -> Self {
        let mut r = Registry {
            types: BTreeMap::new(),
            port_types: BTreeMap::new(),
            library: BTreeMap::new(),
        };
        for t in builtin_port_types() {
            r.port_types.insert(t.name.clone(), t);
        }
        for (spec, factory) in crate::cache::node_types() {
            r.register_shared(spec, factory)
                .expect("built-in cache nodes are consistent");
        }
        r
    }

    /// Registers a port type.
    pub fn register_port_type(&mut self, t: PortType) -> Result<(), RegistryError> {
        if self.port_types.contains_key(&t.name) || t.name == "any" {
            return Err(RegistryError::Duplicate(t.name));
        }
        self.port_types.insert(t.name.clone(), t);
        Ok(())
    }

    /// Registers a library subgraph: a composite node type written as one entry of a graph
    /// file's `"subgraphs"` (`json` is that entry's value). Every graph can instance it; its
    /// stages are ordinary nodes whose parameters are set as `instance.stage.param`, and a
    /// file can copy it under another name to change it. The definition is parsed here and
    /// compiled (type-checked against the registry) when a graph loads.
    pub fn register_subgraph(&mut self, name: &str, json: &str) -> Result<(), RegistryError> {
        if self.types.contains_key(name) || self.library.contains_key(name) {
            return Err(RegistryError::Duplicate(name.to_string()));
        }
        let bad = |message: String| RegistryError::BadSpec {
            node: name.to_string(),
            message,
        };
        let v: serde_json::Value =
            serde_json::from_str(json).map_err(|e| bad(format!("invalid JSON: {e}")))?;
        let mut d = Vec::new();
        let path = vec!["subgraphs".to_string(), name.to_string()];
        let decl = crate::file::parse_subgraph(&v, &path, &mut d);
        match decl {
            Some(s) if d.iter().all(|x| x.severity != crate::diag::Severity::Error) => {
                self.library.insert(name.to_string(), s);
                Ok(())
            }
            _ => Err(bad(d
                .iter()
                .map(|x| x.to_string())
                .collect::<Vec<_>>()
                .join("; "))),
        }
    }

    pub(crate) fn library(&self) -> &BTreeMap<String, crate::file::SubgraphDecl> {
        &self.library
    }

    /// Registers a node type; its spec is checked for consistency first.
    pub fn register<F>(&mut self, spec: NodeSpec, factory: F) -> Result<(), RegistryError>
    where
        F: Fn(&Params) -> Result<Kernel, String> + Send + Sync + 'static,
    {
        self.register_shared(spec, Arc::new(factory))
    }

    pub(crate) fn register_shared(
        &mut self,
        spec: NodeSpec,
        factory: Factory,
    ) -> Result<(), RegistryError> {
        if self.types.contains_key(&spec.name) || self.library.contains_key(&spec.name) {
            return Err(RegistryError::Duplicate(spec.name));
        }
        self.check_spec(&spec)?;
        self.types.insert(
            spec.name.clone(),
            NodeType {
                spec: Arc::new(spec),
                factory,
            },
        );
        Ok(())
    }

    pub(crate) fn check_spec(&self, spec: &NodeSpec) -> Result<(), RegistryError> {
        let bad = |message: String| RegistryError::BadSpec {
            node: spec.name.clone(),
            message,
        };
        for (what, ports) in [("input", &spec.inputs), ("output", &spec.outputs)] {
            for (i, p) in ports.iter().enumerate() {
                if ports[..i].iter().any(|q| q.name == p.name) {
                    return Err(bad(format!("{what} '{}' declared twice", p.name)));
                }
                match &p.ty {
                    TypeRef::Named(t) if !self.port_types.contains_key(t) => {
                        return Err(RegistryError::UnknownPortType {
                            node: spec.name.clone(),
                            port: p.name.clone(),
                            ty: t.clone(),
                        });
                    }
                    TypeRef::SameAs(src) if spec.input_index(src).is_none() => {
                        return Err(bad(format!(
                            "output '{}' copies the type of unknown input '{src}'",
                            p.name
                        )));
                    }
                    TypeRef::FromParam(pp) if spec.param_spec(pp).is_none() => {
                        return Err(bad(format!(
                            "output '{}' takes its type from unknown param '{pp}'",
                            p.name
                        )));
                    }
                    _ => {}
                }
                if let (Some(d), TypeRef::Named(t)) = (&p.default, &p.ty) {
                    let conv = self.port_types[t].from_json;
                    match conv {
                        Some(f) => f(d)
                            .map(|_| ())
                            .map_err(|e| bad(format!("input '{}' default: {e}", p.name)))?,
                        None => {
                            return Err(bad(format!(
                                "input '{}' has a default but type '{t}' has no JSON form",
                                p.name
                            )));
                        }
                    }
                }
            }
        }
        for (i, p) in spec.params.iter().enumerate() {
            if spec.params[..i].iter().any(|q| q.name == p.name) {
                return Err(bad(format!("param '{}' declared twice", p.name)));
            }
            if let Some(d) = &p.default {
                check_param(p, d).map_err(|e| bad(format!("param '{}' default: {e}", p.name)))?;
            }
        }
        Ok(())
    }

    /// A JSON value converted through port type `ty`'s JSON form (`None` when the type has
    /// none or the value does not fit it).
    pub(crate) fn json_value(&self, ty: &str, j: &serde_json::Value) -> Option<crate::Value> {
        self.port_type(ty)
            .and_then(|t| t.from_json)
            .and_then(|f| f(j).ok())
    }

    /// About how many bytes `v` holds: its port type's estimate, else a small constant.
    pub fn value_bytes(&self, v: &crate::Value) -> usize {
        self.port_type_by_id(v.payload_type_id())
            .and_then(|t| t.size)
            .map_or(64, |f| f(v))
    }

    /// A node type by name.
    pub fn node_type(&self, name: &str) -> Option<&NodeType> {
        self.types.get(name)
    }
    /// A port type by name.
    pub fn port_type(&self, name: &str) -> Option<&PortType> {
        self.port_types.get(name)
    }
    /// Every node spec, sorted by name.
    pub fn specs(&self) -> impl Iterator<Item = &NodeSpec> {
        self.types.values().map(|t| &*t.spec)
    }
    /// Every port type, sorted by name.
    pub fn port_types(&self) -> impl Iterator<Item = &PortType> {
        self.port_types.values()
    }
    /// "did you mean …" for an unknown node type name.
    pub fn suggest(&self, name: &str) -> Option<String> {
        nearest(name, self.types.keys().map(|s| s.as_str()))
    }
    /// The registered port type of a value's payload.
    pub fn type_of(&self, v: &crate::value::Value) -> Option<&PortType> {
        self.port_type_by_id(v.payload_type_id())
    }

    /// The port type whose payload has Rust type `id` (a value's `payload_type_id`), if
    /// registered.
    pub fn port_type_by_id(&self, id: std::any::TypeId) -> Option<&PortType> {
        self.port_types.values().find(|t| t.type_id == id)
    }
}

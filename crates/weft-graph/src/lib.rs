//! `weft-graph`: Weft's domain-free dataflow engine.
//!
//! It knows node types, ports, parameters and time, and nothing about physics. A JSON graph
//! file is read into an authoring model, validated (every error collected, each naming the
//! node, the port or parameter and the line) and compiled into a [`Graph`]. Asking the graph
//! for an output at a [`Context`] (frame) evaluates only what that output depends on; changing
//! a parameter dirties the node and its downstream; clean nodes answer from cache. Stateful
//! nodes keep per-frame checkpoints. Subgraphs declared in the file become node types,
//! optionally iterating (a loop to convergence) or stepped (stateful). Cache nodes keep frames
//! in memory or on disk keyed by a hash of everything upstream.
//!
//! This crate never depends on a physics crate: physics registers node and port types from
//! outside through [`Registry`].
//!
//! ```
//! use std::sync::Arc;
//! use weft_graph::{Context, Kernel, NodeSpec, ParamSpec, Registry, load_str};
//!
//! let mut reg = Registry::new();
//! reg.register(
//!     NodeSpec::new("const", "a number").output("out", "float", "the number")
//!         .param(ParamSpec::float("value", 0.0)),
//!     |_| Ok(Kernel::from_fn(|cx| { let v = cx.params().f64("value")?; cx.set("out", v); Ok(()) })),
//! ).unwrap();
//! let reg = Arc::new(reg);
//! let text = r#"{"format": "weft-graph", "version": 1,
//!   "nodes": {"a": {"type": "const", "params": {"value": 2.5}}},
//!   "outputs": {"x": "a.out"}}"#;
//! let mut g = load_str(&reg, text, "<doc>").unwrap();
//! assert_eq!(g.pull("x", Context::new(0)).unwrap().get::<f64>(), Some(&2.5));
//! ```
#![warn(missing_docs)]

mod body;
mod cache;
mod checkpoints;
pub mod codec;
mod compile;
mod composite;
mod diag;
mod edit;
mod engine;
mod feed;
mod file;
mod files;
mod hash;
mod interrupt;
mod locate;
pub mod memory;
mod node;
mod params;
mod paths;
mod persist;
mod registry;
mod report;
mod schema;
mod spec;
mod value;

pub use compile::{library_specs, load_path, load_str};
pub use diag::{Diagnostic, LoadError, Severity};
pub use engine::{Context, Graph, NodeReport, NodeStats, RunWarning, WarningSink};
pub use feed::FedOutput;
pub use file::{FORMAT, SUPPORTED_VERSIONS};
pub use files::{atomic_write, atomic_write_with};
pub use interrupt::{Interrupt, Reporter};
pub use node::Factory;
pub use node::{Compute, EvalCx, EvalError, Kernel, NodeError, Step};
pub use params::{ParamError, Params, check_param};
pub use paths::resolve_output;
pub use registry::{NodeType, Registry, RegistryError};
pub use schema::graph_schema;
pub use spec::{NodeSpec, ParamKind, ParamSpec, PortSpec, TimeClass, TypeRef};
pub use value::{PortType, Value, builtin_port_types};

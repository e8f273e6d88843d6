//! `weft`: the umbrella crate. It re-exports Weft's crates so an embedder depends on one
//! package (`weft::graph::Graph`, `weft::nodes::registry()`), and it owns the graph-level tests
//! in `tests/` (JSON graphs in, numbers out) and the example graphs in `graphs/`.
#![warn(missing_docs)]

pub use weft_graph as graph;
pub use weft_nodes as nodes;

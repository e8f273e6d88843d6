//! Host-fed outputs: a host application (through the C ABI or the Python module) replaces a
//! node's output with its own data, for all frames or frame by frame, so an animated body or
//! collider comes from the host's scene while the graph file stays as written.
//!
//! A fed output is held between samples: at frame f it is the sample at the latest fed frame
//! ≤ f, or the first sample before it. A node whose every output is fed is not computed at
//! all (a file-reading node needs no file in a host); one with some outputs fed is computed
//! and the fed ones replaced. Feeding is refused for stateful and lazy-input nodes (solvers
//! and caches keep their own history), for a value of another type than the port's, and for
//! a value holding a non-finite number. Every change dirties the node and its downstream
//! (stateful nodes downstream start again), so a host feeds every frame before it pulls.

use crate::diag::{Diagnostic, nearest};
use crate::engine::Graph;
use crate::spec::TimeClass;
use crate::value::Value;
use std::collections::BTreeMap;
use xxhash_rust::xxh3::Xxh3;

/// What a host fed one output port.
#[derive(Clone)]
pub(crate) enum Samples {
    /// One value for every frame.
    Static(Value),
    /// Values by frame, each held until the next.
    Frames(BTreeMap<i64, Value>),
}

impl Samples {
    fn at(&self, frame: i64) -> Value {
        match self {
            Samples::Static(v) => v.clone(),
            Samples::Frames(m) => m
                .range(..=frame)
                .next_back()
                .or_else(|| m.iter().next())
                .map(|(_, v)| v.clone())
                .expect("a fed output has at least one sample"),
        }
    }
}

/// One fed output, as [`Graph::fed_outputs`] lists it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FedOutput {
    /// Node id.
    pub node: String,
    /// Output port.
    pub port: String,
    /// The frames fed, or `None` for one value for all frames.
    pub frames: Option<Vec<i64>>,
}

/// How a slot's feeds bear on its time dependence.
pub(crate) enum FedTime {
    /// Every output is fed; `varies` when one of them changes with the frame.
    All { varies: bool },
    /// Some or none are.
    Some { varies: bool },
}

pub(crate) fn time_of(feeds: &[Option<Samples>], outputs: usize) -> FedTime {
    let varies = feeds
        .iter()
        .flatten()
        .any(|s| matches!(s, Samples::Frames(_)));
    if all_fed(feeds, outputs) {
        FedTime::All { varies }
    } else {
        FedTime::Some { varies }
    }
}

/// Whether every one of `outputs` ports is fed (never for a node without outputs).
pub(crate) fn all_fed(feeds: &[Option<Samples>], outputs: usize) -> bool {
    outputs > 0 && feeds.len() == outputs && feeds.iter().all(Option::is_some)
}

/// The node's outputs at `frame` with the fed ones put in (`computed` is empty when the node
/// was not computed because every output is fed).
pub(crate) fn apply(
    feeds: &[Option<Samples>],
    mut computed: Vec<Option<Value>>,
    frame: i64,
    outputs: usize,
) -> Vec<Option<Value>> {
    if feeds.is_empty() {
        return computed;
    }
    computed.resize(outputs, None);
    for (out, fed) in computed.iter_mut().zip(feeds) {
        if let Some(s) = fed {
            *out = Some(s.at(frame));
        }
    }
    computed
}

impl Graph {
    /// Feeds `value` as output `port` of `node` in place of what the node computes: for
    /// every frame (`frame` `None`, replacing any samples), or as the sample at `frame`
    /// (held until the next sample; replacing an earlier sample at that frame). See the
    /// module doc for what is refused. On an error nothing changes.
    pub fn feed(
        &mut self,
        node: &str,
        port: &str,
        frame: Option<i64>,
        value: Value,
    ) -> Result<(), Box<Diagnostic>> {
        let (n, p) = self.fed_port(node, port)?;
        let slot = &self.slots[n];
        if let Some(t) = slot.out_types[p]
            && value.payload_type_id() != t
        {
            let got = self
                .registry
                .port_type_by_id(value.payload_type_id())
                .map(|t| t.name.clone())
                .unwrap_or_else(|| "an unregistered type".into());
            return Err(Box::new(
                Diagnostic::error(
                    vec![],
                    format!("output '{port}' is {}, not {got}", slot.out_type_names[p]),
                )
                .node(node),
            ));
        }
        if let Some(bad) = crate::engine::non_finite(&value) {
            return Err(Box::new(
                Diagnostic::error(vec![], format!("the value fed holds {bad}"))
                    .node(node)
                    .field(format!("output '{port}'")),
            ));
        }
        let outputs = self.slots[n].spec.outputs.len();
        let feeds = &mut self.slots[n].feeds;
        feeds.resize(outputs, None);
        match (frame, &mut feeds[p]) {
            (Some(f), Some(Samples::Frames(m))) => {
                m.insert(f, value);
            }
            (Some(f), slot) => *slot = Some(Samples::Frames(BTreeMap::from([(f, value)]))),
            (None, slot) => *slot = Some(Samples::Static(value)),
        }
        self.feeds_changed(n);
        Ok(())
    }

    /// Stops feeding output `port` of `node`: the node computes it again. Whether it was fed.
    pub fn unfeed(&mut self, node: &str, port: &str) -> Result<bool, Box<Diagnostic>> {
        let (n, p) = self.fed_port(node, port)?;
        let was = self.slots[n]
            .feeds
            .get_mut(p)
            .and_then(Option::take)
            .is_some();
        if self.slots[n].feeds.iter().all(Option::is_none) {
            self.slots[n].feeds.clear();
        }
        if was {
            self.feeds_changed(n);
        }
        Ok(was)
    }

    /// Every fed output, in slot and port order.
    pub fn fed_outputs(&self) -> Vec<FedOutput> {
        let mut out = Vec::new();
        for s in &self.slots {
            for (p, fed) in s.feeds.iter().enumerate() {
                let Some(fed) = fed else { continue };
                out.push(FedOutput {
                    node: s.id.clone(),
                    port: s.spec.outputs[p].name.clone(),
                    frames: match fed {
                        Samples::Static(_) => None,
                        Samples::Frames(m) => Some(m.keys().copied().collect()),
                    },
                });
            }
        }
        out
    }

    /// The slot and port index of `node.port`, when it may be fed.
    fn fed_port(&self, node: &str, port: &str) -> Result<(usize, usize), Box<Diagnostic>> {
        let &n = self.ids.get(node).ok_or_else(|| {
            Diagnostic::error(vec![], "no such node")
                .node(node)
                .help(nearest(node, self.ids.keys().map(|s| s.as_str())))
        })?;
        let spec = &self.slots[n].spec;
        let p = spec.output_index(port).ok_or_else(|| {
            Diagnostic::error(vec![], format!("no output '{port}'"))
                .node(node)
                .help(nearest(port, spec.outputs.iter().map(|o| o.name.as_str())))
        })?;
        if spec.time == TimeClass::Stateful || spec.lazy_inputs {
            return Err(Box::new(
                Diagnostic::error(
                    vec![],
                    format!(
                        "a {} node keeps its own history, so its outputs cannot be fed; feed a node upstream of it",
                        if spec.lazy_inputs { "cache" } else { "stateful" }
                    ),
                )
                .node(node),
            ));
        }
        Ok((n, p))
    }

    /// After slot `n`'s feeds changed: its hash, time dependence and downstream.
    fn feeds_changed(&mut self, n: usize) {
        let mut h = Xxh3::new();
        let feeds = self.slots[n].feeds.clone();
        for (p, fed) in feeds.iter().enumerate() {
            let Some(fed) = fed else { continue };
            h.update(&(p as u64).to_le_bytes());
            match fed {
                Samples::Static(v) => h.update(&self.value_hash(v).to_le_bytes()),
                Samples::Frames(m) => {
                    for (f, v) in m {
                        h.update(&f.to_le_bytes());
                        h.update(&self.value_hash(v).to_le_bytes());
                    }
                }
            }
        }
        self.slots[n].feed_hash = if feeds.is_empty() { 0 } else { h.digest128() };
        self.refresh_time();
        self.mark_dirty(n);
    }
}

#[cfg(test)]
mod tests {
    use crate::{Context, Kernel, NodeSpec, ParamSpec, Registry, TimeClass, Value, load_str};
    use std::sync::Arc;

    /// `const` (a float parameter) → `double` (twice its input) → output `y`; and a
    /// stateful `sum` accumulating its input every frame → output `total`.
    fn graph() -> crate::Graph {
        let mut reg = Registry::new();
        reg.register(
            NodeSpec::new("const", "a number")
                .output("out", "float", "the number")
                .param(ParamSpec::float("value", 1.0)),
            |_| {
                Ok(Kernel::from_fn(|cx| {
                    let v = cx.params().f64("value")?;
                    cx.set("out", v);
                    Ok(())
                }))
            },
        )
        .unwrap();
        reg.register(
            NodeSpec::new("double", "twice its input")
                .input("in", "float", "a number")
                .output("out", "float", "twice it"),
            |_| {
                Ok(Kernel::from_fn(|cx| {
                    let v = cx.f64_input("in")?;
                    cx.set("out", 2.0 * v);
                    Ok(())
                }))
            },
        )
        .unwrap();
        let reg = Arc::new(reg);
        let text = r#"{"format": "weft-graph", "version": 1,
          "nodes": {"a": {"type": "const", "params": {"value": 2.5}},
                    "b": {"type": "double", "inputs": {"in": "a.out"}}},
          "outputs": {"y": "b.out"}}"#;
        load_str(&reg, text, "<feed>").unwrap()
    }

    fn y(g: &mut crate::Graph, frame: i64) -> f64 {
        *g.pull("y", Context::new(frame))
            .unwrap()
            .get::<f64>()
            .unwrap()
    }

    #[test]
    fn a_fed_output_replaces_the_node_and_holds_between_samples() {
        let mut g = graph();
        assert_eq!(y(&mut g, 0), 5.0);
        g.feed("a", "out", None, Value::new(4.0f64)).unwrap();
        assert_eq!(y(&mut g, 7), 8.0);
        assert!(g.output_is_time_dependent("y") == Some(false));
        g.feed("a", "out", Some(10), Value::new(1.0f64)).unwrap();
        g.feed("a", "out", Some(20), Value::new(3.0f64)).unwrap();
        assert_eq!(g.output_is_time_dependent("y"), Some(true));
        // Before the first sample the first holds; between samples the earlier one.
        let got: Vec<f64> = [0, 10, 15, 20, 99].map(|f| y(&mut g, f)).to_vec();
        assert_eq!(got, vec![2.0, 2.0, 2.0, 6.0, 6.0]);
        assert_eq!(g.fed_outputs()[0].frames, Some(vec![10, 20]));
        assert!(g.unfeed("a", "out").unwrap());
        assert_eq!(y(&mut g, 15), 5.0);
        assert_eq!(g.output_is_time_dependent("y"), Some(false));
        assert!(!g.unfeed("a", "out").unwrap());
    }

    #[test]
    fn a_fully_fed_node_pulls_nothing_upstream() {
        let mut g = graph();
        g.feed("b", "out", None, Value::new(7.0f64)).unwrap();
        assert_eq!(y(&mut g, 0), 7.0);
        assert_eq!(
            g.evaluations("a"),
            0,
            "a fed node's inputs are not computed"
        );
    }

    #[test]
    fn bad_feeds_are_refused_with_the_node_named_and_nothing_changes() {
        let mut g = graph();
        let e = g.feed("nope", "out", None, Value::new(1.0f64)).unwrap_err();
        assert!(e.to_string().contains("nope"), "{e}");
        let e = g.feed("a", "outt", None, Value::new(1.0f64)).unwrap_err();
        assert!(e.to_string().contains("out"), "{e}");
        let e = g
            .feed("a", "out", None, Value::new(vec![1.0f64]))
            .unwrap_err();
        assert!(e.to_string().contains("float"), "{e}");
        let e = g
            .feed("a", "out", Some(3), Value::new(f64::NAN))
            .unwrap_err();
        assert!(e.to_string().contains("NaN"), "{e}");
        assert!(g.fed_outputs().is_empty());
        assert_eq!(y(&mut g, 0), 5.0);
        assert_eq!(TimeClass::Static, g.node_spec("a").unwrap().time);
    }
}

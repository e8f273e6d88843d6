//! Changing a compiled graph: parameters and inputs, each change pushing dirtiness to
//! everything downstream.

use crate::diag::{Diagnostic, nearest};
use crate::engine::Graph;
use crate::params::check_param;
use crate::value::Value;
use std::sync::Arc;

impl Graph {
    /// Changes a parameter (validated as at load) and dirties the node and its downstream.
    pub fn set_param(
        &mut self,
        node: &str,
        param: &str,
        value: serde_json::Value,
    ) -> Result<(), Box<Diagnostic>> {
        self.set_params(node, &[(param, value)])
    }

    /// Sets several parameters of one node at once: each is checked, then the node's factory
    /// runs once on all of them, so a combination that is only valid together (both sides of
    /// a periodic axis) can be made. On any error nothing changes.
    pub fn set_params(
        &mut self,
        node: &str,
        values: &[(&str, serde_json::Value)],
    ) -> Result<(), Box<Diagnostic>> {
        let &n = self.ids.get(node).ok_or_else(|| {
            Diagnostic::error(vec![], "no such node")
                .node(node)
                .help(nearest(node, self.ids.keys().map(|s| s.as_str())))
        })?;
        let spec = self.slots[n].spec.clone();
        let mut params = (*self.slots[n].params).clone();
        for (param, value) in values {
            let ps = spec.param_spec(param).ok_or_else(|| {
                Diagnostic::error(vec![], "no such parameter")
                    .node(node)
                    .field(format!("param '{param}'"))
                    .help(nearest(param, spec.params.iter().map(|p| p.name.as_str())))
            })?;
            if spec
                .outputs
                .iter()
                .any(|o| o.ty == crate::spec::TypeRef::FromParam(param.to_string()))
            {
                return Err(Box::new(
                    Diagnostic::error(vec![], "sets an output's type, so it can only be given in the graph file (connections were type-checked against it at load)")
                        .node(node)
                        .field(format!("param '{param}'")),
                ));
            }
            let v = check_param(ps, value).map_err(|m| {
                Diagnostic::error(vec![], m)
                    .node(node)
                    .field(format!("param '{param}'"))
            })?;
            params.set(param, v);
        }
        if let Some(f) = self.slots[n].factory.clone() {
            let names: Vec<&str> = values.iter().map(|(p, _)| *p).collect();
            let k = f(&params).map_err(|m| {
                Diagnostic::error(vec![], m)
                    .node(node)
                    .field(format!("param '{}'", names.join("', '")))
            })?;
            self.slots[n].external = k.kernel_hash();
            self.slots[n].kernel = Some(k);
        }
        self.slots[n].params = Arc::new(params);
        self.mark_dirty(n);
        Ok(())
    }

    /// Sets a graph input's value and dirties its downstream.
    pub fn set_input(&mut self, name: &str, value: Value) -> Result<(), Box<Diagnostic>> {
        let &n = self.inputs.get(name).ok_or_else(|| {
            Diagnostic::error(vec![], format!("the graph has no input '{name}'"))
                .help(nearest(name, self.inputs.keys().map(|s| s.as_str())))
        })?;
        if let Some(t) = self.slots[n].out_types[0]
            && value.payload_type_id() != t
        {
            return Err(Box::new(Diagnostic::error(
                vec![],
                format!("input '{name}' expects {}", self.slots[n].out_type_names[0]),
            )));
        }
        self.slots[n].external = self.value_hash(&value);
        self.slots[n].source = Some(value);
        self.mark_dirty(n);
        Ok(())
    }

    /// Gives a graph input its value at load time (a declared default).
    pub(crate) fn set_input_initial(&mut self, n: usize, v: Value) {
        self.slots[n].external = self.value_hash(&v);
        self.slots[n].source = Some(v);
    }
}

//! Diagnostics: load-time errors that name the node, the port or parameter, and the line.

use std::fmt;

/// How serious a diagnostic is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Severity {
    /// The graph cannot be compiled.
    Error,
    /// The graph runs, but something is probably not what the author meant.
    Warning,
}

/// One problem found in a graph file, located as precisely as the file allows.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// The node id (flattened composites read `instance/inner`).
    pub node: Option<String>,
    /// The port or parameter, as `input 'x'`, `param 'dt'`, `output 'y'`, or a field name.
    pub field: Option<String>,
    /// 1-based line in the file, where known.
    pub line: Option<usize>,
    /// 1-based column, where known.
    pub column: Option<usize>,
    /// What is wrong, saying what was expected and what was found.
    pub message: String,
    /// A suggestion (`did you mean 'math.add'?`).
    pub help: Option<String>,
    /// JSON path of the offending item, used to find the line.
    pub(crate) path: Vec<String>,
}

impl Diagnostic {
    /// A new error about the item at `path`.
    pub(crate) fn error(path: Vec<String>, message: impl Into<String>) -> Self {
        Diagnostic {
            severity: Severity::Error,
            node: None,
            field: None,
            line: None,
            column: None,
            message: message.into(),
            help: None,
            path,
        }
    }
    /// An error about node `node` (none when empty) and its port or parameter `field`,
    /// outside any file: what a host's call did wrong.
    pub fn about(node: &str, field: Option<&str>, message: impl Into<String>) -> Self {
        let d = Diagnostic::error(vec![], message).node(node);
        match field {
            Some(f) => d.field(f),
            None => d,
        }
    }
    /// Names the node (an empty id names none: file-level items such as graph outputs).
    pub(crate) fn node(mut self, id: &str) -> Self {
        self.node = (!id.is_empty()).then(|| id.to_string());
        self
    }
    pub(crate) fn field(mut self, f: impl Into<String>) -> Self {
        self.field = Some(f.into());
        self
    }
    pub(crate) fn help(mut self, h: Option<String>) -> Self {
        self.help = h;
        self
    }
    pub(crate) fn warning(mut self) -> Self {
        self.severity = Severity::Warning;
        self
    }
}

impl Diagnostic {
    /// The message with its node and field, without line or severity:
    /// `node 'solve': param 'dt': must be > 0, got -1`.
    pub fn describe(&self) -> String {
        struct D<'a>(&'a Diagnostic);
        impl fmt::Display for D<'_> {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                self.0.fmt_body(f)
            }
        }
        D(self).to_string()
    }

    fn fmt_body(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(n) = &self.node {
            write!(f, "node '{n}': ")?;
        }
        if let Some(p) = &self.field {
            write!(f, "{p}: ")?;
        }
        write!(f, "{}", self.message)?;
        if let Some(h) = &self.help {
            write!(f, " ({h})")?;
        }
        Ok(())
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(l) = self.line {
            write!(f, "line {l}")?;
            if let Some(c) = self.column {
                write!(f, ", column {c}")?;
            }
            write!(f, ": ")?;
        }
        match self.severity {
            Severity::Error => write!(f, "error: ")?,
            Severity::Warning => write!(f, "warning: ")?,
        }
        self.fmt_body(f)
    }
}

/// A graph file that could not be loaded: every problem found, not just the first.
#[derive(Clone, Debug, thiserror::Error)]
pub struct LoadError {
    /// The file name (or `<memory>`).
    pub source_name: String,
    /// All errors and warnings, in file order.
    pub diagnostics: Vec<Diagnostic>,
}

impl LoadError {
    /// The errors only.
    pub fn errors(&self) -> impl Iterator<Item = &Diagnostic> {
        self.diagnostics
            .iter()
            .filter(|d| d.severity == Severity::Error)
    }
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.errors().count();
        writeln!(
            f,
            "{}: {n} error{} in graph file",
            self.source_name,
            if n == 1 { "" } else { "s" }
        )?;
        for d in &self.diagnostics {
            writeln!(f, "  {}: {d}", self.source_name)?;
        }
        Ok(())
    }
}

/// The registered name closest to `name`, if one is close enough to be a likely typo.
pub(crate) fn nearest<'a>(name: &str, candidates: impl Iterator<Item = &'a str>) -> Option<String> {
    candidates
        .map(|c| (strsim::jaro_winkler(name, c), c))
        .filter(|(s, _)| *s > 0.8)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, c)| format!("did you mean '{c}'?"))
}

//! One measured row of the `graph`, `solid` and `fluid` suites.

/// One measured row: a case, its size, the value and its unit, and the target it is read
/// against (informative: no time is asserted).
#[derive(serde::Serialize)]
pub(crate) struct Row {
    pub case: String,
    pub nodes: usize,
    pub value: f64,
    pub unit: &'static str,
    pub target: &'static str,
}

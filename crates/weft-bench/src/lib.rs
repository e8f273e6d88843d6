//! `weft-bench`: the measurements behind `weft bench` and BENCHMARKS.md.
//!
//! Suites: `graph` (the engine's own overhead), `solid` (cloth and hair solver cost and
//! scaling), `contact` (contacts with colliders: the drape's step split), `fluid` (the pressure solve against memory bandwidth), and three sweeps of
//! verification scenes with known answers, each writing every run to CSV and JSON and
//! drawing charts (PNG, SVG): `accuracy` (solid integrators over step, stiffness and Newton
//! tolerance), `convergence` (scenes under refinement, with fitted orders) and `coupling`
//! (coupling methods over step and drag-to-mass ratio, run through the `solver.coupled`
//! graph users run). With `--quick` a sweep exits non-zero when a fact theory fixes fails,
//! which is how CI asserts them. Nothing here asserts a time.
//!
//! It prints and writes files; the crates it measures never do.
#![warn(missing_docs)]

mod bench;
mod bench_accuracy;
mod bench_contact;
mod bench_convergence;
mod bench_coupling;
mod bench_fluid;
mod bench_solid;
mod charts;
pub mod graphs;
mod row;
pub mod scenes_coupled;
mod scenes_resolution;
pub mod scenes_strand;
mod sweep;

pub use bench::{BenchArgs, chain_graph, fan_in_graph, run};

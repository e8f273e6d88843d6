//! `weft-cli`: the `weft` command line.
//!
//! `weft run` evaluates a graph over frames and prints or writes its outputs; `weft validate`
//! reports every error of one or more graph files; `weft nodes` prints the node registry;
//! `weft bench` measures the engine. Exit codes: 0 success, 1 an evaluation failed, 2 the
//! command line or a graph file is invalid.
#![warn(missing_docs)]

mod nodes;
mod run;
mod ticker;

/// Gives every thread glibc's one main malloc arena: each further arena reserves 64 MiB of
/// address space on a thread's first allocation, which counts against `ulimit -v` without
/// being allocated, and the worker threads start after the memory estimates measured the
/// room left (`weft_graph::memory`). Weft's threads do not allocate in their loops, so they
/// do not contend for it: whole runs of the examples take about the default's wall time
/// (paired runs against glibc's default measure it; figures in
/// docs/history/issue-71-comments.md). Elsewhere a no-op.
pub fn cap_malloc_arenas() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes a glibc tunable; it is called before this process's
    // threads allocate, and glibc takes its own lock.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
    }
}

/// Without a terminal, `weft run` prints what a frame is doing once it has run this long
/// (and every 30 s after): a log shows a long frame working.
pub use ticker::FIRST_LINE as PROGRESS_FIRST_LINE;

use clap::{Parser, Subcommand};
use std::ffi::OsString;
use std::path::PathBuf;
use std::process::ExitCode;

/// Weft: a node-graph simulation engine for hair, cloth and fluids.
#[derive(Parser, Debug)]
#[command(name = "weft", version, about)]
pub struct Cli {
    /// Worker threads for the solvers (default: one per core). Results are bit-identical
    /// whatever the count.
    #[arg(long, global = true, value_name = "N")]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Evaluate a graph's outputs over a frame range.
    Run(run::RunArgs),
    /// Check graph files and print every error; exits 2 if any file is invalid.
    Validate {
        /// Graph files.
        #[arg(required = true)]
        graphs: Vec<PathBuf>,
    },
    /// List the registered node types with ports, parameters, defaults, units and docs.
    Nodes {
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
        /// Only node types whose name contains this text.
        filter: Option<String>,
    },
    /// Print the JSON Schema of graph files (draft 2020-12), generated from the node
    /// registry: point an editor at it to complete and check graph files as they are typed.
    Schema,
    /// Run a benchmark suite.
    Bench(weft_bench::BenchArgs),
}

/// Runs the command line `args` (the first item is the program name).
pub fn main_with_args<I, T>(args: I) -> ExitCode
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    cap_malloc_arenas();
    let cli = match Cli::try_parse_from(args) {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return if e.use_stderr() {
                ExitCode::from(2)
            } else {
                ExitCode::SUCCESS
            };
        }
    };
    match cli.threads {
        Some(n) => match rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build()
        {
            Ok(pool) => pool.install(|| dispatch(cli.command)),
            Err(e) => {
                eprintln!("error: cannot start {n} threads: {e}");
                ExitCode::from(1)
            }
        },
        None => dispatch(cli.command),
    }
}

fn dispatch(command: Command) -> ExitCode {
    let registry = weft_nodes::registry();
    match command {
        Command::Run(a) => run::run(&registry, a),
        Command::Validate { graphs } => validate(&registry, &graphs),
        Command::Nodes { json, filter } => {
            print_out(&nodes::render(&registry, json, filter.as_deref()))
        }
        Command::Schema => {
            let schema = weft_graph::graph_schema(&registry);
            print_out(&(serde_json::to_string_pretty(&schema).unwrap_or_default() + "\n"))
        }
        Command::Bench(a) => weft_bench::run(&registry, a),
    }
}

/// Writes `text` to stdout: a reader that closes the pipe early (`weft schema | head`) ends
/// the output, not the process with a panic.
fn print_out(text: &str) -> ExitCode {
    use std::io::Write;
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            eprintln!("error: cannot write the output: {e}");
            ExitCode::from(1)
        }
        _ => ExitCode::SUCCESS,
    }
}

fn validate(registry: &std::sync::Arc<weft_graph::Registry>, graphs: &[PathBuf]) -> ExitCode {
    let mut bad = 0;
    for path in graphs {
        match weft_graph::load_path(registry, path) {
            Ok(g) => {
                for w in g.load_warnings() {
                    eprintln!("{}: {w}", path.display());
                }
                let outs: Vec<&str> = g.output_names().collect();
                println!(
                    "ok: {} ({} nodes; outputs: {})",
                    path.display(),
                    g.node_ids().count(),
                    outs.join(", ")
                );
            }
            Err(e) => {
                bad += 1;
                eprint!("{e}");
            }
        }
    }
    if bad > 0 {
        ExitCode::from(2)
    } else {
        ExitCode::SUCCESS
    }
}

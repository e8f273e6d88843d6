//! `weft-fuzz`: see the library's documentation. `weft-fuzz --help` lists the options.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// A seeded mutation fuzzer over Weft's graph files and OBJ meshes.
#[derive(Parser, Debug)]
#[command(name = "weft-fuzz", about)]
struct Cli {
    #[command(subcommand)]
    command: Option<Cmd>,
    #[command(flatten)]
    opts: Opts,
}

#[derive(clap::Args, Debug, Clone)]
struct Opts {
    /// Cases to run [default: 1000, unless --seconds is given].
    #[arg(long, global = true)]
    cases: Option<u64>,
    /// Stop starting cases after this many seconds.
    #[arg(long, global = true)]
    seconds: Option<f64>,
    /// Seed of the case generator (a run is reproducible from it).
    #[arg(long, default_value_t = 1, global = true)]
    seed: u64,
    /// Run only this case index (to reproduce one).
    #[arg(long, global = true)]
    only: Option<u64>,
    /// Worker processes side by side [default: one per core].
    #[arg(long, global = true)]
    jobs: Option<usize>,
    /// Each worker's memory ceiling (address space) in MiB; an allocation past it aborts
    /// the worker, which counts as a defect.
    #[arg(long, default_value_t = 4096, global = true)]
    memory_limit_mib: u64,
    /// Each case's `weft run --time-limit` in seconds.
    #[arg(long, default_value_t = 10.0, global = true)]
    time_limit: f64,
    /// Seconds past the time limit after which a silent worker is a hang.
    #[arg(long, default_value_t = 20.0, global = true)]
    grace: f64,
    /// Frames each case runs.
    #[arg(long, default_value = "0..1", global = true)]
    frames: String,
    /// Seed directories, or single seed graph files [default: graphs/, tests/fuzz/seeds/ and
    /// the verification scenes].
    #[arg(long = "seeds", global = true)]
    seeds: Vec<PathBuf>,
    /// Copy every failing case here [default: fuzz-out/failures].
    #[arg(long, global = true)]
    save: Option<PathBuf>,
    /// Write the report as JSON.
    #[arg(long, global = true)]
    json: Option<PathBuf>,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Run saved cases again (case directories, or directories of them).
    Replay {
        /// Case directories.
        dirs: Vec<PathBuf>,
    },
    /// Internal: the worker process.
    #[command(hide = true)]
    Worker {
        #[arg(long)]
        memory_limit_bytes: u64,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let o = cli.opts;
    let exe = match std::env::current_exe() {
        Ok(e) => e,
        Err(e) => {
            eprintln!("error: cannot find this program's path: {e}");
            return ExitCode::from(2);
        }
    };
    let cfg = weft_fuzz::Config {
        seed: o.seed,
        cases: Some(
            o.cases
                .unwrap_or(if o.seconds.is_some() { u64::MAX } else { 1000 }),
        ),
        seconds: o.seconds,
        jobs: o
            .jobs
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(2, |n| n.get())),
        memory_limit: o.memory_limit_mib << 20,
        time_limit: o.time_limit,
        grace: o.grace,
        frames: o.frames.clone(),
        save: Some(
            o.save
                .clone()
                .unwrap_or_else(|| PathBuf::from("fuzz-out/failures")),
        ),
        worker_exe: exe,
        verbose: true,
    };
    let report = match cli.command {
        Some(Cmd::Worker { memory_limit_bytes }) => {
            let args = weft_fuzz::weft_args(&o.frames, Some(o.time_limit));
            return match weft_fuzz::worker_main(memory_limit_bytes, args) {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => {
                    eprintln!("worker: {e}");
                    ExitCode::from(3)
                }
            };
        }
        Some(Cmd::Replay { dirs }) => {
            let mut cases = Vec::new();
            for d in &dirs {
                match weft_fuzz::case_dirs(d) {
                    Ok(c) => cases.extend(c),
                    Err(e) => {
                        eprintln!("error: {}: {e}", d.display());
                        return ExitCode::from(2);
                    }
                }
            }
            weft_fuzz::replay(&cfg, &cases)
        }
        None => {
            let dirs = if o.seeds.is_empty() {
                weft_fuzz::default_seed_dirs()
            } else {
                o.seeds.clone()
            };
            let seeds = match weft_fuzz::load_seeds(&dirs) {
                Ok(s) if !s.is_empty() => s,
                Ok(_) => {
                    eprintln!("error: no seed graphs in {dirs:?}");
                    return ExitCode::from(2);
                }
                Err(e) => {
                    eprintln!("error: cannot read the seeds: {e}");
                    return ExitCode::from(2);
                }
            };
            let mutator = weft_fuzz::mutate::Mutator::new(&seeds, weft_fuzz::node_types());
            let mut cfg = cfg;
            if let Some(i) = o.only {
                cfg.jobs = 1;
                cfg.cases = Some(1);
                let one = weft_fuzz::mutate::Mutator::new(&seeds, weft_fuzz::node_types());
                let case = one.case(&seeds, cfg.seed, i);
                let dir = PathBuf::from(format!("fuzz-out/case-{}-{i}", cfg.seed));
                if let Err(e) = weft_fuzz::write_case(&dir, &case) {
                    eprintln!("error: {e}");
                    return ExitCode::from(2);
                }
                eprintln!(
                    "case {i} from {}: {:?}\nwritten to {}",
                    case.origin,
                    case.mutations,
                    dir.display()
                );
                weft_fuzz::replay(&cfg, &[dir])
            } else {
                weft_fuzz::fuzz(&cfg, &seeds, &mutator)
            }
        }
    };
    match report {
        Ok(r) => {
            print!("{}", r.summary());
            if let Some(p) = &o.json
                && let Err(e) =
                    std::fs::write(p, serde_json::to_string_pretty(&r).unwrap_or_default())
            {
                eprintln!("error: cannot write {}: {e}", p.display());
            }
            if r.defect_count() > 0 {
                ExitCode::from(1)
            } else {
                ExitCode::SUCCESS
            }
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

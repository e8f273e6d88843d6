//! The supervisor: generates cases, hands them to worker processes, classifies what came
//! back, keeps every failing case, and counts.
//!
//! A case fails when `weft` panics, when the worker dies (an abort: an allocation over the
//! memory ceiling, a stack overflow, a signal), or when it does not answer within the hang
//! limit (the run's own `--time-limit` plus a grace: a run that ignores its time limit is a
//! hang). Everything else is a result: a run that succeeds, a graph file that is refused
//! (exit 2) or a run that fails with an error (exit 1), each counted by the kind of error.

use crate::mutate::{Case, Mutator, Seed};
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How a case ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// `weft run` succeeded.
    Ok,
    /// The graph file was refused with diagnostics (exit 2).
    Refused,
    /// The run failed with an error (exit 1).
    Failed,
    /// `weft` panicked: a defect.
    Panic,
    /// The worker process died (abort, signal): a defect.
    Abort,
    /// No answer within the hang limit: a defect.
    Hang,
    /// Stopped by its time limit without having said why it runs long: no warning before
    /// (a cost estimate, a contact band taking in the scene) and no progress line inside
    /// the frame it was stopped in (what the evaluation under way is doing). A user would
    /// have watched it for the time limit with nothing to go on: a defect.
    Silent,
}

impl Kind {
    /// True for the outcomes that are defects in Weft.
    pub fn is_defect(self) -> bool {
        matches!(self, Kind::Panic | Kind::Abort | Kind::Hang | Kind::Silent)
    }
}

/// Whether a run stopped by its time limit of `limit` seconds did so without a word of why
/// it ran long: no warning and no progress line of the frame under way (`frame 3: 6 s so
/// far: …`), though the frame it was stopped in ran long enough for one to be due
/// (`weft_cli::PROGRESS_FIRST_LINE`, and a second for the stop itself; the frames finished
/// before are in its `frame F (i/n): T ms` lines).
fn silent(stderr: &str, limit: f64) -> bool {
    let said = stderr
        .lines()
        .any(|l| l.starts_with("warning: ") || l.contains(" s so far: "));
    let done: f64 = stderr
        .lines()
        .filter(|l| l.starts_with("frame ") && l.ends_with(" ms"))
        .filter_map(|l| {
            l.rsplit(": ")
                .next()?
                .strip_suffix(" ms")?
                .parse::<f64>()
                .ok()
        })
        .sum::<f64>()
        / 1e3;
    let due = weft_cli::PROGRESS_FIRST_LINE.as_secs_f64() + 1.0;
    !said && limit - done >= due
}

/// One case's outcome.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Outcome {
    /// How it ended.
    pub kind: Kind,
    /// The error's category (for refused and failed runs), or the defect's description.
    pub detail: String,
    /// Wall time [s].
    pub seconds: f64,
}

/// What a fuzz run is asked to do.
#[derive(Clone, Debug)]
pub struct Config {
    /// Seed of the case generator.
    pub seed: u64,
    /// Stop after this many cases.
    pub cases: Option<u64>,
    /// Stop starting cases after this many seconds.
    pub seconds: Option<f64>,
    /// Worker processes run side by side.
    pub jobs: usize,
    /// Each worker's address-space ceiling [bytes] (0: none).
    pub memory_limit: u64,
    /// `weft run --time-limit` for each case [s].
    pub time_limit: f64,
    /// Seconds past the time limit after which a silent worker is a hang.
    pub grace: f64,
    /// Frames each case runs.
    pub frames: String,
    /// Where failing cases are copied (one directory each).
    pub save: Option<PathBuf>,
    /// The worker executable (this program).
    pub worker_exe: PathBuf,
    /// Print a line per defect as it happens.
    pub verbose: bool,
}

/// Counts of a fuzz run.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Report {
    /// Cases run.
    pub runs: u64,
    /// Cases per outcome.
    pub by_kind: BTreeMap<String, u64>,
    /// Refused and failed cases per error category.
    pub errors: BTreeMap<String, u64>,
    /// Every defect: case index (or corpus path), origin, outcome, where it was saved.
    pub defects: Vec<serde_json::Value>,
    /// Wall time [s].
    pub seconds: f64,
    /// The slowest case [s].
    pub slowest: f64,
}

impl Report {
    /// Number of defects (panics, aborts, hangs, silent long runs).
    pub fn defect_count(&self) -> usize {
        self.defects.len()
    }

    fn add(&mut self, o: &Outcome) {
        self.runs += 1;
        let k = serde_json::to_value(o.kind)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        *self.by_kind.entry(k.clone()).or_default() += 1;
        if matches!(o.kind, Kind::Refused | Kind::Failed) {
            *self.errors.entry(format!("{k}: {}", o.detail)).or_default() += 1;
        }
        self.slowest = self.slowest.max(o.seconds);
    }

    /// A plain-text summary.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "{} cases in {:.1} s (slowest {:.2} s)\n",
            self.runs, self.seconds, self.slowest
        );
        for (k, n) in &self.by_kind {
            s += &format!("  {k:<8} {n}\n");
        }
        s += "errors by kind:\n";
        let mut e: Vec<_> = self.errors.iter().collect();
        e.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
        for (k, n) in e {
            s += &format!("  {n:>6}  {k}\n");
        }
        s += &format!(
            "defects (panic, abort, hang, silent): {}\n",
            self.defects.len()
        );
        for d in &self.defects {
            s += &format!("  {d}\n");
        }
        s
    }
}

/// The category of an error message: the first `error` line of `weft`'s stderr, reduced to
/// what kind of mistake or failure it reports.
pub fn category(stderr: &str) -> String {
    // The first diagnostic: `FILE: line L, column C: error: node 'n': param 'p': message`
    // or `error: node 'n' at frame F: message`; keep the message.
    let line = stderr
        .lines()
        .find(|l| l.contains("error: "))
        .unwrap_or_else(|| stderr.lines().next().unwrap_or(""));
    let mut msg = line.split_once("error: ").map_or(line, |(_, m)| m).trim();
    // Strip the `node 'n': `, `node 'n' at frame F: `, `param 'p': `, `params: ` prefixes.
    loop {
        let next = ["node '", "param '", "input '", "output '", "subgraph '"]
            .iter()
            .find_map(|p| msg.strip_prefix(p))
            .and_then(|r| r.split_once('\''))
            .and_then(|(_, after)| {
                after.strip_prefix(": ").or_else(|| {
                    after
                        .strip_prefix(" at frame ")
                        .and_then(|r| r.split_once(": ").map(|(_, m)| m))
                })
            })
            .or_else(|| msg.strip_prefix("params: "));
        match next {
            Some(rest) => msg = rest.trim(),
            None => break,
        }
    }
    let l = msg.to_lowercase();
    const KINDS: &[(&str, &str)] = &[
        ("invalid json", "invalid JSON"),
        ("duplicate", "duplicate key or id"),
        ("unknown node type", "unknown node type"),
        ("has no such parameter", "unknown parameter"),
        ("missing required parameter", "missing parameter"),
        ("missing required input", "missing input"),
        ("missing '", "missing field"),
        ("missing \"", "missing field"),
        ("type mismatch", "type mismatch"),
        ("cycle", "cycle"),
        (
            "connection to unknown node",
            "connection to an unknown node",
        ),
        ("has no input", "unknown input port"),
        ("has no output", "unknown output port"),
        ("expected \"node.port\"", "malformed connection"),
        ("takes one connection", "list on a single input"),
        ("unknown field", "unknown field"),
        ("node ids may use only", "bad node id"),
        ("format", "format or version"),
        ("version", "format or version"),
        ("the file declares no", "no outputs"),
        ("unknown port type", "unknown port type"),
        ("cannot run inside", "stateful node inside a subgraph"),
        ("subgraph", "subgraph definition"),
        ("time limit", "time limit reached"),
        ("interrupted", "interrupted"),
        ("gib", "memory estimate refused"),
        ("mib", "memory estimate refused"),
        ("can index", "too many vertices to index"),
        ("non-finite", "non-finite value"),
        ("not finite", "non-finite value"),
        ("finite number", "non-finite value"),
        ("formula gave", "non-finite value"),
        ("nan", "non-finite value"),
        ("converge", "did not converge"),
        ("out of range", "index out of range"),
        ("not a vertex index", "bad vertex index"),
        ("cannot read", "cannot read a file"),
        ("obj file", "bad OBJ file"),
        ("cannot write", "cannot write a file"),
        ("outside", "path outside the output directory"),
        ("climbs out", "path outside the output directory"),
        ("zero rest", "degenerate geometry"),
        ("degenerate", "degenerate geometry"),
        ("has no mass", "no material Behavior for an element"),
        ("the formula", "bad expression"),
        ("cannot parse", "bad expression"),
        ("unknown variable", "bad expression"),
        ("expression", "bad expression"),
        ("must be", "parameter out of range"),
        ("must exceed", "parameter out of range"),
        ("expected", "parameter of the wrong kind"),
        ("unique", "duplicate element name"),
        ("attachment", "bad attachment"),
        ("no element", "unknown element"),
        ("element", "bad element"),
        ("no output", "unknown output"),
        ("empty", "empty input"),
        ("no value was given", "unset input"),
    ];
    for (needle, kind) in KINDS {
        if l.contains(needle) {
            return kind.to_string();
        }
    }
    let mut s: String = msg.chars().take(80).collect();
    if s.is_empty() {
        s = "(no message)".into();
    }
    format!("other: {s}")
}

struct Worker {
    child: Child,
    stdin: ChildStdin,
    replies: Receiver<String>,
}

impl Worker {
    fn start(cfg: &Config) -> std::io::Result<Worker> {
        let mut child = Command::new(&cfg.worker_exe)
            .arg("--time-limit")
            .arg(cfg.time_limit.to_string())
            .arg("--frames")
            .arg(&cfg.frames)
            .arg("worker")
            .arg("--memory-limit-bytes")
            .arg(cfg.memory_limit.to_string())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()?;
        let stdin = child
            .stdin
            .take()
            .ok_or_else(|| std::io::Error::other("no stdin"))?;
        let stdout = child
            .stdout
            .take()
            .ok_or_else(|| std::io::Error::other("no stdout"))?;
        let (tx, rx) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                match line {
                    Ok(l) => {
                        if tx.send(l).is_err() {
                            break;
                        }
                    }
                    Err(_) => break,
                }
            }
        });
        Ok(Worker {
            child,
            stdin,
            replies: rx,
        })
    }

    fn kill(mut self) -> String {
        let _ = self.child.kill();
        match self.child.wait() {
            Ok(s) => describe_status(s),
            Err(e) => format!("wait failed: {e}"),
        }
    }
}

fn describe_status(s: std::process::ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (s.code(), s.signal()) {
        (_, Some(sig)) => format!("killed by signal {sig}"),
        (Some(c), _) => format!("exited with {c}"),
        _ => "ended".into(),
    }
}

/// Writes a case into `dir` (which must not exist).
pub fn write_case(dir: &Path, case: &Case) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    std::fs::write(dir.join("graph.json"), &case.graph)?;
    for (name, bytes) in &case.files {
        std::fs::write(dir.join(name), bytes)?;
    }
    Ok(())
}

/// Reads a saved case directory back (`graph.json` and every `.obj` beside it).
pub fn read_case(dir: &Path) -> std::io::Result<Case> {
    let graph = std::fs::read_to_string(dir.join("graph.json"))?;
    let mut files = Vec::new();
    for e in std::fs::read_dir(dir)? {
        let p = e?.path();
        if p.extension().is_some_and(|x| x == "obj") {
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            files.push((name, std::fs::read(&p)?));
        }
    }
    files.sort();
    Ok(Case {
        origin: dir.display().to_string(),
        mutations: Vec::new(),
        graph,
        files,
    })
}

/// Runs one case on `worker` (started if absent, replaced after a defect).
fn run_case(
    slot: &mut Option<Worker>,
    cfg: &Config,
    work: &Path,
    case: &Case,
) -> std::io::Result<Outcome> {
    let _ = std::fs::remove_dir_all(work);
    write_case(work, case)?;
    if slot.is_none() {
        *slot = Some(Worker::start(cfg)?);
    }
    let w = slot.as_mut().expect("started above");
    let t0 = Instant::now();
    let sent = writeln!(w.stdin, "{}", work.display()).and_then(|_| w.stdin.flush());
    let limit = Duration::from_secs_f64(cfg.time_limit + cfg.grace);
    let reply = match sent {
        Ok(()) => w.replies.recv_timeout(limit),
        Err(_) => Err(RecvTimeoutError::Disconnected),
    };
    let stderr = || std::fs::read_to_string(work.join("stderr.txt")).unwrap_or_default();
    let outcome = match reply {
        Ok(line) => {
            let j: serde_json::Value = serde_json::from_str(&line).unwrap_or_default();
            let seconds = j["seconds"].as_f64().unwrap_or(0.0);
            if let Some(p) = j["panic"].as_str() {
                Outcome {
                    kind: Kind::Panic,
                    detail: p.to_string(),
                    seconds,
                }
            } else {
                let kind = match j["exit"].as_u64() {
                    Some(0) => Kind::Ok,
                    Some(2) => Kind::Refused,
                    _ => Kind::Failed,
                };
                let err = if kind == Kind::Ok {
                    String::new()
                } else {
                    stderr()
                };
                let detail = if kind == Kind::Ok {
                    String::new()
                } else {
                    category(&err)
                };
                let kind = if detail == "time limit reached" && silent(&err, cfg.time_limit) {
                    Kind::Silent
                } else {
                    kind
                };
                Outcome {
                    kind,
                    detail,
                    seconds,
                }
            }
        }
        Err(RecvTimeoutError::Timeout) => {
            let status = slot.take().map(Worker::kill).unwrap_or_default();
            Outcome {
                kind: Kind::Hang,
                detail: format!(
                    "no answer after {:.0} s ({status})",
                    t0.elapsed().as_secs_f64()
                ),
                seconds: t0.elapsed().as_secs_f64(),
            }
        }
        Err(RecvTimeoutError::Disconnected) => {
            let status = slot.take().map(Worker::kill).unwrap_or_default();
            let last: Vec<&str> = Vec::new();
            let err = stderr();
            let tail = err.lines().rev().take(2).collect::<Vec<_>>();
            let tail = if tail.is_empty() { last } else { tail };
            Outcome {
                kind: Kind::Abort,
                detail: format!("worker {status}: {}", tail.join(" | ")),
                seconds: t0.elapsed().as_secs_f64(),
            }
        }
    };
    Ok(outcome)
}

fn save_case(
    save: &Path,
    name: &str,
    case: &Case,
    o: &Outcome,
    work: &Path,
    extra: &str,
) -> std::io::Result<PathBuf> {
    let dir = save.join(name);
    let _ = std::fs::remove_dir_all(&dir);
    write_case(&dir, case)?;
    let stderr = std::fs::read_to_string(work.join("stderr.txt")).unwrap_or_default();
    let text = format!(
        "origin: {}\n{extra}mutations:\n{}\noutcome: {:?}: {}\nstderr:\n{}\n",
        case.origin,
        case.mutations
            .iter()
            .map(|m| format!("  - {m}"))
            .collect::<Vec<_>>()
            .join("\n"),
        o.kind,
        o.detail,
        stderr.chars().take(4000).collect::<String>()
    );
    std::fs::write(dir.join("case.txt"), text)?;
    Ok(dir)
}

/// Runs cases until the count or the time is reached, `cfg.jobs` workers side by side.
pub fn fuzz(cfg: &Config, seeds: &[Seed], mutator: &Mutator) -> std::io::Result<Report> {
    let root = tempfile::Builder::new().prefix("weft-fuzz-").tempdir()?;
    let next = AtomicU64::new(0);
    let report = Arc::new(Mutex::new(Report::default()));
    let t0 = Instant::now();
    let stop = |i: u64| {
        cfg.cases.is_some_and(|n| i >= n)
            || cfg.seconds.is_some_and(|s| t0.elapsed().as_secs_f64() >= s)
    };
    std::thread::scope(|s| -> std::io::Result<()> {
        let mut handles = Vec::new();
        for j in 0..cfg.jobs.max(1) {
            let (next, report, root) = (&next, report.clone(), root.path());
            handles.push(s.spawn(move || -> std::io::Result<()> {
                let mut worker = None;
                let work = root.join(format!("job{j}"));
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if stop(i) {
                        break;
                    }
                    let case = mutator.case(seeds, cfg.seed, i);
                    let o = run_case(&mut worker, cfg, &work, &case)?;
                    let mut saved = None;
                    if o.kind.is_defect() {
                        if cfg.verbose {
                            eprintln!("case {i} ({}): {:?}: {}", case.origin, o.kind, o.detail);
                        }
                        if let Some(dir) = &cfg.save {
                            let extra =
                                format!("reproduce: weft-fuzz --seed {} --only {i}\n", cfg.seed);
                            saved = Some(save_case(
                                dir,
                                &format!("case-{}-{i}", cfg.seed),
                                &case,
                                &o,
                                &work,
                                &extra,
                            )?);
                        }
                    }
                    let mut r = report
                        .lock()
                        .map_err(|_| std::io::Error::other("poisoned"))?;
                    r.add(&o);
                    if o.kind.is_defect() {
                        r.defects.push(serde_json::json!({
                            "case": i, "origin": case.origin, "kind": o.kind, "detail": o.detail,
                            "saved": saved.map(|p| p.display().to_string()),
                        }));
                    }
                }
                if let Some(w) = worker {
                    drop(w.stdin);
                    let mut c = w.child;
                    let _ = c.wait();
                }
                Ok(())
            }));
        }
        for h in handles {
            h.join()
                .map_err(|_| std::io::Error::other("a job thread panicked"))??;
        }
        Ok(())
    })?;
    let mut r = report
        .lock()
        .map_err(|_| std::io::Error::other("poisoned"))?
        .clone();
    r.seconds = t0.elapsed().as_secs_f64();
    Ok(r)
}

/// Runs saved cases (each a directory with `graph.json`) and reports them like a fuzz run.
pub fn replay(cfg: &Config, cases: &[PathBuf]) -> std::io::Result<Report> {
    let root = tempfile::Builder::new().prefix("weft-replay-").tempdir()?;
    let work = root.path().join("case");
    let mut worker = None;
    let mut r = Report::default();
    let t0 = Instant::now();
    for dir in cases {
        let case = read_case(dir)?;
        let o = run_case(&mut worker, cfg, &work, &case)?;
        r.add(&o);
        if o.kind.is_defect() {
            if cfg.verbose {
                eprintln!("{}: {:?}: {}", dir.display(), o.kind, o.detail);
            }
            r.defects.push(serde_json::json!({
                "case": dir.display().to_string(), "kind": o.kind, "detail": o.detail,
            }));
        }
    }
    if let Some(w) = worker {
        drop(w.stdin);
        let mut c = w.child;
        let _ = c.wait();
    }
    r.seconds = t0.elapsed().as_secs_f64();
    Ok(r)
}

/// The case directories under `dir`: `dir` itself when it holds a `graph.json`, else its
/// subdirectories that do, sorted.
pub fn case_dirs(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    if dir.join("graph.json").is_file() {
        return Ok(vec![dir.to_path_buf()]);
    }
    let mut v = Vec::new();
    for e in std::fs::read_dir(dir)? {
        let p = e?.path();
        if p.join("graph.json").is_file() {
            v.push(p);
        }
    }
    v.sort();
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::category;

    #[test]
    fn a_time_limited_run_must_have_said_why_it_ran_long() {
        let stopped = "error: node 'solve' at frame 1: time limit of 10 s reached";
        assert!(super::silent(stopped, 10.0));
        assert!(super::silent(
            &format!("frame 0 (1/2): 20.5 ms\n{stopped}"),
            10.0
        ));
        // Frame 1 ran 10 − 7.5 s, too short for its first progress line.
        assert!(!super::silent(
            &format!("frame 0 (1/2): 7500.0 ms\n{stopped}"),
            10.0
        ));
        assert!(!super::silent(stopped, 3.0));
        let line = "frame 1: 5 s so far: 'solve': substep 1 of 4";
        assert!(!super::silent(&format!("{line}\n{stopped}"), 10.0));
        let warned = "warning: node 'solve' at frame 0: a rough cost model …";
        assert!(!super::silent(&format!("{warned}\n{stopped}"), 10.0));
    }

    #[test]
    fn errors_are_counted_by_what_they_report() {
        let load = "g.json: 2 errors in graph file\n  g.json: line 8, column 78: error: node 'grid': param 'nx': expected an integer, got \"a\"\n";
        assert_eq!(category(load), "parameter of the wrong kind");
        let port = "  g.json: line 3, column 1: error: node 'c': input 'x': node 'probe' (coupled.probe) has no output 'y' (outputs: velocity, max_speed)";
        assert_eq!(category(port), "unknown output port");
        let run = "error: node 'solve' at frame 1: time limit of 2 s reached: stopped at frame 1";
        assert_eq!(category(run), "time limit reached");
        let factory = "  g.json: line 9, column 5: error: node 'pins': params: param 'vertices': -1 is not a vertex index";
        assert_eq!(category(factory), "bad vertex index");
        assert_eq!(category(""), "other: (no message)");
    }
}

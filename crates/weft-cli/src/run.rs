//! `weft run`: evaluate outputs over frames, print them, write them, report statistics.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;
use weft_graph::{Context, Graph, Registry, Value};

/// Arguments of `weft run`.
#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// Graph file (JSON).
    graph: PathBuf,
    /// Frames to evaluate, inclusive: `A..B` or a single frame [default: 0..24 when an output
    /// depends on time, else 0].
    #[arg(long)]
    frames: Option<String>,
    /// Frames per second (time = frame / fps).
    #[arg(long, default_value_t = 24.0)]
    fps: f64,
    /// Override a parameter, `node.param=value`; the value is JSON, a bare word is a string.
    /// Repeatable. Inside a composite instance use `instance.stage.param=value`.
    #[arg(long = "set", value_name = "NODE.PARAM=VALUE")]
    sets: Vec<String>,
    /// Evaluate only these outputs (repeatable) [default: all].
    #[arg(long = "output", value_name = "NAME")]
    outputs: Vec<String>,
    /// Directory for everything the run writes: outputs.json, outputs.csv, stats.json, and
    /// the files of output and cache nodes, whose relative paths resolve under it.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Print per-node evaluation counts and times after the run.
    #[arg(long)]
    stats: bool,
    /// Write per-node statistics, with per-iteration reports of iterating nodes, as JSON.
    #[arg(long, value_name = "FILE")]
    stats_json: Option<PathBuf>,
    /// Print only errors and warnings.
    #[arg(long, short)]
    quiet: bool,
    /// With --out: keep no solver checkpoints in DIR/checkpoints (a run killed and run
    /// again then recomputes every frame instead of resuming).
    #[arg(long)]
    no_checkpoints: bool,
    /// Stop the run after this many seconds (as Ctrl-C does): the frames completed before
    /// are kept and written.
    #[arg(long, value_name = "SECONDS")]
    time_limit: Option<f64>,
}

/// The interrupt of the run in progress, which Ctrl-C stops. One handler serves the
/// process; each run puts its graph's handle here.
static CURRENT: std::sync::Mutex<Option<weft_graph::Interrupt>> = std::sync::Mutex::new(None);

/// Installs the Ctrl-C handler once: the first Ctrl-C stops the run at the next iteration
/// (the frames done are written), a second one ends the process at once.
fn install_ctrl_c(i: &weft_graph::Interrupt) {
    static INSTALLED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    if let Ok(mut c) = CURRENT.lock() {
        *c = Some(i.clone());
    }
    INSTALLED.get_or_init(|| {
        ctrlc::set_handler(|| {
            let cur = CURRENT.lock().ok().and_then(|c| c.clone());
            match cur {
                Some(i) if !i.is_set() => {
                    eprintln!("\nstopping at the next iteration (Ctrl-C again to quit at once)");
                    i.stop();
                }
                _ => std::process::exit(130),
            }
        })
        .is_ok()
    });
}

/// The largest frame number (a start frame's range too): beyond it frame arithmetic could
/// overflow.
const MAX_FRAME: i64 = 1_000_000_000;

/// Parses `A..B` (inclusive) or `F`.
pub fn parse_frames(s: &str) -> Result<Vec<i64>, String> {
    let bad = || format!("--frames expects A..B or a frame number, got {s:?}");
    match s.split_once("..") {
        Some((a, b)) => {
            let a: i64 = a.trim().parse().map_err(|_| bad())?;
            let b: i64 = b.trim().parse().map_err(|_| bad())?;
            if ![a, b].iter().all(|f| (-MAX_FRAME..=MAX_FRAME).contains(f)) {
                return Err(format!("--frames {s}: frames lie within ±{MAX_FRAME}"));
            }
            if b < a {
                return Err(format!(
                    "--frames {s}: the last frame comes before the first"
                ));
            }
            if b - a > 10_000_000 {
                return Err(format!("--frames {s}: more than ten million frames"));
            }
            Ok((a..=b).collect())
        }
        None => {
            let f: i64 = s.trim().parse().map_err(|_| bad())?;
            if !(-MAX_FRAME..=MAX_FRAME).contains(&f) {
                return Err(format!("--frames {s}: frames lie within ±{MAX_FRAME}"));
            }
            Ok(vec![f])
        }
    }
}

/// Applies one `node.param=value` override.
pub fn apply_set(g: &mut Graph, s: &str) -> Result<(), String> {
    let (lhs, rhs) = s
        .split_once('=')
        .ok_or_else(|| format!("--set {s:?}: expected node.param=value"))?;
    let (node, param) = lhs
        .split_once('.')
        .ok_or_else(|| format!("--set {s:?}: expected node.param=value"))?;
    let value =
        serde_json::from_str(rhs).unwrap_or_else(|_| serde_json::Value::String(rhs.to_string()));
    g.set_param(node, param, value)
        .map_err(|d| format!("--set {s}: {}", d.describe()))
}

fn to_json(reg: &Registry, v: &Value) -> serde_json::Value {
    reg.type_of(v)
        .and_then(|t| t.to_json)
        .and_then(|f| f(v))
        .unwrap_or_else(|| {
            serde_json::Value::String(format!(
                "<{}>",
                reg.type_of(v).map_or("value", |t| t.name.as_str())
            ))
        })
}

fn cell(j: &serde_json::Value) -> String {
    match j {
        serde_json::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// Runs `weft run`.
pub fn run(registry: &Arc<Registry>, a: RunArgs) -> ExitCode {
    let mut g = match weft_graph::load_path(registry, &a.graph) {
        Ok(g) => g,
        Err(e) => {
            eprint!("{e}");
            return ExitCode::from(2);
        }
    };
    for w in g.load_warnings() {
        eprintln!("{}: {w}", a.graph.display());
    }
    for s in &a.sets {
        if let Err(m) = apply_set(&mut g, s) {
            eprintln!("error: {m}");
            return ExitCode::from(2);
        }
    }
    if !(a.fps.is_finite() && a.fps > 0.0) {
        eprintln!("error: --fps must be a positive number, got {}", a.fps);
        return ExitCode::from(2);
    }
    g.set_output_root(a.out.clone());
    if !a.no_checkpoints {
        g.set_checkpoint_dir(a.out.as_ref().map(|d| d.join("checkpoints")));
    }
    let interrupt = g.interrupt();
    interrupt.reset();
    if let Some(t) = a.time_limit {
        match std::time::Duration::try_from_secs_f64(t) {
            Ok(d) => interrupt.set_time_limit(d),
            Err(_) => {
                eprintln!("error: --time-limit must be a number of seconds >= 0, got {t}");
                return ExitCode::from(2);
            }
        }
    }
    install_ctrl_c(&interrupt);
    let outputs: Vec<String> = if a.outputs.is_empty() {
        g.output_names().map(str::to_string).collect()
    } else {
        a.outputs.clone()
    };
    for o in &outputs {
        if g.output_type(o).is_none() {
            let known: Vec<&str> = g.output_names().collect();
            eprintln!(
                "error: the graph has no output '{o}' (outputs: {})",
                known.join(", ")
            );
            return ExitCode::from(2);
        }
    }
    let timed = outputs
        .iter()
        .any(|o| g.output_is_time_dependent(o) == Some(true));
    let frames = match a.frames.as_deref().map(parse_frames) {
        Some(Ok(f)) => f,
        Some(Err(m)) => {
            eprintln!("error: {m}");
            return ExitCode::from(2);
        }
        None if timed => (0..=24).collect(),
        None => vec![0],
    };

    let tty = std::io::stderr().is_terminal();
    let bar = (tty && !a.quiet && frames.len() > 1).then(|| {
        let b = ProgressBar::new(frames.len() as u64);
        b.set_style(
            ProgressStyle::with_template(
                "{bar:30} {pos}/{len} frames  {msg}  [{elapsed_precise}, eta {eta}]",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    });
    // Warnings are printed when raised (a cost estimate before a long frame, a retried
    // substep), above the progress bar.
    let sink_bar = bar.clone();
    g.set_warning_sink(Some(std::sync::Arc::new(
        move |w: &weft_graph::RunWarning| {
            let line = warning_line(w);
            match &sink_bar {
                Some(b) => b.println(line),
                None => eprintln!("{line}"),
            }
        },
    )));
    let mut rows: Vec<(i64, Vec<serde_json::Value>)> = Vec::new();
    let mut failure = None;
    // Per frame: its evaluation's seconds and how many of them the output nodes (files
    // written) took, for the statistics.
    let writers: Vec<String> = g
        .node_ids()
        .filter(|id| {
            g.node_spec(id)
                .is_some_and(|s| s.name.starts_with("output."))
        })
        .map(str::to_owned)
        .collect();
    let written = |g: &Graph| -> f64 {
        writers
            .iter()
            .filter_map(|id| g.node_stats(id))
            .map(|s| s.seconds)
            .sum()
    };
    let mut timings = Vec::with_capacity(frames.len());
    let t_run = Instant::now();
    let ticker = (!a.quiet).then(|| crate::ticker::Ticker::start(interrupt.clone(), bar.clone()));
    for (i, &f) in frames.iter().enumerate() {
        if let Some(t) = &ticker {
            t.frame(f);
        }
        let ctx = Context::at(f, a.fps);
        let t0 = Instant::now();
        let w0 = written(&g);
        let mut row = Vec::with_capacity(outputs.len());
        for o in &outputs {
            match g.pull(o, ctx) {
                Ok(v) => row.push(to_json(registry, &v)),
                Err(e) => {
                    failure = Some(e);
                    break;
                }
            }
        }
        if failure.is_some() {
            break;
        }
        rows.push((f, row));
        let seconds = t0.elapsed().as_secs_f64();
        let ms = seconds * 1e3;
        timings.push(FrameTiming {
            frame: f,
            seconds,
            output_seconds: written(&g) - w0,
        });
        match &bar {
            Some(b) => {
                b.set_message(format!("frame {f}: {ms:.2} ms"));
                b.inc(1);
            }
            None if !a.quiet && frames.len() > 1 => {
                eprintln!("frame {f} ({}/{}): {ms:.3} ms", i + 1, frames.len())
            }
            None => {}
        }
    }
    drop(ticker);
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let seconds = t_run.elapsed().as_secs_f64();

    if !a.quiet {
        println!("frame\t{}", outputs.join("\t"));
        for (f, row) in &rows {
            let cells: Vec<String> = row.iter().map(cell).collect();
            println!("{f}\t{}", cells.join("\t"));
        }
    }
    let mut code = ExitCode::SUCCESS;
    if let Some(dir) = &a.out
        && let Err(e) = write_outputs(dir, &a, &outputs, &rows, &g, seconds, &timings)
    {
        eprintln!("error: cannot write to {}: {e}", dir.display());
        code = ExitCode::from(1);
    }
    if let Some(path) = &a.stats_json
        && let Err(e) = weft_graph::atomic_write(path, stats_json(&g, seconds, &timings).as_bytes())
    {
        eprintln!("error: cannot write {}: {e}", path.display());
        code = ExitCode::from(1);
    }
    if a.stats {
        eprint!("{}", stats_text(&g, seconds));
    }
    // Already printed by the sink as they came.
    g.take_warnings();
    if let Some(e) = failure {
        let stopped = matches!(*e.error, weft_graph::NodeError::Interrupted(_));
        eprintln!("error: {e}");
        if !rows.is_empty() {
            eprintln!(
                "note: frames {}..{} completed before the {}{}",
                rows[0].0,
                rows[rows.len() - 1].0,
                if stopped { "stop" } else { "failure" },
                if a.out.is_some() {
                    " and were written"
                } else {
                    ""
                },
            );
        }
        // Ctrl-C is 130 by convention; a time limit is a run that did not finish (1).
        let ctrl_c = stopped && interrupt.reason() == "interrupted";
        return ExitCode::from(if ctrl_c { 130 } else { 1 });
    }
    code
}

fn warning_line(w: &weft_graph::RunWarning) -> String {
    let at = w
        .frame
        .map(|f| format!(" at frame {f}"))
        .unwrap_or_default();
    format!("warning: node '{}'{at}: {}", w.node, w.message)
}

/// One frame's evaluation time: `seconds` in all, `output_seconds` of them in output nodes.
struct FrameTiming {
    frame: i64,
    seconds: f64,
    output_seconds: f64,
}

fn stats_json(g: &Graph, seconds: f64, frames: &[FrameTiming]) -> String {
    let frames: Vec<_> = frames
        .iter()
        .map(|t| {
            serde_json::json!({"frame": t.frame, "seconds": t.seconds, "output_seconds": t.output_seconds})
        })
        .collect();
    let j = serde_json::json!({"seconds": seconds, "frames": frames, "nodes": g.stats()});
    serde_json::to_string_pretty(&j).unwrap_or_default() + "\n"
}

fn write_outputs(
    dir: &Path,
    a: &RunArgs,
    outputs: &[String],
    rows: &[(i64, Vec<serde_json::Value>)],
    g: &Graph,
    seconds: f64,
    timings: &[FrameTiming],
) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let mut per_output = serde_json::Map::new();
    for (k, o) in outputs.iter().enumerate() {
        per_output.insert(o.clone(), rows.iter().map(|(_, r)| r[k].clone()).collect());
    }
    let j = serde_json::json!({
        "graph": a.graph.display().to_string(),
        "fps": a.fps,
        "frames": rows.iter().map(|(f, _)| *f).collect::<Vec<_>>(),
        "outputs": per_output,
    });
    weft_graph::atomic_write(
        &dir.join("outputs.json"),
        (serde_json::to_string_pretty(&j)? + "\n").as_bytes(),
    )?;
    // CSV holds the outputs that are numbers or booleans, one column each, and vectors and
    // lists of numbers one column per component: NAME.x, NAME.y, NAME.z for a vec3 and
    // NAME.0 … NAME.N−1 for a list (N its longest length over the frames; shorter rows
    // leave the rest empty), so a line probe's profile is a row per frame.
    let mut columns: Vec<(usize, Option<usize>, String)> = Vec::new();
    for (k, name) in outputs.iter().enumerate() {
        match g.output_type(name) {
            Some("float" | "int" | "bool") => columns.push((k, None, name.clone())),
            Some("vec3") => {
                for (c, axis) in ["x", "y", "z"].iter().enumerate() {
                    columns.push((k, Some(c), format!("{name}.{axis}")));
                }
            }
            Some("floats") => {
                let n = rows
                    .iter()
                    .map(|(_, r)| r[k].as_array().map_or(0, |a| a.len()))
                    .max()
                    .unwrap_or(0);
                for c in 0..n {
                    columns.push((k, Some(c), format!("{name}.{c}")));
                }
            }
            _ => {}
        }
    }
    let mut csv = String::from("frame");
    for (_, _, head) in &columns {
        csv.push(',');
        csv.push_str(head);
    }
    csv.push('\n');
    for (f, r) in rows {
        csv.push_str(&f.to_string());
        for &(k, c, _) in &columns {
            csv.push(',');
            match c {
                None => csv.push_str(&cell(&r[k])),
                Some(c) => {
                    if let Some(x) = r[k].as_array().and_then(|a| a.get(c)) {
                        csv.push_str(&cell(x));
                    }
                }
            }
        }
        csv.push('\n');
    }
    weft_graph::atomic_write(&dir.join("outputs.csv"), csv.as_bytes())?;
    weft_graph::atomic_write(
        &dir.join("stats.json"),
        stats_json(g, seconds, timings).as_bytes(),
    )
}

fn stats_text(g: &Graph, seconds: f64) -> String {
    let mut s = format!(
        "{:<24} {:<20} {:>8} {:>8} {:>8} {:>10}\n",
        "node", "type", "evals", "hits", "steps", "self ms"
    );
    for r in g.stats() {
        s += &format!(
            "{:<24} {:<20} {:>8} {:>8} {:>8} {:>10.3}\n",
            r.node,
            r.type_name,
            r.stats.evaluations,
            r.stats.cache_hits,
            r.stats.steps,
            r.stats.seconds * 1e3
        );
        if let Some(frames) = r
            .details
            .as_ref()
            .and_then(|d| d.get("frames"))
            .and_then(|f| f.as_array())
            && !frames.is_empty()
        {
            let its: Vec<usize> = frames
                .iter()
                .map(|f| f["iterations"].as_array().map_or(0, |a| a.len()))
                .collect();
            let worst = frames
                .iter()
                .filter_map(|f| f["iterations"].as_array()?.last()?["residual"].as_f64())
                .fold(0.0f64, |m, x| m.max(x.abs()));
            let failed = frames.iter().filter(|f| f["converged"] == false).count();
            s += &format!(
                "  └ iterations over {} frame solves: mean {:.2}, max {}; largest final residual {worst:.3e}; {failed} not converged\n",
                its.len(),
                its.iter().sum::<usize>() as f64 / its.len() as f64,
                its.iter().max().unwrap_or(&0),
            );
        }
        if let Some(frames) = r
            .details
            .as_ref()
            .and_then(|d| d.get("solid_frames"))
            .and_then(|f| f.as_array())
            && !frames.is_empty()
        {
            let sum = |k: &str| frames.iter().filter_map(|f| f[k].as_f64()).sum::<f64>();
            let max = |k: &str| {
                frames
                    .iter()
                    .filter_map(|f| f[k].as_f64())
                    .fold(0.0f64, f64::max)
            };
            let n = frames.len() as f64;
            s += &format!(
                "  └ {} frames: {:.1} steps/frame, {:.1} Newton iterations/frame (max {} in a step), {} retries, largest residual {:.2e} m/s; assembly {:.0} ms, {} factorizations {:.0} ms, solves {:.0} ms\n",
                frames.len(),
                sum("steps") / n,
                sum("newton_iterations") / n,
                max("max_newton_iterations"),
                sum("retries"),
                max("max_residual"),
                sum("assembly_seconds") * 1e3,
                sum("factorizations"),
                sum("factor_seconds") * 1e3,
                sum("solve_seconds") * 1e3,
            );
            if let Some(t) = r.details.as_ref().and_then(|d| d.get("terms")) {
                s += &format!("  └ terms: {t}\n");
            }
        }
    }
    s + &format!("total {:.3} ms\n", seconds * 1e3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_ranges_are_inclusive_and_checked() {
        assert_eq!(parse_frames("2..4").unwrap(), vec![2, 3, 4]);
        assert_eq!(parse_frames("7").unwrap(), vec![7]);
        assert!(
            parse_frames("4..2")
                .unwrap_err()
                .contains("before the first")
        );
        assert!(parse_frames("a..b").unwrap_err().contains("expects A..B"));
        assert!(
            parse_frames("-9223372036854775808..9223372036854775807")
                .unwrap_err()
                .contains("within")
        );
    }
}

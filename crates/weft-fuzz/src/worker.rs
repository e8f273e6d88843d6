//! The worker: a child process that runs cases one after another through `weft run`, in
//! process, and answers the supervisor with one JSON line per case.
//!
//! Isolation is the supervisor's job (a worker that aborts or hangs is killed and replaced);
//! the worker only makes each case's failure visible: a memory ceiling (`RLIMIT_AS`) so an
//! allocation that would have taken the machine aborts the worker instead, a panic hook that
//! records the message and location, and the case's stderr captured to a file in its
//! directory. The protocol goes over a duplicate of the original stdout; stdout itself points
//! at /dev/null so nothing `weft` prints can interleave with it.

use std::fs::File;
use std::io::{BufRead, Write};
use std::os::fd::{AsRawFd, FromRawFd};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

static PANIC: Mutex<Option<String>> = Mutex::new(None);

/// What `weft` is asked to do with each case: run the graph file for two frames, writing under
/// `out/`. Not `--quiet`: the progress lines a long frame prints to stderr are what tells a
/// long run that says what it is doing from a silent one (`Kind::Silent`).
pub fn weft_args(frames: &str, time_limit: Option<f64>) -> Vec<String> {
    let mut a: Vec<String> = [
        "weft",
        "run",
        "graph.json",
        "--frames",
        frames,
        "--out",
        "out",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    if let Some(t) = time_limit {
        a.push("--time-limit".into());
        a.push(format!("{t}"));
    }
    a
}

fn io_err(what: &str) -> std::io::Error {
    std::io::Error::other(format!("{what}: {}", std::io::Error::last_os_error()))
}

/// Runs the worker loop: reads case directories from stdin until it closes.
pub fn worker_main(memory_limit: u64, args: Vec<String>) -> std::io::Result<()> {
    // SAFETY: plain libc calls on this process's own limits and file descriptors; every
    // returned descriptor is checked before use and owned by exactly one `File`.
    let (mut proto, saved_err) = unsafe {
        let lim = libc::rlimit {
            rlim_cur: memory_limit as libc::rlim_t,
            rlim_max: memory_limit as libc::rlim_t,
        };
        if memory_limit > 0 && libc::setrlimit(libc::RLIMIT_AS, &lim) != 0 {
            return Err(io_err("setrlimit"));
        }
        let p = libc::dup(1);
        if p < 0 {
            return Err(io_err("dup stdout"));
        }
        let null = File::options().write(true).open("/dev/null")?;
        if libc::dup2(null.as_raw_fd(), 1) < 0 {
            return Err(io_err("dup2 stdout"));
        }
        let e = libc::dup(2);
        if e < 0 {
            return Err(io_err("dup stderr"));
        }
        (File::from_raw_fd(p), e)
    };
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "<non-string payload>".into());
        let at = info
            .location()
            .map(|l| format!("{}:{}", l.file(), l.line()))
            .unwrap_or_default();
        if let Ok(mut p) = PANIC.lock() {
            *p = Some(format!("{msg} at {at}"));
        }
    }));
    let home = std::env::current_dir()?;
    for line in std::io::stdin().lock().lines() {
        let dir = PathBuf::from(line?);
        let err = File::create(dir.join("stderr.txt"))?;
        // SAFETY: as above; fd 2 is restored from `saved_err` after the case.
        unsafe {
            if libc::dup2(err.as_raw_fd(), 2) < 0 {
                return Err(io_err("dup2 stderr"));
            }
        }
        if let Ok(mut p) = PANIC.lock() {
            *p = None;
        }
        std::env::set_current_dir(&dir)?;
        let t0 = Instant::now();
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            weft_cli::main_with_args(args.iter().cloned())
        }));
        let seconds = t0.elapsed().as_secs_f64();
        std::env::set_current_dir(&home)?;
        // SAFETY: restores the worker's own stderr.
        unsafe {
            libc::dup2(saved_err, 2);
        }
        let exit = match &r {
            Ok(code) => (0..=255u8).find(|&c| std::process::ExitCode::from(c) == *code),
            Err(_) => None,
        };
        let panic = if r.is_err() {
            Some(
                PANIC
                    .lock()
                    .ok()
                    .and_then(|p| p.clone())
                    .unwrap_or_else(|| "panic (no message)".into()),
            )
        } else {
            None
        };
        let reply = serde_json::json!({"exit": exit, "panic": panic, "seconds": seconds});
        writeln!(proto, "{reply}")?;
        proto.flush()?;
    }
    Ok(())
}

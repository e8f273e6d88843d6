//! The progress line inside a frame: what the evaluation under way says it is doing
//! ([`weft_graph::Interrupt::activity`]: a solver's substep, Newton iteration, contacts and
//! ADMM iterations), redrawn while the frame runs, so a frame that takes minutes is seen
//! working rather than stuck.

use indicatif::ProgressBar;
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Without a terminal, a frame's first line comes after this long, the next ones this far
/// apart: a log (CI, a render farm's) shows a long frame working without a line per second.
pub const FIRST_LINE: Duration = Duration::from_secs(5);
const NEXT_LINE: Duration = Duration::from_secs(30);

/// On a terminal the bar's message is redrawn this often.
const REDRAW: Duration = Duration::from_millis(250);

struct Shared {
    done: AtomicBool,
    frame: AtomicI64,
    since: Mutex<Instant>,
}

/// Redraws the current frame's activity until dropped: into the progress bar's message on a
/// terminal, else as a line on stderr once a frame has taken [`FIRST_LINE`] and every
/// [`NEXT_LINE`] after.
pub(crate) struct Ticker {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl Ticker {
    /// Starts redrawing what `run` says into `bar`, or to stderr without one.
    pub(crate) fn start(run: weft_graph::Interrupt, bar: Option<ProgressBar>) -> Self {
        let shared = Arc::new(Shared {
            done: AtomicBool::new(false),
            frame: AtomicI64::new(0),
            since: Mutex::new(Instant::now()),
        });
        let s = shared.clone();
        let thread = std::thread::Builder::new()
            .name("weft-progress".into())
            .spawn(move || {
                let mut printed: Option<Instant> = None;
                let mut frame = i64::MIN;
                while !s.done.load(Ordering::Relaxed) {
                    std::thread::park_timeout(REDRAW);
                    let f = s.frame.load(Ordering::Relaxed);
                    if f != frame {
                        (frame, printed) = (f, None);
                    }
                    let Some(what) = run.activity() else {
                        continue;
                    };
                    let since = s.since.lock().map_or_else(|_| Instant::now(), |t| *t);
                    let taken = since.elapsed();
                    match &bar {
                        Some(b) => b.set_message(format!(
                            "frame {f}: {:.0} s so far, {what}",
                            taken.as_secs_f64()
                        )),
                        None => {
                            let due = match printed {
                                None => taken >= FIRST_LINE,
                                Some(t) => t.elapsed() >= NEXT_LINE,
                            };
                            if due {
                                eprintln!("frame {f}: {:.0} s so far: {what}", taken.as_secs_f64());
                                printed = Some(Instant::now());
                            }
                        }
                    }
                }
            })
            .ok();
        Ticker { shared, thread }
    }

    /// Frame `f` begins.
    pub(crate) fn frame(&self, f: i64) {
        if let Ok(mut t) = self.shared.since.lock() {
            *t = Instant::now();
        }
        self.shared.frame.store(f, Ordering::Relaxed);
    }
}

impl Drop for Ticker {
    fn drop(&mut self) {
        self.shared.done.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            t.thread().unpark();
            let _ = t.join();
        }
    }
}

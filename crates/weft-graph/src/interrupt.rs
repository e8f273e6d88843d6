//! Stopping a run from outside: Ctrl-C, a time limit, a host's cancel button.
//!
//! An [`Interrupt`] is shared (cheap clones of one handle) between a graph and whoever may ask
//! it to stop. The engine looks at it before every node evaluation and every stateful step;
//! long-running kernels hand [`Interrupt::checker`] to their solvers, which look at it once per
//! iteration. A stopped evaluation fails with [`crate::NodeError::Interrupted`], so everything
//! computed before it (cached frames, written files) stays as it was. The same handle carries
//! the other way what a long evaluation is doing ([`Interrupt::set_activity`]), for the
//! progress line of whoever may stop it.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

/// Says in a few words what a long evaluation is doing now (`substep 2 of 4, Newton
/// iteration 37, …`), called by whoever draws a progress line, from its own thread.
pub type Reporter = Arc<dyn Fn() -> String + Send + Sync>;

#[derive(Debug, Default)]
struct Inner {
    stop: AtomicBool,
    /// Deadline as nanoseconds after [`epoch`], plus one; 0: none.
    deadline: AtomicU64,
    /// The time limit the deadline came from [ms], for the message.
    limit_ms: AtomicU64,
    activity: Activity,
}

/// The node under evaluation and, if it set one, its reporter.
#[derive(Default)]
struct Activity(Mutex<Doing>);

/// What [`Interrupt::enter`] returns, for [`Interrupt::leave`]: the evaluation it interrupted.
#[derive(Clone, Default)]
pub(crate) struct Doing {
    node: Option<Arc<str>>,
    reporter: Option<Reporter>,
}

impl std::fmt::Debug for Activity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Activity")
    }
}

/// A process-wide reference instant, so a deadline fits in an atomic integer.
fn epoch() -> Instant {
    static E: OnceLock<Instant> = OnceLock::new();
    *E.get_or_init(Instant::now)
}

/// A shared request to stop evaluating.
#[derive(Clone, Debug, Default)]
pub struct Interrupt {
    inner: Arc<Inner>,
}

impl Interrupt {
    /// A handle that is not set and has no deadline.
    pub fn new() -> Self {
        Self::default()
    }
    /// Asks the evaluation to stop (safe from a signal-handling thread).
    pub fn stop(&self) {
        self.inner.stop.store(true, Ordering::Relaxed);
    }
    /// Clears a stop request and the deadline (before reusing a graph).
    pub fn reset(&self) {
        self.inner.stop.store(false, Ordering::Relaxed);
        self.inner.deadline.store(0, Ordering::Relaxed);
    }
    /// Stops the evaluation once `limit` has passed from now.
    pub fn set_time_limit(&self, limit: Duration) {
        let at = Instant::now() + limit;
        let ns = at.saturating_duration_since(epoch()).as_nanos();
        self.inner.deadline.store(
            u64::try_from(ns).unwrap_or(u64::MAX - 1) + 1,
            Ordering::Relaxed,
        );
        self.inner.limit_ms.store(
            u64::try_from(limit.as_millis()).unwrap_or(u64::MAX),
            Ordering::Relaxed,
        );
    }
    /// True when a stop was asked for or the deadline has passed.
    pub fn is_set(&self) -> bool {
        if self.inner.stop.load(Ordering::Relaxed) {
            return true;
        }
        let d = self.inner.deadline.load(Ordering::Relaxed);
        d != 0 && epoch().elapsed().as_nanos() + 1 >= d as u128
    }
    /// Why the evaluation stops, for messages.
    pub fn reason(&self) -> String {
        if self.inner.stop.load(Ordering::Relaxed) {
            "interrupted".into()
        } else {
            let ms = self.inner.limit_ms.load(Ordering::Relaxed);
            format!("time limit of {} s reached", ms as f64 / 1e3)
        }
    }
    /// A closure for solvers that know nothing of graphs: true when they should stop.
    pub fn checker(&self) -> Arc<dyn Fn() -> bool + Send + Sync> {
        let me = self.clone();
        Arc::new(move || me.is_set())
    }
    /// Sets (or clears) what describes the evaluation under way: a node that may run long
    /// (a solver's frame) sets it for the time of its evaluation, the handle's other holder
    /// (a command's progress bar) asks [`Self::activity`] when it redraws. Shared by every
    /// clone, so a composite's stages report to their outer graph's line.
    pub fn set_activity(&self, reporter: Option<Reporter>) {
        if let Ok(mut a) = self.inner.activity.0.lock() {
            a.reporter = reporter;
        }
    }
    /// The engine begins evaluating `node`: what was under way before, for [`Self::leave`].
    pub(crate) fn enter(&self, node: Arc<str>) -> Doing {
        let now = Doing {
            node: Some(node),
            reporter: None,
        };
        match self.inner.activity.0.lock() {
            Ok(mut a) => std::mem::replace(&mut *a, now),
            Err(_) => Doing::default(),
        }
    }
    /// The evaluation [`Self::enter`] began has ended: `before` is under way again.
    pub(crate) fn leave(&self, before: Doing) {
        if let Ok(mut a) = self.inner.activity.0.lock() {
            *a = before;
        }
    }
    /// What the evaluation under way is doing: the node, and what it says of itself
    /// (`'solve': substep 2 of 4, Newton iteration 3 …`); `None` between evaluations.
    pub fn activity(&self) -> Option<String> {
        let Doing { node, reporter } = self.inner.activity.0.lock().ok()?.clone();
        let node = node?;
        Some(match reporter {
            Some(r) => format!("'{node}': {}", r()),
            None => format!("'{node}'"),
        })
    }
    /// True when both handles are the same request.
    pub fn same(&self, other: &Interrupt) -> bool {
        Arc::ptr_eq(&self.inner, &other.inner)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_activity_is_the_node_and_what_it_says() {
        let i = Interrupt::new();
        assert_eq!(i.activity(), None);
        let j = i.clone();
        let outer = j.enter("solve".into());
        assert_eq!(i.activity().as_deref(), Some("'solve'"));
        j.set_activity(Some(Arc::new(|| "Newton iteration 3".to_string())));
        assert_eq!(i.activity().as_deref(), Some("'solve': Newton iteration 3"));
        // An input pulled during the evaluation, then back.
        let inner = j.enter("grid".into());
        assert_eq!(i.activity().as_deref(), Some("'grid'"));
        j.leave(inner);
        assert_eq!(i.activity().as_deref(), Some("'solve': Newton iteration 3"));
        j.set_activity(None);
        j.leave(outer);
        assert_eq!(i.activity(), None);
    }

    #[test]
    fn stop_deadline_and_reset() {
        let i = Interrupt::new();
        assert!(!i.is_set());
        let j = i.clone();
        j.stop();
        assert!(i.is_set());
        assert_eq!(i.reason(), "interrupted");
        i.reset();
        assert!(!i.is_set());
        i.set_time_limit(Duration::ZERO);
        assert!(i.is_set());
        assert_eq!(i.reason(), "time limit of 0 s reached");
        i.set_time_limit(Duration::from_secs(3600));
        assert!(!i.is_set());
        assert!(!(i.checker())());
    }
}

//! Stopping a run from outside: Ctrl-C, a time limit, a host's cancel button.
//!
//! An [`Interrupt`] is shared (cheap clones of one handle) between a graph and whoever may ask
//! it to stop. The engine looks at it before every node evaluation and every stateful step;
//! long-running kernels hand [`Interrupt::checker`] to their solvers, which look at it once per
//! iteration. A stopped evaluation fails with [`crate::NodeError::Interrupted`], so everything
//! computed before it (cached frames, written files) stays as it was.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

#[derive(Debug, Default)]
struct Inner {
    stop: AtomicBool,
    /// Deadline as nanoseconds after [`epoch`], plus one; 0: none.
    deadline: AtomicU64,
    /// The time limit the deadline came from [ms], for the message.
    limit_ms: AtomicU64,
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
    /// True when both handles are the same request.
    pub fn same(&self, other: &Interrupt) -> bool {
        Arc::ptr_eq(&self.inner, &other.inner)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

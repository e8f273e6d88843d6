//! Running a step on the thread pool, with a second worker kept awake for its fork–joins.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Runs `f` on a worker of the current thread pool when `threaded` and called from outside
/// it (at once otherwise). Why: a fork–join started outside the pool injects its job and
/// waits for a worker to wake, and then for a second one to steal the other half; between two
/// assemblies (a factorization apart) the workers fall asleep, so a job split in two from
/// outside the pool runs no faster than serially, and from a worker nearly twice as fast.
/// The move itself waits for a worker too, once a step: systems with nothing to run
/// concurrently stay on the caller (a small sheet's short steps take many times as long
/// when moved).
///
/// While `f` runs, a second worker stays awake ([`keep_warm`]): the step's fork–joins come
/// every few hundred microseconds (an assembly's tree, the split factorization's halves, its
/// two triangular solves), and a worker that fell asleep between them is woken by a system
/// call and a context switch each time. Kept awake, it makes the hanging cloth, the drape
/// and the hair a few percent faster, with the same bits. The helper leaves after 500 µs
/// without work: spinning through a contact step's sequential stretches costs CPU time for
/// nothing. Paired `farm-bench` runs of the examples measure it; figures in
/// docs/history/issue-71-comments.md.
pub(crate) fn in_pool<R: Send>(threaded: bool, f: impl FnOnce() -> R + Send) -> R {
    if !threaded || rayon::current_thread_index().is_some() || rayon::current_num_threads() < 2 {
        return f();
    }
    let done = AtomicBool::new(false);
    rayon::scope(|s| {
        let home = rayon::current_thread_index();
        let done = &done;
        s.spawn(move |_| keep_warm(home, done));
        // Ends the helper even if `f` panics (the scope would otherwise wait for it forever).
        let _end = SetOnDrop(done);
        f()
    })
}

/// Sets its flag when dropped.
struct SetOnDrop<'a>(&'a AtomicBool);

impl Drop for SetOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

/// How long [`keep_warm`] waits for work before it leaves the worker to rayon's own sleep: a
/// step's long sequential stretches (a contact step's projections, its exact checks) should
/// not hold a core for nothing.
const SPIN: Duration = Duration::from_micros(500);

/// Runs the pool's pending jobs (the other halves of the step's joins) until `done`, on a
/// worker other than `home` (the one running the step: there it returns at once, since the
/// step must go on), spinning between jobs for at most [`SPIN`]. Which thread runs a job
/// never changes what it computes: the results stay bit-identical at any thread count.
fn keep_warm(home: Option<usize>, done: &AtomicBool) {
    if rayon::current_thread_index() == home {
        return;
    }
    let mut idle = Instant::now();
    while !done.load(Ordering::Acquire) {
        if rayon::yield_now() == Some(rayon::Yield::Executed) {
            idle = Instant::now();
        } else if idle.elapsed() < SPIN {
            std::hint::spin_loop();
        } else {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::in_pool;

    #[test]
    fn a_step_that_panics_ends_its_helper() {
        // Without the helper's flag set on unwinding, the scope would wait for it forever.
        let r = std::panic::catch_unwind(|| in_pool(true, || panic!("a failing step")));
        assert!(r.is_err());
        assert_eq!(in_pool(true, || rayon::join(|| 1, || 2)), (1, 2));
    }
}

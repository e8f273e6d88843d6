//! What a step is doing, for a progress line drawn by another thread.
//!
//! A frame of a contact scene can take minutes; a progress line that only moves between
//! frames cannot tell a slow frame from a stuck one. The solvers store where they are (the
//! substep, the exact-check round, the Newton iteration and its last step, the contacts and
//! the ADMM iterations spent on them) in a [`Progress`] as they go, and whoever draws the
//! line (the `weft` command's progress bar, a host's status bar) reads it when it redraws.

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

/// Counters a solver stores as it goes and a progress line reads from another thread:
/// relaxed atomics, each read whole and recent. Storing costs one store per Newton iteration
/// and per ADMM round; the solvers never read them back, so they change no result.
#[derive(Debug, Default)]
pub struct Progress {
    /// Substep (1-based) and substeps per frame.
    substep: AtomicU64,
    substeps: AtomicU64,
    /// Times the current substep was halved after failing.
    halved: AtomicU64,
    /// Solves of the current step (1 plus the exact check's re-solves).
    round: AtomicU64,
    /// Newton iterations of the current solve.
    newton: AtomicU64,
    /// The last Newton step [m/s], as bits.
    residual: AtomicU64,
    /// Contacts of the current solve.
    contacts: AtomicU64,
    /// ADMM iterations of the current solve.
    admm: AtomicU64,
}

impl Progress {
    /// A substep begins: `substep` of `substeps`, halved `halved` times.
    pub fn substep(&self, substep: usize, substeps: usize, halved: usize) {
        self.substep.store(substep as u64, Relaxed);
        self.substeps.store(substeps as u64, Relaxed);
        self.halved.store(halved as u64, Relaxed);
        for a in [&self.round, &self.newton, &self.contacts, &self.admm] {
            a.store(0, Relaxed);
        }
    }

    /// A solve of the step with `contacts` contacts begins (the first, or one of the exact
    /// check's re-solves).
    pub fn solve(&self, contacts: usize) {
        self.round.fetch_add(1, Relaxed);
        self.contacts.store(contacts as u64, Relaxed);
        self.newton.store(0, Relaxed);
        self.admm.store(0, Relaxed);
        self.residual.store(f64::NAN.to_bits(), Relaxed);
    }

    /// Newton iteration `iteration` (1-based) ended with a step of `residual` [m/s].
    pub fn newton(&self, iteration: usize, residual: f64) {
        self.newton.store(iteration as u64, Relaxed);
        self.residual.store(residual.to_bits(), Relaxed);
    }

    /// One more ADMM iteration.
    pub fn admm(&self) {
        self.admm.fetch_add(1, Relaxed);
    }

    /// The line: `substep 2 of 4 (halved twice), round 2, Newton iteration 37 (last step
    /// 3.1e-3 m/s), 1200 contacts, 7400 ADMM iterations`.
    pub fn line(&self) -> String {
        let get = |a: &AtomicU64| a.load(Relaxed);
        let mut s = match get(&self.substeps) {
            // A solve that is not a solver's substep (a coupled iteration's solid stage).
            0 => "solid solve".to_string(),
            n => format!("substep {} of {n}", get(&self.substep)),
        };
        match get(&self.halved) {
            0 => {}
            1 => s += " (halved once)",
            2 => s += " (halved twice)",
            k => s += &format!(" (halved {k} times)"),
        }
        let round = get(&self.round);
        if round > 1 {
            s += &format!(", solve {round} of the step");
        }
        let newton = get(&self.newton);
        if newton > 0 {
            let r = f64::from_bits(get(&self.residual));
            s += &format!(", Newton iteration {newton} (last step {r:.2e} m/s)");
        }
        let contacts = get(&self.contacts);
        if contacts > 0 {
            s += &format!(", {contacts} contacts, {} ADMM iterations", get(&self.admm));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_line_says_where_the_step_is() {
        let p = Progress::default();
        p.substep(2, 4, 0);
        assert_eq!(p.line(), "substep 2 of 4");
        p.substep(2, 4, 2);
        p.solve(1200);
        p.solve(1250);
        p.newton(37, 3.1e-3);
        for _ in 0..5 {
            p.admm();
        }
        assert_eq!(
            p.line(),
            "substep 2 of 4 (halved twice), solve 2 of the step, Newton iteration 37 (last step \
             3.10e-3 m/s), 1250 contacts, 5 ADMM iterations"
        );
    }
}

//! A stateful node's states kept in memory, per frame, within a memory budget.
//!
//! Every step's state is kept, so asking for an earlier frame, or a later one after a
//! pause, resumes from the nearest state instead of the start. States can be large (a
//! fluid grid a frame); when those kept exceed a quarter of the memory the process may
//! still take, the store thins them: the start and the latest stay, and of the others only
//! every second one by frame, then every fourth, and so on. Resuming from any kept state is
//! exact, so thinning only costs recomputation, never a different answer.

use crate::value::Value;
use std::collections::BTreeMap;
use std::ops::RangeInclusive;

/// Below this total the store never asks how much memory is left (reading /proc costs
/// more than a small step).
const QUIET_BYTES: usize = 64 << 20;

#[derive(Default)]
pub(crate) struct Checkpoints {
    states: BTreeMap<i64, (Value, usize)>,
    total: usize,
    /// Frames kept between the start and the latest are multiples of this from the start.
    spacing: i64,
}

impl Checkpoints {
    pub(crate) fn clear(&mut self) {
        self.states.clear();
        self.total = 0;
        self.spacing = 1;
    }

    pub(crate) fn get(&self, frame: &i64) -> Option<&Value> {
        self.states.get(frame).map(|(v, _)| v)
    }

    /// The latest state in `range`.
    pub(crate) fn latest_in(&self, range: RangeInclusive<i64>) -> Option<(i64, Value)> {
        self.states
            .range(range)
            .next_back()
            .map(|(f, (v, _))| (*f, v.clone()))
    }

    pub(crate) fn frames(&self) -> Vec<i64> {
        self.states.keys().copied().collect()
    }

    pub(crate) fn retain_up_to(&mut self, frame: i64) {
        self.states.retain(|&f, _| f <= frame);
        self.total = self.states.values().map(|(_, b)| b).sum();
    }

    /// Keeps `state` (about `bytes` large) for `frame`, thinning when the budget asks.
    pub(crate) fn insert(&mut self, frame: i64, state: Value, bytes: usize, start: i64) {
        self.spacing = self.spacing.max(1);
        if let Some((_, old)) = self.states.insert(frame, (state, bytes)) {
            self.total -= old;
        }
        self.total += bytes;
        if self.total > QUIET_BYTES {
            let budget = usize::try_from(crate::memory::available() / 4).unwrap_or(usize::MAX);
            self.thin_to(budget, start);
        }
    }

    /// Thins until the kept states fit in `budget` or only the start and latest remain.
    fn thin_to(&mut self, budget: usize, start: i64) {
        while self.total > budget && self.states.len() > 2 {
            self.spacing = self.spacing.saturating_mul(2);
            let latest = self.states.keys().next_back().copied().unwrap_or(start);
            let sp = self.spacing;
            self.states
                .retain(|&f, _| f == start || f == latest || (f - start).rem_euclid(sp) == 0);
            self.total = self.states.values().map(|(_, b)| b).sum();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thinning_keeps_the_start_the_latest_and_a_regular_spacing() {
        let mut c = Checkpoints::default();
        for f in 0..=16 {
            c.insert(f, Value::from(f as f64), 10, 0);
        }
        assert_eq!(c.frames().len(), 17);
        c.thin_to(60, 0);
        // 17 × 10 > 60: every second (9 kept, 90), then every fourth (5 kept: 0 4 8 12 16).
        assert_eq!(c.frames(), vec![0, 4, 8, 12, 16]);
        assert_eq!(c.total, 50);
        // New frames keep coming at full resolution until the next thinning.
        c.insert(17, Value::from(17.0), 10, 0);
        assert_eq!(c.latest_in(0..=17).unwrap().0, 17);
        assert_eq!(c.latest_in(0..=11).unwrap().0, 8);
        c.thin_to(0, 0);
        assert_eq!(
            c.frames(),
            vec![0, 17],
            "the start and the latest always stay"
        );
    }
}

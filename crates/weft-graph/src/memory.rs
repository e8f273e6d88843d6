//! Memory estimates: how much a run may still allocate, and refusing before allocating.
//!
//! Anything whose size a user's file sets (a grid's resolution, a strand count, an image's
//! size, the samples a cloth makes in a fluid) is estimated before it is allocated and
//! refused with the estimate and the parameter that caused it, instead of letting the
//! allocator abort the process. [`available`] is what this process may still take: the
//! least of the memory the system reports available, the room left under the process's
//! address-space limit (`ulimit -v`), the room left in its cgroup, and `WEFT_MEMORY_LIMIT`
//! (bytes, or with a K/M/G/T suffix) for users who share a machine.

use std::fmt;

const KIB: u64 = 1 << 10;
const MIB: u64 = 1 << 20;
const GIB: u64 = 1 << 30;

/// A refusal: what would not fit, its estimate and the budget.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub struct MemoryError {
    /// What would have been allocated, and from which parameters.
    pub what: String,
    /// The estimate [bytes].
    pub need: u64,
    /// What was available [bytes].
    pub available: u64,
    /// What to change.
    pub hint: String,
}

impl fmt::Display for MemoryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} needs about {}, more than the {} available",
            self.what,
            human(self.need),
            human(self.available)
        )?;
        if !self.hint.is_empty() {
            write!(f, "; {}", self.hint)?;
        }
        Ok(())
    }
}

/// A byte count for people: `512 B`, `3.0 KiB`, `1.5 GiB`.
pub fn human(b: u64) -> String {
    let x = b as f64;
    if b >= 1 << 40 {
        format!("{:.1} TiB", x / (GIB as f64 * 1024.0))
    } else if b >= GIB {
        format!("{:.1} GiB", x / GIB as f64)
    } else if b >= MIB {
        format!("{:.1} MiB", x / MIB as f64)
    } else if b >= KIB {
        format!("{:.1} KiB", x / KIB as f64)
    } else {
        format!("{b} B")
    }
}

/// Refuses `need` bytes when they exceed `budget`.
pub fn check_within(
    need: u64,
    budget: u64,
    what: impl FnOnce() -> String,
    hint: &str,
) -> Result<(), MemoryError> {
    if need <= budget {
        Ok(())
    } else {
        Err(MemoryError {
            what: what(),
            need,
            available: budget,
            hint: hint.to_string(),
        })
    }
}

/// Refuses `need` bytes when they exceed [`available`].
pub fn check(need: u64, what: impl FnOnce() -> String, hint: &str) -> Result<(), MemoryError> {
    check_within(need, available(), what, hint)
}

/// `a × b × …` saturating: an estimate that overflows is simply too large.
pub fn product(factors: &[u64]) -> u64 {
    factors.iter().fold(1u64, |a, &b| a.saturating_mul(b))
}

/// Parses `WEFT_MEMORY_LIMIT`-style sizes: `1073741824`, `512M`, `8G`, `1.5T`.
pub fn parse_size(s: &str) -> Option<u64> {
    let s = s.trim();
    let (num, mult) = match s.char_indices().last()? {
        (i, c) if c.is_ascii_alphabetic() => (
            &s[..i],
            match c.to_ascii_uppercase() {
                'K' => KIB,
                'M' => MIB,
                'G' => GIB,
                'T' => GIB * 1024,
                'B' => 1,
                _ => return None,
            },
        ),
        _ => (s, 1),
    };
    let x: f64 = num.trim().parse().ok()?;
    (x.is_finite() && x >= 0.0).then(|| (x * mult as f64).min(u64::MAX as f64) as u64)
}

fn read_u64(path: &str) -> Option<u64> {
    std::fs::read_to_string(path).ok()?.trim().parse().ok()
}

/// A `Key:   1234 kB` line of a /proc file, in bytes.
fn proc_kib(file: &str, key: &str) -> Option<u64> {
    let s = std::fs::read_to_string(file).ok()?;
    let kb: u64 = s
        .lines()
        .find(|l| l.starts_with(key))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some(kb.saturating_mul(1024))
}

/// `MemAvailable` from /proc/meminfo.
fn system_available() -> Option<u64> {
    proc_kib("/proc/meminfo", "MemAvailable:")
}

/// Address space a thread reserves beyond what it allocates: its stack (2 MiB for rayon's
/// workers), rounded up. Threads count against `ulimit -v` as soon as they exist, and the
/// solver's workers start after the budget is measured. glibc's malloc arenas (a 64 MiB
/// reservation for each thread's own, on its first allocation) would count too: the `weft`
/// command keeps every thread on the main arena (`weft_cli::cap_malloc_arenas`; measured
/// on a 100² sheet under 250 MiB with glibc's default of 8 arenas a core, the unreserved
/// room let an 8 MiB allocation fail in the integrator's build), and a host under a tight
/// `ulimit -v` should set `MALLOC_ARENA_MAX=1` likewise.
const STACK_RESERVE: u64 = 8 * MIB;

/// Room under the address-space limit: the soft `Max address space` less `VmSize`, less a
/// stack for each worker thread and three more (the main one, the progress line's, a
/// host's) not running yet.
fn address_space_room() -> Option<u64> {
    let limits = std::fs::read_to_string("/proc/self/limits").ok()?;
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    let soft: u64 = line
        .trim_start_matches("Max address space")
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let field = |key: &str| -> Option<u64> {
        status
            .lines()
            .find(|l| l.starts_with(key))?
            .split_whitespace()
            .nth(1)?
            .parse()
            .ok()
    };
    let (vm, running) = (field("VmSize:")?.saturating_mul(KIB), field("Threads:")?);
    let expected = std::thread::available_parallelism().map_or(2, |n| n.get()) as u64 + 3;
    let stacks = expected.saturating_sub(running) * STACK_RESERVE;
    Some(soft.saturating_sub(vm).saturating_sub(stacks))
}

/// Room left in the process's memory cgroup (v2, else v1), when it has a limit.
fn cgroup_room() -> Option<u64> {
    let (limit, usage) = if let Some(max) = std::fs::read_to_string("/sys/fs/cgroup/memory.max")
        .ok()
        .and_then(|s| s.trim().parse::<u64>().ok())
    {
        (max, read_u64("/sys/fs/cgroup/memory.current")?)
    } else {
        (
            read_u64("/sys/fs/cgroup/memory/memory.limit_in_bytes")?,
            read_u64("/sys/fs/cgroup/memory/memory.usage_in_bytes")?,
        )
    };
    // "No limit" is reported as a huge number.
    (limit < (1u64 << 60)).then(|| limit.saturating_sub(usage))
}

/// What this process may still allocate (see the module doc); 16 GiB when the system says
/// nothing. Measured at most every quarter second (reading five /proc and /sys files costs
/// tens of microseconds, and a coupling iteration asks twice): memory changes slower than
/// that, and these are estimates.
pub fn available() -> u64 {
    use std::sync::Mutex;
    use std::time::{Duration, Instant};
    static LAST: Mutex<Option<(Instant, u64)>> = Mutex::new(None);
    let now = Instant::now();
    if let Ok(mut last) = LAST.lock() {
        if let Some((at, v)) = *last
            && now.duration_since(at) < Duration::from_millis(250)
        {
            return v;
        }
        let v = measure();
        *last = Some((now, v));
        return v;
    }
    measure()
}

/// [`available`], measured now.
pub fn measure() -> u64 {
    let env = std::env::var("WEFT_MEMORY_LIMIT")
        .ok()
        .and_then(|s| parse_size(&s));
    [system_available(), address_space_room(), cgroup_room(), env]
        .into_iter()
        .flatten()
        .min()
        .unwrap_or(16 * GIB)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_messages() {
        assert_eq!(parse_size("512M"), Some(512 * MIB));
        assert_eq!(parse_size("1.5G"), Some(3 * GIB / 2));
        assert_eq!(parse_size("4096"), Some(4096));
        assert_eq!(parse_size("-1"), None);
        assert_eq!(parse_size("8X"), None);
        assert_eq!(human(3 * GIB / 2), "1.5 GiB");
        assert_eq!(product(&[u64::MAX, 2]), u64::MAX);
        let e = check_within(6 * GIB, 2 * GIB, || "a grid".into(), "use larger cells").unwrap_err();
        assert_eq!(
            e.to_string(),
            "a grid needs about 6.0 GiB, more than the 2.0 GiB available; use larger cells"
        );
        assert!(check_within(GIB, 2 * GIB, || unreachable!(), "").is_ok());
        // The machine running the tests has some memory, and less than an exabyte.
        let a = available();
        assert!(a > 0 && a < (1 << 60), "{a}");
    }
}

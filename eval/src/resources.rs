//! CPU time and peak memory of a process, read from Linux's `/proc`.
//!
//! `/proc/<pid>/schedstat` gives the time a process's main thread spent on
//! a CPU in nanoseconds (no clock-tick conversion needed), summed over all
//! threads via `/proc/<pid>/task/*/schedstat`; `/proc/<pid>/status` gives
//! `VmHWM`, the peak resident set size. Reading them needs no unsafe code
//! and no extra crate. On other systems the figures are absent (`None`).

use std::path::Path;

/// A reading of a process's counters.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Usage {
    /// CPU time of all threads so far, seconds.
    pub cpu_s: f64,
    /// Peak resident memory so far, bytes.
    pub peak_rss: u64,
}

fn cpu_ns(task_dir: &Path) -> Option<u64> {
    let mut total = 0u64;
    for entry in std::fs::read_dir(task_dir).ok()? {
        let path = entry.ok()?.path().join("schedstat");
        let text = std::fs::read_to_string(path).ok()?;
        total += text.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(total)
}

fn peak_rss(status: &Path) -> Option<u64> {
    let text = std::fs::read_to_string(status).ok()?;
    let line = text.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Counters of process `pid`.
pub fn of_pid(pid: u32) -> Option<Usage> {
    let dir = Path::new("/proc").join(pid.to_string());
    Some(Usage {
        cpu_s: cpu_ns(&dir.join("task"))? as f64 * 1e-9,
        peak_rss: peak_rss(&dir.join("status"))?,
    })
}

/// Counters of this process.
pub fn of_self() -> Option<Usage> {
    of_pid(std::process::id())
}

/// CPU time of the calling thread alone, seconds.
pub fn thread_cpu_s() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    Some(text.split_whitespace().next()?.parse::<u64>().ok()? as f64 * 1e-9)
}

/// Total memory of the machine, bytes (for "% of memory" columns).
pub fn total_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
}

/// A one-line description of the machine: CPU model and core count.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let mem = total_memory().map_or(String::new(), |m| {
        format!(", {:.0} GiB", m as f64 / (1u64 << 30) as f64)
    });
    format!(
        "{cpu}, {cores} cores{mem}, {} {}",
        std::env::consts::OS,
        std::env::consts::ARCH
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_own_counters() {
        let before = of_self().expect("/proc is readable on Linux");
        // Burn a little CPU so the counter moves.
        let mut x = 0u64;
        for i in 0..5_000_000u64 {
            x = x.wrapping_mul(31).wrapping_add(i);
        }
        std::hint::black_box(x);
        let after = of_self().unwrap();
        assert!(after.cpu_s > before.cpu_s);
        assert!(after.peak_rss > 1 << 20);
        assert!(thread_cpu_s().unwrap() > 0.0);
        assert!(machine().contains("cores"));
    }
}

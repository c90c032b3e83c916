//! CPU time and peak memory of a process, read from Linux's `/proc`.
//!
//! Process CPU time is `utime + stime` from `/proc/<pid>/stat` (in clock
//! ticks of 1/100 s, the value Linux reports to user space on every
//! mainstream architecture), which counts every thread, including those that
//! have exited. A single thread's time prefers `/proc/thread-self/schedstat`
//! (nanoseconds) and falls back to ticks where the kernel keeps no
//! scheduler statistics. `VmHWM` in `/proc/<pid>/status` is the peak
//! resident set size. No unsafe code and no extra crate; on other systems
//! the figures are absent (`None`).

use std::path::Path;

/// Clock ticks per second of the times in `/proc/*/stat`.
const TICKS_PER_S: f64 = 100.0;

/// A reading of a process's counters.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Usage {
    /// CPU time of all threads so far, seconds.
    pub cpu_s: f64,
    /// Peak resident memory so far, bytes.
    pub peak_rss: u64,
}

/// `utime + stime` of a `stat` file, seconds.
fn stat_cpu_s(stat: &Path) -> Option<f64> {
    let text = std::fs::read_to_string(stat).ok()?;
    // The command name (field 2) may hold spaces; fields after its closing
    // parenthesis are plain numbers: state is field 3, utime 14, stime 15.
    let rest = &text[text.rfind(')')? + 1..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) / TICKS_PER_S)
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
        cpu_s: stat_cpu_s(&dir.join("stat"))?,
        peak_rss: peak_rss(&dir.join("status"))?,
    })
}

/// Counters of this process.
pub fn of_self() -> Option<Usage> {
    of_pid(std::process::id())
}

/// CPU time of the calling thread alone, seconds.
pub fn thread_cpu_s() -> Option<f64> {
    let ns = std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|t| t.split_whitespace().next()?.parse::<u64>().ok())
        .filter(|&ns| ns > 0);
    match ns {
        Some(ns) => Some(ns as f64 * 1e-9),
        None => stat_cpu_s(Path::new("/proc/thread-self/stat")),
    }
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
        let thread_before = thread_cpu_s().expect("/proc is readable on Linux");
        // Burn 100 ms of CPU so that even tick-based counters move.
        let t = std::time::Instant::now();
        let mut x = 0u64;
        while t.elapsed().as_millis() < 100 {
            for i in 0..10_000u64 {
                x = x.wrapping_mul(31).wrapping_add(i);
            }
        }
        std::hint::black_box(x);
        let after = of_self().unwrap();
        assert!(after.cpu_s > before.cpu_s);
        assert!(after.peak_rss > 1 << 20);
        assert!(thread_cpu_s().unwrap() > thread_before);
        assert!(machine().contains("cores"));
    }
}

//! The detector's own worker threads ([`crate::DetectorConfig::threads`]).
//!
//! Why a pool of the detector's own rather than rayon's global one: the
//! user's thread count is then what runs (the global pool has one thread
//! per core, shared with whatever else the program does in it), and two
//! detectors in one program do not queue behind each other.
//!
//! Every parallel step keeps the single-thread result bit for bit: work is
//! split into pieces whose results do not depend on the split (bands of
//! rows, runs of borders, candidates, regions, detections) and the
//! pieces' results are joined in their sequential order. Where a step's
//! sequential form depends on what earlier pieces found (candidates skipped
//! inside a tag already read), the pieces are computed speculatively and
//! the sequential logic is replayed over them (see
//! `decoding::decode_candidates`). With one thread there is no pool and
//! every stage runs its sequential code as before.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard, PoisonError};

use rayon::prelude::*;
use rayon::ThreadPool;

use crate::{Error, Result};

/// Where the next pinned pool's cores start, counted over the cores a
/// program may run on (taken modulo their number): pools made one after
/// another take the cores in turn, so that two detectors of two threads
/// on a four-core machine get two cores each.
static NEXT_CORE: AtomicUsize = AtomicUsize::new(0);

/// Pieces per thread a list is cut into by [`Workers::map_ranges`]: more
/// than one, so that a thread slowed by another process (or a piece
/// heavier than the rest) leaves pieces for the others to take, few enough
/// that joining the pieces' results costs nothing.
const PIECES_PER_THREAD: usize = 4;

/// The pool and one set of buffers per pool thread.
#[derive(Debug)]
pub(crate) struct Workers<S> {
    pool: ThreadPool,
    /// Buffers of pool thread `i` at index `i`; each is locked by its own
    /// thread only, so the locks are never contended.
    scratch: Vec<Mutex<S>>,
    /// Threads in [`stay_awake`] now (see [`Workers::install_awake`]).
    awake: AtomicUsize,
}

impl<S: Default + Send> Workers<S> {
    /// A pool of `threads` (at least 2) threads. With `pin`, and at least
    /// `threads` cores the calling thread may run on, each thread is pinned
    /// to a core of its own: the next `threads` of those cores in turn
    /// after the ones the last pinned pool took ([`NEXT_CORE`]); else, or
    /// where the system refuses, the threads are left to the scheduler.
    pub(crate) fn new(threads: usize, pin: bool) -> Result<Self> {
        let cores = if pin {
            core_affinity::get_core_ids()
                .filter(|c| c.len() >= threads)
                .map(|c| {
                    let first = NEXT_CORE.fetch_add(threads, Ordering::Relaxed);
                    (0..threads).map(|i| c[(first + i) % c.len()]).collect()
                })
                .unwrap_or_default()
        } else {
            Vec::new()
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("coppertag-{i}"))
            .start_handler(move |i| {
                if let Some(&core) = cores.get(i) {
                    // Refused (a core taken offline since): the thread
                    // stays where the scheduler puts it.
                    let _ = core_affinity::set_for_current(core);
                }
            })
            .build()
            .map_err(|e| Error::InvalidParameter {
                name: "threads",
                reason: format!("{threads} threads could not be started: {e}"),
            })?;
        let scratch = (0..pool.current_num_threads())
            .map(|_| Mutex::new(S::default()))
            .collect();
        Ok(Self {
            pool,
            scratch,
            awake: AtomicUsize::new(0),
        })
    }

    /// Threads of the pool.
    pub(crate) fn threads(&self) -> usize {
        self.scratch.len()
    }

    /// Runs `f` in the pool (so that rayon's parallel iterators inside it
    /// use the pool's threads).
    pub(crate) fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        self.pool.install(f)
    }

    /// [`Workers::install`], with the pool's other threads looking for
    /// work without pause until `f` returns, instead of going to sleep
    /// whenever `f` runs a sequential step.
    ///
    /// Why a broadcast (every thread of the pool called by name) rather
    /// than `f` installed and a task spawned per other thread to keep it
    /// awake: rayon wakes a sleeping thread for a spawned task only when
    /// it counts no thread awake and idle, and the thread just woken for
    /// `f` can count as one. After a pause as long as a frame (30 ms) the
    /// other thread then came in 2.4 ms late in the median and 4 ms at
    /// worst on this project's 2-core virtual machine, a quarter of a 4K
    /// frame spent on one thread; a broadcast's threads all came within
    /// 0.16 ms (50 pauses each way, in a scratch program). The first
    /// thread in runs `f`; the others stay awake until it returns.
    ///
    /// `f` starts only once every other thread is in its awake loop. A
    /// thread takes work from the others before its own part of a
    /// broadcast, and takes that part while it waits inside a piece of
    /// work: had `f` started at once, a thread still looking for work from
    /// the frame before could steal a piece of `f`'s first parallel step,
    /// take its part of the broadcast while waiting inside it and stay
    /// awake there until `f` returned, which the piece it held kept `f`
    /// from doing. With two threads, two processes on two cores, that hung
    /// a trial version of the detector (one whose rim look read ahead on
    /// the threads too, keeping them busier at a frame's end) within 200
    /// to 500 frames of the wild set, in each of two runs. Once every
    /// other thread is awake with no work of `f` under it, each piece of
    /// `f` it takes runs inside its awake loop, and the loop ends when `f`
    /// returns.
    pub(crate) fn install_awake<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        let done = AtomicBool::new(false);
        let f = Mutex::new(Some(f));
        let others = self.threads() - 1;
        let results = self.pool.broadcast(|_| {
            let mine = f.lock().unwrap_or_else(PoisonError::into_inner).take();
            match mine {
                Some(f) => {
                    // The others come within a fraction of a millisecond
                    // (see above), and no work waits meanwhile: the pool
                    // runs nothing but `f`.
                    while self.awake.load(Ordering::Acquire) < others {
                        std::thread::yield_now();
                    }
                    // Set even when `f` panics: the broadcast waits for
                    // the threads kept awake.
                    struct Done<'a>(&'a AtomicBool);
                    impl Drop for Done<'_> {
                        fn drop(&mut self) {
                            self.0.store(true, Ordering::Release);
                        }
                    }
                    let _done = Done(&done);
                    Some(f())
                }
                None => {
                    self.awake.fetch_add(1, Ordering::AcqRel);
                    stay_awake(&done);
                    self.awake.fetch_sub(1, Ordering::AcqRel);
                    None
                }
            }
        });
        // Exactly one thread took `f` (a panic in it has gone on to the
        // caller from the broadcast already).
        results
            .into_iter()
            .flatten()
            .next()
            .expect("one pool thread runs f")
    }

    /// The buffers of the current pool thread. Called from inside
    /// [`Workers::install`]; outside the pool it returns the first set.
    pub(crate) fn scratch(&self) -> MutexGuard<'_, S> {
        let i = rayon::current_thread_index().unwrap_or(0) % self.scratch.len();
        // A panic while the buffers were held leaves them in some state
        // that every user overwrites before reading: the poison is moot.
        self.scratch[i]
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
    }

    /// `0..n` cut into consecutive ranges of at least `min_len` items
    /// (about [`PIECES_PER_THREAD`] per thread), `f` run on each in
    /// parallel, the results in range order.
    pub(crate) fn map_ranges<R: Send>(
        &self,
        n: usize,
        min_len: usize,
        f: impl Fn(Range<usize>) -> R + Sync,
    ) -> Vec<R> {
        let pieces = (self.threads() * PIECES_PER_THREAD)
            .min(n / min_len.max(1))
            .max(1);
        let len = n.div_ceil(pieces).max(1);
        self.install(|| {
            (0..pieces)
                .into_par_iter()
                .map(|k| f((k * len).min(n)..((k + 1) * len).min(n)))
                .collect()
        })
    }

    /// [`Workers::map_ranges`] with items of unequal cost: `0..n` cut
    /// into consecutive ranges of at most about `1 / pieces` of the total
    /// `weight` each (`pieces` about [`PIECES_PER_THREAD`] per thread, and
    /// no more than leaves each `min_weight`), `f` run on each in
    /// parallel, the results in range order. A range is closed before an
    /// item that would take it over its share, so a heavy item gets a
    /// range of its own; there are at most about twice `pieces` ranges.
    pub(crate) fn map_weighted<R: Send>(
        &self,
        n: usize,
        weight: impl Fn(usize) -> usize,
        min_weight: usize,
        f: impl Fn(Range<usize>) -> R + Sync,
    ) -> Vec<R> {
        let total: usize = (0..n).map(&weight).sum();
        let pieces = (self.threads() * PIECES_PER_THREAD)
            .min(total / min_weight.max(1))
            .max(1);
        let share = total.div_ceil(pieces);
        let mut cuts = vec![0];
        let mut acc = 0;
        for i in 0..n {
            let w = weight(i);
            if acc > 0 && acc + w > share {
                cuts.push(i);
                acc = 0;
            }
            acc += w;
        }
        cuts.push(n);
        self.install(|| cuts.par_windows(2).map(|c| f(c[0]..c[1])).collect())
    }
}

/// A pool thread's loop while [`Workers::install_awake`] runs: take and run
/// the pool's pending work, yielding to the system between, until `done`.
fn stay_awake(done: &AtomicBool) {
    while !done.load(Ordering::Acquire) {
        if rayon::yield_now() != Some(rayon::Yield::Executed) {
            std::thread::yield_now();
        }
    }
}

/// `f(range, out)` appends the results of the items `range` of `0..n` to
/// `out`: run on `0..n` at once without `workers`, else on pieces of at
/// least `min_len` items in parallel ([`Workers::map_ranges`]), the
/// pieces' results appended in order. The same `out` either way when `f`
/// treats each item on its own.
pub(crate) fn collect_ranges<T: Send, W: Default + Send>(
    workers: Option<&Workers<W>>,
    n: usize,
    min_len: usize,
    out: &mut Vec<T>,
    f: impl Fn(std::ops::Range<usize>, &mut Vec<T>) + Sync,
) {
    match workers {
        None => f(0..n, out),
        Some(w) => {
            for part in w.map_ranges(n, min_len, |r| {
                let mut v = Vec::new();
                f(r, &mut v);
                v
            }) {
                out.extend(part);
            }
        }
    }
}

/// Runs `a` and `b`, at once on `workers`' threads if given.
pub(crate) fn join<W: Default + Send>(
    workers: Option<&Workers<W>>,
    a: impl FnOnce() + Send,
    b: impl FnOnce() + Send,
) {
    match workers {
        None => {
            a();
            b();
        }
        Some(w) => {
            w.install(|| rayon::join(a, b));
        }
    }
}

/// [`collect_ranges`] for an `f` that needs buffers of type `S`: without
/// `workers` it runs on `0..n` at once with `scratch`, on `workers` each
/// piece gets buffers of its own (`S::default()`, cheap next to the
/// piece's work).
pub(crate) fn collect_ranges_with<T: Send, S: Default, W: Default + Send>(
    workers: Option<&Workers<W>>,
    n: usize,
    min_len: usize,
    scratch: &mut S,
    out: &mut Vec<T>,
    f: impl Fn(Range<usize>, &mut S, &mut Vec<T>) + Sync,
) {
    match workers {
        None => f(0..n, scratch, out),
        Some(w) => {
            for part in w.map_ranges(n, min_len, |r| {
                let mut v = Vec::new();
                f(r, &mut S::default(), &mut v);
                v
            }) {
                out.extend(part);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every other thread is in its awake loop before `f` starts, frame
    /// after frame, pinned or not, with more threads than cores too: a
    /// piece of `f` stolen by a thread that was not yet awake could hang
    /// the pool (see [`Workers::install_awake`]). Its pieces then run
    /// inside the awake loops, and the frames end.
    #[test]
    fn frames_start_with_every_other_thread_awake() {
        for (threads, pin) in [(2, false), (2, true), (3, false)] {
            let w = Workers::<()>::new(threads, pin).unwrap();
            for frame in 0..500u64 {
                let (awake, sum) = w.install_awake(|| {
                    let awake = w.awake.load(Ordering::Acquire);
                    let mut rows = vec![0u8; 64 * 64];
                    rows.par_chunks_mut(64).enumerate().for_each(|(i, r)| {
                        r.iter_mut().for_each(|v| *v = i as u8);
                    });
                    let sum: u64 = rows.iter().map(|&v| u64::from(v)).sum::<u64>() + frame;
                    (awake, sum)
                });
                assert_eq!(awake, threads - 1, "frame {frame}, {threads} threads");
                assert_eq!(sum, (0..64u64).sum::<u64>() * 64 + frame);
            }
        }
    }

    #[test]
    fn awake_pools_run_nested_work_and_end() {
        // Pinned or not; 3 threads are more than this machine's 2 cores
        // (left unpinned).
        for (threads, pin) in [(2, false), (2, true), (3, false), (3, true)] {
            let w = Workers::<()>::new(threads, pin).unwrap();
            for _ in 0..20 {
                // Parallel steps between sequential ones, and a scope whose
                // tasks wait for the caller, as the decoding's read-ahead.
                let sum = w.install_awake(|| {
                    let a: u64 = (0..10_000u64).into_par_iter().sum();
                    let go = std::sync::Mutex::new(false);
                    let cv = std::sync::Condvar::new();
                    rayon::scope(|s| {
                        for _ in 1..threads {
                            s.spawn(|_| {
                                let mut g = go.lock().unwrap();
                                while !*g {
                                    g = cv.wait(g).unwrap();
                                }
                            });
                        }
                        *go.lock().unwrap() = true;
                        cv.notify_all();
                    });
                    a + w.map_ranges(100, 1, |r| r.len() as u64).iter().sum::<u64>()
                });
                assert_eq!(sum, 49_995_000 + 100);
            }
            // A panic in `f` reaches the caller; the pool stays usable.
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                w.install_awake(|| panic!("stage failed"))
            }));
            assert!(r.is_err());
            assert_eq!(w.install_awake(|| 7), 7);
        }
    }

    #[test]
    fn weighted_ranges_cover_the_list_in_order() {
        let w = Workers::<()>::new(2, false).unwrap();
        let weights = [1usize, 50, 0, 0, 3, 3, 3, 100, 1, 1, 1, 1, 0];
        for n in [0, 1, 2, 7, weights.len()] {
            for min_weight in [1, 10, 1000] {
                let r = w.map_weighted(n, |i| weights[i], min_weight, |r| r);
                assert_eq!(r.first().map(|r| r.start), Some(0), "{n} {min_weight}");
                assert_eq!(r.last().map(|r| r.end), Some(n), "{n} {min_weight}");
                assert!(r.windows(2).all(|p| p[0].end == p[1].start));
                assert!(r.iter().all(|r| r.start <= r.end));
                assert!(r.len() <= 2 * 2 * PIECES_PER_THREAD + 1);
            }
        }
        // The two heavy items end up in pieces of their own.
        let r = w.map_weighted(weights.len(), |i| weights[i], 1, |r| r);
        assert!(r.contains(&(7..8)), "{r:?}");
    }

    #[test]
    fn ranges_cover_the_list_in_order() {
        let w = Workers::<()>::new(3, false).unwrap();
        for n in [0, 1, 5, 11, 12, 13, 100, 1001] {
            for min_len in [1, 4, 50] {
                let r = w.map_ranges(n, min_len, |r| r);
                assert_eq!(r.first().map(|r| r.start), Some(0), "{n} {min_len}");
                assert_eq!(r.last().map(|r| r.end), Some(n), "{n} {min_len}");
                assert!(r.windows(2).all(|p| p[0].end == p[1].start));
                assert!(r.len() <= 3 * PIECES_PER_THREAD);
            }
        }
    }
}

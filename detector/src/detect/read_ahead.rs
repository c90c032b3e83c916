//! Stage 6 on the detector's worker threads: the candidates are read
//! ahead of the sequential decoding loop, which takes their readings in
//! order.
//!
//! Whether a candidate is decoded depends on the tags found before it (a
//! candidate inside a tag read cleanly is skipped), so the loop itself
//! stays sequential ([`decode_in_order`]); what takes the time, refusing
//! or reading a candidate ([`outcome`]), is a pure function of the image
//! and the candidate, so it can be done ahead, on any thread, and the
//! loop's result is the one-thread result whatever was read ahead, by
//! whom and when.
//!
//! Each thread takes the next candidate that the tags found so far would
//! not skip, as long as fewer than [`AHEAD_PER_THREAD`] per thread are
//! taken or read from the one the loop is at on (and no more than the
//! attempts left), reads it and leaves the outcome for the loop. The loop
//! takes the outcome of each candidate it decodes: ready, or read by
//! itself if no thread took it; while another thread is reading it, the
//! loop reads ahead too rather than wait. There is no barrier: a thread
//! waits only when the candidates ahead are all taken, or when the loop
//! is about to take a ready outcome (which may find a tag that makes it
//! skip what the thread would read). A reading ahead is in vain when a
//! tag found meanwhile makes the loop skip its candidate, and it costs
//! time when the loop has finished before it: the last readings are
//! waited for.

use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};

use super::decoding::{
    centre_of, decode_in_order, outcome, plan, Decoded, DecodingParams, Found, Outcome, Plan, Quad,
    Target,
};
use super::parallel::Workers;
use super::quads::Candidate;
use super::refine::RefineScratch;
use crate::view::GrayView;

/// Most candidates taken or read ahead of the loop per worker thread:
/// enough that a thread finds work while the others read slow
/// candidates, few enough that little is read in vain when a tag found
/// makes the loop skip candidates read ahead. The window starts at one
/// per thread and doubles each time the loop takes an outcome read ahead
/// with none in vain before it, back to one per thread after one in vain
/// (candidates over a tag found come in runs): the last readings of a
/// frame, waited for even when in vain, are then few.
const AHEAD_PER_THREAD: usize = 4;

/// A candidate's reading ahead.
#[derive(Debug, Default)]
enum Slot {
    /// Not taken by any thread.
    #[default]
    Free,
    /// Being read by some thread.
    Taken,
    /// Read.
    Done(Outcome),
}

/// What the threads share, behind one lock (taken a few times per
/// candidate; a candidate takes a hundred microseconds and more).
#[derive(Debug)]
struct Ahead {
    slots: Vec<Slot>,
    /// The next candidate to look at for reading ahead.
    next: usize,
    /// The first candidate whose outcome the loop has not taken: those
    /// before it are no longer needed.
    at: usize,
    /// Most candidates taken or read from `at` on.
    limit: usize,
    /// The window `limit` is (before the attempts left cap it), and its
    /// least and most.
    window: usize,
    least: usize,
    most: usize,
    /// Whether the loop is reading a candidate itself.
    busy: bool,
    /// The tags the loop has found so far, and the squares of families not
    /// decoded, for skipping candidates ahead.
    found: Vec<Found>,
    foreign: Vec<Quad>,
    /// The loop has finished: threads stop reading ahead.
    finished: bool,
}

impl Ahead {
    /// The next candidate to read ahead, if one is left that the tags
    /// found so far would not skip, the limit allows one and the loop is
    /// not about to take a ready outcome; it is marked taken.
    fn take(&mut self, wanted: impl Fn(usize, &[Found], &[Quad]) -> bool) -> Option<usize> {
        if !self.busy && matches!(self.slots.get(self.at), Some(Slot::Done(_))) {
            return None;
        }
        self.next = self.next.max(self.at);
        let ahead = self.slots[self.at..self.next]
            .iter()
            .filter(|s| !matches!(s, Slot::Free))
            .count();
        if ahead >= self.limit {
            return None;
        }
        while self.next < self.slots.len() {
            let k = self.next;
            self.next += 1;
            if matches!(self.slots[k], Slot::Free) && wanted(k, &self.found, &self.foreign) {
                self.slots[k] = Slot::Taken;
                return Some(k);
            }
        }
        None
    }
}

/// The shared state and the signal that it changed.
struct Shared {
    ahead: Mutex<Ahead>,
    changed: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Ahead> {
        // A thread that panicked while holding the lock left the state
        // consistent (every change is made whole under it).
        self.ahead.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn wait<'a>(&self, g: MutexGuard<'a, Ahead>) -> MutexGuard<'a, Ahead> {
        self.changed.wait(g).unwrap_or_else(PoisonError::into_inner)
    }

    /// Reads candidate `k`, taken by this thread, with `read`, and leaves
    /// the outcome in its slot. Should `read` panic, the slot is freed
    /// (the loop then reads the candidate itself) before the panic goes
    /// on.
    fn read_into_slot(&self, k: usize, read: &impl Fn(usize) -> Outcome) {
        struct Release<'a>(&'a Shared, usize, bool);
        impl Drop for Release<'_> {
            fn drop(&mut self) {
                if !self.2 {
                    self.0.lock().slots[self.1] = Slot::Free;
                    self.0.changed.notify_all();
                }
            }
        }
        let mut release = Release(self, k, false);
        let o = read(k);
        release.2 = true;
        self.lock().slots[k] = Slot::Done(o);
        self.changed.notify_all();
    }

    /// A worker thread's part: read ahead until the loop has finished.
    fn read_ahead(
        &self,
        wanted: &impl Fn(usize, &[Found], &[Quad]) -> bool,
        read: &impl Fn(usize) -> Outcome,
    ) {
        let mut g = self.lock();
        while !g.finished {
            match g.take(wanted) {
                Some(k) => {
                    drop(g);
                    self.read_into_slot(k, read);
                    g = self.lock();
                }
                None => g = self.wait(g),
            }
        }
    }

    /// Runs `read` as the loop's own reading: the threads reading ahead
    /// know the loop is busy meanwhile.
    fn busy<R>(&self, read: impl FnOnce() -> R) -> R {
        struct Idle<'a>(&'a Shared);
        impl Drop for Idle<'_> {
            fn drop(&mut self) {
                self.0.lock().busy = false;
            }
        }
        self.lock().busy = true;
        self.changed.notify_all();
        let _idle = Idle(self);
        read()
    }

    /// The loop's part: the outcome of candidate `j`, `left` attempts
    /// left.
    fn outcome_of(
        &self,
        j: usize,
        left: usize,
        wanted: &impl Fn(usize, &[Found], &[Quad]) -> bool,
        read: &impl Fn(usize) -> Outcome,
    ) -> Outcome {
        let mut g = self.lock();
        // The candidates from `at` to `j` are skipped: any taken or read
        // was read in vain.
        let in_vain = g.slots[g.at..j].iter().any(|s| !matches!(s, Slot::Free));
        g.window = if in_vain {
            g.least
        } else if matches!(g.slots[j], Slot::Done(_)) {
            (2 * g.window).min(g.most)
        } else {
            g.window
        };
        g.at = j;
        g.limit = g.window.min(left);
        loop {
            match &g.slots[j] {
                Slot::Done(_) => {
                    if let Slot::Done(o) = std::mem::take(&mut g.slots[j]) {
                        return o;
                    }
                }
                Slot::Free => {
                    g.slots[j] = Slot::Taken;
                    drop(g);
                    return self.busy(|| read(j));
                }
                // Another thread reads it: read ahead meanwhile.
                Slot::Taken => match g.take(wanted) {
                    Some(k) => {
                        drop(g);
                        self.busy(|| self.read_into_slot(k, read));
                        g = self.lock();
                    }
                    None => g = self.wait(g),
                },
            }
        }
    }

    /// The loop has taken the outcome of candidate `j` into the tags it
    /// has found, `found`, and the squares of families not decoded,
    /// `foreign`: the threads may read ahead past it, skipping the
    /// candidates those make the loop skip.
    fn taken(&self, j: usize, found: &[Found], foreign: &[Quad]) {
        let mut g = self.lock();
        // The loop read it itself or took its outcome out.
        g.slots[j] = Slot::Free;
        g.at = j + 1;
        g.found.clear();
        g.found.extend_from_slice(found);
        g.foreign.clear();
        g.foreign.extend_from_slice(foreign);
        self.changed.notify_all();
    }

    /// Marks the loop finished and wakes the threads waiting for work.
    fn finish(&self) {
        self.lock().finished = true;
        self.changed.notify_all();
    }
}

/// [`super::decoding::decode_candidates`] on `workers`' threads, with the
/// same result: the candidates read ahead of the loop (see the module
/// documentation), each thread with its buffers from `scratch`.
pub(crate) fn decode_candidates_par<W: Default + Send>(
    img: &GrayView<'_>,
    candidates: &[Candidate],
    scale: f64,
    targets: &[Target],
    p: &DecodingParams,
    workers: &Workers<W>,
    scratch: impl Fn(&mut W) -> &mut RefineScratch + Sync,
) -> Decoded {
    let centres: Vec<[f64; 2]> = candidates.iter().map(|c| centre_of(c, scale)).collect();
    // Guessed candidates (`quads::one_corner`) are left to the loop: they
    // come last, and most of them lie over tags the candidates before them
    // find, so read ahead they would be read in vain and waited for at the
    // end of the frame (on the wild 1080p benchmark, decoding with 2
    // threads took 4.58 ms instead of 3.99).
    let wanted = |k: usize, found: &[Found], foreign: &[Quad]| {
        !candidates[k].guessed
            && matches!(
                plan(&candidates[k], centres[k], scale, found, foreign, p),
                Plan::Decode(_)
            )
    };
    let read = |k: usize| {
        let mut w = workers.scratch();
        outcome(
            img,
            &candidates[k],
            scale,
            centres[k],
            targets,
            p,
            scratch(&mut w),
        )
    };
    let (least, most) = (workers.threads(), AHEAD_PER_THREAD * workers.threads());
    let shared = Shared {
        ahead: Mutex::new(Ahead {
            slots: std::iter::repeat_with(Slot::default)
                .take(candidates.len())
                .collect(),
            next: 0,
            at: 0,
            limit: least.min(p.max_attempts),
            window: least,
            least,
            most,
            busy: false,
            found: Vec::new(),
            foreign: Vec::new(),
            finished: false,
        }),
        changed: Condvar::new(),
    };
    // Finishes the loop even when it panics, so that the threads reading
    // ahead stop and the scope can end.
    struct Finish<'a>(&'a Shared);
    impl Drop for Finish<'_> {
        fn drop(&mut self) {
            self.0.finish();
        }
    }
    workers.install(|| {
        rayon::scope(|s| {
            for _ in 1..workers.threads() {
                s.spawn(|_| shared.read_ahead(&wanted, &read));
            }
            let _finish = Finish(&shared);
            let mut attempts = 0;
            decode_in_order(
                candidates,
                scale,
                p,
                |j, _| {
                    let left = p.max_attempts.saturating_sub(attempts);
                    let o = shared.outcome_of(j, left, &wanted, &read);
                    attempts += usize::from(matches!(o, Outcome::Read(_)));
                    o
                },
                |j, found, foreign| shared.taken(j, found, foreign),
            )
        })
    })
}

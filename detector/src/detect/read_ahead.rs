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
//! not skip, preferring one that lies in no square being read (see
//! [`Ahead::take`]), as long as fewer than [`AHEAD_PER_THREAD`] per thread
//! are taken or read from the one the loop is at on (and no more than the
//! attempts left), reads it and leaves the outcome for the loop. The loop
//! takes the outcome of each candidate it decodes: ready, or read by itself
//! if no thread took it; while another thread is reading it, the loop reads
//! ahead too rather than wait. There is no barrier: a thread waits only
//! when the candidates ahead are all taken, or when the loop is about to
//! take a ready outcome (which may find a tag that makes it skip what the
//! thread would read). A reading ahead is in vain when a tag found
//! meanwhile makes the loop skip its candidate, and it costs time when the
//! loop has finished before it: the last readings are waited for.

use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};

use super::decoding::{
    centre_of, decode_in_order, outcome, plan, Decoded, DecodingParams, Found, Outcome, Plan, Quad,
    Target,
};
use super::parallel::Workers;
use super::quads::Candidate;
use super::refine::RefineScratch;
use crate::math::{inside, to_full};
use crate::view::GrayView;

/// Most candidates taken or read ahead of the loop per worker thread:
/// enough that a thread finds work while the loop reads a slow candidate
/// (a tag's hard quads take milliseconds each), few enough that little is
/// read in vain when a tag found makes the loop skip candidates read
/// ahead. Measured on the wild benchmark with 2 threads (pinned): with a
/// window of one to four per thread that grew while nothing was read in
/// vain, the second thread waited 1.9-2.1 ms of a 4K frame's 5.6-5.9 ms
/// of decoding, most of it at the limit; at eight per thread it waits
/// 0.5 ms, and on the 1080p frames 0.2 of 1.9 readings a frame are in
/// vain (decoding 2.7-3.0 -> 2.4-2.6 ms a frame there, both figures with
/// [`Ahead::take`]'s fallback).
const AHEAD_PER_THREAD: usize = 8;

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
    /// The first candidate whose outcome the loop has not taken: those
    /// before it are no longer needed.
    at: usize,
    /// Most candidates taken or read from `at` on.
    limit: usize,
    /// `limit` before the attempts left cap it.
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
    ///
    /// A candidate whose centre lies in the square (`quads`, full px) of
    /// one before it that is being read or waits for the loop is passed
    /// over while another is left: the quads of one tag come in runs (its
    /// data square, its outline, linked and rim quads), and should the
    /// first read a tag, the loop skips the rest, so reading them at the
    /// same time would be in vain; and a thread reading another tag
    /// meanwhile reads pixels its own cache has not held yet, where the
    /// rest of a run is read best by the thread that read the first. On
    /// the wild benchmark's 4K frames with 2 threads (pinned), decoding
    /// took 3.4 ms a frame in the median, against 3.8-3.9 ms when threads
    /// took the next candidate whatever it lay in. When every candidate
    /// left lies in such a square, the first is taken all the same rather
    /// than wait: the first of its run is then often a tag's hard quad,
    /// read to nothing for milliseconds, and with the wait the second
    /// thread stood idle 0.8-1.0 ms of a 4K frame's decoding.
    fn take(
        &mut self,
        quads: &[Quad],
        centres: &[[f64; 2]],
        wanted: impl Fn(usize, &[Found], &[Quad]) -> bool,
    ) -> Option<usize> {
        if !self.busy && matches!(self.slots.get(self.at), Some(Slot::Done(_))) {
            return None;
        }
        let pending: Vec<usize> = (self.at..self.slots.len())
            .filter(|&m| !matches!(self.slots[m], Slot::Free))
            .collect();
        if pending.len() >= self.limit {
            return None;
        }
        let free = || (self.at..self.slots.len()).filter(|&k| matches!(self.slots[k], Slot::Free));
        let apart = |k: usize| {
            !pending
                .iter()
                .any(|&m| m < k && inside(&quads[m], centres[k]))
        };
        let wanted = |k: usize| wanted(k, &self.found, &self.foreign);
        let k = free()
            .find(|&k| apart(k) && wanted(k))
            .or_else(|| free().find(|&k| wanted(k)))?;
        self.slots[k] = Slot::Taken;
        Some(k)
    }
}

/// The shared state and the signal that it changed, and the candidates'
/// squares and centres (full px).
struct Shared<'c> {
    ahead: Mutex<Ahead>,
    changed: Condvar,
    quads: Vec<Quad>,
    centres: &'c [[f64; 2]],
}

impl Shared<'_> {
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
        struct Release<'a, 'c>(&'a Shared<'c>, usize, bool);
        impl Drop for Release<'_, '_> {
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
            match g.take(&self.quads, self.centres, wanted) {
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
        struct Idle<'a, 'c>(&'a Shared<'c>);
        impl Drop for Idle<'_, '_> {
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
        // was read in vain, and is no longer counted against the limit.
        g.at = j;
        g.limit = g.most.min(left);
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
                Slot::Taken => match g.take(&self.quads, self.centres, wanted) {
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
    let most = AHEAD_PER_THREAD * workers.threads();
    let shared = Shared {
        ahead: Mutex::new(Ahead {
            slots: std::iter::repeat_with(Slot::default)
                .take(candidates.len())
                .collect(),
            at: 0,
            limit: most.min(p.max_attempts),
            most,
            busy: false,
            found: Vec::new(),
            foreign: Vec::new(),
            finished: false,
        }),
        changed: Condvar::new(),
        quads: candidates
            .iter()
            .map(|c| c.corners.map(|q| to_full(q, scale)))
            .collect(),
        centres: &centres,
    };
    // Finishes the loop even when it panics, so that the threads reading
    // ahead stop and the scope can end.
    struct Finish<'a, 'c>(&'a Shared<'c>);
    impl Drop for Finish<'_, '_> {
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
                    attempts += usize::from(matches!(
                        o,
                        Outcome::Read(_)
                            | Outcome::LastResort(_)
                            | Outcome::ReadKeeping(..)
                            | Outcome::Unread(_)
                    ));
                    o
                },
                |j, found, foreign| shared.taken(j, found, foreign),
            )
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x: f64, y: f64, side: f64) -> Quad {
        [[x, y], [x, y + side], [x + side, y + side], [x + side, y]]
    }

    fn ahead(n: usize, limit: usize) -> Ahead {
        Ahead {
            slots: std::iter::repeat_with(Slot::default).take(n).collect(),
            at: 0,
            limit,
            most: limit,
            busy: true,
            found: Vec::new(),
            foreign: Vec::new(),
            finished: false,
        }
    }

    #[test]
    fn candidates_inside_a_square_being_read_come_after_the_others() {
        // 0 and 1 are quads of one tag, 2 of another, 3 of the first again,
        // 4 of a third.
        let quads = [
            square(0.0, 0.0, 100.0),
            square(10.0, 10.0, 80.0),
            square(500.0, 0.0, 100.0),
            square(5.0, 5.0, 90.0),
            square(1000.0, 0.0, 100.0),
        ];
        let centres: Vec<[f64; 2]> = quads.iter().map(crate::math::centroid).collect();
        let all = |_: usize, _: &[Found], _: &[Quad]| true;
        let mut a = ahead(quads.len(), 8);
        // The loop reads 0 itself: 1 and 3 lie in it, 2 and 4 come first.
        a.slots[0] = Slot::Taken;
        assert_eq!(a.take(&quads, &centres, all), Some(2));
        assert_eq!(a.take(&quads, &centres, all), Some(4));
        // Then, rather than wait, the first that lies in 0.
        assert_eq!(a.take(&quads, &centres, all), Some(1));
        assert_eq!(a.take(&quads, &centres, all), Some(3));
        assert_eq!(a.take(&quads, &centres, all), None);
        // With the loop past 0 and 1 and at 2, 3 lies in no square being
        // read: it comes before 4, in candidate order.
        let mut a = ahead(quads.len(), 8);
        a.at = 2;
        a.slots[2] = Slot::Taken;
        assert_eq!(a.take(&quads, &centres, all), Some(3));
        // A candidate the tags found would skip is never taken.
        a.slots[3] = Slot::Free;
        let not_3 = |k: usize, _: &[Found], _: &[Quad]| k != 3;
        assert_eq!(a.take(&quads, &centres, not_3), Some(4));
        assert_eq!(a.take(&quads, &centres, not_3), None);
    }

    #[test]
    fn no_more_than_the_limit_is_read_ahead() {
        let quads: Vec<Quad> = (0..6)
            .map(|i| square(200.0 * i as f64, 0.0, 100.0))
            .collect();
        let centres: Vec<[f64; 2]> = quads.iter().map(crate::math::centroid).collect();
        let all = |_: usize, _: &[Found], _: &[Quad]| true;
        let mut a = ahead(quads.len(), 2);
        assert_eq!(a.take(&quads, &centres, all), Some(0));
        assert_eq!(a.take(&quads, &centres, all), Some(1));
        assert_eq!(a.take(&quads, &centres, all), None);
    }
}

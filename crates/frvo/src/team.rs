//! A team of helper threads that run a crowd step's phases together with the calling thread.
//!
//! Why not a work-stealing pool (rayon, which this replaced): entering a pool from outside
//! hands the work to a pool thread and puts the caller to sleep until it is done, and a
//! worker that found nothing to do sleeps too. On a virtual machine each such wake-up is an
//! interrupt to a halted core: measured on the 2-core benchmark machine, 28 us on average
//! between back-to-back calls and 140 us after 1 ms idle, as long as a whole step of 200
//! agents. Here the caller starts on the work at once and never sleeps; helpers join as soon
//! as they are awake, wait between phases and for [`SPIN`] after one (spinning briefly, then
//! yielding the core between checks), and only then park.
//!
//! Work is handed out by index from a shared counter, so whoever is awake takes the next
//! block: a helper that wakes late only means the caller does more of the blocks itself. A
//! forked child (which has none of the parent's threads) steps on the caller alone, and
//! dropping the team there leaves the missing helpers unjoined.

use std::any::Any;
use std::panic::{self, AssertUnwindSafe};
use std::sync::atomic::Ordering::{Acquire, Relaxed, Release, SeqCst};
use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicU64, AtomicUsize};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

/// How long an idle helper waits for the next phase before it parks: longer than the serial
/// work between a step's phases, short enough that an idle tracker costs nothing.
const SPIN: Duration = Duration::from_micros(100);
/// Spins before a waiting thread starts yielding to the OS between checks: a thread that only
/// spins can hold a core that the thread it waits for needs (another process's spinning
/// threads, e.g. a BLAS or onnxruntime pool, can leave both on one core), and a scheduler
/// time slice is a millisecond or more.
const SPINS_BEFORE_YIELD: u32 = 64;

/// One phase: `count` blocks, each run once by whoever claims it.
struct Job<'a> {
    work: &'a (dyn Fn(usize) + Sync),
    count: usize,
    next: AtomicUsize,
    done: AtomicUsize,
    /// The first panic of a block, resumed on the caller once every block has finished.
    panic: Mutex<Option<Box<dyn Any + Send>>>,
}

impl Job<'_> {
    /// Claims and runs blocks until none is left.
    fn help(&self) {
        loop {
            let block = self.next.fetch_add(1, Relaxed);
            if block >= self.count {
                return;
            }
            if let Err(payload) = panic::catch_unwind(AssertUnwindSafe(|| (self.work)(block))) {
                self.panic
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .get_or_insert(payload);
            }
            // Publishes the block's writes to the caller (its `Acquire` load of `done`).
            self.done.fetch_add(1, Release);
        }
    }
}

/// What the caller and the helpers share.
struct Shared {
    /// The current phase, or null between phases. Helpers only read it while counted in
    /// `active`, and the caller only retires a phase once `active` is 0 (see [`Team::run`]).
    job: AtomicPtr<Job<'static>>,
    /// Bumped for every phase, so that helpers notice new work (and `stop`).
    epoch: AtomicU64,
    active: AtomicUsize,
    stop: AtomicBool,
    /// Per helper: parked or about to park, so the caller must unpark it.
    parked: Vec<AtomicBool>,
}

/// The caller plus `helpers` threads, started when the team is made and stopped when it is
/// dropped.
pub(crate) struct Team {
    shared: Arc<Shared>,
    helpers: Vec<JoinHandle<()>>,
    /// Held by the caller of [`Team::run`]: another caller (a clone of the model stepping on
    /// another thread) runs its phase alone instead of waiting.
    busy: AtomicBool,
    /// The process that started the helpers: a forked child has none of them.
    process: u32,
}

impl std::fmt::Debug for Team {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Team")
            .field("threads", &self.threads())
            .finish()
    }
}

impl Team {
    /// A team of `threads` in all (the caller and `threads - 1` helpers; fewer if the OS
    /// refuses to start them).
    pub(crate) fn new(threads: usize) -> Self {
        let wanted = threads.saturating_sub(1);
        let shared = Arc::new(Shared {
            job: AtomicPtr::new(std::ptr::null_mut()),
            epoch: AtomicU64::new(0),
            active: AtomicUsize::new(0),
            stop: AtomicBool::new(false),
            parked: (0..wanted).map(|_| AtomicBool::new(false)).collect(),
        });
        let helpers = (0..wanted)
            .map_while(|me| {
                let shared = Arc::clone(&shared);
                thread::Builder::new()
                    .name(format!("frvo-helper-{me}"))
                    .spawn(move || helper(&shared, me))
                    .ok()
            })
            .collect();
        Self {
            shared,
            helpers,
            busy: AtomicBool::new(false),
            process: std::process::id(),
        }
    }

    /// Whether the helpers are there to help (not in a forked child): [`Team::run`] needs
    /// them (a child's copy of the state may count a helper that was mid-phase at the fork).
    /// A system call, so asked once per step, not per phase.
    pub(crate) fn has_helpers(&self) -> bool {
        !self.helpers.is_empty() && std::process::id() == self.process
    }

    /// Threads that work on a phase: the caller and the helpers.
    pub(crate) fn threads(&self) -> usize {
        self.helpers.len() + 1
    }

    /// Runs `work(0..count)`, each index once, on the caller and whichever helpers are
    /// awake; returns when all have finished (resuming a block's panic, if any). Only where
    /// [`Team::has_helpers`].
    pub(crate) fn run(&self, count: usize, work: &(dyn Fn(usize) + Sync)) {
        if count <= 1 || self.helpers.is_empty() || self.busy.swap(true, Acquire) {
            (0..count).for_each(work);
            return;
        }
        let _free = Free(&self.busy);
        let job = Job {
            work,
            count,
            next: AtomicUsize::new(0),
            done: AtomicUsize::new(0),
            panic: Mutex::new(None),
        };
        let shared = &*self.shared;
        // The lifetime is erased for the shared pointer only: no helper reads it after this
        // function returns (the retirement below waits for them).
        shared.job.store(
            (&job as *const Job<'_>).cast::<Job<'static>>().cast_mut(),
            SeqCst,
        );
        shared.epoch.fetch_add(1, SeqCst);
        for (parked, handle) in shared.parked.iter().zip(&self.helpers) {
            if parked.load(SeqCst) {
                handle.thread().unpark();
            }
        }
        job.help();
        // Blocks that helpers claimed: running, so the wait is short.
        wait_until(|| job.done.load(Acquire) >= count);
        // Retire the job: a helper counted in `active` may still read it (to find no block
        // left); one that counts itself in later sees null (both sides are SeqCst: either its
        // increment comes before our read of `active`, or our store before its load).
        shared.job.store(std::ptr::null_mut(), SeqCst);
        wait_until(|| shared.active.load(SeqCst) == 0);
        let panic = job
            .panic
            .into_inner()
            .unwrap_or_else(PoisonError::into_inner);
        if let Some(payload) = panic {
            panic::resume_unwind(payload);
        }
    }
}

impl Drop for Team {
    fn drop(&mut self) {
        if !self.has_helpers() {
            // A forked child: joining threads that do not exist here would wait forever.
            return;
        }
        self.shared.stop.store(true, SeqCst);
        self.shared.epoch.fetch_add(1, SeqCst);
        for handle in self.helpers.drain(..) {
            handle.thread().unpark();
            // A helper cannot panic (blocks' panics are caught): nothing to report.
            let _ = handle.join();
        }
    }
}

/// Clears the busy flag when [`Team::run`] returns or unwinds.
struct Free<'a>(&'a AtomicBool);

impl Drop for Free<'_> {
    fn drop(&mut self) {
        self.0.store(false, Release);
    }
}

/// Waits until `ready`: spins briefly, then yields to the OS between checks.
fn wait_until(ready: impl Fn() -> bool) {
    let mut spins = 0;
    while !ready() {
        pause(&mut spins);
    }
}

/// One wait between checks: a spin for the first [`SPINS_BEFORE_YIELD`], then a yield.
fn pause(spins: &mut u32) {
    if *spins < SPINS_BEFORE_YIELD {
        *spins += 1;
        std::hint::spin_loop();
    } else {
        thread::yield_now();
    }
}

/// A helper's life: wait for a new phase (spinning, then parked), help with it, repeat.
fn helper(shared: &Shared, me: usize) {
    let mut seen = shared.epoch.load(SeqCst);
    loop {
        let mut idle_since = Instant::now();
        let mut spins = 0;
        loop {
            let epoch = shared.epoch.load(SeqCst);
            // Checked here, not only after a new epoch: a helper that started after the
            // team's last bump (a team dropped at once) would otherwise wait forever.
            if shared.stop.load(SeqCst) {
                return;
            }
            if epoch != seen {
                seen = epoch;
                break;
            }
            if idle_since.elapsed() < SPIN {
                pause(&mut spins);
                continue;
            }
            // Park unless a phase came in meanwhile: the caller sets `epoch` before it reads
            // `parked`, we set `parked` before we read `epoch` (SeqCst), so one of us sees the
            // other. A stray unpark only makes `park` return early. (Dropping the team unparks
            // every helper after setting `stop`.)
            shared.parked[me].store(true, SeqCst);
            if shared.epoch.load(SeqCst) == seen && !shared.stop.load(SeqCst) {
                thread::park();
            }
            shared.parked[me].store(false, SeqCst);
            idle_since = Instant::now();
            spins = 0;
        }
        shared.active.fetch_add(1, SeqCst);
        let job = shared.job.load(SeqCst);
        // SAFETY: non-null, the job is alive: the caller retires it (nulls `job`, then waits
        // for `active` to reach 0) before it returns, and we are counted in `active`.
        if let Some(job) = unsafe { job.as_ref() } {
            job.help();
        }
        shared.active.fetch_sub(1, SeqCst);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs `count` blocks on `team` and checks that each ran exactly once.
    fn check_every_block_runs_once(team: &Team, count: usize) {
        let hits: Vec<AtomicUsize> = (0..count).map(|_| AtomicUsize::new(0)).collect();
        team.run(count, &|b| {
            hits[b].fetch_add(1, Relaxed);
        });
        let runs: Vec<usize> = hits.iter().map(|h| h.load(Relaxed)).collect();
        assert!(runs.iter().all(|&r| r == 1), "{count} blocks: {runs:?}");
    }

    #[test]
    fn every_block_runs_once_whatever_the_team() {
        for threads in [1, 2, 3, 8] {
            let team = Team::new(threads);
            for count in [0, 1, 2, 7, 64, 1000] {
                check_every_block_runs_once(&team, count);
            }
        }
    }

    #[test]
    fn a_team_dropped_at_once_stops() {
        // Helpers may start after the drop's signal: they must still see it.
        for threads in [2, 3, 5] {
            for _ in 0..50 {
                drop(Team::new(threads));
            }
        }
    }

    #[test]
    fn helpers_do_work_and_park_when_idle() {
        let team = Team::new(2);
        // A phase long enough for the helper to wake and take blocks.
        let by_helper = AtomicUsize::new(0);
        let caller = thread::current().id();
        for _ in 0..50 {
            team.run(64, &|_| {
                thread::sleep(Duration::from_micros(200));
                if thread::current().id() != caller {
                    by_helper.fetch_add(1, Relaxed);
                }
            });
        }
        assert!(by_helper.load(Relaxed) > 0, "the helper never took a block");
        // Idle for far longer than SPIN (polled, so that a slow machine only waits longer).
        let start = Instant::now();
        while !team.shared.parked[0].load(SeqCst) && start.elapsed() < Duration::from_secs(10) {
            thread::sleep(SPIN);
        }
        assert!(
            team.shared.parked[0].load(SeqCst),
            "an idle helper should park"
        );
        // And wakes for the next phase.
        check_every_block_runs_once(&team, 16);
    }

    #[test]
    fn a_block_panic_reaches_the_caller_and_the_team_still_works() {
        let team = Team::new(2);
        let result = panic::catch_unwind(AssertUnwindSafe(|| {
            team.run(32, &|b| {
                if b == 17 {
                    panic!("block 17");
                }
            })
        }));
        let payload = result.expect_err("the panic must reach the caller");
        assert_eq!(payload.downcast_ref::<&str>(), Some(&"block 17"));
        check_every_block_runs_once(&team, 32);
    }

    #[test]
    fn a_second_caller_runs_alone_rather_than_wait() {
        let team = Arc::new(Team::new(2));
        let threads: Vec<_> = (0..4)
            .map(|_| {
                let team = Arc::clone(&team);
                thread::spawn(move || {
                    for _ in 0..200 {
                        check_every_block_runs_once(&team, 40);
                    }
                })
            })
            .collect();
        for t in threads {
            t.join().unwrap();
        }
    }
}

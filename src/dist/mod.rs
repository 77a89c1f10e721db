//! Runs spread over several processes (ranks), e.g. under `mpirun -n N frfbayes-mpi ...`.
//!
//! Every rank runs the same command with the same arguments (SPMD): the same seed gives
//! the same proposals and the same task lists on every rank, and the ranks meet only in
//! collective calls of one small trait, [`Comm`] (gather every rank's bytes). On top of
//! it:
//!
//! - [`farm`]: independent tasks (benchmark cases, coverage campaigns, SBC replications,
//!   a diagnosis' evidence runs) dealt round-robin over the ranks and gathered on every
//!   rank, in task order; the results are the same whatever the number of ranks.
//! - `crate::mcmc::Ranks`: one posterior's walker evaluations spread over the ranks.
//!
//! Without MPI (the `frfbayes` binary, or a process not started by `mpirun`) the world is
//! one rank ([`Single`]) and everything runs in this process. The `frfbayes-mpi` binary
//! (package `mpi/`) installs the MPI world ([`install`]) before any command runs.
//!
//! Collectives are only ever made from the thread that installed the world, and never
//! inside a farmed task: there [`active`] is a single rank, so a task's own sampler or
//! nested farm runs in-process. As every rank follows the same code, every rank makes
//! that choice alike.
//!
//! Output: only world rank 0 ([`is_root`]) writes results; the other ranks compute.
//! Errors inside collectives are gathered, so every rank returns the same
//! [`Error::Distributed`] naming the rank that failed and why; a rank that fails outside
//! them cannot be waited for, and the binary aborts the whole run (no hang).

mod farm;

pub use farm::{farm, gather_results};

use crate::error::{Error, Result};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;
use std::thread::ThreadId;

/// A group of ranks that can exchange bytes collectively.
pub trait Comm: Send + Sync {
    /// This process' rank, `0..size()`.
    fn rank(&self) -> usize;
    /// Number of ranks.
    fn size(&self) -> usize;
    /// Every rank's `mine`, in rank order, on every rank. Collective: every rank must
    /// call it, in the same order.
    fn all_gather(&self, mine: &[u8]) -> Result<Vec<Vec<u8>>>;
    /// Ends every rank of the run with `code` (a rank failed where the others cannot
    /// be told).
    fn abort(&self, code: i32);
}

/// The world of one process: rank 0 of 1.
#[derive(Debug, Clone, Copy, Default)]
pub struct Single;

impl Comm for Single {
    fn rank(&self) -> usize {
        0
    }
    fn size(&self) -> usize {
        1
    }
    fn all_gather(&self, mine: &[u8]) -> Result<Vec<Vec<u8>>> {
        Ok(vec![mine.to_vec()])
    }
    fn abort(&self, code: i32) {
        std::process::exit(code)
    }
}

struct World {
    comm: Box<dyn Comm>,
    thread: ThreadId,
}

static WORLD: OnceLock<World> = OnceLock::new();
/// Farmed tasks running on this process (collectives are off while > 0).
static TASK_DEPTH: AtomicUsize = AtomicUsize::new(0);

/// Installs the world communicator (once per process, from the thread that will make
/// every collective call).
pub fn install(comm: Box<dyn Comm>) -> Result<()> {
    let world = World {
        comm,
        thread: std::thread::current().id(),
    };
    WORLD
        .set(world)
        .map_err(|_| Error::Usage("the world communicator is already installed".into()))
}

/// The world: every rank of the run ([`Single`] when none was installed).
pub fn world() -> &'static dyn Comm {
    match WORLD.get() {
        Some(w) => w.comm.as_ref(),
        None => &Single,
    }
}

/// World rank 0: the rank that writes outputs and reports.
pub fn is_root() -> bool {
    world().rank() == 0
}

/// The communicator collectives use here and now: the world on its own thread outside
/// farmed tasks, else this process alone.
pub fn active() -> &'static dyn Comm {
    match WORLD.get() {
        Some(w)
            if w.thread == std::thread::current().id()
                && TASK_DEPTH.load(Ordering::SeqCst) == 0 =>
        {
            w.comm.as_ref()
        }
        _ => &Single,
    }
}

/// Runs `f` as one farmed task: collectives inside it stay in this process.
pub(crate) fn as_task<T>(f: impl FnOnce() -> T) -> T {
    struct Depth;
    impl Drop for Depth {
        fn drop(&mut self) {
            TASK_DEPTH.fetch_sub(1, Ordering::SeqCst);
        }
    }
    TASK_DEPTH.fetch_add(1, Ordering::SeqCst);
    let _depth = Depth;
    f()
}

/// Waits until every rank of the active communicator gets here (e.g. after rank 0
/// wrote files that every rank reads next). Over several ranks, a rank's `Err(why)`
/// is returned on every rank as [`Error::Distributed`], naming it; in one process
/// this returns `Ok` and the caller keeps its own error.
pub fn barrier(mine: std::result::Result<(), String>) -> Result<()> {
    match active().size() {
        1 => Ok(()),
        _ => farm::all_ok(active(), mine),
    }
}

/// Rank 0's `value` on every rank of the active communicator (e.g. a list of tasks
/// that rank 0 decided from the files it owns). Collective.
pub fn from_root<T: serde::Serialize + serde::de::DeserializeOwned + Clone>(
    value: &T,
) -> Result<T> {
    let comm = active();
    if comm.size() == 1 {
        return Ok(value.clone());
    }
    let mine = [(0, Ok(value.clone()))];
    let all = gather_results::<T>(comm, if comm.rank() == 0 { &mine } else { &[] })?;
    match all.into_iter().next() {
        Some((0, (_, Ok(v)))) => Ok(v),
        _ => Err(Error::Distributed {
            rank: 0,
            size: comm.size(),
            what: "sent nothing to share".into(),
        }),
    }
}

/// The message of a caught panic.
pub(crate) fn panic_message(p: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        s.to_string()
    } else if let Some(s) = p.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic".to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn without_an_installed_world_everything_is_one_rank() {
        assert_eq!((world().rank(), world().size()), (0, 1));
        assert!(is_root());
        assert_eq!(active().size(), 1);
        assert_eq!(Single.all_gather(b"ab").unwrap(), vec![b"ab".to_vec()]);
        barrier(Ok(())).unwrap();
        barrier(Err("the caller reports this".into())).unwrap();
    }
}

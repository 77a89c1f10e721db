//! The MPI world: `MPI_COMM_WORLD` (the `mpi` crate on the system's MPI library) as
//! frfbayes' [`Comm`], installed before the command runs.

use frfbayes::dist::{install, Comm};
use frfbayes::{Error, Result};
use mpi::datatype::PartitionMut;
use mpi::environment::Universe;
use mpi::topology::SimpleCommunicator;
use mpi::traits::{Communicator, CommunicatorCollectives};
use mpi::Count;

/// `MPI_COMM_WORLD` as a [`Comm`].
struct MpiWorld {
    comm: SimpleCommunicator,
}

// SAFETY: the handle is only used for collectives from the thread that installed it
// (see `frfbayes::dist`); MPI is initialised with `MPI_THREAD_FUNNELED`, which allows
// exactly that, and `rank`/`size` are read once.
unsafe impl Send for MpiWorld {}
// SAFETY: as above.
unsafe impl Sync for MpiWorld {}

impl Comm for MpiWorld {
    fn rank(&self) -> usize {
        self.comm.rank() as usize
    }
    fn size(&self) -> usize {
        self.comm.size() as usize
    }
    fn all_gather(&self, mine: &[u8]) -> Result<Vec<Vec<u8>>> {
        let n = self.size();
        let len = Count::try_from(mine.len()).map_err(|_| {
            Error::Usage(format!(
                "{} bytes are too many for one MPI message",
                mine.len()
            ))
        })?;
        let mut counts: Vec<Count> = vec![0; n];
        self.comm.all_gather_into(&len, &mut counts[..]);
        let mut displs: Vec<Count> = Vec::with_capacity(n);
        let mut total: i64 = 0;
        for &c in &counts {
            displs.push(Count::try_from(total).map_err(|_| {
                Error::Usage("the gathered results exceed 2 GiB, MPI's message limit".into())
            })?);
            total += i64::from(c);
        }
        let mut buf = vec![0u8; total as usize];
        {
            let mut part = PartitionMut::new(&mut buf[..], &counts[..], &displs[..]);
            self.comm.all_gather_varcount_into(mine, &mut part);
        }
        Ok(counts
            .iter()
            .zip(&displs)
            .map(|(&c, &d)| buf[d as usize..(d + c) as usize].to_vec())
            .collect())
    }
    fn abort(&self, code: i32) {
        self.comm.abort(code)
    }
}

/// Keeps MPI initialised; finalises it when dropped (at the end of `main`).
pub struct Session {
    _universe: Universe,
}

/// True when this process was started by an MPI launcher (`mpirun`, `srun`): its
/// environment names a rank.
pub fn launched() -> bool {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "PMI_RANK"]
        .iter()
        .any(|v| std::env::var_os(v).is_some())
}

/// Initialises MPI and installs its world as [`frfbayes::dist::world`] when this process was
/// started by an MPI launcher; `None` otherwise (the run is one process).
pub fn init() -> Result<Option<Session>> {
    if !launched() {
        return Ok(None);
    }
    let (universe, _level) = mpi::initialize_with_threading(mpi::Threading::Funneled)
        .ok_or_else(|| Error::Usage("MPI was already initialised".into()))?;
    install(Box::new(MpiWorld {
        comm: universe.world(),
    }))?;
    Ok(Some(Session {
        _universe: universe,
    }))
}

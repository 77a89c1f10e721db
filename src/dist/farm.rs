//! Independent tasks dealt over the ranks: task `i` runs on rank `i mod N` in rounds of
//! `N` tasks; after every round each rank's outcomes (CBOR, every `f64` exact) are
//! gathered on every rank, so every rank ends with every result, in task order.

use super::{active, as_task, panic_message, Comm};
use crate::error::{Error, Result};
use serde::{de::DeserializeOwned, Serialize};

/// One task's outcome as it travels between ranks: its index, and its value or why it
/// failed.
type Outcome<T> = (usize, std::result::Result<T, String>);

/// Runs `task(0..n_tasks)` over the ranks of [`active`] and returns every result, in
/// task order, on every rank. After every round, `on_root` sees each new result on
/// rank 0 (e.g. to save it at once: a resumed run then skips it).
///
/// In one process this is a plain loop, errors passed on as they are. Over several
/// ranks a failed task (an error or a panic) ends the farm after its round, on every
/// rank, with [`Error::Distributed`] naming the rank, the task and why; the round's
/// other results still reach `on_root` first.
///
/// ```
/// let squares = frfbayes::dist::farm(4, |i| Ok(i * i), |_, _| Ok(())).unwrap();
/// assert_eq!(squares, vec![0, 1, 4, 9]);
/// ```
pub fn farm<T, F, D>(n_tasks: usize, mut task: F, mut on_root: D) -> Result<Vec<T>>
where
    T: Serialize + DeserializeOwned,
    F: FnMut(usize) -> Result<T>,
    D: FnMut(usize, &T) -> Result<()>,
{
    let comm = active();
    let (rank, size) = (comm.rank(), comm.size());
    let mut out = Vec::with_capacity(n_tasks);
    if size == 1 {
        for i in 0..n_tasks {
            let v = as_task(|| task(i))?;
            on_root(i, &v)?;
            out.push(v);
        }
        return Ok(out);
    }
    for first in (0..n_tasks).step_by(size) {
        let i = first + rank;
        let mine: Vec<Outcome<T>> = if i < n_tasks {
            let r = as_task(|| std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| task(i))));
            let r = match r {
                Ok(Ok(v)) => Ok(v),
                Ok(Err(e)) => Err(e.to_string()),
                Err(p) => Err(format!("panicked: {}", panic_message(p.as_ref()))),
            };
            vec![(i, r)]
        } else {
            Vec::new()
        };
        let mut failed = None;
        for (r, (i, res)) in gather_results(comm, &mine)? {
            match res {
                Ok(v) => {
                    if rank == 0 {
                        on_root(i, &v)?;
                    }
                    out.push(v);
                }
                Err(why) => {
                    failed.get_or_insert((r, format!("task {i}: {why}")));
                }
            }
        }
        if let Some((rank, what)) = failed {
            return Err(Error::Distributed { rank, size, what });
        }
    }
    Ok(out)
}

/// Gathers every rank's outcomes on every rank: `(rank, outcome)` in rank order, then
/// in each rank's order. Collective. A rank whose outcomes cannot be encoded sends
/// that as its failure.
pub fn gather_results<T: Serialize + DeserializeOwned>(
    comm: &dyn Comm,
    mine: &[Outcome<T>],
) -> Result<Vec<(usize, Outcome<T>)>> {
    let mut bytes = Vec::new();
    if let Err(e) = ciborium::into_writer(mine, &mut bytes) {
        bytes.clear();
        let fallback: Vec<Outcome<()>> = vec![(usize::MAX, Err(format!("cannot encode: {e}")))];
        ciborium::into_writer(&fallback, &mut bytes)
            .map_err(|e| Error::Numerical(format!("cannot encode a task's failure: {e}")))?;
    }
    let all = comm.all_gather(&bytes)?;
    let mut out = Vec::new();
    for (rank, b) in all.iter().enumerate() {
        match ciborium::from_reader::<Vec<Outcome<T>>, _>(b.as_slice()) {
            Ok(list) => out.extend(list.into_iter().map(|o| (rank, o))),
            Err(_) => {
                // The encoding fallback above (or a corrupted message).
                let why = ciborium::from_reader::<Vec<Outcome<()>>, _>(b.as_slice())
                    .ok()
                    .and_then(|l| l.into_iter().find_map(|(_, r)| r.err()))
                    .unwrap_or_else(|| "its results could not be decoded".into());
                out.push((rank, (usize::MAX, Err(why))));
            }
        }
    }
    Ok(out)
}

/// Every rank's `Ok(())`, or the first failure as [`Error::Distributed`].
pub(super) fn all_ok(comm: &dyn Comm, mine: std::result::Result<(), String>) -> Result<()> {
    for (rank, (_, r)) in gather_results::<()>(comm, &[(0, mine)])? {
        if let Err(what) = r {
            let size = comm.size();
            return Err(Error::Distributed { rank, size, what });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A world of `size` ranks where every rank sent the same bytes (enough to check
    /// the encoding and the failure reports).
    struct Echo(usize);

    impl Comm for Echo {
        fn rank(&self) -> usize {
            0
        }
        fn size(&self) -> usize {
            self.0
        }
        fn all_gather(&self, mine: &[u8]) -> Result<Vec<Vec<u8>>> {
            Ok(vec![mine.to_vec(); self.0])
        }
        fn abort(&self, _code: i32) {}
    }

    #[test]
    fn outcomes_travel_exactly_and_failures_name_their_rank() {
        let mine: Vec<Outcome<Vec<f64>>> = vec![
            (3, Ok(vec![0.1 + 0.2, f64::NAN, f64::NEG_INFINITY, 1e-310])),
            (5, Err("no convergence".into())),
        ];
        let all = gather_results(&Echo(2), &mine).unwrap();
        assert_eq!(all.len(), 4);
        assert_eq!(all[2].0, 1);
        let v = all[0].1 .1.as_ref().unwrap();
        assert_eq!(v[0].to_bits(), (0.1f64 + 0.2).to_bits());
        assert!(v[1].is_nan() && v[2] == f64::NEG_INFINITY && v[3] == 1e-310);
        assert_eq!(all[3].1, (5, Err("no convergence".to_string())));
        let e = all_ok(&Echo(3), Err("disk full".into())).unwrap_err();
        assert_eq!(e.to_string(), "rank 0 of 3 failed: disk full");
    }

    #[test]
    fn one_process_runs_in_order_and_passes_errors_on() {
        let mut seen = Vec::new();
        let v = farm(
            3,
            |i| Ok(10 * i),
            |i, v| {
                seen.push((i, *v));
                Ok(())
            },
        )
        .unwrap();
        assert_eq!(v, vec![0, 10, 20]);
        assert_eq!(seen, vec![(0, 0), (1, 10), (2, 20)]);
        let e = farm(
            3,
            |i| {
                if i == 1 {
                    Err(Error::Usage("bad".into()))
                } else {
                    Ok(i)
                }
            },
            |_, _| Ok(()),
        );
        assert_eq!(e.unwrap_err().to_string(), "bad");
    }
}

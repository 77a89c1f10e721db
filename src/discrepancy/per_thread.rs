//! One value per thread, kept with the key it was built for: the likelihood's kept
//! noise scales ([`super::posterior`]) and gain factors ([`super::gain_solve`]). A
//! least-squares fit holds the error floor fixed while it moves the model, so each
//! thread builds a value once per key and reuses it; the value is built by the same
//! expressions as before, so results are bit for bit those of building it anew.

use std::cell::RefCell;
use std::sync::atomic::{AtomicUsize, Ordering};
use thread_local::ThreadLocal;

/// Each thread's value at the last key it asked for. A clone starts empty.
pub(super) struct PerThread<K: Send, V: Send> {
    per_thread: ThreadLocal<RefCell<Option<(K, V)>>>,
    /// Values built so far (all threads).
    builds: AtomicUsize,
}

impl<K: Send, V: Send> Default for PerThread<K, V> {
    fn default() -> Self {
        PerThread {
            per_thread: ThreadLocal::new(),
            builds: AtomicUsize::new(0),
        }
    }
}

impl<K: Send, V: Send> Clone for PerThread<K, V> {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl<K: Send, V: Send> std::fmt::Debug for PerThread<K, V> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("PerThread")
    }
}

impl<K: Send, V: Send> PerThread<K, V> {
    /// `apply(value)` with this thread's value, built by `build` (for the key `key()`)
    /// unless the kept one's key satisfies `is_key`.
    pub(super) fn with<R>(
        &self,
        is_key: impl FnOnce(&K) -> bool,
        key: impl FnOnce() -> K,
        build: impl FnOnce() -> V,
        apply: impl FnOnce(&V) -> R,
    ) -> R {
        let cell = self.per_thread.get_or_default();
        let hit = cell.borrow().as_ref().is_some_and(|(k, _)| is_key(k));
        if !hit {
            self.builds.fetch_add(1, Ordering::Relaxed);
            let value = build();
            *cell.borrow_mut() = Some((key(), value));
        }
        let kept = cell.borrow();
        apply(&kept.as_ref().expect("filled above").1)
    }

    /// Values built so far, over all threads.
    #[cfg(test)]
    pub(super) fn builds(&self) -> usize {
        self.builds.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    #[test]
    fn a_value_is_built_once_per_thread_and_key() {
        let kept: PerThread<u64, Vec<u64>> = PerThread::default();
        let get = |k: u64| kept.with(|&c| c == k, || k, || vec![k; 3], |v| v.clone());
        assert_eq!(get(1), vec![1; 3]);
        assert_eq!(get(1), vec![1; 3]);
        assert_eq!(kept.builds(), 1);
        assert_eq!(get(2), vec![2; 3]);
        assert_eq!(get(1), vec![1; 3]);
        assert_eq!(kept.builds(), 3);
        // Threads keep their own; a clone starts empty.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let got: Vec<Vec<u64>> = pool.install(|| (0..8).into_par_iter().map(|_| get(5)).collect());
        assert!(got.iter().all(|v| v == &vec![5; 3]));
        // At most one build on each of the pool's two threads.
        assert!(kept.builds() <= 3 + 2, "{}", kept.builds());
        assert_eq!(kept.clone().builds(), 0);
    }
}

//! The order in which work is spread over the cores (issue 17): list scheduling, longest first.
//!
//! A campaign's work comes in pieces of very different lengths (a gear's sampling episode costs
//! about four times a cross's), and split evenly over the cores up front, as a parallel iterator
//! splits a list, the longest pieces can start last and leave the other cores idle at the end.
//! Here every thread takes the next piece not yet taken whenever it is free, in the order the
//! caller gives; sorted by estimated length, longest first, this is Graham's LPT rule, whose
//! schedule is at most 4/3 as long as the best one when the lengths are known (R. L. Graham,
//! "Bounds on multiprocessing timing anomalies", SIAM J. Appl. Math. 17, 1969). A thread with
//! nothing left to take helps the others' nested parallel work (a registration's restarts, a
//! build's downsampling).
//!
//! Only when work runs depends on the order, never what it computes: the campaign's results are
//! the same whatever it is.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// `f(item)` for every item of `items`, on every thread of the current rayon pool, started in
/// the order of `items` (see the module doc); the results in the order of `items`.
pub fn map_in_order<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let results: Vec<Mutex<Option<R>>> = items.iter().map(|_| Mutex::new(None)).collect();
    take_in_order(items.len(), |i| {
        let r = f(&items[i]);
        *results[i].lock().expect("no result writer panicked") = Some(r);
        true
    });
    results
        .into_iter()
        .map(|r| {
            r.into_inner()
                .expect("no result writer panicked")
                .expect("every item ran")
        })
        .collect()
}

/// `f(item)` for the items of `items` in the order given, as [`map_in_order`], until one fails:
/// no item is started after that, and the first error (in the order they happened) is returned.
pub fn try_in_order<T: Sync, E: Send>(
    items: &[T],
    f: impl Fn(&T) -> Result<(), E> + Sync,
) -> Result<(), E> {
    let first_error = Mutex::new(None);
    take_in_order(items.len(), |i| match f(&items[i]) {
        Ok(()) => true,
        Err(e) => {
            first_error
                .lock()
                .expect("no error writer panicked")
                .get_or_insert(e);
            false
        }
    });
    match first_error.into_inner().expect("no error writer panicked") {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// Runs `run(0)`, `run(1)`, ... `run(count - 1)`, each once, on every thread of the current rayon
/// pool: a free thread takes the next index. Once a call returns `false`, no index is taken after
/// it (the calls running finish).
fn take_in_order(count: usize, run: impl Fn(usize) -> bool + Sync) {
    let next = AtomicUsize::new(0);
    let stopped = AtomicBool::new(false);
    let worker = || {
        while !stopped.load(Ordering::SeqCst) {
            let i = next.fetch_add(1, Ordering::SeqCst);
            if i >= count {
                return;
            }
            if !run(i) {
                stopped.store(true, Ordering::SeqCst);
            }
        }
    };
    let threads = rayon::current_num_threads().min(count);
    rayon::scope(|s| {
        for _ in 0..threads {
            s.spawn(|_| worker());
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicUsize;

    fn pool(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
    }

    #[test]
    fn every_item_runs_once_and_the_results_keep_the_items_order() {
        let items: Vec<u64> = (0..100).collect();
        for threads in [1, 3] {
            let runs = AtomicUsize::new(0);
            let out = pool(threads).install(|| {
                map_in_order(&items, |x| {
                    runs.fetch_add(1, Ordering::SeqCst);
                    x * x
                })
            });
            assert_eq!(runs.load(Ordering::SeqCst), 100);
            assert_eq!(out, items.iter().map(|x| x * x).collect::<Vec<_>>());
        }
    }

    #[test]
    fn items_start_in_the_order_given() {
        // One thread takes them strictly in order; with more, each starts no later than the
        // items after it (the start order is the list order).
        for threads in [1, 4] {
            let started = Mutex::new(Vec::new());
            let items: Vec<usize> = (0..50).collect();
            pool(threads).install(|| {
                map_in_order(&items, |&i| started.lock().unwrap().push(i));
            });
            let started = started.into_inner().unwrap();
            let mut sorted = started.clone();
            sorted.sort();
            assert_eq!(sorted, items);
            if threads == 1 {
                assert_eq!(started, items);
            }
        }
    }

    #[test]
    fn after_an_error_no_item_starts_and_the_error_is_returned() {
        let items: Vec<usize> = (0..1000).collect();
        let failing = |runs: &AtomicUsize, i: usize| {
            runs.fetch_add(1, Ordering::SeqCst);
            if i == 10 {
                Err(format!("item {i}"))
            } else {
                Ok(())
            }
        };
        // One thread: the items before the error and the error's own, then none.
        let runs = AtomicUsize::new(0);
        let out = pool(1).install(|| try_in_order(&items, |&i| failing(&runs, i)));
        assert_eq!(out, Err("item 10".to_string()));
        assert_eq!(runs.load(Ordering::SeqCst), 11);
        // Two: the other thread may run on while the error is being returned, but the error is
        // the one returned.
        let runs = AtomicUsize::new(0);
        let out = pool(2).install(|| try_in_order(&items, |&i| failing(&runs, i)));
        assert_eq!(out, Err("item 10".to_string()));
        let none: Vec<usize> = Vec::new();
        assert_eq!(try_in_order(&none, |_| Err::<(), ()>(())), Ok(()));
    }
}

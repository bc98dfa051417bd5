//! The diagnosis's independent re-solves (the four edges of the boundary family, the mirror
//! images of a finding) on every core: each is one sparse factorisation and eigen-solve,
//! single-threaded inside, so they scale over threads.

use std::sync::atomic::{AtomicUsize, Ordering};

use crate::sim::error::SimError;

/// `f` over `items` on up to the machine's cores, results in the items' order; the first error
/// wins. A worker that panics is reported as an error, not propagated.
pub fn parallel_map<T, R, F>(items: Vec<T>, f: F) -> Result<Vec<R>, SimError>
where
    T: Send,
    R: Send,
    F: Fn(T) -> Result<R, SimError> + Sync,
{
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(items.len())
        .max(1);
    let slots: Vec<std::sync::Mutex<Option<T>>> = items
        .into_iter()
        .map(|t| std::sync::Mutex::new(Some(t)))
        .collect();
    let next = AtomicUsize::new(0);
    let mut out: Vec<Option<Result<R, SimError>>> = (0..slots.len()).map(|_| None).collect();
    let done: Vec<Vec<(usize, Result<R, SimError>)>> = std::thread::scope(|sc| {
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                sc.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let k = next.fetch_add(1, Ordering::Relaxed);
                        let Some(slot) = slots.get(k) else { break };
                        let item = slot
                            .lock()
                            .map(|mut g| g.take())
                            .ok()
                            .flatten()
                            .expect("each item is taken once");
                        mine.push((k, f(item)));
                    }
                    mine
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join().unwrap_or_else(|_| {
                    vec![(
                        usize::MAX,
                        Err(SimError::Eigen("a diagnosis worker panicked".into())),
                    )]
                })
            })
            .collect()
    });
    for (k, r) in done.into_iter().flatten() {
        if k == usize::MAX {
            return Err(r.err().unwrap_or(SimError::Eigen("worker".into())));
        }
        out[k] = Some(r);
    }
    out.into_iter()
        .map(|r| r.unwrap_or_else(|| Err(SimError::Eigen("a diagnosis item was lost".into()))))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_keep_their_order_and_errors_surface() {
        let squares = parallel_map((0..17).collect(), |i: usize| Ok(i * i)).unwrap();
        assert_eq!(squares, (0..17).map(|i| i * i).collect::<Vec<_>>());
        let failed = parallel_map(vec![1, 2, 3], |i: i32| {
            if i == 2 {
                Err(SimError::Eigen("two".into()))
            } else {
                Ok(i)
            }
        });
        assert!(failed.is_err());
    }
}

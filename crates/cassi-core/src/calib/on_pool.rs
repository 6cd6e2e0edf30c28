//! A calibration runs on one of rayon's worker threads, its stage reports
//! handed back to the calling thread.
//!
//! Why: a calibration is thousands of short parallel loops (a 256² case
//! scores ~1100 candidates, each a few loops over rows or bands of 0.1–1
//! ms). Started from a thread outside the pool, every loop is injected
//! into the pool and the caller sleeps until a worker wakes it — two
//! cross-thread wake-ups per loop, each tens of microseconds on a VM. On a
//! worker the loop splits in place and the worker never sleeps. The answers
//! do not depend on which thread runs what (every parallel loop writes
//! disjoint rows or bands; nothing sums across threads), so they are
//! bitwise the same; the benchmark's 256² cases take 0.92 of their time on
//! the 2-core EPYC VM (per-case ratio, two sittings;
//! `bench/results/calibrate_physical_timing_stop64/`).
//!
//! The caller's `on_stage` stays on the caller's thread (it need not be
//! `Send`: a command line's progress display, a Python callback): the
//! worker sends each report back and the caller hands it on as it comes,
//! in order.

use std::sync::mpsc;

use super::StageReport;

/// What the worker sends back.
enum Message<T> {
    Stage(StageReport),
    Done(T),
}

/// `work(report)` on a rayon worker (inline when this thread is one
/// already), every report it makes handed to `on_stage` on this thread.
pub(crate) fn on_pool<T: Send>(
    work: impl FnOnce(&mut dyn FnMut(&StageReport)) -> T + Send,
    on_stage: &mut dyn FnMut(&StageReport),
) -> T {
    if rayon::current_thread_index().is_some() {
        return work(on_stage);
    }
    let answer = rayon::in_place_scope(|scope| {
        let (tx, rx) = mpsc::channel();
        scope.spawn(move |_| {
            let stages = tx.clone();
            let out = work(&mut |s: &StageReport| {
                // a caller that stopped listening has what it wanted
                let _ = stages.send(Message::Stage(s.clone()));
            });
            let _ = tx.send(Message::Done(out));
        });
        // ends early only if the work panicked (the scope then resumes
        // that panic) — its senders are dropped either way
        for message in rx {
            match message {
                Message::Stage(s) => on_stage(&s),
                Message::Done(out) => return Some(out),
            }
        }
        None
    });
    answer.expect("the calibration's worker ended without an answer and without a panic")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::Mismatch;

    fn report(name: &str) -> StageReport {
        StageReport {
            name: name.into(),
            evaluations: 1,
            seconds: 0.0,
            parameters: Mismatch::nominal(2.0),
            score: 0.0,
            passed_over: None,
        }
    }

    /// From outside the pool the work runs on a worker and the reports
    /// reach the caller's own thread, in order; from a worker it runs
    /// inline, on that thread.
    #[test]
    fn the_work_runs_on_a_worker_and_the_reports_come_back_in_order() {
        let caller = std::thread::current().id();
        let mut seen = Vec::new();
        let mut on_stage = |s: &StageReport| {
            assert_eq!(std::thread::current().id(), caller, "reports on the caller");
            seen.push(s.name.clone());
        };
        let worker = on_pool(
            |send| {
                for name in ["first", "second", "third"] {
                    send(&report(name));
                }
                rayon::current_thread_index()
            },
            &mut on_stage,
        );
        assert!(worker.is_some(), "the work ran on a worker");
        assert_eq!(seen, ["first", "second", "third"]);

        let (same_thread, reports) = rayon::scope(|_| {
            let here = std::thread::current().id();
            let mut count = 0;
            let ran_on = on_pool(
                |send| {
                    send(&report("only"));
                    std::thread::current().id()
                },
                &mut |_| count += 1,
            );
            (here == ran_on, count)
        });
        assert!(same_thread && reports == 1);
    }

    /// A panic in the work reaches the caller, the reports before it
    /// delivered.
    #[test]
    fn a_panic_in_the_work_reaches_the_caller() {
        let mut seen = 0;
        let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            on_pool(
                |send| {
                    send(&report("before"));
                    panic!("the work failed")
                },
                &mut |_| seen += 1,
            )
        }));
        assert!(out.is_err(), "the panic was lost");
        assert_eq!(seen, 1);
    }
}

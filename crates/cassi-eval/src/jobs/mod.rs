//! Whole jobs a front end runs (`cassi eval`, `cassi demo`, a simulation
//! written with its sidecar): a plan in, files and values out. The jobs print
//! nothing; what a person should see (stages, progress, lines of results,
//! warnings) and where a signal may end the work go through a
//! [`JobObserver`], which the command line turns into spinners and text and
//! another front end into whatever it shows.

pub mod demo;
pub mod eval;
pub mod simulation;

use std::time::Instant;

/// What a job reports while it runs. Every method has a silent default.
pub trait JobObserver {
    /// A named stage of work begins (a front end may show a spinner).
    fn stage_started(&mut self, _label: &str) {}
    /// The stage that began last ended; `ok` is false when it failed.
    fn stage_finished(&mut self, _label: &str, _seconds: f64, _ok: bool) {}
    /// A counted piece of work of `total` steps begins.
    fn progress_started(&mut self, _label: &str, _total: u64) {}
    /// `done` of the current counted piece's steps are done.
    fn progress(&mut self, _done: u64) {}
    /// The counted piece ended.
    fn progress_finished(&mut self) {}
    /// A line of results a person should see as it comes.
    fn say(&mut self, _line: &str) {}
    /// Something accepted that the user should know about.
    fn warn(&mut self, _text: &str) {}
    /// Called between units of work when nothing is half-written; an error
    /// ends the job there (its files are left as they were).
    fn checkpoint(&mut self) -> anyhow::Result<()> {
        Ok(())
    }
    /// The same point inside callbacks that cannot return an error (study
    /// events, calibration stages): a front end that must stop may end the
    /// process here (its temporaries removed) or note the request for the
    /// next [`checkpoint`](Self::checkpoint).
    fn stop_point(&mut self) {}
}

/// Runs `work` as one stage of `observer`.
pub fn stage<T>(
    observer: &mut dyn JobObserver,
    label: &str,
    work: impl FnOnce(&mut dyn JobObserver) -> anyhow::Result<T>,
) -> anyhow::Result<T> {
    observer.stage_started(label);
    let t0 = Instant::now();
    let out = work(observer);
    observer.stage_finished(label, t0.elapsed().as_secs_f64(), out.is_ok());
    out
}

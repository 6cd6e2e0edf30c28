//! The library's jobs seen on the command line: stages and progress bars on
//! stderr, result lines on stdout, and a signal ending the job between units
//! of work (see [`crate::interrupt`]).

use cassi_eval::jobs::JobObserver;

use crate::interrupt;
use crate::report::{Progress, Reporter};

/// A [`JobObserver`] that shows a job through the CLI's [`Reporter`].
pub struct CliObserver<'a> {
    reporter: &'a Reporter,
    bar: Option<Progress>,
}

impl<'a> CliObserver<'a> {
    pub fn new(reporter: &'a Reporter) -> Self {
        Self {
            reporter,
            bar: None,
        }
    }
}

impl JobObserver for CliObserver<'_> {
    fn stage_started(&mut self, label: &str) {
        self.reporter.begin_stage(label);
    }
    fn stage_finished(&mut self, label: &str, seconds: f64, ok: bool) {
        self.reporter.end_stage(label, seconds, ok);
    }
    fn progress_started(&mut self, label: &str, total: u64) {
        self.bar = Some(self.reporter.progress(label, total));
    }
    fn progress(&mut self, done: u64) {
        if let Some(bar) = &self.bar {
            bar.set(done);
        }
    }
    fn progress_finished(&mut self) {
        self.bar = None;
    }
    fn say(&mut self, line: &str) {
        self.reporter.say(line);
    }
    fn warn(&mut self, text: &str) {
        self.reporter.warn(text);
    }
    fn checkpoint(&mut self) -> anyhow::Result<()> {
        interrupt::check()
    }
    fn stop_point(&mut self) {
        interrupt::stop_point();
    }
}

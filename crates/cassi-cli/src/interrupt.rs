//! Ctrl-C and termination: SIGINT, SIGTERM (and SIGHUP) set a process-wide
//! cancel flag. Iterative work looks at it — solver observers stop, the
//! commands check it between stages and before committing their outputs —
//! and the command ends with an "interrupted" error; dropping its output set
//! removes its temporaries and leaves the previous outputs as they were.
//! Exit code 130.
//!
//! Work that cannot look at the flag (a calibration stage, a network's
//! forward pass) is not waited for long: a second signal, or [`GRACE`] after
//! the first, removes every temporary file this process has registered
//! ([`cassi_io::remove_temporaries_for_exit`], which waits for a commit in
//! progress) and exits with 130 at once. Callbacks that cannot return an
//! error call [`stop_point`], which does the same when the flag is set.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

use cassi_core::solvers::Control;

/// How long after the first signal the process exits even if the work has
/// not stopped by itself.
pub const GRACE: Duration = Duration::from_secs(2);

/// The exit code of an interrupted run (128 + SIGINT, the shell convention).
pub const EXIT_CODE: u8 = 130;

static CANCELLED: AtomicBool = AtomicBool::new(false);
static SIGNALS: AtomicUsize = AtomicUsize::new(0);

/// The error a command returns when it stopped because of a signal.
#[derive(Debug)]
pub struct Interrupted;

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("interrupted; the previous outputs (if any) were left as they were")
    }
}

impl std::error::Error for Interrupted {}

/// Installs the handler (once, at start-up).
pub fn install() {
    // failing to install leaves the default behaviour (the process dies and
    // the next run removes its temporaries): not worth refusing to run
    let _ = ctrlc::set_handler(on_signal);
}

fn on_signal() {
    if SIGNALS.fetch_add(1, Ordering::SeqCst) > 0 {
        exit_now();
    }
    CANCELLED.store(true, Ordering::SeqCst);
    eprintln!("\ninterrupted: stopping (again to quit at once)");
    std::thread::spawn(|| {
        std::thread::sleep(GRACE);
        exit_now();
    });
}

/// Removes this process's temporaries and exits with [`EXIT_CODE`].
pub fn exit_now() -> ! {
    cassi_io::remove_temporaries_for_exit();
    eprintln!("error: {Interrupted}");
    std::process::exit(EXIT_CODE.into())
}

/// Whether a signal asked the process to stop.
pub fn cancelled() -> bool {
    CANCELLED.load(Ordering::SeqCst)
}

/// An [`Interrupted`] error once a signal came.
pub fn check() -> anyhow::Result<()> {
    if cancelled() {
        return Err(Interrupted.into());
    }
    Ok(())
}

/// For solver observers: stop iterating once a signal came.
pub fn control() -> Control {
    if cancelled() {
        Control::Stop
    } else {
        Control::Continue
    }
}

/// For callbacks that cannot return an error (calibration stages, study
/// events), called between units of work when nothing is half-written:
/// exits at once (temporaries removed) once a signal came.
pub fn stop_point() {
    if cancelled() {
        exit_now();
    }
}

/// Whether `e` is (or wraps) an interrupt.
pub fn is_interrupt(e: &anyhow::Error) -> bool {
    e.downcast_ref::<Interrupted>().is_some() || cancelled()
}

//! How the CLI talks to a person or a script: stage timings and spinners on
//! stderr for people, one JSON object on stdout with `--json`, nothing but
//! errors with `--quiet`.

use std::io::IsTerminal;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

pub struct Reporter {
    quiet: bool,
    json: bool,
    interactive: bool,
    active: std::cell::RefCell<Option<ProgressBar>>,
}

impl Reporter {
    pub fn new(quiet: bool, json: bool) -> Self {
        Self {
            quiet,
            json,
            interactive: !quiet && std::io::stderr().is_terminal(),
            active: std::cell::RefCell::new(None),
        }
    }

    pub fn json(&self) -> bool {
        self.json
    }

    /// Runs `work`, showing a spinner while it runs (on a terminal) and its
    /// duration after, on stderr.
    pub fn stage<T>(
        &self,
        label: &str,
        work: impl FnOnce() -> anyhow::Result<T>,
    ) -> anyhow::Result<T> {
        self.begin_stage(label);
        let t0 = Instant::now();
        let out = work();
        self.end_stage(label, t0.elapsed().as_secs_f64(), out.is_ok());
        out
    }

    /// Shows the spinner of a stage that begins (on a terminal).
    pub fn begin_stage(&self, label: &str) {
        if self.interactive {
            let bar = ProgressBar::new_spinner();
            bar.set_style(
                ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("static template"),
            );
            bar.set_message(label.to_string());
            bar.enable_steady_tick(Duration::from_millis(100));
            *self.active.borrow_mut() = Some(bar);
        }
    }

    /// Clears the stage's spinner and, when it succeeded, prints its time.
    pub fn end_stage(&self, label: &str, seconds: f64, ok: bool) {
        self.clear();
        if ok && !self.quiet {
            eprintln!("  {label:<36} {seconds:>8.2} s");
        }
    }

    /// A progress bar over `len` steps (iterations), shown on a terminal only;
    /// the returned closure advances it and the bar is cleared on drop.
    pub fn progress(&self, label: &str, len: u64) -> Progress {
        let bar = if self.interactive {
            let bar = ProgressBar::new(len);
            bar.set_style(
                ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} {elapsed} (ETA {eta})")
                    .expect("static template")
                    .progress_chars("=> "),
            );
            bar.set_message(label.to_string());
            Some(bar)
        } else {
            None
        };
        Progress { bar }
    }

    /// Removes any spinner (before printing an error).
    pub fn clear(&self) {
        if let Some(bar) = self.active.borrow_mut().take() {
            bar.finish_and_clear();
        }
    }

    /// Human-readable result text on stdout (not with --quiet or --json).
    pub fn say(&self, text: &str) {
        if !self.quiet && !self.json {
            println!("{}", terminal_text(text));
        }
    }

    /// A warning on stderr (not with --quiet): something accepted that the
    /// user should know about.
    pub fn warn(&self, text: &str) {
        if !self.quiet {
            self.clear();
            eprintln!("warning: {}", terminal_text(text));
        }
    }

    /// The machine-readable result on stdout, with --json.
    pub fn emit(&self, value: &serde_json::Value) {
        if self.json {
            println!(
                "{}",
                serde_json::to_string_pretty(value).unwrap_or_else(|_| value.to_string())
            );
        }
    }
}

/// A progress bar handle (a no-op when not on a terminal).
pub struct Progress {
    bar: Option<ProgressBar>,
}

impl Progress {
    pub fn set(&self, pos: u64) {
        if let Some(bar) = &self.bar {
            bar.set_position(pos);
        }
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}

/// `text` as it may reach a terminal: control and text-direction characters
/// (an ESC in a file or path name, say) shown escaped, line breaks kept.
pub fn terminal_text(text: &str) -> String {
    text.split('\n')
        .map(|line| cassi_io::esc(line))
        .collect::<Vec<_>>()
        .join("\n")
}

#[cfg(test)]
mod tests {
    use super::terminal_text;

    #[test]
    fn escapes_reach_the_terminal_as_text_and_lines_stay_lines() {
        assert_eq!(
            terminal_text("a\u{1b}[31mred\nnext"),
            "a\\u{1b}[31mred\nnext"
        );
    }
}

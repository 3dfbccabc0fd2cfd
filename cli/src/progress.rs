//! Progress on stderr for the commands that can take more than a second on a
//! large survey (`import`, `export`, `process`, `model-gap`, `report`) or
//! on an instrument that does not answer (`check`); `run` and `resume` draw
//! their own bar of targets in `session`. Drawn only when
//! stderr is a terminal and the command was not asked for `--json`, so
//! scripts, pipes and tests see nothing; cleared when the work ends or fails.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::time::Duration;

/// Whether to draw: stderr is a terminal and the output is not `--json`.
pub fn visible(json: bool) -> bool {
    use std::io::IsTerminal as _;
    !json && std::io::stderr().is_terminal()
}

/// A spinner with a message of what is being done and the time elapsed.
#[derive(Debug)]
pub struct Progress {
    bar: ProgressBar,
}

impl Progress {
    /// A spinner saying `what`, drawn when `show`.
    pub fn spinner(what: impl Into<String>, show: bool) -> Self {
        let bar = ProgressBar::with_draw_target(None, Self::target(show));
        bar.set_style(ProgressStyle::with_template("{spinner} {msg} ({elapsed})").expect("valid template"));
        bar.set_message(what.into());
        if show {
            bar.enable_steady_tick(Duration::from_millis(120));
        }
        Self { bar }
    }

    fn target(show: bool) -> ProgressDrawTarget {
        if show { ProgressDrawTarget::stderr() } else { ProgressDrawTarget::hidden() }
    }

    /// Say what is being done now.
    pub fn stage(&self, what: impl Into<String>) {
        self.bar.set_message(what.into());
    }

    /// Whether it is drawn.
    pub fn is_drawn(&self) -> bool {
        !self.bar.is_hidden()
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hidden_for_json_and_when_asked() {
        // The test harness's stderr is not a terminal under `cargo test` in CI;
        // whatever it is, --json hides the bar.
        assert!(!visible(true));
        let p = Progress::spinner("working", false);
        p.stage("still working");
        assert!(!p.is_drawn());
    }
}

//! The diagnosis's progress bar on standard error (hidden unless asked for).

use indicatif::{ProgressBar, ProgressStyle};

/// Progress over the candidate effects.
pub struct Progress(ProgressBar);

impl Progress {
    /// A bar over `n` candidate effects, drawn when `show` is set.
    pub fn candidates(show: bool, n: usize) -> Self {
        let bar = if show {
            ProgressBar::new(n as u64)
        } else {
            ProgressBar::hidden()
        };
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} candidate effects {msg}",
            )
            .expect("valid template"),
        );
        Self(bar)
    }

    /// A spinner while one long step runs (`what`), drawn when `show` is set.
    pub fn step(show: bool, what: &str) -> Self {
        let bar = if show {
            ProgressBar::new_spinner()
        } else {
            ProgressBar::hidden()
        };
        bar.set_style(
            ProgressStyle::with_template("{spinner} [{elapsed_precise}] {msg}")
                .expect("valid template"),
        );
        bar.set_message(what.to_string());
        if show {
            bar.enable_steady_tick(std::time::Duration::from_millis(200));
        }
        Self(bar)
    }

    /// One more candidate fitted, `name` the last one.
    pub fn done(&self, name: &str) {
        self.0.inc(1);
        self.0.set_message(name.to_string());
    }

    /// Clear the bar.
    pub fn finish(&self) {
        self.0.finish_and_clear();
    }
}

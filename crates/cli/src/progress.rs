//! A spinner on stderr for the commands' long phases (`calibrate --cell`, `calibrate POINTS.csv`,
//! `plan`, `import`, `fk --q-csv`):
//! the phase's name and the elapsed time, cleared when the command is done. Shown only when
//! stderr is a terminal and, for the commands that print a report, the output is not `--json`
//! (scripts and captures see the report alone), like `sim-cell sweep`'s progress bar; the commands
//! whose output is data (`calibrate POINTS.csv`, `fk --q-csv`) show it under `--json` too, since
//! their stdout is a file or a pipe and stderr stays free.

use std::borrow::Cow;
use std::io::IsTerminal;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// How often the spinner redraws.
const TICK: Duration = Duration::from_millis(120);

/// A spinner naming the current phase ([`Progress::phase`]); hidden unless [`shown`].
pub(crate) struct Progress {
    bar: ProgressBar,
}

/// Whether progress is shown: stderr is a terminal and the command prints text, not `--json`.
pub(crate) fn shown(json: bool) -> bool {
    !json && std::io::stderr().is_terminal()
}

impl Progress {
    /// A spinner at `phase`, drawn on stderr when `show` (see [`shown`]), else never drawn.
    pub(crate) fn new(show: bool, phase: impl Into<Cow<'static, str>>) -> Self {
        let target = if show {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        };
        let bar = ProgressBar::with_draw_target(None, target);
        bar.set_style(
            ProgressStyle::with_template("{spinner} {msg} [{elapsed}]")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        bar.set_message(phase);
        if show {
            bar.enable_steady_tick(TICK);
        }
        Self { bar }
    }

    /// The next phase's name.
    pub(crate) fn phase(&self, phase: impl Into<Cow<'static, str>>) {
        self.bar.set_message(phase);
    }

    /// Prints `line` on stderr with the spinner moved out of its way (drawn again below it).
    pub(crate) fn eprintln(&self, line: &str) {
        self.bar.suspend(|| eprintln!("{line}"));
    }

    /// Clears the spinner (before the report is printed).
    pub(crate) fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

impl Drop for Progress {
    /// An error return clears the spinner too, so the error starts on a clean line.
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

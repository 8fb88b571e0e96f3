//! What standard error is connected to, and the people-facing output that depends on it:
//! coloured diagnostics and progress bars, both only on a terminal.
//!
//! [`super::run_with`] records the [`Terminal`] for the duration of one command; [`super::run`]
//! (the form tests call, writing into buffers) uses [`Terminal::default`]: no colour, no
//! progress.

use std::cell::Cell;
use std::io::IsTerminal;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// How people-facing output looks on the process's standard error.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Terminal {
    /// Diagnostics in colour.
    pub color: bool,
    /// Progress bars for long analyses, sweeps and builds.
    pub progress: bool,
}

impl Terminal {
    /// Both when standard error is a terminal; no colour when `NO_COLOR` is set to anything
    /// but the empty string (<https://no-color.org>).
    #[must_use]
    pub fn detect() -> Self {
        let tty = std::io::stderr().is_terminal();
        let no_color = std::env::var_os("NO_COLOR").is_some_and(|v| !v.is_empty());
        Self { color: tty && !no_color, progress: tty }
    }
}

thread_local! {
    static CURRENT: Cell<Terminal> = const { Cell::new(Terminal { color: false, progress: false }) };
}

/// Runs `f` with `terminal` as the current setting, then restores the previous one.
pub(super) fn with<R>(terminal: Terminal, f: impl FnOnce() -> R) -> R {
    let previous = CURRENT.with(|c| c.replace(terminal));
    let result = f();
    CURRENT.with(|c| c.set(previous));
    result
}

/// The current setting.
pub(super) fn current() -> Terminal {
    CURRENT.with(Cell::get)
}

/// A progress bar over `len` items on standard error, or a hidden one when progress is off.
pub(super) fn bar(len: u64, message: &str) -> ProgressBar {
    if !current().progress {
        return ProgressBar::hidden();
    }
    let style =
        ProgressStyle::with_template("{msg:>12} [{bar:32}] {human_pos}/{human_len} eta {eta}")
            .map_or_else(|_| ProgressStyle::default_bar(), |s| s.progress_chars("=> "));
    ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr())
        .with_style(style)
        .with_message(message.to_owned())
}

/// A spinner with a message on standard error, or a hidden one when progress is off.
pub(super) fn spinner(message: &str) -> ProgressBar {
    if !current().progress {
        return ProgressBar::hidden();
    }
    let style = ProgressStyle::with_template("{spinner} {msg} ({elapsed})")
        .unwrap_or_else(|_| ProgressStyle::default_spinner());
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr())
        .with_style(style)
        .with_message(message.to_owned());
    bar.enable_steady_tick(Duration::from_millis(120));
    bar
}

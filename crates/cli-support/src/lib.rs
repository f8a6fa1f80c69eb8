#![doc = include_str!("../README.md")]

pub mod cell_report;
pub mod controllers;
pub mod do_no_harm;
pub mod export_dir;
pub mod points;
pub mod result_check;
pub mod validate;

/// Ends the process quietly with exit 0 when printing fails because stdout was closed early
/// (`handclasp … | head`, `sim-cell … | head`): the reader has what it wanted, so no broken-pipe
/// panic (exit 101). Every other panic goes to the default hook. (`print!` panics on a failed write; SIGPIPE stays ignored,
/// as Rust sets it, so the write error is what is seen here.)
pub fn exit_quietly_on_broken_pipe() {
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.starts_with("failed printing to stdout")
            && message.to_ascii_lowercase().contains("broken pipe")
        {
            std::process::exit(0);
        }
        default_hook(info);
    }));
}

/// The text of an error and its causes (`source()` chain), joined by `": "` as anyhow's `{:#}`
/// joins them, but skipping a cause whose text the message already holds. Library errors that name
/// their I/O error in their own text (`"{path}: {source}"`) also return it as their source, so
/// `{:#}` would print "No such file or directory (os error 2)" twice.
///
/// ```
/// use std::io;
/// #[derive(Debug)]
/// struct ReadFailed(io::Error);
/// impl std::fmt::Display for ReadFailed {
///     fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
///         write!(f, "a.csv: {}", self.0)
///     }
/// }
/// impl std::error::Error for ReadFailed {
///     fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
///         Some(&self.0)
///     }
/// }
/// let e = ReadFailed(io::Error::new(io::ErrorKind::NotFound, "not found"));
/// assert_eq!(cli_support::error_chain_text(&e), "a.csv: not found");
/// ```
pub fn error_chain_text(err: &(dyn std::error::Error + 'static)) -> String {
    let mut text = err.to_string();
    let mut cause = err.source();
    while let Some(c) = cause {
        let part = c.to_string();
        if !text.contains(&part) {
            text.push_str(": ");
            text.push_str(&part);
        }
        cause = c.source();
    }
    text
}

#[cfg(test)]
mod tests {
    use super::error_chain_text;

    /// A cause that the message does not hold is kept; one it holds is not repeated.
    #[test]
    fn chain_text_keeps_new_causes_and_drops_repeated_ones() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let repeated = anyhow::Error::new(io).context("a.csv: no such file");
        assert_eq!(error_chain_text(repeated.as_ref()), "a.csv: no such file");
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let kept = anyhow::Error::new(io).context("a.csv").context("--session");
        assert_eq!(
            error_chain_text(kept.as_ref()),
            "--session: a.csv: no such file"
        );
        assert_eq!(format!("{kept:#}"), error_chain_text(kept.as_ref()));
    }
}

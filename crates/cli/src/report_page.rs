//! What `calibrate --cell … --report` and `diagnose … --report` share at the process edge: the
//! command line and version the page shows, and writing the page.

use std::path::Path;

use anyhow::Context;
use report::Invocation;

/// This process's command line (each argument quoted when it holds a space or a quote) and
/// the program's version.
pub fn invocation() -> Invocation {
    let quote = |a: String| {
        if a.is_empty() || a.contains([' ', '"', '\'', '\t']) {
            format!("'{}'", a.replace('\'', r"'\''"))
        } else {
            a
        }
    };
    Invocation {
        command_line: std::env::args().map(quote).collect::<Vec<_>>().join(" "),
        version: format!("handclasp {}", env!("CARGO_PKG_VERSION")),
    }
}

/// Writes `html` to `path` (`--report`), replacing a file of that name.
pub fn write(path: &Path, html: &str) -> anyhow::Result<()> {
    handclasp_cell::output::write_atomically(path, html.as_bytes()).with_context(|| {
        format!(
            "--report {}: cannot write the page (check that its folder exists and is writable)",
            path.display()
        )
    })
}

/// Prints a `warning:` line on stderr for each work point of `w` that was not predicted.
pub fn warn_unreachable(w: &report::WorkSiteReport) {
    for line in report::unreachable_lines(w) {
        eprintln!("warning: {line}");
    }
}

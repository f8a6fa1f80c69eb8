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
    for u in &w.unreachable {
        eprintln!(
            "warning: work point row {} ({:.1}, {:.1}, {:.1} mm) is not predicted: {}",
            u.row, u.p_b1_mm[0], u.p_b1_mm[1], u.p_b1_mm[2], u.why
        );
    }
}

/// The text lines of a verdict at the work site: the prediction, the placement's rotation
/// error (which figure it is, and the marginal one when it differs), then `verdict: …`.
pub fn work_site_text(w: &report::WorkSiteReport) -> String {
    let rotation = match &w.placement_rotation {
        Some(r) => {
            let marginal = if r.conditional_on.is_empty() {
                String::new()
            } else {
                format!(
                    "; marginal (their prior included): rms {:.4}°, p95 {:.4}°",
                    r.marginal.rms_deg, r.marginal.p95_deg
                )
            };
            format!(
                "placement rotation error: rms {:.4}°, p95 {:.4}° (95 % interval {:.4}–{:.4}°), {}{marginal}\n",
                r.rms_deg, r.p95_deg, r.p95_ci_deg[0], r.p95_ci_deg[1], r.basis
            )
        }
        None => String::new(),
    };
    format!(
        "predicted cooperative accuracy at the work site ({}): rms {:.3} mm, p95 {:.3} mm (95 % interval {:.3}–{:.3} mm)\n{rotation}verdict: {}: {}\n",
        w.source,
        w.predicted_rms_mm,
        w.predicted_p95_mm,
        w.predicted_p95_ci_mm[0],
        w.predicted_p95_ci_mm[1],
        w.verdict.headline(),
        w.why
    )
}

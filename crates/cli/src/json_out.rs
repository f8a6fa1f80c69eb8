//! Printing a report as pretty JSON on stdout without building its text first.
//!
//! `println!("{}", serde_json::to_string_pretty(&report)?)` holds the whole text in memory next
//! to the report (at 1e6 rows of `calibrate POINTS.csv --json`, a 135 MB string whose
//! doublings peak above it). [`print_pretty`] serializes into a buffered, locked stdout as the
//! serializer produces the text: the same bytes (serde_json's pretty formatter, then one `\n`),
//! in a buffer of fixed size.

use std::io::{BufWriter, ErrorKind, Write};

use serde::Serialize;

/// Writes `report` to stdout as `serde_json::to_string_pretty` formats it, followed by a
/// newline: byte for byte what `println!("{}", serde_json::to_string_pretty(report)?)` prints.
///
/// A closed stdout (`handclasp … --json | head`) ends the process quietly with exit 0, as a
/// failed `println!` does through [`cli_support::exit_quietly_on_broken_pipe`]. Errors: the
/// report cannot be serialized, or another write error.
pub(crate) fn print_pretty(report: &impl Serialize) -> anyhow::Result<()> {
    let stdout = std::io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    let written = serde_json::to_writer_pretty(&mut out, report)
        .map_err(|e| match e.io_error_kind() {
            Some(kind) => std::io::Error::new(kind, e),
            None => std::io::Error::other(e),
        })
        .and_then(|()| out.write_all(b"\n"))
        .and_then(|()| out.flush());
    match written {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == ErrorKind::BrokenPipe => std::process::exit(0),
        Err(e) => Err(anyhow::Error::new(e).context("writing the JSON report to stdout")),
    }
}

#[cfg(test)]
mod tests {
    /// The streamed bytes equal `to_string_pretty` plus a newline for a report with nested
    /// arrays, maps, floats and escapes (the writer behind `print_pretty`, into a vector).
    #[test]
    fn streamed_json_equals_the_pretty_string() {
        #[derive(serde::Serialize)]
        struct Report {
            name: &'static str,
            residuals_mm: Vec<[f64; 3]>,
            empty: Vec<f64>,
            nested: std::collections::BTreeMap<&'static str, Option<f64>>,
        }
        let report = Report {
            name: "a \"quoted\"\nline",
            residuals_mm: vec![[0.1, -2.5e-7, 1e300], [f64::MIN_POSITIVE, 0.0, -0.0]],
            empty: vec![],
            nested: [("a", Some(1.5)), ("b", None)].into_iter().collect(),
        };
        let mut streamed = Vec::new();
        serde_json::to_writer_pretty(&mut streamed, &report).unwrap();
        streamed.push(b'\n');
        let printed = format!("{}\n", serde_json::to_string_pretty(&report).unwrap());
        assert_eq!(String::from_utf8(streamed).unwrap(), printed);
    }
}

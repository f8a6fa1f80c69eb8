//! Session CSV text → `handclasp_cell::Session::parse_csv` for a shipped cell. Input: one byte choosing
//! the cell (`cells/*.toml`, see `common::CELL_FILES`), then the CSV text; a session that reads is
//! also put through `handclasp_cell::check_session_inputs`.
#![no_main]

use handclasp_fuzz as common;

use std::path::Path;

use handclasp_cell::Session;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&which, rest)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    let cells = common::cells();
    let cell = &cells[usize::from(which) % cells.len()];
    if let Ok(session) = Session::parse_csv(text, Path::new("fuzz.csv"), cell) {
        let pairs = session.to_point_pairs();
        assert_eq!(pairs.len(), session.points.len());
        // The input checks every command runs before fitting (a header-only session once
        // panicked in calibrate --cell): they answer, never panic.
        let _ = handclasp_cell::check_session_inputs(&session);
    }
});

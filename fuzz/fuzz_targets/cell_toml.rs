//! Cell TOML text → `handclasp_cell::Cell`. The base directory is the repository's `cells/`, so the
//! shipped cells (the seed corpus) resolve `../robots/*.urdf` to the real robots: the target
//! exercises the TOML schema, units, mounts, errors and tolerances on real models without a temp
//! directory per input (URDF text itself is the `urdf` target's job). A cell that loads must
//! serialise ([`Cell::to_toml_string`]) to text that loads again.
#![no_main]

use handclasp_fuzz as common;

use handclasp_cell::Cell;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let base_dir = common::repo_root().join("cells");
    let Ok(cell) = Cell::from_toml_str(text, &base_dir) else {
        return;
    };
    let written = cell.to_toml_string();
    if let Err(e) = Cell::from_toml_str(&written, &base_dir) {
        panic!("a loaded cell does not load back from its own TOML: {e}\n{written}");
    }
});

#!/usr/bin/env bash
# Puts the diagnose CLI, tests and bench in place once `kinematics` implements its contract and
# sim-cell's lib.rs declares `pub mod diagnose;` (they are staged because they cannot compile before).
set -euo pipefail
cd "$(dirname "$0")/../../../../.."
S=crates/sim-cell/src/diagnose/staged
mkdir -p crates/sim-cell/tests
cp $S/diagnose_hidden.rs crates/sim-cell/tests/diagnose_hidden.rs
mkdir -p crates/sim-cell/benches
cp $S/bench_diagnose.rs crates/sim-cell/benches/diagnose.rs
cp $S/cli_diagnose.rs crates/cli/src/diagnose.rs
cp $S/e2e_diagnose.rs tests/e2e/diagnose.rs
grep -q 'name = "diagnose"' crates/sim-cell/Cargo.toml || printf '\n[[bench]]\nname = "diagnose"\nharness = false\n' >> crates/sim-cell/Cargo.toml
echo "installed; now: cargo test -p sim-cell --test diagnose_hidden && cargo test -p handclasp --test e2e diagnose"

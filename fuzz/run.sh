#!/usr/bin/env bash
# Runs handclasp's cargo-fuzz targets, one after the other, each for SECONDS (default 600), and
# prints per target: executions, exec/s, corpus size, new units and findings.
#
#   fuzz/run.sh [SECONDS] [TARGET...]      # no TARGET: every target in fuzz/Cargo.toml
#
# Needs the nightly toolchain (`rustup toolchain install nightly`); installs cargo-fuzz if it is
# missing. The seed corpora (fuzz/corpus/<target>/, committed) are read only: what libFuzzer adds
# goes to fuzz/work/<target>/ (ignored by git). libFuzzer runs in fork mode with one worker
# (-fork=1, FUZZ_JOBS=N for N workers on a bigger machine) and keeps going after a finding, so
# every target gets its full time and every crash, panic, timeout (> 10 s for one input) and OOM
# (> 2048 MB) is counted; each input is saved under fuzz/artifacts/<target>/ and
# `cargo +nightly fuzz run <target> <file>` replays it. Exit status: 1 if any target had a
# finding.
set -uo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cd "$here"

seconds="${1:-600}"
shift || true
if ! [[ "$seconds" =~ ^[0-9]+$ ]]; then
    echo "usage: fuzz/run.sh [SECONDS] [TARGET...]  (SECONDS a whole number, got '$seconds')" >&2
    exit 2
fi

if ! cargo +nightly --version >/dev/null 2>&1; then
    echo "the nightly toolchain is missing: rustup toolchain install nightly" >&2
    exit 2
fi
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
    echo "installing cargo-fuzz (cargo install cargo-fuzz --locked) ..." >&2
    cargo install cargo-fuzz --locked || exit 2
fi

if [ "$#" -gt 0 ]; then
    targets=("$@")
else
    mapfile -t targets < <(cargo +nightly fuzz list)
fi

# FUZZ_NO_BUILD=1 runs the binaries built before (fuzz/target/<triple>/release/<target>), so
# that editing the crates during a long run does not rebuild under it.
if [ -z "${FUZZ_NO_BUILD:-}" ]; then
    cargo +nightly fuzz build || exit 2
fi
triple="$(rustc +nightly -vV | sed -n 's/^host: //p')"
summary=()
status=0
for t in "${targets[@]}"; do
    mkdir -p "work/$t" "corpus/$t" "artifacts/$t"
    log="work/$t.log"
    touch "$log.start"
    echo "== $t: ${seconds} s" >&2
    "target/$triple/release/$t" -artifact_prefix="artifacts/$t/" "work/$t" "corpus/$t" \
        -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 \
        -fork="${FUZZ_JOBS:-1}" -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1 \
        >"$log" 2>&1
    rc=$?
    # Fork mode's progress lines: "#EXECS: cov: C ft: F corp: N exec/s: R oom/timeout/crash: O/T/K time: Ts ..."
    last=$(grep -E '^#[0-9]+: cov:' "$log" | tail -1)
    execs=$(sed -nE 's/^#([0-9]+):.*/\1/p' <<<"$last")
    # The line's exec/s is the last job's; the run's average is executions / elapsed time.
    elapsed=$(sed -nE 's/.* time: ([0-9]+)s.*/\1/p' <<<"$last")
    rate=""
    if [ -n "$execs" ] && [ -n "$elapsed" ] && [ "$elapsed" -gt 0 ]; then
        rate=$((execs / elapsed))
    fi
    corp=$(sed -nE 's/.* corp: ([0-9]+).*/\1/p' <<<"$last")
    otc=$(sed -nE 's/.* oom\/timeout\/crash: ([0-9]+\/[0-9]+\/[0-9]+).*/\1/p' <<<"$last")
    arts=$(find "artifacts/$t" -type f -newer "$log.start" 2>/dev/null | wc -l)
    finding="none"
    if [ "$rc" -ne 0 ] || [ "${otc:-0/0/0}" != "0/0/0" ] || [ "$arts" -gt 0 ]; then
        status=1
        finding="oom/timeout/crash ${otc:-?}, $arts new input(s) in fuzz/artifacts/$t/ (exit $rc)"
    fi
    line=$(printf '%-18s execs %-10s exec/s %-7s corpus %-7s findings: %s' \
        "$t" "${execs:-?}" "${rate:-?}" "${corp:-?}" "$finding")
    echo "$line" >&2
    summary+=("$line")
done
echo
echo "target             results ($seconds s each; logs in fuzz/work/<target>.log)"
printf '%s\n' "${summary[@]}"
exit "$status"

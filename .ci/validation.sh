#!/usr/bin/env bash
# The gap diagnosis's validation suites (docs/gap.md): each takes minutes, so
# `cargo test` skips them (#[ignore]) and CI runs them here, as a stage of their
# own, with their tests' assertions. They run on the test profile's binaries,
# which the `cargo test` stage has just built: the targets are named without
# `-p` so that cargo resolves the features as `cargo test` did and builds
# nothing again. Both suites always run; the stage fails if either does.
# Tables: target/gap-validation.md and target/gap-foreign.md.
set -uo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n== %s\n' "$*"; }
SECONDS=0
failed=""

step "own suite: host-sim/tests/gap_validation.rs"
cargo test --test gap_validation -- --ignored --exact gap_validation_suite --nocapture ||
    failed="$failed own"
own=$SECONDS

step "foreign effect forms: tests/tests/gap_foreign.rs"
cargo test --test gap_foreign -- \
    --ignored --exact gap_diagnosis_on_foreign_effect_forms --nocapture ||
    failed="$failed foreign"

step "validation suites: own ${own} s, foreign $((SECONDS - own)) s${failed:+; FAILED:$failed}"
[ -z "$failed" ]

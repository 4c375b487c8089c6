#!/usr/bin/env bash
# Bounded fuzzing of everything that reads untrusted bytes (docs/fuzzing.md):
# builds the cargo-fuzz targets of tests/fuzz/ (nightly, libFuzzer, ASan),
# runs each for FUZZ_SECONDS from a copy of its seeds and regressions in a
# temporary directory (the repository's corpus never grows here), with its
# dictionary (tests/fuzz/dict/), and fails on any crash, timeout, leak or
# out-of-memory. Prints the build time and a table of inputs executed, corpus
# size and crashes per target.
#
# Runs on a fresh machine: installs the nightly toolchain and cargo-fuzz (at
# CARGO_FUZZ_VERSION, skipped when that version is installed). Settings:
#   FUZZ_SECONDS    run time per target, s (default 20: with the set-up (about
#                   1 min on a fresh machine) and the build (about 4 min on 2
#                   idle cores) the whole script stays under ~8 minutes)
#   FUZZ_TIMEOUT    one input taking longer than this is a hang, s (default 10)
#   FUZZ_RSS_MB     memory limit of a fuzzer process, MB (default 2048)
#   FUZZ_TARGETS    space-separated subset of the targets (default: all)
#   FUZZ_TOOLCHAIN  the nightly toolchain to use (default: nightly)
#   FUZZ_TARGET_DIR cargo's target directory for the fuzz build (default
#                   tests/fuzz/target; one outside the clone lets later runs on
#                   the same machine reuse the build)
#   FUZZ_KEEP=1     keep the temporary directory (corpora, logs, artifacts)
set -euo pipefail
cd "$(dirname "$0")/.."

CARGO_FUZZ_VERSION=0.13.2
FUZZ_SECONDS=${FUZZ_SECONDS:-20}
FUZZ_TIMEOUT=${FUZZ_TIMEOUT:-10}
FUZZ_RSS_MB=${FUZZ_RSS_MB:-2048}
FUZZ_TOOLCHAIN=${FUZZ_TOOLCHAIN:-nightly}
FUZZ_TARGET_DIR=${FUZZ_TARGET_DIR:-$PWD/tests/fuzz/target}
ALL_TARGETS="console console_rx frame settings_image runlog scenario_toml config_toml"
FUZZ_TARGETS=${FUZZ_TARGETS:-$ALL_TARGETS}

step() { printf '\n== %s\n' "$*"; }
SECONDS=0

step "set-up: $FUZZ_TOOLCHAIN toolchain, cargo-fuzz $CARGO_FUZZ_VERSION"
rustup toolchain install "$FUZZ_TOOLCHAIN" --profile minimal --no-self-update
if [ "$(cargo fuzz --version 2>/dev/null || true)" != "cargo-fuzz $CARGO_FUZZ_VERSION" ]; then
    cargo install cargo-fuzz --version "$CARGO_FUZZ_VERSION" --locked
fi
cargo fuzz --version
rustup run "$FUZZ_TOOLCHAIN" rustc --version

WORK=$(mktemp -d "${TMPDIR:-/tmp}/dca-fuzz.XXXXXX")
if [ "${FUZZ_KEEP:-0}" = 1 ]; then
    echo "work directory (kept): $WORK"
else
    trap 'rm -rf "$WORK"' EXIT
fi

# cargo fuzz finds the project from tests/ (tests/Cargo.toml, tests/fuzz/).
cd tests
step "build (release, debug assertions, ASan)"
build_start=$SECONDS
cargo "+$FUZZ_TOOLCHAIN" fuzz build -O --target-dir "$FUZZ_TARGET_DIR"
build_s=$((SECONDS - build_start))
echo "build time: ${build_s} s"

failed=0
rows=()
for t in $FUZZ_TARGETS; do
    step "fuzz $t for ${FUZZ_SECONDS} s"
    corpus="$WORK/$t/corpus"
    artifacts="$WORK/$t/artifacts"
    mkdir -p "$corpus" "$artifacts"
    cp fuzz/corpus/"$t"/* "$corpus"/
    if [ -d fuzz/regressions/"$t" ]; then
        cp fuzz/regressions/"$t"/* "$corpus"/ 2>/dev/null || true
    fi
    seeds=$(find "$corpus" -type f | wc -l)
    log="$WORK/$t/log"
    dict=()
    if [ -f fuzz/dict/"$t".dict ]; then
        dict=(-dict=fuzz/dict/"$t".dict)
    fi
    rc=0
    cargo "+$FUZZ_TOOLCHAIN" fuzz run -O --target-dir "$FUZZ_TARGET_DIR" "$t" "$corpus" -- \
        -max_total_time="$FUZZ_SECONDS" -timeout="$FUZZ_TIMEOUT" \
        -rss_limit_mb="$FUZZ_RSS_MB" -print_final_stats=1 "${dict[@]}" \
        -artifact_prefix="$artifacts/" >"$log" 2>&1 || rc=$?
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
    size=$(find "$corpus" -type f | wc -l)
    crashes=$(find "$artifacts" -type f | wc -l)
    if [ "$rc" -ne 0 ] || [ "$crashes" -ne 0 ]; then
        failed=1
        echo "FAILED: $t (exit $rc); the end of its log:"
        tail -n 60 "$log"
        for a in "$artifacts"/*; do
            [ -f "$a" ] || continue
            echo "artifact $(basename "$a") (base64):"
            base64 -w 0 "$a"
            echo
        done
    else
        tail -n 8 "$log"
    fi
    rows+=("$(printf '%-16s %12s %10s %10s %8s' "$t" "${execs:-n/a}" "$seeds" "$size" "$crashes")")
done

step "summary (${FUZZ_SECONDS} s per target, build ${build_s} s, total ${SECONDS} s)"
printf '%-16s %12s %10s %10s %8s\n' target executed seeds corpus crashes
for r in "${rows[@]}"; do
    echo "$r"
done
if [ "$failed" -ne 0 ]; then
    echo "fuzzing found a crash, hang, leak or memory blow-up: see the logs above;"
    echo "reproduce with: cd tests && cargo +nightly fuzz run -O <target> <artifact file>"
    exit 1
fi

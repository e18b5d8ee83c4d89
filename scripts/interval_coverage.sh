#!/bin/sh
# Coverage study of the diagnosis's 95% intervals (docs/diagnosis.md, "How
# far the intervals hold"): random plants on the 3-DOF arm and the Panda,
# simulated and diagnosed at the defaults. COVERAGE_FIRST_SEED (default 1)
# and COVERAGE_CASES (default 40) choose the seeds; the last line is the
# summary: named parameters covered, median half-width, unnamed ones listed
# or absent.
set -e
cd "$(dirname "$0")/.."
cargo test --release -p sdnn --test tests -- intervals::coverage_study --ignored --nocapture

#!/usr/bin/env bash
# The project's test command (see README): the generator crate's tests
# without Symbolica, then the product's crates' unit and integration tests
# (the runtime, the trait, the compiled models, and the `sdnn` crate with
# the integration tests in tests/).
set -euo pipefail
cd "$(dirname "$0")"
cargo test --release --locked -p sdnn-codegen --no-default-features
cargo test --release --locked -p sdnn -p sdnn-runtime -p sdnn-dynamics -p sdnn-models

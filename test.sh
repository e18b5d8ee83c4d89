#!/usr/bin/env bash
# The project's test command (see README): the generator crate's tests
# without Symbolica, then the product's unit and integration tests.
set -euo pipefail
cd "$(dirname "$0")"
cargo test --release --locked -p sdnn-codegen --no-default-features
cargo test --release --locked

#!/usr/bin/env bash
# The project's test command (see README): the product's unit and
# integration tests, then the generator crate's tests without Symbolica.
set -euo pipefail
cd "$(dirname "$0")"
cargo test --release --locked
cargo test --release --locked -p sdnn-codegen --no-default-features

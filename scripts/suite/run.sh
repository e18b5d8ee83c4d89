#!/usr/bin/env bash
# Independent simulator-and-scoring suite for `sdnn diagnose` (README.md).
# Usage: scripts/suite/run.sh [BINARY] [OUTDIR] [QUICK]
#   BINARY  the sdnn executable (default: target/release/sdnn)
#   OUTDIR  where cases/, results.json and summary.txt go (default: target/suite/out)
#   QUICK   any non-empty value but 0: the ~3 minute subset (one seed)
# Environment: JOBS (default 2) parallel jobs; KEEP_DATA=1 keeps the CSV
# recordings; UR10E_URDF the UR10e's URDF (default: the public
# identification repository, cloned into target/ur10e as scripts/check_ur10e.py does).
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
BIN="$(realpath "${1:-$ROOT/target/release/sdnn}")"
OUT="${2:-$ROOT/target/suite/out}"
QUICK="${3:-}"
VENV="$ROOT/target/suite/venv"
PY="$VENV/bin/python"
if ! "$PY" -c "import pinocchio, numpy" 2>/dev/null; then
    python3 -m venv "$VENV"
    "$PY" -m pip install -q pin numpy
fi
mkdir -p "$OUT"
OUT="$(realpath "$OUT")"
rm -rf "$OUT/cases"
start=$(date +%s)
# the UR10e description: the tool's own import of the public URDF
URDF="${UR10E_URDF:-$ROOT/target/ur10e/dynamic_calibration/URe/urdf/ur10e.urdf}"
if [ ! -f "$URDF" ]; then
    git clone -q --depth 1 https://github.com/shamilmamedov/dynamic_calibration \
        "$ROOT/target/ur10e/dynamic_calibration"
fi
"$BIN" import-urdf "$URDF" --out "$ROOT/target/suite/ur10e.toml"
# 0. the plant must be the tool's model: sdnn tau against Pinocchio rnea, ~1e-9 relative
(cd "$HERE" && "$PY" verify_plant.py "$BIN" "$ROOT/models/kinova_gen3_lite_3dof.toml" \
    "$ROOT/models/panda.toml" "$ROOT/target/suite/ur10e.toml") | tee "$OUT/plant_check.txt"
grep -q "PLANT OK" "$OUT/plant_check.txt" || { echo "plant does not match sdnn tau: stopping"; exit 1; }
# ... and each inertial/gravity/friction effect injected as the description format means it
(cd "$HERE" && "$PY" verify_effects.py "$BIN") > "$OUT/effects_check.txt"
tail -1 "$OUT/effects_check.txt"
grep -q "EFFECTS OK" "$OUT/effects_check.txt" || { echo "effect injection does not match sdnn tau: stopping"; exit 1; }
# 1. the jobs, JOBS at a time
cd "$HERE"
"$PY" suite.py plan "$QUICK" > "$OUT/jobs.txt"
echo "$(wc -l < "$OUT/jobs.txt") jobs (each: generate 3 recordings, diagnose from 3 and from 1)"
xargs -P "${JOBS:-2}" -L 1 "$PY" suite.py job "$BIN" "$OUT" < "$OUT/jobs.txt" 2>&1 | tee "$OUT/progress.log"
end=$(date +%s)
# 2. results.json and summary.txt
"$PY" suite.py summarize "$OUT" "$((end - start))" > /dev/null
echo "wall time: $((end - start)) s"
echo "summary: $OUT/summary.txt"
head -20 "$OUT/summary.txt"

#!/usr/bin/env bash
# Builds and runs the Pinocchio timing anchor for the Panda (see README.md).
# Not part of CI. Run from anywhere:
#
#     scripts/pinocchio_bench/run.sh [RUNS [REPETITIONS [PASSES]]]
#
# RUNS (default 3) runs of each build, each printed with `uptime` beside it.
# Environment: VENV (default target/public-urdfs/venv, the venv of
# scripts/check_public_urdfs.py), PYTHON (to create it, default python3),
# CXX (default g++), BUILDS (default "lib hdr").
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
venv="${VENV:-$root/target/public-urdfs/venv}"
out="$root/target/pinocchio-bench"
runs="${1:-3}"
reps="${2:-15}"
passes="${3:-5}"
cxx="${CXX:-g++}"
builds="${BUILDS:-lib hdr}"

# The venv as scripts/check_public_urdfs.py makes it (same pins), plus the
# two header-only packages the C++ build needs and the wheels leave out:
# Eigen (cmeel-eigen) and urdfdom_headers (Pinocchio 4.1.0's wheel was built
# against urdfdom_headers 3.0.0, per its CMake config).
packages=("example-robot-data==6.0.0" "pin==4.1.0")
build_packages=("cmeel-eigen==3.4.1" "cmeel-urdfdom-headers==3.0.0")
if [[ ! -x "$venv/bin/python" ]]; then
    "${PYTHON:-python3}" -m venv "$venv"
    "$venv/bin/python" -m pip install -q "${packages[@]}"
fi
prefix="$(ls -d "$venv"/lib/python3*/site-packages/cmeel.prefix | head -n 1)"
if [[ ! -f "$prefix/include/eigen3/Eigen/Core" || ! -f "$prefix/include/urdfdom_headers/urdf_model/model.h" ]]; then
    "$venv/bin/python" -m pip install -q "${build_packages[@]}"
fi
urdf="$prefix/share/example-robot-data/robots/panda_description/urdf/panda.urdf"
[[ -f "$urdf" ]] || { echo "no Panda URDF at $urdf" >&2; exit 1; }

# Flags of the pinocchio::pinocchio_parsers CMake target (lib/cmake/pinocchio/
# pinocchioTargets.cmake), by hand; portable code: -O3, no -march=native.
common=(
    -std=c++17 -O3 -DNDEBUG
    -I"$prefix/include" -I"$prefix/include/eigen3" -I"$prefix/include/urdfdom_headers"
    -DBOOST_MPL_LIMIT_LIST_SIZE=30 -DBOOST_MPL_LIMIT_VECTOR_SIZE=30
    -DBOOST_MPL_CFG_NO_PREPROCESSED_HEADERS -DBOOST_FUSION_INVOKE_MAX_ARITY=12
    -DPINOCCHIO_WITH_URDFDOM
    -DPINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION=3 -DPINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION=0
    -DPINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION=0
)
libs=(
    -L"$prefix/lib" -Wl,-rpath,"$prefix/lib"
    -lpinocchio_parsers -lpinocchio_default -lurdfdom_model -lboost_filesystem -lboost_serialization
)
mkdir -p "$out"
for b in $builds; do
    case "$b" in
        # lib: the algorithms as compiled in the wheel's libpinocchio_default
        # (explicit instantiations for double), as a CMake user gets them.
        lib) extra=(-DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION) ;;
        # hdr: the same algorithms compiled from the headers in this file.
        hdr) extra=() ;;
        *) echo "unknown build $b (lib or hdr)" >&2; exit 2 ;;
    esac
    bin="$out/bench_$b"
    if [[ ! -x "$bin" || "$here/bench.cpp" -nt "$bin" || "$0" -nt "$bin" ]]; then
        echo "building $bin ..." >&2
        "$cxx" "${common[@]}" "${extra[@]}" "$here/bench.cpp" -o "$bin" "${libs[@]}"
    fi
done

echo "# $(uname -srm); $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'); $(nproc) CPUs"
echo "# $("$cxx" --version | head -n 1); pin 4.1.0 (PyPI), example-robot-data 6.0.0"
for ((r = 1; r <= runs; r++)); do
    for b in $builds; do
        echo
        echo "## run $r, build $b; before: $(uptime | sed 's/.*load/load/')"
        "$out/bench_$b" "$urdf" "$reps" "$passes"
        echo "## after: $(uptime | sed 's/.*load/load/')"
    done
done

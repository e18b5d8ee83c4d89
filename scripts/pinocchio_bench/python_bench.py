"""Pinocchio's dynamics on the Franka Panda called from Python: the way the
issue 23 table was measured (binding overhead included), on the 4,096
states of benches/dynamics.rs (same generator, same seed). Not part of CI.

Usage: target/public-urdfs/venv/bin/python scripts/pinocchio_bench/python_bench.py
"""

import time
from pathlib import Path

import numpy as np
import pinocchio as pin


def states(count=4096):
    """The 64-bit LCG of benches/dynamics.rs `panda_states`, seed 5."""
    seed = 5
    mask = (1 << 64) - 1
    out = []

    def draw(scale):
        nonlocal seed
        v = np.empty(7)
        for i in range(7):
            seed = (seed * 6364136223846793005 + 1442695040888963407) & mask
            v[i] = scale * ((seed >> 11) / float(1 << 52) - 1.0)
        return v

    for _ in range(count):
        out.append((draw(np.pi), draw(3.0), draw(10.0), draw(20.0)))
    return out


def panda():
    """example-robot-data's Panda URDF (from the venv's share folder), the
    two finger joints locked at 0 as in bench.cpp."""
    prefix = Path(pin.__file__).resolve().parents[4]
    urdf = prefix / "share/example-robot-data/robots/panda_description/urdf/panda.urdf"
    full = pin.buildModelFromUrdf(str(urdf))
    fingers = [full.getJointId(n) for n in ("panda_finger_joint1", "panda_finger_joint2")]
    model = pin.buildReducedModel(full, fingers, pin.neutral(full))
    assert model.nq == 7, model.nq
    return model


def best_ns(call, samples, repetitions=7):
    call(*samples[0])
    best = float("inf")
    for _ in range(repetitions):
        start = time.perf_counter()
        for s in samples:
            call(*s)
        best = min(best, (time.perf_counter() - start) / len(samples))
    return best * 1e9


def main():
    model = panda()
    data = model.createData()
    tip = model.getFrameId("panda_link7")
    samples = states()
    lwa = pin.LOCAL_WORLD_ALIGNED

    def tip_pose_and_jacobian(q, *_):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacement(model, data, tip)
        return pin.getFrameJacobian(model, data, tip, lwa)

    calls = [
        ("rnea", lambda q, v, a, t: pin.rnea(model, data, q, v, a)),
        ("crba", lambda q, v, a, t: pin.crba(model, data, q)),
        ("aba", lambda q, v, a, t: pin.aba(model, data, q, v, t)),
        ("computeRNEADerivatives", lambda q, v, a, t: pin.computeRNEADerivatives(model, data, q, v, a)),
        ("computeABADerivatives", lambda q, v, a, t: pin.computeABADerivatives(model, data, q, v, t)),
        ("tip pose + Jacobian (computeJointJacobians + frame)", tip_pose_and_jacobian),
    ]
    print(f"pinocchio {pin.__version__} from Python, {len(samples)} states, best of 7 passes (ns per call)")
    for name, call in calls:
        print(f"{name:55s} {best_ns(call, samples):8.0f}")


if __name__ == "__main__":
    main()

"""Check the Pinocchio plant against `sdnn tau` on random states (no hidden effect)."""
import subprocess, sys, io
import numpy as np
from plant import Description, rnea_batch

def check(binary, toml, n=2000, seed=0):
    d = Description(toml)
    model = d.build()
    rng = np.random.default_rng(seed)
    lo, hi, vel = d.limits()
    lo = np.maximum(lo, -3.0); hi = np.minimum(hi, 3.0)
    Q = rng.uniform(lo, hi, size=(n, d.n))
    QD = rng.uniform(-2, 2, size=(n, d.n))
    QDD = rng.uniform(-10, 10, size=(n, d.n))
    N = d.n
    hdr = ",".join([f"q{i+1}" for i in range(N)] + [f"qd{i+1}" for i in range(N)] + [f"qdd{i+1}" for i in range(N)])
    buf = io.StringIO()
    buf.write(hdr + "\n")
    for row in np.hstack([Q, QD, QDD]):
        buf.write(",".join(repr(float(x)) for x in row) + "\n")
    p = subprocess.run([binary, "tau", "--model", toml, "--input", "-"], input=buf.getvalue(), capture_output=True, text=True)
    if p.returncode != 0:
        print(p.stderr); return False
    lines = p.stdout.strip().splitlines()
    T = np.array([[float(x) for x in l.split(",")] for l in lines[1:]])
    R = rnea_batch(model, Q, QD, QDD)
    err = np.abs(T - R).max()
    rel = err / np.abs(R).max()
    print(f"{toml}: n={n} dof={N} max abs err {err:.3e} N m, rel to max |tau| {rel:.3e}; per-row worst rel {np.max(np.abs(T-R).max(1)/np.maximum(np.abs(R).max(1),1e-9)):.3e}")
    return rel < 1e-9

if __name__ == "__main__":
    ok = all(check(sys.argv[1], t) for t in sys.argv[2:])
    print("PLANT OK" if ok else "PLANT MISMATCH")
    sys.exit(0 if ok else 1)

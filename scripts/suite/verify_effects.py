"""Check the hidden-effect injection against the tool's own semantics: each
case's plant written as a TOML (payload as a fixed child link, link changes
in the link, tilt in `gravity`, joint effects in `effects`) and evaluated
with `sdnn tau` must give the generator's torques (no noise, |qd| > 0.3 so
tanh(qd/0.01) = sign(qd))."""
import atexit, copy, io, json, os, shutil, subprocess, sys, tempfile, tomllib
import numpy as np
import gen
from plant import Description

# This run's own folder: two runs at once do not share files.
SCRATCH = tempfile.mkdtemp(prefix="sdnn-suite-")
atexit.register(shutil.rmtree, SCRATCH, True)

def val(v):
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {val(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(val(x) for x in v) + "]"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, bool):
        return "true" if v else "false"
    return repr(float(v)) if isinstance(v, float) else str(v)

def emit(d):
    out = io.StringIO()
    for k, v in d.items():
        if not isinstance(v, list) or not v or not isinstance(v[0], dict):
            out.write(f"{k} = {val(v)}\n")
    for k in ("links", "joints"):
        for item in d[k]:
            out.write(f"\n[[{k}]]\n")
            for kk, vv in item.items():
                out.write(f"{kk} = {val(vv)}\n")
    return out.getvalue()

def as_toml(robot, case, seed, path):
    R = gen.ROBOTS[robot]
    desc = Description(R["toml"])
    d = tomllib.load(open(R["toml"], "rb"))
    eff = gen.draw_case(robot, case, seed)
    _, inertias, g = gen.plant_model(desc, eff)
    moving = [j for j in d["joints"] if j.get("type", "revolute") != "fixed"]
    links = {l["name"]: l for l in d["links"]}
    d["gravity"] = list(map(float, g))
    res = {}
    for e in eff:
        t = e["type"]
        if t == "payload":
            ln = moving[e["link"] - 1]["child"]
            I = gen.sphere(e["mass"], e["radius"])
            d["links"].append(dict(name="payload", mass=e["mass"], com=[0.0, 0.0, 0.0],
                                   inertia=dict(ixx=I[0, 0], iyy=I[1, 1], izz=I[2, 2])))
            d["joints"].append(dict(name="payload_mount", type="fixed", parent=ln, child="payload",
                                    origin=dict(xyz=e["com"])))
        elif t in ("heavier_link", "whole_link"):
            k = e["link"] - 1
            l = links[moving[k]["child"]]
            I = inertias[k]
            l["mass"] = float(I.mass); l["com"] = I.lever.tolist()
            l["inertia"] = I.inertia.tolist()
        elif t in ("viscous", "coulomb"):
            for j, m in enumerate(moving):
                m.setdefault("effects", {})[t] = e["b" if t == "viscous" else "c"][j]
        elif t == "armature":
            moving[e["joint"] - 1].setdefault("effects", {})["armature"] = e["inertia"]
        elif t == "stribeck":
            m = moving[e["joint"] - 1].setdefault("effects", {})
            m.update(coulomb=e["coulomb"], stribeck=e["excess"], stribeck_velocity=e["velocity"])
        elif t == "asym_coulomb":
            m = moving[e["joint"] - 1].setdefault("effects", {})
            m.update(coulomb=e["coulomb"], coulomb_asymmetry=e["asymmetry"])
    open(path, "w").write(emit(d))
    return desc, eff

def check(binary, robot, case, seed=1, n=400):
    path = os.path.join(SCRATCH, f"verify_{robot}_{case}.toml")
    desc, eff = as_toml(robot, case, seed, path)
    model, _, _ = gen.plant_model(desc, eff)
    rng = np.random.default_rng(5)
    N = desc.n
    lo, hi, _ = desc.limits()
    Q = rng.uniform(np.maximum(lo, -3), np.minimum(hi, 3), (n, N))
    QD = rng.choice([-1, 1], (n, N)) * rng.uniform(0.3, 2, (n, N))
    QDD = rng.uniform(-8, 8, (n, N))
    import pinocchio as pin
    data = model.createData()
    T = np.array([pin.rnea(model, data, Q[i], QD[i], QDD[i]) for i in range(n)])
    T += gen.joint_torques(eff, Q, QD, QDD, None, {})
    hdr = ",".join([f"q{i+1}" for i in range(N)] + [f"qd{i+1}" for i in range(N)] + [f"qdd{i+1}" for i in range(N)])
    s = hdr + "\n" + "\n".join(",".join(repr(float(x)) for x in r) for r in np.hstack([Q, QD, QDD]))
    p = subprocess.run([binary, "tau", "--model", path, "--input", "-"], input=s, capture_output=True, text=True)
    if p.returncode:
        print(robot, case, "sdnn tau failed:", p.stderr[:500]); return False
    S = np.array([[float(x) for x in l.split(",")] for l in p.stdout.strip().splitlines()[1:]])
    rel = np.abs(S - T).max() / np.abs(T).max()
    print(f"{robot:8s} {case:13s} max |sdnn tau - plant| / max |tau| = {rel:.2e}")
    return rel < 1e-9

if __name__ == "__main__":
    ok = True
    for robot in ("kinova3", "panda", "ur10e"):
        for case in ("payload", "heavier_link", "whole_link", "tilt", "viscous", "coulomb", "armature", "stribeck", "asym_coulomb"):
            for seed in (1, 2):
                ok &= check(sys.argv[1], robot, case, seed)
    print("EFFECTS OK" if ok else "EFFECTS MISMATCH")

"""Recording generator: analytic Fourier excitation, Pinocchio inverse dynamics,
one hidden effect (or a combination) per case, measurement noise.

A case is (suite, case, seed). Everything is drawn from a generator seeded by
a hash of those three, so a case is reproducible.
"""
import hashlib
import json
import os

import numpy as np
import pinocchio as pin

from plant import Description

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
MAIN_MODELS = os.path.join(ROOT, "models")
# written by run.sh: `sdnn import-urdf` of the UR10e's public URDF
UR10E_TOML = os.path.join(ROOT, "target", "suite", "ur10e.toml")

# ---------------------------------------------------------------- robots
ROBOTS = {
    "kinova3": dict(
        toml=os.path.join(MAIN_MODELS, "kinova_gen3_lite_3dof.toml"),
        # friction scale per joint (N m)
        fs=[1.0, 1.0, 1.0],
        # window of joint centres (inside the limits)
        window=[(-2.0, 2.0), (-1.2, 1.2), (-1.6, 1.6)],
        amp=[1.0, 0.8, 1.0], vmax=1.0, amax=6.0,
        wrist=[3], links=[2, 3], scale_joints=[1, 2, 3], payload_mass=(0.4, 1.0),
        payload_com=lambda r: [r.uniform(-0.05, 0.05), r.uniform(-0.05, 0.05), r.uniform(0.25, 0.33)],
        armature=(0.01, 0.03), spring=(1.0, 3.0),
    ),
    "panda": dict(
        toml=os.path.join(MAIN_MODELS, "panda.toml"),
        fs=[1.0, 1.0, 1.0, 1.0, 0.6, 0.6, 0.6],
        window=[(-1.5, 1.5), (-0.9, 0.9), (-1.5, 1.5), (-2.4, -0.8), (-1.5, 1.5), (0.8, 2.8), (-1.5, 1.5)],
        amp=[1.0, 0.7, 1.0, 0.7, 1.0, 0.8, 1.2], vmax=1.2, amax=6.0,
        wrist=[5, 6, 7], links=[3, 4, 5, 6], scale_joints=[1, 2, 3, 4, 5, 6, 7], payload_mass=(0.5, 2.0),
        payload_com=lambda r: [r.choice([-1, 1]) * r.uniform(0.03, 0.08), r.choice([-1, 1]) * r.uniform(0.03, 0.08), 0.107 + r.uniform(0.02, 0.10)],
        armature=(0.02, 0.06), spring=(2.0, 8.0),
    ),
    "ur10e": dict(
        toml=UR10E_TOML,
        fs=[5.0, 5.0, 3.0, 1.0, 1.0, 1.0],
        window=[(-1.5, 1.5), (-2.4, -0.7), (-2.0, 2.0), (-2.5, -0.6), (-1.5, 1.5), (-1.5, 1.5)],
        amp=[1.0, 0.6, 0.9, 1.0, 1.0, 1.2], vmax=1.0, amax=5.0,
        # joint 6 turns a flange whose COM is on its axis: 5e-4 N m RMS, below the
        # noise, so a scale error there changes nothing measurable
        wrist=[4, 5, 6], links=[2, 3, 4], scale_joints=[1, 2, 3, 4, 5], payload_mass=(0.5, 2.0),
        payload_com=lambda r: [r.choice([-1, 1]) * r.uniform(0.03, 0.08), 0.117 + r.uniform(0.02, 0.10), r.choice([-1, 1]) * r.uniform(0.03, 0.08)],
        armature=(0.05, 0.2), spring=(10.0, 40.0),
    ),
}

# Gaz et al. 2019, Panda sigmoid friction (Table of the paper)
GAZ_PHI1 = [0.54615, 0.87224, 0.64068, 1.2794, 0.83904, 0.30301, 0.56489]
GAZ_PHI2 = [5.1181, 9.0657, 10.136, 5.5903, 8.3469, 17.133, 10.336]
GAZ_PHI3 = [0.039533, 0.025882, -0.04607, 0.036194, 0.026226, -0.021047, 0.0035526]

EPS = 0.01  # rad/s, tanh smoothing of sign(qd)

CASES = ["clean", "viscous", "coulomb", "gaz", "stribeck", "armature", "payload",
         "heavier_link", "whole_link", "torque_scale", "torque_offset", "torque_delay",
         "tilt", "spring", "asym_coulomb", "combo"]


def rng_for(*parts):
    h = hashlib.sha256("/".join(str(p) for p in parts).encode()).digest()
    return np.random.default_rng(int.from_bytes(h[:8], "little"))


# ---------------------------------------------------------------- excitation
def excitation(rng, robot, desc, t):
    """Design a sum of 5-12 harmonics per joint inside the limits on the grid t.

    Returns (evaluate, spec): evaluate(times) -> q, qd, qdd (analytic)."""
    R = ROBOTS[robot]
    n = desc.n
    lo, hi, vel = desc.limits()
    f0 = rng.uniform(0.05, 0.2)
    w = 2 * np.pi * f0
    joints = []
    for j in range(n):
        H = int(rng.integers(5, 13))
        k = np.arange(1, H + 1)
        a = rng.normal(size=H) / k
        b = rng.normal(size=H) / k
        x, xd, xdd = _fourier(t, w, k, a, b)
        # the largest scale that keeps amplitude, speed and acceleration inside bounds
        wl, wh = R["window"][j]
        margin = 0.1 * (hi[j] - lo[j]) if np.isfinite(hi[j] - lo[j]) else 0.3
        wl = max(wl, lo[j] + margin); wh = min(wh, hi[j] - margin)
        amp = min(R["amp"][j], 0.5 * (wh - wl))
        scale = min(amp / np.abs(x).max(),
                    min(R["vmax"], 0.6 * vel[j]) / np.abs(xd).max(),
                    R["amax"] / np.abs(xdd).max())
        clo, chi = wl - scale * x.min(), wh - scale * x.max()
        centre = rng.uniform(clo, chi) if chi > clo else 0.5 * (wl + wh)
        joints.append(dict(harmonics=H, a=(scale * a).tolist(), b=(scale * b).tolist(), centre=float(centre)))

    def evaluate(times):
        Q = np.zeros((len(times), n)); QD = np.zeros_like(Q); QDD = np.zeros_like(Q)
        for j, J in enumerate(joints):
            k = np.arange(1, J["harmonics"] + 1)
            x, xd, xdd = _fourier(times, w, k, np.array(J["a"]), np.array(J["b"]))
            Q[:, j] = J["centre"] + x; QD[:, j] = xd; QDD[:, j] = xdd
        return Q, QD, QDD

    Q, _, _ = evaluate(t)
    for j in range(n):
        margin = 0.1 * (hi[j] - lo[j]) if np.isfinite(hi[j] - lo[j]) else 0.3
        assert Q[:, j].min() >= lo[j] + 0.5 * margin and Q[:, j].max() <= hi[j] - 0.5 * margin
    return evaluate, dict(f0=float(f0), joints=joints)


def _fourier(t, w, k, a, b):
    ph = np.outer(t, k) * w
    s, c = np.sin(ph), np.cos(ph)
    return s @ a + c @ b, (c @ (a * k) - s @ (b * k)) * w, -(s @ (a * k * k) + c @ (b * k * k)) * w * w


# ---------------------------------------------------------------- hidden effects
def sphere(m, r):
    return np.eye(3) * 0.4 * m * r * r


def draw_case(robot, case, seed):
    """The hidden effects of a case: a list of dicts (documented in README.md)."""
    R = ROBOTS[robot]
    desc = Description(R["toml"])
    n = desc.n
    r = rng_for(robot, case, seed, "effects")
    fs = np.array(R["fs"])
    eff = []

    def pick(lst):
        return int(lst[int(r.integers(len(lst)))])

    def viscous():
        return dict(type="viscous", b=(r.uniform(0.1, 0.5, n) * fs).tolist())

    def coulomb():
        return dict(type="coulomb", c=(r.uniform(0.2, 0.6, n) * fs).tolist())

    def payload():
        m = r.uniform(*R["payload_mass"])
        return dict(type="payload", link=n, mass=float(m), com=[float(x) for x in R["payload_com"](r)],
                    radius=float(r.uniform(0.03, 0.05)))

    if case == "clean":
        pass
    elif case == "viscous":
        eff.append(viscous())
    elif case == "coulomb":
        eff.append(coulomb())
    elif case == "gaz":
        if robot == "panda":
            p1 = np.array(GAZ_PHI1) * r.uniform(0.7, 1.3, n)
            p2 = np.array(GAZ_PHI2) * r.uniform(0.7, 1.3, n)
            p3 = np.array(GAZ_PHI3) * r.uniform(0.7, 1.3, n)
        else:
            p1 = r.uniform(0.5, 1.2, n) * fs
            p2 = r.uniform(5.0, 17.0, n)
            p3 = r.uniform(-0.04, 0.04, n)
        eff.append(dict(type="gaz", phi1=p1.tolist(), phi2=p2.tolist(), phi3=p3.tolist()))
    elif case == "stribeck":
        j = int(r.integers(1, n + 1))
        fc = r.uniform(0.2, 0.5) * fs[j - 1]
        eff.append(dict(type="stribeck", joint=j, coulomb=float(fc), excess=float(r.uniform(0.5, 1.0) * fc),
                        velocity=float(r.uniform(0.08, 0.2))))
    elif case == "armature":
        j = pick(R["wrist"])
        eff.append(dict(type="armature", joint=j, inertia=float(r.uniform(*R["armature"]))))
    elif case == "payload":
        eff.append(payload())
    elif case == "heavier_link":
        k = pick(R["links"])
        eff.append(dict(type="heavier_link", link=k, factor=float(r.uniform(1.10, 1.25))))
    elif case == "whole_link":
        k = pick(R["links"])
        mf = r.uniform(1.15, 1.30) if r.random() < 0.5 else r.uniform(0.75, 0.85)
        d = r.normal(size=3); d *= r.uniform(0.02, 0.04) / np.linalg.norm(d)
        eff.append(dict(type="whole_link", link=k, mass_factor=float(mf), com_shift=d.tolist(),
                        inertia_factor=float(r.uniform(0.7, 1.4))))
    elif case == "torque_scale":
        j = pick(R["scale_joints"])
        s = 1.0 + r.choice([-1, 1]) * r.uniform(0.05, 0.2)
        eff.append(dict(type="torque_scale", joint=j, scale=float(s)))
    elif case == "torque_offset":
        j = int(r.integers(1, n + 1))
        eff.append(dict(type="torque_offset", joint=j, rel=float(r.choice([-1, 1]) * r.uniform(0.05, 0.15))))
    elif case == "torque_delay":
        eff.append(dict(type="torque_delay", samples=int(r.integers(2, 6))))
    elif case == "tilt":
        ang = r.uniform(1.0, 3.0)
        az = r.uniform(0, 2 * np.pi)
        eff.append(dict(type="tilt", deg=float(ang), axis=[float(np.cos(az)), float(np.sin(az)), 0.0]))
    elif case == "spring":
        j = int(r.integers(1, n + 1))
        eff.append(dict(type="spring", joint=j, rel=float(r.uniform(0.1, 0.3)), rest_u=float(r.uniform(-1, 1))))
    elif case == "asym_coulomb":
        j = int(r.integers(1, n + 1))
        c = r.uniform(0.3, 0.6) * fs[j - 1]
        a = r.choice([-1, 1]) * r.uniform(0.3, 0.6) * c
        eff.append(dict(type="asym_coulomb", joint=j, coulomb=float(c), asymmetry=float(a)))
    elif case == "combo":
        eff.append(viscous())
        eff.append(coulomb())
        eff.append(payload())
        j = int(r.integers(1, n + 1))
        eff.append(dict(type="torque_offset", joint=j, rel=float(r.choice([-1, 1]) * r.uniform(0.05, 0.15))))
    else:
        raise ValueError(case)
    return eff


def plant_model(desc, effects):
    """Pinocchio model of the plant: the description with inertial hidden effects and tilt."""
    inertias = [desc.link_inertia(k) for k in range(desc.n)]
    g = desc.gravity.copy()
    for e in effects:
        if e["type"] == "payload":
            k = e["link"] - 1
            inertias[k] = inertias[k] + pin.Inertia(e["mass"], np.array(e["com"]), sphere(e["mass"], e["radius"]))
        elif e["type"] == "heavier_link":
            k = e["link"] - 1
            I = inertias[k]
            inertias[k] = pin.Inertia(I.mass * e["factor"], I.lever.copy(), I.inertia * e["factor"])
        elif e["type"] == "whole_link":
            k = e["link"] - 1
            I = inertias[k]
            inertias[k] = pin.Inertia(I.mass * e["mass_factor"], I.lever + np.array(e["com_shift"]),
                                      I.inertia * e["inertia_factor"])
        elif e["type"] == "tilt":
            Rm = pin.exp3(np.array(e["axis"]) * np.deg2rad(e["deg"]))
            g = Rm @ g
    return desc.build(inertias=inertias, gravity=g), inertias, g


def joint_torques(effects, Q, QD, QDD, rigid, resolved):
    """Joint-space hidden torques (friction, armature, spring, offset)."""
    n = Q.shape[1]
    T = np.zeros_like(Q)
    sg = np.tanh(QD / EPS)
    for e in effects:
        t = e["type"]
        if t == "viscous":
            T += QD * np.array(e["b"])
        elif t == "coulomb":
            T += sg * np.array(e["c"])
        elif t == "gaz":
            p1, p2, p3 = (np.array(e[k]) for k in ("phi1", "phi2", "phi3"))
            T += p1 / (1 + np.exp(-p2 * (QD + p3))) - p1 / (1 + np.exp(-p2 * p3))
        elif t == "stribeck":
            j = e["joint"] - 1
            v = QD[:, j]
            T[:, j] += (e["coulomb"] + e["excess"] * np.exp(-(v / e["velocity"]) ** 2)) * np.tanh(v / EPS)
        elif t == "armature":
            j = e["joint"] - 1
            T[:, j] += e["inertia"] * QDD[:, j]
        elif t == "asym_coulomb":
            j = e["joint"] - 1
            s = np.tanh(QD[:, j] / EPS)
            T[:, j] += e["coulomb"] * s + e["asymmetry"] * np.abs(s)
        elif t == "spring":
            j = e["joint"] - 1
            T[:, j] += resolved["spring_k"] * (Q[:, j] - resolved["spring_rest"])
        elif t == "torque_offset":
            j = e["joint"] - 1
            T[:, j] += resolved[f"offset_{j+1}"]
    return T


def resolve(effects, desc, Qs, rigid_rms):
    """Turn relative sizes into absolute values, from the first recording's motion and torque RMS."""
    res = {}
    for e in effects:
        if e["type"] == "torque_offset":
            j = e["joint"] - 1
            res[f"offset_{j+1}"] = e["rel"] * rigid_rms[j]
            e["offset"] = res[f"offset_{j+1}"]
        elif e["type"] == "spring":
            j = e["joint"] - 1
            q = np.concatenate([Q[:, j] for Q in Qs])
            rest = q.mean() + e["rest_u"] * q.std()
            rms = np.sqrt(np.mean((q - rest) ** 2))
            k = e["rel"] * rigid_rms[j] / rms
            res["spring_k"] = k; res["spring_rest"] = rest
            e["stiffness"] = float(k); e["rest"] = float(rest)
    return res


def rate_for(robot, case, seed):
    r = rng_for(robot, case, seed, "rate")
    return float(r.choice([1000.0, 1000.0, 1000.0, 500.0, 200.0]))


def qd_mode_for(robot, case, seed):
    """'noise': the true velocity plus white noise of 0.02 rad/s; 'diff': central
    differences of the noisy positions (one case in four)."""
    r = rng_for(robot, case, seed, "qdmode")
    return "diff" if r.random() < 0.25 else "noise"


def generate(robot, case, seed, outdir, nrec=3, duration=20.0):
    os.makedirs(outdir, exist_ok=True)
    R = ROBOTS[robot]
    desc = Description(R["toml"])
    n = desc.n
    effects = draw_case(robot, case, seed)
    rate = rate_for(robot, case, seed)
    qd_mode = qd_mode_for(robot, case, seed)
    dt = 1.0 / rate
    t = np.arange(int(round(duration * rate))) * dt
    model, inertias, g = plant_model(desc, effects)
    data = model.createData()
    nominal = desc.build()
    ndata = nominal.createData()
    rn = rng_for(robot, case, seed, "noise")
    trajs = []
    for i in range(nrec):
        re = rng_for(robot, case, seed, "excitation", i)
        ev, spec = excitation(re, robot, desc, t)
        trajs.append((*ev(t), spec, ev))
    # torque RMS of the nominal rigid body over the recordings: the scale of offsets, springs, noise
    rigid_all = []
    for Q, QD, QDD, _, _ in trajs:
        rigid_all.append(np.array([pin.rnea(nominal, ndata, Q[i], QD[i], QDD[i]) for i in range(0, len(t), 10)]))
    rigid_rms = np.sqrt(np.mean(np.concatenate(rigid_all) ** 2, axis=0))
    # a sensor's noise floor: a joint whose rigid-body torque is tiny (a wrist roll
    # turning a symmetric flange) still sees noise of about 1% of its friction scale
    rigid_rms = np.maximum(rigid_rms, np.array(R["fs"]))
    resolved = resolve(effects, desc, [tr[0] for tr in trajs], rigid_rms)
    delay = next((e["samples"] for e in effects if e["type"] == "torque_delay"), 0)
    scale = np.ones(n)
    for e in effects:
        if e["type"] == "torque_scale":
            scale[e["joint"] - 1] = e["scale"]
    noise_rel = float(rn.uniform(0.01, 0.02))
    files = []
    meta = []
    for i, (Q, QD, QDD, spec, ev) in enumerate(trajs):
        if delay:
            # the torque logged at t is the one at t - delay: the motion there (analytic)
            Qd, QDd, QDDd = ev(t - delay * dt)
        else:
            Qd, QDd, QDDd = Q, QD, QDD
        tau = np.array([pin.rnea(model, data, Qd[k], QDd[k], QDDd[k]) for k in range(len(t))])
        tau += joint_torques(effects, Qd, QDd, QDDd, None, resolved)
        tau *= scale
        sig = noise_rel * rigid_rms
        qn = Q + rn.normal(0, 1e-4, Q.shape)
        if qd_mode == "diff":
            qdn = np.gradient(qn, dt, axis=0)
        else:
            qdn = QD + rn.normal(0, 0.02, QD.shape)
        taun = tau + rn.normal(0, 1, tau.shape) * sig
        path = os.path.join(outdir, f"rec{i+1}.csv")
        hdr = ",".join(["t"] + [f"q{j+1}" for j in range(n)] + [f"qd{j+1}" for j in range(n)] + [f"tau{j+1}" for j in range(n)])
        np.savetxt(path, np.column_stack([t, qn, qdn, taun]), delimiter=",", header=hdr, comments="", fmt="%.9g")
        files.append(path)
        meta.append(spec)
    truth = dict(robot=robot, case=case, seed=seed, toml=R["toml"], dof=n, rate_hz=rate,
                 duration_s=duration, noise=dict(q=1e-4, qd=(0.02 if qd_mode == "noise" else "central differences of noisy q"), tau_rel=noise_rel, tau_sigma=(noise_rel * rigid_rms).tolist()),
                 rigid_rms=rigid_rms.tolist(), effects=effects, excitation=meta,
                 link_names=[m["link_name"] for m in desc.moving],
                 nominal_links=[dict(mass=float(I.mass), com=I.lever.tolist(), inertia=I.inertia.tolist()) for I in (desc.link_inertia(k) for k in range(n))],
                 plant_links=[dict(mass=float(I.mass), com=I.lever.tolist(), inertia=I.inertia.tolist()) for I in inertias],
                 plant_gravity=list(map(float, g)), files=files)
    with open(os.path.join(outdir, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
    return truth


if __name__ == "__main__":
    import sys
    robot, case, seed, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
    tr = generate(robot, case, seed, out)
    print(json.dumps(dict(effects=tr["effects"], rate=tr["rate_hz"], rms=tr["rigid_rms"]), indent=1))

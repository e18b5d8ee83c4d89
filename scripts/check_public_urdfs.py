#!/usr/bin/env python3
"""Issue 22's acceptance check on public URDF collections.

For each fixed-base chain in CHAINS (serial arms whole; arms of humanoids and
mobile manipulators cut base -> tip; grippers; prismatic lifts), this script
imports the unmodified URDF with `sdnn import-urdf`, computes torques on
random states with `sdnn tau` (the numeric path) and with the generated Rust
code (`sdnn-codegen` output compiled by `rustc` into a small harness, the
generated path), and compares both with Pinocchio's RNEA on the same chain.
It writes a markdown table (default `docs/public-urdf-results.md`).

The chain contract (the importer's): the moving joints on the path
base -> tip are the degrees of freedom; every other moving joint is held at 0
or at its `--lock` value; a mimic joint follows its master
(q = multiplier * q_master + offset), so a mimic joint on the chain is driven
by its master's DOF and a held master holds its mimics (a mimic of a joint
the file lacks, as in Alex's hands, is taken as a plain joint); links above the base
never move. URDF damping and friction add damping * qd + friction * sign(qd)
(the importer's viscous and Coulomb effects).

Reference (Pinocchio): the model is built from the whole URDF with its root
fixed in the world (`buildModelFromUrdf`, no root joint; a `floating` joint in
the file is locked at its neutral pose), every joint not driven by a DOF is
locked at its held value with `buildReducedModel` (where Pinocchio refuses,
the full model with those joints at their values and at rest, which gives the
same chain torques), and `rnea` runs with
gravity (0, 0, -9.81) in the URDF root frame. So the base keeps its world
placement with everything above it held, which is the same as re-rooting the
tree at the base with gravity rotated into the base frame. A mimic joint on
the chain stays in the reduced model, and its torque times the multiplier is
added to its master's.

Data, not committed: the URDFs come from the PyPI package example-robot-data
6.0.0 (github.com/gepetto/example-robot-data, package licence BSD-3-Clause;
the robot descriptions keep their own licences, as listed in its
package.xml: BSD-2-Clause, BSD-3-Clause, BSD, Apache-2.0, ISC, MPL-2.0,
CC-BY-SA-4.0 and CC-BY-NC-ND-4.0 among them; per-robot LICENSE files: Panda
and Alexander Apache-2.0, Baxter (Rethink Robotics) BSD-style, ANYmal C
BSD-3, qbrobotics two-DOF BSD-3). They are read in place from the package
installed into a virtual environment and never copied into the repository.
Pinocchio: PyPI `pin` 4.1.0 (BSD-2-Clause).

Usage (from the repository root, after `cargo build --release --locked`):

    python3 scripts/check_public_urdfs.py [--generated] [--only NAME ...]

`--generated` also checks the generated path; it builds `sdnn-codegen`
(`cargo build --locked -p sdnn-codegen`, a few minutes the first time)
unless `--codegen PATH` names a built one. The virtual environment goes to
`target/public-urdfs/venv` (override with `--venv`), scratch files to
`target/public-urdfs/work`.
"""

import argparse
import math
import os
import random
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

PACKAGES = ["example-robot-data==6.0.0", "pin==4.1.0"]
SAMPLES = 200
ROBOTS = "cmeel.prefix/share/example-robot-data/robots"

# name, URDF under the package's robots/, base link, tip link, locks, what it shows
CHAINS = [
    ("panda_hand", "panda_description/urdf/panda.urdf", "panda_link0", "panda_hand_tcp", {},
     "serial arm, hand with two prismatic fingers (one mimic) held"),
    ("panda_hand_open", "panda_description/urdf/panda.urdf", "panda_link0", "panda_hand_tcp",
     {"panda_finger_joint1": 0.04}, "fingers locked open, the mimic follows"),
    ("panda_to_finger", "panda_description/urdf/panda.urdf", "panda_link0", "panda_leftfinger", {},
     "arm to a finger (8 DOF): the other finger follows it off the chain, coupled"),
    ("ur5_gripper", "ur_description/urdf/ur5_gripper.urdf", "world", "tool0", {},
     "serial arm, massless tool frames"),
    ("ur10", "ur_description/urdf/ur10_robot.urdf", "base_link", "tool0", {}, "serial arm"),
    ("jaco_j2s6s200", "kinova_description/robots/kinova.urdf", "base", "j2s6s200_end_effector", {},
     "continuous joints, zero-mass base, fixed fingers"),
    ("xarm7", "xarm_description/urdf/xarm7.urdf", "world", "link7", {}, "serial arm"),
    ("z1_with_gripper_joint", "z1_description/urdf/z1.urdf", "world", "gripperMover", {},
     "gripper joint on the chain"),
    ("z1_arm", "z1_description/urdf/z1.urdf", "world", "link06", {}, "gripper joint held"),
    ("so101", "so_arm_description/urdf/so101.urdf", "base_link", "gripper_link", {},
     "small arm, jaw held"),
    ("finger_edu", "finger_edu_description/robots/finger_edu.urdf", "base_link", None, {},
     "three-joint finger"),
    ("double_pendulum_continuous", "double_pendulum_description/urdf/double_pendulum_continuous.urdf",
     "base_link", None, {}, "continuous joints"),
    ("tiago_lift_arm_hand", "tiago_description/robots/tiago.urdf", "base_footprint", "hand_palm_link", {},
     "prismatic torso lift under the arm, 25 hand joints held"),
    ("tiago_no_hand", "tiago_description/robots/tiago_no_hand.urdf", "torso_lift_link", "arm_tool_link", {},
     "arm cut above the lift (links above the base dropped)"),
    ("tiago_pro_left", "tiago_pro_description/robots/tiago_pro.urdf", "base_footprint",
     "gripper_left_base_link", {}, "lift + left arm, mimic gripper held"),
    ("talos_left_arm", "talos_data/robots/talos_left_arm.urdf", "arm_left_1_link", "gripper_left_base_link", {},
     "mimic tags on fixed joints, gripper held"),
    ("talos_left_arm_cut", "talos_data/robots/talos_full_v2.urdf", "torso_2_link", "gripper_left_base_link",
     {"gripper_left_joint": 0.3}, "humanoid arm, gripper master locked, six mimic joints follow"),
    ("talos_torso_to_arm", "talos_data/robots/talos_full_v2.urdf", "base_link", "arm_left_7_link", {},
     "torso joints on the chain, legs/head/other arm held"),
    ("baxter_right", "baxter_description/urdf/baxter.urdf", "right_arm_mount", "right_gripper_base_link", {},
     "two-arm robot, prismatic mimic fingers held"),
    ("pr2_right_arm", "pr2_description/urdf/pr2.urdf", "torso_lift_link", "r_gripper_palm_link", {},
     "mobile manipulator arm, gripper with five mimic joints held"),
    ("pr2_lift_right_arm", "pr2_description/urdf/pr2.urdf", "base_footprint", "r_gripper_palm_link",
     {"r_gripper_l_finger_joint": 0.3}, "prismatic torso lift on the chain, gripper locked"),
    ("b1_z1", "b1_description/urdf/b1-z1.urdf", "trunk", "gripperStator", {},
     "arm on a quadruped, legs held"),
    ("anymal_kinova", "anymal_b_simple_description/robots/anymal-kinova.urdf", "base",
     "j2s6s200_end_effector", {}, "arm on a quadruped"),
    ("romeo_left_arm", "romeo_description/urdf/romeo.urdf", "torso", "l_gripper", {},
     "humanoid arm, mimic hand held"),
    ("icub_left_arm", "icub_description/robots/icub.urdf", "chest", "l_hand", {},
     "humanoid arm with an F/T sensor frame"),
    ("g1_left_arm", "g1_description/urdf/g1_29dof_with_hand_rev_1_0.urdf", "torso_link",
     "left_hand_palm_link", {}, "humanoid arm, hand joints held"),
    ("alex_left_arm", "alex_description/urdf/alex_psyonic_hands.urdf", "Torso", "LeftGripperYawLink", {},
     "humanoid arm, mimic fingers held"),
]


# ----------------------------------------------------------------- setup --

def ensure_venv(venv: Path):
    """Re-runs this script inside a venv with PACKAGES installed."""
    try:
        import pinocchio  # noqa: F401
        return
    except ImportError:
        pass
    python = venv / "bin" / "python"
    if os.environ.get("CHECK_URDFS_IN_VENV"):
        sys.exit("pinocchio is not importable inside the virtual environment")
    if not python.exists():
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        subprocess.run([str(python), "-m", "pip", "install", "-q", *PACKAGES], check=True)
    env = dict(os.environ, CHECK_URDFS_IN_VENV="1")
    os.execve(str(python), [str(python), *sys.argv], env)


def robots_dir() -> Path:
    import pinocchio
    for parent in Path(pinocchio.__file__).resolve().parents:
        if (parent / ROBOTS).is_dir():
            return parent / ROBOTS
    sys.exit(f"example-robot-data's {ROBOTS} not found beside pinocchio")


# --------------------------------------------------------- the contract --

def read_joints(urdf: Path):
    """joint name -> dict(type, parent, child, mimic, lower, upper)."""
    joints = {}
    for j in ET.parse(urdf).getroot().findall("joint"):
        mimic = j.find("mimic")
        limit = j.find("limit")
        joints[j.get("name")] = {
            "type": j.get("type"),
            "parent": j.find("parent").get("link"),
            "child": j.find("child").get("link"),
            "mimic": None if mimic is None else (
                mimic.get("joint"),
                float(mimic.get("multiplier", 1.0)),
                float(mimic.get("offset", 0.0)),
            ),
            "lower": None if limit is None or limit.get("lower") is None else float(limit.get("lower")),
            "upper": None if limit is None or limit.get("upper") is None else float(limit.get("upper")),
        }
    return joints


MOVING = ("revolute", "continuous", "prismatic")


def chain_path(joints, base, tip):
    by_child = {j["child"]: n for n, j in joints.items()}
    if tip is None:  # the one leaf below base
        children = {}
        for n, j in joints.items():
            children.setdefault(j["parent"], []).append(j["child"])
        tip = base
        while children.get(tip):
            (tip,) = children[tip]
    path, link = [], tip
    while link != base:
        name = by_child[link]
        path.append(name)
        link = joints[name]["parent"]
    return list(reversed(path)), tip


def drives(joints, path, locks):
    """joint -> ('dof', k, a, b) | ('held', value); and the DOF names."""
    out, dofs = {}, []
    for n in path:
        j = joints[n]
        if j["type"] in MOVING and j["mimic"] is None and n not in locks:
            out[n] = ("dof", len(dofs), 1.0, 0.0)
            dofs.append(n)

    def resolve(n, depth=0):
        if n in out:
            return out[n]
        j = joints[n]
        if j["type"] not in MOVING:
            d = ("held", 0.0)
        elif n in locks:
            d = ("held", locks[n])
        elif j["mimic"] is not None and j["mimic"][0] in joints:
            master, m, o = j["mimic"]
            md = resolve(master, depth + 1)
            d = ("held", m * md[1] + o) if md[0] == "held" else ("dof", md[1], m * md[2], m * md[3] + o)
        else:  # not a mimic (or mimicking a joint the file lacks): held at 0
            d = ("held", 0.0)
        out[n] = d
        return d

    for n in joints:
        resolve(n)
    return out, dofs


def states(joints, dofs, seed):
    rng = random.Random(seed)
    rows = []
    for _ in range(SAMPLES):
        q, qd, qdd = [], [], []
        for n in dofs:
            j = joints[n]
            prismatic = j["type"] == "prismatic"
            lo = j["lower"] if j["lower"] is not None and j["type"] != "continuous" else -math.pi
            hi = j["upper"] if j["upper"] is not None and j["type"] != "continuous" else math.pi
            q.append(rng.uniform(lo, hi))
            qd.append(rng.uniform(-1, 1) * (0.3 if prismatic else 2.0))
            qdd.append(rng.uniform(-1, 1) * (1.0 if prismatic else 5.0))
        rows.append((q, qd, qdd))
    return rows


# ------------------------------------------------------------ reference --

def pinocchio_torques(urdf: Path, joints, drive, dofs, rows):
    import numpy as np
    import pinocchio as pin

    full = pin.buildModelFromUrdf(str(urdf))
    q_ref = pin.neutral(full)

    def put(model, q, name, value):
        jm = model.joints[model.getJointId(name)]
        if jm.nq == 1:
            q[jm.idx_q] = value
        elif jm.nq == 2:  # continuous: cos, sin
            q[jm.idx_q:jm.idx_q + 2] = [math.cos(value), math.sin(value)]
        else:
            raise ValueError(f"joint {name}: nq {jm.nq}")

    lock_ids, driven = [], []
    for jid in range(1, full.njoints):
        name = full.names[jid]
        d = drive.get(name)
        if d is None or full.joints[jid].nq > 2:  # floating or planar: neutral
            lock_ids.append(jid)
        elif d[0] == "held":
            put(full, q_ref, name, d[1])
            lock_ids.append(jid)
        else:
            driven.append(name)
    try:
        model = pin.buildReducedModel(full, lock_ids, q_ref)
        start = pin.neutral(model)
    except ValueError:
        # Pinocchio 4.1 refuses to reduce a model where a joint and a link
        # share a name (z1's `gripperStator`). The full model with the held
        # joints at their values and at rest gives the same chain torques.
        model, start = full, q_ref
    data = model.createData()
    out = []
    for q_dof, qd_dof, qdd_dof in rows:
        q = start.copy()
        v, a = np.zeros(model.nv), np.zeros(model.nv)
        for name in driven:
            _, k, m, b = drive[name]
            put(model, q, name, m * q_dof[k] + b)
            iv = model.joints[model.getJointId(name)].idx_v
            v[iv], a[iv] = m * qd_dof[k], m * qdd_dof[k]
        tau_all = pin.rnea(model, data, q, v, a)
        tau = [0.0] * len(dofs)
        for name in driven:
            _, k, m, _ = drive[name]
            iv = model.joints[model.getJointId(name)].idx_v
            vel = float(v[iv])
            sign = (vel > 0) - (vel < 0)
            tau[k] += m * (tau_all[iv] + model.damping[iv] * vel + model.friction[iv] * sign)
        out.append(tau)
    return out


# ------------------------------------------------------------- product --

def run(cmd, **kw):
    return subprocess.run(cmd, capture_output=True, text=True, **kw)


def write_states(path: Path, rows, n):
    header = [f"{c}{i}" for c in ("q", "qd", "qdd") for i in range(1, n + 1)]
    with open(path, "w") as f:
        f.write(",".join(header) + "\n")
        for q, qd, qdd in rows:
            f.write(",".join(repr(x) for x in (*q, *qd, *qdd)) + "\n")


def read_csv(path: Path):
    lines = path.read_text().strip().splitlines()[1:]
    return [[float(x) for x in line.split(",")] for line in lines]


def moving_joints_of(toml_path: Path):
    import tomllib
    doc = tomllib.loads(toml_path.read_text())
    return [j["name"] for j in doc.get("joints", [])
            if j.get("type") != "fixed" and "locked" not in j and "mimic" not in j]


def max_relative(got, want):
    worst = 0.0
    for g, w in zip(got, want):
        if len(g) != len(w):
            return float("inf")
        scale = max(1.0, max(abs(x) for x in w))
        worst = max(worst, max(abs(a - b) for a, b in zip(g, w)) / scale)
    return worst


HARNESS = """#![allow(warnings, clippy::all)]
mod model {{
    include!("{file}");
}}
use std::io::BufRead;
fn main() {{
    const N: usize = model::DOF;
    for line in std::io::stdin().lock().lines().skip(1) {{
        let x: Vec<f64> = line.unwrap().split(',').map(|v| v.parse().unwrap()).collect();
        let mut q = [0.0; N];
        let mut qd = [0.0; N];
        let mut qdd = [0.0; N];
        q.copy_from_slice(&x[..N]);
        qd.copy_from_slice(&x[N..2 * N]);
        qdd.copy_from_slice(&x[2 * N..3 * N]);
        let t = model::tau(&q, &qd, &qdd);
        let s: Vec<String> = t.iter().map(|v| format!("{{v:?}}")).collect();
        println!("{{}}", s.join(","));
    }}
}}
"""


def generated_torques(codegen: Path, toml: Path, states_csv: Path, work: Path):
    gen_dir = work / "gen"
    gen_dir.mkdir(exist_ok=True)
    copy = gen_dir / toml.name
    copy.write_text(toml.read_text())
    r = run([str(codegen), "--force", str(copy)], timeout=1800)
    if r.returncode != 0:
        return None, "codegen: " + (r.stderr.strip().splitlines() or ["failed"])[-1]
    m = re.search(r"regenerated\s+(\S+)", r.stdout)
    generated = Path(m.group(1)) if m else gen_dir / "generated" / f"{toml.stem}.rs"
    harness = gen_dir / f"{toml.stem}_harness.rs"
    harness.write_text(HARNESS.format(file=str(generated.resolve())))
    exe = gen_dir / f"{toml.stem}_harness"
    r = run(["rustc", "--edition", "2024", "-O", "-o", str(exe), str(harness)], timeout=1800)
    if r.returncode != 0:
        return None, "rustc: " + (r.stderr.strip().splitlines() or ["failed"])[0]
    r = run([str(exe)], stdin=open(states_csv), timeout=600)
    if r.returncode != 0:
        return None, "harness: " + (r.stderr.strip().splitlines() or ["failed"])[-1]
    return [[float(x) for x in line.split(",")] for line in r.stdout.strip().splitlines()], None


# ----------------------------------------------------------------- main --

def check(chain, robots: Path, sdnn: Path, codegen, work: Path):
    name, file, base, tip, locks, note = chain
    urdf = robots / file
    joints = read_joints(urdf)
    path, tip = chain_path(joints, base, tip)
    drive, dofs = drives(joints, path, locks)
    row = {"name": name, "file": file, "chain": f"{base} -> {tip}", "locks": locks,
           "dof": len(dofs), "note": note, "import": "", "numeric": "", "generated": ""}
    toml = (work / f"{name}.toml").resolve()
    cmd = [str(sdnn), "import-urdf", file, "--base", base, "--tip", tip, "--name", name,
           "--out", str(toml)]
    for j, v in locks.items():
        cmd += ["--lock", f"{j}={v}"]
    r = run(cmd, cwd=robots)  # messages name the file relative to the collection
    errors = [line for line in r.stderr.splitlines() if line.startswith("sdnn:")]
    if r.returncode != 0:
        message = " ".join(" ".join(errors).split()).replace(f"{work}/", "")
        row["import"] = "error: " + message[:300]
        return row
    dropped = sum("dropped the branch" in line for line in r.stderr.splitlines())
    row["import"] = "ok" + (f" (warns: dropped {dropped} moving branch(es))" if dropped else "")
    got_dofs = moving_joints_of(toml)
    if got_dofs != dofs:
        row["import"] += f", but DOFs {got_dofs} != {dofs}"
        return row
    rows = states(joints, dofs, seed=22)
    want = pinocchio_torques(urdf, joints, drive, dofs, rows)
    states_csv, tau_csv = work / f"{name}_states.csv", work / f"{name}_tau.csv"
    write_states(states_csv, rows, len(dofs))
    r = run([str(sdnn), "tau", "--model", str(toml), "--input", str(states_csv), "--output", str(tau_csv)])
    if r.returncode != 0:
        row["numeric"] = "error: " + " ".join(r.stderr.split())[:300]
    else:
        row["numeric"] = f"{max_relative(read_csv(tau_csv), want):.1e}"
    if codegen:
        got, error = generated_torques(codegen, toml, states_csv, work)
        row["generated"] = error if error else f"{max_relative(got, want):.1e}"
    return row


def table(rows, generated: bool):
    out = ["| chain | URDF (example-robot-data 6.0.0) | base -> tip | locks | DOF | import | "
           "numeric max rel. error | generated max rel. error | what it shows |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        locks = ", ".join(f"{k}={v}" for k, v in r["locks"].items()) or "-"
        gen = r["generated"] or ("not run" if r["numeric"] and not generated else "-")
        cells = [r["name"], r["file"], r["chain"], locks, str(r["dof"]), r["import"].replace("|", "/"),
                 r["numeric"] or "-", gen.replace("|", "/"), r["note"]]
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def main():
    repo = Path(__file__).resolve().parent.parent
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sdnn", default=str(repo / "target/release/sdnn"))
    p.add_argument("--generated", action="store_true", help="also check the generated code")
    p.add_argument("--codegen", help="a built sdnn-codegen (default: cargo builds one)")
    p.add_argument("--venv", default=str(repo / "target/public-urdfs/venv"))
    p.add_argument("--work", default=str(repo / "target/public-urdfs/work"))
    p.add_argument("--out", default=str(repo / "docs/public-urdf-results.md"))
    p.add_argument("--label", default="", help="a line written above the table")
    p.add_argument("--only", nargs="*", help="chain names to run")
    args = p.parse_args()
    ensure_venv(Path(args.venv))
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    codegen = None
    if args.generated:
        codegen = args.codegen
        if not codegen:
            subprocess.run(["cargo", "build", "--locked", "-p", "sdnn-codegen"], cwd=repo, check=True)
            codegen = str(repo / "target/debug/sdnn-codegen")
        codegen = str(Path(codegen).resolve())
    robots = robots_dir()
    rows = []
    for chain in CHAINS:
        if args.only and chain[0] not in args.only:
            continue
        try:
            row = check(chain, robots, Path(args.sdnn).resolve(), codegen, work.resolve())
        except Exception as e:  # a broken reference is reported, not hidden
            row = {"name": chain[0], "file": chain[1], "chain": f"{chain[2]} -> {chain[3]}",
                   "locks": chain[4], "dof": "?", "note": chain[5], "import": f"script error: {e!r}",
                   "numeric": "", "generated": ""}
        print(f"{row['name']:28} import {row['import'][:90]:90} numeric {row['numeric']:>9} "
              f"generated {row['generated']}", flush=True)
        rows.append(row)
    text = "# Public URDF chains against Pinocchio\n\n"
    text += "Written by `scripts/check_public_urdfs.py` (see its header for provenance and licences).\n\n"
    if args.label:
        text += args.label + "\n\n"
    text += table(rows, args.generated)
    Path(args.out).write_text(text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Issue 25's second real arm: `sdnn diagnose --apply` on a UR10e's public
identification data against ordinary least squares on the same files.

Data: the `dataset_ur10e` folder of github.com/shamilmamedov/dynamic_calibration
(Innopolis University; the repository states no licence, so the data are
fetched into `target/`, never committed). Each CSV holds t, q1..6, qd1..6 and
the motor currents; torque = drive gain x current with the gains the
repository's `main.m` quotes. Model: the repository's `URe/urdf/ur10e.urdf`
through `sdnn import-urdf`, as is.

For each identification set (three recordings, and each one alone) the
script runs `diagnose --apply` into a copy of the imported TOML, then
`evaluate` on five validation runs. Least squares (Pinocchio's joint-torque
regressor, 60 inertial parameters, plus per joint viscous, Coulomb and
offset columns, `vco`, and an armature, `vcoa`; the minimum-norm correction
of the URDF's values) is fitted on the same files and both models are
compared as `evaluate` compares: model torque on the filtered full-rate
states (`sdnn preprocess --rate` at the recording's rate), both torques
through the same zero-phase Butterworth, one cut-off period trimmed at each
end. The applied model is scored in that emulation too, so every ratio
compares the same pipeline. Corrections the diagnosis prints (`--torque-scale`,
`--torque-delay`) are passed to `evaluate` and listed; the emulation scores the
applied model alone. Results: docs/diagnosis-measured.md, "A second
real arm".
"""

import argparse
import io
import json
import re
import subprocess
import sys
from pathlib import Path

from check_public_urdfs import ensure_venv

SOURCE = "https://github.com/shamilmamedov/dynamic_calibration"
GAINS = [14.87, 13.26, 11.13, 10.62, 11.03, 11.47]  # N m/A, the repository's main.m
IDENTIFICATION = ["ur-20_02_10-30sec_12harm", "ur-20_02_12-40sec_12harm", "ur-20_02_12-50sec_12harm"]
VALIDATION = ["ur-20_02_05-20sec_12harm", "ur-20_02_05-20sec_8harm", "ur-20_02_06-20sec_10harm",
              "ur-20_02_06-20sec_5harm", "ur-20_02_10-20sec_7harm"]
LOADED = ("ur-20_02_19_14harm50secLoad", 2.805)  # kg, the repository's estimate_drive_gains.m


def fetch(work: Path) -> Path:
    repo = work / "dynamic_calibration"
    if not repo.exists():
        subprocess.run(["git", "clone", "-q", "--depth", "1", SOURCE, str(repo)], check=True)
    return repo


def convert(source: Path, out: Path):
    """The repository's CSV (no header) to the trajectory contract."""
    names = ["t"] + [f"{p}{j}" for p in ("q", "qd", "tau") for j in range(1, 7)]
    lines = [",".join(names)]
    for line in source.read_text().splitlines():
        v = [float(x) for x in line.split(",")]
        tau = [c * g for c, g in zip(v[13:19], GAINS)]
        lines.append(",".join(repr(x) for x in v[0:13] + tau))
    out.write_text("\n".join(lines) + "\n")


def sdnn(binary, *args) -> subprocess.CompletedProcess:
    return subprocess.run([binary, *map(str, args)], capture_output=True, text=True, check=True)


def evaluate_mse(binary, toml, files, corrections=()):
    out = sdnn(binary, "evaluate", "--model", toml, "--data", *files, *corrections,
               "--format", "json").stdout
    return json.loads(out)["mse"]


def printed_corrections(report: str) -> list:
    """The `--torque-scale J=S` and `--torque-delay S` a diagnosis printed."""
    return [a for c in re.findall(r'--torque-(?:scale|delay) [^\s"]+', report) for a in c.split()]


class Filtered:
    """One recording's filtered full-rate states and torque, and the filter."""

    def __init__(self, binary, csv: Path, work: Path):
        import numpy as np
        done = sdnn(binary, "preprocess", "--rate", 100, csv, "--out", work)
        self.cutoff = float(re.search(r"low-pass at ([0-9.]+) Hz", done.stderr).group(1))
        self.path = work / csv.name
        a = np.genfromtxt(self.path, delimiter=",", names=True)
        column = lambda p: np.stack([a[f"{p}{j}"] for j in range(1, 7)], 1)
        self.q, self.qd, self.qdd, self.tau = column("q"), column("qd"), column("qdd"), column("tau")
        self.rate = 1.0 / np.median(np.diff(a["t"]))
        n, trim = len(a), int(np.ceil(self.rate / self.cutoff))
        self.keep = slice(trim, n - trim) if n > 8 * trim else slice(0, n)

    def smooth(self, x):
        """The zero-phase 4th-order Butterworth low-pass of each column."""
        import numpy as np
        x = np.array(x, dtype=float)
        for _ in range(2):
            for b, a in butterworth_sections(self.cutoff, self.rate):
                x = second_order(b, a, x)
            x = x[::-1]
        return x


def butterworth_sections(cutoff, rate, order=4):
    """Second-order sections of the digital Butterworth (bilinear, prewarped)."""
    import numpy as np
    w, k = 2 * rate * np.tan(np.pi * cutoff / rate), 2 * rate
    sections = []
    for i in range(order // 2):
        angle = np.pi * (2 * i + 1) / (2 * order)
        a1, a0 = 2 * w * np.sin(angle), w * w  # s^2 + a1 s + a0
        d0, d1, d2 = k * k + a1 * k + a0, 2 * a0 - 2 * k * k, k * k - a1 * k + a0
        sections.append((np.array([a0, 2 * a0, a0]) / d0, np.array([1.0, d1 / d0, d2 / d0])))
    return sections


def second_order(b, a, x):
    """One section along axis 0, started at the first sample's steady state."""
    import numpy as np
    y = np.empty_like(x)
    gain = b.sum() / a.sum()
    z1, z2 = (gain - b[0]) * x[0], (b[2] - a[2] * gain) * x[0]
    for n in range(len(x)):
        y[n] = b[0] * x[n] + z1
        z1 = b[1] * x[n] - a[1] * y[n] + z2
        z2 = b[2] * x[n] - a[2] * y[n]
    return y


def columns(model, data, rec, kinds):
    """Filtered least-squares columns of a recording: samples x joints x parameters."""
    import numpy as np
    import pinocchio as pin
    rows = []
    for q, qd, qdd in zip(rec.q, rec.qd, rec.qdd):
        y = pin.computeJointTorqueRegressor(model, data, q, qd, qdd).copy()
        per_joint = {"v": qd, "c": np.sign(qd), "o": np.ones(6), "a": qdd}
        extra = [np.diag(per_joint[k]) for k in kinds]
        rows.append(np.hstack([y] + extra))
    return rec.smooth(np.stack(rows))


def least_squares(model, recs, kinds):
    import numpy as np
    data = model.createData()
    prior = np.concatenate([model.inertias[i].toDynamicParameters() for i in range(1, model.njoints)]
                           + [np.zeros(6 * len(kinds))])
    y = np.vstack([columns(model, data, r, kinds)[r.keep].reshape(-1, len(prior)) for r in recs])
    t = np.concatenate([r.tau[r.keep].reshape(-1) for r in recs])
    change, *_ = np.linalg.lstsq(y, t - y @ prior, rcond=1e-8)
    return prior + change


def emulated_mse(predict, recs):
    import numpy as np
    errors = np.vstack([predict(r)[r.keep] - r.tau[r.keep] for r in recs])
    return (errors ** 2).mean(0)


def main():
    repo = Path(__file__).resolve().parent.parent
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sdnn", default=str(repo / "target/release/sdnn"))
    p.add_argument("--venv", default=str(repo / "target/public-urdfs/venv"))
    p.add_argument("--work", default=str(repo / "target/ur10e"))
    args = p.parse_args()
    ensure_venv(Path(args.venv))
    import numpy as np
    import pinocchio as pin

    work = Path(args.work).resolve()
    (work / "csv").mkdir(parents=True, exist_ok=True)
    (work / "filtered").mkdir(exist_ok=True)
    source = fetch(work)
    binary = str(Path(args.sdnn).resolve())
    csv = {}
    for name in IDENTIFICATION + VALIDATION + [LOADED[0]]:
        csv[name] = work / "csv" / f"{name}.csv"
        if not csv[name].exists():
            convert(source / "dataset_ur10e/identification_data" / f"{name}.csv", csv[name])
    urdf = source / "URe/urdf/ur10e.urdf"
    described = work / "ur10e.toml"
    sdnn(binary, "import-urdf", urdf, "--out", described)
    model = pin.buildModelFromUrdf(str(urdf))
    filtered = {n: Filtered(binary, csv[n], work / "filtered") for n in IDENTIFICATION + VALIDATION}
    validation = [filtered[n] for n in VALIDATION]
    np.set_printoptions(precision=4, suppress=True, linewidth=160)
    print("held-out MSE (N m^2) on", ", ".join(VALIDATION))
    print(f"{'URDF, evaluate':44}", np.array(evaluate_mse(binary, described, [csv[n] for n in VALIDATION])))
    sets = [IDENTIFICATION] + [[n] for n in IDENTIFICATION]
    applied_from = {}
    for names in sets:
        label = "3 recordings" if len(names) == 3 else names[0]
        applied = applied_from[len(names), names[0]] = work / f"applied-{len(names)}-{names[0]}.toml"
        applied.write_text(described.read_text())
        report = sdnn(binary, "diagnose", "--model", described, "--data", *[csv[n] for n in names],
                      "--apply", "--toml", applied).stdout
        corrections = printed_corrections(report)
        scored = evaluate_mse(binary, applied, [csv[n] for n in VALIDATION], corrections)
        if corrections:
            print(f"{label}: printed corrections {' '.join(corrections)}, applied by evaluate; "
                  "the emulated rows and ratios are the model alone")

        def tau_of(rec, toml=applied):
            out = sdnn(binary, "tau", "--model", toml, "--input", rec.path,
                       *sum([["--ignore-column", f"tau{j}"] for j in range(1, 7)], [])).stdout
            return rec.smooth(np.genfromtxt(io.StringIO(out), delimiter=",", skip_header=1))

        ours = emulated_mse(tau_of, validation)
        print(f"{'applied, ' + label + ', evaluate':44}", np.array(scored))
        print(f"{'applied, ' + label + ', emulated':44}", ours)
        for kinds in ("vco", "vcoa"):
            theta = least_squares(model, [filtered[n] for n in names], kinds)
            data = model.createData()
            ols = emulated_mse(lambda r: columns(model, data, r, kinds) @ theta, validation)
            print(f"{'OLS ' + kinds + ', ' + label:44}", ols, " applied / OLS", (ours / ols).round(3))
    three = applied_from[len(IDENTIFICATION), IDENTIFICATION[0]]
    found = sdnn(binary, "diagnose", "--model", three, "--data", csv[LOADED[0]], "--format", "json").stdout
    for e in json.loads(found)["effects"]:
        mass = e["parameters"].get("mass")
        print(f"loaded run ({LOADED[1]} kg): {e['kind']} {e.get('link') or e.get('joint')} mass {mass} "
              f"95% CI {e['ci95'].get('mass')}")


if __name__ == "__main__":
    sys.exit(main())

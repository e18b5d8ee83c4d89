"""Scoring of an `sdnn diagnose --format json` report against the hidden effects.

The mapping from hidden effects to the documented kinds (docs/diagnosis.md,
"The kinds") is in `slots()`; README.md states it in words.
"""
import numpy as np


def _ix6(I):
    I = np.asarray(I)
    return [I[0, 0], I[0, 1], I[0, 2], I[1, 1], I[1, 2], I[2, 2]]


def _body(mass, com, inertia=None):
    d = {"mass": float(mass), "com": [float(x) for x in com], "first_moment": [float(mass * x) for x in com]}
    if inertia is not None:
        d["inertia"] = [float(x) for x in _ix6(inertia)]
    return d


def slots(truth):
    """(slots, allowed): each slot is a dict {(kind, where): truth-parameters}, one of
    which must be named; `allowed` lists (kind, where) that may be named besides."""
    n = truth["dof"]
    names = truth["link_names"]
    last = names[-1]
    nominal = truth["nominal_links"]
    plant = truth["plant_links"]
    out, allowed = [], []
    for e in truth["effects"]:
        t = e["type"]
        if t == "viscous":
            out += [{("viscous_friction", j + 1): {"coefficient": e["b"][j]}} for j in range(n)]
        elif t == "coulomb":
            out += [{("coulomb_friction", j + 1): {"level": e["c"][j]}} for j in range(n)]
        elif t == "gaz":
            # a smooth, saturating friction law that the kinds have no name for:
            # friction on every joint, named as Coulomb or viscous friction (either
            # or both: over the speeds a joint reaches the sigmoid may not saturate),
            # and (phi3 != 0) direction-dependent friction on the same joints.
            # No scalar truth for the values.
            out += [{("coulomb_friction", j + 1): {}, ("viscous_friction", j + 1): {}} for j in range(n)]
            allowed += [("coulomb_friction", j + 1) for j in range(n)]
            allowed += [("viscous_friction", j + 1) for j in range(n)]
            allowed += [("coulomb_asymmetry", j + 1) for j in range(n)]
        elif t == "stribeck":
            j = e["joint"]
            out.append({("coulomb_friction", j): {"level": e["coulomb"]}})
            out.append({("stribeck_friction", j): {"excess": e["excess"], "velocity": e["velocity"]}})
        elif t == "asym_coulomb":
            j = e["joint"]
            out.append({("coulomb_friction", j): {"level": e["coulomb"]}})
            out.append({("coulomb_asymmetry", j): {"asymmetry": e["asymmetry"]}})
        elif t == "armature":
            out.append({("armature", e["joint"]): {"inertia": e["inertia"]}})
        elif t == "payload":
            k = e["link"] - 1
            link = plant[k]  # link + payload (no other inertial effect on it in any case)
            m0 = nominal[k]["mass"]
            c0 = np.array(nominal[k]["com"])
            mt = m0 + e["mass"]
            ct = (m0 * c0 + e["mass"] * np.array(e["com"])) / mt
            out.append({("payload", last): _body(e["mass"], e["com"]),
                        ("inertial_error", last): _body(mt, ct, link["inertia"])})
        elif t in ("heavier_link", "whole_link"):
            k = e["link"] - 1
            name = names[k]
            p, q = plant[k], nominal[k]
            alt = {("inertial_error", name): _body(p["mass"], p["com"], p["inertia"])}
            if name == last:
                dm = p["mass"] - q["mass"]
                dfm = p["mass"] * np.array(p["com"]) - q["mass"] * np.array(q["com"])
                alt[("payload", last)] = _body(dm, dfm / dm if abs(dm) > 1e-9 else [0, 0, 0])
                del alt[("payload", last)]["first_moment"]
                if dm <= 0:  # a lighter last link is no payload
                    del alt[("payload", last)]
            out.append(alt)
        elif t == "torque_scale":
            out.append({("torque_scale", e["joint"]): {"scale": e["scale"]}})
        elif t == "torque_offset":
            out.append({("torque_offset", e["joint"]): {"offset": e["offset"]}})
        elif t == "torque_delay":
            out.append({("torque_delay", None): {"delay": e["samples"] / truth["rate_hz"]}})
        elif t == "tilt":
            out.append({("gravity_direction", None): {"tilt_deg": e["deg"]}})
        elif t == "spring":
            out.append({("joint_spring", e["joint"]): {"stiffness": e["stiffness"], "rest": e["rest"]}})
        else:
            raise ValueError(t)
    return out, allowed


# parameters whose intervals are checked (others are derived or have no truth)
COUNTED = {"coefficient", "level", "asymmetry", "excess", "inertia", "offset", "mass", "com",
           "first_moment", "scale", "delay", "tilt_deg", "stiffness", "rest"}


def where_of(e):
    if e.get("joint") is not None:
        return int(e["joint"])
    if e.get("link") is not None:
        return e["link"]
    return None


def fmt_where(w):
    if w is None:
        return ""
    return f" j{w}" if isinstance(w, int) else f" {w}"


def describe(e):
    p = e.get("parameters") or {}
    vals = []
    for k, v in p.items():
        if k in ("correction", "physically_consistent", "nominal_mass", "nominal_com", "nominal_inertia",
                 "combinations", "determined", "identifiable_combinations", "gravity", "constant", "scale_error"):
            continue
        if isinstance(v, (int, float)):
            vals.append(f"{k}={v:.4g}")
        elif isinstance(v, list) and all(isinstance(x, (int, float)) for x in v):
            vals.append(f"{k}=[" + ",".join(f"{x:.3g}" for x in v) + "]")
    s = f"{e['kind']}{fmt_where(where_of(e))}"
    if vals:
        s += " (" + " ".join(vals) + ")"
    return s


def coverage(e, truthp):
    rows = []
    ci = e.get("ci95") or {}
    det = (e.get("parameters") or {}).get("determined")
    for k, tv in truthp.items():
        if k not in COUNTED or k not in ci or ci[k] is None:
            continue
        iv = ci[k]
        val = (e.get("parameters") or {}).get(k)
        if isinstance(tv, list):
            for c, (t, b) in enumerate(zip(tv, iv)):
                if b is None:
                    continue
                rows.append(dict(kind=e["kind"], where=where_of(e), param=f"{k}[{c}]", truth=t,
                                 value=(val[c] if isinstance(val, list) else None), ci95=b,
                                 covered=bool(b[0] <= t <= b[1])))
        else:
            if iv is None:
                continue
            rows.append(dict(kind=e["kind"], where=where_of(e), param=k, truth=tv, value=val, ci95=iv,
                             covered=bool(iv[0] <= tv <= iv[1])))
    if det is not None:
        for r in rows:
            r["determined"] = det
    return rows


def score(truth, report, exit_code):
    """A result entry for one diagnose run."""
    sl, allowed = slots(truth)
    hidden = []
    for s in sl:
        hidden.append(" | ".join(f"{k}{fmt_where(w)}" for (k, w) in s))
    res = dict(exit_code=exit_code, hidden=hidden, named=[], named_detail=[], missing=[], extra=[],
               allowed_extra=[], coverage=[], strict_pass=False, lenient_pass=False, error=None)
    if exit_code != 0 or report is None or "effects" not in report:
        res["error"] = (f"exit {exit_code}" + (": sanity gate" if exit_code == 3 else "")
                        + ("" if report is not None else ", no JSON"))
        if report is not None and "findings" in report:
            res["findings"] = [f.get("message", "") for f in report["findings"]]
        return res
    filled = [None] * len(sl)
    ambiguous_hits = 0
    for e in report["effects"]:
        key = (e["kind"], where_of(e))
        res["named"].append(describe(e))
        res["named_detail"].append(dict(kind=e["kind"], where=where_of(e), parameters=e.get("parameters"),
                                        ci95=e.get("ci95"), ambiguous_with=e.get("ambiguous_with") or []))
        hit = None
        for i, s in enumerate(sl):
            if filled[i] is None and key in s:
                hit = i
                break
        if hit is not None:
            filled[hit] = key
            res["coverage"] += coverage(e, sl[hit][key])
        elif key in allowed:
            res["allowed_extra"].append(describe(e))
        else:
            res["extra"].append(describe(e))
            # lenient: the extra is named where a missing slot's kind is listed as ambiguous
            amb = " ".join(e.get("ambiguous_with") or [])
            for i, s in enumerate(sl):
                if filled[i] is None and any(k in amb and (w is None or (f"joint {w}" in amb if isinstance(w, int) else w in amb)) for (k, w) in s):
                    ambiguous_hits += 1
                    filled[i] = ("ambiguous", key)
                    break
    for i, s in enumerate(sl):
        if filled[i] is None:
            res["missing"].append(hidden[i])
    res["strict_pass"] = not res["missing"] and not res["extra"] and all(
        f is not None and f[0] != "ambiguous" for f in filled)
    res["lenient_pass"] = not res["missing"] and len(res["extra"]) == ambiguous_hits
    return res

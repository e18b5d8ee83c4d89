"""Pinocchio plant built from an sdnn TOML description (docs/description-format.md).

Independent of the sdnn sources: it reads only the documented TOML fields
(links: mass, com, inertia about the COM in link axes; joints: origin xyz/rpy
in the parent frame, axis, type revolute/fixed, limits) and builds a
Pinocchio model with the URDF conventions the format states.
"""
import tomllib

import numpy as np
import pinocchio as pin


def _inertia_matrix(spec):
    if spec is None:
        return np.zeros((3, 3))
    if isinstance(spec, dict):
        ixx = spec.get("ixx", 0.0); iyy = spec.get("iyy", 0.0); izz = spec.get("izz", 0.0)
        ixy = spec.get("ixy", 0.0); ixz = spec.get("ixz", 0.0); iyz = spec.get("iyz", 0.0)
        return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]], float)
    return np.array(spec, float)


def _origin(j):
    o = j.get("origin", {}) or {}
    xyz = np.array(o.get("xyz", [0.0, 0.0, 0.0]), float)
    rpy = o.get("rpy", [0.0, 0.0, 0.0])
    R = pin.rpy.rpyToMatrix(float(rpy[0]), float(rpy[1]), float(rpy[2]))
    return pin.SE3(R, xyz)


class Description:
    """The moving chain of a TOML description, fixed joints lumped."""

    def __init__(self, path):
        with open(path, "rb") as f:
            d = tomllib.load(f)
        self.path = path
        self.gravity = np.array(d.get("gravity", [0.0, 0.0, -9.81]), float)
        links = {l["name"]: l for l in d["links"]}
        joints = d["joints"]
        child_of = {j["child"]: j for j in joints}
        children = {}
        for j in joints:
            children.setdefault(j["parent"], []).append(j)
        roots = [n for n in links if n not in child_of]
        assert len(roots) == 1, roots
        self.root = roots[0]
        # walk the tree; for each link find (moving body index or -1, placement in that body)
        self.moving = []  # list of dicts: name, joint, parent_body, placement (joint frame in parent body frame), axis, limits, link
        body_of = {self.root: (-1, pin.SE3.Identity())}
        lumped = {}  # body index -> list of (placement, link)
        order = [self.root]
        while order:
            ln = order.pop(0)
            for j in children.get(ln, []):
                pb, pM = body_of[ln]
                M = pM * _origin(j)
                t = j.get("type", "revolute")
                if t == "fixed" or ("locked" in j):
                    assert "locked" not in j, "locked joints not supported by this harness"
                    body_of[j["child"]] = (pb, M)
                    lumped.setdefault(pb, []).append((M, links[j["child"]]))
                else:
                    assert t == "revolute", t
                    idx = len(self.moving)
                    self.moving.append(dict(name=j["name"], joint=j, parent_body=pb, placement=M,
                                            axis=np.array(j["axis"], float) / np.linalg.norm(j["axis"]),
                                            limits=j.get("limits", {}), link=links[j["child"]],
                                            link_name=j["child"]))
                    body_of[j["child"]] = (idx, pin.SE3.Identity())
                order.append(j["child"])
        self.lumped = lumped
        self.n = len(self.moving)
        for k, m in enumerate(self.moving):
            assert m["parent_body"] == k - 1, "serial chain expected"

    def link_inertia(self, k):
        """Pinocchio Inertia of moving body k in its own frame, fixed children lumped."""
        l = self.moving[k]["link"]
        I = pin.Inertia.Zero()
        if "mass" in l:
            I = pin.Inertia(float(l["mass"]), np.array(l.get("com", [0, 0, 0]), float), _inertia_matrix(l.get("inertia")))
        for M, lk in self.lumped.get(k, []):
            if "mass" in lk:
                Ic = pin.Inertia(float(lk["mass"]), np.array(lk.get("com", [0, 0, 0]), float), _inertia_matrix(lk.get("inertia")))
                I = I + M.act(Ic)
        return I

    def limits(self):
        lo = []; hi = []; vel = []
        for m in self.moving:
            L = m["limits"] or {}
            lo.append(L.get("lower", -np.pi)); hi.append(L.get("upper", np.pi)); vel.append(L.get("velocity", 2.0))
        return np.array(lo), np.array(hi), np.array(vel)

    def build(self, inertias=None, gravity=None):
        """A Pinocchio model; inertias: optional list of pin.Inertia replacing the links'."""
        model = pin.Model()
        parent = 0
        for k, m in enumerate(self.moving):
            ax = m["axis"]
            if np.allclose(ax, [1, 0, 0]):
                jm = pin.JointModelRX()
            elif np.allclose(ax, [0, 1, 0]):
                jm = pin.JointModelRY()
            elif np.allclose(ax, [0, 0, 1]):
                jm = pin.JointModelRZ()
            else:
                jm = pin.JointModelRevoluteUnaligned(ax)
            jid = model.addJoint(parent, jm, m["placement"], m["name"])
            I = inertias[k] if inertias is not None else self.link_inertia(k)
            model.appendBodyToJoint(jid, I, pin.SE3.Identity())
            parent = jid
        model.gravity.linear = self.gravity if gravity is None else np.asarray(gravity, float)
        return model


def rnea_batch(model, Q, QD, QDD):
    data = model.createData()
    out = np.empty_like(Q)
    for i in range(Q.shape[0]):
        out[i] = pin.rnea(model, data, Q[i], QD[i], QDD[i])
    return out

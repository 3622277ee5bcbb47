#!/usr/bin/env python3
"""Loads kinserve's URDF exports with Pinocchio and compares FK with kinserve's.

Usage: check-urdf-pinocchio.py CASES.json
CASES.json: [{"name", "urdf" (path), "samples": [{"q": [...], "pose": 4x4}]}] with
q and pose in URDF units (rad, m) and pose = world -> tool as kinserve computes it.
Prints one line per robot and exits 1 on any mismatch above 1e-9.
Needs `pip install pin` (Pinocchio's Python package).
"""
import json
import sys

import numpy as np
import pinocchio as pin

TOL = 1e-9


def check(case):
    model = pin.buildModelFromUrdf(case["urdf"])
    data = model.createData()
    tool = model.getFrameId("tool")
    worst = 0.0
    for s in case["samples"]:
        q = np.zeros(model.nq)
        # Pinocchio orders joints as in the URDF tree (one chain here); continuous
        # joints take (cos q, sin q).
        values = iter(s["q"])
        for j in model.joints[1:]:
            v = next(values)
            if j.nq == 2:
                q[j.idx_q:j.idx_q + 2] = [np.cos(v), np.sin(v)]
            else:
                q[j.idx_q] = v
        pin.framesForwardKinematics(model, data, q)
        got = data.oMf[tool].homogeneous
        worst = max(worst, float(np.max(np.abs(got - np.array(s["pose"])))))
    ok = worst <= TOL
    print(f"{case['name']}: {model.njoints - 1} joints, max |diff| {worst:.2e} {'ok' if ok else 'FAIL'}")
    return ok


def main():
    cases = json.load(open(sys.argv[1]))
    results = [check(c) for c in cases]
    sys.exit(0 if all(results) else 1)


if __name__ == "__main__":
    main()

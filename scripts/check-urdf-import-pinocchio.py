#!/usr/bin/env python3
"""Checks kinserve's URDF imports against Pinocchio loading the same URDF files.

Usage: check-urdf-import-pinocchio.py CASES.json
CASES.json: [{"name", "urdf" (path), "base", "tip", "joints": [names],
              "samples": [{"q": [...], "pose": 4x4}]}], q in rad / m for the named
joints (every other joint at zero), pose = base -> tip as kinserve's imported
DH table computes it. Prints one line per case and exits 1 on any mismatch
above 1e-12 of the chain's size (the sum of the pose translations, at least 1 m).
Needs `pip install pin`.

With --robots-dir it prints example-robot-data's robots directory and exits.
"""
import json
import os
import sys
import sysconfig

import numpy as np
import pinocchio as pin

TOL = 1e-12


def robots_dir():
    for base in {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}:
        d = os.path.join(base, "cmeel.prefix", "share", "example-robot-data", "robots")
        if os.path.isdir(d):
            return d
    raise SystemExit("example-robot-data is not installed (pip install example-robot-data)")


def check(case):
    model = pin.buildModelFromUrdf(case["urdf"])
    data = model.createData()
    base, tip = model.getFrameId(case["base"]), model.getFrameId(case["tip"])
    ids = [model.getJointId(n) for n in case["joints"]]
    worst, size = 0.0, 1.0
    for s in case["samples"]:
        q = pin.neutral(model)
        for jid, v in zip(ids, s["q"]):
            j = model.joints[jid]
            if j.nq == 2:  # continuous: (cos q, sin q)
                q[j.idx_q:j.idx_q + 2] = [np.cos(v), np.sin(v)]
            else:
                q[j.idx_q] = v
        pin.framesForwardKinematics(model, data, q)
        got = (data.oMf[base].inverse() * data.oMf[tip]).homogeneous
        want = np.array(s["pose"])
        size = max(size, float(np.sum(np.abs(want[:3, 3]))))
        worst = max(worst, float(np.max(np.abs(got - want))))
    ok = worst <= TOL * size
    print(f"{case['name']}: {len(ids)} joints, max |diff| {worst:.2e} (size {size:.2f} m) {'ok' if ok else 'FAIL'}")
    return ok


def main():
    if sys.argv[1:] == ["--robots-dir"]:
        print(robots_dir())
        return
    cases = json.load(open(sys.argv[1]))
    results = [check(c) for c in cases]
    sys.exit(0 if all(results) else 1)


if __name__ == "__main__":
    main()

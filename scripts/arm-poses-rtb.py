#!/usr/bin/env python3
"""Tool poses of Peter Corke's Robotics Toolbox DH models (roboticstoolbox-python,
`pip install roboticstoolbox-python`), an implementation and a transcription of the
arms' DH tables independent of kinserve's robot files.

Reads a JSON file {"Model": [[q1, ...], ...]} (model names of roboticstoolbox.models.DH,
joint values in rad / m) and prints {"Model": [4x4 row-major matrix, ...]} as JSON:
fkine(q) with the model's tool and base transforms removed (kinserve's files end at
the flange). Used by crates/kinserve-kinematics/tests/kinematics/published_poses.rs.
"""
import json
import sys

import roboticstoolbox as rtb
from spatialmath import SE3


def main(path):
    with open(path) as f:
        cases = json.load(f)
    out = {}
    for name, configs in cases.items():
        robot = getattr(rtb.models.DH, name)()
        robot.tool = SE3()
        robot.base = SE3()
        out[name] = [robot.fkine(q).A.tolist() for q in configs]
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1])

"""The FastAPI peer of scripts/bench-peers.sh: the same REST FK as kinserve's
`POST /v1/robots/{name}/fk` (body `{"joints": [...]}` in rad, answer
`{"robot", "length_unit", "pose": {"matrix", "position", "quaternion", "rpy"}}`)
computed with Peter Corke's Robotics Toolbox for Python on the same DH table,
read from robots/<PEER_ROBOT>.json. Run by the script as
    PEER_ROBOT=puma560 uvicorn --app-dir scripts/peers fastapi_fk:app --workers 2
Serves one robot; a model with a base, a tool or a fixed row other than the
last ones is refused at start-up (the benchmark robot has none).
"""

import json
import math
import os
from pathlib import Path

import numpy as np
import roboticstoolbox as rtb
from fastapi import FastAPI, HTTPException
from pydantic import BaseModel
from spatialmath import SE3, UnitQuaternion

ROOT = Path(__file__).resolve().parents[2]


def load(name: str) -> tuple[rtb.DHRobot, str]:
    spec = json.loads((ROOT / "robots" / f"{name}.json").read_text())
    if spec.get("base") or spec.get("tool"):
        raise SystemExit(f"{name}: base/tool transforms are not supported by this peer")
    deg = spec.get("angle_unit", "rad") == "deg"
    ang = (lambda v: math.radians(v)) if deg else (lambda v: v)
    modified = spec["convention"] == "modified"
    links, tool = [], SE3()
    for row in spec["links"]:
        a, alpha, d, theta = row["a"], ang(row["alpha"]), row["d"], ang(row.get("theta", 0.0))
        kind = row.get("joint", "revolute")
        if kind == "fixed":
            # Only trailing fixed rows: fold them into the tool.
            if modified:
                tool = tool * SE3.Rx(alpha) * SE3.Tx(a) * SE3.Rz(theta) * SE3.Tz(d)
            else:
                tool = tool * SE3.Rz(theta) * SE3.Tz(d) * SE3.Tx(a) * SE3.Rx(alpha)
            continue
        if tool != SE3():
            raise SystemExit(f"{name}: a fixed row before a joint is not supported by this peer")
        cls = {
            (False, "revolute"): rtb.RevoluteDH,
            (False, "prismatic"): rtb.PrismaticDH,
            (True, "revolute"): rtb.RevoluteMDH,
            (True, "prismatic"): rtb.PrismaticMDH,
        }[(modified, kind)]
        links.append(cls(a=a, alpha=alpha, d=d, offset=theta) if kind == "revolute" else cls(a=a, alpha=alpha, theta=theta, offset=d))
    return rtb.DHRobot(links, name=name, tool=tool), spec.get("length_unit", "m")


NAME = os.environ.get("PEER_ROBOT", "puma560")
ROBOT, LENGTH_UNIT = load(NAME)
app = FastAPI()


class FkRequest(BaseModel):
    joints: list[float]


@app.get("/healthz")
def healthz():
    return {"status": "ok"}


@app.post("/v1/robots/{name}/fk")
def fk(name: str, req: FkRequest):
    if name != NAME:
        raise HTTPException(404, f"unknown robot {name}")
    if len(req.joints) != ROBOT.n:
        raise HTTPException(422, f"expected {ROBOT.n} joint values")
    t = ROBOT.fkine(np.array(req.joints))
    q = UnitQuaternion(t).vec
    return {
        "robot": NAME,
        "length_unit": LENGTH_UNIT,
        "pose": {
            "matrix": t.A.tolist(),
            "position": t.t.tolist(),
            "quaternion": {"w": q[0], "x": q[1], "y": q[2], "z": q[3]},
            "rpy": t.rpy().tolist(),
        },
    }

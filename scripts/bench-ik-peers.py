#!/usr/bin/env python3
"""Numeric IK side by side: kinserve (numeric, and analytic where the arm is
classified), TRAC-IK (PyPI `pytracik`) and Robotics Toolbox `ik_LM` (C++) on
the same random reachable targets of every shipped 6/7-joint arm and the
Robotics Toolbox DH arms (registered as kinserve robot files from their DH
tables), every answer checked by an independent FK (numpy, the textbook DH
product from the rows) to 1e-5 and within the limits.

    python3 scripts/bench-ik-peers.py [--n 1000] [--rounds 5] [--arms a,b] [--seed S] [--json F]

(`--seed`: another set of random targets; default, the driver's own seed.)

Needs a release build of the kinserve driver (built on first use):
    cargo build --release -p kinserve-kinematics --example ik_peers
and `pip install roboticstoolbox-python pytracik`.

The machine may be shared: the targets of each arm are split into `--rounds`
slices and the solvers alternate slice by slice (kinserve, TRAC-IK, RTB,
kinserve, ...), so a burst of load hits every solver alike.

Settings: kinserve default options at tolerance 1e-6 (m and rad), no deadline,
no seed (mid-limit start); TRAC-IK Speed, 5 ms, eps 1e-6, mid-limit seed, on
kinserve's URDF export (`kinserve_model::to_urdf`, what `kinserve urdf --robot
NAME` prints); RTB `ETS.ik_LM` (C++, Chan's method), `tol` 1e-12 (it bounds
½‖e‖², so ‖e‖ ≈ 1.4e-6), joint limits on, ilimit 30, slimit 100, mid-limit
start (its own random restarts after). Times per solve in µs, failures
included: CPU time (kinserve: its thread, `CLOCK_THREAD_CPUTIME_ID`; the peers:
the process, around the Python call of their C++ solver, as TRAC-IK solves in
two threads), so time the shared machine gave to other processes does not
count; the wall-clock mean is printed beside it.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DRIVER = os.path.join(ROOT, "target", "release", "examples", "ik_peers")
SHIPPED = ["puma560", "abb_irb140", "kuka_kr5", "stanford", "ur3e", "ur5", "ur5e",
           "ur10e", "ur20", "panda", "kinova_gen3", "inline_6dof",
           "cylindrical_wrist_6dof", "spherical_wrist"]
RTB_ARMS = ["IRB140", "KR5", "Jaco", "LWR4", "Sawyer", "Baxter", "Panda", "UR5", "Puma560"]
CHECK_TOL = 1e-5
DRIVER_ARGS = []  # --seed S, when given


def rtb_model_file(name, out_dir):
    """A kinserve robot file (rad, m) from roboticstoolbox.models.DH.<name>."""
    import roboticstoolbox as rtb
    r = getattr(rtb.models.DH, name)()
    links = []
    for i, L in enumerate(r.links):
        link = {"name": f"j{i + 1}", "joint": "prismatic" if L.isprismatic else "revolute",
                "a": float(L.a), "alpha": float(L.alpha), "d": float(L.d),
                "theta": float(L.theta if L.isprismatic else L.offset)}
        if L.isprismatic:
            link["d"] = float(L.offset)
        if L.qlim is not None:
            link["limits"] = [float(L.qlim[0]), float(L.qlim[1])]
        links.append(link)
    spec = {"name": "rtb_" + name.lower(),
            "description": f"roboticstoolbox-python models.DH.{name} (benchmark copy)",
            "convention": "modified" if r.mdh else "standard",
            "angle_unit": "rad", "length_unit": "m", "links": links}
    for key, T in (("base", r.base.A), ("tool", r.tool.A)):
        if not np.allclose(T, np.eye(4)):
            spec[key] = {"matrix": T.tolist()}
    path = os.path.join(out_dir, spec["name"] + ".json")
    with open(path, "w") as f:
        json.dump(spec, f)
    return path, r


def dh_matrix(modified, row, q):
    th, d = row["theta"], row["d"]
    if row["kind"] == "revolute":
        th += q
    elif row["kind"] == "prismatic":
        d += q
    ct, st = math.cos(th), math.sin(th)
    ca, sa = math.cos(row["alpha"]), math.sin(row["alpha"])
    a = row["a"]
    if modified:
        return np.array([[ct, -st, 0, a], [st * ca, ct * ca, -sa, -sa * d],
                         [st * sa, ct * sa, ca, ca * d], [0, 0, 0, 1.0]])
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                     [0, sa, ca, d], [0, 0, 0, 1.0]])


def fk(info, q):
    """Independent FK: base · Π A_i(q_i) · tool, from the rows alone."""
    T = np.array(info["base"]).reshape(4, 4)
    j = 0
    for row in info["rows"]:
        qi = 0.0
        if row["kind"] != "fixed":
            qi, j = q[j], j + 1
        T = T @ dh_matrix(info["modified"], row, qi)
    if info["tool"] is not None:
        T = T @ np.array(info["tool"]).reshape(4, 4)
    return T


def pose_error(T, target):
    dp = np.linalg.norm(T[:3, 3] - target[:3, 3])
    R = target[:3, :3] @ T[:3, :3].T
    ang = math.acos(max(-1.0, min(1.0, (np.trace(R) - 1) / 2)))
    return dp, ang


def check(info, q, target):
    """Whether q is within the limits and FK(q) is within 1e-5 of the target."""
    if q is None or len(q) != info["dof"] or not all(math.isfinite(x) for x in q):
        return False
    for x, lim in zip(q, info["limits"]):
        if lim is not None and not (lim[0] - 1e-12 <= x <= lim[1] + 1e-12):
            return False
    dp, dr = pose_error(fk(info, q), target)
    return dp <= CHECK_TOL and dr <= CHECK_TOL


def mid(info):
    return np.array([0.5 * (l[0] + l[1]) if l is not None else 0.0 for l in info["limits"]])


def run_driver(path, n, lo, hi):
    out = subprocess.run([DRIVER, "--robot", path, "--n", str(n), "--from", str(lo),
                          "--to", str(hi), *DRIVER_ARGS], check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


class TracIk:
    def __init__(self, info, tmp):
        import pytracik
        with open(os.path.join(tmp, info["name"] + ".urdf"), "w") as f:
            f.write(info["urdf"])
        base, tip = urdf_ends(info["urdf"])
        # pytracik takes the URDF document itself (not a path).
        self.ik = pytracik.TRAC_IK(base, tip, info["urdf"], 0.005, 1e-6, pytracik.Speed)
        self.seed = mid(info)
        self.ok = pytracik.get_num_joints(self.ik) == info["dof"]
        self.pytracik = pytracik

    def solve(self, target):
        T = target
        R = T[:3, :3]
        qw, qx, qy, qz = quaternion(R)
        res = self.pytracik.ik(self.ik, self.seed, T[0, 3], T[1, 3], T[2, 3], qx, qy, qz, qw)
        # [status, q...]: status >= 0 when TRAC-IK found a solution.
        return res[1:] if res[0] >= 0 else None


def urdf_ends(urdf):
    """The root link and the last child link of the URDF's joint chain."""
    import xml.etree.ElementTree as ET
    root = ET.fromstring(urdf)
    parents, children = set(), []
    for j in root.iter("joint"):
        parents.add(j.find("parent").get("link"))
        children.append(j.find("child").get("link"))
    base = [p for p in parents if p not in children][0]
    tip = [c for c in children if c not in parents][0]
    return base, tip


def quaternion(R):
    w = math.sqrt(max(0.0, 1 + R[0, 0] + R[1, 1] + R[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + R[0, 0] - R[1, 1] - R[2, 2])) / 2, R[2, 1] - R[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1 - R[0, 0] + R[1, 1] - R[2, 2])) / 2, R[0, 2] - R[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1 - R[0, 0] - R[1, 1] + R[2, 2])) / 2, R[1, 0] - R[0, 1])
    return w, x, y, z


class RtbLm:
    """Robotics Toolbox ETS built from the same rows; `ETS.ik_LM` (C++)."""

    def __init__(self, info):
        import roboticstoolbox as rtb
        from spatialmath import SE3
        ET = rtb.ET
        ets = ET.SE3(SE3(np.array(info["base"]).reshape(4, 4), check=False))
        j = 0
        for row in info["rows"]:
            lim = None
            if row["kind"] != "fixed":
                lim = info["limits"][j]
                j += 1
            parts = []
            if info["modified"]:
                parts += [ET.Rx(row["alpha"]), ET.tx(row["a"])]
            if row["theta"] != 0.0:
                parts.append(ET.Rz(row["theta"]))
            if row["kind"] == "revolute":
                parts.append(ET.Rz(qlim=lim if lim is not None else [-math.pi, math.pi]))
            if row["d"] != 0.0:
                parts.append(ET.tz(row["d"]))
            if row["kind"] == "prismatic":
                parts.append(ET.tz(qlim=lim if lim is not None else [-0.5, 0.5]))
            if not info["modified"]:
                parts += [ET.tx(row["a"]), ET.Rx(row["alpha"])]
            for p in parts:
                ets = ets * p
        if info["tool"] is not None:
            ets = ets * ET.SE3(SE3(np.array(info["tool"]).reshape(4, 4), check=False))
        self.ets = ets
        self.q0 = mid(info)

    def fk(self, q):
        return np.array(self.ets.fkine(q).A)

    def solve(self, target):
        sol = self.ets.ik_LM(target, q0=self.q0, ilimit=30, slimit=100, tol=1e-12,
                             joint_limits=True)
        return sol.q if sol.success else None


def stats(times, ok):
    t = np.sort(np.array(times))
    if len(t) == 0:
        return None
    return {"solved": ok, "n": len(t), "mean": float(t.mean()), "median": float(np.median(t)),
            "p99": float(t[int(round((len(t) - 1) * 0.99))]), "max": float(t[-1])}


def bench_arm(path, n, rounds, tmp):
    head = run_driver(path, n, 0, 0)
    trac = TracIk(head, tmp)
    lm = RtbLm(head)
    res = {k: ([], 0) for k in ("numeric", "analytic", "tracik", "rtb_lm")}
    wall = {k: [] for k in res}
    bad_numeric = []
    step = (n + rounds - 1) // rounds
    for lo in range(0, n, step):
        hi = min(n, lo + step)
        part = run_driver(path, n, lo, hi)
        targets = [np.array(c["target"]).reshape(4, 4) for c in part["cases"]]
        for k, c in enumerate(part["cases"]):
            # The conversion to RTB's ETS reproduces kinserve's FK and the textbook product.
            T = targets[k]
            assert np.abs(fk(head, c["q_true"]) - T).max() < 1e-9, head["name"]
            assert np.abs(lm.fk(c["q_true"]) - T).max() < 1e-9, head["name"]
            ok = c["numeric"]["converged"] and check(head, c["numeric"]["q"], T)
            if c["numeric"]["converged"] and not ok:
                bad_numeric.append(lo + k)
            t, s = res["numeric"]
            res["numeric"] = (t + [c["numeric"]["us"]], s + ok)
            wall["numeric"].append(c["numeric"]["wall_us"])
            if c["analytic"] is not None:
                ok = check(head, c["analytic"]["q"], T)
                t, s = res["analytic"]
                res["analytic"] = (t + [c["analytic"]["us"]], s + ok)
                wall["analytic"].append(c["analytic"]["wall_us"])
        for key, solver in (("tracik", trac), ("rtb_lm", lm)):
            t, s = res[key]
            for T in targets:
                # CPU time of the process (TRAC-IK solves in two threads), and wall time.
                c0, t0 = time.process_time(), time.perf_counter()
                q = solver.solve(T)
                dt, dw = (time.process_time() - c0) * 1e6, (time.perf_counter() - t0) * 1e6
                ok = q is not None and check(head, list(q), T)
                t, s = t + [dt], s + ok
                wall[key].append(dw)
            res[key] = (t, s)
    out = {"name": head["name"], "dof": head["dof"], "class": head["analytic_class"],
           "bad_numeric": bad_numeric}
    for k, (t, s) in res.items():
        out[k] = stats(t, s)
        if out[k] is not None:
            out[k]["wall_mean"] = float(np.mean(wall[k]))
    return out


def fmt(s):
    if s is None:
        return "—"
    pct = 100.0 * s["solved"] / s["n"]
    return (f"{pct:.2f} % | {s['mean']:.1f} | {s['median']:.1f} | {s['p99']:.1f} "
            f"| {s['wall_mean']:.0f}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--arms", default="")
    ap.add_argument("--json", default="")
    ap.add_argument("--seed", type=int, default=None)
    args = ap.parse_args()
    if args.seed is not None:
        DRIVER_ARGS.extend(["--seed", str(args.seed)])
    if not os.path.exists(DRIVER):
        subprocess.run(["cargo", "build", "--release", "-p", "kinserve-kinematics",
                        "--example", "ik_peers"], check=True, cwd=ROOT)
    tmp = tempfile.mkdtemp(prefix="ik-peers-")
    paths = [os.path.join(ROOT, "robots", a + ".json") for a in SHIPPED]
    paths += [rtb_model_file(a, tmp)[0] for a in RTB_ARMS]
    want = set(filter(None, args.arms.split(",")))
    rows = []
    for p in paths:
        name = os.path.basename(p)[:-5]
        if want and name not in want:
            continue
        r = bench_arm(p, args.n, args.rounds, tmp)
        rows.append(r)
        print(f"{name}: numeric {fmt(r['numeric'])}; analytic {fmt(r['analytic'])}; "
              f"trac-ik {fmt(r['tracik'])}; rtb {fmt(r['rtb_lm'])}"
              + (f"; converged but failed the check: {r['bad_numeric']}" if r["bad_numeric"] else ""),
              file=sys.stderr, flush=True)
    cols = " | mean | median | p99 | wall mean"
    print("| arm | dof | kinserve numeric: solved" + cols + " | kinserve analytic: solved" + cols
          + " | TRAC-IK: solved" + cols + " | RTB ik_LM: solved" + cols + " |")
    print("| --- " * 22 + "|")
    for r in rows:
        print(f"| {r['name']} | {r['dof']} | {fmt(r['numeric'])} | {fmt(r['analytic']) if r['analytic'] else '— | | | |'} "
              f"| {fmt(r['tracik'])} | {fmt(r['rtb_lm'])} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()

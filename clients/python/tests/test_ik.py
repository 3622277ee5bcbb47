"""Closed-form IK, every solution, Cartesian paths and error kinds on both
transports (sync and async, and the streams) against the real server: values
equal to the server's own REST JSON (to 1e-12: the same doubles re-encoded),
every ``solutions="all"`` answer handed to the cargo test, which checks each
solution by the kinematics library's FK (``KINSERVE_OUT``), and the same
problem ``type`` / ``status`` / fields from REST and gRPC."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

import kinserve_client as kc
from conftest import Server, planar_model

EXACT = 1e-12
Q_DEG = [20.0, -30.0, 45.0, 10.0, 50.0, -20.0]
PATH_START = [5.0, -20.0, 35.0, 10.0, 30.0, -15.0]


def _target(server: Server) -> np.ndarray:
    """The IK target: the library's FK of ``expected["ik"]["joints"]`` when the
    cargo test wrote it, else the server's FK of ``Q_DEG``."""
    if "ik" in server.expected:
        return np.asarray(server.expected["ik"]["matrix"], dtype=np.float64)
    raw = server.raw("POST", "/v1/robots/puma560/fk", {"joints": Q_DEG, "angle_unit": "deg"})
    return np.asarray(raw["pose"]["matrix"], dtype=np.float64)


def _hand_off(name: str, target: np.ndarray, solutions: np.ndarray) -> None:
    """Writes solutions (rad) for the cargo test to check by the library's FK."""
    out = os.environ.get("KINSERVE_OUT")
    if out:
        doc = {"robot": "puma560", "target": target.tolist(), "solutions": solutions.tolist()}
        (Path(out) / f"{name}.json").write_text(json.dumps(doc))


def _same_solution(got: kc.IkSolution, want: dict[str, Any]) -> None:
    assert np.allclose(got.joints, want["joints"], rtol=0, atol=EXACT)
    b = want["branch"]
    assert got.branch == (None if b is None else kc.IkBranch(b["shoulder"], b["elbow"], b["wrist"]))
    assert list(got.singular) == want["singular"]
    assert abs(got.distance - want["distance"]) <= EXACT
    assert abs(got.position_error - want["position_error"]) <= EXACT
    assert abs(got.orientation_error - want["orientation_error"]) <= EXACT


def test_every_solution_equals_the_server_json(client: kc.Client, server: Server, transport: str) -> None:
    target = _target(server)
    r = client.ik("puma560", target, solutions="all", solver="analytic", max_solutions=32)
    raw = server.raw(
        "POST",
        "/v1/robots/puma560/ik",
        {"target": {"matrix": target.tolist()}, "solutions": "all", "solver": "analytic", "max_solutions": 32},
    )
    assert r.converged and r.solver == "analytic" == raw["solver"]
    assert r.iterations == raw["iterations"] == 0
    assert r.branch is not None and r.branch == kc.IkBranch(**raw["branch"])
    assert list(r.singular) == raw["singular"]
    assert r.truncated is raw["truncated"] is False
    assert r.solutions is not None and r.solution_details is not None
    assert r.solutions.shape == (len(raw["solutions"]), 6) and r.solutions.shape[0] >= 2
    assert np.allclose(r.solutions, [s["joints"] for s in raw["solutions"]], rtol=0, atol=EXACT)
    for got, want in zip(r.solution_details, raw["solutions"]):
        _same_solution(got, want)
    assert np.array_equal(r.solutions[0], r.joints)
    assert r.extra == {}, r.extra
    # The server's FK of each, and the library's in the cargo test.
    assert np.allclose(client.fk_batch("puma560", r.solutions), target, atol=1e-10)
    _hand_off(f"ik_all_{transport}", target, r.solutions)
    # A smaller max_solutions keeps the nearest ones and says it truncated.
    few = client.ik("puma560", target, solutions="all", max_solutions=2)
    assert few.truncated is True and few.solutions is not None
    assert np.allclose(few.solutions, r.solutions[:2], atol=EXACT)
    # The best answer alone has no solutions; the numeric solver no branch.
    best = client.ik("puma560", target, solutions="best")
    assert best.solutions is None and best.truncated is None and best.solver == "analytic"
    numeric = client.ik("puma560", target, solver="numeric", tolerance=1e-10)
    assert numeric.solver == "numeric" and numeric.branch is None and numeric.iterations > 0


def test_batch_with_every_solution(client: kc.Client, server: Server) -> None:
    target = _target(server)
    other = client.fk("puma560", np.radians([0.0, -20.0, 30.0, 0.0, 40.0, 0.0])).transform
    targets = np.stack([target, other])
    b = client.ik_batch("puma560", targets, solutions="all", max_solutions=16)
    raw = server.raw(
        "POST",
        "/v1/robots/puma560/ik/batch",
        {"targets": [{"matrix": t.tolist()} for t in targets], "solutions": "all", "max_solutions": 16},
    )
    assert b.solver == [x["solver"] for x in raw["results"]] == ["analytic", "analytic"]
    assert b.truncated is not None and b.truncated.tolist() == [x["truncated"] for x in raw["results"]]
    assert b.singular.tolist() == [bool(x["singular"]) for x in raw["results"]]
    assert b.solutions is not None and len(b.solutions) == 2
    for got, want, t in zip(b.solutions, raw["results"], targets):
        assert got.shape == (len(want["solutions"]), 6)
        assert np.allclose(got, [s["joints"] for s in want["solutions"]], atol=EXACT)
        assert np.allclose(client.fk_batch("puma560", got), t, atol=1e-10)
    plain = client.ik_batch("puma560", targets)
    assert plain.solutions is None and plain.truncated is None


def test_robot_summaries_carry_the_ik_class(client: kc.Client, server: Server) -> None:
    raw = {r["name"]: r.get("ik_class") for r in server.raw("GET", "/v1/robots?page_size=1000")["robots"]}
    got = {r.name: r.ik_class for r in client.robots()}
    assert got == raw
    assert got["puma560"] == "spherical_wrist_parallel_23" and got["planar_2dof"] is None


def _path_body(server: Server) -> tuple[dict[str, Any], np.ndarray]:
    pose = server.raw("POST", "/v1/robots/puma560/fk", {"joints": PATH_START, "angle_unit": "deg"})["pose"]
    end = np.asarray(pose["position"]) + [0.0, 0.0, 0.04]
    q = pose["quaternion"]
    waypoints = [
        {"position": end.tolist(), "quaternion": q},
        {"position": [2.0, 0.0, 0.5], "quaternion": q},
    ]
    body = {"start": PATH_START, "angle_unit": "deg", "waypoints": waypoints, "max_step_length": 0.01}
    return body, end


def _same_path(p: kc.IkPath, raw: dict[str, Any]) -> None:
    assert p.points.shape == (len(raw["points"]), 6)
    assert np.allclose(p.points, raw["points"], rtol=0, atol=EXACT)
    assert p.fraction == raw["fraction"] and p.waypoints_reached == raw["waypoints_reached"]
    stop = raw["stop"]
    if stop is None:
        assert p.stop is None and p.complete
    else:
        assert p.stop == kc.PathStop(stop["step"], stop["waypoint"], stop["reason"], stop["detail"])


def test_a_cartesian_path_equals_the_server_json(client: kc.Client, server: Server) -> None:
    body, end = _path_body(server)
    raw = server.raw("POST", "/v1/robots/puma560/ik/path", body)
    p = client.ik_path("puma560", PATH_START, body["waypoints"], angle_unit="deg", max_step_length=0.01)
    _same_path(p, raw)
    assert (p.robot, p.length_unit, p.angle_unit) == ("puma560", "m", "deg")
    # The first leg is taken (4 steps of 1 cm), the far waypoint stops it.
    assert p.waypoints_reached == 1 and 0 < p.fraction < 1 and not p.complete
    assert p.stop is not None and p.stop.reason in ("unreachable", "joint_limits", "joint_jump")
    assert p.stop.step == p.points.shape[0] and p.stop.waypoint == 1
    assert np.allclose(p.points[0], PATH_START, atol=EXACT)
    leg_end = client.fk("puma560", p.points[4], angle_unit="deg").transform
    assert np.allclose(leg_end[:3, 3], end, atol=1e-9)
    # Waypoints as an (N, 4, 4) array: the first leg alone is complete.
    matrix = client.fk("puma560", p.points[4], angle_unit="deg").transform
    whole = client.ik_path("puma560", PATH_START, matrix[np.newaxis], angle_unit="deg", max_step_length=0.01)
    assert whole.complete and whole.fraction == 1.0 and whole.waypoints_reached == 1
    assert np.allclose(
        client.fk("puma560", whole.points[-1], angle_unit="deg").transform, matrix, atol=1e-8
    )


def test_a_path_that_would_jump_stops_saying_so(client: kc.Client, server: Server) -> None:
    body, _ = _path_body(server)
    body["waypoints"] = body["waypoints"][:1]
    body["max_joint_step"] = 1e-4
    raw = server.raw("POST", "/v1/robots/puma560/ik/path", body)
    p = client.ik_path(
        "puma560", PATH_START, body["waypoints"], angle_unit="deg", max_step_length=0.01, max_joint_step=1e-4
    )
    _same_path(p, raw)
    assert p.stop is not None and p.stop.reason == "joint_jump"
    assert p.stop.step == 1 and p.points.shape == (1, 6) and p.fraction == 0.0


def _error(fn: Callable[[], Any]) -> kc.KinserveError:
    with pytest.raises(kc.KinserveError) as e:
        fn()
    return e.value


def _error_cases(c: kc.Client, transport: str) -> list[tuple[str, Callable[[], Any]]]:
    name = f"py-kinds-{transport}"
    return [
        ("out of limits", lambda: c.fk("puma560", [0, 3.0, 0, 0, 0, 0])),
        ("wrong count", lambda: c.fk("puma560", [0.0] * 5)),
        ("batch value", lambda: c.fk_batch("puma560", [[0.0] * 6, [0, 0, 9.0, 0, 0, 0]])),
        ("unknown robot", lambda: c.jacobian("nope", [0.0])),
        ("name taken", lambda: c.register(planar_model(name))),
        ("built-in", lambda: c.register(planar_model("puma560"))),
        ("stale etag", lambda: c.replace(planar_model(name), etag='"no-such-version"')),
        ("not reached", lambda: c.ik("puma560", [5.0, 5.0, 5.0], position_only=True, restarts=1)),
        ("no closed form", lambda: c.ik("planar_2dof", [0.5, 0.3, 0.0], position_only=True, solutions="all")),
        ("step of zero", lambda: c.ik_path("puma560", [0.0] * 6, [[0.5, 0.0, 0.5]], position_only=True, max_step_length=0.0)),
        ("too many", lambda: c.fk_batch("puma560", np.zeros((10_001, 6)))),
    ]


POSTURE_DEG = [0.0, 0.0, 0.0, -90.0, 0.0, 90.0, 45.0]


def test_posture_and_free_axes_equal_the_server_json(client: kc.Client, server: Server) -> None:
    """The objectives pass as keyword options on both transports (``free_axes``
    by their REST names) and give the server's own REST answer."""
    q = [40.0, 30.0, -20.0, -120.0, 30.0, 100.0, 10.0]
    raw_fk = server.raw("POST", "/v1/robots/panda/fk", {"joints": q, "angle_unit": "deg"})
    target = np.asarray(raw_fk["pose"]["matrix"], dtype=np.float64)
    options: dict[str, Any] = {"posture": {"joints": POSTURE_DEG}, "free_axes": ["rz"]}
    r = client.ik("panda", target, angle_unit="deg", **options)
    raw = server.raw("POST", "/v1/robots/panda/ik", {"target": {"matrix": target.tolist()}, "angle_unit": "deg", **options})
    assert r.converged and raw["solver"] == "numeric"
    assert np.allclose(r.joints, raw["joints"], rtol=0, atol=EXACT)
    with pytest.raises(kc.errors.InvalidArgument) as e:
        client.ik("panda", target, angle_unit="deg", posture={"joints": [0.0, 0.0]})
    assert list(e.value.fields) == ["posture.joints"]


def test_errors_have_the_same_type_status_and_fields_on_both_transports(server: Server) -> None:
    """Over gRPC the problem kind comes from the ``google.rpc.ErrorInfo``
    every error status carries; it must be REST's problem type."""
    got: dict[str, list[tuple[Any, ...]]] = {}
    transports: list[kc.types.Transport] = ["rest", "grpc"]
    for transport in transports:
        with kc.Client(server.address(transport), transport=transport, token=server.token) as c:
            c.register(planar_model(f"py-kinds-{transport}"))
            try:
                for label, fn in _error_cases(c, transport):
                    e = _error(fn)
                    assert e.type is not None and e.type.startswith("urn:kinserve:problem:"), (label, e)
                    got.setdefault(label, []).append((type(e), e.code, e.type, e.status, sorted(e.fields)))
            finally:
                c.delete(f"py-kinds-{transport}")
    for label, (rest, grpc) in got.items():
        assert rest == grpc, f"{label}: REST {rest} vs gRPC {grpc}"
    kinds = {label: v[0][2].rsplit(":", 1)[1] for label, v in got.items()}
    assert kinds["unknown robot"] == "not-found" and kinds["built-in"] == "read-only"
    assert kinds["stale etag"] == "precondition-failed" and kinds["not reached"] == "ik-not-converged"
    assert kinds["too many"] == "too-large" and kinds["out of limits"] == "invalid-input"


@pytest.mark.anyio
async def test_async_client_and_streams_answer_paths_and_every_solution(server: Server, transport: str) -> None:
    target = _target(server)
    body, _ = _path_body(server)
    raw_path = server.raw("POST", "/v1/robots/puma560/ik/path", body)
    raw_all = server.raw("POST", "/v1/robots/puma560/ik", {"target": {"matrix": target.tolist()}, "solutions": "all"})
    async with kc.AsyncClient(server.address(transport), transport=transport) as c:  # type: ignore[arg-type]
        p = await c.ik_path("puma560", PATH_START, body["waypoints"], angle_unit="deg", max_step_length=0.01)
        _same_path(p, raw_path)
        r = await c.ik("puma560", target, solutions="all")
        assert r.solutions is not None
        assert np.allclose(r.solutions, [s["joints"] for s in raw_all["solutions"]], atol=EXACT)
        async with c.stream("puma560") as s:
            await s.send_ik_path(PATH_START, body["waypoints"], angle_unit="deg", max_step_length=0.01)
            reply = (await s.recv()).unwrap()
            assert reply.ik_path is not None
            _same_path(reply.ik_path, raw_path)
            await s.send_ik(target, solutions="all")
            ik = (await s.recv()).unwrap().ik
            assert ik is not None and ik.solutions is not None and ik.solution_details is not None
            assert np.allclose(ik.solutions, [x["joints"] for x in raw_all["solutions"]], atol=EXACT)
            for got, want in zip(ik.solution_details, raw_all["solutions"]):
                _same_solution(got, want)
            await s.send_ik_path([0.0] * 6, [[0.5, 0.0, 0.5]], position_only=True, max_step_length=0.0)
            bad = await s.recv()
            assert bad.error is not None and bad.error.kind == "invalid-input"
            assert list(bad.error.fields) == ["max_step_length"]

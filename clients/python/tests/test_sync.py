"""The blocking client on both transports against the real server: numbers
equal to the server's own REST JSON (to 1e-12: the same doubles, only
re-encoded) or the kinematics library (to 1e-9), numpy shapes, registry
operations with ETags, typed errors with field paths."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import kinserve_client as kc
from conftest import Server, planar_model

EXACT = 1e-12  # the server's JSON against the client's arrays: same doubles
LIBRARY = 1e-9  # the kinematics library's FK against the server's
Q = [0.3, -0.4, 0.6, 0.2, -0.5, 0.7]


def test_fk_equals_the_server_json_and_the_library(client: kc.Client, server: Server) -> None:
    fk = client.fk("puma560", Q)
    raw = server.raw("POST", "/v1/robots/puma560/fk", {"joints": Q})
    assert fk.transform.shape == (4, 4)
    assert np.allclose(fk.transform, raw["pose"]["matrix"], rtol=0, atol=EXACT)
    assert fk.pose is not None
    q = raw["pose"]["quaternion"]
    assert np.allclose(fk.pose.quaternion, [q["w"], q["x"], q["y"], q["z"]], atol=EXACT)
    if server.expected:
        assert np.allclose(fk.transform, server.expected["fk"]["matrix"], atol=LIBRARY)
    frames = client.fk("puma560", Q, frames=True).frames
    assert frames is not None and frames.shape == (7, 4, 4)
    assert np.allclose(frames[-1], fk.transform, atol=EXACT)


def test_fk_compact_formats_and_degrees(client: kc.Client) -> None:
    full = client.fk("puma560", Q).transform
    m = client.fk("puma560", Q, pose_format="matrix", frames=True)
    assert m.transform.shape == (3, 4) and m.frames is not None and m.frames.shape == (7, 3, 4)
    assert np.allclose(m.transform, full[:3], atol=EXACT)
    p = client.fk("puma560", Q, pose_format="position").transform
    assert p.shape == (3,) and np.allclose(p, full[:3, 3], atol=EXACT)
    deg = client.fk("puma560", np.degrees(Q), angle_unit="deg").transform
    assert np.allclose(deg, full, atol=1e-12)


@pytest.mark.parametrize("fmt,shape", [("full", (4, 4)), ("matrix", (3, 4)), ("position", (3,))])
def test_fk_batch_shapes_and_numbers(client: kc.Client, server: Server, fmt: str, shape: tuple[int, ...]) -> None:
    rng = np.random.default_rng(7)
    q = rng.uniform(-1.0, 1.0, size=(50, 6))
    out = client.fk_batch("puma560", q, pose_format=fmt)  # type: ignore[arg-type]
    assert out.shape == (50, *shape) and out.dtype == np.float64
    raw = server.raw("POST", "/v1/robots/puma560/fk/batch", {"configurations": q.tolist()})
    matrices = np.array([p["matrix"] for p in raw["poses"]])
    expected = {"full": matrices, "matrix": matrices[:, :3, :], "position": matrices[:, :3, 3]}[fmt]
    assert np.allclose(out, expected, rtol=0, atol=EXACT)
    deg = client.fk_batch("puma560", np.degrees(q), angle_unit="deg", pose_format=fmt)  # type: ignore[arg-type]
    assert np.allclose(deg, out, atol=1e-12)


def test_jacobian_and_batch(client: kc.Client, server: Server) -> None:
    j = client.jacobian("puma560", Q)
    raw = server.raw("POST", "/v1/robots/puma560/jacobian", {"joints": Q})
    assert j.jacobian.shape == (6, 6)
    assert np.allclose(j.jacobian, raw["jacobian"], atol=EXACT)
    assert math.isclose(j.manipulability, raw["manipulability"], abs_tol=EXACT)
    q = np.array([Q, [0.0] * 6, [0.1] * 6])
    b = client.jacobian_batch("puma560", q, frame="tool")
    assert b.jacobians.shape == (3, 6, 6) and b.poses.shape == (3, 4, 4)
    raw_b = server.raw("POST", "/v1/robots/puma560/jacobian/batch", {"configurations": q.tolist(), "frame": "tool"})
    res = raw_b["results"]
    assert np.allclose(b.jacobians, [r["jacobian"] for r in res], atol=EXACT)
    assert b.singular.tolist() == [r["singular"] for r in res]
    assert np.allclose(b.manipulability, [r["manipulability"] for r in res], atol=EXACT)
    assert np.allclose(b.condition_number, [r["condition_number"] for r in res], atol=EXACT)
    assert np.allclose(b.poses, [r["pose"]["matrix"] for r in res], atol=EXACT)
    assert (b.robot, b.length_unit, b.frame) == (raw_b["robot"], raw_b["length_unit"], "tool")
    # The stretched planar arm: a smallest singular value of exactly 0, JSON's
    # null condition number, NaN in the arrays on both transports.
    qp = [[0.0, 0.0], [0.5, 0.1]]
    p = client.jacobian_batch("planar_2dof", qp)
    raw_p = server.raw("POST", "/v1/robots/planar_2dof/jacobian/batch", {"configurations": qp})["results"]
    assert raw_p[0]["condition_number"] is None and np.isnan(p.condition_number[0])
    assert math.isclose(p.condition_number[1], raw_p[1]["condition_number"], rel_tol=0, abs_tol=EXACT)
    assert p.singular.tolist() == [True, False]


def test_ik_reaches_targets_given_as_matrices(client: kc.Client) -> None:
    rng = np.random.default_rng(3)
    q = rng.uniform(-0.8, 0.8, size=(5, 6))
    targets = client.fk_batch("puma560", q)
    one = client.ik("puma560", targets[0], tolerance=1e-10)
    assert one.converged and one.joints.shape == (6,)
    assert np.allclose(client.fk("puma560", one.joints).transform, targets[0], atol=1e-8)
    batch = client.ik_batch("puma560", targets, tolerance=1e-10)
    assert batch.joints.shape == (5, 6) and batch.poses.shape == (5, 4, 4)
    assert batch.converged.all()
    reached = client.fk_batch("puma560", batch.joints)
    assert np.allclose(reached, targets, atol=1e-8)
    pos = client.ik_batch("planar_2dof", np.array([[0.5, 0.3, 0.0], [0.5, 0.32, 0.0]]), position_only=True)
    assert pos.converged.all() and np.isnan(pos.orientation_error).all()
    assert np.allclose(pos.poses[:, :3, 3], [[0.5, 0.3, 0.0], [0.5, 0.32, 0.0]], atol=1e-8)


def test_unknown_ik_options_are_passed_through(client: kc.Client, transport: str) -> None:
    """Options without a parameter (fields of newer servers) are passed
    through by their REST names: the server names one it does not know, and
    over gRPC a name this build's messages lack is a ``ValueError``; the typed
    ones reach the server on both transports."""
    target = client.fk("puma560", Q).transform
    if transport == "grpc":
        with pytest.raises(ValueError, match="frobnicate"):
            client.ik("puma560", target, frobnicate=1)
    else:
        with pytest.raises(kc.InvalidArgument) as e:
            client.ik("puma560", target, frobnicate=1)
        assert "frobnicate" in e.value.detail and e.value.kind == "malformed-request"
    assert client.ik("puma560", target, solver="analytic").solver == "analytic"


def test_link_transforms_multiply_to_the_pose(client: kc.Client) -> None:
    lt = client.link_transforms("planar_2dof", [0.5, 0.1])
    assert lt.matrices.shape == (2, 4, 4)
    product = lt.matrices[0] @ lt.matrices[1]
    assert np.allclose(product, client.fk("planar_2dof", [0.5, 0.1]).transform, atol=1e-12)
    assert np.allclose(lt.matrices[0] @ lt.inverses[0], np.eye(4), atol=1e-12)


def test_robots_pages_cover_the_list(client: kc.Client, server: Server) -> None:
    names = [r.name for r in client.robots(page_size=2)]
    raw = server.raw("GET", "/v1/robots?page_size=1000")
    assert names == [r["name"] for r in raw["robots"]]
    assert len(names) > 2
    page = client.list_robots_page(2)
    assert len(page.robots) == 2 and page.next_page_token
    puma = next(r for r in client.robots() if r.name == "puma560")
    assert (puma.dof, puma.convention, puma.source) == (6, "standard", "builtin")


def test_get_robot_is_the_same_model_on_both_transports(client: kc.Client, server: Server) -> None:
    info = client.get_robot("puma560")
    assert info.robot == server.raw("GET", "/v1/robots/puma560")
    assert info.etag.startswith('"builtin-')


def _name(transport: str, what: str) -> str:
    return f"py-{what}-{transport}"


def test_register_replace_delete_with_etags(client: kc.Client, transport: str, server: Server) -> None:
    name = _name(transport, "etag")
    reg = client.register(planar_model(name))
    assert reg.created and reg.etag
    fk = client.fk(name, [30, 20], angle_unit="deg").transform
    a1, a12 = math.radians(30), math.radians(50)
    assert np.allclose(fk[:3, 3], [0.5 * math.cos(a1) + 0.3 * math.cos(a12), 0.5 * math.sin(a1) + 0.3 * math.sin(a12), 0], atol=1e-12)
    with pytest.raises(kc.AlreadyExists):
        client.register(planar_model(name))
    with pytest.raises(kc.FailedPrecondition) as stale:
        client.replace(planar_model(name), etag='"no-such-version"')
    assert stale.value.code == "FAILED_PRECONDITION"
    changed = planar_model(name)
    changed["links"][1]["a"] = 0.25
    rep = client.replace(changed, etag=reg.etag)
    assert not rep.created and rep.etag != reg.etag
    assert client.get_robot(name).robot["links"][1]["a"] == 0.25
    with pytest.raises(kc.FailedPrecondition):
        client.delete(name, etag=reg.etag)
    client.delete(name, etag=rep.etag)
    with pytest.raises(kc.NotFound):
        client.get_robot(name)


def test_register_from_a_file(client: kc.Client, transport: str, tmp_path: Path) -> None:
    name = _name(transport, "file")
    path = tmp_path / "robot.json"
    path.write_text(json.dumps(planar_model(name)))
    assert client.register(path).created
    assert client.get_robot(name).robot["links"][0]["a"] == 0.5
    client.delete(name)


def test_urdf_round_trip(client: kc.Client, transport: str) -> None:
    urdf = client.urdf("puma560")
    assert urdf.startswith("<?xml") or urdf.lstrip().startswith("<robot")
    name = _name(transport, "urdf")
    reg = client.import_urdf(name, urdf, tip_link="tool")
    assert reg.created
    q = np.array([Q, [0.1] * 6])
    assert np.allclose(client.fk_batch(name, q), client.fk_batch("puma560", q), atol=1e-9)
    client.delete(name)


def test_closed_form_is_the_same_on_both_transports(client: kc.Client, server: Server) -> None:
    cf = client.closed_form("planar_2dof")
    raw = server.raw("GET", "/v1/robots/planar_2dof/closed-form")
    assert cf.symbols == raw["symbols"]
    assert cf.transform.text == raw["transform"]["text"]
    assert cf.variables == raw["variables"]
    assert np.array_equal(cf.base, raw["base"])


def _error(fn: Any) -> kc.KinserveError:
    with pytest.raises(kc.KinserveError) as e:
        fn()
    return e.value


def test_errors_are_typed_with_field_paths(client: kc.Client, transport: str) -> None:
    e = _error(lambda: client.fk("puma560", [0, 3.0, 0, 0, 0, 0]))
    assert isinstance(e, kc.InvalidArgument) and e.code == "INVALID_ARGUMENT"
    assert list(e.fields) == ["joints[1]"], e
    e = _error(lambda: client.fk_batch("puma560", [[0.0] * 6, [0, 3.0, 0, 0, 0, 0]]))
    assert list(e.fields) == ["configurations[1][1]"], e
    e = _error(lambda: client.fk("nope", [0.0]))
    assert isinstance(e, kc.NotFound) and e.kind == "not-found" and e.status == 404
    e = _error(lambda: client.ik("puma560", [5.0, 5.0, 5.0], position_only=True, restarts=1))
    assert isinstance(e, kc.IkNotConverged) and e.kind == "ik-not-converged"
    assert e.best_attempt is not None and e.best_attempt.joints.shape == (6,)
    if transport == "rest":
        assert (e.status, e.type) == (422, "urn:kinserve:problem:ik-not-converged")


def test_writes_without_the_token_are_unauthenticated(server: Server, transport: str) -> None:
    with kc.Client(server.address(transport), transport=transport) as anonymous:  # type: ignore[arg-type]
        e = _error(lambda: anonymous.register(planar_model(_name(transport, "anon"))))
    assert isinstance(e, kc.Unauthenticated) and e.kind == "unauthenticated"


def test_grpc_batches_send_packed_configurations() -> None:
    """The gRPC batches' configurations go as ``packed_configurations`` (one
    block of doubles), which the generated message reads back as sent; an
    answer shorter than the batch (a server that ignores the field) is an
    error, not a short array."""
    from kinserve_client import _grpc
    from kinserve_client._pb.kinematics.v1 import kinematics_pb2 as pb

    q = np.random.default_rng(3).uniform(-1.0, 1.0, size=(5, 7))
    msg = pb.ForwardKinematicsBatchRequest.FromString(_grpc.packed_configurations(4, q))
    assert msg.packed_configurations.joint_count == 7 and not msg.configurations
    assert np.array_equal(np.asarray(msg.packed_configurations.values), q.ravel())
    jac = pb.JacobianBatchRequest.FromString(_grpc.packed_configurations(5, q[:0]))
    assert jac.HasField("packed_configurations") and not jac.packed_configurations.values
    with pytest.raises(kc.KinserveError, match="packed_configurations") as e:
        _grpc.answered(np.zeros((0, 3)), 5, "poses")
    assert e.value.code == "UNIMPLEMENTED"


def test_a_batch_of_the_wrong_width_is_refused(client: kc.Client) -> None:
    """Six configurations of 7 values for the 6-joint PUMA: 42 values, a whole
    number of 6-joint configurations too, refused on both transports (the
    packed batch says its width) instead of read as seven others."""
    q = np.zeros((6, 7))
    for call in (client.fk_batch, client.jacobian_batch):
        with pytest.raises(kc.errors.InvalidArgument) as e:
            call("puma560", q)
        assert [f.rsplit(".", 1)[-1] for f in e.value.fields] == ["joint_count"], e.value

"""REST calls: each operation as an HTTP request on ``/v1/robots/...`` and the
parser of its JSON answer; problem+json errors decoded into
:class:`~kinserve_client.errors.KinserveError`.

Owns the REST mapping; depends on ``_calls``, the result types and the
errors, not on gRPC.
"""

from __future__ import annotations

import os
from typing import Any, Mapping, Sequence
from urllib.parse import quote

import httpx
import numpy as np

from . import errors
from ._calls import (
    RestCall,
    configurations,
    ik_choices,
    joint_vector,
    load_model,
    load_urdf,
    pad_rows,
    target_json,
    targets_json,
    waypoints_json,
)
from .types import (
    JSON,
    AngleUnit,
    Array,
    ArrayLike,
    ClosedForm,
    FkResult,
    Frame,
    IkBatch,
    IkBranch,
    IkPath,
    IkResult,
    IkSolution,
    IkSolutions,
    IkSolver,
    Jacobian,
    JacobianBatch,
    LinkTransforms,
    PathStop,
    Pose,
    PoseFormat,
    Registered,
    RobotInfo,
    RobotPage,
    RobotSummary,
    SymbolicMatrix,
)

URDF_IMPORT = "application/vnd.kinserve.urdf-import+json"
OCTETS = "application/octet-stream"

_IK_FIELDS = {
    "joints", "converged", "position_error", "orientation_error", "iterations", "pose",
    "solver", "branch", "singular", "solutions", "truncated",
}
_IK_TOP = {"robot", "length_unit", "angle_unit"}


def _robot_path(name: str, tail: str = "") -> str:
    return f"/v1/robots/{quote(name, safe='')}{tail}"


def _f(a: Any) -> Array:
    return np.asarray(a, dtype=np.float64)


def parse_pose(p: Mapping[str, Any]) -> Pose:
    """A REST pose object."""
    q = p["quaternion"]
    return Pose(
        matrix=_f(p["matrix"]),
        position=_f(p["position"]),
        quaternion=_f([q["w"], q["x"], q["y"], q["z"]]),
        rpy=_f(p["rpy"]),
    )


def parse_branch(b: Mapping[str, Any] | None) -> IkBranch | None:
    """A REST ``IkBranch`` (``None`` stays ``None``)."""
    if b is None:
        return None
    return IkBranch(int(b["shoulder"]), int(b["elbow"]), int(b["wrist"]))


def parse_solution(s: Mapping[str, Any]) -> IkSolution:
    """A REST ``IkSolutionItem``."""
    return IkSolution(
        joints=_f(s["joints"]),
        branch=parse_branch(s.get("branch")),
        singular=tuple(s.get("singular") or ()),
        distance=float(s["distance"]),
        position_error=float(s["position_error"]),
        orientation_error=float(s["orientation_error"]),
    )


def solutions_array(details: list[IkSolution], dof: int) -> Array:
    """(K, dof) joints of ``details`` (K may be 0)."""
    return np.asarray([d.joints for d in details], dtype=np.float64).reshape(len(details), dof)


def parse_ik_item(item: Mapping[str, Any], top: Mapping[str, Any] | None = None) -> IkResult:
    """A REST IK answer (``IkItem``, optionally flattened with the top fields;
    a WebSocket IK reply too)."""
    top = top or {}
    orient = item.get("orientation_error")
    joints = _f(item["joints"])
    raw = item.get("solutions")
    details = None if raw is None else [parse_solution(x) for x in raw]
    truncated = item.get("truncated")
    return IkResult(
        joints=joints,
        converged=bool(item["converged"]),
        position_error=float(item["position_error"]),
        orientation_error=None if orient is None else float(orient),
        iterations=int(item["iterations"]),
        pose=parse_pose(item["pose"]),
        robot=top.get("robot"),
        length_unit=top.get("length_unit"),
        angle_unit=top.get("angle_unit"),
        solver=item.get("solver"),
        branch=parse_branch(item.get("branch")),
        singular=tuple(item.get("singular") or ()),
        solutions=None if details is None else solutions_array(details, joints.shape[0]),
        solution_details=details,
        truncated=None if truncated is None else bool(truncated),
        extra={k: v for k, v in item.items() if k not in _IK_FIELDS | _IK_TOP},
    )


def parse_path(b: Mapping[str, Any], top: Mapping[str, Any] | None = None) -> IkPath:
    """A REST ``IkPathOutput`` (or the path part of a WebSocket reply)."""
    top = top if top is not None else b
    points = b["points"]
    dof = len(points[0]) if points else 0
    stop = b.get("stop")
    return IkPath(
        robot=str(top.get("robot", "")),
        length_unit=str(top.get("length_unit", "")),
        angle_unit=str(top.get("angle_unit", "")),
        points=_f(points).reshape(len(points), dof),
        fraction=float(b["fraction"]),
        waypoints_reached=int(b["waypoints_reached"]),
        stop=None
        if stop is None
        else PathStop(int(stop["step"]), int(stop["waypoint"]), stop["reason"], str(stop["detail"])),
    )


def error_from_problem(status: int, body: Any, reason: str) -> errors.KinserveError:
    """The exception for a non-success answer (problem+json when the server wrote one)."""
    if not isinstance(body, dict) or "type" not in body:
        kind = {404: "no-route", 401: "unauthenticated"}.get(status)
        code = errors.KINDS[kind][0] if kind else "UNKNOWN"
        return errors.make_error(
            code=code, kind=kind, detail=reason, status=status, transport="rest"
        )
    type_ = str(body["type"])
    kind = type_[len(errors.PROBLEM_PREFIX) :] if type_.startswith(errors.PROBLEM_PREFIX) else None
    code = errors.KINDS[kind][0] if kind in errors.KINDS else "UNKNOWN"
    fields = {str(e["field"]): str(e["message"]) for e in body.get("errors") or []}
    best = body.get("best_attempt")
    return errors.make_error(
        code=code,
        kind=kind,
        detail=str(body.get("detail", reason)),
        status=int(body.get("status", status)),
        title=body.get("title"),
        fields=fields,
        best_attempt=None if best is None else parse_ik_item(best),
        transport="rest",
    )


def raise_for(r: httpx.Response) -> None:
    """Raises the :class:`KinserveError` of an error answer."""
    if r.is_success:
        return
    try:
        body = r.json()
    except ValueError:
        body = None
    err = error_from_problem(r.status_code, body, r.reason_phrase or str(r.status_code))
    try:
        err.retry_after = float(r.headers["Retry-After"])
    except (KeyError, ValueError):
        pass
    raise err


def _json(r: httpx.Response) -> Any:
    return r.json()


def _etag_precondition(etag: str | None) -> dict[str, str]:
    return {} if etag is None else {"If-Match": etag}


class RestOps:
    """The operations as REST calls (see :class:`kinserve_client.Client` for the docs)."""

    def list_robots_page(
        self, page_size: int | None = None, page_token: str | None = None
    ) -> RestCall[RobotPage]:
        params = {}
        if page_size is not None:
            params["page_size"] = str(page_size)
        if page_token:
            params["page_token"] = page_token

        def parse(r: httpx.Response) -> RobotPage:
            body = r.json()
            robots = [
                RobotSummary(
                    name=s["name"],
                    dof=int(s["dof"]),
                    convention=s["convention"],
                    length_unit=s["length_unit"],
                    source=s["source"],
                    ik_class=s.get("ik_class"),
                )
                for s in body["robots"]
            ]
            return RobotPage(robots, body.get("next_page_token"))

        return RestCall("GET", "/v1/robots", parse, params=params)

    def get_robot(self, name: str) -> RestCall[RobotInfo]:
        return RestCall(
            "GET", _robot_path(name), lambda r: RobotInfo(r.json(), r.headers.get("etag", ""))
        )

    def register(
        self,
        model: Mapping[str, Any] | str | os.PathLike[str],
        *,
        replace: bool = False,
        etag: str | None = None,
    ) -> RestCall[Registered]:
        body = load_model(model)
        return self._write(str(body.get("name", "")), replace, etag, json_body=body)

    def import_urdf(
        self,
        name: str,
        urdf: str | os.PathLike[str],
        *,
        base_link: str | None = None,
        tip_link: str | None = None,
        convention: str | None = None,
        replace: bool = False,
        etag: str | None = None,
    ) -> RestCall[Registered]:
        body: dict[str, JSON] = {"name": name, "urdf": load_urdf(urdf)}
        for key, value in [("base_link", base_link), ("tip_link", tip_link), ("convention", convention)]:
            if value is not None:
                body[key] = value
        call = self._write(name, replace, etag, json_body=body)
        call.headers["Content-Type"] = URDF_IMPORT
        return call

    def _write(
        self, name: str, replace: bool, etag: str | None, *, json_body: dict[str, JSON]
    ) -> RestCall[Registered]:
        def parse(r: httpx.Response) -> Registered:
            return Registered(r.json(), r.headers.get("etag", ""), r.status_code == 201)

        import json as _j

        content = _j.dumps(json_body).encode()
        headers = {"Content-Type": "application/json"}
        if not replace:
            return RestCall("POST", "/v1/robots", parse, content=content, headers=headers)
        headers.update(_etag_precondition(etag))
        return RestCall("PUT", _robot_path(name), parse, content=content, headers=headers)

    def delete(self, name: str, *, etag: str | None = None) -> RestCall[None]:
        return RestCall(
            "DELETE", _robot_path(name), lambda r: None, headers=_etag_precondition(etag)
        )

    def urdf(self, robot: str) -> RestCall[str]:
        return RestCall("GET", _robot_path(robot, "/urdf"), lambda r: r.text)

    def closed_form(self, robot: str) -> RestCall[ClosedForm]:
        def sym(m: Mapping[str, Any]) -> SymbolicMatrix:
            return SymbolicMatrix([list(row) for row in m["text"]], m["latex"], m["mathml"])

        def parse(r: httpx.Response) -> ClosedForm:
            b = r.json()
            tool = b.get("tool")
            return ClosedForm(
                robot=b["robot"],
                convention=b["convention"],
                length_unit=b["length_unit"],
                variables=list(b["variables"]),
                symbols={k: float(v) for k, v in b["symbols"].items()},
                link_transforms=[sym(m) for m in b["link_transforms"]],
                transform=sym(b["transform"]),
                base=_f(b["base"]),
                tool=None if tool is None else _f(tool),
            )

        return RestCall("GET", _robot_path(robot, "/closed-form"), parse)

    def fk(
        self,
        robot: str,
        joints: ArrayLike,
        *,
        angle_unit: AngleUnit = "rad",
        frames: bool = False,
        check_limits: bool = True,
        pose_format: PoseFormat = "full",
    ) -> RestCall[FkResult]:
        body = {
            "joints": joint_vector(joints),
            "angle_unit": angle_unit,
            "frames": frames,
            "check_limits": check_limits,
            "pose_format": pose_format,
        }

        def parse(r: httpx.Response) -> FkResult:
            b = r.json()
            return fk_result(b, pose_format)

        return RestCall("POST", _robot_path(robot, "/fk"), parse, json=body)

    def fk_batch(
        self,
        robot: str,
        configurations_: ArrayLike,
        *,
        angle_unit: AngleUnit = "rad",
        check_limits: bool = True,
        pose_format: PoseFormat = "full",
    ) -> RestCall[Array]:
        q = configurations(configurations_)
        wire = "position" if pose_format == "position" else "matrix"
        # Packed both ways (application/octet-stream, little-endian float64):
        # the array's bytes in, the poses' doubles out, nothing printed or
        # parsed; the options are query parameters, with the array's width
        # (joint_count) so that one of the wrong width is refused, not read
        # as other configurations.
        params = {
            "angle_unit": angle_unit,
            "check_limits": "true" if check_limits else "false",
            "pose_format": wire,
            "joint_count": str(q.shape[1]),
        }
        packed = np.ascontiguousarray(q, dtype="<f8").tobytes()

        def parse(r: httpx.Response) -> Array:
            values = np.frombuffer(r.content, dtype="<f8").astype(np.float64)
            if wire == "position":
                return values.reshape(-1, 3)
            top = values.reshape(-1, 3, 4)
            return top if pose_format == "matrix" else pad_rows(top)

        headers = {"content-type": OCTETS, "accept": OCTETS}
        return RestCall(
            "POST", _robot_path(robot, "/fk/batch"), parse, content=packed, params=params, headers=headers
        )

    def jacobian(
        self,
        robot: str,
        joints: ArrayLike,
        *,
        angle_unit: AngleUnit = "rad",
        check_limits: bool = True,
        frame: Frame = "base",
    ) -> RestCall[Jacobian]:
        body = {
            "joints": joint_vector(joints),
            "angle_unit": angle_unit,
            "check_limits": check_limits,
            "frame": frame,
        }
        return RestCall(
            "POST", _robot_path(robot, "/jacobian"), lambda r: jacobian_item(r.json()), json=body
        )

    def jacobian_batch(
        self,
        robot: str,
        configurations_: ArrayLike,
        *,
        angle_unit: AngleUnit = "rad",
        check_limits: bool = True,
        frame: Frame = "base",
    ) -> RestCall[JacobianBatch]:
        q = configurations(configurations_)
        dof = q.shape[1]
        # Packed both ways, as fk_batch: per result the 6 × dof rows,
        # manipulability, condition number (+inf where JSON has null),
        # singular (1 or 0) and the pose's 12 `matrix` numbers.
        params = {
            "angle_unit": angle_unit,
            "check_limits": "true" if check_limits else "false",
            "frame": frame,
            "joint_count": str(dof),
        }
        packed = np.ascontiguousarray(q, dtype="<f8").tobytes()

        def parse(r: httpx.Response) -> JacobianBatch:
            j = 6 * dof
            v = np.frombuffer(r.content, dtype="<f8").astype(np.float64).reshape(-1, j + 15)
            n = len(v)
            cond = v[:, j + 1].copy()
            cond[np.isinf(cond)] = np.nan  # JSON's null: no finite condition number
            return JacobianBatch(
                robot=robot,
                length_unit=r.headers.get("kinserve-length-unit", ""),
                frame=frame,
                jacobians=v[:, :j].reshape(n, 6, dof),
                manipulability=v[:, j].copy(),
                condition_number=cond,
                singular=v[:, j + 2] != 0.0,
                poses=pad_rows(v[:, j + 3 :].reshape(n, 3, 4)),
            )

        headers = {"content-type": OCTETS, "accept": OCTETS}
        return RestCall(
            "POST", _robot_path(robot, "/jacobian/batch"), parse, content=packed, params=params, headers=headers
        )

    def ik(
        self,
        /,
        robot: str,
        target: ArrayLike | Mapping[str, Any],
        *,
        seed: ArrayLike | None = None,
        angle_unit: AngleUnit = "rad",
        position_only: bool = False,
        tolerance: float | None = None,
        max_iterations: int | None = None,
        restarts: int | None = None,
        solver: IkSolver | None = None,
        solutions: IkSolutions | None = None,
        max_solutions: int | None = None,
        **options: JSON,
    ) -> RestCall[IkResult]:
        options = {**ik_choices(solver, solutions, max_solutions), **options}
        body = ik_body(seed, angle_unit, position_only, tolerance, max_iterations, restarts, options)
        body["target"] = target_json(target)

        def parse(r: httpx.Response) -> IkResult:
            b = r.json()
            return parse_ik_item(b, b)

        return RestCall("POST", _robot_path(robot, "/ik"), parse, json=body)

    def ik_batch(
        self,
        /,
        robot: str,
        targets: ArrayLike,
        *,
        seed: ArrayLike | None = None,
        angle_unit: AngleUnit = "rad",
        position_only: bool = False,
        tolerance: float | None = None,
        max_iterations: int | None = None,
        restarts: int | None = None,
        solver: IkSolver | None = None,
        solutions: IkSolutions | None = None,
        max_solutions: int | None = None,
        **options: JSON,
    ) -> RestCall[IkBatch]:
        options = {**ik_choices(solver, solutions, max_solutions), **options}
        body = ik_body(seed, angle_unit, position_only, tolerance, max_iterations, restarts, options)
        body["targets"] = targets_json(targets)

        def parse(r: httpx.Response) -> IkBatch:
            b = r.json()
            results = [parse_ik_item(x) for x in b["results"]]
            return ik_batch(b["robot"], b["length_unit"], b["angle_unit"], results)

        return RestCall("POST", _robot_path(robot, "/ik/batch"), parse, json=body)

    def ik_path(
        self,
        /,
        robot: str,
        start: ArrayLike,
        waypoints: ArrayLike | Sequence[ArrayLike | Mapping[str, Any]],
        *,
        angle_unit: AngleUnit = "rad",
        position_only: bool = False,
        max_step_length: float | None = None,
        max_step_angle: float | None = None,
        max_joint_step: float | None = None,
        tolerance: float | None = None,
        solver: IkSolver | None = None,
        max_iterations: int | None = None,
        restarts: int | None = None,
    ) -> RestCall[IkPath]:
        body = path_body(
            start, waypoints, angle_unit, position_only,
            {
                "max_step_length": max_step_length,
                "max_step_angle": max_step_angle,
                "max_joint_step": max_joint_step,
                "tolerance": tolerance,
                "solver": solver,
                "max_iterations": max_iterations,
                "restarts": restarts,
            },
        )
        return RestCall("POST", _robot_path(robot, "/ik/path"), lambda r: parse_path(r.json()), json=body)

    def link_transforms(
        self,
        robot: str,
        joints: ArrayLike,
        *,
        angle_unit: AngleUnit = "rad",
        check_limits: bool = True,
    ) -> RestCall[LinkTransforms]:
        body = {"joints": joint_vector(joints), "angle_unit": angle_unit, "check_limits": check_limits}

        def parse(r: httpx.Response) -> LinkTransforms:
            b = r.json()
            items = b["link_transforms"]
            n = len(items)
            return LinkTransforms(
                robot=b["robot"],
                length_unit=b["length_unit"],
                matrices=_f([x["matrix"] for x in items]).reshape(n, 4, 4),
                inverses=_f([x["inverse"] for x in items]).reshape(n, 4, 4),
            )

        return RestCall("POST", _robot_path(robot, "/link-transforms"), parse, json=body)


def ik_body(
    seed: ArrayLike | None,
    angle_unit: AngleUnit,
    position_only: bool,
    tolerance: float | None,
    max_iterations: int | None,
    restarts: int | None,
    options: Mapping[str, JSON],
) -> dict[str, JSON]:
    """The REST IK body's common fields; ``options`` (fields this client has
    no parameter for) are passed through as they are."""
    body: dict[str, JSON] = {"angle_unit": angle_unit, "position_only": position_only}
    if seed is not None:
        body["seed"] = joint_vector(seed)
    for key, value in [("tolerance", tolerance), ("max_iterations", max_iterations), ("restarts", restarts)]:
        if value is not None:
            body[key] = value
    body.update(options)
    return body


def path_body(
    start: ArrayLike,
    waypoints: ArrayLike | Sequence[ArrayLike | Mapping[str, Any]],
    angle_unit: AngleUnit,
    position_only: bool,
    optional: Mapping[str, JSON],
) -> dict[str, JSON]:
    """The REST body of a Cartesian path (the optional fields that were given)."""
    body: dict[str, JSON] = {
        "start": joint_vector(start),
        "waypoints": waypoints_json(waypoints),
        "angle_unit": angle_unit,
        "position_only": position_only,
    }
    body.update({k: v for k, v in optional.items() if v is not None})
    return body


def fk_result(b: Mapping[str, Any], pose_format: PoseFormat) -> FkResult:
    """An FK answer (REST body or WebSocket reply) in ``pose_format``."""
    frames: Array | None = None
    pose: Pose | None = None
    if pose_format == "full":
        pose = parse_pose(b["pose"])
        transform = pose.matrix
        if "frames" in b:
            frames = _f([f["matrix"] for f in b["frames"]]).reshape(-1, 4, 4)
    elif pose_format == "matrix":
        transform = _f(b["matrix"]).reshape(3, 4)
        if "frame_matrices" in b:
            frames = _f(b["frame_matrices"]).reshape(-1, 3, 4)
    else:
        transform = _f(b["position"]).reshape(3)
        if "frame_positions" in b:
            frames = _f(b["frame_positions"]).reshape(-1, 3)
    return FkResult(
        robot=str(b.get("robot", "")),
        length_unit=str(b["length_unit"]),
        pose_format=pose_format,
        transform=transform,
        pose=pose,
        frames=frames,
    )


def jacobian_item(b: Mapping[str, Any]) -> Jacobian:
    """A Jacobian answer (REST body or WebSocket reply)."""
    cond = b.get("condition_number")
    return Jacobian(
        robot=str(b.get("robot", "")),
        length_unit=str(b.get("length_unit", "")),
        frame=str(b["frame"]),
        jacobian=_f(b["jacobian"]),
        manipulability=float(b["manipulability"]),
        condition_number=None if cond is None else float(cond),
        singular=bool(b["singular"]),
        pose=parse_pose(b["pose"]) if isinstance(b.get("pose"), Mapping) else None,
    )


def ik_batch(robot: str, length_unit: str, angle_unit: str, results: list[IkResult]) -> IkBatch:
    """The arrays of N IK answers."""
    n = len(results)
    all_ = n > 0 and all(r.solutions is not None for r in results)
    return IkBatch(
        robot=robot,
        length_unit=length_unit,
        angle_unit=angle_unit,
        joints=np.asarray([r.joints for r in results], dtype=np.float64).reshape(n, -1),
        converged=np.asarray([r.converged for r in results], dtype=np.bool_),
        position_error=_f([r.position_error for r in results]),
        orientation_error=_f(
            [np.nan if r.orientation_error is None else r.orientation_error for r in results]
        ),
        iterations=np.asarray([r.iterations for r in results], dtype=np.int64),
        poses=np.asarray([r.pose.matrix for r in results], dtype=np.float64).reshape(n, 4, 4),
        results=results,
        solver=[r.solver for r in results],
        singular=np.asarray([bool(r.singular) for r in results], dtype=np.bool_),
        solutions=None if not all_ else [r.solutions for r in results if r.solutions is not None],
        truncated=None if not all_ else np.asarray([bool(r.truncated) for r in results], dtype=np.bool_),
    )

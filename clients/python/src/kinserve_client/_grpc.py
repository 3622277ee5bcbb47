"""gRPC calls: each operation as a unary call of
``kinematics.v1.KinematicsService`` (messages generated from ``proto/`` at
build time) and the parser of its response.

Batches are encoded straight from the numpy array (every configuration has
the same wire prefix, so the repeated messages are one array operation, not
a Python loop per pose) and compact answers decoded from one packed field.

Owns the gRPC mapping; depends on ``_calls``, ``_pbconv`` and the result
types, not on REST.
"""

from __future__ import annotations

import os
from typing import Any, Mapping, Sequence, Sized, TypeVar

import numpy as np

from ._calls import (
    GrpcCall,
    configurations,
    ik_choices,
    joint_vector,
    load_model,
    load_urdf,
    pad_rows,
    target_json,
    waypoints_json,
)
from ._pb.kinematics.v1 import kinematics_pb2 as pb
from ._pbconv import (
    enum_text,
    enum_value,
    extras,
    ik_path,
    ik_result,
    pose,
    robot_from_pb,
    robot_to_pb,
    set_options,
    target_to_pb,
)
from ._rest import ik_batch as ik_batch_arrays
from .errors import KinserveError
from .types import (
    JSON,
    AngleUnit,
    Array,
    ArrayLike,
    ClosedForm,
    FkResult,
    Frame,
    IkBatch,
    IkPath,
    IkResult,
    IkSolutions,
    IkSolver,
    Jacobian,
    JacobianBatch,
    LinkTransforms,
    PoseFormat,
    Registered,
    RobotInfo,
    RobotPage,
    RobotSummary,
    SymbolicMatrix,
)

SERVICE = pb.DESCRIPTOR.services_by_name["KinematicsService"]


def method_path(name: str) -> str:
    """``/kinematics.v1.KinematicsService/<name>``, checked against the generated descriptor."""
    return f"/{SERVICE.full_name}/{SERVICE.methods_by_name[name].name}"


def _f(a: Any) -> Array:
    return np.asarray(a, dtype=np.float64)


def _varint(n: int) -> bytes:
    out = bytearray()
    while True:
        b, n = n & 0x7F, n >> 7
        out.append(b | 0x80 if n else b)
        if not n:
            return bytes(out)


def _tag(field: int, wire: int) -> bytes:
    return _varint(field << 3 | wire)


def nested_rows(fields: list[int], rows: Array) -> bytes:
    """Wire bytes of one repeated message per row of ``rows`` (N, k): the
    fields ``fields`` nested outside in, the innermost a packed double of k
    values (``configurations[i].joints``, ``targets[i].matrix.values``)."""
    n, k = rows.shape
    header, length = b"", 8 * k
    for field in reversed(fields):
        header = _tag(field, 2) + _varint(length) + header
        length = len(header) + 8 * k
    buf = np.empty((n, len(header) + 8 * k), dtype=np.uint8)
    buf[:, : len(header)] = np.frombuffer(header, dtype=np.uint8)
    buf[:, len(header) :] = np.ascontiguousarray(rows, dtype="<f8").view(np.uint8).reshape(n, 8 * k)
    return buf.tobytes()


def packed_configurations(field: int, rows: Array) -> bytes:
    """Wire bytes of ``PackedConfigurations { joint_count, values }`` as the
    batch request's field ``field``: the (N, dof) rows in one packed double
    field, one copy of the array (the server reads it in one block too)."""
    n, k = rows.shape
    data = np.ascontiguousarray(rows, dtype="<f8").tobytes()
    inner = _tag(1, 0) + _varint(k) if k else b""
    if n:
        inner += _tag(2, 2) + _varint(len(data)) + data
    return _tag(field, 2) + _varint(len(inner)) + inner


S = TypeVar("S", bound=Sized)


def answered(values: S, n: int, what: str) -> S:
    """``values`` when they hold ``n`` answers; else the server ignored
    ``packed_configurations`` (a server older than the field answers an
    empty batch): an error saying so instead of a silently short answer."""
    if len(values) != n:
        raise KinserveError(
            code="UNIMPLEMENTED",
            detail=f"{len(values)} {what} for {n} configurations: the server does not read "
            "packed_configurations (older than this client); upgrade the server",
            transport="grpc",
        )
    return values


def position_targets(field: int, rows: Array) -> bytes:
    """Wire bytes of ``IkTarget { position: Vector3 {x, y, z} }`` per row of (N, 3)."""
    n = rows.shape[0]
    vector = 3 * 9
    header = _tag(field, 2) + _varint(2 + vector) + _tag(2, 2) + _varint(vector)
    buf = np.empty((n, len(header) + vector), dtype=np.uint8)
    buf[:, : len(header)] = np.frombuffer(header, dtype=np.uint8)
    values = np.ascontiguousarray(rows, dtype="<f8").view(np.uint8).reshape(n, 3, 8)
    for j in range(3):
        at = len(header) + 9 * j
        buf[:, at] = (j + 1) << 3 | 1
        buf[:, at + 1 : at + 9] = values[:, j, :]
    return buf.tobytes()


def _options(
    angle_unit: AngleUnit,
    check_limits: bool,
    frames: bool | None = None,
    pose_format: str | None = None,
) -> Any:
    o = pb.FkOptions(angle_unit=enum_value(pb.AngleUnit, angle_unit), check_limits=check_limits)
    if frames is not None:
        o.frames = frames
    if pose_format is not None:
        o.pose_format = enum_value(pb.PoseFormat, pose_format)
    return o


def _unit(n: int) -> str:
    return enum_text(pb.LengthUnit, n, "m")


def _packed(p: Any, k: int) -> Array:
    return _f(p.values).reshape(-1, k) if k > 1 else _f(p.values)


def fk_answer(robot: str, length_unit: int, m: Any, pose_format: PoseFormat, has_frames: bool) -> FkResult:
    """An FK answer (unary or stream message) in ``pose_format``."""
    frames: Array | None = None
    if pose_format == "full":
        p = pose(m.pose)
        if has_frames:
            frames = _f([f.matrix for f in m.frames]).reshape(-1, 4, 4)
        return FkResult(robot, _unit(length_unit), pose_format, p.matrix, p, frames)
    shape = (3, 4) if pose_format == "matrix" else (3,)
    transform = _f(m.packed_pose.values).reshape(shape)
    if has_frames:
        frames = _f(m.packed_frames.values).reshape((-1,) + shape)
    return FkResult(robot, _unit(length_unit), pose_format, transform, None, frames)


def jacobian_of(robot: str, length_unit: int, r: Any) -> Jacobian:
    """A ``JacobianResult``."""
    return Jacobian(
        robot=robot,
        length_unit=_unit(length_unit),
        frame=enum_text(pb.JacobianFrame, r.frame, "base"),
        jacobian=_f(r.values).reshape(6, r.columns),
        manipulability=r.manipulability,
        condition_number=r.condition_number if r.HasField("condition_number") else None,
        singular=r.singular,
        pose=pose(r.pose),
    )


def _ik_request(
    msg: Any,
    seed: ArrayLike | None,
    angle_unit: AngleUnit,
    position_only: bool,
    tolerance: float | None,
    max_iterations: int | None,
    restarts: int | None,
    options: Mapping[str, JSON],
) -> Any:
    """Sets the IK request fields (``options`` by their REST names:
    ``solver``, ``solutions``, ``max_solutions`` and any newer ones)."""
    msg.angle_unit = enum_value(pb.AngleUnit, angle_unit)
    msg.position_only = position_only
    if seed is not None:
        msg.seed.joints.extend(joint_vector(seed))
    if tolerance is not None:
        msg.tolerance = tolerance
    if max_iterations is not None:
        msg.max_iterations = max_iterations
    if restarts is not None:
        msg.restarts = restarts
    set_options(msg, options)
    return msg


class GrpcOps:
    """The operations as gRPC calls (see :class:`kinserve_client.Client` for the docs)."""

    def list_robots_page(
        self, page_size: int | None = None, page_token: str | None = None
    ) -> GrpcCall[RobotPage]:
        req = pb.ListRobotsRequest(page_size=page_size or 0, page_token=page_token or "")

        def parse(r: Any) -> RobotPage:
            robots = [
                RobotSummary(
                    name=s.name,
                    dof=s.dof,
                    convention=enum_text(pb.Convention, s.convention, "standard"),
                    length_unit=_unit(s.length_unit),
                    source=enum_text(pb.RobotSource, s.source, ""),
                    ik_class=s.ik_class if s.HasField("ik_class") else None,
                )
                for s in r.robots
            ]
            return RobotPage(robots, r.next_page_token or None)

        return GrpcCall("ListRobots", req, pb.ListRobotsResponse, parse)

    def get_robot(self, name: str) -> GrpcCall[RobotInfo]:
        return GrpcCall(
            "GetRobot",
            pb.GetRobotRequest(name=name),
            pb.GetRobotResponse,
            lambda r: RobotInfo(robot_from_pb(r.robot), r.etag),
        )

    def register(
        self,
        model: Mapping[str, Any] | str | os.PathLike[str],
        *,
        replace: bool = False,
        etag: str | None = None,
    ) -> GrpcCall[Registered]:
        req = pb.RegisterRobotRequest(
            robot=robot_to_pb(load_model(model)), replace=replace, etag=etag or ""
        )
        return GrpcCall("RegisterRobot", req, pb.RegisterRobotResponse, _registered)

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
    ) -> GrpcCall[Registered]:
        req = pb.ImportUrdfRequest(
            name=name,
            urdf=load_urdf(urdf),
            base_link=base_link or "",
            tip_link=tip_link or "",
            convention=enum_value(pb.Convention, convention),
            replace=replace,
            etag=etag or "",
        )
        return GrpcCall("ImportUrdf", req, pb.RegisterRobotResponse, _registered)

    def delete(self, name: str, *, etag: str | None = None) -> GrpcCall[None]:
        req = pb.DeleteRobotRequest(name=name, etag=etag or "")
        return GrpcCall("DeleteRobot", req, pb.DeleteRobotResponse, lambda r: None)

    def urdf(self, robot: str) -> GrpcCall[str]:
        return GrpcCall(
            "GetUrdf", pb.GetUrdfRequest(robot=robot), pb.GetUrdfResponse, lambda r: str(r.urdf)
        )

    def closed_form(self, robot: str) -> GrpcCall[ClosedForm]:
        def sym(m: Any) -> SymbolicMatrix:
            text = list(m.text)
            return SymbolicMatrix([text[i : i + 4] for i in range(0, 16, 4)], m.latex, m.mathml)

        def parse(r: Any) -> ClosedForm:
            variables: list[dict[str, JSON]] = [
                {
                    "name": v.name,
                    "row": v.row,
                    "joint": v.joint,
                    "kind": enum_text(pb.JointType, v.kind, ""),
                    "offset": v.offset,
                }
                for v in r.variables
            ]
            return ClosedForm(
                robot=r.robot,
                convention=enum_text(pb.Convention, r.convention, "standard"),
                length_unit=_unit(r.length_unit),
                variables=variables,
                symbols=dict(r.symbols),
                link_transforms=[sym(m) for m in r.link_transforms],
                transform=sym(r.transform),
                base=_f(r.base.values).reshape(4, 4),
                tool=_f(r.tool.values).reshape(4, 4) if r.HasField("tool") else None,
            )

        return GrpcCall(
            "GetClosedForm", pb.GetClosedFormRequest(robot=robot), pb.GetClosedFormResponse, parse
        )

    def fk(
        self,
        robot: str,
        joints: ArrayLike,
        *,
        angle_unit: AngleUnit = "rad",
        frames: bool = False,
        check_limits: bool = True,
        pose_format: PoseFormat = "full",
    ) -> GrpcCall[FkResult]:
        req = pb.ForwardKinematicsRequest(
            robot=robot,
            joints=joint_vector(joints),
            options=_options(angle_unit, check_limits, frames, pose_format),
        )
        return GrpcCall(
            "ForwardKinematics",
            req,
            pb.ForwardKinematicsResponse,
            lambda r: fk_answer(r.robot, r.length_unit, r, pose_format, frames),
        )

    def fk_batch(
        self,
        robot: str,
        configurations_: ArrayLike,
        *,
        angle_unit: AngleUnit = "rad",
        check_limits: bool = True,
        pose_format: PoseFormat = "full",
    ) -> GrpcCall[Array]:
        q = configurations(configurations_)
        wire = "position" if pose_format == "position" else "matrix"
        head = pb.ForwardKinematicsBatchRequest(
            robot=robot, options=_options(angle_unit, check_limits, None, wire)
        )
        request = head.SerializeToString() + packed_configurations(4, q)

        def parse(r: Any) -> Array:
            if wire == "position":
                return answered(_packed(r.packed_poses, 3), len(q), "poses")
            top = answered(_f(r.packed_poses.values).reshape(-1, 3, 4), len(q), "poses")
            return top if pose_format == "matrix" else pad_rows(top)

        return GrpcCall("ForwardKinematicsBatch", request, pb.ForwardKinematicsBatchResponse, parse)

    def jacobian(
        self,
        robot: str,
        joints: ArrayLike,
        *,
        angle_unit: AngleUnit = "rad",
        check_limits: bool = True,
        frame: Frame = "base",
    ) -> GrpcCall[Jacobian]:
        req = pb.JacobianRequest(
            robot=robot,
            joints=joint_vector(joints),
            options=_options(angle_unit, check_limits),
            frame=enum_value(pb.JacobianFrame, frame),
        )
        return GrpcCall(
            "Jacobian",
            req,
            pb.JacobianResponse,
            lambda r: jacobian_of(r.robot, r.length_unit, r.result),
        )

    def jacobian_batch(
        self,
        robot: str,
        configurations_: ArrayLike,
        *,
        angle_unit: AngleUnit = "rad",
        check_limits: bool = True,
        frame: Frame = "base",
    ) -> GrpcCall[JacobianBatch]:
        q = configurations(configurations_)
        head = pb.JacobianBatchRequest(
            robot=robot,
            options=_options(angle_unit, check_limits),
            frame=enum_value(pb.JacobianFrame, frame),
        )
        request = head.SerializeToString() + packed_configurations(5, q)

        def parse(r: Any) -> JacobianBatch:
            res = answered(r.results, len(q), "Jacobians")
            n = len(res)
            return JacobianBatch(
                robot=r.robot,
                length_unit=_unit(r.length_unit),
                frame=frame,
                jacobians=_f([x.values for x in res]).reshape(n, 6, q.shape[1]),
                manipulability=_f([x.manipulability for x in res]),
                condition_number=_f(
                    [x.condition_number if x.HasField("condition_number") else np.nan for x in res]
                ),
                singular=np.asarray([x.singular for x in res], dtype=np.bool_),
                poses=_f([x.pose.matrix for x in res]).reshape(n, 4, 4),
            )

        return GrpcCall("JacobianBatch", request, pb.JacobianBatchResponse, parse)

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
    ) -> GrpcCall[IkResult]:
        req = pb.InverseKinematicsRequest(robot=robot, target=target_to_pb(target_json(target)))
        options = {**ik_choices(solver, solutions, max_solutions), **options}
        _ik_request(req, seed, angle_unit, position_only, tolerance, max_iterations, restarts, options)
        every = options.get("solutions") == "all"

        def parse(r: Any) -> IkResult:
            result = ik_result(
                r.result,
                all_solutions=every,
                robot=r.robot,
                length_unit=_unit(r.length_unit),
                angle_unit=enum_text(pb.AngleUnit, r.angle_unit, "rad"),
            )
            more = extras(r, {"robot", "length_unit", "angle_unit", "result"})
            result.extra.update(more)
            return result

        return GrpcCall("InverseKinematics", req, pb.InverseKinematicsResponse, parse)

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
    ) -> GrpcCall[IkBatch]:
        t = np.asarray(targets, dtype=np.float64)
        head = pb.InverseKinematicsBatchRequest(robot=robot)
        options = {**ik_choices(solver, solutions, max_solutions), **options}
        _ik_request(head, seed, angle_unit, position_only, tolerance, max_iterations, restarts, options)
        every = options.get("solutions") == "all"
        if t.ndim == 3 and t.shape[1:] == (4, 4):
            blob = nested_rows([2, 1, 1], t.reshape(-1, 16))
        elif t.ndim == 2 and t.shape[1] == 3:
            blob = position_targets(2, t)
        else:
            raise ValueError(f"IK targets are (N, 4, 4) matrices or (N, 3) positions, got shape {t.shape}")
        request = head.SerializeToString() + blob

        def parse(r: Any) -> IkBatch:
            results = [ik_result(x, all_solutions=every) for x in r.results]
            unit = enum_text(pb.AngleUnit, r.angle_unit, "rad")
            return ik_batch_arrays(r.robot, _unit(r.length_unit), unit, results)

        return GrpcCall("InverseKinematicsBatch", request, pb.InverseKinematicsBatchResponse, parse)

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
    ) -> GrpcCall[IkPath]:
        req = path_request(
            robot,
            {
                "start": joint_vector(start),
                "waypoints": waypoints_json(waypoints),
                "angle_unit": angle_unit,
                "position_only": position_only,
                "max_step_length": max_step_length,
                "max_step_angle": max_step_angle,
                "max_joint_step": max_joint_step,
                "tolerance": tolerance,
                "solver": solver,
                "max_iterations": max_iterations,
                "restarts": restarts,
            },
        )

        def parse(r: Any) -> IkPath:
            unit = enum_text(pb.AngleUnit, r.angle_unit, "rad")
            return ik_path(r, r.robot, _unit(r.length_unit), unit)

        return GrpcCall("InverseKinematicsPath", req, pb.InverseKinematicsPathResponse, parse)

    def link_transforms(
        self,
        robot: str,
        joints: ArrayLike,
        *,
        angle_unit: AngleUnit = "rad",
        check_limits: bool = True,
    ) -> GrpcCall[LinkTransforms]:
        req = pb.LinkTransformsRequest(
            robot=robot, joints=joint_vector(joints), options=_options(angle_unit, check_limits)
        )

        def parse(r: Any) -> LinkTransforms:
            items = r.link_transforms
            n = len(items)
            return LinkTransforms(
                robot=r.robot,
                length_unit=_unit(r.length_unit),
                matrices=_f([x.matrix.values for x in items]).reshape(n, 4, 4),
                inverses=_f([x.inverse.values for x in items]).reshape(n, 4, 4),
            )

        return GrpcCall("LinkTransforms", req, pb.LinkTransformsResponse, parse)


def path_request(robot: str, body: Mapping[str, Any]) -> Any:
    """A path request in the REST schema (``start``, ``waypoints`` as
    targets, the optional fields, ``None`` meaning absent) as an
    ``InverseKinematicsPathRequest``."""
    msg = pb.InverseKinematicsPathRequest(
        robot=robot,
        angle_unit=enum_value(pb.AngleUnit, body.get("angle_unit", "rad")),
        position_only=bool(body.get("position_only", False)),
    )
    msg.start.joints.extend(float(v) for v in body["start"])
    for w in body["waypoints"]:
        msg.waypoints.append(target_to_pb(w))
    for key in ("max_step_length", "max_step_angle", "max_joint_step", "tolerance", "max_iterations", "restarts"):
        if body.get(key) is not None:
            setattr(msg, key, body[key])
    if body.get("solver") is not None:
        set_options(msg, {"solver": body["solver"]})
    return msg


def _registered(r: Any) -> Registered:
    return Registered(robot_from_pb(r.robot), r.etag, r.created)


def _serialize_stream(request: Any) -> bytes:
    return bytes(request.SerializeToString())


_CODE_NAMES = {int(c.value[0]): c.name for c in __import__("grpc").StatusCode}


def stream_request(robot: str, request: Mapping[str, Any]) -> Any:
    """A stream request dict (the WebSocket schema) as a ``StreamForwardKinematicsRequest``."""
    out = pb.StreamForwardKinematicsRequest(id=int(request["id"]), robot=robot)
    path = request.get("ik_path")
    if path is not None:
        out.ik_path.CopyFrom(path_request(robot, path))
        return out
    ik = request.get("ik")
    if ik is not None:
        known = {"target", "seed", "angle_unit", "position_only", "tolerance", "max_iterations", "restarts"}
        msg = pb.InverseKinematicsRequest(robot=robot, target=target_to_pb(ik["target"]))
        _ik_request(
            msg,
            ik.get("seed"),
            ik.get("angle_unit", "rad"),
            bool(ik.get("position_only", False)),
            ik.get("tolerance"),
            ik.get("max_iterations"),
            ik.get("restarts"),
            {k: v for k, v in ik.items() if k not in known},
        )
        out.ik.CopyFrom(msg)
        return out
    rows = request.get("configurations")
    if rows is not None:
        q = np.asarray(rows, dtype=np.float64)
        out.packed_configurations.SetInParent()  # present even when empty
        out.packed_configurations.joint_count = q.shape[1] if q.ndim == 2 else 0
        out.packed_configurations.values.extend(q.ravel().tolist())
    else:
        out.joints.extend(request["joints"])
    out.options.CopyFrom(
        _options(
            request.get("angle_unit", "rad"),
            bool(request.get("check_limits", True)),
            bool(request.get("frames", False)),
            request.get("pose_format", "full"),
        )
    )
    if request.get("jacobian"):
        out.include_jacobian = True
        out.jacobian_frame = enum_value(pb.JacobianFrame, request.get("frame", "base"))
    if request.get("link_transforms"):
        out.include_link_transforms = True
    return out


def _many_poses(m: Any, pose_format: str) -> Array:
    """A many-configuration stream reply's poses: ``poses`` for ``full``, else ``packed_poses``."""
    if pose_format == "full":
        return _f([p.matrix for p in m.poses]).reshape(-1, 4, 4)
    shape = (-1, 3, 4) if pose_format == "matrix" else (-1, 3)
    return _f(m.packed_poses.values).reshape(shape)


def stream_reply(m: Any, requests: Mapping[int, Mapping[str, Any]]) -> Any:
    """A ``StreamForwardKinematicsResponse`` as a :class:`~kinserve_client.stream.StreamReply`."""
    from ._pbconv import error_from_status
    from .stream import StreamReply

    rid = int(m.id)
    if m.WhichOneof("result") == "error":
        e = m.error
        code = _CODE_NAMES.get(e.code, "UNKNOWN")
        return StreamReply(rid, error=error_from_status(code, e.message, e.SerializeToString()))
    request = requests.get(rid, {})
    if m.HasField("ik_path"):
        p = m.ik_path
        unit = enum_text(pb.AngleUnit, p.angle_unit, "rad")
        return StreamReply(rid, ik_path=ik_path(p, p.robot, _unit(p.length_unit), unit))
    if m.HasField("ik"):
        every = (request.get("ik") or {}).get("solutions") == "all"
        return StreamReply(rid, ik=ik_result(m.ik, all_solutions=every, length_unit=_unit(m.length_unit)))
    fmt = request.get("pose_format", "full")
    if "configurations" in request:
        return StreamReply(rid, poses=_many_poses(m, fmt))
    fk = fk_answer("", m.length_unit, m, fmt, bool(request.get("frames")))
    jac = jacobian_of("", m.length_unit, m.jacobian) if m.HasField("jacobian") else None
    lt = None
    if len(m.link_transforms):
        lt = _f([[x.matrix.values, x.inverse.values] for x in m.link_transforms]).reshape(-1, 2, 4, 4)
    return StreamReply(rid, fk=fk, jacobian=jac, link_transforms=lt)

"""Conversions between the REST JSON schema (the client's own vocabulary for
models and targets) and the generated protobuf messages, and the decoding
of gRPC errors.

Owns those conversions; depends on the generated ``_pb`` modules, the
result types and the errors, not on any transport.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
from google.protobuf import json_format
from google.protobuf.message import Message

from . import errors
from ._pb.kinematics.v1 import kinematics_pb2 as pb
from .types import JSON, Array, IkBranch, IkPath, IkResult, IkSolution, PathStop, Pose

ENUM_PREFIX = {
    "Convention": "CONVENTION_",
    "JointType": "JOINT_TYPE_",
    "AngleUnit": "ANGLE_UNIT_",
    "LengthUnit": "LENGTH_UNIT_",
    "RobotSource": "ROBOT_SOURCE_",
    "PoseFormat": "POSE_FORMAT_",
    "JacobianFrame": "JACOBIAN_FRAME_",
    "IkSolver": "IK_SOLVER_",
    "IkSolutions": "IK_SOLUTIONS_",
    "Singularity": "SINGULARITY_",
    "PathStopReason": "PATH_STOP_REASON_",
}


def enum_value(enum: Any, text: str | None) -> Any:
    """The enum number of a REST name (``"standard"`` -> ``CONVENTION_STANDARD``);
    unknown names give 0 (unspecified), which the server refuses naming the field."""
    if text is None:
        return 0
    prefix = ENUM_PREFIX[enum.DESCRIPTOR.name]
    try:
        return int(enum.Value(prefix + str(text).upper()))
    except ValueError:
        return 0


def enum_text(enum: Any, number: int, default: str) -> str:
    """The REST name of an enum number (``default`` for unspecified)."""
    if number == 0:
        return default
    return str(enum.Name(number))[len(ENUM_PREFIX[enum.DESCRIPTOR.name]) :].lower()


def _f(a: Any) -> Array:
    return np.asarray(a, dtype=np.float64)


def pose(p: Any) -> Pose:
    """A ``Pose`` message."""
    q, pos, rpy = p.quaternion, p.position, p.rpy
    return Pose(
        matrix=_f(p.matrix).reshape(4, 4),
        position=_f([pos.x, pos.y, pos.z]),
        quaternion=_f([q.w, q.x, q.y, q.z]),
        rpy=_f([rpy.roll, rpy.pitch, rpy.yaw]),
    )


def transform_to_pb(t: Mapping[str, Any]) -> Any:
    """A REST ``TransformSpec`` as a ``FixedTransform``."""
    out = pb.FixedTransform()
    if t.get("translation") is not None:
        x, y, z = t["translation"]
        out.translation.CopyFrom(pb.Vector3(x=x, y=y, z=z))
    if t.get("rpy") is not None:
        r, p_, y_ = t["rpy"]
        out.rpy.CopyFrom(pb.Rpy(roll=r, pitch=p_, yaw=y_))
    if t.get("quaternion") is not None:
        out.quaternion.CopyFrom(pb.Quaternion(**t["quaternion"]))
    if t.get("matrix") is not None:
        out.matrix.values.extend(float(v) for v in np.ravel(t["matrix"]))
    return out


def transform_from_pb(t: Any) -> dict[str, JSON]:
    """A ``FixedTransform`` as a REST ``TransformSpec``."""
    out: dict[str, JSON] = {}
    if t.HasField("translation"):
        out["translation"] = [t.translation.x, t.translation.y, t.translation.z]
    which = t.WhichOneof("rotation")
    if which == "rpy":
        out["rpy"] = [t.rpy.roll, t.rpy.pitch, t.rpy.yaw]
    elif which == "quaternion":
        q = t.quaternion
        out["quaternion"] = {"w": q.w, "x": q.x, "y": q.y, "z": q.z}
    elif which == "matrix":
        out["matrix"] = _f(t.matrix.values).reshape(4, 4).tolist()
    return out


def robot_to_pb(d: Mapping[str, Any]) -> Any:
    """A model in the robot-file schema as a ``Robot`` message."""
    r = pb.Robot(
        name=str(d.get("name", "")),
        convention=enum_value(pb.Convention, d.get("convention")),
        angle_unit=enum_value(pb.AngleUnit, d.get("angle_unit")),
        length_unit=enum_value(pb.LengthUnit, d.get("length_unit")),
    )
    for key in ("description", "source"):
        if d.get(key) is not None:
            setattr(r, key, d[key])
    for key in ("base", "tool"):
        if d.get(key) is not None:
            getattr(r, key).CopyFrom(transform_to_pb(d[key]))
    for link in d.get("links") or []:
        row = r.links.add(joint=enum_value(pb.JointType, link.get("joint")))
        for key in ("name", "a", "alpha", "d", "theta"):
            if link.get(key) is not None:
                setattr(row, key, link[key])
        if link.get("limits") is not None:
            lo, hi = link["limits"]
            row.limits.CopyFrom(pb.Limits(lo=lo, hi=hi))
    return r


def robot_from_pb(r: Any) -> dict[str, JSON]:
    """A ``Robot`` message in the robot-file schema (as REST gives it)."""
    out: dict[str, JSON] = {"name": r.name}
    for key in ("description", "source"):
        if r.HasField(key):
            out[key] = getattr(r, key)
    out["convention"] = enum_text(pb.Convention, r.convention, "standard")
    out["angle_unit"] = enum_text(pb.AngleUnit, r.angle_unit, "rad")
    out["length_unit"] = enum_text(pb.LengthUnit, r.length_unit, "m")
    for key in ("base", "tool"):
        if r.HasField(key):
            out[key] = transform_from_pb(getattr(r, key))
    links = []
    for row in r.links:
        link: dict[str, JSON] = {}
        if row.HasField("name"):
            link["name"] = row.name
        link["joint"] = enum_text(pb.JointType, row.joint, "")
        for key in ("a", "alpha", "d", "theta"):
            link[key] = getattr(row, key)
        if row.HasField("limits"):
            link["limits"] = [row.limits.lo, row.limits.hi]
        links.append(link)
    out["links"] = links
    return out


def target_to_pb(t: Mapping[str, Any]) -> Any:
    """A REST IK target (``_calls.target_json``) as an ``IkTarget``."""
    out = pb.IkTarget()
    if t.get("matrix") is not None:
        out.matrix.values.extend(float(v) for v in np.ravel(t["matrix"]))
    if t.get("position") is not None:
        x, y, z = t["position"]
        out.position.CopyFrom(pb.Vector3(x=x, y=y, z=z))
    if t.get("quaternion") is not None:
        out.quaternion.CopyFrom(pb.Quaternion(**t["quaternion"]))
    return out


def set_options(msg: Message, options: Mapping[str, JSON]) -> None:
    """Sets fields this client has no parameter for (``solutions``, ``solver``…)
    on an IK request, by their REST names: an enum takes its REST name
    (``"all"`` -> ``…_ALL``). A name the generated messages lack (the package
    was built from an older ``proto/``) is a ``ValueError``."""
    fields = msg.DESCRIPTOR.fields_by_name
    for key, value in options.items():
        f = fields.get(key)
        if f is None:
            raise ValueError(
                f"IK option {key!r} is not in {msg.DESCRIPTOR.full_name} of this build "
                "(rebuild kinserve-client from the current proto/, or use transport='rest')"
            )
        if f.enum_type is not None and isinstance(value, str):
            value = _enum_name(f.enum_type, value)
        elif f.enum_type is not None and isinstance(value, list):
            value = [_enum_name(f.enum_type, v) if isinstance(v, str) else v for v in value]
        json_format.ParseDict({f.json_name: value}, msg)


def _enum_name(enum: Any, value: str) -> str:
    """The proto name of a REST enum value (``"rz"`` -> ``POSE_AXIS_RZ``); an
    unknown one is passed on for the proto parser to refuse."""
    wanted = value.upper()
    names = [v.name for v in enum.values if v.name == wanted or v.name.endswith("_" + wanted)]
    return names[0] if names else value


_IK_KNOWN = {
    "joints", "converged", "position_error", "orientation_error", "iterations", "pose",
    "solver", "branch", "singular", "solutions", "truncated",
}


def extras(msg: Message, known: set[str]) -> dict[str, JSON]:
    """Fields of ``msg`` this client has no attribute for, as JSON by their
    proto names (enum values by their REST-style names)."""
    out: dict[str, JSON] = {}
    unknown = [f for f, _ in msg.ListFields() if f.name not in known]
    if not unknown:
        return out
    as_json = json_format.MessageToDict(msg, preserving_proto_field_name=True)
    for f in unknown:
        value = as_json.get(f.name)
        if f.enum_type is not None and isinstance(value, str):
            value = _strip_enum(value, f.enum_type)
        out[f.name] = value
    return out


def _strip_enum(name: str, enum_type: Any) -> str:
    values = [v.name for v in enum_type.values]
    common = values[0].rsplit("_", 1)[0] + "_" if values else ""
    return name[len(common) :].lower() if name.startswith(common) else name


def branch(m: Any, present: bool) -> IkBranch | None:
    """An ``IkBranch`` message (``None`` when absent)."""
    return IkBranch(m.shoulder, m.elbow, m.wrist) if present else None


def singularities(values: Any) -> tuple[Any, ...]:
    """Repeated ``Singularity`` as REST names (``shoulder``, ``wrist``)."""
    return tuple(enum_text(pb.Singularity, v, "") for v in values)


def ik_solution(m: Any) -> IkSolution:
    """An ``IkSolution``."""
    return IkSolution(
        joints=_f(m.joints),
        branch=branch(m.branch, m.HasField("branch")),
        singular=singularities(m.singular),
        distance=m.distance,
        position_error=m.position_error,
        orientation_error=m.orientation_error,
    )


def ik_result(r: Any, *, all_solutions: bool = False, **top: str | None) -> IkResult:
    """An ``InverseKinematicsResult``. ``solutions`` is repeated (absent and
    empty look the same): an answer to ``solutions="all"`` is told by its
    ``truncated`` (always set then) or ``all_solutions``, and then an empty
    list is "none fits", as REST's ``[]``."""
    joints = _f(r.joints)
    every = all_solutions or r.HasField("truncated") or len(r.solutions) > 0
    details = [ik_solution(x) for x in r.solutions] if every else None
    solutions = None
    if details is not None:
        solutions = np.asarray([d.joints for d in details], dtype=np.float64).reshape(len(details), joints.shape[0])
    solver = enum_text(pb.IkSolver, r.solver, "")
    return IkResult(
        joints=joints,
        converged=r.converged,
        position_error=r.position_error,
        orientation_error=r.orientation_error if r.HasField("orientation_error") else None,
        iterations=r.iterations,
        pose=pose(r.pose),
        robot=top.get("robot"),
        length_unit=top.get("length_unit"),
        angle_unit=top.get("angle_unit"),
        solver=solver if solver in ("analytic", "numeric") else None,  # type: ignore[arg-type]
        branch=branch(r.branch, r.HasField("branch")),
        singular=singularities(r.singular),
        solutions=solutions,
        solution_details=details,
        truncated=r.truncated if r.HasField("truncated") else None,
        extra=extras(r, _IK_KNOWN),
    )


def ik_path(r: Any, robot: str, length_unit: str, angle_unit: str) -> IkPath:
    """An ``InverseKinematicsPathResponse`` (unary or stream)."""
    points = [list(p.joints) for p in r.points]
    dof = len(points[0]) if points else 0
    stop = None
    if r.HasField("stop"):
        s = r.stop
        reason: Any = enum_text(pb.PathStopReason, s.reason, "")
        stop = PathStop(s.step, s.waypoint, reason, s.detail)
    return IkPath(
        robot=robot,
        length_unit=length_unit,
        angle_unit=angle_unit,
        points=_f(points).reshape(len(points), dof),
        fraction=r.fraction,
        waypoints_reached=r.waypoints_reached,
        stop=stop,
    )


IK_RESULT_TYPE = "type.googleapis.com/kinematics.v1.InverseKinematicsResult"


def error_from_status(code: str, message: str, status_bin: bytes | None) -> errors.KinserveError:
    """The exception for a gRPC error status (``grpc-status-details-bin``:
    ``google.rpc.Status`` with BadRequest / ErrorInfo / RetryInfo / the IK best
    attempt)."""
    from google.rpc import error_details_pb2, status_pb2

    fields: dict[str, str] = {}
    kind = errors.kind_of_code(code)
    best: IkResult | None = None
    retry_after: float | None = None
    if status_bin:
        status = status_pb2.Status.FromString(status_bin)
        message = status.message or message
        for any_ in status.details:
            if any_.Is(error_details_pb2.BadRequest.DESCRIPTOR):
                bad = error_details_pb2.BadRequest()
                any_.Unpack(bad)
                fields.update({v.field: v.description for v in bad.field_violations})
            elif any_.Is(error_details_pb2.ErrorInfo.DESCRIPTOR):
                info = error_details_pb2.ErrorInfo()
                any_.Unpack(info)
                if info.domain == "kinserve" and info.reason:
                    kind = info.reason.lower().replace("_", "-")
            elif any_.Is(error_details_pb2.RetryInfo.DESCRIPTOR):
                retry = error_details_pb2.RetryInfo()
                any_.Unpack(retry)
                retry_after = retry.retry_delay.ToTimedelta().total_seconds()
            elif any_.type_url == IK_RESULT_TYPE:
                best = ik_result(pb.InverseKinematicsResult.FromString(any_.value))
    err = errors.make_error(
        code=code,
        kind=kind,
        detail=message,
        status=None,
        fields=fields,
        best_attempt=best,
        transport="grpc",
    )
    err.retry_after = retry_after
    return err

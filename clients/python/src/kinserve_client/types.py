"""Result types of the client, the same whichever transport produced them.

Arrays are ``numpy.float64`` arrays; positions are in the robot's length
unit, joint values in the request's angle unit (rad or deg) for revolute
joints. Owns the result shapes; depends on numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, Union

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]
"""A float64 array."""

AngleUnit = Literal["rad", "deg"]
"""Unit of revolute joint values."""

PoseFormat = Literal["full", "matrix", "position"]
"""How FK poses come back: ``full`` (4×4 matrices), ``matrix`` (the top three
rows, 3×4) or ``position`` (x, y, z)."""

Frame = Literal["base", "tool"]
"""Frame of a Jacobian's rows."""

Transport = Literal["rest", "grpc"]
"""How a client talks to the server."""

IkSolver = Literal["auto", "analytic", "numeric"]
"""Which IK solver a request asks for: ``auto`` (the closed form where the arm
has one and the target an orientation, else numeric), ``analytic`` (the closed
form only), ``numeric`` (damped least squares)."""

IkSolverUsed = Literal["analytic", "numeric"]
"""The IK solver that produced an answer."""

IkSolutions = Literal["best", "all"]
"""One IK answer (``best``) or every closed-form solution in the limits (``all``)."""

Singularity = Literal["shoulder", "wrist"]
"""A singularity a closed-form solution stands at."""

PathStopReason = Literal["unreachable", "joint_limits", "joint_jump", "singularity", "time_limit"]
"""Why a Cartesian path stopped before its end."""

JSON = Any
"""A JSON value (dicts, lists, str, float, bool, None)."""

ArrayLike = Union[npt.ArrayLike, Array]


@dataclass(frozen=True)
class Pose:
    """A pose in the world frame.

    Attributes:
        matrix: (4, 4) homogeneous matrix.
        position: (3,) x, y, z in the robot's length unit.
        quaternion: (4,) unit quaternion ``w, x, y, z`` with ``w >= 0``.
        rpy: (3,) roll, pitch, yaw in rad, ``R = Rz(yaw) Ry(pitch) Rx(roll)``.
    """

    matrix: Array
    position: Array
    quaternion: Array
    rpy: Array


@dataclass(frozen=True)
class RobotSummary:
    """A line of the robot list.

    Attributes:
        ik_class: the closed-form IK class (``spherical_wrist_parallel_23``, …)
            when ``solver="analytic"`` and ``solutions="all"`` work; ``None``
            when only the numeric solver applies.
    """

    name: str
    dof: int
    convention: str
    length_unit: str
    source: str
    ik_class: str | None = None


@dataclass(frozen=True)
class RobotPage:
    """One page of the robot list and the token of the next (``None`` on the last)."""

    robots: list[RobotSummary]
    next_page_token: str | None


@dataclass(frozen=True)
class RobotInfo:
    """A robot as registered (the robot-file JSON schema) and its ETag
    (``"17"``, quotes included; pass it as ``etag=`` to replace or delete
    only this version)."""

    robot: dict[str, JSON]
    etag: str

    @property
    def name(self) -> str:
        """The robot's name."""
        return str(self.robot["name"])


@dataclass(frozen=True)
class Registered:
    """The answer to a registration: the model as stored, its new ETag, and
    whether it was created (``False``: replaced)."""

    robot: dict[str, JSON]
    etag: str
    created: bool


@dataclass(frozen=True)
class FkResult:
    """Forward kinematics of one configuration.

    Attributes:
        transform: the tool pose in the request's ``pose_format``: (4, 4) for
            ``full``, (3, 4) for ``matrix``, (3,) for ``position``.
        pose: the full pose (with quaternion and rpy), ``full`` only.
        frames: with ``frames=True``, the base frame then the frame after each
            DH row: (F, 4, 4), (F, 3, 4) or (F, 3) by ``pose_format``.
    """

    robot: str
    length_unit: str
    pose_format: PoseFormat
    transform: Array
    pose: Pose | None = None
    frames: Array | None = None


@dataclass(frozen=True)
class Jacobian:
    """The geometric Jacobian of one configuration.

    Attributes:
        jacobian: (6, dof): rows vx, vy, vz, wx, wy, wz; columns per rad
            (revolute) or per length unit (prismatic).
        manipulability: Yoshikawa's measure (see the server's docs).
        condition_number: largest over smallest singular value; ``None`` when
            the smallest is exactly 0.
        singular: the smallest singular value is below 1e-6.
        pose: the tool pose at these joint values (``None`` in a stream reply
            of a compact ``pose_format``, whose pose is the FK part).
    """

    robot: str
    length_unit: str
    frame: str
    jacobian: Array
    manipulability: float
    condition_number: float | None
    singular: bool
    pose: Pose | None


@dataclass(frozen=True)
class JacobianBatch:
    """Jacobians of N configurations, as arrays.

    Attributes:
        jacobians: (N, 6, dof).
        manipulability: (N,).
        condition_number: (N,), ``nan`` where the server gave ``null``.
        singular: (N,) bool.
        poses: (N, 4, 4) tool poses.
    """

    robot: str
    length_unit: str
    frame: str
    jacobians: Array
    manipulability: Array
    condition_number: Array
    singular: npt.NDArray[np.bool_]
    poses: Array


@dataclass(frozen=True)
class IkBranch:
    """Which root of each subproblem a closed-form solution took (0 or 1):
    ``shoulder`` joint 1 (lefty / righty), ``elbow`` joint 3, ``wrist`` joints 4–5."""

    shoulder: int
    elbow: int
    wrist: int


@dataclass(frozen=True)
class IkSolution:
    """One solution of ``solutions="all"``.

    Attributes:
        joints: (dof,) in the request's angle unit, within the joint limits.
        branch: its closed-form branch.
        singular: singularities it stands at (empty almost always).
        distance: limits-aware distance to the seed (or the middle of the limits), rad.
        position_error: length unit.
        orientation_error: rad.
    """

    joints: Array
    branch: IkBranch | None
    singular: tuple[Singularity, ...]
    distance: float
    position_error: float
    orientation_error: float


@dataclass(frozen=True)
class IkResult:
    """One inverse-kinematics answer.

    Attributes:
        joints: (dof,) in the request's angle unit (prismatic: length unit),
            within the joint limits.
        converged: both errors are within the tolerance.
        position_error: distance from the target position, length unit.
        orientation_error: angle from the target orientation, rad (``None``
            when the target had none).
        iterations: solver iterations over all attempts (0 from the closed form).
        pose: the tool pose at ``joints``.
        solver: the solver that produced ``joints`` (``analytic`` or ``numeric``).
        branch: the closed-form branch of ``joints`` (``None`` from the numeric solver).
        singular: singularities ``joints`` stands at (closed form only).
        solutions: with ``solutions="all"``: (K, dof) joints of every solution
            in the limits, nearest the seed first (``joints`` is the first);
            ``None`` otherwise.
        solution_details: with ``solutions="all"``: each solution's branch,
            singularities, distance and errors, in the order of ``solutions``.
        truncated: with ``solutions="all"``: more solutions fit the limits than
            ``max_solutions``; ``None`` otherwise.
        extra: answer fields this client version has no attribute for (for
            example fields added by newer servers), as JSON.
    """

    joints: Array
    converged: bool
    position_error: float
    orientation_error: float | None
    iterations: int
    pose: Pose
    robot: str | None = None
    length_unit: str | None = None
    angle_unit: str | None = None
    solver: IkSolverUsed | None = None
    branch: IkBranch | None = None
    singular: tuple[Singularity, ...] = ()
    solutions: Array | None = None
    solution_details: list[IkSolution] | None = None
    truncated: bool | None = None
    extra: dict[str, JSON] = field(default_factory=dict)


@dataclass(frozen=True)
class IkBatch:
    """Answers to N IK targets, as arrays (and per answer in ``results``).

    Attributes:
        joints: (N, dof).
        converged: (N,) bool.
        position_error: (N,).
        orientation_error: (N,), ``nan`` where the target had no orientation.
        iterations: (N,) int.
        poses: (N, 4, 4).
        solver: (N,) the solver of each answer.
        singular: (N,) bool: the answer stands at a singularity.
        solutions: with ``solutions="all"``: per target a (K_i, dof) array
            (K_i may differ, and be 0); ``None`` otherwise.
        truncated: with ``solutions="all"``: (N,) bool; ``None`` otherwise.
        results: each answer as an :class:`IkResult` (branches, details).
    """

    robot: str
    length_unit: str
    angle_unit: str
    joints: Array
    converged: npt.NDArray[np.bool_]
    position_error: Array
    orientation_error: Array
    iterations: npt.NDArray[np.int64]
    poses: Array
    results: list[IkResult]
    solver: list[IkSolverUsed | None] = field(default_factory=list)
    singular: npt.NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=np.bool_))
    solutions: list[Array] | None = None
    truncated: npt.NDArray[np.bool_] | None = None


@dataclass(frozen=True)
class PathStop:
    """Where and why a Cartesian path stopped.

    Attributes:
        step: the 1-based step that was not taken (step 0 is the start).
        waypoint: the 0-based waypoint that step heads for.
        reason: why.
        detail: what happened, in words.
    """

    step: int
    waypoint: int
    reason: PathStopReason
    detail: str


@dataclass(frozen=True)
class IkPath:
    """A Cartesian path (:meth:`Client.ik_path`).

    Attributes:
        points: (M, dof) joints of every step, the start first, in the
            request's angle unit.
        fraction: steps taken / steps planned (1.0 when complete).
        waypoints_reached: waypoints fully reached.
        stop: ``None`` when complete; else where and why it stopped (still an
            answer, not an error).
    """

    robot: str
    length_unit: str
    angle_unit: str
    points: Array
    fraction: float
    waypoints_reached: int
    stop: PathStop | None

    @property
    def complete(self) -> bool:
        """The path reached its last waypoint."""
        return self.stop is None


@dataclass(frozen=True)
class LinkTransforms:
    """Each DH row's link matrix ``ⁱ⁻¹Aᵢ`` and its inverse, (n, 4, 4) each;
    ``base · A₁ ⋯ Aₙ · tool`` is the tool pose."""

    robot: str
    length_unit: str
    matrices: Array
    inverses: Array


@dataclass(frozen=True)
class SymbolicMatrix:
    """A symbolic 4×4 matrix: ``text`` (4 rows of 4 expression strings),
    LaTeX and MathML."""

    text: list[list[str]]
    latex: str
    mathml: str


@dataclass(frozen=True)
class ClosedForm:
    """The closed-form FK of a robot's DH table (see the server's docs for
    the expression grammar)."""

    robot: str
    convention: str
    length_unit: str
    variables: list[dict[str, JSON]]
    symbols: dict[str, float]
    link_transforms: list[SymbolicMatrix]
    transform: SymbolicMatrix
    base: Array
    tool: Array | None

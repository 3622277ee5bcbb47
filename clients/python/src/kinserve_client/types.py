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
    """A line of the robot list."""

    name: str
    dof: int
    convention: str
    length_unit: str
    source: str


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
class IkResult:
    """One inverse-kinematics answer.

    Attributes:
        joints: (dof,) in the request's angle unit (prismatic: length unit),
            within the joint limits.
        converged: both errors are within the tolerance.
        position_error: distance from the target position, length unit.
        orientation_error: angle from the target orientation, rad (``None``
            when the target had none).
        iterations: solver iterations over all attempts.
        pose: the tool pose at ``joints``.
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

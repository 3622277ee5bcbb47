"""What one operation sends and how its answer is read, independent of
whether it runs blocking or on asyncio: a :class:`RestCall` or a
:class:`GrpcCall`. The clients (``client.py``) only execute calls.

Owns the call descriptions and the shared argument handling (joint arrays,
IK targets, model files); depends on the result types.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Generic, Mapping, Sequence, TypeVar, Union, cast

import httpx
import numpy as np

from .types import Array, ArrayLike, JSON

R = TypeVar("R")


@dataclass
class RestCall(Generic[R]):
    """An HTTP request and the parser of its success answer."""

    method: str
    path: str
    parse: Callable[[httpx.Response], R]
    json: JSON = None
    content: bytes | None = None
    params: dict[str, str] | None = None
    headers: dict[str, str] = field(default_factory=dict)


@dataclass
class GrpcCall(Generic[R]):
    """A unary gRPC call (method name of ``kinematics.v1.KinematicsService``)
    and the parser of its response message."""

    method: str
    request: Any
    response_type: Any
    parse: Callable[[Any], R]


Call = Union[RestCall[R], GrpcCall[R]]


def configurations(q: ArrayLike) -> Array:
    """``q`` as a float64 (N, dof) array (a single (dof,) vector is one row)."""
    a = np.asarray(q, dtype=np.float64)
    if a.ndim == 1:
        a = a[np.newaxis, :]
    if a.ndim != 2:
        raise ValueError(f"expected an (N, dof) array of joint values, got shape {a.shape}")
    return a


def joint_vector(q: ArrayLike) -> list[float]:
    """``q`` as a list of floats (one configuration)."""
    a = np.asarray(q, dtype=np.float64)
    if a.ndim != 1:
        raise ValueError(f"expected a (dof,) vector of joint values, got shape {a.shape}")
    return [float(v) for v in a]


def target_json(target: ArrayLike | Mapping[str, Any]) -> dict[str, JSON]:
    """An IK target in the REST schema: a (4, 4) matrix, a (3,) position
    (with ``position_only``), or a mapping already in the schema
    (``{"position": [...], "quaternion": {"w":…}}``)."""
    if isinstance(target, Mapping):
        out: dict[str, JSON] = {}
        for key, value in target.items():
            out[key] = value if key == "quaternion" else np.asarray(value, np.float64).tolist()
        return out
    a = np.asarray(target, dtype=np.float64)
    if a.shape == (4, 4):
        return {"matrix": a.tolist()}
    if a.shape == (3,):
        return {"position": a.tolist()}
    raise ValueError(f"an IK target is a (4, 4) matrix or a (3,) position, got shape {a.shape}")


def targets_json(targets: ArrayLike) -> list[dict[str, JSON]]:
    """N IK targets: an (N, 4, 4) array of matrices or (N, 3) of positions."""
    a = np.asarray(targets, dtype=np.float64)
    if a.ndim == 3 and a.shape[1:] == (4, 4):
        return [{"matrix": m} for m in a.tolist()]
    if a.ndim == 2 and a.shape[1] == 3:
        return [{"position": p} for p in a.tolist()]
    raise ValueError(f"IK targets are (N, 4, 4) matrices or (N, 3) positions, got shape {a.shape}")


def waypoints_json(waypoints: ArrayLike | Sequence[ArrayLike | Mapping[str, Any]]) -> list[dict[str, JSON]]:
    """Path waypoints: an (N, 4, 4) array of matrices, (N, 3) of positions
    (with ``position_only``), or a sequence of single targets (each as
    :func:`target_json` takes it)."""
    if isinstance(waypoints, Sequence) and not isinstance(waypoints, str):
        if any(isinstance(w, Mapping) for w in waypoints):
            return [target_json(w) for w in waypoints]
    return targets_json(cast(ArrayLike, waypoints))


def ik_choices(
    solver: str | None, solutions: str | None, max_solutions: int | None
) -> dict[str, JSON]:
    """The IK solver fields that were given, by their REST names."""
    out: dict[str, JSON] = {}
    for key, value in [("solver", solver), ("solutions", solutions), ("max_solutions", max_solutions)]:
        if value is not None:
            out[key] = value
    return out


def load_model(model: Mapping[str, Any] | str | os.PathLike[str]) -> dict[str, JSON]:
    """A robot model: a mapping in the robot-file schema, or the path of a robot file (JSON)."""
    if isinstance(model, Mapping):
        return dict(model)
    value = json.loads(Path(model).read_text(encoding="utf-8"))
    if not isinstance(value, dict):
        raise ValueError(f"{model}: a robot file holds a JSON object")
    return value


def load_urdf(urdf: str | os.PathLike[str]) -> str:
    """URDF text: a path (``os.PathLike``, or a ``str`` without ``<``) is read."""
    if isinstance(urdf, str) and "<" in urdf:
        return urdf
    return Path(urdf).read_text(encoding="utf-8")


def pad_rows(top: Array) -> Array:
    """(…, 3, 4) top rows of homogeneous matrices -> (…, 4, 4)."""
    shape = top.shape[:-2] + (4, 4)
    out = np.zeros(shape, dtype=np.float64)
    out[..., :3, :] = top
    out[..., 3, 3] = 1.0
    return out

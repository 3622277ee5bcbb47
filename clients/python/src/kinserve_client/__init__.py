"""kinserve-client: a Python client of kinserve.

:class:`Client` (blocking) and :class:`AsyncClient` (asyncio) speak REST
(httpx) or gRPC (grpcio), chosen by ``transport=``, with the same methods and
results; arrays are numpy. Errors are :class:`KinserveError` (with a
subclass per status code) carrying the problem type, status, detail and the
field paths at fault, the same from both transports.

``GENERATED_FROM`` says which API the package was built from: the OpenAPI
document's version and the hashes of ``proto/`` and of the OpenAPI snapshot.
"""

from __future__ import annotations

from ._pb._source import GENERATED_FROM
from ._version import __version__
from .client import AsyncClient, Client
from .errors import (
    AlreadyExists,
    DeadlineExceeded,
    FailedPrecondition,
    IkNotConverged,
    Internal,
    InvalidArgument,
    KinserveError,
    NotFound,
    PermissionDenied,
    ResourceExhausted,
    Unauthenticated,
    Unavailable,
    Unimplemented,
)
from .stream import Stream, StreamReply
from .types import (
    ClosedForm,
    FkResult,
    IkBatch,
    IkBranch,
    IkPath,
    IkResult,
    IkSolution,
    IkSolutions,
    IkSolver,
    IkSolverUsed,
    Jacobian,
    JacobianBatch,
    LinkTransforms,
    PathStop,
    PathStopReason,
    Pose,
    Registered,
    RobotInfo,
    RobotPage,
    RobotSummary,
    Singularity,
    SymbolicMatrix,
)

API_VERSION: str = GENERATED_FROM["api_version"]
"""The API version (the OpenAPI document's ``info.version``) this package was built from."""

__all__ = [
    "API_VERSION",
    "GENERATED_FROM",
    "AlreadyExists",
    "AsyncClient",
    "Client",
    "ClosedForm",
    "DeadlineExceeded",
    "FailedPrecondition",
    "FkResult",
    "IkBatch",
    "IkBranch",
    "IkNotConverged",
    "IkPath",
    "IkResult",
    "IkSolution",
    "IkSolutions",
    "IkSolver",
    "IkSolverUsed",
    "Internal",
    "InvalidArgument",
    "Jacobian",
    "JacobianBatch",
    "KinserveError",
    "LinkTransforms",
    "NotFound",
    "PathStop",
    "PathStopReason",
    "PermissionDenied",
    "Pose",
    "Registered",
    "ResourceExhausted",
    "RobotInfo",
    "RobotPage",
    "RobotSummary",
    "Stream",
    "StreamReply",
    "Singularity",
    "SymbolicMatrix",
    "Unauthenticated",
    "Unavailable",
    "Unimplemented",
    "__version__",
]

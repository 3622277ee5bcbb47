"""Errors: one exception type, :class:`KinserveError`, with a subclass per
gRPC status code, raised the same way from REST (``application/problem+json``)
and gRPC (the status with ``google.rpc.BadRequest`` / ``ErrorInfo`` details
in ``grpc-status-details-bin``).

Owns decoding errors; depends on nothing else of the package but the result
types (an unreached IK target carries its best attempt).
"""

from __future__ import annotations

from typing import Any, Mapping

# Problem kind (REST's `urn:kinserve:problem:<kind>`) -> (gRPC code, HTTP status),
# the server's two exhaustive mappings (src/api/rest/problem.rs, src/api/grpc/status.rs).
KINDS: dict[str, tuple[str, int]] = {
    "malformed-request": ("INVALID_ARGUMENT", 400),
    "invalid-input": ("INVALID_ARGUMENT", 422),
    "unsupported-media-type": ("INVALID_ARGUMENT", 415),
    "not-found": ("NOT_FOUND", 404),
    "no-route": ("UNIMPLEMENTED", 404),
    "already-exists": ("ALREADY_EXISTS", 409),
    "read-only": ("FAILED_PRECONDITION", 409),
    "precondition-failed": ("FAILED_PRECONDITION", 412),
    "ik-not-converged": ("FAILED_PRECONDITION", 422),
    "unauthenticated": ("UNAUTHENTICATED", 401),
    "forbidden": ("PERMISSION_DENIED", 403),
    "registry-full": ("RESOURCE_EXHAUSTED", 507),
    "too-large": ("RESOURCE_EXHAUSTED", 413),
    "overloaded": ("RESOURCE_EXHAUSTED", 503),
    "unavailable": ("UNAVAILABLE", 503),
    "storage": ("UNAVAILABLE", 507),
    "store-unavailable": ("UNAVAILABLE", 503),
    "request-timeout": ("DEADLINE_EXCEEDED", 408),
    "not-implemented": ("UNIMPLEMENTED", 501),
    "internal": ("INTERNAL", 500),
}

PROBLEM_PREFIX = "urn:kinserve:problem:"


class KinserveError(Exception):
    """An error answer of the server, from either transport.

    Attributes:
        code: the gRPC status code name (``"INVALID_ARGUMENT"``, ``"NOT_FOUND"``, …);
            over REST derived from the problem type by the server's own mapping.
        fields: field path -> message (``{"joints[1]": "outside the limits …"}``),
            from the problem's ``errors`` or gRPC's ``google.rpc.BadRequest``.
        detail: the explanation (the problem's ``detail``, the gRPC message).
        type: the problem type URI (``urn:kinserve:problem:invalid-input``), the
            same on both transports: over gRPC from the ``google.rpc.ErrorInfo``
            every error status carries (domain ``kinserve``, reason
            ``INVALID_INPUT``); ``None`` only for a status without it (a
            transport failure, or an older server whose code has several kinds).
        status: the HTTP status (REST's; over gRPC the one REST gives that kind).
        best_attempt: with ``ik-not-converged``, the best attempt as an
            :class:`~kinserve_client.types.IkResult`.
        retry_after: seconds the server asked to wait before trying again
            (REST's ``Retry-After``, gRPC's ``google.rpc.RetryInfo``); ``None``
            when it did not say.
    """

    def __init__(
        self,
        *,
        code: str,
        detail: str,
        type: str | None = None,
        status: int | None = None,
        title: str | None = None,
        fields: Mapping[str, str] | None = None,
        best_attempt: Any = None,
        transport: str = "rest",
        retry_after: float | None = None,
    ) -> None:
        super().__init__(detail)
        self.code = code
        self.detail = detail
        self.type = type
        self.status = status
        self.title = title
        self.fields: dict[str, str] = dict(fields or {})
        self.best_attempt = best_attempt
        self.transport = transport
        self.retry_after = retry_after

    @property
    def refused(self) -> bool:
        """Whether the server refused the request before doing anything
        (``overloaded``: a budget spent, or the client holding its share of
        it), so that sending it again is safe whatever it asks."""
        return self.kind == "overloaded"

    @property
    def kind(self) -> str | None:
        """The problem kind (``invalid-input``), the end of :attr:`type`."""
        if self.type is None or not self.type.startswith(PROBLEM_PREFIX):
            return None
        return self.type[len(PROBLEM_PREFIX) :]

    def __repr__(self) -> str:
        return (
            f"{type(self).__name__}(code={self.code!r}, type={self.type!r}, "
            f"status={self.status!r}, detail={self.detail!r}, fields={self.fields!r})"
        )


class InvalidArgument(KinserveError):
    """400 / 415 / 422 ``INVALID_ARGUMENT``: the request is at fault (see ``fields``)."""


class NotFound(KinserveError):
    """404 ``NOT_FOUND``: no robot of that name."""


class AlreadyExists(KinserveError):
    """409 ``ALREADY_EXISTS``: a robot of that name is registered."""


class FailedPrecondition(KinserveError):
    """409 / 412 ``FAILED_PRECONDITION``: read-only robot or ETag mismatch."""


class IkNotConverged(FailedPrecondition):
    """422 ``ik-not-converged``: the target was not reached; ``best_attempt`` holds the best try."""


class Unauthenticated(KinserveError):
    """401 ``UNAUTHENTICATED``: a token is needed (``Client(token=...)``)."""


class PermissionDenied(KinserveError):
    """403 ``PERMISSION_DENIED``."""


class ResourceExhausted(KinserveError):
    """413 / 503 / 507 ``RESOURCE_EXHAUSTED``: too large, overloaded or full."""


class Unavailable(KinserveError):
    """503 ``UNAVAILABLE``: the server or its store is unavailable; retry later."""


class DeadlineExceeded(KinserveError):
    """408 ``DEADLINE_EXCEEDED``: the request ran out of time."""


class Unimplemented(KinserveError):
    """404 (no route) / 501 ``UNIMPLEMENTED``."""


class Internal(KinserveError):
    """500 ``INTERNAL``."""


_BY_CODE: dict[str, type[KinserveError]] = {
    "INVALID_ARGUMENT": InvalidArgument,
    "NOT_FOUND": NotFound,
    "ALREADY_EXISTS": AlreadyExists,
    "FAILED_PRECONDITION": FailedPrecondition,
    "UNAUTHENTICATED": Unauthenticated,
    "PERMISSION_DENIED": PermissionDenied,
    "RESOURCE_EXHAUSTED": ResourceExhausted,
    "UNAVAILABLE": Unavailable,
    "DEADLINE_EXCEEDED": DeadlineExceeded,
    "UNIMPLEMENTED": Unimplemented,
    "INTERNAL": Internal,
}


def error_class(code: str, kind: str | None) -> type[KinserveError]:
    """The exception class for a code (and kind: ``ik-not-converged`` has its own)."""
    if kind == "ik-not-converged":
        return IkNotConverged
    return _BY_CODE.get(code, KinserveError)


def kind_of_code(code: str) -> str | None:
    """The problem kind of a gRPC code when only one kind maps to it."""
    kinds = [k for k, (c, _) in KINDS.items() if c == code]
    return kinds[0] if len(kinds) == 1 else None


def make_error(
    *,
    code: str,
    kind: str | None,
    detail: str,
    status: int | None,
    title: str | None = None,
    fields: Mapping[str, str] | None = None,
    best_attempt: Any = None,
    transport: str,
) -> KinserveError:
    """The exception for one error answer."""
    if status is None and kind in KINDS:
        status = KINDS[kind][1]
    cls = error_class(code, kind)
    return cls(
        code=code,
        detail=detail,
        type=None if kind is None else PROBLEM_PREFIX + kind,
        status=status,
        title=title,
        fields=fields,
        best_attempt=best_attempt,
        transport=transport,
    )

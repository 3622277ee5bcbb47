"""The two clients, :class:`Client` (blocking) and :class:`AsyncClient`
(asyncio), with the same methods over REST (httpx) or gRPC (grpcio), chosen
by ``transport=``.

Every operation is described once as a call (``_rest.RestOps`` /
``_grpc.GrpcOps``); the clients only execute calls and turn error answers
into :class:`~kinserve_client.errors.KinserveError`. Owns connections and
execution; depends on every other module of the package.
"""

from __future__ import annotations

import asyncio
import functools
import os
import time
from typing import (
    Any,
    AsyncIterator,
    Callable,
    Concatenate,
    Coroutine,
    Iterator,
    Mapping,
    ParamSpec,
    TypeVar,
    cast,
)

import grpc
import grpc.aio
import httpx

from ._calls import Call, GrpcCall, RestCall
from ._grpc import GrpcOps, method_path
from ._pbconv import error_from_status
from ._rest import RestOps, raise_for
from .errors import KinserveError
from .stream import Stream, open_stream
from .types import JSON, AngleUnit, PoseFormat, Registered, RobotSummary, Transport

P = ParamSpec("P")
R = TypeVar("R")

GRPC_OPTIONS = [
    ("grpc.max_receive_message_length", 256 << 20),
    ("grpc.max_send_message_length", 256 << 20),
]


def _grpc_target(address: str) -> str:
    for scheme in ("http://", "grpc://"):
        if address.startswith(scheme):
            return address[len(scheme) :].rstrip("/")
    return address


def _status_bin(e: grpc.RpcError) -> bytes | None:
    trailing: Any = e.trailing_metadata() if hasattr(e, "trailing_metadata") else None
    for key, value in trailing or ():
        if key == "grpc-status-details-bin":
            return value if isinstance(value, bytes) else value.encode()
    return None


def grpc_error(e: grpc.RpcError) -> Exception:
    """The :class:`KinserveError` of a failed call (transport failures too:
    ``UNAVAILABLE`` when the server cannot be reached)."""
    code = e.code() if hasattr(e, "code") else grpc.StatusCode.UNKNOWN
    details = e.details() if hasattr(e, "details") else str(e)
    return error_from_status(code.name, details or "", _status_bin(e))


#: How long to wait before sending a refused request again when the server
#: did not say (it does: REST's Retry-After, gRPC's google.rpc.RetryInfo).
DEFAULT_RETRY_AFTER = 1.0
#: The longest wait between attempts, whatever the server asks.
MAX_RETRY_AFTER = 5.0


def _retry_delay(e: KinserveError, attempt: int, retries: int) -> float | None:
    """Seconds to wait before attempt ``attempt + 1``, or ``None`` to raise ``e``."""
    if not e.refused or attempt >= retries:
        return None
    wait = DEFAULT_RETRY_AFTER if e.retry_after is None else e.retry_after
    return min(max(wait, 0.0), MAX_RETRY_AFTER)


def _serialize(request: Any) -> bytes:
    return request if isinstance(request, bytes) else bytes(request.SerializeToString())


def _op_sync(op: Callable[Concatenate[RestOps, P], RestCall[R]]) -> Callable[Concatenate[Client, P], R]:
    name = op.__name__

    @functools.wraps(op)
    def method(self: Client, *args: P.args, **kwargs: P.kwargs) -> R:
        result: R = self._run(getattr(self._ops, name)(*args, **kwargs))
        return result

    return cast("Callable[Concatenate[Client, P], R]", method)


def _op_async(
    op: Callable[Concatenate[RestOps, P], RestCall[R]],
) -> Callable[Concatenate[AsyncClient, P], Coroutine[Any, Any, R]]:
    name = op.__name__

    @functools.wraps(op)
    async def method(self: AsyncClient, *args: P.args, **kwargs: P.kwargs) -> R:
        result: R = await self._run(getattr(self._ops, name)(*args, **kwargs))
        return result

    return cast("Callable[Concatenate[AsyncClient, P], Coroutine[Any, Any, R]]", method)


class _Base:
    def __init__(
        self,
        address: str,
        transport: Transport,
        token: str | None,
        timeout: float,
        retries: int,
    ) -> None:
        if transport not in ("rest", "grpc"):
            raise ValueError(f"transport is 'rest' or 'grpc', got {transport!r}")
        if retries < 0:
            raise ValueError(f"retries is 0 or more, got {retries}")
        self.address = address.rstrip("/")
        self.transport: Transport = transport
        self.timeout = timeout
        self.retries = retries
        self._token = token
        self._ops: Any = RestOps() if transport == "rest" else GrpcOps()
        self._headers = {} if token is None else {"Authorization": f"Bearer {token}"}
        self._metadata: tuple[tuple[str, str | bytes], ...] = (
            () if token is None else (("authorization", f"Bearer {token}"),)
        )


class Client(_Base):
    """A blocking kinserve client.

    ``Client("http://127.0.0.1:8080")`` speaks REST; ``Client("127.0.0.1:50051",
    transport="grpc")`` speaks gRPC; the methods and their answers are the
    same. ``token`` is the server's API token (needed to register and delete
    when the server has one). A request the server refused before doing
    anything (``overloaded``: it is busy, or this client holds its share of
    it) is sent again up to ``retries`` times, after the ``Retry-After`` the
    server asked for (``Retry-After``, gRPC's ``RetryInfo``; at most 5 s); past that the
    :class:`~kinserve_client.errors.ResourceExhausted` is raised. Use it as a
    context manager or call :meth:`close`.

    >>> with Client(BASE) as c:  # doctest: +SKIP
    ...     c.fk("planar_2dof", [0.5, 0.1]).transform[:3, 3]
    """

    def __init__(
        self,
        address: str = "http://127.0.0.1:8080",
        *,
        transport: Transport = "rest",
        token: str | None = None,
        timeout: float = 30.0,
        retries: int = 3,
    ) -> None:
        super().__init__(address, transport, token, timeout, retries)
        self._http: httpx.Client | None = None
        self._channel: grpc.Channel | None = None
        if transport == "rest":
            self._http = httpx.Client(base_url=self.address, headers=self._headers, timeout=timeout)
        else:
            self._channel = grpc.insecure_channel(_grpc_target(self.address), options=GRPC_OPTIONS)

    def close(self) -> None:
        """Closes the connection pool or channel."""
        if self._http is not None:
            self._http.close()
        if self._channel is not None:
            self._channel.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _run(self, call: Call[R]) -> R:
        attempt = 0
        while True:
            try:
                return self._run_once(call)
            except KinserveError as e:
                wait = _retry_delay(e, attempt, self.retries)
                if wait is None:
                    raise
            time.sleep(wait)
            attempt += 1

    def _run_once(self, call: Call[R]) -> R:
        if isinstance(call, RestCall):
            assert self._http is not None
            r = self._http.request(
                call.method,
                call.path,
                json=call.json,
                content=call.content,
                params=call.params,
                headers=call.headers,
            )
            raise_for(r)
            return call.parse(r)
        assert self._channel is not None
        fn = self._channel.unary_unary(
            method_path(call.method),
            request_serializer=_serialize,
            response_deserializer=call.response_type.FromString,
        )
        try:
            response = fn(call.request, metadata=self._metadata, timeout=self.timeout)
        except grpc.RpcError as e:
            raise grpc_error(e) from None
        return call.parse(response)

    def robots(self, page_size: int | None = None) -> Iterator[RobotSummary]:
        """Every robot, sorted by name, fetched a page (``page_size``, server
        default 100) at a time as the iterator advances."""
        token: str | None = None
        while True:
            page = self.list_robots_page(page_size, token)
            yield from page.robots
            token = page.next_page_token
            if not token:
                return

    def replace(
        self, model: Mapping[str, Any] | str | os.PathLike[str], *, etag: str | None = None
    ) -> Registered:
        """Registers or replaces a robot (``register(model, replace=True, etag=etag)``)."""
        return self.register(model, replace=True, etag=etag)

    list_robots_page = _op_sync(RestOps.list_robots_page)
    get_robot = _op_sync(RestOps.get_robot)
    register = _op_sync(RestOps.register)
    import_urdf = _op_sync(RestOps.import_urdf)
    delete = _op_sync(RestOps.delete)
    urdf = _op_sync(RestOps.urdf)
    closed_form = _op_sync(RestOps.closed_form)
    fk = _op_sync(RestOps.fk)
    fk_batch = _op_sync(RestOps.fk_batch)
    jacobian = _op_sync(RestOps.jacobian)
    jacobian_batch = _op_sync(RestOps.jacobian_batch)
    ik = _op_sync(RestOps.ik)
    ik_batch = _op_sync(RestOps.ik_batch)
    ik_path = _op_sync(RestOps.ik_path)
    link_transforms = _op_sync(RestOps.link_transforms)


class AsyncClient(_Base):
    """The asyncio twin of :class:`Client`: the same constructor and methods,
    each a coroutine, plus :meth:`stream`.

    >>> async with AsyncClient(BASE) as c:  # doctest: +SKIP
    ...     (await c.fk("planar_2dof", [0.5, 0.1])).transform
    """

    def __init__(
        self,
        address: str = "http://127.0.0.1:8080",
        *,
        transport: Transport = "rest",
        token: str | None = None,
        timeout: float = 30.0,
        retries: int = 3,
    ) -> None:
        super().__init__(address, transport, token, timeout, retries)
        self._http: httpx.AsyncClient | None = None
        self._channel: grpc.aio.Channel | None = None
        if transport == "rest":
            self._http = httpx.AsyncClient(
                base_url=self.address, headers=self._headers, timeout=timeout
            )
        else:
            self._channel = grpc.aio.insecure_channel(
                _grpc_target(self.address), options=GRPC_OPTIONS
            )

    async def close(self) -> None:
        """Closes the connection pool or channel."""
        if self._http is not None:
            await self._http.aclose()
        if self._channel is not None:
            await self._channel.close()

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def _run(self, call: Call[R]) -> R:
        attempt = 0
        while True:
            try:
                return await self._run_once(call)
            except KinserveError as e:
                wait = _retry_delay(e, attempt, self.retries)
                if wait is None:
                    raise
            await asyncio.sleep(wait)
            attempt += 1

    async def _run_once(self, call: Call[R]) -> R:
        if isinstance(call, RestCall):
            assert self._http is not None
            r = await self._http.request(
                call.method,
                call.path,
                json=call.json,
                content=call.content,
                params=call.params,
                headers=call.headers,
            )
            raise_for(r)
            return call.parse(r)
        assert isinstance(call, GrpcCall) and self._channel is not None
        fn = self._channel.unary_unary(
            method_path(call.method),
            request_serializer=_serialize,
            response_deserializer=call.response_type.FromString,
        )
        try:
            response = await fn(call.request, metadata=self._metadata, timeout=self.timeout)
        except grpc.RpcError as e:
            raise grpc_error(e) from None
        return call.parse(response)

    async def robots(self, page_size: int | None = None) -> AsyncIterator[RobotSummary]:
        """Every robot, sorted by name, a page at a time (see :meth:`Client.robots`)."""
        token: str | None = None
        while True:
            page = await self.list_robots_page(page_size, token)
            for robot in page.robots:
                yield robot
            token = page.next_page_token
            if not token:
                return

    async def replace(
        self, model: Mapping[str, Any] | str | os.PathLike[str], *, etag: str | None = None
    ) -> Registered:
        """Registers or replaces a robot (``register(model, replace=True, etag=etag)``)."""
        return await self.register(model, replace=True, etag=etag)

    def stream(
        self,
        robot: str,
        *,
        latest_wins: bool = False,
        angle_unit: AngleUnit = "rad",
        pose_format: PoseFormat = "full",
        check_limits: bool = True,
    ) -> Stream:
        """A stream of FK / Jacobian / IK requests on one connection (the
        WebSocket ``/v1/robots/{robot}/fk/stream`` over REST, the
        ``StreamForwardKinematics`` call over gRPC); replies come in order.

        With ``latest_wins=True`` at most one request is in flight: a
        :meth:`Stream.send` while one is answered replaces any unsent request
        and goes out when the reply arrives (for UIs following a slider).

        ``async with client.stream("puma560") as s: await s.send(q); reply = await s.recv()``
        """
        defaults: dict[str, JSON] = {
            "angle_unit": angle_unit,
            "pose_format": pose_format,
            "check_limits": check_limits,
        }
        opener = functools.partial(
            open_stream,
            transport=self.transport,
            address=self.address,
            robot=robot,
            headers=self._headers,
            channel=self._channel,
            metadata=self._metadata,
        )
        return Stream(opener, robot=robot, latest_wins=latest_wins, defaults=defaults)

    list_robots_page = _op_async(RestOps.list_robots_page)
    get_robot = _op_async(RestOps.get_robot)
    register = _op_async(RestOps.register)
    import_urdf = _op_async(RestOps.import_urdf)
    delete = _op_async(RestOps.delete)
    urdf = _op_async(RestOps.urdf)
    closed_form = _op_async(RestOps.closed_form)
    fk = _op_async(RestOps.fk)
    fk_batch = _op_async(RestOps.fk_batch)
    jacobian = _op_async(RestOps.jacobian)
    jacobian_batch = _op_async(RestOps.jacobian_batch)
    ik = _op_async(RestOps.ik)
    ik_batch = _op_async(RestOps.ik_batch)
    ik_path = _op_async(RestOps.ik_path)
    link_transforms = _op_async(RestOps.link_transforms)

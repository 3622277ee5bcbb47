"""Streams: many FK / Jacobian / IK requests on one connection, over the
WebSocket (REST) or the gRPC ``StreamForwardKinematics`` call, with a
"latest wins" mode that keeps at most one request in flight.

A request is a dict in the WebSocket schema (``id``, ``joints``, ``ik`` or ``ik_path``,
``angle_unit``, ``frames``, ``pose_format``, ``jacobian``, ``frame``,
``link_transforms``, ``check_limits``); the gRPC wire converts it. Owns the
stream bookkeeping; depends on the parsers of ``_rest`` and ``_pbconv``.
"""

from __future__ import annotations

import asyncio
import json
from dataclasses import dataclass
from typing import Any, Awaitable, Callable, Mapping, Protocol, Sequence
from urllib.parse import quote

import numpy as np

from . import errors
from ._calls import configurations, joint_vector, target_json
from ._rest import error_from_problem, fk_result, jacobian_item, parse_ik_item, parse_path, path_body
from .types import JSON, Array, ArrayLike, FkResult, IkPath, IkResult, Jacobian, PoseFormat, Transport


@dataclass(frozen=True)
class StreamReply:
    """One reply of a stream: ``fk`` (and ``jacobian``, ``link_transforms``
    when asked for) for an FK request, ``poses`` for many configurations
    (:meth:`Stream.send_many`), ``ik`` for an IK request, ``ik_path`` for a
    Cartesian path, or ``error``."""

    id: int
    fk: FkResult | None = None
    jacobian: Jacobian | None = None
    ik: IkResult | None = None
    link_transforms: Any = None
    error: errors.KinserveError | None = None
    ik_path: IkPath | None = None
    poses: Array | None = None
    """:meth:`Stream.send_many`'s poses, shaped as :meth:`Client.fk_batch`
    returns them: (N, 4, 4) for ``full``, (N, 3, 4) ``matrix``, (N, 3) ``position``."""

    def unwrap(self) -> StreamReply:
        """The reply itself, or its error raised."""
        if self.error is not None:
            raise self.error
        return self


class _Wire(Protocol):
    async def send(self, request: Mapping[str, JSON]) -> None: ...

    async def recv(self, requests: Mapping[int, Mapping[str, JSON]]) -> StreamReply | None: ...

    async def close(self) -> None: ...


Opener = Callable[[], Awaitable[_Wire]]

CLOSE_WAIT_S = 2.0
"""How long closing a gRPC stream waits for the server to end it before cancelling."""


class Stream:
    """An open stream (from :meth:`AsyncClient.stream`): an async context
    manager and an async iterator of :class:`StreamReply`, in request order."""

    def __init__(
        self,
        opener: Opener,
        *,
        robot: str,
        latest_wins: bool,
        defaults: Mapping[str, JSON],
    ) -> None:
        self._opener = opener
        self._wire: _Wire | None = None
        self.robot = robot
        self.latest_wins = latest_wins
        self._defaults = dict(defaults)
        self._next_id = 1
        self._sent: dict[int, dict[str, JSON]] = {}
        self._pending: dict[str, JSON] | None = None
        self._lock = asyncio.Lock()
        self.superseded = 0
        """Requests replaced by a newer one before they went out (latest wins)."""

    async def __aenter__(self) -> Stream:
        self._wire = await self._opener()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def close(self) -> None:
        """Closes the connection."""
        if self._wire is not None:
            await self._wire.close()
            self._wire = None

    async def send(
        self,
        joints: ArrayLike,
        *,
        jacobian: bool = False,
        frame: str = "base",
        frames: bool = False,
        link_transforms: bool = False,
        **options: JSON,
    ) -> int:
        """Queues an FK request (with the Jacobian / frames / link transforms
        when asked for); ``options`` override the stream's defaults
        (``angle_unit``, ``pose_format``, ``check_limits``). Returns its id."""
        request: dict[str, JSON] = {**self._defaults, **options, "joints": joint_vector(joints)}
        if jacobian:
            request.update(jacobian=True, frame=frame)
        if frames:
            request["frames"] = True
        if link_transforms:
            request["link_transforms"] = True
        return await self._submit(request)

    async def send_many(self, configurations_: ArrayLike, **options: JSON) -> int:
        """Queues FK of many configurations in one message (an (N, dof) array;
        at most the server's batch limit): one reply whose ``poses`` hold them
        all, in order, as :meth:`Client.fk_batch` answers them. ``options`` as
        for :meth:`send`. Over gRPC the configurations go packed
        (``packed_configurations``); one bad value refuses the message, naming
        ``configurations[i][j]``, and the stream goes on. Returns its id.

        Cheaper per pose than one :meth:`send` each when a planner has many
        configurations at once (a whole path, a sampled region)."""
        rows = configurations(configurations_)
        request: dict[str, JSON] = {**self._defaults, **options, "configurations": rows.tolist()}
        return await self._submit(request)

    async def send_ik(self, target: ArrayLike | Mapping[str, Any], **ik: JSON) -> int:
        """Queues an IK request: ``target`` as for :meth:`Client.ik`, ``ik`` the
        IK fields (``seed``, ``angle_unit``, ``position_only``, ``tolerance``,
        … and any newer ones, passed through). Returns its id."""
        body: dict[str, JSON] = {"target": target_json(target)}
        for key, value in ik.items():
            body[key] = joint_vector(value) if key == "seed" and value is not None else value
        body.setdefault("angle_unit", self._defaults["angle_unit"])
        return await self._submit({"ik": body})

    async def send_ik_path(
        self,
        start: ArrayLike,
        waypoints: ArrayLike | Sequence[ArrayLike | Mapping[str, Any]],
        *,
        position_only: bool = False,
        **path: JSON,
    ) -> int:
        """Queues a Cartesian path: ``start``, ``waypoints`` and the options
        (``max_step_length``, ``max_joint_step``, ``solver``, …) as for
        :meth:`Client.ik_path`; the reply's ``ik_path`` is an
        :class:`~kinserve_client.types.IkPath`. Returns its id."""
        angle_unit = path.pop("angle_unit", self._defaults["angle_unit"])
        body = path_body(start, waypoints, angle_unit, position_only, path)
        return await self._submit({"ik_path": body})

    async def _submit(self, request: dict[str, JSON]) -> int:
        request["id"] = self._next_id
        self._next_id += 1
        async with self._lock:
            if self.latest_wins and self._sent:
                if self._pending is not None:
                    self.superseded += 1
                self._pending = request
            else:
                await self._transmit(request)
        return int(request["id"])

    async def _transmit(self, request: dict[str, JSON]) -> None:
        if self._wire is None:
            raise RuntimeError("the stream is not open (use `async with client.stream(...)`)")
        self._sent[int(request["id"])] = request
        await self._wire.send(request)

    async def recv(self) -> StreamReply:
        """The next reply (raises ``StopAsyncIteration`` when the server closed the stream)."""
        if self._wire is None:
            raise RuntimeError("the stream is not open")
        reply = await self._wire.recv(self._sent)
        if reply is None:
            raise StopAsyncIteration
        async with self._lock:
            self._sent.pop(reply.id, None)
            if self._pending is not None and not self._sent:
                pending, self._pending = self._pending, None
                await self._transmit(pending)
        return reply

    @property
    def in_flight(self) -> int:
        """Requests sent and not answered yet."""
        return len(self._sent)

    def __aiter__(self) -> Stream:
        return self

    async def __anext__(self) -> StreamReply:
        if self._wire is None or (not self._sent and self._pending is None):
            raise StopAsyncIteration
        return await self.recv()


def _reply_from_json(m: Mapping[str, Any], requests: Mapping[int, Mapping[str, JSON]]) -> StreamReply:
    rid = int(m.get("id") or 0)
    if m.get("error") is not None:
        problem = m["error"]
        return StreamReply(rid, error=error_from_problem(int(problem.get("status", 0)), problem, ""))
    request = requests.get(rid, {})
    if "ik_path" in request:
        top = {"robot": "", "length_unit": m.get("length_unit", ""), "angle_unit": request["ik_path"].get("angle_unit", "rad")}
        return StreamReply(rid, ik_path=parse_path(m, top))
    if "ik" in request:
        return StreamReply(rid, ik=parse_ik_item(m))
    fmt: PoseFormat = request.get("pose_format", "full")
    if "configurations" in request:
        return StreamReply(rid, poses=_many_from_json(m, fmt))
    fk = fk_result(m, fmt)
    jac = jacobian_item(m) if "jacobian" in m else None
    lt = None
    if "link_transforms" in m:
        lt = np.asarray([[x["matrix"], x["inverse"]] for x in m["link_transforms"]], dtype=np.float64)
    return StreamReply(rid, fk=fk, jacobian=jac, link_transforms=lt)


def _many_from_json(m: Mapping[str, Any], fmt: PoseFormat) -> Array:
    """A many-configuration reply's poses (``poses``, ``matrices`` or ``positions``)."""
    if fmt == "full":
        return np.asarray([p["matrix"] for p in m["poses"]], dtype=np.float64).reshape(-1, 4, 4)
    if fmt == "matrix":
        return np.asarray(m["matrices"], dtype=np.float64).reshape(-1, 3, 4)
    return np.asarray(m["positions"], dtype=np.float64).reshape(-1, 3)


class _WebSocketWire:
    def __init__(self, ws: Any) -> None:
        self._ws = ws

    async def send(self, request: Mapping[str, JSON]) -> None:
        await self._ws.send(json.dumps(request))

    async def recv(self, requests: Mapping[int, Mapping[str, JSON]]) -> StreamReply | None:
        import websockets

        try:
            text = await self._ws.recv()
        except websockets.ConnectionClosed:
            return None
        return _reply_from_json(json.loads(text), requests)

    async def close(self) -> None:
        await self._ws.close()


class _GrpcWire:
    def __init__(self, call: Any, robot: str) -> None:
        self._call = call
        self._robot = robot

    async def send(self, request: Mapping[str, JSON]) -> None:
        from ._grpc import stream_request

        await self._call.write(stream_request(self._robot, request))

    async def recv(self, requests: Mapping[int, Mapping[str, JSON]]) -> StreamReply | None:
        import grpc.aio

        from ._grpc import stream_reply

        try:
            m = await self._call.read()
        except grpc.aio.AioRpcError as e:
            from .client import grpc_error

            raise grpc_error(e) from None
        if m is grpc.aio.EOF:
            return None
        reply: StreamReply = stream_reply(m, requests)
        return reply

    async def close(self) -> None:
        """Half-closes the call and waits for it to end (the server ends it once
        it answered everything sent), cancelling it after ``CLOSE_WAIT_S``.
        Either way the call has ended when this returns: gRPC delivers no
        late event of it to an event loop that is closed by then (seen as
        ``RuntimeError: Event loop is closed`` in the next test of a suite)."""
        try:
            await self._call.done_writing()
            await asyncio.wait_for(self._call.code(), CLOSE_WAIT_S)
        except Exception:  # a timeout, or the call failed: end it here
            self._call.cancel()
            await self._call.code()


async def open_stream(
    *,
    transport: Transport,
    address: str,
    robot: str,
    headers: Mapping[str, str],
    channel: Any,
    metadata: Any,
) -> _Wire:
    """Opens the connection of a stream."""
    if transport == "rest":
        from websockets.asyncio.client import connect

        url = address.replace("http://", "ws://", 1).replace("https://", "wss://", 1)
        ws = await connect(
            f"{url}/v1/robots/{quote(robot, safe='')}/fk/stream",
            additional_headers=dict(headers),
            max_size=None,
        )
        return _WebSocketWire(ws)
    from ._grpc import SERVICE, _serialize_stream
    from ._pb.kinematics.v1 import kinematics_pb2 as pb

    method = f"/{SERVICE.full_name}/StreamForwardKinematics"
    fn = channel.stream_stream(
        method,
        request_serializer=_serialize_stream,
        response_deserializer=pb.StreamForwardKinematicsResponse.FromString,
    )
    return _GrpcWire(fn(metadata=metadata), robot)

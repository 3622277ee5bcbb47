"""The asyncio client and streams on both transports: the same answers as
the blocking client, replies in order, latest-wins keeping one request in
flight, errors in stream replies carrying field paths."""

from __future__ import annotations

import numpy as np
import pytest

import kinserve_client as kc
from conftest import Server

pytestmark = pytest.mark.anyio
Q = [0.3, -0.4, 0.6, 0.2, -0.5, 0.7]


async def test_async_client_answers_as_the_blocking_one(server: Server, transport: str) -> None:
    addr = server.address(transport)
    with kc.Client(addr, transport=transport) as sync:  # type: ignore[arg-type]
        want = sync.fk_batch("puma560", [Q, [0.0] * 6])
        names = [r.name for r in sync.robots()]
    async with kc.AsyncClient(addr, transport=transport) as c:  # type: ignore[arg-type]
        got = await c.fk_batch("puma560", [Q, [0.0] * 6])
        assert got.shape == (2, 4, 4) and np.array_equal(got, want)
        assert [r.name async for r in c.robots(page_size=3)] == names
        j = await c.jacobian_batch("puma560", [Q])
        assert j.jacobians.shape == (1, 6, 6)
        ik = await c.ik("puma560", want[0])
        assert ik.converged
        with pytest.raises(kc.InvalidArgument) as e:
            await c.fk("puma560", [0, 3.0, 0, 0, 0, 0])
        assert list(e.value.fields) == ["joints[1]"]


async def test_stream_replies_in_order_with_fk_jacobian_and_ik(server: Server, transport: str) -> None:
    qs = np.random.default_rng(1).uniform(-1, 1, size=(5, 6))
    async with kc.AsyncClient(server.address(transport), transport=transport) as c:  # type: ignore[arg-type]
        want = await c.fk_batch("puma560", qs)
        async with c.stream("puma560") as s:
            ids = [await s.send(q) for q in qs]
            replies = [await s.recv() for _ in ids]
            assert [r.id for r in replies] == ids
            for reply, pose in zip(replies, want):
                assert reply.fk is not None and np.allclose(reply.fk.transform, pose, atol=1e-12)
            await s.send(Q, jacobian=True)
            jac = (await s.recv()).unwrap().jacobian
            assert jac is not None
            assert np.allclose(jac.jacobian, (await c.jacobian("puma560", Q)).jacobian, atol=1e-12)
            await s.send_ik(want[0], tolerance=1e-10)
            ik = (await s.recv()).unwrap().ik
            assert ik is not None and ik.converged
            assert np.allclose((await c.fk("puma560", ik.joints)).transform, want[0], atol=1e-8)
            await s.send([0, 3.0, 0, 0, 0, 0])
            bad = await s.recv()
            assert bad.error is not None and list(bad.error.fields) == ["joints[1]"]
            assert bad.error.code == "INVALID_ARGUMENT"


async def test_stream_many_configurations_in_one_message(server: Server, transport: str) -> None:
    """send_many: one reply holding every pose, bit for bit the batch's, in
    each format (over gRPC the configurations go packed); a bad value
    refuses that message only, naming it."""
    qs = np.random.default_rng(3).uniform(-1, 1, size=(37, 6))
    async with kc.AsyncClient(server.address(transport), transport=transport) as c:  # type: ignore[arg-type]
        async with c.stream("puma560") as s:
            for fmt in ["full", "matrix", "position"]:
                want = await c.fk_batch("puma560", qs, pose_format=fmt)  # type: ignore[arg-type]
                rid = await s.send_many(qs, pose_format=fmt)
                reply = (await s.recv()).unwrap()
                assert reply.id == rid and reply.poses is not None and reply.fk is None
                assert reply.poses.shape == want.shape and np.array_equal(reply.poses, want), fmt
            bad = qs[:3].copy()
            bad[2, 1] = 3.0
            await s.send_many(bad)
            refused = await s.recv()
            assert refused.error is not None and list(refused.error.fields) == ["configurations[2][1]"]
            await s.send_many(np.zeros((0, 6)))
            empty = (await s.recv()).unwrap()
            assert empty.poses is not None and empty.poses.shape == (0, 4, 4)


async def test_stream_compact_format(server: Server, transport: str) -> None:
    async with kc.AsyncClient(server.address(transport), transport=transport) as c:  # type: ignore[arg-type]
        full = (await c.fk("puma560", Q)).transform
        async with c.stream("puma560", pose_format="position") as s:
            await s.send(Q)
            reply = (await s.recv()).unwrap()
            assert reply.fk is not None and reply.fk.transform.shape == (3,)
            assert np.allclose(reply.fk.transform, full[:3, 3], atol=1e-12)


async def test_latest_wins_keeps_one_request_in_flight(server: Server, transport: str) -> None:
    qs = np.linspace(-1.0, 1.0, 20)[:, None] * np.ones((20, 6))
    async with kc.AsyncClient(server.address(transport), transport=transport) as c:  # type: ignore[arg-type]
        last = (await c.fk("puma560", qs[-1])).transform
        async with c.stream("puma560", latest_wins=True) as s:
            ids = []
            for q in qs:
                ids.append(await s.send(q))
                assert s.in_flight == 1
            replies = [r async for r in s]
    # The first went out at once; each later one replaced the unsent one, so
    # only the newest followed the first reply.
    assert [r.id for r in replies] == [ids[0], ids[-1]]
    assert s.superseded == 18
    assert replies[-1].fk is not None and np.allclose(replies[-1].fk.transform, last, atol=1e-12)

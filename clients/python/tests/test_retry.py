"""A request the server refused before doing anything (``overloaded``: the
client holds its share of the compute pool) is sent again after the wait
the server asked for, on both transports; with ``retries=0`` the refusal is
raised, marked ``refused``. Other requests of this address hold the share:
IK batches of targets out of reach, whose callers give up after a while
(the server then stops them)."""

from __future__ import annotations

import threading
import time
from typing import Iterator

import httpx
import pytest

import kinserve_client as kc
from conftest import Server

HOLDS = 8  # batches at once: the whole share of a server of up to 17 CPUs
HOLD_SECONDS = 5.0  # how long each hold's caller waits before it gives up (the window the tests use)
FAR = {"position": [3.0, 0.0, 0.2]}
REACHABLE = [0.4, 0.1, 0.4]


def _hold(server: Server) -> list[threading.Thread]:
    body = {"targets": [FAR] * 10_000, "position_only": True, "solver": "numeric"}

    def one() -> None:
        try:
            httpx.post(server.url + "/v1/robots/ur5e/ik/batch", json=body, timeout=HOLD_SECONDS)
        except httpx.TimeoutException:
            pass

    threads = [threading.Thread(target=one) for _ in range(HOLDS)]
    for t in threads:
        t.start()
    return threads


@pytest.fixture
def share_held(server: Server) -> Iterator[None]:
    """The client's share held (a probe of ours is refused) until the holds give up."""
    deadline = time.monotonic() + 30
    probe = {"target": {"position": REACHABLE}, "position_only": True}
    while True:
        threads = _hold(server)
        time.sleep(0.3)
        r = httpx.post(server.url + "/v1/robots/ur5e/ik", json=probe, timeout=30)
        if r.status_code == 503:
            break
        for t in threads:  # the holds had not started, or a probe refused them: again
            t.join()
        assert time.monotonic() < deadline, "the holds never took the share"
    yield
    for t in threads:
        t.join()


def test_a_refused_request_is_sent_again_after_retry_after(
    server: Server, transport: str, share_held: None
) -> None:
    start = time.monotonic()
    with kc.Client(server.address(transport), transport=transport, retries=10) as c:  # type: ignore[arg-type]
        answer = c.ik("ur5e", REACHABLE, position_only=True)
    assert answer.converged
    assert time.monotonic() - start >= 0.9, "answered only after waiting at least once"


def test_without_retries_the_refusal_is_raised(
    server: Server, transport: str, share_held: None
) -> None:
    with kc.Client(server.address(transport), transport=transport, retries=0) as c:  # type: ignore[arg-type]
        with pytest.raises(kc.ResourceExhausted) as caught:
            c.ik("ur5e", REACHABLE, position_only=True)
    e = caught.value
    assert e.refused and e.kind == "overloaded", repr(e)
    assert "holds" in e.detail and "--client-share-percent" in e.detail, e.detail
    assert e.status == 503 and e.retry_after == 1.0, repr(e)

"""Fixtures: the server under test and clients of it.

The server comes from the environment (the cargo test ``tests/api/clients.rs``
sets ``KINSERVE_URL``, ``KINSERVE_GRPC``, ``KINSERVE_TOKEN`` and
``KINSERVE_EXPECTED``, the values from the kinematics library), or, when
``KINSERVE_URL`` is unset, this starts ``$KINSERVE_BIN`` (default: ``kinserve``
on PATH) on free ports with a token.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any, Iterator

import httpx
import pytest

import kinserve_client as kc

REPO = Path(os.environ.get("KINSERVE_REPO", Path(__file__).resolve().parents[3]))


class Server:
    """Where the server is, its token and the expected values."""

    def __init__(self, url: str, grpc: str, token: str, expected: dict[str, Any]) -> None:
        self.url = url
        self.grpc = grpc
        self.token = token
        self.expected = expected

    def address(self, transport: str) -> str:
        return self.url if transport == "rest" else self.grpc

    def raw(self, method: str, path: str, body: Any = None) -> Any:
        """The server's own JSON answer to a REST request (the reference)."""
        r = httpx.request(method, self.url + path, json=body, timeout=30)
        assert r.status_code == 200, r.text
        return r.json()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="session")
def server() -> Iterator[Server]:
    expected_path = os.environ.get("KINSERVE_EXPECTED")
    expected = json.loads(Path(expected_path).read_text()) if expected_path else {}
    if os.environ.get("KINSERVE_URL"):
        yield Server(
            os.environ["KINSERVE_URL"],
            os.environ["KINSERVE_GRPC"],
            os.environ.get("KINSERVE_TOKEN", ""),
            expected,
        )
        return
    binary = os.environ.get("KINSERVE_BIN") or shutil.which("kinserve")
    if binary is None:
        pytest.skip("no server: set KINSERVE_URL/KINSERVE_GRPC or KINSERVE_BIN")
    http, grpc_port, token = _free_port(), _free_port(), "pytest-token"
    with tempfile.TemporaryDirectory() as data:
        proc = subprocess.Popen(
            [binary, "serve", "--http-addr", f"127.0.0.1:{http}", "--grpc-addr",
             f"127.0.0.1:{grpc_port}", "--data-dir", data, "--api-token", token],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )
        try:
            url = f"http://127.0.0.1:{http}"
            for _ in range(100):
                try:
                    if httpx.get(url + "/readyz").status_code == 200:
                        break
                except httpx.HTTPError:
                    time.sleep(0.1)
            yield Server(url, f"127.0.0.1:{grpc_port}", token, expected)
        finally:
            proc.terminate()
            proc.wait(10)


@pytest.fixture(params=["rest", "grpc"])
def transport(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture
def client(server: Server, transport: str) -> Iterator[kc.Client]:
    with kc.Client(server.address(transport), transport=transport, token=server.token) as c:  # type: ignore[arg-type]
        yield c


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


def planar_model(name: str) -> dict[str, Any]:
    """Two revolute joints, links of 0.5 and 0.3 m, angles in degrees."""
    return {
        "name": name,
        "convention": "standard",
        "angle_unit": "deg",
        "length_unit": "m",
        "links": [
            {"joint": "revolute", "a": 0.5, "alpha": 0.0, "d": 0.0, "theta": 0.0, "limits": [-170.0, 170.0]},
            {"joint": "revolute", "a": 0.3, "alpha": 0.0, "d": 0.0, "theta": 0.0, "limits": [-170.0, 170.0]},
        ],
    }

"""The package was built from the contract the server has now: the hashes
recorded at build time (``GENERATED_FROM``) equal the hashes of the
repository's ``proto/`` and of the server's live ``/openapi.json``; the
snapshot ``clients/openapi.json`` is that document. A failure means: rebuild
the package (``pip install ./clients/python``) or refresh the snapshot
(``KINSERVE_UPDATE_CLIENTS=1 cargo test --test api clients``)."""

from __future__ import annotations

import json

import httpx

import kinserve_client as kc
from conftest import REPO, Server
from kinserve_client import _inputs


def test_built_from_the_current_proto() -> None:
    assert kc.GENERATED_FROM["proto_sha256"] == _inputs.proto_sha256(REPO / "proto"), (
        "proto/ changed since kinserve-client was built: pip install ./clients/python"
    )


def test_built_from_the_servers_openapi_document(server: Server) -> None:
    live = httpx.get(server.url + "/openapi.json").json()
    snapshot = json.loads((REPO / "clients/openapi.json").read_text(encoding="utf-8"))
    assert live == snapshot, "clients/openapi.json is stale: KINSERVE_UPDATE_CLIENTS=1 cargo test --test api clients"
    assert kc.GENERATED_FROM["openapi_sha256"] == _inputs.openapi_sha256(live), (
        "the OpenAPI snapshot changed since kinserve-client was built: pip install ./clients/python"
    )
    assert kc.API_VERSION == live["info"]["version"]

"""What the client is generated from, hashed: the ``proto/`` tree and the
OpenAPI snapshot ``clients/openapi.json``.

Owns the hash rule and nothing else; standard library only, because the build
hook (``hatch_build.py``) loads this file by path before the package exists.
The tests recompute these hashes from the repository and compare them with
``kinserve_client.GENERATED_FROM`` to catch a client not rebuilt after the
contract changed.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any


def proto_sha256(proto_dir: Path) -> str:
    """SHA-256 over every ``.proto`` file under ``proto_dir``: for each, in
    sorted order of its ``/``-separated relative path, the path, a NUL byte,
    the file's bytes and a NUL byte."""
    h = hashlib.sha256()
    files = sorted(p for p in proto_dir.rglob("*.proto") if p.is_file())
    for path in files:
        h.update(path.relative_to(proto_dir).as_posix().encode())
        h.update(b"\0")
        h.update(path.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


def canonical_json(value: Any) -> bytes:
    """The JSON text hashed for an OpenAPI document: keys sorted, no spaces,
    non-ASCII kept (the TypeScript build hashes its own canonical form)."""
    return json.dumps(
        value, sort_keys=True, separators=(",", ":"), ensure_ascii=False
    ).encode()


def openapi_sha256(document: Any) -> str:
    """SHA-256 of :func:`canonical_json` of an OpenAPI document."""
    return hashlib.sha256(canonical_json(document)).hexdigest()


def describe(proto_dir: Path, openapi_path: Path) -> dict[str, str]:
    """``GENERATED_FROM``: the API version (the OpenAPI document's
    ``info.version``) and both hashes."""
    document = json.loads(openapi_path.read_text(encoding="utf-8"))
    return {
        "api_version": str(document["info"]["version"]),
        "proto_package": "kinematics.v1",
        "proto_sha256": proto_sha256(proto_dir),
        "openapi_sha256": openapi_sha256(document),
    }

"""Every ```python block of README.md runs against the server as written
(with ``BASE``, ``GRPC`` and ``TOKEN`` defined)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from conftest import Server

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)


def test_the_readme_has_examples() -> None:
    assert len(BLOCKS) >= 6


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_example_runs(server: Server, index: int) -> None:
    code = compile(BLOCKS[index], f"README.md block {index + 1}", "exec")
    exec(code, {"BASE": server.url, "GRPC": server.grpc, "TOKEN": server.token, "__name__": "readme"})

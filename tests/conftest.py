"""Shared test configuration.

Cases marked ``slow`` run in CI (``CI=true``) and with ``--runslow``; a local default run skips
them to stay fast.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

import pytest

from urdfpost._compiled import Kernels

ROOT = Path(__file__).resolve().parents[1]
SHARED_CL = ROOT.parent / "shared" / "testdata" / "cl"


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--runslow", action="store_true", help="run tests marked slow")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.getoption("--runslow") or os.environ.get("CI", "").lower() in ("1", "true", "yes"):
        return
    skip = pytest.mark.skip(reason="slow: runs in CI or with --runslow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


def shared_cl(name: str) -> Path:
    """Path of a real CL file in ../shared/testdata/cl, skipping the test when absent."""
    path = SHARED_CL / name
    if not path.is_file():
        pytest.skip(f"real CL file {path} not present (../shared is not part of a fresh clone)")
    return path


StandIn = Callable[[Kernels, SimpleNamespace], None]
Unloaded = Callable[[Kernels], None]


@pytest.fixture
def stand_in(monkeypatch: pytest.MonkeyPatch) -> StandIn:
    """Make a :class:`~urdfpost._compiled.Kernels` hand out a stand-in for its module (kernels
    that fail, or wrap the real ones) in this test, as if loaded and never failed; the object is
    as it was after the test."""

    def install(kernels: Kernels, module: SimpleNamespace) -> None:
        monkeypatch.setattr(kernels, "module", module)
        monkeypatch.setattr(kernels, "failed", None)
        monkeypatch.setattr(kernels, "_tried", True)

    return install


@pytest.fixture
def unloaded(monkeypatch: pytest.MonkeyPatch) -> Unloaded:
    """Make a :class:`~urdfpost._compiled.Kernels` as if its module had never been looked for
    in this process (nor failed); the object is as it was after the test."""

    def reset(kernels: Kernels) -> None:
        monkeypatch.setattr(kernels, "module", None)
        monkeypatch.setattr(kernels, "failed", None)
        monkeypatch.setattr(kernels, "_tried", False)

    return reset

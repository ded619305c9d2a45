"""The jobs handed to a verification worker with their arrays in a file of ``/dev/shm``
(``posting.worker._share`` / ``_taken``): the same job arrives, nothing is left behind, and what
a killed post left is removed by the next."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from jobs import write_hemisphere

from urdfpost import load_machine
from urdfpost.posting import worker
from urdfpost.posting.options import PostOptions
from urdfpost.posting.stream import post_stream
from urdfpost.readers import read_cl
from urdfpost.toolpath import Toolpath, toolpath_pieces

shm = pytest.mark.skipif(not os.path.isdir(worker.SHARED_DIR), reason="no /dev/shm here")


def own_files() -> list[str]:
    prefix = f"{worker._SHARED_PREFIX}{os.getpid()}-"
    return [n for n in os.listdir(worker.SHARED_DIR) if n.startswith(prefix)]


@shm
def test_a_job_with_many_arrays_arrives_the_same_and_its_file_is_gone() -> None:
    rng = np.random.default_rng(3)
    job = {
        "q": rng.normal(size=(60_000, 5)),
        "lines": np.arange(60_000),
        "flags": rng.normal(size=60_000) > 0,
        "text": "GOTO/1,2,3",
        "empty": np.zeros(0),
    }
    shared = worker._share(job)
    assert shared is not None and os.path.exists(shared.path)
    assert len(shared.data) < 10_000  # the arrays' bytes are in the file, not the pickle
    got = worker._taken(shared)
    assert not os.path.exists(shared.path)
    assert got.keys() == job.keys() and got["text"] == job["text"]
    for key in ("q", "lines", "flags", "empty"):
        assert got[key].dtype == job[key].dtype
        assert np.array_equal(got[key], job[key])
    got["q"][0, 0] = 1.0e9  # mapped copy-on-write: the job may write to its arrays
    assert got["q"][0, 0] == 1.0e9


def test_a_small_job_goes_through_the_pipe() -> None:
    assert worker._share({"q": np.zeros((10, 5)), "name": "x"}) is None


@shm
def test_the_files_of_a_post_that_is_gone_are_removed_and_no_others() -> None:
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)  # fmt: skip
    stale = Path(worker.SHARED_DIR) / f"{worker._SHARED_PREFIX}{int(dead.stdout)}-abc"
    live = Path(worker.SHARED_DIR) / f"{worker._SHARED_PREFIX}{os.getpid()}-abc"
    other = Path(worker.SHARED_DIR) / "not-urdfpost-job-1-abc"
    try:
        for p in (stale, live, other):
            p.write_bytes(b"x")
        worker._stale_shared()
        assert not stale.exists() and live.exists() and other.exists()
    finally:
        for p in (stale, live, other):
            p.unlink(missing_ok=True)


@shm
@pytest.mark.skipif(not worker.FORK or (os.cpu_count() or 1) < 2, reason="forked worker")
def test_a_streamed_post_sends_its_pieces_through_files_to_the_same_program(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    raster: Toolpath = read_cl(write_hemisphere(3000, tmp_path / "hemisphere.apt"))
    options = PostOptions(controller="heidenhain", tcp=False)

    def post(name: str) -> bytes:
        out = tmp_path / name
        post_stream(toolpath_pieces(raster, 997), load_machine("dmu50"), out, options,
                    piece_points=700, lookahead=200, parallel=True)  # fmt: skip
        return out.read_bytes()

    shared: list[str] = []
    share = worker._share

    def counted(job: object) -> worker._Shared | None:
        found = share(job)
        if found is not None:
            shared.append(found.path)
        return found

    monkeypatch.setattr(worker, "SHARED_FROM", 0)
    monkeypatch.setattr(worker, "_share", counted)
    through_files = post("files.nc")
    assert len(shared) > 3, "the pieces did not go through files"
    assert own_files() == []
    monkeypatch.setattr(worker, "SHARED_DIR", str(tmp_path / "none"))
    assert post("pipe.nc") == through_files

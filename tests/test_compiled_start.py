"""numba made ready without its BLAS probe (``urdfpost._compiled.start_numba``): the kernels run,
``scipy.linalg`` is not imported on the way and imports as ever afterwards."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("numba")

_SCRIPT = textwrap.dedent(
    """
    import sys
    import numpy as np
    from urdfpost._compiled import start_numba
    from urdfpost.readers.apt import KERNELS

    start_numba()
    assert "scipy.linalg" not in sys.modules, "numba imported scipy.linalg"
    kernels = KERNELS.load()
    assert kernels is not None and KERNELS.failed is None, KERNELS.failed
    data = np.frombuffer(b"GOTO/1,2,3\\nGOTO/4,5,6\\n", dtype=np.uint8)
    count, plain = kernels.plain_goto_lines(data, False)
    assert (count, plain) == (2, True), (count, plain)
    assert "scipy.linalg" not in sys.modules, "a kernel imported scipy.linalg"
    import numba.np.arraymath

    assert numba.np.arraymath._HAVE_BLAS is False  # what start_numba changes, and only that
    import numba.np.linalg

    assert numba.np.linalg.ensure_blas.__name__ == "ensure_blas"  # the probe put back
    import scipy.linalg

    assert scipy.linalg.norm([3.0, 4.0]) == 5.0
    print("ok")
    """
)


def test_numba_starts_without_scipy_linalg_and_scipy_linalg_imports_afterwards() -> None:
    done = subprocess.run(
        [sys.executable, "-c", _SCRIPT], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"

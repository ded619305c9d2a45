"""Bad input through the command line, one row per case (issue 22: "nothing lost, nothing
destroyed").

Every row is run through the real command line in-process (``urdfpost.cli.main``) in a folder
of its own, whose files the row lists, and checked for three things:

- the exit code: 0 (done, perhaps with warnings), 1 (bad input, a fault, a program beyond
  tolerance), 2 (usage);
- a fragment of what the user reads (stderr, or stdout for verification figures), which names
  the file and, where the input has lines, the line (``bad.apt:6:``); no traceback;
- what is on disk afterwards: for a failure, the folder exactly as it was (no output, an old
  output byte for byte, no temporary ``.part`` or ``.tmp`` file), and no file left in the
  temporary folder of a streamed post; for a success, only the named outputs new or changed.

CL rows are run three ways where the case applies (``post`` whole with a report, ``post
--piece-points 50`` over an old program and report that must survive, and ``verify`` with a
report), machine-file rows through ``post`` (and ``verify``, ``machine show`` for a few). The
classes and what the user does about each are in ``docs/errors.md``. A row marked ``xfail``
fails today (strict: it shows when the fix lands); its reason says what is wrong.
"""

from __future__ import annotations

import os
import random
import re
import stat
import tempfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import pytest
from conftest import shared_cl

from urdfpost.cli import main

ROOT = Path(__file__).resolve().parents[1]
DMU50 = ROOT / "robots" / "urdf" / "dmu50.urdf"
ROOT_USER = hasattr(os, "geteuid") and os.geteuid() == 0

#: The head of every small CL job: units, tool, spindle and feed; line 6 is the first motion.
HEAD = "UNITS/MM\nMULTAX/ON\nLOADTL/1\nSPINDL/10000,CLW\nFEDRAT/MMPM,1000\n"
#: A two-point job that posts and verifies on dmu50 (tool axis tilted 15 degrees).
JOB = HEAD + "GOTO/0,0,10,0,0.2588190,0.9659258\nGOTO/20,0,10,0.2588190,0,0.9659258\nFINI\n"
#: What an old program and an old report hold: a run that fails must leave them as they are.
OLD = b"the program of the last post\n"
OLD_REPORT = b'{"the report of": "the last post"}\n'

Content = str | bytes | Callable[[], str | bytes]


@dataclass(frozen=True)
class Row:
    """One case.

    Attributes
    ----------
    id : str
        The test id.
    argv : tuple of str
        The command line after ``urdfpost``; file names relative to the case's folder.
    code : int
        Expected exit code.
    message : str
        A fragment of stderr (``stream="out"``: of stdout); ``{line}`` is replaced by the
        line of ``at``.
    files : mapping of str to content
        The folder's files before the run (text, bytes, or a function giving either); the
        program ``prog.h`` is the one posted from :data:`JOB`.
    after : tuple of str
        The files the run writes (new or changed); every other file, link and folder must be
        as it was. Empty: nothing may change.
    at : (str, str), optional
        File and needle: ``{line}`` is the first line of that file holding the needle.
    stream : str
        "err" or "out": where ``message`` is.
    contains : mapping of str to str
        A fragment each written file must hold.
    links : mapping of str to str
        Symbolic links to make (name to target).
    modes : mapping of str to int
        Permissions to give files after they are written.
    small : int, optional
        Largest size in bytes of stderr and of every written file.
    user : str
        "any", "non-root" (skipped as root, who may read and write anything) or "root".
    xfail : str
        Why the row fails today (empty: it passes).
    """

    id: str
    argv: tuple[str, ...]
    code: int
    message: str
    files: Mapping[str, Content] = field(default_factory=dict)
    after: tuple[str, ...] = ()
    at: tuple[str, str] | None = None
    stream: str = "err"
    contains: Mapping[str, str] = field(default_factory=dict)
    links: Mapping[str, str] = field(default_factory=dict)
    modes: Mapping[str, int] = field(default_factory=dict)
    small: int | None = None
    user: str = "any"
    xfail: str = ""


# -- CL files --------------------------------------------------------------------------------

#: How a CL row is run: the command line and the folder's outputs.
POST = ("post", "bad.apt", "-m", "dmu50", "-q", "-o", "out.h", "--report", "out.json")
STREAM = (*POST, "--piece-points", "50")
VERIFY = (
    "verify",
    "prog.h",
    "-m",
    "dmu50",
    "--cl",
    "bad.apt",
    "--angle-tolerance",
    "2",
    "--report",
    "r.json",
)
ALL = ("post", "stream", "verify")
POSTS = ("post", "stream")


def cl_rows(
    name: str,
    text: Content | None,
    code: int,
    message: str,
    *,
    ways: tuple[str, ...] = ALL,
    options: tuple[str, ...] = (),
    xfail: str = "",
    extra: Mapping[str, Content] | None = None,
    **more: Any,
) -> list[Row]:
    """The rows of one CL case, one per way of running it.

    ``text`` is the CL file ``bad.apt`` (None: no such file). A post over an old program
    (``stream``) must keep it; a successful run writes the outputs of its way.
    """
    rows = []
    for way in ways:
        files: dict[str, Content] = {} if text is None else {"bad.apt": text}
        files |= extra or {}
        argv = {"post": POST, "stream": STREAM, "verify": VERIFY}[way] + options
        if way == "stream":
            files |= {"out.h": OLD, "out.json": OLD_REPORT}
        if way == "verify":
            files["prog.h"] = program
        outputs = ("r.json",) if way == "verify" else ("out.h", "out.json")
        after = outputs if code == 0 else ()
        row = Row(f"cl-{name}-{way}", argv, code, message, files, after, xfail=xfail)
        rows.append(replace(row, **more))
    return rows


#: The program posted from :data:`JOB` by the command line (:func:`posted_program`).
_PROGRAM: dict[str, str] = {}


def program() -> str:
    """The program posted from :data:`JOB`: the ``prog.h`` of the rows that verify."""
    return _PROGRAM["text"]


@pytest.fixture(scope="module", autouse=True)
def posted_program(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Post :data:`JOB` once, for :func:`program`."""
    folder = tmp_path_factory.mktemp("program")
    (folder / "job.apt").write_text(JOB)
    code = main(["post", str(folder / "job.apt"), "-m", "dmu50", "-q", "-o", str(folder / "p.h")])
    assert code == 0
    _PROGRAM["text"] = (folder / "p.h").read_text()


def random_text(seed: int, size: int) -> bytes:
    """Characters of CL text in random order: APT records to the eye, none of them known."""
    rng = random.Random(seed)
    return bytes(rng.choice(b"ABCDEFGHIJ/,.0123456789$ \n") for _ in range(size))


def random_bytes(seed: int, size: int) -> bytes:
    """Bytes of any value in random order (NUL among them): a file that is not text."""
    rng = random.Random(seed)
    return bytes(rng.randrange(256) for _ in range(size))


def nx_ballmill(edit: Callable[[list[str]], None]) -> Callable[[], str]:
    """The real NX listing, edited (the row is skipped where the file is absent)."""

    def text() -> str:
        lines = shared_cl("nx_variable_axis_ballmill_inch.cls").read_text().splitlines(True)
        edit(lines)
        return "".join(lines)

    return text


def _nan_in_goto(lines: list[str]) -> None:
    k = [i for i, ln in enumerate(lines) if ln.startswith("GOTO/")][100]
    lines[k] = lines[k].replace("GOTO/", "GOTO/nan,", 1).rsplit(",", 1)[0] + "\n"


def _cut_in_goto(lines: list[str]) -> None:
    k = [i for i, ln in enumerate(lines) if ln.startswith("GOTO/")][200]
    lines[k] = lines[k][: lines[k].index(",")] + "\n"
    del lines[k + 1 :]


#: The needle of the last line of a file.
LAST = "(the last line)"
LENGTH = "is beyond the largest length urdfpost accepts (1e9 mm)"
NUL = "a NUL byte: expected text in ASCII or UTF-8 (or UTF-16 with a byte-order mark)"
CUT = "expected the continuation of this record (its last line ends with '$')"

CL_ROWS = [
    # numbers
    *cl_rows(
        "letters",
        HEAD + "GOTO/0,0,abc,0,0,1\n",
        1,
        "urdfpost: bad.apt:6: expected a number for the 3rd value of GOTO, got 'abc'",
    ),
    *cl_rows(
        "nan",
        HEAD + "GOTO/0,nan,10\n",
        1,
        "urdfpost: bad.apt:6: expected a finite number for the 2nd value of GOTO, got 'nan'",
    ),
    *cl_rows(
        "inf",
        HEAD + "GOTO/0,0,10\nGOTO/inf,0,10\n",
        1,
        "urdfpost: bad.apt:7: expected a finite number for the 1st value of GOTO, got 'inf'",
    ),
    *cl_rows(
        "overflow",
        HEAD + "GOTO/0,0,1e999\n",
        1,
        "urdfpost: bad.apt:6: expected a finite number for the 3rd value of GOTO",
    ),
    *cl_rows("huge", HEAD + "GOTO/0,2e9,10\n", 1, f"urdfpost: bad.apt:6: GOTO: y 2e9 mm {LENGTH}"),
    *cl_rows(
        "huge-inch",
        "UNITS/INCHES\nLOADTL/1\nGOTO/0,0,4e7\n",
        1,
        f"urdfpost: bad.apt:3: GOTO: z 4e7 inch {LENGTH}",
        ways=("post", "verify"),
    ),
    *cl_rows(
        "two-values",
        HEAD + "GOTO/0,0\n",
        1,
        "urdfpost: bad.apt:6: expected 3 or 6 values in GOTO, got 2",
    ),
    *cl_rows(
        "five-values",
        HEAD + "GOTO/0,0,10,0,0\n",
        1,
        "urdfpost: bad.apt:6: expected 3 or 6 values in GOTO, got 5",
        ways=("post",),
    ),
    *cl_rows(
        "zero-axis",
        HEAD + "GOTO/0,0,10,0,0,0\n",
        1,
        "urdfpost: bad.apt:6: expected a unit tool axis, got (0, 0, 0)",
    ),
    *cl_rows(
        "dollar-swallows-goto",
        HEAD + "GOTO/0,0,10,$\nGOTO/10,0,10\nGOTO/20,0,10\n",
        1,
        f"urdfpost: bad.apt:6: {CUT}, got the motion record at line 7",
    ),
    *cl_rows(
        "dollar-at-the-end",
        HEAD + "GOTO/0,0,10\nGOTO/10,0,10,$\n",
        1,
        f"urdfpost: bad.apt:7: {CUT}, got the end of the file",
        ways=("post", "stream"),
    ),
    # arcs
    *cl_rows(
        "circle-six-values",
        HEAD + "GOTO/1,0,10\nCIRCLE/0,0,10,0,0,1\nGOTO/-1,0,10\n",
        1,
        "urdfpost: bad.apt:7: expected at least 7 values in CIRCLE, got 6",
    ),
    *cl_rows(
        "circle-at-the-end",
        HEAD + "GOTO/1,0,10\nCIRCLE/0,0,10,0,0,1,1\n",
        1,
        "urdfpost: bad.apt:7: expected a GOTO after CIRCLE, got the end of file",
    ),
    *cl_rows(
        "circle-zero-axis",
        HEAD + "GOTO/1,0,10\nCIRCLE/0,0,10,0,0,0,1\nGOTO/-1,0,10\n",
        1,
        "urdfpost: bad.apt:7: expected a unit circle axis, got (0, 0, 0)",
        ways=("post", "verify"),
    ),
    *cl_rows(
        "circle-radius-inf",
        HEAD + "GOTO/1,0,10\nCIRCLE/0,0,10,0,0,1,inf\nGOTO/-1,0,10\n",
        1,
        "urdfpost: bad.apt:7: expected a positive radius",
        ways=("post",),
    ),
    *cl_rows(
        "circle-radius-huge",
        HEAD + "GOTO/1,0,10\nCIRCLE/0,0,10,0,0,1,1e300\nGOTO/-1,0,10\n",
        1,
        f"urdfpost: bad.apt:7: CIRCLE: radius 1e300 mm {LENGTH}",
        ways=("stream",),
    ),
    *cl_rows(
        "circle-times-letters",
        HEAD + "GOTO/1,0,10\nCIRCLE/0,0,10,0,0,1,1,TIMES,x\nGOTO/-1,0,10\n",
        1,
        "urdfpost: bad.apt:7: expected a number for the 9th value of CIRCLE, got 'x'",
        ways=("post",),
    ),
    # feeds, spindle, tools
    *cl_rows(
        "fedrat-zero",
        JOB.replace("FEDRAT/MMPM,1000", "FEDRAT/MMPM,0"),
        1,
        "urdfpost: bad.apt:5: expected a positive feed in FEDRAT, got 0",
    ),
    *cl_rows(
        "fedrat-two-values",
        JOB.replace("FEDRAT/MMPM,1000", "FEDRAT/1000,2000"),
        1,
        "urdfpost: bad.apt:5: expected one feed value in FEDRAT, got 2",
        ways=("post",),
    ),
    *cl_rows(
        "fedrat-huge",
        JOB.replace("FEDRAT/MMPM,1000", "FEDRAT/IPM,1e308"),
        1,
        "urdfpost: bad.apt:5: FEDRAT: feed 1e308 inch/min is beyond the fastest feed",
        ways=("stream", "verify"),
    ),
    *cl_rows(
        "spindl-negative",
        JOB.replace("SPINDL/10000,CLW", "SPINDL/-5,CLW"),
        1,
        "urdfpost: bad.apt:4: expected a spindle speed >= 0 in SPINDL, got -5",
    ),
    *cl_rows(
        "cutter-negative",
        JOB.replace("LOADTL/1\n", "LOADTL/1\nCUTTER/-6\n"),
        1,
        "urdfpost: bad.apt:4: expected tool dimensions >= 0 in CUTTER, got -6",
        ways=("post",),
    ),
    *cl_rows(
        "loadtl-negative",
        JOB.replace("LOADTL/1", "LOADTL/-1"),
        1,
        "urdfpost: bad.apt:3: expected a tool number for the 1st value of LOADTL, got '-1'",
    ),
    *cl_rows(
        "loadtl-fraction",
        JOB.replace("LOADTL/1", "LOADTL/1.5"),
        1,
        "urdfpost: bad.apt:3: expected a tool number for the 1st value of LOADTL, got '1.5'",
        ways=("post",),
    ),
    *cl_rows(
        "loadtl-empty",
        JOB.replace("LOADTL/1", "LOADTL/"),
        1,
        "urdfpost: bad.apt:3: expected a number for the 1st value of LOADTL, got ''",
        ways=("stream",),
    ),
    *cl_rows(
        "loadtl-length-nan",
        JOB.replace("LOADTL/1", "LOADTL/1,LENGTH,nan"),
        1,
        "urdfpost: bad.apt:3: expected a finite tool length for the 3rd value of LOADTL",
        ways=("post", "verify"),
    ),
    *cl_rows(
        "loadtl-1e30",
        JOB.replace("LOADTL/1", "LOADTL/1e30"),
        1,
        "urdfpost: bad.apt:3: tool number 1000000000000000019884624838656 is outside the tool "
        "numbers of heidenhain (1 to 32767)",
        ways=POSTS,
    ),
    *cl_rows(
        "loadtl-adjust-without-registers",
        JOB.replace("LOADTL/1", "LOADTL/3,ADJUST,7"),
        1,
        "urdfpost: bad.apt:3: length offset register 7 (ADJUST) for tool 3: heidenhain has no "
        "length offset register",
        ways=POSTS,
    ),
    *cl_rows(
        "no-fedrat-before-a-cut",
        "UNITS/MM\nLOADTL/1\nSPINDL/10000,CLW\nGOTO/0,0,10\nGOTO/10,0,10\n",
        1,
        "urdfpost: bad.apt:4: a cutting move with no feed (no FEDRAT before it); expected a "
        "FEDRAT record, or give the job a feed with --feed",
        ways=POSTS,
    ),
    *cl_rows(
        "no-spindle-before-a-cut",
        "UNITS/MM\nLOADTL/1\nFEDRAT/MMPM,1000\nGOTO/0,0,10\nGOTO/10,0,10\n",
        1,
        "urdfpost: bad.apt:4: a cutting move with the spindle off (no SPINDL before it)",
        ways=POSTS,
    ),
    # NX CLSF records
    *cl_rows(
        "nx-tldata-nan",
        JOB.replace("LOADTL/1\n", "LOADTL/1\nTLDATA/MILL,nan,0.5\n"),
        1,
        "urdfpost: bad.apt:4: expected tool dimensions >= 0 in TLDATA, got nan",
        ways=("post", "verify"),
    ),
    *cl_rows(
        "nx-msys-six-values",
        HEAD + "MSYS/0,0,0,1,0,0\nGOTO/0,0,10\n",
        1,
        "urdfpost: bad.apt:6: expected 9 values in MSYS, got 6",
        ways=("post",),
    ),
    *cl_rows(
        "nx-msys-parallel-axes",
        HEAD + "MSYS/0,0,0,1,0,0,1,0,0\nGOTO/0,0,10\n",
        1,
        "urdfpost: bad.apt:6: expected two independent axis vectors in MSYS, got (1, 0, 0) and "
        "(1, 0, 0)",
        ways=("stream",),
    ),
    *cl_rows(
        "nx-load-tool-letters",
        HEAD + "LOAD/TOOL,abc\nGOTO/0,0,10\n",
        1,
        "urdfpost: bad.apt:6: expected a number for the 2nd value of LOAD, got 'abc'",
        ways=("post", "verify"),
    ),
    *cl_rows(
        "nx-real-file-nan",
        nx_ballmill(_nan_in_goto),
        1,
        "urdfpost: bad.apt:{line}: expected a finite number for the 1st value of GOTO, got 'nan'",
        ways=("post", "stream"),
        options=("-m", "umc750", "--spindle", "5000"),
        at=("bad.apt", "GOTO/nan,"),
    ),
    *cl_rows(
        "nx-real-file-cut-short",
        nx_ballmill(_cut_in_goto),
        1,
        "urdfpost: bad.apt:{line}: expected 3 or 6 values in GOTO, got 1",
        ways=("post", "stream"),
        options=("-m", "umc750", "--spindle", "5000"),
        at=("bad.apt", LAST),
    ),
    *cl_rows(
        "nx-real-file-nan",
        nx_ballmill(_nan_in_goto),
        1,
        "urdfpost: bad.apt:{line}: expected a finite number for the 1st value of GOTO, got 'nan'",
        ways=("verify",),
        options=("-m", "umc750"),
        at=("bad.apt", "GOTO/nan,"),
    ),
    # Creo and CATIA layouts
    *cl_rows(
        "creo-nan",
        "UNITS / MM\nLOADTL / 1\nSPINDL / RPM, 1000.0, CLW\nFEDRAT / 500.0, MMPM\n"
        "GOTO / 0.0, 0.0, nan\n",
        1,
        "urdfpost: bad.apt:5: expected a finite number for the 3rd value of GOTO, got 'nan'",
    ),
    *cl_rows(
        "creo-continuation-short",
        "UNITS / MM\nLOADTL / 1\nSPINDL / RPM, 1000.0, CLW\nFEDRAT / 500.0, MMPM\n"
        "GOTO / 0.0, 0.0, 50.0, $\n        0.0, 0.0\n",
        1,
        "urdfpost: bad.apt:5: expected 3 or 6 values in GOTO, got 5",
        ways=("post", "stream"),
    ),
    *cl_rows(
        "catia-continuation-swallows-goto",
        "$$*CATIA0\n" + HEAD + "CUTTER/ 10.000000, 2.000000,$\nGOTO/0,0,10\n",
        1,
        f"urdfpost: bad.apt:7: {CUT}, got the motion record at line 8",
        ways=("post", "verify"),
    ),
    *cl_rows(
        "catia-continuation-swallows-loadtl",
        "$$*CATIA0\nPARTNO PART\nCUTTER/ 10.000000, 2.000000, 3.000000, 2.000000, 0.000000,$\n"
        "LOADTL/1,1,1\n" + JOB,
        1,
        "urdfpost: bad.apt:3: expected a number for the 6th value of CUTTER, got 'LOADTL/1'",
        ways=("stream",),
    ),
    # plain tables
    *cl_rows(
        "plain-letters",
        "0 0 10\n1 0 abc\n",
        1,
        "urdfpost: bad.apt:2: expected a number for the 3rd value, got 'abc'",
    ),
    *cl_rows(
        "plain-five-values",
        "0 0 10\n1 0 10 0 0\n",
        1,
        "urdfpost: bad.apt:2: expected 3 or 6 values (x y z [i j k]), got 5",
        ways=("post",),
    ),
    *cl_rows(
        "plain-inf",
        "0 0 10\n0 0 inf\n",
        1,
        "urdfpost: bad.apt:2: expected a finite number for the 3rd value, got 'inf'",
        ways=("verify",),
    ),
    *cl_rows(
        "wrong-format-given",
        JOB,
        1,
        "urdfpost: bad.apt:1: expected 3 or 6 values (x y z [i j k]), got 1",
        options=("--format", "plain"),
        ways=("post", "verify"),
    ),
    # encodings and not text at all
    *cl_rows("nul-byte", HEAD.encode() + b"GOTO/0,0,10\nGOTO/1,\x000,10\n", 1, f"bad.apt:7: {NUL}"),
    *cl_rows("utf-16-without-mark", JOB.encode("utf-16-le"), 1, f"urdfpost: bad.apt:1: {NUL}"),
    *cl_rows("random-bytes", random_bytes(22, 4096), 1, "urdfpost: bad.apt:"),
    *cl_rows(
        "random-text",
        random_text(5, 4000),
        1,
        "urdfpost: bad.apt:1: not a CL file: no motion record, and",
    ),
    # what cannot be read at all
    *cl_rows("missing", None, 1, "urdfpost: bad.apt: cannot read: No such file or directory"),
    *cl_rows(
        "a-folder",
        None,
        1,
        "urdfpost: bad.apt: cannot read: Is a directory",
        extra={"bad.apt/x.apt": JOB},
    ),
    # reached by nothing the machine can do
    *cl_rows(
        "tool-axis-unreachable",
        HEAD + "GOTO/0,0,10,0,0,-1\n",
        1,
        "urdfpost: bad.apt:6: tool axis (0, 0, -1) cannot be reached within the travel of machine "
        "dmu50 on any branch",
        ways=POSTS,
    ),
    *cl_rows(
        "point-outside-travel",
        HEAD + "GOTO/5000,0,10\n",
        1,
        "urdfpost: bad.apt:6: axis X would need 5018.000 mm, outside its travel",
        ways=POSTS,
    ),
    # read with warnings: the program is written, the warning names the line
    *cl_rows(
        "unknown-record",
        JOB.replace("FEDRAT/MMPM,1000\n", "FEDRAT/MMPM,1000\nFROBNICATE/1,2\n"),
        0,
        "urdfpost: warning: bad.apt:6: unknown record 'FROBNICATE/1,2' carried as a comment",
        ways=POSTS,
        contains={"out.h": "; FROBNICATE/1,2"},
    ),
    *cl_rows(
        "units-cm",
        JOB.replace("UNITS/MM", "UNITS/CM"),
        0,
        "urdfpost: warning: bad.apt:1: unknown record 'UNITS/CM' carried as a comment",
        ways=("post",),
    ),
    *cl_rows(
        "five-megabyte-line",
        JOB.replace("FEDRAT/MMPM,1000\n", "FEDRAT/MMPM,1000\n" + "X" * (5 << 20) + "\n"),
        0,
        "urdfpost: warning: bad.apt:6: unknown record 'XXXXXXXX",
        ways=POSTS,
        small=64 << 10,
    ),
    *cl_rows(
        "lines-after-fini",
        JOB + "GOTO/5,5,5\n",
        0,
        "urdfpost: warning: bad.apt:9: 1 non-blank line(s) after FINI ignored",
        ways=POSTS,
    ),
    *cl_rows(
        "axis-not-unit",
        HEAD + "GOTO/0,0,10,0,0,2\n",
        0,
        "urdfpost: warning: bad.apt:6: tool axis (0, 0, 2) has length 2; normalised",
        ways=("post",),
    ),
    *cl_rows(
        "circle-off-its-radius",
        HEAD + "GOTO/1,0,10\nCIRCLE/0,0,10,0,0,1,5\nGOTO/-1,0,10\n",
        0,
        "urdfpost: warning: bad.apt:7: arc end points are 4 mm off the CIRCLE radius 5 mm",
        ways=("stream",),
    ),
    *cl_rows(
        "units-overridden",
        JOB.replace("UNITS/MM", "UNITS/INCHES").replace("MMPM", "IPM"),
        0,
        "urdfpost: warning: bad.apt:1: CL file says inch at line 1; read as mm (--cl-units)",
        ways=("post",),
        options=("--cl-units", "mm"),
    ),
    *cl_rows(
        "empty-file",
        "",
        0,
        "urdfpost: warning: bad.apt: no motion records; the program has no moves",
        ways=POSTS,
    ),
    *cl_rows(
        "utf-8-byte-order-mark",
        b"\xef\xbb\xbf" + JOB.encode(),
        0,
        "wrote out.h (heidenhain, TCP, mm)",
        ways=("post",),
        stream="out",
        contains={"out.h": "TOOL CALL 1 Z S10000"},
    ),
    *cl_rows(
        "utf-16-with-mark",
        JOB.encode("utf-16"),
        0,
        "wrote out.h (heidenhain, TCP, mm)",
        ways=("stream",),
        stream="out",
        contains={"out.h": "TOOL CALL 1 Z S10000"},
    ),
]

CL_ROWS += [
    Row(
        "cl-nan-compare",
        ("compare", "bad.apt", "-m", "dmu50", "--strategies", "none,cone"),
        1,
        "urdfpost: bad.apt:6: expected a finite number for the 2nd value of GOTO, got 'nan'",
        {"bad.apt": HEAD + "GOTO/0,nan,10\n"},
    ),
    Row(
        "cl-unreadable-post",
        POST,
        1,
        "urdfpost: bad.apt: cannot read: Permission denied",
        {"bad.apt": JOB},
        modes={"bad.apt": 0o000},
        user="non-root",
    ),
]


# -- machine files ---------------------------------------------------------------------------


def machine(old: str = "", new: str = "", text: str | None = None) -> Callable[[], str]:
    """The shipped dmu50 file with ``old`` replaced by ``new`` once (or ``text`` itself)."""

    def make() -> str:
        if text is not None:
            return text
        base = DMU50.read_text()
        assert old in base, f"{old!r} is no longer in {DMU50}"
        return base.replace(old, new, 1)

    return make


M_POST = ("post", "job.apt", "-m", "m.urdf", "-q", "-o", "out.h")


def machine_row(
    name: str, urdf: Callable[[], str], message: str, needle: str | None, **more: Any
) -> Row:
    """A post with the machine file ``m.urdf``: exit 1, the message at ``needle``'s line."""
    at = ("m.urdf", needle) if needle else None
    row = Row(f"urdf-{name}", M_POST, 1, message, {"job.apt": JOB, "m.urdf": urdf}, at=at)
    return replace(row, **more)


B_AXIS = '<axis xyz="0 -1 0"/>'
X_LIMIT = '<limit lower="-0.3" upper="0.35" effort="12000" velocity="0.5"/>'
C_LIMIT = '<limit effort="1200" velocity="3.14"/>'
SETTINGS = '<urdfpost controller="heidenhain" units="mm" tool_length="0.1">'

URDF_ROWS = [
    machine_row(
        "axis-nan",
        machine(B_AXIS, '<axis xyz="nan -1 0"/>'),
        "urdfpost: m.urdf:{line}: joint 'B': <axis> xyz='nan -1 0': expected 3 finite numbers",
        'xyz="nan -1 0"',
    ),
    machine_row(
        "axis-zero",
        machine(B_AXIS, '<axis xyz="0 0 0"/>'),
        "urdfpost: m.urdf:{line}: joint 'B': zero axis vector (0.0, 0.0, 0.0): expected a "
        "direction",
        '<axis xyz="0 0 0"/>',
    ),
    machine_row(
        "limit-nan",
        machine(X_LIMIT, X_LIMIT.replace('lower="-0.3"', 'lower="nan"')),
        "urdfpost: m.urdf:{line}: joint 'X': <limit> lower='nan': expected a finite number",
        'lower="nan"',
    ),
    machine_row(
        "velocity-inf",
        machine(C_LIMIT, '<limit effort="1200" velocity="inf"/>'),
        "urdfpost: m.urdf:{line}: joint 'C': <limit> velocity='inf': expected a finite number",
        'velocity="inf"',
    ),
    machine_row(
        "limit-missing",
        machine(X_LIMIT, ""),
        "urdfpost: m.urdf:{line}: joint 'X' is prismatic: it needs <limit",
        '<joint name="X"',
    ),
    machine_row(
        "lower-above-upper",
        machine(X_LIMIT, X_LIMIT.replace('lower="-0.3"', 'lower="0.5"')),
        "urdfpost: m.urdf:{line}: joint 'X': lower limit 0.5 is above upper limit 0.35",
        '<joint name="X"',
    ),
    machine_row(
        "duplicate-link",
        machine('<link name="fixture">', '<link name="b_cradle"/>\n  <link name="fixture">'),
        "urdfpost: m.urdf:{line}: link 'b_cradle' defined twice (first at line",
        '<link name="b_cradle"/>',
    ),
    machine_row(
        "duplicate-joint",
        machine('<joint name="spindle_mount"', '<joint  name="fixture_mount"'),
        "urdfpost: m.urdf:{line}: joint 'fixture_mount' defined twice (first at line",
        '<joint  name="fixture_mount"',
    ),
    machine_row(
        "joint-lower-case",
        machine('<joint name="X"', '<joint name="x"'),
        "urdfpost: m.urdf:{line}: joint 'x': a moving joint must be named with its NC address",
        '<joint name="x"',
    ),
    machine_row(
        "entity-declaration",
        machine('<robot name="dmu50">', '<!DOCTYPE robot [<!ENTITY x "1">]>\n<robot name="dmu50">'),
        "urdfpost: m.urdf:{line}: <!ENTITY x>: entity declarations are not allowed",
        "<!ENTITY",
    ),
    machine_row(
        "external-entity",
        machine(
            '<robot name="dmu50">',
            '<!DOCTYPE robot [<!ENTITY h SYSTEM "file:///etc/hostname">]>\n<robot name="dmu50">',
        ),
        "urdfpost: m.urdf:{line}: <!ENTITY h>: entity declarations are not allowed",
        "<!ENTITY",
    ),
    machine_row(
        "controller-unknown",
        machine('controller="heidenhain"', 'controller="okuma"'),
        "urdfpost: m.urdf:{line}: <urdfpost controller='okuma'>: expected one of",
        "<urdfpost ",
    ),
    machine_row(
        "units-unknown",
        machine(SETTINGS, SETTINGS.replace('units="mm"', 'units="cm"')),
        "urdfpost: m.urdf:{line}: <urdfpost units='cm'>: expected mm or inch",
        "<urdfpost ",
    ),
    machine_row(
        "tool-length-negative",
        machine('tool_length="0.1"', 'tool_length="-1"'),
        "urdfpost: m.urdf:{line}: <urdfpost> tool_length='-1': expected a finite length >= 0 m",
        "<urdfpost ",
    ),
    machine_row(
        "strategy-unknown",
        machine('tool_length="0.1"', 'tool_length="0.1" strategy="magic"'),
        "urdfpost: m.urdf:{line}: <urdfpost strategy='magic'>: expected one of",
        "<urdfpost ",
    ),
    machine_row(
        "prefer-axis-missing",
        machine('<prefer axis="B" sign="+"/>', '<prefer axis="A" sign="+"/>'),
        "urdfpost: m.urdf:{line}: <prefer axis='A' sign='+'>: expected a rotary axis of the chain",
        "<prefer",
    ),
    machine_row(
        "home-outside-travel",
        machine('<home X="0"', '<home X="9"'),
        "urdfpost: m.urdf:{line}: <home X=9>: outside the travel of joint 'X'",
        "<home",
    ),
    machine_row(
        "mimic-on-the-chain",
        machine(C_LIMIT, C_LIMIT + '\n    <mimic joint="B" multiplier="1"/>'),
        "urdfpost: m.urdf:{line}: joint 'C' mimics joint 'B'",
        "<mimic",
    ),
    machine_row(
        "no-tool-link",
        machine('<link name="tool">', '<link name="tool0">'),
        "urdfpost: m.urdf",
        None,
    ),
    machine_row(
        "not-xml",
        machine(text="this is not a machine\n"),
        "urdfpost: m.urdf:1: not a URDF: broken XML",
        None,
    ),
    machine_row(
        "empty",
        machine(text=""),
        "urdfpost: m.urdf:1: not a URDF: broken XML",
        None,
    ),
    machine_row(
        "cut-short",
        lambda: DMU50.read_text()[: DMU50.read_text().index("<inertial>") + 6],
        "urdfpost: m.urdf:{line}: not a URDF: broken XML",
        "<inert",
    ),
    machine_row(
        # B may tilt 0.5 degrees only: the job's 15 degrees are out of reach, at its CL line
        "travel-too-short",
        machine('lower="-0.0872664626" upper="1.9198621772"', 'lower="0" upper="0.0087"'),
        "urdfpost: job.apt:6: tool axis",
        None,
    ),
    machine_row(
        "verify-axis-nan",
        machine(B_AXIS, '<axis xyz="nan -1 0"/>'),
        "urdfpost: m.urdf:{line}: joint 'B': <axis> xyz='nan -1 0'",
        'xyz="nan -1 0"',
        argv=("verify", "prog.h", "-m", "m.urdf", "--cl", "job.apt", "--report", "r.json"),
    ),
    machine_row(
        "show-duplicate-link",
        machine('<link name="fixture">', '<link name="b_cradle"/>\n  <link name="fixture">'),
        "urdfpost: m.urdf:{line}: link 'b_cradle' defined twice",
        '<link name="b_cradle"/>',
        argv=("machine", "show", "m.urdf"),
    ),
]
URDF_ROWS = [
    replace(r, files={**r.files, "prog.h": program}) if "verify" in r.id else r for r in URDF_ROWS
]
URDF_ROWS += [
    Row(
        "urdf-unknown-name",
        ("post", "job.apt", "-m", "nosuch", "-q", "-o", "out.h"),
        1,
        "urdfpost: nosuch: no such machine file or shipped machine; known machines: dmu50,",
        {"job.apt": JOB},
    ),
    Row(
        "urdf-missing-file",
        ("post", "job.apt", "-m", "gone.urdf", "-q", "-o", "out.h"),
        1,
        "urdfpost: gone.urdf: no such machine file",
        {"job.apt": JOB},
    ),
    Row(
        "urdf-unreadable",
        M_POST,
        1,
        "urdfpost: m.urdf: cannot read: Permission denied\n",
        {"job.apt": JOB, "m.urdf": machine()},
        modes={"m.urdf": 0o000},
        user="non-root",
    ),
]

# -- options ---------------------------------------------------------------------------------

P_JOB = ("post", "job.apt", "-m", "dmu50", "-q", "-o", "out.h")
V_JOB = ("verify", "prog.h", "-m", "dmu50", "--cl", "job.apt", "--report", "r.json")
C_JOB = ("compare", "job.apt", "-m", "dmu50")


def usage(name: str, argv: tuple[str, ...], message: str, xfail: str = "") -> Row:
    """A usage error: exit 2, the message of argparse or of the command line."""
    files: dict[str, Content] = {"job.apt": JOB, "prog.h": program}
    return Row(f"option-{name}", argv, 2, message, files, xfail=xfail)


def arg(command: str, option: str, what: str) -> str:
    return f"urdfpost {command}: error: argument {option}: {what}"


OPTION_ROWS = [
    usage(
        "tolerance-nan", (*P_JOB, "--tolerance", "nan"), arg("post", "--tolerance", "expected a")
    ),
    usage(
        "tolerance-negative",
        (*P_JOB, "--tolerance", "-5"),
        arg("post", "--tolerance", "expected a"),
    ),
    usage(
        "tolerance-zero",
        (*P_JOB, "--tolerance", "0"),
        arg("post", "--tolerance", "expected a positive number, got 0"),
    ),
    usage(
        "tolerance-letters",
        (*P_JOB, "--tolerance", "x"),
        arg("post", "--tolerance", "expected a number, got 'x'"),
    ),
    usage(
        "angle-tolerance-nan",
        (*P_JOB, "--angle-tolerance", "nan"),
        arg("post", "--angle-tolerance", "expected a"),
    ),
    usage(
        "angle-tolerance-negative",
        (*P_JOB, "--angle-tolerance", "-5"),
        arg("post", "--angle-tolerance", "expected a"),
    ),
    usage(
        "piece-points-1",
        (*P_JOB, "--piece-points", "1"),
        arg("post", "--piece-points", "expected 0 or at least 2, got 1"),
    ),
    usage(
        "piece-points-negative",
        (*P_JOB, "--piece-points", "-3"),
        arg("post", "--piece-points", "expected 0 or at least 2, got -3"),
    ),
    usage(
        "piece-points-letters",
        (*P_JOB, "--piece-points", "x"),
        arg("post", "--piece-points", "expected a whole number, got 'x'"),
    ),
    usage(
        "prefer-axis-the-machine-lacks",
        (*P_JOB, "--prefer", "A+"),
        "urdfpost: error: --prefer A: machine dmu50 has no rotary axis A; expected one of",
    ),
    usage(
        "prefer-no-sign",
        (*P_JOB, "--prefer", "B"),
        arg("post", "--prefer", "expected a preferred branch like B+ or C-, got 'B'"),
    ),
    usage(
        "controller-unknown",
        (*P_JOB, "-c", "okuma"),
        arg("post", "--controller/-c", "invalid choice: 'okuma'"),
    ),
    usage(
        "strategy-unknown",
        (*P_JOB, "--strategy", "magic"),
        "--strategy",
    ),
    usage(
        "setup-two-numbers",
        (*P_JOB, "--setup", "1,2"),
        arg("post", "--setup", "expected X,Y,Z or X,Y,Z,ROT"),
    ),
    usage(
        "setup-nan",
        (*P_JOB, "--setup=nan,0,0"),
        arg("post", "--setup", "expected X,Y,Z or X,Y,Z,ROT"),
    ),
    usage(
        "setup-minus-without-equals",
        (*P_JOB, "--setup", "-10,5,80"),
        arg("post", "--setup", "expected one argument"),
    ),
    usage(
        "units-unknown", (*P_JOB, "--units", "cm"), arg("post", "--units", "invalid choice: 'cm'")
    ),
    usage(
        "format-unknown",
        (*P_JOB, "--format", "iso"),
        arg("post", "--format", "invalid choice: 'iso'"),
    ),
    usage(
        "tool-length-negative",
        (*P_JOB, "--tool-length", "-1"),
        arg("post", "--tool-length", "expected a non-negative number, got '-1'"),
    ),
    usage(
        "feed-zero",
        (*P_JOB, "--feed", "0"),
        arg("post", "--feed", "expected a positive number, got 0"),
    ),
    usage(
        "tcp-and-no-tcp",
        (*P_JOB, "--tcp", "--no-tcp"),
        arg("post", "--no-tcp", "not allowed with argument --tcp"),
    ),
    usage(
        "machine-missing",
        ("post", "job.apt", "-o", "out.h"),
        "urdfpost post: error: the following arguments are required: --machine/-m",
    ),
    usage(
        "unknown-option", (*P_JOB, "--bogus"), "urdfpost: error: unrecognized arguments: --bogus"
    ),
    usage(
        "unknown-command",
        ("frobnicate",),
        "urdfpost: error: argument COMMAND: invalid choice: 'frobnicate'",
    ),
    usage(
        "work-offset-beyond-the-control",
        (*P_JOB, "--work-offset", "0"),
        "urdfpost: error: --work-offset",
    ),
    usage(
        "verify-tolerance-nan",
        (*V_JOB, "--tolerance", "nan"),
        arg("verify", "--tolerance", "expected a"),
    ),
    usage(
        "verify-tolerance-negative",
        (*V_JOB, "--tolerance", "-5"),
        arg("verify", "--tolerance", "expected a"),
    ),
    usage(
        "verify-angle-tolerance-nan",
        (*V_JOB, "--angle-tolerance", "nan"),
        arg("verify", "--angle-tolerance", "expected a"),
    ),
    usage(
        "verify-angle-tolerance-negative",
        (*V_JOB, "--angle-tolerance", "-5"),
        arg("verify", "--angle-tolerance", "expected a"),
    ),
    usage(
        "verify-piece-points-1",
        (*V_JOB, "--piece-points", "1"),
        arg("verify", "--piece-points", "expected 0 or at least 2, got 1"),
    ),
    usage(
        "verify-setup-letters",
        (*V_JOB, "--setup", "a,b,c"),
        arg("verify", "--setup", "expected X,Y,Z or X,Y,Z,ROT"),
    ),
    usage(
        "verify-controller-unknown",
        (*V_JOB, "-c", "okuma"),
        arg("verify", "--controller/-c", "invalid choice: 'okuma'"),
    ),
    usage(
        "verify-cl-missing",
        ("verify", "prog.h", "-m", "dmu50"),
        "urdfpost verify: error: the following arguments are required: --cl",
    ),
    usage(
        "compare-prefer-axis-the-machine-lacks",
        (*C_JOB, "--prefer", "A+"),
        "urdfpost: error: --prefer A: machine dmu50 has no rotary axis A",
    ),
    usage(
        "compare-strategies-unknown",
        (*C_JOB, "--strategies", "magic"),
        "urdfpost: error: --strategies: unknown magic",
    ),
    usage(
        "testpath-unknown",
        ("testpath", "nope"),
        "urdfpost: error: unknown test path 'nope'",
    ),
]

# -- output paths and faults -----------------------------------------------------------------

P_OUT = ("post", "job.apt", "-m", "dmu50", "-q", "-c", "heidenhain")


def output_rows(
    name: str,
    options: tuple[str, ...],
    code: int,
    message: str,
    files: Mapping[str, Content] | None = None,
    **more: Any,
) -> list[Row]:
    """An output case posted whole and in pieces; the folder holds :data:`JOB` and ``files``."""
    given = {"job.apt": JOB, **(files or {})}
    ways = (("post", ()), ("stream", ("--piece-points", "50")))
    return [
        replace(Row(f"out-{name}-{way}", (*P_OUT, *options, *extra), code, message, given), **more)
        for way, extra in ways
    ]


OUTPUT_ROWS = [
    *output_rows(
        "program-is-the-cl-file",
        ("-o", "job.apt"),
        1,
        "urdfpost: job.apt: the program (-o) would overwrite the CL file: expected another file",
    ),
    *output_rows(
        "report-is-the-program",
        ("-o", "out.h", "--report", "out.h"),
        1,
        "urdfpost: out.h: the report (--report) would overwrite the program (-o)",
        {"out.h": OLD},
    ),
    *output_rows(
        "report-is-the-cl-file",
        ("-o", "out.h", "--report", "job.apt"),
        1,
        "urdfpost: job.apt: the report (--report) would overwrite the CL file",
    ),
    *output_rows(
        "program-is-the-machine-file",
        ("-m", "m.urdf", "-o", "m.urdf"),
        1,
        "urdfpost: m.urdf: the program (-o) would overwrite the machine file",
        {"m.urdf": machine()},
    ),
    *output_rows(
        "program-links-to-the-cl-file",
        ("-o", "link.h"),
        1,
        "urdfpost: link.h: the program (-o) would overwrite the CL file",
        links={"link.h": "job.apt"},
    ),
    *output_rows(
        "program-hard-link-to-the-cl-file",
        ("-o", "hard.h"),
        1,
        "urdfpost: hard.h: the program (-o) would overwrite the CL file",
        links={"hard.h": "=job.apt"},
    ),
    *output_rows(
        "link-followed",
        ("-o", "link.h"),
        0,
        "wrote link.h (heidenhain, TCP, mm)",
        {"old.h": OLD},
        links={"link.h": "old.h"},
        after=("old.h",),
        stream="out",
        contains={"old.h": "TOOL CALL 1 Z S10000"},
    ),
    *output_rows(
        "link-into-no-folder",
        ("-o", "link.h"),
        1,
        "urdfpost: link.h: cannot write: no such folder",
        links={"link.h": "gone/x.h"},
    ),
    *output_rows(
        "folder-missing",
        ("-o", "gone/out.h"),
        1,
        "urdfpost: gone/out.h: cannot write: no such folder",
    ),
    *output_rows(
        "report-folder-missing",
        ("-o", "out.h", "--report", "gone/out.json"),
        1,
        "urdfpost: gone/out.json: cannot write: no such folder",
        {"out.h": OLD},
    ),
    *output_rows(
        "program-is-a-folder",
        ("-o", "out.h"),
        1,
        "urdfpost: out.h: cannot write: it is a folder",
        {"out.h/x": OLD},
    ),
    *output_rows(
        "program-on-a-full-disk",
        ("-o", "/dev/full", "--report", "out.json"),
        1,
        "urdfpost: /dev/full: cannot write: No space left on device",
        {"out.json": OLD_REPORT},
    ),
    *output_rows(
        "report-on-a-full-disk",
        ("-o", "out.h", "--report", "/dev/full"),
        1,
        "urdfpost: /dev/full: cannot write: No space left on device",
        {"out.h": OLD},
    ),
    *output_rows(
        "read-only-file",
        ("-o", "out.h"),
        1,
        "urdfpost: out.h: cannot write: permission denied (a read-only file)",
        {"out.h": OLD},
        modes={"out.h": 0o444},
        user="non-root",
    ),
    *output_rows(
        "read-only-file-as-root",  # written, as cp writes it
        ("-o", "out.h"),
        0,
        "wrote out.h (heidenhain, TCP, mm)",
        {"out.h": OLD},
        modes={"out.h": 0o444},
        user="root",
        after=("out.h",),
        stream="out",
    ),
    *output_rows(
        "read-only-folder",
        ("-o", "ro/out.h"),
        1,
        "urdfpost: ro/out.h: cannot write: permission denied in",
        {"ro/old.h": OLD},
        modes={"ro": 0o555},
        user="non-root",
    ),
    Row(
        "out-extension-unknown-post",
        ("post", "job.apt", "-m", "dmu50", "-q", "-o", "out.txt"),
        1,
        "urdfpost: cannot tell the control from the extension '.txt' of 'out.txt'",
        {"job.apt": JOB},
    ),
    Row(
        "out-beyond-tolerance-keeps-the-old-program-post",
        ("post", "job.apt", "-m", "dmu50", "-q", "-o", "out.h", "--no-tcp", "--tolerance", "1e-7"),
        1,
        "urdfpost: job.apt: the program misses its tolerance against the CL data, nothing written",
        {"job.apt": JOB, "out.h": OLD},
    ),
    Row(
        "out-compare-report-is-the-cl-file",
        (*C_JOB, "--strategies", "none", "--report", "job.apt"),
        1,
        "urdfpost: job.apt: the report (--report) would overwrite the CL file",
        {"job.apt": JOB},
    ),
    Row(
        "out-compare-plot-folder-missing",
        (*C_JOB, "--strategies", "none", "--plot", "gone/c.png"),
        1,
        "urdfpost: gone/c.png: cannot write: no such folder",
        {"job.apt": JOB},
    ),
    Row(
        "out-testpath-on-a-full-disk",
        ("testpath", "sweep-1", "-o", "/dev/full"),
        1,
        "urdfpost: /dev/full: cannot write: No space left on device",
    ),
    Row(
        "out-testpath-into-a-folder",
        ("testpath", "sweep-1", "-o", "d"),
        1,
        "urdfpost: d: cannot write: it is a folder",
        {"d/x": OLD},
    ),
]

# -- verify: the program, its report, its figures ----------------------------------------------

V = ("verify", "prog.h", "-m", "dmu50", "--cl", "job.apt", "--angle-tolerance", "2")


def edited(old: str, new: str) -> Callable[[], str]:
    def make() -> str:
        text = program()
        assert old in text, old
        return text.replace(old, new, 1)

    return make


VERIFY_ROWS = [
    Row(
        "verify-report-is-the-program",
        (*V, "--report", "prog.h"),
        1,
        "urdfpost: prog.h: the report (--report) would overwrite the program: expected another "
        "file",
        {"job.apt": JOB, "prog.h": program},
    ),
    Row(
        "verify-report-is-the-cl-file",
        (*V, "--report", "job.apt"),
        1,
        "urdfpost: job.apt: the report (--report) would overwrite the CL file",
        {"job.apt": JOB, "prog.h": program},
    ),
    Row(
        "verify-report-on-a-full-disk",
        (*V, "--report", "/dev/full"),
        1,
        "urdfpost: /dev/full: cannot write: No space left on device",
        {"job.apt": JOB, "prog.h": program},
    ),
    Row(
        "verify-program-missing",
        (*V, "--report", "r.json"),
        1,
        "urdfpost: prog.h: cannot read: No such file or directory\n",
        {"job.apt": JOB},
    ),
    Row(
        "verify-program-malformed-number",
        (*V, "--report", "r.json"),
        1,
        "urdfpost: prog.h:{line}: malformed number Xabc+5.000; expected e.g. X12.345",
        {"job.apt": JOB, "prog.h": edited("L X+5.000", "L Xabc+5.000")},
        at=("prog.h", "Xabc"),
    ),
    Row(
        "verify-program-extension-unknown",
        ("verify", "prog.txt", "-m", "dmu50", "--cl", "job.apt"),
        1,
        "urdfpost: cannot tell the control from the extension '.txt' of 'prog.txt'",
        {"job.apt": JOB, "prog.txt": program},
    ),
    Row(
        "verify-program-empty",
        (*V, "--report", "r.json"),
        1,
        "prog.h: verification BEYOND TOLERANCE: 0/2 CL points reached, 0 blocks",
        {"job.apt": JOB, "prog.h": ""},
        after=("r.json",),
        stream="out",
        contains={"r.json": '"verified": false'},
    ),
    Row(
        "verify-program-of-another-job",
        (*V, "--report", "r.json"),
        1,
        "prog.h: verification BEYOND TOLERANCE: 1/2 CL points reached",
        {"job.apt": JOB.replace("GOTO/20,0,10", "GOTO/25,0,10"), "prog.h": program},
        after=("r.json",),
        stream="out",
    ),
    Row(
        "verify-feed-changed",
        V,
        1,
        "prog.h:{line}: feed F1100 where the CL has F1000 (CL line 6)",
        {"job.apt": JOB, "prog.h": edited("F1000", "F1100")},
        at=("prog.h", "F1100"),
        stream="out",
    ),
    Row(
        "verify-spindle-changed",
        V,
        1,
        "prog.h: process DIFFERS from the CL data: spindle",
        {"job.apt": JOB, "prog.h": edited("S10000", "S9000")},
        stream="out",
    ),
    # issue 23: a damaged process is refused with its line, as damaged geometry is
    Row(
        "verify-spindle-start-removed",
        V,
        1,
        "prog.h:{line}: spindle off where the CL has S10000 CW (CL line 6)",
        {"job.apt": JOB, "prog.h": edited(" M3\n", " M9\n")},
        at=("prog.h", "F1000"),
        stream="out",
    ),
    Row(
        "verify-tool-changed",
        V,
        1,
        "prog.h:{line}: tool T7 where the CL loads tool 1 (CL line 3)",
        {"job.apt": JOB, "prog.h": edited("TOOL CALL 1 ", "TOOL CALL 7 ")},
        at=("prog.h", "TOOL CALL 7"),
        stream="out",
    ),
    Row(
        "verify-end-pgm-removed",
        V,
        1,
        "prog.h:{line}: no program end (M30 and END PGM) after this line",
        {"job.apt": JOB, "prog.h": lambda: program().rsplit("\n", 2)[0] + "\n"},
        at=("prog.h", "M30"),
        stream="out",
    ),
    Row(
        "verify-point-moved",
        (*V, "--report", "r.json"),
        1,
        "prog.h: verification BEYOND TOLERANCE: ",
        {"job.apt": JOB, "prog.h": edited("L X+10.000", "L X+10.000 Y+0.500")},
        after=("r.json",),
        stream="out",
    ),
]

ROWS = [*CL_ROWS, *URDF_ROWS, *OPTION_ROWS, *OUTPUT_ROWS, *VERIFY_ROWS]


def _param(row: Row) -> object:
    marks = []
    if row.xfail:
        marks.append(pytest.mark.xfail(strict=True, reason=row.xfail))
    if row.user == "non-root" and ROOT_USER:
        marks.append(pytest.mark.skip(reason="as root every file can be read and written"))
    if row.user == "root" and not ROOT_USER:
        marks.append(pytest.mark.skip(reason="the case of the root user"))
    return pytest.param(row, id=row.id, marks=marks)


# -- running a row ---------------------------------------------------------------------------


def snapshot(*folders: Path) -> dict[str, tuple[str, object]]:
    """Every file, link and folder under ``folders``: kind and content (bytes and mode, link
    target)."""
    found: dict[str, tuple[str, object]] = {}
    for top in folders:
        for path in sorted(_walk(top)):
            key = f"{top.name}/{path.relative_to(top)}"
            if path.is_symlink():
                found[key] = ("link", os.readlink(path))
            elif path.is_dir():
                found[key] = ("folder", stat.S_IMODE(path.lstat().st_mode))
            else:
                mode = stat.S_IMODE(path.lstat().st_mode)
                found[key] = ("file", (path.read_bytes() if mode & 0o400 else b"", mode))
    return found


def _walk(top: Path) -> Iterator[Path]:
    for entry in top.iterdir():
        yield entry
        if entry.is_dir() and not entry.is_symlink():
            yield from _walk(entry)


def make_files(folder: Path, row: Row) -> None:
    for name, content in row.files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        data = content() if callable(content) else content
        if isinstance(data, str):
            path.write_text(data, encoding="utf-8")
        else:
            path.write_bytes(data)
    for name, target in row.links.items():
        if target.startswith("="):  # a hard link
            os.link(folder / target[1:], folder / name)
        else:
            os.symlink(target, folder / name)
    for name, mode in row.modes.items():
        os.chmod(folder / name, mode)


def line_of(path: Path, needle: str) -> int:
    text = path.read_text(encoding="utf-8", errors="replace")
    if needle == LAST:
        return len(text.splitlines())
    for number, line in enumerate(text.splitlines(), 1):
        if needle in line:
            return number
    raise AssertionError(f"{needle!r} not in {path}")


@pytest.fixture
def case(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[Path, Path]]:
    """The row's folder (the working folder of the run) and a temporary folder of its own
    (where a streamed post to a device stages its program)."""
    folder, temp = tmp_path / "case", tmp_path / "temp"
    folder.mkdir()
    temp.mkdir()
    monkeypatch.chdir(folder)
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    yield folder, temp
    for path in [folder, *_walk(folder)]:  # let pytest remove what a row made read-only
        if not path.is_symlink():
            path.chmod(0o700 if path.is_dir() else 0o600)


def run(row: Row, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """Run the row's command line in-process: exit code, stdout, stderr."""
    capsys.readouterr()
    try:
        code = main(list(row.argv))
    except SystemExit as e:  # argparse
        code = e.code if isinstance(e.code, int) else 1
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("row", [_param(r) for r in ROWS])
def test_bad_input(row: Row, case: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    folder, temp = case
    make_files(folder, row)
    before = snapshot(folder, temp)
    code, out, err = run(row, capsys)
    after = snapshot(folder, temp)
    shown = out if row.stream == "out" else err
    message = row.message
    if row.at is not None:
        message = message.replace("{line}", str(line_of(folder / row.at[0], row.at[1])))

    assert "Traceback" not in err, err
    assert (code, message in shown) == (row.code, True), (
        f"exit {code}\nstdout: {out}\nstderr: {err}"
    )
    if row.code == 1 and row.stream == "err":
        assert err.splitlines()[-1].startswith("urdfpost: "), err
    if row.code == 2:
        assert "urdfpost" in err and "error:" in err, err
    # on disk: the outputs named, nothing else
    changed = sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k))
    assert changed == sorted(f"case/{name}" for name in row.after), changed
    for name in row.after:
        assert after[f"case/{name}"][0] == "file", name
    for name, fragment in row.contains.items():
        assert fragment in (folder / name).read_text(), name
    if row.small is not None:
        assert len(err) <= row.small, len(err)
        for name in row.after:
            assert (folder / name).stat().st_size <= row.small, name


def test_the_table_covers_every_class() -> None:
    """About a hundred and more rows, in every class, each id once."""
    ids = [r.id for r in ROWS]
    assert len(ids) == len(set(ids)), [i for i in ids if ids.count(i) > 1]
    classes = {i.split("-", 1)[0] for i in ids}
    assert classes == {"cl", "urdf", "option", "out", "verify"}
    assert len(ids) >= 100
    for row in ROWS:  # the message names the file, and its line where the input has lines
        if row.code and row.stream == "err" and not row.id.startswith("option"):
            assert re.search(r"[\w./]+(:\d+|:\{line\})?:", row.message), row.id


# -- docs/errors.md ----------------------------------------------------------------------------

DOCS = ROOT / "docs" / "errors.md"
#: An example of docs/errors.md: the row it comes from, then its text block.
EXAMPLE = re.compile(r"<!-- row: (\S+) -->\n```text\n(.*?)```", re.S)


def _examples() -> list[tuple[str, str]]:
    return EXAMPLE.findall(DOCS.read_text()) if DOCS.is_file() else []


def _pattern(line: str) -> re.Pattern[str]:
    """An example line as a pattern: ``...`` stands for anything, a machine file's line
    numbers for any (the shipped machine files change)."""
    parts = [re.escape(part) for part in line.split("...")]
    text = ".*".join(parts)
    return re.compile(re.sub(r"(\\.urdf):\d+:", r"\1:\\d+:", text))


@pytest.mark.parametrize(("row_id", "block"), _examples(), ids=[e[0] for e in _examples()])
def test_the_examples_of_the_docs_are_what_the_command_line_prints(
    row_id: str, block: str, case: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    rows = {r.id: r for r in ROWS}
    assert row_id in rows, f"docs/errors.md cites no row of this table: {row_id}"
    row = rows[row_id]
    if row.user == "non-root" and ROOT_USER:
        pytest.skip("as root every file can be read and written")
    make_files(case[0], row)
    code, out, err = run(row, capsys)
    assert code == row.code
    printed = (out + err).splitlines()
    for line in block.splitlines():
        pattern = _pattern(line)
        assert any(pattern.fullmatch(p) for p in printed), f"{line!r} not in\n{out}{err}"


def test_the_docs_cite_examples() -> None:
    if not DOCS.is_file():
        pytest.skip("docs/errors.md not written yet")
    assert len(_examples()) >= 10

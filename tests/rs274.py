"""LinuxCNC's standalone interpreter ``rs274`` as a test oracle (issue 17).

Debian's ``linuxcnc-uspace`` package ships ``rs274``: LinuxCNC's own G-code interpreter with a
canon layer that prints every canonical call (``STRAIGHT_FEED(...)``, ``SET_FEED_RATE(...)``,
``START_SPINDLE_CLOCKWISE(...)``, ``CHANGE_TOOL(...)``, ...) instead of moving a machine.
:func:`run_rs274` runs a program through it, in a directory of its own, and returns the calls;
an interpreter error is raised as :class:`Rs274Error` with the message and the program line.

Import it from a test as ``from rs274 import run_rs274`` (pytest puts ``tests/`` on
``sys.path``). Without ``rs274`` on the PATH the test is skipped, except in CI (``CI=true``),
which installs the package: there a missing interpreter is a failure.

The set-up written next to the program:

- an INI file whose ``[RS274NGC]`` section remaps ``M428`` / ``M429`` (LinuxCNC's switchable
  kinematics: TCP on / identity kinematics) the way the sim configs
  ``sim/axis/vismach/5axis/table-rotary-tilting/xyzac-trt.ini`` and ``xyzbc-trt.ini`` of
  LinuxCNC's sample configs do (``REMAP = M428 modalgroup=10 ngc=428remap``, the subroutines on
  ``SUBROUTINE_PATH``). The sample subroutines set a HAL pin (``M68``) and read it back through
  ``#<_hal[motion.switchkins-type]>``, which the standalone interpreter has not got; here they
  are empty but for a ``(debug,...)`` line, which the interpreter passes on as a
  ``MESSAGE(...)`` call, so a test sees where TCP goes on and off (:attr:`Rs274Result.TCP_ON`).
- a tool table. The standalone canon's external length unit is the inch (its
  ``GET_EXTERNAL_LENGTH_UNITS`` returns 1/25.4), so the table's lengths are written in inches
  and come back as ``USE_TOOL_LENGTH_OFFSET`` in the program's units.
- a parameter (``.var``) file that starts the interpreter in G55, with a G55 offset that is not
  zero and a G54 offset that is: a program that does not select G54 itself is seen (the
  ``SET_G5X_OFFSET(2, ...)`` of the start stays in effect and its positions are shifted).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import pytest

#: Axis letters of the coordinates of ``STRAIGHT_FEED`` / ``STRAIGHT_TRAVERSE``, in order (the
#: Debian build prints X Y Z A B C, no U V W).
AXES = ("X", "Y", "Z", "A", "B", "C")

#: The G55 offset the interpreter starts with, mm (G54 is zero).
START_G55_MM = (100.0, 50.0, -20.0)

_INCH = 25.4
_TIMEOUT = 120.0

_REMAP_SUB = """\
; {code} remapped as LinuxCNC's xyzac-trt / xyzbc-trt sim configs do, but empty: the standalone
; interpreter has no HAL pin to switch the kinematics with. The debug line becomes a MESSAGE call.
o<{name}>sub
(debug,{message})
o<{name}>endsub
M2
"""

_INI = """\
# urdfpost tests: LinuxCNC's standalone interpreter rs274 on a posted program
[RS274NGC]
SUBROUTINE_PATH = {subs}
REMAP = M428  modalgroup=10  ngc=428remap
REMAP = M429  modalgroup=10  ngc=429remap
"""

_CALL = re.compile(r"^\s*\d+\s+N\S*\s+([A-Z_0-9]+)\((.*)\)\s*$")


def _truthy(value: str | None) -> bool:
    return (value or "").strip().lower() in ("1", "true", "yes")


def rs274_path() -> str:
    """Path of ``rs274``; skips the test when it is not installed, fails when ``CI=true``."""
    path = shutil.which("rs274")
    if path is None:
        message = (
            "LinuxCNC's standalone interpreter rs274 is not installed "
            "(Debian: apt-get install linuxcnc-uspace)"
        )
        if _truthy(os.environ.get("CI")):
            pytest.fail(message + "; CI installs it, so it must be there", pytrace=False)
        pytest.skip(message)
    return path


@dataclass(frozen=True)
class Call:
    """One canonical call: its name and its arguments (numbers as floats, words as text)."""

    name: str
    args: tuple[float | str, ...]
    #: The canonical output line it was read from.
    text: str = field(default="", compare=False)

    def number(self, k: int) -> float:
        value = self.args[k]
        if not isinstance(value, float):
            raise TypeError(f"argument {k} of {self.text!r} is not a number")
        return value


@dataclass(frozen=True)
class Rs274Result:
    """What the interpreter made of a program."""

    #: The canonical calls, in order.
    calls: tuple[Call, ...]
    #: The canonical output as printed.
    canon: str
    stdout: str
    stderr: str
    returncode: int

    #: The ``MESSAGE`` texts of the remapped M428 / M429 (see the module docstring).
    TCP_ON = "urdfpost M428 TCP on"
    TCP_OFF = "urdfpost M429 TCP off"

    def named(self, *names: str) -> list[Call]:
        return [c for c in self.calls if c.name in names]

    def index(self, name: str, start: int = 0) -> int:
        """Index of the first call ``name`` at or after ``start``; -1 when none."""
        for k in range(start, len(self.calls)):
            if self.calls[k].name == name:
                return k
        return -1

    @property
    def ended(self) -> bool:
        """The program ran to its end (``M2`` / ``M30``: ``PROGRAM_END``)."""
        return any(c.name == "PROGRAM_END" for c in self.calls)


class Rs274Error(AssertionError):
    """The interpreter stopped on an error (an AssertionError, so a test reports it plainly)."""

    def __init__(self, message: str, line: str, line_numbers: tuple[int, ...], output: str):
        self.message = message
        self.line = line
        self.line_numbers = line_numbers
        where = (
            "program line " + ", ".join(str(n) for n in line_numbers)
            if line_numbers
            else "program line"
        )
        text = f"rs274: {message}"
        if line:
            text += f" ({where}: {line!r})"
        super().__init__(text + "\n" + output)


def _parse_args(raw: str) -> tuple[float | str, ...]:
    raw = raw.strip()
    if not raw:
        return ()
    if raw.startswith('"'):  # COMMENT("..."), MESSAGE("..."): one text argument
        return (raw[1:-1] if raw.endswith('"') else raw[1:],)
    out: list[float | str] = []
    for word in re.split(r"[,\s]+", raw):
        if not word:
            continue
        try:
            out.append(float(word))
        except ValueError:
            out.append(word)
    return tuple(out)


def parse_canon(text: str) -> tuple[Call, ...]:
    """The canonical calls of rs274's output, e.g. ``   38 N..... STRAIGHT_FEED(0.0000, ...)``."""
    calls = []
    for line in text.splitlines():
        m = _CALL.match(line)
        if m is None:
            if line.strip():
                raise ValueError(f"not a canonical call: {line!r}")
            continue
        calls.append(Call(m.group(1), _parse_args(m.group(2)), line.strip()))
    return tuple(calls)


def _tool_table(tools: Mapping[int, float], units: str) -> str:
    """Tool table lines; lengths (program units) in the standalone canon's inches."""
    per_inch = 1.0 if units == "inch" else 1.0 / _INCH
    return "".join(
        f"T{n} P{n} Z{length * per_inch:.9f} D0 ;urdfpost test tool\n"
        for n, length in sorted(tools.items())
    )


def _parameters() -> str:
    """A parameter file: G55 active (5220 = 2) with a non-zero offset (inches), G54 zero."""
    g55 = [v / _INCH for v in START_G55_MM]
    rows = [(5220, 2.0)] + [(5221 + k, 0.0) for k in range(9)]
    rows += [(5241 + k, g55[k] if k < 3 else 0.0) for k in range(9)]
    return "".join(f"{n}\t{v:.9f}\n" for n, v in rows)


def _error_lines(stderr: str, stdout: str) -> list[str]:
    """What the interpreter said beyond its ``executing`` banner."""
    lines = [ln.rstrip() for ln in (stderr + "\n" + stdout).splitlines()]
    return [ln for ln in lines if ln.strip() and ln.strip() != "executing"]


def run_rs274(
    program_text: str,
    tools: Mapping[int, float],
    tmp_path: Path,
    *,
    units: str = "mm",
    name: str = "prog.ngc",
    wrapped: tuple[str, ...] = (),
) -> Rs274Result:
    """Run ``program_text`` through LinuxCNC's standalone interpreter.

    Parameters
    ----------
    program_text : str
        The program (``.ngc`` text).
    tools : mapping
        Tool number to tool length, program units (0 for machine-coordinate programs).
    tmp_path : Path
        A directory for the program, the INI, remap, tool table and parameter files and the
        output (the interpreter also writes its parameter file back there).
    units : str
        "mm" or "inch": the program's units, for the tool table.
    wrapped : tuple of str
        Rotary axes the INI makes wrapped (``[AXIS_C] WRAPPED_ROTARY = 1``, a rollover axis):
        the interpreter reads their absolute values in (-360, 360), the sign the direction.

    Returns
    -------
    Rs274Result

    Raises
    ------
    Rs274Error
        The interpreter reported an error (non-zero exit, or error text on stdout / stderr),
        with the message and the program line it names.
    """
    exe = rs274_path()
    tmp_path.mkdir(parents=True, exist_ok=True)
    subs = tmp_path / "remap_subs"
    subs.mkdir(exist_ok=True)
    for code, message in (("428", Rs274Result.TCP_ON), ("429", Rs274Result.TCP_OFF)):
        (subs / f"{code}remap.ngc").write_text(
            _REMAP_SUB.format(code="M" + code, name=code + "remap", message=message)
        )
    ini = tmp_path / "rs274.ini"
    ini.write_text(
        _INI.format(subs=subs) + "".join(f"[AXIS_{a}]\nWRAPPED_ROTARY = 1\n" for a in wrapped)
    )
    table = tmp_path / "tool.tbl"
    table.write_text(_tool_table(tools, units))
    var = tmp_path / "rs274.var"
    var.write_text(_parameters())
    program = tmp_path / name
    program.write_text(program_text)
    out = tmp_path / (program.stem + ".canon")
    out.unlink(missing_ok=True)
    argv = [exe, "-g", "-t", str(table), "-v", str(var), "-i", str(ini), str(program), str(out)]
    try:
        done = subprocess.run(
            argv,
            cwd=tmp_path,
            stdin=subprocess.DEVNULL,
            capture_output=True,
            text=True,
            timeout=_TIMEOUT,
            check=False,
        )
    except subprocess.TimeoutExpired as exc:
        raise AssertionError(f"rs274 did not finish within {_TIMEOUT:.0f} s: {argv}") from exc
    canon = out.read_text() if out.exists() else ""
    said = _error_lines(done.stderr, done.stdout)
    if done.returncode != 0 or said:
        message = said[0] if said else f"exit code {done.returncode}"
        # rs274 prints the message, then the offending block as written
        line = said[1].strip() if len(said) > 1 else ""
        numbers = tuple(
            k
            for k, text in enumerate(program_text.splitlines(), 1)
            if line and text.strip() == line
        )
        tail = "\n".join(canon.splitlines()[-5:])
        raise Rs274Error(
            message,
            line,
            numbers,
            f"exit code {done.returncode}; stderr:\n{done.stderr}\nlast canonical calls:\n{tail}",
        )
    return Rs274Result(parse_canon(canon), canon, done.stdout, done.stderr, done.returncode)

"""Files written through a temporary file and renamed into place.

A temporary file is hidden beside the file it becomes and named after it and after the process
that made it: ``.NAME.PID-XXXXXXXX.part`` (a streamed program) or ``.tmp`` (any other output).
A process killed outright (``SIGKILL``, a power cut) cannot remove its own; the next one that
writes ``NAME`` in that folder removes those whose process is gone (:func:`temp_file`).
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import stat
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from urdfpost import _stops
from urdfpost.errors import UrdfpostError

log = logging.getLogger(__name__)

_TEMP = re.compile(r"\.(?P<base>.+)\.(?P<pid>[0-9]+)-[a-z0-9_]{8}\.(?:part|tmp)")
"""The name of a temporary file of :func:`temp_file` (``tempfile`` draws the eight characters
from ``[a-z0-9_]``)."""


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists (a zombie that its parent has not reaped does too)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process (EPERM)
        return True
    return True


def remove_stale_temps(folder: str | os.PathLike[str], name: str) -> list[Path]:
    """Remove the temporary files of output ``name`` in ``folder`` left by processes that no
    longer run (killed before they could remove them), and return them.

    A file of a process that still runs is another post of the same output at work: it stays.
    Only POSIX systems can tell (elsewhere nothing is removed: a signal 0 is no question there).
    """
    if os.name != "posix":
        return []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return []
    removed = []
    for entry in entries:
        found = _TEMP.fullmatch(entry.name)
        if found is None or found["base"] != name or _alive(int(found["pid"])):
            continue
        path = Path(entry.path)
        try:
            path.unlink()
        except OSError as e:  # removed meanwhile by another post, or not ours to remove
            log.debug("stale temporary file %s not removed: %s", path, e)
            continue
        log.info("removed %s, left by process %s", path, found["pid"])
        removed.append(path)
    return removed


def temp_file(
    target: str | os.PathLike[str],
    suffix: str = ".part",
    folder: str | os.PathLike[str] | None = None,
) -> tuple[int, Path]:
    """Create a temporary file for ``target``, hidden in its folder (or in ``folder``), after
    removing the stale ones of ``target`` there (:func:`remove_stale_temps`).

    The temporary file of a temporary file of this module is one more of the same output
    (``.x.h.PID-XXXXXXXX.part`` again, not ``..x.h.PID-XXXXXXXX.part.PID-YYYYYYYY.part``), so
    that the next post of ``x.h`` finds it.

    Parameters
    ----------
    target : path
        The file the temporary file becomes.
    suffix : str
        ``".part"`` or ``".tmp"``.
    folder : path, optional
        Where the temporary file goes; default the folder of ``target``.

    Returns
    -------
    fd : int
        The open file descriptor (mode 0600, as :func:`tempfile.mkstemp` makes it).
    path : Path

    Raises
    ------
    OSError
        The file cannot be created.
    """
    target = Path(target)
    where = Path(folder) if folder is not None else target.parent
    found = _TEMP.fullmatch(target.name)
    name = found["base"] if found is not None else target.name
    remove_stale_temps(where, name)
    fd, path = tempfile.mkstemp(prefix=f".{name}.{os.getpid()}-", suffix=suffix, dir=where)
    return fd, Path(path)


def give_mode(tmp: str | os.PathLike[str], target: str | os.PathLike[str]) -> None:
    """Give a temporary file the permissions ``target`` will need once it is renamed there.

    Those of the file it replaces; for a new file, what creating it would give (read and
    write for all, less the process umask). A temporary file is made private (0600), which a
    program file handed to a DNC server or a colleague must not stay.
    """
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except FileNotFoundError:
        mask = os.umask(0)  # (read by setting it: there is no other portable way)
        os.umask(mask)
        mode = 0o666 & ~mask
    os.chmod(tmp, mode)


@dataclass(frozen=True)
class Target:
    """Where an output file goes.

    Attributes
    ----------
    named : Path
        The path as given.
    real : Path
        The file the bytes go to: symbolic links followed (the link stays a link, its target
        gets the new text).
    regular : bool
        Whether ``real`` is a regular file or does not exist yet: written through a temporary
        file beside it and renamed into place. False for a character device or a FIFO
        (``/dev/null``, ``/dev/stdout``, a named pipe): written directly, never replaced.
    """

    named: Path
    real: Path
    regular: bool


def output_target(path: str | os.PathLike[str]) -> Target:
    """Check that ``path`` can be written, as ``cp`` checks it, and say how.

    Raises
    ------
    UrdfpostError
        ``PATH: cannot write: REASON`` for a missing folder, a folder, a file or folder that
        this user may not write (as root, a read-only file is written, as ``cp`` does), or
        another kind of file (a socket).
    """
    named = Path(path)
    real = Path(os.path.realpath(named))

    def refuse(reason: str) -> UrdfpostError:
        return UrdfpostError(f"{named}: cannot write: {reason}")

    try:
        st = os.stat(real)
    except FileNotFoundError:
        folder = real.parent
        if not folder.is_dir():
            raise refuse(f"no such folder {folder}") from None
        if not os.access(folder, os.W_OK | os.X_OK):
            raise refuse(f"permission denied in {folder}") from None
        return Target(named, real, True)
    except OSError as e:
        raise refuse(e.strerror or str(e)) from e
    if stat.S_ISDIR(st.st_mode):
        raise refuse("it is a folder")
    if not (stat.S_ISREG(st.st_mode) or stat.S_ISCHR(st.st_mode) or stat.S_ISFIFO(st.st_mode)):
        raise refuse("not a regular file, a device or a FIFO")
    if not os.access(real, os.W_OK):
        raise refuse("permission denied (a read-only file)")
    regular = stat.S_ISREG(st.st_mode)
    if regular and not os.access(real.parent, os.W_OK | os.X_OK):
        raise refuse(f"permission denied in {real.parent} (the file is replaced through a copy)")
    return Target(named, real, regular)


def _identity(path: Path) -> tuple[object, ...]:
    """What makes two paths the same file: device and inode when it exists, else the path."""
    real = os.path.realpath(path)
    try:
        st = os.stat(real)
    except OSError:
        return ("path", real)
    return ("inode", st.st_dev, st.st_ino)


def check_distinct(
    outputs: Mapping[str, str | os.PathLike[str]], inputs: Mapping[str, str | os.PathLike[str]]
) -> None:
    """Refuse an output that is one of the inputs or another output (links and hard links
    followed), before anything is written.

    Parameters
    ----------
    outputs, inputs : mapping of str to path
        What each file is for (``"the program (-o)"``, ``"the CL file"``) and its path.
        Character devices (``/dev/null``) may be named more than once.

    Raises
    ------
    UrdfpostError
        Naming both roles.
    """
    given = {_identity(Path(path)): role for role, path in inputs.items()}
    seen = dict(given)
    for role, path in outputs.items():
        key = _identity(Path(path))
        if key in seen and (key in given or not _is_device(Path(path))):
            raise UrdfpostError(
                f"{path}: {role} would overwrite {seen[key]}: expected another file"
            )
        seen[key] = role


def _is_device(path: Path) -> bool:
    try:
        return stat.S_ISCHR(os.stat(path).st_mode)
    except OSError:
        return False


def write_texts(
    files: Mapping[Path, str],
    inputs: Mapping[str, str | os.PathLike[str]] | None = None,
    roles: Mapping[Path, str] | None = None,
    staged: Mapping[Path, Path] | None = None,
) -> None:
    """Write all of ``files`` or none of them.

    Every target is checked first (:func:`output_target`, :func:`check_distinct` against the
    ``inputs``); then each regular file is written to a temporary file beside it, devices and
    FIFOs are written directly, and only when all that succeeded are the regular files renamed
    into place. Nothing is left behind when any of them cannot be written.

    Parameters
    ----------
    files : mapping of path to str
        Text of each output.
    inputs : mapping of str to path, optional
        The job's input files by role, which no output may be.
    roles : mapping of path to str, optional
        What each output is, for messages (default ``"the output"``).
    staged : mapping of path to path, optional
        Outputs already written in full to a temporary file (a streamed program): moved into
        place with the others (or copied, onto a device), the temporary file removed.

    Raises
    ------
    UrdfpostError
        Naming the file that could not be written.
    """
    staged = dict(staged or {})
    names = {Path(p): (roles or {}).get(p, "the output") for p in [*files, *staged]}
    targets = {path: output_target(path) for path in names}
    outputs: dict[str, Path] = {}
    for p, role in names.items():
        outputs[role if role not in outputs else f"{role} {p}"] = p
    check_distinct(outputs, inputs or {})
    temps: dict[Path, Path] = {Path(p): Path(t) for p, t in staged.items()}
    made: list[Path] = []
    try:
        for path, text in files.items():
            target = targets[Path(path)]
            if not target.regular:
                continue
            try:
                fd, name = temp_file(target.real, ".tmp")
            except OSError as e:
                raise UrdfpostError(f"{path}: cannot write: {e.strerror or e}") from e
            made.append(name)
            temps[Path(path)] = name
            try:
                with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as f:
                    f.write(text)
            except OSError as e:
                raise UrdfpostError(f"{path}: cannot write: {e.strerror or e}") from e
        _stops.check()  # a stop lost on the way: nothing is replaced
        # devices and FIFOs next (what cannot be taken back, before any file is replaced)
        for path, tmp in temps.items():
            if not targets[path].regular:
                try:
                    with open(tmp, "rb") as src, open(targets[path].real, "wb") as dst:
                        shutil.copyfileobj(src, dst)
                except OSError as e:
                    raise UrdfpostError(f"{path}: cannot write: {e.strerror or e}") from e
        for path, text in files.items():
            target = targets[Path(path)]
            if not target.regular:
                try:
                    with open(target.real, "w", encoding="utf-8", newline="\n") as f:
                        f.write(text)
                except OSError as e:
                    raise UrdfpostError(f"{path}: cannot write: {e.strerror or e}") from e
        # then every regular file moves into place
        for path, tmp in temps.items():
            target = targets[path]
            if target.regular:
                try:
                    give_mode(tmp, target.real)
                    os.replace(tmp, target.real)
                except OSError as e:
                    raise UrdfpostError(f"{path}: cannot write: {e.strerror or e}") from e
    finally:
        for tmp in [*made, *temps.values()]:
            tmp.unlink(missing_ok=True)

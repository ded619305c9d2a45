"""Files written through a temporary file and renamed into place."""

from __future__ import annotations

import os
import stat


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

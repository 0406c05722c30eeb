"""Writing files a person keeps (checkpoints, exported policies, results): atomic, with the usual permissions.

A temp file beside the target is renamed over it, so a crash never leaves half a file. The temp file is created by
the writer itself (not by ``tempfile``, which makes 0600 files), so the result gets the mode the umask gives every
other file (0644 under the usual umask 022), and its name never ends up inside the file.
"""

from __future__ import annotations

import json
import os
import uuid
from collections.abc import Callable


def atomic_write(path: str, write: Callable[[str], object]) -> str:
    """Call ``write(tmp_path)`` for a fresh path in ``path``'s folder, then rename it to ``path``. Returns ``path``."""
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    tmp_path = os.path.join(directory, f"{os.path.basename(path)}.{uuid.uuid4().hex[:8]}.tmp")
    try:
        write(tmp_path)
        os.replace(tmp_path, path)
    finally:
        if os.path.exists(tmp_path):
            os.remove(tmp_path)
    return path


def write_json(path: str, data) -> str:
    """``data`` as indented JSON at ``path``, written atomically: an interrupted write never leaves half a file."""

    def write(tmp_path: str) -> None:
        with open(tmp_path, "w") as f:
            json.dump(data, f, indent=2)

    return atomic_write(path, write)


def recorded_path(path: str) -> str:
    """``path`` as a results file records it: relative to the working directory when the file lies under it (results
    committed beside the policy they measure stay true in every checkout), absolute otherwise."""
    absolute = os.path.abspath(path)
    relative = os.path.relpath(absolute)
    return absolute if relative == os.pardir or relative.startswith(os.pardir + os.sep) else relative

"""Pictures of motion: a self-contained HTML player (3-D skeletons, play/pause/scrub, no network)
and an animated GIF, written by the library.

    from troupe import viewer, motion
    viewer.write({"actor": actor, "reactor": reactor}, html="pair.html", gif="pair.gif",
                 fmt=motion.JointsFormat(units="m", up="y", fps=30), title="troupe")
"""

from __future__ import annotations

import ctypes
import os

from numpy.typing import ArrayLike

from . import _check, _lib, _ptr
from .motion import JointsFormat, _people

__all__ = ["write"]


def write(people: ArrayLike | dict[str, ArrayLike], html: str | os.PathLike | None = None,
          gif: str | os.PathLike | None = None,
          fmt: JointsFormat | None = None, title: str = "troupe") -> None:
    """Writes the HTML player and/or the GIF of `people` ({name: positions [T, 22, 3]} in the
    world `fmt` describes; its fps is the playback rate). Both or neither are written."""
    if html is None and gif is None:
        raise ValueError("give html, gif or both")
    stacked, names, c = _people(people, fmt)
    _check(_lib.troupe_viewer_write(os.fsencode(html) if html is not None else None,
                                    os.fsencode(gif) if gif is not None else None, _ptr(stacked), stacked.shape[0],
                                    stacked.shape[1], ctypes.byref(c), names, title.encode()))

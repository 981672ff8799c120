"""Load a checkpoint of the official code into our module definitions, strictly.

Our modules carry the official module and parameter names (each family's `reference.py`), so
an official state dict loads without renaming. What this module adds is the strictness a user
needs when a checkpoint does not match the configuration it is exported with: every missing,
unexpected or mis-shaped tensor is named in one error, instead of a silent partial load.

A few tensors of the official checkpoints are deliberately not used at inference; each exporter
lists them with the reason (`IGNORED`), and they are reported, never silently dropped. Tensors
that repeat another module's (UMF's flow schedulers hold the denoisers they drive) are checked
equal to what they repeat, then skipped.
"""

from __future__ import annotations

from pathlib import Path

import torch
import torch.nn as nn


class CheckpointError(ValueError):
    """The checkpoint does not match the model configuration."""


def read_checkpoint(path: Path):
    """A checkpoint file's contents, loaded with `weights_only=True`: a checkpoint cannot run
    code."""
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # noqa: BLE001 - torch raises many types for a bad file
        raise CheckpointError(f"{path}: not a readable torch checkpoint ({type(e).__name__}: {e})") from e


def read_state_dict(path: Path) -> dict[str, torch.Tensor]:
    """The tensors of a checkpoint file: a Lightning checkpoint (`state_dict` inside) or a
    plain state dict."""
    obj = read_checkpoint(path)
    if isinstance(obj, dict) and isinstance(obj.get("state_dict"), dict):
        obj = obj["state_dict"]
    if not isinstance(obj, dict) or not all(isinstance(v, torch.Tensor) for v in obj.values()):
        raise CheckpointError(f"{path}: expected a state dict (name -> tensor) or a Lightning checkpoint")
    return obj


def load_strict(
    model: nn.Module, state: dict[str, torch.Tensor], ignored: dict[str, str], aliases: dict[str, str] | None = None
) -> list[str]:
    """Copy `state` into `model`. Names starting with a prefix of `ignored` (prefix -> reason)
    are skipped; names starting with a prefix of `aliases` (alias -> the prefix it repeats, as
    when a module holds another module's network) are skipped once they equal the tensor they
    repeat. Everything else must match the model's state dict exactly, name and shape.
    Returns the skipped names; raises CheckpointError naming every problem."""
    want = model.state_dict()
    aliases = aliases or {}
    skip = tuple(ignored) + tuple(aliases)
    skipped = sorted(k for k in state if k not in want and k.startswith(skip))
    missing = sorted(k for k in want if k not in state)
    extra = sorted(k for k in state if k not in want and k not in skipped)
    shapes = sorted(
        f"{k}: checkpoint {tuple(state[k].shape)}, model {tuple(want[k].shape)}"
        for k in want
        if k in state and tuple(state[k].shape) != tuple(want[k].shape)
    )
    differing = []
    for k in skipped:
        for alias, target in aliases.items():
            if k.startswith(alias):
                original = target + k[len(alias) :]
                same = original in state and torch.equal(state[original], state[k])
                if not same:
                    differing.append(f"{k} (should repeat {original})")
    problems = []
    for title, names in (
        ("missing", missing),
        ("unexpected", extra),
        ("mis-shaped", shapes),
        ("inconsistent repeated", differing),
    ):
        if names:
            problems.append(f"{len(names)} {title} parameter(s):\n  " + "\n  ".join(names))
    if problems:
        raise CheckpointError("checkpoint does not match the configuration:\n" + "\n".join(problems))
    bad = sorted(k for k in want if k in state and not torch.isfinite(state[k].float()).all())
    if bad:
        raise CheckpointError("non-finite values in:\n  " + "\n  ".join(bad))
    model.load_state_dict({k: state[k].to(want[k].dtype) for k in want}, strict=True)
    return skipped


def load_checkpoint(
    model: nn.Module, path: Path, ignored: dict[str, str], aliases: dict[str, str] | None = None
) -> None:
    """`load_strict` from a checkpoint file, then report what was skipped, prefix by prefix."""
    skipped = load_strict(model, read_state_dict(path), ignored, aliases)
    reasons = dict(ignored) | {a: f"repeats {t}* (checked equal)" for a, t in (aliases or {}).items()}
    for prefix, why in reasons.items():
        n = sum(k.startswith(prefix) for k in skipped)
        if n:
            print(f"ignored {n} tensor(s) {prefix}*: {why}")

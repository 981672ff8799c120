"""The configuration an official ARMFlow checkpoint carries, read against the exporter's preset.

`ARMFlowModule.__init__` calls `save_hyperparameters(OmegaConf.to_container(cfg))`, so a
Lightning checkpoint holds the whole training configuration (`cfg/armflow/armflow.yaml`) under
`hyper_parameters`: `vae.*`, `mf.*`, `dataset.*`. Tensor shapes alone do not pin a model: a
checkpoint trained with 4 attention heads has the same shapes as one with 8, and the scale
factor, step count and guidance scale are not tensors at all. So the exporter takes every field
below from the checkpoint where it has one (the preset is only the default, and each field that
differs from it is reported), and refuses, naming each field, a configuration that selects a
code path troupe does not implement.

A checkpoint without `hyper_parameters` (a bare state dict) exports with the preset, and the
exporter says so.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from troupe_onnx.armflow.reference import ArmflowConfig, clip_tokens
from troupe_onnx.shared.checkpoint import CheckpointError, read_checkpoint

# CLIP text towers by `clip_version`: (layers, heads). Their width is `text_encoder.d_cond`.
# "troupe-tiny" is the test checkpoints' own, which no official configuration names.
CLIP_TOWERS = {"ViT-L/14@336px": (12, 12), "ViT-L/14": (12, 12), "ViT-B/32": (12, 8), "troupe-tiny": (1, 2)}

# Fields copied from the checkpoint: configuration path -> ArmflowConfig field.
COPIED = {
    "mf.nhead": "heads",
    "mf.nlayer_ar": "layers",
    "mf.nlayer_mlp": "mlp_blocks",
    "mf.d_model": "latent_dim",
    "mf.text_encoder.d_cond": "cond_dim",
    "mf.scale_factor": "latent_scale",
    "mf.num_steps": "steps",
    "vae.d_input": "frame_dim",
    "vae.depth": "vae.depth",
    "vae.width": "vae.decoder_width",
    "dataset.max_motion_length": "clip_frames",
}

# Settings selecting code paths troupe implements only one way: path -> the value it needs.
REQUIRED = {
    "mf.text_encoder.is_intergen_clip": "intergen",  # CLIP tower + clipTrans + clipln, EOT token
    "mf.text_encoder.is_dmodel": False,  # no Linear after the text encoder
    "mf.is_text_cond": True,
    "mf.is_skip": True,  # the skip-connected context encoder (3 in, 1 mid, 3 out)
    "vae.down_t": 2,  # 4 frames per token
    "vae.stride_t": 2,
    "vae.dilation_growth_rate": 3,
    "vae.norm": "GN",
}


def read_hyper_parameters(path: Path) -> dict | None:
    """The checkpoint's `hyper_parameters`, or None when it stores none."""
    obj = read_checkpoint(path)
    hp = obj.get("hyper_parameters") if isinstance(obj, dict) else None
    return hp if isinstance(hp, dict) else None


def _get(tree: dict, path: str):
    node = tree
    for key in path.split("."):
        if not isinstance(node, dict) or key not in node:
            return _MISSING
        node = node[key]
    return node


_MISSING = object()


def _field(cfg, path: str):
    for part in path.split("."):
        cfg = getattr(cfg, part)
    return cfg


def _replace(cfg, path: str, value):
    head, _, rest = path.partition(".")
    if not rest:
        return dataclasses.replace(cfg, **{head: value})
    return dataclasses.replace(cfg, **{head: _replace(getattr(cfg, head), rest, value)})


def config_from_checkpoint(hp: dict, preset: ArmflowConfig) -> tuple[ArmflowConfig, list[str]]:
    """The preset with every field the checkpoint's configuration sets; returns it and one line
    per field that differs from the preset. Raises CheckpointError naming every setting troupe
    cannot follow."""
    problems = [
        f"{path} = {_get(hp, path)!r} (troupe implements {want!r})"
        for path, want in REQUIRED.items()
        if _get(hp, path) is not _MISSING and _get(hp, path) != want
    ]
    version = _get(hp, "mf.text_encoder.clip_version")
    if version is not _MISSING and version not in CLIP_TOWERS:
        problems.append(f"mf.text_encoder.clip_version = {version!r} (known: {', '.join(CLIP_TOWERS)})")
    if problems:
        raise CheckpointError("the checkpoint's configuration selects what troupe does not implement:\n  " + "\n  ".join(problems))
    cfg, notes = preset, []

    def take(path: str, field: str, value, given=_MISSING):
        """Sets `field` to `value`, derived from the checkpoint's `path` (whose own value,
        `given`, the note quotes when it differs from the derived one)."""
        nonlocal cfg
        if value is _MISSING:
            return
        old = _field(cfg, field)
        value = type(old)(value)
        if value != old:
            shown = value if given is _MISSING else given
            derived = "" if given is _MISSING or given == value else f", so {field} = {value!r}"
            notes.append(f"{path} = {shown!r} from the checkpoint{derived} (the preset has {field} = {old!r})")
            cfg = _replace(cfg, field, value)

    for path, field in COPIED.items():
        take(path, field, _get(hp, path))
    double = _get(hp, "vae.is_double")
    if double is not _MISSING:
        take("vae.is_double", "vae.encoder_width", cfg.vae.decoder_width * (2 if double else 1), double)
    if version is not _MISSING:
        layers, heads = CLIP_TOWERS[version]
        take("mf.text_encoder.clip_version", "clip_layers", layers, version)
        take("mf.text_encoder.clip_version", "clip_heads", heads, version)
    # The official test loop forces guidance off when training baked it in (cfg_omega > 1).
    omega, scale = _get(hp, "mf.siloss.cfg_omega"), _get(hp, "mf.cfg_scale")
    if scale is not _MISSING:
        baked = omega is not _MISSING and float(omega) > 1
        take("mf.cfg_scale (1 when mf.siloss.cfg_omega > 1)", "cfg_scale", 1.0 if baked else float(scale), scale)
    return cfg, notes


def hyper_parameters(cfg: ArmflowConfig, cfg_omega: float = 1.8) -> dict:
    """The `hyper_parameters` the official module would save for `cfg` (the test checkpoints'),
    in the layout of `cfg/armflow/armflow.yaml`."""
    clip = next(v for v, tower in CLIP_TOWERS.items() if tower == (cfg.clip_layers, cfg.clip_heads))
    return {
        "vae": {
            "latent_size": clip_tokens(cfg), "d_input": cfg.frame_dim, "output_emb_width": cfg.latent_dim, "down_t": 2,
            "stride_t": 2, "width": cfg.vae.decoder_width, "depth": cfg.vae.depth, "dilation_growth_rate": 3,
            "norm": "GN", "is_double": cfg.vae.encoder_width == 2 * cfg.vae.decoder_width,
        },
        "mf": {
            "name": "armflow", "nlayer_ar": cfg.layers, "nlayer_mlp": cfg.mlp_blocks, "d_model": cfg.latent_dim,
            "d_ffn": 1024, "nhead": cfg.heads, "scale_factor": cfg.latent_scale, "clip_dim": cfg.cond_dim,
            "cfg_scale": cfg.cfg_scale, "num_steps": cfg.steps, "is_text_cond": True, "is_skip": True,
            "text_encoder": {"clip_version": clip, "d_cond": cfg.cond_dim, "is_intergen_clip": "intergen", "is_dmodel": False},
            "siloss": {"cfg_omega": cfg_omega},
        },
        "dataset": {"max_motion_length": cfg.clip_frames},
    }

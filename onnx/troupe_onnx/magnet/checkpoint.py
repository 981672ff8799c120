"""MAGNet's released checkpoints, read strictly (`docs/spec/magnet.md` §8), and written in the
same layout from random weights (the tiny bundle's "official" checkpoint).

Layout, relative to a root directory (the official repository's working directory):

    checkpoints/dfot/<run>/v0/config.yaml                         the DFoT training config
    checkpoints/dfot/<run>/v0/checkpoints_<step>/model.safetensors  diffuser.model.* + _vqvae.*
    checkpoints/vqvae/<run>/v0/config.yaml                        the VQ-VAE training config
    checkpoints/vqvae/<run>/v0/checkpoints_<step>/model.safetensors
    data/<run>_mean_std.npz                                       mean, std [361]

The configuration is read from the checkpoint's own `config.yaml` and checked against the
preset; the DFoT file's `_vqvae.*` copy is the VQ-VAE that runs (the official loader lets it
override the VQ-VAE file, §8.2). Every missing, unexpected, mis-shaped or non-finite tensor is
named.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path, PurePosixPath, PureWindowsPath

import numpy as np

from troupe_onnx.magnet.motion import STATS_DIM, Stats
from troupe_onnx.magnet.layout import FRAMES_PER_TOKEN
from troupe_onnx.magnet.networks import Magnet, MagnetConfig, VqConfig
from troupe_onnx.shared.checkpoint import CheckpointError, load_strict

# VQ-VAE settings the exported architecture implements; anything else is refused by name.
FIXED_VQ = {"down_t": 2, "stride_t": 2, "dilation_growth_rate": 3, "norm": "LN", "activation": "gelu", "is_add_last_ln": True}
FIXED_DFOT = {"diffusion_objective": "pred_x0"}


def _yaml():
    try:
        import yaml
    except ModuleNotFoundError as e:
        raise CheckpointError("reading a MAGNet config.yaml needs PyYAML: pip install pyyaml") from e
    return yaml


def _safetensors():
    try:
        import safetensors.torch as st
    except ModuleNotFoundError as e:
        raise CheckpointError("reading a MAGNet checkpoint needs safetensors: pip install safetensors") from e
    return st


# The path classes whose pickled form omegaconf 2.3/2.4 writes for `Path` fields.
_PATH_TAGS = {"PosixPath": PurePosixPath, "PurePosixPath": PurePosixPath, "Path": PurePosixPath,
              "WindowsPath": PureWindowsPath, "PureWindowsPath": PureWindowsPath}


def _config_loader(yaml):
    """PyYAML's safe loader, plus the tags omegaconf 2.3/2.4 writes for `Path` fields
    (`!!python/object/apply:pathlib.PosixPath` over the path's parts), read as plain path
    strings. Nothing is imported or constructed: any other Python tag stays refused."""

    class ConfigLoader(yaml.SafeLoader):
        pass

    def path(loader, suffix, node):
        kind = _PATH_TAGS.get(suffix)
        if isinstance(node, yaml.MappingNode):  # the long form: {args: [parts...]}
            fields = loader.construct_mapping(node, deep=True)
            parts = fields.get("args") if set(fields) == {"args"} else None
        elif isinstance(node, yaml.SequenceNode):
            parts = loader.construct_sequence(node, deep=True)
        else:
            parts = [loader.construct_scalar(node)]
        if kind is None or not isinstance(parts, list) or not all(isinstance(p, str) for p in parts):
            raise yaml.constructor.ConstructorError(
                None, None, f"python/object/apply:pathlib.{suffix} is not a path of string parts", node.start_mark)
        return str(kind(*parts))

    ConfigLoader.add_multi_constructor("tag:yaml.org,2002:python/object/apply:pathlib.", path)
    return ConfigLoader


def read_config(path: Path) -> dict:
    if not path.is_file():
        raise CheckpointError(f"{path}: no config.yaml beside the checkpoint (the run's v0/ folder holds it)")
    try:
        yaml = _yaml()
        data = yaml.load(path.read_text(), Loader=_config_loader(yaml))  # noqa: S506 - a safe loader
    except Exception as e:  # noqa: BLE001 - the YAML parser raises many kinds
        raise CheckpointError(f"{path}: not readable YAML ({type(e).__name__}: {e})") from e
    if not isinstance(data, dict) or not isinstance(data.get("model_cfg"), dict):
        raise CheckpointError(f"{path}: no `model_cfg` mapping")
    return data


def _field(cfg: dict, key: str, path: Path):
    if key not in cfg:
        raise CheckpointError(f"{path}: model_cfg has no `{key}`")
    return cfg[key]


def config_from_yaml(dfot: dict, vq: dict, dfot_path: Path, vq_path: Path, embed_dim: int) -> MagnetConfig:
    """The architecture the two configs describe; fields the export cannot honour are refused."""
    m, v = dfot["model_cfg"], vq["model_cfg"]
    for key, want in FIXED_VQ.items():
        got = _field(v, key, vq_path)
        if got != want:
            raise CheckpointError(f"{vq_path}: model_cfg.{key} is {got!r}; this exporter implements {want!r}")
    for key, want in FIXED_DFOT.items():
        got = _field(m, key, dfot_path)
        if got != want:
            raise CheckpointError(f"{dfot_path}: model_cfg.{key} is {got!r}; MAGNet's released models use {want!r}")
    frames = int(_field(m, "sequence_length", dfot_path))
    if frames % FRAMES_PER_TOKEN:
        raise CheckpointError(f"{dfot_path}: sequence_length {frames} is not a multiple of {FRAMES_PER_TOKEN}")
    if int(_field(m, "d_latent", dfot_path)) != int(_field(v, "d_latent", vq_path)):
        raise CheckpointError(f"{dfot_path}: d_latent differs from the VQ-VAE's ({vq_path})")
    return MagnetConfig(
        persons=int(_field(m, "person_num", dfot_path)),
        window=frames // FRAMES_PER_TOKEN,
        layers=int(_field(m, "layers", dfot_path)),
        heads=int(_field(m, "num_heads", dfot_path)),
        d_feedforward=int(_field(m, "d_feedforward", dfot_path)),
        embed_dim=embed_dim,
        person_embedding_mode=str(_field(m, "person_embedding_mode", dfot_path)),
        max_t=int(_field(m, "max_t", dfot_path)),
        vq=VqConfig(
            d_latent=int(_field(v, "d_latent", vq_path)), d_hidden=int(_field(v, "d_hidden", vq_path)),
            code_nb=int(_field(v, "code_nb", vq_path)), depth=int(_field(v, "depth", vq_path)),
            r_max=float(v.get("r_max", 45.0)),
        ),
    )


def _embed_dim(state: dict, dfot: dict, path: Path) -> int:
    """The level/person embedding width, which no config field holds (256 in the official code):
    read from `init_mlp.0.weight`'s input width (§11 A9)."""
    m = dfot["model_cfg"]
    key = "diffuser.model.init_mlp.0.weight"
    if key not in state:
        raise CheckpointError(f"{path}: no {key}")
    persons, latent = int(_field(m, "person_num", path)), int(_field(m, "d_latent", path))
    extra = state[key].shape[1] - (latent + 36 * persons)
    concat = _field(m, "person_embedding_mode", path) == "concat"
    if extra <= 0 or (concat and extra % 2):
        raise CheckpointError(f"{path}: {key} has input width {state[key].shape[1]}, which fits no embedding width")
    return extra // 2 if concat else extra


def _resolve(name: str, root: Path, what: str) -> Path:
    path = Path(name)
    for candidate in (path, root / path):
        if candidate.exists():
            return candidate
    raise CheckpointError(f"{what} `{name}` found neither as given nor under {root}")


def load_release(checkpoint_dir: Path, preset: MagnetConfig | None = None) -> tuple[Magnet, Stats, dict]:
    """A released DFoT checkpoint folder (`.../v0/checkpoints_<step>`) -> (model, statistics,
    the DFoT config). With `preset`, the checkpoint's architecture must equal it."""
    st = _safetensors()
    checkpoint_dir = Path(checkpoint_dir)
    weights = checkpoint_dir / "model.safetensors"
    if not weights.is_file():
        raise CheckpointError(f"{checkpoint_dir}: no model.safetensors (give the checkpoints_<step> folder)")
    root = checkpoint_dir.parents[4] if len(checkpoint_dir.parents) > 4 else checkpoint_dir.parent
    dfot_path = checkpoint_dir.parent / "config.yaml"
    dfot = read_config(dfot_path)
    vq_dir = _resolve(str(dfot.get("vqvae_model_path", "")), root, "vqvae_model_path") if dfot.get("vqvae_model_path") else None
    if vq_dir is None:
        raise CheckpointError(f"{dfot_path}: no `vqvae_model_path`")
    vq_path = vq_dir.parent / "config.yaml"
    vq = read_config(vq_path)
    try:
        state = st.load_file(str(weights))
    except Exception as e:  # noqa: BLE001
        raise CheckpointError(f"{weights}: not a readable safetensors file ({type(e).__name__}: {e})") from e
    cfg = config_from_yaml(dfot, vq, dfot_path, vq_path, _embed_dim(state, dfot, weights))
    if preset is not None and cfg != preset:
        diffs = [f"{f.name}: checkpoint {getattr(cfg, f.name)!r}, preset {getattr(preset, f.name)!r}"
                 for f in dataclasses.fields(cfg) if getattr(cfg, f.name) != getattr(preset, f.name)]
        raise CheckpointError(f"{checkpoint_dir}: the checkpoint is not the preset's architecture:\n  " + "\n  ".join(diffs))
    model = Magnet(cfg)
    load_strict(model, state, ignored={})
    stats_name = dfot.get("mean_std_path") or vq.get("mean_std_path")
    if not stats_name:
        raise CheckpointError(f"{dfot_path}: no `mean_std_path` (nor in {vq_path})")
    stats = read_stats(_resolve(str(stats_name), root, "mean_std_path"))
    return model.eval(), stats, dfot


def read_stats(path: Path) -> Stats:
    try:
        with np.load(path) as data:
            mean, std = data["mean"], data["std"]
    except Exception as e:  # noqa: BLE001
        raise CheckpointError(f"{path}: not an npz with `mean` and `std` ({type(e).__name__}: {e})") from e
    for name, a in (("mean", mean), ("std", std)):
        if a.shape != (STATS_DIM,):
            raise CheckpointError(f"{path}: `{name}` has shape {a.shape}, expected ({STATS_DIM},)")
        if not np.isfinite(a).all():
            raise CheckpointError(f"{path}: `{name}` holds non-finite values")
    if (std <= 0).any():
        raise CheckpointError(f"{path}: `std` has entries <= 0")
    return Stats(mean.astype(np.float32), std.astype(np.float32))


def write_release(model: Magnet, stats: Stats, root: Path, run: str, dfot_step: int = 500000, vq_step: int = 100000) -> Path:
    """Saves `model` and `stats` in the released layout under `root`; returns the DFoT
    checkpoint folder."""
    yaml, st = _yaml(), _safetensors()
    cfg = model.cfg
    dfot_dir = root / "checkpoints" / "dfot" / run / "v0" / f"checkpoints_{dfot_step}"
    vq_dir = root / "checkpoints" / "vqvae" / run / "v0" / f"checkpoints_{vq_step}"
    stats_path = root / "data" / f"{run}_mean_std.npz"
    for d in (dfot_dir, vq_dir, stats_path.parent):
        d.mkdir(parents=True, exist_ok=True)
    vq_cfg = {"d_latent": cfg.vq.d_latent, "d_hidden": cfg.vq.d_hidden, "code_nb": cfg.vq.code_nb, "depth": cfg.vq.depth,
              **FIXED_VQ, "is_set_r": True, "r_max": cfg.vq.r_max, "ema_mu": 0.99}
    rel = lambda p: str(p.relative_to(root))  # noqa: E731 - paths as the official working directory sees them
    (vq_dir.parent / "config.yaml").write_text(yaml.safe_dump({"model_cfg": vq_cfg, "mean_std_path": rel(stats_path)}, sort_keys=False))
    dfot_cfg = {
        "person_num": cfg.persons, "sequence_length": cfg.window * FRAMES_PER_TOKEN, "person_embedding_mode": cfg.person_embedding_mode,
        "layers": cfg.layers, "d_latent": cfg.vq.d_latent, "d_feedforward": cfg.d_feedforward, "num_heads": cfg.heads,
        **FIXED_DFOT, "max_t": cfg.max_t, "vqvae_cfg": vq_cfg,
    }
    (dfot_dir.parent / "config.yaml").write_text(yaml.safe_dump(
        {"model_cfg": dfot_cfg, "vqvae_model_path": rel(vq_dir), "mean_std_path": rel(stats_path)}, sort_keys=False))
    state = {k: v.contiguous() for k, v in model.state_dict().items()}
    st.save_file(state, str(dfot_dir / "model.safetensors"))
    # The VQ-VAE's own file: the same tensors without the `_vqvae.` prefix (§8.2).
    st.save_file({k[len("_vqvae."):]: v for k, v in state.items() if k.startswith("_vqvae.")}, str(vq_dir / "model.safetensors"))
    np.savez(stats_path, mean=stats.mean, std=stats.std)
    return dfot_dir

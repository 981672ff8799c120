"""MAGNet's torch side (needs torch, onnx, onnxruntime, safetensors, pyyaml; run by
`cargo test --test export_reproducible` where they are installed, or
`python3 -m pytest onnx/tests/test_magnet_torch.py`):

- the hand-written decoder gradients (the guidance graphs) equal autograd's;
- a checkpoint in the released layout loads strictly: every missing, unexpected, mis-shaped or
  non-finite tensor is named, the configuration comes from its own config.yaml and must match the
  preset, what the exporter cannot follow is refused by field;
- a released-layout checkpoint of the tiny preset exports to exactly the committed bundle's graphs;
- the committed graphs run in onnxruntime as torch computes them.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")
pytest.importorskip("safetensors")
yaml = pytest.importorskip("yaml")

from troupe_onnx.magnet import export  # noqa: E402
from troupe_onnx.magnet.checkpoint import load_release, write_release  # noqa: E402
from troupe_onnx.magnet.decoder_gradients import DecoderVjp, foot_skating_loss, pose_gradient, smoothing_loss  # noqa: E402
from troupe_onnx.shared.checkpoint import CheckpointError  # noqa: E402

BUNDLES = Path(__file__).resolve().parents[1] / "bundles"
torch.set_num_threads(1)


@pytest.mark.parametrize("preset", ["tiny", "tiny-trio"])
@pytest.mark.parametrize("weights", [(1.0, 0.0), (0.0, 1.0), (2.0, 3.0)])
def test_decoder_gradients_equal_autograd(preset, weights):
    """The hand-written gradient the bundle exports (per person-sequence, channels-last) against
    autograd of the losses through the official decoder: every person together, and each alone."""
    model, _, _ = export.build_model(preset, 0)
    lat = model.cfg.vq.d_latent
    sequences = DecoderVjp(model.vqvae.decoder, lat)
    ws, wf = weights
    loss = lambda r: ws * smoothing_loss(r) + wf * foot_skating_loss(r)  # noqa: E731
    for batch in (1, 3):
        rng = np.random.default_rng(batch)
        b, t, p, d = batch, model.cfg.window, model.cfg.persons, model.cfg.token_dim
        x0 = rng.standard_normal((b, t, p, d)).astype(np.float32)
        betas = rng.standard_normal((b, p, 10)).astype(np.float32)
        want = pose_gradient(model.vqvae.decoder, loss, x0, betas, lat)[..., :lat]
        w = torch.tensor(weights, dtype=torch.float32)
        with torch.no_grad():
            folded = sequences(torch.from_numpy(x0.transpose(0, 2, 1, 3).reshape(b * p, t, d)),
                               torch.from_numpy(betas.reshape(b * p, 10)), w).numpy()
        folded = folded.reshape(b, p, t, lat).transpose(0, 2, 1, 3)
        assert np.abs(folded - want).max() <= 1e-5 * np.abs(want).max()
        # One person's sequences alone, the weights scaled by their share: that person's rows.
        for person in range(p):
            with torch.no_grad():
                alone = sequences(torch.from_numpy(np.ascontiguousarray(x0[:, :, person])),
                                  torch.from_numpy(np.ascontiguousarray(betas[:, person])), w / p).numpy()
            assert np.abs(alone - want[:, :, person]).max() <= 1e-5 * np.abs(want).max()


def release(tmp_path: Path, preset: str = "tiny") -> Path:
    model, stats, _ = export.build_model(preset, 0)
    return write_release(model, stats, tmp_path, "magnet_test")


def test_released_layout_round_trips(tmp_path):
    folder = release(tmp_path)
    model, stats, config = load_release(folder, export.PRESETS["tiny"])
    fresh, fresh_stats, _ = export.build_model("tiny", 0)
    for (name, a), (_, b) in zip(model.state_dict().items(), fresh.state_dict().items()):
        assert torch.equal(a, b), name
    np.testing.assert_array_equal(stats.mean, fresh_stats.mean)
    assert config["model_cfg"]["person_num"] == 2


def test_checkpoint_export_equals_the_committed_graphs(tmp_path):
    folder = release(tmp_path)
    out = tmp_path / "bundle"
    export.export_bundle("tiny", out, checkpoint=folder)
    committed = BUNDLES / "magnet-tiny"
    import onnx
    from onnx import numpy_helper

    for name in ("denoiser", "vq_encoder", "vq_decoder", "guidance"):
        a, b = onnx.load(out / f"{name}.onnx"), onnx.load(committed / f"{name}.onnx")
        wa = {i.name: numpy_helper.to_array(i) for i in a.graph.initializer}
        wb = {i.name: numpy_helper.to_array(i) for i in b.graph.initializer}
        assert wa.keys() == wb.keys() and all(np.array_equal(wa[k], wb[k]) for k in wa), name
    assert (out / "codebook.f32").read_bytes() == (committed / "codebook.f32").read_bytes()
    manifest = json.loads((out / "troupe.json").read_text())
    assert manifest["producer"]["checkpoint"] == folder.name
    assert manifest["statistics"] == json.loads((committed / "troupe.json").read_text())["statistics"]


def _edit_state(folder: Path, edit) -> None:
    from safetensors.torch import load_file, save_file

    state = load_file(str(folder / "model.safetensors"))
    edit(state)
    save_file(state, str(folder / "model.safetensors"))


def _edit_config(folder: Path, edit) -> None:
    path = folder.parent / "config.yaml"
    cfg = yaml.safe_load(path.read_text())
    edit(cfg)
    path.write_text(yaml.safe_dump(cfg))


@pytest.mark.parametrize("edit,expected", [
    (lambda s: s.pop("diffuser.model.out.bias"), "1 missing parameter(s):\n  diffuser.model.out.bias"),
    (lambda s: s.update({"diffuser.model.extra": torch.zeros(2)}), "1 unexpected parameter(s):\n  diffuser.model.extra"),
    (lambda s: s.update({"_vqvae.vqvae.quantizer.codebook": torch.zeros(3, 32)}), "_vqvae.vqvae.quantizer.codebook: checkpoint (3, 32)"),
    (lambda s: s["diffuser.model.out.weight"].__setitem__((0, 0), float("nan")), "non-finite values in:\n  diffuser.model.out.weight"),
])
def test_bad_tensors_are_named(tmp_path, edit, expected):
    folder = release(tmp_path)
    _edit_state(folder, edit)
    with pytest.raises(CheckpointError) as e:
        load_release(folder, export.PRESETS["tiny"])
    assert expected in str(e.value)


def test_configuration_comes_from_the_checkpoint_and_must_match_the_preset(tmp_path):
    folder = release(tmp_path, "tiny-trio")
    with pytest.raises(CheckpointError) as e:
        load_release(folder, export.PRESETS["tiny"])
    assert "persons: checkpoint 3, preset 2" in str(e.value)
    assert "person_embedding_mode: checkpoint 'add', preset 'concat'" in str(e.value)
    model, _, _ = load_release(folder)  # no preset: whatever it says
    assert model.cfg.persons == 3


@pytest.mark.parametrize("edit,expected", [
    (lambda c: c["model_cfg"].update({"diffusion_objective": "pred_noise"}), "diffusion_objective is 'pred_noise'"),
    (lambda c: c["model_cfg"].pop("num_heads"), "model_cfg has no `num_heads`"),
    (lambda c: c.update({"mean_std_path": "data/missing.npz"}), "mean_std_path `data/missing.npz` found neither"),
    (lambda c: c["model_cfg"].update({"sequence_length": 62}), "sequence_length 62 is not a multiple of 4"),
])
def test_unsupported_or_broken_configs_are_refused_by_field(tmp_path, edit, expected):
    folder = release(tmp_path)
    _edit_config(folder, edit)
    with pytest.raises(CheckpointError) as e:
        load_release(folder, export.PRESETS["tiny"])
    assert expected in str(e.value)


def test_omegaconf_path_tags_are_read_as_plain_paths(tmp_path):
    """omegaconf 2.3/2.4 writes `Path` fields as `!!python/object/apply:pathlib.PosixPath` over
    the path's parts, which `yaml.safe_load` refuses: they load as the paths they name."""
    import pathlib

    folder = release(tmp_path)
    path = folder.parent / "config.yaml"
    cfg = yaml.safe_load(path.read_text())
    cfg["vqvae_model_path"] = pathlib.PosixPath(cfg["vqvae_model_path"])
    cfg["mean_std_path"] = pathlib.PosixPath(tmp_path.resolve() / cfg["mean_std_path"])  # absolute: "/" a part
    text = yaml.dump(cfg)  # the full dumper, as omegaconf's: the pickled form of PosixPath
    assert "!!python/object/apply:pathlib.PosixPath" in text
    path.write_text(text)
    model, stats, config = load_release(folder, export.PRESETS["tiny"])
    assert config["vqvae_model_path"] == str(cfg["vqvae_model_path"])
    assert config["mean_std_path"] == str(cfg["mean_std_path"])


@pytest.mark.parametrize("hostile", [
    "!!python/object/apply:os.system ['echo owned']",
    "!!python/object/apply:pathlib.PosixPath [[1, 2]]",
    "!!python/object/apply:pathlib.Thing ['a']",
    "!!python/object/new:pathlib.PosixPath ['a']",
])
def test_other_python_tags_are_still_refused(tmp_path, hostile):
    folder = release(tmp_path)
    path = folder.parent / "config.yaml"
    path.write_text(path.read_text() + f"extra: {hostile}\n")
    with pytest.raises(CheckpointError, match="not readable YAML"):
        load_release(folder, export.PRESETS["tiny"])


def test_vq_config_that_the_exporter_cannot_follow_is_refused(tmp_path):
    folder = release(tmp_path)
    vq_config = next((tmp_path / "checkpoints" / "vqvae").rglob("config.yaml"))
    cfg = yaml.safe_load(vq_config.read_text())
    cfg["model_cfg"]["norm"] = "BN"
    vq_config.write_text(yaml.safe_dump(cfg))
    with pytest.raises(CheckpointError, match="model_cfg.norm is 'BN'; this exporter implements 'LN'"):
        load_release(folder)


def test_missing_files_are_named(tmp_path):
    folder = release(tmp_path)
    (folder / "model.safetensors").unlink()
    with pytest.raises(CheckpointError, match="no model.safetensors"):
        load_release(folder)
    folder = release(tmp_path / "b")
    (folder.parent / "config.yaml").unlink()
    with pytest.raises(CheckpointError, match="no config.yaml"):
        load_release(folder)


@pytest.mark.parametrize("bundle,preset", [("magnet-tiny", "tiny"), ("magnet-tiny-trio", "tiny-trio")])
def test_committed_graphs_run_in_onnxruntime_as_torch(bundle, preset):
    model, _, _ = export.build_model(preset, 0)
    specs = json.loads((BUNDLES / bundle / "troupe.json").read_text())["graphs"]
    errors = export.validate_graphs(model, BUNDLES / bundle, specs)
    assert max(errors.values()) <= export.MAX_ABS_ERROR


class _Float32Drift(torch.nn.Module):
    """`inner`, but 2 % of its largest value off whenever it runs in float32: a torch float32
    forward far from float64, as one of a DD100-size checkpoint was found to be."""

    def __init__(self, inner, also_float64=False):
        super().__init__()
        self.inner, self.also_float64 = inner, also_float64

    def forward(self, *args):
        out = self.inner(*args)
        if out.dtype == torch.float32 or self.also_float64:
            out = out + 0.02 * out.abs().max()
        return out


def test_the_export_check_compares_with_float64_not_torch_float32():
    """A checkpoint whose torch float32 forward is far from float64 exports (onnxruntime is
    compared with float64); a graph that is itself off is still refused."""
    model, _, _ = export.build_model("tiny", 0)
    specs = json.loads((BUNDLES / "magnet-tiny" / "troupe.json").read_text())["graphs"]
    modules = export.graph_modules(model)
    drifting = dict(modules, denoiser=_Float32Drift(modules["denoiser"]))
    errors = export.validate_graphs(model, BUNDLES / "magnet-tiny", specs, drifting)
    assert errors["denoiser"] <= export.MAX_ABS_ERROR
    wrong = dict(modules, denoiser=_Float32Drift(modules["denoiser"], also_float64=True))
    with pytest.raises(RuntimeError, match="denoiser: onnxruntime differs from torch"):
        export.validate_graphs(model, BUNDLES / "magnet-tiny", specs, wrong)

"""The official-checkpoint path of the ARMFlow exporter (needs torch; run by
`cargo test --test export_reproducible`, or `python3 -m pytest onnx/test_official.py`).

- A checkpoint in the official layout exports to exactly the committed parity bundles.
- A checkpoint with missing, unexpected or mis-shaped tensors is rejected, naming each.
- The text branch written out for ONNX equals torch's own TransformerEncoder on the same
  official parameters.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
import export  # noqa: E402
from checkpoint import CheckpointError  # noqa: E402

torch.set_num_threads(1)  # as the exporter runs: the goldens compare within 1e-6


@pytest.fixture(scope="module")
def official_checkpoint(tmp_path_factory):
    path = tmp_path_factory.mktemp("ckpt") / "armflow.ckpt"
    export.write_checkpoint("tiny-interhuman", 0, path)
    return path


@pytest.mark.parametrize("preset", ["tiny-interhuman", "tiny-interx"])
def test_checkpoint_exports_to_the_committed_bundle(preset, tmp_path):
    ckpt = tmp_path / "official.ckpt"
    export.write_checkpoint(preset, 0, ckpt)
    out = tmp_path / "bundle"
    model = export.export_bundle(preset, out, checkpoint=ckpt)
    export.write_golden(model, out)
    committed = ROOT / f"armflow-{preset}"
    # Weights, graphs and goldens equal; the manifest differs in naming its source only.
    assert export.compare_bundles(committed, out) == ["troupe.json: contents differ"]
    a, b = (json.loads((d / "troupe.json").read_text()) for d in (committed, out))
    assert a.pop("producer")["seed"] == 0
    assert b.pop("producer")["checkpoint"] == "official.ckpt"
    assert a == b


def mutated(path: Path, tmp_path: Path, edit) -> Path:
    ckpt = torch.load(path, weights_only=True)
    edit(ckpt["state_dict"])
    out = tmp_path / "mutated.ckpt"
    torch.save(ckpt, out)
    return out


def export_error(ckpt: Path, tmp_path: Path) -> str:
    with pytest.raises(CheckpointError) as e:
        export.export_bundle("tiny-interhuman", tmp_path / "bundle", checkpoint=ckpt)
    return str(e.value)


def test_missing_parameters_are_named(official_checkpoint, tmp_path):
    def drop(sd):
        del sd["armflow.arnet.mid_layer.attn.q_bias"]
        del sd["vae.decoder.model.2.0.model.1.norm1.weight"]

    msg = export_error(mutated(official_checkpoint, tmp_path, drop), tmp_path)
    assert "2 missing" in msg
    assert "armflow.arnet.mid_layer.attn.q_bias" in msg
    assert "vae.decoder.model.2.0.model.1.norm1.weight" in msg


def test_unexpected_parameters_are_named(official_checkpoint, tmp_path):
    def add(sd):
        sd["armflow.arnet.in_layers.7.attn.q_bias"] = torch.zeros(32)

    msg = export_error(mutated(official_checkpoint, tmp_path, add), tmp_path)
    assert "1 unexpected" in msg and "armflow.arnet.in_layers.7.attn.q_bias" in msg


def test_misshaped_parameters_are_named(official_checkpoint, tmp_path):
    def reshape(sd):
        sd["armflow.mlp.blocks.0.linear1.weight"] = torch.zeros(128, 31)

    msg = export_error(mutated(official_checkpoint, tmp_path, reshape), tmp_path)
    assert "1 mis-shaped" in msg
    assert "armflow.mlp.blocks.0.linear1.weight: checkpoint (128, 31), model (128, 32)" in msg


def test_non_finite_weights_are_named(official_checkpoint, tmp_path):
    def poison(sd):
        sd["armflow.start_token"][0, 0, 3] = float("nan")

    msg = export_error(mutated(official_checkpoint, tmp_path, poison), tmp_path)
    assert "non-finite" in msg and "armflow.start_token" in msg


def test_a_file_that_is_not_a_checkpoint_is_rejected(tmp_path):
    bad = tmp_path / "bad.ckpt"
    bad.write_bytes(b"not a checkpoint")
    assert "not a readable torch checkpoint" in export_error(bad, tmp_path)


def test_ignored_tensors_are_reported(official_checkpoint, tmp_path, capsys):
    export.export_bundle("tiny-interhuman", tmp_path / "bundle", checkpoint=official_checkpoint)
    out = capsys.readouterr().out
    assert "ignored 2 tensor(s) armflow.arnet.head_nm.*" in out
    assert "ignored 1 tensor(s) text_encoder.clip_*" in out


def test_text_branch_equals_torch_transformer_encoder():
    torch.manual_seed(5)
    model = export.build_model("tiny-interhuman", 0)
    cfg = model.cfg
    layer = torch.nn.TransformerEncoderLayer(cfg.cond_dim, cfg.text_heads, cfg.text_ffn, dropout=0.1,
                                             activation="gelu", batch_first=True)
    official = torch.nn.ModuleDict({
        "clipTrans": torch.nn.TransformerEncoder(layer, num_layers=2, enable_nested_tensor=False),
        "clipln": torch.nn.LayerNorm(cfg.cond_dim),
    }).eval()
    official.load_state_dict(model.text_encoder.state_dict(), strict=True)
    tokens, eot = torch.randn(3, 77, cfg.cond_dim), torch.tensor([9, 76, 0])
    with torch.no_grad():
        want = official["clipln"](official["clipTrans"](tokens))[torch.arange(3), eot]
        got = model.text_encoder(tokens, eot)
    assert torch.allclose(got, want, atol=1e-5), (got - want).abs().max()

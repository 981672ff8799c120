"""The official-checkpoint path of the ARMFlow and UMF exporters (needs torch; run by
`cargo test --test export_reproducible`, or `python3 -m pytest onnx/tests/test_official.py`).

- A checkpoint in the official layout exports to exactly the committed parity bundles.
- A checkpoint with missing, unexpected or mis-shaped tensors is rejected, naming each.
- The text branches written out for ONNX equal torch's own TransformerEncoder on the same
  official parameters.
"""

from __future__ import annotations

import json

import numpy as np
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")

from troupe_onnx.armflow import export  # noqa: E402
from troupe_onnx.shared.checkpoint import CheckpointError  # noqa: E402
from troupe_onnx.shared.export import compare_bundles  # noqa: E402
from troupe_onnx.umf import export as export_umf  # noqa: E402

BUNDLES = Path(__file__).resolve().parents[1] / "bundles"

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
    committed = BUNDLES / f"armflow-{preset}"
    # Weights, graphs and goldens equal; the manifest differs in naming its source only.
    assert compare_bundles(committed, out) == ["troupe.json: contents differ"]
    a, b = (json.loads((d / "troupe.json").read_text()) for d in (committed, out))
    assert a.pop("producer")["seed"] == 0
    assert b.pop("producer")["checkpoint"] == "official.ckpt"
    assert a == b


def mutated(path: Path, tmp_path: Path, edit, section: str = "state_dict") -> Path:
    """A copy of the checkpoint at `path` with `edit` applied to one of its sections."""
    ckpt = torch.load(path, weights_only=True)
    edit(ckpt[section])
    out = tmp_path / "mutated.ckpt"
    torch.save(ckpt, out)
    return out


def bare(path: Path, tmp_path: Path) -> Path:
    """A copy of the checkpoint at `path` holding only its state dict (no configuration)."""
    out = tmp_path / "bare.ckpt"
    torch.save({"state_dict": torch.load(path, weights_only=True)["state_dict"]}, out)
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
    assert "text_encoder.clip_" not in out  # CLIP's tower is loaded: it is the bundle's text encoder


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
    branch = {k: v for k, v in model.text_encoder.state_dict().items() if k.startswith(("clipTrans.", "clipln."))}
    official.load_state_dict(branch, strict=True)
    tokens, eot = torch.randn(3, 77, cfg.cond_dim), torch.tensor([9, 76, 0])
    with torch.no_grad():
        want = official["clipln"](official["clipTrans"](tokens))[torch.arange(3), eot]
        got = model.text_encoder(tokens, eot)
    assert torch.allclose(got, want, atol=1e-5), (got - want).abs().max()


def openai_clip_text(model_tower, width: int, layers: int, heads: int):
    """OpenAI CLIP's own text Transformer (`clip/model.py` of the openai-clip package, loaded by
    file) with the weights of our tower, and its `encode_text` up to ln_final."""
    import importlib.util

    spec = importlib.util.find_spec("clip")
    if spec is None:
        pytest.skip("openai-clip is not installed")
    path = Path(spec.origin).parent / "model.py"
    module_spec = importlib.util.spec_from_file_location("openai_clip_model", path)
    clip_model = importlib.util.module_from_spec(module_spec)
    module_spec.loader.exec_module(clip_model)
    mask = torch.empty(77, 77).fill_(float("-inf")).triu_(1)
    transformer = clip_model.Transformer(width, layers, heads, attn_mask=mask).eval()
    transformer.load_state_dict(model_tower.state_dict(), strict=True)
    return transformer


@pytest.mark.parametrize("preset", ["tiny-interhuman", "umf-tiny"])
def test_the_text_encoder_is_openai_clips_text_tower(preset):
    """Our tower (batch first, written-out attention) against OpenAI's modules on the same
    weights: the features after ln_final for random ids, within 1e-5."""
    if preset == "umf-tiny":
        m = export_umf.build_model("tiny", 0)
        parts = (m.token_embedding, m.positional_embedding, m.clip_transformer, m.ln_final, m.clip_features)
        width, layers, heads = m.cfg.text_dim, m.cfg.clip_layers, m.cfg.clip_heads
    else:
        t = export.build_model(preset, 0).text_encoder
        parts = (t.clip_token_embedding, t.clip_positional_embedding, t.clip_transformer, t.clip_ln_final, t.clip_features)
        cfg = export.PRESETS[preset]
        width, layers, heads = cfg.cond_dim, cfg.clip_layers, cfg.clip_heads
    embedding, positions, tower, ln_final, ours = parts
    official = openai_clip_text(tower, width, layers, heads)
    ids = torch.randint(0, embedding.num_embeddings, (3, 77))
    with torch.no_grad():
        x = (embedding(ids) + positions).permute(1, 0, 2)  # encode_text, sequence first
        want = ln_final(official(x).permute(1, 0, 2))
        got = ours(ids)
    assert torch.allclose(got, want, atol=1e-5), (got - want).abs().max()


def test_the_null_condition_of_armflow_is_the_empty_prompt(tmp_path):
    """The official `encode_null_condition` encodes "" through CLIP and the text branch; the
    exported manifest's null is that, not zeros, and the reference loop uses it for None."""
    from troupe_onnx.shared.clip import reference_tokenizer, tokenize, write_merges

    model = export.build_model("tiny-interhuman", 0)
    tokenizer = reference_tokenizer(write_merges(tmp_path, model.cfg.clip_merges))
    ids = torch.from_numpy(tokenize(tokenizer, ""))[None]
    assert ids[0, :3].tolist() == [tokenizer.encoder["<|startoftext|>"], tokenizer.encoder["<|endoftext|>"], 0]
    with torch.no_grad():
        want = model.text_encoder(model.text_encoder.clip_features(ids), ids.argmax(dim=-1))[0]
    manifest = export.condition_manifest(model)
    assert manifest["null_source"] == "empty_prompt"
    assert np.allclose(manifest["null"], want.numpy(), atol=1e-6)
    assert np.abs(want.numpy()).max() > 0.1


# --------------------------------------------------------------------------------------------
# The checkpoint's stored configuration (Lightning `hyper_parameters`)
# --------------------------------------------------------------------------------------------


def with_hyper_parameters(path: Path, tmp_path: Path, edit) -> Path:
    return mutated(path, tmp_path, edit, section="hyper_parameters")


def manifest_of(ckpt: Path, out: Path) -> dict:
    export.export_bundle("tiny-interhuman", out, checkpoint=ckpt)
    return json.loads((out / "troupe.json").read_text())


def test_the_checkpoint_configuration_wins_over_the_preset(official_checkpoint, tmp_path, capsys):
    def edit(hp):
        hp["mf"]["nhead"] = 4  # same tensor shapes as 2 heads
        hp["mf"]["scale_factor"] = 0.25
        hp["mf"]["num_steps"] = 3
        hp["mf"]["cfg_scale"] = 2.0
        hp["mf"]["siloss"]["cfg_omega"] = 1.0  # guidance not baked in: cfg_scale stands

    m = manifest_of(with_hyper_parameters(official_checkpoint, tmp_path, edit), tmp_path / "b")
    assert (m["context"]["heads"], m["context"]["head_dim"]) == (4, 8)
    assert m["latent"]["scale"] == 0.25
    assert (m["sampler"]["steps"], m["sampler"]["cfg_scale"]) == (3, 2.0)
    out = capsys.readouterr().out
    for field in ("mf.nhead = 4", "mf.scale_factor = 0.25", "mf.num_steps = 3"):
        assert field in out, out
    # The same weights exported with heads=4 given by hand are the same graphs.
    import dataclasses

    by_hand = dataclasses.replace(export.PRESETS["tiny-interhuman"], heads=4, latent_scale=0.25, steps=3, cfg_scale=2.0)
    export.export_bundle("tiny-interhuman", tmp_path / "hand", checkpoint=bare(official_checkpoint, tmp_path), config=by_hand)
    differences = compare_bundles(tmp_path / "b", tmp_path / "hand")
    assert differences == ["troupe.json: contents differ"], differences


def test_baked_in_guidance_turns_cfg_off_as_the_official_test_loop(official_checkpoint, tmp_path):
    def edit(hp):
        hp["mf"]["cfg_scale"] = 3.0
        hp["mf"]["siloss"]["cfg_omega"] = 1.8

    m = manifest_of(with_hyper_parameters(official_checkpoint, tmp_path, edit), tmp_path / "b")
    assert m["sampler"]["cfg_scale"] == 1.0


def test_the_notes_quote_the_checkpoints_own_values():
    """What the exporter prints: each setting as the checkpoint writes it, and what troupe
    derived from it (not the derived width or head count in the setting's place)."""
    from troupe_onnx.armflow.hparams import config_from_checkpoint, hyper_parameters

    preset = export.PRESETS["tiny-interhuman"]
    hp = hyper_parameters(preset)
    hp["vae"]["is_double"] = not hp["vae"]["is_double"]
    hp["mf"]["text_encoder"]["clip_version"] = "ViT-B/32"
    hp["mf"]["cfg_scale"], hp["mf"]["siloss"]["cfg_omega"] = 2.0, 1.0
    cfg, notes = config_from_checkpoint(hp, preset)
    text = "\n".join(notes)
    assert f"vae.is_double = {hp['vae']['is_double']!r} from the checkpoint, so vae.encoder_width" in text, text
    assert "mf.text_encoder.clip_version = 'ViT-B/32' from the checkpoint, so clip_layers = 12" in text, text
    assert "mf.text_encoder.clip_version = 'ViT-B/32' from the checkpoint, so clip_heads = 8" in text, text
    assert "= 2.0 from the checkpoint (the preset has cfg_scale = 1.0)" in text, text
    assert (cfg.clip_layers, cfg.clip_heads, cfg.cfg_scale) == (12, 8, 2.0)
    assert "= 256" not in text and "clip_version = 8" not in text, text


def test_configurations_troupe_cannot_follow_are_refused_by_field(official_checkpoint, tmp_path):
    def edit(hp):
        hp["mf"]["text_encoder"]["is_intergen_clip"] = "easy"
        hp["vae"]["norm"] = "BN"
        hp["mf"]["text_encoder"]["clip_version"] = "RN50"

    msg = export_error(with_hyper_parameters(official_checkpoint, tmp_path, edit), tmp_path)
    for field in ("mf.text_encoder.is_intergen_clip = 'easy'", "vae.norm = 'BN'", "clip_version = 'RN50'"):
        assert field in msg, msg


def test_a_checkpoint_without_configuration_exports_with_the_preset_and_says_so(official_checkpoint, tmp_path, capsys):
    export.export_bundle("tiny-interhuman", tmp_path / "b", checkpoint=bare(official_checkpoint, tmp_path))
    assert "no stored configuration" in capsys.readouterr().out


def test_umf_takes_its_configuration_from_a_file_and_says_so(tmp_path, capsys):
    ckpt = tmp_path / "umf.ckpt"
    export_umf.write_checkpoint("tiny", 0, ckpt)
    export_umf.export_bundle("tiny", tmp_path / "plain", checkpoint=ckpt)
    assert "store no configuration" in capsys.readouterr().out
    config = tmp_path / "umf.json"
    config.write_text(json.dumps({"gamma": -0.25, "cfg_scale": 2.5, "reaction_solver": {"method": "euler", "steps": 6}}))
    export_umf.export_bundle("tiny", tmp_path / "configured", checkpoint=ckpt, config_file=config)
    out = capsys.readouterr().out
    assert "gamma = -0.25" in out and "cfg_scale = 2.5" in out
    m = json.loads((tmp_path / "configured" / "troupe.json").read_text())
    assert m["pyramid"]["gamma"] == -0.25 and m["sampler"]["cfg_scale"] == 2.5
    assert m["sampler"]["reaction"] == {"method": "euler", "steps": 6}
    assert m["producer"]["config"] == "umf.json"
    config.write_text(json.dumps({"heads_typo": 3}))
    with pytest.raises(CheckpointError, match="heads_typo"):
        export_umf.export_bundle("tiny", tmp_path / "bad", checkpoint=ckpt, config_file=config)


# --------------------------------------------------------------------------------------------
# UMF (Githubhgh/UMF_CVPR): the committed `umf-tiny` bundle is the official layout at reduced
# width; its checkpoint carries the schedulers' copies of the denoisers and evaluator extras.
# --------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def umf_checkpoint(tmp_path_factory):
    path = tmp_path_factory.mktemp("umf") / "umf.ckpt"
    export_umf.write_checkpoint("tiny", 0, path)
    return path


def statistics(ckpt: Path) -> tuple[Path, Path]:
    """The normaliser write_checkpoint saves beside a checkpoint."""
    return ckpt.parent / "global_mean.npy", ckpt.parent / "global_std.npy"


def umf_export(ckpt: Path, tmp_path: Path, normaliser: tuple[Path, Path]):
    return export_umf.export_bundle("tiny", tmp_path / "bundle", checkpoint=ckpt, normaliser=normaliser)


def umf_error(ckpt: Path, tmp_path: Path, normaliser: tuple[Path, Path]) -> str:
    with pytest.raises(CheckpointError) as e:
        umf_export(ckpt, tmp_path, normaliser)
    return str(e.value)


def test_umf_checkpoint_exports_to_the_committed_bundle(umf_checkpoint, tmp_path, capsys):
    model = umf_export(umf_checkpoint, tmp_path, statistics(umf_checkpoint))
    export_umf.write_golden(model, tmp_path / "bundle")
    committed = BUNDLES / "umf-tiny"
    assert compare_bundles(committed, tmp_path / "bundle") == ["troupe.json: contents differ"]
    a, b = (json.loads((d / "troupe.json").read_text()) for d in (committed, tmp_path / "bundle"))
    assert a.pop("producer")["seed"] == 0
    assert b.pop("producer")["checkpoint"] == "umf.ckpt"
    assert a == b  # the null condition included: it is computed from the checkpoint's CLIP
    out = capsys.readouterr().out
    assert "tensor(s) flow_scheduler.net.*: repeats indi_denoiser.* (checked equal)" in out
    assert "ignored 1 tensor(s) t2m_textencoder.*" in out


def test_umf_missing_extra_and_misshaped_parameters_are_named(umf_checkpoint, tmp_path):
    def edit(sd):
        del sd["indi_denoiser.expert_ih_blocks.0.linear1.bias"]
        del sd["clipTransEncoder_react.layers.1.norm2.weight"]
        sd["reac_denoiser.expert_ih_norm.weight"] = torch.ones(32)
        sd["vae.final_layer.weight"] = torch.zeros(263, 32)

    msg = umf_error(mutated(umf_checkpoint, tmp_path, edit), tmp_path, statistics(umf_checkpoint))
    assert "2 missing" in msg and "indi_denoiser.expert_ih_blocks.0.linear1.bias" in msg
    assert "clipTransEncoder_react.layers.1.norm2.weight" in msg
    assert "1 unexpected" in msg and "reac_denoiser.expert_ih_norm.weight" in msg
    assert "vae.final_layer.weight: checkpoint (263, 32), model (262, 32)" in msg


def test_umf_scheduler_copies_must_repeat_the_denoisers(umf_checkpoint, tmp_path):
    def edit(sd):
        key = "flow_scheduler_org.net.latent_pre.bias"
        sd[key] = sd[key] + 1.0  # a new tensor: in the file the copy shares its original's storage

    msg = umf_error(mutated(umf_checkpoint, tmp_path, edit), tmp_path, statistics(umf_checkpoint))
    assert "1 inconsistent repeated" in msg
    assert "flow_scheduler_org.net.latent_pre.bias (should repeat reac_denoiser.latent_pre.bias)" in msg


def test_umf_non_finite_weights_and_bad_normalisers_are_named(umf_checkpoint, tmp_path):
    def poison(sd):
        sd["dataset_embedding.weight"][1, 0] = float("inf")

    msg = umf_error(mutated(umf_checkpoint, tmp_path, poison), tmp_path, statistics(umf_checkpoint))
    assert "non-finite" in msg and "dataset_embedding.weight" in msg
    short = tmp_path / "short.npy"
    np.save(short, np.ones(261, np.float32))
    mean, std = statistics(umf_checkpoint)
    assert "expected 262 finite floats, got shape (261,)" in umf_error(umf_checkpoint, tmp_path, (short, std))
    zero = tmp_path / "zero.npy"
    np.save(zero, np.zeros(262, np.float32))
    assert "must be positive" in umf_error(umf_checkpoint, tmp_path, (mean, zero))


def test_umf_text_branches_equal_torch_transformer_encoders():
    model = export_umf.build_model("tiny", 0)
    cfg = model.cfg
    official = {}
    for name in ("ih", "react"):
        layer = torch.nn.TransformerEncoderLayer(cfg.text_dim, cfg.text_heads, cfg.text_ffn, dropout=0.1,
                                                 activation="gelu", batch_first=True)
        encoder = torch.nn.TransformerEncoder(layer, num_layers=cfg.text_layers, enable_nested_tensor=False).eval()
        encoder.load_state_dict(getattr(model, f"clipTransEncoder_{name}").state_dict(), strict=True)
        official[name] = lambda x, e=encoder, n=name: getattr(model, f"clip_ln_{n}")(e(x))
    torch.manual_seed(5)
    tokens, eot = torch.randn(3, 77, cfg.text_dim), torch.tensor([9, 76, 1])
    with torch.no_grad():
        want = torch.cat([official[n](tokens)[torch.arange(3), eot] for n in ("ih", "react")], dim=-1)
        got = model.text_condition(tokens, eot)
    assert torch.allclose(got, want, atol=1e-5), (got - want).abs().max()


def test_umf_null_condition_is_the_empty_prompt_through_clip():
    model = export_umf.build_model("tiny", 0)
    vocab = model.cfg.clip_vocab
    ids = torch.zeros(1, 77, dtype=torch.long)
    ids[0, :2] = torch.tensor([vocab - 2, vocab - 1])  # clip.tokenize(""): <|startoftext|> <|endoftext|>
    tower = openai_clip_text(model.clip_transformer, model.cfg.text_dim, model.cfg.clip_layers, model.cfg.clip_heads)
    with torch.no_grad():
        # CLIP's text tower as OpenAI's CLIP runs it: sequence-first, causal mask, then ln_final.
        x = (model.token_embedding(ids) + model.positional_embedding).permute(1, 0, 2)
        feats = model.ln_final(tower(x).permute(1, 0, 2))
        want = model.text_condition(feats, ids.argmax(dim=-1))[0]
    assert torch.allclose(model.null_condition, want, atol=1e-6)
    assert not torch.allclose(model.null_condition, torch.zeros_like(want))
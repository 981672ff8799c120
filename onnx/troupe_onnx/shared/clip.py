"""CLIP's text tower and vocabulary, for the families whose official code conditions on text
through OpenAI's CLIP (ARMFlow, UMF): the exporters write the tower as the bundle's
`text_encoder` graph (token ids -> the features after `ln_final`, what the text branch reads)
and the byte-pair merges as the bundle's `clip_merges.txt`, so that troupe turns a prompt into
a condition by itself.

The tower is OpenAI CLIP's (`clip/model.py`, `encode_text` up to `ln_final`): token embedding
plus learned positions, pre-norm residual blocks with a causal mask and QuickGELU, a final
LayerNorm. Each family keeps the official attribute names of its checkpoint and calls
`clip_features` with them.

The vocabulary is OpenAI's `bpe_simple_vocab_16e6.txt.gz` (MIT licence, Copyright (c) 2021
OpenAI), read at export time from the `openai-clip` or `open_clip_torch` package. A model of
`merges` merges has `512 + merges + 2` tokens: the 256 byte symbols, the same with `</w>`, one
per merge, then `<|startoftext|>` and `<|endoftext|>`. The official models use all 48,894
merges; the tiny test bundles use the first 1,000, so their embedding tables stay small.
"""

from __future__ import annotations

import gzip
import importlib.util
import json
import tempfile
from collections import OrderedDict
from pathlib import Path

import numpy as np
import torch
import torch.nn as nn

from troupe_onnx.shared.transformer import Attention

CONTEXT = 77  # CLIP's context length: every prompt is 77 token ids
FULL_MERGES = 49152 - 256 - 2  # the merges SimpleTokenizer reads from the vocabulary file
MERGES_FILE = "clip_merges.txt"  # the bundle's copy of the merges


def vocab_size(merges: int) -> int:
    """Tokens of a tokenizer with `merges` merges (49,408 for CLIP's own)."""
    return 512 + merges + 2


class QuickGELU(nn.Module):
    def forward(self, x):
        return x * torch.sigmoid(1.702 * x)


class ClipBlock(nn.Module):
    """CLIP's ResidualAttentionBlock: pre-norm, causal self-attention, QuickGELU MLP (its
    parameter names: `attn.in_proj_*`, `attn.out_proj`, `ln_1`, `mlp.c_fc`, `mlp.c_proj`,
    `ln_2`). Batch first; CLIP runs sequence first, which changes no value."""

    def __init__(self, width: int, heads: int):
        super().__init__()
        self.attn = Attention(width, heads)
        self.ln_1 = nn.LayerNorm(width)
        self.mlp = nn.Sequential(
            OrderedDict(c_fc=nn.Linear(width, 4 * width), gelu=QuickGELU(), c_proj=nn.Linear(4 * width, width))
        )
        self.ln_2 = nn.LayerNorm(width)

    def forward(self, x, mask):  # x [B, T, C]
        x = x + self.attn(self.ln_1(x), mask=mask)
        return x + self.mlp(self.ln_2(x))


class ClipTransformer(nn.Module):
    """CLIP's text Transformer (`resblocks`)."""

    def __init__(self, width: int, layers: int, heads: int):
        super().__init__()
        self.resblocks = nn.ModuleList(ClipBlock(width, heads) for _ in range(layers))

    def forward(self, x):  # [B, T, C]
        t = x.shape[1]
        mask = torch.full((t, t), float("-inf")).triu_(1)
        for block in self.resblocks:
            x = block(x, mask)
        return x


def clip_features(token_embedding: nn.Embedding, positional_embedding: torch.Tensor,
                  transformer: ClipTransformer, ln_final: nn.LayerNorm, ids: torch.Tensor) -> torch.Tensor:
    """CLIP's text tower: token ids [B, T] -> the features after ln_final [B, T, C]."""
    x = token_embedding(ids) + positional_embedding[: ids.shape[1]]
    return ln_final(transformer(x))


def empty_prompt(vocab: int) -> tuple[torch.Tensor, torch.Tensor]:
    """`clip.tokenize("")` for a tokenizer of `vocab` ids, the official "no text": ids [1, 77]
    `[<|startoftext|>, <|endoftext|>, 0, ...]` (the two special ids are the last two of the
    vocabulary) and the index of its end-of-text token, [1]."""
    ids = torch.zeros(1, CONTEXT, dtype=torch.long)
    ids[0, 0], ids[0, 1] = vocab - 2, vocab - 1
    return ids, torch.tensor([1])


class TextEncoderGraph(nn.Module):
    """The bundle's `text_encoder` graph: `features` (a family's bound clip_features) as a
    module for torch.onnx.export."""

    def __init__(self, owner: nn.Module, features: str):
        super().__init__()
        self.owner, self.features = owner, features

    def forward(self, ids):
        return getattr(self.owner, self.features)(ids)


def text_encoder_spec(width: int) -> dict:
    """The manifest's declaration of the `text_encoder` graph."""
    return {
        "file": "text_encoder.onnx",
        "inputs": [{"name": "token_ids", "dtype": "int64", "shape": ["B", CONTEXT]}],
        "outputs": [{"name": "clip_tokens", "dtype": "float32", "shape": ["B", CONTEXT, width]}],
    }


def tokenizer_manifest(merges: int) -> dict:
    """The manifest's `tokenizer` section: how troupe turns a prompt into the token ids of the
    `text_encoder` graph."""
    return {"kind": "clip-bpe", "merges_file": MERGES_FILE, "merges": merges, "context": CONTEXT}


# --------------------------------------------------------------------------------------------
# The vocabulary and the reference tokenizer
# --------------------------------------------------------------------------------------------


def _package_dir(name: str) -> Path | None:
    spec = importlib.util.find_spec(name)
    return Path(spec.origin).parent if spec and spec.origin else None


def vocabulary_file() -> Path:
    """OpenAI's `bpe_simple_vocab_16e6.txt.gz`, from the installed `openai-clip` (module `clip`)
    or `open_clip_torch` (module `open_clip`) package."""
    for package in ("clip", "open_clip"):
        directory = _package_dir(package)
        if directory and (directory / "bpe_simple_vocab_16e6.txt.gz").is_file():
            return directory / "bpe_simple_vocab_16e6.txt.gz"
    raise FileNotFoundError(
        "CLIP's vocabulary (bpe_simple_vocab_16e6.txt.gz) was not found: pip install openai-clip ftfy regex"
    )


def merges_text(merges: int) -> str:
    """The header line and the first `merges` merges of CLIP's vocabulary file: the bundle's
    `clip_merges.txt`, readable by SimpleTokenizer as its `bpe_path` once gzipped. No newline
    after the last merge: SimpleTokenizer would read the empty line after it as a merge."""
    if not 1 <= merges <= FULL_MERGES:
        raise ValueError(f"merges must be in 1..{FULL_MERGES}, got {merges}")
    lines = gzip.open(vocabulary_file()).read().decode("utf-8").split("\n")
    return "\n".join(lines[: merges + 1])


def write_merges(out_dir: Path, merges: int) -> Path:
    path = out_dir / MERGES_FILE
    path.write_text(merges_text(merges), encoding="utf-8")
    return path


def reference_tokenizer(merges_path: Path):
    """OpenAI's own `SimpleTokenizer` (from the `openai-clip` package, loaded by file: the
    package's `__init__` imports torchvision) over a merges file, gzipped or not."""
    directory = _package_dir("clip")
    if directory is None:
        raise ModuleNotFoundError("the reference tokenizer needs the openai-clip package (pip install openai-clip)")
    spec = importlib.util.spec_from_file_location("clip_simple_tokenizer", directory / "simple_tokenizer.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    data = merges_path.read_bytes()
    with tempfile.TemporaryDirectory() as tmp:  # SimpleTokenizer gunzips its bpe_path
        packed = Path(tmp) / "merges.txt.gz"
        packed.write_bytes(data if data[:2] == b"\x1f\x8b" else gzip.compress(data, mtime=0))
        return module.SimpleTokenizer(bpe_path=str(packed))


def tokenize(tokenizer, text: str, context: int = CONTEXT) -> np.ndarray:
    """`clip.tokenize(text, context, truncate=True)` for one prompt: [context] int64."""
    sot, eot = tokenizer.encoder["<|startoftext|>"], tokenizer.encoder["<|endoftext|>"]
    ids = [sot] + tokenizer.encode(text) + [eot]
    if len(ids) > context:
        ids = ids[:context]
        ids[-1] = eot
    out = np.zeros(context, np.int64)
    out[: len(ids)] = ids
    return out


# Prompts of the golden files: the empty prompt (the null condition), ordinary ones, punctuation,
# Unicode, and one past CLIP's 77 tokens (truncated, its last id <|endoftext|>).
GOLDEN_PROMPTS = [
    "",
    "two people shake hands",
    "A person waves at the other, then both sit down.",
    "Ein Mensch läuft weg – der andere folgt! 🏃",
    "one person pushes the other, who stumbles back " * 8,
]


@torch.no_grad()
def write_prompt_golden(bundle_dir: Path, features, condition):
    """`golden/prompts.json` (the prompts), `prompt_ids.npy` [P, 77] (OpenAI's tokenizer over
    the bundle's merges) and `prompt_conditions.npy` [P, dim]: `condition(features(ids),
    end-of-text index)`, the family's text encoder and branch in torch."""
    g = bundle_dir / "golden"
    g.mkdir(exist_ok=True)
    tokenizer = reference_tokenizer(bundle_dir / MERGES_FILE)
    ids = np.stack([tokenize(tokenizer, p) for p in GOLDEN_PROMPTS])
    t = torch.from_numpy(ids)
    conditions = condition(features(t), t.argmax(dim=-1)).numpy().astype(np.float32)
    (g / "prompts.json").write_text(json.dumps(GOLDEN_PROMPTS, ensure_ascii=False, indent=2) + "\n", encoding="utf-8")
    np.save(g / "prompt_ids.npy", ids)
    np.save(g / "prompt_conditions.npy", np.ascontiguousarray(conditions))

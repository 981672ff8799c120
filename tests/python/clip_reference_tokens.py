"""OpenAI CLIP's own tokenizer over a file of prompts: the reference tests/text_tokenizer.rs
checks troupe's `ClipTokenizer` against.

    python3 tests/python/clip_reference_tokens.py PROMPTS.jsonl OUT.json [MERGES ...]

PROMPTS.jsonl holds one JSON string per line (so a prompt may hold newlines and any Unicode).
For each vocabulary, CLIP's full one (48,894 merges) and the first MERGES merges of it (default:
2,000, a tiny test bundle's kind), this writes the merges file troupe reads into OUT.json's
directory (`clip_merges_<N>.txt`: the `#version` line and N merges, no newline after the last:
SimpleTokenizer would read one more, empty, merge) and runs `SimpleTokenizer` over it: per
prompt, `encode` and the `clip.tokenize(prompt, 77, truncate=True)` row. A prompt the reference
raises on gets `{"error": ...}` instead. `fix_encoding` says, per prompt, whether ftfy's mojibake
repair (the ftfy step troupe does not reproduce) changes it; `prompts` echoes the prompts as
Python read them.

The reference is the file `clip/simple_tokenizer.py` of the installed `openai-clip` package,
loaded by path: importing the `clip` package imports torch, which these tests do without. Needs
ftfy, regex and openai-clip (tests/requirements.txt).
"""

import gzip
import importlib.util
import json
import platform
import sys
import unicodedata
from pathlib import Path

import ftfy
import regex

CONTEXT = 77
FULL_MERGES = 49152 - 256 - 2  # the merges SimpleTokenizer reads


def clip_directory() -> Path:
    """The installed `clip` package's directory, found without importing it."""
    spec = importlib.util.find_spec("clip")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("the openai-clip package is not installed (pip install openai-clip)")
    return Path(list(spec.submodule_search_locations)[0])


def load_simple_tokenizer(directory: Path):
    spec = importlib.util.spec_from_file_location("clip_simple_tokenizer", directory / "simple_tokenizer.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def tokenize(tokenizer, text: str) -> list:
    """`clip.tokenize(text, CONTEXT, truncate=True)[0]` without torch."""
    sot, eot = tokenizer.encoder["<|startoftext|>"], tokenizer.encoder["<|endoftext|>"]
    ids = [sot] + tokenizer.encode(text) + [eot]
    if len(ids) > CONTEXT:
        ids = ids[:CONTEXT]
        ids[-1] = eot
    return ids + [0] * (CONTEXT - len(ids))


def run(module, lines: list, merges: int, out_dir: Path, prompts: list) -> dict:
    text = "\n".join(lines[: merges + 1])  # SimpleTokenizer reads lines[1 : merges + 1]
    merges_file = out_dir / f"clip_merges_{merges}.txt"
    merges_file.write_text(text, encoding="utf-8")
    if merges == FULL_MERGES:
        tokenizer = module.SimpleTokenizer()  # CLIP's own file, as CLIP reads it
    else:
        packed = out_dir / f"clip_merges_{merges}.txt.gz"  # SimpleTokenizer gunzips its bpe_path
        packed.write_bytes(gzip.compress(text.encode("utf-8"), mtime=0))
        tokenizer = module.SimpleTokenizer(bpe_path=str(packed))
    results = []
    for prompt in prompts:
        try:
            results.append({"encode": tokenizer.encode(prompt), "tokenize": tokenize(tokenizer, prompt)})
        except Exception as e:  # noqa: BLE001 - the reference's failure is the datum
            results.append({"error": f"{type(e).__name__}: {e}"[:300]})
    return {
        "merges": merges,
        "merges_file": str(merges_file.resolve()),
        "vocab_size": len(tokenizer.encoder),
        "start_of_text": tokenizer.encoder["<|startoftext|>"],
        "end_of_text": tokenizer.encoder["<|endoftext|>"],
        "results": results,
    }


def main() -> None:
    prompts_path, out = Path(sys.argv[1]), Path(sys.argv[2])
    sizes = [int(a) for a in sys.argv[3:]] or [2000]
    # Lines end at "\n" only (str.splitlines would also break at U+2028, U+0085, ...).
    prompts = [json.loads(line) for line in prompts_path.read_text(encoding="utf-8").split("\n") if line.strip()]
    if not all(isinstance(p, str) for p in prompts):
        raise SystemExit(f"{prompts_path}: every line must be one JSON string")
    out.parent.mkdir(parents=True, exist_ok=True)
    directory = clip_directory()
    module = load_simple_tokenizer(directory)
    vocabulary = gzip.open(directory / "bpe_simple_vocab_16e6.txt.gz").read().decode("utf-8")
    lines = vocabulary.split("\n")
    fix_encoding = []
    for prompt in prompts:
        try:
            fix_encoding.append(ftfy.fix_text(prompt) != ftfy.fix_text(prompt, fix_encoding=False))
        except Exception:  # noqa: BLE001
            fix_encoding.append(False)
    report = {
        "reference": {
            "simple_tokenizer": str(directory / "simple_tokenizer.py"),
            "ftfy": ftfy.__version__,
            "regex": regex.__version__,
            "python": platform.python_version(),
            "unicodedata": unicodedata.unidata_version,
        },
        "context": CONTEXT,
        "prompts": prompts,
        "fix_encoding": fix_encoding,
        "vocabularies": [run(module, lines, n, out.parent, prompts) for n in [FULL_MERGES, *sizes]],
    }
    out.write_text(json.dumps(report), encoding="utf-8")
    print(json.dumps(report["reference"]))


if __name__ == "__main__":
    main()

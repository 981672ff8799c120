"""The context encoder's per-layer split (the `context_layers` graphs troupe runs, with its own
attention between them) equals the reference's whole step with the cache, on the tiny preset's
weights (needs torch)."""

import pytest

torch = pytest.importorskip("torch")

from troupe_onnx.armflow.export import build_model  # noqa: E402


def split_step(arnet, tokens, positions, modulation, past):
    """`SkipAdaLNTransformer.step` for S = 1 token per stream, through `layer_entry`,
    `layer_link` and `layer_exit` with attention written out: softmax over the cached keys and
    the new one, heads side by side."""
    b, c = tokens.shape
    heads = arnet.in_layers[0].attn.heads
    dh = c // heads

    def attend(i, q, k, v):
        keys = torch.cat([past[i][0], k.view(b, heads, 1, dh)], dim=2)  # [B, H, P+1, Dh]
        values = torch.cat([past[i][1], v.view(b, heads, 1, dh)], dim=2)
        weights = torch.softmax(keys @ q.view(b, heads, dh, 1), dim=2)  # [B, H, P+1, 1]
        return (weights * values).sum(dim=2).reshape(b, c)

    layers = len(arnet.blocks())
    modulation = modulation.transpose(1, 2)  # [B, L, 6, C] -> [B, 6, L, C]: mod(i) is [6, B, C]
    mod = lambda i: modulation[:, :, i].transpose(0, 1)  # noqa: E731
    x, q, k, v = arnet.layer_entry(tokens, positions, mod(0))
    skips = []
    for i in range(1, layers + 1):
        attention = attend(i - 1, q, k, v)
        if i == layers:
            return arnet.layer_exit(x, attention, mod(i - 1))
        skip = skips.pop() if i > layers // 2 else None
        x, q, k, v = arnet.layer_link(i, x, attention, mod(i - 1), mod(i), skip)
        if arnet.layer_skip_source(i):
            skips.append(x)


def test_the_split_equals_the_whole_step():
    torch.manual_seed(0)
    arnet = build_model("tiny", 0).armflow.arnet
    b, c, heads = 3, arnet.width, arnet.in_layers[0].attn.heads
    dh, p = c // heads, 5
    tokens = torch.randn(b, c)
    positions = torch.tensor([5, 5, 5])
    modulation = 0.3 * torch.randn(b, len(arnet.blocks()), 6, c)
    past = [(torch.randn(b, heads, p, dh), torch.randn(b, heads, p, dh)) for _ in arnet.blocks()]
    with torch.no_grad():
        want, _ = arnet.step(tokens[:, None], positions[:, None], modulation, past)
        got = split_step(arnet, tokens, positions, modulation, past)
    assert (got - want).abs().max().item() < 1e-5

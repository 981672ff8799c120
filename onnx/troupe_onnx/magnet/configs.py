"""The released sampling configurations (`docs/spec/magnet.md` §5.12), by the official YAML's
name. Their numbers go into every bundle's manifest (`sampling`), so the runtime runs them as
released; the model-side numbers come from the checkpoint."""

from __future__ import annotations

from troupe_onnx.magnet.guidance import GuidanceConfig, X0Guidance
from troupe_onnx.magnet.tasks import Sampling

_DD100_GUIDANCE = GuidanceConfig(smoothing=X0Guidance(2.0, 0.0, 1.0), foot_skating=X0Guidance(2.0, 0.0, 1.0))

RELEASED = {
    "dd100": Sampling(task="joint", subseq_len=16, ar_seq_stride=16, seq_len=200, samples=10,
                      root_mode="temporal_partner", guidance=_DD100_GUIDANCE),
    "dd100_partner_prediction": Sampling(task="partner_prediction", subseq_len=1, ar_seq_stride=8, seq_len=200,
                                         samples=10, root_mode="temporal_partner", guidance=_DD100_GUIDANCE),
    "dd100_turn_taking": Sampling(task="agentic_turn_taking", subseq_len=4, ar_seq_stride=8, seq_len=200,
                                  samples=10, root_mode="temporal", guidance=_DD100_GUIDANCE),
    "dd100_motion_control": Sampling(task="motion_control_live", subseq_len=4, ar_seq_stride=8, offset_proportion=0.75,
                                     seq_len=200, samples=1, root_mode="temporal", guidance=_DD100_GUIDANCE),
    "dd100_partner_inpainting": Sampling(task="partner_inpainting", schedule="full_sequence", subseq_len=2,
                                         ar_seq_stride=32, seq_len=150, samples=10, root_mode="temporal_partner",
                                         guidance=_DD100_GUIDANCE),
    "dd100_inbetweening": Sampling(task="inbetweening", subseq_len=2, ar_seq_stride=4, seq_len=64, samples=1,
                                   root_mode="temporal", keyframes=(0, 63), guidance=_DD100_GUIDANCE),
    "dd100_pp2joint": Sampling(task="pp2joint", subseq_len=1, ar_seq_stride=8, seq_len=400, samples=10,
                               root_mode="temporal_partner", guidance=_DD100_GUIDANCE),
    # The README's synchronous agents: no YAML ships; the turn-taking numbers (§5.8).
    "dd100_sync": Sampling(task="agentic_sync", subseq_len=4, ar_seq_stride=8, seq_len=200, samples=10,
                           root_mode="temporal", guidance=_DD100_GUIDANCE),
    "meta_trio": Sampling(task="joint", subseq_len=4, ar_seq_stride=16, seq_len=300, samples=10, eta=1.0,
                          root_mode="temporal", seed=111,
                          guidance=GuidanceConfig(smoothing=X0Guidance(3.0, 0.0, 1.0), foot_skating=X0Guidance(3.0, 0.0, 1.0))),
}

def released_for(persons: int) -> dict:
    """The released configurations a checkpoint of `persons` persons runs: DD100's at P = 2, the
    trio's at P = 3, DD100's joint generation otherwise (§11 A8)."""
    if persons == 2:
        return {k: v for k, v in RELEASED.items() if k != "meta_trio"}
    if persons == 3:
        return {"meta_trio": RELEASED["meta_trio"]}
    return {"dd100": RELEASED["dd100"]}

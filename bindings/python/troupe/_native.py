"""ctypes view of libtroupe: library lookup, the prototype of every C function, the option struct."""

from __future__ import annotations

import ctypes
import os
import sys
from pathlib import Path
from typing import Any, Callable, Sequence

ABI_VERSION = 1  # TROUPE_ABI_VERSION this package was written for

_LIB_NAMES = {"linux": "libtroupe.so", "darwin": "libtroupe.dylib", "win32": "troupe.dll"}
LIB_NAME = _LIB_NAMES.get(sys.platform, "libtroupe.so")

status = ctypes.c_int32
c_size = ctypes.c_size_t
f32p = ctypes.POINTER(ctypes.c_float)

# The C integer types of the API and their ranges. ctypes wraps an integer that does not fit
# (2**32 + 1 into a uint32_t is 1) without a word; troupe refuses it instead.
_INT_TYPES = (ctypes.c_int8, ctypes.c_uint8, ctypes.c_int16, ctypes.c_uint16, ctypes.c_int32,
              ctypes.c_uint32, ctypes.c_int64, ctypes.c_uint64, ctypes.c_size_t, ctypes.c_int,
              ctypes.c_uint, ctypes.c_long, ctypes.c_ulong)


def _int_range(ctype: type) -> tuple[int, int, str]:
    bits = 8 * ctypes.sizeof(ctype)
    signed = ctype(-1).value == -1
    if signed:
        return -(1 << (bits - 1)), (1 << (bits - 1)) - 1, f"int{bits}_t"
    return 0, (1 << bits) - 1, f"uint{bits}_t"


def checked_int(what: str, value: object, ctype: type) -> int:
    """`value` as an integer that fits the C type `ctype`; a `TypeError` for a non-integer (a
    bool, a float, a string) and an `InvalidArgument` (a `ValueError`) for one out of range,
    never the silent wrap ctypes would apply."""
    from .errors import InvalidArgument

    if isinstance(value, bool) or not hasattr(value, "__index__"):
        raise TypeError(f"{what} must be an integer, got {type(value).__name__}")
    number = value.__index__()  # type: ignore[attr-defined]
    low, high, name = _int_range(ctype)
    if not low <= number <= high:
        raise InvalidArgument(f"{what} = {number} does not fit {name} ({low} to {high})")
    return number


class CStruct(ctypes.Structure):
    """A C struct whose integer fields refuse values their type cannot hold (see
    `checked_int`) instead of wrapping them, and whose number fields refuse bools."""

    def __setattr__(self, name: str, value: object) -> None:
        for field in type(self)._fields_:
            if field[0] != name:
                continue
            what = f"{type(self).__name__}.{name}"
            if field[1] in _INT_TYPES:
                value = checked_int(what, value, field[1])
            elif field[1] in (ctypes.c_float, ctypes.c_double) and isinstance(value, bool):
                # A JSON `true` or a Python flag is not a number, though Python calls it 1.
                raise TypeError(f"{what} must be a number, got bool")
            break
        super().__setattr__(name, value)


def checked_function(name: str, fn: Callable[..., Any], argtypes: Sequence[Any]) -> Callable[..., Any]:
    """`fn` with its integer arguments checked as `checked_int` checks them (`fn` itself when it
    takes none)."""
    ints = [(i, t) for i, t in enumerate(argtypes) if t in _INT_TYPES]
    if not ints:
        return fn

    def call(*args: Any) -> Any:
        for i, ctype in ints:
            if i < len(args):
                checked_int(f"{name}: argument {i + 1}", args[i], ctype)
        return fn(*args)

    call.__name__ = call.__qualname__ = name
    call.__wrapped__ = fn  # type: ignore[attr-defined]
    return call


class SessionOptions(CStruct):
    """Mirror of `troupe_session_options` (checked against troupe_session_options_size())."""

    _fields_ = [
        ("struct_size", ctypes.c_uint32),
        ("steps", ctypes.c_uint32),
        ("seed", ctypes.c_uint64),
        ("cfg_scale", ctypes.c_float),
        ("context_capacity", ctypes.c_uint32),
        ("actor_latent", ctypes.c_int32),
        ("reserved", ctypes.c_uint32),
    ]


class ArmflowSessionOptions(CStruct):
    """Mirror of `troupe_armflow_session_options` (checked against
    troupe_armflow_session_options_size())."""

    _fields_ = [
        ("struct_size", ctypes.c_uint32),
        ("cfg_scale", ctypes.c_float),
        ("actor_latent", ctypes.c_int32),
        ("vae_windows", ctypes.c_int32),
    ]


class LimitValues(CStruct):
    """Mirror of `troupe_limit_values`."""

    _fields_ = [
        (name, ctypes.c_uint64)
        for name in (
            "max_bundle_bytes", "max_manifest_bytes", "max_archive_members", "max_graph_nodes",
            "max_tensor_elements", "max_steps", "max_cfg_scale", "max_abs_input",
            "max_frames_per_call", "max_queued_noise_tokens", "max_context_capacity", "max_people",
            "max_text_tokens", "max_manifest_dim", "max_prompt_bytes",
            "max_compute_threads",
        )
    ]


class Limits(CStruct):
    """Mirror of `troupe_limits`."""

    _fields_ = [("struct_size", ctypes.c_uint32), ("reserved", ctypes.c_uint32), ("values", LimitValues)]


class PersonClip(CStruct):
    """Mirror of `troupe_person_clip`."""

    _fields_ = [("name", ctypes.c_char_p), ("positions", ctypes.POINTER(ctypes.c_float)), ("n_frames", ctypes.c_size_t)]


class CallBudget(CStruct):
    """Mirror of `troupe_call_budget`."""

    _fields_ = [("max_work", ctypes.c_uint64), ("max_seconds", ctypes.c_double)]


MAX_STAGES = 8  # TROUPE_MAX_STAGES


class GroupOptions(CStruct):
    """Mirror of `troupe_group_options` (checked against troupe_umf_options_size())."""

    _fields_ = [
        ("struct_size", ctypes.c_uint32),
        ("stage_count", ctypes.c_uint32),
        ("seed", ctypes.c_uint64),
        ("cfg_scale", ctypes.c_float),
        ("reaction_solver", ctypes.c_uint32),
        ("reaction_steps", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
        ("stage_solver", ctypes.c_uint32 * MAX_STAGES),
        ("stage_steps", ctypes.c_uint32 * MAX_STAGES),
    ]


MAGNET_MAX_KEYFRAMES = 8  # TROUPE_MAGNET_MAX_KEYFRAMES
MAGNET_SEED, MAGNET_ETA, MAGNET_NO_X0_GUIDANCE, MAGNET_KEYFRAMES = 1, 2, 4, 8  # TROUPE_MAGNET_*


class ArflowOptions(CStruct):
    """Mirror of `troupe_arflow_options` (checked against troupe_arflow_options_size())."""

    _fields_ = [
        ("struct_size", ctypes.c_uint32),
        ("steps", ctypes.c_uint32),
        ("guidance", ctypes.c_float),
        ("weight", ctypes.c_float),
        ("eta", ctypes.c_float),
        ("d_safe", ctypes.c_float),
        ("sigma", ctypes.c_float),
        ("flags", ctypes.c_uint32),
        ("seed", ctypes.c_uint64),
    ]


ARFLOW_SQUARED_HINGE, ARFLOW_UNGUIDED_BACKPROJECTION, ARFLOW_VARIANCE_PRESERVING = 1, 2, 4


class MagnetOptions(CStruct):
    """Mirror of `troupe_magnet_options` (checked against troupe_magnet_options_size())."""

    _fields_ = [
        ("struct_size", ctypes.c_uint32),
        ("samples", ctypes.c_uint32),
        ("steps", ctypes.c_uint32),
        ("seq_len", ctypes.c_uint32),
        ("flags", ctypes.c_uint32),
        ("keyframe_count", ctypes.c_uint32),
        ("seed", ctypes.c_uint64),
        ("eta", ctypes.c_float),
        ("reserved", ctypes.c_uint32),
        ("keyframes", ctypes.c_uint32 * MAGNET_MAX_KEYFRAMES),
    ]


class GroupNoise(CStruct):
    """Mirror of `troupe_group_noise`."""

    _fields_ = [
        ("prior", ctypes.POINTER(ctypes.c_float)),
        ("prior_len", ctypes.c_size_t),
        ("jumps", ctypes.POINTER(ctypes.c_float)),
        ("jumps_len", ctypes.c_size_t),
        ("reactions", ctypes.POINTER(ctypes.c_float)),
        ("reactions_len", ctypes.c_size_t),
    ]


class ClipOptions(CStruct):
    """Mirror of `troupe_armflow_clip_options` (checked against
    troupe_armflow_clip_options_size())."""

    _fields_ = [
        ("struct_size", ctypes.c_uint32),
        ("steps", ctypes.c_uint32),
        ("seed", ctypes.c_uint64),
        ("cfg_scale", ctypes.c_float),
        ("reserved", ctypes.c_uint32),
    ]


class ClipNoise(CStruct):
    """Mirror of `troupe_clip_noise`."""

    _fields_ = [
        ("actor_posterior", ctypes.POINTER(ctypes.c_float)),
        ("actor_posterior_len", ctypes.c_size_t),
        ("reactor_noise", ctypes.POINTER(ctypes.c_float)),
        ("reactor_noise_len", ctypes.c_size_t),
    ]


class JointsFormat(CStruct):
    """Mirror of `troupe_joints_format`."""

    _fields_ = [
        ("struct_size", ctypes.c_uint32),
        ("units", ctypes.c_uint32),
        ("up_axis", ctypes.c_uint32),
        ("handedness", ctypes.c_uint32),
        ("fps", ctypes.c_float),
        ("reserved", ctypes.c_uint32),
    ]


class Placement(CStruct):
    """Mirror of `troupe_placement` (a plain value)."""

    _fields_ = [
        ("floor", ctypes.c_double),
        ("origin_x", ctypes.c_double),
        ("origin_z", ctypes.c_double),
        ("heading", ctypes.c_double * 4),
    ]


class PoseBuffers(CStruct):
    """Mirror of `troupe_pose_buffers`."""

    _fields_ = [
        ("positions", ctypes.POINTER(ctypes.c_float)),
        ("positions_len", ctypes.c_size_t),
        ("rotations", ctypes.POINTER(ctypes.c_float)),
        ("rotations_len", ctypes.c_size_t),
        ("rotations_6d", ctypes.POINTER(ctypes.c_float)),
        ("rotations_6d_len", ctypes.c_size_t),
        ("contacts", ctypes.POINTER(ctypes.c_float)),
        ("contacts_len", ctypes.c_size_t),
    ]


LOG_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int32, ctypes.c_char_p, ctypes.c_char_p)
PROGRESS_FN = ctypes.CFUNCTYPE(ctypes.c_int32, ctypes.c_void_p, ctypes.c_uint64, ctypes.c_uint64)

model_p = ctypes.c_void_p
session_p = ctypes.c_void_p
stream_p = ctypes.c_void_p
bvh_p = ctypes.c_void_p
rig_p = ctypes.c_void_p
retargeter_p = ctypes.c_void_p
fmt_p = ctypes.POINTER(JointsFormat)
placement_p = ctypes.POINTER(Placement)

# name: (restype, argtypes) for every function of include/troupe.h.
PROTOTYPES: dict[str, tuple[Any, list[Any]]] = {
    "troupe_version_string": (ctypes.c_char_p, []),
    "troupe_version_number": (ctypes.c_uint32, []),
    "troupe_abi_version": (ctypes.c_uint32, []),
    "troupe_status_name": (ctypes.c_char_p, [status]),
    "troupe_last_error_message": (ctypes.c_char_p, []),
    "troupe_last_error_copy": (status, [ctypes.c_char_p, c_size, ctypes.POINTER(c_size)]),
    "troupe_set_log_callback": (status, [LOG_FN, ctypes.c_void_p, ctypes.c_int32]),
    "troupe_limits_get": (status, [ctypes.POINTER(Limits), c_size]),
    "troupe_set_load_threads": (None, [c_size]),
    "troupe_set_progress_callback": (None, [PROGRESS_FN, ctypes.c_void_p]),
    "troupe_set_call_budget": (status, [ctypes.POINTER(CallBudget)]),
    "troupe_load_threads": (c_size, []),
    "troupe_set_compute_threads": (status, [c_size]),
    "troupe_compute_threads": (c_size, []),
    "troupe_model_load_file": (status, [ctypes.c_char_p, ctypes.POINTER(model_p)]),
    "troupe_model_load_memory": (status, [ctypes.c_char_p, c_size, ctypes.POINTER(model_p)]),
    "troupe_model_free": (None, [model_p]),
    "troupe_model_frame_dim": (c_size, [model_p]),
    "troupe_model_fps": (c_size, [model_p]),
    "troupe_model_identity": (status, [model_p, ctypes.c_void_p]),
    "troupe_model_frames_per_token": (c_size, [model_p]),
    "troupe_model_latency_frames": (c_size, [model_p]),
    "troupe_model_condition_dim": (c_size, [model_p]),
    "troupe_model_latent_dim": (c_size, [model_p]),
    "troupe_model_condition_label_count": (c_size, [model_p]),
    "troupe_model_condition_label": (ctypes.c_char_p, [model_p, c_size]),
    "troupe_model_condition_for_label": (status, [model_p, ctypes.c_char_p, f32p, c_size]),
    "troupe_model_reduced_precision_count": (c_size, [model_p]),
    "troupe_model_reduced_precision_graph": (ctypes.c_char_p, [model_p, c_size]),
    "troupe_model_reduced_precision_weights": (ctypes.c_char_p, [model_p, c_size]),
    "troupe_model_max_output_frames": (c_size, [model_p, c_size]),
    "troupe_session_options_size": (c_size, []),
    "troupe_session_options_init": (status, [model_p, ctypes.POINTER(SessionOptions), c_size]),
    "troupe_session_new": (status, [model_p, ctypes.POINTER(SessionOptions), ctypes.POINTER(session_p)]),
    "troupe_armflow_session_options_size": (c_size, []),
    "troupe_armflow_session_options_init": (status, [model_p, ctypes.POINTER(ArmflowSessionOptions), c_size]),
    "troupe_armflow_session_new": (status, [model_p, ctypes.POINTER(SessionOptions),
                                            ctypes.POINTER(ArmflowSessionOptions), ctypes.POINTER(session_p)]),
    "troupe_model_family": (ctypes.c_char_p, [model_p]),
    "troupe_session_free": (None, [session_p]),
    "troupe_session_step": (status, [session_p, f32p, c_size, f32p, c_size, ctypes.POINTER(c_size)]),
    "troupe_sessions_step": (status, [ctypes.POINTER(session_p), c_size, ctypes.POINTER(f32p), ctypes.POINTER(c_size),
                                      ctypes.POINTER(f32p), ctypes.POINTER(c_size), ctypes.POINTER(c_size)]),
    "troupe_session_output_frames": (status, [session_p, c_size, ctypes.POINTER(c_size)]),
    "troupe_session_snapshot": (status, [session_p, ctypes.c_void_p, c_size, ctypes.POINTER(c_size)]),
    "troupe_session_restore": (status, [model_p, ctypes.c_char_p, c_size, ctypes.POINTER(session_p)]),
    "troupe_session_restore_sealed": (status, [model_p, ctypes.c_char_p, c_size, ctypes.c_char_p, c_size,
                                               ctypes.POINTER(session_p)]),
    "troupe_snapshot_seal": (status, [ctypes.c_char_p, c_size, ctypes.c_char_p, c_size, ctypes.c_void_p, c_size,
                                      ctypes.POINTER(c_size)]),
    "troupe_session_reset": (status, [session_p]),
    "troupe_session_set_seed": (status, [session_p, ctypes.c_uint64]),
    "troupe_session_set_steps": (status, [session_p, ctypes.c_uint32]),
    "troupe_session_set_cfg_scale": (status, [session_p, ctypes.c_float]),
    "troupe_session_set_condition": (status, [session_p, f32p, c_size]),
    "troupe_armflow_session_queue_noise": (status, [session_p, f32p, f32p, c_size]),
    "troupe_session_queue_normals": (status, [session_p, f32p, c_size]),
    "troupe_session_capabilities": (status, [session_p, ctypes.POINTER(ctypes.c_uint32)]),
    "troupe_umf_options_size": (c_size, []),
    "troupe_umf_options_init": (status, [model_p, ctypes.POINTER(GroupOptions), c_size]),
    "troupe_umf_stages": (c_size, [model_p]),
    "troupe_umf_tokens": (c_size, [model_p]),
    "troupe_model_clip_frames": (c_size, [model_p]),
    "troupe_umf_noise_lengths": (
        status, [model_p, ctypes.c_uint32, ctypes.POINTER(c_size), ctypes.POINTER(c_size), ctypes.POINTER(c_size)]),
    "troupe_umf_generate": (status, [
        model_p, ctypes.POINTER(GroupOptions), f32p, c_size, ctypes.c_uint32, ctypes.POINTER(GroupNoise),
        f32p, c_size, f32p, c_size]),
    "troupe_magnet_options_size": (c_size, []),
    "troupe_magnet_options_init": (status, [ctypes.POINTER(MagnetOptions), c_size]),
    "troupe_arflow_options_size": (c_size, []),
    "troupe_arflow_options_init": (status, [model_p, ctypes.POINTER(ArflowOptions), c_size]),
    "troupe_arflow_generate": (status, [model_p, ctypes.POINTER(ArflowOptions), f32p, c_size, f32p, c_size]),
    "troupe_arflow_generate_with_draws": (status, [model_p, ctypes.POINTER(ArflowOptions), f32p, c_size, f32p, c_size,
                                                   ctypes.POINTER(c_size), f32p, c_size]),
    "troupe_motion_penetration_metrics": (status, [f32p, f32p, c_size, ctypes.POINTER(c_size),
                                            ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_double),
                                            ctypes.POINTER(ctypes.c_double)]),
    "troupe_magnet_people": (c_size, [model_p]),
    "troupe_magnet_config_count": (c_size, [model_p]),
    "troupe_magnet_config": (ctypes.c_char_p, [model_p, c_size]),
    "troupe_magnet_output_shape": (status, [model_p, ctypes.c_char_p, ctypes.POINTER(MagnetOptions), c_size,
                                            ctypes.POINTER(c_size), ctypes.POINTER(c_size), ctypes.POINTER(c_size)]),
    "troupe_magnet_generate": (status, [model_p, ctypes.c_char_p, ctypes.POINTER(MagnetOptions), f32p, c_size,
                                        ctypes.POINTER(ctypes.c_uint8), f32p, c_size]),
    "troupe_magnet_generate_with_draws": (status, [
        model_p, ctypes.c_char_p, ctypes.POINTER(MagnetOptions), f32p, c_size, ctypes.POINTER(ctypes.c_uint8),
        f32p, c_size, ctypes.POINTER(c_size), f32p, c_size]),
    "troupe_armflow_clip_tokens": (c_size, [model_p]),
    "troupe_model_text_token_dim": (c_size, [model_p]),
    "troupe_armflow_clip_options_size": (c_size, []),
    "troupe_armflow_clip_options_init": (status, [model_p, ctypes.POINTER(ClipOptions), c_size]),
    "troupe_armflow_clip_generate_with_options": (status, [
        model_p, ctypes.POINTER(ClipOptions), f32p, c_size, f32p, c_size, ctypes.POINTER(ClipNoise),
        f32p, c_size, f32p, c_size]),
    "troupe_armflow_clip_generate": (status, [
        model_p, f32p, c_size, f32p, c_size, ctypes.c_uint64, ctypes.c_uint32, ctypes.POINTER(ClipNoise),
        f32p, c_size, f32p, c_size]),
    "troupe_text_encode": (status, [model_p, f32p, c_size, c_size, f32p, c_size]),
    "troupe_model_takes_prompts": (c_size, [model_p]),
    "troupe_text_prompt_encode": (status, [model_p, ctypes.c_char_p, f32p, c_size]),
    "troupe_session_set_prompt": (status, [session_p, ctypes.c_char_p]),
    "troupe_magnet_session_set_partner_opening": (status, [session_p, f32p, ctypes.c_size_t]),
    "troupe_magnet_session_set_early_emission": (status, [session_p, ctypes.c_int32]),
    "troupe_session_set_penetration_guard": (status, [session_p, ctypes.c_int32, ctypes.c_float, ctypes.c_float]),
    "troupe_session_set_root_smoothing": (status, [session_p, ctypes.c_int32, ctypes.c_float]),
    "troupe_armflow_session_set_recentring": (status, [session_p, ctypes.c_int32, ctypes.c_float]),
    "troupe_session_set_foot_lock": (status, [session_p, ctypes.c_int32, ctypes.c_float, ctypes.c_uint32, ctypes.c_float]),
    "troupe_arflow_session_set_options": (status, [session_p, ctypes.POINTER(ArflowOptions)]),
    "troupe_magnet_session_set_live_config": (status, [session_p, ctypes.c_char_p]),
    "troupe_joints_format_init": (status, [fmt_p, c_size]),
    "troupe_motion_joint_count": (c_size, []),
    "troupe_motion_joint_name": (ctypes.c_char_p, [c_size]),
    "troupe_motion_skeleton": (status, [ctypes.POINTER(ctypes.c_int32), c_size, f32p, c_size]),
    "troupe_motion_smplx145_positions": (status, [f32p, c_size, f32p, c_size]),
    "troupe_motion_encoded_frames": (status, [model_p, fmt_p, c_size, ctypes.POINTER(c_size)]),
    "troupe_motion_encode": (status, [model_p, fmt_p, f32p, c_size, placement_p, f32p, c_size,
                                      ctypes.POINTER(c_size), placement_p]),
    "troupe_motion_decode": (status, [model_p, fmt_p, placement_p, f32p, c_size, ctypes.POINTER(PoseBuffers)]),
    "troupe_motion_stream_new": (status, [model_p, fmt_p, placement_p, ctypes.POINTER(stream_p)]),
    "troupe_motion_stream_latency_frames": (c_size, []),
    "troupe_motion_stream_max_frames": (c_size, [stream_p]),
    "troupe_motion_stream_push": (status, [stream_p, f32p, c_size, f32p, c_size, ctypes.POINTER(c_size)]),
    "troupe_motion_stream_placement": (status, [stream_p, placement_p]),
    "troupe_motion_stream_reset": (status, [stream_p, placement_p]),
    "troupe_motion_stream_free": (None, [stream_p]),
    "troupe_bvh_read": (status, [ctypes.c_char_p, ctypes.c_char_p, ctypes.c_uint32, ctypes.POINTER(bvh_p)]),
    "troupe_bvh_frames": (c_size, [bvh_p]),
    "troupe_bvh_joint_source": (ctypes.c_char_p, [bvh_p, c_size]),
    "troupe_bvh_inferred": (ctypes.c_char_p, [bvh_p]),
    "troupe_bvh_format": (status, [bvh_p, fmt_p, c_size]),
    "troupe_bvh_positions": (status, [bvh_p, f32p, c_size]),
    "troupe_bvh_free": (None, [bvh_p]),
    "troupe_bvh_write": (status, [ctypes.c_char_p, f32p, c_size, c_size, fmt_p, ctypes.POINTER(ctypes.c_char_p),
                                  ctypes.c_uint32, ctypes.c_uint32]),
    "troupe_rig_from_bvh": (status, [ctypes.c_char_p, ctypes.c_uint32, ctypes.c_uint32, ctypes.c_char_p,
                                     ctypes.POINTER(rig_p)]),
    "troupe_rig_from_json": (status, [ctypes.c_char_p, ctypes.c_char_p, ctypes.POINTER(rig_p)]),
    "troupe_rig_from_gltf": (status, [ctypes.c_char_p, c_size, ctypes.c_char_p, ctypes.POINTER(rig_p)]),
    "troupe_rig_joint_count": (c_size, [rig_p]),
    "troupe_rig_joint_name": (ctypes.c_char_p, [rig_p, c_size]),
    "troupe_rig_free": (None, [rig_p]),
    "troupe_rig_retargeter_new": (status, [rig_p, fmt_p, ctypes.c_uint32, ctypes.POINTER(retargeter_p)]),
    "troupe_rig_retarget_push": (status, [retargeter_p, f32p, c_size, f32p, c_size, f32p, ctypes.POINTER(c_size)]),
    "troupe_rig_retarget_reset": (status, [retargeter_p]),
    "troupe_rig_retargeter_mapping": (status, [retargeter_p, ctypes.POINTER(ctypes.c_int64), c_size]),
    "troupe_rig_retargeter_free": (None, [retargeter_p]),
    "troupe_rig_retarget_clip": (status, [rig_p, f32p, c_size, fmt_p, ctypes.c_uint32, f32p, c_size, f32p, c_size,
                                          ctypes.POINTER(c_size)]),
    "troupe_gltf_write_people": (status, [ctypes.c_char_p, rig_p, ctypes.POINTER(PersonClip), c_size, fmt_p,
                                          ctypes.c_uint32]),
    "troupe_gltf_write": (status, [ctypes.c_char_p, rig_p, f32p, c_size, c_size, fmt_p,
                                   ctypes.POINTER(ctypes.c_char_p), ctypes.c_uint32]),
    "troupe_rig_bvh_write": (status, [ctypes.c_char_p, rig_p, f32p, c_size, fmt_p, ctypes.c_uint32, ctypes.c_uint32]),
    "troupe_rig_fbx_write": (status, [ctypes.c_char_p, rig_p, f32p, c_size, fmt_p, ctypes.c_uint32, ctypes.c_uint32]),
    "troupe_session_set_joints_format": (status, [session_p, fmt_p]),
    "troupe_session_step_joints": (status, [session_p, f32p, c_size, ctypes.POINTER(PoseBuffers), c_size,
                                            ctypes.POINTER(c_size)]),
    "troupe_session_joints_ready_after": (status, [session_p, c_size, ctypes.POINTER(c_size)]),
    "troupe_session_joints_placement": (status, [session_p, placement_p]),
    "troupe_model_joints_latency_frames": (c_size, [model_p]),
    "troupe_motion_write_json": (status, [ctypes.c_char_p, f32p, c_size, c_size, fmt_p, ctypes.POINTER(ctypes.c_char_p)]),
    "troupe_viewer_write": (status, [ctypes.c_char_p, ctypes.c_char_p, f32p, c_size, c_size, fmt_p,
                                     ctypes.POINTER(ctypes.c_char_p), ctypes.c_char_p]),
}


def _candidates() -> list[Path]:
    """Where the library is looked for, in order: TROUPE_LIBRARY_PATH (a file, or a folder
    holding it) alone when set; else next to this package (an installed wheel); else, for the
    package used from a checkout of the repository, where `cargo build --release` and the
    README's first command leave it."""
    env = os.environ.get("TROUPE_LIBRARY_PATH")
    if env:
        p = Path(env)
        return [p / LIB_NAME if p.is_dir() else p]
    here = Path(__file__).resolve().parent
    candidates = [here / LIB_NAME]
    repo = here.parents[2] if len(here.parents) > 2 else None
    if repo is not None and (repo / "Cargo.toml").is_file() and (repo / "include" / "troupe.h").is_file():
        target = repo / os.environ.get("CARGO_TARGET_DIR", "target")  # a relative one is the repository's
        candidates.append(target / "release" / LIB_NAME)
    return candidates


def load() -> ctypes.CDLL:
    """Opens libtroupe (see `_candidates` for where it is looked for) and declares every
    prototype. CDLL releases the GIL during each call."""
    tried = []
    for path in _candidates():
        if path.exists():
            lib = ctypes.CDLL(str(path))
            break
        tried.append(str(path))
    else:
        raise OSError(
            f"libtroupe not found (looked at {', '.join(tried)}); build it with "
            "`cargo build --release`, or set TROUPE_LIBRARY_PATH to a built libtroupe, or install "
            "the wheel (docs/INSTALL.md)"
        )
    for name, (restype, argtypes) in PROTOTYPES.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
        setattr(lib, name, checked_function(name, fn, argtypes))
    abi = lib.troupe_abi_version()
    if abi != ABI_VERSION:
        raise OSError(f"{path} speaks troupe ABI {abi}, this package needs {ABI_VERSION}")
    return lib

/*
 * troupe: real-time human interaction motion generation.
 *
 * GENERATED from src/ffi/ by cbindgen and tests/c_header.rs -- do not edit.
 * Regenerate with: TROUPE_BLESS=1 cargo test --test c_header
 *
 * Usage
 *   troupe_model *model;                      // 1. load a bundle (once, any thread)
 *   troupe_model_load_file("bundle.tar", &model);
 *   troupe_session *s;                        // 2. one stream per actor/user
 *   troupe_session_new(model, NULL, &s);
 *   troupe_session_step(s, frames, n, out, cap, &n_out);   // 3. every frame or tick
 *   troupe_session_free(s);                   // 4. free in any order
 *   troupe_model_free(model);
 *
 * Families. A bundle is one model family; what it offers:
 *   armflow  online reaction: troupe_session streams the reactor to an actor, a token of
 *            4 frames at a time; official clips with troupe_armflow_clip_generate.
 *   umf      text to a group of any size: troupe_umf_generate (no streaming).
 *   magnet   multi-agent diffusion forcing: troupe_magnet_generate runs every released task;
 *            troupe_session streams a live partner (troupe_magnet_session_* settings).
 *   arflow   action to reaction with penetration guidance: troupe_arflow_generate; its online
 *            variant streams through troupe_session (troupe_arflow_session_set_options).
 *   A call the bundle's family does not offer returns TROUPE_ERR_UNSUPPORTED. Family calls
 *   are named troupe_<family>_...; everything else serves every family that has it.
 *
 * Threads. troupe_model is immutable: every function taking a `const troupe_model *` may be
 *   called from any thread at any time. A troupe_session (and a troupe_motion_stream) is used
 *   by one thread at a time and may move between threads; a call on one that another thread
 *   is using fails with TROUPE_ERR_BUSY and does nothing. Distinct sessions run in parallel.
 *   By default the library starts threads only while loading (troupe_set_load_threads bounds
 *   them, all joined before the load returns); troupe_set_compute_threads(n >= 2) opts in to a
 *   library-owned pool the matrix products split over. No global initialisation is needed.
 *
 * Ownership. Handles returned through an out-parameter belong to the caller and are freed
 *   with their _free function; _free(NULL) is a no-op. A session keeps its model alive, so the
 *   two may be freed in any order. Inputs (frames, paths, bytes) are borrowed for the call
 *   only; outputs go into caller-owned buffers; strings returned as `const char *` belong to
 *   the library (static, or alive as long as the handle they came from). Frames are contiguous
 *   row-major float32 [frames][frame_dim]; input and output buffers must not overlap.
 *
 * Errors. Every fallible function returns a troupe_status: TROUPE_OK or a TROUPE_ERR_* code.
 *   Out-parameters are written only on success (out-handles are set to NULL on entry), and a
 *   failed call leaves every handle as it was. troupe_last_error_message() then says what
 *   failed; it is per thread and cleared by the next successful status-returning call.
 *   Sizes from a file or a caller are checked against troupe_limits_get before anything is
 *   allocated; NaN, infinite and out-of-range inputs are refused; a call that would return a
 *   non-finite value fails with TROUPE_ERR_INFERENCE instead. No panic crosses this
 *   boundary: an internal one returns TROUPE_ERR_PANIC and poisons the session involved
 *   (TROUPE_ERR_POISONED until troupe_session_reset).
 *
 * Compatibility (docs/ABI.md). Versioned structs start with `uint32_t struct_size`: fill them
 *   with their _init function, which sets it. The library accepts every older size (fields the
 *   caller did not know take their defaults) and newer sizes whose extra bytes are zero.
 *   Functions and constants are only ever added within ABI version 1; old names stay as
 *   deprecated aliases until 2.0. Long calls report progress to the calling thread's
 *   troupe_set_progress_callback, which may cancel them (TROUPE_ERR_CANCELLED); logging is
 *   silent unless troupe_set_log_callback is used.
 */

#ifndef TROUPE_H
#define TROUPE_H

#include <stddef.h>
#include <stdint.h>

/* Version of this header, from Cargo.toml; compare with troupe_version_number(). */
#define TROUPE_VERSION_MAJOR 0
#define TROUPE_VERSION_MINOR 2
#define TROUPE_VERSION_PATCH 0
#define TROUPE_VERSION_STRING "0.2.0"
#define TROUPE_VERSION_NUMBER 512

/* Marks the deprecated names; define TROUPE_NO_DEPRECATION_WARNINGS to silence them. */
#if defined(TROUPE_NO_DEPRECATION_WARNINGS)
#define TROUPE_DEPRECATED(note)
#elif defined(__cplusplus) && __cplusplus >= 201402L
#define TROUPE_DEPRECATED(note) [[deprecated(note)]]
#elif defined(__GNUC__) || defined(__clang__)
#define TROUPE_DEPRECATED(note) __attribute__((deprecated(note)))
#elif defined(_MSC_VER)
#define TROUPE_DEPRECATED(note) __declspec(deprecated(note))
#else
#define TROUPE_DEPRECATED(note)
#endif

#ifdef __cplusplus
extern "C" {
#endif

/*
 * Sections
 *    1. Version and ABI
 *    2. Status codes and errors
 *    3. Limits
 *    4. Threads, logging and progress
 *    5. Model
 *    6. Session
 *    7. Text prompts
 *    8. Motion
 *    9. Rigs and glTF
 *   10. Session motion
 *   11. ARMFlow
 *   12. UMF
 *   13. MAGNet
 *   14. ARFlow
 *   15. Viewer
 *   16. Deprecated names
 */

/* ============================================================================================
 * 1. Version and ABI
 *
 * What this library is; compare with the TROUPE_VERSION_* macros above.
 * ============================================================================================ */

/**
 * ABI version of this library. Bumped on every incompatible change of the C ABI; bindings
 * check `troupe_abi_version() == TROUPE_ABI_VERSION` when they load the library.
 */
#define TROUPE_ABI_VERSION 1

/**
 * The library version, e.g. `"0.2.0"`.
 *
 * Returns a static NUL-terminated string (never free it). Thread-safe.
 */
const char *troupe_version_string(void);

/**
 * The library version packed as `(major << 16) | (minor << 8) | patch`; equals
 * `TROUPE_VERSION_NUMBER` of the header the caller compiled against when they match. Thread-safe.
 */
uint32_t troupe_version_number(void);

/**
 * The ABI version the library was built with (see `TROUPE_ABI_VERSION`). Thread-safe.
 */
uint32_t troupe_abi_version(void);

/* ============================================================================================
 * 2. Status codes and errors
 *
 * What every fallible call returns, and the calling thread's last error message.
 * ============================================================================================ */

/**
 * Status returned by every fallible function: `TROUPE_OK` or one of the `TROUPE_ERR_*` codes.
 */
typedef int32_t troupe_status;

/**
 * Success.
 */
#define TROUPE_OK 0

/**
 * A required pointer argument was NULL.
 */
#define TROUPE_ERR_NULL_ARG 1

/**
 * An argument is out of range, malformed, or non-finite.
 */
#define TROUPE_ERR_INVALID_ARG 2

/**
 * A buffer's size does not match what the model needs (e.g. noise length).
 */
#define TROUPE_ERR_SHAPE 3

/**
 * The output buffer cannot hold the frames this call would return.
 */
#define TROUPE_ERR_BUFFER_TOO_SMALL 4

/**
 * A file could not be read or written.
 */
#define TROUPE_ERR_IO 5

/**
 * The bundle is corrupt, unsupported, or inconsistent with its graphs.
 */
#define TROUPE_ERR_MODEL 6

/**
 * A network failed while running.
 */
#define TROUPE_ERR_INFERENCE 7

/**
 * The session panicked earlier; only `troupe_session_reset` and `troupe_session_free` work.
 */
#define TROUPE_ERR_POISONED 8

/**
 * An internal panic was caught; a session involved is poisoned.
 */
#define TROUPE_ERR_PANIC 9

/**
 * The handle is in use by another thread: a session or joint stream is used from one thread
 * at a time. Nothing was done; the call may be retried once the other thread is done.
 */
#define TROUPE_ERR_BUSY 10

/**
 * The call was stopped by the calling thread's progress callback
 * (`troupe_set_progress_callback`); nothing was written.
 */
#define TROUPE_ERR_CANCELLED 11

/**
 * The bundle's family does not offer this call or setting (a group asked of an `armflow`
 * bundle, a MAGNet setting of an ARMFlow stream); the message names the family and the one
 * that does. Nothing was done.
 */
#define TROUPE_ERR_UNSUPPORTED 12

/**
 * A static name for a status code (`"TROUPE_OK"`, `"TROUPE_ERR_NULL_ARG"`, ...), or
 * `"TROUPE_ERR_UNKNOWN"`. Never free it. Thread-safe.
 */
const char *troupe_status_name(troupe_status status);

/**
 * The message of the last failed troupe call on this thread, or NULL if the last call
 * succeeded.
 *
 * The string is owned by the library and valid until the next troupe call on the same thread;
 * copy it (or use `troupe_last_error_copy`) to keep it. Thread-safe (per-thread state).
 */
const char *troupe_last_error_message(void);

/**
 * Copies the last error message of this thread into `buf` (capacity `capacity` bytes, always
 * NUL-terminated when `capacity > 0`, truncated if needed) and writes the bytes the whole
 * message needs, NUL included, to `*needed` (1 when there is no error). `buf` may be NULL when
 * `capacity` is 0. Does not clear the error.
 *
 * Returns `TROUPE_OK`, or `TROUPE_ERR_NULL_ARG` if `needed` is NULL or `buf` is NULL with a
 * non-zero capacity. Thread-safe.
 *
 * # Safety
 * `buf` must be writable for `capacity` bytes; `needed` must be writable.
 */
troupe_status troupe_last_error_copy(char *buf, size_t capacity, size_t *needed);

/* ============================================================================================
 * 3. Limits
 *
 * The bounds every size from a file or a caller is checked against.
 * ============================================================================================ */

/**
 * troupe's limits, one value per build (`troupe::Limits` in Rust), inside `troupe_limits`. A
 * call given more than a limit fails, naming it, before anything is allocated.
 */
typedef struct troupe_limit_values {
  /**
   * Bytes of a whole bundle: the archive file or memory, or the sum of a directory bundle's
   * files. The paper-size ARMFlow bundle is about 200 MB.
   */
  uint64_t max_bundle_bytes;
  /**
   * Bytes of `troupe.json`.
   */
  uint64_t max_manifest_bytes;
  /**
   * Members of a tar bundle (graphs, manifest, directories).
   */
  uint64_t max_archive_members;
  /**
   * Nodes of one ONNX graph.
   */
  uint64_t max_graph_nodes;
  /**
   * Elements of any one tensor a graph declares or would build from constants.
   */
  uint64_t max_tensor_elements;
  /**
   * Solver steps per token or per stage (MeanFlow, Euler, RK4).
   */
  uint64_t max_steps;
  /**
   * Magnitude of a classifier-free guidance scale.
   */
  uint64_t max_cfg_scale;
  /**
   * Magnitude of a motion feature or conditioning value a caller passes in.
   */
  uint64_t max_abs_input;
  /**
   * Motion frames passed to one call (a step, a clip, an encoding).
   */
  uint64_t max_frames_per_call;
  /**
   * Tokens of noise queued on a session and not yet used.
   */
  uint64_t max_queued_noise_tokens;
  /**
   * Tokens kept in a session's context cache.
   */
  uint64_t max_context_capacity;
  /**
   * People in one generated group.
   */
  uint64_t max_people;
  /**
   * Text tokens passed to the text branch: CLIP's context, the most its text tower makes.
   */
  uint64_t max_text_tokens;
  /**
   * Any integer a manifest declares outside `producer` (layers, heads, dimensions, token and
   * frame counts, steps).
   */
  uint64_t max_manifest_dim;
  /**
   * Bytes of UTF-8 in one text prompt (a few hundred make 77 CLIP tokens; the rest is cut).
   */
  uint64_t max_prompt_bytes;
  /**
   * Threads of the compute pool (`troupe_set_compute_threads`).
   */
  uint64_t max_compute_threads;
} troupe_limit_values;

/**
 * troupe's limits, for `troupe_limits_get`. A call given more than a limit fails with
 * `TROUPE_ERR_INVALID_ARG` (a caller's value) or `TROUPE_ERR_MODEL` / `TROUPE_ERR_IO` (a
 * bundle's), naming the limit, before anything is allocated. Fields are only ever appended.
 */
typedef struct troupe_limits {
  /**
   * `sizeof(troupe_limits)` as the caller compiled it (set by `troupe_limits_get`).
   */
  uint32_t struct_size;
  /**
   * Always 0.
   */
  uint32_t reserved;
  /**
   * The limits.
   */
  struct troupe_limit_values values;
} troupe_limits;

/**
 * Writes troupe's limits to `out` (pass `sizeof(troupe_limits)` as `size`; the library writes
 * only that many bytes, zeroing fields it does not know).
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (`size` smaller than the
 * first version of the struct). Thread-safe.
 *
 * # Safety
 * `out` must be writable for `size` bytes.
 */
troupe_status troupe_limits_get(struct troupe_limits *out, size_t size);

/* ============================================================================================
 * 4. Threads, logging and progress
 *
 * Process-wide settings: threads troupe may start, where its log goes, and the calling
 * thread's progress callback for long calls.
 * ============================================================================================ */

/**
 * Log level: something failed.
 */
#define TROUPE_LOG_ERROR 1

/**
 * Log level: something looks wrong.
 */
#define TROUPE_LOG_WARN 2

/**
 * Log level: milestones (model loaded, session created).
 */
#define TROUPE_LOG_INFO 3

/**
 * Log level: details, including every error returned to the caller.
 */
#define TROUPE_LOG_DEBUG 4

/**
 * A log callback: `level` is one of `TROUPE_LOG_*`; `target` and `message` are NUL-terminated
 * and valid only during the call.
 */
typedef void (*troupe_log_fn)(void *user_data, int32_t level, const char *target, const char *message);

/**
 * A progress callback: `done` of `total` units of a long call are finished. Return 0 to go on,
 * anything else to cancel the call (it then fails with `TROUPE_ERR_CANCELLED`, having written
 * nothing). Called on the thread that made the call, between units of work; it must not unwind
 * (throw) into the library. It may call troupe functions; a long call it makes runs without a
 * callback.
 */
typedef int32_t (*troupe_progress_fn)(void *user_data, uint64_t done, uint64_t total);

/**
 * What one long call may cost (`troupe_set_call_budget`). A zero field sets no bound.
 */
typedef struct troupe_call_budget {
  /**
   * The most work one call may take, in the call's own unit: a group's network evaluations,
   * a clip's tokens × solver steps, a MAGNet generation's sampler iterations, an ARFlow
   * generation's sampler steps. A call that would take more fails with
   * `TROUPE_ERR_INVALID_ARG` before it starts.
   */
  uint64_t max_work;
  /**
   * The most seconds one call may run. A call past it stops at its next unit of work with
   * `TROUPE_ERR_CANCELLED`, nothing written.
   */
  double max_seconds;
} troupe_call_budget;

/**
 * Routes the library's log lines at `max_level` or more severe (`TROUPE_LOG_ERROR` ..
 * `TROUPE_LOG_DEBUG`) to `callback`, with `user_data` passed back untouched. NULL restores the
 * default: silent (or stderr when the environment sets `TROUPE_LOG=error|warn|info|debug`).
 *
 * Thread-safe: the callback may be swapped at any time. The callback itself may be called
 * concurrently from every thread that calls into troupe, so it must be thread-safe; it must
 * not call troupe functions, and must not unwind or `longjmp` out.
 *
 * Returns `TROUPE_OK`, or `TROUPE_ERR_INVALID_ARG` for a level outside 1..=4.
 */
troupe_status troupe_set_log_callback(troupe_log_fn callback, void *user_data, int32_t max_level);

/**
 * Sets the calling thread's progress callback (NULL removes it): from now on, long calls made
 * on this thread (`troupe_model_load_file`, `troupe_model_load_memory`,
 * `troupe_umf_generate`, `troupe_armflow_clip_generate`, `troupe_magnet_generate`,
 * `troupe_arflow_generate`, `troupe_bvh_read`, `troupe_viewer_write`) report to it between units
 * of work (graphs loaded, a group's network evaluations, clip tokens, sampler steps, BVH frames
 * by 4096, GIF frames) and stop with `TROUPE_ERR_CANCELLED` when it returns non-zero. To cancel from another thread, have the callback read a flag that thread sets.
 * `user_data` is passed back untouched and must stay valid while the callback is set.
 * Per thread, like the last error; thread-safe.
 *
 * ```c
 * static int32_t keep_going(void *stop, uint64_t done, uint64_t total) {
 *     (void)done; (void)total;
 *     return atomic_load((atomic_int *)stop);   // non-zero cancels
 * }
 * troupe_set_progress_callback(keep_going, &stop);
 * ```
 */
void troupe_set_progress_callback(troupe_progress_fn callback, void *user_data);

/**
 * Sets the calling thread's call budget (NULL, or all fields zero, removes it): from now on,
 * `troupe_umf_generate`, `troupe_armflow_clip_generate`, `troupe_magnet_generate` and
 * `troupe_arflow_generate` made on this thread are refused when they would take more than
 * `max_work`, and stop once they have run `max_seconds`. A bound set up front, for a service
 * that runs callers' requests, beside the progress callback's cancelling. Returns `TROUPE_OK`,
 * or `TROUPE_ERR_INVALID_ARG` when `max_seconds` is negative or not a number (the budget is
 * then unchanged). The struct is copied; the caller keeps ownership. Per thread, like the last
 * error; thread-safe.
 *
 * ```c
 * troupe_call_budget budget = { .max_work = 5000, .max_seconds = 2.0 };
 * troupe_set_call_budget(&budget);
 * ```
 *
 * # Safety
 * `budget` is NULL or points to a readable `troupe_call_budget`.
 */
troupe_status troupe_set_call_budget(const struct troupe_call_budget *budget);

/**
 * Sets how many threads a model load may use: 0 (the default) one per core, 1 only the calling
 * thread. Loading optimises the bundle's graphs in parallel on scoped threads that are all
 * joined before the load returns; no other call starts a thread. Applies to loads that start
 * afterwards, process-wide. Thread-safe.
 */
void troupe_set_load_threads(size_t threads);

/**
 * How many threads a model load uses now (the `troupe_set_load_threads` setting, or the number
 * of cores). Thread-safe.
 */
size_t troupe_load_threads(void);

/**
 * Sets how many threads the matrix products of every model may split over: 1 (the default)
 * runs all work on the calling thread; `n >= 2` starts a pool of `n` threads, owned by the
 * library and named `troupe-compute`, shared by every model and session of the process, and
 * kept until the setting changes (the old pool's threads then exit); 0 means one per core.
 * Sessions stepped from several host threads share the pool. Applies to calls that start
 * afterwards. Returns `TROUPE_OK`, or `TROUPE_ERR_INVALID_ARG` when `threads` is above 1024 or
 * the pool cannot be started (the setting is then unchanged). Thread-safe.
 */
troupe_status troupe_set_compute_threads(size_t threads);

/**
 * How many threads the matrix products use now (`troupe_set_compute_threads`; 1 by default).
 * Thread-safe.
 */
size_t troupe_compute_threads(void);

/* ============================================================================================
 * 5. Model
 *
 * Loading a bundle and what every bundle answers, whatever its family.
 * ============================================================================================ */

/**
 * A loaded bundle. Immutable and thread-safe: every function taking a `const troupe_model*`
 * may be called from any number of threads at once. Free it with `troupe_model_free`; sessions
 * created from it keep it alive, so it may be freed before them.
 */
typedef struct troupe_model troupe_model;

/**
 * Loads a bundle from `path` (UTF-8): a bundle directory, or an uncompressed tar archive of
 * one. Loading parses, validates and optimises every graph; it takes a fraction of a second.
 *
 * On success `*out` receives a new handle owned by the caller (free with `troupe_model_free`);
 * on failure `*out` is set to NULL. `path` is borrowed for the call only.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG` (path or out NULL), `TROUPE_ERR_INVALID_ARG`
 * (path not UTF-8), `TROUPE_ERR_IO` (missing file), `TROUPE_ERR_MODEL` (corrupt or mismatched
 * bundle; the message names file, tensor and shape), `TROUPE_ERR_PANIC`. Thread-safe.
 *
 * ```c
 * troupe_model *model = NULL;
 * if (troupe_model_load_file("onnx/bundles/armflow-tiny", &model) != TROUPE_OK)
 *     fprintf(stderr, "%s\n", troupe_last_error_message());
 * ```
 *
 * # Safety
 * `path` must be NUL-terminated; `out` must be writable.
 */
troupe_status troupe_model_load_file(const char *path, struct troupe_model **out);

/**
 * Loads a bundle from memory: `data` holds `len` bytes of an uncompressed tar archive of a
 * bundle directory. The bytes are copied; `data` is borrowed for the call only.
 *
 * Ownership of `*out`, statuses and threading as `troupe_model_load_file`.
 *
 * # Safety
 * `data` must be readable for `len` bytes; `out` must be writable.
 */
troupe_status troupe_model_load_memory(const uint8_t *data, size_t len, struct troupe_model **out);

/**
 * Releases the caller's reference to a model; the model itself lives on while sessions made
 * from it exist. NULL is a no-op. The handle must not be used afterwards.
 *
 * # Safety
 * `model` must be NULL or a handle from `troupe_model_load_*` not freed before.
 */
void troupe_model_free(struct troupe_model *model);

/**
 * The model's family as its manifest names it (`"armflow"`, `"umf"`, `"magnet"`, `"arflow"`):
 * which family's calls (`troupe_<family>_...`) it serves. NULL for NULL. The string is owned by
 * the model and valid until `troupe_model_free`; never free it. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
const char *troupe_model_family(const struct troupe_model *model);

/**
 * Floats per motion frame (262 for the `interhuman262` layout); 0 for NULL. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_model_frame_dim(const struct troupe_model *model);

/**
 * Writes the model's identity to `out` (32 bytes): the SHA-256 of its bundle's files as the
 * load read them, the same for a directory and a tar of it. Two processes hold the same model
 * exactly when their identities are equal; session snapshots carry it.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_PANIC`. Thread-safe.
 *
 * # Safety
 * `model` must be a live handle; `out` writable for 32 bytes.
 */
troupe_status troupe_model_identity(const struct troupe_model *model, uint8_t *out);

/**
 * Frames per second of the motion; 0 for NULL. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_model_fps(const struct troupe_model *model);

/**
 * Motion frames per generated token (reactor frames come out in multiples of it); 0 for NULL
 * and for a `umf` bundle. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_model_frames_per_token(const struct troupe_model *model);

/**
 * Algorithmic latency in frames: at worst, how many actor frames after frame t arrive before
 * reactor frame t is returned; 0 for NULL and for a `umf` bundle. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_model_latency_frames(const struct troupe_model *model);

/**
 * Floats in the conditioning vector (`troupe_session_set_condition`, `troupe_umf_generate`);
 * 0 for NULL. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_model_condition_dim(const struct troupe_model *model);

/**
 * Named conditions the bundle was trained on (the demo model's partner rules `mirror`,
 * `follow`, `keep-away`); 0 for NULL and for bundles conditioned on free vectors. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_model_condition_label_count(const struct troupe_model *model);

/**
 * The name of condition label `index` (`0 <= index < troupe_model_condition_label_count`), or
 * NULL for NULL or an index out of range. The string is owned by the model and valid until
 * `troupe_model_free`; never free it. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
const char *troupe_model_condition_label(const struct troupe_model *model, size_t index);

/**
 * Writes the conditioning vector of the label `label` (UTF-8, borrowed for the call) into
 * `condition[0 .. troupe_model_condition_dim)`, ready for `troupe_session_set_condition`,
 * `troupe_armflow_clip_generate` or `troupe_umf_generate`.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (no such label: the
 * message lists the bundle's labels; or `label` not UTF-8), `TROUPE_ERR_BUFFER_TOO_SMALL`
 * (`capacity` below the condition's length), `TROUPE_ERR_PANIC`. `condition` is untouched on
 * failure. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle; `label` NUL-terminated; `condition` writable for
 * `capacity` floats.
 */
troupe_status troupe_model_condition_for_label(const struct troupe_model *model, const char *label, float *condition, size_t capacity);

/**
 * How many of the bundle's graphs hold weights in reduced precision (a graph entry's
 * `"weights": "int8"`, checked against the file at load); 0 for a float32 bundle and for NULL.
 * Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_model_reduced_precision_count(const struct troupe_model *model);

/**
 * The role of reduced-precision graph `index` (`"context_layers"`, `"velocity"`, ...;
 * `0 <= index < troupe_model_reduced_precision_count`), or NULL for NULL or an index out of
 * range. Owned by the model and valid until `troupe_model_free`; never free it. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
const char *troupe_model_reduced_precision_graph(const struct troupe_model *model, size_t index);

/**
 * How reduced-precision graph `index` stores its weights (`"int8"`), or NULL for NULL or an
 * index out of range. Owned by the model and valid until `troupe_model_free`; never free it.
 * Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
const char *troupe_model_reduced_precision_weights(const struct troupe_model *model, size_t index);

/**
 * Floats per latent token (the length of injected noise vectors, per token); 0 for NULL.
 * Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_model_latent_dim(const struct troupe_model *model);

/**
 * The most reactor frames one `troupe_session_step` call with `n_actor_frames` input frames can
 * return, whatever the session's state: size output buffers with it. 0 for NULL and for a
 * `umf` bundle. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_model_max_output_frames(const struct troupe_model *model, size_t n_actor_frames);

/**
 * Frames of motion per clip (0 for other bundles or NULL): per person of
 * `troupe_umf_generate` (`[people][clip_frames][frame_dim]`) for a `umf` bundle, of
 * `troupe_armflow_clip_generate` for an `armflow` bundle with an official clip. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_model_clip_frames(const struct troupe_model *model);

/* ============================================================================================
 * 6. Session
 *
 * One stream (ARMFlow reaction, MAGNet live partner, ARFlow online): options, stepping one or
 * many, reset, the settings every stream takes and those a stream reports as capabilities.
 * ============================================================================================ */

/**
 * Actor tokens are the VAE posterior sample `(mean + std * noise) * scale` (the official choice).
 */
#define TROUPE_ACTOR_LATENT_SAMPLE 0

/**
 * Actor tokens are the posterior mean: no actor noise is drawn.
 */
#define TROUPE_ACTOR_LATENT_MEAN 1

/**
 * The session takes a conditioning vector (`troupe_session_set_condition`).
 */
#define TROUPE_CAP_CONDITION (1 << 0)

/**
 * The session takes a text prompt (`troupe_session_set_prompt`).
 */
#define TROUPE_CAP_PROMPT (1 << 1)

/**
 * The session takes a CFG scale other than 1 (`troupe_session_set_cfg_scale`).
 */
#define TROUPE_CAP_CFG_SCALE (1 << 2)

/**
 * The session takes queued standard normals (`troupe_session_queue_normals`).
 */
#define TROUPE_CAP_QUEUED_NORMALS (1 << 3)

/**
 * One stream. A session is used from one thread at a time (it may move between threads);
 * distinct sessions run fully in parallel. A call on a session that another thread is using
 * fails with `TROUPE_ERR_BUSY` instead of racing.
 */
typedef struct troupe_session troupe_session;

/**
 * Options every stream takes at its start. Fill with `troupe_session_options_init`, then change
 * fields. Fields are only ever appended; `struct_size` tells the library which version the
 * caller has. A family's own options go in its own struct (`troupe_armflow_session_options`);
 * `cfg_scale` and `actor_latent` are ARMFlow's, kept here (deprecated since 0.2) so that 0.1
 * programs keep their layout: `troupe_session_new` still reads them, and
 * `troupe_armflow_session_new` does not.
 */
typedef struct troupe_session_options {
  /**
   * `sizeof(troupe_session_options)` as the caller compiled it (set by `_init`).
   */
  uint32_t struct_size;
  /**
   * Sampler steps, >= 1: MeanFlow steps per token (armflow), DDIM steps per chunk (magnet).
   */
  uint32_t steps;
  /**
   * Seed of the portable noise generator: equal seeds give bit-identical motion everywhere.
   */
  uint64_t seed;
  /**
   * Deprecated since 0.2 (use `troupe_armflow_session_options.cfg_scale`): an ARMFlow
   * stream's classifier-free guidance scale, finite; another family's session takes 1.
   */
  float cfg_scale;
  /**
   * armflow: tokens kept in the context cache, `<sos>` included, >= 2; older ones slide out.
   * magnet: context tokens per window (1 to window - 1; the window advances by the rest).
   */
  uint32_t context_capacity;
  /**
   * Deprecated since 0.2 (use `troupe_armflow_session_options.actor_latent`):
   * `TROUPE_ACTOR_LATENT_SAMPLE` or `_MEAN` for an ARMFlow stream; another family's session
   * takes `_SAMPLE`.
   */
  int32_t actor_latent;
  /**
   * Must be 0.
   */
  uint32_t reserved;
} troupe_session_options;

/**
 * `sizeof(troupe_session_options)` in this library, for bindings to check their mirror.
 */
size_t troupe_session_options_size(void);

/**
 * Fills `options` with the defaults of `model`'s bundle (sampler steps, CFG scale, context
 * capacity, actor latent) and seed 0, and sets `struct_size`. Pass
 * `sizeof(troupe_session_options)` as `options_size`: the library writes only that many bytes
 * (zeroing fields it does not know), so callers built against an older or newer header are safe.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, or `TROUPE_ERR_INVALID_ARG` when `options_size`
 * is smaller than the first version of the struct. Thread-safe.
 *
 * ```c
 * troupe_session_options opt;
 * troupe_session_options_init(model, &opt, sizeof opt);
 * ```
 *
 * # Safety
 * `model` must be a live handle; `options` must be writable for `options_size` bytes.
 */
troupe_status troupe_session_options_init(const struct troupe_model *model, struct troupe_session_options *options, size_t options_size);

/**
 * Starts a stream on `model` with `options` (NULL: the bundle's defaults). On an `armflow`
 * model the session answers an actor with the reactor, starting with the null condition (set
 * one with `troupe_session_set_condition`); `troupe_armflow_session_new` opens one with
 * ARMFlow's own options. On a two-person `magnet` model it answers a user
 * with the live partner (its `motion_control_live` configuration); give the partner's opening
 * frames with `troupe_magnet_session_set_partner_opening` before the first step.
 *
 * On success `*out` receives a new handle owned by the caller (free with
 * `troupe_session_free`); it keeps `model` alive. On failure `*out` is set to NULL.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (bad option values or
 * `struct_size`), `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_PANIC`. Thread-safe with respect to
 * `model`: sessions may be created from many threads at once.
 *
 * ```c
 * troupe_session_options opt;
 * troupe_session_options_init(model, &opt, sizeof opt);
 * opt.seed = 42;
 * troupe_session *session = NULL;
 * troupe_status st = troupe_session_new(model, &opt, &session);
 * ```
 *
 * # Safety
 * `model` must be a live handle; `options` NULL or readable for its `struct_size`; `out`
 * writable.
 */
troupe_status troupe_session_new(const struct troupe_model *model, const struct troupe_session_options *options, struct troupe_session **out);

/**
 * Frees a session. NULL is a no-op. The handle must not be used afterwards. A session that
 * another thread is using at that moment is not freed (that would free memory in use): the
 * call logs an error and leaks it.
 *
 * # Safety
 * `session` must be NULL or a handle from `troupe_session_new` not freed before.
 */
void troupe_session_free(struct troupe_session *session);

/**
 * Feeds `n_actor_frames` actor frames (`actor`: row-major float32
 * `[n_actor_frames][frame_dim]`, borrowed for the call; may be NULL when `n_actor_frames` is 0)
 * and writes the reactor frames that became ready into `out` (capacity `out_capacity_frames`
 * frames of `frame_dim` floats), their count into `*n_written`. Any number of frames may be
 * fed per call; reactor frames come in multiples of `troupe_model_frames_per_token`.
 * `troupe_model_max_output_frames(model, n)` frames always suffice, and
 * `troupe_session_output_frames` gives the exact count. No allocation is handed to the caller.
 *
 * On any error nothing is written and the session is exactly as before the call, except after
 * `TROUPE_ERR_PANIC`, which poisons it.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a NaN or infinite
 * value; the message gives its index), `TROUPE_ERR_BUFFER_TOO_SMALL` (the message says how many
 * frames are needed), `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One
 * thread at a time per session.
 *
 * ```c
 * float reactor[4 * 262];
 * size_t n = 0;
 * troupe_status st = troupe_session_step(session, frame, 1, reactor, 4, &n);
 * ```
 *
 * # Safety
 * `session` must be a live handle; `actor` readable for `n_actor_frames * frame_dim` floats;
 * `out` writable for `out_capacity_frames * frame_dim` floats and not overlapping `actor`;
 * `n_written` writable.
 */
troupe_status troupe_session_step(struct troupe_session *session, const float *actor, size_t n_actor_frames, float *out, size_t out_capacity_frames, size_t *n_written);

/**
 * Advances `n_sessions` sessions of one model in one call, reading the model's weights once
 * per token for all of them rather than once per session: the way to run a crowd. For each
 * `i < n_sessions`, `actor[i]` holds `n_actor_frames[i]` frames for `sessions[i]` (row-major
 * float32, borrowed; may be NULL when the count is 0), and the reactor frames that became ready
 * go to `out[i]` (capacity `out_capacity_frames[i]` frames; may be NULL when none are ready),
 * their count to `n_written[i]`. Each session's result equals what `troupe_session_step` gives
 * it alone, up to float rounding (1e-5). Sessions may differ in every option and in how many
 * frames they are given (0 included), but must share one model and appear once each.
 *
 * On any error nothing is written and every session is exactly as before the call, except after
 * `TROUPE_ERR_PANIC`, which poisons every session of the call. Messages name the session index.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a session listed twice,
 * sessions of different models, a NaN or infinite value), `TROUPE_ERR_BUFFER_TOO_SMALL`,
 * `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. The sessions must not be
 * used by another thread during the call; the arrays are borrowed for the call.
 *
 * ```c
 * troupe_session *crowd[64]; const float *in[64]; size_t n_in[64];
 * float *out[64]; size_t cap[64], n_out[64];
 * troupe_status st = troupe_sessions_step(crowd, 64, in, n_in, out, cap, n_out);
 * ```
 *
 * # Safety
 * Each array must be readable (`n_written` writable) for `n_sessions` entries (any may be NULL
 * when `n_sessions` is 0); `sessions[i]` live handles; `actor[i]` readable for
 * `n_actor_frames[i] * frame_dim` floats; `out[i]` writable for `out_capacity_frames[i] *
 * frame_dim` floats, overlapping no other buffer of the call.
 */
troupe_status troupe_sessions_step(struct troupe_session *const *sessions, size_t n_sessions, const float *const *actor, const size_t *n_actor_frames, float *const *out, const size_t *out_capacity_frames, size_t *n_written);

/**
 * Writes to `*n_frames` exactly how many reactor frames a `troupe_session_step` with
 * `n_actor_frames` frames would return now.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One
 * thread at a time per session.
 *
 * # Safety
 * `session` must be a live handle; `n_frames` writable.
 */
troupe_status troupe_session_output_frames(struct troupe_session *session, size_t n_actor_frames, size_t *n_frames);

/**
 * Saves everything the stream needs to go on (its settings, caches, pending frames, noise
 * position) as bytes: `troupe_session_restore` on the same model, in this process or another,
 * gives a session whose steps are this one's bit for bit. The format is versioned, checksummed
 * and bound to the model (`troupe_model_identity`). The session is unchanged.
 *
 * Writes the snapshot's size to `*needed`, and the snapshot to `buf` when `capacity` holds it.
 * Call with `buf` NULL and `capacity` 0 to learn the size (it changes when the session steps
 * or its settings change), then with a buffer that size.
 *
 * Returns `TROUPE_OK` (also for the size query), `TROUPE_ERR_NULL_ARG` (`needed` NULL, or `buf`
 * NULL with a non-zero capacity), `TROUPE_ERR_BUFFER_TOO_SMALL` (nothing written but
 * `*needed`), `TROUPE_ERR_UNSUPPORTED` (a family whose streams cannot be saved yet),
 * `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * ```c
 * size_t size = 0;
 * troupe_session_snapshot(session, NULL, 0, &size);
 * uint8_t *bytes = malloc(size);
 * troupe_status st = troupe_session_snapshot(session, bytes, size, &size);
 * ```
 *
 * # Safety
 * `session` must be a live handle; `buf` writable for `capacity` bytes; `needed` writable.
 */
troupe_status troupe_session_snapshot(struct troupe_session *session, uint8_t *buf, size_t capacity, size_t *needed);

/**
 * Seals a snapshot (`snapshot`, `len` bytes, from `troupe_session_snapshot`) under `key`
 * (`key_len` bytes, at least 16, kept secret by the caller): an HMAC-SHA-256 tag that only a
 * holder of the key can make, for snapshot stores that others can write. Restore it with
 * `troupe_session_restore_sealed` and the same key; another key, or any changed byte, is
 * refused there. The layout is in `docs/SNAPSHOTS.md`.
 *
 * Writes the sealed size (`len` + 44) to `*needed`, and the sealed snapshot to `buf` when
 * `capacity` holds it (`buf` NULL and `capacity` 0: the size only). Returns `TROUPE_OK`,
 * `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a key under 16 bytes, or bytes that are not
 * a snapshot), `TROUPE_ERR_BUFFER_TOO_SMALL` (nothing written but `*needed`),
 * `TROUPE_ERR_PANIC`. Every buffer is borrowed for the call. Thread-safe.
 *
 * ```c
 * size_t sealed_size = 0;
 * troupe_snapshot_seal(bytes, size, key, 32, NULL, 0, &sealed_size);
 * uint8_t *sealed = malloc(sealed_size);
 * troupe_status st = troupe_snapshot_seal(bytes, size, key, 32, sealed, sealed_size, &sealed_size);
 * ```
 *
 * # Safety
 * `snapshot` readable for `len` bytes, `key` for `key_len`; `buf` writable for `capacity`;
 * `needed` writable.
 */
troupe_status troupe_snapshot_seal(const uint8_t *snapshot, size_t len, const uint8_t *key, size_t key_len, uint8_t *buf, size_t capacity, size_t *needed);

/**
 * Starts a session that goes on exactly where the session saved in `bytes` (`len` bytes, from
 * `troupe_session_snapshot`; borrowed for the call) stopped. The snapshot must come from this
 * model (the same bundle files); a truncated, altered, foreign or other-version snapshot is
 * refused before anything it claims is allocated.
 *
 * On success `*out` receives a new handle owned by the caller (free with
 * `troupe_session_free`); it keeps `model` alive. On failure `*out` is set to NULL.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (the message says what
 * is wrong with the snapshot), `TROUPE_ERR_UNSUPPORTED`, `TROUPE_ERR_INFERENCE`,
 * `TROUPE_ERR_PANIC`. Thread-safe with respect to `model`.
 *
 * ```c
 * troupe_session *again = NULL;
 * troupe_status st = troupe_session_restore(model, bytes, size, &again);
 * ```
 *
 * # Safety
 * `model` must be a live handle; `bytes` readable for `len` bytes; `out` writable.
 */
troupe_status troupe_session_restore(const struct troupe_model *model, const uint8_t *bytes, size_t len, struct troupe_session **out);

/**
 * `troupe_session_restore` of a snapshot sealed with `troupe_snapshot_seal` under `key`
 * (`key_len` bytes). The seal is checked first, in constant time, so a snapshot sealed under
 * another key, or with any byte changed, is refused before any of it is read; an unsealed
 * snapshot is refused too (a store that needs seals takes no other).
 *
 * On success `*out` receives a new handle owned by the caller (free with
 * `troupe_session_free`); on failure `*out` is NULL. Returns what `troupe_session_restore`
 * returns; `TROUPE_ERR_INVALID_ARG` names a seal that does not match. Every buffer is borrowed
 * for the call. Thread-safe with respect to `model`.
 *
 * # Safety
 * `model` must be a live handle; `bytes` readable for `len` bytes, `key` for `key_len`; `out`
 * writable.
 */
troupe_status troupe_session_restore_sealed(const struct troupe_model *model, const uint8_t *bytes, size_t len, const uint8_t *key, size_t key_len, struct troupe_session **out);

/**
 * Makes the session equal to a fresh one with its current settings (seed, steps, CFG,
 * condition, capacity); queued noise is dropped. Clears the poison left by a panic.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_PANIC`. One thread at a time per
 * session.
 *
 * # Safety
 * `session` must be NULL or a live handle.
 */
troupe_status troupe_session_reset(struct troupe_session *session);

/**
 * Sets the noise seed for tokens generated from now on.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One
 * thread at a time per session.
 *
 * # Safety
 * `session` must be NULL or a live handle.
 */
troupe_status troupe_session_set_seed(struct troupe_session *session, uint64_t seed);

/**
 * Sets the sampler's steps (>= 1): MeanFlow steps per token (armflow), DDIM steps per chunk
 * (a magnet live partner), for what is generated from now on.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (0 steps),
 * `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * # Safety
 * `session` must be NULL or a live handle.
 */
troupe_status troupe_session_set_steps(struct troupe_session *session, uint32_t steps);

/**
 * Sets the classifier-free guidance scale (finite) for what is generated from now on, on a
 * stream with the capability (`troupe_session_capabilities`, `TROUPE_CAP_CFG_SCALE`: ARMFlow's),
 * applied as the family's official sampler applies it (ARMFlow: guided only above 1; the null
 * branch zeroes the actor token and the context). A stream without guidance accepts 1.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (NaN or infinite),
 * `TROUPE_ERR_UNSUPPORTED` (a scale other than 1 on a stream without the capability),
 * `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * # Safety
 * `session` must be NULL or a live handle.
 */
troupe_status troupe_session_set_cfg_scale(struct troupe_session *session, float scale);

/**
 * Sets the conditioning vector (`len` must equal `troupe_model_condition_dim`; borrowed for the
 * call) for what is generated from now on, on a stream with the capability
 * (`TROUPE_CAP_CONDITION`). `condition` NULL with `len` 0 selects the null condition, which
 * every stream accepts.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (wrong `len`),
 * `TROUPE_ERR_INVALID_ARG` (NaN or infinite value), `TROUPE_ERR_UNSUPPORTED` (a condition other
 * than the null one on a stream without the capability), `TROUPE_ERR_INFERENCE`,
 * `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * # Safety
 * `session` must be a live handle; `condition` readable for `len` floats.
 */
troupe_status troupe_session_set_condition(struct troupe_session *session, const float *condition, size_t len);

/**
 * Conditions what is generated from now on on a text prompt (a NUL-terminated UTF-8 string,
 * borrowed for the call): the condition `troupe_text_prompt_encode` gives, on a stream with
 * the capability (`TROUPE_CAP_PROMPT`: bundles with `troupe_model_takes_prompts`). The model
 * caches the last 64 prompts it encoded.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (text that is not UTF-8
 * or longer than 64 KiB), `TROUPE_ERR_UNSUPPORTED` (a stream without the capability),
 * `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_BUSY`, `TROUPE_ERR_PANIC`. One
 * thread at a time per session.
 *
 * # Safety
 * `session` must be a live handle; `prompt` NUL-terminated and readable for the call.
 */
troupe_status troupe_session_set_prompt(struct troupe_session *session, const char *prompt);

/**
 * Writes to `*out` the session's capabilities: the `TROUPE_CAP_*` bits of what it takes beyond
 * frames, seed and steps. A call for a capability it lacks returns `TROUPE_ERR_UNSUPPORTED`
 * naming it.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One
 * thread at a time per session.
 *
 * # Safety
 * `session` must be NULL or a live handle; `out` writable.
 */
troupe_status troupe_session_capabilities(struct troupe_session *session, uint32_t *out);

/**
 * Queues standard normals for the draws the stream makes next, to replay another
 * implementation's stream exactly (`TROUPE_CAP_QUEUED_NORMALS`: every streaming family):
 * `normals` holds `len` floats (borrowed for the call), appended to any still queued. Each
 * draw takes the next ones it needs while any are queued, in the sampler's order (ARMFlow per
 * token the actor's posterior noise then the reactor's start noise, `troupe_model_latent_dim`
 * each, whole tokens only; MAGNet as `docs/MAGNET.md` gives; ARFlow per frame the start noise
 * when σ > 0, then one ε per step when η > 0, 262 each); then the seeded generator goes on as
 * if the queued draws had been its. A step whose draw needs more than are left fails with
 * `TROUPE_ERR_INVALID_ARG`, the session as it was. `troupe_session_reset` drops them.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a non-finite value;
 * ARMFlow: not whole tokens), `TROUPE_ERR_UNSUPPORTED` (a stream without the capability),
 * `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * # Safety
 * `session` must be a live handle; `normals` readable for `len` floats.
 */
troupe_status troupe_session_queue_normals(struct troupe_session *session, const float *normals, size_t len);

/* ============================================================================================
 * 7. Text prompts
 *
 * Conditions from text, for bundles with a text encoder or text branch.
 * ============================================================================================ */

/**
 * 1 if the bundle turns text prompts into conditions (`troupe_text_prompt_encode`): it carries
 * CLIP's text tower, its tokenizer and a text branch; 0 otherwise or for NULL. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_model_takes_prompts(const struct troupe_model *model);

/**
 * Encodes a text prompt into the bundle's condition vector, as the official code does: the
 * prompt tokenized as CLIP tokenizes it (lower-cased, cleaned, byte-pair encoded, cut at 77
 * tokens), CLIP's text tower, then the family's text branch at the end-of-text token. The
 * empty prompt `""` gives the official "no text". Writes `troupe_model_condition_dim` floats to
 * `condition` (capacity `condition_capacity` floats). The last 64 prompts are cached, so asking
 * again is cheap. Nothing is written unless the call succeeds.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a bundle that takes no
 * prompts, text that is not UTF-8 or longer than 64 KiB), `TROUPE_ERR_BUFFER_TOO_SMALL`,
 * `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_PANIC`. Thread-safe: any number of threads may encode on
 * one model at once.
 *
 * # Safety
 * `model` must be a live handle; `prompt` a NUL-terminated string readable for the call;
 * `condition` writable for `condition_capacity` floats.
 */
troupe_status troupe_text_prompt_encode(const struct troupe_model *model, const char *prompt, float *condition, size_t condition_capacity);

/**
 * Width of the CLIP token features `troupe_text_encode` reads (the bundle's CLIP width: the
 * condition dim of an official ARMFlow bundle, 768 for UMF as released); 0 for bundles without
 * a text branch, or NULL. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_model_text_token_dim(const struct troupe_model *model);

/**
 * Runs the official text branch of a bundle that has one (`troupe_model_text_token_dim` > 0:
 * official ARMFlow and UMF bundles): CLIP's token features `clip_tokens`, row-major
 * `[n_tokens][text_token_dim]` (the output of CLIP's final LayerNorm for one prompt), and the
 * index of the end-of-text token (the argmax of CLIP's token ids) give the condition vector,
 * written to `condition` (capacity `condition_capacity` floats, at least
 * `troupe_model_condition_dim`). Inputs are borrowed; nothing is written unless the call
 * succeeds.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (no text branch, no
 * tokens, index out of range, non-finite input), `TROUPE_ERR_BUFFER_TOO_SMALL`,
 * `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_PANIC`. Thread-safe.
 *
 * # Safety
 * `model` must be a live handle; `clip_tokens` readable for `n_tokens * text_token_dim` floats;
 * `condition` writable for `condition_capacity` floats and not overlapping `clip_tokens`.
 */
troupe_status troupe_text_encode(const struct troupe_model *model, const float *clip_tokens, size_t n_tokens, size_t eot_index, float *condition, size_t condition_capacity);

/* ============================================================================================
 * 8. Motion
 *
 * Joint positions of the t2m-22 skeleton in the caller's units and axes, feature encoding, BVH
 * and JSON files, the penetration metrics.
 * ============================================================================================ */

/**
 * Positions in metres.
 */
#define TROUPE_UNITS_METERS 0

/**
 * Positions in centimetres.
 */
#define TROUPE_UNITS_CENTIMETERS 1

/**
 * Positions in millimetres.
 */
#define TROUPE_UNITS_MILLIMETERS 2

/**
 * Positions in inches.
 */
#define TROUPE_UNITS_INCHES 3

/**
 * +Y is up (troupe, Unity, glTF, most BVH).
 */
#define TROUPE_UP_Y 0

/**
 * +Z is up (SMPL raw data, Blender, ROS, Unreal); converted as `(x, y, z) -> (x, z, -y)`.
 */
#define TROUPE_UP_Z 1

/**
 * Right-handed axes.
 */
#define TROUPE_RIGHT_HANDED 0

/**
 * Left-handed axes (Unity, Unreal): x is negated first.
 */
#define TROUPE_LEFT_HANDED 1

/**
 * Joints of the t2m-22 skeleton every `interhuman262` bundle speaks.
 */
#define TROUPE_MOTION_JOINTS 22

/**
 * Let `troupe_bvh_read` guess a file's units from the figure's height.
 */
#define TROUPE_UNITS_AUTO 4294967295

/**
 * A BVH take read as t2m-22 joint positions. Immutable: any thread may query it. Free with
 * `troupe_bvh_free`.
 */
typedef struct troupe_bvh troupe_bvh;

/**
 * A stream turning joint-position frames into feature frames for one person, used from one
 * thread at a time (a call while another thread uses it fails with `TROUPE_ERR_BUSY`). Free
 * with `troupe_motion_stream_free`; it does not need its model after creation.
 */
typedef struct troupe_motion_stream troupe_motion_stream;

/**
 * How the caller measures joint positions. Fill with `troupe_joints_format_init` (metres, Y up,
 * right-handed, 30 fps), then change fields. Fields are only ever appended.
 */
typedef struct troupe_joints_format {
  /**
   * `sizeof(troupe_joints_format)` as the caller compiled it (set by `_init`).
   */
  uint32_t struct_size;
  /**
   * `TROUPE_UNITS_*`.
   */
  uint32_t units;
  /**
   * `TROUPE_UP_Y` or `TROUPE_UP_Z`.
   */
  uint32_t up_axis;
  /**
   * `TROUPE_RIGHT_HANDED` or `TROUPE_LEFT_HANDED`.
   */
  uint32_t handedness;
  /**
   * Frames per second of the caller's motion, in [1, 1000]; resampled to the bundle's rate.
   */
  float fps;
  /**
   * Must be 0.
   */
  uint32_t reserved;
} troupe_joints_format;

/**
 * Where a clip's canonical frame sits in the caller's world (InterGen's canonicalisation): the
 * floor height and first-frame root x, z in troupe's axes (metres, Y up), and the turn about +Y
 * that makes frame 0 face +Z. Written by `troupe_motion_encode` and the streams; pass it back to
 * put generated motion where the caller's was, and to put a second person in the first one's
 * frame. A plain value: copy it freely.
 */
typedef struct troupe_placement {
  /**
   * Floor height, metres.
   */
  double floor;
  /**
   * First-frame root x, metres.
   */
  double origin_x;
  /**
   * First-frame root z, metres.
   */
  double origin_z;
  /**
   * The turn as a unit quaternion `[w, x, y, z]`.
   */
  double heading[4];
} troupe_placement;

/**
 * Where `troupe_motion_decode` writes each part of a pose; any pointer may be NULL (with
 * length 0) to skip that part. Lengths are in floats. Every part is in the caller's world and
 * axes.
 */
typedef struct troupe_pose_buffers {
  /**
   * Joint positions `[frames][22][3]`.
   */
  float *positions;
  /**
   * Length of `positions`.
   */
  size_t positions_len;
  /**
   * Rotations `[frames][22][4]` as `[w, x, y, z]`: joint 0 the root's world orientation, the
   * others local to their parent.
   */
  float *rotations;
  /**
   * Length of `rotations`.
   */
  size_t rotations_len;
  /**
   * The same rotations as 6-D vectors `[frames][22][6]`.
   */
  float *rotations_6d;
  /**
   * Length of `rotations_6d`.
   */
  size_t rotations_6d_len;
  /**
   * Contacts `[frames][4]`: left ankle, left foot, right ankle, right foot.
   */
  float *contacts;
  /**
   * Length of `contacts`.
   */
  size_t contacts_len;
} troupe_pose_buffers;

/**
 * Fills `*format` with the defaults: metres, Y up, right-handed, 30 fps. `format_size` is
 * `sizeof(troupe_joints_format)`.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a size smaller than
 * the first version's). Thread-safe.
 *
 * # Safety
 * `format` must be writable for `format_size` bytes.
 */
troupe_status troupe_joints_format_init(struct troupe_joints_format *format, size_t format_size);

/**
 * Joints of the t2m-22 skeleton (22). Thread-safe.
 */
size_t troupe_motion_joint_count(void);

/**
 * The name of t2m-22 joint `joint` (`"pelvis"`, `"left_hip"`, ...; SMPL's order), or NULL when
 * `joint >= 22`. Static storage: never free it. Thread-safe.
 */
const char *troupe_motion_joint_name(size_t joint);

/**
 * Writes the t2m-22 skeleton: `parents[22]` (each joint's parent, -1 for the root; parents
 * come before children) and `rest_offsets[22 * 3]` (each joint's rest offset from its parent in
 * metres, Y up, facing +Z, +X the body's left; the root's is its rest position). Either may be
 * NULL with length 0 to skip it.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (a length other than 22 or
 * 66). Thread-safe.
 *
 * # Safety
 * Non-NULL arrays must be writable for their lengths.
 */
troupe_status troupe_motion_skeleton(int32_t *parents, size_t parents_len, float *rest_offsets, size_t rest_offsets_len);

/**
 * Poses MAGNet frames on the t2m-22 skeleton: `frames` holds `n_frames` frames of one person in
 * the `magnet-smplx145` layout (145 floats each, row-major: betas, the 21 body joints' 6-D
 * rotations, the pelvis's pose in the world), and `positions` receives `[n_frames][22][3]`
 * joint positions (metres, Y up, the frames' world; `positions_len` = `n_frames * 66`). The
 * bone lengths are troupe's neutral body's, not the person's betas. For pictures
 * (`troupe_viewer_write`), BVH files and JSON poses of a MAGNet output.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (`positions_len`),
 * `TROUPE_ERR_INVALID_ARG` (a NaN or infinite value, a degenerate rotation). On error nothing is
 * written. Thread-safe.
 *
 * # Safety
 * `frames` readable for `n_frames * 145` floats; `positions` writable for `positions_len`
 * floats and not overlapping `frames`.
 */
troupe_status troupe_motion_smplx145_positions(const float *frames, size_t n_frames, float *positions, size_t positions_len);

/**
 * How much two people's bodies pass through each other (`docs/ARFLOW.md`): `first` and
 * `second` hold `n_frames` frames of t2m-22 joint positions each (row-major float32
 * `[n_frames][22][3]`, metres, Y up, one world), each person's joints are tested against the
 * other's body (one capsule per bone), and the results go to the non-NULL out-pointers:
 * `*frames_intersecting` (frames where a joint lies inside the other body), `*frequency` (their
 * share, 0 for no frames), `*depth_sum` (the depths of every such joint, summed over joints and
 * frames, metres: the intersection volume's proxy) and `*max_depth` (metres).
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a NaN or infinite
 * value). On error nothing is written. Thread-safe.
 *
 * # Safety
 * `first` and `second` readable for `n_frames * 66` floats; each non-NULL out-pointer writable.
 */
troupe_status troupe_motion_penetration_metrics(const float *first, const float *second, size_t n_frames, size_t *frames_intersecting, double *frequency, double *depth_sum, double *max_depth);

/**
 * Writes to `*n_frames_out` how many feature frames `troupe_motion_encode` gives for a clip of
 * `n_frames` position frames measured as `format` says: the clip resampled to the bundle's
 * rate, less one (velocities look one frame ahead).
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a bad format, more
 * frames than `troupe_motion_encode` takes, or a bundle whose features are not
 * `interhuman262`). Thread-safe.
 *
 * # Safety
 * `format` readable, `n_frames_out` writable.
 */
troupe_status troupe_motion_encoded_frames(const struct troupe_model *model, const struct troupe_joints_format *format, size_t n_frames, size_t *n_frames_out);

/**
 * Turns a clip of joint positions (`positions`: float32 `[n_frames][22][3]` measured as
 * `format` says) into the bundle's features (`features_out`: `[frames][frame_dim]`, capacity
 * `out_capacity_frames` frames; the count goes to `*n_written`, see
 * `troupe_motion_encoded_frames`). The clip is resampled to the bundle's rate and put in its
 * canonical frame: InterGen's (floor under the clip's lowest joint, origin and facing from
 * frame 0) when `placement` is NULL, else the given one (e.g. the first person's, for the
 * second). The placement used is written to `placement_out` unless it is NULL.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (NaN or infinite
 * positions, naming frame and joint; a clip too short; a bad format or placement; a bundle
 * whose features are not `interhuman262`), `TROUPE_ERR_BUFFER_TOO_SMALL`, `TROUPE_ERR_PANIC`.
 * Nothing is written on error. Thread-safe.
 *
 * # Safety
 * `positions` readable for `n_frames * 66` floats; `features_out` writable for
 * `out_capacity_frames * frame_dim` floats; the rest readable/writable as their types say.
 */
troupe_status troupe_motion_encode(const struct troupe_model *model, const struct troupe_joints_format *format, const float *positions, size_t n_frames, const struct troupe_placement *placement, float *features_out, size_t out_capacity_frames, size_t *n_written, struct troupe_placement *placement_out);

/**
 * Turns `n_frames` feature frames (`features`: `[n_frames][frame_dim]`) into poses in the
 * caller's world: positions, rotations (quaternions and 6-D) and contacts, into the buffers of
 * `*out` (see `troupe_pose_buffers`), using the `placement` the actor's motion was encoded
 * with and the caller's axes and units from `format` (its `fps` is not used).
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (a buffer length other than
 * the frames need), `TROUPE_ERR_INVALID_ARG` (non-finite features, a bad format or placement, a
 * bundle whose features are not `interhuman262`), `TROUPE_ERR_PANIC`. Nothing is written on
 * error. Thread-safe.
 *
 * # Safety
 * `features` readable for `n_frames * frame_dim` floats; `format`, `placement`, `out` readable;
 * the buffers in `out` writable for their lengths and not overlapping `features`.
 */
troupe_status troupe_motion_decode(const struct troupe_model *model, const struct troupe_joints_format *format, const struct troupe_placement *placement, const float *features, size_t n_frames, const struct troupe_pose_buffers *out);

/**
 * Starts a stream turning one person's joint-position frames (measured as `format` says) into
 * the bundle's feature frames, for a session's actor input. The canonical frame is fixed by
 * the first frame (origin and facing as InterGen takes them, the floor under that frame's
 * lowest joint) unless `placement` is given (e.g. another person's). Feature frame t is ready
 * when position frame t + 1 has arrived: one frame of latency
 * (`troupe_motion_stream_latency_frames`). `*out` is set to NULL on entry and to the new
 * stream on success; free it with `troupe_motion_stream_free`.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (bad format or
 * placement, a bundle whose features are not `interhuman262`), `TROUPE_ERR_PANIC`.
 * Thread-safe.
 *
 * # Safety
 * `format` and a non-NULL `placement` readable; `out` writable.
 */
troupe_status troupe_motion_stream_new(const struct troupe_model *model, const struct troupe_joints_format *format, const struct troupe_placement *placement, struct troupe_motion_stream **out);

/**
 * Frames of latency a stream adds (1): feature frame t needs position frame t + 1.
 * Thread-safe.
 */
size_t troupe_motion_stream_latency_frames(void);

/**
 * The most feature frames one `troupe_motion_stream_push` writes (1 unless the caller's rate
 * is above the bundle's), or 0 for a NULL stream. Thread-safe.
 */
size_t troupe_motion_stream_max_frames(const struct troupe_motion_stream *stream);

/**
 * Feeds one frame of joint positions (`frame`: float32 `[22][3]`, `frame_len` = 66) and writes
 * the feature frames it completes into `features_out` (capacity `out_capacity_frames` frames of
 * `frame_dim` floats), their count into `*n_written` (0 for the first frame).
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (`frame_len` not 66),
 * `TROUPE_ERR_INVALID_ARG` (a NaN or infinite position, naming the joint; a first frame whose
 * hips give no facing), `TROUPE_ERR_BUFFER_TOO_SMALL` (capacity below
 * `troupe_motion_stream_max_frames`), `TROUPE_ERR_PANIC`. On error the stream is as before the
 * call. One thread at a time per stream.
 *
 * # Safety
 * `stream` a live handle; `frame` readable for `frame_len` floats; `features_out` writable for
 * `out_capacity_frames * frame_dim` floats; `n_written` writable.
 */
troupe_status troupe_motion_stream_push(struct troupe_motion_stream *stream, const float *frame, size_t frame_len, float *features_out, size_t out_capacity_frames, size_t *n_written);

/**
 * Writes the stream's placement (fixed by its first frame, or the one it was given) to `*out`.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (no frame yet and no
 * placement given). One thread at a time per stream.
 *
 * # Safety
 * `out` writable.
 */
troupe_status troupe_motion_stream_placement(const struct troupe_motion_stream *stream, struct troupe_placement *out);

/**
 * Forgets the stream's motion and placement, as if new (keeping its format), or fixes the
 * placement to `placement` when it is not NULL.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a bad placement; the
 * stream is then unchanged). One thread at a time per stream.
 *
 * # Safety
 * `stream` a live handle; a non-NULL `placement` readable.
 */
troupe_status troupe_motion_stream_reset(struct troupe_motion_stream *stream, const struct troupe_placement *placement);

/**
 * Frees a stream. NULL is a no-op.
 *
 * # Safety
 * `stream` must be NULL or a live handle from `troupe_motion_stream_new`, not used afterwards.
 */
void troupe_motion_stream_free(struct troupe_motion_stream *stream);

/**
 * Reads the BVH or FBX file at `path` (UTF-8; told apart by content) as t2m-22 joint positions. `joint_map_json`: a joint
 * map (JSON, see the built-in `src/motion/rigs/t2m22-joint-names.json`) or NULL for the
 * built-in one (LAFAN1, Mixamo, CMU, HumanIK, SMPL and Rigify names). t2m-22 joints the rig
 * lacks are placed from the others where they can be (`troupe_bvh_inferred` says which).
 * `units`: the file's length unit (`TROUPE_UNITS_*`), or `TROUPE_UNITS_AUTO` to guess from the
 * figure's height; an FBX file declares its own, and is converted to `units` (metres for
 * `TROUPE_UNITS_AUTO`). `*out` is set to NULL on entry and to the take on success.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_IO` (unreadable file),
 * `TROUPE_ERR_INVALID_ARG` (malformed file, naming line, joint and frame; a rig lacking a
 * t2m-22 joint that cannot be placed from the others, naming it and the names tried; a bad
 * map or units), `TROUPE_ERR_CANCELLED` (the progress callback stopped it: it reports every
 * 4096 frames), `TROUPE_ERR_PANIC`.
 * Thread-safe.
 *
 * # Safety
 * `path` and a non-NULL `joint_map_json` NUL-terminated; `out` writable.
 */
troupe_status troupe_bvh_read(const char *path, const char *joint_map_json, uint32_t units, struct troupe_bvh **out);

/**
 * The t2m-22 joints the take's rig lacks and how they were placed (spine joints along its
 * spine, toes along its feet, collars, a hand at a forearm's end; see docs/RIGS.md), one line
 * each (UTF-8, owned by the take, valid until it is freed; "" when the rig has every joint, NULL
 * for NULL). Thread-safe.
 */
const char *troupe_bvh_inferred(const struct troupe_bvh *bvh);

/**
 * The name of the rig joint t2m-22 joint `joint` (0 to 21, the order of the take's positions)
 * is read from: which joint became which, found by the joint map's names or by the rig's
 * shape. NULL where the joint is placed from others (`troupe_bvh_inferred` says how), for
 * `joint` above 21, and for NULL. UTF-8, owned by the take, valid until it is freed.
 * Thread-safe.
 */
const char *troupe_bvh_joint_source(const struct troupe_bvh *bvh, size_t joint);

/**
 * Frames of a take; 0 for NULL. Thread-safe.
 */
size_t troupe_bvh_frames(const struct troupe_bvh *bvh);

/**
 * Writes how to read the take's positions (its units, Y up, right-handed, its frame rate) into
 * `*format` (`format_size` = `sizeof(troupe_joints_format)`): pass it to the conversion
 * functions with the positions.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a size smaller than
 * the first version's). Thread-safe.
 *
 * # Safety
 * `format` writable for `format_size` bytes.
 */
troupe_status troupe_bvh_format(const struct troupe_bvh *bvh, struct troupe_joints_format *format, size_t format_size);

/**
 * Copies the take's t2m-22 joint positions, float32 `[frames][22][3]` in the file's units and
 * axes, into `positions` (`positions_len` = frames × 66).
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (another length).
 * Thread-safe.
 *
 * # Safety
 * `positions` writable for `positions_len` floats.
 */
troupe_status troupe_bvh_positions(const struct troupe_bvh *bvh, float *positions, size_t positions_len);

/**
 * Frees a take. NULL is a no-op.
 *
 * # Safety
 * `bvh` NULL or a live handle from `troupe_bvh_read`, not used afterwards.
 */
void troupe_bvh_free(struct troupe_bvh *bvh);

/**
 * Writes a BVH file at `path` (UTF-8; atomically: nothing is left on error) holding `n_people`
 * people on the t2m-22 skeleton: `positions` is float32 `[n_people][n_frames][22][3]` in the
 * caller's world as `format` says (its `fps` becomes the file's rate), `names` their names (NULL
 * or a NULL entry for "person1", "person2", ...; prefixed to joint names when there are several
 * people, who then
 * share a root joint called `scene`; at most 64 people). Rotations come from inverse kinematics; each person's bone
 * lengths are measured from their motion when `fit_skeleton` is non-zero (the file then
 * reproduces the positions), else troupe's neutral body is used. `units`: the file's length unit
 * (`TROUPE_UNITS_*`; centimetres are what most tools expect). The file is Y up.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (NaN or infinite
 * positions, no people or frames, a bad format or units; a name its reader would refuse:
 * repeated, too long, with whitespace, braces or control characters; a root beyond ±1e6 file
 * units; something at `path` that is not a regular file: a directory, link, FIFO, socket or
 * device), `TROUPE_ERR_IO`, `TROUPE_ERR_PANIC`. What it writes, `troupe_bvh_read` reads back.
 * Thread-safe.
 *
 * # Safety
 * `path` NUL-terminated; `positions` readable for `n_people * n_frames * 66` floats; `format`
 * readable; a non-NULL `names` readable for `n_people` NUL-terminated strings.
 */
troupe_status troupe_bvh_write(const char *path, const float *positions, size_t n_people, size_t n_frames, const struct troupe_joints_format *format, const char *const *names, uint32_t units, uint32_t fit_skeleton);

/**
 * Writes people's poses as a JSON document at `path` (UTF-8; atomically: nothing is left on
 * error): per person and frame, the 22 joint positions and rotations (unit quaternions
 * `[w, x, y, z]`: joint 0 the root's world orientation, the others local to their parent, from
 * inverse kinematics) and the 4 foot contacts, with the skeleton (joint names and parents),
 * units, up axis, handedness and frame rate stated in the document. `positions` is float32
 * `[n_people][n_frames][22][3]` in the caller's world as `format` says, which the document
 * keeps; `names` as for `troupe_bvh_write` (NULL: "person1", ...; at most 64 people).
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (NaN or infinite
 * positions, naming person, frame and joint; no people or frames; a bad format or name),
 * `TROUPE_ERR_IO`, `TROUPE_ERR_PANIC`. Thread-safe.
 *
 * # Safety
 * `path` NUL-terminated; `positions` readable for `n_people * n_frames * 66` floats; `format`
 * readable; a non-NULL `names` readable for `n_people` pointers, each NULL or NUL-terminated.
 */
troupe_status troupe_motion_write_json(const char *path, const float *positions, size_t n_people, size_t n_frames, const struct troupe_joints_format *format, const char *const *names);

/* ============================================================================================
 * 9. Rigs and glTF
 *
 * A caller's character rig, troupe's motion retargeted onto it frame by frame or as a clip,
 * and glTF (.glb) and BVH files of it.
 * ============================================================================================ */

/**
 * `troupe_rig_from_bvh`: the rest pose is the file's all-zero pose (its offsets).
 */
#define TROUPE_RIG_ZERO_POSE 4294967295

/**
 * Retargeting flag: do not pin feet in contact.
 */
#define TROUPE_RETARGET_NO_FOOT_LOCK 1

/**
 * Retargeting flag: no two-bone IK for hands and feet (feet are then not pinned either).
 */
#define TROUPE_RETARGET_NO_LIMB_IK 2

/**
 * `troupe_gltf_write` flag: no capsule bodies, the skeletons only.
 */
#define TROUPE_GLTF_NO_BODIES 4

/**
 * A character rig with the joint map that says which of its joints is which t2m-22 joint.
 * Immutable: any thread may use it. Free with `troupe_rig_free`.
 */
typedef struct troupe_rig troupe_rig;

/**
 * Retargeting one stream onto a rig, one frame at a time; used from one thread at a time (a
 * call while another thread uses it fails with `TROUPE_ERR_BUSY`). Free with
 * `troupe_rig_retargeter_free`; it does not need its rig afterwards.
 */
typedef struct troupe_rig_retargeter troupe_rig_retargeter;

/**
 * One person's clip for `troupe_gltf_write_people`: its own number of frames.
 */
typedef struct troupe_person_clip {
  /**
   * The person's name (NUL-terminated UTF-8), or NULL for "person1", "person2", ...
   */
  const char *name;
  /**
   * t2m-22 joint positions, float32 `[n_frames][22][3]`, in the caller's world.
   */
  const float *positions;
  /**
   * Frames of `positions`, at least 1.
   */
  size_t n_frames;
} troupe_person_clip;

/**
 * Reads the rig of the BVH or FBX file at `path` (UTF-8; told apart by content). `units`: the
 * file's length unit (`TROUPE_UNITS_*`, or `TROUPE_UNITS_AUTO` to guess from the rest pose's
 * height); an FBX file declares its own and is converted to `units` (metres for
 * `TROUPE_UNITS_AUTO`), its rest pose being its bind pose where it has one.
 * `rest_frame`: the frame whose pose is the rig's rest pose (for files whose all-zero pose lies
 * down, as LAFAN1's does), or `TROUPE_RIG_ZERO_POSE`. `joint_map_json`: which rig joint is
 * which t2m-22 joint (JSON), or NULL for the built-in names (Mixamo, LAFAN1, CMU, HumanIK,
 * SMPL, Rigify). `*out` is set to NULL on entry and to the rig on success.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_IO`, `TROUPE_ERR_INVALID_ARG` (a
 * malformed file, a frame past its end, a bad map or units), `TROUPE_ERR_PANIC`. Thread-safe.
 *
 * # Safety
 * `path` and a non-NULL `joint_map_json` NUL-terminated; `out` writable.
 */
troupe_status troupe_rig_from_bvh(const char *path, uint32_t units, uint32_t rest_frame, const char *joint_map_json, struct troupe_rig **out);

/**
 * The rig of skin `skin` in the glTF file at `path` (UTF-8; `.glb`, or `.gltf` JSON): the
 * skin's joints with their nodes' hierarchy and transforms as the rest pose (metres, Y up),
 * with `joint_map_json` as in `troupe_rig_from_bvh`. `*out` is set to NULL on entry and to the
 * rig on success.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_IO`, `TROUPE_ERR_INVALID_ARG` (not
 * glTF, no such skin, joints that are no tree, scaled joints, a bad map), `TROUPE_ERR_PANIC`.
 * Thread-safe.
 *
 * # Safety
 * `path` and a non-NULL `joint_map_json` NUL-terminated; `out` writable.
 */
troupe_status troupe_rig_from_gltf(const char *path, size_t skin, const char *joint_map_json, struct troupe_rig **out);

/**
 * A rig from its JSON document (`rig_json`: name, units, up axis, handedness, and joints with
 * parent, rest offset, optional rest rotation `[w, x, y, z]` and end site; see docs/RIGS.md),
 * with `joint_map_json` as in `troupe_rig_from_bvh`. `*out` is set to NULL on entry and to the
 * rig on success.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a malformed document or
 * map, naming what is wrong), `TROUPE_ERR_PANIC`. Thread-safe.
 *
 * # Safety
 * `rig_json` and a non-NULL `joint_map_json` NUL-terminated; `out` writable.
 */
troupe_status troupe_rig_from_json(const char *rig_json, const char *joint_map_json, struct troupe_rig **out);

/**
 * Joints of a rig; 0 for NULL. Thread-safe.
 */
size_t troupe_rig_joint_count(const struct troupe_rig *rig);

/**
 * The name of joint `joint` of a rig (UTF-8, owned by the rig, valid until it is freed), or
 * NULL for NULL or a joint past the end. Thread-safe.
 */
const char *troupe_rig_joint_name(const struct troupe_rig *rig, size_t joint);

/**
 * Frees a rig. NULL is a no-op.
 *
 * # Safety
 * `rig` NULL or a live handle from `troupe_rig_from_*`, not used afterwards.
 */
void troupe_rig_free(struct troupe_rig *rig);

/**
 * A retargeter of one stream onto `rig`: the stream's t2m-22 joint positions are in the
 * caller's world as `format` says (its `fps` sets contact speeds); `flags` is 0 or
 * `TROUPE_RETARGET_*` bits. `*out` is set to NULL on entry and to the retargeter on success.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a rig lacking a joint
 * retargeting needs, naming it and the names tried; a bad format or flags), `TROUPE_ERR_PANIC`.
 * Thread-safe.
 *
 * # Safety
 * `format` readable; `out` writable.
 */
troupe_status troupe_rig_retargeter_new(const struct troupe_rig *rig, const struct troupe_joints_format *format, uint32_t flags, struct troupe_rig_retargeter **out);

/**
 * Poses the rig for the stream's next frame: `positions` holds its 22 t2m-22 joint positions
 * (`positions_len` = 66) in the caller's world; writes every rig joint's local rotation as
 * `[w, x, y, z]` in the rig's axes into `rotations` (`rotations_len` = joints × 4), the moving
 * joint's local translation (rig units and axes) into `root_translation` (3 floats), and that
 * joint's index into `*root_joint`. No latency: the pose is this frame's.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (other lengths),
 * `TROUPE_ERR_INVALID_ARG` (NaN or infinite positions; the stream is then unchanged),
 * `TROUPE_ERR_BUSY`, `TROUPE_ERR_PANIC`. One thread at a time per retargeter.
 *
 * # Safety
 * `retargeter` a live handle; `positions` readable for `positions_len` floats; `rotations`
 * writable for `rotations_len` floats; `root_translation` writable for 3 floats; `root_joint`
 * writable.
 */
troupe_status troupe_rig_retarget_push(struct troupe_rig_retargeter *retargeter, const float *positions, size_t positions_len, float *rotations, size_t rotations_len, float *root_translation, size_t *root_joint);

/**
 * Forgets the stream (foot pins, the previous frame), as if new.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_BUSY`. One thread at a time per
 * retargeter.
 *
 * # Safety
 * `retargeter` a live handle.
 */
troupe_status troupe_rig_retarget_reset(struct troupe_rig_retargeter *retargeter);

/**
 * How the retargeter mapped its rig: for each t2m-22 joint (the order
 * `troupe_rig_retarget_push` takes positions in), the index of the rig joint it drives
 * (`troupe_rig_joint_name` names it), or -1 where the rig has none and that joint drives
 * nothing. Found by the joint map's names, or by the rig's shape where the names fall short
 * (`docs/RIGS.md`): this shows the user which joint became which. Writes 22 values.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_BUFFER_TOO_SMALL` (`capacity` under
 * 22: nothing written), `TROUPE_ERR_BUSY`. One thread at a time per retargeter.
 *
 * # Safety
 * `retargeter` a live handle; `rig_joints` writable for `capacity` values.
 */
troupe_status troupe_rig_retargeter_mapping(struct troupe_rig_retargeter *retargeter, int64_t *rig_joints, size_t capacity);

/**
 * Frees a retargeter. NULL is a no-op.
 *
 * # Safety
 * `retargeter` NULL or a live handle from `troupe_rig_retargeter_new`, not used afterwards.
 */
void troupe_rig_retargeter_free(struct troupe_rig_retargeter *retargeter);

/**
 * Retargets a whole clip onto `rig`: `positions`, float32 `[n_frames][22][3]` in the caller's
 * world as `format` says, with `flags` (0 or `TROUPE_RETARGET_*`); the source's proportions are
 * measured from the clip first (a stream uses troupe's neutral body). Writes each frame's local
 * rotations `[n_frames][joints][4]` (`[w, x, y, z]`, the rig's axes) into `rotations`
 * (`rotations_len` = frames × joints × 4), the moving joint's local translations `[n_frames][3]`
 * (rig units and axes) into `root_translations` (`root_len` = frames × 3), and the moving
 * joint's index into `*root_joint`.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (other lengths),
 * `TROUPE_ERR_INVALID_ARG` (as `troupe_rig_retargeter_new`; NaN or infinite positions; no
 * frames); on error nothing is written. `TROUPE_ERR_PANIC`. Thread-safe.
 *
 * # Safety
 * `positions` readable for `n_frames * 66` floats; `format` readable; `rotations` and
 * `root_translations` writable for their lengths; `root_joint` writable.
 */
troupe_status troupe_rig_retarget_clip(const struct troupe_rig *rig, const float *positions, size_t n_frames, const struct troupe_joints_format *format, uint32_t flags, float *rotations, size_t rotations_len, float *root_translations, size_t root_len, size_t *root_joint);

/**
 * `troupe_gltf_write` for people of different lengths (a partner streamed back lags its actor
 * by the stream's latency): `people`, `n_people` clips, each with its own frames. Each person's
 * animation keeps its own keys, and a shorter one holds its last pose to the end of the longest,
 * as glTF clients hold a sampler past its last key. Nothing is trimmed or padded. The rest is as
 * `troupe_gltf_write` says: retargeted onto `rig` (NULL: troupe's own body), `format` for every
 * person (its `fps` the animation's rate), `flags` its bits.
 *
 * Returns what `troupe_gltf_write` returns. Every buffer is borrowed for the call.
 * Thread-safe.
 *
 * ```c
 * troupe_person_clip people[2] = {{"actor", actor, n_actor}, {"partner", partner, n_partner}};
 * troupe_status st = troupe_gltf_write_people("duet.glb", NULL, people, 2, &format, 0);
 * ```
 *
 * # Safety
 * `path` NUL-terminated; `people` readable for `n_people` clips, each clip's `positions`
 * readable for `n_frames * 66` floats and its `name` NULL or NUL-terminated; `format` readable.
 */
troupe_status troupe_gltf_write_people(const char *path, const struct troupe_rig *rig, const struct troupe_person_clip *people, size_t n_people, const struct troupe_joints_format *format, uint32_t flags);

/**
 * Writes a glTF 2.0 binary file (`.glb`) at `path` (UTF-8; atomically): `n_people` people,
 * each retargeted onto `rig` (NULL: troupe's own t2m-22 body) from t2m-22 joint positions
 * `positions`, float32 `[n_people][n_frames][22][3]` in the caller's world as `format` says (its
 * `fps` becomes the animation's rate). Each person is a skeleton of nodes with a skin, a skinned
 * capsule body (unless `TROUPE_GLTF_NO_BODIES`) coloured per person, and channels of one
 * animation; `names` (NULL, or NULL entries, for "person1", ...) prefix node names when there
 * are several people (at most 64). `flags`: 0 or `TROUPE_RETARGET_*` and `TROUPE_GLTF_*` bits.
 * The file is in glTF's axes: metres, +Y up.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (NaN or infinite
 * positions, no people or frames, a bad format or flags, a rig lacking a joint retargeting
 * needs, something at `path` that is not a regular file), `TROUPE_ERR_IO`, `TROUPE_ERR_PANIC`.
 * Thread-safe.
 *
 * # Safety
 * `path` NUL-terminated; `positions` readable for `n_people * n_frames * 66` floats; `format`
 * readable; a non-NULL `names` readable for `n_people` pointers, each NULL or NUL-terminated.
 */
troupe_status troupe_gltf_write(const char *path, const struct troupe_rig *rig, const float *positions, size_t n_people, size_t n_frames, const struct troupe_joints_format *format, const char *const *names, uint32_t flags);

/**
 * Writes a BVH file at `path` (UTF-8; atomically) of `rig` posed by one person's t2m-22 joint
 * positions (`positions`, float32 `[n_frames][22][3]` in the caller's world as `format` says;
 * its `fps` becomes the file's rate), retargeted with `flags` (0 or `TROUPE_RETARGET_*`). The
 * file has the rig's hierarchy and rest offsets in `units` (`TROUPE_UNITS_*`), Y up; each
 * joint's channels hold its whole local rotation.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (as
 * `troupe_gltf_write`; a joint name with spaces or braces), `TROUPE_ERR_IO`,
 * `TROUPE_ERR_PANIC`. Thread-safe.
 *
 * # Safety
 * `path` NUL-terminated; `positions` readable for `n_frames * 66` floats; `format` readable.
 */
troupe_status troupe_rig_bvh_write(const char *path, const struct troupe_rig *rig, const float *positions, size_t n_frames, const struct troupe_joints_format *format, uint32_t units, uint32_t flags);

/**
 * Writes a binary FBX 7.4 file at `path` (UTF-8; atomically) of `rig` posed by one person's t2m-22 joint
 * positions (`positions`, float32 `[n_frames][22][3]` in the caller's world as `format` says;
 * its `fps` becomes the file's rate), retargeted with `flags` (0 or `TROUPE_RETARGET_*`). The
 * file has the rig's skeleton (`LimbNode`s, its rest pose as their transforms, `_end` leaves
 * at its end sites) in `units` (`TROUPE_UNITS_*`; FBX's own is centimetres), Y up, and one
 * animation with a key per frame: every joint's rotation, the moving joint's translation.
 * Blender, Unity, Unreal and Maya import it; `troupe_rig_from_bvh` reads it back.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (as
 * `troupe_gltf_write`; a joint name holding the bytes 0 or 1), `TROUPE_ERR_IO`,
 * `TROUPE_ERR_PANIC`. Thread-safe.
 *
 * # Safety
 * `path` NUL-terminated; `positions` readable for `n_frames * 66` floats; `format` readable.
 */
troupe_status troupe_rig_fbx_write(const char *path, const struct troupe_rig *rig, const float *positions, size_t n_frames, const struct troupe_joints_format *format, uint32_t units, uint32_t flags);

/* ============================================================================================
 * 10. Session motion
 *
 * Every streaming family's motion stages, chosen by its frame layout: joint positions in and
 * poses out, the penetration guard, the root smoothing, the foot lock.
 * ============================================================================================ */

/**
 * Turns a session's foot lock on (`enabled` nonzero) or off (`interhuman262` streams: ARMFlow,
 * ARFlow; MAGNet's frames carry no contact labels), from the next pose
 * `troupe_session_step_joints` returns: while a foot's ankle contact label is at least
 * `contact_threshold` (in (0, 1]) the ankle stays where the contact began, the leg bent by
 * two-bone IK; when the label drops, or the motion's ankle is farther than `max_stretch` metres
 * (in (0, 1]) from where it is held, it returns to the motion over `release_frames` frames (1
 * to 60). No frame is held back. The defaults are 0.5, 4 frames and 0.25 m; the other values
 * are ignored when turning it off. Turning it on starts with no foot held. Feature frames
 * (`troupe_session_step`) are not changed.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a value out of range;
 * the session keeps its foot lock), `TROUPE_ERR_UNSUPPORTED` (a stream whose frames the stage does not know),
 * `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * # Safety
 * `session` must be NULL or a live handle.
 */
troupe_status troupe_session_set_foot_lock(struct troupe_session *session, int32_t enabled, float contact_threshold, uint32_t release_frames, float max_stretch);

/**
 * Turns a session's penetration guard on (`enabled` nonzero) or off, for the frames sent from
 * now on (every streaming family: ARMFlow, ARFlow, MAGNet): each sent frame is shifted in the
 * floor plane out of the input person's body (joints nearer than `d_safe` metres, in [0, 0.5]), never faster than `max_speed` metres
 * per second (in (0, 10]); `docs/ARFLOW.md` states the rule and what it measured. The defaults
 * are 0.05 m and 2 m/s. `d_safe` and `max_speed` are ignored when turning it off.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a value out of range),
 * `TROUPE_ERR_UNSUPPORTED` (a stream whose frames the stage does not know), `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`.
 * One thread at a time per session.
 *
 * # Safety
 * `session` must be NULL or a live handle.
 */
troupe_status troupe_session_set_penetration_guard(struct troupe_session *session, int32_t enabled, float d_safe, float max_speed);

/**
 * Sets how `troupe_session_step_joints` reads the input person's positions (units, up axis,
 * handedness, frame rate; resampled to the bundle's rate) and forgets the joint stream's
 * frames and placement. Without it, positions are metres, Y up, right-handed, at the bundle's
 * rate. Every streaming family takes joint positions: `interhuman262` streams (ARMFlow, ARFlow)
 * as features, `magnet-smplx145` streams (MAGNet) by inverse kinematics (`docs/MOTION.md`).
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a bad format; the
 * session is then unchanged),
 * `TROUPE_ERR_UNSUPPORTED` (a stream whose frames carry no joints), `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`.
 * One thread at a time per session.
 *
 * # Safety
 * `session` a live handle; `format` readable for its `struct_size` bytes.
 */
troupe_status troupe_session_set_joints_format(struct troupe_session *session, const struct troupe_joints_format *format);

/**
 * Feeds `n_frames` frames of the input person's joint positions (`actor`: float32
 * `[n_frames][22][3]`, measured as `troupe_session_set_joints_format` said; may be NULL when
 * `n_frames` is 0) and writes the other person's poses that became ready, in the caller's
 * world, into the buffers of `*out` (each non-NULL buffer must hold `out_capacity_frames`
 * frames of its part), their count into `*n_written`. `troupe_session_joints_ready_after`
 * gives the exact count; `troupe_model_joints_latency_frames` the latency.
 *
 * On any error nothing is written and the session is exactly as before the call, except after
 * `TROUPE_ERR_PANIC`, which poisons it.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE` (a buffer smaller than its
 * capacity says), `TROUPE_ERR_INVALID_ARG` (a NaN or infinite position, naming frame and
 * joint), `TROUPE_ERR_UNSUPPORTED` (a stream whose frames carry no joints),
 * `TROUPE_ERR_BUFFER_TOO_SMALL`,
 * `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per
 * session.
 *
 * # Safety
 * `session` a live handle; `actor` readable for `n_frames * 66` floats; `out` readable and its
 * buffers writable for their lengths, overlapping nothing else; `n_written` writable.
 */
troupe_status troupe_session_step_joints(struct troupe_session *session, const float *actor, size_t n_frames, const struct troupe_pose_buffers *out, size_t out_capacity_frames, size_t *n_written);

/**
 * Writes to `*n_out` how many poses `troupe_session_step_joints` returns for the next
 * `n_frames` joint frames.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_UNSUPPORTED` (a stream whose frames
 * carry no joints),
 * `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * # Safety
 * `session` a live handle; `n_out` writable.
 */
troupe_status troupe_session_joints_ready_after(struct troupe_session *session, size_t n_frames, size_t *n_out);

/**
 * Writes the joint stream's placement (where the poses are put: fixed by the first joint
 * frame for `interhuman262` streams, the caller's own world for `magnet-smplx145` ones) to
 * `*out`.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (no joint frame yet),
 * `TROUPE_ERR_UNSUPPORTED` (a stream whose frames carry no joints), `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`.
 * One thread at a time per session.
 *
 * # Safety
 * `session` a live handle; `out` writable.
 */
troupe_status troupe_session_joints_placement(struct troupe_session *session, struct troupe_placement *out);

/**
 * Latency in frames when the input person streams joint positions: `troupe_model_latency_frames`
 * plus what the conversion waits for (one frame for `interhuman262` velocities and contacts,
 * none for `magnet-smplx145`); 0 for NULL and for a model whose streams take no joint
 * positions (a `umf` model, an ARMFlow bundle of InterX frames). Thread-safe.
 */
size_t troupe_model_joints_latency_frames(const struct troupe_model *model);

/**
 * Turns a session's root smoothing on (`enabled` nonzero) or off, for the frames sent from now
 * on (every streaming family): the generated person's root path on the floor is filtered causally with time constant
 * `time_constant` seconds (in (0, 2]; 0.1 is the demo's), the whole body moving with it, before
 * the penetration guard. No frame is held back; the root lags by about the time constant.
 * `time_constant` is ignored when turning it off.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a value out of range;
 * the session keeps its setting), `TROUPE_ERR_UNSUPPORTED` (a stream whose frames the stage does not know),
 * `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * # Safety
 * `session` must be NULL or a live handle.
 */
troupe_status troupe_session_set_root_smoothing(struct troupe_session *session, int32_t enabled, float time_constant);

/* ============================================================================================
 * 11. ARMFlow
 *
 * Online reaction: its session options, recentring, noise queued per token, the official clip.
 * ============================================================================================ */

/**
 * The random draws of one clip, given instead of seeded. Arrays are row-major float32, each
 * borrowed for the call; lengths are in floats.
 */
typedef struct troupe_clip_noise {
  /**
   * Standard normals of the actor posterior sample, `[clip_tokens][latent_dim]`.
   */
  const float *actor_posterior;
  /**
   * Length of `actor_posterior`.
   */
  size_t actor_posterior_len;
  /**
   * The one noise token every reactor token starts from, `[latent_dim]`.
   */
  const float *reactor_noise;
  /**
   * Length of `reactor_noise`.
   */
  size_t reactor_noise_len;
} troupe_clip_noise;

/**
 * The settings of one `troupe_armflow_clip_generate_with_options` call. Fill with
 * `troupe_armflow_clip_options_init` (the bundle's defaults), then change fields. Fields are
 * only ever appended; `struct_size` tells the library which version the caller has.
 */
typedef struct troupe_armflow_clip_options {
  /**
   * `sizeof(troupe_armflow_clip_options)` as the caller compiled it (set by `_init`).
   */
  uint32_t struct_size;
  /**
   * MeanFlow steps per token, >= 1 (`_init`: the bundle's, 1 for the official models).
   */
  uint32_t steps;
  /**
   * Seed of the draws when no noise is given.
   */
  uint64_t seed;
  /**
   * Classifier-free guidance scale, finite; 1 disables guidance (`_init`: the bundle's
   * `sampler.cfg_scale`, which the official sampler applies).
   */
  float cfg_scale;
  /**
   * Must be 0.
   */
  uint32_t reserved;
} troupe_armflow_clip_options;

/**
 * Options only an ARMFlow stream takes. Fill with `troupe_armflow_session_options_init`, then
 * change fields. Fields are only ever appended; `struct_size` tells the library which version
 * the caller has.
 */
typedef struct troupe_armflow_session_options {
  /**
   * `sizeof(troupe_armflow_session_options)` as the caller compiled it (set by `_init`).
   */
  uint32_t struct_size;
  /**
   * Classifier-free guidance scale, finite; the stream guides only above 1, as the official
   * sampler does. Changeable later with `troupe_session_set_cfg_scale`.
   */
  float cfg_scale;
  /**
   * `TROUPE_ACTOR_LATENT_SAMPLE` (the official choice) or `TROUPE_ACTOR_LATENT_MEAN`.
   */
  int32_t actor_latent;
  /**
   * Nonzero: run the VAE over windows of frames (the reference path) rather than the
   * bundle's per-token steps; slower, and recentring is then unavailable.
   */
  int32_t vae_windows;
} troupe_armflow_session_options;

/**
 * `sizeof(troupe_armflow_clip_options)` in this library, for bindings to check their mirror.
 */
size_t troupe_armflow_clip_options_size(void);

/**
 * Fills `options` with `model`'s sampler settings (MeanFlow steps, CFG scale) and seed 0, and
 * sets `struct_size`. Pass `sizeof(troupe_armflow_clip_options)` as `options_size`.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (`options_size` smaller
 * than the first version), `TROUPE_ERR_UNSUPPORTED` (not an `armflow` bundle). Thread-safe.
 *
 * # Safety
 * `model` must be a live handle; `options` writable for `options_size` bytes.
 */
troupe_status troupe_armflow_clip_options_init(const struct troupe_model *model, struct troupe_armflow_clip_options *options, size_t options_size);

/**
 * Tokens of the official clip of an `armflow` bundle exported from the official layout (75
 * InterHuman, 37 InterX); 0 for other bundles or NULL. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_armflow_clip_tokens(const struct troupe_model *model);

/**
 * Runs the official ARMFlow sampler on one actor clip with the bundle's settings (its MeanFlow
 * steps when `steps` is 0, and its CFG scale, `sampler.cfg_scale`, as the official sampler
 * applies it): `troupe_armflow_clip_generate_with_options` with `steps` and `seed` set and
 * the rest of `troupe_armflow_clip_options_init`'s defaults. Writes the reactor motion,
 * row-major float32 `[clip_frames][frame_dim]`, into `frames` (capacity `frames_capacity`
 * floats), and, when `reactor_latents` is not NULL, the reactor tokens
 * `[clip_tokens][latent_dim]` into it (capacity `latents_capacity` floats).
 *
 * `actor` holds `n_actor_frames` frames (1 to `troupe_model_clip_frames`), zero-padded to the
 * clip. `condition` holds `troupe_model_condition_dim` floats (NULL with `condition_len` 0:
 * the null condition). `noise` NULL draws from `seed` (the draws a session with that seed
 * makes for those tokens); otherwise it supplies every draw, the way to reproduce another
 * implementation's run exactly. Inputs are borrowed for the call; nothing is written unless
 * the call succeeds.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_UNSUPPORTED` (not an `armflow`
 * bundle), `TROUPE_ERR_INVALID_ARG` (a bundle without a clip, a clip of 0 or too many frames, non-finite input, bad noise length: the message says
 * which), `TROUPE_ERR_SHAPE` (condition length), `TROUPE_ERR_BUFFER_TOO_SMALL`,
 * `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_PANIC`. Thread-safe: any number of threads may generate
 * on one model at once.
 *
 * # Safety
 * `model` must be a live handle; `actor` readable for `n_actor_frames * frame_dim` floats;
 * `condition` for `condition_len`; `noise` NULL or a readable struct whose arrays are readable
 * for their lengths; `frames` writable for `frames_capacity` floats and `reactor_latents` (if
 * not NULL) for `latents_capacity`, neither overlapping an input.
 */
troupe_status troupe_armflow_clip_generate(const struct troupe_model *model, const float *actor, size_t n_actor_frames, const float *condition, size_t condition_len, uint64_t seed, uint32_t steps, const struct troupe_clip_noise *noise, float *frames, size_t frames_capacity, float *reactor_latents, size_t latents_capacity);

/**
 * `troupe_armflow_clip_generate` with every setting of the sampler: `options` NULL takes the
 * bundle's (`troupe_armflow_clip_options_init`). Guidance (`cfg_scale` other than 1) runs a
 * null row beside each conditional one, the actor token and the context zeroed, and takes
 * `u_null + cfg_scale * (u_cond - u_null)`, as the official sampler does.
 *
 * ```c
 * troupe_armflow_clip_options opt;
 * troupe_armflow_clip_options_init(model, &opt, sizeof opt);
 * opt.cfg_scale = 2.0f;
 * troupe_status st = troupe_armflow_clip_generate_with_options(model, &opt, actor, n, NULL, 0,
 *                                                             NULL, frames, n_frames, NULL, 0);
 * ```
 *
 * Returns what `troupe_armflow_clip_generate` returns, and `TROUPE_ERR_INVALID_ARG` for
 * options out of range (0 steps, a non-finite or too large CFG scale, a non-zero `reserved`,
 * a wrong `struct_size`). Thread-safe: any number of threads may generate on one model at
 * once.
 *
 * # Safety
 * As `troupe_armflow_clip_generate`; `options` NULL or readable for its `struct_size`.
 */
troupe_status troupe_armflow_clip_generate_with_options(const struct troupe_model *model, const struct troupe_armflow_clip_options *options, const float *actor, size_t n_actor_frames, const float *condition, size_t condition_len, const struct troupe_clip_noise *noise, float *frames, size_t frames_capacity, float *reactor_latents, size_t latents_capacity);

/**
 * Queues the noise of the next token an ARMFlow stream has not yet generated, to reproduce a
 * run exactly: `actor_noise` (the posterior sample's standard normals) and `reactor_noise` (the
 * starting noise), `len` floats each (`troupe_model_latent_dim`), borrowed for the call. Queued
 * noise is used in order before the seeded generator; `troupe_session_reset` drops it.
 * `troupe_session_queue_normals` queues the same draws as one run of floats, on any family.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_SHAPE`, `TROUPE_ERR_INVALID_ARG`
 * (non-finite value), `TROUPE_ERR_UNSUPPORTED` (not an ARMFlow stream), `TROUPE_ERR_POISONED`,
 * `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * # Safety
 * `session` must be a live handle; both noise pointers readable for `len` floats.
 */
troupe_status troupe_armflow_session_queue_noise(struct troupe_session *session, const float *actor_noise, const float *reactor_noise, size_t len);

/**
 * `sizeof(troupe_armflow_session_options)` in this library, for bindings to check their mirror.
 * Thread-safe.
 */
size_t troupe_armflow_session_options_size(void);

/**
 * Fills `options` with the defaults of `model`'s bundle (its CFG scale and actor latent, the
 * VAE's per-token steps) and sets `struct_size`. Pass `sizeof(troupe_armflow_session_options)`
 * as `options_size`: the library writes only that many bytes (zeroing fields it does not know).
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (an `options_size`
 * smaller than the first version of the struct), `TROUPE_ERR_UNSUPPORTED` (not an ARMFlow
 * model). Thread-safe.
 *
 * # Safety
 * `model` must be a live handle; `options` must be writable for `options_size` bytes.
 */
troupe_status troupe_armflow_session_options_init(const struct troupe_model *model, struct troupe_armflow_session_options *options, size_t options_size);

/**
 * Starts an ARMFlow stream on `model` (the reactor to an actor, from the null condition) with
 * the options every stream takes (`options`, NULL: the bundle's defaults) and ARMFlow's own
 * (`armflow`, NULL: the bundle's defaults). The deprecated `cfg_scale` and `actor_latent` fields
 * of `options` are not read: `armflow` says them.
 *
 * On success `*out` receives a new handle owned by the caller (free with
 * `troupe_session_free`); it keeps `model` alive. On failure `*out` is set to NULL.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (bad option values or
 * `struct_size`), `TROUPE_ERR_UNSUPPORTED` (not an ARMFlow model), `TROUPE_ERR_INFERENCE`,
 * `TROUPE_ERR_PANIC`. Thread-safe with respect to `model`.
 *
 * ```c
 * troupe_armflow_session_options arm;
 * troupe_armflow_session_options_init(model, &arm, sizeof arm);
 * arm.cfg_scale = 2.0f;
 * troupe_session *session = NULL;
 * troupe_status st = troupe_armflow_session_new(model, NULL, &arm, &session);
 * ```
 *
 * # Safety
 * `model` must be a live handle; `options` and `armflow` NULL or readable for their
 * `struct_size`; `out` writable.
 */
troupe_status troupe_armflow_session_new(const struct troupe_model *model, const struct troupe_session_options *options, const struct troupe_armflow_session_options *armflow, struct troupe_session **out);

/**
 * Turns an ARMFlow session's recentring on (`enabled` nonzero) or off: before each token, when
 * the actor's root is farther than `distance` metres (in [0.1, 100]; 1 is the demo's) on the
 * floor from where the networks' frame is centred, the centre moves to the actor and the
 * networks' state is rebuilt around it from the last 8 tokens of both people's motion, which
 * the session keeps while recentring is on (67 KB at the demo model's size). What the session
 * returns (frames and poses) stays in the stream's frame; a model trained near the origin then
 * keeps its quality however far the actor walks. The result does not depend on how frames are
 * split into calls. Turning it off keeps the centre where it is; `distance` is then ignored.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a distance out of
 * range; the session keeps its setting), `TROUPE_ERR_UNSUPPORTED` (not an ARMFlow session, or
 * one that runs the VAE over windows or whose VAE looks ahead), `TROUPE_ERR_POISONED`,
 * `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * # Safety
 * `session` must be NULL or a live handle.
 */
troupe_status troupe_armflow_session_set_recentring(struct troupe_session *session, int32_t enabled, float distance);

/* ============================================================================================
 * 12. UMF
 *
 * Text to a group of any size.
 * ============================================================================================ */

/**
 * Forward Euler.
 */
#define TROUPE_SOLVER_EULER 1

/**
 * The 3/8-rule fourth-order Runge-Kutta (torchdiffeq's `rk4`, UMF's solver).
 */
#define TROUPE_SOLVER_RK4 2

/**
 * The most pyramid stages `troupe_group_options` can describe.
 */
#define TROUPE_MAX_STAGES 8

/**
 * Options of `troupe_umf_generate`. Fill with `troupe_umf_options_init` (the bundle's
 * defaults), then change fields. Fields are only ever appended; `struct_size` tells the library
 * which version the caller has.
 */
typedef struct troupe_group_options {
  /**
   * `sizeof(troupe_group_options)` as the caller compiled it (set by `_init`).
   */
  uint32_t struct_size;
  /**
   * Pyramid stages of the bundle; must equal `troupe_umf_stages`.
   */
  uint32_t stage_count;
  /**
   * Seed of the portable noise generator, for draws not given as `troupe_group_noise`.
   */
  uint64_t seed;
  /**
   * Classifier-free guidance scale, finite; 1 runs the conditional branch only.
   */
  float cfg_scale;
  /**
   * Solver of each further person: `TROUPE_SOLVER_EULER` or `TROUPE_SOLVER_RK4`.
   */
  uint32_t reaction_solver;
  /**
   * Intervals of the further persons' solve, >= 1.
   */
  uint32_t reaction_steps;
  /**
   * Must be 0.
   */
  uint32_t reserved;
  /**
   * Solver of each pyramid stage, coarsest first (the first `stage_count` are read).
   */
  uint32_t stage_solver[TROUPE_MAX_STAGES];
  /**
   * Intervals of each pyramid stage, >= 1.
   */
  uint32_t stage_steps[TROUPE_MAX_STAGES];
} troupe_group_options;

/**
 * Every random draw of one generation, given instead of seeded. Arrays are row-major float32;
 * each pointer is borrowed for the call and its length is in floats.
 */
typedef struct troupe_group_noise {
  /**
   * First person's start at the coarsest stage, `[stage 0 tokens][latent_dim]`.
   */
  const float *prior;
  /**
   * Length of `prior`.
   */
  size_t prior_len;
  /**
   * Block noise of each jump, concatenated in stage order: `[stage k tokens][latent_dim]` for
   * k = 1, 2, ...
   */
  const float *jumps;
  /**
   * Length of `jumps`.
   */
  size_t jumps_len;
  /**
   * Noise half of each further person's start, `[people - 1][tokens][latent_dim]`.
   */
  const float *reactions;
  /**
   * Length of `reactions`.
   */
  size_t reactions_len;
} troupe_group_noise;

/**
 * `sizeof(troupe_group_options)` in this library, for bindings to check their mirror.
 */
size_t troupe_umf_options_size(void);

/**
 * Fills `options` with the defaults of `model`'s bundle (solvers per stage and for further
 * persons, CFG scale) and seed 0, and sets `struct_size`. Pass `sizeof(troupe_group_options)`
 * as `options_size`: the library writes only that many bytes.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (`options_size`
 * smaller than the first version, or a bundle with more than `TROUPE_MAX_STAGES` stages),
 * `TROUPE_ERR_UNSUPPORTED` (not a `umf` bundle). Thread-safe.
 *
 * ```c
 * troupe_group_options opt;
 * troupe_umf_options_init(model, &opt, sizeof opt);
 * opt.stage_solver[0] = TROUPE_SOLVER_EULER; opt.stage_steps[0] = 45;
 * ```
 *
 * # Safety
 * `model` must be a live handle; `options` must be writable for `options_size` bytes.
 */
troupe_status troupe_umf_options_init(const struct troupe_model *model, struct troupe_group_options *options, size_t options_size);

/**
 * Pyramid stages of a `umf` bundle (0 for other bundles or NULL). Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_umf_stages(const struct troupe_model *model);

/**
 * Latent tokens per person of a `umf` bundle at full resolution (0 for other bundles or
 * NULL). A person's latent is `tokens * troupe_model_latent_dim` floats. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_umf_tokens(const struct troupe_model *model);

/**
 * Writes the lengths, in floats, of the three arrays of a `troupe_group_noise` for `people`
 * people. Any out-pointer may be NULL.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG` (model), `TROUPE_ERR_INVALID_ARG` (people outside
 * 1..=256), `TROUPE_ERR_UNSUPPORTED` (not a `umf` bundle). Thread-safe.
 *
 * # Safety
 * `model` must be a live handle; each non-NULL out-pointer writable.
 */
troupe_status troupe_umf_noise_lengths(const struct troupe_model *model, uint32_t people, size_t *prior_len, size_t *jumps_len, size_t *reactions_len);

/**
 * Generates a group of `people` persons for `condition` and writes their motion, row-major
 * float32 `[people][clip_frames][frame_dim]`, into `motion` (capacity `motion_capacity`
 * floats), and, when `latents` is not NULL, their latents `[people][tokens][latent_dim]` into
 * `latents` (capacity `latents_capacity` floats).
 *
 * `condition` holds `troupe_model_condition_dim` floats, the prior text feature then the
 * reaction text feature; NULL (with `condition_len` 0) is the bundle's null condition.
 * `options` NULL means the bundle's defaults with seed 0. `noise` NULL draws every random value
 * from `options->seed`; otherwise it supplies them all (lengths from
 * `troupe_umf_noise_lengths`). Inputs are borrowed for the call. Nothing is written unless
 * the call succeeds.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (people outside
 * 1..=256, bad options, non-finite input: the message says which), `TROUPE_ERR_UNSUPPORTED`
 * (not a `umf` bundle),
 * `TROUPE_ERR_SHAPE` (condition or noise length), `TROUPE_ERR_BUFFER_TOO_SMALL` (the message
 * gives the floats needed), `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_PANIC`. Thread-safe: any number
 * of threads may generate on one model at once.
 *
 * ```c
 * size_t n = 2 * troupe_model_clip_frames(model) * troupe_model_frame_dim(model);
 * float *motion = malloc(n * sizeof *motion);
 * troupe_status st = troupe_umf_generate(model, NULL, text, text_len, 2, NULL,
 *                                          motion, n, NULL, 0);
 * ```
 *
 * # Safety
 * `model` must be a live handle; `options` NULL or readable for its `struct_size`;
 * `condition` readable for `condition_len` floats; `noise` NULL or a readable struct whose
 * arrays are readable for their lengths; `motion` writable for `motion_capacity` floats and
 * `latents` (if not NULL) for `latents_capacity`, neither overlapping an input.
 */
troupe_status troupe_umf_generate(const struct troupe_model *model, const struct troupe_group_options *options, const float *condition, size_t condition_len, uint32_t people, const struct troupe_group_noise *noise, float *motion, size_t motion_capacity, float *latents, size_t latents_capacity);

/* ============================================================================================
 * 13. MAGNet
 *
 * Multi-agent diffusion forcing: the released tasks, and the live partner's settings.
 * ============================================================================================ */

/**
 * `troupe_magnet_options.flags`: use `seed` instead of the configuration's.
 */
#define TROUPE_MAGNET_SEED 1

/**
 * `troupe_magnet_options.flags`: use `eta` instead of the configuration's.
 */
#define TROUPE_MAGNET_ETA 2

/**
 * `troupe_magnet_options.flags`: turn the x0 corrections (smoothing, foot skating) off; three
 * to five times cheaper (`docs/MAGNET.md`), not the released behaviour.
 */
#define TROUPE_MAGNET_NO_X0_GUIDANCE 4

/**
 * `troupe_magnet_options.flags`: use the first `keyframe_count` of `keyframes`.
 */
#define TROUPE_MAGNET_KEYFRAMES 8

/**
 * The most key frames `troupe_magnet_options` can carry.
 */
#define TROUPE_MAGNET_MAX_KEYFRAMES 8

/**
 * Changes to a released configuration for one `troupe_magnet_generate` call. Fill with
 * `troupe_magnet_options_init` (no changes), then set fields; zero counts keep the
 * configuration's value. Fields are only ever appended; `struct_size` tells the library which
 * version the caller has.
 */
typedef struct troupe_magnet_options {
  /**
   * `sizeof(troupe_magnet_options)` as the caller compiled it (set by `_init`).
   */
  uint32_t struct_size;
  /**
   * Samples generated at once (S); 0 keeps the configuration's.
   */
  uint32_t samples;
  /**
   * DDIM steps; 0 keeps the configuration's.
   */
  uint32_t steps;
  /**
   * Frames to generate (`sampling_seq_len`); 0 keeps the configuration's.
   */
  uint32_t seq_len;
  /**
   * `TROUPE_MAGNET_*` flags.
   */
  uint32_t flags;
  /**
   * Key frames used with `TROUPE_MAGNET_KEYFRAMES`.
   */
  uint32_t keyframe_count;
  /**
   * Seed of troupe's generator, with `TROUPE_MAGNET_SEED`.
   */
  uint64_t seed;
  /**
   * DDIM η, with `TROUPE_MAGNET_ETA`.
   */
  float eta;
  /**
   * Must be 0.
   */
  uint32_t reserved;
  /**
   * In-betweening's key frames (frames `k..k + 4` set token `k / 4`).
   */
  uint32_t keyframes[TROUPE_MAGNET_MAX_KEYFRAMES];
} troupe_magnet_options;

/**
 * `sizeof(troupe_magnet_options)` in this library, for bindings to check their mirror.
 */
size_t troupe_magnet_options_size(void);

/**
 * Fills `options` with no changes (every field 0) and sets `struct_size`. Pass
 * `sizeof(troupe_magnet_options)` as `options_size`: the library writes only that many bytes.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, or `TROUPE_ERR_INVALID_ARG` (`options_size`
 * smaller than the first version). Thread-safe.
 *
 * # Safety
 * `options` must be writable for `options_size` bytes.
 */
troupe_status troupe_magnet_options_init(struct troupe_magnet_options *options, size_t options_size);

/**
 * People a `magnet` model generates together (its checkpoint's P); 0 for other bundles or
 * NULL. Frames in and out are `[frames][people][145]`. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_magnet_people(const struct troupe_model *model);

/**
 * How many released sampling configurations a `magnet` bundle lists (0 for other bundles or
 * NULL). Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
size_t troupe_magnet_config_count(const struct troupe_model *model);

/**
 * The name of released configuration `index` (`"dd100"`, `"dd100_partner_prediction"`, ...),
 * or NULL for NULL or an index out of range. Owned by the model and valid until
 * `troupe_model_free`; never free it. Thread-safe.
 *
 * # Safety
 * `model` must be NULL or a live handle.
 */
const char *troupe_magnet_config(const struct troupe_model *model, size_t index);

/**
 * Writes the shape of the frames `troupe_magnet_generate` returns for `frame_count` frames of
 * input: `*samples`, `*frames`, `*people` (each float row is 145 wide). Any out-pointer may be
 * NULL. Makes the same checks of the configuration and the input's length as the generation.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_UNSUPPORTED` (not a `magnet` bundle),
 * `TROUPE_ERR_INVALID_ARG` (an unknown configuration, options the model cannot run, too few
 * input frames). Thread-safe.
 *
 * # Safety
 * `model` must be a live handle; `config` a NUL-terminated string; `options` NULL or readable
 * for its `struct_size`; each non-NULL out-pointer writable.
 */
troupe_status troupe_magnet_output_shape(const struct troupe_model *model, const char *config, const struct troupe_magnet_options *options, size_t frame_count, size_t *samples, size_t *frames, size_t *people);

/**
 * Runs the sampling configuration `config` (a name from `troupe_magnet_config`, or a
 * whole configuration as a JSON object with the fields of the manifest's `sampling` entries) on
 * `frame_count` frames of troupe motion, row-major float32 `[frame_count][people][145]` (per
 * person and frame: betas, the 21 body joints' 6-D rotations, the root's pose in the world, y
 * up), and writes the frames it generates, `[samples][frames][people][145]`
 * (`troupe_magnet_output_shape`), into `out` (capacity `out_capacity` floats). `present`
 * (NULL: everyone) is `[frame_count][people]` bytes, non-zero where the person is present.
 * What the input is depends on the task: the context for joint generation, turn-taking and
 * sync; person 0's whole motion for partner prediction, the live partner, inpainting and
 * pp2joint; the key frames for in-betweening. `options` NULL runs the configuration as
 * released. Inputs are borrowed for the call; nothing is written unless it succeeds.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_UNSUPPORTED` (not a `magnet` bundle),
 * `TROUPE_ERR_INVALID_ARG` (an unknown configuration, bad options, non-finite input, too few frames: the message says
 * which), `TROUPE_ERR_SHAPE`, `TROUPE_ERR_BUFFER_TOO_SMALL` (the message gives the floats
 * needed), `TROUPE_ERR_CANCELLED` (the progress callback stopped it), `TROUPE_ERR_INFERENCE`,
 * `TROUPE_ERR_PANIC`. Thread-safe: any number of threads may generate on one model at once.
 * Reports progress (network calls done, of the run's iterations) to the calling thread's
 * progress callback.
 *
 * ```c
 * size_t s, f, p;
 * troupe_magnet_output_shape(model, "dd100", NULL, n_frames, &s, &f, &p);
 * float *out = malloc(s * f * p * 145 * sizeof *out);
 * troupe_status st = troupe_magnet_generate(model, "dd100", NULL, frames, n_frames, NULL,
 *                                           out, s * f * p * 145);
 * ```
 *
 * # Safety
 * `model` must be a live handle; `config` a NUL-terminated string; `options` NULL or readable
 * for its `struct_size`; `frames` readable for `frame_count * people * 145` floats; `present`
 * NULL or readable for `frame_count * people` bytes; `out` writable for `out_capacity` floats
 * and not overlapping an input.
 */
troupe_status troupe_magnet_generate(const struct troupe_model *model, const char *config, const struct troupe_magnet_options *options, const float *frames, size_t frame_count, const uint8_t *present, float *out, size_t out_capacity);

/**
 * `troupe_magnet_generate` with the run's standard normals given instead of drawn: `draws`
 * holds `draws_len` normals (borrowed for the call), and each draw the sampler makes, in the
 * order `docs/MAGNET.md` lists, takes the next ones it needs. This is how a run of another
 * implementation (the official code, with its random draws recorded) is reproduced exactly.
 * `*draws_used` (when not NULL) receives how many it took; a run that needs more than given
 * fails with `TROUPE_ERR_INVALID_ARG`, naming the draw. Nothing is written unless the call
 * succeeds.
 *
 * Returns what `troupe_magnet_generate` returns. Thread-safe: any number of threads may
 * generate on one model at once.
 *
 * # Safety
 * As `troupe_magnet_generate`; `draws` readable for `draws_len` floats; `draws_used` NULL or
 * writable.
 */
troupe_status troupe_magnet_generate_with_draws(const struct troupe_model *model, const char *config, const struct troupe_magnet_options *options, const float *frames, size_t frame_count, const uint8_t *present, const float *draws, size_t draws_len, size_t *draws_used, float *out, size_t out_capacity);

/**
 * Sets the partner's opening frames of a MAGNet live partner session: `n_frames` frames
 * (the configuration's context, `4 * context_capacity`) of `troupe_model_frame_dim` floats,
 * row-major, borrowed for the call; kept across resets. A stream needs them before the user's
 * first frame. Only before the first step or after `troupe_session_reset`.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (the wrong number of
 * frames, a NaN or infinite value, a stream already started), `TROUPE_ERR_UNSUPPORTED` (not a
 * MAGNet session), `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * ```c
 * troupe_magnet_session_set_partner_opening(session, partner_frames, 32);
 * ```
 *
 * # Safety
 * `session` must be a live handle; `frames` readable for `n_frames * 145` floats.
 */
troupe_status troupe_magnet_session_set_partner_opening(struct troupe_session *session, const float *frames, size_t n_frames);

/**
 * Makes a MAGNet live partner session send each chunk's frames as soon as they are generated
 * (`early` nonzero: `4 * (window - context)` frames less latency; the next chunk's smoothing no
 * longer reaches them) or once final (0, the default). Only before the first step or after
 * `troupe_session_reset`.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (a stream already
 * started), `TROUPE_ERR_UNSUPPORTED` (not a MAGNet session), `TROUPE_ERR_POISONED`,
 * `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * # Safety
 * `session` must be NULL or a live handle.
 */
troupe_status troupe_magnet_session_set_early_emission(struct troupe_session *session, int32_t early);

/**
 * Makes a MAGNet live partner session run the sampling configuration `config` (a
 * NUL-terminated name from `troupe_magnet_config`, or a whole configuration as JSON;
 * borrowed for the call), for instance one with the x0 guidance off. Only before the first
 * step or after `troupe_session_reset`; set opening frames after it when its context differs.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_UNSUPPORTED` (not a MAGNet session),
 * `TROUPE_ERR_INVALID_ARG` (an unknown name, bad JSON, a configuration that is not `motion_control_live`, a stream already
 * started), `TROUPE_ERR_POISONED`, `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * # Safety
 * `session` must be a live handle; `config` a NUL-terminated string.
 */
troupe_status troupe_magnet_session_set_live_config(struct troupe_session *session, const char *config);

/* ============================================================================================
 * 14. ARFlow
 *
 * Action to reaction with penetration guidance, offline and online.
 * ============================================================================================ */

/**
 * `troupe_arflow_options.flags`: a squared hinge in the penetration loss (else linear).
 */
#define TROUPE_ARFLOW_SQUARED_HINGE 1

/**
 * `troupe_arflow_options.flags`: back-project with the network's x̂_1, not the guided one.
 */
#define TROUPE_ARFLOW_UNGUIDED_BACKPROJECTION 2

/**
 * `troupe_arflow_options.flags`: mix the stochastic direction as `√(1 − η²) v + η ε` (else
 * `(1 − η) v + η ε`).
 */
#define TROUPE_ARFLOW_VARIANCE_PRESERVING 4

/**
 * ARFlow's sampler settings for one `troupe_arflow_generate` call. Fill with
 * `troupe_arflow_options_init` (the bundle's defaults), then change fields. Fields are only
 * ever appended; `struct_size` tells the library which version the caller has.
 */
typedef struct troupe_arflow_options {
  /**
   * `sizeof(troupe_arflow_options)` as the caller compiled it (set by `_init`).
   */
  uint32_t struct_size;
  /**
   * Euler steps M, >= 1.
   */
  uint32_t steps;
  /**
   * The guidance strength λ, >= 0 (0: no guidance).
   */
  float guidance;
  /**
   * The reweighting toward the actor w, in [0, 1] (1: none).
   */
  float weight;
  /**
   * The stochastic share η, in [0, 1) (0: deterministic).
   */
  float eta;
  /**
   * The penetration loss's safe distance, metres, in [0, 1].
   */
  float d_safe;
  /**
   * The start noise σ (0: the flow starts at the actor exactly).
   */
  float sigma;
  /**
   * `TROUPE_ARFLOW_*` flags.
   */
  uint32_t flags;
  /**
   * Seed of troupe's generator (used when η > 0 or σ > 0).
   */
  uint64_t seed;
} troupe_arflow_options;

/**
 * `sizeof(troupe_arflow_options)` in this library, for bindings to check their mirror.
 */
size_t troupe_arflow_options_size(void);

/**
 * Fills `options` with `model`'s sampler defaults (`docs/ARFLOW.md`: 5 steps, λ 2, w 0.7,
 * η 0, d_safe 0.02 m, linear hinge, guided back-projection, σ 0) and seed 0, and sets
 * `struct_size`. Pass `sizeof(troupe_arflow_options)` as `options_size`.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (`options_size` smaller
 * than the first version), `TROUPE_ERR_UNSUPPORTED` (not an `arflow` bundle). Thread-safe.
 *
 * # Safety
 * `model` must be a live handle; `options` writable for `options_size` bytes.
 */
troupe_status troupe_arflow_options_init(const struct troupe_model *model, struct troupe_arflow_options *options, size_t options_size);

/**
 * ARFlow's generation: the reactor's frames for the actor's. `actor` holds `n_frames`
 * `interhuman262` frames (row-major float32 `[n_frames][262]`, one world frame for both people,
 * borrowed for the call); the reactor's `n_frames` frames go into `out` (capacity
 * `out_capacity_frames` frames). `options` NULL runs the bundle's defaults with seed 0. With an
 * online bundle (a causal network) frame `n` of the result depends only on the actor's frames up
 * to `n`. Nothing is written unless it succeeds.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_UNSUPPORTED` (not an `arflow`
 * bundle), `TROUPE_ERR_INVALID_ARG` (settings out of range, a NaN or infinite value, 0 frames or more than the bundle's
 * `model.max_frames`), `TROUPE_ERR_BUFFER_TOO_SMALL`, `TROUPE_ERR_CANCELLED`,
 * `TROUPE_ERR_INFERENCE`, `TROUPE_ERR_PANIC`. Thread-safe: any number of threads may generate on
 * one model at once. Reports progress (steps done) to the calling thread's progress callback.
 *
 * ```c
 * troupe_arflow_options opt;
 * troupe_arflow_options_init(model, &opt, sizeof opt);
 * opt.guidance = 0.0f;
 * troupe_status st = troupe_arflow_generate(model, &opt, actor, n, reactor, n);
 * ```
 *
 * # Safety
 * `model` must be a live handle; `options` NULL or readable for its `struct_size`; `actor`
 * readable for `n_frames * 262` floats; `out` writable for `out_capacity_frames * 262` floats
 * and not overlapping `actor`.
 */
troupe_status troupe_arflow_generate(const struct troupe_model *model, const struct troupe_arflow_options *options, const float *actor, size_t n_frames, float *out, size_t out_capacity_frames);

/**
 * `troupe_arflow_generate` with the run's standard normals given instead of drawn from the
 * seed: `draws` holds `draws_len` normals (borrowed for the call), and each draw (the start
 * noise when σ > 0, then one ε per step when η > 0, each `n_frames * 262` normals) takes the
 * next ones, as another implementation's recorded draws are replayed. `*draws_used` (when
 * not NULL) receives how many it took; a run that needs more than given fails with
 * `TROUPE_ERR_INVALID_ARG`, naming the draw. Nothing is written unless the call succeeds.
 *
 * Returns what `troupe_arflow_generate` returns. Thread-safe: any number of threads may
 * generate on one model at once.
 *
 * # Safety
 * As `troupe_arflow_generate`; `draws` readable for `draws_len` floats; `draws_used` NULL or
 * writable.
 */
troupe_status troupe_arflow_generate_with_draws(const struct troupe_model *model, const struct troupe_arflow_options *options, const float *actor, size_t n_frames, const float *draws, size_t draws_len, size_t *draws_used, float *out, size_t out_capacity_frames);

/**
 * Sets an ARFlow stream's sampler settings (`options`, filled by `troupe_arflow_options_init`;
 * its seed too); a new step count only before the first frame or after `troupe_session_reset`.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG`, `TROUPE_ERR_INVALID_ARG` (settings out of range,
 * unknown flags), `TROUPE_ERR_UNSUPPORTED` (not an ARFlow stream), `TROUPE_ERR_POISONED`,
 * `TROUPE_ERR_PANIC`. One thread at a time per session.
 *
 * # Safety
 * `session` must be a live handle; `options` readable for its `struct_size`.
 */
troupe_status troupe_arflow_session_set_options(struct troupe_session *session, const struct troupe_arflow_options *options);

/* ============================================================================================
 * 15. Viewer
 *
 * Pictures of motion: a self-contained HTML player and a GIF.
 * ============================================================================================ */

/**
 * Writes pictures of `n_people` people moving on the t2m-22 skeleton: a self-contained HTML
 * player (no network; drag to orbit, wheel to zoom, play/pause, frame slider, speed) to
 * `html_path`, and an animated GIF (480 × 360, at most 15 frames per second, from the
 * player's starting view) to `gif_path`. Either path may be NULL, not both.
 *
 * `positions` holds float32 `[n_people][n_frames][22][3]` joint positions measured as `format`
 * says (units, up axis, handedness; its `fps` is the playback rate). `names` holds `n_people`
 * UTF-8 names for the legend (at most 64 characters each); NULL names them "person1",
 * "person2", ..., as does a NULL entry. `title` is a UTF-8 title (at most 200 characters) or
 * NULL for none. People are coloured blue (#1f77b4), orange (#ff7f0e), green, red, purple,
 * brown, pink, cyan, in order.
 *
 * Returns `TROUPE_OK`, `TROUPE_ERR_NULL_ARG` (`positions` or `format` NULL, or both paths
 * NULL), `TROUPE_ERR_INVALID_ARG` (`n_people` not in 1..=8; `n_frames` not in 1..=18000; a
 * non-finite position or one farther than 10 km, naming the person, frame and joint; a bad
 * format; a path, name or title not UTF-8 or too long; something at a path that is not a
 * regular file: a directory, link, FIFO, socket or device), `TROUPE_ERR_IO` (a file that
 * cannot be written, e.g. its directory is missing), `TROUPE_ERR_CANCELLED` (the progress
 * callback stopped the GIF, which reports every frame), `TROUPE_ERR_PANIC`. Nothing is
 * written on error:
 * both files are rendered and written to temporary files beside them first, then renamed into
 * place. Thread-safe.
 *
 * # Safety
 * `positions` readable for `n_people * n_frames * 66` floats; `format` readable for its
 * `struct_size` bytes; a non-NULL `names` readable for `n_people` pointers, each NULL or
 * NUL-terminated; non-NULL `html_path`, `gif_path` and `title` NUL-terminated.
 */
troupe_status troupe_viewer_write(const char *html_path, const char *gif_path, const float *positions, size_t n_people, size_t n_frames, const struct troupe_joints_format *format, const char *const *names, const char *title);

/* ============================================================================================
 * 16. Deprecated names
 *
 * The names before every family call had its family's prefix; each forwards to the function it
 * names. Kept until 2.0.
 * ============================================================================================ */

/**
 * Deprecated name of `troupe_armflow_clip_tokens`, kept until 2.0.
 *
 * # Safety
 * As `troupe_armflow_clip_tokens`.
 */
TROUPE_DEPRECATED("use troupe_armflow_clip_tokens") size_t troupe_model_clip_tokens(const struct troupe_model *model);

/**
 * Deprecated name of `troupe_armflow_clip_generate`, kept until 2.0.
 *
 * # Safety
 * As `troupe_armflow_clip_generate`.
 */
TROUPE_DEPRECATED("use troupe_armflow_clip_generate") troupe_status troupe_clip_generate(const struct troupe_model *model, const float *actor, size_t n_actor_frames, const float *condition, size_t condition_len, uint64_t seed, uint32_t steps, const struct troupe_clip_noise *noise, float *frames, size_t frames_capacity, float *reactor_latents, size_t latents_capacity);

/**
 * Deprecated name of `troupe_session_set_penetration_guard` (0.2: the guard serves every
 * streaming family), kept until 2.0.
 *
 * # Safety
 * As `troupe_session_set_penetration_guard`.
 */
TROUPE_DEPRECATED("use troupe_session_set_penetration_guard") troupe_status troupe_armflow_session_set_penetration_guard(struct troupe_session *session, int32_t enabled, float d_safe, float max_speed);

/**
 * Deprecated name of `troupe_session_set_root_smoothing` (0.2: the smoothing serves every
 * streaming family), kept until 2.0.
 *
 * # Safety
 * As `troupe_session_set_root_smoothing`.
 */
TROUPE_DEPRECATED("use troupe_session_set_root_smoothing") troupe_status troupe_armflow_session_set_root_smoothing(struct troupe_session *session, int32_t enabled, float time_constant);

/**
 * Deprecated name of `troupe_session_set_foot_lock` (0.2: the foot lock serves every stream
 * whose frames carry contact labels), kept until 2.0.
 *
 * # Safety
 * As `troupe_session_set_foot_lock`.
 */
TROUPE_DEPRECATED("use troupe_session_set_foot_lock") troupe_status troupe_armflow_session_set_foot_lock(struct troupe_session *session, int32_t enabled, float contact_threshold, uint32_t release_frames, float max_stretch);

/**
 * Deprecated name of `troupe_armflow_session_queue_noise` (0.2: ARMFlow's own calls are named
 * for it), kept until 2.0.
 *
 * # Safety
 * As `troupe_armflow_session_queue_noise`.
 */
TROUPE_DEPRECATED("use troupe_armflow_session_queue_noise") troupe_status troupe_session_queue_noise(struct troupe_session *session, const float *actor_noise, const float *reactor_noise, size_t len);

/**
 * Deprecated name of `troupe_umf_options_size`, kept until 2.0.
 */
TROUPE_DEPRECATED("use troupe_umf_options_size") size_t troupe_group_options_size(void);

/**
 * Deprecated name of `troupe_umf_options_init`, kept until 2.0.
 *
 * # Safety
 * As `troupe_umf_options_init`.
 */
TROUPE_DEPRECATED("use troupe_umf_options_init") troupe_status troupe_group_options_init(const struct troupe_model *model, struct troupe_group_options *options, size_t options_size);

/**
 * Deprecated name of `troupe_umf_stages`, kept until 2.0.
 *
 * # Safety
 * As `troupe_umf_stages`.
 */
TROUPE_DEPRECATED("use troupe_umf_stages") size_t troupe_model_group_stages(const struct troupe_model *model);

/**
 * Deprecated name of `troupe_umf_tokens`, kept until 2.0.
 *
 * # Safety
 * As `troupe_umf_tokens`.
 */
TROUPE_DEPRECATED("use troupe_umf_tokens") size_t troupe_model_group_tokens(const struct troupe_model *model);

/**
 * Deprecated name of `troupe_umf_noise_lengths`, kept until 2.0.
 *
 * # Safety
 * As `troupe_umf_noise_lengths`.
 */
TROUPE_DEPRECATED("use troupe_umf_noise_lengths") troupe_status troupe_group_noise_lengths(const struct troupe_model *model, uint32_t people, size_t *prior_len, size_t *jumps_len, size_t *reactions_len);

/**
 * Deprecated name of `troupe_umf_generate`, kept until 2.0.
 *
 * # Safety
 * As `troupe_umf_generate`.
 */
TROUPE_DEPRECATED("use troupe_umf_generate") troupe_status troupe_group_generate(const struct troupe_model *model, const struct troupe_group_options *options, const float *condition, size_t condition_len, uint32_t people, const struct troupe_group_noise *noise, float *motion, size_t motion_capacity, float *latents, size_t latents_capacity);

/**
 * Deprecated name of `troupe_magnet_people`, kept until 2.0.
 *
 * # Safety
 * As `troupe_magnet_people`.
 */
TROUPE_DEPRECATED("use troupe_magnet_people") size_t troupe_model_magnet_people(const struct troupe_model *model);

/**
 * Deprecated name of `troupe_magnet_config_count`, kept until 2.0.
 *
 * # Safety
 * As `troupe_magnet_config_count`.
 */
TROUPE_DEPRECATED("use troupe_magnet_config_count") size_t troupe_model_magnet_config_count(const struct troupe_model *model);

/**
 * Deprecated name of `troupe_magnet_config`, kept until 2.0.
 *
 * # Safety
 * As `troupe_magnet_config`.
 */
TROUPE_DEPRECATED("use troupe_magnet_config") const char *troupe_model_magnet_config(const struct troupe_model *model, size_t index);

/**
 * Deprecated name of `troupe_magnet_session_set_partner_opening`, kept until 2.0.
 *
 * # Safety
 * As `troupe_magnet_session_set_partner_opening`.
 */
TROUPE_DEPRECATED("use troupe_magnet_session_set_partner_opening") troupe_status troupe_session_set_partner_opening(struct troupe_session *session, const float *frames, size_t n_frames);

/**
 * Deprecated name of `troupe_magnet_session_set_early_emission`, kept until 2.0.
 *
 * # Safety
 * As `troupe_magnet_session_set_early_emission`.
 */
TROUPE_DEPRECATED("use troupe_magnet_session_set_early_emission") troupe_status troupe_session_set_early_emission(struct troupe_session *session, int32_t early);

/**
 * Deprecated name of `troupe_magnet_session_set_live_config`, kept until 2.0.
 *
 * # Safety
 * As `troupe_magnet_session_set_live_config`.
 */
TROUPE_DEPRECATED("use troupe_magnet_session_set_live_config") troupe_status troupe_session_set_live_config(struct troupe_session *session, const char *config);

/**
 * Deprecated name of `troupe_arflow_session_set_options`, kept until 2.0.
 *
 * # Safety
 * As `troupe_arflow_session_set_options`.
 */
TROUPE_DEPRECATED("use troupe_arflow_session_set_options") troupe_status troupe_session_set_arflow_options(struct troupe_session *session, const struct troupe_arflow_options *options);

/**
 * Deprecated name of `troupe_motion_penetration_metrics`, kept until 2.0.
 *
 * # Safety
 * As `troupe_motion_penetration_metrics`.
 */
TROUPE_DEPRECATED("use troupe_motion_penetration_metrics") troupe_status troupe_penetration_metrics(const float *first, const float *second, size_t n_frames, size_t *frames_intersecting, double *frequency, double *depth_sum, double *max_depth);

#ifdef __cplusplus
}  /* extern "C" */
#endif

#endif  /* TROUPE_H */

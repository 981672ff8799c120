// troupe.hpp: header-only C++17 RAII wrapper over the troupe C ABI (include/troupe.h).
//
// Move-only troupe::Model and troupe::Session own their handles. Every fallible method returns
// a troupe::Status (works with -fno-exceptions); define TROUPE_CPP_EXCEPTIONS before including
// to also get the throwing helpers troupe::check() and the *_or_throw factories.
//
// Threading follows the C API: a Model may be shared by any number of threads; a Session is
// used by one thread at a time.
#ifndef TROUPE_HPP
#define TROUPE_HPP

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "troupe.h"

#ifdef TROUPE_CPP_EXCEPTIONS
#include <stdexcept>
#endif

namespace troupe {

/// A status code plus the library's message for it (empty on success).
class Status {
  public:
    Status() = default;
    /// Captures `code` and, on failure, this thread's last error message.
    static Status from(troupe_status code) {
        Status s;
        s.code_ = code;
        if (code != TROUPE_OK) {
            const char *m = troupe_last_error_message();
            s.message_ = m ? m : troupe_status_name(code);
        }
        return s;
    }
    bool ok() const { return code_ == TROUPE_OK; }
    explicit operator bool() const { return ok(); }
    troupe_status code() const { return code_; }
    const std::string &message() const { return message_; }

  private:
    troupe_status code_ = TROUPE_OK;
    std::string message_;
};

#ifdef TROUPE_CPP_EXCEPTIONS
/// Thrown by check(): carries the status code and message.
class Error : public std::runtime_error {
  public:
    explicit Error(const Status &s) : std::runtime_error(s.message()), code_(s.code()) {}
    troupe_status code() const { return code_; }

  private:
    troupe_status code_;
};

/// Throws troupe::Error unless `s` is ok.
inline void check(const Status &s) {
    if (!s.ok()) throw Error(s);
}
#endif

/// True when the loaded library speaks the ABI this header was written for.
inline bool abi_compatible() { return troupe_abi_version() == TROUPE_ABI_VERSION; }

/// The library's limits (troupe_limits_get): every size from a file or a caller is checked
/// against them before anything is allocated.
inline troupe_limits limits() {
    troupe_limits l{};
    troupe_limits_get(&l, sizeof l);
    return l;
}

/// The library's version: "MAJOR.MINOR.PATCH", and as one number ((major << 16) | (minor << 8) |
/// patch), for comparing with TROUPE_VERSION_NUMBER at run time.
inline std::string version() { return troupe_version_string(); }
inline std::uint32_t version_number() { return troupe_version_number(); }

/// Threads for matrix products (0: every core) and for loading graphs; process-wide.
inline Status set_compute_threads(std::size_t threads) {
    return Status::from(troupe_set_compute_threads(threads));
}
inline std::size_t compute_threads() { return troupe_compute_threads(); }
inline void set_load_threads(std::size_t threads) { troupe_set_load_threads(threads); }
inline std::size_t load_threads() { return troupe_load_threads(); }

/// Bounds the work and time of the long calls this thread makes (zeros: no bound); see
/// troupe_set_call_budget.
inline Status set_call_budget(const troupe_call_budget &budget) {
    return Status::from(troupe_set_call_budget(&budget));
}

/// Sends the library's log records up to `max_level` (TROUPE_LOG_*) to `callback` (null: back to
/// stderr per TROUPE_LOG); process-wide, called from any thread, so it must be thread-safe.
inline Status set_log_callback(troupe_log_fn callback, void *user_data, std::int32_t max_level) {
    return Status::from(troupe_set_log_callback(callback, user_data, max_level));
}

/// Reports the progress of long calls (loads, groups, clips) made by this thread while it lives
/// to `callback(done, total)`; a callback returning false cancels the call
/// (TROUPE_ERR_CANCELLED). The callback must not throw. Restores "no callback" when destroyed.
template <class F>
class ProgressScope {
  public:
    explicit ProgressScope(F callback) : callback_(std::move(callback)) {
        troupe_set_progress_callback(&ProgressScope::call, this);
    }
    ~ProgressScope() { troupe_set_progress_callback(nullptr, nullptr); }
    ProgressScope(const ProgressScope &) = delete;
    ProgressScope &operator=(const ProgressScope &) = delete;

  private:
    static std::int32_t call(void *self, std::uint64_t done, std::uint64_t total) {
        return static_cast<ProgressScope *>(self)->callback_(done, total) ? 0 : 1;
    }
    F callback_;
};

class Session;

/// A loaded bundle. Move-only; freeing it while sessions exist is safe.
class Model {
  public:
    Model() = default;
    Model(Model &&other) noexcept : handle_(std::exchange(other.handle_, nullptr)) {}
    Model &operator=(Model &&other) noexcept {
        if (this != &other) {
            troupe_model_free(handle_);
            handle_ = std::exchange(other.handle_, nullptr);
        }
        return *this;
    }
    Model(const Model &) = delete;
    Model &operator=(const Model &) = delete;
    ~Model() { troupe_model_free(handle_); }

    /// Loads a bundle directory or archive file.
    static Status load(const std::string &path, Model &out) {
        troupe_model *h = nullptr;
        Status s = Status::from(troupe_model_load_file(path.c_str(), &h));
        if (s) out = Model(h);
        return s;
    }
    /// Loads a bundle archive from memory (the bytes are copied).
    static Status load_memory(const void *data, std::size_t len, Model &out) {
        troupe_model *h = nullptr;
        Status s = Status::from(troupe_model_load_memory(static_cast<const std::uint8_t *>(data), len, &h));
        if (s) out = Model(h);
        return s;
    }
#ifdef TROUPE_CPP_EXCEPTIONS
    static Model load_or_throw(const std::string &path) {
        Model m;
        check(load(path, m));
        return m;
    }
#endif

    bool valid() const { return handle_ != nullptr; }
    std::size_t frame_dim() const { return troupe_model_frame_dim(handle_); }
    std::size_t fps() const { return troupe_model_fps(handle_); }
    std::size_t frames_per_token() const { return troupe_model_frames_per_token(handle_); }
    std::size_t latency_frames() const { return troupe_model_latency_frames(handle_); }
    /// The width of one CLIP token (0 for a bundle without a text branch).
    std::size_t text_token_dim() const { return troupe_model_text_token_dim(handle_); }
    /// The condition for CLIP tokens computed elsewhere (`n_tokens` x text_token_dim floats, the
    /// end-of-text token at `eot_index`); `condition` replaced only on success.
    Status encode_text(const float *tokens, std::size_t n_tokens, std::size_t eot_index,
                       std::vector<float> &condition) const {
        std::vector<float> v(troupe_model_condition_dim(handle_));
        Status s = Status::from(troupe_text_encode(handle_, tokens, n_tokens, eot_index, v.data(), v.size()));
        if (s) condition.swap(v);
        return s;
    }
    /// Frames of latency of the joint stream (step_joints) over the feature stream.
    std::size_t joints_latency_frames() const { return troupe_model_joints_latency_frames(handle_); }
    std::size_t condition_dim() const { return troupe_model_condition_dim(handle_); }
    std::size_t latent_dim() const { return troupe_model_latent_dim(handle_); }
    /// The named conditions the bundle was trained on (the demo model's partner rules).
    std::vector<std::string> condition_labels() const {
        std::vector<std::string> out;
        for (std::size_t i = 0, n = troupe_model_condition_label_count(handle_); i < n; ++i)
            out.emplace_back(troupe_model_condition_label(handle_, i));
        return out;
    }
    /// The graphs whose weights are not float32, as (role, storage) pairs ({"velocity", "int8"});
    /// empty for a float32 bundle.
    std::vector<std::pair<std::string, std::string>> reduced_precision() const {
        std::vector<std::pair<std::string, std::string>> out;
        for (std::size_t i = 0, n = troupe_model_reduced_precision_count(handle_); i < n; ++i)
            out.emplace_back(troupe_model_reduced_precision_graph(handle_, i),
                             troupe_model_reduced_precision_weights(handle_, i));
        return out;
    }
    /// Whether encode_prompt works: the bundle carries CLIP's text tower and tokenizer.
    bool takes_prompts() const { return troupe_model_takes_prompts(handle_) != 0; }
    /// The condition for a text prompt (CLIP's tokenizer and text tower, then the bundle's text
    /// branch; "" is the official "no text"); `out` is resized to condition_dim() on success only.
    Status encode_prompt(const std::string &prompt, std::vector<float> &out) const {
        std::vector<float> v(condition_dim());
        Status s = Status::from(troupe_text_prompt_encode(handle_, prompt.c_str(), v.data(), v.size()));
        if (s) out = std::move(v);
        return s;
    }
    /// The vector of a named condition; `out` is resized to condition_dim() on success only.
    Status condition_for(const std::string &label, std::vector<float> &out) const {
        std::vector<float> v(condition_dim());
        Status s = Status::from(troupe_model_condition_for_label(handle_, label.c_str(), v.data(), v.size()));
        if (s) out = std::move(v);
        return s;
    }
    /// The model's identity: the SHA-256 of its bundle's files (snapshots carry it).
    Status identity(std::uint8_t (&out)[32]) const { return Status::from(troupe_model_identity(handle_, out)); }
    std::size_t max_output_frames(std::size_t n_actor_frames) const {
        return troupe_model_max_output_frames(handle_, n_actor_frames);
    }
    /// The bundle's default session options (armflow bundles).
    Status default_options(troupe_session_options &out) const {
        return Status::from(troupe_session_options_init(handle_, &out, sizeof out));
    }

    /// Frames per clip: per person of a UMF bundle, of an official ARMFlow clip (0 otherwise).
    std::size_t clip_frames() const { return troupe_model_clip_frames(handle_); }
    /// The family: "armflow", "umf", "magnet" or "arflow".
    std::string family() const { return troupe_model_family(handle_); }

    /// What only an ARMFlow model offers: `model.armflow().generate_clip(...)`. The calls of
    /// another family's model answer `TROUPE_ERR_UNSUPPORTED`.
    class Armflow {
      public:
        /// Tokens of an official clip (0 for a streaming-only bundle).
        std::size_t clip_tokens() const { return troupe_armflow_clip_tokens(m_); }
        /// The bundle's clip settings (steps, CFG), seed 0.
        Status default_session_options(troupe_armflow_session_options &out) const {
            return Status::from(troupe_armflow_session_options_init(m_, &out, sizeof out));
        }
        Status default_clip_options(troupe_armflow_clip_options &out) const {
            return Status::from(troupe_armflow_clip_options_init(m_, &out, sizeof out));
        }
        /// The official clip loop: `n_actor_frames` (1..clip_frames) actor frames in, the
        /// reactor's `clip_frames x frame_dim` frames out (`frames` replaced only on success). A
        /// NULL `condition` is the null condition; NULL `options` the bundle's defaults; NULL
        /// `noise` draws from the seed.
        Status generate_clip(const float *actor, std::size_t n_actor_frames, std::vector<float> &frames,
                             const float *condition = nullptr, std::size_t condition_len = 0,
                             const troupe_armflow_clip_options *options = nullptr,
                             const troupe_clip_noise *noise = nullptr) const {
            troupe_armflow_clip_options defaults;
            if (!options) {
                Status st = default_clip_options(defaults);
                if (!st) return st;
                options = &defaults;
            }
            std::vector<float> out(troupe_model_clip_frames(m_) * troupe_model_frame_dim(m_));
            Status st = Status::from(troupe_armflow_clip_generate_with_options(
                m_, options, actor, n_actor_frames, condition, condition_len, noise, out.data(), out.size(), nullptr, 0));
            if (st) frames.swap(out);
            return st;
        }

      private:
        friend class Model;
        explicit Armflow(const troupe_model *m) : m_(m) {}
        const troupe_model *m_;
    };

    /// What only a UMF model offers: `model.umf().generate_group(...)`.
    class Umf {
      public:
        std::size_t tokens() const { return troupe_umf_tokens(m_); }
        std::size_t stages() const { return troupe_umf_stages(m_); }
        /// The bundle's default group options (solvers, CFG), seed 0.
        Status default_options(troupe_group_options &out) const {
            return Status::from(troupe_umf_options_init(m_, &out, sizeof out));
        }
        /// How many standard normals a group of `people` draws, by part (for replaying noise).
        Status noise_lengths(std::uint32_t people, std::size_t &prior, std::size_t &jumps,
                             std::size_t &reactions) const {
            return Status::from(troupe_umf_noise_lengths(m_, people, &prior, &jumps, &reactions));
        }
        /// Generates `people` persons; `motion` becomes [people][clip_frames][frame_dim]. A NULL
        /// `condition` is the null condition; NULL `options` the bundle's defaults; NULL `noise`
        /// draws from the seed. On failure `motion` is left as it was.
        Status generate_group(const float *condition, std::size_t condition_len, std::uint32_t people,
                              std::vector<float> &motion, const troupe_group_options *options = nullptr,
                              const troupe_group_noise *noise = nullptr) const {
            std::vector<float> out(static_cast<std::size_t>(people) * troupe_model_clip_frames(m_) *
                                   troupe_model_frame_dim(m_));
            Status s = Status::from(troupe_umf_generate(m_, options, condition, condition_len, people, noise,
                                                          out.data(), out.size(), nullptr, 0));
            if (s) motion.swap(out);
            return s;
        }

      private:
        friend class Model;
        explicit Umf(const troupe_model *m) : m_(m) {}
        const troupe_model *m_;
    };

    /// What only a MAGNet model offers: `model.magnet().generate(...)`.
    class Magnet {
      public:
        /// People the model generates together.
        std::size_t people() const { return troupe_magnet_people(m_); }
        /// The released sampling configurations, by the official YAML's name ("dd100", ...).
        std::vector<std::string> configs() const {
            std::vector<std::string> out;
            for (std::size_t i = 0, n = troupe_magnet_config_count(m_); i < n; ++i)
                out.emplace_back(troupe_magnet_config(m_, i));
            return out;
        }
        /// Options that run a configuration as released (no field overridden).
        static Status default_options(troupe_magnet_options &out) {
            return Status::from(troupe_magnet_options_init(&out, sizeof out));
        }
        /// Runs a sampling configuration (a released name, or a whole configuration as JSON) on
        /// `frame_count` frames `[frame_count][people][145]`; `out` becomes
        /// `[samples][frames][people][145]` and `shape` {samples, frames, people} on success only.
        /// NULL `options` runs the configuration as released; NULL `present` means everyone.
        Status generate(const std::string &config, const float *frames, std::size_t frame_count,
                        std::vector<float> &out, std::size_t shape[3],
                        const troupe_magnet_options *options = nullptr,
                        const std::uint8_t *present = nullptr) const {
            std::size_t s = 0, f = 0, p = 0;
            Status st = Status::from(troupe_magnet_output_shape(m_, config.c_str(), options, frame_count, &s, &f, &p));
            if (!st) return st;
            std::vector<float> v(s * f * p * 145);
            st = Status::from(troupe_magnet_generate(m_, config.c_str(), options, frames, frame_count, present,
                                                     v.data(), v.size()));
            if (st) {
                out.swap(v);
                shape[0] = s;
                shape[1] = f;
                shape[2] = p;
            }
            return st;
        }
        /// `generate` with the run's standard normals given instead of drawn (`draws`, in the
        /// order docs/MAGNET.md lists; `draws_used` receives how many it took): how a recorded
        /// run of another implementation is reproduced.
        Status generate_with_draws(const std::string &config, const float *frames, std::size_t frame_count,
                                   const std::vector<float> &draws, std::vector<float> &out, std::size_t shape[3],
                                   std::size_t &draws_used, const troupe_magnet_options *options = nullptr,
                                   const std::uint8_t *present = nullptr) const {
            std::size_t s = 0, f = 0, p = 0;
            Status st = Status::from(troupe_magnet_output_shape(m_, config.c_str(), options, frame_count, &s, &f, &p));
            if (!st) return st;
            std::vector<float> v(s * f * p * 145);
            st = Status::from(troupe_magnet_generate_with_draws(m_, config.c_str(), options, frames, frame_count,
                                                                present, draws.data(), draws.size(), &draws_used,
                                                                v.data(), v.size()));
            if (st) {
                out.swap(v);
                shape[0] = s;
                shape[1] = f;
                shape[2] = p;
            }
            return st;
        }

      private:
        friend class Model;
        explicit Magnet(const troupe_model *m) : m_(m) {}
        const troupe_model *m_;
    };

    /// What only an ARFlow model offers: `model.arflow().generate(...)`.
    class Arflow {
      public:
        /// The bundle's sampler settings (steps, guidance), seed 0.
        Status default_options(troupe_arflow_options &out) const {
            return Status::from(troupe_arflow_options_init(m_, &out, sizeof out));
        }
        /// The reactor's `frame_count` x 262 frames for the actor's; `options` null runs the
        /// bundle's defaults. `out` is replaced only on success.
        Status generate(const float *actor, std::size_t frame_count, std::vector<float> &out,
                        const troupe_arflow_options *options = nullptr) const {
            std::vector<float> v(frame_count * 262);
            Status st = Status::from(troupe_arflow_generate(m_, options, actor, frame_count, v.data(), frame_count));
            if (st) out.swap(v);
            return st;
        }
        /// `generate` with the run's standard normals given instead of drawn (`draws_used`
        /// receives how many it took).
        Status generate_with_draws(const float *actor, std::size_t frame_count, const std::vector<float> &draws,
                                   std::vector<float> &out, std::size_t &draws_used,
                                   const troupe_arflow_options *options = nullptr) const {
            std::vector<float> v(frame_count * 262);
            Status st = Status::from(troupe_arflow_generate_with_draws(m_, options, actor, frame_count, draws.data(),
                                                                       draws.size(), &draws_used, v.data(),
                                                                       frame_count));
            if (st) out.swap(v);
            return st;
        }

      private:
        friend class Model;
        explicit Arflow(const troupe_model *m) : m_(m) {}
        const troupe_model *m_;
    };

    Armflow armflow() const { return Armflow(handle_); }
    Umf umf() const { return Umf(handle_); }
    Magnet magnet() const { return Magnet(handle_); }
    Arflow arflow() const { return Arflow(handle_); }

    // ---- the 0.1 names, kept for one release ----
    [[deprecated("use umf().tokens()")]] std::size_t group_tokens() const { return umf().tokens(); }
    [[deprecated("use umf().stages()")]] std::size_t group_stages() const { return umf().stages(); }
    [[deprecated("use umf().default_options()")]] Status default_group_options(troupe_group_options &out) const {
        return umf().default_options(out);
    }
    [[deprecated("use umf().generate_group()")]] Status generate_group(
        const float *condition, std::size_t condition_len, std::uint32_t people, std::vector<float> &motion,
        const troupe_group_options *options = nullptr, const troupe_group_noise *noise = nullptr) const {
        return umf().generate_group(condition, condition_len, people, motion, options, noise);
    }
    [[deprecated("use magnet().people()")]] std::size_t magnet_people() const { return magnet().people(); }
    [[deprecated("use magnet().configs()")]] std::vector<std::string> magnet_configs() const {
        return magnet().configs();
    }
    [[deprecated("use magnet().generate()")]] Status magnet_generate(
        const std::string &config, const float *frames, std::size_t frame_count, std::vector<float> &out,
        std::size_t shape[3], const troupe_magnet_options *options = nullptr,
        const std::uint8_t *present = nullptr) const {
        return magnet().generate(config, frames, frame_count, out, shape, options, present);
    }
    [[deprecated("use arflow().generate()")]] Status arflow_generate(
        const float *actor, std::size_t frame_count, std::vector<float> &out,
        const troupe_arflow_options *options = nullptr) const {
        return arflow().generate(actor, frame_count, out, options);
    }
    const troupe_model *get() const { return handle_; }

  private:
    explicit Model(troupe_model *h) : handle_(h) {}
    troupe_model *handle_ = nullptr;
};

/// One stream (an ARMFlow reactor, or a MAGNet live partner). Move-only; use from one thread at
/// a time.
class Session {
  public:
    Session() = default;
    Session(Session &&other) noexcept : handle_(std::exchange(other.handle_, nullptr)), dim_(other.dim_) {}
    Session &operator=(Session &&other) noexcept {
        if (this != &other) {
            troupe_session_free(handle_);
            handle_ = std::exchange(other.handle_, nullptr);
            dim_ = other.dim_;
        }
        return *this;
    }
    Session(const Session &) = delete;
    Session &operator=(const Session &) = delete;
    ~Session() { troupe_session_free(handle_); }

    /// Starts a stream; `options` may be null for the bundle's defaults.
    static Status create(const Model &model, const troupe_session_options *options, Session &out) {
        troupe_session *h = nullptr;
        Status s = Status::from(troupe_session_new(model.get(), options, &h));
        if (s) out = Session(h, model.frame_dim());
        return s;
    }
    /// Starts an ARMFlow stream with ARMFlow's own options (`armflow` null: the bundle's).
    static Status create_armflow(const Model &model, const troupe_session_options *options,
                                 const troupe_armflow_session_options *armflow, Session &out) {
        troupe_session *h = nullptr;
        Status s = Status::from(troupe_armflow_session_new(model.get(), options, armflow, &h));
        if (s) out = Session(h, model.frame_dim());
        return s;
    }
#ifdef TROUPE_CPP_EXCEPTIONS
    static Session create_or_throw(const Model &model, const troupe_session_options *options = nullptr) {
        Session s;
        check(create(model, options, s));
        return s;
    }
#endif

    /// Feeds `n_actor_frames` frames; writes ready reactor frames to `out` (capacity in frames).
    Status step(const float *actor, std::size_t n_actor_frames, float *out, std::size_t out_capacity_frames,
                std::size_t &n_written) {
        return Status::from(
            troupe_session_step(handle_, actor, n_actor_frames, out, out_capacity_frames, &n_written));
    }
    Status reset() { return Status::from(troupe_session_reset(handle_)); }
    Status set_seed(std::uint64_t seed) { return Status::from(troupe_session_set_seed(handle_, seed)); }
    Status set_steps(std::uint32_t steps) { return Status::from(troupe_session_set_steps(handle_, steps)); }
    Status set_cfg_scale(float scale) { return Status::from(troupe_session_set_cfg_scale(handle_, scale)); }
    /// `condition == nullptr && len == 0` selects the null condition.
    Status set_condition(const float *condition, std::size_t len) {
        return Status::from(troupe_session_set_condition(handle_, condition, len));
    }
    /// Conditions the tokens from now on on a text prompt (streams with the prompt capability).
    Status set_prompt(const std::string &prompt) {
        return Status::from(troupe_session_set_prompt(handle_, prompt.c_str()));
    }
    /// Standard normals for the stream's next draws, in its sampler's order (every family).
    Status queue_normals(const float *normals, std::size_t len) {
        return Status::from(troupe_session_queue_normals(handle_, normals, len));
    }
    /// The `TROUPE_CAP_*` bits of what the stream takes beyond frames, seed and steps.
    Status capabilities(std::uint32_t &out) const { return Status::from(troupe_session_capabilities(handle_, &out)); }
    /// The session's penetration guard (every streaming family; `enabled` false: off); see
    /// docs/MOTION.md.
    Status set_penetration_guard(bool enabled, float d_safe = 0.05f, float max_speed = 2.0f) {
        return Status::from(troupe_session_set_penetration_guard(handle_, enabled ? 1 : 0, d_safe, max_speed));
    }
    /// The session's root smoothing (every streaming family; `enabled` false: off): the root
    /// path filtered with
    /// `time_constant` seconds before the guard.
    Status set_root_smoothing(bool enabled, float time_constant = 0.1f) {
        return Status::from(troupe_session_set_root_smoothing(handle_, enabled ? 1 : 0, time_constant));
    }
    /// The session's foot lock on the poses `step_joints` returns (ARMFlow, ARFlow; `enabled`
    /// false: off):
    /// a foot whose ankle contact label is at least `contact_threshold` stays put, released over
    /// `release_frames` frames or when the motion is `max_stretch` metres away.
    Status set_foot_lock(bool enabled, float contact_threshold = 0.5f, std::uint32_t release_frames = 4,
                         float max_stretch = 0.25f) {
        return Status::from(
            troupe_session_set_foot_lock(handle_, enabled ? 1 : 0, contact_threshold, release_frames, max_stretch));
    }
    /// What only an ARMFlow stream takes: `session.armflow().set_recentring(true)`. The calls
    /// on another family's stream answer `TROUPE_ERR_UNSUPPORTED`.
    class Armflow {
      public:
        /// Recentring (`enabled` false: off): before each token, when the actor's root is more
        /// than `distance` metres from the networks' centre, the centre moves to it and the
        /// networks' state is rebuilt from the last 8 tokens; output stays in the stream's frame.
        Status set_recentring(bool enabled, float distance = 1.0f) {
            return Status::from(troupe_armflow_session_set_recentring(s_, enabled ? 1 : 0, distance));
        }
        /// The noise of the next token (`Session::queue_normals` queues whole tokens too).
        Status queue_noise(const float *actor_noise, const float *reactor_noise, std::size_t len) {
            return Status::from(troupe_armflow_session_queue_noise(s_, actor_noise, reactor_noise, len));
        }

      private:
        friend class Session;
        explicit Armflow(troupe_session *s) : s_(s) {}
        troupe_session *s_;
    };

    /// What only a MAGNet live partner takes (before the first step or after a reset).
    class Magnet {
      public:
        /// The partner's opening frames, `n_frames` x 145 floats, row-major.
        Status set_partner_opening(const float *frames, std::size_t n_frames) {
            return Status::from(troupe_magnet_session_set_partner_opening(s_, frames, n_frames));
        }
        /// Send each chunk's frames as soon as they are generated (lower latency).
        Status set_early_emission(bool early) {
            return Status::from(troupe_magnet_session_set_early_emission(s_, early ? 1 : 0));
        }
        /// The sampling configuration: a released name or JSON.
        Status set_live_config(const std::string &config) {
            return Status::from(troupe_magnet_session_set_live_config(s_, config.c_str()));
        }

      private:
        friend class Session;
        explicit Magnet(troupe_session *s) : s_(s) {}
        troupe_session *s_;
    };

    /// What only an ARFlow online stream takes.
    class Arflow {
      public:
        /// The stream's sampler settings (from `troupe_arflow_options_init`).
        Status set_options(const troupe_arflow_options &options) {
            return Status::from(troupe_arflow_session_set_options(s_, &options));
        }

      private:
        friend class Session;
        explicit Arflow(troupe_session *s) : s_(s) {}
        troupe_session *s_;
    };

    Armflow armflow() { return Armflow(handle_); }
    Magnet magnet() { return Magnet(handle_); }
    Arflow arflow() { return Arflow(handle_); }

    // ---- the 0.1 names, kept for one release ----
    [[deprecated("use armflow().set_recentring()")]] Status set_recentring(bool enabled, float distance = 1.0f) {
        return armflow().set_recentring(enabled, distance);
    }
    [[deprecated("use armflow().queue_noise()")]] Status queue_noise(const float *actor_noise,
                                                                    const float *reactor_noise, std::size_t len) {
        return armflow().queue_noise(actor_noise, reactor_noise, len);
    }
    [[deprecated("use arflow().set_options()")]] Status set_arflow_options(const troupe_arflow_options &options) {
        return arflow().set_options(options);
    }
    [[deprecated("use magnet().set_partner_opening()")]] Status set_partner_opening(const float *frames,
                                                                                   std::size_t n_frames) {
        return magnet().set_partner_opening(frames, n_frames);
    }
    [[deprecated("use magnet().set_early_emission()")]] Status set_early_emission(bool early) {
        return magnet().set_early_emission(early);
    }
    [[deprecated("use magnet().set_live_config()")]] Status set_live_config(const std::string &config) {
        return magnet().set_live_config(config);
    }
    /// Everything the stream needs to go on, as bytes (`out` replaced only on success): restore it
    /// with `Session::restore` on the same model, in this process or another, and it continues
    /// bit for bit.
    Status snapshot(std::vector<std::uint8_t> &out) {
        std::size_t size = 0;
        Status st = Status::from(troupe_session_snapshot(handle_, nullptr, 0, &size));
        if (!st) return st;
        std::vector<std::uint8_t> v(size);
        st = Status::from(troupe_session_snapshot(handle_, v.data(), v.size(), &size));
        if (st) out.swap(v);
        return st;
    }
    /// A snapshot sealed with `key` (HMAC-SHA-256; docs/SNAPSHOTS.md), for storage the caller
    /// does not trust; `Session::restore_sealed` with the same key verifies it.
    static Status seal(const std::vector<std::uint8_t> &snapshot, const std::vector<std::uint8_t> &key,
                       std::vector<std::uint8_t> &out) {
        std::size_t size = 0;
        Status st = Status::from(
            troupe_snapshot_seal(snapshot.data(), snapshot.size(), key.data(), key.size(), nullptr, 0, &size));
        if (!st) return st;
        std::vector<std::uint8_t> v(size);
        st = Status::from(troupe_snapshot_seal(snapshot.data(), snapshot.size(), key.data(), key.size(), v.data(),
                                               v.size(), &size));
        if (st) out.swap(v);
        return st;
    }
    static Status restore_sealed(const Model &model, const std::vector<std::uint8_t> &sealed,
                                 const std::vector<std::uint8_t> &key, Session &out) {
        troupe_session *h = nullptr;
        Status s = Status::from(
            troupe_session_restore_sealed(model.get(), sealed.data(), sealed.size(), key.data(), key.size(), &h));
        if (s) out = Session(h, model.frame_dim());
        return s;
    }
    /// The stream a snapshot of `model`'s session saved; foreign or damaged bytes are refused.
    static Status restore(const Model &model, const std::uint8_t *bytes, std::size_t len, Session &out) {
        troupe_session *h = nullptr;
        Status s = Status::from(troupe_session_restore(model.get(), bytes, len, &h));
        if (s) out = Session(h, model.frame_dim());
        return s;
    }
    /// Exactly how many frames a step with `n_actor_frames` frames would return now.
    Status output_frames(std::size_t n_actor_frames, std::size_t &n_frames) {
        return Status::from(troupe_session_output_frames(handle_, n_actor_frames, &n_frames));
    }
    // ---- joint positions in, poses out (interhuman262 bundles) ----
    /// How step_joints reads positions; forgets the joint stream's frames and placement.
    Status set_joints_format(const troupe_joints_format &format) {
        return Status::from(troupe_session_set_joints_format(handle_, &format));
    }
    /// Feeds `n_frames` frames of [22][3] actor positions; `positions` (and, when non-null,
    /// `rotations` wxyz) become the reactor poses that are ready ([m][22][3], [m][22][4]) in the
    /// caller's world. On failure they are left as they were.
    Status step_joints(const float *actor, std::size_t n_frames, std::vector<float> &positions,
                       std::vector<float> *rotations = nullptr) {
        std::size_t ready = 0, written = 0;
        Status s = Status::from(troupe_session_joints_ready_after(handle_, n_frames, &ready));
        if (!s) return s;
        std::vector<float> p(ready * TROUPE_MOTION_JOINTS * 3), r(rotations ? ready * TROUPE_MOTION_JOINTS * 4 : 0);
        troupe_pose_buffers out = {p.data(), p.size(), rotations ? r.data() : nullptr, r.size(), nullptr, 0, nullptr, 0};
        s = Status::from(troupe_session_step_joints(handle_, actor, n_frames, &out, ready, &written));
        if (s) {
            p.resize(written * TROUPE_MOTION_JOINTS * 3);
            positions.swap(p);
            if (rotations) {
                r.resize(written * TROUPE_MOTION_JOINTS * 4);
                rotations->swap(r);
            }
        }
        return s;
    }
    /// Where the reactor's poses are put (fixed by the first actor joint frame).
    Status joints_placement(troupe_placement &out) {
        return Status::from(troupe_session_joints_placement(handle_, &out));
    }

    bool valid() const { return handle_ != nullptr; }
    std::size_t frame_dim() const { return dim_; }
    troupe_session *get() { return handle_; }

  private:
    Session(troupe_session *h, std::size_t dim) : handle_(h), dim_(dim) {}
    troupe_session *handle_ = nullptr;
    std::size_t dim_ = 0;
};

/// Advances many sessions of one model in one call (`troupe_sessions_step`, which reads the
/// weights once per token for all of them): `sessions[i]` gets `n_actor_frames[i]` frames from
/// `actor[i]`, and `out[i]` becomes its reactor frames (`[m_i][frame_dim]`). On error every
/// session and `out` are unchanged. The sessions must not be used by other threads meanwhile.
inline Status step_sessions(const std::vector<Session *> &sessions, const std::vector<const float *> &actor,
                            const std::vector<std::size_t> &n_actor_frames, std::vector<std::vector<float>> &out) {
    const std::size_t n = sessions.size();
    std::vector<troupe_session *> handles(n);
    std::vector<std::vector<float>> fresh(n);
    std::vector<float *> buffers(n);
    std::vector<std::size_t> capacity(n), written(n);
    // Mismatched arrays are described to the library as a NULL array, which it rejects by name.
    const bool sizes_match = actor.size() == n && n_actor_frames.size() == n;
    for (std::size_t i = 0; i < n && sizes_match; i++) {
        handles[i] = sessions[i] ? sessions[i]->get() : nullptr;
        if (handles[i] && sessions[i]->output_frames(n_actor_frames[i], capacity[i]).ok())
            fresh[i].resize(capacity[i] * sessions[i]->frame_dim());
        buffers[i] = fresh[i].data();
    }
    Status s = Status::from(troupe_sessions_step(handles.data(), n, sizes_match ? actor.data() : nullptr,
                                                 sizes_match ? n_actor_frames.data() : nullptr, buffers.data(),
                                                 capacity.data(), written.data()));
    if (s.ok()) {
        for (std::size_t i = 0; i < n; i++) fresh[i].resize(written[i] * sessions[i]->frame_dim());
        out = std::move(fresh);
    }
    return s;
}

/// Motion people have: the t2m-22 skeleton, joint positions to features and back, BVH and JSON
/// files, pictures. Positions are float32 [frames][22][3] measured as a troupe_joints_format says.
namespace motion {

/// A format: `units` TROUPE_UNITS_*, `up_axis` TROUPE_UP_Y/Z, `fps` the positions' rate.
inline troupe_joints_format format(std::uint32_t units = TROUPE_UNITS_METERS, std::uint32_t up_axis = TROUPE_UP_Y,
                                   float fps = 30.0f, std::uint32_t handedness = TROUPE_RIGHT_HANDED) {
    troupe_joints_format f;
    troupe_joints_format_init(&f, sizeof f);
    f.units = units;
    f.up_axis = up_axis;
    f.fps = fps;
    f.handedness = handedness;
    return f;
}

/// The t2m-22 skeleton: names, parents (-1 for the root), rest offsets [22][3] in metres.
struct Skeleton {
    std::vector<std::string> names;
    std::vector<std::int32_t> parents;
    std::vector<float> rest_offsets;
};

inline Skeleton skeleton() {
    Skeleton s;
    const std::size_t n = troupe_motion_joint_count();
    s.parents.resize(n);
    s.rest_offsets.resize(3 * n);
    troupe_motion_skeleton(s.parents.data(), n, s.rest_offsets.data(), 3 * n);
    for (std::size_t j = 0; j < n; j++) s.names.emplace_back(troupe_motion_joint_name(j));
    return s;
}

/// Features of `n_frames` frames of positions; `placement` receives the canonical frame used
/// (pass `given` to use another person's). On failure `features` is left as it was.
inline Status encode(const Model &model, const troupe_joints_format &format, const float *positions,
                     std::size_t n_frames, std::vector<float> &features, troupe_placement &placement,
                     const troupe_placement *given = nullptr) {
    std::size_t frames = 0, written = 0;
    Status s = Status::from(troupe_motion_encoded_frames(model.get(), &format, n_frames, &frames));
    if (!s) return s;
    std::vector<float> out(frames * model.frame_dim());
    troupe_placement used;
    s = Status::from(troupe_motion_encode(model.get(), &format, positions, n_frames, given, out.data(), frames,
                                          &written, &used));
    if (s) {
        features.swap(out);
        placement = used;
    }
    return s;
}

/// Positions [n][22][3] (and rotations [n][22][4] wxyz when non-null) of `n_frames` feature
/// frames, in the caller's world.
inline Status decode(const Model &model, const troupe_joints_format &format, const troupe_placement &placement,
                     const float *features, std::size_t n_frames, std::vector<float> &positions,
                     std::vector<float> *rotations = nullptr) {
    std::vector<float> p(n_frames * TROUPE_MOTION_JOINTS * 3), r(rotations ? n_frames * TROUPE_MOTION_JOINTS * 4 : 0);
    troupe_pose_buffers out = {p.data(), p.size(), rotations ? r.data() : nullptr, r.size(), nullptr, 0, nullptr, 0};
    Status s = Status::from(troupe_motion_decode(model.get(), &format, &placement, features, n_frames, &out));
    if (s) {
        positions.swap(p);
        if (rotations) rotations->swap(r);
    }
    return s;
}

/// A BVH take read as t2m-22 positions (file units, Y up) and the format to read them with.
struct Take {
    std::vector<float> positions;
    troupe_joints_format format;
    std::size_t frames = 0;
    /// The t2m-22 joints the rig lacks and how they were placed, one line each.
    std::string inferred;
    /// For each t2m-22 joint, the rig joint it is read from ("" where it was placed).
    std::array<std::string, 22> mapping;
};

/// Reads a BVH or FBX file (told apart by content); `units` TROUPE_UNITS_* or
/// TROUPE_UNITS_AUTO (an FBX file is converted to them; metres for AUTO); `joint_map_json`
/// null for the built-in map.
inline Status read_bvh(const std::string &path, Take &out, std::uint32_t units = TROUPE_UNITS_AUTO,
                       const char *joint_map_json = nullptr) {
    troupe_bvh *h = nullptr;
    Status s = Status::from(troupe_bvh_read(path.c_str(), joint_map_json, units, &h));
    if (!s) return s;
    Take t;
    t.frames = troupe_bvh_frames(h);
    t.positions.resize(t.frames * TROUPE_MOTION_JOINTS * 3);
    s = Status::from(troupe_bvh_positions(h, t.positions.data(), t.positions.size()));
    if (s) s = Status::from(troupe_bvh_format(h, &t.format, sizeof t.format));
    if (s) {
        const char *said = troupe_bvh_inferred(h);
        t.inferred = said ? said : "";
        for (std::size_t k = 0; k < t.mapping.size(); k++) {
            const char *name = troupe_bvh_joint_source(h, k);
            t.mapping[k] = name ? name : "";
        }
    }
    troupe_bvh_free(h);
    if (s) out = std::move(t);
    return s;
}

/// `names.size()` people's positions ([people][frames][22][3] in `positions`).
inline std::vector<const char *> c_names(const std::vector<std::string> &names) {
    std::vector<const char *> out;
    for (const auto &n : names) out.push_back(n.c_str());
    return out;
}

/// Writes people on the t2m-22 skeleton to a BVH file (units TROUPE_UNITS_*).
inline Status write_bvh(const std::string &path, const std::vector<std::string> &names, const float *positions,
                        std::size_t n_frames, const troupe_joints_format &format,
                        std::uint32_t units = TROUPE_UNITS_CENTIMETERS, bool fit_skeleton = true) {
    auto c = c_names(names);
    return Status::from(troupe_bvh_write(path.c_str(), positions, names.size(), n_frames, &format, c.data(), units,
                                         fit_skeleton ? 1u : 0u));
}

/// Writes people's poses as a JSON document for robots and tools.
inline Status write_json(const std::string &path, const std::vector<std::string> &names, const float *positions,
                         std::size_t n_frames, const troupe_joints_format &format) {
    auto c = c_names(names);
    return Status::from(troupe_motion_write_json(path.c_str(), positions, names.size(), n_frames, &format, c.data()));
}

/// Writes the HTML player and/or GIF of people (an empty path skips that file).
inline Status write_pictures(const std::string &html, const std::string &gif, const std::vector<std::string> &names,
                             const float *positions, std::size_t n_frames, const troupe_joints_format &format,
                             const std::string &title = "troupe") {
    auto c = c_names(names);
    return Status::from(troupe_viewer_write(html.empty() ? nullptr : html.c_str(), gif.empty() ? nullptr : gif.c_str(),
                                            positions, names.size(), n_frames, &format, c.data(), title.c_str()));
}

/// A character rig with its joint map (docs/RIGS.md). Move-only; immutable, so any thread may
/// use it.
class Rig {
  public:
    Rig() = default;
    Rig(Rig &&other) noexcept : handle_(std::exchange(other.handle_, nullptr)) {}
    Rig &operator=(Rig &&other) noexcept {
        if (this != &other) {
            troupe_rig_free(handle_);
            handle_ = std::exchange(other.handle_, nullptr);
        }
        return *this;
    }
    Rig(const Rig &) = delete;
    Rig &operator=(const Rig &) = delete;
    ~Rig() { troupe_rig_free(handle_); }

    /// The rig of a BVH file (`rest_frame`: TROUPE_RIG_ZERO_POSE or the frame whose pose is the
    /// rest pose; `joint_map_json`: null for the built-in names).
    static Status from_bvh(const std::string &path, Rig &out, std::uint32_t units = TROUPE_UNITS_AUTO,
                           std::uint32_t rest_frame = TROUPE_RIG_ZERO_POSE, const char *joint_map_json = nullptr) {
        troupe_rig *h = nullptr;
        Status s = Status::from(troupe_rig_from_bvh(path.c_str(), units, rest_frame, joint_map_json, &h));
        if (s) out = Rig(h);
        return s;
    }
    /// The rig of an FBX file (binary or ASCII; its bind pose as rest where it has one):
    /// `from_bvh`, which reads either.
    static Status from_fbx(const std::string &path, Rig &out, std::uint32_t units = TROUPE_UNITS_AUTO,
                           const char *joint_map_json = nullptr) {
        return from_bvh(path, out, units, TROUPE_RIG_ZERO_POSE, joint_map_json);
    }
    /// The rig of skin `skin` of a glTF file (.glb or .gltf).
    static Status from_gltf(const std::string &path, Rig &out, std::size_t skin = 0,
                            const char *joint_map_json = nullptr) {
        troupe_rig *h = nullptr;
        Status s = Status::from(troupe_rig_from_gltf(path.c_str(), skin, joint_map_json, &h));
        if (s) out = Rig(h);
        return s;
    }
    /// A rig from its JSON document.
    static Status from_json(const std::string &json, Rig &out, const char *joint_map_json = nullptr) {
        troupe_rig *h = nullptr;
        Status s = Status::from(troupe_rig_from_json(json.c_str(), joint_map_json, &h));
        if (s) out = Rig(h);
        return s;
    }
    std::size_t joint_count() const { return troupe_rig_joint_count(handle_); }
    /// Joint `joint`'s name ("" past the end).
    std::string joint_name(std::size_t joint) const {
        const char *n = troupe_rig_joint_name(handle_, joint);
        return n ? n : "";
    }
    const troupe_rig *get() const { return handle_; }

  private:
    explicit Rig(troupe_rig *h) : handle_(h) {}
    troupe_rig *handle_ = nullptr;
};

/// One pose of a rig: local rotations [joints][4] (wxyz, the rig's axes), the moving joint's
/// local translation (rig units and axes) and its index.
struct RigPose {
    std::vector<float> rotations;
    std::array<float, 3> root_translation{};
    std::size_t root_joint = 0;
};

/// One stream retargeted onto a rig a frame at a time. Move-only; one thread at a time.
class Retargeter {
  public:
    Retargeter() = default;
    Retargeter(Retargeter &&other) noexcept
        : handle_(std::exchange(other.handle_, nullptr)), joints_(other.joints_) {}
    Retargeter &operator=(Retargeter &&other) noexcept {
        if (this != &other) {
            troupe_rig_retargeter_free(handle_);
            handle_ = std::exchange(other.handle_, nullptr);
            joints_ = other.joints_;
        }
        return *this;
    }
    Retargeter(const Retargeter &) = delete;
    Retargeter &operator=(const Retargeter &) = delete;
    ~Retargeter() { troupe_rig_retargeter_free(handle_); }

    /// A retargeter onto `rig` of positions measured as `format` says (`flags`: TROUPE_RETARGET_*).
    static Status create(const Rig &rig, const troupe_joints_format &format, Retargeter &out,
                         std::uint32_t flags = 0) {
        troupe_rig_retargeter *h = nullptr;
        Status s = Status::from(troupe_rig_retargeter_new(rig.get(), &format, flags, &h));
        if (s) out = Retargeter(h, rig.joint_count());
        return s;
    }
    /// The rig's pose for the next frame (66 floats of t2m-22 positions).
    Status push(const float *positions, RigPose &out) {
        out.rotations.resize(4 * joints_);
        return Status::from(troupe_rig_retarget_push(handle_, positions, 66, out.rotations.data(),
                                                     out.rotations.size(), out.root_translation.data(),
                                                     &out.root_joint));
    }
    Status reset() { return Status::from(troupe_rig_retarget_reset(handle_)); }
    /// For each t2m-22 joint, the rig joint it drives (-1: none).
    Status mapping(std::array<std::int64_t, 22> &out) {
        return Status::from(troupe_rig_retargeter_mapping(handle_, out.data(), out.size()));
    }

  private:
    Retargeter(troupe_rig_retargeter *h, std::size_t joints) : handle_(h), joints_(joints) {}
    troupe_rig_retargeter *handle_ = nullptr;
    std::size_t joints_ = 0;
};

/// A whole clip ([frames][22][3] in `positions`) retargeted onto `rig`: one pose per frame.
inline Status retarget_clip(const Rig &rig, const float *positions, std::size_t n_frames,
                            const troupe_joints_format &format, std::vector<RigPose> &out, std::uint32_t flags = 0) {
    const std::size_t joints = rig.joint_count();
    std::vector<float> rotations(n_frames * joints * 4), roots(n_frames * 3);
    std::size_t root_joint = 0;
    Status s = Status::from(troupe_rig_retarget_clip(rig.get(), positions, n_frames, &format, flags, rotations.data(),
                                                     rotations.size(), roots.data(), roots.size(), &root_joint));
    if (!s) return s;
    out.assign(n_frames, RigPose{});
    for (std::size_t t = 0; t < n_frames; t++) {
        out[t].rotations.assign(rotations.begin() + t * joints * 4, rotations.begin() + (t + 1) * joints * 4);
        out[t].root_translation = {roots[3 * t], roots[3 * t + 1], roots[3 * t + 2]};
        out[t].root_joint = root_joint;
    }
    return s;
}

/// One person's clip ([frames][22][3]) retargeted onto `rig` and written as a BVH file of the
/// rig's hierarchy, or as a binary FBX file of its skeleton, in `units` (TROUPE_UNITS_*).
inline Status write_rig_bvh(const std::string &path, const Rig &rig, const float *positions, std::size_t n_frames,
                            const troupe_joints_format &format, std::uint32_t units = TROUPE_UNITS_CENTIMETERS,
                            std::uint32_t flags = 0) {
    return Status::from(troupe_rig_bvh_write(path.c_str(), rig.get(), positions, n_frames, &format, units, flags));
}
inline Status write_rig_fbx(const std::string &path, const Rig &rig, const float *positions, std::size_t n_frames,
                            const troupe_joints_format &format, std::uint32_t units = TROUPE_UNITS_CENTIMETERS,
                            std::uint32_t flags = 0) {
    return Status::from(troupe_rig_fbx_write(path.c_str(), rig.get(), positions, n_frames, &format, units, flags));
}

/// Writes people ([people][frames][22][3] in `positions`) retargeted onto `rig` (null: troupe's
/// own body) as a glTF binary file (`flags`: TROUPE_RETARGET_* and TROUPE_GLTF_*).
inline Status write_gltf(const std::string &path, const std::vector<std::string> &names, const float *positions,
                         std::size_t n_frames, const troupe_joints_format &format, const Rig *rig = nullptr,
                         std::uint32_t flags = 0) {
    auto c = c_names(names);
    return Status::from(troupe_gltf_write(path.c_str(), rig ? rig->get() : nullptr, positions, names.size(), n_frames,
                                          &format, c.data(), flags));
}

/// One person of `write_gltf_people`: a name and their own clip ([n_frames][22][3]).
struct PersonClip {
    std::string name;
    const float *positions = nullptr;
    std::size_t n_frames = 0;
};

/// Writes people of different lengths, each with their own frames, as one glTF binary file; a
/// shorter person holds their last pose to the end.
inline Status write_gltf_people(const std::string &path, const std::vector<PersonClip> &people,
                                const troupe_joints_format &format, const Rig *rig = nullptr,
                                std::uint32_t flags = 0) {
    std::vector<troupe_person_clip> c(people.size());
    for (std::size_t i = 0; i < people.size(); i++) {
        c[i].name = people[i].name.c_str();
        c[i].positions = people[i].positions;
        c[i].n_frames = people[i].n_frames;
    }
    return Status::from(
        troupe_gltf_write_people(path.c_str(), rig ? rig->get() : nullptr, c.data(), c.size(), &format, flags));
}

/// MAGNet's SMPL-X frames (145 floats each) posed on the t2m-22 skeleton ([n_frames][22][3]).
inline Status smplx145_positions(const float *frames, std::size_t n_frames, std::vector<float> &positions) {
    std::vector<float> v(n_frames * 66);
    Status s = Status::from(troupe_motion_smplx145_positions(frames, n_frames, v.data(), v.size()));
    if (s) positions.swap(v);
    return s;
}

/// How two people's bodies intersect over `n_frames` frames of t2m-22 positions (metres, Y up).
struct PenetrationMetrics {
    std::size_t frames_intersecting = 0;
    double frequency = 0, depth_sum = 0, max_depth = 0;
};
inline Status penetration_metrics(const float *first, const float *second, std::size_t n_frames,
                                  PenetrationMetrics &out) {
    return Status::from(troupe_motion_penetration_metrics(first, second, n_frames, &out.frames_intersecting,
                                                          &out.frequency, &out.depth_sum, &out.max_depth));
}

/// One person's joint positions turned into a bundle's feature frames as they arrive (for a
/// session's actor input). Move-only; one thread at a time.
class Stream {
  public:
    Stream() = default;
    Stream(Stream &&other) noexcept
        : handle_(std::exchange(other.handle_, nullptr)), frame_dim_(other.frame_dim_) {}
    Stream &operator=(Stream &&other) noexcept {
        if (this != &other) {
            troupe_motion_stream_free(handle_);
            handle_ = std::exchange(other.handle_, nullptr);
            frame_dim_ = other.frame_dim_;
        }
        return *this;
    }
    Stream(const Stream &) = delete;
    Stream &operator=(const Stream &) = delete;
    ~Stream() { troupe_motion_stream_free(handle_); }

    /// A stream for `model`'s features of positions measured as `format` says; its canonical
    /// frame is the first frame's unless `placement` is given.
    static Status create(const Model &model, const troupe_joints_format &format, Stream &out,
                         const troupe_placement *placement = nullptr) {
        troupe_motion_stream *h = nullptr;
        Status s = Status::from(troupe_motion_stream_new(model.get(), &format, placement, &h));
        if (s) out = Stream(h, model.frame_dim());
        return s;
    }
    /// Frames of latency every stream adds (feature frame t needs position frame t + 1).
    static std::size_t latency_frames() { return troupe_motion_stream_latency_frames(); }
    /// One frame of positions (66 floats) in; the feature frames it completes appended to `features`.
    Status push(const float *frame, std::vector<float> &features) {
        const std::size_t room = troupe_motion_stream_max_frames(handle_);
        std::vector<float> out(room * frame_dim_);
        std::size_t n = 0;
        Status s = Status::from(troupe_motion_stream_push(handle_, frame, 66, out.data(), room, &n));
        if (s) features.insert(features.end(), out.begin(), out.begin() + n * frame_dim_);
        return s;
    }
    /// The canonical frame the stream uses (after its first frame).
    Status placement(troupe_placement &out) const {
        return Status::from(troupe_motion_stream_placement(handle_, &out));
    }
    /// Starts over: the next frame fixes the canonical frame, unless `placement` is given.
    Status reset(const troupe_placement *placement = nullptr) {
        return Status::from(troupe_motion_stream_reset(handle_, placement));
    }

  private:
    Stream(troupe_motion_stream *h, std::size_t frame_dim) : handle_(h), frame_dim_(frame_dim) {}
    troupe_motion_stream *handle_ = nullptr;
    std::size_t frame_dim_ = 0;
};

}  // namespace motion

}  // namespace troupe

#endif  // TROUPE_HPP

/* ABI test of libtroupe through include/troupe.h only. Compiled as C99 and as C++17 with
 * -Wall -Wextra -Werror -pedantic, linked against the cdylib and the staticlib, and run under
 * valgrind (tests/c_abi.rs). Usage: smoke BUNDLE_DIR BUNDLE_ARCHIVE */
#include "troupe.h"
#include "check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef TROUPE_TESTING
#ifdef __cplusplus
extern "C"
#endif
troupe_status troupe_testing_panic(troupe_session *session);
#endif


static int log_calls = 0;
static void on_log(void *user_data, int32_t level, const char *target, const char *message) {
    (void)target;
    if (user_data == (void *)&log_calls && level >= TROUPE_LOG_ERROR && message[0] != '\0')
        log_calls++;
}

static float *synthetic_actor(size_t frames, size_t dim) {
    float *x = (float *)malloc(frames * dim * sizeof(float));
    size_t t, d;
    for (t = 0; t < frames; t++)
        for (d = 0; d < dim; d++)
            x[t * dim + d] = 0.5f * (float)sin(0.1 * (double)t * (1.0 + (double)(d % 7)) + (double)d);
    return x;
}

/* Streams `frames` actor frames `tick` at a time; returns the reactor frames written. */
static size_t stream(troupe_session *s, const float *actor, size_t frames, size_t dim, size_t tick,
                     float *out, size_t out_frames) {
    size_t done = 0, written = 0;
    while (done < frames) {
        size_t n = frames - done < tick ? frames - done : tick, got = 0;
        troupe_status st =
            troupe_session_step(s, actor + done * dim, n, out + written * dim, out_frames - written, &got);
        if (st != TROUPE_OK) {
            fprintf(stderr, "step failed: %s\n", troupe_last_error_message());
            return (size_t)-1;
        }
        written += got;
        done += n;
    }
    return written;
}

static unsigned char *read_file(const char *path, size_t *len) {
    FILE *f = fopen(path, "rb");
    unsigned char *bytes;
    long size;
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    size = ftell(f);
    fseek(f, 0, SEEK_SET);
    bytes = (unsigned char *)malloc((size_t)size);
    *len = fread(bytes, 1, (size_t)size, f);
    fclose(f);
    return bytes;
}

int main(int argc, char **argv) {
    troupe_model *model = NULL, *from_memory = NULL;
    troupe_session *session = NULL, *other = NULL;
    troupe_session_options opt;
    size_t dim, fpt, lat, cdim, n = 0, needed = 0, frames = 80, len = 0;
    float *actor, *out, *again, *noise, *cond, saved;
    unsigned char *archive;
    char small[8];

    if (argc < 3) {
        fprintf(stderr, "usage: %s BUNDLE_DIR BUNDLE_ARCHIVE\n", argv[0]);
        return 2;
    }

    /* versions: header macros equal the library */
    CHECK(troupe_abi_version() == TROUPE_ABI_VERSION);
    CHECK(troupe_version_number() == TROUPE_VERSION_NUMBER);
    CHECK(strcmp(troupe_version_string(), TROUPE_VERSION_STRING) == 0);
    CHECK(strcmp(troupe_status_name(TROUPE_ERR_BUFFER_TOO_SMALL), "TROUPE_ERR_BUFFER_TOO_SMALL") == 0);
    CHECK(strcmp(troupe_status_name(TROUPE_ERR_UNSUPPORTED), "TROUPE_ERR_UNSUPPORTED") == 0);
    CHECK(strcmp(troupe_status_name(12345), "TROUPE_ERR_UNKNOWN") == 0);

    /* logging: errors reach the callback at debug level */
    EXPECT(troupe_set_log_callback(on_log, &log_calls, 99), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_set_log_callback(on_log, &log_calls, TROUPE_LOG_DEBUG), TROUPE_OK);

    /* loading */
    model = (troupe_model *)&n; /* out-handles are set to NULL on failure */
    EXPECT(troupe_model_load_file(NULL, &model), TROUPE_ERR_NULL_ARG);
    CHECK(model == NULL);
    EXPECT(troupe_model_load_file(argv[1], NULL), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_model_load_file("/nonexistent/bundle", &model), TROUPE_ERR_IO);
    CHECK(troupe_last_error_message() != NULL && strstr(troupe_last_error_message(), "/nonexistent/bundle") != NULL);
    CHECK(log_calls > 0);
    EXPECT(troupe_model_load_memory((const uint8_t *)"junk", 4, &model), TROUPE_ERR_IO);
    EXPECT(troupe_model_load_memory(NULL, 10, &model), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_set_log_callback(NULL, NULL, 0), TROUPE_OK);
    EXPECT(troupe_model_load_file(argv[1], &model), TROUPE_OK);
    CHECK(model != NULL && troupe_last_error_message() == NULL);
    archive = read_file(argv[2], &len);
    CHECK(archive != NULL);
    EXPECT(troupe_model_load_memory(archive, len, &from_memory), TROUPE_OK);
    free(archive);

    /* last error copy-out */
    EXPECT(troupe_session_reset(NULL), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_last_error_copy(small, sizeof small, &needed), TROUPE_OK);
    CHECK(needed > sizeof small && strlen(small) == sizeof small - 1);
    EXPECT(troupe_last_error_copy(NULL, 4, &needed), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_last_error_copy(NULL, 0, NULL), TROUPE_ERR_NULL_ARG);

    /* getters, NULL-safe */
    dim = troupe_model_frame_dim(model);
    CHECK(strcmp(troupe_model_family(model), "armflow") == 0 && troupe_model_family(NULL) == NULL);
    fpt = troupe_model_frames_per_token(model);
    lat = troupe_model_latent_dim(model);
    cdim = troupe_model_condition_dim(model);
    CHECK(dim == 262 && fpt == 4 && lat == 16 && cdim == 32);
    CHECK(troupe_model_fps(model) == 30 && troupe_model_latency_frames(model) == 3);
    CHECK(troupe_model_max_output_frames(model, 1) == 4 && troupe_model_max_output_frames(model, 37) == 40);
    CHECK(troupe_model_frame_dim(NULL) == 0 && troupe_model_max_output_frames(NULL, 5) == 0);
    CHECK(troupe_model_fps(NULL) == 0 && troupe_model_frames_per_token(NULL) == 0);
    CHECK(troupe_model_latency_frames(NULL) == 0 && troupe_model_condition_dim(NULL) == 0);
    CHECK(troupe_model_latent_dim(NULL) == 0);

    /* options */
    CHECK(troupe_session_options_size() == sizeof(troupe_session_options));
    EXPECT(troupe_session_options_init(NULL, &opt, sizeof opt), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_options_init(model, NULL, sizeof opt), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_options_init(model, &opt, 8), TROUPE_ERR_INVALID_ARG);
    {
        /* a caller built against a newer header: its unknown tail is zeroed and accepted */
        union {
            troupe_session_options opt;
            unsigned char bytes[sizeof(troupe_session_options) + 8];
        } newer;
        troupe_session *probe = NULL;
        memset(newer.bytes, 0xab, sizeof newer.bytes);
        EXPECT(troupe_session_options_init(model, &newer.opt, sizeof newer.bytes), TROUPE_OK);
        CHECK(newer.bytes[sizeof newer.bytes - 1] == 0 && newer.opt.struct_size == sizeof newer.bytes);
        EXPECT(troupe_session_new(model, &newer.opt, &probe), TROUPE_OK);
        troupe_session_free(probe);
        newer.bytes[sizeof newer.bytes - 1] = 1;
        EXPECT(troupe_session_new(model, &newer.opt, &probe), TROUPE_ERR_INVALID_ARG);
    }
    EXPECT(troupe_session_options_init(model, &opt, sizeof opt), TROUPE_OK);
    CHECK(opt.struct_size == sizeof opt && opt.steps == 1 && opt.cfg_scale == 1.0f && opt.context_capacity == 64);
    opt.seed = 42;
    opt.struct_size = 8;
    EXPECT(troupe_session_new(model, &opt, &session), TROUPE_ERR_INVALID_ARG);
    CHECK(session == NULL);
    opt.struct_size = sizeof opt;
    opt.actor_latent = 7;
    EXPECT(troupe_session_new(model, &opt, &session), TROUPE_ERR_INVALID_ARG);
    opt.actor_latent = TROUPE_ACTOR_LATENT_SAMPLE;
    opt.steps = 0;
    EXPECT(troupe_session_new(model, &opt, &session), TROUPE_ERR_INVALID_ARG);
    opt.steps = 1;
    EXPECT(troupe_session_new(NULL, &opt, &session), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_new(model, &opt, NULL), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_new(model, &opt, &session), TROUPE_OK);
    EXPECT(troupe_session_new(from_memory, &opt, &other), TROUPE_OK);

    /* streaming */
    actor = synthetic_actor(frames, dim);
    out = (float *)calloc(frames * dim, sizeof(float));
    again = (float *)calloc(frames * dim, sizeof(float));
    CHECK(stream(session, actor, frames, dim, 1, out, frames) == frames);
    EXPECT(troupe_session_reset(session), TROUPE_OK);
    CHECK(stream(session, actor, frames, dim, 7, again, frames) == frames);
    CHECK(memcmp(out, again, frames * dim * sizeof(float)) == 0);
    CHECK(stream(other, actor, frames, dim, 37, again, frames) == frames); /* memory-loaded bundle */
    CHECK(memcmp(out, again, frames * dim * sizeof(float)) == 0);

    /* bad inputs leave the session as it was */
    EXPECT(troupe_session_reset(session), TROUPE_OK);
    EXPECT(troupe_session_step(session, actor, 3, out, 0, &n), TROUPE_OK);
    CHECK(n == 0);
    n = 77;
    EXPECT(troupe_session_step(session, actor + 3 * dim, 1, out, 3, &n), TROUPE_ERR_BUFFER_TOO_SMALL);
    CHECK(n == 77 && strstr(troupe_last_error_message(), "returns 4 frames") != NULL);
    EXPECT(troupe_session_output_frames(session, 1, &n), TROUPE_OK);
    CHECK(n == 4);
    EXPECT(troupe_session_step(NULL, actor, 1, out, 4, &n), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_step(session, NULL, 1, out, 4, &n), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_step(session, actor, 1, NULL, 4, &n), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_step(session, actor, 1, out, 4, NULL), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_step(session, actor, (size_t)-1, out, 4, &n), TROUPE_ERR_INVALID_ARG);
    saved = actor[3 * dim + 5];
    actor[3 * dim + 5] = NAN;
    EXPECT(troupe_session_step(session, actor + 3 * dim, 1, out, 4, &n), TROUPE_ERR_INVALID_ARG);
    actor[3 * dim + 5] = saved;
    EXPECT(troupe_session_step(session, NULL, 0, NULL, 0, &n), TROUPE_OK);
    CHECK(n == 0);
    EXPECT(troupe_session_step(session, actor + 3 * dim, 1, again, 4, &n), TROUPE_OK);
    CHECK(n == 4 && memcmp(out, again, 4 * dim * sizeof(float)) == 0); /* as if nothing failed */
    EXPECT(troupe_session_reset(session), TROUPE_OK);
    CHECK(stream(session, actor, frames, dim, 4, again, frames) == frames);
    CHECK(memcmp(out, again, frames * dim * sizeof(float)) == 0);

    /* ARMFlow's own options: the stream the deprecated fields of the common options give */
    {
        troupe_armflow_session_options arm;
        troupe_session *own = NULL, *legacy = NULL;
        float *guided = (float *)calloc(frames * dim, sizeof(float));
        EXPECT(troupe_armflow_session_options_init(model, &arm, 8), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_armflow_session_options_init(model, NULL, sizeof arm), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_armflow_session_options_init(model, &arm, sizeof arm), TROUPE_OK);
        CHECK(arm.struct_size == sizeof arm && arm.cfg_scale == 1.0f &&
              arm.actor_latent == TROUPE_ACTOR_LATENT_SAMPLE && arm.vae_windows == 0);
        arm.cfg_scale = 2.0f;
        arm.actor_latent = TROUPE_ACTOR_LATENT_MEAN;
        opt.cfg_scale = 2.0f;
        opt.actor_latent = TROUPE_ACTOR_LATENT_MEAN;
        EXPECT(troupe_session_new(model, &opt, &legacy), TROUPE_OK);
        opt.cfg_scale = 1.0f;
        opt.actor_latent = 7; /* the family's call does not read the deprecated fields */
        EXPECT(troupe_armflow_session_new(model, &opt, &arm, &own), TROUPE_OK);
        opt.actor_latent = TROUPE_ACTOR_LATENT_SAMPLE;
        CHECK(stream(own, actor, frames, dim, 5, guided, frames) == frames);
        CHECK(stream(legacy, actor, frames, dim, 3, again, frames) == frames);
        CHECK(memcmp(guided, again, frames * dim * sizeof(float)) == 0);
        CHECK(memcmp(guided, out, frames * dim * sizeof(float)) != 0); /* guided, mean: not `out` */
        troupe_session_free(own);
        troupe_session_free(legacy);
        own = NULL;
        arm.actor_latent = 9;
        EXPECT(troupe_armflow_session_new(model, NULL, &arm, &own), TROUPE_ERR_INVALID_ARG);
        CHECK(own == NULL && strstr(troupe_last_error_message(), "armflow.actor_latent 9") != NULL);
        arm.actor_latent = TROUPE_ACTOR_LATENT_SAMPLE;
        arm.cfg_scale = NAN;
        EXPECT(troupe_armflow_session_new(model, NULL, &arm, &own), TROUPE_ERR_INVALID_ARG);
        arm.cfg_scale = 1.0f;
        arm.struct_size = 4;
        EXPECT(troupe_armflow_session_new(model, NULL, &arm, &own), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_armflow_session_new(model, NULL, NULL, NULL), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_armflow_session_new(NULL, NULL, NULL, &own), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_armflow_session_new(model, NULL, NULL, &own), TROUPE_OK);
        troupe_session_free(own);
        free(guided);
    }

    /* many sessions in one call: each equals the session streamed alone (`out`) */
    {
        troupe_session *crowd[3] = {NULL, NULL, NULL}, *kept;
        const float *in[3];
        size_t n_in[3], cap[3], n_out[3], fed[3] = {0, 0, 0}, got[3] = {0, 0, 0}, k, i;
        static const size_t ticks[3] = {1, 5, 12};
        float *res[3], *dst[3], worst = 0.0f;
        for (k = 0; k < 3; k++) {
            EXPECT(troupe_session_new(model, &opt, &crowd[k]), TROUPE_OK);
            res[k] = (float *)calloc(frames * dim, sizeof(float));
        }
        while (fed[0] < frames || fed[1] < frames || fed[2] < frames) {
            for (k = 0; k < 3; k++) {
                n_in[k] = fed[k] + ticks[k] <= frames ? ticks[k] : frames - fed[k];
                in[k] = actor + fed[k] * dim;
                dst[k] = res[k] + got[k] * dim;
                cap[k] = frames - got[k];
            }
            EXPECT(troupe_sessions_step(crowd, 3, in, n_in, dst, cap, n_out), TROUPE_OK);
            for (k = 0; k < 3; k++) {
                fed[k] += n_in[k];
                got[k] += n_out[k];
            }
        }
        for (k = 0; k < 3; k++) {
            CHECK(got[k] == frames);
            for (i = 0; i < frames * dim; i++)
                worst = fabsf(res[k][i] - out[i]) > worst ? fabsf(res[k][i] - out[i]) : worst;
        }
        CHECK(worst <= 1e-5f);

        /* bad calls write nothing and change no session */
        for (k = 0; k < 3; k++) {
            EXPECT(troupe_session_reset(crowd[k]), TROUPE_OK);
            in[k] = actor;
            n_in[k] = 4;
            dst[k] = res[k];
            cap[k] = 4;
            n_out[k] = 77;
        }
        kept = crowd[2];
        crowd[2] = crowd[0];
        EXPECT(troupe_sessions_step(crowd, 3, in, n_in, dst, cap, n_out), TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "sessions[0] and sessions[2] are the same") != NULL);
        crowd[2] = other; /* a session of another model (the memory-loaded bundle) */
        EXPECT(troupe_sessions_step(crowd, 3, in, n_in, dst, cap, n_out), TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "session 2 runs another model") != NULL);
        crowd[2] = NULL;
        EXPECT(troupe_sessions_step(crowd, 3, in, n_in, dst, cap, n_out), TROUPE_ERR_NULL_ARG);
        crowd[2] = kept;
        cap[1] = 3;
        EXPECT(troupe_sessions_step(crowd, 3, in, n_in, dst, cap, n_out), TROUPE_ERR_BUFFER_TOO_SMALL);
        CHECK(strstr(troupe_last_error_message(), "session 1: this call returns 4 frames") != NULL);
        cap[1] = 4;
        in[1] = NULL;
        EXPECT(troupe_sessions_step(crowd, 3, in, n_in, dst, cap, n_out), TROUPE_ERR_NULL_ARG);
        in[1] = actor;
        saved = actor[5];
        actor[5] = NAN;
        EXPECT(troupe_sessions_step(crowd, 3, in, n_in, dst, cap, n_out), TROUPE_ERR_INVALID_ARG);
        actor[5] = saved;
        EXPECT(troupe_sessions_step(NULL, 3, in, n_in, dst, cap, n_out), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_sessions_step(crowd, 3, NULL, n_in, dst, cap, n_out), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_sessions_step(crowd, 3, in, n_in, dst, NULL, n_out), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_sessions_step(crowd, 3, in, n_in, dst, cap, NULL), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_sessions_step(NULL, 0, NULL, NULL, NULL, NULL, NULL), TROUPE_OK);
        CHECK(n_out[0] == 77 && n_out[1] == 77 && n_out[2] == 77);
        EXPECT(troupe_sessions_step(crowd, 3, in, n_in, dst, cap, n_out), TROUPE_OK);
        worst = 0.0f;
        for (k = 0; k < 3; k++) {
            CHECK(n_out[k] == 4);
            for (i = 0; i < 4 * dim; i++) /* as if nothing failed */
                worst = fabsf(res[k][i] - out[i]) > worst ? fabsf(res[k][i] - out[i]) : worst;
        }
        CHECK(worst <= 1e-5f);
        for (k = 0; k < 3; k++) {
            troupe_session_free(crowd[k]);
            free(res[k]);
        }
    }

    /* setters */
    cond = (float *)calloc(cdim, sizeof(float));
    noise = (float *)calloc(lat, sizeof(float));
    EXPECT(troupe_session_set_condition(session, cond, cdim - 1), TROUPE_ERR_SHAPE);
    EXPECT(troupe_session_set_condition(session, NULL, cdim), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_set_condition(NULL, cond, cdim), TROUPE_ERR_NULL_ARG);
    cond[1] = INFINITY;
    EXPECT(troupe_session_set_condition(session, cond, cdim), TROUPE_ERR_INVALID_ARG);
    cond[1] = 0.25f;
    EXPECT(troupe_session_set_condition(session, cond, cdim), TROUPE_OK);
    EXPECT(troupe_session_set_condition(session, NULL, 0), TROUPE_OK);
    EXPECT(troupe_armflow_session_queue_noise(session, noise, noise, lat + 1), TROUPE_ERR_SHAPE);
    EXPECT(troupe_armflow_session_queue_noise(session, NULL, noise, lat), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_armflow_session_queue_noise(session, noise, NULL, lat), TROUPE_ERR_NULL_ARG);
    noise[2] = NAN;
    EXPECT(troupe_armflow_session_queue_noise(session, noise, noise, lat), TROUPE_ERR_INVALID_ARG);
    noise[2] = 0.0f;
    EXPECT(troupe_armflow_session_queue_noise(session, noise, noise, lat), TROUPE_OK);
    EXPECT(troupe_session_set_steps(session, 0), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_session_set_steps(session, 2), TROUPE_OK);
    EXPECT(troupe_session_set_cfg_scale(session, NAN), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_session_set_cfg_scale(session, 2.0f), TROUPE_OK);
    EXPECT(troupe_session_set_seed(session, 9), TROUPE_OK);
    EXPECT(troupe_session_set_seed(NULL, 9), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_set_steps(NULL, 1), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_set_cfg_scale(NULL, 1.0f), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_armflow_session_queue_noise(NULL, noise, noise, lat), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_output_frames(NULL, 1, &n), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_output_frames(session, 1, NULL), TROUPE_ERR_NULL_ARG);
    CHECK(stream(session, actor, 8, dim, 8, again, frames) == 8);

#ifdef TROUPE_TESTING
    /* panic -> PANIC -> POISONED -> reset -> OK */
    EXPECT(troupe_testing_panic(session), TROUPE_ERR_PANIC);
    CHECK(strstr(troupe_last_error_message(), "deliberate test panic (at src/") != NULL);
    /* One line, however the host sets RUST_BACKTRACE (tests/c_abi.rs sets it): no backtrace. */
    CHECK(strchr(troupe_last_error_message(), '\n') == NULL);
    EXPECT(troupe_session_step(session, actor, 1, out, 4, &n), TROUPE_ERR_POISONED);
    EXPECT(troupe_session_set_seed(session, 1), TROUPE_ERR_POISONED);
    EXPECT(troupe_session_reset(session), TROUPE_OK);
    EXPECT(troupe_session_step(session, actor, 4, out, 4, &n), TROUPE_OK);
    CHECK(n == 4);
#endif

    /* freeing the model first is safe: sessions keep it alive */
    troupe_model_free(model);
    troupe_model_free(NULL);
    EXPECT(troupe_session_reset(session), TROUPE_OK);
    CHECK(stream(session, actor, 8, dim, 8, again, frames) == 8);
    troupe_session_free(session);
    troupe_session_free(other);
    troupe_session_free(NULL);
    troupe_model_free(from_memory);
    free(actor);
    free(out);
    free(again);
    free(noise);
    free(cond);

    printf("sanitizer: %s\n", TROUPE_TEST_SANITIZER);

    printf("c smoke: %d passed, %d failed\n", passed, failed);
    return failed == 0 ? 0 : 1;
}

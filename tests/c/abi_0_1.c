/* A program written and compiled against the 0.1.0 header (abi/0.1.0/troupe.h, frozen as it
 * was released) and run against this library: the compatibility promise of docs/ABI.md, checked
 * (tests/abi.rs). It uses only what that header declares, under the names it had, plus the
 * prototypes of today's names that it compares them with, declared here by hand.
 * Usage: abi_0_1 ARMFLOW_DIR ARMFLOW_CLIP_DIR UMF_DIR MAGNET_DIR ARFLOW_ONLINE_DIR */
#include "troupe.h"
#include "check.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Today's names of two renamed calls, to check that the old name is the same function. */
troupe_status troupe_umf_generate(const struct troupe_model *model,
                                  const struct troupe_group_options *options,
                                  const float *condition, size_t condition_len, uint32_t people,
                                  const struct troupe_group_noise *noise, float *motion,
                                  size_t motion_capacity, float *latents, size_t latents_capacity);
troupe_status troupe_armflow_clip_generate(const struct troupe_model *model, const float *actor,
                                           size_t n_actor_frames, const float *condition,
                                           size_t condition_len, uint64_t seed, uint32_t steps,
                                           const struct troupe_clip_noise *noise, float *frames,
                                           size_t frames_capacity, float *reactor_latents,
                                           size_t latents_capacity);

/* A caller compiled against a newer header: one field this library does not know. */
typedef struct {
    troupe_session_options known;
    uint64_t newer_field;
} newer_session_options;

static int all_finite(const float *v, size_t n) {
    size_t i;
    for (i = 0; i < n; i++)
        if (!isfinite(v[i])) return 0;
    return 1;
}

static void sessions(const char *dir) {
    troupe_model *model = NULL;
    troupe_session *s = NULL;
    troupe_session_options opt;
    newer_session_options newer;
    float frames[4 * 262], out[4 * 262];
    size_t i, n = 0;

    EXPECT(troupe_model_load_file(dir, &model), TROUPE_OK);
    if (!model) return;
    /* The struct sizes this program was compiled with are the library's. */
    CHECK(troupe_session_options_size() == sizeof(troupe_session_options));
    CHECK(troupe_arflow_options_size() == sizeof(troupe_arflow_options));
    CHECK(troupe_magnet_options_size() == sizeof(troupe_magnet_options));
    CHECK(troupe_group_options_size() == sizeof(troupe_group_options));

    EXPECT(troupe_session_options_init(model, &opt, sizeof opt), TROUPE_OK);
    CHECK(opt.struct_size == sizeof opt);
    opt.seed = 3;
    EXPECT(troupe_session_new(model, &opt, &s), TROUPE_OK);
    for (i = 0; i < 4 * 262; i++) frames[i] = 0.01f * (float)(i % 97);
    EXPECT(troupe_session_step(s, frames, 4, out, 4, &n), TROUPE_OK);
    CHECK(n == 4 && all_finite(out, n * 262));
    /* Renamed: the penetration guard, under its 0.1 name. */
    EXPECT(troupe_session_set_penetration_guard(s, 1, 0.05f, 2.0f), TROUPE_OK);
    EXPECT(troupe_session_set_penetration_guard(s, 1, -1.0f, 2.0f), TROUPE_ERR_INVALID_ARG);
    /* A MAGNet setting on an ARMFlow stream: refused with the status 0.1 did not know. */
    CHECK(troupe_session_set_early_emission(s, 1) == 12);
    CHECK(strcmp(troupe_status_name(12), "TROUPE_ERR_UNSUPPORTED") == 0);
    troupe_session_free(s);
    s = NULL;

    /* A newer caller's struct: accepted while the fields it adds are zero. */
    memset(&newer, 0, sizeof newer);
    EXPECT(troupe_session_options_init(model, &newer.known, sizeof newer), TROUPE_OK);
    CHECK(newer.known.struct_size == sizeof newer && newer.newer_field == 0);
    EXPECT(troupe_session_new(model, &newer.known, &s), TROUPE_OK);
    troupe_session_free(s);
    s = NULL;
    newer.newer_field = 1;
    EXPECT(troupe_session_new(model, &newer.known, &s), TROUPE_ERR_INVALID_ARG);
    CHECK(s == NULL);
    /* Smaller than any version of the struct. */
    opt.struct_size = 4;
    EXPECT(troupe_session_new(model, &opt, &s), TROUPE_ERR_INVALID_ARG);
    troupe_model_free(model);
}

static void clip(const char *dir) {
    troupe_model *model = NULL;
    size_t frames, dim, tokens, latent, i;
    float *actor, *a, *b, *la, *lb;

    EXPECT(troupe_model_load_file(dir, &model), TROUPE_OK);
    if (!model) return;
    frames = troupe_model_clip_frames(model);
    dim = troupe_model_frame_dim(model);
    tokens = troupe_model_clip_tokens(model);
    latent = troupe_model_latent_dim(model);
    CHECK(frames > 0 && tokens > 0);
    actor = calloc(frames * dim, sizeof *actor);
    a = calloc(frames * dim, sizeof *a);
    b = calloc(frames * dim, sizeof *b);
    la = calloc(tokens * latent, sizeof *la);
    lb = calloc(tokens * latent, sizeof *lb);
    for (i = 0; i < frames * dim; i++) actor[i] = 0.02f * sinf((float)i);
    EXPECT(troupe_clip_generate(model, actor, frames, NULL, 0, 5, 1, NULL, a, frames * dim, la,
                                tokens * latent),
           TROUPE_OK);
    EXPECT(troupe_armflow_clip_generate(model, actor, frames, NULL, 0, 5, 1, NULL, b,
                                        frames * dim, lb, tokens * latent),
           TROUPE_OK);
    CHECK(memcmp(a, b, frames * dim * sizeof *a) == 0 && all_finite(a, frames * dim));
    CHECK(memcmp(la, lb, tokens * latent * sizeof *la) == 0);
    free(actor), free(a), free(b), free(la), free(lb);
    troupe_model_free(model);
}

static void group(const char *dir, const char *armflow_dir) {
    troupe_model *model = NULL, *armflow = NULL;
    troupe_group_options opt;
    size_t n, prior = 0, jumps = 0, reactions = 0;
    float *a, *b;

    EXPECT(troupe_model_load_file(dir, &model), TROUPE_OK);
    EXPECT(troupe_model_load_file(armflow_dir, &armflow), TROUPE_OK);
    if (!model || !armflow) return;
    CHECK(troupe_model_group_stages(model) == 2 && troupe_model_group_tokens(model) == 16);
    EXPECT(troupe_group_noise_lengths(model, 2, &prior, &jumps, &reactions), TROUPE_OK);
    CHECK(prior > 0 && reactions > 0);
    EXPECT(troupe_group_options_init(model, &opt, sizeof opt), TROUPE_OK);
    opt.seed = 9;
    n = 2 * troupe_model_clip_frames(model) * troupe_model_frame_dim(model);
    a = calloc(n, sizeof *a);
    b = calloc(n, sizeof *b);
    EXPECT(troupe_group_generate(model, &opt, NULL, 0, 2, NULL, a, n, NULL, 0), TROUPE_OK);
    EXPECT(troupe_umf_generate(model, &opt, NULL, 0, 2, NULL, b, n, NULL, 0), TROUPE_OK);
    CHECK(memcmp(a, b, n * sizeof *a) == 0 && all_finite(a, n));
    /* Another family's bundle: an error, now TROUPE_ERR_UNSUPPORTED. */
    CHECK(troupe_group_options_init(armflow, &opt, sizeof opt) == 12);
    free(a), free(b);
    troupe_model_free(model);
    troupe_model_free(armflow);
}

static void magnet(const char *dir) {
    troupe_model *model = NULL;
    troupe_session *s = NULL;

    EXPECT(troupe_model_load_file(dir, &model), TROUPE_OK);
    if (!model) return;
    CHECK(troupe_model_magnet_people(model) == 2);
    CHECK(troupe_model_magnet_config_count(model) > 0);
    CHECK(troupe_model_magnet_config(model, 0) != NULL);
    CHECK(troupe_model_magnet_config(model, troupe_model_magnet_config_count(model)) == NULL);
    EXPECT(troupe_session_new(model, NULL, &s), TROUPE_OK);
    EXPECT(troupe_session_set_early_emission(s, 1), TROUPE_OK);
    EXPECT(troupe_session_set_live_config(s, "no such configuration"), TROUPE_ERR_INVALID_ARG);
    troupe_session_free(s);
    troupe_model_free(model);
}

static void arflow(const char *dir) {
    troupe_model *model = NULL;
    troupe_session *s = NULL;
    troupe_arflow_options opt;
    float first[66 * 3], second[66 * 3];
    size_t intersecting = 99, i;
    double frequency = -1, depth_sum = -1, max_depth = -1;

    EXPECT(troupe_model_load_file(dir, &model), TROUPE_OK);
    if (!model) return;
    EXPECT(troupe_arflow_options_init(model, &opt, sizeof opt), TROUPE_OK);
    EXPECT(troupe_session_new(model, NULL, &s), TROUPE_OK);
    EXPECT(troupe_session_set_arflow_options(s, &opt), TROUPE_OK);
    opt.flags = 0x80000000u;
    EXPECT(troupe_session_set_arflow_options(s, &opt), TROUPE_ERR_INVALID_ARG);
    troupe_session_free(s);
    troupe_model_free(model);

    /* Renamed: the penetration metrics. Two people (every joint at one point) 3 m apart never
     * intersect. */
    for (i = 0; i < 66 * 3; i++) {
        first[i] = 0.0f;
        second[i] = i % 3 == 0 ? 3.0f : 0.0f;
    }
    EXPECT(troupe_penetration_metrics(first, second, 3, &intersecting, &frequency, &depth_sum,
                                      &max_depth),
           TROUPE_OK);
    CHECK(intersecting == 0 && frequency == 0.0 && depth_sum == 0.0 && max_depth == 0.0);
}

int main(int argc, char **argv) {
    if (argc < 6) {
        fprintf(stderr, "usage: %s ARMFLOW CLIP UMF MAGNET ARFLOW_ONLINE\n", argv[0]);
        return 2;
    }
    CHECK(troupe_abi_version() == TROUPE_ABI_VERSION);
    CHECK(troupe_version_number() >= TROUPE_VERSION_NUMBER);
    sessions(argv[1]);
    clip(argv[2]);
    group(argv[3], argv[1]);
    magnet(argv[4]);
    arflow(argv[5]);
    printf("%d passed, %d failed\n", passed, failed);
    return failed != 0;
}

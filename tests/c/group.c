/* ABI test of UMF group generation through include/troupe.h only. Compiled as C99 and C++17
 * with -Wall -Wextra -Werror -pedantic and run under valgrind (tests/c_abi.rs).
 * Usage: group UMF_BUNDLE_DIR ARMFLOW_BUNDLE_DIR */
#include "troupe.h"
#include "check.h"
#include "npy.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>


int main(int argc, char **argv) {
    troupe_model *model = NULL, *armflow = NULL;
    troupe_session *session = NULL;
    troupe_session_options session_opt;
    troupe_group_options opt, bad;
    troupe_group_noise noise;
    size_t frames, dim, tokens, lat, cdim, n_motion, n_latents, prior_len = 0, jumps_len = 0,
        reactions_len = 0, n = 0, i;
    float *motion, *again, *latents, *golden, *cond, *prior, *jumps, *reactions;
    float *clip_tokens, *text_golden, *three, *three_latents, *want;
    float *t_prior, *t_jumps, *t_reactions;
    float text_cond[32];
    const char *dir;

    if (argc < 3) {
        fprintf(stderr, "usage: %s UMF_BUNDLE_DIR ARMFLOW_BUNDLE_DIR\n", argv[0]);
        return 2;
    }
    dir = argv[1];
    EXPECT(troupe_model_load_file(dir, &model), TROUPE_OK);
    EXPECT(troupe_model_load_file(argv[2], &armflow), TROUPE_OK);
    if (!model || !armflow) return 1;

    /* queries */
    frames = troupe_model_clip_frames(model);
    dim = troupe_model_frame_dim(model);
    tokens = troupe_umf_tokens(model);
    lat = troupe_model_latent_dim(model);
    cdim = troupe_model_condition_dim(model);
    CHECK(frames == 40 && dim == 262 && tokens == 16 && lat == 8 && cdim == 32);
    CHECK(troupe_umf_stages(model) == 2 && troupe_model_frames_per_token(model) == 0);
    CHECK(troupe_model_max_output_frames(model, 10) == 0 && troupe_model_latency_frames(model) == 0);
    CHECK(troupe_model_clip_frames(armflow) == 0 && troupe_umf_stages(armflow) == 0);
    CHECK(troupe_model_clip_frames(NULL) == 0 && troupe_umf_tokens(NULL) == 0);

    /* options: the bundle's defaults */
    CHECK(troupe_umf_options_size() == sizeof(troupe_group_options));
    EXPECT(troupe_umf_options_init(model, &opt, sizeof opt), TROUPE_OK);
    CHECK(opt.struct_size == sizeof opt && opt.stage_count == 2 && opt.cfg_scale == 3.0f);
    CHECK(opt.stage_solver[0] == TROUPE_SOLVER_RK4 && opt.stage_steps[1] == 4);
    CHECK(opt.reaction_solver == TROUPE_SOLVER_RK4 && opt.reaction_steps == 4);
    EXPECT(troupe_umf_options_init(model, &opt, 8), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_umf_options_init(armflow, &opt, sizeof opt), TROUPE_ERR_UNSUPPORTED);
    CHECK(strstr(troupe_last_error_message(), "needs a `umf` bundle") != NULL);
    EXPECT(troupe_umf_options_init(NULL, &opt, sizeof opt), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_umf_options_init(model, &opt, sizeof opt), TROUPE_OK);
    opt.seed = 7;

    /* seeded generation equals the Python reference's seeded case */
    n_motion = 2 * frames * dim;
    n_latents = 2 * tokens * lat;
    motion = (float *)calloc(n_motion, sizeof(float));
    again = (float *)calloc(n_motion, sizeof(float));
    latents = (float *)calloc(n_latents, sizeof(float));
    cond = read_npy(dir, "seeded_2p_condition", &n);
    CHECK(cond != NULL && n == cdim);
    EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 2, NULL, motion, n_motion, latents, n_latents),
           TROUPE_OK);
    golden = read_npy(dir, "seeded_2p_motion", &n);
    CHECK(golden != NULL && n == n_motion);
    if (golden) {
        printf("seeded 2 people: motion max-abs %.2e vs the reference\n", (double)max_abs(motion, golden, n_motion));
        CHECK(max_abs(motion, golden, n_motion) <= 1e-4f);
    }

    /* the same draws given as troupe_group_noise give the same motion */
    EXPECT(troupe_umf_noise_lengths(model, 2, &prior_len, &jumps_len, &reactions_len), TROUPE_OK);
    CHECK(prior_len == 4 * lat && jumps_len == 16 * lat && reactions_len == tokens * lat);
    prior = read_npy(dir, "seeded_2p_prior_noise", &n);
    CHECK(prior != NULL && n == prior_len);
    jumps = read_npy(dir, "seeded_2p_jump1", &n);
    CHECK(jumps != NULL && n == jumps_len);
    reactions = read_npy(dir, "seeded_2p_reaction_noise", &n);
    CHECK(reactions != NULL && n == reactions_len);
    noise.prior = prior;
    noise.prior_len = prior_len;
    noise.jumps = jumps;
    noise.jumps_len = jumps_len;
    noise.reactions = reactions;
    noise.reactions_len = reactions_len;
    opt.seed = 12345; /* ignored: every draw is given */
    EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 2, &noise, again, n_motion, NULL, 0), TROUPE_OK);
    CHECK(max_abs(motion, again, n_motion) <= 1e-5f);

    /* NULL options and NULL condition: defaults, null condition */
    EXPECT(troupe_umf_generate(model, NULL, NULL, 0, 1, NULL, again, n_motion, NULL, 0), TROUPE_OK);

    /* the official text branches: CLIP token features -> [P-Flow text ; S-Flow text], then a
       3-person group on that condition with the reference's draws equals the reference */
    CHECK(troupe_model_text_token_dim(model) == 16 && troupe_model_text_token_dim(armflow) == 0);
    CHECK(troupe_model_text_token_dim(NULL) == 0);
    clip_tokens = read_npy(dir, "text_clip_tokens", &n);
    CHECK(clip_tokens != NULL && n == 77 * 16);
    EXPECT(troupe_text_encode(model, clip_tokens, 77, 9, text_cond, 32), TROUPE_OK);
    text_golden = read_npy(dir, "text_condition", &n);
    CHECK(text_golden != NULL && n == cdim);
    if (text_golden) CHECK(max_abs(text_cond, text_golden, cdim) <= 1e-5f);
    EXPECT(troupe_text_encode(armflow, clip_tokens, 77, 9, text_cond, 32), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "no text_branch") != NULL);
    t_prior = read_npy(dir, "text_3p_prior_noise", &n);
    CHECK(t_prior != NULL && n == prior_len);
    t_jumps = read_npy(dir, "text_3p_jump1", &n);
    CHECK(t_jumps != NULL && n == jumps_len);
    t_reactions = read_npy(dir, "text_3p_reaction_noise", &n);
    CHECK(t_reactions != NULL && n == 2 * reactions_len);
    noise.prior = t_prior;
    noise.jumps = t_jumps;
    noise.reactions = t_reactions;
    noise.reactions_len = 2 * reactions_len;
    three = (float *)calloc(3 * frames * dim, sizeof(float));
    three_latents = (float *)calloc(3 * tokens * lat, sizeof(float));
    EXPECT(troupe_umf_generate(model, &opt, text_cond, cdim, 3, &noise, three, 3 * frames * dim, three_latents,
                                 3 * tokens * lat),
           TROUPE_OK);
    want = read_npy(dir, "text_3p_latents", &n);
    CHECK(want != NULL && n == 3 * tokens * lat);
    if (want) {
        printf("text-conditioned 3 people: latents max-abs %.2e vs the reference\n",
               (double)max_abs(three_latents, want, n));
        CHECK(max_abs(three_latents, want, n) <= 1e-5f);
        free(want);
    }
    want = read_npy(dir, "text_3p_motion", &n);
    CHECK(want != NULL && n == 3 * frames * dim);
    if (want) CHECK(max_abs(three, want, n) <= 1e-4f);
    free(want);
    noise.prior = prior;
    noise.jumps = jumps;
    noise.reactions = reactions;
    noise.reactions_len = reactions_len;

    /* a call budget: a group that would take more work is refused before it starts, nothing
       written; a budget of negative seconds is refused; without one the group runs */
    {
        troupe_call_budget budget = {0, 0.0};
        budget.max_work = 3;
        EXPECT(troupe_set_call_budget(&budget), TROUPE_OK);
        memcpy(again, motion, n_motion * sizeof(float));
        EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 2, NULL, again, n_motion, NULL, 0),
               TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "network evaluations, above this thread's call budget of 3") != NULL);
        CHECK(memcmp(again, motion, n_motion * sizeof(float)) == 0);
        budget.max_work = 0;
        budget.max_seconds = -1.0;
        EXPECT(troupe_set_call_budget(&budget), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 2, NULL, again, n_motion, NULL, 0),
               TROUPE_ERR_INVALID_ARG); /* the refused budget left the old one */
        EXPECT(troupe_set_call_budget(NULL), TROUPE_OK);
        EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 2, NULL, again, n_motion, NULL, 0), TROUPE_OK);
    }

    /* bad inputs: a clear status, and nothing written */
    memcpy(again, motion, n_motion * sizeof(float));
    EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 0, NULL, again, n_motion, NULL, 0), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "people is 0") != NULL);
    EXPECT(troupe_umf_generate(model, &opt, cond, cdim - 1, 2, NULL, again, n_motion, NULL, 0), TROUPE_ERR_SHAPE);
    EXPECT(troupe_umf_generate(model, &opt, NULL, cdim, 2, NULL, again, n_motion, NULL, 0), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 2, NULL, again, n_motion - 1, NULL, 0),
           TROUPE_ERR_BUFFER_TOO_SMALL);
    EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 2, NULL, again, n_motion, latents, 3),
           TROUPE_ERR_BUFFER_TOO_SMALL);
    EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 2, NULL, NULL, 0, NULL, 0), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_umf_generate(NULL, &opt, cond, cdim, 2, NULL, again, n_motion, NULL, 0), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_umf_generate(armflow, &opt, cond, cdim, 2, NULL, again, n_motion, NULL, 0),
           TROUPE_ERR_UNSUPPORTED);
    bad = opt;
    bad.stage_count = 1;
    EXPECT(troupe_umf_generate(model, &bad, cond, cdim, 2, NULL, again, n_motion, NULL, 0), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "1 prior solvers given for a pyramid of 2 stages") != NULL);
    bad = opt;
    bad.stage_solver[1] = 9;
    EXPECT(troupe_umf_generate(model, &bad, cond, cdim, 2, NULL, again, n_motion, NULL, 0), TROUPE_ERR_INVALID_ARG);
    bad = opt;
    bad.reaction_steps = 0;
    EXPECT(troupe_umf_generate(model, &bad, cond, cdim, 2, NULL, again, n_motion, NULL, 0), TROUPE_ERR_INVALID_ARG);
    bad = opt;
    bad.cfg_scale = NAN;
    EXPECT(troupe_umf_generate(model, &bad, cond, cdim, 2, NULL, again, n_motion, NULL, 0), TROUPE_ERR_INVALID_ARG);
    bad = opt;
    bad.struct_size = 4;
    EXPECT(troupe_umf_generate(model, &bad, cond, cdim, 2, NULL, again, n_motion, NULL, 0), TROUPE_ERR_INVALID_ARG);
    noise.jumps_len = jumps_len - 1;
    EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 2, &noise, again, n_motion, NULL, 0), TROUPE_ERR_SHAPE);
    noise.jumps_len = jumps_len;
    EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 3, &noise, again, n_motion * 2, NULL, 0), TROUPE_ERR_SHAPE);
    if (cond) {
        float saved = cond[5];
        cond[5] = NAN;
        EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 2, NULL, again, n_motion, NULL, 0),
               TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "index 5") != NULL);
        cond[5] = saved;
    }
    CHECK(memcmp(again, motion, n_motion * sizeof(float)) == 0);

    /* the families do not mix */
    EXPECT(troupe_session_options_init(model, &session_opt, sizeof session_opt), TROUPE_ERR_UNSUPPORTED);
    EXPECT(troupe_session_new(model, NULL, &session), TROUPE_ERR_UNSUPPORTED);
    CHECK(session == NULL);

    /* a success clears the last error */
    EXPECT(troupe_umf_generate(model, &opt, cond, cdim, 1, NULL, again, n_motion, NULL, 0), TROUPE_OK);
    CHECK(troupe_last_error_message() == NULL);
    for (i = 0; i < frames * dim; i++)
        if (again[i] != again[i]) break;
    CHECK(i == frames * dim);

    troupe_model_free(model);
    troupe_model_free(armflow);
    free(motion);
    free(again);
    free(latents);
    free(golden);
    free(cond);
    free(prior);
    free(jumps);
    free(reactions);
    free(clip_tokens);
    free(text_golden);
    free(three);
    free(three_latents);
    free(t_prior);
    free(t_jumps);
    free(t_reactions);
    printf("sanitizer: %s\n", TROUPE_TEST_SANITIZER);
    printf("c group: %d passed, %d failed\n", passed, failed);
    return failed == 0 ? 0 : 1;
}

/* ABI test of the official ARMFlow clip loop, text branch and text prompts through
 * include/troupe.h only.
 * Compiled as C99 and C++17 with -Wall -Wextra -Werror -pedantic and run under valgrind
 * (tests/c_abi.rs). Usage: clip OFFICIAL_LAYOUT_BUNDLE_DIR STREAMING_ONLY_BUNDLE_DIR */
#include "troupe.h"
#include "check.h"
#include "npy.h"

int main(int argc, char **argv) {
    troupe_model *model = NULL, *streaming = NULL;
    troupe_clip_noise noise;
    size_t frames, dim, tokens, lat, cdim, n_frames, n_lat, n = 0;
    float *out, *again, *latents, *actor, *xi, *eps, *tokens_in, *golden, *cond, *prompt_conditions;
    float condition[64], by_prompt[64];
    const char *dir;

    if (argc < 3) {
        fprintf(stderr, "usage: %s OFFICIAL_LAYOUT_BUNDLE_DIR STREAMING_ONLY_BUNDLE_DIR\n", argv[0]);
        return 2;
    }
    dir = argv[1];
    EXPECT(troupe_model_load_file(dir, &model), TROUPE_OK);
    EXPECT(troupe_model_load_file(argv[2], &streaming), TROUPE_OK);
    if (!model || !streaming) return 1;

    frames = troupe_model_clip_frames(model);
    tokens = troupe_armflow_clip_tokens(model);
    dim = troupe_model_frame_dim(model);
    lat = troupe_model_latent_dim(model);
    cdim = troupe_model_condition_dim(model);
    CHECK(frames == 300 && tokens == 75 && dim == 262 && lat == 16 && cdim == 32);
    CHECK(troupe_armflow_clip_tokens(streaming) == 0 && troupe_model_clip_frames(streaming) == 0);
    CHECK(troupe_armflow_clip_tokens(NULL) == 0);
    CHECK(troupe_model_text_token_dim(model) == cdim && troupe_model_text_token_dim(streaming) == 0);

    /* the text branch: CLIP token features -> condition, as the reference */
    tokens_in = read_npy(dir, "text_clip_tokens", &n);
    CHECK(tokens_in != NULL && n == 77 * cdim);
    EXPECT(troupe_text_encode(model, tokens_in, 77, 9, condition, 64), TROUPE_OK);
    cond = read_npy(dir, "text_condition", &n);
    CHECK(cond != NULL && n == cdim);
    if (cond) CHECK(max_abs(condition, cond, cdim) <= 1e-5f);
    EXPECT(troupe_text_encode(model, tokens_in, 77, 77, condition, 64), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "outside the 77 tokens") != NULL);
    EXPECT(troupe_text_encode(model, tokens_in, 77, 9, condition, cdim - 1), TROUPE_ERR_BUFFER_TOO_SMALL);
    EXPECT(troupe_text_encode(model, NULL, 77, 9, condition, 64), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_text_encode(streaming, tokens_in, 77, 9, condition, 64), TROUPE_ERR_INVALID_ARG);

    /* prompts: the bundle's tokenizer, CLIP tower and text branch, as the reference */
    prompt_conditions = read_npy(dir, "prompt_conditions", &n);
    CHECK(prompt_conditions != NULL && n == 5 * cdim);
    CHECK(troupe_model_takes_prompts(model) == 1 && troupe_model_takes_prompts(streaming) == 0);
    CHECK(troupe_model_takes_prompts(NULL) == 0);
    EXPECT(troupe_text_prompt_encode(model, "", by_prompt, 64), TROUPE_OK);
    if (prompt_conditions) CHECK(max_abs(by_prompt, prompt_conditions, cdim) <= 1e-5f);
    EXPECT(troupe_text_prompt_encode(model, "two people shake hands", by_prompt, 64), TROUPE_OK);
    if (prompt_conditions) CHECK(max_abs(by_prompt, prompt_conditions + cdim, cdim) <= 1e-5f);
    EXPECT(troupe_text_prompt_encode(model, "Ein Mensch l\xc3\xa4uft weg \xe2\x80\x93 der andere folgt! "
                                            "\xf0\x9f\x8f\x83", by_prompt, 64), TROUPE_OK);
    if (prompt_conditions) CHECK(max_abs(by_prompt, prompt_conditions + 3 * cdim, cdim) <= 1e-5f);
    EXPECT(troupe_text_prompt_encode(model, NULL, by_prompt, 64), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_text_prompt_encode(model, "hi", NULL, 64), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_text_prompt_encode(NULL, "hi", by_prompt, 64), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_text_prompt_encode(model, "hi", by_prompt, cdim - 1), TROUPE_ERR_BUFFER_TOO_SMALL);
    EXPECT(troupe_text_prompt_encode(model, "bad \xff utf-8", by_prompt, 64), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_text_prompt_encode(streaming, "hi", by_prompt, 64), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "takes no text prompts") != NULL);
    {
        /* a session conditioned on a prompt streams as one given its vector (40 frames: past
         * the official VAE's 16-frame lookahead) */
        troupe_session *a = NULL, *b = NULL;
        static float in[40 * 262], out_a[40 * 262], out_b[40 * 262];
        size_t got_a = 0, got_b = 0, i;
        for (i = 0; i < 40 * 262; i++) in[i] = 0.01f * (float)(i % 97);
        EXPECT(troupe_session_new(model, NULL, &a), TROUPE_OK);
        EXPECT(troupe_session_new(model, NULL, &b), TROUPE_OK);
        EXPECT(troupe_session_set_prompt(a, "two people shake hands"), TROUPE_OK);
        EXPECT(troupe_text_prompt_encode(model, "two people shake hands", by_prompt, 64), TROUPE_OK);
        EXPECT(troupe_session_set_condition(b, by_prompt, cdim), TROUPE_OK);
        EXPECT(troupe_session_set_prompt(a, NULL), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_session_set_prompt(NULL, "x"), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_session_step(a, in, 40, out_a, 40, &got_a), TROUPE_OK);
        EXPECT(troupe_session_step(b, in, 40, out_b, 40, &got_b), TROUPE_OK);
        CHECK(got_a == got_b && got_a > 0 && memcmp(out_a, out_b, got_a * 262 * sizeof(float)) == 0);
        troupe_session_free(a);
        troupe_session_free(b);
    }

    /* the clip loop with the reference's draws equals the reference */
    n_frames = frames * dim;
    n_lat = tokens * lat;
    out = (float *)calloc(n_frames, sizeof(float));
    again = (float *)calloc(n_frames, sizeof(float));
    latents = (float *)calloc(n_lat, sizeof(float));
    actor = read_npy(dir, "clip_actor", &n);
    CHECK(actor != NULL && n == 200 * dim);
    xi = read_npy(dir, "clip_xi", &n);
    CHECK(xi != NULL && n == n_lat);
    eps = read_npy(dir, "clip_eps", &n);
    CHECK(eps != NULL && n == lat);
    noise.actor_posterior = xi;
    noise.actor_posterior_len = n_lat;
    noise.reactor_noise = eps;
    noise.reactor_noise_len = lat;
    EXPECT(troupe_armflow_clip_generate(model, actor, 200, condition, cdim, 0, 0, &noise, out, n_frames, latents, n_lat),
           TROUPE_OK);
    golden = read_npy(dir, "clip_frames", &n);
    CHECK(golden != NULL && n == n_frames);
    if (golden) {
        printf("clip: frames max-abs %.2e vs the reference\n", (double)max_abs(out, golden, n_frames));
        CHECK(max_abs(out, golden, n_frames) <= 1e-4f);
        free(golden);
    }
    golden = read_npy(dir, "clip_reactor_latents", &n);
    CHECK(golden != NULL && n == n_lat);
    if (golden) CHECK(max_abs(latents, golden, n_lat) <= 1e-5f);

    /* seeded: deterministic, and NULL condition is the null condition */
    EXPECT(troupe_armflow_clip_generate(model, actor, 200, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0), TROUPE_OK);
    EXPECT(troupe_armflow_clip_generate(model, actor, 200, NULL, 0, 3, 0, NULL, out, n_frames, NULL, 0), TROUPE_OK);
    CHECK(memcmp(out, again, n_frames * sizeof(float)) == 0);

    /* bad inputs: a clear status and nothing written */
    EXPECT(troupe_armflow_clip_generate(model, actor, 301, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0),
           TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_armflow_clip_generate(model, actor, 0, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0),
           TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_armflow_clip_generate(model, NULL, 200, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_armflow_clip_generate(model, actor, 200, condition, cdim - 1, 3, 0, NULL, again, n_frames, NULL, 0),
           TROUPE_ERR_SHAPE);
    EXPECT(troupe_armflow_clip_generate(model, actor, 200, NULL, 0, 3, 0, NULL, again, n_frames - 1, NULL, 0),
           TROUPE_ERR_BUFFER_TOO_SMALL);
    EXPECT(troupe_armflow_clip_generate(model, actor, 200, NULL, 0, 3, 0, NULL, again, n_frames, latents, 5),
           TROUPE_ERR_BUFFER_TOO_SMALL);
    EXPECT(troupe_armflow_clip_generate(model, actor, 200, NULL, 0, 3, 0, NULL, NULL, 0, NULL, 0), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_armflow_clip_generate(NULL, actor, 200, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_armflow_clip_generate(streaming, actor, 200, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0),
           TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "no `clip` section") != NULL);
    noise.reactor_noise_len = lat - 1;
    EXPECT(troupe_armflow_clip_generate(model, actor, 200, NULL, 0, 3, 0, &noise, again, n_frames, NULL, 0),
           TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "reactor_noise") != NULL);
    noise.reactor_noise_len = lat;
    if (actor) {
        float saved = actor[7];
        actor[7] = NAN;
        EXPECT(troupe_armflow_clip_generate(model, actor, 200, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0),
               TROUPE_ERR_INVALID_ARG);
        actor[7] = saved;
    }
    CHECK(memcmp(out, again, n_frames * sizeof(float)) == 0);

    {
        /* every setting: _init gives the bundle's; a CFG scale of 2 (what a checkpoint saved
         * with mf.cfg_scale 2 runs) equals the reference guided as the official sampler guides */
        troupe_armflow_clip_options opt;
        size_t n_xi = 0, n_eps = 0, n_lat_g = 0, n_frames_g = 0;
        float *gxi = read_npy(dir, "clip_guided_xi", &n_xi), *geps = read_npy(dir, "clip_guided_eps", &n_eps);
        float *glat = read_npy(dir, "clip_guided_reactor_latents", &n_lat_g);
        float *gframes = read_npy(dir, "clip_guided_frames", &n_frames_g);
        CHECK(gxi && geps && glat && gframes && n_xi == n_lat && n_eps == lat && n_lat_g == n_lat &&
              n_frames_g == n_frames);
        CHECK(troupe_armflow_clip_options_size() == sizeof opt);
        EXPECT(troupe_armflow_clip_options_init(model, &opt, sizeof opt), TROUPE_OK);
        CHECK(opt.struct_size == sizeof opt && opt.steps == 1 && opt.cfg_scale == 1.0f && opt.seed == 0 &&
              opt.reserved == 0);
        opt.seed = 3; /* the plain call's seeded clip, held in `out` */
        EXPECT(troupe_armflow_clip_generate_with_options(model, &opt, actor, 200, NULL, 0, NULL, again, n_frames,
                                                         NULL, 0),
               TROUPE_OK);
        CHECK(memcmp(out, again, n_frames * sizeof(float)) == 0);
        if (gxi && geps && glat && gframes) {
            noise.actor_posterior = gxi;
            noise.reactor_noise = geps;
            opt.cfg_scale = 2.0f;
            EXPECT(troupe_armflow_clip_generate_with_options(model, &opt, actor, 200, condition, cdim, &noise, again,
                                                             n_frames, latents, n_lat),
                   TROUPE_OK);
            printf("guided clip: reactor latents max-abs %.2e, frames %.2e vs the reference\n",
                   (double)max_abs(latents, glat, n_lat), (double)max_abs(again, gframes, n_frames));
            CHECK(max_abs(latents, glat, n_lat) <= 1e-5f);
            CHECK(max_abs(again, gframes, n_frames) <= 1e-4f);
            /* bad settings: refused with a message, nothing written */
            memcpy(out, again, n_frames * sizeof(float));
            opt.reserved = 1;
            EXPECT(troupe_armflow_clip_generate_with_options(model, &opt, actor, 200, NULL, 0, NULL, again, n_frames,
                                                             NULL, 0),
                   TROUPE_ERR_INVALID_ARG);
            CHECK(strstr(troupe_last_error_message(), "reserved") != NULL);
            opt.reserved = 0;
            opt.cfg_scale = NAN;
            EXPECT(troupe_armflow_clip_generate_with_options(model, &opt, actor, 200, NULL, 0, NULL, again, n_frames,
                                                             NULL, 0),
                   TROUPE_ERR_INVALID_ARG);
            opt.cfg_scale = 2.0f;
            opt.steps = 0;
            EXPECT(troupe_armflow_clip_generate_with_options(model, &opt, actor, 200, NULL, 0, NULL, again, n_frames,
                                                             NULL, 0),
                   TROUPE_ERR_INVALID_ARG);
            opt.steps = 1;
            opt.struct_size = 4;
            EXPECT(troupe_armflow_clip_generate_with_options(model, &opt, actor, 200, NULL, 0, NULL, again, n_frames,
                                                             NULL, 0),
                   TROUPE_ERR_INVALID_ARG);
            CHECK(memcmp(out, again, n_frames * sizeof(float)) == 0);
            noise.actor_posterior = xi;
            noise.reactor_noise = eps;
        }
        EXPECT(troupe_armflow_clip_options_init(NULL, &opt, sizeof opt), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_armflow_clip_options_init(model, NULL, sizeof opt), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_armflow_clip_options_init(model, &opt, 4), TROUPE_ERR_INVALID_ARG);
        /* NULL options are the bundle's: the plain call's clip */
        EXPECT(troupe_armflow_clip_generate_with_options(model, NULL, actor, 200, NULL, 0, NULL, again, n_frames,
                                                         NULL, 0),
               TROUPE_OK);
        EXPECT(troupe_armflow_clip_generate(model, actor, 200, NULL, 0, 0, 0, NULL, out, n_frames, NULL, 0), TROUPE_OK);
        CHECK(memcmp(out, again, n_frames * sizeof(float)) == 0);
        free(gxi);
        free(geps);
        free(glat);
        free(gframes);
    }

    free(out);
    free(again);
    free(latents);
    free(actor);
    free(xi);
    free(eps);
    free(tokens_in);
    free(cond);
    free(prompt_conditions);
    free(golden);
    troupe_model_free(model);
    troupe_model_free(streaming);
    printf("sanitizer: %s\n", TROUPE_TEST_SANITIZER);
    printf("%d passed, %d failed\n", passed, failed);
    return failed != 0;
}

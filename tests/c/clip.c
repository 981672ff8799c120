/* ABI test of the official ARMFlow clip loop and text branch through include/troupe.h only.
 * Compiled as C99 and C++17 with -Wall -Wextra -Werror -pedantic and run under valgrind
 * (tests/c_abi.rs). Usage: clip OFFICIAL_LAYOUT_BUNDLE_DIR STREAMING_ONLY_BUNDLE_DIR */
#include "troupe.h"
#include "check.h"
#include "npy.h"

int main(int argc, char **argv) {
    troupe_model *model = NULL, *streaming = NULL;
    troupe_clip_noise noise;
    size_t frames, dim, tokens, lat, cdim, n_frames, n_lat, n = 0;
    float *out, *again, *latents, *actor, *xi, *eps, *tokens_in, *golden, *cond;
    float condition[64];
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
    tokens = troupe_model_clip_tokens(model);
    dim = troupe_model_frame_dim(model);
    lat = troupe_model_latent_dim(model);
    cdim = troupe_model_condition_dim(model);
    CHECK(frames == 300 && tokens == 75 && dim == 262 && lat == 16 && cdim == 32);
    CHECK(troupe_model_clip_tokens(streaming) == 0 && troupe_model_clip_frames(streaming) == 0);
    CHECK(troupe_model_clip_tokens(NULL) == 0);
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
    EXPECT(troupe_clip_generate(model, actor, 200, condition, cdim, 0, 0, &noise, out, n_frames, latents, n_lat),
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
    EXPECT(troupe_clip_generate(model, actor, 200, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0), TROUPE_OK);
    EXPECT(troupe_clip_generate(model, actor, 200, NULL, 0, 3, 0, NULL, out, n_frames, NULL, 0), TROUPE_OK);
    CHECK(memcmp(out, again, n_frames * sizeof(float)) == 0);

    /* bad inputs: a clear status and nothing written */
    EXPECT(troupe_clip_generate(model, actor, 301, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0),
           TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_clip_generate(model, actor, 0, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0),
           TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_clip_generate(model, NULL, 200, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_clip_generate(model, actor, 200, condition, cdim - 1, 3, 0, NULL, again, n_frames, NULL, 0),
           TROUPE_ERR_SHAPE);
    EXPECT(troupe_clip_generate(model, actor, 200, NULL, 0, 3, 0, NULL, again, n_frames - 1, NULL, 0),
           TROUPE_ERR_BUFFER_TOO_SMALL);
    EXPECT(troupe_clip_generate(model, actor, 200, NULL, 0, 3, 0, NULL, again, n_frames, latents, 5),
           TROUPE_ERR_BUFFER_TOO_SMALL);
    EXPECT(troupe_clip_generate(model, actor, 200, NULL, 0, 3, 0, NULL, NULL, 0, NULL, 0), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_clip_generate(NULL, actor, 200, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_clip_generate(streaming, actor, 200, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0),
           TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "no `clip` section") != NULL);
    noise.reactor_noise_len = lat - 1;
    EXPECT(troupe_clip_generate(model, actor, 200, NULL, 0, 3, 0, &noise, again, n_frames, NULL, 0),
           TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "reactor_noise") != NULL);
    noise.reactor_noise_len = lat;
    if (actor) {
        float saved = actor[7];
        actor[7] = NAN;
        EXPECT(troupe_clip_generate(model, actor, 200, NULL, 0, 3, 0, NULL, again, n_frames, NULL, 0),
               TROUPE_ERR_INVALID_ARG);
        actor[7] = saved;
    }
    CHECK(memcmp(out, again, n_frames * sizeof(float)) == 0);

    free(out);
    free(again);
    free(latents);
    free(actor);
    free(xi);
    free(eps);
    free(tokens_in);
    free(cond);
    free(golden);
    troupe_model_free(model);
    troupe_model_free(streaming);
    printf("sanitizer: %s\n", TROUPE_TEST_SANITIZER);
    printf("%d passed, %d failed\n", passed, failed);
    return failed != 0;
}

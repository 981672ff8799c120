/* ABI test of MAGNet generation through include/troupe.h only. Compiled as C99 and C++17 with
 * -Wall -Wextra -Werror -pedantic (tests/c_abi.rs).
 * Usage: magnet MAGNET_BUNDLE_DIR ARMFLOW_BUNDLE_DIR JOINT_SAMPLING_JSON LIVE_SAMPLING_JSON
 * (the golden `joint` and `live_stream` cases' configurations, from golden/cases.json) */
#include "troupe.h"
#include "check.h"
#include "npy.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The live partner through troupe_session_*: the golden stream (person 0 the user, person 1's
 * first 32 frames the partner's opening) equals the reference; bad input changes nothing. */
static void live_partner(troupe_model *model, troupe_model *armflow, const float *clip,
                         const char *dir, const char *live_json) {
    troupe_session *session = NULL, *reactor = NULL;
    troupe_session_options sopt;
    float user[128 * 145], opening[32 * 145], *golden, *out;
    size_t n_golden = 0, written = 0, total = 0, ready, t, a;

    for (t = 0; t < 128; t++) memcpy(user + t * 145, clip + (t * 2) * 145, 145 * sizeof(float));
    for (t = 0; t < 32; t++) memcpy(opening + t * 145, clip + (t * 2 + 1) * 145, 145 * sizeof(float));
    golden = read_npy(dir, "live_stream_frames", &n_golden);
    CHECK(golden != NULL && n_golden == 96 * 145);
    if (!golden) return;
    out = (float *)malloc(n_golden * sizeof *out);

    /* defaults: the released live configuration's 50 steps and 8 context tokens */
    EXPECT(troupe_session_options_init(model, &sopt, sizeof sopt), TROUPE_OK);
    CHECK(sopt.steps == 50 && sopt.context_capacity == 8 && sopt.cfg_scale == 1.0f);
    sopt.seed = 5;
    EXPECT(troupe_session_new(model, &sopt, &session), TROUPE_OK);
    CHECK(troupe_model_latency_frames(model) == 63);
    /* no opening frames yet: the first user frame is refused */
    EXPECT(troupe_session_step(session, user, 1, out, 96, &written), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "opening frames") != NULL);
    EXPECT(troupe_magnet_session_set_live_config(session, "nope"), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_magnet_session_set_live_config(session, "dd100"), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_magnet_session_set_live_config(session, live_json), TROUPE_OK);
    EXPECT(troupe_magnet_session_set_partner_opening(session, opening, 31), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_magnet_session_set_partner_opening(session, NULL, 32), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_magnet_session_set_partner_opening(session, opening, 32), TROUPE_OK);
    EXPECT(troupe_magnet_session_set_early_emission(session, 0), TROUPE_OK);

    /* the stream, 20 frames at a time, each output sized by troupe_session_output_frames */
    for (a = 0; a < 128; a += 20) {
        size_t n = a + 20 <= 128 ? 20 : 128 - a;
        EXPECT(troupe_session_output_frames(session, n, &ready), TROUPE_OK);
        CHECK(ready <= troupe_model_max_output_frames(model, n));
        if (ready > 0) {
            /* one frame too little: refused, the session unchanged */
            EXPECT(troupe_session_step(session, user + a * 145, n, out + total * 145, ready - 1, &written),
                   TROUPE_ERR_BUFFER_TOO_SMALL);
        }
        EXPECT(troupe_session_step(session, user + a * 145, n, out + total * 145, ready, &written), TROUPE_OK);
        CHECK(written == ready);
        total += written;
    }
    CHECK(total == 96);
    printf("live partner through the C ABI: frames %.2e relative max-abs\n",
           (double)(max_abs(out, golden, n_golden) / max_value(golden, n_golden)));
    CHECK(max_abs(out, golden, n_golden) <= 1e-4f * max_value(golden, n_golden));
    /* settings of a running stream, and what only armflow sessions have */
    EXPECT(troupe_magnet_session_set_early_emission(session, 1), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_magnet_session_set_partner_opening(session, opening, 32), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_session_set_prompt(session, "wave"), TROUPE_ERR_UNSUPPORTED);
    EXPECT(troupe_session_set_cfg_scale(session, 2.0f), TROUPE_ERR_UNSUPPORTED);
    {
        troupe_armflow_session_options arm;
        troupe_session *not_armflow = NULL;
        EXPECT(troupe_armflow_session_options_init(model, &arm, sizeof arm), TROUPE_ERR_UNSUPPORTED);
        EXPECT(troupe_armflow_session_new(model, NULL, NULL, &not_armflow), TROUPE_ERR_UNSUPPORTED);
        CHECK(not_armflow == NULL);
    }
    /* after a reset the same stream comes out again (the opening is kept) */
    EXPECT(troupe_session_reset(session), TROUPE_OK);
    EXPECT(troupe_session_step(session, user, 128, out, 96, &written), TROUPE_OK);
    CHECK(written == 96 && max_abs(out, golden, n_golden) <= 1e-4f * max_value(golden, n_golden));

    /* an armflow session has no partner */
    EXPECT(troupe_session_new(armflow, NULL, &reactor), TROUPE_OK);
    EXPECT(troupe_magnet_session_set_partner_opening(reactor, opening, 32), TROUPE_ERR_UNSUPPORTED);
    EXPECT(troupe_magnet_session_set_early_emission(reactor, 1), TROUPE_ERR_UNSUPPORTED);

    troupe_session_free(reactor);
    troupe_session_free(session);
    free(out);
    free(golden);
}

int main(int argc, char **argv) {
    troupe_model *model = NULL, *armflow = NULL;
    troupe_magnet_options opt;
    size_t n_frames = 0, n_golden = 0, s = 0, f = 0, p = 0, n, i, count;
    float *frames, *golden, *out, *nan_frames;
    int found_dd100 = 0;
    unsigned char present[128 * 2];

    if (argc < 5) {
        fprintf(stderr, "usage: %s MAGNET_BUNDLE_DIR ARMFLOW_BUNDLE_DIR JOINT_SAMPLING_JSON LIVE_SAMPLING_JSON\n", argv[0]);
        return 2;
    }
    EXPECT(troupe_model_load_file(argv[1], &model), TROUPE_OK);
    EXPECT(troupe_model_load_file(argv[2], &armflow), TROUPE_OK);
    frames = read_npy(argv[1], "frames", &n_frames);
    golden = read_npy(argv[1], "joint_frames", &n_golden);
    if (!model || !armflow || !frames || !golden) return 1;
    CHECK(n_frames == 128 * 2 * 145);

    /* queries */
    CHECK(troupe_magnet_people(model) == 2 && troupe_magnet_people(armflow) == 0);
    CHECK(troupe_magnet_people(NULL) == 0 && troupe_model_frame_dim(model) == 145);
    count = troupe_magnet_config_count(model);
    CHECK(count == 8 && troupe_magnet_config_count(armflow) == 0);
    for (i = 0; i < count; i++)
        if (strcmp(troupe_magnet_config(model, i), "dd100") == 0) found_dd100 = 1;
    CHECK(found_dd100);
    CHECK(troupe_magnet_config(model, count) == NULL && troupe_magnet_config(NULL, 0) == NULL);

    /* options */
    CHECK(troupe_magnet_options_size() == sizeof(troupe_magnet_options));
    EXPECT(troupe_magnet_options_init(&opt, sizeof opt), TROUPE_OK);
    CHECK(opt.struct_size == sizeof opt && opt.samples == 0 && opt.flags == 0);
    EXPECT(troupe_magnet_options_init(&opt, 8), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_magnet_options_init(NULL, sizeof opt), TROUPE_ERR_NULL_ARG);

    /* the golden joint case, configuration given as JSON: parity with the reference */
    EXPECT(troupe_magnet_output_shape(model, argv[3], NULL, 128, &s, &f, &p), TROUPE_OK);
    CHECK(s == 2 && f == 96 && p == 2);
    n = s * f * p * 145;
    CHECK(n == n_golden);
    out = (float *)malloc(n * sizeof *out);
    EXPECT(troupe_magnet_generate(model, argv[3], NULL, frames, 128, NULL, out, n), TROUPE_OK);
    printf("joint through the C ABI: frames %.2e relative max-abs\n",
           (double)(max_abs(out, golden, n) / max_value(golden, n)));
    CHECK(max_abs(out, golden, n) <= 1e-4f * max_value(golden, n));

    /* a released configuration, changed by options */
    EXPECT(troupe_magnet_options_init(&opt, sizeof opt), TROUPE_OK);
    opt.samples = 1;
    opt.steps = 2;
    opt.seq_len = 64;
    opt.flags = TROUPE_MAGNET_NO_X0_GUIDANCE | TROUPE_MAGNET_SEED;
    opt.seed = 3;
    EXPECT(troupe_magnet_output_shape(model, "dd100", &opt, 128, &s, &f, &p), TROUPE_OK);
    CHECK(s == 1 && f == 64 && p == 2);
    for (i = 0; i < sizeof present; i++) present[i] = 1;
    EXPECT(troupe_magnet_generate(model, "dd100", &opt, frames, 128, present, out, n), TROUPE_OK);
    for (i = 0; i < s * f * p * 145; i++)
        if (!isfinite(out[i])) break;
    CHECK(i == s * f * p * 145);

    {
        /* the run's normals given as one queue (all zero: any finite values are normals to the
         * sampler): the call says how many it took; exactly that many replay it, fewer are
         * refused naming the draw, and nothing is written then */
        size_t big = (size_t)1 << 20, used = 0, used_again = 0, m = s * f * p * 145;
        float *zeros = (float *)calloc(big, sizeof *zeros), *again = (float *)malloc(n * sizeof *again);
        EXPECT(troupe_magnet_generate_with_draws(model, "dd100", &opt, frames, 128, NULL, zeros, big, &used, out, n),
               TROUPE_OK);
        CHECK(used > 0 && used < big);
        EXPECT(troupe_magnet_generate_with_draws(model, "dd100", &opt, frames, 128, NULL, zeros, used, &used_again,
                                                 again, n),
               TROUPE_OK);
        CHECK(used_again == used && memcmp(out, again, m * sizeof *out) == 0);
        again[0] = 12345.0f;
        EXPECT(troupe_magnet_generate_with_draws(model, "dd100", &opt, frames, 128, NULL, zeros, used - 1, NULL,
                                                 again, n),
               TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "needs") != NULL);
        EXPECT(troupe_magnet_generate_with_draws(model, "dd100", &opt, frames, 128, NULL, NULL, 5, NULL, again, n),
               TROUPE_ERR_NULL_ARG);
        zeros[7] = NAN;
        EXPECT(troupe_magnet_generate_with_draws(model, "dd100", &opt, frames, 128, NULL, zeros, used, NULL, again,
                                                 n),
               TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "injected normal 7 is not finite") != NULL);
        CHECK(again[0] == 12345.0f);
        free(zeros);
        free(again);
    }

    /* bad input: a clear status and message, the output untouched */
    out[0] = 12345.0f;
    EXPECT(troupe_magnet_generate(model, NULL, &opt, frames, 128, NULL, out, n), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_magnet_generate(model, "nope", &opt, frames, 128, NULL, out, n), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "no sampling configuration `nope`") != NULL);
    EXPECT(troupe_magnet_generate(model, "{\"task\": 3}", &opt, frames, 128, NULL, out, n), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "not valid") != NULL);
    EXPECT(troupe_magnet_generate(model, "dd100", &opt, frames, 128, NULL, out, 10), TROUPE_ERR_BUFFER_TOO_SMALL);
    EXPECT(troupe_magnet_generate(model, "dd100", &opt, frames, 16, NULL, out, n), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "needs at least 32 frames") != NULL);
    EXPECT(troupe_magnet_generate(model, "dd100", &opt, NULL, 128, NULL, out, n), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_magnet_generate(armflow, "dd100", &opt, frames, 128, NULL, out, n), TROUPE_ERR_UNSUPPORTED);
    CHECK(strstr(troupe_last_error_message(), "needs a `magnet` bundle") != NULL);
    nan_frames = (float *)malloc(n_frames * sizeof *nan_frames);
    memcpy(nan_frames, frames, n_frames * sizeof *nan_frames);
    nan_frames[1000] = NAN;
    EXPECT(troupe_magnet_generate(model, "dd100", &opt, nan_frames, 128, NULL, out, n), TROUPE_ERR_INVALID_ARG);
    opt.flags = 1u << 20;
    EXPECT(troupe_magnet_generate(model, "dd100", &opt, frames, 128, NULL, out, n), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "unknown flags") != NULL);
    opt.flags = TROUPE_MAGNET_KEYFRAMES;
    opt.keyframe_count = 9;
    EXPECT(troupe_magnet_generate(model, "dd100_inbetweening", &opt, frames, 128, NULL, out, n), TROUPE_ERR_INVALID_ARG);
    CHECK(out[0] == 12345.0f);

    live_partner(model, armflow, frames, argv[1], argv[4]);

    free(nan_frames);
    free(out);
    free(golden);
    free(frames);
    troupe_model_free(model);
    troupe_model_free(armflow);
    printf("sanitizer: %s\n", TROUPE_TEST_SANITIZER);
    printf("c magnet: %d passed, %d failed\n", passed, failed);
    return failed != 0;
}

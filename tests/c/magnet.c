/* ABI test of MAGNet generation through include/troupe.h only. Compiled as C99 and C++17 with
 * -Wall -Wextra -Werror -pedantic (tests/c_abi.rs).
 * Usage: magnet MAGNET_BUNDLE_DIR ARMFLOW_BUNDLE_DIR JOINT_SAMPLING_JSON
 * (the golden `joint` case's configuration, from golden/cases.json) */
#include "troupe.h"
#include "check.h"
#include "npy.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static float max_value(const float *a, size_t n) {
    float m = 0.0f;
    size_t i;
    for (i = 0; i < n; i++)
        if (fabsf(a[i]) > m) m = fabsf(a[i]);
    return m;
}

int main(int argc, char **argv) {
    troupe_model *model = NULL, *armflow = NULL;
    troupe_magnet_options opt;
    size_t n_frames = 0, n_golden = 0, s = 0, f = 0, p = 0, n, i, count;
    float *frames, *golden, *out, *nan_frames;
    int found_dd100 = 0;
    unsigned char present[128 * 2];

    if (argc < 4) {
        fprintf(stderr, "usage: %s MAGNET_BUNDLE_DIR ARMFLOW_BUNDLE_DIR JOINT_SAMPLING_JSON\n", argv[0]);
        return 2;
    }
    EXPECT(troupe_model_load_file(argv[1], &model), TROUPE_OK);
    EXPECT(troupe_model_load_file(argv[2], &armflow), TROUPE_OK);
    frames = read_npy(argv[1], "frames", &n_frames);
    golden = read_npy(argv[1], "joint_frames", &n_golden);
    if (!model || !armflow || !frames || !golden) return 1;
    CHECK(n_frames == 128 * 2 * 145);

    /* queries */
    CHECK(troupe_model_magnet_people(model) == 2 && troupe_model_magnet_people(armflow) == 0);
    CHECK(troupe_model_magnet_people(NULL) == 0 && troupe_model_frame_dim(model) == 145);
    count = troupe_model_magnet_config_count(model);
    CHECK(count == 8 && troupe_model_magnet_config_count(armflow) == 0);
    for (i = 0; i < count; i++)
        if (strcmp(troupe_model_magnet_config(model, i), "dd100") == 0) found_dd100 = 1;
    CHECK(found_dd100);
    CHECK(troupe_model_magnet_config(model, count) == NULL && troupe_model_magnet_config(NULL, 0) == NULL);

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
    EXPECT(troupe_magnet_generate(armflow, "dd100", &opt, frames, 128, NULL, out, n), TROUPE_ERR_INVALID_ARG);
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

/* Named conditions through the header: the trained demo bundle's partner rules by name, and every
 * bad input (NULL, unknown label, short buffer, a bundle without labels) refused with the buffer
 * untouched; and which graphs hold reduced-precision weights. Arguments: the demo bundle, a
 * bundle without labels, the demo with int8 weights. */
#include <string.h>

#include "check.h"

int main(int argc, char **argv) {
    troupe_model *demo = NULL, *plain = NULL, *int8 = NULL;
    float v[8];
    size_t k, i;
    const char *rules[3] = {"mirror", "follow", "keep-away"};

    if (argc < 4) {
        fprintf(stderr, "usage: %s DEMO_BUNDLE PLAIN_BUNDLE INT8_DEMO_BUNDLE\n", argv[0]);
        return 2;
    }
    EXPECT(troupe_model_load_file(argv[1], &demo), TROUPE_OK);
    EXPECT(troupe_model_load_file(argv[2], &plain), TROUPE_OK);
    EXPECT(troupe_model_load_file(argv[3], &int8), TROUPE_OK);
    if (!demo || !plain || !int8) return 1;

    /* reduced precision: the int8 demo says which graphs, the float32 one none */
    CHECK(troupe_model_reduced_precision_count(demo) == 0);
    CHECK(troupe_model_reduced_precision_graph(demo, 0) == NULL);
    CHECK(troupe_model_reduced_precision_count(int8) == 2);
    CHECK(strcmp(troupe_model_reduced_precision_graph(int8, 0), "context_layers") == 0);
    CHECK(strcmp(troupe_model_reduced_precision_graph(int8, 1), "velocity") == 0);
    CHECK(strcmp(troupe_model_reduced_precision_weights(int8, 1), "int8") == 0);
    CHECK(troupe_model_reduced_precision_weights(int8, 2) == NULL);
    CHECK(troupe_model_reduced_precision_count(NULL) == 0);
    CHECK(troupe_model_reduced_precision_graph(NULL, 0) == NULL);
    CHECK(troupe_model_reduced_precision_weights(NULL, 0) == NULL);

    CHECK(troupe_model_condition_dim(demo) == 3);
    CHECK(troupe_model_condition_label_count(demo) == 3);
    for (k = 0; k < 3; k++) {
        const char *name = troupe_model_condition_label(demo, k);
        CHECK(name && strcmp(name, rules[k]) == 0);
        for (i = 0; i < 8; i++) v[i] = -7.0f;
        EXPECT(troupe_model_condition_for_label(demo, rules[k], v, 3), TROUPE_OK);
        for (i = 0; i < 3; i++) CHECK(v[i] == (i == k ? 1.0f : 0.0f));
        CHECK(v[3] == -7.0f); /* nothing past the condition */
    }
    CHECK(troupe_model_condition_label(demo, 3) == NULL);
    CHECK(troupe_model_condition_label(NULL, 0) == NULL);
    CHECK(troupe_model_condition_label_count(NULL) == 0);

    /* bad input: an error, a message, the buffer untouched */
    for (i = 0; i < 8; i++) v[i] = -7.0f;
    EXPECT(troupe_model_condition_for_label(demo, "dance", v, 3), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "has: mirror, follow, keep-away") != NULL);
    EXPECT(troupe_model_condition_for_label(demo, "mirror", v, 2), TROUPE_ERR_BUFFER_TOO_SMALL);
    CHECK(strstr(troupe_last_error_message(), "needs 3 floats") != NULL);
    EXPECT(troupe_model_condition_for_label(demo, NULL, v, 3), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_model_condition_for_label(demo, "mirror", NULL, 3), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_model_condition_for_label(NULL, "mirror", v, 3), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_model_condition_for_label(demo, "\xff\xfe", v, 3), TROUPE_ERR_INVALID_ARG);
    for (i = 0; i < 8; i++) CHECK(v[i] == -7.0f);

    /* a bundle conditioned on free vectors has no labels */
    CHECK(troupe_model_condition_label_count(plain) == 0);
    CHECK(troupe_model_condition_label(plain, 0) == NULL);
    EXPECT(troupe_model_condition_for_label(plain, "mirror", v, 8), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "has no named conditions") != NULL);

    /* a label's vector drives a session */
    {
        troupe_session *s = NULL;
        EXPECT(troupe_session_new(demo, NULL, &s), TROUPE_OK);
        EXPECT(troupe_model_condition_for_label(demo, "follow", v, 3), TROUPE_OK);
        EXPECT(troupe_session_set_condition(s, v, 3), TROUPE_OK);
        troupe_session_free(s);
    }
    troupe_model_free(demo);
    troupe_model_free(plain);
    troupe_model_free(int8);
    printf("sanitizer: %s\n", TROUPE_TEST_SANITIZER);
    printf("labels: %d passed, %d failed\n", passed, failed);
    return failed ? 1 : 0;
}

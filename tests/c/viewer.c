/* ABI test of troupe_viewer_write (the HTML player and the GIF) through include/troupe.h only.
 * Compiled as C99 and C++17 with -Wall -Wextra -Werror -pedantic (tests/c_abi.rs).
 * Usage: viewer SCRATCH_DIR */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "troupe.h"
#include "check.h"

#define J 22
#define FRAMES 20
#define PEOPLE 2

/* Two people in a z-up centimetre world: the neutral body's rest pose at x = -0.8 m and, walking
 * toward +y (the world's forward), at x = +0.8 m. Canonical (x, y, z) m -> (100 x, -100 z, 100 y). */
static void make_people(float *positions) {
    int parents[J];
    float offsets[3 * J], rest[3 * J];
    size_t p, t, j;
    troupe_motion_skeleton(parents, J, offsets, 3 * J);
    for (j = 0; j < J; j++) {
        int d;
        for (d = 0; d < 3; d++)
            rest[3 * j + d] = offsets[3 * j + d] + (parents[j] >= 0 ? rest[3 * parents[j] + d] : 0.0f);
    }
    for (p = 0; p < PEOPLE; p++) {
        for (t = 0; t < FRAMES; t++) {
            for (j = 0; j < J; j++) {
                float *w = &positions[((p * FRAMES + t) * J + j) * 3];
                float x = rest[3 * j] + (p == 0 ? -0.8f : 0.8f);
                float z = rest[3 * j + 2] + (p == 0 ? 0.0f : 0.02f * (float)t);
                w[0] = 100.0f * x;
                w[1] = -100.0f * z;
                w[2] = 100.0f * rest[3 * j + 1];
            }
        }
    }
}

/* Whether `path` exists and starts with `magic`. */
static int starts_with(const char *path, const char *magic) {
    char head[16] = {0};
    size_t n = strlen(magic), got;
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    got = fread(head, 1, n, f);
    fclose(f);
    return got == n && memcmp(head, magic, n) == 0;
}

static int exists(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    fclose(f);
    return 1;
}

int main(int argc, char **argv) {
    troupe_joints_format format, bad_format;
    float *positions;
    const char *names[PEOPLE] = {"actor", NULL};
    char html[4096], gif[4096], nan_html[4096], missing[4096];
    size_t n = (size_t)PEOPLE * FRAMES * J * 3;

    if (argc < 2) {
        fprintf(stderr, "usage: %s SCRATCH_DIR\n", argv[0]);
        return 2;
    }
    snprintf(html, sizeof html, "%s/viewer_c.html", argv[1]);
    snprintf(gif, sizeof gif, "%s/viewer_c.gif", argv[1]);
    snprintf(nan_html, sizeof nan_html, "%s/viewer_c_nan.html", argv[1]);
    snprintf(missing, sizeof missing, "%s/no/such/dir/viewer_c.gif", argv[1]);
    remove(html);
    remove(gif);
    remove(nan_html);

    positions = (float *)malloc(n * sizeof(float));
    make_people(positions);
    EXPECT(troupe_joints_format_init(&format, sizeof format), TROUPE_OK);
    format.units = TROUPE_UNITS_CENTIMETERS;
    format.up_axis = TROUPE_UP_Z;
    format.fps = 20.0f;

    /* Both pictures; the second name defaults ("person2"). */
    EXPECT(troupe_viewer_write(html, gif, positions, PEOPLE, FRAMES, &format, names, "from C"),
           TROUPE_OK);
    CHECK(troupe_last_error_message() == NULL);
    CHECK(starts_with(html, "<!doctype html>"));
    CHECK(starts_with(gif, "GIF89a"));
    /* One picture, no names, no title. */
    remove(gif);
    EXPECT(troupe_viewer_write(NULL, gif, positions, 1, FRAMES, &format, NULL, NULL), TROUPE_OK);
    CHECK(starts_with(gif, "GIF89a"));

    /* Refusals, each writing nothing. */
    EXPECT(troupe_viewer_write(NULL, NULL, positions, PEOPLE, FRAMES, &format, NULL, NULL),
           TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_viewer_write(nan_html, NULL, NULL, PEOPLE, FRAMES, &format, NULL, NULL),
           TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_viewer_write(nan_html, NULL, positions, PEOPLE, FRAMES, NULL, NULL, NULL),
           TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_viewer_write(nan_html, NULL, positions, 0, FRAMES, &format, NULL, NULL),
           TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_viewer_write(nan_html, NULL, positions, 9, FRAMES, &format, NULL, NULL),
           TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_viewer_write(nan_html, NULL, positions, PEOPLE, 0, &format, NULL, NULL),
           TROUPE_ERR_INVALID_ARG);
    bad_format = format;
    bad_format.up_axis = 7;
    EXPECT(troupe_viewer_write(nan_html, NULL, positions, PEOPLE, FRAMES, &bad_format, NULL, NULL),
           TROUPE_ERR_INVALID_ARG);
    positions[(FRAMES * J + 3) * 3 + 1] = (float)NAN;
    EXPECT(troupe_viewer_write(nan_html, NULL, positions, PEOPLE, FRAMES, &format, names, NULL),
           TROUPE_ERR_INVALID_ARG);
    CHECK(troupe_last_error_message() != NULL &&
          strstr(troupe_last_error_message(), "person2: frame 0, joint 3") != NULL);
    CHECK(!exists(nan_html));
    make_people(positions);
    /* The GIF's directory is missing: the HTML is not written either. */
    EXPECT(troupe_viewer_write(nan_html, missing, positions, PEOPLE, FRAMES, &format, NULL, NULL),
           TROUPE_ERR_IO);
    CHECK(!exists(nan_html));

    remove(html);
    remove(gif);
    free(positions);
    printf("sanitizer: %s\n", TROUPE_TEST_SANITIZER);
    printf("viewer: %d passed, %d failed\n", passed, failed);
    return failed != 0;
}

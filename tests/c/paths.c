/* Paths as an engine hands them to troupe, on every platform: UTF-8 strings with either
 * separator, drive letters on Windows, names in any script, and names that must be refused
 * (Windows device names, files reached through links out of the bundle).
 *
 *   paths LIST
 *
 * LIST is a UTF-8 text file (so that no path passes through the command line's code page), one
 * "VERB PATH" per line:
 *   load PATH         the bundle loads, and a session on it streams exactly what the first
 *                     loaded bundle streamed (the same files under another spelling)
 *   refuse PATH       loading fails (not OK, not a crash, not a hang) with a message
 *   bvh PATH          a BVH file is written at PATH and read back with the same frame count
 *   refuse-write PATH writing a BVH file at PATH fails
 *   refuse-bvh PATH   reading a BVH file at PATH fails
 * Prints each verdict and "N passed, M failed". */
#include <stdlib.h>
#include <string.h>

#include "check.h"

#define J 22
#define FRAMES 4
#define TOKENS 6
/* Room for TOKENS tokens of the tiny bundle's frames (4 frames of 262 floats each). */
#define CAP (TOKENS * 4 * 262)

static float first[CAP];
static size_t first_len = 0;

/* Streams TOKENS tokens of a still actor from a fresh default session; the output in `out`. */
static size_t stream(const troupe_model *model, float *out, size_t cap) {
    troupe_session *session = NULL;
    size_t dim = troupe_model_frame_dim(model), fpt = troupe_model_frames_per_token(model);
    size_t total = 0, n = 0, i;
    float *actor = (float *)calloc(fpt * dim, sizeof(float));
    if (!actor || troupe_session_new(model, NULL, &session) != TROUPE_OK) {
        free(actor);
        return 0;
    }
    for (i = 0; i < TOKENS; i++) {
        if (troupe_session_step(session, actor, fpt, out + total, cap - total, &n) != TROUPE_OK) break;
        total += n * dim;
    }
    troupe_session_free(session);
    free(actor);
    return total;
}

/* A standing person: the skeleton's rest offsets summed along its chains, 1 m up. */
static void rest_pose(float *clip) {
    int parents[J];
    float offsets[3 * J];
    int f, j, k;
    if (troupe_motion_skeleton(parents, J, offsets, 3 * J) != TROUPE_OK) return;
    for (f = 0; f < FRAMES; f++) {
        for (j = 0; j < J; j++) {
            for (k = 0; k < 3; k++) {
                float base = parents[j] < 0 ? (k == 2 ? 1.0f : 0.0f) : clip[(f * J + parents[j]) * 3 + k];
                clip[(f * J + j) * 3 + k] = base + offsets[3 * j + k] + (k == 0 ? 0.01f * (float)f : 0.0f);
            }
        }
    }
}

static void run(const char *verb, const char *path) {
    troupe_model *model = NULL;
    troupe_bvh *bvh = NULL;
    troupe_joints_format format;
    float clip[FRAMES * J * 3];
    static float out[CAP];
    const char *names[1] = {"actor"};
    size_t len;
    int before = failed;
    troupe_status status;
    if (strcmp(verb, "load") == 0) {
        EXPECT(troupe_model_load_file(path, &model), TROUPE_OK);
        if (model) {
            len = stream(model, out, CAP);
            CHECK(len > 0);
            if (first_len == 0) {
                memcpy(first, out, len * sizeof(float));
                first_len = len;
            } else {
                CHECK(len == first_len && memcmp(first, out, len * sizeof(float)) == 0);
            }
        }
        troupe_model_free(model);
    } else if (strcmp(verb, "refuse") == 0) {
        status = troupe_model_load_file(path, &model);
        CHECK(status != TROUPE_OK && model == NULL);
        CHECK(troupe_last_error_message() != NULL);
        printf("  refused (%s): %s\n", troupe_status_name(status), troupe_last_error_message());
        troupe_model_free(model);
    } else if (strcmp(verb, "bvh") == 0 || strcmp(verb, "refuse-write") == 0) {
        EXPECT(troupe_joints_format_init(&format, sizeof format), TROUPE_OK);
        format.up_axis = TROUPE_UP_Z;
        rest_pose(clip);
        status = troupe_bvh_write(path, clip, 1, FRAMES, &format, names, TROUPE_UNITS_CENTIMETERS, 1);
        if (verb[0] == 'b') {
            EXPECT(status, TROUPE_OK);
            EXPECT(troupe_bvh_read(path, NULL, TROUPE_UNITS_AUTO, &bvh), TROUPE_OK);
            CHECK(troupe_bvh_frames(bvh) == FRAMES);
            troupe_bvh_free(bvh);
        } else {
            CHECK(status != TROUPE_OK && troupe_last_error_message() != NULL);
            printf("  refused (%s): %s\n", troupe_status_name(status), troupe_last_error_message());
        }
    } else if (strcmp(verb, "refuse-bvh") == 0) {
        status = troupe_bvh_read(path, NULL, TROUPE_UNITS_AUTO, &bvh);
        CHECK(status != TROUPE_OK && bvh == NULL && troupe_last_error_message() != NULL);
        printf("  refused (%s): %s\n", troupe_status_name(status), troupe_last_error_message());
        troupe_bvh_free(bvh);
    } else {
        fprintf(stderr, "unknown verb %s\n", verb);
        failed++;
    }
    printf("%s %s: %s\n", verb, path, failed == before ? "ok" : "FAILED");
}

int main(int argc, char **argv) {
    char line[2048];
    FILE *list;
    if (argc < 2 || !(list = fopen(argv[1], "rb"))) {
        fprintf(stderr, "usage: %s LIST\n", argv[0]);
        return 2;
    }
    while (fgets(line, sizeof line, list)) {
        char *space = strchr(line, ' ');
        size_t end = strcspn(line, "\r\n");
        line[end] = '\0';
        if (!space || end == 0) continue;
        *space = '\0';
        run(line, space + 1);
    }
    fclose(list);
    printf("paths: %d passed, %d failed\n", passed, failed);
    return failed != 0;
}

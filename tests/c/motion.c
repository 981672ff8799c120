/* ABI test of the motion functions (skeleton, joint positions <-> features, streams) through
 * include/troupe.h only. Compiled as C99 and C++17 with -Wall -Wextra -Werror -pedantic and run
 * under valgrind (tests/c_abi.rs). Usage: motion INTERHUMAN262_BUNDLE_DIR INTERX_BUNDLE_DIR
 * [SCRATCH_DIR for the BVH files] */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "troupe.h"
#include "check.h"

#define J 22
#define FRAMES 24

/* A z-up centimetre world: canonical (x, y, z) metres -> (100 x, -100 z, 100 y). */
static void to_world(const float c[3], float w[3]) {
    w[0] = 100.0f * c[0];
    w[1] = -100.0f * c[2];
    w[2] = 100.0f * c[1];
}

/* The neutral body's rest pose walking forward 1.5 cm per frame, turned 0.3 rad, in that world. */
static void make_clip(float *positions) {
    int parents[J];
    float offsets[3 * J], rest[3 * J];
    size_t t, j;
    troupe_motion_skeleton(parents, J, offsets, 3 * J);
    for (j = 0; j < J; j++) {
        int d;
        for (d = 0; d < 3; d++)
            rest[3 * j + d] = offsets[3 * j + d] + (parents[j] >= 0 ? rest[3 * parents[j] + d] : 0.0f);
    }
    for (t = 0; t < FRAMES; t++) {
        for (j = 0; j < J; j++) {
            float c[3], x = rest[3 * j], z = rest[3 * j + 2];
            float s = sinf(0.3f), k = cosf(0.3f);
            c[0] = k * x + s * z + 0.4f;
            c[1] = rest[3 * j + 1] + 0.01f * sinf(0.5f * (float)t);
            c[2] = -s * x + k * z + 0.015f * (float)t - 1.0f;
            to_world(c, &positions[(t * J + j) * 3]);
        }
    }
}

int main(int argc, char **argv) {
    troupe_model *model = NULL, *interx = NULL;
    troupe_joints_format format;
    troupe_placement placement, again;
    troupe_pose_buffers pose;
    troupe_motion_stream *stream = NULL;
    float *clip, *features, *positions, *rotations, *contacts, *streamed, *row, sentinel;
    int parents[J];
    float offsets[3 * J];
    size_t n = 0, dim, frames, t, i, written;
    float worst = 0.0f;

    if (argc < 3) {
        fprintf(stderr, "usage: %s INTERHUMAN262_BUNDLE_DIR INTERX_BUNDLE_DIR\n", argv[0]);
        return 2;
    }
    EXPECT(troupe_model_load_file(argv[1], &model), TROUPE_OK);
    EXPECT(troupe_model_load_file(argv[2], &interx), TROUPE_OK);
    if (!model || !interx) return 1;
    dim = troupe_model_frame_dim(model);
    CHECK(dim == 262);

    /* the skeleton as data */
    CHECK(troupe_motion_joint_count() == J && TROUPE_MOTION_JOINTS == J);
    CHECK(strcmp(troupe_motion_joint_name(0), "pelvis") == 0);
    CHECK(strcmp(troupe_motion_joint_name(21), "right_wrist") == 0);
    CHECK(troupe_motion_joint_name(22) == NULL);
    EXPECT(troupe_motion_skeleton(parents, J, offsets, 3 * J), TROUPE_OK);
    CHECK(parents[0] == -1 && parents[4] == 1 && parents[13] == 9 && parents[21] == 19);
    CHECK(offsets[3 * 1] > 0.0f && offsets[3 * 2] < 0.0f); /* left hip at +x */
    EXPECT(troupe_motion_skeleton(parents, J - 1, NULL, 0), TROUPE_ERR_SHAPE);
    EXPECT(troupe_motion_skeleton(NULL, J, NULL, 0), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_motion_skeleton(NULL, 0, offsets, 3 * J + 1), TROUPE_ERR_SHAPE);

    /* formats */
    EXPECT(troupe_joints_format_init(&format, sizeof format), TROUPE_OK);
    CHECK(format.units == TROUPE_UNITS_METERS && format.up_axis == TROUPE_UP_Y && format.fps == 30.0f);
    EXPECT(troupe_joints_format_init(&format, 4), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_joints_format_init(NULL, sizeof format), TROUPE_ERR_NULL_ARG);
    format.units = TROUPE_UNITS_CENTIMETERS;
    format.up_axis = TROUPE_UP_Z;

    clip = (float *)malloc(sizeof(float) * FRAMES * J * 3);
    features = (float *)malloc(sizeof(float) * FRAMES * dim);
    positions = (float *)malloc(sizeof(float) * FRAMES * J * 3);
    rotations = (float *)malloc(sizeof(float) * FRAMES * J * 4);
    contacts = (float *)malloc(sizeof(float) * FRAMES * 4);
    streamed = (float *)malloc(sizeof(float) * FRAMES * dim);
    if (!clip || !features || !positions || !rotations || !contacts || !streamed) return 1;
    make_clip(clip);

    /* batch: positions -> features -> positions, in the caller's world */
    EXPECT(troupe_motion_encoded_frames(model, &format, FRAMES, &frames), TROUPE_OK);
    CHECK(frames == FRAMES - 1);
    EXPECT(troupe_motion_encode(model, &format, clip, FRAMES, NULL, features, FRAMES, &n, &placement), TROUPE_OK);
    CHECK(n == FRAMES - 1);
    CHECK(fabsf(features[0]) < 1e-5f && fabsf(features[2]) < 1e-5f); /* root xz at the origin */
    CHECK(features[3] > features[6]);                                 /* left hip at +x */
    memset(&pose, 0, sizeof pose);
    pose.positions = positions;
    pose.positions_len = n * J * 3;
    pose.rotations = rotations;
    pose.rotations_len = n * J * 4;
    pose.contacts = contacts;
    pose.contacts_len = n * 4;
    EXPECT(troupe_motion_decode(model, &format, &placement, features, n, &pose), TROUPE_OK);
    for (i = 0; i < n * J * 3; i++) {
        float e = fabsf(positions[i] - clip[i]);
        if (e > worst) worst = e;
    }
    CHECK(worst < 1e-3f); /* centimetres: 1e-5 m */
    printf("positions -> features -> positions: max error %g cm\n", (double)worst);
    /* the rest pose has no local rotation; the root is turned by the walk's heading */
    CHECK(fabsf(rotations[4 * 4] - 1.0f) < 1e-5f);
    CHECK(fabsf(rotations[0] - cosf(0.15f)) < 1e-4f);

    /* bad input: a clear error, nothing written */
    sentinel = features[0];
    clip[(3 * J + 13) * 3 + 1] = NAN;
    n = 777;
    EXPECT(troupe_motion_encode(model, &format, clip, FRAMES, NULL, features, FRAMES, &n, NULL), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "frame 3") != NULL);
    CHECK(strstr(troupe_last_error_message(), "left_collar") != NULL);
    CHECK(n == 777 && features[0] == sentinel);
    make_clip(clip);
    EXPECT(troupe_motion_encode(model, &format, clip, FRAMES, NULL, features, FRAMES - 2, &n, NULL), TROUPE_ERR_BUFFER_TOO_SMALL);
    EXPECT(troupe_motion_encode(model, &format, clip, 1, NULL, features, FRAMES, &n, NULL), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "at least 2") != NULL);
    EXPECT(troupe_motion_encode(model, &format, clip, 0, NULL, features, FRAMES, &n, NULL), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_motion_encode(model, &format, NULL, FRAMES, NULL, features, FRAMES, &n, NULL), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_motion_encode(NULL, &format, clip, FRAMES, NULL, features, FRAMES, &n, NULL), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_motion_encode(model, &format, clip, (size_t)-1, NULL, features, FRAMES, &n, NULL), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_motion_encode(interx, &format, clip, FRAMES, NULL, features, FRAMES, &n, NULL), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "interhuman262") != NULL);
    format.units = 9;
    EXPECT(troupe_motion_encode(model, &format, clip, FRAMES, NULL, features, FRAMES, &n, NULL), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "units") != NULL);
    format.units = TROUPE_UNITS_CENTIMETERS;
    format.fps = 0.0f;
    EXPECT(troupe_motion_encode(model, &format, clip, FRAMES, NULL, features, FRAMES, &n, NULL), TROUPE_ERR_INVALID_ARG);
    format.fps = NAN;
    EXPECT(troupe_motion_encoded_frames(model, &format, FRAMES, &frames), TROUPE_ERR_INVALID_ARG);
    /* lengths at the edge: SIZE_MAX frames at 1 fps (x30 overflowed to 0 with TROUPE_OK) */
    format.fps = 1.0f;
    frames = 12345;
    EXPECT(troupe_motion_encoded_frames(model, &format, (size_t)-1, &frames), TROUPE_ERR_INVALID_ARG);
    CHECK(frames == 12345 && strstr(troupe_last_error_message(), "troupe encodes") != NULL);
    EXPECT(troupe_motion_encoded_frames(model, &format, 36000, &frames), TROUPE_OK);
    CHECK(frames == 1079970);
    EXPECT(troupe_motion_encoded_frames(model, &format, 36001, &frames), TROUPE_ERR_INVALID_ARG);
    format.fps = 30.0f;
    /* a placement beyond 1e6 m gave non-finite features with TROUPE_OK */
    again = placement;
    again.floor = 1e300;
    EXPECT(troupe_motion_encode(model, &format, clip, FRAMES, &again, features, FRAMES, &n, NULL), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "within 1000000 m") != NULL);
    again = placement;
    again.heading[0] = 2.0;
    EXPECT(troupe_motion_encode(model, &format, clip, FRAMES, &again, features, FRAMES, &n, NULL), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_motion_decode(model, &format, &again, features, 2, &pose), TROUPE_ERR_INVALID_ARG);
    pose.positions_len = 5;
    EXPECT(troupe_motion_decode(model, &format, &placement, features, FRAMES - 1, &pose), TROUPE_ERR_SHAPE);
    pose.positions_len = (FRAMES - 1) * J * 3;
    sentinel = positions[0];
    features[dim + 7] = INFINITY;
    EXPECT(troupe_motion_decode(model, &format, &placement, features, FRAMES - 1, &pose), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "frame 1") != NULL && positions[0] == sentinel);
    EXPECT(troupe_motion_decode(model, &format, NULL, features, FRAMES - 1, &pose), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_motion_encode(model, &format, clip, FRAMES, NULL, features, FRAMES, &n, NULL), TROUPE_OK);

    /* a stream gives the batch features one frame late */
    EXPECT(troupe_motion_stream_new(model, &format, NULL, &stream), TROUPE_OK);
    CHECK(troupe_motion_stream_latency_frames() == 1 && troupe_motion_stream_max_frames(stream) == 1);
    EXPECT(troupe_motion_stream_placement(stream, &again), TROUPE_ERR_INVALID_ARG);
    written = 0;
    for (t = 0; t < FRAMES; t++) {
        if (t == 5) {
            /* refused frames leave the stream as it was */
            EXPECT(troupe_motion_stream_push(stream, clip, 65, streamed, 1, &n), TROUPE_ERR_SHAPE);
            sentinel = clip[7];
            clip[7] = NAN;
            EXPECT(troupe_motion_stream_push(stream, clip, 66, streamed, 1, &n), TROUPE_ERR_INVALID_ARG);
            CHECK(strstr(troupe_last_error_message(), "joint 2") != NULL);
            clip[7] = sentinel;
            EXPECT(troupe_motion_stream_push(stream, clip, 66, streamed, 0, &n), TROUPE_ERR_BUFFER_TOO_SMALL);
        }
        EXPECT(troupe_motion_stream_push(stream, &clip[t * J * 3], J * 3, &streamed[written * dim], 1, &n), TROUPE_OK);
        CHECK(n == (t > 0 ? 1u : 0u));
        written += n;
    }
    CHECK(written == FRAMES - 1);
    EXPECT(troupe_motion_stream_placement(stream, &again), TROUPE_OK);
    EXPECT(troupe_motion_encode(model, &format, clip, FRAMES, &again, features, FRAMES, &n, NULL), TROUPE_OK);
    CHECK(memcmp(features, streamed, sizeof(float) * written * dim) == 0);
    EXPECT(troupe_motion_stream_reset(stream, NULL), TROUPE_OK);
    EXPECT(troupe_motion_stream_placement(stream, &again), TROUPE_ERR_INVALID_ARG);
    row = streamed;
    EXPECT(troupe_motion_stream_push(NULL, clip, 66, row, 1, &n), TROUPE_ERR_NULL_ARG);
    troupe_motion_stream_free(stream);
    EXPECT(troupe_motion_stream_new(interx, &format, NULL, &stream), TROUPE_ERR_INVALID_ARG);
    CHECK(stream == NULL);

    /* a session fed joint positions gives the poses of the feature path */
    {
        troupe_session_options options;
        troupe_session *joints = NULL, *plain = NULL;
        float *reactor = (float *)malloc(sizeof(float) * FRAMES * dim);
        float *posed = (float *)malloc(sizeof(float) * FRAMES * J * 3);
        size_t ready = 0, got = 0, n_reactor = 0, k;
        if (!reactor || !posed) return 1;
        EXPECT(troupe_session_options_init(model, &options, sizeof options), TROUPE_OK);
        options.seed = 3;
        EXPECT(troupe_session_new(model, &options, &joints), TROUPE_OK);
        EXPECT(troupe_session_new(model, &options, &plain), TROUPE_OK);
        CHECK(troupe_model_joints_latency_frames(model) == troupe_model_latency_frames(model) + 1);
        CHECK(troupe_model_joints_latency_frames(NULL) == 0);
        EXPECT(troupe_session_joints_placement(joints, &again), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_session_set_joints_format(joints, &format), TROUPE_OK);
        EXPECT(troupe_session_joints_ready_after(joints, FRAMES, &ready), TROUPE_OK);
        CHECK(ready == 20); /* 23 feature frames: 5 whole tokens of 4 */
        memset(&pose, 0, sizeof pose);
        pose.positions = posed;
        pose.positions_len = FRAMES * J * 3;
        /* refused: a buffer too small, a NaN; the session stays as it was */
        EXPECT(troupe_session_step_joints(joints, clip, FRAMES, &pose, ready - 1, &got), TROUPE_ERR_BUFFER_TOO_SMALL);
        pose.positions_len = 3;
        EXPECT(troupe_session_step_joints(joints, clip, FRAMES, &pose, FRAMES, &got), TROUPE_ERR_SHAPE);
        pose.positions_len = FRAMES * J * 3;
        clip[(9 * J + 4) * 3] = INFINITY;
        EXPECT(troupe_session_step_joints(joints, clip, FRAMES, &pose, FRAMES, &got), TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "frame 9") != NULL);
        make_clip(clip);
        EXPECT(troupe_session_step_joints(joints, clip, FRAMES, &pose, FRAMES, &got), TROUPE_OK);
        CHECK(got == ready);
        /* the same through features: encode with the session's placement, step, decode */
        EXPECT(troupe_session_joints_placement(joints, &again), TROUPE_OK);
        EXPECT(troupe_motion_encode(model, &format, clip, FRAMES, &again, features, FRAMES, &n, NULL), TROUPE_OK);
        EXPECT(troupe_session_step(plain, features, n, reactor, FRAMES, &n_reactor), TROUPE_OK);
        CHECK(n_reactor == got);
        pose.positions = positions;
        pose.positions_len = n_reactor * J * 3;
        pose.rotations = NULL;
        pose.rotations_len = 0;
        pose.contacts = NULL;
        pose.contacts_len = 0;
        EXPECT(troupe_motion_decode(model, &format, &again, reactor, n_reactor, &pose), TROUPE_OK);
        worst = 0.0f;
        for (k = 0; k < n_reactor * J * 3; k++) {
            float e = fabsf(positions[k] - posed[k]);
            if (e > worst) worst = e;
        }
        CHECK(worst == 0.0f);
        EXPECT(troupe_session_step_joints(NULL, clip, 1, &pose, 4, &got), TROUPE_ERR_NULL_ARG);
        troupe_session_free(joints);
        /* a stream whose frames carry no joints the motion stages know (InterX's) */
        EXPECT(troupe_session_new(interx, NULL, &joints), TROUPE_OK);
        EXPECT(troupe_session_set_joints_format(joints, &format), TROUPE_ERR_UNSUPPORTED);
        CHECK(strstr(troupe_last_error_message(), "interx336") != NULL);
        troupe_session_free(joints);
        troupe_session_free(plain);
        free(reactor);
        free(posed);
    }
    troupe_motion_stream_free(NULL);

    /* BVH out and back in */
    if (argc > 3) {
        char path[1024], bad[1024];
        troupe_bvh *bvh = NULL;
        troupe_joints_format read_format;
        const char *names[2] = {"actor", "reactor"};
        const char *self = argv[0];
        const char *c;
        float *back = (float *)malloc(sizeof(float) * FRAMES * J * 3);
        FILE *f;
        for (c = argv[0]; *c; c++) /* the program's own name, after either separator */
            if (*c == '/' || *c == '\\') self = c + 1;
        if (!back) return 1;
        /* named after this binary: the C, C++ and valgrind runs may share the directory */
        snprintf(path, sizeof path, "%s/%s.bvh", argv[3], self);
        snprintf(bad, sizeof bad, "%s/%s_bad.bvh", argv[3], self);
        EXPECT(troupe_bvh_write(path, clip, 1, FRAMES, &format, names, TROUPE_UNITS_CENTIMETERS, 1), TROUPE_OK);
        EXPECT(troupe_bvh_read(path, NULL, TROUPE_UNITS_AUTO, &bvh), TROUPE_OK);
        CHECK(troupe_bvh_frames(bvh) == FRAMES && troupe_bvh_frames(NULL) == 0);
        EXPECT(troupe_bvh_format(bvh, &read_format, sizeof read_format), TROUPE_OK);
        CHECK(read_format.units == TROUPE_UNITS_CENTIMETERS && read_format.up_axis == TROUPE_UP_Y);
        CHECK(read_format.fps == 30.0f); /* Frame Time 0.03333333 read as the 30 fps meant */
        EXPECT(troupe_bvh_positions(bvh, back, FRAMES * J * 3 - 1), TROUPE_ERR_SHAPE);
        EXPECT(troupe_bvh_positions(bvh, back, FRAMES * J * 3), TROUPE_OK);
        /* the file is Y up; the clip Z up: BVH (x, y, z) is our world's (x, -z, y) */
        worst = 0.0f;
        for (i = 0; i < FRAMES * J; i++) {
            float e = fabsf(back[3 * i] - clip[3 * i]) + fabsf(-back[3 * i + 2] - clip[3 * i + 1]) +
                      fabsf(back[3 * i + 1] - clip[3 * i + 2]);
            if (e > worst) worst = e;
        }
        CHECK(worst < 1e-2f); /* centimetres */
        printf("BVH written and read back: max error %g cm\n", (double)worst);
        troupe_bvh_free(bvh);
        troupe_bvh_free(NULL);
        /* two unnamed people in one scene */
        {
            float *pair = (float *)malloc(sizeof(float) * 2 * FRAMES * J * 3);
            if (!pair) return 1;
            memcpy(pair, clip, sizeof(float) * FRAMES * J * 3);
            memcpy(pair + FRAMES * J * 3, clip, sizeof(float) * FRAMES * J * 3);
            EXPECT(troupe_bvh_write(path, pair, 2, FRAMES, &format, NULL, TROUPE_UNITS_CENTIMETERS, 1), TROUPE_OK);
            EXPECT(troupe_bvh_read(path, NULL, TROUPE_UNITS_AUTO, &bvh), TROUPE_ERR_INVALID_ARG); /* person1_pelvis... */
            CHECK(strstr(troupe_last_error_message(), "pelvis") != NULL);
            free(pair);
        }
        EXPECT(troupe_bvh_write(path, features, 0, FRAMES, &format, NULL, TROUPE_UNITS_CENTIMETERS, 1), TROUPE_ERR_INVALID_ARG);
        clip[5] = NAN;
        EXPECT(troupe_bvh_write(bad, clip, 1, FRAMES, &format, names, TROUPE_UNITS_CENTIMETERS, 1), TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "person 0, frame 0, joint 1 (left_hip)") != NULL);
        f = fopen(bad, "rb");
        CHECK(f == NULL); /* nothing written */
        if (f) fclose(f);
        make_clip(clip);
        EXPECT(troupe_bvh_write(path, clip, 1, FRAMES, &format, names, 77, 1), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_bvh_write("/nonexistent/dir/x.bvh", clip, 1, FRAMES, &format, names, TROUPE_UNITS_CENTIMETERS, 1), TROUPE_ERR_IO);
        /* bad files: missing, malformed (naming the line), a rig without the t2m-22 joints */
        EXPECT(troupe_bvh_read("/nonexistent/x.bvh", NULL, TROUPE_UNITS_AUTO, &bvh), TROUPE_ERR_IO);
        CHECK(bvh == NULL);
        f = fopen(bad, "wb");
        if (f) {
            fputs("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Xposition Yposition Qrotation\n}\n", f);
            fclose(f);
        }
        EXPECT(troupe_bvh_read(bad, NULL, TROUPE_UNITS_AUTO, &bvh), TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), ":5:") != NULL);
        CHECK(strstr(troupe_last_error_message(), "Qrotation") != NULL);
        f = fopen(bad, "wb");
        if (f) {
            fputs("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Xposition Yposition Zposition\n}\n"
                  "MOTION\nFrames: 1\nFrame Time: 0.0333\n0 0 0\n", f);
            fclose(f);
        }
        EXPECT(troupe_bvh_read(bad, NULL, TROUPE_UNITS_AUTO, &bvh), TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "left_hip") != NULL);
        EXPECT(troupe_bvh_read(bad, "{\"not\": \"a map\"}", TROUPE_UNITS_AUTO, &bvh), TROUPE_ERR_INVALID_ARG);
        /* a truncated file, and one declaring an absurd number of frames: refused, nothing allocated */
        f = fopen(bad, "wb");
        if (f) {
            fputs("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Xposition Yposition Zposition\n}\n"
                  "MOTION\nFrames: 3\nFrame Time: 0.0333\n0 0 0\n1 1 1\n2 2\n", f);
            fclose(f);
        }
        EXPECT(troupe_bvh_read(bad, NULL, TROUPE_UNITS_AUTO, &bvh), TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "truncated") != NULL);
        CHECK(strstr(troupe_last_error_message(), "frame 2") != NULL);
        f = fopen(bad, "wb");
        if (f) {
            fputs("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Xposition Yposition Zposition\n}\n"
                  "MOTION\nFrames: 1000000000000\nFrame Time: 0.0333\n0 0 0\n", f);
            fclose(f);
        }
        EXPECT(troupe_bvh_read(bad, NULL, TROUPE_UNITS_AUTO, &bvh), TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "Frames") != NULL);
        CHECK(bvh == NULL);
        EXPECT(troupe_bvh_read(bad, NULL, 12345, &bvh), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_bvh_read(NULL, NULL, TROUPE_UNITS_AUTO, &bvh), TROUPE_ERR_NULL_ARG);
        /* poses as JSON for robots */
        snprintf(path, sizeof path, "%s/%s.json", argv[3], self);
        EXPECT(troupe_motion_write_json(path, clip, 1, FRAMES, &format, names), TROUPE_OK);
        f = fopen(path, "rb");
        CHECK(f != NULL);
        if (f) {
            char head[64] = {0};
            CHECK(fread(head, 1, sizeof head - 1, f) > 0 && strstr(head, "\"troupe-poses\"") != NULL);
            fclose(f);
        }
        remove(path);
        clip[(2 * J + 5) * 3] = NAN;
        EXPECT(troupe_motion_write_json(path, clip, 1, FRAMES, &format, names), TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "person 0, frame 2, joint 5") != NULL);
        f = fopen(path, "rb");
        CHECK(f == NULL);
        if (f) fclose(f);
        make_clip(clip);
        EXPECT(troupe_motion_write_json(NULL, clip, 1, FRAMES, &format, names), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_motion_write_json(path, clip, 1, 0, &format, names), TROUPE_ERR_INVALID_ARG);
        remove(bad);
        free(back);
    }

    free(clip);
    free(features);
    free(positions);
    free(rotations);
    free(contacts);
    free(streamed);
    troupe_model_free(model);
    troupe_model_free(interx);
    printf("sanitizer: %s\n", TROUPE_TEST_SANITIZER);
    printf("motion: %d passed, %d failed\n", passed, failed);
    return failed != 0;
}

/* ABI test of the rig functions (rigs from BVH and JSON, the streaming retargeter, glTF and BVH
 * files on a rig) through include/troupe.h only. Compiled as C99 and C++17 with the strict
 * flags (tests/c_abi.rs). Usage: rig MIXAMO_BVH SCRATCH_DIR */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "troupe.h"
#include "check.h"

#define J 22
#define FRAMES 40

/* A z-up centimetre world: canonical (x, y, z) metres -> (100 x, -100 z, 100 y). */
static void to_world(const float c[3], float w[3]) {
    w[0] = 100.0f * c[0];
    w[1] = -100.0f * c[2];
    w[2] = 100.0f * c[1];
}

/* troupe's neutral body at rest, its rest positions (canonical metres) in `rest`. */
static void rest_pose(float rest[3 * J], int parents[J], float offsets[3 * J]) {
    size_t j;
    troupe_motion_skeleton(parents, J, offsets, 3 * J);
    for (j = 0; j < J; j++) {
        int d;
        for (d = 0; d < 3; d++)
            rest[3 * j + d] = offsets[3 * j + d] + (parents[j] >= 0 ? rest[3 * parents[j] + d] : 0.0f);
    }
}

/* The rest pose gliding forward 1 cm per frame, in the z-up centimetre world. */
static void make_clip(float *positions) {
    int parents[J];
    float offsets[3 * J], rest[3 * J];
    size_t t, j;
    rest_pose(rest, parents, offsets);
    for (t = 0; t < FRAMES; t++)
        for (j = 0; j < J; j++) {
            float c[3];
            c[0] = rest[3 * j] + 0.2f;
            c[1] = rest[3 * j + 1];
            c[2] = rest[3 * j + 2] + 0.01f * (float)t;
            to_world(c, &positions[(t * J + j) * 3]);
        }
}

/* troupe's own body as a rig JSON document in centimetres, Z up. */
static char *own_rig_json(void) {
    int parents[J];
    float offsets[3 * J], rest[3 * J];
    size_t j, at = 0, cap = 8192;
    char *text = (char *)malloc(cap);
    rest_pose(rest, parents, offsets);
    at += (size_t)snprintf(text + at, cap - at,
                           "{\"name\": \"own\", \"units\": \"centimeters\", \"up\": \"z\", \"joints\": [");
    for (j = 0; j < J; j++) {
        float w[3];
        to_world(&offsets[3 * j], w);
        at += (size_t)snprintf(text + at, cap - at,
                               "%s{\"name\": \"%s\", \"parent\": %s%s%s, \"offset\": [%.6f, %.6f, %.6f]}",
                               j ? ", " : "", troupe_motion_joint_name(j), parents[j] >= 0 ? "\"" : "",
                               parents[j] >= 0 ? troupe_motion_joint_name((size_t)parents[j]) : "null",
                               parents[j] >= 0 ? "\"" : "", w[0], w[1], w[2]);
    }
    snprintf(text + at, cap - at, "]}");
    return text;
}

/* Writes troupe's body as a BVH hierarchy without spine2 and without toes (the ankles end in
 * end sites where the toes were), then two frames of zeros: a rig lacking three t2m-22 joints. */
static void write_joint(FILE *f, const int parents[J], const float offsets[3 * J], int j, const float *extra) {
    int c;
    float o[3];
    o[0] = offsets[3 * j] + (extra ? extra[0] : 0.0f);
    o[1] = offsets[3 * j + 1] + (extra ? extra[1] : 0.0f);
    o[2] = offsets[3 * j + 2] + (extra ? extra[2] : 0.0f);
    fprintf(f, "%s %s\n{\nOFFSET %f %f %f\nCHANNELS %s\n", j ? "JOINT" : "ROOT", troupe_motion_joint_name((size_t)j),
            100 * o[0], 100 * o[1], 100 * o[2],
            j ? "3 Zrotation Yrotation Xrotation" : "6 Xposition Yposition Zposition Zrotation Yrotation Xrotation");
    if (j == 7 || j == 8) {
        const float *toe = &offsets[3 * (j + 3)];
        fprintf(f, "End Site\n{\nOFFSET %f %f %f\n}\n", 100 * toe[0], 100 * toe[1], 100 * toe[2]);
    }
    for (c = 0; c < J; c++) {
        if (parents[c] != j || c == 10 || c == 11) continue;
        if (c == 6) { /* spine2 skipped: its child hangs from spine1 */
            write_joint(f, parents, offsets, 9, &offsets[3 * 6]);
            continue;
        }
        write_joint(f, parents, offsets, c, NULL);
    }
    if (j == 15 || j == 20 || j == 21) fprintf(f, "End Site\n{\nOFFSET 0 5 0\n}\n");
    fprintf(f, "}\n");
}

static int write_rig_without_toes(const char *path) {
    int parents[J], i;
    float offsets[3 * J], rest[3 * J];
    FILE *f = fopen(path, "w");
    if (!f) return 0;
    rest_pose(rest, parents, offsets);
    fprintf(f, "HIERARCHY\n");
    write_joint(f, parents, offsets, 0, NULL);
    fprintf(f, "MOTION\nFrames: 2\nFrame Time: 0.0333333\n");
    for (i = 0; i < 2; i++) {
        int k;
        for (k = 0; k < 6 + 3 * (J - 4); k++) fprintf(f, "0 ");
        fprintf(f, "\n");
    }
    fclose(f);
    return 1;
}

int main(int argc, char **argv) {
    troupe_rig *mixamo = NULL, *own = NULL, *bad = NULL;
    troupe_rig_retargeter *stream = NULL, *fresh = NULL;
    troupe_joints_format format;
    float *clip, nan_frame[3 * J], root[3], root_fresh[3], *rotations, *rotations_fresh;
    size_t joints, root_joint = 99, t, i;
    char path[1024], *json;
    FILE *f;
    char magic[4];

    if (argc < 3) {
        fprintf(stderr, "usage: %s MIXAMO_BVH SCRATCH_DIR\n", argv[0]);
        return 2;
    }
    clip = (float *)malloc(sizeof(float) * FRAMES * J * 3);
    make_clip(clip);
    EXPECT(troupe_joints_format_init(&format, sizeof format), TROUPE_OK);
    format.units = TROUPE_UNITS_CENTIMETERS;
    format.up_axis = TROUPE_UP_Z;

    /* A real rig from BVH, its joints named. */
    EXPECT(troupe_rig_from_bvh(argv[1], TROUPE_UNITS_AUTO, TROUPE_RIG_ZERO_POSE, NULL, &mixamo), TROUPE_OK);
    joints = troupe_rig_joint_count(mixamo);
    CHECK(joints > J);
    CHECK(strcmp(troupe_rig_joint_name(mixamo, 0), "mixamorig:Hips") == 0);
    CHECK(troupe_rig_joint_name(mixamo, joints) == NULL);
    CHECK(troupe_rig_joint_name(NULL, 0) == NULL);
    CHECK(troupe_rig_joint_count(NULL) == 0);
    bad = (troupe_rig *)&bad; /* not NULL: must be reset on failure */
    EXPECT(troupe_rig_from_bvh(NULL, TROUPE_UNITS_AUTO, TROUPE_RIG_ZERO_POSE, NULL, &bad), TROUPE_ERR_NULL_ARG);
    CHECK(bad == NULL);
    EXPECT(troupe_rig_from_bvh("/nonexistent.bvh", TROUPE_UNITS_AUTO, TROUPE_RIG_ZERO_POSE, NULL, &bad), TROUPE_ERR_IO);
    EXPECT(troupe_rig_from_bvh(argv[1], 77, TROUPE_RIG_ZERO_POSE, NULL, &bad), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_rig_from_bvh(argv[1], TROUPE_UNITS_AUTO, 1000000, NULL, &bad), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "frame 1000000") != NULL);
    EXPECT(troupe_rig_from_bvh(argv[1], TROUPE_UNITS_AUTO, 0, "{\"skeleton\": \"t2m22\"}", &bad), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_rig_from_json("{\"name\": \"x\", \"joints\": []}", NULL, &bad), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "0 joints") != NULL);
    CHECK(bad == NULL);

    /* troupe's own body in cm, Z up: the retargeted root is the clip's pelvis. */
    json = own_rig_json();
    EXPECT(troupe_rig_from_json(json, NULL, &own), TROUPE_OK);
    free(json);
    CHECK(troupe_rig_joint_count(own) == J);
    EXPECT(troupe_rig_retargeter_new(own, &format, 0, &stream), TROUPE_OK);
    rotations = (float *)malloc(sizeof(float) * 4 * J);
    for (t = 0; t < FRAMES; t++) {
        float worst = 0.0f;
        EXPECT(troupe_rig_retarget_push(stream, &clip[t * J * 3], 3 * J, rotations, 4 * J, root, &root_joint), TROUPE_OK);
        for (i = 0; i < 3; i++) worst = fmaxf(worst, fabsf(root[i] - clip[t * J * 3 + i]));
        CHECK(root_joint == 0);
        CHECK(worst < 1e-3f);
        for (i = 0; i < J; i++) {
            const float *q = &rotations[4 * i];
            CHECK(fabsf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1.0f) < 1e-4f);
        }
    }
    /* The whole clip at once: the same roots; wrong lengths refused. */
    {
        float *all = (float *)malloc(sizeof(float) * FRAMES * 4 * J), roots[3 * FRAMES];
        float worst = 0.0f;
        EXPECT(troupe_rig_retarget_clip(own, clip, FRAMES, &format, 0, all, FRAMES * 4 * J, roots, 3 * FRAMES, &root_joint), TROUPE_OK);
        for (t = 0; t < FRAMES; t++)
            for (i = 0; i < 3; i++) worst = fmaxf(worst, fabsf(roots[3 * t + i] - clip[t * J * 3 + i]));
        CHECK(worst < 1e-3f);
        CHECK(root_joint == 0);
        EXPECT(troupe_rig_retarget_clip(own, clip, FRAMES, &format, 0, all, FRAMES * 4 * J - 1, roots, 3 * FRAMES, &root_joint), TROUPE_ERR_SHAPE);
        EXPECT(troupe_rig_retarget_clip(own, clip, 0, &format, 0, all, 0, roots, 0, &root_joint), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_rig_retarget_clip(NULL, clip, FRAMES, &format, 0, all, FRAMES * 4 * J, roots, 3 * FRAMES, &root_joint), TROUPE_ERR_NULL_ARG);
        free(all);
    }
    /* Bad input is refused and leaves the stream as it was: the next push equals a fresh
     * retargeter's after the same frames. */
    memcpy(nan_frame, clip, sizeof nan_frame);
    nan_frame[5] = NAN;
    EXPECT(troupe_rig_retarget_push(stream, nan_frame, 3 * J, rotations, 4 * J, root, &root_joint), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_rig_retarget_push(stream, clip, 3 * J - 1, rotations, 4 * J, root, &root_joint), TROUPE_ERR_SHAPE);
    EXPECT(troupe_rig_retarget_push(stream, clip, 3 * J, rotations, 4 * J - 4, root, &root_joint), TROUPE_ERR_SHAPE);
    EXPECT(troupe_rig_retarget_push(stream, clip, 3 * J, NULL, 4 * J, root, &root_joint), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_rig_retarget_push(NULL, clip, 3 * J, rotations, 4 * J, root, &root_joint), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_rig_retarget_reset(stream), TROUPE_OK);
    EXPECT(troupe_rig_retargeter_new(own, &format, 0, &fresh), TROUPE_OK);
    rotations_fresh = (float *)malloc(sizeof(float) * 4 * J);
    for (t = 0; t < 3; t++) {
        EXPECT(troupe_rig_retarget_push(stream, &clip[t * J * 3], 3 * J, rotations, 4 * J, root, &root_joint), TROUPE_OK);
        EXPECT(troupe_rig_retarget_push(fresh, &clip[t * J * 3], 3 * J, rotations_fresh, 4 * J, root_fresh, &root_joint), TROUPE_OK);
    }
    CHECK(memcmp(rotations, rotations_fresh, sizeof(float) * 4 * J) == 0);
    CHECK(memcmp(root, root_fresh, sizeof root) == 0);
    troupe_rig_retargeter_free(fresh);
    EXPECT(troupe_rig_retargeter_new(own, &format, 0x100, &fresh), TROUPE_ERR_INVALID_ARG);
    CHECK(fresh == NULL);
    troupe_rig_retargeter_free(stream);
    troupe_rig_retargeter_free(NULL);

    /* The Mixamo rig: a streaming retargeter, a glTF file of two people, a BVH file. */
    EXPECT(troupe_rig_retargeter_new(mixamo, &format, TROUPE_RETARGET_NO_FOOT_LOCK, &stream), TROUPE_OK);
    free(rotations);
    rotations = (float *)malloc(sizeof(float) * 4 * joints);
    EXPECT(troupe_rig_retarget_push(stream, clip, 3 * J, rotations, 4 * joints, root, &root_joint), TROUPE_OK);
    CHECK(root_joint == 0);
    /* Which Mixamo joint each t2m-22 joint drives: the left wrist is LeftHand. */
    {
        int64_t mapping[22];
        EXPECT(troupe_rig_retargeter_mapping(stream, mapping, 22), TROUPE_OK);
        CHECK(mapping[20] >= 0 && strstr(troupe_rig_joint_name(mixamo, (size_t)mapping[20]), "LeftHand") != NULL);
        CHECK(mapping[0] >= 0 && strstr(troupe_rig_joint_name(mixamo, (size_t)mapping[0]), "Hips") != NULL);
        EXPECT(troupe_rig_retargeter_mapping(stream, mapping, 21), TROUPE_ERR_BUFFER_TOO_SMALL);
        EXPECT(troupe_rig_retargeter_mapping(stream, NULL, 22), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_rig_retargeter_mapping(NULL, mapping, 22), TROUPE_ERR_NULL_ARG);
    }
    troupe_rig_retargeter_free(stream);
    {
        float *two = (float *)malloc(sizeof(float) * 2 * FRAMES * J * 3);
        const char *names[2] = {"actor", NULL};
        memcpy(two, clip, sizeof(float) * FRAMES * J * 3);
        for (i = 0; i < FRAMES * J; i++) {
            two[FRAMES * J * 3 + 3 * i] = clip[3 * i] + 150.0f;
            two[FRAMES * J * 3 + 3 * i + 1] = clip[3 * i + 1];
            two[FRAMES * J * 3 + 3 * i + 2] = clip[3 * i + 2];
        }
        snprintf(path, sizeof path, "%s/rig_c.glb", argv[2]);
        EXPECT(troupe_gltf_write(path, mixamo, two, 2, FRAMES, &format, names, 0), TROUPE_OK);
        f = fopen(path, "rb");
        CHECK(f != NULL && fread(magic, 1, 4, f) == 4 && memcmp(magic, "glTF", 4) == 0);
        if (f) fclose(f);
        {
            /* The file's first skin read back as a rig: the Mixamo rig's joints. */
            troupe_rig *back = NULL;
            EXPECT(troupe_rig_from_gltf(path, 0, NULL, &back), TROUPE_OK);
            CHECK(troupe_rig_joint_count(back) == joints);
            CHECK(strcmp(troupe_rig_joint_name(back, 0), "actor_mixamorig:Hips") == 0);
            troupe_rig_free(back);
            EXPECT(troupe_rig_from_gltf(path, 5, NULL, &back), TROUPE_ERR_INVALID_ARG);
            CHECK(back == NULL);
            EXPECT(troupe_rig_from_gltf("/nonexistent.glb", 0, NULL, &back), TROUPE_ERR_IO);
            EXPECT(troupe_rig_from_gltf(argv[1], 0, NULL, &back), TROUPE_ERR_INVALID_ARG);
        }
        snprintf(path, sizeof path, "%s/own_c.glb", argv[2]);
        EXPECT(troupe_gltf_write(path, NULL, two, 2, FRAMES, &format, NULL, TROUPE_GLTF_NO_BODIES), TROUPE_OK);
        EXPECT(troupe_gltf_write(path, mixamo, two, 0, FRAMES, &format, NULL, 0), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_gltf_write(path, mixamo, two, 2, FRAMES, &format, NULL, 0x100), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_gltf_write(argv[2], mixamo, two, 2, FRAMES, &format, NULL, 0), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_gltf_write(NULL, mixamo, two, 2, FRAMES, &format, NULL, 0), TROUPE_ERR_NULL_ARG);
        {
            /* People of different lengths, each its own clip: nothing trimmed. */
            troupe_person_clip people[2];
            people[0].name = "actor";
            people[0].positions = two;
            people[0].n_frames = FRAMES;
            people[1].name = NULL;
            people[1].positions = two + FRAMES * J * 3;
            people[1].n_frames = FRAMES - 3;
            snprintf(path, sizeof path, "%s/uneven_c.glb", argv[2]);
            EXPECT(troupe_gltf_write_people(path, mixamo, people, 2, &format, 0), TROUPE_OK);
            people[1].n_frames = 0;
            EXPECT(troupe_gltf_write_people(path, mixamo, people, 2, &format, 0), TROUPE_ERR_INVALID_ARG);
            people[1].positions = NULL;
            people[1].n_frames = 4;
            EXPECT(troupe_gltf_write_people(path, mixamo, people, 2, &format, 0), TROUPE_ERR_NULL_ARG);
            EXPECT(troupe_gltf_write_people(path, mixamo, NULL, 2, &format, 0), TROUPE_ERR_NULL_ARG);
        }
        two[7] = INFINITY;
        EXPECT(troupe_gltf_write(path, mixamo, two, 2, FRAMES, &format, NULL, 0), TROUPE_ERR_INVALID_ARG);
        free(two);
    }
    {
        troupe_bvh *back = NULL;
        snprintf(path, sizeof path, "%s/rig_c.bvh", argv[2]);
        EXPECT(troupe_rig_bvh_write(path, mixamo, clip, FRAMES, &format, TROUPE_UNITS_CENTIMETERS, 0), TROUPE_OK);
        EXPECT(troupe_bvh_read(path, NULL, TROUPE_UNITS_CENTIMETERS, &back), TROUPE_OK);
        CHECK(troupe_bvh_frames(back) == FRAMES);
        troupe_bvh_free(back);
        EXPECT(troupe_rig_bvh_write(path, NULL, clip, FRAMES, &format, TROUPE_UNITS_CENTIMETERS, 0), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_rig_bvh_write(path, mixamo, clip, FRAMES, &format, 9, 0), TROUPE_ERR_INVALID_ARG);
    }
    {
        /* FBX on the rig: read back as a take and as a rig of the same joints. */
        troupe_bvh *back = NULL;
        troupe_rig *again = NULL;
        snprintf(path, sizeof path, "%s/rig_c.fbx", argv[2]);
        EXPECT(troupe_rig_fbx_write(path, mixamo, clip, FRAMES, &format, TROUPE_UNITS_CENTIMETERS, 0), TROUPE_OK);
        EXPECT(troupe_bvh_read(path, NULL, TROUPE_UNITS_AUTO, &back), TROUPE_OK);
        CHECK(troupe_bvh_frames(back) == FRAMES);
        troupe_bvh_free(back);
        EXPECT(troupe_rig_from_bvh(path, TROUPE_UNITS_AUTO, TROUPE_RIG_ZERO_POSE, NULL, &again), TROUPE_OK);
        CHECK(troupe_rig_joint_count(again) == troupe_rig_joint_count(mixamo));
        troupe_rig_free(again);
        EXPECT(troupe_rig_fbx_write(path, NULL, clip, FRAMES, &format, TROUPE_UNITS_CENTIMETERS, 0), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_rig_fbx_write(path, mixamo, clip, FRAMES, &format, 9, 0), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_rig_fbx_write(NULL, mixamo, clip, FRAMES, &format, TROUPE_UNITS_CENTIMETERS, 0), TROUPE_ERR_NULL_ARG);
    }
    {
        /* A rig lacking joints is read with them placed from the others, and says which. */
        troupe_bvh *take = NULL;
        snprintf(path, sizeof path, "%s/no_toes_c.bvh", argv[2]);
        CHECK(write_rig_without_toes(path));
        EXPECT(troupe_bvh_read(path, NULL, TROUPE_UNITS_CENTIMETERS, &take), TROUPE_OK);
        CHECK(troupe_bvh_frames(take) == 2);
        CHECK(strstr(troupe_bvh_inferred(take), "spine2 at") != NULL);
        CHECK(strstr(troupe_bvh_inferred(take), "left_foot three quarters of the way from left_ankle") != NULL);
        CHECK(troupe_bvh_inferred(NULL) == NULL);
        /* Which rig joint each t2m-22 joint is read from: none for the toes it placed. */
        CHECK(troupe_bvh_joint_source(take, 10) == NULL); /* left_foot */
        CHECK(troupe_bvh_joint_source(take, 0) != NULL);
        CHECK(troupe_bvh_joint_source(take, 22) == NULL && troupe_bvh_joint_source(NULL, 0) == NULL);
        troupe_bvh_free(take);
        EXPECT(troupe_bvh_read(argv[1], NULL, TROUPE_UNITS_AUTO, &take), TROUPE_OK);
        CHECK(strcmp(troupe_bvh_inferred(take), "") == 0);
        CHECK(troupe_bvh_joint_source(take, 20) != NULL && strstr(troupe_bvh_joint_source(take, 20), "LeftHand") != NULL);
        troupe_bvh_free(take);
    }
    troupe_rig_free(mixamo);
    troupe_rig_free(own);
    troupe_rig_free(NULL);
    free(rotations);
    free(rotations_fresh);
    free(clip);
    printf("rig: %d passed, %d failed (sanitizer: %s)\n", passed, failed, TROUPE_TEST_SANITIZER);
    return failed ? 1 : 0;
}

/* A program written and compiled against the 0.2.0 header (abi/0.2.0/troupe.h, frozen as it
 * was released) and run against this library: the compatibility promise of docs/ABI.md for what
 * 0.2 added (tests/abi.rs). It uses only what that header declares, under the names it has:
 * ARMFlow's own session options, the capabilities a stream reports, and the motion stages every
 * streaming family takes (joints in, poses out, the guard, the smoothing, the foot lock).
 * Usage: abi_0_2 ARMFLOW_DIR ARFLOW_ONLINE_DIR MAGNET_DIR */
#include "troupe.h"
#include "check.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define JOINTS 66 /* 22 joints, xyz */

static int all_finite(const float *v, size_t n) {
    size_t i;
    for (i = 0; i < n; i++)
        if (!isfinite(v[i])) return 0;
    return 1;
}

/* A person walking slowly along x, as joint positions (metres, Y up). */
static void walker(float *joints, size_t frames, float x0) {
    size_t t, j;
    for (t = 0; t < frames; t++)
        for (j = 0; j < 22; j++) {
            float *p = joints + t * JOINTS + j * 3;
            p[0] = x0 + 0.01f * (float)t + 0.05f * (float)(j % 3);
            p[1] = 0.05f + 0.08f * (float)j;
            p[2] = 0.03f * (float)(j % 5);
        }
}

/* Streams `frames` joint frames one at a time; returns the poses that came back, all finite. */
static size_t stream_joints(troupe_session *s, const float *joints, size_t frames) {
    static float posed[64 * JOINTS];
    troupe_pose_buffers pose;
    size_t t, ready = 0, got = 0, total = 0;
    memset(&pose, 0, sizeof pose);
    pose.positions = posed;
    pose.positions_len = 64 * JOINTS;
    for (t = 0; t < frames; t++) {
        EXPECT(troupe_session_joints_ready_after(s, 1, &ready), TROUPE_OK);
        EXPECT(troupe_session_step_joints(s, joints + t * JOINTS, 1, &pose, 64, &got), TROUPE_OK);
        CHECK(got == ready && all_finite(posed, got * JOINTS));
        total += got;
    }
    return total;
}

static void armflow(const char *dir) {
    troupe_model *model = NULL;
    troupe_session *s = NULL;
    troupe_armflow_session_options arm;
    uint32_t caps = 0;
    float *joints, actor_noise[64], reactor_noise[64];
    size_t latent, i;

    EXPECT(troupe_model_load_file(dir, &model), TROUPE_OK);
    if (!model) return;
    CHECK(strcmp(troupe_model_family(model), "armflow") == 0);
    /* The struct sizes this program was compiled with are the library's. */
    CHECK(troupe_session_options_size() == sizeof(troupe_session_options));
    CHECK(troupe_armflow_session_options_size() == sizeof(troupe_armflow_session_options));
    CHECK(troupe_armflow_clip_options_size() == sizeof(troupe_armflow_clip_options));

    EXPECT(troupe_armflow_session_options_init(model, &arm, sizeof arm), TROUPE_OK);
    arm.cfg_scale = 2.0f;
    EXPECT(troupe_armflow_session_new(model, NULL, &arm, &s), TROUPE_OK);
    if (!s) return;
    EXPECT(troupe_session_capabilities(s, &caps), TROUPE_OK);
    CHECK((caps & TROUPE_CAP_CONDITION) && (caps & TROUPE_CAP_CFG_SCALE) &&
          (caps & TROUPE_CAP_QUEUED_NORMALS));
    latent = troupe_model_latent_dim(model);
    CHECK(latent <= 64);
    for (i = 0; i < latent; i++) actor_noise[i] = reactor_noise[i] = 0.1f * (float)i - 0.5f;
    EXPECT(troupe_armflow_session_queue_noise(s, actor_noise, reactor_noise, latent), TROUPE_OK);
    EXPECT(troupe_session_set_penetration_guard(s, 1, 0.05f, 2.0f), TROUPE_OK);
    EXPECT(troupe_session_set_root_smoothing(s, 1, 0.1f), TROUPE_OK);
    EXPECT(troupe_session_set_foot_lock(s, 1, 0.5f, 4, 0.25f), TROUPE_OK);
    joints = malloc(40 * JOINTS * sizeof *joints);
    walker(joints, 40, 0.0f);
    CHECK(stream_joints(s, joints, 40) + troupe_model_joints_latency_frames(model) >= 40);
    free(joints);
    troupe_session_free(s);
    troupe_model_free(model);
}

static void arflow_online(const char *dir) {
    troupe_model *model = NULL;
    troupe_session *s = NULL;
    uint32_t caps = 99;
    float *joints;

    EXPECT(troupe_model_load_file(dir, &model), TROUPE_OK);
    if (!model) return;
    CHECK(strcmp(troupe_model_family(model), "arflow") == 0);
    EXPECT(troupe_session_new(model, NULL, &s), TROUPE_OK);
    if (!s) return;
    EXPECT(troupe_session_capabilities(s, &caps), TROUPE_OK);
    CHECK((caps & TROUPE_CAP_CFG_SCALE) == 0 && (caps & TROUPE_CAP_PROMPT) == 0);
    EXPECT(troupe_session_set_cfg_scale(s, 2.0f), TROUPE_ERR_UNSUPPORTED);
    EXPECT(troupe_session_set_penetration_guard(s, 1, 0.5f, 10.0f), TROUPE_OK);
    joints = malloc(40 * JOINTS * sizeof *joints);
    walker(joints, 40, 0.0f);
    CHECK(stream_joints(s, joints, 40) > 0);
    free(joints);
    troupe_session_free(s);
    troupe_model_free(model);
}

static void magnet(const char *dir) {
    troupe_model *model = NULL;
    troupe_session *s = NULL;
    troupe_armflow_session_options arm;

    EXPECT(troupe_model_load_file(dir, &model), TROUPE_OK);
    if (!model) return;
    CHECK(strcmp(troupe_model_family(model), "magnet") == 0);
    EXPECT(troupe_armflow_session_options_init(model, &arm, sizeof arm), TROUPE_ERR_UNSUPPORTED);
    EXPECT(troupe_armflow_session_new(model, NULL, NULL, &s), TROUPE_ERR_UNSUPPORTED);
    CHECK(s == NULL);
    EXPECT(troupe_session_new(model, NULL, &s), TROUPE_OK);
    if (!s) return;
    /* The foot lock needs contact labels a MAGNet partner's frames do not carry. */
    EXPECT(troupe_session_set_foot_lock(s, 1, 0.5f, 4, 0.25f), TROUPE_ERR_UNSUPPORTED);
    EXPECT(troupe_session_set_root_smoothing(s, 1, 0.1f), TROUPE_OK);
    troupe_session_free(s);
    troupe_model_free(model);
}

int main(int argc, char **argv) {
    if (argc < 4) {
        fprintf(stderr, "usage: %s ARMFLOW ARFLOW_ONLINE MAGNET\n", argv[0]);
        return 2;
    }
    CHECK(troupe_abi_version() == TROUPE_ABI_VERSION);
    CHECK(troupe_version_number() >= TROUPE_VERSION_NUMBER);
    armflow(argv[1]);
    arflow_online(argv[2]);
    magnet(argv[3]);
    printf("%d passed, %d failed\n", passed, failed);
    return failed != 0;
}

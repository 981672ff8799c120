/* ABI test of ARFlow generation and the penetration metrics through include/troupe.h only.
 * Compiled as C99 and C++17 with -Wall -Wextra -Werror -pedantic (tests/c_abi.rs).
 * Usage: arflow ARFLOW_BUNDLE_DIR ARMFLOW_BUNDLE_DIR [MAGNET_BUNDLE_DIR [ARFLOW_ONLINE_BUNDLE_DIR]] */
#include "troupe.h"
#include "check.h"
#include "npy.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Streams `frames` frames of joint positions (metres, Y up, at the bundle's rate) through
 * `session` one frame at a time; each call returns exactly the poses troupe said it would, all
 * finite. Returns the number of poses. */
static size_t stream_joints(troupe_session *session, const float *joints, size_t frames) {
    size_t t, k, ready = 0, got = 0, total = 0;
    static float posed[64 * 66]; /* a MAGNet partner sends a chunk of frames at once */
    troupe_pose_buffers pose;
    memset(&pose, 0, sizeof pose);
    pose.positions = posed;
    pose.positions_len = 64 * 66;
    for (t = 0; t < frames; t++) {
        EXPECT(troupe_session_joints_ready_after(session, 1, &ready), TROUPE_OK);
        CHECK(ready <= 64);
        EXPECT(troupe_session_step_joints(session, joints + t * 66, 1, &pose, 64, &got), TROUPE_OK);
        CHECK(got == ready);
        for (k = 0; k < got * 66; k++) CHECK(isfinite(posed[k]));
        total += got;
    }
    return total;
}

int main(int argc, char **argv) {
    troupe_model *model = NULL, *armflow = NULL;
    troupe_arflow_options opt;
    size_t n_actor = 0, n_golden = 0, frames, i, t, inside = 99;
    float *actor, *euler, *guided, *out, *bad, *joints_a, *joints_b;
    double frequency = -1.0, depth = -1.0, deepest = -1.0;

    if (argc < 3) {
        fprintf(stderr, "usage: %s ARFLOW_BUNDLE_DIR ARMFLOW_BUNDLE_DIR\n", argv[0]);
        return 2;
    }
    EXPECT(troupe_model_load_file(argv[1], &model), TROUPE_OK);
    EXPECT(troupe_model_load_file(argv[2], &armflow), TROUPE_OK);
    actor = read_npy(argv[1], "actor", &n_actor);
    euler = read_npy(argv[1], "euler_reactor", &n_golden);
    guided = read_npy(argv[1], "guided_reactor", &n_golden);
    if (!model || !armflow || !actor || !euler || !guided) return 1;
    frames = n_actor / 262;
    CHECK(frames == 40 && n_golden == n_actor);
    out = (float *)malloc(n_actor * sizeof *out);

    /* options: the bundle's defaults */
    CHECK(troupe_arflow_options_size() == sizeof(troupe_arflow_options));
    EXPECT(troupe_arflow_options_init(model, &opt, sizeof opt), TROUPE_OK);
    CHECK(opt.steps == 5 && opt.guidance == 2.0f && fabsf(opt.weight - 0.7f) < 1e-6f && opt.eta == 0.0f);
    CHECK(opt.flags == 0 && opt.seed == 0);
    EXPECT(troupe_arflow_options_init(armflow, &opt, sizeof opt), TROUPE_ERR_UNSUPPORTED);
    EXPECT(troupe_arflow_options_init(model, &opt, 8), TROUPE_ERR_INVALID_ARG);

    /* the golden cases: plain Euler, and the guided defaults with seed 3 */
    EXPECT(troupe_arflow_options_init(model, &opt, sizeof opt), TROUPE_OK);
    opt.guidance = 0.0f;
    opt.weight = 1.0f;
    opt.seed = 3;
    EXPECT(troupe_arflow_generate(model, &opt, actor, frames, out, frames), TROUPE_OK);
    printf("arflow euler through the C ABI: %.2e relative\n",
           (double)(max_abs(out, euler, n_actor) / max_value(euler, n_actor)));
    CHECK(max_abs(out, euler, n_actor) <= 1e-5f * max_value(euler, n_actor));
    EXPECT(troupe_arflow_options_init(model, &opt, sizeof opt), TROUPE_OK);
    opt.seed = 3;
    EXPECT(troupe_arflow_generate(model, &opt, actor, frames, out, frames), TROUPE_OK);
    printf("arflow guided through the C ABI: %.2e relative\n",
           (double)(max_abs(out, guided, n_actor) / max_value(guided, n_actor)));
    CHECK(max_abs(out, guided, n_actor) <= 1e-4f * max_value(guided, n_actor));

    {
        /* the run's normals given as one queue: the start noise (sigma > 0), then one eps per
         * step (eta > 0), frames x 262 each, taken in that order; fewer are refused */
        size_t each = n_actor, used = 0;
        float *zeros = (float *)calloc(5 * each, sizeof *zeros), *again = (float *)malloc(n_actor * sizeof *again);
        troupe_arflow_options noisy;
        EXPECT(troupe_arflow_options_init(model, &noisy, sizeof noisy), TROUPE_OK);
        noisy.steps = 3;
        noisy.eta = 0.5f;
        noisy.sigma = 0.1f;
        EXPECT(troupe_arflow_generate_with_draws(model, &noisy, actor, frames, zeros, 5 * each, &used, out, frames),
               TROUPE_OK);
        CHECK(used == 4 * each);
        EXPECT(troupe_arflow_generate_with_draws(model, &noisy, actor, frames, zeros, used, NULL, again, frames),
               TROUPE_OK);
        CHECK(memcmp(out, again, n_actor * sizeof *out) == 0);
        EXPECT(troupe_arflow_generate(model, &noisy, actor, frames, again, frames), TROUPE_OK);
        CHECK(memcmp(out, again, n_actor * sizeof *out) != 0); /* the seed's draws are not zeros */
        again[0] = 12345.0f;
        EXPECT(troupe_arflow_generate_with_draws(model, &noisy, actor, frames, zeros, used - 1, NULL, again, frames),
               TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "draw 3 needs") != NULL);
        EXPECT(troupe_arflow_generate_with_draws(model, &noisy, actor, frames, NULL, 3, NULL, again, frames),
               TROUPE_ERR_NULL_ARG);
        CHECK(again[0] == 12345.0f);
        free(zeros);
        free(again);
    }

    /* bad input: a clear status, the output untouched */
    out[0] = 12345.0f;
    EXPECT(troupe_arflow_generate(NULL, &opt, actor, frames, out, frames), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_arflow_generate(model, &opt, NULL, frames, out, frames), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_arflow_generate(model, &opt, actor, frames, out, frames - 1), TROUPE_ERR_BUFFER_TOO_SMALL);
    EXPECT(troupe_arflow_generate(model, &opt, actor, 0, out, frames), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_arflow_generate(armflow, &opt, actor, frames, out, frames), TROUPE_ERR_UNSUPPORTED);
    CHECK(strstr(troupe_last_error_message(), "needs an `arflow` bundle") != NULL);
    bad = (float *)malloc(n_actor * sizeof *bad);
    memcpy(bad, actor, n_actor * sizeof *bad);
    bad[500] = NAN;
    EXPECT(troupe_arflow_generate(model, &opt, bad, frames, out, frames), TROUPE_ERR_INVALID_ARG);
    opt.guidance = -1.0f;
    EXPECT(troupe_arflow_generate(model, &opt, actor, frames, out, frames), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "guidance strength") != NULL);
    opt.guidance = 2.0f;
    opt.d_safe = 5.0f;
    EXPECT(troupe_arflow_generate(model, &opt, actor, frames, out, frames), TROUPE_ERR_INVALID_ARG);
    opt.d_safe = 0.02f;
    opt.flags = 1u << 12;
    EXPECT(troupe_arflow_generate(model, &opt, actor, frames, out, frames), TROUPE_ERR_INVALID_ARG);
    CHECK(out[0] == 12345.0f);

    /* penetration metrics: the actor's joints against themselves moved 0.1 m, then 3 m */
    joints_a = (float *)malloc(frames * 66 * sizeof *joints_a);
    joints_b = (float *)malloc(frames * 66 * sizeof *joints_b);
    for (t = 0; t < frames; t++)
        for (i = 0; i < 66; i++) {
            joints_a[t * 66 + i] = actor[t * 262 + i];
            joints_b[t * 66 + i] = actor[t * 262 + i] + (i % 3 == 0 ? 0.1f : 0.0f);
        }
    EXPECT(troupe_motion_penetration_metrics(joints_a, joints_b, frames, &inside, &frequency, &depth, &deepest),
           TROUPE_OK);
    CHECK(inside == frames && frequency == 1.0 && depth > 0.0 && deepest > 0.0);
    for (t = 0; t < frames * 22; t++) joints_b[t * 3] += 2.9f;
    EXPECT(troupe_motion_penetration_metrics(joints_a, joints_b, frames, &inside, &frequency, &depth, NULL),
           TROUPE_OK);
    CHECK(inside == 0 && frequency == 0.0 && depth == 0.0);
    EXPECT(troupe_motion_penetration_metrics(NULL, joints_b, frames, &inside, NULL, NULL, NULL), TROUPE_ERR_NULL_ARG);
    joints_b[7] = NAN;
    inside = 77;
    EXPECT(troupe_motion_penetration_metrics(joints_a, joints_b, frames, &inside, NULL, NULL, NULL),
           TROUPE_ERR_INVALID_ARG);
    CHECK(inside == 77);

    /* a session's motion stages (the penetration guard, root smoothing, foot lock), and ARMFlow's recentring */
    {
        troupe_session *session = NULL, *partner = NULL;
        troupe_model *magnet = NULL;
        size_t n_poses;
        EXPECT(troupe_session_new(armflow, NULL, &session), TROUPE_OK);
        /* joint positions in, poses out, with the guard on */
        EXPECT(troupe_session_set_penetration_guard(session, 1, 0.05f, 2.0f), TROUPE_OK);
        n_poses = stream_joints(session, joints_a, frames);
        CHECK(n_poses + troupe_model_joints_latency_frames(armflow) >= frames && n_poses < frames);
        EXPECT(troupe_session_reset(session), TROUPE_OK);
        EXPECT(troupe_session_set_penetration_guard(session, 1, -1.0f, 2.0f), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_session_set_penetration_guard(session, 1, 0.05f, 0.0f), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_session_set_penetration_guard(session, 0, NAN, NAN), TROUPE_OK);
        EXPECT(troupe_session_set_penetration_guard(NULL, 1, 0.05f, 2.0f), TROUPE_ERR_NULL_ARG);
        /* its root smoothing */
        EXPECT(troupe_session_set_root_smoothing(session, 1, 0.1f), TROUPE_OK);
        EXPECT(troupe_session_set_root_smoothing(session, 1, 0.0f), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_session_set_root_smoothing(session, 1, NAN), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_session_set_root_smoothing(session, 1, 3.0f), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_session_set_root_smoothing(session, 0, NAN), TROUPE_OK);
        EXPECT(troupe_session_set_root_smoothing(NULL, 1, 0.1f), TROUPE_ERR_NULL_ARG);
        /* and its foot lock */
        EXPECT(troupe_session_set_foot_lock(session, 1, 0.5f, 4, 0.25f), TROUPE_OK);
        EXPECT(troupe_session_set_foot_lock(session, 1, 0.0f, 4, 0.25f), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_session_set_foot_lock(session, 1, NAN, 4, 0.25f), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_session_set_foot_lock(session, 1, 0.5f, 0, 0.25f), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_session_set_foot_lock(session, 1, 0.5f, 4, INFINITY), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_session_set_foot_lock(session, 0, NAN, 0, NAN), TROUPE_OK);
        EXPECT(troupe_session_set_foot_lock(NULL, 1, 0.5f, 4, 0.25f), TROUPE_ERR_NULL_ARG);
        /* and its recentring */
        EXPECT(troupe_armflow_session_set_recentring(session, 1, 0.5f), TROUPE_OK);
        EXPECT(troupe_armflow_session_set_recentring(session, 1, 0.0f), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_armflow_session_set_recentring(session, 1, NAN), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_armflow_session_set_recentring(session, 1, 1000.0f), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_armflow_session_set_recentring(session, 0, NAN), TROUPE_OK);
        EXPECT(troupe_armflow_session_set_recentring(NULL, 1, 0.5f), TROUPE_ERR_NULL_ARG);
        if (argc > 3) {
            float *pair, opening[32 * 145];
            size_t n_pair = 0;
            EXPECT(troupe_model_load_file(argv[3], &magnet), TROUPE_OK);
            EXPECT(troupe_session_new(magnet, NULL, &partner), TROUPE_OK);
            /* joint positions through a live partner (SMPL-X frames by inverse kinematics), its
             * opening the second person of the bundle's golden pair ([128][2][145]) */
            pair = read_npy(argv[3], "frames", &n_pair);
            CHECK(pair != NULL && n_pair == 128 * 2 * 145);
            for (t = 0; pair && t < 32; t++) memcpy(opening + t * 145, pair + (t * 2 + 1) * 145, 145 * sizeof *pair);
            free(pair);
            EXPECT(troupe_magnet_session_set_partner_opening(partner, opening, 32), TROUPE_OK);
            EXPECT(troupe_session_set_penetration_guard(partner, 1, 0.05f, 2.0f), TROUPE_OK);
            /* the clip three times over: the partner's latency is a window of frames */
            for (n_poses = 0, t = 0; t < 3; t++) n_poses += stream_joints(partner, joints_a, frames);
            CHECK(troupe_model_joints_latency_frames(magnet) == troupe_model_latency_frames(magnet));
            CHECK(n_poses > 0 && n_poses + troupe_model_joints_latency_frames(magnet) >= 3 * frames);
            /* a MAGNet partner takes the guard and the smoothing (its bodies have joints), not the
             * foot lock (its frames carry no contact labels) nor ARMFlow's recentring */
            EXPECT(troupe_session_set_penetration_guard(partner, 1, 0.05f, 2.0f), TROUPE_OK);
            EXPECT(troupe_session_set_root_smoothing(partner, 1, 0.1f), TROUPE_OK);
            EXPECT(troupe_session_set_foot_lock(partner, 1, 0.5f, 4, 0.25f), TROUPE_ERR_UNSUPPORTED);
            CHECK(strstr(troupe_last_error_message(), "contact labels") != NULL);
            EXPECT(troupe_armflow_session_set_recentring(partner, 1, 0.5f), TROUPE_ERR_UNSUPPORTED);
            troupe_session_free(partner);
            troupe_model_free(magnet);
        }
        troupe_session_free(session);
    }

    /* the online variant streams through troupe_session_*: frame by frame as the whole clip */
    if (argc > 4) {
        troupe_model *online = NULL;
        troupe_session *flow = NULL;
        troupe_session_options sopt;
        float *want;
        size_t n_want = 0, written = 0;
        EXPECT(troupe_model_load_file(argv[4], &online), TROUPE_OK);
        want = read_npy(argv[4], "guided_reactor", &n_want);
        CHECK(want != NULL && n_want == n_actor);
        EXPECT(troupe_session_options_init(online, &sopt, sizeof sopt), TROUPE_OK);
        CHECK(sopt.steps == 5 && sopt.cfg_scale == 1.0f);
        EXPECT(troupe_session_new(online, &sopt, &flow), TROUPE_OK);
        EXPECT(troupe_arflow_options_init(online, &opt, sizeof opt), TROUPE_OK);
        opt.seed = 3;
        EXPECT(troupe_arflow_session_set_options(flow, &opt), TROUPE_OK);
        for (t = 0; t < frames; t++) {
            EXPECT(troupe_session_step(flow, actor + t * 262, 1, out + t * 262, 1, &written), TROUPE_OK);
            CHECK(written == 1);
        }
        printf("arflow stream through the C ABI: %.2e relative\n",
               (double)(max_abs(out, want, n_actor) / max_value(want, n_actor)));
        CHECK(max_abs(out, want, n_actor) <= 1e-4f * max_value(want, n_actor));
        /* joint positions through the online stream (its frames are ARMFlow's), guarded */
        EXPECT(troupe_session_reset(flow), TROUPE_OK);
        EXPECT(troupe_session_set_penetration_guard(flow, 1, 0.05f, 2.0f), TROUPE_OK);
        written = stream_joints(flow, joints_a, frames);
        CHECK(written + troupe_model_joints_latency_frames(online) == frames);
        EXPECT(troupe_session_set_penetration_guard(flow, 0, 0.0f, 0.0f), TROUPE_OK);
        EXPECT(troupe_session_reset(flow), TROUPE_OK);
        {
            /* queued normals: all zero, a stream given them steps as the whole clip given the
             * same zeros as its draws (the order cannot matter then); a draw the queue cannot
             * fill fails and changes nothing; ARMFlow sessions take them in whole tokens */
            size_t m = (size_t)frames * 6 * 262, used = 0;
            float *zeros = (float *)calloc(m, sizeof *zeros), *whole = (float *)malloc(n_actor * sizeof *whole);
            troupe_session *reactor = NULL;
            opt.eta = 0.5f;
            opt.sigma = 0.1f;
            EXPECT(troupe_arflow_generate_with_draws(online, &opt, actor, frames, zeros, m, &used, whole, frames),
                   TROUPE_OK);
            CHECK(used == m); /* 5 steps: the start noise and 5 eps per frame */
            EXPECT(troupe_session_reset(flow), TROUPE_OK);
            EXPECT(troupe_arflow_session_set_options(flow, &opt), TROUPE_OK);
            EXPECT(troupe_session_queue_normals(flow, zeros, m), TROUPE_OK);
            for (t = 0; t < frames; t++)
                EXPECT(troupe_session_step(flow, actor + t * 262, 1, out + t * 262, 1, &written), TROUPE_OK);
            printf("arflow stream with queued normals vs the whole clip given them: %.2e relative\n",
                   (double)(max_abs(out, whole, n_actor) / max_value(whole, n_actor)));
            CHECK(max_abs(out, whole, n_actor) <= 1e-4f * max_value(whole, n_actor));
            EXPECT(troupe_session_reset(flow), TROUPE_OK);
            EXPECT(troupe_session_queue_normals(flow, zeros, 100), TROUPE_OK);
            written = 77;
            EXPECT(troupe_session_step(flow, actor, 1, out, 1, &written), TROUPE_ERR_INVALID_ARG);
            CHECK(strstr(troupe_last_error_message(), "needs 262 normals") != NULL && written == 77);
            EXPECT(troupe_session_queue_normals(flow, NULL, 4), TROUPE_ERR_NULL_ARG);
            zeros[0] = NAN;
            EXPECT(troupe_session_queue_normals(flow, zeros, 4), TROUPE_ERR_INVALID_ARG);
            EXPECT(troupe_session_new(armflow, NULL, &reactor), TROUPE_OK);
            EXPECT(troupe_session_queue_normals(reactor, whole, 4), TROUPE_ERR_INVALID_ARG);
            CHECK(strstr(troupe_last_error_message(), "not whole tokens") != NULL);
            troupe_session_free(reactor);
            free(zeros);
            free(whole);
        }
        opt.weight = 7.0f;
        EXPECT(troupe_arflow_session_set_options(flow, &opt), TROUPE_ERR_INVALID_ARG);
        EXPECT(troupe_arflow_session_set_options(flow, NULL), TROUPE_ERR_NULL_ARG);
        troupe_session_free(flow);
        EXPECT(troupe_session_new(model, NULL, &flow), TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "does not stream") != NULL);
        free(want);
        troupe_model_free(online);
    }

    free(joints_a);
    free(joints_b);
    free(bad);
    free(out);
    free(actor);
    free(euler);
    free(guided);
    troupe_model_free(model);
    troupe_model_free(armflow);
    printf("sanitizer: %s\n", TROUPE_TEST_SANITIZER);
    printf("c arflow: %d passed, %d failed\n", passed, failed);
    return failed != 0;
}

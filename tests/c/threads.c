/* Threads through include/troupe.h (tests/c_abi.rs; also built with AddressSanitizer and
 * UndefinedBehaviorSanitizer, and in the long form with ThreadSanitizer):
 *  1. one model shared by 8 threads x 8 sessions: every session's output is bit-identical to
 *     the same session run alone on the main thread;
 *  2. two threads driving one session at once: every call returns TROUPE_OK or TROUPE_ERR_BUSY
 *     (never a race), and the session counts exactly the frames of the calls that succeeded;
 *  3. the same for a batched call racing a single step, and for a joint stream;
 *  4. the library's limits are reported and enforced at the C boundary;
 *  5. a load cancelled by its progress callback, and one cancelled from another thread.
 * Usage: threads BUNDLE_DIR */
#include "troupe.h"
#include "check.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#define THREADS 8
#define SESSIONS 8
#define FRAMES 40

static troupe_model *model;
static size_t dim;
static float actor[FRAMES * 262];

/* Streams the actor through a new session with `seed` into `out` (FRAMES frames). Returns the
 * frames written, or (size_t)-1 on error. */
static size_t run_alone(uint64_t seed, float *out) {
    troupe_session_options opt;
    troupe_session *s = NULL;
    size_t written = 0, t, got;
    if (troupe_session_options_init(model, &opt, sizeof opt) != TROUPE_OK) return (size_t)-1;
    opt.seed = seed;
    if (troupe_session_new(model, &opt, &s) != TROUPE_OK) return (size_t)-1;
    for (t = 0; t < FRAMES; t++) {
        if (troupe_session_step(s, actor + t * dim, 1, out + written * dim, FRAMES - written, &got) !=
            TROUPE_OK) {
            troupe_session_free(s);
            return (size_t)-1;
        }
        written += got;
    }
    troupe_session_free(s);
    return written;
}

typedef struct {
    int index;
    float *out[SESSIONS];
    size_t written[SESSIONS];
} worker;

static void *run_sessions(void *arg) {
    worker *w = (worker *)arg;
    int i;
    for (i = 0; i < SESSIONS; i++)
        w->written[i] = run_alone((uint64_t)(w->index * SESSIONS + i), w->out[i]);
    return NULL;
}

/* Two threads on one session. */
typedef struct {
    troupe_session *session;
    troupe_motion_stream *stream;
    int calls, ok, busy, other, batched;
    size_t frames_out;
} racer;

static void *race(void *arg) {
    racer *r = (racer *)arg;
    float out[8 * 262];
    size_t got = 0;
    int i = 0;
    /* Each thread makes `calls` successful calls, retrying those refused as busy, so that both
     * really take turns on the handle. */
    while (r->ok < r->calls && r->busy < 10000000 && r->other == 0) {
        troupe_status st;
        if (r->stream) {
            float joints[66];
            int j;
            for (j = 0; j < 66; j++) joints[j] = (j % 3 == 1) ? 1.0f + 0.01f * (float)(j / 3) : 0.1f * (float)(j % 5);
            st = troupe_motion_stream_push(r->stream, joints, 66, out, 8, &got);
        } else if (r->batched) {
            troupe_session *sessions[1];
            const float *in[1];
            size_t n_in[1] = {1}, cap[1] = {8}, written[1] = {0};
            float *outs[1];
            sessions[0] = r->session;
            in[0] = actor + (size_t)(i % FRAMES) * dim;
            outs[0] = out;
            st = troupe_sessions_step(sessions, 1, in, n_in, outs, cap, written);
            got = written[0];
        } else {
            st = troupe_session_step(r->session, actor + (size_t)(i % FRAMES) * dim, 1, out, 8, &got);
        }
        if (st == TROUPE_OK) {
            r->ok++;
            r->frames_out += got;
        }
        else if (st == TROUPE_ERR_BUSY)
            r->busy++;
        else {
            r->other++;
            fprintf(stderr, "racing call: %s: %s\n", troupe_status_name(st), troupe_last_error_message());
        }
        i += st == TROUPE_OK;
    }
    return NULL;
}

/* Runs `a` and `b` (each 300 successful calls on the same handle) on two threads at once and
 * checks that every call was either done or refused as busy. */
static void run_race(racer *a, racer *b) {
    pthread_t ta, tb;
    a->calls = b->calls = 300;
    CHECK(pthread_create(&ta, NULL, race, a) == 0);
    CHECK(pthread_create(&tb, NULL, race, b) == 0);
    pthread_join(ta, NULL);
    pthread_join(tb, NULL);
    CHECK(a->other == 0 && b->other == 0);
    CHECK(a->ok == a->calls && b->ok == b->calls);
}

static void race_on_one_session(int batched_b) {
    troupe_session *s = NULL;
    racer a, b;
    EXPECT(troupe_session_new(model, NULL, &s), TROUPE_OK);
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    a.session = b.session = s;
    b.batched = batched_b;
    run_race(&a, &b);
    /* The session saw exactly the frames of the calls that succeeded, one each, and returned
     * every complete token's frames to them. */
    CHECK(a.frames_out + b.frames_out == (size_t)((a.ok + b.ok) / 4 * 4));
    {
        size_t ready = 0;
        EXPECT(troupe_session_output_frames(s, (size_t)(4 - (a.ok + b.ok) % 4), &ready), TROUPE_OK);
        CHECK(ready == 4);
    }
    printf("race%s: %d + %d calls succeeded, %d + %d were refused as busy\n",
           batched_b ? " (batched)" : "", a.ok, b.ok, a.busy, b.busy);
    troupe_session_free(s);
}

static void race_on_one_stream(void) {
    troupe_joints_format format;
    troupe_motion_stream *stream = NULL;
    racer a, b;
    EXPECT(troupe_joints_format_init(&format, sizeof format), TROUPE_OK);
    EXPECT(troupe_motion_stream_new(model, &format, NULL, &stream), TROUPE_OK);
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    a.stream = b.stream = stream;
    run_race(&a, &b);
    printf("stream race: %d + %d pushes succeeded, %d + %d were refused as busy\n", a.ok, b.ok,
           a.busy, b.busy);
    troupe_motion_stream_free(stream);
}

static int32_t stop_at_two(void *user_data, uint64_t done, uint64_t total) {
    int *calls = (int *)user_data;
    (*calls)++;
    return done >= 2 && total > 2;
}

/* Cancelling from another thread: the loading thread's callback announces that the load is
 * under way, then waits until the main thread has set `stop`. */
typedef struct {
    pthread_mutex_t lock;
    pthread_cond_t changed;
    int started, stop;
    const char *bundle;
    troupe_status status;
    troupe_model *loaded;
} cancel_state;

static int32_t read_stop(void *user_data, uint64_t done, uint64_t total) {
    cancel_state *c = (cancel_state *)user_data;
    int stop;
    (void)done;
    (void)total;
    pthread_mutex_lock(&c->lock);
    c->started = 1;
    pthread_cond_broadcast(&c->changed);
    while (!c->stop) pthread_cond_wait(&c->changed, &c->lock);
    stop = c->stop;
    pthread_mutex_unlock(&c->lock);
    return stop;
}

static void *load_with_cancel(void *arg) {
    cancel_state *c = (cancel_state *)arg;
    troupe_set_progress_callback(read_stop, c);
    c->status = troupe_model_load_file(c->bundle, &c->loaded);
    troupe_set_progress_callback(NULL, NULL);
    return NULL;
}

static void cancelling(const char *bundle) {
    int calls = 0;
    troupe_model *m = NULL;
    cancel_state c;
    pthread_t loader;
    troupe_set_progress_callback(stop_at_two, &calls);
    EXPECT(troupe_model_load_file(bundle, &m), TROUPE_ERR_CANCELLED);
    CHECK(m == NULL && calls == 2);
    CHECK(strstr(troupe_last_error_message(), "cancelled") != NULL);
    CHECK(strcmp(troupe_status_name(TROUPE_ERR_CANCELLED), "TROUPE_ERR_CANCELLED") == 0);
    troupe_set_progress_callback(NULL, NULL);
    EXPECT(troupe_model_load_file(bundle, &m), TROUPE_OK);
    CHECK(calls == 2);
    troupe_model_free(m);

    memset(&c, 0, sizeof c);
    pthread_mutex_init(&c.lock, NULL);
    pthread_cond_init(&c.changed, NULL);
    c.bundle = bundle;
    CHECK(pthread_create(&loader, NULL, load_with_cancel, &c) == 0);
    pthread_mutex_lock(&c.lock);
    while (!c.started) pthread_cond_wait(&c.changed, &c.lock);
    c.stop = 1;
    pthread_cond_broadcast(&c.changed);
    pthread_mutex_unlock(&c.lock);
    pthread_join(loader, NULL);
    CHECK(c.status == TROUPE_ERR_CANCELLED && c.loaded == NULL);
    pthread_cond_destroy(&c.changed);
    pthread_mutex_destroy(&c.lock);
}

static void limits(void) {
    troupe_limits l;
    troupe_session_options opt;
    troupe_session *s = NULL;
    memset(&l, 0xff, sizeof l);
    EXPECT(troupe_limits_get(&l, sizeof l), TROUPE_OK);
    CHECK(l.struct_size == sizeof l && l.reserved == 0);
    CHECK(l.values.max_steps == 10000 && l.values.max_text_tokens == 77 && l.values.max_people == 256);
    CHECK(l.values.max_bundle_bytes >= ((uint64_t)1 << 30));
    EXPECT(troupe_limits_get(NULL, sizeof l), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_limits_get(&l, 4), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_session_options_init(model, &opt, sizeof opt), TROUPE_OK);
    opt.steps = UINT32_MAX;
    EXPECT(troupe_session_new(model, &opt, &s), TROUPE_ERR_INVALID_ARG);
    CHECK(s == NULL);
    CHECK(strstr(troupe_last_error_message(), "limit of 10000") != NULL);
    EXPECT(troupe_session_new(model, NULL, &s), TROUPE_OK);
    EXPECT(troupe_session_set_steps(s, UINT32_MAX), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_session_set_cfg_scale(s, 3.4e38f), TROUPE_ERR_INVALID_ARG);
    troupe_session_free(s);
    CHECK(troupe_load_threads() >= 1);
    troupe_set_load_threads(1);
    CHECK(troupe_load_threads() == 1);
    troupe_set_load_threads(0);
}

int main(int argc, char **argv) {
    static float reference[THREADS * SESSIONS][FRAMES * 262];
    static float results[THREADS * SESSIONS][FRAMES * 262];
    worker workers[THREADS];
    pthread_t threads[THREADS];
    size_t t, d;
    int i, j, same = 0;
    if (argc != 2) {
        fprintf(stderr, "usage: threads BUNDLE_DIR\n");
        return 2;
    }
    EXPECT(troupe_model_load_file(argv[1], &model), TROUPE_OK);
    if (!model) return 1;
    dim = troupe_model_frame_dim(model);
    CHECK(dim == 262);
    for (t = 0; t < FRAMES; t++)
        for (d = 0; d < dim; d++)
            actor[t * dim + d] = 0.5f * (float)sin(0.1 * (double)t * (1.0 + (double)(d % 7)) + (double)d);

    for (i = 0; i < THREADS * SESSIONS; i++) CHECK(run_alone((uint64_t)i, reference[i]) == FRAMES);
    for (i = 0; i < THREADS; i++) {
        workers[i].index = i;
        for (j = 0; j < SESSIONS; j++) workers[i].out[j] = results[i * SESSIONS + j];
        CHECK(pthread_create(&threads[i], NULL, run_sessions, &workers[i]) == 0);
    }
    for (i = 0; i < THREADS; i++) pthread_join(threads[i], NULL);
    for (i = 0; i < THREADS * SESSIONS; i++) {
        CHECK(workers[i / SESSIONS].written[i % SESSIONS] == FRAMES);
        same += memcmp(reference[i], results[i], FRAMES * dim * sizeof(float)) == 0;
    }
    CHECK(same == THREADS * SESSIONS);
    printf("%d threads x %d sessions: %d of %d bit-identical to running alone\n", THREADS, SESSIONS,
           same, THREADS * SESSIONS);

    race_on_one_session(0);
    race_on_one_session(1);
    race_on_one_stream();
    limits();
    cancelling(argv[1]);

    troupe_model_free(model);
    printf("sanitizer: %s\n", TROUPE_TEST_SANITIZER);
    printf("%d passed, %d failed\n", passed, failed);
    return failed ? 1 : 0;
}

/* The streaming demo through the C header only: feed a synthetic actor frame by frame (or in
 * ticks of N frames) as an engine would, write the reactor motion to a .npy file, and print
 * per-step latency and the real-time factor.
 *
 *   cargo build --release
 *   cc -std=c99 -O2 -Iinclude examples/c/stream.c -Ltarget/release -ltroupe \
 *      -Wl,-rpath,$PWD/target/release -lm -o stream_c
 *   ./stream_c [BUNDLE] [FRAMES] [TICK] [OUT.npy]
 */
#define _POSIX_C_SOURCE 199309L
#include "troupe.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec / 1e6;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Writes float32 [rows, cols] as a .npy (format 1.0) file. */
static int write_npy(const char *path, const float *data, size_t rows, size_t cols) {
    char header[128];
    int len;
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    len = snprintf(header, sizeof header, "{'descr': '<f4', 'fortran_order': False, 'shape': (%lu, %lu), }",
                   (unsigned long)rows, (unsigned long)cols);
    while ((10 + len + 1) % 64 != 0) header[len++] = ' ';
    header[len++] = '\n';
    fwrite("\x93NUMPY\x01\x00", 1, 8, f);
    fputc(len & 0xff, f);
    fputc((len >> 8) & 0xff, f);
    fwrite(header, 1, (size_t)len, f);
    fwrite(data, sizeof(float), rows * cols, f);
    return fclose(f);
}

int main(int argc, char **argv) {
    const char *bundle = argc > 1 ? argv[1] : "onnx/bundles/armflow-tiny";
    size_t frames = argc > 2 ? (size_t)atol(argv[2]) : 600, tick = argc > 3 ? (size_t)atol(argv[3]) : 1;
    const char *out_path = argc > 4 ? argv[4] : "reactor_c.npy";
    troupe_model *model = NULL;
    troupe_session *session = NULL;
    troupe_session_options opt;
    size_t dim, t, d, done = 0, written = 0, calls = 0, token_calls = 0;
    float *actor, *reactor;
    double *latency, *token_latency, total = 0.0;

    if (tick == 0) tick = 1;
    if (troupe_model_load_file(bundle, &model) != TROUPE_OK) {
        fprintf(stderr, "load: %s\n", troupe_last_error_message());
        return 1;
    }
    troupe_session_options_init(model, &opt, sizeof opt);
    opt.seed = 7;
    if (troupe_session_new(model, &opt, &session) != TROUPE_OK) {
        fprintf(stderr, "session: %s\n", troupe_last_error_message());
        return 1;
    }
    dim = troupe_model_frame_dim(model);
    actor = (float *)malloc(frames * dim * sizeof(float));
    reactor = (float *)malloc((frames + tick) * dim * sizeof(float));
    latency = (double *)malloc((frames / tick + 1) * sizeof(double));
    token_latency = (double *)malloc((frames / tick + 1) * sizeof(double));
    for (t = 0; t < frames; t++)
        for (d = 0; d < dim; d++)
            actor[t * dim + d] = 0.5f * (float)sin(2.0 * 3.14159265 * (0.2 + 0.05 * (double)(d % 37)) * (double)t / 30.0 + (double)d);

    while (done < frames) {
        size_t n = frames - done < tick ? frames - done : tick, got = 0;
        double t0 = now_ms(), ms;
        troupe_status st = troupe_session_step(session, actor + done * dim, n, reactor + written * dim,
                                               troupe_model_max_output_frames(model, n), &got);
        ms = now_ms() - t0;
        if (st != TROUPE_OK) {
            fprintf(stderr, "step: %s\n", troupe_last_error_message());
            return 1;
        }
        total += ms;
        latency[calls++] = ms;
        if (got > 0) token_latency[token_calls++] = ms;
        written += got;
        done += n;
    }
    qsort(latency, calls, sizeof(double), cmp_double);
    qsort(token_latency, token_calls, sizeof(double), cmp_double);
    if (write_npy(out_path, reactor, written, dim) != 0) fprintf(stderr, "could not write %s\n", out_path);
    printf("troupe %s, bundle %s: %lu actor frames in ticks of %lu, %lu reactor frames -> %s\n",
           troupe_version_string(), bundle, (unsigned long)frames, (unsigned long)tick, (unsigned long)written, out_path);
    if (token_calls > 0)
        printf("step latency (calls that produced a token, %lu): p50 %.3f ms  p99 %.3f ms  max %.3f ms\n",
               (unsigned long)token_calls, token_latency[token_calls / 2],
               token_latency[(size_t)((double)(token_calls - 1) * 0.99 + 0.5)], token_latency[token_calls - 1]);
    printf("real-time factor %.1fx\n", (double)frames / (double)troupe_model_fps(model) * 1e3 / total);

    troupe_session_free(session);
    troupe_model_free(model);
    free(actor);
    free(reactor);
    free(latency);
    free(token_latency);
    return 0;
}

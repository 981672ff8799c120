/* MAGNet from C: run one of a `magnet` bundle's sampling configurations on a clip of troupe
 * frames and report the time, through include/troupe.h only.
 *
 *   ln -sf libtroupe.so target/release/libtroupe.so.1    # the SONAME the program asks for
 *   cc -std=c99 -O2 -Iinclude examples/c/magnet.c -Ltarget/release -ltroupe \
 *      -Wl,-rpath,$PWD/target/release -o magnet_c
 *   ./magnet_c BUNDLE CONFIG FRAMES.npy [SAMPLES [STEPS]]
 *
 * FRAMES.npy: float32 [frames, people, 145] (betas, the 21 body joints' 6-D rotations, the
 * root's pose in the world). SAMPLES and STEPS change the configuration (0: as released). */
#define _POSIX_C_SOURCE 199309L /* clock_gettime */
#include "troupe.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifdef _WIN32
/* kernel32's monotonic clock, declared here so that the example needs no <windows.h>. */
__declspec(dllimport) int __stdcall QueryPerformanceCounter(long long *count);
__declspec(dllimport) int __stdcall QueryPerformanceFrequency(long long *frequency);

static double now_seconds(void) {
    long long count, frequency;
    QueryPerformanceCounter(&count);
    QueryPerformanceFrequency(&frequency);
    return (double)count / (double)frequency;
}
#else
static double now_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
#endif

/* Reads a little-endian float32 .npy (format 1.0) of `row` floats per frame; returns the
 * frames, or 0 on failure. */
static size_t read_rows(const char *path, size_t row, float **out) {
    char magic[8];
    unsigned char len_bytes[2];
    size_t header_len, bytes, rows;
    long end;
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    if (fread(magic, 1, 8, f) != 8 || memcmp(magic, "\x93NUMPY", 6) != 0 || fread(len_bytes, 1, 2, f) != 2) {
        fclose(f);
        return 0;
    }
    header_len = (size_t)len_bytes[0] | ((size_t)len_bytes[1] << 8);
    fseek(f, 0, SEEK_END);
    end = ftell(f);
    bytes = (size_t)end - 10 - header_len;
    rows = bytes / (sizeof(float) * row);
    fseek(f, (long)(10 + header_len), SEEK_SET);
    *out = (float *)malloc(rows * row * sizeof(float));
    if (!*out || fread(*out, sizeof(float) * row, rows, f) != rows) rows = 0;
    fclose(f);
    return rows;
}

int main(int argc, char **argv) {
    troupe_model *model = NULL;
    troupe_magnet_options opt;
    size_t people, frames, s = 0, f = 0, p = 0, n, i, bad = 0;
    float *clip = NULL, *out;
    double seconds;
    troupe_status st;

    if (argc < 4) {
        fprintf(stderr, "usage: %s BUNDLE CONFIG FRAMES.npy [SAMPLES [STEPS]]\n", argv[0]);
        return 2;
    }
    if (troupe_model_load_file(argv[1], &model) != TROUPE_OK) {
        fprintf(stderr, "load: %s\n", troupe_last_error_message());
        return 1;
    }
    people = troupe_magnet_people(model);
    frames = people ? read_rows(argv[3], people * 145, &clip) : 0;
    if (!frames) {
        fprintf(stderr, "%s: not a float32 [frames, %lu, 145] .npy (or not a magnet bundle)\n", argv[3],
                (unsigned long)people);
        return 1;
    }
    troupe_magnet_options_init(&opt, sizeof opt);
    opt.samples = argc > 4 ? (uint32_t)atoi(argv[4]) : 0;
    opt.steps = argc > 5 ? (uint32_t)atoi(argv[5]) : 0;
    st = troupe_magnet_output_shape(model, argv[2], &opt, frames, &s, &f, &p);
    if (st != TROUPE_OK) {
        fprintf(stderr, "%s: %s\n", argv[2], troupe_last_error_message());
        return 1;
    }
    n = s * f * p * 145;
    out = (float *)malloc(n * sizeof *out);
    seconds = now_seconds();
    st = troupe_magnet_generate(model, argv[2], &opt, clip, frames, NULL, out, n);
    seconds = now_seconds() - seconds;
    if (st != TROUPE_OK) {
        fprintf(stderr, "generate: %s\n", troupe_last_error_message());
        return 1;
    }
    for (i = 0; i < n; i++) bad += !isfinite(out[i]);
    printf("%s on %lu frames: %lu samples x %lu frames x %lu people in %.2f s; non-finite values: %lu\n", argv[2],
           (unsigned long)frames, (unsigned long)s, (unsigned long)f, (unsigned long)p, seconds, (unsigned long)bad);
    free(out);
    free(clip);
    troupe_model_free(model);
    return bad != 0;
}

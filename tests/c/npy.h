/* Helpers of the C ABI tests that read golden files: a float32 .npy reader and max-abs. */
#ifndef TROUPE_TEST_NPY_H
#define TROUPE_TEST_NPY_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Reads a little-endian float32 .npy file (version 1 header); returns NULL on failure. */
static inline float *read_npy(const char *dir, const char *name, size_t *count) {
    char path[1024], magic[8];
    unsigned char len_bytes[2];
    size_t header_len, bytes;
    long end;
    float *data;
    FILE *f;
    snprintf(path, sizeof path, "%s/golden/%s.npy", dir, name);
    f = fopen(path, "rb");
    if (!f) return NULL;
    if (fread(magic, 1, 8, f) != 8 || memcmp(magic, "\x93NUMPY", 6) != 0 ||
        fread(len_bytes, 1, 2, f) != 2) {
        fclose(f);
        return NULL;
    }
    header_len = (size_t)len_bytes[0] | ((size_t)len_bytes[1] << 8);
    fseek(f, 0, SEEK_END);
    end = ftell(f);
    bytes = (size_t)end - 10 - header_len;
    fseek(f, (long)(10 + header_len), SEEK_SET);
    data = (float *)malloc(bytes);
    if (data && fread(data, 1, bytes, f) != bytes) {
        free(data);
        data = NULL;
    }
    fclose(f);
    *count = bytes / sizeof(float);
    return data;
}

static inline float max_abs(const float *a, const float *b, size_t n) {
    float m = 0.0f;
    size_t i;
    for (i = 0; i < n; i++) {
        float d = fabsf(a[i] - b[i]);
        if (d > m) m = d;
    }
    return m;
}

/* The largest |a[i]|: the scale relative errors are measured against. */
static inline float max_value(const float *a, size_t n) {
    float m = 0.0f;
    size_t i;
    for (i = 0; i < n; i++)
        if (fabsf(a[i]) > m) m = fabsf(a[i]);
    return m;
}

#endif

/* Session snapshots through the header, across processes: `save` streams the golden actor
 * whole and, in another session, up to frame CUT, then writes the snapshot and both outputs to
 * STATE_DIR; `resume`, run as a second process, restores the snapshot, streams the rest and
 * checks that the two halves equal the whole stream bit for bit. Every bad input (NULL, a short
 * buffer, a truncated, altered or foreign snapshot) is refused with its code and message.
 * Arguments: BUNDLE OTHER_BUNDLE STATE_DIR save|resume. */
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "npy.h"

#define CUT 37
#define CHUNK 5

static int write_file(const char *dir, const char *name, const void *data, size_t n) {
    char path[1024];
    FILE *f;
    size_t done;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    f = fopen(path, "wb");
    if (!f) return 0;
    done = fwrite(data, 1, n, f);
    fclose(f);
    return done == n;
}

static unsigned char *read_file(const char *dir, const char *name, size_t *n) {
    char path[1024];
    FILE *f;
    long end;
    unsigned char *data;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    end = ftell(f);
    fseek(f, 0, SEEK_SET);
    data = (unsigned char *)malloc(end > 0 ? (size_t)end : 1);
    *n = data ? fread(data, 1, (size_t)end, f) : 0;
    fclose(f);
    return data;
}

/* Streams frames [from, to) of `actor` in chunks; appends the reactor frames to `out` (room for
 * every frame) and returns how many floats were written. */
static size_t stream(troupe_session *s, const float *actor, size_t dim, size_t from, size_t to,
                     float *out) {
    size_t at = from, floats = 0;
    while (at < to) {
        size_t n = to - at < CHUNK ? to - at : CHUNK, got = 0;
        EXPECT(troupe_session_step(s, actor + at * dim, n, out + floats, 2 * CHUNK, &got),
               TROUPE_OK);
        floats += got * dim;
        at += n;
    }
    return floats;
}

static troupe_session *open_session(troupe_model *model) {
    troupe_session_options opt;
    troupe_session *s = NULL;
    troupe_session_options_init(model, &opt, sizeof opt);
    opt.seed = 3;
    opt.context_capacity = 5; /* the cache's ring wraps before the cut */
    EXPECT(troupe_session_new(model, &opt, &s), TROUPE_OK);
    return s;
}

static void save(troupe_model *model, troupe_model *other, const float *actor, size_t frames,
                 size_t dim, const char *dir) {
    float *whole = (float *)calloc(frames * dim, sizeof(float));
    float *first = (float *)calloc(frames * dim, sizeof(float));
    troupe_session *a = open_session(model), *b = open_session(model), *again = NULL;
    size_t n_whole, n_first, size = 0, size2 = 0;
    unsigned char *bytes, *bytes2, id[32], id_other[32];
    troupe_status st;

    n_whole = stream(a, actor, dim, 0, frames, whole);
    n_first = stream(b, actor, dim, 0, CUT, first);
    CHECK(write_file(dir, "whole.bin", whole, n_whole * sizeof(float)));
    CHECK(write_file(dir, "first.bin", first, n_first * sizeof(float)));

    /* the size query, then the snapshot */
    EXPECT(troupe_session_snapshot(b, NULL, 0, &size), TROUPE_OK);
    CHECK(size > 64);
    bytes = (unsigned char *)malloc(size);
    bytes2 = (unsigned char *)malloc(size);
    memset(bytes, 0xAB, size);
    EXPECT(troupe_session_snapshot(b, bytes, size - 1, &size2), TROUPE_ERR_BUFFER_TOO_SMALL);
    CHECK(strstr(troupe_last_error_message(), "bytes, the buffer holds") != NULL);
    CHECK(bytes[0] == 0xAB && size2 == size); /* nothing written but the size */
    EXPECT(troupe_session_snapshot(b, bytes, size, &size2), TROUPE_OK);
    CHECK(size2 == size && memcmp(bytes, "TRPSNAP", 8) == 0);
    CHECK(write_file(dir, "snapshot.bin", bytes, size));
    EXPECT(troupe_session_snapshot(NULL, bytes, size, &size2), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_snapshot(b, bytes, size, NULL), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_snapshot(b, NULL, size, &size2), TROUPE_ERR_NULL_ARG);

    /* restored in this process, it saves to the same bytes */
    EXPECT(troupe_session_restore(model, bytes, size, &again), TROUPE_OK);
    EXPECT(troupe_session_snapshot(again, bytes2, size, &size2), TROUPE_OK);
    CHECK(size2 == size && memcmp(bytes, bytes2, size) == 0);
    troupe_session_free(again);

    /* hostile snapshots: refused, *out NULL, with a message */
    again = (troupe_session *)bytes2; /* any non-NULL value: it must come back NULL */
    EXPECT(troupe_session_restore(model, bytes, size - 1, &again), TROUPE_ERR_INVALID_ARG);
    CHECK(again == NULL && strstr(troupe_last_error_message(), "snapshot") != NULL);
    memcpy(bytes2, bytes, size);
    bytes2[size / 2] ^= 0x40;
    EXPECT(troupe_session_restore(model, bytes2, size, &again), TROUPE_ERR_INVALID_ARG);
    CHECK(strstr(troupe_last_error_message(), "checksum") != NULL);
    st = troupe_session_restore(other, bytes, size, &again);
    CHECK(st == TROUPE_ERR_INVALID_ARG && again == NULL);
    CHECK(strstr(troupe_last_error_message(), "another model") != NULL);
    EXPECT(troupe_session_restore(model, NULL, size, &again), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_restore(model, NULL, 0, &again), TROUPE_ERR_INVALID_ARG);
    EXPECT(troupe_session_restore(NULL, bytes, size, &again), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_session_restore(model, bytes, size, NULL), TROUPE_ERR_NULL_ARG);

    /* sealed under a key: restored with that key only; an edited byte, another key, an
       unsealed snapshot through the sealed restore and a sealed one through the plain restore
       are refused by name */
    {
        uint8_t key[32], other_key[32];
        size_t sealed_size = 0, k;
        uint8_t *sealed;
        for (k = 0; k < 32; k++) {
            key[k] = (uint8_t)(k * 7 + 1);
            other_key[k] = (uint8_t)(key[k] ^ 0x5A);
        }
        EXPECT(troupe_snapshot_seal(bytes, size, key, 32, NULL, 0, &sealed_size), TROUPE_OK);
        CHECK(sealed_size == size + 44);
        sealed = (uint8_t *)malloc(sealed_size);
        EXPECT(troupe_snapshot_seal(bytes, size, key, 32, sealed, sealed_size - 1, &sealed_size),
               TROUPE_ERR_BUFFER_TOO_SMALL);
        EXPECT(troupe_snapshot_seal(bytes, size, key, 32, sealed, sealed_size, &sealed_size), TROUPE_OK);
        CHECK(memcmp(sealed, "TRPSEAL", 8) == 0);
        EXPECT(troupe_session_restore_sealed(model, sealed, sealed_size, key, 32, &again), TROUPE_OK);
        EXPECT(troupe_session_snapshot(again, bytes2, size, &size2), TROUPE_OK);
        CHECK(size2 == size && memcmp(bytes, bytes2, size) == 0);
        troupe_session_free(again);
        EXPECT(troupe_session_restore_sealed(model, sealed, sealed_size, other_key, 32, &again),
               TROUPE_ERR_INVALID_ARG);
        CHECK(again == NULL && strstr(troupe_last_error_message(), "does not match this key") != NULL);
        sealed[sealed_size / 2] ^= 0x01;
        EXPECT(troupe_session_restore_sealed(model, sealed, sealed_size, key, 32, &again),
               TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "does not match this key") != NULL);
        sealed[sealed_size / 2] ^= 0x01;
        EXPECT(troupe_session_restore_sealed(model, bytes, size, key, 32, &again), TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "not sealed") != NULL);
        EXPECT(troupe_session_restore(model, sealed, sealed_size, &again), TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "sealed with a key") != NULL);
        EXPECT(troupe_session_restore_sealed(model, sealed, sealed_size, key, 15, &again),
               TROUPE_ERR_INVALID_ARG);
        CHECK(strstr(troupe_last_error_message(), "at least 16 bytes") != NULL);
        EXPECT(troupe_session_restore_sealed(model, sealed, sealed_size, NULL, 32, &again), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_snapshot_seal(bytes, size, key, 32, NULL, 0, NULL), TROUPE_ERR_NULL_ARG);
        EXPECT(troupe_snapshot_seal(key, 32, key, 32, NULL, 0, &sealed_size), TROUPE_ERR_INVALID_ARG);
        free(sealed);
    }

    /* identities: 32 bytes, equal for equal files, different for other weights */
    EXPECT(troupe_model_identity(model, id), TROUPE_OK);
    EXPECT(troupe_model_identity(other, id_other), TROUPE_OK);
    CHECK(memcmp(id, id_other, 32) != 0);
    CHECK(memcmp(id, bytes + 8 + 4 + 4 + 7, 32) == 0); /* the snapshot carries it */
    EXPECT(troupe_model_identity(NULL, id), TROUPE_ERR_NULL_ARG);
    EXPECT(troupe_model_identity(model, NULL), TROUPE_ERR_NULL_ARG);

    troupe_session_free(a);
    troupe_session_free(b);
    free(bytes);
    free(bytes2);
    free(whole);
    free(first);
}

static void resume(troupe_model *model, const float *actor, size_t frames, size_t dim,
                   const char *dir) {
    size_t n_snapshot = 0, n_whole = 0, n_first = 0, n_rest;
    unsigned char *snapshot = read_file(dir, "snapshot.bin", &n_snapshot);
    unsigned char *whole = read_file(dir, "whole.bin", &n_whole);
    unsigned char *first = read_file(dir, "first.bin", &n_first);
    float *rest = (float *)calloc(frames * dim, sizeof(float));
    troupe_session *s = NULL;

    CHECK(snapshot && whole && first);
    if (!snapshot || !whole || !first) return;
    EXPECT(troupe_session_restore(model, snapshot, n_snapshot, &s), TROUPE_OK);
    if (!s) return;
    n_rest = stream(s, actor, dim, CUT, frames, rest) * sizeof(float);
    CHECK(n_first + n_rest == n_whole);
    CHECK(n_whole > 0 && memcmp(first, whole, n_first) == 0);
    CHECK(n_first + n_rest == n_whole && memcmp(rest, whole + n_first, n_rest) == 0);
    printf("resumed at frame %d from a %zu-byte snapshot: %zu + %zu bytes of frames equal the "
           "uninterrupted stream's\n",
           CUT, n_snapshot, n_first, n_rest);
    troupe_session_free(s);
    free(snapshot);
    free(whole);
    free(first);
    free(rest);
}

int main(int argc, char **argv) {
    troupe_model *model = NULL, *other = NULL;
    float *actor;
    size_t count = 0, dim, frames;

    if (argc < 5) {
        fprintf(stderr, "usage: %s BUNDLE OTHER_BUNDLE STATE_DIR save|resume\n", argv[0]);
        return 2;
    }
    EXPECT(troupe_model_load_file(argv[1], &model), TROUPE_OK);
    EXPECT(troupe_model_load_file(argv[2], &other), TROUPE_OK);
    actor = read_npy(argv[1], "actor", &count);
    CHECK(actor != NULL);
    if (!model || !other || !actor) return 1;
    dim = troupe_model_frame_dim(model);
    frames = count / dim;
    if (strcmp(argv[4], "save") == 0) {
        save(model, other, actor, frames, dim, argv[3]);
    } else {
        resume(model, actor, frames, dim, argv[3]);
    }
    troupe_model_free(model);
    troupe_model_free(other);
    free(actor);
    printf("snapshot %s (sanitizer: %s): %d passed, %d failed\n", argv[4], TROUPE_TEST_SANITIZER,
           passed, failed);
    return failed ? 1 : 0;
}

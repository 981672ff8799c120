/* The streaming demo through the C header only: feed an actor's joint positions frame by frame
 * (or in ticks of N frames) as an engine would, get the reactor's joint positions back, write
 * them to a .npy file with a picture beside it (an HTML player and a GIF of both people), and
 * print per-step latency and the real-time factor.
 *
 *   cargo build --release
 *   ln -sf libtroupe.so target/release/libtroupe.so.1    # the SONAME the program asks for
 *   cc -std=c99 -O2 -Iinclude examples/c/stream.c -Ltarget/release -ltroupe \
 *      -Wl,-rpath,$PWD/target/release -lm -o stream_c
 *   ./stream_c [BUNDLE] [FRAMES] [TICK] [OUT.npy] [JOINTS.npy] [RULE]
 *
 * BUNDLE defaults to the trained demo model (onnx/bundles/armflow-demo) and RULE to its first
 * named condition (mirror; follow and keep-away are the others). On the default clip the demo
 * prints how far the reactor is from the rule's partner (tests/data/mocap/cmu-playground.RULE.npy).
 * JOINTS.npy: float32 [T, 22, 3] t2m-22 positions, metres, z up, 120 fps (default: the CMU
 * excerpt in tests/data/mocap). OUT.npy gets float32 [T, 22, 3] in the same world; OUT.html and
 * OUT.gif go beside it.
 */
#define _POSIX_C_SOURCE 199309L
#include "troupe.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define J 22
#define CLIP_FPS 120.0f

#ifdef _WIN32
/* kernel32's monotonic clock, declared here so that the example needs no <windows.h>. */
__declspec(dllimport) int __stdcall QueryPerformanceCounter(long long *count);
__declspec(dllimport) int __stdcall QueryPerformanceFrequency(long long *frequency);

static double now_ms(void) {
    long long count, frequency;
    QueryPerformanceCounter(&count);
    QueryPerformanceFrequency(&frequency);
    return (double)count * 1e3 / (double)frequency;
}
#else
static double now_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec / 1e6;
}
#endif

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Writes float32 [rows, J, 3] as a .npy (format 1.0) file. */
static int write_npy(const char *path, const float *data, size_t rows) {
    char header[128];
    int len;
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    len = snprintf(header, sizeof header, "{'descr': '<f4', 'fortran_order': False, 'shape': (%lu, %d, 3), }",
                   (unsigned long)rows, J);
    while ((10 + len + 1) % 64 != 0) header[len++] = ' ';
    header[len++] = '\n';
    fwrite("\x93NUMPY\x01\x00", 1, 8, f);
    fputc(len & 0xff, f);
    fputc((len >> 8) & 0xff, f);
    fwrite(header, 1, (size_t)len, f);
    fwrite(data, sizeof(float), rows * J * 3, f);
    return fclose(f);
}

/* Reads a little-endian float32 [T, 22, 3] .npy (format 1.0); returns T, or 0 on failure. */
static size_t read_joints(const char *path, float **out) {
    char magic[8];
    unsigned char len_bytes[2];
    size_t header_len, bytes, frames;
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
    frames = bytes / (sizeof(float) * J * 3);
    fseek(f, (long)(10 + header_len), SEEK_SET);
    *out = (float *)malloc(frames * J * 3 * sizeof(float));
    if (!*out || fread(*out, sizeof(float) * J * 3, frames, f) != frames) frames = 0;
    fclose(f);
    return frames;
}

/* Mean per-joint distance in cm between two [frames, 22, 3] clips. */
static double mpjpe_cm(const float *a, const float *b, size_t frames) {
    double sum = 0.0;
    size_t i;
    for (i = 0; i < frames * J; i++) {
        double dx = a[3 * i] - b[3 * i], dy = a[3 * i + 1] - b[3 * i + 1], dz = a[3 * i + 2] - b[3 * i + 2];
        sum += sqrt(dx * dx + dy * dy + dz * dz);
    }
    return frames ? 100.0 * sum / (double)(frames * J) : 0.0;
}

int main(int argc, char **argv) {
    const char *bundle = argc > 1 ? argv[1] : "onnx/bundles/armflow-demo";
    size_t limit = argc > 2 ? (size_t)atol(argv[2]) : 0, tick = argc > 3 ? (size_t)atol(argv[3]) : 1;
    const char *out_path = argc > 4 ? argv[4] : "reactor_c.npy";
    const char *default_clip = "tests/data/mocap/cmu-playground-120fps.npy";
    const char *joints_path = argc > 5 ? argv[5] : default_clip;
    const char *rule = argc > 6 ? argv[6] : NULL;
    float *condition = NULL;
    troupe_model *model = NULL;
    troupe_session *session = NULL;
    troupe_session_options opt;
    troupe_joints_format format;
    troupe_pose_buffers pose;
    size_t frames, t, done = 0, written = 0, calls = 0, token_calls = 0, stride, shown;
    float *actor = NULL, *reactor, *both;
    double *latency, *token_latency, total = 0.0;
    char html[1024], gif[1024];
    const char *names[2] = {"actor", "reactor"};

    if (tick == 0) tick = 1;
    frames = read_joints(joints_path, &actor);
    if (frames == 0) {
        fprintf(stderr, "could not read float32 [T, 22, 3] joint positions from %s\n", joints_path);
        return 1;
    }
    if (limit > 0 && limit < frames) frames = limit;
    if (troupe_model_load_file(bundle, &model) != TROUPE_OK) {
        fprintf(stderr, "load: %s\n", troupe_last_error_message());
        return 1;
    }
    troupe_session_options_init(model, &opt, sizeof opt);
    opt.seed = 7;
    if (!rule && troupe_model_condition_label_count(model) > 0) rule = troupe_model_condition_label(model, 0);
    if (rule) {
        condition = (float *)malloc(troupe_model_condition_dim(model) * sizeof(float));
        if (troupe_model_condition_for_label(model, rule, condition, troupe_model_condition_dim(model)) != TROUPE_OK) {
            fprintf(stderr, "rule: %s\n", troupe_last_error_message());
            return 1;
        }
    }
    troupe_joints_format_init(&format, sizeof format);
    format.units = TROUPE_UNITS_METERS;
    format.up_axis = TROUPE_UP_Z;
    format.fps = CLIP_FPS;
    if (troupe_session_new(model, &opt, &session) != TROUPE_OK ||
        (condition && troupe_session_set_condition(session, condition, troupe_model_condition_dim(model)) != TROUPE_OK) ||
        troupe_session_set_joints_format(session, &format) != TROUPE_OK) {
        fprintf(stderr, "session: %s\n", troupe_last_error_message());
        return 1;
    }
    reactor = (float *)malloc((frames + tick) * J * 3 * sizeof(float));
    latency = (double *)malloc((frames / tick + 1) * sizeof(double));
    token_latency = (double *)malloc((frames / tick + 1) * sizeof(double));
    memset(&pose, 0, sizeof pose);

    while (done < frames) {
        size_t n = frames - done < tick ? frames - done : tick, got = 0, room = frames + tick - written;
        double t0 = now_ms(), ms;
        troupe_status st;
        pose.positions = reactor + written * J * 3;
        pose.positions_len = room * J * 3;
        st = troupe_session_step_joints(session, actor + done * J * 3, n, &pose, room, &got);
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
    if (write_npy(out_path, reactor, written) != 0) fprintf(stderr, "could not write %s\n", out_path);
    printf("troupe %s, bundle %s: %lu actor frames (%.0f fps) in ticks of %lu, %lu reactor frames -> %s\n",
           troupe_version_string(), bundle, (unsigned long)frames, (double)CLIP_FPS, (unsigned long)tick,
           (unsigned long)written, out_path);
    if (rule && strcmp(joints_path, default_clip) == 0) {
        char truth_path[256];
        float *truth = NULL;
        size_t truth_frames;
        snprintf(truth_path, sizeof truth_path, "tests/data/mocap/cmu-playground.%s.npy", rule);
        truth_frames = read_joints(truth_path, &truth);
        if (truth_frames > 0)
            printf("the %s rule's partner vs the reactor: %.1f cm mean per-joint error\n", rule,
                   mpjpe_cm(reactor, truth, written < truth_frames ? written : truth_frames));
        free(truth);
    }

    /* The picture plays both people at the bundle's rate: every stride-th actor frame. */
    stride = (size_t)(CLIP_FPS / (float)troupe_model_fps(model) + 0.5f);
    shown = written;
    both = (float *)malloc(2 * shown * J * 3 * sizeof(float) + 1);
    for (t = 0; t < shown; t++) memcpy(both + t * J * 3, actor + t * stride * J * 3, sizeof(float) * J * 3);
    if (shown > 0) memcpy(both + shown * J * 3, reactor, sizeof(float) * shown * J * 3);
    snprintf(html, sizeof html, "%.*s.html", (int)(strlen(out_path) - (strstr(out_path, ".npy") ? 4 : 0)), out_path);
    snprintf(gif, sizeof gif, "%.*s.gif", (int)(strlen(out_path) - (strstr(out_path, ".npy") ? 4 : 0)), out_path);
    format.fps = (float)troupe_model_fps(model);
    if (shown == 0)
        printf("no reactor frames yet: no picture\n");
    else if (troupe_viewer_write(html, gif, both, 2, shown, &format, names, "troupe: C streaming demo") != TROUPE_OK)
        fprintf(stderr, "pictures: %s\n", troupe_last_error_message());
    else
        printf("pictures: %s (open it in a browser) and %s\n", html, gif);
    if (token_calls > 0)
        printf("step latency (calls that produced a token, %lu): p50 %.3f ms  p99 %.3f ms  max %.3f ms\n",
               (unsigned long)token_calls, token_latency[token_calls / 2],
               token_latency[(size_t)((double)(token_calls - 1) * 0.99 + 0.5)], token_latency[token_calls - 1]);
    printf("real-time factor %.1fx\n", (double)frames / (double)CLIP_FPS * 1e3 / total);

    troupe_session_free(session);
    troupe_model_free(model);
    free(actor);
    free(condition);
    free(reactor);
    free(both);
    free(latency);
    free(token_latency);
    return 0;
}

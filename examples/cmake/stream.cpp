// Streams the installed demo model through troupe's C++ wrapper: an actor walks in a circle,
// one frame per call as an engine's update loop would feed it, and the partner's frames come
// back a token (4 frames) at a time. Built by examples/cmake/CMakeLists.txt against an
// installed troupe; prints what it streamed and exits non-zero on any error.
//
//   stream_cpp [BUNDLE] [FRAMES]
#include <troupe.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

int main(int argc, char **argv) {
    const std::string bundle = argc > 1 ? argv[1] : TROUPE_BUNDLE_DIR "/armflow-demo";
    const std::size_t frames = argc > 2 ? std::strtoul(argv[2], nullptr, 10) : 120;
    std::printf("troupe %s (C ABI %u)\n", troupe_version_string(), troupe_abi_version());

    troupe::Model model;
    troupe::Session session;
    if (troupe::Status s = troupe::Model::load(bundle, model); !s) {
        std::fprintf(stderr, "load %s: %s\n", bundle.c_str(), s.message().c_str());
        return 1;
    }
    if (troupe::Status s = troupe::Session::create(model, nullptr, session); !s) {
        std::fprintf(stderr, "session: %s\n", s.message().c_str());
        return 1;
    }

    // The actor: 22 joints, metres, y up, 30 fps (the format's defaults), walking round a circle.
    troupe_joints_format format;
    troupe_joints_format_init(&format, sizeof format);
    if (troupe::Status s = session.set_joints_format(format); !s) {
        std::fprintf(stderr, "joints format: %s\n", s.message().c_str());
        return 1;
    }
    std::vector<float> actor(TROUPE_MOTION_JOINTS * 3), partner;
    std::size_t produced = 0;
    double reach = 0.0;
    for (std::size_t t = 0; t < frames; t++) {
        const float a = 0.02f * static_cast<float>(t);
        for (std::size_t j = 0; j < TROUPE_MOTION_JOINTS; j++) {
            actor[3 * j + 0] = std::cos(a) + 0.01f * static_cast<float>(j % 3);
            actor[3 * j + 1] = 0.05f + 0.08f * static_cast<float>(j % 11);
            actor[3 * j + 2] = std::sin(a);
        }
        if (troupe::Status s = session.step_joints(actor.data(), 1, partner); !s) {
            std::fprintf(stderr, "frame %zu: %s\n", t, s.message().c_str());
            return 1;
        }
        for (float v : partner) {
            if (!std::isfinite(v)) {
                std::fprintf(stderr, "frame %zu: a partner coordinate is not finite\n", t);
                return 1;
            }
            reach = std::fmax(reach, std::fabs(v));
        }
        produced += partner.size() / (TROUPE_MOTION_JOINTS * 3);
    }
    std::printf("streamed %zu actor frames, %zu partner frames back, largest coordinate %.2f m\n",
                frames, produced, reach);
    return produced > 0 ? 0 : 1;
}

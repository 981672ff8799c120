// The C++ wrapper, compiled with -fno-exceptions: RAII, moves, status returns.
// Usage: wrapper ARMFLOW_BUNDLE_DIR UMF_BUNDLE_DIR [SCRATCH_DIR [DEMO_BUNDLE [INT8_DEMO_BUNDLE
//        [MAGNET_BUNDLE]]]]
#include "troupe.hpp"
#include "../c/check.h"
#include "../c/npy.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

static std::vector<float> run(troupe::Session &s, const std::vector<float> &actor, std::size_t frames) {
    // Room for a token more than the frames fed: a restored stream sends the frames it held.
    const std::size_t room = frames + 4;
    std::vector<float> out(room * s.frame_dim());
    std::size_t written = 0;
    for (std::size_t t = 0; t < frames; t++) {
        std::size_t n = 0;
        troupe::Status st = s.step(&actor[t * s.frame_dim()], 1, &out[written * s.frame_dim()], room - written, n);
        if (!st) {
            std::fprintf(stderr, "step: %s\n", st.message().c_str());
            return {};
        }
        written += n;
    }
    out.resize(written * s.frame_dim());
    return out;
}

static std::atomic<int> log_records{0};
static void count_log(void *, std::int32_t, const char *, const char *) { log_records++; }

int main(int argc, char **argv) {
    if (argc < 3) return 2;
    CHECK(troupe::abi_compatible());
    CHECK(troupe::version_number() == TROUPE_VERSION_NUMBER && troupe::version() == TROUPE_VERSION_STRING);
    {
        // Process-wide settings: set, read back, restored.
        const std::size_t compute = troupe::compute_threads(), load = troupe::load_threads();
        CHECK(troupe::set_compute_threads(1).ok() && troupe::compute_threads() == 1);
        CHECK(troupe::set_compute_threads(compute).ok());
        troupe::set_load_threads(1);
        CHECK(troupe::load_threads() == 1);
        troupe::set_load_threads(load);
        troupe_call_budget budget{};
        budget.max_seconds = -1.0;
        CHECK(troupe::set_call_budget(budget).code() == TROUPE_ERR_INVALID_ARG);
        budget.max_seconds = 0.0;
        CHECK(troupe::set_call_budget(budget).ok());
    }
    CHECK(troupe::limits().values.max_steps == 10000);
    troupe::Model missing;
    troupe::Status bad = troupe::Model::load("/nonexistent/bundle", missing);
    CHECK(!bad && bad.code() == TROUPE_ERR_IO && !bad.message().empty() && !missing.valid());

    troupe::Model model;
    {
        // A load cancelled at its first progress report, then one that reports every graph.
        std::uint64_t reports = 0;
        {
            troupe::ProgressScope<bool (*)(std::uint64_t, std::uint64_t)> stop(
                [](std::uint64_t, std::uint64_t) { return false; });
            troupe::Status cancelled = troupe::Model::load(argv[1], model);
            CHECK(cancelled.code() == TROUPE_ERR_CANCELLED && !model.valid());
        }
        auto count = [&reports](std::uint64_t done, std::uint64_t total) {
            reports++;
            return done <= total;
        };
        troupe::ProgressScope<decltype(count)> progress(count);
        CHECK(troupe::Model::load(argv[1], model).ok());
        CHECK(reports >= 5);
    }

    // Named conditions: none on the plain bundle; the demo bundle's partner rules by name.
    {
        std::vector<float> v{9.0f};
        CHECK(model.condition_labels().empty());
        CHECK(model.reduced_precision().empty());
        CHECK(!model.condition_for("mirror", v) && v.size() == 1 && v[0] == 9.0f);
        troupe::Model demo;
        if (argc > 4 && troupe::Model::load(argv[4], demo).ok()) {
            CHECK((demo.condition_labels() == std::vector<std::string>{"mirror", "follow", "keep-away"}));
            // Joint positions add the feature stream's latency and the motion stages' own.
            CHECK(demo.joints_latency_frames() > demo.latency_frames());
            CHECK(demo.condition_for("follow", v).ok() && (v == std::vector<float>{0.0f, 1.0f, 0.0f}));
            troupe::Status unknown = demo.condition_for("dance", v);
            CHECK(unknown.code() == TROUPE_ERR_INVALID_ARG && v.size() == 3);
        } else {
            CHECK(argc <= 4);
        }
        troupe::Model int8;
        if (argc > 5 && troupe::Model::load(argv[5], int8).ok()) {
            using Graphs = std::vector<std::pair<std::string, std::string>>;
            CHECK((int8.reduced_precision() == Graphs{{"context_layers", "int8"}, {"velocity", "int8"}}));
        } else {
            CHECK(argc <= 5);
        }
    }
    troupe_session_options opt;
    CHECK(model.default_options(opt).ok());
    opt.seed = 5;
    troupe::Session a, b;
    CHECK(troupe::Session::create(model, &opt, a).ok());
    CHECK(troupe::Session::create(model, &opt, b).ok());

    const std::size_t frames = 24, dim = model.frame_dim();
    std::vector<float> actor(frames * dim);
    for (std::size_t i = 0; i < actor.size(); i++) actor[i] = 0.3f * std::sin(0.01f * static_cast<float>(i));
    std::vector<float> ra = run(a, actor, frames);
    CHECK(ra.size() == frames * dim);

    troupe::Session moved(std::move(b));  // moves keep the stream; the source is empty
    CHECK(moved.valid() && !b.valid());
    CHECK(run(moved, actor, frames) == ra);
    CHECK(!b.reset() && b.reset().code() == TROUPE_ERR_NULL_ARG);

    // A snapshot at frame 10 restored into a new session continues as the whole stream.
    {
        troupe::Session half, resumed;
        CHECK(troupe::Session::create(model, &opt, half).ok());
        std::vector<float> head = run(half, actor, 10);
        std::vector<std::uint8_t> bytes;
        CHECK(half.snapshot(bytes).ok() && bytes.size() > 64);
        std::uint8_t id[32];
        CHECK(model.identity(id).ok() && std::memcmp(id, bytes.data() + 23, 32) == 0);
        CHECK(troupe::Session::restore(model, bytes.data(), bytes.size(), resumed).ok());
        std::vector<float> rest_in(actor.begin() + 10 * dim, actor.end());
        std::vector<float> rest = run(resumed, rest_in, frames - 10);
        head.insert(head.end(), rest.begin(), rest.end());
        CHECK(head == ra);
        // Sealed with a key: restored with it, refused with another.
        const std::vector<std::uint8_t> key(32, 7), other(32, 8);
        std::vector<std::uint8_t> sealed;
        CHECK(troupe::Session::seal(bytes, key, sealed).ok() && sealed.size() > bytes.size());
        troupe::Session unsealed, forged;
        CHECK(troupe::Session::restore_sealed(model, sealed, key, unsealed).ok() && unsealed.valid());
        CHECK(troupe::Session::restore_sealed(model, sealed, other, forged).code() == TROUPE_ERR_INVALID_ARG);
        CHECK(!forged.valid());
        bytes[bytes.size() / 2] ^= 1;
        troupe::Session refused;
        troupe::Status st = troupe::Session::restore(model, bytes.data(), bytes.size(), refused);
        CHECK(!st && st.code() == TROUPE_ERR_INVALID_ARG && !refused.valid());
        CHECK(st.message().find("checksum") != std::string::npos);
        std::vector<std::uint8_t> none;
        CHECK(!b.snapshot(none) && none.empty());
    }

    // Many sessions in one call: each equals the session stepped alone.
    {
        troupe::Session c1, c2;
        CHECK(troupe::Session::create(model, &opt, c1).ok() && troupe::Session::create(model, &opt, c2).ok());
        std::vector<std::vector<float>> outs, crowd(2);
        for (std::size_t t = 0; t < frames; t += 4) {
            CHECK(troupe::step_sessions({&c1, &c2}, {&actor[t * dim], &actor[t * dim]}, {4, 4}, outs).ok());
            for (std::size_t k = 0; k < 2; k++) crowd[k].insert(crowd[k].end(), outs[k].begin(), outs[k].end());
        }
        float worst = 0.0f;
        for (std::size_t k = 0; k < 2; k++) {
            CHECK(crowd[k].size() == ra.size());
            for (std::size_t i = 0; i < ra.size() && crowd[k].size() == ra.size(); i++)
                worst = std::fmax(worst, std::fabs(crowd[k][i] - ra[i]));
        }
        CHECK(worst <= 1e-5f);
        troupe::Status dup = troupe::step_sessions({&c1, &c1}, {actor.data(), actor.data()}, {4, 4}, outs);
        CHECK(dup.code() == TROUPE_ERR_INVALID_ARG && outs.size() == 2);
        CHECK(troupe::step_sessions({&c1, &c2}, {actor.data()}, {4, 4}, outs).code() == TROUPE_ERR_NULL_ARG);
    }

    std::vector<float> cond(model.condition_dim() + 1, 0.0f);
    CHECK(a.set_condition(cond.data(), cond.size()).code() == TROUPE_ERR_SHAPE);
    CHECK(a.reset().ok());
    CHECK(run(a, actor, frames) == ra);

    troupe::Model other = std::move(model);  // the sessions keep the model alive regardless
    other = troupe::Model();
    CHECK(a.reset().ok() && run(a, actor, frames) == ra);

    // Groups: defaults, a seed, determinism, and a failure that leaves the output alone.
    troupe::Model umf;
    // Loading logs at debug level: the records reach a callback, then stderr again.
    CHECK(troupe::set_log_callback(count_log, nullptr, TROUPE_LOG_DEBUG).ok());
    CHECK(troupe::Model::load(argv[2], umf).ok());
    CHECK(troupe::set_log_callback(nullptr, nullptr, TROUPE_LOG_WARN).ok() && log_records > 0);
    CHECK(umf.umf().stages() == 2 && umf.clip_frames() == 40 && umf.umf().tokens() == 16);
    {
        std::size_t prior = 0, jumps = 0, reactions = 0;
        CHECK(umf.umf().noise_lengths(2, prior, jumps, reactions).ok() && prior > 0);
        troupe_magnet_options mo;
        CHECK(troupe::Model::Magnet::default_options(mo).ok() && mo.struct_size == sizeof mo);
        troupe_arflow_options ao;
        CHECK(umf.arflow().default_options(ao).code() == TROUPE_ERR_UNSUPPORTED);
        std::vector<float> reaction, no_draws(8);
        std::size_t used = 0;
        CHECK(umf.arflow().generate_with_draws(no_draws.data(), 1, no_draws, reaction, used).code() ==
              TROUPE_ERR_UNSUPPORTED && reaction.empty());
        troupe_armflow_session_options so;
        CHECK(umf.armflow().default_session_options(so).code() == TROUPE_ERR_UNSUPPORTED);
        // The tiny UMF bundle has a text branch: CLIP token features in, a condition out.
        const std::size_t width = umf.text_token_dim();
        CHECK(width > 0);
        std::vector<float> tokens(4 * width), condition;
        for (std::size_t i = 0; i < tokens.size(); i++) tokens[i] = 0.01f * static_cast<float>(i % 17);
        CHECK(umf.encode_text(tokens.data(), 4, 3, condition).ok() && condition.size() == umf.condition_dim());
        std::vector<float> kept = condition;
        CHECK(umf.encode_text(tokens.data(), 4, 4, condition).code() == TROUPE_ERR_INVALID_ARG && condition == kept);
    }
    troupe_group_options gopt;
    CHECK(umf.umf().default_options(gopt).ok() && gopt.stage_count == 2);
    gopt.seed = 3;
    std::vector<float> g1, g2;
    CHECK(umf.umf().generate_group(nullptr, 0, 2, g1, &gopt).ok());
    CHECK(g1.size() == 2 * umf.clip_frames() * umf.frame_dim());
    CHECK(umf.umf().generate_group(nullptr, 0, 2, g2, &gopt).ok() && g1 == g2);
    troupe::Status none = umf.umf().generate_group(nullptr, 0, 0, g2, &gopt);
    CHECK(none.code() == TROUPE_ERR_INVALID_ARG && g1 == g2);
    CHECK(other.umf().generate_group(nullptr, 0, 1, g2).code() == TROUPE_ERR_NULL_ARG);

    // Prompts: the bundle's tokenizer, CLIP tower and text branches give a condition.
    CHECK(umf.takes_prompts() && !other.takes_prompts());
    std::vector<float> p1, p2;
    CHECK(umf.encode_prompt("two people shake hands", p1).ok() && p1.size() == umf.condition_dim());
    CHECK(umf.encode_prompt("two people shake hands", p2).ok() && p1 == p2);
    CHECK(umf.umf().generate_group(p1.data(), p1.size(), 2, g2, &gopt).ok() && g1 != g2);
    CHECK(other.encode_prompt("hello", p2).code() == TROUPE_ERR_NULL_ARG && p1 == p2);

    // MAGNet: released configurations, a changed one, determinism, a failure that leaves the
    // output alone.
    if (argc > 6) {
        troupe::Model magnet;
        CHECK(troupe::Model::load(argv[6], magnet).ok());
        const std::vector<std::string> configs = magnet.magnet().configs();
        CHECK(magnet.magnet().people() == 2 && configs.size() == 8);
        CHECK(std::find(configs.begin(), configs.end(), "dd100") != configs.end());
        CHECK(umf.magnet().people() == 0 && umf.magnet().configs().empty());
        std::size_t n = 0;
        float *clip = read_npy(argv[6], "frames", &n);
        CHECK(clip != nullptr && n == 128 * 2 * 145);
        std::vector<float> posed;
        CHECK(troupe::motion::smplx145_positions(clip, 4, posed).ok() && posed.size() == 4 * 66);
        CHECK(std::isfinite(posed[0]) && posed[3 * 15 + 1] > posed[1]);
        troupe_magnet_options mopt;
        CHECK(troupe_magnet_options_init(&mopt, sizeof mopt) == TROUPE_OK);
        mopt.samples = 1;
        mopt.steps = 2;
        mopt.seq_len = 64;
        mopt.flags = TROUPE_MAGNET_NO_X0_GUIDANCE;
        std::vector<float> m1, m2;
        std::size_t shape[3] = {0, 0, 0};
        CHECK(magnet.magnet().generate("dd100", clip, 128, m1, shape, &mopt).ok());
        CHECK(shape[0] == 1 && shape[1] == 64 && shape[2] == 2 && m1.size() == 64 * 2 * 145);
        CHECK(magnet.magnet().generate("dd100", clip, 128, m2, shape, &mopt).ok() && m1 == m2);
        // Given draws: a run that needs more than given is refused; the same draws, the same run.
        std::vector<float> draws(1 << 20), d1, d2;
        for (std::size_t i = 0; i < draws.size(); i++) draws[i] = std::sin(0.37f * static_cast<float>(i));
        std::size_t used = 0;
        CHECK(magnet.magnet().generate_with_draws("dd100", clip, 128, draws, d1, shape, used, &mopt).ok());
        CHECK(used > 0 && used < draws.size() && d1.size() == m1.size());
        CHECK(magnet.magnet().generate_with_draws("dd100", clip, 128, draws, d2, shape, used, &mopt).ok() && d1 == d2);
        const std::vector<float> few(used - 1);
        CHECK(magnet.magnet().generate_with_draws("dd100", clip, 128, few, d2, shape, used, &mopt).code() ==
              TROUPE_ERR_INVALID_ARG);
        troupe::Status missing = magnet.magnet().generate("nope", clip, 128, m2, shape, &mopt);
        CHECK(missing.code() == TROUPE_ERR_INVALID_ARG && m1 == m2);
        CHECK(missing.message().find("no sampling configuration") != std::string::npos);

        // The live partner through a session: person 0 the user, person 1's first 32 frames the
        // opening; two steps, exact output counts, the same stream again after a reset.
        troupe::Session live;
        CHECK(troupe::Session::create(magnet, nullptr, live).ok());
        std::vector<float> user(128 * 145), opening(32 * 145);
        for (std::size_t t = 0; t < 128; t++)
            std::copy(clip + t * 2 * 145, clip + t * 2 * 145 + 145, user.begin() + t * 145);
        for (std::size_t t = 0; t < 32; t++)
            std::copy(clip + (t * 2 + 1) * 145, clip + (t * 2 + 1) * 145 + 145, opening.begin() + t * 145);
        std::size_t ready = 0, written = 0;
        troupe::Status early = live.step(user.data(), 1, nullptr, 0, written);
        CHECK(early.code() == TROUPE_ERR_INVALID_ARG);
        CHECK(live.magnet().set_live_config("{\"task\": 1}").code() == TROUPE_ERR_INVALID_ARG);
        CHECK(live.set_steps(2).ok() && live.magnet().set_partner_opening(opening.data(), 32).ok());
        CHECK(live.magnet().set_early_emission(true).ok());
        CHECK(live.output_frames(64, ready).ok() && ready == 64);
        std::vector<float> partner(128 * 145), again(128 * 145);
        CHECK(live.step(user.data(), 64, partner.data(), 128, written).ok() && written == 64);
        CHECK(live.step(user.data() + 64 * 145, 64, partner.data() + 64 * 145, 64, written).ok() && written == 64);
        CHECK(live.magnet().set_early_emission(false).code() == TROUPE_ERR_INVALID_ARG);
        CHECK(live.reset().ok());
        CHECK(live.step(user.data(), 128, again.data(), 128, written).ok() && written == 128);
        CHECK(partner == again);
        std::free(clip);
    }

    // ARFlow: the defaults, a changed setting, a failure that leaves the output alone.
    if (argc > 7) {
        troupe::Model arflow;
        CHECK(troupe::Model::load(argv[7], arflow).ok());
        std::size_t n = 0;
        float *actor = read_npy(argv[7], "actor", &n);
        CHECK(actor != nullptr && n == 40 * 262);
        std::vector<float> guided, plain, kept;
        CHECK(arflow.arflow().generate(actor, 40, guided).ok() && guided.size() == n);
        troupe_arflow_options aopt;
        CHECK(troupe_arflow_options_init(arflow.get(), &aopt, sizeof aopt) == TROUPE_OK);
        aopt.guidance = 0.0f;
        CHECK(arflow.arflow().generate(actor, 40, plain, &aopt).ok() && plain != guided);
        kept = plain;
        troupe::Model reactor_model;
        CHECK(troupe::Model::load(argv[1], reactor_model).ok());
        troupe::Session reactor;
        CHECK(troupe::Session::create(reactor_model, nullptr, reactor).ok());
        CHECK(reactor.set_penetration_guard(true).ok());
        CHECK(reactor.set_penetration_guard(true, -1.0f).code() == TROUPE_ERR_INVALID_ARG);
        CHECK(reactor.set_penetration_guard(false).ok());
        CHECK(reactor.arflow().set_options(aopt).code() == TROUPE_ERR_UNSUPPORTED);
        aopt.weight = 2.0f;
        troupe::Status refused = arflow.arflow().generate(actor, 40, plain, &aopt);
        CHECK(refused.code() == TROUPE_ERR_INVALID_ARG && plain == kept);
        std::free(actor);
    }

    // The family views: the model's family, ARMFlow's own session options, the official clip.
    {
        CHECK(umf.family() == "umf");
        troupe::Model plain;
        CHECK(troupe::Model::load(argv[1], plain).ok() && plain.family() == "armflow");
        troupe_armflow_session_options arm;
        CHECK(troupe_armflow_session_options_init(plain.get(), &arm, sizeof arm) == TROUPE_OK);
        arm.cfg_scale = 2.0f;
        troupe::Session guided, refused;
        CHECK(troupe::Session::create_armflow(plain, nullptr, &arm, guided).ok());
        std::uint32_t caps = 0;
        CHECK(guided.capabilities(caps).ok() && (caps & TROUPE_CAP_CFG_SCALE) != 0);
        CHECK((caps & TROUPE_CAP_PROMPT) == 0 && guided.set_prompt("wave").code() == TROUPE_ERR_UNSUPPORTED);
        CHECK(troupe::Session::create_armflow(umf, nullptr, nullptr, refused).code() == TROUPE_ERR_UNSUPPORTED);
        CHECK(!refused.valid());
        std::vector<float> untouched{1.0f};
        CHECK(!plain.armflow().generate_clip(nullptr, 0, untouched) && untouched.size() == 1);  // no clip
        if (argc > 8) {
            troupe::Model clip;
            CHECK(troupe::Model::load(argv[8], clip).ok());
            const std::size_t n = clip.clip_frames(), dim = clip.frame_dim();
            CHECK(n > 0 && clip.armflow().clip_tokens() > 0);
            std::vector<float> actor(n * dim), out, direct(n * dim);
            for (std::size_t i = 0; i < actor.size(); i++) actor[i] = 0.02f * std::sin(static_cast<float>(i));
            troupe_armflow_clip_options copt;
            CHECK(clip.armflow().default_clip_options(copt).ok());
            copt.seed = 5;
            CHECK(clip.armflow().generate_clip(actor.data(), n, out, nullptr, 0, &copt).ok() && out.size() == n * dim);
            CHECK(troupe_armflow_clip_generate_with_options(clip.get(), &copt, actor.data(), n, nullptr, 0, nullptr,
                                                            direct.data(), direct.size(), nullptr, 0) == TROUPE_OK);
            CHECK(out == direct);
        }
    }

    // ---- motion: skeleton, positions <-> features, joint sessions, files ----
    {
        troupe::Model model;
        CHECK(troupe::Model::load(argv[1], model).ok());
        const troupe::motion::Skeleton skel = troupe::motion::skeleton();
        CHECK(skel.names.size() == 22 && skel.names[0] == "pelvis" && skel.parents[4] == 1);
        // The neutral body walking along x, 40 frames, metres, y up, 30 fps.
        const std::size_t frames = 40;
        std::vector<float> clip(frames * 22 * 3), rest(22 * 3);
        for (std::size_t j = 0; j < 22; j++)
            for (int d = 0; d < 3; d++)
                rest[j * 3 + d] = skel.rest_offsets[j * 3 + d] + (skel.parents[j] >= 0 ? rest[skel.parents[j] * 3 + d] : 0.0f);
        for (std::size_t t = 0; t < frames; t++)
            for (std::size_t j = 0; j < 22; j++)
                for (int d = 0; d < 3; d++) clip[(t * 22 + j) * 3 + d] = rest[j * 3 + d] + (d == 2 ? 0.02f * t : 0.0f);
        const troupe_joints_format fmt = troupe::motion::format(TROUPE_UNITS_METERS, TROUPE_UP_Y, 30.0f);
        std::vector<float> features, back, rotations;
        troupe_placement placement;
        CHECK(troupe::motion::encode(model, fmt, clip.data(), frames, features, placement).ok());
        CHECK(features.size() == (frames - 1) * 262);
        CHECK(troupe::motion::decode(model, fmt, placement, features.data(), frames - 1, back, &rotations).ok());
        float worst = 0.0f;
        for (std::size_t i = 0; i < back.size(); i++) worst = std::max(worst, std::fabs(back[i] - clip[i]));
        CHECK(worst < 1e-5f && rotations.size() == (frames - 1) * 22 * 4);
        std::vector<float> kept = features;
        clip[5] = NAN;
        CHECK(troupe::motion::encode(model, fmt, clip.data(), frames, features, placement).code() ==
              TROUPE_ERR_INVALID_ARG);
        CHECK(features == kept);
        clip[5] = rest[5];
        // The same clip a frame at a time: the stream's frames are encode's, one frame late.
        {
            troupe::motion::Stream stream;
            CHECK(troupe::motion::Stream::create(model, fmt, stream).ok());
            CHECK(troupe::motion::Stream::latency_frames() == 1);
            std::vector<float> streamed;
            for (std::size_t t = 0; t < frames; t++) CHECK(stream.push(&clip[t * 66], streamed).ok());
            CHECK(streamed.size() == features.size());
            float apart = 0.0f;
            for (std::size_t i = 0; i < streamed.size(); i++) apart = std::max(apart, std::fabs(streamed[i] - features[i]));
            CHECK(apart < 1e-4f);
            troupe_placement used;
            CHECK(stream.placement(used).ok() && std::fabs(used.floor - placement.floor) < 1e-6f);
            CHECK(stream.reset().ok());
            std::vector<float> bad(clip.begin(), clip.begin() + 66);
            bad[0] = NAN;
            std::vector<float> none;
            CHECK(stream.push(bad.data(), none).code() == TROUPE_ERR_INVALID_ARG && none.empty());
        }
        // Two people: the clip and itself 5 cm aside intersect in every frame.
        {
            std::vector<float> aside(clip);
            for (std::size_t i = 0; i < aside.size(); i += 3) aside[i] += 0.05f;
            troupe::motion::PenetrationMetrics m;
            CHECK(troupe::motion::penetration_metrics(clip.data(), aside.data(), frames, m).ok());
            CHECK(m.frames_intersecting == frames && m.frequency == 1.0 && m.max_depth > 0.0);
            CHECK(troupe::motion::penetration_metrics(clip.data(), nullptr, frames, m).code() == TROUPE_ERR_NULL_ARG);
        }

        troupe::Session joints;
        CHECK(troupe::Session::create(model, &opt, joints).ok());
        CHECK(joints.set_joints_format(fmt).ok());
        std::vector<float> poses;
        CHECK(joints.step_joints(clip.data(), frames, poses).ok());
        CHECK(poses.size() == 36 * 22 * 3);  // 39 feature frames: 9 tokens of 4
        CHECK(joints.joints_placement(placement).ok());
        // The foot lock and the guard: settings in range are taken, others refused.
        CHECK(joints.set_foot_lock(true).ok() && joints.set_penetration_guard(true).ok());
        CHECK(joints.set_foot_lock(true, 0.5f, 0).code() == TROUPE_ERR_INVALID_ARG);
        CHECK(joints.set_foot_lock(false).ok());
        CHECK(joints.set_root_smoothing(true).ok() && joints.set_root_smoothing(true, -1.0f).code() == TROUPE_ERR_INVALID_ARG);
        // Recentring: a distance in range is taken, others refused; the stream goes on with it.
        CHECK(joints.armflow().set_recentring(true).ok() && joints.armflow().set_recentring(true, 0.0f).code() == TROUPE_ERR_INVALID_ARG);
        CHECK(joints.step_joints(clip.data(), frames, poses).ok() && !poses.empty());
        CHECK(joints.armflow().set_recentring(false).ok());

        if (argc > 3) {
            // Named after this binary: the builds with and without exceptions share the directory.
            const std::string self = std::strrchr(argv[0], '/') ? std::strrchr(argv[0], '/') + 1 : argv[0];
            const std::string base = std::string(argv[3]) + "/" + self;
            const std::string bvh = base + ".bvh", json = base + ".json", html = base + ".html";
            CHECK(troupe::motion::write_bvh(bvh, {"actor"}, clip.data(), frames, fmt).ok());
            troupe::motion::Take take;
            CHECK(troupe::motion::read_bvh(bvh, take).ok() && take.frames == frames);
            CHECK(take.inferred.empty() && take.mapping[0] == "pelvis" && take.mapping[21] == "right_wrist");
            CHECK(take.format.units == TROUPE_UNITS_CENTIMETERS);
            CHECK(std::fabs(take.positions[3 * 15 + 1] / 100.0f - clip[3 * 15 + 1]) < 1e-4f);
            CHECK(troupe::motion::read_bvh(base + "-missing.bvh", take).code() == TROUPE_ERR_IO);
            // The file as a rig: the clip retargeted onto it a frame at a time, and a glTF file.
            troupe::motion::Rig rig;
            CHECK(troupe::motion::Rig::from_bvh(bvh, rig).ok() && rig.joint_count() == 22);
            CHECK(rig.joint_name(0) == "pelvis" && rig.joint_name(22).empty());
            troupe::motion::Retargeter retargeter;
            CHECK(troupe::motion::Retargeter::create(rig, fmt, retargeter).ok());
            troupe::motion::RigPose pose;
            CHECK(retargeter.push(clip.data(), pose).ok() && pose.rotations.size() == 88 && pose.root_joint == 0);
            CHECK(troupe::motion::Rig::from_bvh(base + "-missing.bvh", rig).code() == TROUPE_ERR_IO);
            const std::string glb = base + ".glb";
            std::array<std::int64_t, 22> drives{};
            CHECK(retargeter.mapping(drives).ok() && drives[0] == 0 && drives[21] >= 0);
            std::vector<troupe::motion::RigPose> poses;
            CHECK(troupe::motion::retarget_clip(rig, clip.data(), frames, fmt, poses).ok() && poses.size() == frames);
            CHECK(poses[0].rotations.size() == 88 && poses[0].root_joint == 0);
            CHECK(troupe::motion::write_gltf(glb, {"actor"}, clip.data(), frames, fmt, &rig).ok());
            CHECK(troupe::motion::write_gltf(glb, {}, clip.data(), frames, fmt).code() == TROUPE_ERR_INVALID_ARG);
            // The glTF file's skin as a rig, and the clip on the rig as BVH and FBX, read back.
            troupe::motion::Rig from_glb;
            CHECK(troupe::motion::Rig::from_gltf(glb, from_glb).ok() && from_glb.joint_count() == 22);
            CHECK(troupe::motion::Rig::from_gltf(glb, from_glb, 5).code() == TROUPE_ERR_INVALID_ARG);
            CHECK(troupe::motion::write_gltf_people(glb, {{"actor", clip.data(), frames}, {"late", clip.data(), frames / 2}},
                                                    fmt, &rig)
                      .ok());
            CHECK(troupe::motion::write_gltf_people(glb, {{"actor", clip.data(), 0}}, fmt).code() ==
                  TROUPE_ERR_INVALID_ARG);
            std::remove(glb.c_str());
            const std::string on_rig = base + "-rig.bvh", fbx = base + ".fbx";
            CHECK(troupe::motion::write_rig_bvh(on_rig, rig, clip.data(), frames, fmt).ok());
            CHECK(troupe::motion::write_rig_fbx(fbx, rig, clip.data(), frames, fmt).ok());
            CHECK(troupe::motion::write_rig_fbx(fbx, rig, clip.data(), frames, fmt, 9).code() ==
                  TROUPE_ERR_INVALID_ARG);
            troupe::motion::Rig from_fbx;
            CHECK(troupe::motion::Rig::from_fbx(fbx, from_fbx).ok() && from_fbx.joint_count() == 22);
            CHECK(troupe::motion::read_bvh(fbx, take).ok() && take.frames == frames);
            std::remove(on_rig.c_str());
            std::remove(fbx.c_str());
            CHECK(troupe::motion::write_json(json, {"actor"}, clip.data(), frames, fmt).ok());
            CHECK(troupe::motion::write_pictures(html, "", {"actor"}, clip.data(), frames, fmt).ok());
            CHECK(troupe::motion::write_pictures("", "", {"actor"}, clip.data(), frames, fmt).code() ==
                  TROUPE_ERR_NULL_ARG);
            std::remove(bvh.c_str());
            std::remove(json.c_str());
            std::remove(html.c_str());
        }
    }

#ifdef TROUPE_CPP_EXCEPTIONS
    bool thrown = false;
    try {
        troupe::Model::load_or_throw("/nonexistent/bundle");
    } catch (const troupe::Error &e) {
        thrown = e.code() == TROUPE_ERR_IO;
    }
    CHECK(thrown);
    troupe::Model again = troupe::Model::load_or_throw(argv[1]);
    troupe::Session s = troupe::Session::create_or_throw(again);
    CHECK(s.valid());
#endif

    std::printf("c++ wrapper: %d passed, %d failed\n", passed, failed);
    return failed == 0 ? 0 : 1;
}

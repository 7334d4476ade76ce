// ACL 2.1.0 on the same clips and machine as `quatcurve bench --fitted`: each raw clip of
// `examples/acl_raw.rs` compressed at ACL's defaults (0.01 cm at virtual vertices 3 cm from each
// joint, in the clip's units), then decompressed as the bench decodes a fitted clip: every
// frame in order, `copies` copies of the clip one after another, warm cache, one thread.
// Prints the ratio (raw bytes as ACL counts them, 40 per joint per frame) and the median of
// `runs` runs in ns per bone-pose.
//
// Build and run: examples/acl/run.sh.

#include <acl/compression/compress.h>
#include <acl/compression/track_array.h>
#include <acl/compression/transform_error_metrics.h>
#include <acl/core/ansi_allocator.h>
#include <acl/decompression/decompress.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

namespace {

struct PoseWriter final : public acl::track_writer {
    rtm::qvvf* pose;
    explicit PoseWriter(rtm::qvvf* p) : pose(p) {}
    void RTM_SIMD_CALL write_rotation(uint32_t i, rtm::quatf_arg0 r) { pose[i].rotation = r; }
    void RTM_SIMD_CALL write_translation(uint32_t i, rtm::vector4f_arg0 t) { pose[i].translation = t; }
    void RTM_SIMD_CALL write_scale(uint32_t i, rtm::vector4f_arg0 s) { pose[i].scale = s; }
};

// As ACL's own decompression benchmark (tools/acl_decompressor) sets them.
struct Settings final : public acl::default_transform_decompression_settings {
    static constexpr acl::compressed_tracks_version16 version_supported() {
        return acl::compressed_tracks_version16::latest;
    }
    static constexpr bool skip_initialize_safety_checks() { return true; }
};

struct Raw {
    uint32_t joints = 0, frames = 0;
    float rate = 0;
    std::vector<int32_t> parents;
    std::vector<float> values;  // per frame per joint: rotation x y z w, translation x y z
};

bool read_raw(const char* path, Raw& raw) {
    FILE* f = std::fopen(path, "rb");
    if (!f) return false;
    bool ok = std::fread(&raw.joints, 4, 1, f) == 1 && std::fread(&raw.frames, 4, 1, f) == 1 &&
              std::fread(&raw.rate, 4, 1, f) == 1;
    if (ok) {
        raw.parents.resize(raw.joints);
        raw.values.resize(size_t(raw.joints) * raw.frames * 7);
        ok = std::fread(raw.parents.data(), 4, raw.joints, f) == raw.joints &&
             std::fread(raw.values.data(), 4, raw.values.size(), f) == raw.values.size();
    }
    std::fclose(f);
    return ok;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: harness CLIP.raw [COPIES [RUNS]]\n");
        return 2;
    }
    const int copies = argc > 2 ? std::atoi(argv[2]) : 10;
    const int runs = argc > 3 ? std::atoi(argv[3]) : 9;
    Raw raw;
    if (!read_raw(argv[1], raw)) {
        std::fprintf(stderr, "%s: not a raw clip of examples/acl_raw.rs\n", argv[1]);
        return 2;
    }
    acl::ansi_allocator allocator;
    acl::track_array_qvvf tracks(allocator, raw.joints);
    for (uint32_t j = 0; j < raw.joints; ++j) {
        acl::track_desc_transformf desc;
        desc.output_index = j;
        desc.parent_index = raw.parents[j] < 0 ? acl::k_invalid_track_index : uint32_t(raw.parents[j]);
        desc.precision = 0.01F;
        desc.shell_distance = 3.0F;
        acl::track_qvvf track = acl::track_qvvf::make_reserve(desc, allocator, raw.frames, raw.rate);
        for (uint32_t s = 0; s < raw.frames; ++s) {
            const float* v = &raw.values[(size_t(s) * raw.joints + j) * 7];
            track[s].rotation = rtm::quat_normalize(rtm::quat_set(v[0], v[1], v[2], v[3]));
            track[s].translation = rtm::vector_set(v[4], v[5], v[6]);
            track[s].scale = rtm::vector_set(1.0F);
        }
        tracks[j] = std::move(track);
    }
    acl::compression_settings settings = acl::get_default_compression_settings();
    acl::qvvf_transform_error_metric metric;
    settings.error_metric = &metric;
    acl::output_stats stats;
    acl::compressed_tracks* compressed = nullptr;
    const acl::error_result result = acl::compress_track_list(allocator, tracks, settings, compressed, stats);
    if (result.any()) {
        std::fprintf(stderr, "%s: ACL did not compress it: %s\n", argv[1], result.c_str());
        return 1;
    }
    const double bone_poses = double(raw.joints) * raw.frames;
    std::printf("%s: %u joints, %u frames at %g Hz; ACL %u bytes, %.2f:1\n", argv[1], raw.joints, raw.frames,
                raw.rate, compressed->get_size(), bone_poses * 40.0 / compressed->get_size());

    // Each copy in its own 16-byte aligned buffer, as a decoder holds many clips.
    std::vector<std::vector<uint8_t>> buffers(copies, std::vector<uint8_t>(compressed->get_size() + 16));
    std::vector<acl::compressed_tracks*> clips;
    for (auto& buffer : buffers) {
        uint8_t* p = reinterpret_cast<uint8_t*>((reinterpret_cast<uintptr_t>(buffer.data()) + 15) & ~uintptr_t(15));
        std::memcpy(p, compressed, compressed->get_size());
        clips.push_back(reinterpret_cast<acl::compressed_tracks*>(p));
    }
    std::vector<rtm::qvvf> poses(size_t(raw.joints) * raw.frames);
    std::vector<double> seconds;
    for (int run = 0; run < runs; ++run) {
        const auto start = std::chrono::steady_clock::now();
        for (acl::compressed_tracks* clip : clips) {
            acl::decompression_context<Settings> context;
            context.initialize(*clip);
            for (uint32_t s = 0; s < raw.frames; ++s) {
                context.seek(float(s) / raw.rate, acl::sample_rounding_policy::none);
                PoseWriter writer(&poses[size_t(s) * raw.joints]);
                context.decompress_tracks(writer);
            }
        }
        seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    }
    // Read the output, so that no decompression is optimized away.
    double sum = 0;
    for (const rtm::qvvf& p : poses) sum += double(rtm::quat_get_w(p.rotation));
    std::sort(seconds.begin(), seconds.end());
    const double median = seconds[seconds.size() / 2];
    std::printf("ACL decompression, %d copies, every frame, one thread: %.2f ns a bone-pose (median of %d runs; "
                "checksum %.3f)\n",
                copies, median * 1e9 / (bone_poses * copies), runs, sum);
    allocator.deallocate(compressed, compressed->get_size());
    return 0;
}

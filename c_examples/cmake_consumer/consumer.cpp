// consumer.cpp: a C++17 program that uses an installed Antumbra the way an engine
// would: found through CMake's find_package or pkg-config, not through this
// repository. It casts rays at a square and rasterizes the hemisphere mask of a
// point under it, and checks each answer against geometry it can work out itself.
#include <antumbra.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>

namespace {

// Owns a scene handle; antumbra_scene_destroy(NULL) is allowed, so the deleter need not check.
struct SceneDeleter {
    void operator()(antumbra_scene *scene) const { antumbra_scene_destroy(scene); }
};
using ScenePtr = std::unique_ptr<antumbra_scene, SceneDeleter>;

bool ok(antumbra_result result, const char *what)
{
    if (result == ANTUMBRA_RESULT_OK) {
        return true;
    }
    std::fprintf(stderr, "consumer: %s failed: %s (%s)\n", what, antumbra_result_str(result),
                 antumbra_last_error_message());
    return false;
}

}  // namespace

int main()
{
    if (antumbra_version() != ANTUMBRA_VERSION) {
        std::fprintf(stderr, "consumer: header %u and library %u differ\n", ANTUMBRA_VERSION, antumbra_version());
        return 1;
    }

    // The square [-1, 1] x [-1, 1] at height z = 1, facing down.
    constexpr std::array<float, 12> positions = {-1, -1, 1, 1, -1, 1, 1, 1, 1, -1, 1, 1};
    constexpr std::array<uint32_t, 6> indices = {0, 2, 1, 0, 3, 2};
    antumbra_mesh_view mesh{};
    mesh.positions = positions.data();
    mesh.vertex_count = 4;
    mesh.position_stride = 0;
    mesh.indices = indices.data();
    mesh.triangle_count = 2;

    antumbra_scene *raw_scene = nullptr;
    if (!ok(antumbra_scene_create(&mesh, &raw_scene), "antumbra_scene_create")) {
        return 1;
    }
    ScenePtr scene(raw_scene);

    // Rays from below the square's centre, straight up (hit at t = 1), straight down
    // (miss), and up past its edge at x = 2 (miss).
    constexpr std::size_t kRays = 3;
    constexpr std::array<float, 3 * kRays> origins = {0.25f, -0.5f, 0, 0.25f, -0.5f, 0, 2, 0, 0};
    constexpr std::array<float, 3 * kRays> directions = {0, 0, 1, 0, 0, -1, 0, 0, 1};
    const std::array<float, kRays> t_max = {INFINITY, INFINITY, INFINITY};
    std::array<antumbra_hit, kRays> hits{};
    if (!ok(antumbra_scene_intersect(scene.get(), origins.data(), directions.data(), t_max.data(), kRays,
                                     hits.data()),
            "antumbra_scene_intersect")) {
        return 1;
    }
    if (std::fabs(hits[0].distance - 1.0f) > 1e-6f || hits[0].triangle == ANTUMBRA_INVALID_INDEX ||
        std::isfinite(hits[1].distance) || std::isfinite(hits[2].distance)) {
        std::fprintf(stderr, "consumer: ray hits %g %g %g, expected 1, inf, inf\n", hits[0].distance,
                     hits[1].distance, hits[2].distance);
        return 1;
    }

    // The hemisphere mask of the origin, facing up: a cell is covered exactly when
    // its direction (u, v, z) meets the square, |u| <= z and |v| <= z (no cell
    // centre lies on those planes, so the count is unambiguous).
    constexpr std::array<float, 3> receiver = {0, 0, 0};
    constexpr std::array<float, 3> normal = {0, 0, 1};
    antumbra_hemi_mask mask{};
    if (!ok(antumbra_hemi_rasterize(&mesh, receiver.data(), normal.data(), 1, nullptr, &mask),
            "antumbra_hemi_rasterize")) {
        return 1;
    }
    int covered = 0;
    int expected = 0;
    for (uint32_t j = 0; j < 32; ++j) {
        for (uint32_t i = 0; i < 32; ++i) {
            const bool bit = (mask.rows[j] >> i) & 1u;
            covered += bit ? 1 : 0;
            std::array<float, 3> local{};
            if (antumbra_hemi_cell_direction(i, j, local.data()) != ANTUMBRA_RESULT_OK) {
                if (bit) {
                    std::fprintf(stderr, "consumer: cell (%u, %u) outside the disk is set\n", i, j);
                    return 1;
                }
                continue;
            }
            // The frame of a +z normal maps local to world up to signs of the
            // tangents, to which the square is symmetric.
            const bool meets = std::fabs(local[0]) <= local[2] && std::fabs(local[1]) <= local[2];
            expected += meets ? 1 : 0;
            if (meets != bit) {
                std::fprintf(stderr, "consumer: cell (%u, %u) is %d, the square says %d\n", i, j, bit, meets);
                return 1;
            }
        }
    }
    std::printf("consumer: antumbra %s, 3 rays as expected, mask covers %d of the cells (expected %d)\n",
                antumbra_version_string(), covered, expected);
    return 0;
}

/*
 * header_cxx_b.cpp: second C++11 translation unit of the header test. Uses the
 * API the way a C++ engine would (aggregate initialisation, a capturing-free
 * callback, a one-triangle scene) so linking proves the calls resolve.
 */
#include "antumbra.h"
#include "header_cxx.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>

namespace {

struct CallbackLog {
    int calls;
    antumbra_result code;
};

extern "C" void record_error(antumbra_result code, const char * /*message*/, void *user_data)
{
    CallbackLog *log = static_cast<CallbackLog *>(user_data);
    ++log->calls;
    log->code = code;
}

}  // namespace

int header_cxx_b_checks()
{
    int failures = 0;
    const float positions[] = {0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f};
    const uint32_t indices[] = {0, 1, 2};
    const antumbra_mesh_view mesh = {positions, 3, 0, indices, 1};

    antumbra_scene *scene = nullptr;
    antumbra_result result = antumbra_scene_create(&mesh, &scene);
    if (result != ANTUMBRA_RESULT_OK || scene == nullptr) {
        std::fprintf(stderr, "header_cxx_b: antumbra_scene_create: %s: %s\n", antumbra_result_str(result),
                     antumbra_last_error_message());
        return 1;
    }

    // Straight down through (0.25, 0.25, 0): t = 1 along a unit direction.
    const float origin[] = {0.25f, 0.25f, 1.0f};
    const float direction[] = {0.0f, 0.0f, -1.0f};
    const float t_max[] = {INFINITY};
    antumbra_hit hit = {0.0f, 0, 0.0f, 0.0f};
    result = antumbra_scene_intersect(scene, origin, direction, t_max, 1, &hit);
    if (result != ANTUMBRA_RESULT_OK || hit.triangle != 0 || std::fabs(hit.distance - 1.0f) > 1e-6f ||
        std::fabs(hit.u - 0.25f) > 1e-6f || std::fabs(hit.v - 0.25f) > 1e-6f) {
        std::fprintf(stderr, "header_cxx_b: intersect: %s, hit t=%g triangle=%u u=%g v=%g\n",
                     antumbra_result_str(result), static_cast<double>(hit.distance), hit.triangle,
                     static_cast<double>(hit.u), static_cast<double>(hit.v));
        ++failures;
    }

    // A C++ function with C linkage is a valid callback; it sees a failure's code.
    CallbackLog log = {0, ANTUMBRA_RESULT_OK};
    antumbra_set_error_callback(record_error, &log);
    result = antumbra_scene_intersect(nullptr, origin, direction, t_max, 1, &hit);
    antumbra_set_error_callback(nullptr, nullptr);
    if (result != ANTUMBRA_RESULT_NULL_ARGUMENT || log.calls != 1 || log.code != ANTUMBRA_RESULT_NULL_ARGUMENT) {
        std::fprintf(stderr, "header_cxx_b: NULL scene gave %s, callback calls %d\n", antumbra_result_str(result),
                     log.calls);
        ++failures;
    }

    antumbra_scene_destroy(scene);
    return failures;
}

/*
 * header_cxx_a.cpp: first C++11 translation unit of the header test. Checks, at
 * compile time, that every declaration has the exact type the ABI promises as
 * seen from C++, and at run time that the library's version matches the header.
 */
#include "antumbra.h"
#include "header_cxx.hpp"

#include <cstdio>
#include <cstring>
#include <type_traits>

namespace {

template <typename Expected, typename Actual>
constexpr bool same() { return std::is_same<Expected, Actual>::value; }

// Language linkage is not part of the function type for GCC and Clang, so these
// plain function-pointer types match the extern "C" declarations exactly.
static_assert(same<const char *(*)(), decltype(&antumbra_last_error_message)>(), "last_error_message");
static_assert(same<antumbra_result (*)(char *, size_t, size_t *), decltype(&antumbra_last_error_message_copy)>(),
              "last_error_message_copy");
static_assert(same<void (*)(antumbra_error_callback, void *), decltype(&antumbra_set_error_callback)>(),
              "set_error_callback");
static_assert(same<void (*)(const float *, float *, float *), decltype(&antumbra_frame_from_normal)>(),
              "frame_from_normal");
static_assert(same<const char *(*)(antumbra_result), decltype(&antumbra_result_str)>(), "result_str");
static_assert(same<antumbra_result (*)(const antumbra_mesh_view *, antumbra_scene **),
                   decltype(&antumbra_scene_create)>(),
              "scene_create");
static_assert(same<void (*)(antumbra_scene *), decltype(&antumbra_scene_destroy)>(), "scene_destroy");
static_assert(same<antumbra_result (*)(const antumbra_scene *, const float *, const float *, const float *,
                                       size_t, uint8_t *),
                   decltype(&antumbra_scene_occluded)>(),
              "scene_occluded");
static_assert(same<antumbra_result (*)(const antumbra_scene *, const float *, const float *, const float *,
                                       size_t, antumbra_hit *),
                   decltype(&antumbra_scene_intersect)>(),
              "scene_intersect");
static_assert(same<void (*)(antumbra_hemi_options *), decltype(&antumbra_hemi_options_init)>(),
              "hemi_options_init");
static_assert(same<antumbra_result (*)(uint32_t, antumbra_hemi_table **), decltype(&antumbra_hemi_table_create)>(),
              "hemi_table_create");
static_assert(same<void (*)(antumbra_hemi_table *), decltype(&antumbra_hemi_table_destroy)>(), "hemi_table_destroy");
static_assert(same<antumbra_result (*)(const antumbra_mesh_view *, const float *, const float *, size_t,
                                       const antumbra_hemi_options *, antumbra_hemi_mask *),
                   decltype(&antumbra_hemi_rasterize)>(),
              "hemi_rasterize");
static_assert(same<antumbra_result (*)(uint32_t, uint32_t, float *), decltype(&antumbra_hemi_cell_direction)>(),
              "hemi_cell_direction");
static_assert(same<antumbra_result (*)(antumbra_hemi_mask *), decltype(&antumbra_hemi_valid_mask)>(),
              "hemi_valid_mask");
static_assert(same<void (*)(antumbra_hemi_shading_options *), decltype(&antumbra_hemi_shading_options_init)>(),
              "hemi_shading_options_init");
static_assert(same<void (*)(antumbra_hemi_material *), decltype(&antumbra_hemi_material_init)>(),
              "hemi_material_init");
static_assert(same<antumbra_result (*)(const antumbra_mesh_view *, const antumbra_mesh_view *,
                                       const antumbra_hemi_shading_options *, antumbra_hemi_shader **),
                   decltype(&antumbra_hemi_shader_create)>(),
              "hemi_shader_create");
static_assert(same<void (*)(antumbra_hemi_shader *), decltype(&antumbra_hemi_shader_destroy)>(),
              "hemi_shader_destroy");
static_assert(same<antumbra_result (*)(antumbra_hemi_shader *, const antumbra_mesh_view *, const antumbra_mesh_view *),
                   decltype(&antumbra_hemi_shader_regroup)>(),
              "hemi_shader_regroup");
static_assert(same<antumbra_result (*)(antumbra_hemi_shader *, const antumbra_mesh_view *, const float *,
                                       const antumbra_mesh_view *, float *),
                   decltype(&antumbra_hemi_shader_transfer)>(),
              "hemi_shader_transfer");
static_assert(same<antumbra_result (*)(antumbra_hemi_shader *, const antumbra_mesh_view *, const float *,
                                       const antumbra_mesh_view *, const float *, const antumbra_hemi_material *,
                                       float *, float *, float *),
                   decltype(&antumbra_hemi_shader_shade)>(),
              "hemi_shader_shade");
static_assert(same<antumbra_result (*)(const antumbra_mesh_view *, const float *, const antumbra_mesh_view *,
                                       const antumbra_hemi_shading_options *, float *),
                   decltype(&antumbra_hemi_transfer)>(),
              "hemi_transfer");
static_assert(same<antumbra_result (*)(const antumbra_mesh_view *, const float *, const antumbra_mesh_view *,
                                       const antumbra_hemi_shading_options *, const float *,
                                       const antumbra_hemi_material *, float *, float *, float *),
                   decltype(&antumbra_hemi_shade)>(),
              "hemi_shade");
static_assert(same<antumbra_result (*)(const float *, uint32_t, uint32_t, size_t, uint32_t, float *),
                   decltype(&antumbra_sh_project_equirect)>(),
              "sh_project_equirect");
static_assert(same<antumbra_result (*)(const float *, uint32_t, float *), decltype(&antumbra_sh_eval)>(), "sh_eval");
static_assert(same<uint32_t (*)(), decltype(&antumbra_version)>(), "version");
static_assert(same<const char *(*)(), decltype(&antumbra_version_string)>(), "version_string");
static_assert(same<int32_t, antumbra_result>(), "antumbra_result is int32_t");

// Plain data a C++ caller may memcpy and aggregate-initialise.
static_assert(std::is_standard_layout<antumbra_mesh_view>::value, "mesh_view is standard layout");
static_assert(std::is_trivially_copyable<antumbra_mesh_view>::value, "mesh_view is trivially copyable");
static_assert(std::is_standard_layout<antumbra_hit>::value, "hit is standard layout");
static_assert(std::is_trivially_copyable<antumbra_hit>::value, "hit is trivially copyable");
static_assert(sizeof(antumbra_hit) == 16, "hit size as seen from C++");
static_assert(sizeof(antumbra_mesh_view) == 5 * sizeof(void *), "mesh_view size as seen from C++");
static_assert(std::is_standard_layout<antumbra_hemi_mask>::value, "hemi_mask is standard layout");
static_assert(std::is_trivially_copyable<antumbra_hemi_mask>::value, "hemi_mask is trivially copyable");
static_assert(sizeof(antumbra_hemi_mask) == 128, "hemi_mask size as seen from C++");
static_assert(std::is_standard_layout<antumbra_hemi_options>::value, "hemi_options is standard layout");
static_assert(std::is_trivially_copyable<antumbra_hemi_options>::value, "hemi_options is trivially copyable");
static_assert(sizeof(antumbra_hemi_options) == 16 + sizeof(void *), "hemi_options size as seen from C++");
static_assert(std::is_standard_layout<antumbra_hemi_shading_options>::value, "hemi_shading_options is standard layout");
static_assert(std::is_trivially_copyable<antumbra_hemi_shading_options>::value,
              "hemi_shading_options is trivially copyable");
static_assert(sizeof(antumbra_hemi_shading_options) == sizeof(antumbra_hemi_options) + 24,
              "hemi_shading_options size as seen from C++");
static_assert(std::is_standard_layout<antumbra_hemi_material>::value, "hemi_material is standard layout");
static_assert(std::is_trivially_copyable<antumbra_hemi_material>::value, "hemi_material is trivially copyable");
static_assert(sizeof(antumbra_hemi_material) == 40 + 2 * sizeof(void *), "hemi_material size as seen from C++");

}  // namespace

int header_cxx_a_checks()
{
    int failures = 0;
    if (antumbra_version() != ANTUMBRA_VERSION) {
        std::fprintf(stderr, "header_cxx_a: library version 0x%06x, header 0x%06x\n",
                     static_cast<unsigned>(antumbra_version()), static_cast<unsigned>(ANTUMBRA_VERSION));
        ++failures;
    }
    if (std::strcmp(antumbra_version_string(), ANTUMBRA_VERSION_STRING) != 0) {
        std::fprintf(stderr, "header_cxx_a: library version \"%s\", header \"%s\"\n", antumbra_version_string(),
                     ANTUMBRA_VERSION_STRING);
        ++failures;
    }
    if (std::strcmp(antumbra_result_str(ANTUMBRA_RESULT_OK), "ANTUMBRA_RESULT_OK") != 0) {
        std::fprintf(stderr, "header_cxx_a: antumbra_result_str(OK) is \"%s\"\n",
                     antumbra_result_str(ANTUMBRA_RESULT_OK));
        ++failures;
    }
    return failures;
}

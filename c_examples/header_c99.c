/*
 * header_c99.c: compile-only check that include/antumbra.h is valid, warning-free
 * C99 (and C11: the Makefile compiles this file both ways).
 *
 * The header is included first, so it must be self-contained, and twice, so its
 * include guard must work. Every function is then assigned to a pointer of the
 * exact type the ABI promises: a changed parameter or return type is an
 * "incompatible pointer type" diagnostic, which -Werror turns into a failure.
 */
#include "antumbra.h"
#include "antumbra.h"

/* The version macros must be usable by the preprocessor, for feature tests. */
#if !defined(ANTUMBRA_VERSION_MAJOR) || !defined(ANTUMBRA_VERSION_MINOR) || \
    !defined(ANTUMBRA_VERSION_PATCH)
#error "antumbra.h lacks a version macro"
#endif
#if ANTUMBRA_VERSION_MAJOR < 0 || ANTUMBRA_VERSION_MINOR > 255 || ANTUMBRA_VERSION_PATCH > 255
#error "a version part does not fit the packed ANTUMBRA_VERSION"
#endif
#if ANTUMBRA_INVALID_INDEX != 0xFFFFFFFF
#error "ANTUMBRA_INVALID_INDEX is not UINT32_MAX"
#endif

/* Not static: a static would be unused and trip -Wunused-variable. */
extern const struct antumbra_api_table {
    const char *(*last_error_message)(void);
    antumbra_result (*last_error_message_copy)(char *, size_t, size_t *);
    void (*set_error_callback)(antumbra_error_callback, void *);
    void (*frame_from_normal)(const float *, float *, float *);
    const char *(*result_str)(antumbra_result);
    antumbra_result (*scene_create)(const antumbra_mesh_view *, antumbra_scene **);
    void (*scene_destroy)(antumbra_scene *);
    antumbra_result (*scene_occluded)(const antumbra_scene *, const float *, const float *,
                                      const float *, size_t, uint8_t *);
    antumbra_result (*scene_intersect)(const antumbra_scene *, const float *, const float *,
                                       const float *, size_t, antumbra_hit *);
    void (*hemi_options_init)(antumbra_hemi_options *);
    antumbra_result (*hemi_table_create)(uint32_t, antumbra_hemi_table **);
    void (*hemi_table_destroy)(antumbra_hemi_table *);
    antumbra_result (*hemi_rasterize)(const antumbra_mesh_view *, const float *, const float *, size_t,
                                      const antumbra_hemi_options *, antumbra_hemi_mask *);
    antumbra_result (*hemi_cell_direction)(uint32_t, uint32_t, float *);
    antumbra_result (*hemi_valid_mask)(antumbra_hemi_mask *);
    void (*hemi_shading_options_init)(antumbra_hemi_shading_options *);
    void (*hemi_material_init)(antumbra_hemi_material *);
    antumbra_result (*hemi_shader_create)(const antumbra_mesh_view *, const antumbra_mesh_view *,
                                          const antumbra_hemi_shading_options *, antumbra_hemi_shader **);
    void (*hemi_shader_destroy)(antumbra_hemi_shader *);
    antumbra_result (*hemi_shader_regroup)(antumbra_hemi_shader *, const antumbra_mesh_view *,
                                           const antumbra_mesh_view *);
    antumbra_result (*hemi_shader_set_receivers)(antumbra_hemi_shader *, const antumbra_mesh_view *, uint32_t,
                                                 float);
    antumbra_result (*hemi_shader_transfer)(antumbra_hemi_shader *, const antumbra_mesh_view *, const float *,
                                            const antumbra_mesh_view *, float *);
    antumbra_result (*hemi_shader_shade)(antumbra_hemi_shader *, const antumbra_mesh_view *, const float *,
                                         const antumbra_mesh_view *, const float *, const antumbra_hemi_material *,
                                         float *, float *, float *);
    antumbra_result (*hemi_transfer)(const antumbra_mesh_view *, const float *, const antumbra_mesh_view *,
                                     const antumbra_hemi_shading_options *, float *);
    antumbra_result (*hemi_shade)(const antumbra_mesh_view *, const float *, const antumbra_mesh_view *,
                                  const antumbra_hemi_shading_options *, const float *, const antumbra_hemi_material *,
                                  float *, float *, float *);
    antumbra_result (*sh_project_equirect)(const float *, uint32_t, uint32_t, size_t, uint32_t, float *);
    antumbra_result (*sh_eval)(const float *, uint32_t, float *);
    uint32_t (*version)(void);
    const char *(*version_string)(void);
} antumbra_api_table_c;

const struct antumbra_api_table antumbra_api_table_c = {
    antumbra_last_error_message,
    antumbra_last_error_message_copy,
    antumbra_set_error_callback,
    antumbra_frame_from_normal,
    antumbra_result_str,
    antumbra_scene_create,
    antumbra_scene_destroy,
    antumbra_scene_occluded,
    antumbra_scene_intersect,
    antumbra_hemi_options_init,
    antumbra_hemi_table_create,
    antumbra_hemi_table_destroy,
    antumbra_hemi_rasterize,
    antumbra_hemi_cell_direction,
    antumbra_hemi_valid_mask,
    antumbra_hemi_shading_options_init,
    antumbra_hemi_material_init,
    antumbra_hemi_shader_create,
    antumbra_hemi_shader_destroy,
    antumbra_hemi_shader_regroup,
    antumbra_hemi_shader_set_receivers,
    antumbra_hemi_shader_transfer,
    antumbra_hemi_shader_shade,
    antumbra_hemi_transfer,
    antumbra_hemi_shade,
    antumbra_sh_project_equirect,
    antumbra_sh_eval,
    antumbra_version,
    antumbra_version_string,
};

/* The callback typedef must accept a plain C function of the documented shape. */
void antumbra_header_c99_callback(antumbra_result code, const char *message, void *user_data);
void antumbra_header_c99_callback(antumbra_result code, const char *message, void *user_data)
{
    (void)code;
    (void)message;
    (void)user_data;
}
extern const antumbra_error_callback antumbra_header_c99_callback_ptr;
const antumbra_error_callback antumbra_header_c99_callback_ptr = antumbra_header_c99_callback;

/* The struct tags and the typedefs name the same types. */
extern const struct antumbra_mesh_view antumbra_header_c99_mesh;
const antumbra_mesh_view antumbra_header_c99_mesh = {NULL, 0, 0, NULL, 0};
extern const struct antumbra_hit antumbra_header_c99_hit;
const antumbra_hit antumbra_header_c99_hit = {0.0f, ANTUMBRA_INVALID_INDEX, 0.0f, 0.0f};
extern const struct antumbra_hemi_mask antumbra_header_c99_hemi_mask;
const antumbra_hemi_mask antumbra_header_c99_hemi_mask = {{0}};
extern const struct antumbra_hemi_options antumbra_header_c99_hemi_options;
const antumbra_hemi_options antumbra_header_c99_hemi_options = {ANTUMBRA_HEMI_QUALITY_EXACT, 0, 0.0f, 0, NULL};
extern const struct antumbra_hemi_shading_options antumbra_header_c99_hemi_shading_options;
const antumbra_hemi_shading_options antumbra_header_c99_hemi_shading_options = {
    {ANTUMBRA_HEMI_QUALITY_EXACT, 0, 0.0f, 0, NULL}, 3, ANTUMBRA_HEMI_METHOD_CELLS, ANTUMBRA_HEMI_SPACE_WORLD, 1.0f, 0, 0};
extern const struct antumbra_hemi_material antumbra_header_c99_hemi_material;
const antumbra_hemi_material antumbra_header_c99_hemi_material = {
    {1.0f, 1.0f, 1.0f}, {0.0f, 0.0f, 0.0f}, 16.0f, {0.0f, 0.0f, 0.0f}, NULL, NULL};

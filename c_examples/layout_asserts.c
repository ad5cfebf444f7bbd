/*
 * layout_asserts.c: compile-time checks (C11) that the header's types have the
 * layout the Rust side was built with, and that its constants have the values
 * the ABI publishes. Nothing here runs; compiling it is the test.
 *
 * Offsets are checked twice: once in terms of sizeof(void *) and sizeof(size_t),
 * which holds on every ABI, and once as literal numbers for the ABI this check
 * runs on (LP64, LLP64 or ILP32), chosen by pointer width so the numbers are
 * never asserted on an ABI they were not written for.
 */
#include "antumbra.h"

#include <stdalign.h>
#include <stddef.h>
#include <stdint.h>

/* A field's type, checked without evaluating anything. */
#define FIELD_TYPE_IS(type, field, expected) \
    _Generic(((type *)0)->field, expected: 1, default: 0)

/* ---- antumbra_mesh_view: five pointer-sized fields, no padding ---- */
_Static_assert(FIELD_TYPE_IS(antumbra_mesh_view, positions, const float *), "positions type");
_Static_assert(FIELD_TYPE_IS(antumbra_mesh_view, vertex_count, size_t), "vertex_count type");
_Static_assert(FIELD_TYPE_IS(antumbra_mesh_view, position_stride, size_t), "position_stride type");
_Static_assert(FIELD_TYPE_IS(antumbra_mesh_view, indices, const uint32_t *), "indices type");
_Static_assert(FIELD_TYPE_IS(antumbra_mesh_view, triangle_count, size_t), "triangle_count type");

_Static_assert(sizeof(void *) == sizeof(size_t), "Rust's usize is size_t only where it is pointer-sized");
_Static_assert(offsetof(antumbra_mesh_view, positions) == 0, "mesh_view.positions offset");
_Static_assert(offsetof(antumbra_mesh_view, vertex_count) == 1 * sizeof(void *), "mesh_view.vertex_count offset");
_Static_assert(offsetof(antumbra_mesh_view, position_stride) == 2 * sizeof(void *), "mesh_view.position_stride offset");
_Static_assert(offsetof(antumbra_mesh_view, indices) == 3 * sizeof(void *), "mesh_view.indices offset");
_Static_assert(offsetof(antumbra_mesh_view, triangle_count) == 4 * sizeof(void *), "mesh_view.triangle_count offset");
_Static_assert(sizeof(antumbra_mesh_view) == 5 * sizeof(void *), "mesh_view size");
_Static_assert(alignof(antumbra_mesh_view) == alignof(void *), "mesh_view alignment");

/* ---- antumbra_hit: four 4-byte fields on every ABI ---- */
_Static_assert(FIELD_TYPE_IS(antumbra_hit, distance, float), "distance type");
_Static_assert(FIELD_TYPE_IS(antumbra_hit, triangle, uint32_t), "triangle type");
_Static_assert(FIELD_TYPE_IS(antumbra_hit, u, float), "u type");
_Static_assert(FIELD_TYPE_IS(antumbra_hit, v, float), "v type");
_Static_assert(sizeof(float) == 4, "f32 is a 4-byte float");
_Static_assert(offsetof(antumbra_hit, distance) == 0, "hit.distance offset");
_Static_assert(offsetof(antumbra_hit, triangle) == 4, "hit.triangle offset");
_Static_assert(offsetof(antumbra_hit, u) == 8, "hit.u offset");
_Static_assert(offsetof(antumbra_hit, v) == 12, "hit.v offset");
_Static_assert(sizeof(antumbra_hit) == 16, "hit size");
_Static_assert(alignof(antumbra_hit) == 4, "hit alignment");
/* Callers allocate hit arrays with malloc(n * sizeof(antumbra_hit)); no tail padding. */
_Static_assert(sizeof(antumbra_hit[3]) == 48, "hit array stride");

/* ---- antumbra_hemi_mask: 32 rows of 32 bits, 128 bytes on every ABI ---- */
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_mask, rows[0], uint32_t), "hemi_mask.rows element type");
_Static_assert(sizeof(((antumbra_hemi_mask *)0)->rows) == 32 * sizeof(uint32_t), "hemi_mask.rows has 32 rows");
_Static_assert(offsetof(antumbra_hemi_mask, rows) == 0, "hemi_mask.rows offset");
_Static_assert(sizeof(antumbra_hemi_mask) == 128, "hemi_mask size");
_Static_assert(alignof(antumbra_hemi_mask) == 4, "hemi_mask alignment");
/* Callers allocate one mask per receiver: no tail padding. */
_Static_assert(sizeof(antumbra_hemi_mask[3]) == 384, "hemi_mask array stride");

/* ---- antumbra_hemi_options: four 4-byte fields, then a pointer, no padding ---- */
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_options, quality, uint32_t), "quality type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_options, cull_backfaces, uint32_t), "cull_backfaces type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_options, normal_offset, float), "normal_offset type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_options, parallel, uint32_t), "parallel type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_options, table, const antumbra_hemi_table *), "table type");
/* The leading fields are fixed: external tools rely on them. */
_Static_assert(offsetof(antumbra_hemi_options, quality) == 0, "hemi_options.quality offset");
_Static_assert(offsetof(antumbra_hemi_options, cull_backfaces) == 4, "hemi_options.cull_backfaces offset");
_Static_assert(offsetof(antumbra_hemi_options, normal_offset) == 8, "hemi_options.normal_offset offset");
_Static_assert(offsetof(antumbra_hemi_options, parallel) == 12, "hemi_options.parallel offset");
_Static_assert(offsetof(antumbra_hemi_options, table) == 16, "hemi_options.table offset");
_Static_assert(sizeof(antumbra_hemi_options) == 16 + sizeof(void *), "hemi_options size");
_Static_assert(alignof(antumbra_hemi_options) == alignof(void *), "hemi_options alignment");

/* ---- antumbra_hemi_shading_options: the raster options, then six 4-byte fields ---- */
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_shading_options, raster, antumbra_hemi_options), "raster type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_shading_options, bands, uint32_t), "bands type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_shading_options, method, uint32_t), "method type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_shading_options, space, uint32_t), "space type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_shading_options, near_radius, float), "near_radius type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_shading_options, far_triangles, uint32_t), "far_triangles type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_shading_options, far_levels, uint32_t), "far_levels type");
_Static_assert(offsetof(antumbra_hemi_shading_options, raster) == 0, "shading_options.raster offset");
_Static_assert(offsetof(antumbra_hemi_shading_options, bands) == sizeof(antumbra_hemi_options),
               "shading_options.bands offset");
_Static_assert(offsetof(antumbra_hemi_shading_options, method) == sizeof(antumbra_hemi_options) + 4,
               "shading_options.method offset");
_Static_assert(offsetof(antumbra_hemi_shading_options, space) == sizeof(antumbra_hemi_options) + 8,
               "shading_options.space offset");
_Static_assert(offsetof(antumbra_hemi_shading_options, near_radius) == sizeof(antumbra_hemi_options) + 12,
               "shading_options.near_radius offset");
_Static_assert(offsetof(antumbra_hemi_shading_options, far_triangles) == sizeof(antumbra_hemi_options) + 16,
               "shading_options.far_triangles offset");
_Static_assert(offsetof(antumbra_hemi_shading_options, far_levels) == sizeof(antumbra_hemi_options) + 20,
               "shading_options.far_levels offset");
_Static_assert(sizeof(antumbra_hemi_shading_options) == sizeof(antumbra_hemi_options) + 24, "shading_options size");
_Static_assert(alignof(antumbra_hemi_shading_options) == alignof(void *), "shading_options alignment");

/* ---- antumbra_hemi_material: ten floats, then two pointers ---- */
_Static_assert(sizeof(((antumbra_hemi_material *)0)->albedo) == 3 * sizeof(float), "material.albedo is float[3]");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_material, albedo[0], float), "albedo element type");
_Static_assert(sizeof(((antumbra_hemi_material *)0)->specular) == 3 * sizeof(float), "material.specular is float[3]");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_material, specular[0], float), "specular element type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_material, phong_exponent, float), "phong_exponent type");
_Static_assert(sizeof(((antumbra_hemi_material *)0)->eye) == 3 * sizeof(float), "material.eye is float[3]");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_material, eye[0], float), "eye element type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_material, vertex_albedo, const float *), "vertex_albedo type");
_Static_assert(FIELD_TYPE_IS(antumbra_hemi_material, view_directions, const float *), "view_directions type");
_Static_assert(offsetof(antumbra_hemi_material, albedo) == 0, "material.albedo offset");
_Static_assert(offsetof(antumbra_hemi_material, specular) == 12, "material.specular offset");
_Static_assert(offsetof(antumbra_hemi_material, phong_exponent) == 24, "material.phong_exponent offset");
_Static_assert(offsetof(antumbra_hemi_material, eye) == 28, "material.eye offset");
_Static_assert(offsetof(antumbra_hemi_material, vertex_albedo) == 40, "material.vertex_albedo offset");
_Static_assert(offsetof(antumbra_hemi_material, view_directions) == 40 + sizeof(void *),
               "material.view_directions offset");
_Static_assert(sizeof(antumbra_hemi_material) == 40 + 2 * sizeof(void *), "material size");
_Static_assert(alignof(antumbra_hemi_material) == alignof(void *), "material alignment");

/* ---- antumbra_ssv_options: twelve 4-byte fields, the same on every ABI ---- */
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_options, structure, uint32_t), "ssv_options.structure type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_options, leaf_edges, uint32_t), "ssv_options.leaf_edges type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_options, max_depth, uint32_t), "ssv_options.max_depth type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_options, hemicube_resolution, uint32_t),
               "ssv_options.hemicube_resolution type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_options, parallel, uint32_t), "ssv_options.parallel type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_options, use_root_bounds, uint32_t), "ssv_options.use_root_bounds type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_options, root_min[0], float), "ssv_options.root_min element type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_options, root_max[0], float), "ssv_options.root_max element type");
_Static_assert(sizeof(((antumbra_ssv_options *)0)->root_min) == 3 * sizeof(float), "ssv_options.root_min is float[3]");
_Static_assert(sizeof(((antumbra_ssv_options *)0)->root_max) == 3 * sizeof(float), "ssv_options.root_max is float[3]");
/* `structure` first is fixed: external tools rely on it. */
_Static_assert(offsetof(antumbra_ssv_options, structure) == 0, "ssv_options.structure offset");
_Static_assert(offsetof(antumbra_ssv_options, leaf_edges) == 4, "ssv_options.leaf_edges offset");
_Static_assert(offsetof(antumbra_ssv_options, max_depth) == 8, "ssv_options.max_depth offset");
_Static_assert(offsetof(antumbra_ssv_options, hemicube_resolution) == 12, "ssv_options.hemicube_resolution offset");
_Static_assert(offsetof(antumbra_ssv_options, parallel) == 16, "ssv_options.parallel offset");
_Static_assert(offsetof(antumbra_ssv_options, use_root_bounds) == 20, "ssv_options.use_root_bounds offset");
_Static_assert(offsetof(antumbra_ssv_options, root_min) == 24, "ssv_options.root_min offset");
_Static_assert(offsetof(antumbra_ssv_options, root_max) == 36, "ssv_options.root_max offset");
_Static_assert(sizeof(antumbra_ssv_options) == 48, "ssv_options size");
_Static_assert(alignof(antumbra_ssv_options) == 4, "ssv_options alignment");

/* ---- antumbra_ssv_statistics: four 4-byte fields, then ten 8-byte ones ---- */
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, structure, uint32_t), "ssv_statistics.structure type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, sample_count, uint32_t), "ssv_statistics.sample_count type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, words_per_receiver, uint32_t),
               "ssv_statistics.words_per_receiver type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, light_vertex_count, uint32_t),
               "ssv_statistics.light_vertex_count type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, edges, uint64_t), "ssv_statistics.edges type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, potential_edges, uint64_t),
               "ssv_statistics.potential_edges type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, near_light_triangles, uint64_t),
               "ssv_statistics.near_light_triangles type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, nodes, uint64_t), "ssv_statistics.nodes type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, bytes, uint64_t), "ssv_statistics.bytes type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, queries, uint64_t), "ssv_statistics.queries type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, candidates, uint64_t), "ssv_statistics.candidates type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, silhouettes, uint64_t), "ssv_statistics.silhouettes type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, rays, uint64_t), "ssv_statistics.rays type");
_Static_assert(FIELD_TYPE_IS(antumbra_ssv_statistics, candidates_per_query, double),
               "ssv_statistics.candidates_per_query type");
_Static_assert(offsetof(antumbra_ssv_statistics, structure) == 0, "ssv_statistics.structure offset");
_Static_assert(offsetof(antumbra_ssv_statistics, sample_count) == 4, "ssv_statistics.sample_count offset");
_Static_assert(offsetof(antumbra_ssv_statistics, words_per_receiver) == 8, "ssv_statistics.words_per_receiver offset");
_Static_assert(offsetof(antumbra_ssv_statistics, light_vertex_count) == 12,
               "ssv_statistics.light_vertex_count offset");
_Static_assert(offsetof(antumbra_ssv_statistics, edges) == 16, "ssv_statistics.edges offset");
_Static_assert(offsetof(antumbra_ssv_statistics, potential_edges) == 24, "ssv_statistics.potential_edges offset");
_Static_assert(offsetof(antumbra_ssv_statistics, near_light_triangles) == 32,
               "ssv_statistics.near_light_triangles offset");
_Static_assert(offsetof(antumbra_ssv_statistics, nodes) == 40, "ssv_statistics.nodes offset");
_Static_assert(offsetof(antumbra_ssv_statistics, bytes) == 48, "ssv_statistics.bytes offset");
_Static_assert(offsetof(antumbra_ssv_statistics, queries) == 56, "ssv_statistics.queries offset");
_Static_assert(offsetof(antumbra_ssv_statistics, candidates) == 64, "ssv_statistics.candidates offset");
_Static_assert(offsetof(antumbra_ssv_statistics, silhouettes) == 72, "ssv_statistics.silhouettes offset");
_Static_assert(offsetof(antumbra_ssv_statistics, rays) == 80, "ssv_statistics.rays offset");
_Static_assert(offsetof(antumbra_ssv_statistics, candidates_per_query) == 88,
               "ssv_statistics.candidates_per_query offset");
_Static_assert(sizeof(antumbra_ssv_statistics) == 96, "ssv_statistics size");
/* 8 on LP64 and LLP64; i386 aligns 8-byte scalars in structs to 4, as Rust does there. */
_Static_assert(alignof(antumbra_ssv_statistics) == alignof(uint64_t), "ssv_statistics alignment");

/* ---- antumbra_transfer_options: twelve 4-byte fields, then the 8-byte seed ---- */
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_options, kind, uint32_t), "transfer_options.kind type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_options, bands, uint32_t), "transfer_options.bands type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_options, grid, uint32_t), "transfer_options.grid type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_options, rays, uint32_t), "transfer_options.rays type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_options, bounces, uint32_t), "transfer_options.bounces type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_options, parallel, uint32_t), "transfer_options.parallel type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_options, brdf, uint32_t), "transfer_options.brdf type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_options, brdf_params[0], float), "transfer_options.brdf_params type");
_Static_assert(sizeof(((antumbra_transfer_options *)0)->brdf_params) == 2 * sizeof(float),
               "transfer_options.brdf_params is float[2]");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_options, albedo, float), "transfer_options.albedo type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_options, ray_offset, float), "transfer_options.ray_offset type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_options, reserved, uint32_t), "transfer_options.reserved type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_options, seed, uint64_t), "transfer_options.seed type");
_Static_assert(offsetof(antumbra_transfer_options, kind) == 0, "transfer_options.kind offset");
_Static_assert(offsetof(antumbra_transfer_options, bands) == 4, "transfer_options.bands offset");
_Static_assert(offsetof(antumbra_transfer_options, grid) == 8, "transfer_options.grid offset");
_Static_assert(offsetof(antumbra_transfer_options, rays) == 12, "transfer_options.rays offset");
_Static_assert(offsetof(antumbra_transfer_options, bounces) == 16, "transfer_options.bounces offset");
_Static_assert(offsetof(antumbra_transfer_options, parallel) == 20, "transfer_options.parallel offset");
_Static_assert(offsetof(antumbra_transfer_options, brdf) == 24, "transfer_options.brdf offset");
_Static_assert(offsetof(antumbra_transfer_options, brdf_params) == 28, "transfer_options.brdf_params offset");
_Static_assert(offsetof(antumbra_transfer_options, albedo) == 36, "transfer_options.albedo offset");
_Static_assert(offsetof(antumbra_transfer_options, ray_offset) == 40, "transfer_options.ray_offset offset");
_Static_assert(offsetof(antumbra_transfer_options, reserved) == 44, "transfer_options.reserved offset");
_Static_assert(offsetof(antumbra_transfer_options, seed) == 48, "transfer_options.seed offset");
_Static_assert(sizeof(antumbra_transfer_options) == 56, "transfer_options size");

/* ---- antumbra_transfer_info: sixteen 4-byte fields, then two size_t ---- */
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, kind, uint32_t), "transfer_info.kind type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, bands, uint32_t), "transfer_info.bands type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, coeff_count, uint32_t), "transfer_info.coeff_count type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, grid, uint32_t), "transfer_info.grid type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, components, uint32_t), "transfer_info.components type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, vertex_count, uint32_t), "transfer_info.vertex_count type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, rays, uint32_t), "transfer_info.rays type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, bounces, uint32_t), "transfer_info.bounces type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, albedo, float), "transfer_info.albedo type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, brdf, uint32_t), "transfer_info.brdf type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, brdf_params[0], float), "transfer_info.brdf_params type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, clusters, uint32_t), "transfer_info.clusters type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, atlas_width, uint32_t), "transfer_info.atlas_width type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, atlas_height, uint32_t), "transfer_info.atlas_height type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, reserved, uint32_t), "transfer_info.reserved type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, data_bytes, size_t), "transfer_info.data_bytes type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_info, file_bytes, size_t), "transfer_info.file_bytes type");
_Static_assert(offsetof(antumbra_transfer_info, kind) == 0, "transfer_info.kind offset");
_Static_assert(offsetof(antumbra_transfer_info, coeff_count) == 8, "transfer_info.coeff_count offset");
_Static_assert(offsetof(antumbra_transfer_info, components) == 16, "transfer_info.components offset");
_Static_assert(offsetof(antumbra_transfer_info, vertex_count) == 20, "transfer_info.vertex_count offset");
_Static_assert(offsetof(antumbra_transfer_info, albedo) == 32, "transfer_info.albedo offset");
_Static_assert(offsetof(antumbra_transfer_info, brdf) == 36, "transfer_info.brdf offset");
_Static_assert(offsetof(antumbra_transfer_info, brdf_params) == 40, "transfer_info.brdf_params offset");
_Static_assert(offsetof(antumbra_transfer_info, clusters) == 48, "transfer_info.clusters offset");
_Static_assert(offsetof(antumbra_transfer_info, atlas_width) == 52, "transfer_info.atlas_width offset");
_Static_assert(offsetof(antumbra_transfer_info, atlas_height) == 56, "transfer_info.atlas_height offset");
_Static_assert(offsetof(antumbra_transfer_info, reserved) == 60, "transfer_info.reserved offset");
_Static_assert(offsetof(antumbra_transfer_info, data_bytes) == 64, "transfer_info.data_bytes offset");
_Static_assert(offsetof(antumbra_transfer_info, file_bytes) == 64 + sizeof(size_t), "transfer_info.file_bytes offset");
_Static_assert(sizeof(antumbra_transfer_info) == 64 + 2 * sizeof(size_t), "transfer_info size");

/* ---- antumbra_transfer_material: ten floats, then a pointer ---- */
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_material, albedo[0], float), "transfer_material.albedo type");
_Static_assert(sizeof(((antumbra_transfer_material *)0)->albedo) == 3 * sizeof(float),
               "transfer_material.albedo is float[3]");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_material, specular[0], float), "transfer_material.specular type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_material, phong_exponent, float), "transfer_material.phong_exponent type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_material, eye[0], float), "transfer_material.eye type");
_Static_assert(FIELD_TYPE_IS(antumbra_transfer_material, view_directions, const float *),
               "transfer_material.view_directions type");
_Static_assert(offsetof(antumbra_transfer_material, albedo) == 0, "transfer_material.albedo offset");
_Static_assert(offsetof(antumbra_transfer_material, specular) == 12, "transfer_material.specular offset");
_Static_assert(offsetof(antumbra_transfer_material, phong_exponent) == 24, "transfer_material.phong_exponent offset");
_Static_assert(offsetof(antumbra_transfer_material, eye) == 28, "transfer_material.eye offset");
_Static_assert(offsetof(antumbra_transfer_material, view_directions) == 40, "transfer_material.view_directions offset");
_Static_assert(sizeof(antumbra_transfer_material) == 40 + sizeof(void *), "transfer_material size");
_Static_assert(alignof(antumbra_transfer_material) == alignof(void *), "transfer_material alignment");
_Static_assert(sizeof(antumbra_transfer_progress_fn) == sizeof(void (*)(void)), "progress is one function pointer");

/* ---- antumbra_lightmap_options: four uint32_t ---- */
_Static_assert(FIELD_TYPE_IS(antumbra_lightmap_options, width, uint32_t), "lightmap_options.width type");
_Static_assert(FIELD_TYPE_IS(antumbra_lightmap_options, lift_probes, uint32_t), "lightmap_options.lift_probes type");
_Static_assert(offsetof(antumbra_lightmap_options, width) == 0, "lightmap_options.width offset");
_Static_assert(offsetof(antumbra_lightmap_options, height) == 4, "lightmap_options.height offset");
_Static_assert(offsetof(antumbra_lightmap_options, gutter) == 8, "lightmap_options.gutter offset");
_Static_assert(offsetof(antumbra_lightmap_options, lift_probes) == 12, "lightmap_options.lift_probes offset");
_Static_assert(sizeof(antumbra_lightmap_options) == 16, "lightmap_options size");

/* ---- antumbra_lightmap_info: four uint32_t, then a size_t ---- */
_Static_assert(FIELD_TYPE_IS(antumbra_lightmap_info, lifted, uint32_t), "lightmap_info.lifted type");
_Static_assert(FIELD_TYPE_IS(antumbra_lightmap_info, receiver_count, size_t), "lightmap_info.receiver_count type");
_Static_assert(offsetof(antumbra_lightmap_info, gutter) == 8, "lightmap_info.gutter offset");
_Static_assert(offsetof(antumbra_lightmap_info, lifted) == 12, "lightmap_info.lifted offset");
_Static_assert(offsetof(antumbra_lightmap_info, receiver_count) == 16, "lightmap_info.receiver_count offset");
_Static_assert(sizeof(antumbra_lightmap_info) == 16 + sizeof(size_t), "lightmap_info size");

/* ---- Literal numbers for the ABI at hand ---- */
#if UINTPTR_MAX == UINT64_MAX
/* LP64 (and LLP64, where the layout of these structs is the same). */
_Static_assert(sizeof(void *) == 8 && sizeof(size_t) == 8, "64-bit guard is honest");
_Static_assert(offsetof(antumbra_mesh_view, positions) == 0, "LP64 mesh_view.positions");
_Static_assert(offsetof(antumbra_mesh_view, vertex_count) == 8, "LP64 mesh_view.vertex_count");
_Static_assert(offsetof(antumbra_mesh_view, position_stride) == 16, "LP64 mesh_view.position_stride");
_Static_assert(offsetof(antumbra_mesh_view, indices) == 24, "LP64 mesh_view.indices");
_Static_assert(offsetof(antumbra_mesh_view, triangle_count) == 32, "LP64 mesh_view.triangle_count");
_Static_assert(sizeof(antumbra_mesh_view) == 40, "LP64 mesh_view size");
_Static_assert(alignof(antumbra_mesh_view) == 8, "LP64 mesh_view alignment");
_Static_assert(sizeof(antumbra_hemi_options) == 24, "LP64 hemi_options size");
_Static_assert(alignof(antumbra_hemi_options) == 8, "LP64 hemi_options alignment");
_Static_assert(offsetof(antumbra_hemi_shading_options, bands) == 24, "LP64 shading_options.bands");
_Static_assert(offsetof(antumbra_hemi_shading_options, near_radius) == 36, "LP64 shading_options.near_radius");
_Static_assert(offsetof(antumbra_hemi_shading_options, far_triangles) == 40, "LP64 shading_options.far_triangles");
_Static_assert(sizeof(antumbra_hemi_shading_options) == 48, "LP64 shading_options size");
_Static_assert(offsetof(antumbra_hemi_material, view_directions) == 48, "LP64 material.view_directions");
_Static_assert(sizeof(antumbra_hemi_material) == 56, "LP64 material size");
_Static_assert(sizeof(antumbra_transfer_info) == 80, "LP64 transfer_info size");
_Static_assert(sizeof(antumbra_transfer_material) == 48, "LP64 transfer_material size");
#elif UINTPTR_MAX == UINT32_MAX
_Static_assert(sizeof(void *) == 4 && sizeof(size_t) == 4, "32-bit guard is honest");
_Static_assert(offsetof(antumbra_mesh_view, vertex_count) == 4, "ILP32 mesh_view.vertex_count");
_Static_assert(offsetof(antumbra_mesh_view, position_stride) == 8, "ILP32 mesh_view.position_stride");
_Static_assert(offsetof(antumbra_mesh_view, indices) == 12, "ILP32 mesh_view.indices");
_Static_assert(offsetof(antumbra_mesh_view, triangle_count) == 16, "ILP32 mesh_view.triangle_count");
_Static_assert(sizeof(antumbra_mesh_view) == 20, "ILP32 mesh_view size");
_Static_assert(alignof(antumbra_mesh_view) == 4, "ILP32 mesh_view alignment");
_Static_assert(sizeof(antumbra_hemi_options) == 20, "ILP32 hemi_options size");
_Static_assert(alignof(antumbra_hemi_options) == 4, "ILP32 hemi_options alignment");
_Static_assert(offsetof(antumbra_hemi_shading_options, bands) == 20, "ILP32 shading_options.bands");
_Static_assert(offsetof(antumbra_hemi_shading_options, near_radius) == 32, "ILP32 shading_options.near_radius");
_Static_assert(offsetof(antumbra_hemi_shading_options, far_triangles) == 36, "ILP32 shading_options.far_triangles");
_Static_assert(sizeof(antumbra_hemi_shading_options) == 44, "ILP32 shading_options size");
_Static_assert(offsetof(antumbra_hemi_material, view_directions) == 44, "ILP32 material.view_directions");
_Static_assert(sizeof(antumbra_hemi_material) == 48, "ILP32 material size");
_Static_assert(sizeof(antumbra_transfer_info) == 72, "ILP32 transfer_info size");
_Static_assert(sizeof(antumbra_transfer_material) == 44, "ILP32 transfer_material size");
#else
#error "no literal layout written for this pointer width; add one"
#endif

/* ---- Scalar and function-pointer types ---- */
_Static_assert(FIELD_TYPE_IS(struct { antumbra_result r; }, r, int32_t), "antumbra_result is int32_t");
_Static_assert(sizeof(antumbra_error_callback) == sizeof(void (*)(void)), "callback is one function pointer");

/* ---- Result codes: append-only, so every published value is pinned ---- */
_Static_assert(ANTUMBRA_RESULT_OK == 0, "OK");
_Static_assert(ANTUMBRA_RESULT_NULL_ARGUMENT == 1, "NULL_ARGUMENT");
_Static_assert(ANTUMBRA_RESULT_INVALID_ARGUMENT == 2, "INVALID_ARGUMENT");
_Static_assert(ANTUMBRA_RESULT_NON_FINITE == 3, "NON_FINITE");
_Static_assert(ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE == 4, "INDEX_OUT_OF_RANGE");
_Static_assert(ANTUMBRA_RESULT_BUFFER_TOO_SMALL == 5, "BUFFER_TOO_SMALL");
_Static_assert(ANTUMBRA_RESULT_OUT_OF_MEMORY == 6, "OUT_OF_MEMORY");
_Static_assert(ANTUMBRA_RESULT_UNSUPPORTED == 7, "UNSUPPORTED");
_Static_assert(ANTUMBRA_RESULT_PANIC == 8, "PANIC");
_Static_assert(ANTUMBRA_RESULT_POISONED == 9, "POISONED");
_Static_assert(ANTUMBRA_RESULT_INVALID_DATA == 10, "INVALID_DATA");

/* ---- Other constants ---- */
_Static_assert(ANTUMBRA_INVALID_INDEX == UINT32_MAX, "INVALID_INDEX is UINT32_MAX");
_Static_assert(ANTUMBRA_HEMI_QUALITY_EXACT == 0, "HEMI_QUALITY_EXACT is 0 (fixed)");
_Static_assert(ANTUMBRA_HEMI_QUALITY_TABLE == 1, "HEMI_QUALITY_TABLE is 1 (fixed)");
_Static_assert(ANTUMBRA_HEMI_GRID == 32, "HEMI_GRID");
_Static_assert(ANTUMBRA_HEMI_VALID_CELL_COUNT == 812, "HEMI_VALID_CELL_COUNT");
_Static_assert(ANTUMBRA_HEMI_TABLE_DEFAULT_RESOLUTION == 128, "HEMI_TABLE_DEFAULT_RESOLUTION");
_Static_assert(ANTUMBRA_HEMI_TABLE_MAX_RESOLUTION == 1024, "HEMI_TABLE_MAX_RESOLUTION");
_Static_assert(ANTUMBRA_SH_MAX_BANDS == 8, "SH_MAX_BANDS");
_Static_assert(ANTUMBRA_HEMI_METHOD_CELLS == 0, "HEMI_METHOD_CELLS");
_Static_assert(ANTUMBRA_HEMI_METHOD_LUT == 1, "HEMI_METHOD_LUT");
_Static_assert(ANTUMBRA_HEMI_METHOD_DOWNSAMPLED == 2, "HEMI_METHOD_DOWNSAMPLED");
_Static_assert(ANTUMBRA_HEMI_SPACE_WORLD == 0, "HEMI_SPACE_WORLD");
_Static_assert(ANTUMBRA_HEMI_SPACE_LOCAL == 1, "HEMI_SPACE_LOCAL");
_Static_assert(ANTUMBRA_SSV_STRUCTURE_HIERARCHY == 0, "SSV_STRUCTURE_HIERARCHY is 0 (fixed)");
_Static_assert(ANTUMBRA_SSV_STRUCTURE_HEMICUBE == 1, "SSV_STRUCTURE_HEMICUBE is 1 (fixed)");
_Static_assert(ANTUMBRA_SSV_STRUCTURE_BRUTE_FORCE == 2, "SSV_STRUCTURE_BRUTE_FORCE is 2 (fixed)");
_Static_assert(ANTUMBRA_SSV_STRUCTURE_RAY_TRACE == 3, "SSV_STRUCTURE_RAY_TRACE is 3 (fixed)");
_Static_assert(ANTUMBRA_SSV_SAMPLES_JITTERED == 0, "SSV_SAMPLES_JITTERED");
_Static_assert(ANTUMBRA_SSV_SAMPLES_STRATIFIED == 1, "SSV_SAMPLES_STRATIFIED");
_Static_assert(ANTUMBRA_SSV_MAX_SAMPLES == 1024, "SSV_MAX_SAMPLES");
_Static_assert(ANTUMBRA_SSV_MAX_LIGHT_VERTICES == 16, "SSV_MAX_LIGHT_VERTICES");
_Static_assert(ANTUMBRA_SSV_MAX_DEPTH_LIMIT == 24, "SSV_MAX_DEPTH_LIMIT");
_Static_assert(ANTUMBRA_SSV_MAX_HEMICUBE_RESOLUTION == 1024, "SSV_MAX_HEMICUBE_RESOLUTION");

_Static_assert(ANTUMBRA_TRANSFER_KIND_DIFFUSE == 1, "TRANSFER_KIND_DIFFUSE (the bake file's kind code)");
_Static_assert(ANTUMBRA_TRANSFER_KIND_GLOSSY_SH == 2, "TRANSFER_KIND_GLOSSY_SH");
_Static_assert(ANTUMBRA_TRANSFER_KIND_MRT == 3, "TRANSFER_KIND_MRT");
_Static_assert(ANTUMBRA_TRANSFER_BRDF_PHONG == 1, "TRANSFER_BRDF_PHONG (the bake file's brdf_kind)");
_Static_assert(ANTUMBRA_TRANSFER_BRDF_WARD == 2, "TRANSFER_BRDF_WARD");
_Static_assert(ANTUMBRA_TRANSFER_MAX_GRID == 64, "TRANSFER_MAX_GRID");
_Static_assert(ANTUMBRA_TRANSFER_MAX_RAYS == 4194304, "TRANSFER_MAX_RAYS");
_Static_assert(ANTUMBRA_TRANSFER_MAX_BOUNCES == 64, "TRANSFER_MAX_BOUNCES");
_Static_assert(_Generic(ANTUMBRA_VERSION, uint32_t: 1, default: 0), "ANTUMBRA_VERSION is a uint32_t");
_Static_assert(ANTUMBRA_VERSION ==
                   ANTUMBRA_MAKE_VERSION(ANTUMBRA_VERSION_MAJOR, ANTUMBRA_VERSION_MINOR,
                                         ANTUMBRA_VERSION_PATCH),
               "ANTUMBRA_VERSION packs the MAJOR/MINOR/PATCH macros");
_Static_assert(ANTUMBRA_MAKE_VERSION(1, 2, 3) == 0x010203u, "MAKE_VERSION packs major<<16|minor<<8|patch");
/* ANTUMBRA_VERSION_STRING cannot be compared in a constant expression; the example
 * programs check it against the numeric macros and the library at run time. */

/* ISO C forbids an empty translation unit. */
typedef int antumbra_layout_asserts_translation_unit_is_not_empty;

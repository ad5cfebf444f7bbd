/*
 * bad_input.c: the C ABI's validation, exercised exactly as a foreign caller
 * would see it.
 *
 * For each bad input this checks the exact result code, that
 * antumbra_last_error_message() is "<function>: ..." and names the offending
 * argument, and that every output was left byte-for-byte untouched (outputs are
 * pre-filled with a sentinel and compared afterwards). It also covers the error
 * plumbing: message copying, the error callback, per-thread messages, result
 * names, and antumbra_frame_from_normal; and the precomputed-transfer entry
 * points, including loading every truncation and many bit flips of a bake file.
 *
 * Every check runs even after one fails; the exit status is 1 if any failed.
 *
 * It is also built as firmware against the bare-metal library
 * (tools/check_embedded.sh): the checks of what that build lacks (scenes,
 * threads, bakes, compression) are left out there with `#if
 * defined(ANTUMBRA_HAS_STD)`; every other check runs in both and expects the
 * same result codes.
 */
#define _POSIX_C_SOURCE 200809L /* pthreads, for the per-thread message check */

#include "antumbra.h"

#include <math.h>
#if defined(ANTUMBRA_HAS_STD)
#include <pthread.h>
#endif
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SENTINEL 0xA5

static int checks_run;
static int checks_failed;

static void expect(int ok, const char *format, ...)
{
    ++checks_run;
    if (!ok) {
        va_list args;
        ++checks_failed;
        va_start(args, format);
        fputs("bad_input: FAILED: ", stderr);
        vfprintf(stderr, format, args);
        fputc('\n', stderr);
        va_end(args);
    }
}

/* Holds for a failed call: the code is the expected one, and the message starts
 * with the function's name and mentions every fragment (NULL-terminated list),
 * e.g. the argument and the offending index. */
static void expect_failure(const char *what, antumbra_result got, antumbra_result want, const char *function,
                           const char *fragment, ...)
{
    const char *message = antumbra_last_error_message();
    size_t prefix = strlen(function);
    va_list fragments;
    expect(got == want, "%s: got %s (%d), want %s", what, antumbra_result_str(got), (int)got,
           antumbra_result_str(want));
    expect(message != NULL && message[0] != '\0', "%s: empty last error message", what);
    if (message == NULL) {
        return;
    }
    expect(strncmp(message, function, prefix) == 0 && message[prefix] == ':',
           "%s: message \"%s\" does not start with \"%s:\"", what, message, function);
    va_start(fragments, fragment);
    for (; fragment != NULL; fragment = va_arg(fragments, const char *)) {
        expect(strstr(message, fragment) != NULL, "%s: message \"%s\" does not mention \"%s\"", what, message,
               fragment);
    }
    va_end(fragments);
}

static void expect_success(const char *what, antumbra_result got)
{
    const char *message = antumbra_last_error_message();
    expect(got == ANTUMBRA_RESULT_OK, "%s: got %s (%d): %s", what, antumbra_result_str(got), (int)got, message);
    expect(message != NULL && message[0] == '\0', "%s: succeeded but the last error message is \"%s\"", what,
           message ? message : "(NULL)");
}

static void expect_untouched(const char *what, const void *memory, size_t size)
{
    const unsigned char *bytes = memory;
    size_t i;
    for (i = 0; i < size; ++i) {
        if (bytes[i] != SENTINEL) {
            expect(0, "%s: output byte %lu was written on failure (0x%02x)", what, (unsigned long)i, bytes[i]);
            return;
        }
    }
    ++checks_run;
}

/* A pointer `offset` bytes past `base`, built through uintptr_t: converting an
 * integer to a misaligned pointer is implementation-defined (GCC and Clang keep
 * the bits), whereas casting a misaligned char * to float * would be undefined. */
static const void *offset_pointer(const void *base, size_t offset)
{
    return (const void *)((uintptr_t)base + offset);
}

/* ------------------------------------------------------------------------- */
/* A known-good mesh: the unit square as two triangles, with each position     */
/* followed by a fourth float so the stride (16) is not the packed 12.          */
/* ------------------------------------------------------------------------- */

static float square_positions[4 * 4] = {
    0.0f, 0.0f, 0.0f, -1.0f, /* the 4th float of each vertex is padding */
    1.0f, 0.0f, 0.0f, -1.0f, /*                                          */
    1.0f, 1.0f, 0.0f, -1.0f, /*                                          */
    0.0f, 1.0f, 0.0f, -1.0f,
};
static uint32_t square_indices[6] = {0, 1, 2, 0, 2, 3};

static antumbra_mesh_view square_mesh(void)
{
    antumbra_mesh_view view;
    view.positions = square_positions;
    view.vertex_count = 4;
    view.position_stride = 4 * sizeof(float);
    view.indices = square_indices;
    view.triangle_count = 2;
    return view;
}

#if defined(ANTUMBRA_HAS_STD)
/* scene_create on a bad mesh: the exact code, the message, and *out untouched. */
static void expect_create_fails(const char *what, const antumbra_mesh_view *mesh, antumbra_result want,
                                const char *fragment, const char *fragment2)
{
    antumbra_scene *out;
    memset(&out, SENTINEL, sizeof out);
    expect_failure(what, antumbra_scene_create(mesh, &out), want, "antumbra_scene_create", fragment, fragment2,
                   (const char *)NULL);
    expect_untouched(what, &out, sizeof out);
}

static void test_scene_create(void)
{
    antumbra_mesh_view mesh;
    antumbra_scene *scene;
    float positions[4 * 4];
    uint32_t indices[6];
    unsigned char shifted[4 * 4 * sizeof(float) + 8];
    uint32_t shifted_indices[6 + 1];

    mesh = square_mesh();
    /* NULL-argument messages all read "<argument> is NULL...", from one helper. */
    expect_create_fails("NULL mesh", NULL, ANTUMBRA_RESULT_NULL_ARGUMENT, ": mesh is NULL", NULL);
    expect_failure("NULL out", antumbra_scene_create(&mesh, NULL), ANTUMBRA_RESULT_NULL_ARGUMENT,
                   "antumbra_scene_create", ": out is NULL", (const char *)NULL);

    mesh = square_mesh();
    mesh.positions = NULL;
    expect_create_fails("NULL positions", &mesh, ANTUMBRA_RESULT_NULL_ARGUMENT, "mesh->positions is NULL", NULL);

    mesh = square_mesh();
    mesh.indices = NULL;
    expect_create_fails("NULL indices", &mesh, ANTUMBRA_RESULT_NULL_ARGUMENT, "mesh->indices is NULL", NULL);

    /* A scene needs a triangle, whether the empty index array is NULL or not. */
    mesh = square_mesh();
    mesh.indices = NULL;
    mesh.triangle_count = 0;
    expect_create_fails("zero triangles, NULL indices", &mesh, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                        "mesh->triangle_count", NULL);
    mesh = square_mesh();
    mesh.triangle_count = 0;
    expect_create_fails("zero triangles", &mesh, ANTUMBRA_RESULT_INVALID_ARGUMENT, "mesh->triangle_count", NULL);

    mesh = square_mesh();
    mesh.position_stride = 8;
    expect_create_fails("stride 8", &mesh, ANTUMBRA_RESULT_INVALID_ARGUMENT, "position_stride", NULL);

    /* indices[5] is the third corner of triangle 1; vertex_count is a valid
     * index's exclusive bound, so it is the smallest bad one. */
    mesh = square_mesh();
    memcpy(indices, square_indices, sizeof indices);
    indices[5] = 4;
    mesh.indices = indices;
    expect_create_fails("index == vertex_count", &mesh, ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE, "mesh->indices[5]",
                        "vertex_count");

    mesh = square_mesh();
    memcpy(positions, square_positions, sizeof positions);
    positions[2 * 4 + 1] = NAN;
    mesh.positions = positions;
    expect_create_fails("NaN coordinate", &mesh, ANTUMBRA_RESULT_NON_FINITE, "mesh->positions", "vertex 2");
    positions[2 * 4 + 1] = 1.0f;
    positions[3 * 4 + 0] = -INFINITY;
    expect_create_fails("-Inf coordinate", &mesh, ANTUMBRA_RESULT_NON_FINITE, "mesh->positions", "vertex 3");

    /* The padding float is not a coordinate: a NaN there is none of our business. */
    memcpy(positions, square_positions, sizeof positions);
    positions[1 * 4 + 3] = NAN;
    mesh = square_mesh();
    mesh.positions = positions;
    scene = NULL;
    expect_success("NaN in the stride padding", antumbra_scene_create(&mesh, &scene));
    antumbra_scene_destroy(scene);

    /* Sizes that overflow are rejected before any memory is read. */
    mesh = square_mesh();
    mesh.vertex_count = SIZE_MAX;
    expect_create_fails("vertex_count * stride overflows", &mesh, ANTUMBRA_RESULT_INVALID_ARGUMENT, "overflow",
                        NULL);

    /* Indices must be 4-byte aligned... */
    memcpy(shifted_indices, square_indices, sizeof square_indices);
    mesh = square_mesh();
    mesh.indices = offset_pointer(shifted_indices, 2);
    expect_create_fails("misaligned indices", &mesh, ANTUMBRA_RESULT_INVALID_ARGUMENT, "mesh->indices", "aligned");

    /* ...positions need not be: the header promises any alignment works. */
    memcpy(shifted + 1, square_positions, sizeof square_positions);
    mesh = square_mesh();
    mesh.positions = offset_pointer(shifted, 1);
    scene = NULL;
    expect_success("unaligned positions", antumbra_scene_create(&mesh, &scene));
    expect(scene != NULL, "unaligned positions: OK but NULL scene");
    antumbra_scene_destroy(scene);

    /* Stride 0 means packed. */
    {
        const float packed[] = {0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f};
        const uint32_t triangle[] = {0, 1, 2};
        mesh.positions = packed;
        mesh.vertex_count = 3;
        mesh.position_stride = 0;
        mesh.indices = triangle;
        mesh.triangle_count = 1;
        scene = NULL;
        expect_success("stride 0 (packed)", antumbra_scene_create(&mesh, &scene));
        antumbra_scene_destroy(scene);
    }

    /* Destroying nothing is allowed. */
    antumbra_scene_destroy(NULL);
    ++checks_run;
}

/* scene_refit on bad input: the exact code and message, and the scene still
 * the one it was (a ray down onto the square at x = 0.25 hits it at t = 1). */
static void test_scene_refit(void)
{
    antumbra_mesh_view mesh;
    antumbra_scene *scene = NULL;
    float positions[4 * 4];
    const float origin[3] = {0.25f, 0.25f, 1.0f}, down[3] = {0.0f, 0.0f, -1.0f}, t_max = 10.0f;
    antumbra_hit hit;

    mesh = square_mesh();
    expect_success("refit: create", antumbra_scene_create(&mesh, &scene));
    expect_failure("refit: NULL scene", antumbra_scene_refit(NULL, &mesh), ANTUMBRA_RESULT_NULL_ARGUMENT,
                   "antumbra_scene_refit", ": scene is NULL", (const char *)NULL);
    expect_failure("refit: NULL mesh", antumbra_scene_refit(scene, NULL), ANTUMBRA_RESULT_NULL_ARGUMENT,
                   "antumbra_scene_refit", ": mesh is NULL", (const char *)NULL);
    mesh.triangle_count = 1;
    expect_failure("refit: another triangle count", antumbra_scene_refit(scene, &mesh),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_scene_refit", "mesh->triangle_count is 1",
                   "the scene has 2 triangles", (const char *)NULL);
    mesh = square_mesh();
    memcpy(positions, square_positions, sizeof positions);
    positions[4 + 2] = NAN;
    mesh.positions = positions;
    expect_failure("refit: NaN position", antumbra_scene_refit(scene, &mesh), ANTUMBRA_RESULT_NON_FINITE,
                   "antumbra_scene_refit", "mesh->positions", (const char *)NULL);
    positions[4 + 2] = 2e12f;
    expect_failure("refit: coordinate out of range", antumbra_scene_refit(scene, &mesh),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_scene_refit", "vertex 1", (const char *)NULL);
    expect_success("refit: query after refused refits",
                   antumbra_scene_intersect(scene, origin, down, &t_max, 1, &hit));
    expect(hit.distance == 1.0f, "refit: a refused refit moved the square (hit at t = %g)", (double)hit.distance);
    /* The square lowered by 0.5: the same ray now travels 1.5. */
    memcpy(positions, square_positions, sizeof positions);
    positions[2] = positions[4 + 2] = positions[8 + 2] = positions[12 + 2] = -0.5f;
    expect_success("refit: lowered square", antumbra_scene_refit(scene, &mesh));
    expect_success("refit: query after the refit", antumbra_scene_intersect(scene, origin, down, &t_max, 1, &hit));
    expect(hit.distance == 1.5f, "refit: the lowered square is hit at t = %g, not 1.5", (double)hit.distance);
    antumbra_scene_destroy(scene);
    ++checks_run;
}

/* ------------------------------------------------------------------------- */
/* Ray queries                                                                 */
/* ------------------------------------------------------------------------- */

/* Three rays straight down onto the square (z = 0), from z = 1. */
typedef struct rays {
    float origins[9], directions[9], t_max[3];
} rays;

static rays good_rays(void)
{
    rays r;
    int i;
    for (i = 0; i < 3; ++i) {
        r.origins[3 * i + 0] = 0.25f + 0.25f * (float)i;
        r.origins[3 * i + 1] = 0.5f;
        r.origins[3 * i + 2] = 1.0f;
        r.directions[3 * i + 0] = 0.0f;
        r.directions[3 * i + 1] = 0.0f;
        r.directions[3 * i + 2] = -1.0f;
        r.t_max[i] = INFINITY;
    }
    return r;
}

/* Both queries on the same bad batch fail the same way and write nothing. */
static void expect_queries_fail(const char *what, const antumbra_scene *scene, const rays *r, size_t count,
                                antumbra_result want, const char *fragment)
{
    uint8_t occluded[3];
    antumbra_hit hits[3];
    char label[128];

    memset(occluded, SENTINEL, sizeof occluded);
    sprintf(label, "occluded: %s", what);
    expect_failure(label, antumbra_scene_occluded(scene, r->origins, r->directions, r->t_max, count, occluded),
                   want, "antumbra_scene_occluded", fragment, (const char *)NULL);
    expect_untouched(label, occluded, sizeof occluded);

    memset(hits, SENTINEL, sizeof hits);
    sprintf(label, "intersect: %s", what);
    expect_failure(label, antumbra_scene_intersect(scene, r->origins, r->directions, r->t_max, count, hits), want,
                   "antumbra_scene_intersect", fragment, (const char *)NULL);
    expect_untouched(label, hits, sizeof hits);
}

static void test_queries(void)
{
    antumbra_mesh_view mesh = square_mesh();
    antumbra_scene *scene = NULL;
    rays r;
    uint8_t occluded[3];
    antumbra_hit hits[3];
    unsigned char unaligned[64];

    expect_success("create the square", antumbra_scene_create(&mesh, &scene));
    if (scene == NULL) {
        return;
    }

    /* The good path first, so the failures below are failures of validation. */
    r = good_rays();
    memset(occluded, SENTINEL, sizeof occluded);
    expect_success("occluded, good rays", antumbra_scene_occluded(scene, r.origins, r.directions, r.t_max, 3,
                                                                   occluded));
    expect(occluded[0] == 1 && occluded[1] == 1 && occluded[2] == 1, "good rays: occluded %u %u %u", occluded[0],
           occluded[1], occluded[2]);
    expect_success("intersect, good rays", antumbra_scene_intersect(scene, r.origins, r.directions, r.t_max, 3,
                                                                     hits));
    expect(hits[0].distance == 1.0f && hits[0].triangle == 1 && fabsf(hits[0].u - 0.25f) < 1e-6f &&
               fabsf(hits[0].v - 0.25f) < 1e-6f,
           "ray 0 should hit triangle 1 at t = 1, (u, v) = (0.25, 0.25); got t = %g, %u, (%g, %g)",
           (double)hits[0].distance, hits[0].triangle, (double)hits[0].u, (double)hits[0].v);

    /* t counts lengths of the direction, and the segment is open at t_max. */
    r.directions[0 * 3 + 2] = r.directions[1 * 3 + 2] = r.directions[2 * 3 + 2] = -2.0f;
    r.t_max[0] = 0.5f;
    r.t_max[1] = 0.5001f;
    r.t_max[2] = -0.0f; /* >= 0 holds for -0.0: a valid, empty segment */
    expect_success("occluded, t_max edge cases", antumbra_scene_occluded(scene, r.origins, r.directions, r.t_max,
                                                                          3, occluded));
    expect(occluded[0] == 0 && occluded[1] == 1 && occluded[2] == 0,
           "t_max 0.5 (hit at exactly 0.5), 0.5001, -0.0: occluded %u %u %u, want 0 1 0", occluded[0],
           occluded[1], occluded[2]);
    expect_success("intersect, t_max edge cases", antumbra_scene_intersect(scene, r.origins, r.directions,
                                                                            r.t_max, 3, hits));
    expect(hits[0].triangle == ANTUMBRA_INVALID_INDEX && isinf(hits[0].distance) && hits[0].distance > 0.0f &&
               hits[0].u == 0.0f && hits[0].v == 0.0f,
           "a miss is (+inf, INVALID_INDEX, 0, 0); got (%g, %u, %g, %g)", (double)hits[0].distance,
           hits[0].triangle, (double)hits[0].u, (double)hits[0].v);
    expect(hits[1].distance == 0.5f, "direction of length 2: hit at t = %g, want 0.5", (double)hits[1].distance);

    r = good_rays();
    expect_queries_fail("NULL scene", NULL, &r, 3, ANTUMBRA_RESULT_NULL_ARGUMENT, ": scene is NULL");
    expect_queries_fail("NULL scene, no rays", NULL, &r, 0, ANTUMBRA_RESULT_NULL_ARGUMENT, ": scene is NULL");

    r = good_rays();
    r.origins[2 * 3 + 1] = NAN;
    expect_queries_fail("NaN origin", scene, &r, 3, ANTUMBRA_RESULT_NON_FINITE, "origins[2]");

    r = good_rays();
    r.directions[1 * 3 + 0] = INFINITY;
    expect_queries_fail("Inf direction", scene, &r, 3, ANTUMBRA_RESULT_NON_FINITE, "directions[1]");

    r = good_rays();
    r.directions[0] = r.directions[1] = r.directions[2] = 0.0f;
    expect_queries_fail("zero direction", scene, &r, 3, ANTUMBRA_RESULT_INVALID_ARGUMENT, "directions[0]");

    r = good_rays();
    r.directions[1 * 3 + 2] = -0.0f;
    r.directions[1 * 3 + 0] = -0.0f;
    r.directions[1 * 3 + 1] = 0.0f;
    expect_queries_fail("negative-zero direction", scene, &r, 3, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                        "directions[1]");

    r = good_rays();
    r.t_max[1] = NAN;
    expect_queries_fail("NaN t_max", scene, &r, 3, ANTUMBRA_RESULT_NON_FINITE, "t_max[1]");

    r = good_rays();
    r.t_max[2] = -1.0f;
    expect_queries_fail("negative t_max", scene, &r, 3, ANTUMBRA_RESULT_INVALID_ARGUMENT, "t_max[2]");
    r.t_max[2] = -INFINITY;
    expect_queries_fail("-Inf t_max", scene, &r, 3, ANTUMBRA_RESULT_INVALID_ARGUMENT, "t_max[2]");

    /* NULL arrays with rays to cast. */
    r = good_rays();
    memset(occluded, SENTINEL, sizeof occluded);
    expect_failure("NULL origins", antumbra_scene_occluded(scene, NULL, r.directions, r.t_max, 3, occluded),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_scene_occluded", ": origins is NULL", (const char *)NULL);
    expect_failure("NULL directions", antumbra_scene_occluded(scene, r.origins, NULL, r.t_max, 3, occluded),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_scene_occluded", ": directions is NULL", (const char *)NULL);
    expect_failure("NULL t_max", antumbra_scene_occluded(scene, r.origins, r.directions, NULL, 3, occluded),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_scene_occluded", ": t_max is NULL", (const char *)NULL);
    expect_untouched("NULL input arrays", occluded, sizeof occluded);
    expect_failure("NULL occluded", antumbra_scene_occluded(scene, r.origins, r.directions, r.t_max, 3, NULL),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_scene_occluded", ": occluded is NULL", (const char *)NULL);
    expect_failure("NULL hits", antumbra_scene_intersect(scene, r.origins, r.directions, r.t_max, 3, NULL),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_scene_intersect", ": hits is NULL", (const char *)NULL);

    /* An empty batch is fine with NULL everywhere. */
    expect_success("occluded, 0 rays, NULL arrays", antumbra_scene_occluded(scene, NULL, NULL, NULL, 0, NULL));
    expect_success("intersect, 0 rays, NULL arrays", antumbra_scene_intersect(scene, NULL, NULL, NULL, 0, NULL));

    /* Arrays of floats must be float-aligned. */
    r = good_rays();
    memcpy(unaligned + 1, r.origins, sizeof r.origins);
    memset(occluded, SENTINEL, sizeof occluded);
    expect_failure("misaligned origins",
                   antumbra_scene_occluded(scene, offset_pointer(unaligned, 1), r.directions, r.t_max, 3, occluded),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_scene_occluded", "origins", "aligned",
                   (const char *)NULL);
    expect_untouched("misaligned origins", occluded, sizeof occluded);
    expect_failure("misaligned hits",
                   antumbra_scene_intersect(scene, r.origins, r.directions, r.t_max, 3,
                                            (antumbra_hit *)(uintptr_t)offset_pointer(unaligned, 2)),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_scene_intersect", "hits", "aligned",
                   (const char *)NULL);

    /* A ray count whose array sizes overflow is rejected before any memory is
     * read (the arrays here are far too short, and must not be touched). */
    memset(occluded, SENTINEL, sizeof occluded);
    expect_failure("ray_count overflows",
                   antumbra_scene_occluded(scene, r.origins, r.directions, r.t_max, SIZE_MAX, occluded),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_scene_occluded", "ray_count", (const char *)NULL);
    expect_untouched("ray_count overflows", occluded, sizeof occluded);

    antumbra_scene_destroy(scene);
}

#endif /* ANTUMBRA_HAS_STD: scenes and ray queries */

/* ------------------------------------------------------------------------- */
/* Soft shadows                                                                */
/* ------------------------------------------------------------------------- */

/* A unit square light at z = 2 over the square mesh (which lies at z = 0), and
 * five samples on it: its centre and four points near its corners. */
static const float ssv_light[4 * 3] = {0.0f, 0.0f, 2.0f, 1.0f, 0.0f, 2.0f, 1.0f, 1.0f, 2.0f, 0.0f, 1.0f, 2.0f};
static const float ssv_samples[5 * 3] = {0.5f, 0.5f, 2.0f, 0.1f, 0.1f, 2.0f, 0.9f, 0.1f, 2.0f,
                                         0.9f, 0.9f, 2.0f, 0.1f, 0.9f, 2.0f};

static antumbra_result ssv_create_with(const antumbra_mesh_view *mesh, const float *light, size_t light_count,
                                       const float *samples, size_t sample_count, const antumbra_ssv_options *options,
                                       antumbra_ssv **out)
{
    return antumbra_ssv_create(mesh, light, light_count, samples, sample_count, options, out);
}

/* ssv_create fails with the exact code and message; *out stays untouched. */
static void expect_ssv_create_fails(const char *what, const antumbra_mesh_view *mesh, const float *light,
                                    size_t light_count, const float *samples, size_t sample_count,
                                    const antumbra_ssv_options *options, antumbra_result want, const char *fragment,
                                    const char *fragment2)
{
    antumbra_ssv *out;
    memset(&out, SENTINEL, sizeof out);
    expect_failure(what, ssv_create_with(mesh, light, light_count, samples, sample_count, options, &out), want,
                   "antumbra_ssv_create", fragment, fragment2, (const char *)NULL);
    expect_untouched(what, &out, sizeof out);
}

static void test_ssv_create(void)
{
    antumbra_mesh_view mesh = square_mesh();
    antumbra_ssv_options options;
    antumbra_ssv *ssv = NULL;
    float light[17 * 3];
    float samples[1025 * 3];
    unsigned char shifted[sizeof ssv_light + 8];
    size_t i;

    /* The good call first, so the failures below are failures of validation. */
    expect_success("ssv create", antumbra_ssv_create(&mesh, ssv_light, 4, ssv_samples, 5, NULL, &ssv));
    expect(ssv != NULL, "ssv create: OK but NULL handle");
    antumbra_ssv_destroy(ssv);

    expect_ssv_create_fails("ssv NULL occluders", NULL, ssv_light, 4, ssv_samples, 5, NULL,
                            ANTUMBRA_RESULT_NULL_ARGUMENT, ": occluders is NULL", NULL);
    expect_failure("ssv NULL out", antumbra_ssv_create(&mesh, ssv_light, 4, ssv_samples, 5, NULL, NULL),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_ssv_create", ": out is NULL", (const char *)NULL);
    expect_ssv_create_fails("ssv NULL light", &mesh, NULL, 4, ssv_samples, 5, NULL, ANTUMBRA_RESULT_NULL_ARGUMENT,
                            "light_vertices is NULL", NULL);
    expect_ssv_create_fails("ssv NULL samples", &mesh, ssv_light, 4, NULL, 5, NULL, ANTUMBRA_RESULT_NULL_ARGUMENT,
                            "samples is NULL", NULL);
    mesh.indices = NULL;
    expect_ssv_create_fails("ssv NULL mesh indices", &mesh, ssv_light, 4, ssv_samples, 5, NULL,
                            ANTUMBRA_RESULT_NULL_ARGUMENT, "occluders->indices is NULL", NULL);
    mesh = square_mesh();

    /* Light vertex counts: 3..16. */
    expect_ssv_create_fails("ssv 0 light vertices", &mesh, NULL, 0, ssv_samples, 5, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "light_vertex_count is 0", NULL);
    expect_ssv_create_fails("ssv 2 light vertices", &mesh, ssv_light, 2, ssv_samples, 5, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "light_vertex_count is 2", NULL);
    /* A 17-gon, convex and planar, is still too many. */
    for (i = 0; i < 17; ++i) {
        light[3 * i + 0] = 0.5f + 0.5f * cosf(2.0f * 3.14159265f * (float)i / 17.0f);
        light[3 * i + 1] = 0.5f + 0.5f * sinf(2.0f * 3.14159265f * (float)i / 17.0f);
        light[3 * i + 2] = 2.0f;
    }
    expect_ssv_create_fails("ssv 17 light vertices", &mesh, light, 17, ssv_samples, 1, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "light_vertex_count is 17", NULL);
    ssv = NULL;
    expect_success("ssv 16-gon light", antumbra_ssv_create(&mesh, light, 16, ssv_samples, 1, NULL, &ssv));
    antumbra_ssv_destroy(ssv);

    /* Non-planar, non-convex, degenerate, NaN lights. */
    memcpy(light, ssv_light, sizeof ssv_light);
    light[2 * 3 + 2] = 2.2f;
    expect_ssv_create_fails("ssv non-planar light", &mesh, light, 4, ssv_samples, 1, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "light_vertices[", "plane");
    memcpy(light, ssv_light, sizeof ssv_light);
    light[2 * 3 + 0] = 0.4f; /* (0.4, 0.4) pulls corner 2 inside: a dart, not convex */
    light[2 * 3 + 1] = 0.4f;
    expect_ssv_create_fails("ssv non-convex light", &mesh, light, 4, ssv_samples, 1, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "not convex", "light_vertices[");
    memcpy(light, ssv_light, sizeof ssv_light);
    memcpy(&light[3], &light[0], 3 * sizeof(float));
    expect_ssv_create_fails("ssv repeated light vertex", &mesh, light, 4, ssv_samples, 1, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "light_vertices", "degenerate");
    memcpy(light, ssv_light, sizeof ssv_light);
    light[3 * 3 + 1] = NAN;
    expect_ssv_create_fails("ssv NaN light vertex", &mesh, light, 4, ssv_samples, 1, NULL,
                            ANTUMBRA_RESULT_NON_FINITE, "light_vertices[3]", NULL);

    /* Samples: 1..1024 of them, each on the light. */
    expect_ssv_create_fails("ssv 0 samples", &mesh, ssv_light, 4, ssv_samples, 0, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "sample_count is 0", NULL);
    for (i = 0; i < 1025; ++i) {
        memcpy(&samples[3 * i], &ssv_samples[3 * (i % 5)], 3 * sizeof(float));
    }
    expect_ssv_create_fails("ssv 1025 samples", &mesh, ssv_light, 4, samples, 1025, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "sample_count is 1025", NULL);
    ssv = NULL;
    expect_success("ssv 1024 samples", antumbra_ssv_create(&mesh, ssv_light, 4, samples, 1024, NULL, &ssv));
    antumbra_ssv_destroy(ssv);
    memcpy(samples, ssv_samples, sizeof ssv_samples);
    samples[3 * 3 + 2] = 2.01f; /* off the light's plane */
    expect_ssv_create_fails("ssv sample off the plane", &mesh, ssv_light, 4, samples, 5, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "samples[3]", "off the light");
    memcpy(samples, ssv_samples, sizeof ssv_samples);
    samples[4 * 3 + 0] = 1.5f; /* on the plane, outside the square */
    expect_ssv_create_fails("ssv sample outside the light", &mesh, ssv_light, 4, samples, 5, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "samples[4]", "off the light");
    memcpy(samples, ssv_samples, sizeof ssv_samples);
    samples[1 * 3 + 0] = INFINITY;
    expect_ssv_create_fails("ssv infinite sample", &mesh, ssv_light, 4, samples, 5, NULL,
                            ANTUMBRA_RESULT_NON_FINITE, "samples[1]", NULL);

    /* Misaligned float arrays. */
    memcpy(shifted + 1, ssv_light, sizeof ssv_light);
    expect_ssv_create_fails("ssv misaligned light", &mesh, offset_pointer(shifted, 1), 4, ssv_samples, 5, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "light_vertices", "aligned");
    memcpy(shifted + 2, ssv_samples, 3 * sizeof(float));
    expect_ssv_create_fails("ssv misaligned samples", &mesh, ssv_light, 4, offset_pointer(shifted, 2), 1, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "samples", "aligned");

    /* A bad mesh is named as the occluders. */
    mesh = square_mesh();
    mesh.position_stride = 8;
    expect_ssv_create_fails("ssv stride 8", &mesh, ssv_light, 4, ssv_samples, 5, NULL,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "occluders->position_stride", NULL);
    mesh = square_mesh();
    {
        uint32_t indices[6];
        memcpy(indices, square_indices, sizeof indices);
        indices[4] = 9;
        mesh.indices = indices;
        expect_ssv_create_fails("ssv index out of range", &mesh, ssv_light, 4, ssv_samples, 5, NULL,
                                ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE, "occluders->indices[4]", NULL);
    }

    /* Options: every field checked. */
    mesh = square_mesh();
    antumbra_ssv_options_init(&options);
    options.structure = 4;
    expect_ssv_create_fails("ssv structure 4", &mesh, ssv_light, 4, ssv_samples, 5, &options,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->structure is 4", NULL);
    antumbra_ssv_options_init(&options);
    options.leaf_edges = 0;
    expect_ssv_create_fails("ssv leaf_edges 0", &mesh, ssv_light, 4, ssv_samples, 5, &options,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->leaf_edges", NULL);
    antumbra_ssv_options_init(&options);
    options.max_depth = ANTUMBRA_SSV_MAX_DEPTH_LIMIT + 1;
    expect_ssv_create_fails("ssv max_depth too deep", &mesh, ssv_light, 4, ssv_samples, 5, &options,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->max_depth", NULL);
    antumbra_ssv_options_init(&options);
    options.hemicube_resolution = 0;
    expect_ssv_create_fails("ssv hemicube_resolution 0", &mesh, ssv_light, 4, ssv_samples, 5, &options,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->hemicube_resolution", NULL);
    antumbra_ssv_options_init(&options);
    options.parallel = 2;
    expect_ssv_create_fails("ssv parallel 2", &mesh, ssv_light, 4, ssv_samples, 5, &options,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->parallel", NULL);
    antumbra_ssv_options_init(&options);
    options.use_root_bounds = 1; /* root_min == root_max == 0: an empty box */
    expect_ssv_create_fails("ssv empty root box", &mesh, ssv_light, 4, ssv_samples, 5, &options,
                            ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->root_min", NULL);
    options.root_max[0] = options.root_max[1] = options.root_max[2] = 1.0f;
    options.root_min[1] = NAN;
    expect_ssv_create_fails("ssv NaN root box", &mesh, ssv_light, 4, ssv_samples, 5, &options,
                            ANTUMBRA_RESULT_NON_FINITE, "options->root_min", NULL);
    expect_ssv_create_fails("ssv misaligned options", &mesh, ssv_light, 4, ssv_samples, 5,
                            offset_pointer(&options, 1), ANTUMBRA_RESULT_INVALID_ARGUMENT, "options", "aligned");

    /* options_init on NULL writes nothing and says so. */
    antumbra_ssv_options_init(NULL);
    expect_failure("ssv options_init(NULL)", ANTUMBRA_RESULT_NULL_ARGUMENT, ANTUMBRA_RESULT_NULL_ARGUMENT,
                   "antumbra_ssv_options_init", "options is NULL", (const char *)NULL);

    /* No occluders at all is fine: everything is lit. */
    mesh = square_mesh();
    mesh.indices = NULL;
    mesh.triangle_count = 0;
    ssv = NULL;
    expect_success("ssv no occluders", antumbra_ssv_create(&mesh, ssv_light, 4, ssv_samples, 5, NULL, &ssv));
    if (ssv != NULL) {
        const float point[3] = {0.5f, 0.5f, -1.0f};
        uint64_t bits = 0;
        uint32_t count = 0;
        expect_success("ssv query, no occluders", antumbra_ssv_query(ssv, point, 1, &bits, &count));
        expect(bits == 0x1f && count == 5, "no occluders: bits 0x%lx, count %u", (unsigned long)bits,
               (unsigned)count);
    }
    antumbra_ssv_destroy(ssv);

    /* Destroying nothing is allowed. */
    antumbra_ssv_destroy(NULL);
    ++checks_run;
}

/* Both outputs pre-filled with the sentinel; the query fails and writes neither. */
static void expect_ssv_query_fails(const char *what, const antumbra_ssv *ssv, const float *points, size_t count,
                                   uint64_t *bits, uint32_t *counts, antumbra_result want, const char *fragment,
                                   const char *fragment2)
{
    expect_failure(what, antumbra_ssv_query(ssv, points, count, bits, counts), want, "antumbra_ssv_query", fragment,
                   fragment2, (const char *)NULL);
}

static void test_ssv_query(void)
{
    antumbra_mesh_view mesh = square_mesh();
    antumbra_ssv *ssv = NULL;
    antumbra_ssv_statistics stats;
    /* Below the square (z = -1): the square hides the whole light from (0.5, 0.5)
     * and none of it from (3, 3). */
    float points[3 * 3] = {0.5f, 0.5f, -1.0f, 3.0f, 3.0f, -1.0f, -3.0f, 0.5f, -1.0f};
    uint64_t bits[4];
    uint32_t counts[4];
    /* 8-aligned (a union with uint64_t), so that 4 bytes in is misaligned for a
     * uint64_t on every target, whatever the stack's alignment. */
    union {
        uint64_t align;
        unsigned char bytes[sizeof points + sizeof bits + 8];
    } shifted_storage;
    unsigned char *shifted = shifted_storage.bytes;

    expect_success("ssv create (query)", antumbra_ssv_create(&mesh, ssv_light, 4, ssv_samples, 5, NULL, &ssv));
    if (ssv == NULL) {
        return;
    }
    memset(bits, SENTINEL, sizeof bits);
    memset(counts, SENTINEL, sizeof counts);
    expect_success("ssv query", antumbra_ssv_query(ssv, points, 3, bits, counts));
    expect(bits[0] == 0 && counts[0] == 0 && bits[1] == 0x1f && counts[1] == 5 && bits[2] == 0x1f && counts[2] == 5,
           "ssv query: bits %lx %lx %lx, counts %u %u %u", (unsigned long)bits[0], (unsigned long)bits[1],
           (unsigned long)bits[2], (unsigned)counts[0], (unsigned)counts[1], (unsigned)counts[2]);
    expect(bits[3] == (uint64_t)0xA5A5A5A5A5A5A5A5u && counts[3] == 0xA5A5A5A5u,
           "ssv query wrote past point_count");
    /* visible_counts may be NULL. */
    memset(bits, SENTINEL, sizeof bits);
    expect_success("ssv query, NULL counts", antumbra_ssv_query(ssv, points, 3, bits, NULL));
    expect(bits[1] == 0x1f, "ssv query, NULL counts: bits %lx", (unsigned long)bits[1]);
    /* An empty batch may be all NULL. */
    expect_success("ssv query, empty", antumbra_ssv_query(ssv, NULL, 0, NULL, NULL));

    memset(bits, SENTINEL, sizeof bits);
    memset(counts, SENTINEL, sizeof counts);
    expect_ssv_query_fails("ssv query NULL handle", NULL, points, 3, bits, counts, ANTUMBRA_RESULT_NULL_ARGUMENT,
                           "ssv is NULL", NULL);
    expect_ssv_query_fails("ssv query NULL points", ssv, NULL, 3, bits, counts, ANTUMBRA_RESULT_NULL_ARGUMENT,
                           "points is NULL", NULL);
    expect_ssv_query_fails("ssv query NULL bits", ssv, points, 3, NULL, counts, ANTUMBRA_RESULT_NULL_ARGUMENT,
                           "visibility_bits is NULL", NULL);
    points[2 * 3 + 1] = NAN;
    expect_ssv_query_fails("ssv query NaN point", ssv, points, 3, bits, counts, ANTUMBRA_RESULT_NON_FINITE,
                           "points[2]", "not finite");
    points[2 * 3 + 1] = 0.5f;
    points[1 * 3 + 0] = 2e12f;
    expect_ssv_query_fails("ssv query point out of range", ssv, points, 3, bits, counts,
                           ANTUMBRA_RESULT_INVALID_ARGUMENT, "points[1]", "range");
    points[1 * 3 + 0] = 3.0f;
    expect_ssv_query_fails("ssv query count overflows", ssv, points, SIZE_MAX, bits, counts,
                           ANTUMBRA_RESULT_INVALID_ARGUMENT, "overflow", NULL);
    expect_untouched("ssv query failures: bits", bits, sizeof bits);
    expect_untouched("ssv query failures: counts", counts, sizeof counts);

    /* Misaligned points, bits, counts. */
    memcpy(shifted + 1, points, sizeof points);
    expect_ssv_query_fails("ssv query misaligned points", ssv, offset_pointer(shifted, 1), 3, bits, counts,
                           ANTUMBRA_RESULT_INVALID_ARGUMENT, "points", "aligned");
    expect_ssv_query_fails("ssv query misaligned bits", ssv, points, 3, (uint64_t *)offset_pointer(shifted, 4),
                           counts, ANTUMBRA_RESULT_INVALID_ARGUMENT, "visibility_bits", "aligned");
    expect_ssv_query_fails("ssv query misaligned counts", ssv, points, 3, bits,
                           (uint32_t *)offset_pointer(shifted, 2), ANTUMBRA_RESULT_INVALID_ARGUMENT,
                           "visible_counts", "aligned");
    expect_untouched("ssv query misaligned: bits", bits, sizeof bits);
    expect_untouched("ssv query misaligned: counts", counts, sizeof counts);

    /* Statistics: NULL arguments, and the queries counted so far (3 + 3 + 0). */
    memset(&stats, SENTINEL, sizeof stats);
    expect_failure("ssv statistics NULL handle", antumbra_ssv_get_statistics(NULL, &stats),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_ssv_get_statistics", "ssv is NULL", (const char *)NULL);
    expect_failure("ssv statistics NULL out", antumbra_ssv_get_statistics(ssv, NULL), ANTUMBRA_RESULT_NULL_ARGUMENT,
                   "antumbra_ssv_get_statistics", "statistics is NULL", (const char *)NULL);
    expect_failure("ssv statistics misaligned",
                   antumbra_ssv_get_statistics(ssv, (antumbra_ssv_statistics *)offset_pointer(&stats, 4)),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_ssv_get_statistics", "statistics", (const char *)NULL);
    expect_untouched("ssv statistics failures", &stats, sizeof stats);
    expect_success("ssv statistics", antumbra_ssv_get_statistics(ssv, &stats));
    expect(stats.queries == 6 && stats.sample_count == 5 && stats.words_per_receiver == 1 &&
               stats.light_vertex_count == 4 && stats.structure == ANTUMBRA_SSV_STRUCTURE_HIERARCHY,
           "ssv statistics: %lu queries, %u samples", (unsigned long)stats.queries, (unsigned)stats.sample_count);

    /* Update: refused inputs change nothing; the square moved 3 units along x
     * then shadows (5, 0.5, -1) and not (0.5, 0.5, -1), and the statistics
     * restart. */
    {
        float moved[4 * 4];
        uint32_t bad_indices[6] = {0, 1, 2, 0, 2, 4};
        antumbra_mesh_view bad = mesh;
        size_t i;
        memcpy(moved, square_positions, sizeof moved);
        for (i = 0; i < 4; ++i) {
            moved[4 * i] += 3.0f;
        }
        expect_failure("ssv update NULL handle", antumbra_ssv_update(NULL, &mesh), ANTUMBRA_RESULT_NULL_ARGUMENT,
                       "antumbra_ssv_update", "ssv is NULL", (const char *)NULL);
        expect_failure("ssv update NULL occluders", antumbra_ssv_update(ssv, NULL), ANTUMBRA_RESULT_NULL_ARGUMENT,
                       "antumbra_ssv_update", "occluders is NULL", (const char *)NULL);
        bad.indices = bad_indices;
        expect_failure("ssv update index out of range", antumbra_ssv_update(ssv, &bad),
                       ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE, "antumbra_ssv_update", "occluders->indices[5]",
                       (const char *)NULL);
        expect_success("ssv query after refused updates", antumbra_ssv_query(ssv, points, 1, bits, counts));
        expect(bits[0] == 0, "ssv: a refused update moved the square (bits %lx)", (unsigned long)bits[0]);
        bad = mesh;
        bad.positions = moved;
        expect_success("ssv update", antumbra_ssv_update(ssv, &bad));
        points[3] = 5.0f; /* every segment to the light meets z = 0 at x in [3.37, 3.63] */
        points[4] = 0.5f;
        expect_success("ssv query after the update", antumbra_ssv_query(ssv, points, 2, bits, counts));
        expect(bits[0] == 0x1f && bits[1] == 0, "ssv update: bits %lx %lx, want 1f 0", (unsigned long)bits[0],
               (unsigned long)bits[1]);
        expect_success("ssv statistics after the update", antumbra_ssv_get_statistics(ssv, &stats));
        expect(stats.queries == 2, "ssv statistics after the update: %lu queries, want 2",
               (unsigned long)stats.queries);
    }

    antumbra_ssv_destroy(ssv);
}

static void test_ssv_generate_samples(void)
{
    float samples[3 * 8], light[4 * 3];
    unsigned char shifted[sizeof samples + 8];
    size_t i;

    memset(samples, SENTINEL, sizeof samples);
    expect_success("generate samples",
                   antumbra_ssv_generate_samples(ssv_light, 4, 8, ANTUMBRA_SSV_SAMPLES_STRATIFIED, 1, samples));
    for (i = 0; i < 8; ++i) {
        expect(samples[3 * i] >= 0.0f && samples[3 * i] <= 1.0f && samples[3 * i + 1] >= 0.0f &&
                   samples[3 * i + 1] <= 1.0f && fabsf(samples[3 * i + 2] - 2.0f) < 1e-6f,
               "generated sample %lu (%g, %g, %g) is off the light", (unsigned long)i, (double)samples[3 * i],
               (double)samples[3 * i + 1], (double)samples[3 * i + 2]);
    }

    memset(samples, SENTINEL, sizeof samples);
    expect_failure("generate NULL light",
                   antumbra_ssv_generate_samples(NULL, 4, 8, ANTUMBRA_SSV_SAMPLES_JITTERED, 1, samples),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_ssv_generate_samples", "light_vertices is NULL",
                   (const char *)NULL);
    expect_failure("generate NULL samples",
                   antumbra_ssv_generate_samples(ssv_light, 4, 8, ANTUMBRA_SSV_SAMPLES_JITTERED, 1, NULL),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_ssv_generate_samples", "samples is NULL",
                   (const char *)NULL);
    expect_failure("generate 0 samples",
                   antumbra_ssv_generate_samples(ssv_light, 4, 0, ANTUMBRA_SSV_SAMPLES_JITTERED, 1, samples),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_ssv_generate_samples", "sample_count is 0",
                   (const char *)NULL);
    expect_failure("generate 1025 samples",
                   antumbra_ssv_generate_samples(ssv_light, 4, 1025, ANTUMBRA_SSV_SAMPLES_JITTERED, 1, samples),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_ssv_generate_samples", "sample_count is 1025",
                   (const char *)NULL);
    expect_failure("generate pattern 2", antumbra_ssv_generate_samples(ssv_light, 4, 8, 2, 1, samples),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_ssv_generate_samples", "pattern is 2",
                   (const char *)NULL);
    expect_failure("generate 2 light vertices",
                   antumbra_ssv_generate_samples(ssv_light, 2, 8, ANTUMBRA_SSV_SAMPLES_JITTERED, 1, samples),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_ssv_generate_samples", "light_vertex_count is 2",
                   (const char *)NULL);
    memcpy(light, ssv_light, sizeof light);
    light[0] = NAN;
    expect_failure("generate NaN light",
                   antumbra_ssv_generate_samples(light, 4, 8, ANTUMBRA_SSV_SAMPLES_JITTERED, 1, samples),
                   ANTUMBRA_RESULT_NON_FINITE, "antumbra_ssv_generate_samples", "light_vertices[0]",
                   (const char *)NULL);
    expect_failure("generate misaligned samples",
                   antumbra_ssv_generate_samples(ssv_light, 4, 8, ANTUMBRA_SSV_SAMPLES_JITTERED, 1,
                                                 (float *)offset_pointer(shifted, 1)),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_ssv_generate_samples", "samples", (const char *)NULL);
    expect_untouched("generate failures", samples, sizeof samples);
}

/* ------------------------------------------------------------------------- */
/* The last error message                                                      */
/* ------------------------------------------------------------------------- */

/* A call that fails the same way in every build: NULL_ARGUMENT, naming
 * "occluders". */
static antumbra_result known_failure(void)
{
    antumbra_ssv *out = NULL;
    return antumbra_ssv_create(NULL, NULL, 0, NULL, 0, NULL, &out);
}

static void test_last_error(void)
{
    const char *message;
    size_t length, required;
    char buffer[256];
    antumbra_result result;

    /* Make a known failure. */
    result = known_failure();
    message = antumbra_last_error_message();
    length = strlen(message);
    expect(result == ANTUMBRA_RESULT_NULL_ARGUMENT && length > 0 && length + 1 < sizeof buffer,
           "setup: NULL occluders gave %s, \"%s\"", antumbra_result_str(result), message);

    /* Too small by one (no room for the NUL): nothing written, size reported. */
    memset(buffer, SENTINEL, sizeof buffer);
    required = 0;
    expect(antumbra_last_error_message_copy(buffer, length, &required) == ANTUMBRA_RESULT_BUFFER_TOO_SMALL,
           "copy into %lu bytes is not BUFFER_TOO_SMALL", (unsigned long)length);
    expect(required == length + 1, "required size %lu, want %lu", (unsigned long)required,
           (unsigned long)(length + 1));
    expect_untouched("copy into too small a buffer", buffer, sizeof buffer);

    /* Sizing with (NULL, 0) is the usual first call. */
    required = 0;
    expect(antumbra_last_error_message_copy(NULL, 0, &required) == ANTUMBRA_RESULT_BUFFER_TOO_SMALL &&
               required == length + 1,
           "sizing call (NULL, 0): required %lu", (unsigned long)required);
    expect(antumbra_last_error_message_copy(NULL, 8, &required) == ANTUMBRA_RESULT_NULL_ARGUMENT,
           "copy into (NULL, 8) is not NULL_ARGUMENT");
    expect(antumbra_last_error_message_copy(buffer, 0, NULL) == ANTUMBRA_RESULT_BUFFER_TOO_SMALL,
           "copy with no required_size out-parameter");

    /* Exactly big enough, then with room to spare. */
    memset(buffer, SENTINEL, sizeof buffer);
    required = 0;
    expect(antumbra_last_error_message_copy(buffer, length + 1, &required) == ANTUMBRA_RESULT_OK,
           "copy into exactly %lu bytes failed", (unsigned long)(length + 1));
    expect(required == length + 1 && strcmp(buffer, antumbra_last_error_message()) == 0 &&
               (unsigned char)buffer[length + 1] == SENTINEL,
           "exact copy: \"%s\" (required %lu) vs \"%s\"", buffer, (unsigned long)required,
           antumbra_last_error_message());
    expect(antumbra_last_error_message_copy(buffer, sizeof buffer, NULL) == ANTUMBRA_RESULT_OK &&
               strcmp(buffer, antumbra_last_error_message()) == 0,
           "roomy copy differs");

    /* Copying does not replace the message it copies, even when copying fails. */
    expect(strlen(antumbra_last_error_message()) == length && strstr(antumbra_last_error_message(), "occluders"),
           "the message changed while being copied: \"%s\"", antumbra_last_error_message());
}

static void test_success_clears_message(void)
{
    const float direction[3] = {0.0f, 0.0f, 1.0f};
    const float identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    float values[4];
    size_t required = 0;
    char buffer[4];

    expect(known_failure() != ANTUMBRA_RESULT_OK && antumbra_last_error_message()[0] != '\0',
           "setup: NULL occluders did not fail with a message");
    expect_success("eval after a failure", antumbra_sh_eval(direction, 2, values));
    required = 0;
    memset(buffer, SENTINEL, sizeof buffer);
    expect(antumbra_last_error_message_copy(buffer, sizeof buffer, &required) == ANTUMBRA_RESULT_OK &&
               required == 1 && buffer[0] == '\0',
           "copy of the empty message: required %lu", (unsigned long)required);

    expect(antumbra_sh_rotate(NULL, 2, NULL, 0, NULL) == ANTUMBRA_RESULT_NULL_ARGUMENT,
           "setup: NULL rotation did not fail");
    expect_success("empty batch after a failure", antumbra_sh_rotate(identity, 2, NULL, 0, NULL));
}

/* ------------------------------------------------------------------------- */
/* Result names                                                                */
/* ------------------------------------------------------------------------- */

static void test_result_str(void)
{
    static const struct {
        antumbra_result code;
        const char *name;
    } names[] = {
        {ANTUMBRA_RESULT_OK, "ANTUMBRA_RESULT_OK"},
        {ANTUMBRA_RESULT_NULL_ARGUMENT, "ANTUMBRA_RESULT_NULL_ARGUMENT"},
        {ANTUMBRA_RESULT_INVALID_ARGUMENT, "ANTUMBRA_RESULT_INVALID_ARGUMENT"},
        {ANTUMBRA_RESULT_NON_FINITE, "ANTUMBRA_RESULT_NON_FINITE"},
        {ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE, "ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE"},
        {ANTUMBRA_RESULT_BUFFER_TOO_SMALL, "ANTUMBRA_RESULT_BUFFER_TOO_SMALL"},
        {ANTUMBRA_RESULT_OUT_OF_MEMORY, "ANTUMBRA_RESULT_OUT_OF_MEMORY"},
        {ANTUMBRA_RESULT_UNSUPPORTED, "ANTUMBRA_RESULT_UNSUPPORTED"},
        {ANTUMBRA_RESULT_PANIC, "ANTUMBRA_RESULT_PANIC"},
        {ANTUMBRA_RESULT_POISONED, "ANTUMBRA_RESULT_POISONED"},
        {ANTUMBRA_RESULT_INVALID_DATA, "ANTUMBRA_RESULT_INVALID_DATA"},
        {11, "ANTUMBRA_RESULT_UNKNOWN"},
        {-1, "ANTUMBRA_RESULT_UNKNOWN"},
        {INT32_MAX, "ANTUMBRA_RESULT_UNKNOWN"},
        {INT32_MIN, "ANTUMBRA_RESULT_UNKNOWN"},
    };
    size_t i;
    for (i = 0; i < sizeof names / sizeof names[0]; ++i) {
        const char *name = antumbra_result_str(names[i].code);
        expect(name != NULL && strcmp(name, names[i].name) == 0, "antumbra_result_str(%ld) is \"%s\", want \"%s\"",
               (long)names[i].code, name ? name : "(NULL)", names[i].name);
    }
}

/* ------------------------------------------------------------------------- */
/* The error callback                                                          */
/* ------------------------------------------------------------------------- */

typedef struct callback_log {
    int calls;
    antumbra_result code;
    char message[256];
} callback_log;

/* Must not call into Antumbra: it only records what it was given. */
static void record_error(antumbra_result code, const char *message, void *user_data)
{
    callback_log *log = user_data;
    log->calls++;
    log->code = code;
    strncpy(log->message, message ? message : "(NULL)", sizeof log->message - 1);
    log->message[sizeof log->message - 1] = '\0';
}

static void test_error_callback(void)
{
    static callback_log log; /* static: its address is the user_data we expect back */
    callback_log other;
    antumbra_result result;
    float tangent[3], bitangent[3];
    const float normal[3] = {0.0f, 0.0f, 1.0f};

    memset(&log, 0, sizeof log);
    memset(&other, 0, sizeof other);
    antumbra_set_error_callback(record_error, &log);

    result = known_failure();
    expect(log.calls == 1, "callback called %d times for one failure", log.calls);
    expect(log.code == result && result == ANTUMBRA_RESULT_NULL_ARGUMENT, "callback got code %d, call returned %d",
           (int)log.code, (int)result);
    expect(strcmp(log.message, antumbra_last_error_message()) == 0,
           "callback message \"%s\" differs from the last error \"%s\"", log.message, antumbra_last_error_message());

    /* Successes do not call it. */
    antumbra_frame_from_normal(normal, tangent, bitangent);
    expect(log.calls == 1, "callback called on a success");

    /* Replacing the callback's user_data routes reports to the new one. */
    antumbra_set_error_callback(record_error, &other);
    result = antumbra_sh_rotate(NULL, 2, NULL, 0, NULL);
    expect(log.calls == 1 && other.calls == 1 && other.code == ANTUMBRA_RESULT_NULL_ARGUMENT,
           "after switching user_data: old log %d calls, new log %d calls", log.calls, other.calls);

    /* Removed: failures still fail, silently. */
    antumbra_set_error_callback(NULL, NULL);
    result = known_failure();
    expect(result == ANTUMBRA_RESULT_NULL_ARGUMENT && log.calls == 1 && other.calls == 1,
           "callback called after removal (%d, %d calls)", log.calls, other.calls);
}

/* ------------------------------------------------------------------------- */
/* antumbra_frame_from_normal                                                  */
/* ------------------------------------------------------------------------- */

/* Calls the void function with a callback installed, to learn its result code. */
static antumbra_result frame_result(const float *normal, float *tangent, float *bitangent)
{
    callback_log log;
    memset(&log, 0, sizeof log);
    log.code = ANTUMBRA_RESULT_OK;
    antumbra_set_error_callback(record_error, &log);
    antumbra_frame_from_normal(normal, tangent, bitangent);
    antumbra_set_error_callback(NULL, NULL);
    return log.code;
}

static void expect_frame_fails(const char *what, const float *normal, antumbra_result want, const char *fragment)
{
    float tangent[3], bitangent[3];
    memset(tangent, SENTINEL, sizeof tangent);
    memset(bitangent, SENTINEL, sizeof bitangent);
    expect_failure(what, frame_result(normal, tangent, bitangent), want, "antumbra_frame_from_normal", fragment,
                   (const char *)NULL);
    expect_untouched(what, tangent, sizeof tangent);
    expect_untouched(what, bitangent, sizeof bitangent);
}

static float dot3(const float *a, const float *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void test_frame(void)
{
    static const float normals[][3] = {
        {0.0f, 0.0f, 1.0f},   {0.0f, 0.0f, -1.0f},        {1.0f, 0.0f, 0.0f},   {0.0f, -1.0f, 0.0f},
        {0.6f, 0.0f, 0.8f},   {0.48f, -0.64f, -0.6f},     {0.0f, 0.6f, -0.8f},  {0.267261f, 0.534522f, 0.801784f},
        {0.0f, 0.0f, -0.0f},  /* not unit: rejected below, skipped here */
    };
    const float nan_normal[3] = {NAN, 0.0f, 1.0f};
    const float long_normal[3] = {0.0f, 0.0f, 2.0f};
    const float short_normal[3] = {0.0f, 0.0f, 0.998f};
    const float up[3] = {0.0f, 0.0f, 1.0f};
    float tangent[3], bitangent[3];
    size_t i;

    expect_frame_fails("NULL normal", NULL, ANTUMBRA_RESULT_NULL_ARGUMENT, ": normal is NULL");
    expect_frame_fails("NaN normal", nan_normal, ANTUMBRA_RESULT_NON_FINITE, ": normal");
    expect_frame_fails("normal of length 2", long_normal, ANTUMBRA_RESULT_INVALID_ARGUMENT, ": normal");
    expect_frame_fails("normal of length 0.998", short_normal, ANTUMBRA_RESULT_INVALID_ARGUMENT, ": normal");
    expect_frame_fails("zero normal", normals[8], ANTUMBRA_RESULT_INVALID_ARGUMENT, ": normal");
    memset(bitangent, SENTINEL, sizeof bitangent);
    expect_failure("NULL tangent", frame_result(up, NULL, bitangent), ANTUMBRA_RESULT_NULL_ARGUMENT,
                   "antumbra_frame_from_normal", ": tangent is NULL", (const char *)NULL);
    expect_untouched("NULL tangent", bitangent, sizeof bitangent);
    memset(tangent, SENTINEL, sizeof tangent);
    expect_failure("NULL bitangent", frame_result(up, tangent, NULL), ANTUMBRA_RESULT_NULL_ARGUMENT,
                   "antumbra_frame_from_normal", ": bitangent is NULL", (const char *)NULL);
    expect_untouched("NULL bitangent", tangent, sizeof tangent);

    /* The +z normal gives exactly the x and y axes. */
    expect(frame_result(up, tangent, bitangent) == ANTUMBRA_RESULT_OK, "frame of +z failed");
    expect(antumbra_last_error_message()[0] == '\0', "frame of +z left message \"%s\"", antumbra_last_error_message());
    expect(tangent[0] == 1.0f && tangent[1] == 0.0f && tangent[2] == 0.0f && bitangent[0] == 0.0f &&
               bitangent[1] == 1.0f && bitangent[2] == 0.0f,
           "frame of +z: tangent (%g, %g, %g), bitangent (%g, %g, %g)", (double)tangent[0], (double)tangent[1],
           (double)tangent[2], (double)bitangent[0], (double)bitangent[1], (double)bitangent[2]);

    for (i = 0; i < 8; ++i) {
        const float *n = normals[i];
        /* The documented formula, evaluated here in the same order. */
        const float s = n[2] >= 0.0f ? 1.0f : -1.0f, a = -1.0f / (s + n[2]), c = n[0] * n[1] * a;
        const float want_t[3] = {1.0f + s * n[0] * n[0] * a, s * c, -s * n[0]};
        const float want_b[3] = {c, s + n[1] * n[1] * a, -n[1]};
        float cross_tb[3];
        int k;
        expect(frame_result(n, tangent, bitangent) == ANTUMBRA_RESULT_OK, "frame of normal %lu failed",
               (unsigned long)i);
        cross_tb[0] = tangent[1] * bitangent[2] - tangent[2] * bitangent[1];
        cross_tb[1] = tangent[2] * bitangent[0] - tangent[0] * bitangent[2];
        cross_tb[2] = tangent[0] * bitangent[1] - tangent[1] * bitangent[0];
        expect(fabsf(dot3(tangent, tangent) - 1.0f) < 1e-5f && fabsf(dot3(bitangent, bitangent) - 1.0f) < 1e-5f &&
                   fabsf(dot3(tangent, bitangent)) < 1e-5f && fabsf(dot3(tangent, n)) < 1e-5f &&
                   fabsf(dot3(bitangent, n)) < 1e-5f,
               "frame of normal %lu is not orthonormal", (unsigned long)i);
        for (k = 0; k < 3; ++k) {
            expect(fabsf(cross_tb[k] - n[k]) < 1e-5f, "normal %lu: tangent x bitangent is not the normal",
                   (unsigned long)i);
            expect(fabsf(tangent[k] - want_t[k]) < 1e-6f && fabsf(bitangent[k] - want_b[k]) < 1e-6f,
                   "normal %lu: frame differs from the documented formula", (unsigned long)i);
        }
    }
}

#if defined(ANTUMBRA_HAS_STD)
/* ------------------------------------------------------------------------- */
/* Per-thread messages                                                         */
/* ------------------------------------------------------------------------- */

static void *fail_on_another_thread(void *argument)
{
    antumbra_scene *out = NULL;
    int *ok = argument;
    antumbra_result result;
    /* A new thread starts with no error, whatever other threads did. */
    const int starts_empty = antumbra_last_error_message()[0] == '\0';
    result = antumbra_scene_create(NULL, &out);
    *ok = starts_empty && result == ANTUMBRA_RESULT_NULL_ARGUMENT &&
          strstr(antumbra_last_error_message(), "mesh") != NULL;
    return NULL;
}

static void test_thread_local_message(void)
{
    pthread_t thread;
    int other_ok = 0;
    char before[256];

    expect(antumbra_scene_occluded(NULL, NULL, NULL, NULL, 0, NULL) == ANTUMBRA_RESULT_NULL_ARGUMENT,
           "setup: NULL scene did not fail");
    strncpy(before, antumbra_last_error_message(), sizeof before - 1);
    before[sizeof before - 1] = '\0';

    if (pthread_create(&thread, NULL, fail_on_another_thread, &other_ok) != 0 || pthread_join(thread, NULL) != 0) {
        expect(0, "could not run the second thread");
        return;
    }
    expect(other_ok, "the second thread did not see its own, fresh error message");
    expect(strcmp(before, antumbra_last_error_message()) == 0,
           "another thread's failure changed this thread's message to \"%s\"", antumbra_last_error_message());
}

/* ------------------------------------------------------------------------- */
/* Precomputed transfer: bake, describe, save, load, compress, shade           */
/* ------------------------------------------------------------------------- */

/* Square normals: +Z, packed. */
static float square_normals[4 * 3] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};

static antumbra_transfer_options small_options(uint32_t kind)
{
    antumbra_transfer_options o;
    antumbra_transfer_options_init(&o);
    o.kind = kind;
    o.bands = 2;
    o.grid = 2;
    o.rays = 8;
    return o;
}

/* A bake that must fail with `want`, leave `out` untouched and name `fragment`. */
static void expect_bake_fails(const char *what, const antumbra_mesh_view *mesh, const float *normals,
                              const antumbra_transfer_options *options, antumbra_result want, const char *fragment)
{
    antumbra_transfer *out;
    antumbra_result r;
    memset(&out, SENTINEL, sizeof out);
    r = antumbra_transfer_bake(mesh, normals, options, NULL, NULL, &out);
    expect_failure(what, r, want, "antumbra_transfer_bake", fragment, NULL);
    expect_untouched(what, &out, sizeof out);
}

static void test_transfer_bake(void)
{
    antumbra_mesh_view mesh = square_mesh();
    antumbra_mesh_view bad = square_mesh();
    antumbra_transfer_options o = small_options(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    float normals[12];
    uint32_t bad_indices[6] = {0, 1, 2, 0, 2, 4};
    antumbra_transfer *out = NULL;

    /* The init functions tolerate NULL and say so. */
    antumbra_transfer_options_init(NULL);
    expect(strstr(antumbra_last_error_message(), "antumbra_transfer_options_init: options") != NULL,
           "options_init(NULL) message is \"%s\"", antumbra_last_error_message());
    antumbra_transfer_material_init(NULL);
    expect(strstr(antumbra_last_error_message(), "antumbra_transfer_material_init: material") != NULL,
           "material_init(NULL) message is \"%s\"", antumbra_last_error_message());

    expect_failure("bake, out NULL", antumbra_transfer_bake(&mesh, NULL, &o, NULL, NULL, NULL),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_transfer_bake", "out", NULL);
    expect_bake_fails("bake, mesh NULL", NULL, NULL, &o, ANTUMBRA_RESULT_NULL_ARGUMENT, "mesh");
    expect_bake_fails("bake, options NULL", &mesh, NULL, NULL, ANTUMBRA_RESULT_NULL_ARGUMENT, "options");

    o.kind = 4;
    expect_bake_fails("bake, kind 4", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->kind");
    o = small_options(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    o.bands = 0;
    expect_bake_fails("bake, bands 0", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->bands");
    o.bands = ANTUMBRA_SH_MAX_BANDS + 1;
    expect_bake_fails("bake, bands 9", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->bands");
    o = small_options(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    o.rays = 0;
    expect_bake_fails("bake, rays 0", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->rays");
    o.rays = ANTUMBRA_TRANSFER_MAX_RAYS + 1;
    expect_bake_fails("bake, rays too many", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->rays");
    o = small_options(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    o.bounces = ANTUMBRA_TRANSFER_MAX_BOUNCES + 1;
    expect_bake_fails("bake, bounces", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->bounces");
    o = small_options(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    o.parallel = 2;
    expect_bake_fails("bake, parallel 2", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->parallel");
    o = small_options(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    o.reserved = 1;
    expect_bake_fails("bake, reserved", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->reserved");
    o = small_options(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    o.albedo = 1.0f;
    expect_bake_fails("bake, albedo 1", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->albedo");
    o.albedo = NAN;
    expect_bake_fails("bake, albedo NaN", &mesh, NULL, &o, ANTUMBRA_RESULT_NON_FINITE, "options->albedo");
    o = small_options(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    o.ray_offset = -1.0f;
    expect_bake_fails("bake, ray_offset", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->ray_offset");
    o = small_options(ANTUMBRA_TRANSFER_KIND_MRT);
    o.grid = 1;
    expect_bake_fails("bake, MRT grid 1", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->grid");
    o = small_options(ANTUMBRA_TRANSFER_KIND_MRT);
    o.brdf = 3;
    expect_bake_fails("bake, brdf 3", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->brdf");
    o = small_options(ANTUMBRA_TRANSFER_KIND_MRT);
    o.brdf = ANTUMBRA_TRANSFER_BRDF_WARD;
    o.brdf_params[0] = 0.3f;
    o.brdf_params[1] = 0.0f;
    expect_bake_fails("bake, Ward alpha 0", &mesh, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                      "options->brdf_params[1]");
    o = small_options(ANTUMBRA_TRANSFER_KIND_MRT);
    o.brdf_params[0] = INFINITY;
    expect_bake_fails("bake, Phong exponent inf", &mesh, NULL, &o, ANTUMBRA_RESULT_NON_FINITE,
                      "options->brdf_params[0]");

    o = small_options(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    memcpy(normals, square_normals, sizeof normals);
    normals[3 * 2 + 2] = 2.0f;
    expect_bake_fails("bake, normal not unit", &mesh, normals, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "normals[2]");
    normals[3 * 2 + 2] = NAN;
    expect_bake_fails("bake, normal NaN", &mesh, normals, &o, ANTUMBRA_RESULT_NON_FINITE, "normals[2]");
    bad.triangle_count = 0;
    expect_bake_fails("bake, no triangles", &bad, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "triangle_count");
    bad = square_mesh();
    bad.indices = bad_indices;
    expect_bake_fails("bake, index out of range", &bad, NULL, &o, ANTUMBRA_RESULT_INDEX_OUT_OF_RANGE,
                      "mesh->indices[5]");
    bad = square_mesh();
    bad.triangle_count = 1; /* vertex 3 is then used by no triangle */
    expect_bake_fails("bake, unused vertex without normals", &bad, NULL, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                      "vertex 3");
    /* ...but with normals given it bakes. */
    expect_success("bake, unused vertex with normals",
                   antumbra_transfer_bake(&bad, square_normals, &o, NULL, NULL, &out));
    antumbra_transfer_destroy(out);
    antumbra_transfer_destroy(NULL); /* a no-op */
}

static antumbra_transfer *bake_square(uint32_t kind)
{
    antumbra_mesh_view mesh = square_mesh();
    antumbra_transfer_options o = small_options(kind);
    antumbra_transfer *out = NULL;
    antumbra_result r = antumbra_transfer_bake(&mesh, NULL, &o, NULL, NULL, &out);
    expect_success("bake the square", r);
    if (r != ANTUMBRA_RESULT_OK) {
        fprintf(stderr, "bad_input: cannot continue the transfer checks\n");
        exit(EXIT_FAILURE);
    }
    return out;
}

static void expect_load_fails(const char *what, const uint8_t *bytes, size_t len, antumbra_result want,
                              const char *fragment)
{
    antumbra_transfer *out;
    antumbra_result r;
    memset(&out, SENTINEL, sizeof out);
    r = antumbra_transfer_load(bytes, len, &out);
    expect_failure(what, r, want, "antumbra_transfer_load", fragment, NULL);
    expect_untouched(what, &out, sizeof out);
    if (r == ANTUMBRA_RESULT_OK) {
        antumbra_transfer_destroy(out);
    }
}

static void test_transfer_files(void)
{
    antumbra_transfer *set = bake_square(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    antumbra_transfer_info info;
    uint8_t *bytes, *copy;
    size_t size = 0, small_size, i;
    int bit;
    char what[96];
    antumbra_transfer *loaded = NULL;

    expect_failure("describe, transfer NULL", antumbra_transfer_describe(NULL, &info), ANTUMBRA_RESULT_NULL_ARGUMENT,
                   "antumbra_transfer_describe", "transfer", NULL);
    expect_failure("describe, info NULL", antumbra_transfer_describe(set, NULL), ANTUMBRA_RESULT_NULL_ARGUMENT,
                   "antumbra_transfer_describe", "info", NULL);
    expect_success("describe", antumbra_transfer_describe(set, &info));
    expect(info.kind == ANTUMBRA_TRANSFER_KIND_DIFFUSE && info.bands == 2 && info.coeff_count == 4 &&
               info.vertex_count == 4 && info.components == 0,
           "describe: kind %u bands %u coeffs %u vertices %u", info.kind, info.bands, info.coeff_count,
           info.vertex_count);

    /* Save: sizing, too small (buffer untouched), NULL with capacity. */
    expect_failure("save, size query", antumbra_transfer_save(set, NULL, 0, &size), ANTUMBRA_RESULT_BUFFER_TOO_SMALL,
                   "antumbra_transfer_save", "capacity", NULL);
    expect(size == info.file_bytes, "save reports %lu bytes needed, describe %lu", (unsigned long)size,
           (unsigned long)info.file_bytes);
    bytes = malloc(size + 1);
    copy = malloc(size + 1);
    if (!bytes || !copy) {
        fprintf(stderr, "bad_input: out of memory\n");
        exit(EXIT_FAILURE);
    }
    memset(bytes, SENTINEL, size);
    small_size = 0;
    expect_failure("save, one byte short", antumbra_transfer_save(set, bytes, size - 1, &small_size),
                   ANTUMBRA_RESULT_BUFFER_TOO_SMALL, "antumbra_transfer_save", "capacity", NULL);
    expect_untouched("save, one byte short", bytes, size);
    expect(small_size == size, "a short save reports %lu, want %lu", (unsigned long)small_size, (unsigned long)size);
    expect_failure("save, buffer NULL", antumbra_transfer_save(set, NULL, size, NULL), ANTUMBRA_RESULT_NULL_ARGUMENT,
                   "antumbra_transfer_save", "buffer", NULL);
    expect_failure("save, transfer NULL", antumbra_transfer_save(NULL, bytes, size, NULL),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_transfer_save", "transfer", NULL);
    expect_success("save", antumbra_transfer_save(set, bytes, size, NULL));

    /* Load: NULL, empty, every truncation, every single-bit flip, a trailing byte. */
    expect_failure("load, out NULL", antumbra_transfer_load(bytes, size, NULL), ANTUMBRA_RESULT_NULL_ARGUMENT,
                   "antumbra_transfer_load", "out", NULL);
    expect_load_fails("load, bytes NULL", NULL, size, ANTUMBRA_RESULT_NULL_ARGUMENT, "bytes");
    expect_load_fails("load, empty", NULL, 0, ANTUMBRA_RESULT_INVALID_DATA, "truncated");
    for (i = 0; i < size; ++i) {
        snprintf(what, sizeof what, "load, truncated to %lu bytes", (unsigned long)i);
        expect_load_fails(what, bytes, i, ANTUMBRA_RESULT_INVALID_DATA, "bytes");
    }
    for (i = 0; i < size; ++i) {
        for (bit = 0; bit < 8; bit += 3) {
            memcpy(copy, bytes, size);
            copy[i] ^= (uint8_t)(1u << bit);
            snprintf(what, sizeof what, "load, bit %d of byte %lu flipped", bit, (unsigned long)i);
            expect_load_fails(what, copy, size, ANTUMBRA_RESULT_INVALID_DATA, "bytes");
        }
    }
    memcpy(copy, bytes, size);
    copy[size] = 0;
    expect_load_fails("load, a trailing byte", copy, size + 1, ANTUMBRA_RESULT_INVALID_DATA, "after the payload");
    memcpy(copy, bytes, size);
    copy[0] = 'X';
    expect_load_fails("load, bad magic", copy, size, ANTUMBRA_RESULT_INVALID_DATA, "magic");
    expect_success("load", antumbra_transfer_load(bytes, size, &loaded));
    antumbra_transfer_destroy(loaded);

    free(bytes);
    free(copy);
    antumbra_transfer_destroy(set);
}

static void expect_compress_fails(const char *what, const antumbra_transfer *set, uint32_t k, antumbra_result want,
                                  const char *fragment)
{
    antumbra_transfer *out;
    antumbra_result r;
    memset(&out, SENTINEL, sizeof out);
    r = antumbra_transfer_compress(set, k, &out);
    expect_failure(what, r, want, "antumbra_transfer_compress", fragment, NULL);
    expect_untouched(what, &out, sizeof out);
}

static void test_transfer_compress(void)
{
    antumbra_transfer *diffuse = bake_square(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    antumbra_transfer *mrt = bake_square(ANTUMBRA_TRANSFER_KIND_MRT);
    antumbra_transfer *pca = NULL;
    expect_compress_fails("compress, transfer NULL", NULL, 1, ANTUMBRA_RESULT_NULL_ARGUMENT, "transfer");
    expect_failure("compress, out NULL", antumbra_transfer_compress(mrt, 1, NULL), ANTUMBRA_RESULT_NULL_ARGUMENT,
                   "antumbra_transfer_compress", "out", NULL);
    expect_compress_fails("compress, diffuse set", diffuse, 1, ANTUMBRA_RESULT_INVALID_ARGUMENT, "MRT");
    expect_compress_fails("compress, 0 components", mrt, 0, ANTUMBRA_RESULT_INVALID_ARGUMENT, "components");
    /* 4 vertices: at most 4 components. */
    expect_compress_fails("compress, 5 components", mrt, 5, ANTUMBRA_RESULT_INVALID_ARGUMENT, "components");
    expect_success("compress", antumbra_transfer_compress(mrt, 2, &pca));
    expect_compress_fails("compress, already compressed", pca, 1, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                          "already compressed");
    antumbra_transfer_destroy(pca);
    antumbra_transfer_destroy(mrt);
    antumbra_transfer_destroy(diffuse);
}

static void expect_clustered_fails(const char *what, const antumbra_transfer *set, uint32_t clusters, uint32_t k,
                                   antumbra_result want, const char *fragment)
{
    antumbra_transfer *out;
    antumbra_result r;
    memset(&out, SENTINEL, sizeof out);
    r = antumbra_transfer_compress_clustered(set, clusters, k, &out);
    expect_failure(what, r, want, "antumbra_transfer_compress_clustered", fragment, NULL);
    expect_untouched(what, &out, sizeof out);
}

static void test_transfer_compress_clustered(void)
{
    antumbra_transfer *diffuse = bake_square(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    antumbra_transfer *mrt = bake_square(ANTUMBRA_TRANSFER_KIND_MRT);
    antumbra_transfer *cpca = NULL;
    antumbra_transfer_info info;
    expect_clustered_fails("clustered, transfer NULL", NULL, 2, 1, ANTUMBRA_RESULT_NULL_ARGUMENT, "transfer");
    expect_failure("clustered, out NULL", antumbra_transfer_compress_clustered(mrt, 2, 1, NULL),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_transfer_compress_clustered", "out", NULL);
    expect_clustered_fails("clustered, diffuse set", diffuse, 2, 1, ANTUMBRA_RESULT_INVALID_ARGUMENT, "MRT");
    expect_clustered_fails("clustered, 0 clusters", mrt, 0, 1, ANTUMBRA_RESULT_INVALID_ARGUMENT, "clusters");
    /* 4 vertices: at most 4 clusters and 4 components. */
    expect_clustered_fails("clustered, 5 clusters", mrt, 5, 1, ANTUMBRA_RESULT_INVALID_ARGUMENT, "clusters");
    expect_clustered_fails("clustered, 0 components", mrt, 2, 0, ANTUMBRA_RESULT_INVALID_ARGUMENT, "components");
    expect_clustered_fails("clustered, 5 components", mrt, 2, 5, ANTUMBRA_RESULT_INVALID_ARGUMENT, "components");
    expect_success("clustered", antumbra_transfer_compress_clustered(mrt, 2, 1, &cpca));
    expect_success("describe clustered", antumbra_transfer_describe(cpca, &info));
    expect(info.clusters == 2 && info.components == 1 && info.reserved == 0,
           "describe clustered: clusters %u, components %u, reserved %u", info.clusters, info.components,
           info.reserved);
    expect_clustered_fails("clustered, already compressed", cpca, 2, 1, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                           "already compressed");
    antumbra_transfer_destroy(cpca);
    antumbra_transfer_destroy(mrt);
    antumbra_transfer_destroy(diffuse);
}

/* lightmap_create with bad input: the exact code, the message, and *out untouched. */
static void expect_lightmap_fails(const char *what, const antumbra_mesh_view *mesh, const float *uvs,
                                  const antumbra_lightmap_options *options, antumbra_result want,
                                  const char *fragment)
{
    antumbra_lightmap *out;
    antumbra_result r;
    memset(&out, SENTINEL, sizeof out);
    r = antumbra_lightmap_create(mesh, uvs, NULL, options, &out);
    expect_failure(what, r, want, "antumbra_lightmap_create", fragment, NULL);
    expect_untouched(what, &out, sizeof out);
    if (r == ANTUMBRA_RESULT_OK) {
        antumbra_lightmap_destroy(out);
    }
}

static void test_lightmap(void)
{
    antumbra_mesh_view mesh = square_mesh();
    antumbra_mesh_view one_triangle = square_mesh();
    float uvs[8] = {0.1f, 0.1f, 0.9f, 0.1f, 0.9f, 0.9f, 0.1f, 0.9f};
    float bad_uvs[8];
    uint32_t doubled[6] = {0, 1, 2, 1, 2, 3}; /* two halves that overlap on the right */
    antumbra_mesh_view overlapping = square_mesh();
    antumbra_lightmap_options o;
    antumbra_lightmap *lightmap = NULL;
    antumbra_lightmap_info info;
    antumbra_transfer_options t = small_options(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    antumbra_transfer *set = NULL;
    antumbra_transfer_info set_info;
    antumbra_transfer *vertex_set = NULL;
    float *values, *image;
    uint32_t *entry_texels;
    uint32_t texels[2 * 1024];
    size_t n, texel_count;
    antumbra_result r;

    antumbra_lightmap_options_init(NULL);
    expect(strstr(antumbra_last_error_message(), "antumbra_lightmap_options_init: options") != NULL,
           "lightmap options_init(NULL) message is \"%s\"", antumbra_last_error_message());
    antumbra_lightmap_options_init(&o);
    expect(o.width == 256 && o.height == 256 && o.gutter == 2 && o.lift_probes == 8,
           "lightmap defaults %u x %u, gutter %u, probes %u", o.width, o.height, o.gutter, o.lift_probes);
    o.width = 16;
    o.height = 8;

    expect_failure("lightmap, out NULL", antumbra_lightmap_create(&mesh, uvs, NULL, &o, NULL),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_lightmap_create", "out", NULL);
    expect_lightmap_fails("lightmap, mesh NULL", NULL, uvs, &o, ANTUMBRA_RESULT_NULL_ARGUMENT, "mesh");
    expect_lightmap_fails("lightmap, uvs NULL", &mesh, NULL, &o, ANTUMBRA_RESULT_NULL_ARGUMENT, "uvs");
    expect_lightmap_fails("lightmap, options NULL", &mesh, uvs, NULL, ANTUMBRA_RESULT_NULL_ARGUMENT, "options");
    o.width = 0;
    expect_lightmap_fails("lightmap, width 0", &mesh, uvs, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->width");
    o.width = ANTUMBRA_LIGHTMAP_MAX_SIDE + 1;
    expect_lightmap_fails("lightmap, width too large", &mesh, uvs, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                          "options->width");
    o.width = 16;
    o.gutter = ANTUMBRA_LIGHTMAP_MAX_GUTTER + 1;
    expect_lightmap_fails("lightmap, gutter", &mesh, uvs, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "options->gutter");
    o.gutter = 2;
    o.lift_probes = ANTUMBRA_LIGHTMAP_MAX_PROBES + 1;
    expect_lightmap_fails("lightmap, probes", &mesh, uvs, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                          "options->lift_probes");
    o.lift_probes = 8;
    memcpy(bad_uvs, uvs, sizeof uvs);
    bad_uvs[5] = NAN;
    expect_lightmap_fails("lightmap, uv NaN", &mesh, bad_uvs, &o, ANTUMBRA_RESULT_NON_FINITE, "uvs[2]");
    bad_uvs[5] = 1.5f;
    expect_lightmap_fails("lightmap, uv outside", &mesh, bad_uvs, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT, "uvs[2]");
    memcpy(bad_uvs, uvs, sizeof uvs);
    bad_uvs[4] = 0.5f; /* vertex 2 on the line through vertices 0 and 1 */
    bad_uvs[5] = 0.1f;
    expect_lightmap_fails("lightmap, collinear uvs", &mesh, bad_uvs, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                          "collinear");
    overlapping.indices = doubled;
    expect_lightmap_fails("lightmap, overlapping charts", &overlapping, uvs, &o, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                          "overlap");

    expect_success("lightmap", antumbra_lightmap_create(&mesh, uvs, NULL, &o, &lightmap));
    expect_failure("lightmap describe, info NULL", antumbra_lightmap_describe(lightmap, NULL),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_lightmap_describe", "info", NULL);
    expect_failure("lightmap describe, lightmap NULL", antumbra_lightmap_describe(NULL, &info),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_lightmap_describe", "lightmap", NULL);
    expect_success("lightmap describe", antumbra_lightmap_describe(lightmap, &info));
    n = info.receiver_count;
    expect(info.width == 16 && info.height == 8 && info.gutter == 2 && n > 40 && n <= 128,
           "lightmap describe: %u x %u, gutter %u, %zu receivers", info.width, info.height, info.gutter, n);
    memset(texels, SENTINEL, sizeof texels);
    expect_failure("lightmap receivers, count", antumbra_lightmap_receivers(lightmap, NULL, NULL, texels, n + 1),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_lightmap_receivers", "receiver_count", NULL);
    expect_failure("lightmap receivers, all NULL", antumbra_lightmap_receivers(lightmap, NULL, NULL, NULL, n),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_lightmap_receivers", "all NULL", NULL);
    expect_untouched("lightmap receivers", texels, sizeof texels);
    expect_success("lightmap receivers", antumbra_lightmap_receivers(lightmap, NULL, NULL, texels, n));
    expect(texels[0] < 16 && texels[1] < 8, "lightmap receivers: first texel (%u, %u)", texels[0], texels[1]);

    one_triangle.triangle_count = 1;
    r = antumbra_lightmap_bake(lightmap, &one_triangle, NULL, &t, NULL, NULL, &set);
    expect_failure("lightmap bake, another mesh", r, ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_lightmap_bake",
                   "built from", NULL);
    expect_failure("lightmap bake, out NULL", antumbra_lightmap_bake(lightmap, &mesh, NULL, &t, NULL, NULL, NULL),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_lightmap_bake", "out", NULL);
    t.bands = 0;
    expect_failure("lightmap bake, bands 0", antumbra_lightmap_bake(lightmap, &mesh, NULL, &t, NULL, NULL, &set),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_lightmap_bake", "options->bands", NULL);
    expect(set == NULL, "lightmap bake: out written on failure");
    t = small_options(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    expect_success("lightmap bake", antumbra_lightmap_bake(lightmap, &mesh, NULL, &t, NULL, NULL, &set));
    expect_success("lightmap bake describe", antumbra_transfer_describe(set, &set_info));
    expect(set_info.vertex_count == n, "lightmap bake: %u entries for %zu receivers", set_info.vertex_count, n);

    texel_count = (size_t)info.width * info.height;
    values = (float *)calloc(n, sizeof(float));
    image = (float *)malloc(texel_count * sizeof(float));
    if (values == NULL || image == NULL) {
        fprintf(stderr, "bad_input: out of memory\n");
        exit(EXIT_FAILURE);
    }
    memset(image, SENTINEL, texel_count * sizeof(float));
    expect_failure("lightmap expand, value_count",
                   antumbra_lightmap_expand(lightmap, values, n - 1, 1, image, texel_count),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_lightmap_expand", "value_count", NULL);
    expect_failure("lightmap expand, image_count",
                   antumbra_lightmap_expand(lightmap, values, n, 1, image, texel_count + 1),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_lightmap_expand", "image_count", NULL);
    expect_failure("lightmap expand, channels 0", antumbra_lightmap_expand(lightmap, values, n, 0, image, texel_count),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_lightmap_expand", "channels", NULL);
    expect_failure("lightmap expand, values NULL", antumbra_lightmap_expand(lightmap, NULL, n, 1, image, texel_count),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_lightmap_expand", "values", NULL);
    expect_untouched("lightmap expand", image, texel_count * sizeof(float));
    expect_success("lightmap expand", antumbra_lightmap_expand(lightmap, values, n, 1, image, texel_count));

    /* The set's own texels and texture (what a loaded lightmap file offers). */
    expect(set_info.atlas_width == info.width && set_info.atlas_height == info.height,
           "lightmap set: atlas %ux%u, lightmap %ux%u", set_info.atlas_width, set_info.atlas_height, info.width,
           info.height);
    entry_texels = (uint32_t *)malloc(n * sizeof(uint32_t));
    if (entry_texels == NULL) {
        fprintf(stderr, "bad_input: out of memory\n");
        exit(EXIT_FAILURE);
    }
    memset(entry_texels, SENTINEL, n * sizeof(uint32_t));
    expect_failure("transfer texels, count", antumbra_transfer_texels(set, entry_texels, n + 1),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_transfer_texels", "count", NULL);
    expect_failure("transfer texels, texels NULL", antumbra_transfer_texels(set, NULL, n),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_transfer_texels", "texels", NULL);
    expect_failure("transfer texels, transfer NULL", antumbra_transfer_texels(NULL, entry_texels, n),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_transfer_texels", "transfer", NULL);
    expect_untouched("transfer texels", entry_texels, n * sizeof(uint32_t));
    expect_success("transfer texels", antumbra_transfer_texels(set, entry_texels, n));
    for (size_t k = 1; k < n; k++) {
        expect(entry_texels[k] > entry_texels[k - 1], "transfer texels: %u after %u", entry_texels[k],
               entry_texels[k - 1]);
    }
    memset(image, SENTINEL, texel_count * sizeof(float));
    expect_failure("transfer expand, gutter", antumbra_transfer_expand(set, 65, values, n, 1, image, texel_count),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_transfer_expand", "gutter", NULL);
    expect_failure("transfer expand, value_count",
                   antumbra_transfer_expand(set, 2, values, n + 1, 1, image, texel_count),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_transfer_expand", "value_count", NULL);
    expect_failure("transfer expand, image_count",
                   antumbra_transfer_expand(set, 2, values, n, 1, image, texel_count - 1),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_transfer_expand", "image_count", NULL);
    expect_failure("transfer expand, overlap", antumbra_transfer_expand(set, 2, image, n, 1, image, texel_count),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_transfer_expand", "overlap", NULL);
    expect_failure("transfer expand, image NULL", antumbra_transfer_expand(set, 2, values, n, 1, NULL, texel_count),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_transfer_expand", "image", NULL);
    expect_untouched("transfer expand", image, texel_count * sizeof(float));
    expect_success("transfer expand", antumbra_transfer_expand(set, 2, values, n, 1, image, texel_count));
    /* A per-vertex set has no texels. */
    expect_success("vertex bake", antumbra_transfer_bake(&mesh, NULL, &t, NULL, NULL, &vertex_set));
    expect_success("vertex bake describe", antumbra_transfer_describe(vertex_set, &set_info));
    expect(set_info.atlas_width == 0 && set_info.atlas_height == 0, "vertex set: atlas %ux%u",
           set_info.atlas_width, set_info.atlas_height);
    expect_failure("transfer texels, vertex set", antumbra_transfer_texels(vertex_set, entry_texels, 4),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_transfer_texels", "per-vertex", NULL);
    expect_failure("transfer expand, vertex set",
                   antumbra_transfer_expand(vertex_set, 2, values, 4, 1, image, texel_count),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_transfer_expand", "per-vertex", NULL);
    antumbra_transfer_destroy(vertex_set);
    free(entry_texels);
    free(values);
    free(image);
    antumbra_transfer_destroy(set);
    antumbra_lightmap_destroy(lightmap);
    antumbra_lightmap_destroy(NULL);
}

static void expect_shade_fails(const char *what, const antumbra_transfer *set, const float *lighting, size_t count,
                               const antumbra_transfer_material *material, size_t vertices, antumbra_result want,
                               const char *fragment)
{
    float rgb[4 * 3];
    antumbra_result r;
    memset(rgb, SENTINEL, sizeof rgb);
    r = antumbra_transfer_shade(set, lighting, count, material, 0, rgb, vertices);
    expect_failure(what, r, want, "antumbra_transfer_shade", fragment, NULL);
    expect_untouched(what, rgb, sizeof rgb);
}

static void test_transfer_shade(void)
{
    antumbra_transfer *set = bake_square(ANTUMBRA_TRANSFER_KIND_DIFFUSE);
    float lighting[3 * 4] = {1, 0, 0.5f, 0, 1, 0, 0.5f, 0, 1, 0, 0.5f, 0};
    float bad_lighting[3 * 4];
    float directions[4 * 3] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
    float positions[4 * 3], rgb[4 * 3];
    antumbra_transfer_material m;
    size_t i;

    antumbra_transfer_material_init(&m);
    expect_shade_fails("shade, transfer NULL", NULL, lighting, 12, &m, 4, ANTUMBRA_RESULT_NULL_ARGUMENT, "transfer");
    expect_shade_fails("shade, lighting NULL", set, NULL, 12, &m, 4, ANTUMBRA_RESULT_NULL_ARGUMENT, "lighting");
    expect_shade_fails("shade, lighting_count 27", set, lighting, 27, &m, 4, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                       "lighting_count");
    memcpy(bad_lighting, lighting, sizeof lighting);
    bad_lighting[6] = NAN;
    expect_shade_fails("shade, lighting NaN", set, bad_lighting, 12, &m, 4, ANTUMBRA_RESULT_NON_FINITE, "lighting[6]");
    expect_shade_fails("shade, vertex_count 3", set, lighting, 12, &m, 3, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                       "vertex_count");
    m.albedo[1] = -1.0f;
    expect_shade_fails("shade, negative albedo", set, lighting, 12, &m, 4, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                       "material->albedo[1]");
    antumbra_transfer_material_init(&m);
    m.phong_exponent = NAN;
    expect_shade_fails("shade, exponent NaN", set, lighting, 12, &m, 4, ANTUMBRA_RESULT_NON_FINITE,
                       "material->phong_exponent");
    antumbra_transfer_material_init(&m);
    m.eye[2] = INFINITY;
    expect_shade_fails("shade, eye inf", set, lighting, 12, &m, 4, ANTUMBRA_RESULT_NON_FINITE, "material->eye[2]");
    antumbra_transfer_material_init(&m);
    directions[3 * 3 + 0] = 0.0f;
    directions[3 * 3 + 2] = 0.0f;
    m.view_directions = directions;
    expect_shade_fails("shade, zero view direction", set, lighting, 12, &m, 4, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                       "material->view_directions[3]");
    directions[3 * 3 + 2] = NAN;
    expect_shade_fails("shade, NaN view direction", set, lighting, 12, &m, 4, ANTUMBRA_RESULT_NON_FINITE,
                       "material->view_directions[3]");
    antumbra_transfer_material_init(&m);
    expect_failure("shade, rgb NULL", antumbra_transfer_shade(set, lighting, 12, &m, 0, NULL, 4),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_transfer_shade", "rgb", NULL);
    expect_success("shade, default material (NULL)", antumbra_transfer_shade(set, lighting, 12, NULL, 0, rgb, 4));
    for (i = 0; i < 12; ++i) {
        expect(isfinite(rgb[i]) && rgb[i] >= 0.0f, "shade: rgb[%lu] = %g", (unsigned long)i, rgb[i]);
    }

    /* Geometry: wrong count, outputs untouched. */
    memset(positions, SENTINEL, sizeof positions);
    expect_failure("geometry, vertex_count 5", antumbra_transfer_geometry(set, positions, NULL, 5),
                   ANTUMBRA_RESULT_INVALID_ARGUMENT, "antumbra_transfer_geometry", "vertex_count", NULL);
    expect_untouched("geometry, vertex_count 5", positions, sizeof positions);
    expect_failure("geometry, transfer NULL", antumbra_transfer_geometry(NULL, positions, NULL, 4),
                   ANTUMBRA_RESULT_NULL_ARGUMENT, "antumbra_transfer_geometry", "transfer", NULL);
    expect_success("geometry", antumbra_transfer_geometry(set, positions, NULL, 4));
    expect(positions[3 * 2 + 0] == 1.0f && positions[3 * 2 + 1] == 1.0f && positions[3 * 2 + 2] == 0.0f,
           "geometry: vertex 2 is (%g, %g, %g)", positions[6], positions[7], positions[8]);
    antumbra_transfer_destroy(set);
}

#endif /* ANTUMBRA_HAS_STD: threads and precomputed transfer */

static void expect_rotate_fails(const char *what, const float *rotation, uint32_t bands, const float *coefficients,
                                size_t vectors, antumbra_result want, const char *fragment)
{
    float out[2 * 9];
    antumbra_result r;
    memset(out, SENTINEL, sizeof out);
    r = antumbra_sh_rotate(rotation, bands, coefficients, vectors, out);
    expect_failure(what, r, want, "antumbra_sh_rotate", fragment, NULL);
    expect_untouched(what, out, sizeof out);
}

static void test_sh_rotate(void)
{
    float identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    float sheared[9] = {1, 0.5f, 0, 0, 1, 0, 0, 0, 1};
    float nan_rotation[9] = {1, 0, 0, 0, NAN, 0, 0, 0, 1};
    float coefficients[2 * 9] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 1, 2, 3, 4, 5, 6, 7, 8, 9};
    float out[2 * 9];
    expect_rotate_fails("rotate, rotation NULL", NULL, 3, coefficients, 2, ANTUMBRA_RESULT_NULL_ARGUMENT, "rotation");
    expect_rotate_fails("rotate, sheared", sheared, 3, coefficients, 2, ANTUMBRA_RESULT_INVALID_ARGUMENT,
                        "orthogonal");
    expect_rotate_fails("rotate, NaN", nan_rotation, 3, coefficients, 2, ANTUMBRA_RESULT_NON_FINITE, "rotation[4]");
    expect_rotate_fails("rotate, bands 0", identity, 0, coefficients, 2, ANTUMBRA_RESULT_INVALID_ARGUMENT, "bands");
    expect_rotate_fails("rotate, coefficients NULL", identity, 3, NULL, 2, ANTUMBRA_RESULT_NULL_ARGUMENT,
                        "coefficients");
    coefficients[12] = INFINITY;
    expect_rotate_fails("rotate, coefficient inf", identity, 3, coefficients, 2, ANTUMBRA_RESULT_NON_FINITE,
                        "coefficients[12]");
    coefficients[12] = 4.0f;
    expect_success("rotate, empty batch", antumbra_sh_rotate(identity, 3, NULL, 0, NULL));
    expect_success("rotate", antumbra_sh_rotate(identity, 3, coefficients, 2, out));
    expect(memcmp(out, coefficients, sizeof out) == 0, "the identity rotation changed the coefficients");
}

int main(void)
{
    if (antumbra_version() != ANTUMBRA_VERSION ||
        strcmp(antumbra_version_string(), ANTUMBRA_VERSION_STRING) != 0) {
        fprintf(stderr, "bad_input: library %s (0x%06lx) does not match header %s\n", antumbra_version_string(),
                (unsigned long)antumbra_version(), ANTUMBRA_VERSION_STRING);
        return EXIT_FAILURE;
    }
    /* A fresh thread has no error yet. */
    expect(antumbra_last_error_message()[0] == '\0', "initial message is \"%s\"", antumbra_last_error_message());

#if defined(ANTUMBRA_HAS_STD)
    test_scene_create();
    test_scene_refit();
    test_queries();
#endif
    test_ssv_create();
    test_ssv_query();
    test_ssv_generate_samples();
    test_last_error();
    test_success_clears_message();
    test_result_str();
    test_error_callback();
    test_frame();
#if defined(ANTUMBRA_HAS_STD)
    test_thread_local_message();
    test_transfer_bake();
    test_transfer_files();
    test_transfer_compress();
    test_transfer_compress_clustered();
    test_transfer_shade();
    test_lightmap();
#endif
    test_sh_rotate();

    if (checks_failed != 0) {
        fprintf(stderr, "bad_input: %d of %d checks failed\n", checks_failed, checks_run);
        return EXIT_FAILURE;
    }
    printf("bad_input: all %d checks passed\n", checks_run);
    return EXIT_SUCCESS;
}

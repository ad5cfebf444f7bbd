/*
 * soft_shadows.c: exact soft shadows from a quad area light on a floor, through
 * Antumbra's soft shadow volumes (Laine et al. 2005) and the lazily built 3D
 * wedge hierarchy of Lehtinen, Laine and Aila 2006.
 *
 * A tilted torus and a sphere, generated here, hover over a floor (itself an
 * occluder, so every receiver lies on a surface); a slightly rotated square light
 * above them gets 256 jittered samples from antumbra_ssv_generate_samples. The
 * floor is queried on a SIZE x SIZE grid of points with the hierarchy:
 *
 *   - on this thread, on the library's worker threads (options.parallel = 1),
 *     and from four threads of our own sharing one fresh handle (its nodes are
 *     built lazily by whichever query arrives first); the bits must be identical;
 *   - on a subset of the grid (at most 32 x 32 points) with the three other
 *     structures (hemicube, brute force, ray tracing of the 256 shadow rays),
 *     which must give the same bits, timed per receiver;
 *   - sanity: visible_counts is the number of bits set; the image corners, far
 *     from the objects, see the whole light; the floor point straight below the
 *     sphere (seen from the light's centre) sees none of it; there is a
 *     penumbra; the hierarchy hands far fewer candidate edges to the exact tests
 *     than brute force.
 *
 * The visible fraction is written as a binary PGM image.
 *
 * Usage: soft_shadows [out.pgm [size]]   (defaults soft_shadows.pgm, 256)
 * Exit status: 0 on success, 1 on any unexpected result.
 */
#define _POSIX_C_SOURCE 199309L /* clock_gettime */

#include "antumbra.h"

#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define PI_F 3.14159265358979323846f

#define SAMPLES 256
#define WORDS ((SAMPLES + 63) / 64)
#define SEED 20060905u
#define THREADS 4
/* The subset checked against the other structures: at most this many points per side. */
#define SUBSET_SIDE 32

/* The occluders: a torus of TORUS_RINGS x TORUS_SIDES quads, a sphere of
 * SPHERE_SLICES x SPHERE_STACKS quads (the poles' quads are triangles in effect:
 * one degenerate triangle each, which never occludes), and a floor of 2 triangles. */
#define TORUS_RINGS 48
#define TORUS_SIDES 16
#define SPHERE_SLICES 32
#define SPHERE_STACKS 16
#define TORUS_VERTICES (TORUS_RINGS * TORUS_SIDES)
#define SPHERE_VERTICES ((SPHERE_SLICES + 1) * (SPHERE_STACKS + 1))
#define VERTEX_COUNT (TORUS_VERTICES + SPHERE_VERTICES + 4)
#define TRIANGLE_COUNT (2 * TORUS_RINGS * TORUS_SIDES + 2 * SPHERE_SLICES * SPHERE_STACKS + 2)

/* The floor is z = 0 over [-FLOOR_HALF, FLOOR_HALF]^2; the image covers it. */
#define FLOOR_HALF 2.5f
#define SPHERE_X 0.95f
#define SPHERE_Y (-0.7f)
#define SPHERE_Z 0.5f
#define SPHERE_R 0.35f

/* ------------------------------------------------------------------------- */
/* Failure reporting                                                          */
/* ------------------------------------------------------------------------- */

static void fail(const char *format, ...)
{
    va_list args;
    va_start(args, format);
    fputs("soft_shadows: ", stderr);
    vfprintf(stderr, format, args);
    fputc('\n', stderr);
    va_end(args);
    exit(EXIT_FAILURE);
}

/* Every antumbra_result goes through here: anything but OK ends the program with
 * the library's own explanation. */
static void check(antumbra_result result, const char *call)
{
    if (result != ANTUMBRA_RESULT_OK) {
        fail("%s failed: %s: %s", call, antumbra_result_str(result), antumbra_last_error_message());
    }
    if (antumbra_last_error_message()[0] != '\0') {
        fail("%s succeeded but left the error message \"%s\"", call, antumbra_last_error_message());
    }
}

static void *checked_malloc(size_t size)
{
    void *memory = malloc(size);
    if (memory == NULL) {
        fail("out of memory (%lu bytes)", (unsigned long)size);
    }
    return memory;
}

static double now_ms(void)
{
    struct timespec t;
    if (clock_gettime(CLOCK_MONOTONIC, &t) != 0) {
        fail("clock_gettime failed");
    }
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

static int popcount64(uint64_t x)
{
    int n = 0;
    while (x != 0) {
        x &= x - 1;
        ++n;
    }
    return n;
}

/* ------------------------------------------------------------------------- */
/* The scene                                                                  */
/* ------------------------------------------------------------------------- */

typedef struct scene {
    float positions[3 * VERTEX_COUNT];
    uint32_t indices[3 * TRIANGLE_COUNT];
    float light[3 * 4];
} scene;

static void put_vertex(scene *s, int v, float x, float y, float z)
{
    s->positions[3 * v + 0] = x;
    s->positions[3 * v + 1] = y;
    s->positions[3 * v + 2] = z;
}

static void put_quad(scene *s, int *t, uint32_t a, uint32_t b, uint32_t c, uint32_t d)
{
    uint32_t *i = &s->indices[3 * *t];
    i[0] = a;
    i[1] = b;
    i[2] = c;
    i[3] = a;
    i[4] = c;
    i[5] = d;
    *t += 2;
}

static void build_scene(scene *s)
{
    /* The torus: ring radius 0.7, tube 0.2, centred at (-0.2, 0.3, 1.1), tilted
     * 35 degrees about the x axis so its shadow is not a plain annulus. */
    const float tilt = 35.0f * PI_F / 180.0f;
    const float ct = cosf(tilt), st = sinf(tilt);
    int v = 0, t = 0, i, j;
    for (i = 0; i < TORUS_RINGS; ++i) {
        const float u = 2.0f * PI_F * (float)i / TORUS_RINGS;
        for (j = 0; j < TORUS_SIDES; ++j) {
            const float w = 2.0f * PI_F * (float)j / TORUS_SIDES;
            const float r = 0.7f + 0.2f * cosf(w);
            const float x = r * cosf(u), y = r * sinf(u), z = 0.2f * sinf(w);
            put_vertex(s, v++, -0.2f + x, 0.3f + ct * y - st * z, 1.1f + st * y + ct * z);
        }
    }
    for (i = 0; i < TORUS_RINGS; ++i) {
        for (j = 0; j < TORUS_SIDES; ++j) {
            const int i1 = (i + 1) % TORUS_RINGS, j1 = (j + 1) % TORUS_SIDES;
            put_quad(s, &t, (uint32_t)(i * TORUS_SIDES + j), (uint32_t)(i1 * TORUS_SIDES + j),
                     (uint32_t)(i1 * TORUS_SIDES + j1), (uint32_t)(i * TORUS_SIDES + j1));
        }
    }
    /* The sphere, latitude-longitude, with a seam of duplicated vertices (an
     * unwelded seam, which the library welds by position). */
    for (i = 0; i <= SPHERE_STACKS; ++i) {
        const float polar = PI_F * (float)i / SPHERE_STACKS;
        for (j = 0; j <= SPHERE_SLICES; ++j) {
            const float azimuth = 2.0f * PI_F * (float)(j % SPHERE_SLICES) / SPHERE_SLICES;
            put_vertex(s, v++, SPHERE_X + SPHERE_R * sinf(polar) * cosf(azimuth),
                       SPHERE_Y + SPHERE_R * sinf(polar) * sinf(azimuth), SPHERE_Z + SPHERE_R * cosf(polar));
        }
    }
    for (i = 0; i < SPHERE_STACKS; ++i) {
        for (j = 0; j < SPHERE_SLICES; ++j) {
            const uint32_t base = TORUS_VERTICES, row = SPHERE_SLICES + 1;
            put_quad(s, &t, base + (uint32_t)(i * row + j), base + (uint32_t)((i + 1) * row + j),
                     base + (uint32_t)((i + 1) * row + j + 1), base + (uint32_t)(i * row + j + 1));
        }
    }
    /* The floor: receivers lie exactly on it, and it blocks nothing above it. */
    put_vertex(s, v++, -FLOOR_HALF - 1.0f, -FLOOR_HALF - 1.0f, 0.0f);
    put_vertex(s, v++, FLOOR_HALF + 1.0f, -FLOOR_HALF - 1.0f, 0.0f);
    put_vertex(s, v++, FLOOR_HALF + 1.0f, FLOOR_HALF + 1.0f, 0.0f);
    put_vertex(s, v++, -FLOOR_HALF - 1.0f, FLOOR_HALF + 1.0f, 0.0f);
    put_quad(s, &t, (uint32_t)v - 4, (uint32_t)v - 3, (uint32_t)v - 2, (uint32_t)v - 1);
    if (v != VERTEX_COUNT || t != TRIANGLE_COUNT) {
        fail("internal: built %d vertices and %d triangles, expected %d and %d", v, t, VERTEX_COUNT,
             TRIANGLE_COUNT);
    }

    /* The light: a 1.2 x 1.2 square at z = 3.2 over (0.3, 0.1), turned 20 degrees
     * about the vertical and tipped 10 degrees about x. */
    {
        const float turn = 20.0f * PI_F / 180.0f, tip = 10.0f * PI_F / 180.0f;
        const float corner[4][2] = {{-0.6f, -0.6f}, {0.6f, -0.6f}, {0.6f, 0.6f}, {-0.6f, 0.6f}};
        int k;
        for (k = 0; k < 4; ++k) {
            const float x = cosf(turn) * corner[k][0] - sinf(turn) * corner[k][1];
            const float y = sinf(turn) * corner[k][0] + cosf(turn) * corner[k][1];
            s->light[3 * k + 0] = 0.3f + x;
            s->light[3 * k + 1] = 0.1f + cosf(tip) * y;
            s->light[3 * k + 2] = 3.2f + sinf(tip) * y;
        }
    }
}

/* ------------------------------------------------------------------------- */
/* Queries                                                                    */
/* ------------------------------------------------------------------------- */

typedef struct result {
    uint64_t *bits;   /* count * WORDS */
    uint32_t *counts; /* count */
} result;

static result new_result(size_t count)
{
    result r;
    r.bits = checked_malloc(count * WORDS * sizeof *r.bits);
    r.counts = checked_malloc(count * sizeof *r.counts);
    return r;
}

static void free_result(result *r)
{
    free(r->bits);
    free(r->counts);
}

static antumbra_ssv *create(const antumbra_mesh_view *view, const scene *s, const float *samples, uint32_t structure,
                            uint32_t parallel, const char *what)
{
    antumbra_ssv_options options;
    antumbra_ssv *ssv = NULL;
    antumbra_ssv_options_init(&options);
    options.structure = structure;
    options.parallel = parallel;
    check(antumbra_ssv_create(view, s->light, 4, samples, SAMPLES, &options, &ssv), what);
    if (ssv == NULL) {
        fail("%s returned OK and a NULL handle", what);
    }
    return ssv;
}

static double query_timed(const antumbra_ssv *ssv, const float *points, size_t count, result *r, const char *what)
{
    const double start = now_ms();
    check(antumbra_ssv_query(ssv, points, count, r->bits, r->counts), what);
    return now_ms() - start;
}

/* Rows of the grid queried from several threads on one handle. */
typedef struct worker {
    const antumbra_ssv *ssv;
    const float *points;
    size_t first, count;
    result *out;
    antumbra_result status;
} worker;

static void *run_worker(void *argument)
{
    worker *w = argument;
    /* Small batches, so the threads interleave and race for the lazy nodes. */
    size_t done = 0;
    w->status = ANTUMBRA_RESULT_OK;
    while (done < w->count && w->status == ANTUMBRA_RESULT_OK) {
        const size_t batch = w->count - done < 97 ? w->count - done : 97;
        const size_t at = w->first + done;
        w->status = antumbra_ssv_query(w->ssv, w->points + 3 * at, batch, w->out->bits + at * WORDS,
                                       w->out->counts + at);
        done += batch;
    }
    return NULL;
}

static double query_threads(const antumbra_ssv *ssv, const float *points, size_t count, result *r)
{
    pthread_t threads[THREADS];
    worker workers[THREADS];
    const double start = now_ms();
    int k;
    for (k = 0; k < THREADS; ++k) {
        workers[k].ssv = ssv;
        workers[k].points = points;
        /* Interleaved ranges would be kinder to the cache; contiguous ones make
         * every thread start in a different part of the hierarchy. */
        workers[k].first = count * (size_t)k / THREADS;
        workers[k].count = count * (size_t)(k + 1) / THREADS - workers[k].first;
        workers[k].out = r;
        if (pthread_create(&threads[k], NULL, run_worker, &workers[k]) != 0) {
            fail("could not start thread %d", k);
        }
    }
    for (k = 0; k < THREADS; ++k) {
        if (pthread_join(threads[k], NULL) != 0) {
            fail("could not join thread %d", k);
        }
        if (workers[k].status != ANTUMBRA_RESULT_OK) {
            fail("antumbra_ssv_query on thread %d failed: %s", k, antumbra_result_str(workers[k].status));
        }
    }
    return now_ms() - start;
}

/* Number of receivers whose bits differ between a and b at the same points. */
static size_t differing_receivers(const result *a, const result *b, size_t count, size_t *bits_differing)
{
    size_t k, differ = 0;
    int w;
    *bits_differing = 0;
    for (k = 0; k < count; ++k) {
        int d = 0;
        for (w = 0; w < WORDS; ++w) {
            d += popcount64(a->bits[k * WORDS + w] ^ b->bits[k * WORDS + w]);
        }
        *bits_differing += (size_t)d;
        differ += d != 0;
    }
    return differ;
}

static void check_counts(const result *r, size_t count, const char *what)
{
    size_t k;
    int w;
    for (k = 0; k < count; ++k) {
        int n = 0;
        for (w = 0; w < WORDS; ++w) {
            n += popcount64(r->bits[k * WORDS + w]);
        }
        if (n != (int)r->counts[k]) {
            fail("%s: receiver %lu has %d bits set but visible_counts says %u", what, (unsigned long)k, n,
                 (unsigned)r->counts[k]);
        }
    }
}

static antumbra_ssv_statistics statistics(const antumbra_ssv *ssv, const char *what)
{
    antumbra_ssv_statistics stats;
    check(antumbra_ssv_get_statistics(ssv, &stats), what);
    return stats;
}

/* ------------------------------------------------------------------------- */
/* Main                                                                       */
/* ------------------------------------------------------------------------- */

static void check_version(void)
{
    char expected[32];
    if (antumbra_version() != ANTUMBRA_VERSION) {
        fail("library version 0x%06lx does not match header 0x%06lx", (unsigned long)antumbra_version(),
             (unsigned long)ANTUMBRA_VERSION);
    }
    if (strcmp(antumbra_version_string(), ANTUMBRA_VERSION_STRING) != 0) {
        fail("library version \"%s\" does not match header \"%s\"", antumbra_version_string(),
             ANTUMBRA_VERSION_STRING);
    }
    sprintf(expected, "%d.%d.%d", ANTUMBRA_VERSION_MAJOR, ANTUMBRA_VERSION_MINOR, ANTUMBRA_VERSION_PATCH);
    if (strcmp(expected, ANTUMBRA_VERSION_STRING) != 0) {
        fail("header: ANTUMBRA_VERSION_STRING \"%s\" is not %s", ANTUMBRA_VERSION_STRING, expected);
    }
}

static void write_pgm(const char *path, const uint32_t *counts, int size)
{
    FILE *file = fopen(path, "wb");
    int x, y;
    if (file == NULL) {
        fail("cannot open %s for writing", path);
    }
    fprintf(file, "P5\n%d %d\n255\n", size, size);
    /* Image row 0 is the floor's far edge (+y), so the picture is seen from above. */
    for (y = size - 1; y >= 0; --y) {
        for (x = 0; x < size; ++x) {
            const uint32_t n = counts[(size_t)y * (size_t)size + (size_t)x];
            /* Gamma 2.2 so the penumbra's gradient reads evenly. */
            const double value = 255.0 * pow((double)n / SAMPLES, 1.0 / 2.2) + 0.5;
            fputc((int)value, file);
        }
    }
    if (fclose(file) != 0) {
        fail("cannot write %s", path);
    }
}

/* The floor point below `p` as seen from `from`. */
static void project_to_floor(const float *from, const float *p, float *out)
{
    const float t = from[2] / (from[2] - p[2]);
    out[0] = from[0] + t * (p[0] - from[0]);
    out[1] = from[1] + t * (p[1] - from[1]);
    out[2] = 0.0f;
}

int main(int argc, char **argv)
{
    static const uint32_t others[3] = {ANTUMBRA_SSV_STRUCTURE_HEMICUBE, ANTUMBRA_SSV_STRUCTURE_BRUTE_FORCE,
                                       ANTUMBRA_SSV_STRUCTURE_RAY_TRACE};
    static const char *const other_names[3] = {"hemicube", "brute force", "ray trace"};
    const char *path = argc > 1 ? argv[1] : "soft_shadows.pgm";
    const int size = argc > 2 ? atoi(argv[2]) : 256;
    scene *s = checked_malloc(sizeof *s);
    float samples[3 * SAMPLES];
    float *points, *subset_points;
    size_t count, subset_count, k;
    int step, x, y, full_corners = 0, penumbra = 0;
    double ms_serial, ms_parallel, ms_threads, ms_subset_hierarchy, mean = 0.0;
    result serial, parallel, threaded, subset_hierarchy, subset_other;
    antumbra_mesh_view view;
    antumbra_ssv_options options;
    antumbra_ssv *hierarchy, *hierarchy_parallel, *hierarchy_threads;
    antumbra_ssv_statistics stats;

    if (size < 8 || size > 4096) {
        fail("size %d: expected 8 to 4096", size);
    }
    check_version();
    build_scene(s);
    view.positions = s->positions;
    view.vertex_count = VERTEX_COUNT;
    view.position_stride = 0;
    view.indices = s->indices;
    view.triangle_count = TRIANGLE_COUNT;
    printf("soft_shadows: antumbra %s, torus + sphere + floor: %d triangles; square light, %d jittered samples; "
           "%dx%d floor points\n",
           antumbra_version_string(), TRIANGLE_COUNT, SAMPLES, size, size);

    antumbra_ssv_options_init(&options);
    if (antumbra_last_error_message()[0] != '\0' || options.structure != ANTUMBRA_SSV_STRUCTURE_HIERARCHY ||
        options.leaf_edges != 16 || options.max_depth != 12 || options.hemicube_resolution != 64 ||
        options.parallel != 0 || options.use_root_bounds != 0) {
        fail("antumbra_ssv_options_init did not write the documented defaults");
    }

    /* Samples: the same seed gives the same samples, and they are on the light
     * (antumbra_ssv_create checks that too). */
    check(antumbra_ssv_generate_samples(s->light, 4, SAMPLES, ANTUMBRA_SSV_SAMPLES_JITTERED, SEED, samples),
          "antumbra_ssv_generate_samples");
    {
        float again[3 * SAMPLES];
        check(antumbra_ssv_generate_samples(s->light, 4, SAMPLES, ANTUMBRA_SSV_SAMPLES_JITTERED, SEED, again),
              "antumbra_ssv_generate_samples (again)");
        if (memcmp(samples, again, sizeof again) != 0) {
            fail("antumbra_ssv_generate_samples is not deterministic in its seed");
        }
    }

    /* The grid of floor points, at pixel centres. */
    count = (size_t)size * (size_t)size;
    points = checked_malloc(3 * count * sizeof *points);
    for (y = 0; y < size; ++y) {
        for (x = 0; x < size; ++x) {
            float *p = &points[3 * ((size_t)y * (size_t)size + (size_t)x)];
            p[0] = -FLOOR_HALF + 2.0f * FLOOR_HALF * ((float)x + 0.5f) / (float)size;
            p[1] = -FLOOR_HALF + 2.0f * FLOOR_HALF * ((float)y + 0.5f) / (float)size;
            p[2] = 0.0f;
        }
    }

    /* The hierarchy, on this thread. */
    serial = new_result(count);
    hierarchy = create(&view, s, samples, ANTUMBRA_SSV_STRUCTURE_HIERARCHY, 0, "antumbra_ssv_create (hierarchy)");
    ms_serial = query_timed(hierarchy, points, count, &serial, "antumbra_ssv_query (hierarchy)");
    check_counts(&serial, count, "hierarchy");
    stats = statistics(hierarchy, "antumbra_ssv_get_statistics (hierarchy)");
    printf("soft_shadows: hierarchy, one thread: %.1f ms for %lu receivers (%.2f us per receiver); %.1f candidate "
           "edges per query of %lu potential silhouette edges; %lu nodes, %.1f KiB\n",
           ms_serial, (unsigned long)count, 1e3 * ms_serial / (double)count, stats.candidates_per_query,
           (unsigned long)stats.potential_edges, (unsigned long)stats.nodes, (double)stats.bytes / 1024.0);
    if (stats.queries != count || stats.sample_count != SAMPLES || stats.words_per_receiver != WORDS ||
        stats.structure != ANTUMBRA_SSV_STRUCTURE_HIERARCHY || stats.light_vertex_count != 4 ||
        stats.rays != count) {
        fail("statistics: %lu queries, %u samples, %u words, structure %u, %u light vertices, %lu rays: not what "
             "was asked",
             (unsigned long)stats.queries, (unsigned)stats.sample_count, (unsigned)stats.words_per_receiver,
             (unsigned)stats.structure, (unsigned)stats.light_vertex_count, (unsigned long)stats.rays);
    }
    if (!(stats.nodes > 1 && stats.bytes > 0 && stats.candidates_per_query < 0.5 * (double)stats.potential_edges)) {
        fail("the hierarchy (%lu nodes, %lu bytes) hands %.1f of %lu edges per query to the exact tests; it "
             "should cull most",
             (unsigned long)stats.nodes, (unsigned long)stats.bytes, stats.candidates_per_query,
             (unsigned long)stats.potential_edges);
    }

    /* The same on the library's worker threads, and from our own threads. */
    parallel = new_result(count);
    hierarchy_parallel = create(&view, s, samples, ANTUMBRA_SSV_STRUCTURE_HIERARCHY, 1,
                                "antumbra_ssv_create (hierarchy, parallel)");
    ms_parallel = query_timed(hierarchy_parallel, points, count, &parallel, "antumbra_ssv_query (parallel)");
    threaded = new_result(count);
    /* This handle is made for an earlier frame, the occluders 0.4 to the
     * side, and moved into place with antumbra_ssv_update, as a moving
     * object's handle is kept from frame to frame: its bits must still be the
     * serial handle's. */
    {
        antumbra_mesh_view earlier = view;
        float *shifted = checked_malloc(sizeof s->positions);
        for (k = 0; k < 3 * VERTEX_COUNT; ++k) {
            shifted[k] = s->positions[k] + (k % 3 == 0 ? 0.4f : 0.0f);
        }
        earlier.positions = shifted;
        hierarchy_threads = create(&earlier, s, samples, ANTUMBRA_SSV_STRUCTURE_HIERARCHY, 0,
                                   "antumbra_ssv_create (hierarchy, threads)");
        check(antumbra_ssv_update(hierarchy_threads, &view), "antumbra_ssv_update");
        free(shifted);
    }
    ms_threads = query_threads(hierarchy_threads, points, count, &threaded);
    printf("soft_shadows: hierarchy, worker threads: %.1f ms; %d threads of ours on one handle: %.1f ms\n",
           ms_parallel, THREADS, ms_threads);
    if (memcmp(serial.bits, parallel.bits, count * WORDS * sizeof *serial.bits) != 0 ||
        memcmp(serial.counts, parallel.counts, count * sizeof *serial.counts) != 0) {
        fail("options.parallel = 1 changed the bits");
    }
    if (memcmp(serial.bits, threaded.bits, count * WORDS * sizeof *serial.bits) != 0 ||
        memcmp(serial.counts, threaded.counts, count * sizeof *serial.counts) != 0) {
        fail("querying one handle from %d threads changed the bits", THREADS);
    }
    stats = statistics(hierarchy_threads, "antumbra_ssv_get_statistics (threads)");
    if (stats.queries != count) {
        fail("after %d threads, statistics count %lu queries, not %lu", THREADS, (unsigned long)stats.queries,
             (unsigned long)count);
    }
    antumbra_ssv_destroy(hierarchy_threads);
    antumbra_ssv_destroy(hierarchy_parallel);
    free_result(&threaded);
    free_result(&parallel);

    /* The subset against the other structures, same API, same bits. */
    step = size > SUBSET_SIDE ? size / SUBSET_SIDE : 1;
    subset_count = 0;
    subset_points = checked_malloc(3 * count * sizeof *subset_points);
    subset_hierarchy = new_result(count);
    for (y = step / 2; y < size; y += step) {
        for (x = step / 2; x < size; x += step) {
            const size_t at = (size_t)y * (size_t)size + (size_t)x;
            memcpy(&subset_points[3 * subset_count], &points[3 * at], 3 * sizeof *points);
            memcpy(&subset_hierarchy.bits[subset_count * WORDS], &serial.bits[at * WORDS],
                   WORDS * sizeof *serial.bits);
            ++subset_count;
        }
    }
    /* The hierarchy's time on the subset, its nodes already built by the image. */
    subset_other = new_result(subset_count);
    ms_subset_hierarchy =
        query_timed(hierarchy, subset_points, subset_count, &subset_other, "antumbra_ssv_query (hierarchy, subset)");
    for (k = 0; k < 3; ++k) {
        antumbra_ssv *other = create(&view, s, samples, others[k], 0, "antumbra_ssv_create (baseline)");
        size_t differing_bits, differing;
        const double ms = query_timed(other, subset_points, subset_count, &subset_other, "antumbra_ssv_query (baseline)");
        stats = statistics(other, "antumbra_ssv_get_statistics (baseline)");
        check_counts(&subset_other, subset_count, other_names[k]);
        differing = differing_receivers(&subset_hierarchy, &subset_other, subset_count, &differing_bits);
        printf("soft_shadows: %-11s on %lu receivers: %.2f us per receiver, %.2fx the hierarchy's %.2f us; "
               "%.1f candidates per query; %lu bits differ from the hierarchy\n",
               other_names[k], (unsigned long)subset_count, 1e3 * ms / (double)subset_count,
               ms / ms_subset_hierarchy, 1e3 * ms_subset_hierarchy / (double)subset_count,
               stats.candidates_per_query, (unsigned long)differing_bits);
        if (differing != 0) {
            fail("%s and the hierarchy disagree on %lu bits of %lu receivers", other_names[k],
                 (unsigned long)differing_bits, (unsigned long)differing);
        }
        antumbra_ssv_destroy(other);
    }
    free_result(&subset_other);
    free_result(&subset_hierarchy);
    free(subset_points);

    /* Sanity: the corners see the whole light, the point below the sphere's centre
     * (seen from the light's centre) none of it, and there is a penumbra. */
    {
        const size_t last = (size_t)size - 1;
        const size_t corners[4] = {0, last, last * (size_t)size, last * (size_t)size + last};
        for (k = 0; k < 4; ++k) {
            full_corners += serial.counts[corners[k]] == SAMPLES;
        }
    }
    for (k = 0; k < count; ++k) {
        penumbra += serial.counts[k] > 0 && serial.counts[k] < SAMPLES;
        mean += (double)serial.counts[k] / SAMPLES / (double)count;
    }
    {
        float centre[3] = {0.0f, 0.0f, 0.0f}, below[3];
        const float sphere[3] = {SPHERE_X, SPHERE_Y, SPHERE_Z};
        uint64_t bits[WORDS];
        uint32_t visible = 1234;
        int c;
        for (c = 0; c < 4; ++c) {
            centre[0] += s->light[3 * c + 0] / 4.0f;
            centre[1] += s->light[3 * c + 1] / 4.0f;
            centre[2] += s->light[3 * c + 2] / 4.0f;
        }
        project_to_floor(centre, sphere, below);
        check(antumbra_ssv_query(hierarchy, below, 1, bits, &visible), "antumbra_ssv_query (below the sphere)");
        printf("soft_shadows: mean visible fraction %.3f; %d%% of the floor in penumbra; the point below the "
               "sphere (%.2f, %.2f) sees %u of %d samples; %d of 4 corners see all\n",
               mean, (int)(100 * (size_t)penumbra / count), (double)below[0], (double)below[1], (unsigned)visible,
               SAMPLES, full_corners);
        if (visible != 0) {
            fail("the floor point below the sphere sees %u samples; it is in the umbra", (unsigned)visible);
        }
    }
    if (full_corners != 4) {
        fail("only %d of the 4 image corners see the whole light", full_corners);
    }
    if (penumbra < (int)(count / 50) || !(mean > 0.5 && mean < 0.99)) {
        fail("%d penumbra points, mean visible fraction %.3f: not the soft shadow of two objects", penumbra, mean);
    }

    write_pgm(path, serial.counts, size);
    printf("soft_shadows: wrote %s (%dx%d, visible fraction)\n", path, size, size);

    antumbra_ssv_destroy(hierarchy);
    free_result(&serial);
    free(points);
    free(s);
    return EXIT_SUCCESS;
}

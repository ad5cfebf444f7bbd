/*
 * hemi_shadows.c: self-shadowing of a mesh that deforms every frame, through
 * Antumbra's hemispherical rasterizer (Kautz, Lehtinen and Aila 2004), shaded
 * under spherical-harmonic lighting.
 *
 * A torus with an elliptical cross-section is generated here and deformed on the
 * C side every frame (the cross-section twists along the ring, the ring breathes
 * and waves), as a skinned or simulated mesh would be. Beyond a near radius a far
 * mesh stands in for it, which the library makes from the rest pose (the
 * far_triangles option) and moves with the positions passed every frame. Per frame:
 *
 *   - antumbra_hemi_rasterize gives the 32x32 visibility mask above every vertex,
 *     from which this program computes ambient visibility and decides which
 *     sunward vertices are in shadow (cell directions from
 *     antumbra_hemi_cell_direction, frame from antumbra_frame_from_normal);
 *   - antumbra_hemi_shader_shade shades every vertex, diffuse + glossy, under a
 *     procedural sky (a blue gradient and a bright sun lobe, generated here as
 *     an equirectangular float image and projected onto 5 SH bands with
 *     antumbra_sh_project_equirect), with and without the far mesh, timed.
 *
 * The shaded colours must be plausible: sunward vertices the masks say are lit
 * brighter than those in shadow, glossy light only where the viewer is in front
 * and stronger where the mirror direction is open, the far mesh close to the
 * full one, and the diffuse colour equal to albedo/pi times the dot product of
 * antumbra_hemi_shader_transfer's vectors with the lighting.
 *
 * On the first frame the transfer vectors and colours are also made with sparse
 * receivers (antumbra_hemi_shader_set_receivers): the keys exact, the rest
 * interpolated where their keys agree.
 *
 * The last frame is also rasterized with the table quality (the shared table,
 * on the library's worker threads, and a caller-owned table, on this thread),
 * which must agree with the exact masks on at least 99 % of the valid cells and
 * with each other bit for bit, and its shaded colours are drawn into a PPM image
 * by a small z-buffered software rasterizer, over the sky. A linear sky is also
 * projected onto 3 SH bands, and the SH irradiance must match the cell sum.
 *
 * Usage: hemi_shadows [out.ppm]   (default hemi_shadows.ppm)
 * Exit status: 0 on success, 1 on any unexpected result or implausible shading.
 */
#define _POSIX_C_SOURCE 199309L /* clock_gettime */

#include "antumbra.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define PI_F 3.14159265358979323846f

/* The mesh: RINGS cross-sections of SIDES vertices, 2 * RINGS * SIDES triangles. */
#define RINGS 48
#define SIDES 16
#define VERTEX_COUNT (RINGS * SIDES)
#define TRIANGLE_COUNT (2 * RINGS * SIDES)
#define FRAMES 3

/* The far mesh the library makes: about a sixth of the triangles. The near radius
 * is the library's rule for its own far mesh (near_radius left at +INFINITY). */
#define FAR_TRIANGLES 256

/* SH lighting: 5 bands (25 coefficients per channel), enough for a glossy lobe. */
#define SH_BANDS 5
#define SH_COEFFS (SH_BANDS * SH_BANDS)
#define SKY_MAP_W 128
#define SKY_MAP_H 64

#define WIDTH 200
#define HEIGHT 150

/* ------------------------------------------------------------------------- */
/* Failure reporting                                                          */
/* ------------------------------------------------------------------------- */

static void fail(const char *format, ...)
{
    va_list args;
    va_start(args, format);
    fputs("hemi_shadows: ", stderr);
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

/* ------------------------------------------------------------------------- */
/* Small vector helpers                                                       */
/* ------------------------------------------------------------------------- */

typedef struct vec3 {
    float x, y, z;
} vec3;

static vec3 v3(float x, float y, float z)
{
    vec3 v;
    v.x = x;
    v.y = y;
    v.z = z;
    return v;
}
static vec3 add(vec3 a, vec3 b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static vec3 sub(vec3 a, vec3 b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static vec3 scale(vec3 a, float s) { return v3(a.x * s, a.y * s, a.z * s); }
static float dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static vec3 cross(vec3 a, vec3 b)
{
    return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static float length(vec3 a) { return sqrtf(dot(a, a)); }
static vec3 normalize(vec3 a) { return scale(a, 1.0f / length(a)); }
static vec3 load3(const float *p) { return v3(p[0], p[1], p[2]); }
static void store3(float *p, vec3 v)
{
    p[0] = v.x;
    p[1] = v.y;
    p[2] = v.z;
}

static int popcount32(uint32_t x)
{
    int n = 0;
    for (; x != 0; x &= x - 1) {
        ++n;
    }
    return n;
}

/* ------------------------------------------------------------------------- */
/* The deforming torus                                                        */
/* ------------------------------------------------------------------------- */

typedef struct mesh {
    float positions[3 * VERTEX_COUNT];
    float normals[3 * VERTEX_COUNT];
    uint32_t indices[3 * TRIANGLE_COUNT];
} mesh;

static uint32_t torus_index(int rings, int sides, int ring, int side)
{
    return (uint32_t)(((ring + rings) % rings) * sides + (side + sides) % sides);
}

/* Quads between neighbouring cross-sections, counter-clockwise seen from
 * outside, so the computed normals point out of the tube. */
static void build_torus_indices(uint32_t *indices, int rings, int sides)
{
    int ring, side, t = 0;
    for (ring = 0; ring < rings; ++ring) {
        for (side = 0; side < sides; ++side) {
            const uint32_t a = torus_index(rings, sides, ring, side), b = torus_index(rings, sides, ring + 1, side);
            const uint32_t c = torus_index(rings, sides, ring + 1, side + 1);
            const uint32_t d = torus_index(rings, sides, ring, side + 1);
            uint32_t *tri = &indices[3 * t];
            tri[0] = a;
            tri[1] = c;
            tri[2] = b;
            tri[3] = a;
            tri[4] = d;
            tri[5] = c;
            t += 2;
        }
    }
}

/* The pose at time `time`: around the vertical axis, a ring of radius about 1
 * carrying an elliptical cross-section (semi-axes 0.42 and 0.2) that turns once
 * along the ring (so the seam closes) and spins with time; the ring's radius
 * breathes and its height waves. The same surface at any sampling, so the far
 * mesh follows the full one. */
static void deform_torus(float *positions, int rings, int sides, float time)
{
    int ring, side;
    for (ring = 0; ring < rings; ++ring) {
        const float phi = 2.0f * PI_F * (float)ring / (float)rings;
        const vec3 radial = v3(cosf(phi), 0.0f, sinf(phi));
        const vec3 up = v3(0.0f, 1.0f, 0.0f);
        const float major = 1.0f + 0.08f * sinf(3.0f * phi + 1.7f * time);
        const float lift = 0.18f * sinf(2.0f * phi - 1.3f * time);
        const float twist = phi + 0.9f * time;
        const vec3 center = add(scale(radial, major), scale(up, lift));
        for (side = 0; side < sides; ++side) {
            const float theta = 2.0f * PI_F * (float)side / (float)sides;
            const float a = 0.42f * cosf(theta), b = 0.2f * sinf(theta);
            const float r = a * cosf(twist) - b * sinf(twist);
            const float y = a * sinf(twist) + b * cosf(twist);
            store3(&positions[3 * torus_index(rings, sides, ring, side)],
                   add(center, add(scale(radial, r), scale(up, y))));
        }
    }
}

static void build_indices(mesh *m) { build_torus_indices(m->indices, RINGS, SIDES); }
static void deform(mesh *m, float time) { deform_torus(m->positions, RINGS, SIDES, time); }

/* Area-weighted vertex normals: the sum of the unnormalised face normals around
 * each vertex, normalised in float (the library wants unit normals within 1e-3). */
static void compute_normals(mesh *m)
{
    int t, v;
    memset(m->normals, 0, sizeof m->normals);
    for (t = 0; t < TRIANGLE_COUNT; ++t) {
        const uint32_t *tri = &m->indices[3 * t];
        const vec3 a = load3(&m->positions[3 * tri[0]]), b = load3(&m->positions[3 * tri[1]]);
        const vec3 c = load3(&m->positions[3 * tri[2]]);
        const vec3 face = cross(sub(b, a), sub(c, a));
        int k;
        for (k = 0; k < 3; ++k) {
            float *n = &m->normals[3 * tri[k]];
            store3(n, add(load3(n), face));
        }
    }
    for (v = 0; v < VERTEX_COUNT; ++v) {
        float *n = &m->normals[3 * v];
        const float len = length(load3(n));
        if (!(len > 0.0f)) {
            fail("vertex %d has a zero normal", v);
        }
        store3(n, normalize(load3(n)));
    }
}

/* Distance of a vertex from the torus axis, to find the innermost (facing the
 * hole: concave along the ring, looking at the far side) and outermost vertices. */
static float axis_distance(const mesh *m, int v)
{
    return sqrtf(m->positions[3 * v] * m->positions[3 * v] + m->positions[3 * v + 2] * m->positions[3 * v + 2]);
}

/* ------------------------------------------------------------------------- */
/* Lighting                                                                   */
/* ------------------------------------------------------------------------- */

/* Sky radiance: constant + linear in the direction, brighter and bluer above,
 * darker (ground bounce) below, a little warmer towards +X. Positive everywhere.
 * Its irradiance has a closed form: E(n) = pi k0 + (2 pi / 3)(k1 n.y + k2 n.x). */
static const vec3 SKY_K0 = {0.30f, 0.36f, 0.50f};
static const vec3 SKY_K1 = {0.18f, 0.22f, 0.30f};
static const vec3 SKY_K2 = {0.04f, 0.02f, 0.00f};
static const vec3 ALBEDO = {0.80f, 0.56f, 0.36f};
static const vec3 SPECULAR = {0.25f, 0.25f, 0.25f};
#define GLOSSY_EXPONENT 24.0f

static vec3 sky_radiance(vec3 d) { return add(SKY_K0, add(scale(SKY_K1, d.y), scale(SKY_K2, d.x))); }

static vec3 sky_irradiance_exact(vec3 n)
{
    return add(scale(SKY_K0, PI_F), scale(add(scale(SKY_K1, n.y), scale(SKY_K2, n.x)), 2.0f * PI_F / 3.0f));
}

/* The 812 valid cells with their local directions, read from the library. */
typedef struct cells {
    int count;
    uint8_t i[ANTUMBRA_HEMI_VALID_CELL_COUNT], j[ANTUMBRA_HEMI_VALID_CELL_COUNT];
    vec3 direction[ANTUMBRA_HEMI_VALID_CELL_COUNT];
    antumbra_hemi_mask valid;
} cells;

/* Asks for every cell of the grid: valid ones must succeed with the documented
 * formula's direction, invalid ones must be refused with INVALID_ARGUMENT, and the
 * valid ones must be antumbra_hemi_valid_mask's. */
static void load_cells(cells *c)
{
    antumbra_hemi_mask from_directions;
    uint32_t i, j;
    memset(&from_directions, 0, sizeof from_directions);
    c->count = 0;
    for (j = 0; j < ANTUMBRA_HEMI_GRID; ++j) {
        for (i = 0; i < ANTUMBRA_HEMI_GRID; ++i) {
            const float u = ((float)i + 0.5f) / 16.0f - 1.0f, v = ((float)j + 0.5f) / 16.0f - 1.0f;
            float d[3] = {-9.0f, -9.0f, -9.0f};
            const antumbra_result result = antumbra_hemi_cell_direction(i, j, d);
            if (u * u + v * v >= 1.0f) {
                if (result != ANTUMBRA_RESULT_INVALID_ARGUMENT || d[0] != -9.0f) {
                    fail("antumbra_hemi_cell_direction(%u, %u) outside the disk returned %s", i, j,
                         antumbra_result_str(result));
                }
                continue;
            }
            check(result, "antumbra_hemi_cell_direction");
            {
                const float z = sqrtf(1.0f - u * u - v * v);
#if FLT_EVAL_METHOD == 0
                /* Documented: exact coordinates and one correctly rounded sqrtf. */
                const int same = d[0] == u && d[1] == v && d[2] == z;
#else
                const int same = d[0] == u && d[1] == v && fabsf(d[2] - z) <= 1e-7f;
#endif
                if (!same) {
                    fail("cell (%u, %u): direction (%.9g, %.9g, %.9g), formula (%.9g, %.9g, %.9g)", i, j,
                         (double)d[0], (double)d[1], (double)d[2], (double)u, (double)v, (double)z);
                }
            }
            from_directions.rows[j] |= 1u << i;
            c->i[c->count] = (uint8_t)i;
            c->j[c->count] = (uint8_t)j;
            c->direction[c->count] = load3(d);
            ++c->count;
        }
    }
    check(antumbra_hemi_valid_mask(&c->valid), "antumbra_hemi_valid_mask");
    if (c->count != ANTUMBRA_HEMI_VALID_CELL_COUNT || memcmp(&from_directions, &c->valid, sizeof c->valid) != 0) {
        fail("%d cells have directions; antumbra_hemi_valid_mask disagrees or the count is not %d", c->count,
             ANTUMBRA_HEMI_VALID_CELL_COUNT);
    }
}

typedef struct frame3 {
    vec3 t, b, n;
} frame3;

static frame3 receiver_frame(vec3 n)
{
    float normal[3], tangent[3], bitangent[3];
    frame3 f;
    store3(normal, n);
    antumbra_frame_from_normal(normal, tangent, bitangent);
    if (antumbra_last_error_message()[0] != '\0') {
        fail("antumbra_frame_from_normal failed: %s", antumbra_last_error_message());
    }
    f.t = load3(tangent);
    f.b = load3(bitangent);
    f.n = n;
    return f;
}

static vec3 to_world(const frame3 *f, vec3 local)
{
    return add(add(scale(f->t, local.x), scale(f->b, local.y)), scale(f->n, local.z));
}

/* Irradiance from the sky over the cells not set in `mask` (all of them for NULL):
 * every valid cell stands for pi / 812 of the cosine-weighted hemisphere. */
static vec3 sky_irradiance_cells(const cells *c, const frame3 *f, const antumbra_hemi_mask *mask)
{
    vec3 sum = v3(0.0f, 0.0f, 0.0f);
    int k;
    for (k = 0; k < c->count; ++k) {
        if (mask != NULL && (mask->rows[c->j[k]] >> c->i[k] & 1u)) {
            continue;
        }
        sum = add(sum, sky_radiance(to_world(f, c->direction[k])));
    }
    return scale(sum, PI_F / (float)c->count);
}

/* Whether a world direction (unit) is blocked: the cell it falls in. A
 * direction below the horizon is "blocked" too (no light from there). */
static int direction_blocked(const frame3 *f, vec3 d, const antumbra_hemi_mask *mask)
{
    const float u = dot(d, f->t), v = dot(d, f->b), w = dot(d, f->n);
    int i, j;
    if (w <= 0.0f) {
        return 1;
    }
    i = (int)floorf((u + 1.0f) * 16.0f);
    j = (int)floorf((v + 1.0f) * 16.0f);
    i = i < 0 ? 0 : i > 31 ? 31 : i;
    j = j < 0 ? 0 : j > 31 ? 31 : j;
    return (int)(mask->rows[j] >> i & 1u);
}

/* The sky projected onto 3 SH bands through the library, and the irradiance
 * those coefficients give (clamped-cosine convolution: pi, 2pi/3, pi/4 per band),
 * checked against the closed form and against the cell sum of an unoccluded
 * receiver: three routes to the same number that share only the conventions. */
static void check_sky_sh(const cells *c)
{
    enum { MAP_W = 64, MAP_H = 32, BANDS = 3, COEFFS = BANDS * BANDS };
    static float map[MAP_H][MAP_W][3];
    float sh[3 * COEFFS];
    const float band_factor[BANDS] = {PI_F, 2.0f * PI_F / 3.0f, PI_F / 4.0f};
    const vec3 normals[3] = {{0.0f, 1.0f, 0.0f}, {0.6f, 0.0f, 0.8f}, {-0.48f, -0.6f, 0.64f}};
    int row, column, k;
    for (row = 0; row < MAP_H; ++row) {
        for (column = 0; column < MAP_W; ++column) {
            /* The documented map convention: theta from +Y, u = 0.5 along +X,
             * u = 0.75 along +Z. */
            const float theta = ((float)row + 0.5f) / (float)MAP_H * PI_F;
            const float phi = (((float)column + 0.5f) / (float)MAP_W - 0.5f) * 2.0f * PI_F;
            const vec3 d = v3(sinf(theta) * cosf(phi), cosf(theta), sinf(theta) * sinf(phi));
            store3(map[row][column], sky_radiance(d));
        }
    }
    check(antumbra_sh_project_equirect(&map[0][0][0], MAP_W, MAP_H, 0, BANDS, sh), "antumbra_sh_project_equirect");
    for (k = 0; k < 3; ++k) {
        const vec3 n = normalize(normals[k]);
        const frame3 f = receiver_frame(n);
        const vec3 exact = sky_irradiance_exact(n), from_cells = sky_irradiance_cells(c, &f, NULL);
        float y[COEFFS], n3[3], e[3];
        int channel, l, m;
        store3(n3, n);
        check(antumbra_sh_eval(n3, BANDS, y), "antumbra_sh_eval");
        for (channel = 0; channel < 3; ++channel) {
            e[channel] = 0.0f;
            for (l = 0; l < BANDS; ++l) {
                for (m = -l; m <= l; ++m) {
                    e[channel] += band_factor[l] * sh[channel * COEFFS + l * (l + 1) + m] * y[l * (l + 1) + m];
                }
            }
        }
        printf("hemi_shadows: sky irradiance at n = (%.2f, %.2f, %.2f): exact %.4f, SH %.4f, cells %.4f (green)\n",
               (double)n.x, (double)n.y, (double)n.z, (double)exact.y, (double)e[1], (double)from_cells.y);
        if (fabsf(e[0] - exact.x) > 0.01f * exact.x || fabsf(e[1] - exact.y) > 0.01f * exact.y ||
            fabsf(e[2] - exact.z) > 0.01f * exact.z) {
            fail("SH irradiance (%g, %g, %g) differs from the closed form (%g, %g, %g) by more than 1%%",
                 (double)e[0], (double)e[1], (double)e[2], (double)exact.x, (double)exact.y, (double)exact.z);
        }
        if (length(sub(from_cells, exact)) > 0.02f * length(exact)) {
            fail("cell-sum irradiance (%g, %g, %g) differs from the closed form (%g, %g, %g) by more than 2%%",
                 (double)from_cells.x, (double)from_cells.y, (double)from_cells.z, (double)exact.x,
                 (double)exact.y, (double)exact.z);
        }
    }
}

/* ------------------------------------------------------------------------- */
/* Shading                                                                    */
/* ------------------------------------------------------------------------- */

typedef struct shading {
    float visibility[VERTEX_COUNT]; /* unoccluded fraction of the valid cells */
    signed char sun[VERTEX_COUNT];  /* facing the sun: 1 lit, 0 blocked; -1 facing away */
    int in_shadow;                  /* vertices facing the sun but blocked */
} shading;

/* What the masks say about each vertex: its visibility and whether the sun is
 * blocked; checks that no invalid cell is set. */
static void read_masks(const mesh *m, const cells *c, const antumbra_hemi_mask *masks, vec3 sun, shading *out)
{
    int v, j;
    out->in_shadow = 0;
    for (v = 0; v < VERTEX_COUNT; ++v) {
        const antumbra_hemi_mask *mask = &masks[v];
        const vec3 n = load3(&m->normals[3 * v]);
        int occluded = 0;
        for (j = 0; j < ANTUMBRA_HEMI_GRID; ++j) {
            if (mask->rows[j] & ~c->valid.rows[j]) {
                fail("vertex %d: mask row %d sets invalid cells (0x%08lx)", v, j, (unsigned long)mask->rows[j]);
            }
            occluded += popcount32(mask->rows[j]);
        }
        out->visibility[v] = 1.0f - (float)occluded / (float)c->count;
        out->sun[v] = -1;
        if (dot(n, sun) > 0.0f) {
            const frame3 f = receiver_frame(n);
            out->sun[v] = (signed char)!direction_blocked(&f, sun, mask);
            out->in_shadow += !out->sun[v];
        }
    }
}

/* Mean visibility of the `count` vertices nearest to (sign = +1) or farthest from
 * (sign = -1) the torus axis. */
static float extreme_visibility(const mesh *m, const shading *s, int count, float sign)
{
    static int order[VERTEX_COUNT];
    float sum = 0.0f;
    int v, k;
    /* Selection by repeated minimum: small and obviously right. */
    for (v = 0; v < VERTEX_COUNT; ++v) {
        order[v] = v;
    }
    for (k = 0; k < count; ++k) {
        int best = k;
        for (v = k + 1; v < VERTEX_COUNT; ++v) {
            if (sign * axis_distance(m, order[v]) < sign * axis_distance(m, order[best])) {
                best = v;
            }
        }
        v = order[k];
        order[k] = order[best];
        order[best] = v;
        sum += s->visibility[order[k]];
    }
    return sum / (float)count;
}

/* ------------------------------------------------------------------------- */
/* Shading under SH lighting, through the library                             */
/* ------------------------------------------------------------------------- */

static const vec3 CAMERA_EYE = {0.0f, 2.3f, 2.9f};
static const vec3 CAMERA_TARGET = {0.0f, -0.1f, 0.0f};

/* The procedural sky: a blue gradient from a pale horizon to a deep zenith, a
 * dark warm ground, and a bright sun lobe of radiance SUN_PEAK exp(k (d.s - 1))
 * (irradiance about 2 pi SUN_PEAK / k facing it). */
static const vec3 SKY_ZENITH = {0.10f, 0.20f, 0.55f};
static const vec3 SKY_HORIZON = {0.50f, 0.60f, 0.75f};
static const vec3 SKY_GROUND = {0.10f, 0.08f, 0.06f};
static const vec3 SUN_PEAK = {40.0f, 36.0f, 29.0f};
#define SUN_SHARPNESS 60.0f

static vec3 lerp3(vec3 a, vec3 b, float t) { return add(scale(a, 1.0f - t), scale(b, t)); }

static vec3 sky_map_radiance(vec3 d, vec3 sun)
{
    const vec3 sky = d.y >= 0.0f ? lerp3(SKY_HORIZON, SKY_ZENITH, sqrtf(d.y))
                                 : lerp3(scale(SKY_HORIZON, 0.5f), SKY_GROUND, sqrtf(-d.y));
    return add(sky, scale(SUN_PEAK, expf(SUN_SHARPNESS * (dot(d, sun) - 1.0f))));
}

/* The sky as an equirectangular float image (the documented map convention:
 * row 0 looks up, u = 0.5 along +X, u = 0.75 along +Z), projected onto SH_BANDS
 * bands: sh[c * SH_COEFFS + k], red, green, blue. */
static void project_sky(vec3 sun, float *sh)
{
    static float map[SKY_MAP_H][SKY_MAP_W][3];
    int row, column;
    for (row = 0; row < SKY_MAP_H; ++row) {
        for (column = 0; column < SKY_MAP_W; ++column) {
            const float theta = ((float)row + 0.5f) / (float)SKY_MAP_H * PI_F;
            const float phi = (((float)column + 0.5f) / (float)SKY_MAP_W - 0.5f) * 2.0f * PI_F;
            const vec3 d = v3(sinf(theta) * cosf(phi), cosf(theta), sinf(theta) * sinf(phi));
            store3(map[row][column], sky_map_radiance(d, sun));
        }
    }
    check(antumbra_sh_project_equirect(&map[0][0][0], SKY_MAP_W, SKY_MAP_H, 0, SH_BANDS, sh),
          "antumbra_sh_project_equirect (sky)");
    /* A sun this sharp rings on 5 bands (negative radiance around it, which a
     * glossy lobe picks up); the Lanczos sigma factors sinc(l / SH_BANDS) trade a
     * little sharpness for much less ringing, as engines do. */
    {
        int channel, l, m;
        for (l = 1; l < SH_BANDS; ++l) {
            const float x = PI_F * (float)l / (float)SH_BANDS;
            const float sigma = sinf(x) / x;
            for (channel = 0; channel < 3; ++channel) {
                for (m = -l; m <= l; ++m) {
                    sh[channel * SH_COEFFS + l * (l + 1) + m] *= sigma;
                }
            }
        }
    }
}

/* The SH lighting's radiance towards a direction (for a plausibility check). */
static vec3 sh_radiance(const float *sh, vec3 d)
{
    float y[SH_COEFFS], dir[3];
    vec3 out = v3(0.0f, 0.0f, 0.0f);
    int k;
    store3(dir, d);
    check(antumbra_sh_eval(dir, SH_BANDS, y), "antumbra_sh_eval");
    for (k = 0; k < SH_COEFFS; ++k) {
        out = add(out, v3(sh[k] * y[k], sh[SH_COEFFS + k] * y[k], sh[2 * SH_COEFFS + k] * y[k]));
    }
    return out;
}

static float luminance(const float *rgb) { return 0.2126f * rgb[0] + 0.7152f * rgb[1] + 0.0722f * rgb[2]; }

/* One frame of per-vertex colours. */
typedef struct shaded {
    float rgb[3 * VERTEX_COUNT];
    float diffuse[3 * VERTEX_COUNT];
    float glossy[3 * VERTEX_COUNT];
} shaded;

static double shade_timed(antumbra_hemi_shader *shader, const antumbra_mesh_view *view, const mesh *m,
                          const float *sky_sh, const antumbra_hemi_material *material, shaded *out, const char *what)
{
    const double start = now_ms();
    check(antumbra_hemi_shader_shade(shader, view, m->normals, NULL, sky_sh, material, out->rgb, out->diffuse,
                                     out->glossy),
          what);
    return now_ms() - start;
}

/* The shaded colours must make sense against what the masks say:
 *   - sunward vertices whose sun cell is open are brighter (diffuse) than those
 *     whose sun cell is blocked;
 *   - the glossy term is exactly 0 where the viewer is behind the surface, never
 *     noticeably negative, and stronger where the mirror direction is open than
 *     where it is blocked;
 *   - rgb = diffuse + glossy. */
static void check_plausible(int frame, const mesh *m, const antumbra_hemi_mask *masks, const shading *s,
                            const shaded *out, const char *which)
{
    double lit = 0.0, blocked = 0.0, open_glossy = 0.0, closed_glossy = 0.0;
    int lit_count = 0, blocked_count = 0, open_count = 0, closed_count = 0, behind = 0, v, k;
    float max_glossy = 0.0f, min_glossy = 0.0f;
    for (v = 0; v < VERTEX_COUNT; ++v) {
        const vec3 n = load3(&m->normals[3 * v]), p = load3(&m->positions[3 * v]);
        const vec3 to_eye = normalize(sub(CAMERA_EYE, p));
        const float *g = &out->glossy[3 * v];
        for (k = 0; k < 3; ++k) {
            if (out->rgb[3 * v + k] != out->diffuse[3 * v + k] + g[k]) {
                fail("frame %d (%s): vertex %d: rgb is not diffuse + glossy", frame, which, v);
            }
            max_glossy = fmaxf(max_glossy, g[k]);
            min_glossy = fminf(min_glossy, g[k]);
        }
        if (s->sun[v] >= 0) {
            if (s->sun[v]) {
                lit += luminance(&out->diffuse[3 * v]);
                ++lit_count;
            } else {
                blocked += luminance(&out->diffuse[3 * v]);
                ++blocked_count;
            }
        }
        if (dot(n, to_eye) < -1e-3f) {
            /* Clearly behind (not a rounding-level grazing view). */
            ++behind;
            if (g[0] != 0.0f || g[1] != 0.0f || g[2] != 0.0f) {
                fail("frame %d (%s): vertex %d faces away from the viewer but has glossy light (%g, %g, %g)", frame,
                     which, v, (double)g[0], (double)g[1], (double)g[2]);
            }
        } else if (dot(n, to_eye) > 0.0f) {
            const vec3 mirror = sub(scale(n, 2.0f * dot(n, to_eye)), to_eye);
            const frame3 f = receiver_frame(n);
            if (direction_blocked(&f, mirror, &masks[v])) {
                closed_glossy += luminance(g);
                ++closed_count;
            } else {
                open_glossy += luminance(g);
                ++open_count;
            }
        }
    }
    lit /= lit_count > 0 ? lit_count : 1;
    blocked /= blocked_count > 0 ? blocked_count : 1;
    open_glossy /= open_count > 0 ? open_count : 1;
    closed_glossy /= closed_count > 0 ? closed_count : 1;
    printf("hemi_shadows: frame %d (%s): sunward diffuse luminance %.3f lit (%d) vs %.3f shadowed (%d); glossy %.3f "
           "with the mirror direction open (%d) vs %.3f blocked (%d), 0 on %d vertices facing away\n",
           frame, which, lit, lit_count, blocked, blocked_count, open_glossy, open_count, closed_glossy, closed_count,
           behind);
    if (blocked_count == 0 || closed_count == 0 || behind == 0) {
        fail("frame %d (%s): the pose has no shadowed sunward vertex, no blocked mirror direction or no vertex facing "
             "away; the checks below would be vacuous",
             frame, which);
    }
    if (!(lit > 1.5 * blocked)) {
        fail("frame %d (%s): sunward vertices in the open (%.3f) are not clearly brighter than shadowed ones (%.3f)",
             frame, which, lit, blocked);
    }
    if (!(open_glossy > 1.5 * closed_glossy)) {
        fail("frame %d (%s): glossy light with the mirror direction open (%.3f) is not clearly above blocked (%.3f)",
             frame, which, open_glossy, closed_glossy);
    }
    if (!(min_glossy > -0.02f * max_glossy)) {
        fail("frame %d (%s): glossy light goes down to %g (max %g)", frame, which, (double)min_glossy,
             (double)max_glossy);
    }
}

/* antumbra_hemi_shader_transfer's world vectors dotted with the lighting are the
 * diffuse colours (times albedo/pi), and their band-0 coefficient is the
 * cosine-weighted visibility: T_0 = (sqrt(pi)/2) * (visible share of the disk),
 * close to the mask's share of visible cells. */
static void check_transfer(antumbra_hemi_shader *shader, const antumbra_mesh_view *view, const mesh *m,
                           const float *sky_sh, const shaded *full, const shading *s)
{
    static float transfer[VERTEX_COUNT * SH_COEFFS];
    const float t0_open = 0.886226925f;
    double worst_colour = 0.0, worst_t0 = 0.0, sum_t0 = 0.0;
    int v, k, channel;
    check(antumbra_hemi_shader_transfer(shader, view, m->normals, NULL, transfer), "antumbra_hemi_shader_transfer");
    for (v = 0; v < VERTEX_COUNT; ++v) {
        const float *t = &transfer[v * SH_COEFFS];
        const float albedo[3] = {ALBEDO.x, ALBEDO.y, ALBEDO.z};
        for (channel = 0; channel < 3; ++channel) {
            double e = 0.0, want = full->diffuse[3 * v + channel], error;
            for (k = 0; k < SH_COEFFS; ++k) {
                e += (double)t[k] * (double)sky_sh[channel * SH_COEFFS + k];
            }
            e *= albedo[channel] / PI_F;
            error = fabs(e - want) / (fabs(want) + 1e-3);
            worst_colour = error > worst_colour ? error : worst_colour;
        }
        {
            const double difference = fabs(t[0] / t0_open - s->visibility[v]);
            worst_t0 = difference > worst_t0 ? difference : worst_t0;
            sum_t0 += difference;
        }
    }
    printf("hemi_shadows: transfer vectors: diffuse from T.l within %.2g (relative) of the shaded diffuse; "
           "T_0 / 0.886227 within %.3f of the visible cell share (mean %.4f)\n",
           worst_colour, worst_t0, sum_t0 / VERTEX_COUNT);
    if (!(worst_colour < 1e-4)) {
        fail("albedo/pi * T.l differs from the shaded diffuse by %g (relative)", worst_colour);
    }
    if (!(worst_t0 < 0.05)) {
        fail("T_0 / 0.886227 differs from the visible share of the cells by %g", worst_t0);
    }
}

/* Sparse receivers: with keys one edge apart and a tolerance of 0.05, every
 * vertex either keeps its exact vector (keys, and vertices whose keys disagree)
 * or gets its keys' interpolation (some do on this torus), whose T_0 stays within the tolerance (times
 * the open hemisphere's 0.886) of the exact one where occlusion varies
 * smoothly; spacing 0 restores the exact vectors. A spacing above the maximum
 * is refused. */
static void check_sparse_receivers(antumbra_hemi_shader *shader, const antumbra_mesh_view *view, const mesh *m,
                                   const float *sky_sh, const antumbra_hemi_material *material, const shaded *full)
{
    static float exact[VERTEX_COUNT * SH_COEFFS], sparse[VERTEX_COUNT * SH_COEFFS];
    static shaded sparse_colours;
    const float tolerance = 0.05f, t0_open = 0.886226925f;
    double sum = 0.0, colour_difference = 0.0, colour_total = 0.0;
    int v, i, same = 0, same_colours = 0;
    check(antumbra_hemi_shader_transfer(shader, view, m->normals, NULL, exact), "antumbra_hemi_shader_transfer");
    check(antumbra_hemi_shader_set_receivers(shader, view, 1, tolerance), "antumbra_hemi_shader_set_receivers");
    check(antumbra_hemi_shader_transfer(shader, view, m->normals, NULL, sparse),
          "antumbra_hemi_shader_transfer (sparse receivers)");
    for (v = 0; v < VERTEX_COUNT; ++v) {
        same += memcmp(&exact[v * SH_COEFFS], &sparse[v * SH_COEFFS], sizeof(float) * SH_COEFFS) == 0;
        sum += fabs((double)sparse[v * SH_COEFFS] - (double)exact[v * SH_COEFFS]);
    }
    printf("hemi_shadows: sparse receivers (spacing 1, tolerance %.2f): %d of %d vertices exact, mean |T_0 "
           "difference| %.5f\n",
           (double)tolerance, same, VERTEX_COUNT, sum / VERTEX_COUNT);
    if (same == 0 || same == VERTEX_COUNT || !(sum / VERTEX_COUNT <= tolerance * t0_open)) {
        fail("sparse receivers: %d exact vectors, mean T_0 difference %g", same, sum / VERTEX_COUNT);
    }
    /* Shading borrows the diffuse and glossy occlusion the same way. */
    shade_timed(shader, view, m, sky_sh, material, &sparse_colours,
                "antumbra_hemi_shader_shade (sparse receivers)");
    for (v = 0; v < VERTEX_COUNT; ++v) {
        same_colours += memcmp(&sparse_colours.rgb[3 * v], &full->rgb[3 * v], 3 * sizeof(float)) == 0;
        for (i = 3 * v; i < 3 * v + 3; ++i) {
            colour_difference += fabs((double)sparse_colours.rgb[i] - (double)full->rgb[i]);
            colour_total += fabs((double)full->rgb[i]);
        }
    }
    printf("hemi_shadows: sparse receivers shading: %d of %d colours exact, mean difference %.3f%%\n", same_colours,
           VERTEX_COUNT, 100.0 * colour_difference / colour_total);
    if (same_colours == 0 || same_colours == VERTEX_COUNT || !(colour_difference <= tolerance * colour_total)) {
        fail("sparse receivers: %d exact colours, mean difference %g", same_colours,
             colour_difference / colour_total);
    }
    if (antumbra_hemi_shader_set_receivers(shader, view, ANTUMBRA_HEMI_MAX_RECEIVER_SPACING + 1, tolerance) !=
        ANTUMBRA_RESULT_INVALID_ARGUMENT) {
        fail("a receiver spacing above ANTUMBRA_HEMI_MAX_RECEIVER_SPACING was not refused");
    }
    check(antumbra_hemi_shader_set_receivers(shader, view, 0, 0.0f), "antumbra_hemi_shader_set_receivers (off)");
    check(antumbra_hemi_shader_transfer(shader, view, m->normals, NULL, sparse), "antumbra_hemi_shader_transfer");
    if (memcmp(exact, sparse, sizeof exact) != 0) {
        fail("spacing 0 did not restore the exact transfer vectors");
    }
}

/* The far mesh stands in for the distant full mesh: the colours must stay close. */
static void compare_far(int frame, const shaded *full, const shaded *far)
{
    double difference = 0.0, total = 0.0;
    int i;
    for (i = 0; i < 3 * VERTEX_COUNT; ++i) {
        difference += fabs((double)far->rgb[i] - (double)full->rgb[i]);
        total += fabs((double)full->rgb[i]);
    }
    printf("hemi_shadows: frame %d: the far mesh changes the colours by %.2f%% on average\n", frame,
           100.0 * difference / total);
    if (!(difference < 0.05 * total)) {
        fail("frame %d: the far mesh changes the colours by %.2f%%; at most 5%% expected", frame,
             100.0 * difference / total);
    }
}

/* ------------------------------------------------------------------------- */
/* Software rasterizer (perspective, z-buffered, Gouraud)                     */
/* ------------------------------------------------------------------------- */

typedef struct image {
    float depth[WIDTH * HEIGHT];
    unsigned char rgb[WIDTH * HEIGHT * 3];
} image;

typedef struct camera {
    vec3 eye, forward, right, up;
    float focal; /* pixels */
} camera;

static camera look_at(vec3 eye, vec3 target, float vertical_fov_degrees)
{
    camera c;
    c.eye = eye;
    c.forward = normalize(sub(target, eye));
    c.right = normalize(cross(c.forward, v3(0.0f, 1.0f, 0.0f)));
    c.up = cross(c.right, c.forward);
    c.focal = 0.5f * (float)HEIGHT / tanf(0.5f * vertical_fov_degrees * PI_F / 180.0f);
    return c;
}

/* Screen position (pixels, y down) and view depth of a point. */
static vec3 project(const camera *c, vec3 p)
{
    const vec3 d = sub(p, c->eye);
    const float depth = dot(d, c->forward);
    return v3(0.5f * (float)WIDTH + c->focal * dot(d, c->right) / depth,
              0.5f * (float)HEIGHT - c->focal * dot(d, c->up) / depth, depth);
}

static unsigned char to_byte(float linear)
{
    /* Exposure tone curve (the sunlit side reaches a radiance of about 1.5), then
     * display gamma. */
    const float mapped = powf(1.0f - expf(-0.6f * fmaxf(linear, 0.0f)), 1.0f / 2.2f);
    return (unsigned char)(mapped * 255.0f + 0.5f);
}

/* Draws the mesh with per-vertex colours `rgb` (linear) over the sky. */
static int render(const mesh *m, const float *rgb, vec3 sun, image *img)
{
    const camera cam = look_at(CAMERA_EYE, CAMERA_TARGET, 45.0f);
    int x, y, t, covered = 0;
    for (y = 0; y < HEIGHT; ++y) {
        for (x = 0; x < WIDTH; ++x) {
            /* Background: the procedural sky along the pixel's ray. */
            const vec3 d = normalize(add(scale(cam.forward, cam.focal),
                                         add(scale(cam.right, (float)x + 0.5f - 0.5f * (float)WIDTH),
                                             scale(cam.up, 0.5f * (float)HEIGHT - (float)y - 0.5f))));
            const vec3 sky = sky_map_radiance(d, sun);
            unsigned char *px = &img->rgb[3 * (y * WIDTH + x)];
            img->depth[y * WIDTH + x] = INFINITY;
            px[0] = to_byte(sky.x);
            px[1] = to_byte(sky.y);
            px[2] = to_byte(sky.z);
        }
    }
    for (t = 0; t < TRIANGLE_COUNT; ++t) {
        const uint32_t *tri = &m->indices[3 * t];
        const vec3 a = project(&cam, load3(&m->positions[3 * tri[0]]));
        const vec3 b = project(&cam, load3(&m->positions[3 * tri[1]]));
        const vec3 c = project(&cam, load3(&m->positions[3 * tri[2]]));
        const float area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        int x0, x1, y0, y1;
        if (a.z <= 0.1f || b.z <= 0.1f || c.z <= 0.1f || area >= 0.0f) {
            continue; /* behind the camera, or back-facing (clockwise on a y-down screen) */
        }
        x0 = (int)floorf(fminf(a.x, fminf(b.x, c.x)));
        x1 = (int)ceilf(fmaxf(a.x, fmaxf(b.x, c.x)));
        y0 = (int)floorf(fminf(a.y, fminf(b.y, c.y)));
        y1 = (int)ceilf(fmaxf(a.y, fmaxf(b.y, c.y)));
        x0 = x0 < 0 ? 0 : x0;
        y0 = y0 < 0 ? 0 : y0;
        x1 = x1 > WIDTH - 1 ? WIDTH - 1 : x1;
        y1 = y1 > HEIGHT - 1 ? HEIGHT - 1 : y1;
        for (y = y0; y <= y1; ++y) {
            for (x = x0; x <= x1; ++x) {
                const float px = (float)x + 0.5f, py = (float)y + 0.5f;
                const float wa = ((b.x - px) * (c.y - py) - (b.y - py) * (c.x - px)) / area;
                const float wb = ((c.x - px) * (a.y - py) - (c.y - py) * (a.x - px)) / area;
                const float wc = 1.0f - wa - wb;
                float depth;
                vec3 colour;
                unsigned char *out;
                if (wa < 0.0f || wb < 0.0f || wc < 0.0f) {
                    continue;
                }
                /* Perspective-correct: 1/z is linear on screen. */
                depth = 1.0f / (wa / a.z + wb / b.z + wc / c.z);
                if (depth >= img->depth[y * WIDTH + x]) {
                    continue;
                }
                img->depth[y * WIDTH + x] = depth;
                colour = scale(add(add(scale(load3(&rgb[3 * tri[0]]), wa / a.z),
                                       scale(load3(&rgb[3 * tri[1]]), wb / b.z)),
                                   scale(load3(&rgb[3 * tri[2]]), wc / c.z)),
                               depth);
                out = &img->rgb[3 * (y * WIDTH + x)];
                out[0] = to_byte(colour.x);
                out[1] = to_byte(colour.y);
                out[2] = to_byte(colour.z);
            }
        }
    }
    for (x = 0; x < WIDTH * HEIGHT; ++x) {
        covered += isfinite(img->depth[x]) != 0;
    }
    return covered;
}

static void write_ppm(const char *path, const image *img)
{
    FILE *file = fopen(path, "wb");
    if (file == NULL) {
        fail("cannot open %s for writing", path);
    }
    if (fprintf(file, "P6\n%d %d\n255\n", WIDTH, HEIGHT) < 0 ||
        fwrite(img->rgb, 1, sizeof img->rgb, file) != sizeof img->rgb) {
        fclose(file);
        fail("cannot write %s", path);
    }
    if (fclose(file) != 0) {
        fail("cannot finish writing %s", path);
    }
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

/* Fraction of valid cells on which two batches of masks agree. */
static double agreement(const antumbra_hemi_mask *a, const antumbra_hemi_mask *b, int count)
{
    long differ = 0;
    int v, j;
    for (v = 0; v < count; ++v) {
        for (j = 0; j < ANTUMBRA_HEMI_GRID; ++j) {
            differ += popcount32(a[v].rows[j] ^ b[v].rows[j]);
        }
    }
    return 1.0 - (double)differ / ((double)count * ANTUMBRA_HEMI_VALID_CELL_COUNT);
}

static double rasterize_timed(const antumbra_mesh_view *view, const mesh *m, const antumbra_hemi_options *options,
                              antumbra_hemi_mask *masks, const char *what)
{
    const double start = now_ms();
    check(antumbra_hemi_rasterize(view, m->positions, m->normals, VERTEX_COUNT, options, masks), what);
    return now_ms() - start;
}

int main(int argc, char **argv)
{
    const char *path = argc > 1 ? argv[1] : "hemi_shadows.ppm";
    const vec3 sun = normalize(v3(0.3f, 0.4f, 0.85f));
    mesh *m = checked_malloc(sizeof *m);
    cells *c = checked_malloc(sizeof *c);
    shading *s = checked_malloc(sizeof *s);
    image *img = checked_malloc(sizeof *img);
    antumbra_hemi_mask *exact = checked_malloc(VERTEX_COUNT * sizeof *exact);
    antumbra_hemi_mask *table = checked_malloc(VERTEX_COUNT * sizeof *table);
    antumbra_hemi_mask *own_table = checked_malloc(VERTEX_COUNT * sizeof *own_table);
    shaded *full = checked_malloc(sizeof *full);
    shaded *lod = checked_malloc(sizeof *lod);
    antumbra_hemi_table *handle = NULL;
    antumbra_hemi_shader *shader = NULL, *full_shader = NULL;
    antumbra_hemi_options options;
    antumbra_hemi_shading_options shading_options;
    antumbra_hemi_material material;
    antumbra_mesh_view view;
    float sky_sh[3 * SH_COEFFS];
    double table_agreement = 0.0, ms_far_total = 0.0, ms_full_total = 0.0;
    int frame, covered;

    check_version();
    printf("hemi_shadows: antumbra %s, torus of %d vertices and %d triangles (far mesh: about %d), %d frames\n",
           antumbra_version_string(), VERTEX_COUNT, TRIANGLE_COUNT, FAR_TRIANGLES, FRAMES);

    load_cells(c);
    check_sky_sh(c);

    build_indices(m);
    view.positions = m->positions;
    view.vertex_count = VERTEX_COUNT;
    view.position_stride = 0;
    view.indices = m->indices;
    view.triangle_count = TRIANGLE_COUNT;

    antumbra_hemi_options_init(&options);
    if (antumbra_last_error_message()[0] != '\0' || options.quality != ANTUMBRA_HEMI_QUALITY_EXACT ||
        options.cull_backfaces != 0 || options.normal_offset != 0.0f || options.parallel != 0 ||
        options.table != NULL) {
        fail("antumbra_hemi_options_init did not write the documented defaults");
    }

    /* The sky, projected once; it must be brighter towards the sun than away. */
    project_sky(sun, sky_sh);
    {
        const vec3 towards = sh_radiance(sky_sh, sun), away = sh_radiance(sky_sh, scale(sun, -1.0f));
        printf("hemi_shadows: sky on %d SH bands: radiance %.2f towards the sun, %.2f away (green)\n", SH_BANDS,
               (double)towards.y, (double)away.y);
        if (!(towards.y > 4.0f * away.y) || !(away.y > 0.0f)) {
            fail("the projected sky is not brighter towards the sun (%g vs %g)", (double)towards.y,
                 (double)away.y);
        }
    }

    /* Two shaders for the whole animation, created from the rest pose: one with
     * the library's far mesh, one with the full mesh everywhere (to compare);
     * every frame passes the current positions. */
    antumbra_hemi_shading_options_init(&shading_options);
    if (antumbra_last_error_message()[0] != '\0' || memcmp(&shading_options.raster, &options, sizeof options) != 0 ||
        shading_options.bands != 3 || shading_options.method != ANTUMBRA_HEMI_METHOD_CELLS ||
        shading_options.space != ANTUMBRA_HEMI_SPACE_WORLD || shading_options.near_radius != INFINITY ||
        shading_options.far_triangles != 0 || shading_options.far_levels != 0) {
        fail("antumbra_hemi_shading_options_init did not write the documented defaults");
    }
    shading_options.bands = SH_BANDS;
    antumbra_hemi_material_init(&material);
    if (antumbra_last_error_message()[0] != '\0' || material.albedo[0] != 1.0f || material.specular[0] != 0.0f ||
        material.phong_exponent != 16.0f || material.vertex_albedo != NULL || material.view_directions != NULL) {
        fail("antumbra_hemi_material_init did not write the documented defaults");
    }
    store3(material.albedo, ALBEDO);
    store3(material.specular, SPECULAR);
    material.phong_exponent = GLOSSY_EXPONENT;
    store3(material.eye, CAMERA_EYE);
    deform(m, 0.0f);
    check(antumbra_hemi_shader_create(&view, NULL, &shading_options, &full_shader), "antumbra_hemi_shader_create");
    shading_options.far_triangles = FAR_TRIANGLES;
    check(antumbra_hemi_shader_create(&view, NULL, &shading_options, &shader),
          "antumbra_hemi_shader_create (far_triangles)");
    if (shader == NULL || full_shader == NULL) {
        fail("antumbra_hemi_shader_create returned OK and a NULL shader");
    }

    for (frame = 0; frame < FRAMES; ++frame) {
        const float time = 0.7f * (float)frame;
        float inner, outer, mean = 0.0f;
        double ms, ms_far, ms_full;
        int v;

        deform(m, time);
        compute_normals(m);
        ms = rasterize_timed(&view, m, &options, exact, "antumbra_hemi_rasterize (exact)");
        read_masks(m, c, exact, sun, s);
        for (v = 0; v < VERTEX_COUNT; ++v) {
            mean += s->visibility[v] / (float)VERTEX_COUNT;
        }
        inner = extreme_visibility(m, s, SIDES, 1.0f);
        outer = extreme_visibility(m, s, SIDES, -1.0f);
        printf("hemi_shadows: frame %d: exact masks in %.2f ms (%.1f us per vertex); visibility mean %.3f, "
               "innermost %.3f, outermost %.3f; %d sunward vertices in shadow\n",
               frame, ms, 1e3 * ms / VERTEX_COUNT, (double)mean, (double)inner, (double)outer, s->in_shadow);
        /* The innermost vertices look across the hole at the far side of the
         * torus; the outermost ones see open sky over a convex surface. */
        if (!(outer > 0.97f) || !(inner < outer - 0.05f)) {
            fail("frame %d: innermost visibility %.3f, outermost %.3f: expected the hole side darker and the "
                 "outside nearly unoccluded",
                 frame, (double)inner, (double)outer);
        }
        if (s->in_shadow == 0) {
            fail("frame %d: no vertex facing the sun is shadowed; the torus should shadow itself", frame);
        }

        /* Shaded under the sky, diffuse + glossy, on this thread. */
        ms_far = shade_timed(shader, &view, m, sky_sh, &material, lod,
                             "antumbra_hemi_shader_shade (far mesh)");
        ms_full = shade_timed(full_shader, &view, m, sky_sh, &material, full,
                              "antumbra_hemi_shader_shade (full mesh)");
        ms_far_total += ms_far;
        ms_full_total += ms_full;
        printf("hemi_shadows: frame %d: shaded (diffuse + glossy, %d SH bands) in %.2f ms (%.1f us per vertex) with "
               "the far mesh, %.2f ms (%.1f us per vertex) without\n",
               frame, SH_BANDS, ms_far, 1e3 * ms_far / VERTEX_COUNT, ms_full, 1e3 * ms_full / VERTEX_COUNT);
        check_plausible(frame, m, exact, s, full, "full mesh");
        check_plausible(frame, m, exact, s, lod, "far mesh");
        compare_far(frame, full, lod);
        if (frame == 0) {
            check_transfer(full_shader, &view, m, sky_sh, full, s);
            check_sparse_receivers(full_shader, &view, m, sky_sh, &material, full);
        }
    }
    printf("hemi_shadows: shading every vertex on one thread: %.2f ms per frame (%.1f us per vertex) with the far "
           "mesh, %.2f ms (%.1f us per vertex) without\n",
           ms_far_total / FRAMES, 1e3 * ms_far_total / FRAMES / VERTEX_COUNT, ms_full_total / FRAMES,
           1e3 * ms_full_total / FRAMES / VERTEX_COUNT);
    antumbra_hemi_shader_destroy(shader);
    antumbra_hemi_shader_destroy(full_shader);

    /* The last frame again with the table quality: the library's shared table on
     * its worker threads, and a table of our own (same resolution) on this thread;
     * the two must be identical, and close to the exact masks. */
    {
        antumbra_hemi_options table_options = options;
        double ms_shared, ms_own;
        table_options.quality = ANTUMBRA_HEMI_QUALITY_TABLE;
        table_options.parallel = 1;
        ms_shared = rasterize_timed(&view, m, &table_options, table, "antumbra_hemi_rasterize (table, parallel)");
        check(antumbra_hemi_table_create(0, &handle), "antumbra_hemi_table_create");
        if (handle == NULL) {
            fail("antumbra_hemi_table_create returned OK and a NULL table");
        }
        table_options.table = handle;
        table_options.parallel = 0;
        ms_own = rasterize_timed(&view, m, &table_options, own_table, "antumbra_hemi_rasterize (own table)");
        antumbra_hemi_table_destroy(handle);
        table_agreement = agreement(exact, table, VERTEX_COUNT);
        printf("hemi_shadows: table masks in %.2f ms on the worker threads (first call builds the shared table), "
               "%.2f ms (%.1f us per vertex) on this thread; %.3f%% of valid cells agree with exact\n",
               ms_shared, ms_own, 1e3 * ms_own / VERTEX_COUNT, 100.0 * table_agreement);
        if (memcmp(table, own_table, VERTEX_COUNT * sizeof *table) != 0) {
            fail("the shared table on worker threads and an own table of the same resolution gave different masks");
        }
        if (!(table_agreement >= 0.99)) {
            fail("table quality agrees with exact on %.3f%% of cells; at least 99%% expected",
                 100.0 * table_agreement);
        }
    }

    covered = render(m, lod->rgb, sun, img);
    write_ppm(path, img);
    printf("hemi_shadows: wrote %s (%dx%d, %d%% covered)\n", path, WIDTH, HEIGHT, 100 * covered / (WIDTH * HEIGHT));
    if (covered < WIDTH * HEIGHT / 10) {
        fail("the torus covers only %d of %d pixels", covered, WIDTH * HEIGHT);
    }

    free(lod);
    free(full);
    free(own_table);
    free(table);
    free(exact);
    free(img);
    free(s);
    free(c);
    free(m);
    return EXIT_SUCCESS;
}

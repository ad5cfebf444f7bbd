/*
 * prt_relight.c: relighting a baked transfer set every frame through Antumbra's
 * precomputed radiance transfer (Lehtinen 2007; Lehtinen and Kautz, "Matrix
 * Radiance Transfer", 2003), as an engine does at run time.
 *
 * With a bake file on the command line (written by `antumbra bake --mesh FILE
 * --kind diffuse|glossy-sh|mrt ... -o FILE`) it loads that file. Without one it
 * bakes its own scene first: a ground grid under a floating sphere, baked twice
 * through antumbra_transfer_bake (diffuse PRT with one interreflection bounce, and
 * MRT with a Phong BRDF), each saved to bytes and loaded back as a game would
 * load its bake files. Then, per frame:
 *
 *   - a procedural sky (a blue gradient and a soft sun) is projected once onto SH
 *     with antumbra_sh_project_equirect and rotated about the vertical axis for
 *     each frame with antumbra_sh_rotate (checked against projecting the rotated
 *     sky directly);
 *   - every vertex is relit with antumbra_transfer_shade, timed (best of 20
 *     calls): diffuse, MRT, and MRT from its PCA with a few component counts;
 *   - the colours are splatted orthographically into a PPM image per frame.
 *
 * Checks (exit status 1 on any failure): antumbra_version() matches the header;
 * every colour finite, diffuse colours non-negative; the reloaded set saves to
 * the same bytes and shades bit for bit like the original; PCA with all
 * components reproduces uncompressed MRT to float precision (and is closer than
 * one component); relighting moves the light (frames differ); with the
 * sun high the ground in the sphere's shadow is darker than the open ground; the
 * bake's progress callback counts every vertex pass.
 *
 * Usage: prt_relight [--small] [-o OUT_PREFIX] [BAKE_FILE]
 *   --small        a smaller scene and fewer frames (for valgrind)
 *   -o OUT_PREFIX  images OUT_PREFIX-<frame>.ppm (default prt_relight)
 * Exit status: 0 on success, 1 on any unexpected result.
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

#define SKY_W 96
#define SKY_H 48
#define IMAGE_W 160
#define IMAGE_H 120

/* ------------------------------------------------------------------------- */
/* Failure reporting and small helpers                                         */
/* ------------------------------------------------------------------------- */

static int failures = 0;

static void fail(const char *format, ...)
{
    va_list args;
    va_start(args, format);
    fprintf(stderr, "prt_relight: FAILED: ");
    vfprintf(stderr, format, args);
    fprintf(stderr, "\n");
    va_end(args);
    failures++;
}

static void check(antumbra_result result, const char *call)
{
    if (result != ANTUMBRA_RESULT_OK) {
        fprintf(stderr, "prt_relight: %s returned %s: %s\n", call, antumbra_result_str(result),
                antumbra_last_error_message());
        exit(1);
    }
}

static void *checked_malloc(size_t size)
{
    void *p = malloc(size ? size : 1);
    if (!p) {
        fprintf(stderr, "prt_relight: out of memory (%zu bytes)\n", size);
        exit(1);
    }
    return p;
}

static double now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

typedef struct {
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
static float dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

/* ------------------------------------------------------------------------- */
/* The scene baked when no file is given                                       */
/* ------------------------------------------------------------------------- */

typedef struct {
    float *positions;
    float *normals;
    uint32_t *indices;
    size_t vertex_count;
    size_t triangle_count;
    size_t ground_vertices; /* the first ones are the ground grid */
    size_t ground_side;
} scene;

#define SPHERE_Y 0.9f
#define SPHERE_R 0.6f

/* A (side x side) ground grid over [-2, 2]² at y = 0, facing up, and a UV sphere
 * of radius SPHERE_R centred SPHERE_Y above the origin, open at the poles. */
static void build_scene(scene *s, int side, int rings, int segments)
{
    size_t ground = (size_t)side * (size_t)side;
    size_t sphere = (size_t)(rings + 1) * (size_t)(segments + 1);
    size_t tris = 2 * (size_t)(side - 1) * (size_t)(side - 1) + 2 * (size_t)rings * (size_t)segments;
    size_t v = 0, t = 0;
    int i, j;
    s->vertex_count = ground + sphere;
    s->triangle_count = tris;
    s->ground_vertices = ground;
    s->ground_side = (size_t)side;
    s->positions = checked_malloc(3 * s->vertex_count * sizeof(float));
    s->normals = checked_malloc(3 * s->vertex_count * sizeof(float));
    s->indices = checked_malloc(3 * tris * sizeof(uint32_t));
    for (j = 0; j < side; j++) {
        for (i = 0; i < side; i++, v++) {
            s->positions[3 * v + 0] = -2.0f + 4.0f * (float)i / (float)(side - 1);
            s->positions[3 * v + 1] = 0.0f;
            s->positions[3 * v + 2] = -2.0f + 4.0f * (float)j / (float)(side - 1);
            s->normals[3 * v + 0] = 0.0f;
            s->normals[3 * v + 1] = 1.0f;
            s->normals[3 * v + 2] = 0.0f;
        }
    }
    for (j = 0; j + 1 < side; j++) {
        for (i = 0; i + 1 < side; i++) {
            uint32_t a = (uint32_t)(j * side + i), b = a + 1, c = a + (uint32_t)side, d = c + 1;
            uint32_t quad[6];
            quad[0] = a; quad[1] = c; quad[2] = b;
            quad[3] = b; quad[4] = c; quad[5] = d;
            memcpy(&s->indices[3 * t], quad, sizeof quad);
            t += 2;
        }
    }
    for (j = 0; j <= rings; j++) {
        /* Open at the poles (no degenerate triangles), so every vertex has an
         * area-weighted normal for the bake that computes them. */
        float theta = PI_F * ((float)j + 0.5f) / (float)(rings + 1);
        for (i = 0; i <= segments; i++, v++) {
            float phi = 2.0f * PI_F * (float)i / (float)segments;
            vec3 n = v3(sinf(theta) * cosf(phi), cosf(theta), sinf(theta) * sinf(phi));
            float len = sqrtf(dot(n, n));
            n = v3(n.x / len, n.y / len, n.z / len);
            s->positions[3 * v + 0] = SPHERE_R * n.x;
            s->positions[3 * v + 1] = SPHERE_Y + SPHERE_R * n.y;
            s->positions[3 * v + 2] = SPHERE_R * n.z;
            s->normals[3 * v + 0] = n.x;
            s->normals[3 * v + 1] = n.y;
            s->normals[3 * v + 2] = n.z;
        }
    }
    for (j = 0; j < rings; j++) {
        for (i = 0; i < segments; i++) {
            uint32_t a = (uint32_t)(ground + (size_t)j * (size_t)(segments + 1) + (size_t)i);
            uint32_t b = a + 1, c = a + (uint32_t)(segments + 1), d = c + 1;
            uint32_t quad[6];
            quad[0] = a; quad[1] = b; quad[2] = c;
            quad[3] = b; quad[4] = d; quad[5] = c;
            memcpy(&s->indices[3 * t], quad, sizeof quad);
            t += 2;
        }
    }
    if (v != s->vertex_count || t != tris) {
        fail("scene construction miscounted (%zu/%zu vertices, %zu/%zu triangles)", v,
             s->vertex_count, t, tris);
    }
}

static void free_scene(scene *s)
{
    free(s->positions);
    free(s->normals);
    free(s->indices);
}

/* Progress of a serial bake: calls must arrive in order, 1..total. */
typedef struct {
    size_t calls;
    size_t last_done;
    size_t total;
    int out_of_order;
} progress_state;

static void on_progress(size_t done, size_t total, void *user_data)
{
    progress_state *p = (progress_state *)user_data;
    if (done != p->last_done + 1 || (p->total && total != p->total)) {
        p->out_of_order = 1;
    }
    p->calls++;
    p->last_done = done;
    p->total = total;
}

/* ------------------------------------------------------------------------- */
/* Bake files                                                                  */
/* ------------------------------------------------------------------------- */

static uint8_t *save_bytes(const antumbra_transfer *t, size_t *size)
{
    uint8_t *bytes;
    size_t needed = 0, written = 0;
    antumbra_result r = antumbra_transfer_save(t, NULL, 0, &needed);
    if (r != ANTUMBRA_RESULT_BUFFER_TOO_SMALL || needed == 0) {
        fail("sizing a save returned %s with size %zu", antumbra_result_str(r), needed);
        exit(1);
    }
    bytes = checked_malloc(needed);
    check(antumbra_transfer_save(t, bytes, needed, &written), "antumbra_transfer_save");
    if (written != needed) {
        fail("antumbra_transfer_save wrote %zu bytes, sized %zu", written, needed);
    }
    *size = written;
    return bytes;
}

static uint8_t *read_file(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    uint8_t *bytes;
    long len;
    if (!f) {
        fprintf(stderr, "prt_relight: cannot open %s\n", path);
        exit(1);
    }
    if (fseek(f, 0, SEEK_END) != 0 || (len = ftell(f)) < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fprintf(stderr, "prt_relight: cannot size %s\n", path);
        exit(1);
    }
    bytes = checked_malloc((size_t)len);
    if (fread(bytes, 1, (size_t)len, f) != (size_t)len) {
        fprintf(stderr, "prt_relight: cannot read %s\n", path);
        exit(1);
    }
    fclose(f);
    *size = (size_t)len;
    return bytes;
}

static void write_file(const char *path, const uint8_t *bytes, size_t size)
{
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(bytes, 1, size, f) != size || fclose(f) != 0) {
        fprintf(stderr, "prt_relight: cannot write %s\n", path);
        exit(1);
    }
}

static antumbra_transfer_info describe(const antumbra_transfer *t)
{
    antumbra_transfer_info info;
    check(antumbra_transfer_describe(t, &info), "antumbra_transfer_describe");
    return info;
}

static const char *kind_name(uint32_t kind)
{
    switch (kind) {
    case ANTUMBRA_TRANSFER_KIND_DIFFUSE: return "diffuse";
    case ANTUMBRA_TRANSFER_KIND_GLOSSY_SH: return "glossy SH";
    case ANTUMBRA_TRANSFER_KIND_MRT: return "MRT";
    default: return "unknown";
    }
}

static void print_info(const char *label, const antumbra_transfer_info *i)
{
    printf("%s: %s, %u bands, grid %u, %u PCA components, %u vertices, %u rays, %u bounces, "
           "%.1f KB data (%.0f B/vertex), %zu-byte file\n",
           label, kind_name(i->kind), i->bands, i->grid, i->components, i->vertex_count, i->rays,
           i->bounces, (double)i->data_bytes / 1024.0,
           (double)i->data_bytes / (double)i->vertex_count, i->file_bytes);
}

/* Saves `t`, loads the bytes back, and checks the copy saves to the same bytes.
 * Returns the loaded copy; the original is destroyed: from here on the program
 * runs on a loaded set, as a game would. */
static antumbra_transfer *round_trip(antumbra_transfer *t, const char *path)
{
    size_t size = 0, size2 = 0;
    uint8_t *bytes = save_bytes(t, &size);
    uint8_t *again;
    antumbra_transfer *loaded = NULL;
    antumbra_transfer_info a = describe(t), b;
    check(antumbra_transfer_load(bytes, size, &loaded), "antumbra_transfer_load");
    b = describe(loaded);
    if (memcmp(&a, &b, sizeof a) != 0) {
        fail("the reloaded set describes itself differently");
    }
    if (a.file_bytes != size) {
        fail("describe says %zu file bytes, save wrote %zu", a.file_bytes, size);
    }
    again = save_bytes(loaded, &size2);
    if (size2 != size || memcmp(bytes, again, size) != 0) {
        fail("the reloaded set does not save to the same bytes");
    }
    if (path) {
        write_file(path, bytes, size);
    }
    free(bytes);
    free(again);
    antumbra_transfer_destroy(t);
    return loaded;
}

/* ------------------------------------------------------------------------- */
/* Lighting                                                                    */
/* ------------------------------------------------------------------------- */

/* The sky: a blue gradient over a dim ground, and a soft sun. */
static vec3 sky_radiance(vec3 d, vec3 sun)
{
    float up = d.y > 0.0f ? d.y : 0.0f;
    float s = dot(d, sun);
    float lobe = s > 0.0f ? powf(s, 12.0f) : 0.0f;
    vec3 c;
    if (d.y >= 0.0f) {
        c = v3(0.45f - 0.25f * up, 0.55f - 0.2f * up, 0.75f);
    } else {
        c = v3(0.12f, 0.10f, 0.08f);
    }
    c.x += 6.0f * lobe;
    c.y += 5.6f * lobe;
    c.z += 4.8f * lobe;
    return c;
}

/* SH of the sky with its sun at `sun` (channel-planar, 3 * bands² floats). */
static void project_sky(vec3 sun, uint32_t bands, float *coefficients)
{
    static float map[SKY_H][SKY_W][3];
    int row, column;
    for (row = 0; row < SKY_H; row++) {
        for (column = 0; column < SKY_W; column++) {
            /* The +Y-up equirect convention of antumbra_sh_project_equirect. */
            float theta = PI_F * ((float)row + 0.5f) / (float)SKY_H;
            float phi = 2.0f * PI_F * (((float)column + 0.5f) / (float)SKY_W - 0.5f);
            vec3 d = v3(sinf(theta) * cosf(phi), cosf(theta), sinf(theta) * sinf(phi));
            vec3 c = sky_radiance(d, sun);
            map[row][column][0] = c.x;
            map[row][column][1] = c.y;
            map[row][column][2] = c.z;
        }
    }
    check(antumbra_sh_project_equirect(&map[0][0][0], SKY_W, SKY_H, 0, bands, coefficients),
          "antumbra_sh_project_equirect");
}

/* Row-major rotation by `angle` about +Y. */
static void rotation_y(float angle, float r[9])
{
    float c = cosf(angle), s = sinf(angle);
    r[0] = c;     r[1] = 0.0f; r[2] = s;
    r[3] = 0.0f;  r[4] = 1.0f; r[5] = 0.0f;
    r[6] = -s;    r[7] = 0.0f; r[8] = c;
}

static vec3 rotate_y(vec3 d, float angle)
{
    float r[9];
    rotation_y(angle, r);
    return v3(r[0] * d.x + r[1] * d.y + r[2] * d.z, r[3] * d.x + r[4] * d.y + r[5] * d.z,
              r[6] * d.x + r[7] * d.y + r[8] * d.z);
}

/* Rotating the projected sky must equal projecting the rotated sky, up to the
 * quadrature and band-limiting error of the projection (a few 1e-3 of the sky's
 * energy at this map size). */
static void check_rotation(uint32_t bands, vec3 sun, const float *base)
{
    size_t n = 3 * (size_t)bands * bands, k;
    float *rotated = checked_malloc(n * sizeof(float));
    float *direct = checked_malloc(n * sizeof(float));
    float r[9];
    double diff = 0.0, norm = 0.0;
    float angle = 1.1f;
    rotation_y(angle, r);
    check(antumbra_sh_rotate(r, bands, base, 3, rotated), "antumbra_sh_rotate");
    project_sky(rotate_y(sun, angle), bands, direct);
    for (k = 0; k < n; k++) {
        diff += (double)(rotated[k] - direct[k]) * (double)(rotated[k] - direct[k]);
        norm += (double)direct[k] * (double)direct[k];
    }
    printf("SH rotation vs projecting the rotated sky: relative difference %.2e\n",
           sqrt(diff / norm));
    if (!(sqrt(diff / norm) < 2e-2)) {
        fail("rotated lighting differs from the rotated sky's projection by %.3e", sqrt(diff / norm));
    }
    /* In place, by the identity. */
    memcpy(rotated, base, n * sizeof(float));
    rotation_y(0.0f, r);
    check(antumbra_sh_rotate(r, bands, rotated, 3, rotated), "antumbra_sh_rotate (in place)");
    for (k = 0; k < n; k++) {
        if (fabsf(rotated[k] - base[k]) > 1e-5f * (1.0f + fabsf(base[k]))) {
            fail("the identity rotation changed coefficient %zu: %g -> %g", k, base[k], rotated[k]);
            break;
        }
    }
    free(rotated);
    free(direct);
}

/* ------------------------------------------------------------------------- */
/* Shading, checks, images                                                     */
/* ------------------------------------------------------------------------- */

typedef struct {
    antumbra_transfer *set;
    antumbra_transfer_info info;
    float *positions;
    float *normals;
    antumbra_transfer_material material;
    float *view_directions; /* orthographic: every vertex looks at the camera */
} relit;

static vec3 CAMERA_DIR; /* from the scene towards the camera, unit */

static void prepare(relit *r, antumbra_transfer *set)
{
    size_t n;
    size_t v;
    r->set = set;
    r->info = describe(set);
    n = r->info.vertex_count;
    r->positions = checked_malloc(3 * n * sizeof(float));
    r->normals = checked_malloc(3 * n * sizeof(float));
    r->view_directions = checked_malloc(3 * n * sizeof(float));
    check(antumbra_transfer_geometry(set, r->positions, r->normals, n), "antumbra_transfer_geometry");
    for (v = 0; v < n; v++) {
        r->view_directions[3 * v + 0] = CAMERA_DIR.x;
        r->view_directions[3 * v + 1] = CAMERA_DIR.y;
        r->view_directions[3 * v + 2] = CAMERA_DIR.z;
    }
    antumbra_transfer_material_init(&r->material);
    r->material.albedo[0] = 0.8f;
    r->material.albedo[1] = 0.7f;
    r->material.albedo[2] = 0.6f;
    /* Glossy SH and MRT sets hold only the glossy term: their baked lobe as it is. */
    r->material.specular[0] = r->material.specular[1] = r->material.specular[2] = 1.0f;
    r->material.view_directions = r->view_directions;
}

static void release(relit *r)
{
    antumbra_transfer_destroy(r->set);
    free(r->positions);
    free(r->normals);
    free(r->view_directions);
}

/* Shades `repeats` times, returns the fastest call's milliseconds (the least
 * disturbed by other processes on a shared machine). */
static double shade_timed(const relit *r, const float *lighting, uint32_t components, float *rgb,
                          int repeats)
{
    size_t count = 3 * (size_t)r->info.coeff_count;
    double best = HUGE_VAL;
    int i;
    for (i = 0; i < repeats; i++) {
        double start = now_ms(), ms;
        check(antumbra_transfer_shade(r->set, lighting, count, &r->material, components, rgb,
                                      r->info.vertex_count),
              "antumbra_transfer_shade");
        ms = now_ms() - start;
        best = ms < best ? ms : best;
    }
    return best;
}

static float check_colours(const char *what, int frame, const float *rgb, size_t vertices,
                           int non_negative)
{
    size_t k;
    float max = 0.0f;
    for (k = 0; k < 3 * vertices; k++) {
        if (!isfinite(rgb[k])) {
            fail("%s, frame %d: vertex %zu channel %zu is not finite", what, frame, k / 3, k % 3);
            return 0.0f;
        }
        if (rgb[k] > max) {
            max = rgb[k];
        }
    }
    if (non_negative) {
        for (k = 0; k < 3 * vertices; k++) {
            /* SH-limited lighting may ring slightly below zero; this sky does not. */
            if (rgb[k] < -1e-4f * max) {
                fail("%s, frame %d: vertex %zu channel %zu is negative (%g)", what, frame, k / 3,
                     k % 3, rgb[k]);
                break;
            }
        }
    }
    if (!(max > 0.0f)) {
        fail("%s, frame %d: every colour is zero", what, frame);
    }
    return max;
}

static double max_abs_diff(const float *a, const float *b, size_t n)
{
    double m = 0.0;
    size_t k;
    for (k = 0; k < n; k++) {
        double d = fabs((double)a[k] - (double)b[k]);
        if (d > m) {
            m = d;
        }
    }
    return m;
}

static double rel_rms_diff(const float *a, const float *b, size_t n)
{
    double e = 0.0, s = 0.0;
    size_t k;
    for (k = 0; k < n; k++) {
        e += ((double)a[k] - (double)b[k]) * ((double)a[k] - (double)b[k]);
        s += (double)b[k] * (double)b[k];
    }
    return s > 0.0 ? sqrt(e / s) : 0.0;
}

typedef struct {
    unsigned char rgb[IMAGE_H][IMAGE_W][3];
    float depth[IMAGE_H][IMAGE_W];
} image;

static unsigned char to_byte(float linear)
{
    float c = linear <= 0.0f ? 0.0f : linear / (1.0f + linear); /* Reinhard */
    c = powf(c, 1.0f / 2.2f);
    return (unsigned char)(c * 255.0f + 0.5f);
}

/* An orthographic splat along CAMERA_DIR: each vertex a small z-buffered square. */
static void splat(const float *positions, const float *rgb, size_t vertices, image *img)
{
    vec3 forward = v3(-CAMERA_DIR.x, -CAMERA_DIR.y, -CAMERA_DIR.z);
    vec3 right = v3(forward.z, 0.0f, -forward.x);
    vec3 up;
    float lr = sqrtf(dot(right, right)), lo[2] = {FLT_MAX, FLT_MAX}, hi[2] = {-FLT_MAX, -FLT_MAX};
    float scale;
    int radius;
    size_t v;
    int x, y;
    right = v3(right.x / lr, right.y / lr, right.z / lr);
    up = v3(right.y * forward.z - right.z * forward.y, right.z * forward.x - right.x * forward.z,
            right.x * forward.y - right.y * forward.x);
    for (v = 0; v < vertices; v++) {
        vec3 p = v3(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]);
        float u = dot(p, right), w = dot(p, up);
        lo[0] = u < lo[0] ? u : lo[0];
        hi[0] = u > hi[0] ? u : hi[0];
        lo[1] = w < lo[1] ? w : lo[1];
        hi[1] = w > hi[1] ? w : hi[1];
    }
    scale = 0.9f * fminf((float)IMAGE_W / fmaxf(hi[0] - lo[0], 1e-6f),
                         (float)IMAGE_H / fmaxf(hi[1] - lo[1], 1e-6f));
    radius = (int)(0.8f * sqrtf((float)(IMAGE_W * IMAGE_H) / (float)vertices)) + 1;
    for (y = 0; y < IMAGE_H; y++) {
        for (x = 0; x < IMAGE_W; x++) {
            img->rgb[y][x][0] = 20;
            img->rgb[y][x][1] = 22;
            img->rgb[y][x][2] = 28;
            img->depth[y][x] = FLT_MAX;
        }
    }
    for (v = 0; v < vertices; v++) {
        vec3 p = v3(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]);
        float cx = (float)IMAGE_W * 0.5f + (dot(p, right) - 0.5f * (lo[0] + hi[0])) * scale;
        float cy = (float)IMAGE_H * 0.5f - (dot(p, up) - 0.5f * (lo[1] + hi[1])) * scale;
        float depth = dot(p, forward);
        int px = (int)cx, py = (int)cy;
        for (y = py - radius; y <= py + radius; y++) {
            for (x = px - radius; x <= px + radius; x++) {
                if (x < 0 || y < 0 || x >= IMAGE_W || y >= IMAGE_H || depth >= img->depth[y][x]) {
                    continue;
                }
                img->depth[y][x] = depth;
                img->rgb[y][x][0] = to_byte(rgb[3 * v + 0]);
                img->rgb[y][x][1] = to_byte(rgb[3 * v + 1]);
                img->rgb[y][x][2] = to_byte(rgb[3 * v + 2]);
            }
        }
    }
}

static void write_ppm(const char *path, const image *img)
{
    FILE *f = fopen(path, "wb");
    if (!f || fprintf(f, "P6\n%d %d\n255\n", IMAGE_W, IMAGE_H) < 0 ||
        fwrite(img->rgb, 1, sizeof img->rgb, f) != sizeof img->rgb || fclose(f) != 0) {
        fprintf(stderr, "prt_relight: cannot write %s\n", path);
        exit(1);
    }
}

static void check_version(void)
{
    uint32_t v = antumbra_version();
    if (v != ANTUMBRA_VERSION) {
        fail("antumbra_version() is 0x%06x, the header says 0x%06x", (unsigned)v,
             (unsigned)ANTUMBRA_VERSION);
    }
    if (strcmp(antumbra_version_string(), ANTUMBRA_VERSION_STRING) != 0) {
        fail("antumbra_version_string() is %s, the header says %s", antumbra_version_string(),
             ANTUMBRA_VERSION_STRING);
    }
}

/* ------------------------------------------------------------------------- */
/* Main                                                                        */
/* ------------------------------------------------------------------------- */

typedef struct {
    int small;
    const char *out_prefix;
    const char *bake_file;
} arguments;

static arguments parse(int argc, char **argv)
{
    arguments a;
    int i;
    a.small = 0;
    a.out_prefix = "prt_relight";
    a.bake_file = NULL;
    for (i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--small") == 0) {
            a.small = 1;
        } else if (strcmp(argv[i], "-o") == 0 && i + 1 < argc) {
            a.out_prefix = argv[++i];
        } else if (argv[i][0] != '-' && !a.bake_file) {
            a.bake_file = argv[i];
        } else {
            fprintf(stderr, "usage: prt_relight [--small] [-o OUT_PREFIX] [BAKE_FILE]\n");
            exit(2);
        }
    }
    return a;
}

/* Bakes the built-in scene; returns the loaded-back diffuse and MRT sets. */
static void bake_builtin(const arguments *a, scene *s, antumbra_transfer **diffuse,
                         antumbra_transfer **mrt)
{
    antumbra_mesh_view view;
    antumbra_transfer_options options;
    antumbra_transfer *baked = NULL;
    progress_state progress = {0, 0, 0, 0};
    char path[1024];
    double start;

    build_scene(s, a->small ? 9 : 25, a->small ? 6 : 14, a->small ? 8 : 24);
    view.positions = s->positions;
    view.vertex_count = s->vertex_count;
    view.position_stride = 0;
    view.indices = s->indices;
    view.triangle_count = s->triangle_count;

    /* Diffuse PRT with one bounce, on this thread so progress arrives in order. */
    antumbra_transfer_options_init(&options);
    options.kind = ANTUMBRA_TRANSFER_KIND_DIFFUSE;
    options.bands = 4;
    options.rays = a->small ? 32 : 256;
    options.bounces = 1;
    options.albedo = 0.6f;
    options.parallel = 0;
    options.seed = 7;
    start = now_ms();
    check(antumbra_transfer_bake(&view, s->normals, &options, on_progress, &progress, &baked),
          "antumbra_transfer_bake (diffuse)");
    printf("baked diffuse PRT of %zu vertices, %u rays, 1 bounce in %.1f ms\n", s->vertex_count,
           options.rays, now_ms() - start);
    if (progress.out_of_order || progress.calls != 2 * s->vertex_count ||
        progress.total != 2 * s->vertex_count || progress.last_done != progress.total) {
        fail("progress: %zu calls, last %zu of %zu (expected %zu in order)", progress.calls,
             progress.last_done, progress.total, 2 * s->vertex_count);
    }
    snprintf(path, sizeof path, "%s-diffuse.antx", a->out_prefix);
    *diffuse = round_trip(baked, path);

    /* MRT with a Phong lobe, on the library's threads, normals computed. */
    antumbra_transfer_options_init(&options);
    options.kind = ANTUMBRA_TRANSFER_KIND_MRT;
    /* Small enough that compressing with every component (K = grid² bands², the
     * exactness check) stays quick: its cost grows as vertices · K². */
    options.bands = a->small ? 2 : 3;
    options.grid = a->small ? 3 : 4;
    options.rays = a->small ? 32 : 256;
    options.brdf = ANTUMBRA_TRANSFER_BRDF_PHONG;
    options.brdf_params[0] = 8.0f;
    options.seed = 7;
    baked = NULL;
    start = now_ms();
    check(antumbra_transfer_bake(&view, NULL, &options, NULL, NULL, &baked),
          "antumbra_transfer_bake (MRT)");
    printf("baked MRT (grid %u, %u bands, Phong 8, normals computed) of %zu vertices in %.1f ms\n", options.grid,
           options.bands, s->vertex_count, now_ms() - start);
    snprintf(path, sizeof path, "%s-mrt.antx", a->out_prefix);
    *mrt = round_trip(baked, path);
}

/* A reloaded copy must shade bit for bit like the set it was saved from. */
static void check_reload_shades_same(const relit *r, const float *lighting, float *rgb)
{
    size_t size = 0, n = 3 * (size_t)r->info.vertex_count;
    uint8_t *bytes = save_bytes(r->set, &size);
    antumbra_transfer *copy = NULL;
    float *other = checked_malloc(n * sizeof(float));
    check(antumbra_transfer_load(bytes, size, &copy), "antumbra_transfer_load");
    check(antumbra_transfer_shade(r->set, lighting, 3 * (size_t)r->info.coeff_count, &r->material,
                                  0, rgb, r->info.vertex_count),
          "antumbra_transfer_shade");
    check(antumbra_transfer_shade(copy, lighting, 3 * (size_t)r->info.coeff_count, &r->material, 0,
                                  other, r->info.vertex_count),
          "antumbra_transfer_shade (reloaded)");
    if (memcmp(rgb, other, n * sizeof(float)) != 0) {
        fail("%s: the reloaded set shades differently (max difference %g)",
             kind_name(r->info.kind), max_abs_diff(rgb, other, n));
    }
    antumbra_transfer_destroy(copy);
    free(other);
    free(bytes);
}

/* PCA of an MRT set: all components must reproduce it; error vs K, timed. */
static void check_pca(const relit *mrt, const float *lighting, int repeats)
{
    uint32_t max_k = mrt->info.grid * mrt->info.grid * mrt->info.coeff_count;
    uint32_t ks[4];
    size_t n = 3 * (size_t)mrt->info.vertex_count;
    float *dense = checked_malloc(n * sizeof(float));
    float *compressed = checked_malloc(n * sizeof(float));
    double dense_ms, previous = HUGE_VAL, first = 0.0;
    antumbra_transfer *pca = NULL;
    relit view = *mrt;
    int i;
    if (max_k > mrt->info.vertex_count) {
        max_k = mrt->info.vertex_count;
    }
    ks[0] = 1;
    ks[1] = 4;
    ks[2] = 16;
    ks[3] = max_k;
    dense_ms = shade_timed(mrt, lighting, 0, dense, repeats);
    check(antumbra_transfer_compress(mrt->set, max_k, &pca), "antumbra_transfer_compress");
    view.set = pca;
    view.info = describe(pca);
    print_info("PCA", &view.info);
    for (i = 0; i < 4; i++) {
        double ms = shade_timed(&view, lighting, ks[i], compressed, repeats);
        double err = rel_rms_diff(compressed, dense, n);
        double bytes = 4.0 * ((double)mrt->info.grid * mrt->info.grid * mrt->info.coeff_count *
                                  (ks[i] + 1) + (double)mrt->info.vertex_count * ks[i]);
        printf("  K = %3u: relative RMS error %.2e, %.2f ms (%.1f ns/vertex; dense %.1f), "
               "%.0f B/vertex\n",
               ks[i], err, ms, 1e6 * ms / mrt->info.vertex_count,
               1e6 * dense_ms / mrt->info.vertex_count, bytes / mrt->info.vertex_count);
        check_colours("MRT from PCA", 0, compressed, mrt->info.vertex_count, 0);
        /* PCA minimises the matrices' error, not the colours', so the colour error
         * need not fall at every step; it must end below where it started. */
        if (i == 0) {
            first = err;
        }
        previous = err;
    }
    /* All components: float precision (a few ulps of the largest colour per
     * multiply-add chain). */
    if (!(previous < 1e-4)) {
        fail("PCA with all %u components is %.3e from uncompressed MRT", max_k, previous);
    }
    if (max_k > 1 && !(previous < first)) {
        fail("PCA with %u components is no closer than with 1 (%.3e vs %.3e)", max_k, previous,
             first);
    }
    antumbra_transfer_destroy(pca);
    free(dense);
    free(compressed);
}

int main(int argc, char **argv)
{
    arguments a = parse(argc, argv);
    scene s;
    antumbra_transfer *first = NULL, *second = NULL;
    relit sets[2];
    int set_count = 0, frames = a.small ? 2 : 4, repeats = a.small ? 1 : 20;
    uint32_t bands;
    float *base, *lighting, *rgb, *previous_rgb;
    vec3 sun = v3(0.45f, 0.85f, 0.3f);
    float sun_len = sqrtf(dot(sun, sun));
    static image img;
    int f, i;

    check_version();
    sun = v3(sun.x / sun_len, sun.y / sun_len, sun.z / sun_len);
    /* Looking down from the side the shadow falls towards, so it is not hidden
     * behind the sphere in the images. */
    CAMERA_DIR = v3(-0.45f, 1.0f, -0.3f);
    {
        float l = sqrtf(dot(CAMERA_DIR, CAMERA_DIR));
        CAMERA_DIR = v3(CAMERA_DIR.x / l, CAMERA_DIR.y / l, CAMERA_DIR.z / l);
    }
    memset(&s, 0, sizeof s);

    if (a.bake_file) {
        size_t size = 0;
        uint8_t *bytes = read_file(a.bake_file, &size);
        check(antumbra_transfer_load(bytes, size, &first), "antumbra_transfer_load");
        free(bytes);
        printf("loaded %s (%zu bytes)\n", a.bake_file, size);
    } else {
        bake_builtin(&a, &s, &first, &second);
    }
    prepare(&sets[set_count++], first);
    if (second) {
        prepare(&sets[set_count++], second);
    }
    bands = 0;
    for (i = 0; i < set_count; i++) {
        print_info(i == 0 ? "set 1" : "set 2", &sets[i].info);
        if (sets[i].info.bands > bands) {
            bands = sets[i].info.bands;
        }
    }
    if (!a.bake_file) {
        /* The built-in scene: geometry must come back as baked. */
        if (sets[0].info.vertex_count != s.vertex_count ||
            memcmp(sets[0].positions, s.positions, 3 * s.vertex_count * sizeof(float)) != 0 ||
            memcmp(sets[0].normals, s.normals, 3 * s.vertex_count * sizeof(float)) != 0) {
            fail("antumbra_transfer_geometry does not return the baked positions and normals");
        }
    }

    base = checked_malloc(3 * (size_t)bands * bands * sizeof(float));
    lighting = checked_malloc(3 * (size_t)bands * bands * sizeof(float));
    project_sky(sun, bands, base);
    check_rotation(bands, sun, base);

    for (i = 0; i < set_count; i++) {
        relit *r = &sets[i];
        size_t n = 3 * (size_t)r->info.vertex_count;
        uint32_t b = r->info.bands;
        int non_negative = r->info.kind == ANTUMBRA_TRANSFER_KIND_DIFFUSE;
        float *rotated = checked_malloc(3 * (size_t)b * b * sizeof(float));
        rgb = checked_malloc(n * sizeof(float));
        previous_rgb = checked_malloc(n * sizeof(float));
        /* A set with fewer bands than the largest takes the leading bands of each
         * channel (the projection of the same sky at its own band count). */
        project_sky(sun, b, lighting);
        check_reload_shades_same(r, lighting, rgb);
        for (f = 0; f < frames; f++) {
            float rotation[9];
            float angle = 2.0f * PI_F * (float)f / (float)frames;
            char path[1024];
            double ms, max;
            rotation_y(angle, rotation);
            check(antumbra_sh_rotate(rotation, b, lighting, 3, rotated), "antumbra_sh_rotate");
            ms = shade_timed(r, rotated, 0, rgb, repeats);
            max = check_colours(kind_name(r->info.kind), f, rgb, r->info.vertex_count, non_negative);
            printf("%s frame %d (sky turned %3.0f deg): %.3f ms, %.1f ns/vertex, max %.3f\n",
                   kind_name(r->info.kind), f, (double)(angle * 180.0f / PI_F), ms,
                   1e6 * ms / r->info.vertex_count, max);
            if (f > 0 && !(max_abs_diff(rgb, previous_rgb, n) > 1e-3 * max)) {
                fail("%s: frame %d looks like frame %d: the lighting did not move",
                     kind_name(r->info.kind), f, f - 1);
            }
            if (f == 0 && !a.bake_file && r->info.kind == ANTUMBRA_TRANSFER_KIND_DIFFUSE) {
                /* The ground vertex where the sphere's centre casts its shadow vs a
                 * ground corner in the open. */
                float t = SPHERE_Y / sun.y, sx = -sun.x * t, sz = -sun.z * t;
                size_t side = s.ground_side, corner = side - 1;
                size_t ix = (size_t)((sx + 2.0f) / 4.0f * (float)(side - 1) + 0.5f);
                size_t iz = (size_t)((sz + 2.0f) / 4.0f * (float)(side - 1) + 0.5f);
                size_t shadowed = iz * side + ix;
                float ls = rgb[3 * shadowed + 1], lo = rgb[3 * corner + 1];
                printf("  ground in the sphere's shadow %.3f, open ground %.3f\n", ls, lo);
                if (!(ls < 0.8f * lo)) {
                    fail("the sphere casts no shadow: in it %.3f, open ground %.3f", ls, lo);
                }
            }
            memcpy(previous_rgb, rgb, n * sizeof(float));
            splat(r->positions, rgb, r->info.vertex_count, &img);
            snprintf(path, sizeof path, "%s-%s-%d.ppm", a.out_prefix,
                     r->info.kind == ANTUMBRA_TRANSFER_KIND_DIFFUSE ? "diffuse"
                     : r->info.kind == ANTUMBRA_TRANSFER_KIND_MRT ? "mrt" : "glossy",
                     f);
            write_ppm(path, &img);
        }
        if (r->info.kind == ANTUMBRA_TRANSFER_KIND_MRT && r->info.components == 0) {
            check_pca(r, lighting, repeats);
        }
        free(rotated);
        free(rgb);
        free(previous_rgb);
    }
    printf("images: %s-*.ppm\n", a.out_prefix);

    for (i = 0; i < set_count; i++) {
        release(&sets[i]);
    }
    free(base);
    free(lighting);
    if (!a.bake_file) {
        free_scene(&s);
    }
    if (failures) {
        fprintf(stderr, "prt_relight: %d check(s) failed\n", failures);
        return 1;
    }
    printf("prt_relight: all checks passed\n");
    return 0;
}

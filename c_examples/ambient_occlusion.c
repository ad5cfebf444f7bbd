/*
 * ambient_occlusion.c: ray-cast ambient occlusion of a small procedural scene
 * through the Antumbra C API, written as a binary PGM image.
 *
 * A ground plane (a grid of quads), two boxes and a torus are generated here as
 * interleaved position + normal vertices (24-byte stride, so the library has to
 * honour position_stride). A pinhole camera casts one primary ray per pixel with
 * antumbra_scene_intersect; each hit then casts AO_RAYS cosine-distributed rays
 * over the hemisphere of its interpolated normal with antumbra_scene_occluded,
 * one image row per batch. The pixel is the unoccluded fraction. The scene is
 * created with the objects lifted (an earlier frame) and moved into place
 * with antumbra_scene_refit.
 *
 * Usage: ambient_occlusion [out.pgm]   (default ao.pgm)
 * Exit status: 0 on success, 1 on any unexpected result or implausible image.
 */
#include "antumbra.h"

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define WIDTH 96
#define HEIGHT 64
/* AO rays per pixel, stratified on an AO_STRATA x AO_STRATA grid. */
#define AO_STRATA 4
#define AO_RAYS (AO_STRATA * AO_STRATA)
/* Occluders farther than this do not darken a point (scene units). */
#define AO_RADIUS 2.0f
/* AO rays start this far off the surface, so they cannot hit their own triangle. */
#define SURFACE_OFFSET 1e-3f
#define PI_F 3.14159265358979323846f

/* ------------------------------------------------------------------------- */
/* Failure reporting                                                          */
/* ------------------------------------------------------------------------- */

static void fail(const char *format, ...)
{
    va_list args;
    va_start(args, format);
    fputs("ambient_occlusion: ", stderr);
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
}

static void *checked_malloc(size_t size)
{
    void *memory = malloc(size);
    if (memory == NULL) {
        fail("out of memory (%lu bytes)", (unsigned long)size);
    }
    return memory;
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

/* ------------------------------------------------------------------------- */
/* Procedural scene                                                           */
/* ------------------------------------------------------------------------- */

/* One interleaved vertex as an engine would store it: the library reads only the
 * position, the normal is ours for shading. */
typedef struct vertex {
    float position[3];
    float normal[3];
} vertex;

typedef struct mesh {
    vertex *vertices;
    size_t vertex_count, vertex_capacity;
    uint32_t *indices;
    size_t triangle_count, triangle_capacity;
} mesh;

static uint32_t add_vertex(mesh *m, vec3 p, vec3 n)
{
    vertex *v;
    if (m->vertex_count == m->vertex_capacity) {
        m->vertex_capacity = m->vertex_capacity ? 2 * m->vertex_capacity : 256;
        m->vertices = realloc(m->vertices, m->vertex_capacity * sizeof *m->vertices);
        if (m->vertices == NULL) {
            fail("out of memory for vertices");
        }
    }
    v = &m->vertices[m->vertex_count];
    v->position[0] = p.x;
    v->position[1] = p.y;
    v->position[2] = p.z;
    v->normal[0] = n.x;
    v->normal[1] = n.y;
    v->normal[2] = n.z;
    return (uint32_t)m->vertex_count++;
}

static void add_triangle(mesh *m, uint32_t a, uint32_t b, uint32_t c)
{
    if (m->triangle_count == m->triangle_capacity) {
        m->triangle_capacity = m->triangle_capacity ? 2 * m->triangle_capacity : 256;
        m->indices = realloc(m->indices, 3 * m->triangle_capacity * sizeof *m->indices);
        if (m->indices == NULL) {
            fail("out of memory for indices");
        }
    }
    m->indices[3 * m->triangle_count + 0] = a;
    m->indices[3 * m->triangle_count + 1] = b;
    m->indices[3 * m->triangle_count + 2] = c;
    m->triangle_count++;
}

/* A quad p0 p1 p2 p3 (counter-clockwise seen from the side n points to). */
static void add_quad(mesh *m, vec3 p0, vec3 p1, vec3 p2, vec3 p3, vec3 n)
{
    const uint32_t a = add_vertex(m, p0, n), b = add_vertex(m, p1, n);
    const uint32_t c = add_vertex(m, p2, n), d = add_vertex(m, p3, n);
    add_triangle(m, a, b, c);
    add_triangle(m, a, c, d);
}

/* The ground y = 0 over [-half, half]^2 as cells x cells quads with shared
 * vertices, so the BVH sees many small triangles and shared edges (which the
 * watertight test must not let rays slip through). */
static void add_ground(mesh *m, float half, int cells)
{
    const uint32_t first = (uint32_t)m->vertex_count;
    const vec3 up = v3(0.0f, 1.0f, 0.0f);
    int i, j;
    for (j = 0; j <= cells; ++j) {
        for (i = 0; i <= cells; ++i) {
            const float x = -half + 2.0f * half * (float)i / (float)cells;
            const float z = -half + 2.0f * half * (float)j / (float)cells;
            add_vertex(m, v3(x, 0.0f, z), up);
        }
    }
    for (j = 0; j < cells; ++j) {
        for (i = 0; i < cells; ++i) {
            const uint32_t row = (uint32_t)(cells + 1);
            const uint32_t a = first + (uint32_t)j * row + (uint32_t)i;
            add_triangle(m, a, a + row, a + row + 1);
            add_triangle(m, a, a + row + 1, a + 1);
        }
    }
}

/* An axis-aligned box standing on the ground, without its bottom face (it would
 * coincide with the ground and is never visible). Flat normals: every face has
 * its own vertices. */
static void add_box(mesh *m, vec3 lo, vec3 hi)
{
    add_quad(m, v3(lo.x, hi.y, lo.z), v3(lo.x, hi.y, hi.z), v3(hi.x, hi.y, hi.z), v3(hi.x, hi.y, lo.z),
             v3(0, 1, 0));
    add_quad(m, v3(lo.x, lo.y, hi.z), v3(hi.x, lo.y, hi.z), v3(hi.x, hi.y, hi.z), v3(lo.x, hi.y, hi.z),
             v3(0, 0, 1));
    add_quad(m, v3(hi.x, lo.y, lo.z), v3(lo.x, lo.y, lo.z), v3(lo.x, hi.y, lo.z), v3(hi.x, hi.y, lo.z),
             v3(0, 0, -1));
    add_quad(m, v3(hi.x, lo.y, hi.z), v3(hi.x, lo.y, lo.z), v3(hi.x, hi.y, lo.z), v3(hi.x, hi.y, hi.z),
             v3(1, 0, 0));
    add_quad(m, v3(lo.x, lo.y, lo.z), v3(lo.x, lo.y, hi.z), v3(lo.x, hi.y, hi.z), v3(lo.x, hi.y, lo.z),
             v3(-1, 0, 0));
}

/* A torus around the vertical axis through center, with smooth normals. */
static void add_torus(mesh *m, vec3 center, float major, float minor, int rings, int sides)
{
    const uint32_t first = (uint32_t)m->vertex_count;
    int i, j;
    for (i = 0; i < rings; ++i) {
        const float phi = 2.0f * PI_F * (float)i / (float)rings;
        const vec3 radial = v3(cosf(phi), 0.0f, sinf(phi));
        for (j = 0; j < sides; ++j) {
            const float theta = 2.0f * PI_F * (float)j / (float)sides;
            const vec3 n = add(scale(radial, cosf(theta)), v3(0.0f, sinf(theta), 0.0f));
            add_vertex(m, add(center, add(scale(radial, major), scale(n, minor))), n);
        }
    }
    for (i = 0; i < rings; ++i) {
        for (j = 0; j < sides; ++j) {
            const uint32_t i1 = (uint32_t)((i + 1) % rings), j1 = (uint32_t)((j + 1) % sides);
            const uint32_t a = first + (uint32_t)(i * sides + j);
            const uint32_t b = first + i1 * (uint32_t)sides + (uint32_t)j;
            const uint32_t c = first + i1 * (uint32_t)sides + j1;
            const uint32_t d = first + (uint32_t)(i * sides) + j1;
            add_triangle(m, a, b, c);
            add_triangle(m, a, c, d);
        }
    }
}

static vec3 vertex_position(const mesh *m, uint32_t index)
{
    const float *p = m->vertices[index].position;
    return v3(p[0], p[1], p[2]);
}

static vec3 vertex_normal(const mesh *m, uint32_t index)
{
    const float *n = m->vertices[index].normal;
    return v3(n[0], n[1], n[2]);
}

/* ------------------------------------------------------------------------- */
/* Sampling                                                                   */
/* ------------------------------------------------------------------------- */

/* PCG32 (O'Neill 2014): small, deterministic on every platform, and seeded per
 * pixel so an image does not depend on batch sizes or order. */
typedef struct rng {
    uint64_t state;
} rng;

static uint32_t rng_next(rng *r)
{
    const uint64_t old = r->state;
    uint32_t xorshifted, rot;
    r->state = old * 6364136223846793005ULL + 1442695040888963407ULL;
    xorshifted = (uint32_t)(((old >> 18) ^ old) >> 27);
    rot = (uint32_t)(old >> 59);
    return (xorshifted >> rot) | (xorshifted << ((32u - rot) & 31u));
}

static rng rng_for_pixel(int x, int y)
{
    rng r;
    r.state = 0x853c49e6748fea9bULL ^ ((uint64_t)(uint32_t)y << 32 | (uint32_t)x);
    (void)rng_next(&r);
    (void)rng_next(&r);
    return r;
}

/* Uniform in [0, 1): the top 24 bits, exactly representable as a float. */
static float rng_float(rng *r) { return (float)(rng_next(r) >> 8) * (1.0f / 16777216.0f); }

/* ------------------------------------------------------------------------- */
/* Camera                                                                     */
/* ------------------------------------------------------------------------- */

typedef struct camera {
    vec3 eye, forward, right, up;
    float tan_half_fov, aspect;
} camera;

static camera look_at(vec3 eye, vec3 target, float vertical_fov_degrees)
{
    camera c;
    c.eye = eye;
    c.forward = normalize(sub(target, eye));
    c.right = normalize(cross(c.forward, v3(0.0f, 1.0f, 0.0f)));
    c.up = cross(c.right, c.forward);
    c.tan_half_fov = tanf(0.5f * vertical_fov_degrees * PI_F / 180.0f);
    c.aspect = (float)WIDTH / (float)HEIGHT;
    return c;
}

/* Direction through the centre of pixel (x, y). Deliberately not normalised: the
 * library measures t in units of the direction's length, and we rely on that. */
static vec3 camera_ray(const camera *c, int x, int y)
{
    const float sx = (2.0f * ((float)x + 0.5f) / (float)WIDTH - 1.0f) * c->tan_half_fov * c->aspect;
    const float sy = (1.0f - 2.0f * ((float)y + 0.5f) / (float)HEIGHT) * c->tan_half_fov;
    return add(c->forward, add(scale(c->right, sx), scale(c->up, sy)));
}

/* The pixel a world point projects to, or 0 when it is off screen. */
static int camera_project(const camera *c, vec3 p, int *x, int *y)
{
    const vec3 d = sub(p, c->eye);
    const float depth = dot(d, c->forward);
    float sx, sy;
    if (depth <= 0.0f) {
        return 0;
    }
    sx = dot(d, c->right) / depth / (c->tan_half_fov * c->aspect);
    sy = dot(d, c->up) / depth / c->tan_half_fov;
    *x = (int)floorf((sx + 1.0f) * 0.5f * (float)WIDTH);
    *y = (int)floorf((1.0f - sy) * 0.5f * (float)HEIGHT);
    return *x >= 0 && *x < WIDTH && *y >= 0 && *y < HEIGHT;
}

/* ------------------------------------------------------------------------- */
/* Rendering                                                                  */
/* ------------------------------------------------------------------------- */

typedef struct image {
    float ao[WIDTH * HEIGHT];      /* unoccluded fraction, or -1 for sky */
    uint32_t triangle[WIDTH * HEIGHT]; /* primary hit, ANTUMBRA_INVALID_INDEX for sky */
    vec3 point[WIDTH * HEIGHT];    /* primary hit point */
} image;

/* Per-row scratch arrays, in the layout the batch calls take. */
typedef struct row_batch {
    float origins[WIDTH * 3], directions[WIDTH * 3], t_max[WIDTH];
    float bounded_t_max[WIDTH];
    antumbra_hit hits[WIDTH];
    uint8_t before_hit[WIDTH], past_hit[WIDTH];
    float ao_origins[WIDTH * AO_RAYS * 3], ao_directions[WIDTH * AO_RAYS * 3], ao_t_max[WIDTH * AO_RAYS];
    uint8_t ao_occluded[WIDTH * AO_RAYS];
    int ao_pixel[WIDTH];
} row_batch;

static void set3(float *out, vec3 v)
{
    out[0] = v.x;
    out[1] = v.y;
    out[2] = v.z;
}

/* Checks one primary-ray answer against the documented hit/miss conventions and
 * against the geometry: the barycentric point must be where the ray says it is. */
static void check_hit(const mesh *m, const antumbra_hit *hit, vec3 origin, vec3 direction, int x, int y)
{
    vec3 p0, p1, p2, from_barycentrics, from_ray;
    float w;
    if (hit->triangle == ANTUMBRA_INVALID_INDEX) {
        if (!(isinf(hit->distance) && hit->distance > 0.0f) || hit->u != 0.0f || hit->v != 0.0f) {
            fail("pixel (%d, %d): a miss must be (+inf, INVALID_INDEX, 0, 0), got (%g, %g, %g)", x, y,
                 (double)hit->distance, (double)hit->u, (double)hit->v);
        }
        return;
    }
    if (hit->triangle >= m->triangle_count || !(hit->distance > 0.0f) || !isfinite(hit->distance)) {
        fail("pixel (%d, %d): bad hit triangle %u at t = %g", x, y, hit->triangle, (double)hit->distance);
    }
    w = 1.0f - hit->u - hit->v;
    if (hit->u < -1e-5f || hit->v < -1e-5f || w < -1e-5f) {
        fail("pixel (%d, %d): barycentrics (%g, %g) outside the triangle", x, y, (double)hit->u, (double)hit->v);
    }
    p0 = vertex_position(m, m->indices[3 * hit->triangle + 0]);
    p1 = vertex_position(m, m->indices[3 * hit->triangle + 1]);
    p2 = vertex_position(m, m->indices[3 * hit->triangle + 2]);
    from_barycentrics = add(add(scale(p0, w), scale(p1, hit->u)), scale(p2, hit->v));
    from_ray = add(origin, scale(direction, hit->distance));
    if (length(sub(from_barycentrics, from_ray)) > 1e-3f) {
        fail("pixel (%d, %d): hit point from barycentrics (%g, %g, %g) is not on the ray (%g, %g, %g)", x, y,
             (double)from_barycentrics.x, (double)from_barycentrics.y, (double)from_barycentrics.z,
             (double)from_ray.x, (double)from_ray.y, (double)from_ray.z);
    }
}

static void render_row(const antumbra_scene *scene, const mesh *m, const camera *cam, int y, row_batch *b,
                       image *img)
{
    int x, k, ao_pixels = 0;
    size_t ao_count = 0;

    for (x = 0; x < WIDTH; ++x) {
        set3(&b->origins[3 * x], cam->eye);
        set3(&b->directions[3 * x], camera_ray(cam, x, y));
        b->t_max[x] = INFINITY;
    }
    check(antumbra_scene_intersect(scene, b->origins, b->directions, b->t_max, WIDTH, b->hits),
          "antumbra_scene_intersect (primary rays)");

    /* The closest hit and any-hit queries must agree: nothing is hit before the
     * closest hit, and the closest triangle is hit just past it. */
    for (x = 0; x < WIDTH; ++x) {
        const float t = b->hits[x].distance;
        b->t_max[x] = isinf(t) ? INFINITY : t * 0.999f;
        b->bounded_t_max[x] = isinf(t) ? INFINITY : t * 1.001f;
    }
    check(antumbra_scene_occluded(scene, b->origins, b->directions, b->t_max, WIDTH, b->before_hit),
          "antumbra_scene_occluded (before the closest hit)");
    check(antumbra_scene_occluded(scene, b->origins, b->directions, b->bounded_t_max, WIDTH, b->past_hit),
          "antumbra_scene_occluded (past the closest hit)");

    for (x = 0; x < WIDTH; ++x) {
        const antumbra_hit *hit = &b->hits[x];
        const int pixel = y * WIDTH + x;
        const vec3 origin = cam->eye, direction = camera_ray(cam, x, y);
        const int is_hit = hit->triangle != ANTUMBRA_INVALID_INDEX;
        vec3 p0, p1, p2, geometric, shading, point, start;
        float n[3], tangent[3], bitangent[3];
        rng r;
        int i, j;

        check_hit(m, hit, origin, direction, x, y);
        if (b->before_hit[x] != 0 || b->past_hit[x] != (uint8_t)is_hit) {
            fail("pixel (%d, %d): occluded() disagrees with intersect(): before %u past %u hit %d", x, y,
                 b->before_hit[x], b->past_hit[x], is_hit);
        }
        img->triangle[pixel] = hit->triangle;
        if (!is_hit) {
            img->ao[pixel] = -1.0f;
            continue;
        }

        /* Triangles are two-sided: face the geometric normal towards the camera,
         * and the interpolated shading normal to the same side. */
        p0 = vertex_position(m, m->indices[3 * hit->triangle + 0]);
        p1 = vertex_position(m, m->indices[3 * hit->triangle + 1]);
        p2 = vertex_position(m, m->indices[3 * hit->triangle + 2]);
        geometric = normalize(cross(sub(p1, p0), sub(p2, p0)));
        if (dot(geometric, direction) > 0.0f) {
            geometric = scale(geometric, -1.0f);
        }
        shading = add(add(scale(vertex_normal(m, m->indices[3 * hit->triangle + 0]), 1.0f - hit->u - hit->v),
                          scale(vertex_normal(m, m->indices[3 * hit->triangle + 1]), hit->u)),
                      scale(vertex_normal(m, m->indices[3 * hit->triangle + 2]), hit->v));
        shading = normalize(shading);
        if (dot(shading, geometric) < 0.0f) {
            shading = scale(shading, -1.0f);
        }

        /* Antumbra's own frame, so these directions are the ones its hemisphere
         * algorithms would use. It is a void function: success is an empty
         * last-error message. */
        set3(n, shading);
        antumbra_frame_from_normal(n, tangent, bitangent);
        if (antumbra_last_error_message()[0] != '\0') {
            fail("antumbra_frame_from_normal failed: %s", antumbra_last_error_message());
        }

        point = add(origin, scale(direction, hit->distance));
        img->point[pixel] = point;
        start = add(point, scale(geometric, SURFACE_OFFSET));
        r = rng_for_pixel(x, y);
        for (j = 0; j < AO_STRATA; ++j) {
            for (i = 0; i < AO_STRATA; ++i) {
                /* Cosine-weighted (Malley): uniform on the disk, lifted to the
                 * hemisphere. One jittered sample per stratum. */
                const float u1 = ((float)j + rng_float(&r)) / (float)AO_STRATA;
                const float u2 = ((float)i + rng_float(&r)) / (float)AO_STRATA;
                const float radius = sqrtf(u1), phi = 2.0f * PI_F * u2;
                const float lx = radius * cosf(phi), ly = radius * sinf(phi), lz = sqrtf(1.0f - u1);
                const vec3 world = v3(lx * tangent[0] + ly * bitangent[0] + lz * n[0],
                                      lx * tangent[1] + ly * bitangent[1] + lz * n[1],
                                      lx * tangent[2] + ly * bitangent[2] + lz * n[2]);
                set3(&b->ao_origins[3 * ao_count], start);
                set3(&b->ao_directions[3 * ao_count], world);
                b->ao_t_max[ao_count] = AO_RADIUS;
                ++ao_count;
            }
        }
        b->ao_pixel[ao_pixels++] = pixel;
    }

    check(antumbra_scene_occluded(scene, b->ao_origins, b->ao_directions, b->ao_t_max, ao_count, b->ao_occluded),
          "antumbra_scene_occluded (AO rays)");
    for (k = 0; k < ao_pixels; ++k) {
        int i, blocked = 0;
        for (i = 0; i < AO_RAYS; ++i) {
            const uint8_t flag = b->ao_occluded[k * AO_RAYS + i];
            if (flag > 1) {
                fail("antumbra_scene_occluded wrote %u, not 0 or 1", flag);
            }
            blocked += flag;
        }
        img->ao[b->ao_pixel[k]] = 1.0f - (float)blocked / (float)AO_RAYS;
    }
}

static void write_pgm(const char *path, const image *img)
{
    unsigned char pixels[WIDTH * HEIGHT];
    FILE *file;
    int i;
    for (i = 0; i < WIDTH * HEIGHT; ++i) {
        /* Sky mid grey, surfaces their AO with a display gamma of 2.2. */
        const float value = img->ao[i] < 0.0f ? 0.5f : powf(img->ao[i], 1.0f / 2.2f);
        pixels[i] = (unsigned char)(value * 255.0f + 0.5f);
    }
    file = fopen(path, "wb");
    if (file == NULL) {
        fail("cannot open %s for writing", path);
    }
    if (fprintf(file, "P5\n%d %d\n255\n", WIDTH, HEIGHT) < 0 ||
        fwrite(pixels, 1, sizeof pixels, file) != sizeof pixels) {
        fclose(file);
        fail("cannot write %s", path);
    }
    if (fclose(file) != 0) {
        fail("cannot finish writing %s", path);
    }
}

/* AO of the ground at p, by projecting p into the image and checking the pixel
 * really sees the ground there (and not some object in front of it). */
static float ground_ao_at(const camera *cam, const image *img, size_t ground_triangles, vec3 p, const char *what)
{
    int x, y, pixel;
    if (!camera_project(cam, p, &x, &y)) {
        fail("%s (%g, %g, %g) is off screen", what, (double)p.x, (double)p.y, (double)p.z);
    }
    pixel = y * WIDTH + x;
    if (img->triangle[pixel] >= ground_triangles || length(sub(img->point[pixel], p)) > 0.1f) {
        fail("%s: pixel (%d, %d) does not see the ground at (%g, %g, %g)", what, x, y, (double)p.x, (double)p.y,
             (double)p.z);
    }
    return img->ao[pixel];
}

int main(int argc, char **argv)
{
    const char *path = argc > 1 ? argv[1] : "ao.pgm";
    char expected_version[32];
    mesh m = {NULL, 0, 0, NULL, 0, 0};
    antumbra_mesh_view view;
    antumbra_scene *scene = NULL;
    size_t ground_triangles, ground_vertices;
    camera cam;
    image *img;
    row_batch *batch;
    float ao_open, ao_corner;
    int y, i, covered = 0;

    /* A header from one build and a library from another would disagree on
     * layouts; refuse to run rather than render garbage. */
    if (antumbra_version() != ANTUMBRA_VERSION) {
        fail("library version 0x%06lx does not match header 0x%06lx", (unsigned long)antumbra_version(),
             (unsigned long)ANTUMBRA_VERSION);
    }
    if (strcmp(antumbra_version_string(), ANTUMBRA_VERSION_STRING) != 0) {
        fail("library version \"%s\" does not match header \"%s\"", antumbra_version_string(),
             ANTUMBRA_VERSION_STRING);
    }
    sprintf(expected_version, "%d.%d.%d", ANTUMBRA_VERSION_MAJOR, ANTUMBRA_VERSION_MINOR, ANTUMBRA_VERSION_PATCH);
    if (strcmp(expected_version, ANTUMBRA_VERSION_STRING) != 0) {
        fail("header: ANTUMBRA_VERSION_STRING \"%s\" is not %s", ANTUMBRA_VERSION_STRING, expected_version);
    }

    add_ground(&m, 5.0f, 24);
    ground_triangles = m.triangle_count;
    ground_vertices = m.vertex_count;
    add_box(&m, v3(-1.8f, 0.0f, -0.6f), v3(-0.6f, 1.2f, 0.6f));
    add_box(&m, v3(1.5f, 0.0f, -1.3f), v3(2.1f, 1.8f, -0.7f));
    add_torus(&m, v3(0.9f, 0.25f, 1.2f), 0.6f, 0.25f, 32, 12);

    view.positions = m.vertices[0].position;
    view.vertex_count = m.vertex_count;
    view.position_stride = sizeof(vertex);
    view.indices = m.indices;
    view.triangle_count = m.triangle_count;
    /* An earlier frame of an animation: the objects 3 units up. The scene is
     * made there, then refitted to where they land, as an engine moves a
     * scene's triangles between frames without building it again. The checks
     * below (ground next to the box half occluded) hold only if the refit
     * moved them. */
    for (i = (int)ground_vertices; i < (int)m.vertex_count; ++i) {
        m.vertices[i].position[1] += 3.0f;
    }
    check(antumbra_scene_create(&view, &scene), "antumbra_scene_create");
    if (scene == NULL) {
        fail("antumbra_scene_create returned OK and a NULL scene");
    }
    if (antumbra_last_error_message()[0] != '\0') {
        fail("the last error message after a success is \"%s\", not empty", antumbra_last_error_message());
    }
    for (i = (int)ground_vertices; i < (int)m.vertex_count; ++i) {
        m.vertices[i].position[1] -= 3.0f;
    }
    check(antumbra_scene_refit(scene, &view), "antumbra_scene_refit");

    img = checked_malloc(sizeof *img);
    batch = checked_malloc(sizeof *batch);
    cam = look_at(v3(0.0f, 3.0f, 6.5f), v3(0.0f, 0.3f, 0.0f), 50.0f);
    for (y = 0; y < HEIGHT; ++y) {
        render_row(scene, &m, &cam, y, batch, img);
    }
    antumbra_scene_destroy(scene);

    write_pgm(path, img);

    /* Plausibility: the camera looks down at the scene, so most pixels see
     * something; open ground far from every object is fully lit; ground right
     * against the box's front face loses roughly the half of its hemisphere that
     * faces the box. */
    for (i = 0; i < WIDTH * HEIGHT; ++i) {
        covered += img->ao[i] >= 0.0f;
    }
    ao_open = ground_ao_at(&cam, img, ground_triangles, v3(-3.0f, 0.0f, 2.8f), "open ground");
    ao_corner = ground_ao_at(&cam, img, ground_triangles, v3(-1.2f, 0.0f, 0.65f), "ground next to the box");
    printf("ambient_occlusion: antumbra %s, %lu triangles, %dx%d pixels, %d AO rays each\n",
           antumbra_version_string(), (unsigned long)m.triangle_count, WIDTH, HEIGHT, AO_RAYS);
    printf("ambient_occlusion: %d%% of pixels hit; AO of open ground %.3f, next to the box %.3f\n",
           100 * covered / (WIDTH * HEIGHT), (double)ao_open, (double)ao_corner);
    if (covered < WIDTH * HEIGHT / 2) {
        fail("only %d of %d pixels hit the scene", covered, WIDTH * HEIGHT);
    }
    if (!(ao_open >= 0.99f)) {
        fail("open ground has AO %.3f; nothing is within %g of it, so it should be 1", (double)ao_open,
             (double)AO_RADIUS);
    }
    if (!(ao_corner <= 0.75f && ao_corner >= 0.25f)) {
        fail("ground next to the box has AO %.3f; about 0.5 expected", (double)ao_corner);
    }
    printf("ambient_occlusion: wrote %s\n", path);

    free(batch);
    free(img);
    free(m.vertices);
    free(m.indices);
    return EXIT_SUCCESS;
}

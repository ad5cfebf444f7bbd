/* The embedded example's procedural scene: a ground square of GROUND×GROUND
 * quads under a UV sphere. make_bakes builds it on the host and writes its floats
 * (as exact hexadecimal literals) next to the bakes, so that the device and the
 * host run on the same bits whatever their sinf and cosf. */
#ifndef EMBEDDED_SCENE_H
#define EMBEDDED_SCENE_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#define GROUND 6
#define RINGS 6
#define SEGMENTS 10
#define GROUND_VERTICES ((GROUND + 1) * (GROUND + 1))
#define SPHERE_VERTICES ((RINGS + 1) * (SEGMENTS + 1))
#define SCENE_VERTICES (GROUND_VERTICES + SPHERE_VERTICES)
#define SCENE_TRIANGLES (2 * GROUND * GROUND + 2 * RINGS * SEGMENTS)

struct scene {
    float positions[3 * SCENE_VERTICES];
    float normals[3 * SCENE_VERTICES];
    uint32_t indices[3 * SCENE_TRIANGLES];
};

static void scene_quad(uint32_t *indices, size_t *t, uint32_t a, uint32_t b, uint32_t c, uint32_t d)
{
    /* Counter-clockwise seen from outside: (a, b, c) and (a, c, d). */
    uint32_t *tri = indices + 3 * *t;
    tri[0] = a, tri[1] = b, tri[2] = c;
    tri[3] = a, tri[4] = c, tri[5] = d;
    *t += 2;
}

static void scene_build(struct scene *s)
{
    size_t v = 0, t = 0;
    /* Ground: y = 0, x and z in [-2, 2], normals up. */
    for (int j = 0; j <= GROUND; j++) {
        for (int i = 0; i <= GROUND; i++, v++) {
            s->positions[3 * v] = -2.0f + 4.0f * (float)i / GROUND;
            s->positions[3 * v + 1] = 0.0f;
            s->positions[3 * v + 2] = -2.0f + 4.0f * (float)j / GROUND;
            s->normals[3 * v] = 0.0f, s->normals[3 * v + 1] = 1.0f, s->normals[3 * v + 2] = 0.0f;
        }
    }
    for (uint32_t j = 0; j < GROUND; j++) {
        for (uint32_t i = 0; i < GROUND; i++) {
            uint32_t a = j * (GROUND + 1) + i;
            scene_quad(s->indices, &t, a, a + GROUND + 1, a + GROUND + 2, a + 1);
        }
    }
    /* Sphere of radius 0.8 centred 1.1 above the ground. */
    const float pi = 3.14159265f;
    for (int r = 0; r <= RINGS; r++) {
        float polar = pi * (float)r / RINGS;
        for (int k = 0; k <= SEGMENTS; k++, v++) {
            float azimuth = 2.0f * pi * (float)k / SEGMENTS;
            float nx = sinf(polar) * cosf(azimuth), ny = cosf(polar), nz = sinf(polar) * sinf(azimuth);
            float length = sqrtf(nx * nx + ny * ny + nz * nz);
            nx /= length, ny /= length, nz /= length;
            s->positions[3 * v] = 0.8f * nx;
            s->positions[3 * v + 1] = 1.1f + 0.8f * ny;
            s->positions[3 * v + 2] = 0.8f * nz;
            s->normals[3 * v] = nx, s->normals[3 * v + 1] = ny, s->normals[3 * v + 2] = nz;
        }
    }
    for (uint32_t r = 0; r < RINGS; r++) {
        for (uint32_t k = 0; k < SEGMENTS; k++) {
            uint32_t a = GROUND_VERTICES + r * (SEGMENTS + 1) + k;
            scene_quad(s->indices, &t, a, a + 1, a + SEGMENTS + 2, a + SEGMENTS + 1);
        }
    }
}

static struct antumbra_mesh_view scene_view(const struct scene *s)
{
    struct antumbra_mesh_view view;
    view.positions = s->positions;
    view.vertex_count = SCENE_VERTICES;
    view.position_stride = 0;
    view.indices = s->indices;
    view.triangle_count = SCENE_TRIANGLES;
    return view;
}

#endif

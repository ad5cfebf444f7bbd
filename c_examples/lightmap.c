/* Bakes a lightmap for a small scene, a box standing on a floor, and writes it as
 * an OpenEXR image an engine can load.
 *
 *   lightmap OUT.exr
 *
 * Every quad of the scene is its own UV chart. The program builds the lightmap's
 * receivers from the UVs (antumbra_lightmap_create: covered and touched texels,
 * lifted out of geometry, a 2-texel gutter), bakes diffuse transfer at them with
 * one bounce (antumbra_lightmap_bake), relights them under a sky given in
 * spherical harmonics (antumbra_transfer_shade: outgoing radiance of a white
 * surface), spreads the radiance over the texels and the gutter
 * (antumbra_lightmap_expand), checks what it can (the open floor brighter than
 * the floor beside the box, texels outside the charts untouched) and writes an
 * uncompressed 32-bit float RGB OpenEXR image. Row 0 of the image is the atlas's
 * top (v = 1), as textures are drawn. Then it saves the lightmap as a bake file
 * (antumbra_transfer_save; the file carries each entry's texel), loads it back
 * and builds the same texture from the loaded set alone
 * (antumbra_transfer_expand), as an engine would. Exit status 0 on success. */

#include <antumbra.h>

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define WIDTH 64
#define HEIGHT 32
#define QUADS 6

static void check(antumbra_result r, const char *what)
{
    if (r != ANTUMBRA_RESULT_OK) {
        fprintf(stderr, "lightmap: %s failed: %s (%s)\n", what, antumbra_result_str(r),
                antumbra_last_error_message());
        exit(EXIT_FAILURE);
    }
}

static void *checked_malloc(size_t size)
{
    void *p = malloc(size);
    if (p == NULL) {
        fprintf(stderr, "lightmap: out of memory\n");
        exit(EXIT_FAILURE);
    }
    return p;
}

/* The scene: the floor [-1, 1]^2 on the left half of the atlas, and the five
 * visible faces of the box [-0.3, 0.3]^2 x [0, 0.4] in charts on the right half.
 * Corners run counter-clockwise seen from where the quad faces. */
static const float QUAD_CORNERS[QUADS][4][3] = {
    {{-1.0f, -1.0f, 0.0f}, {1.0f, -1.0f, 0.0f}, {1.0f, 1.0f, 0.0f}, {-1.0f, 1.0f, 0.0f}},
    {{-0.3f, -0.3f, 0.4f}, {0.3f, -0.3f, 0.4f}, {0.3f, 0.3f, 0.4f}, {-0.3f, 0.3f, 0.4f}},
    {{-0.3f, -0.3f, 0.0f}, {0.3f, -0.3f, 0.0f}, {0.3f, -0.3f, 0.4f}, {-0.3f, -0.3f, 0.4f}},
    {{0.3f, 0.3f, 0.0f}, {-0.3f, 0.3f, 0.0f}, {-0.3f, 0.3f, 0.4f}, {0.3f, 0.3f, 0.4f}},
    {{0.3f, -0.3f, 0.0f}, {0.3f, 0.3f, 0.0f}, {0.3f, 0.3f, 0.4f}, {0.3f, -0.3f, 0.4f}},
    {{-0.3f, 0.3f, 0.0f}, {-0.3f, -0.3f, 0.0f}, {-0.3f, -0.3f, 0.4f}, {-0.3f, 0.3f, 0.4f}},
};
/* Lower-left corner and size of each quad's chart. */
static const float CHARTS[QUADS][3] = {
    {0.0f, 0.0f, 0.5f}, /* the floor: [0, 0.5] x [0, 1] */
    {0.55f, 0.05f, 0.15f}, {0.77f, 0.05f, 0.15f}, {0.55f, 0.35f, 0.15f},
    {0.77f, 0.35f, 0.15f}, {0.55f, 0.65f, 0.15f},
};

static float positions[QUADS * 4 * 3];
static float uvs[QUADS * 4 * 2];
static uint32_t indices[QUADS * 6];

static void build_scene(void)
{
    int q, k;
    for (q = 0; q < QUADS; q++) {
        const float *chart = CHARTS[q];
        float height = q == 0 ? 2.0f * chart[2] : chart[2]; /* the floor's chart is 0.5 x 1 */
        float corner_uv[4][2];
        corner_uv[0][0] = chart[0];
        corner_uv[0][1] = chart[1];
        corner_uv[1][0] = chart[0] + chart[2];
        corner_uv[1][1] = chart[1];
        corner_uv[2][0] = chart[0] + chart[2];
        corner_uv[2][1] = chart[1] + height;
        corner_uv[3][0] = chart[0];
        corner_uv[3][1] = chart[1] + height;
        for (k = 0; k < 4; k++) {
            memcpy(&positions[(q * 4 + k) * 3], QUAD_CORNERS[q][k], 3 * sizeof(float));
            uvs[(q * 4 + k) * 2 + 0] = corner_uv[k][0];
            uvs[(q * 4 + k) * 2 + 1] = corner_uv[k][1];
        }
        indices[q * 6 + 0] = (uint32_t)(q * 4 + 0);
        indices[q * 6 + 1] = (uint32_t)(q * 4 + 1);
        indices[q * 6 + 2] = (uint32_t)(q * 4 + 2);
        indices[q * 6 + 3] = (uint32_t)(q * 4 + 0);
        indices[q * 6 + 4] = (uint32_t)(q * 4 + 2);
        indices[q * 6 + 5] = (uint32_t)(q * 4 + 3);
    }
}

/* ---- A minimal OpenEXR writer: one part, scan lines, no compression, FLOAT ---- */

static void put_bytes(FILE *f, const void *bytes, size_t n)
{
    if (fwrite(bytes, 1, n, f) != n) {
        fprintf(stderr, "lightmap: write failed\n");
        exit(EXIT_FAILURE);
    }
}

/* Little-endian integers and floats, whatever the host's byte order. */
static void put_u32(FILE *f, uint32_t v)
{
    unsigned char b[4];
    b[0] = (unsigned char)v;
    b[1] = (unsigned char)(v >> 8);
    b[2] = (unsigned char)(v >> 16);
    b[3] = (unsigned char)(v >> 24);
    put_bytes(f, b, 4);
}

static void put_u64(FILE *f, uint64_t v)
{
    put_u32(f, (uint32_t)v);
    put_u32(f, (uint32_t)(v >> 32));
}

static void put_f32(FILE *f, float v)
{
    uint32_t bits;
    memcpy(&bits, &v, sizeof bits);
    put_u32(f, bits);
}

static void put_attribute(FILE *f, const char *name, const char *type, uint32_t size)
{
    put_bytes(f, name, strlen(name) + 1);
    put_bytes(f, type, strlen(type) + 1);
    put_u32(f, size);
}

/* Writes `rgb` (3 floats per pixel, row 0 the top) as an RGB OpenEXR image. */
static void write_exr(const char *path, const float *rgb, int width, int height)
{
    /* Channels in the alphabetical order the format requires. */
    static const char *const names[3] = {"B", "G", "R"};
    static const int source[3] = {2, 1, 0};
    const uint32_t line_bytes = (uint32_t)(3 * width * 4);
    /* chlist: per channel name, pixel type, pLinear + 3 reserved, x and y sampling. */
    const uint32_t chlist_size = 3 * (2 + 16) + 1;
    uint64_t header_size, offset;
    int c, x, y;
    FILE *f = fopen(path, "wb");
    if (f == NULL) {
        fprintf(stderr, "lightmap: cannot write %s\n", path);
        exit(EXIT_FAILURE);
    }
    put_u32(f, 20000630u); /* magic */
    put_u32(f, 2u);        /* version 2, single-part scan lines */
    put_attribute(f, "channels", "chlist", chlist_size);
    for (c = 0; c < 3; c++) {
        put_bytes(f, names[c], 2);
        put_u32(f, 2u); /* FLOAT */
        put_u32(f, 0u); /* pLinear 0, reserved */
        put_u32(f, 1u);
        put_u32(f, 1u);
    }
    put_bytes(f, "", 1);
    put_attribute(f, "compression", "compression", 1);
    put_bytes(f, "", 1); /* NO_COMPRESSION */
    put_attribute(f, "dataWindow", "box2i", 16);
    put_u32(f, 0u);
    put_u32(f, 0u);
    put_u32(f, (uint32_t)(width - 1));
    put_u32(f, (uint32_t)(height - 1));
    put_attribute(f, "displayWindow", "box2i", 16);
    put_u32(f, 0u);
    put_u32(f, 0u);
    put_u32(f, (uint32_t)(width - 1));
    put_u32(f, (uint32_t)(height - 1));
    put_attribute(f, "lineOrder", "lineOrder", 1);
    put_bytes(f, "", 1); /* INCREASING_Y */
    put_attribute(f, "pixelAspectRatio", "float", 4);
    put_f32(f, 1.0f);
    put_attribute(f, "screenWindowCenter", "v2f", 8);
    put_f32(f, 0.0f);
    put_f32(f, 0.0f);
    put_attribute(f, "screenWindowWidth", "float", 4);
    put_f32(f, 1.0f);
    put_bytes(f, "", 1); /* end of header */
    /* The offset table: one block per scan line. */
    header_size = (uint64_t)ftell(f);
    offset = header_size + 8u * (uint64_t)height;
    for (y = 0; y < height; y++) {
        put_u64(f, offset);
        offset += 8u + line_bytes;
    }
    for (y = 0; y < height; y++) {
        put_u32(f, (uint32_t)y);
        put_u32(f, line_bytes);
        for (c = 0; c < 3; c++) {
            for (x = 0; x < width; x++) {
                put_f32(f, rgb[(y * width + x) * 3 + source[c]]);
            }
        }
    }
    if (fclose(f) != 0) {
        fprintf(stderr, "lightmap: cannot finish %s\n", path);
        exit(EXIT_FAILURE);
    }
}

/* Luminance of texel (x, y) of the atlas (row 0 at v = 0). */
static float luminance_at(const float *image, int x, int y)
{
    const float *p = &image[(y * WIDTH + x) * 3];
    return 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2];
}

int main(int argc, char **argv)
{
    antumbra_mesh_view mesh;
    antumbra_lightmap_options options;
    antumbra_lightmap *lightmap = NULL;
    antumbra_lightmap_info info;
    antumbra_transfer_options bake;
    antumbra_transfer *set = NULL;
    antumbra_transfer_material material;
    /* 3 bands per channel, channel-planar: a sky brighter overhead (Y_1^0 ~ z),
     * slightly blue. */
    float sky[3 * 9];
    antumbra_transfer *loaded = NULL;
    antumbra_transfer_info set_info, loaded_info;
    uint8_t *file;
    size_t file_size;
    float *radiance, *atlas, *image;
    float open_floor, beside_box;
    size_t n, texels;
    int x, y;

    if (argc != 2) {
        fprintf(stderr, "usage: lightmap OUT.exr\n");
        return EXIT_FAILURE;
    }
    build_scene();
    mesh.positions = positions;
    mesh.vertex_count = QUADS * 4;
    mesh.position_stride = 0;
    mesh.indices = indices;
    mesh.triangle_count = QUADS * 2;

    antumbra_lightmap_options_init(&options);
    options.width = WIDTH;
    options.height = HEIGHT;
    check(antumbra_lightmap_create(&mesh, uvs, NULL, &options, &lightmap), "antumbra_lightmap_create");
    check(antumbra_lightmap_describe(lightmap, &info), "antumbra_lightmap_describe");
    n = info.receiver_count;

    antumbra_transfer_options_init(&bake);
    bake.kind = ANTUMBRA_TRANSFER_KIND_DIFFUSE;
    bake.bands = 3;
    bake.rays = 64;
    bake.bounces = 1;
    bake.albedo = 0.6f;
    check(antumbra_lightmap_bake(lightmap, &mesh, NULL, &bake, NULL, NULL, &set), "antumbra_lightmap_bake");

    memset(sky, 0, sizeof sky);
    sky[0] = 2.0f;  /* red: constant */
    sky[2] = 1.2f;  /* red: overhead */
    sky[9] = 2.1f;  /* green */
    sky[11] = 1.3f;
    sky[18] = 2.4f; /* blue */
    sky[20] = 1.5f;
    antumbra_transfer_material_init(&material);
    radiance = (float *)checked_malloc(3 * n * sizeof(float));
    check(antumbra_transfer_shade(set, sky, 27, &material, 0, radiance, n), "antumbra_transfer_shade");

    texels = (size_t)WIDTH * HEIGHT;
    atlas = (float *)checked_malloc(3 * texels * sizeof(float));
    image = (float *)checked_malloc(3 * texels * sizeof(float));
    memset(atlas, 0, 3 * texels * sizeof(float));
    check(antumbra_lightmap_expand(lightmap, radiance, 3 * n, 3, atlas, 3 * texels), "antumbra_lightmap_expand");

    /* The floor's corner (texel (0, 0)) sees nearly the whole sky; the floor just
     * beside the box's wall (x = 0.31..0.38, y = 0: texel (21, 16)) sees half of
     * it. Far right of the box's charts, beyond the gutter, nothing is written. */
    open_floor = luminance_at(atlas, 0, 0);
    beside_box = luminance_at(atlas, 21, 16);
    printf("lightmap: %zu receivers (%u moved by the lift) in a %d x %d atlas; radiance %.3f on the open "
           "floor, %.3f beside the box\n",
           n, info.lifted, WIDTH, HEIGHT, (double)open_floor, (double)beside_box);
    if (!(open_floor > 1.2f * beside_box && beside_box > 0.0f)) {
        fprintf(stderr, "lightmap: the floor beside the box is not darker than the open floor\n");
        return EXIT_FAILURE;
    }
    if (luminance_at(atlas, WIDTH - 2, HEIGHT - 2) != 0.0f) {
        fprintf(stderr, "lightmap: a texel outside the charts and gutter was written\n");
        return EXIT_FAILURE;
    }
    for (y = 0; y < HEIGHT; y++) {
        for (x = 0; x < WIDTH; x++) {
            /* Image row 0 is the atlas's top row (v = 1). */
            memcpy(&image[(y * WIDTH + x) * 3], &atlas[((HEIGHT - 1 - y) * WIDTH + x) * 3], 3 * sizeof(float));
        }
    }
    write_exr(argv[1], image, WIDTH, HEIGHT);
    printf("lightmap: wrote %s\n", argv[1]);

    /* What an engine does with the saved lightmap: the bake file carries the
     * texels, so after loading it the texture is built from the set alone, and
     * it equals the one above. */
    check(antumbra_transfer_describe(set, &set_info), "antumbra_transfer_describe");
    file_size = set_info.file_bytes;
    file = (uint8_t *)checked_malloc(file_size);
    check(antumbra_transfer_save(set, file, file_size, &file_size), "antumbra_transfer_save");
    check(antumbra_transfer_load(file, file_size, &loaded), "antumbra_transfer_load");
    check(antumbra_transfer_describe(loaded, &loaded_info), "antumbra_transfer_describe");
    if (loaded_info.atlas_width != WIDTH || loaded_info.atlas_height != HEIGHT || loaded_info.vertex_count != n) {
        fprintf(stderr, "lightmap: the loaded file is a %u x %u lightmap of %u texels\n", loaded_info.atlas_width,
                loaded_info.atlas_height, loaded_info.vertex_count);
        return EXIT_FAILURE;
    }
    check(antumbra_transfer_shade(loaded, sky, 27, &material, 0, radiance, n), "antumbra_transfer_shade (loaded)");
    memset(image, 0, 3 * texels * sizeof(float));
    check(antumbra_transfer_expand(loaded, info.gutter, radiance, 3 * n, 3, image, 3 * texels),
          "antumbra_transfer_expand");
    if (memcmp(image, atlas, 3 * texels * sizeof(float)) != 0) {
        fprintf(stderr, "lightmap: the loaded file's texture differs from the lightmap's\n");
        return EXIT_FAILURE;
    }
    printf("lightmap: the %zu-byte bake file (version %u) loads back into the same texture\n", file_size,
           (unsigned)file[8] | (unsigned)file[9] << 8 | (unsigned)file[10] << 16 | (unsigned)file[11] << 24);

    antumbra_transfer_destroy(loaded);
    free(file);
    free(image);
    free(atlas);
    free(radiance);
    antumbra_transfer_destroy(set);
    antumbra_lightmap_destroy(lightmap);
    return EXIT_SUCCESS;
}

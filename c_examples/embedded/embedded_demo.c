/*
 * embedded_demo.c: Antumbra on bare metal, and the same program on the host.
 *
 * Built twice from this one source:
 *   - for a Cortex-M4 (QEMU's mps2-an386) with -DANTUMBRA_NO_STD, linked against
 *     the no_std libantumbra.a, newlib and the firmware support code;
 *   - for the host, linked against the hosted libantumbra.a.
 * Both print the same lines:
 *   - checksums (FNV-1a over the bits) of the 32x32 hemisphere masks of every
 *     vertex of a small scene (exact quality), and of the soft-shadow visibility
 *     bits of points on the ground under an area light, with the hierarchy and
 *     with brute force (which must agree);
 *   - every float, as its bits in hexadecimal, of the SH transfer vectors
 *     and the diffuse shading computed from the masks, of SH evaluation and
 *     rotation, and of the shading of four bake files compiled into the image
 *     (diffuse, glossy SH, MRT, MRT from PCA).
 * tools/compare_embedded.py compares the two outputs: every line equal, except
 * the floats of "values" lines, equal within a stated bound, and the "info:"
 * lines (memory figures of the device), not compared.
 *
 * With -DMASKS_ONLY only the masks are computed: the smallest useful image, whose
 * flash and RAM the README reports.
 *
 * On the device the program then sweeps out-of-memory: it repeats each call that
 * allocates with an allocator that refuses the 1st, 2nd, ... allocation, and
 * requires every such call to return ANTUMBRA_RESULT_OUT_OF_MEMORY (or succeed),
 * with its outputs untouched, never to stop.
 */
#include "antumbra.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "embedded_data.h"

#if !defined(ANTUMBRA_HAS_STD)
#include "firmware.h"
#endif

static int failures;

/* Output. The masks-only image does without printf (newlib's stdio would be a
 * fifth of its flash): it writes through semihosting directly. */
#if defined(MASKS_ONLY) && !defined(ANTUMBRA_HAS_STD)
static void put(const char *text)
{
    firmware_write(text);
}
#else
static void put(const char *text)
{
    fputs(text, stdout);
}
#endif

/* `value` in `base` (10 or 16), with at least `digits` digits. */
static void put_number(unsigned long value, unsigned base, int digits)
{
    char reversed[24], text[24];
    int n = 0;
    do {
        reversed[n++] = "0123456789abcdef"[value % base];
        value /= base;
    } while (value != 0 || n < digits);
    for (int i = 0; i < n; i++) {
        text[i] = reversed[n - 1 - i];
    }
    text[n] = '\0';
    put(text);
}

static void fail(const char *call, antumbra_result result)
{
    put("FAILED: ");
    put(call);
    put(" returned ");
    put(antumbra_result_str(result));
    put(": ");
    put(antumbra_last_error_message());
    put("\n");
    failures++;
}

#define CHECK(call)                                                                                                    \
    do {                                                                                                               \
        antumbra_result check_result_ = (call);                                                                        \
        if (check_result_ != ANTUMBRA_RESULT_OK) {                                                                     \
            fail(#call, check_result_);                                                                                \
        }                                                                                                              \
    } while (0)

/* FNV-1a, 32 bits, over bytes. */
static uint32_t fnv(uint32_t hash, const void *data, size_t size)
{
    const uint8_t *bytes = (const uint8_t *)data;
    for (size_t i = 0; i < size; i++) {
        hash = (hash ^ bytes[i]) * 16777619u;
    }
    return hash;
}

#define FNV_START 2166136261u

static struct antumbra_mesh_view scene(void)
{
    struct antumbra_mesh_view mesh;
    mesh.positions = scene_positions;
    mesh.vertex_count = SCENE_VERTICES;
    mesh.position_stride = 0;
    mesh.indices = scene_indices;
    mesh.triangle_count = SCENE_TRIANGLES;
    return mesh;
}

/* Masks of every vertex, rasterized a few receivers at a time into a small buffer
 * (what a device with little RAM does). */
static void masks(void)
{
    enum { BATCH = 8 };
    static struct antumbra_hemi_mask batch[BATCH];
    struct antumbra_mesh_view mesh = scene();
    struct antumbra_hemi_options options;
    antumbra_hemi_options_init(&options);
    options.normal_offset = 1e-3f;
    uint32_t hash = FNV_START;
    unsigned long occluded = 0;
    for (size_t first = 0; first < SCENE_VERTICES; first += BATCH) {
        size_t count = SCENE_VERTICES - first < BATCH ? SCENE_VERTICES - first : BATCH;
        antumbra_result result = antumbra_hemi_rasterize(&mesh, scene_positions + 3 * first,
                                                         scene_normals + 3 * first, count, &options, batch);
        if (result != ANTUMBRA_RESULT_OK) {
            fail("antumbra_hemi_rasterize", result);
            return;
        }
        for (size_t k = 0; k < count; k++) {
            hash = fnv(hash, batch[k].rows, sizeof batch[k].rows);
            for (int row = 0; row < 32; row++) {
                for (uint32_t bits = batch[k].rows[row]; bits; bits &= bits - 1) {
                    occluded++;
                }
            }
        }
    }
    put("masks: ");
    put_number(SCENE_VERTICES, 10, 1);
    put(" receivers, ");
    put_number(occluded, 10, 1);
    put(" occluded cells, fnv ");
    put_number(hash, 16, 8);
    put("\n");
}

#if !defined(MASKS_ONLY)

/* Prints floats as their IEEE-754 bits in hexadecimal (exact, and independent of
 * the C library's float formatting), for the comparison with the host: float
 * results may differ in the last bits between the two (see
 * tools/compare_embedded.py for the bound and why). */
static void print_values(const char *name, const float *values, size_t count)
{
    printf("values %s:", name);
    for (size_t i = 0; i < count; i++) {
        uint32_t bits;
        memcpy(&bits, &values[i], sizeof bits);
        printf(" %08lx", (unsigned long)bits);
    }
    printf("\n");
}

/* Smooth RGB sky lighting, 3 bands, channel-planar (9 red, 9 green, 9 blue). */
static const float sky[27] = {
    1.6f, 0.9f, 0.2f, 0.1f, 0.05f, 0.0f, -0.2f, 0.0f, 0.1f,
    1.5f, 0.8f, 0.2f, 0.1f, 0.05f, 0.0f, -0.2f, 0.0f, 0.1f,
    1.9f, 1.1f, 0.3f, 0.1f, 0.05f, 0.0f, -0.2f, 0.0f, 0.1f,
};

static void hemi_shading(void)
{
    static float transfer[SCENE_VERTICES * 9];
    static float rgb[SCENE_VERTICES * 3];
    struct antumbra_mesh_view mesh = scene();
    struct antumbra_hemi_shading_options options;
    antumbra_hemi_shading_options_init(&options);
    options.raster.normal_offset = 1e-3f;
    CHECK(antumbra_hemi_transfer(&mesh, scene_normals, NULL, &options, transfer));
    print_values("hemi transfer (3 bands)", transfer, sizeof transfer / sizeof transfer[0]);
    struct antumbra_hemi_material material;
    antumbra_hemi_material_init(&material);
    CHECK(antumbra_hemi_shade(&mesh, scene_normals, NULL, &options, sky, &material, rgb, NULL, NULL));
    print_values("hemi shade (diffuse)", rgb, sizeof rgb / sizeof rgb[0]);
    /* Bad input gets the same code in both builds, even for an option the
     * bare-metal build does not support (a far mesh the library makes). */
    options.far_triangles = SCENE_TRIANGLES;
    printf("hemi transfer, far_triangles = the mesh's: %s\n",
           antumbra_result_str(antumbra_hemi_transfer(&mesh, scene_normals, NULL, &options, transfer)));
}

static void spherical_harmonics(void)
{
    const float direction[3] = {0.36f, 0.48f, 0.8f};
    float values[16];
    CHECK(antumbra_sh_eval(direction, 4, values));
    /* A rotation by 30 degrees about y, row-major. */
    const float c = 0.866025404f, s = 0.5f;
    const float rotation[9] = {c, 0.0f, s, 0.0f, 1.0f, 0.0f, -s, 0.0f, c};
    float rotated[16];
    CHECK(antumbra_sh_rotate(rotation, 4, values, 1, rotated));
    print_values("sh eval (4 bands)", values, 16);
    print_values("sh rotate (4 bands)", rotated, 16);
}

struct bake {
    const char *name;
    const uint8_t *bytes;
    size_t size;
};

static const struct bake bakes[] = {
    {"diffuse", bake_diffuse, sizeof bake_diffuse},
    {"glossy", bake_glossy, sizeof bake_glossy},
    {"mrt", bake_mrt, sizeof bake_mrt},
    {"mrt-pca", bake_mrt_pca, sizeof bake_mrt_pca},
};

/* Loads a bake and shades it; returns 0 on success, the failing result otherwise
 * (the out-of-memory sweep calls it too). */
static antumbra_result shade_bake(const struct bake *bake, float *rgb, int print)
{
    struct antumbra_transfer *set = NULL;
    antumbra_result result = antumbra_transfer_load(bake->bytes, bake->size, &set);
    if (result != ANTUMBRA_RESULT_OK) {
        return result;
    }
    struct antumbra_transfer_info info;
    result = antumbra_transfer_describe(set, &info);
    if (result == ANTUMBRA_RESULT_OK) {
        struct antumbra_transfer_material material;
        antumbra_transfer_material_init(&material);
        material.eye[0] = 3.0f, material.eye[1] = 4.0f, material.eye[2] = 5.0f;
        result = antumbra_transfer_shade(set, sky, 27, &material, info.components, rgb, SCENE_VERTICES);
    }
    if (result == ANTUMBRA_RESULT_OK && print) {
        printf("bake %s: kind %u, %u bands, grid %u, %u components, %u vertices\n", bake->name, (unsigned)info.kind,
               (unsigned)info.bands, (unsigned)info.grid, (unsigned)info.components, (unsigned)info.vertex_count);
        char name[64];
        snprintf(name, sizeof name, "bake %s", bake->name);
        print_values(name, rgb, 3 * SCENE_VERTICES);
    }
    antumbra_transfer_destroy(set);
    return result;
}

/* Loads and shades every bake, printing the results when `print`; returns the
 * first failure. */
static antumbra_result shade_bakes(int print)
{
    static float rgb[3 * SCENE_VERTICES];
    for (size_t b = 0; b < sizeof bakes / sizeof bakes[0]; b++) {
        antumbra_result result = shade_bake(&bakes[b], rgb, print);
        if (result != ANTUMBRA_RESULT_OK) {
            return result;
        }
    }
    return ANTUMBRA_RESULT_OK;
}

static void transfer(void)
{
    antumbra_result result = shade_bakes(1);
    if (result != ANTUMBRA_RESULT_OK) {
        fail("loading and shading the bakes", result);
    }
}

/* A square light of side 1.2 at height 3.5, facing down (counter-clockwise seen
 * from below). */
static const float light[12] = {
    -0.6f, 3.5f, -0.6f, 0.6f, 3.5f, -0.6f, 0.6f, 3.5f, 0.6f, -0.6f, 3.5f, 0.6f,
};

enum { SAMPLES = 64, POINTS_SIDE = 9, POINTS = POINTS_SIDE * POINTS_SIDE, WORDS = SAMPLES / 64 };

static float light_samples[3 * SAMPLES];
static float ground_points[3 * POINTS];
/* The hierarchy's bits with memory to spare, for the out-of-memory sweep. */
static uint64_t ssv_reference_bits[POINTS * WORDS];

static antumbra_result create_ssv(uint32_t structure, struct antumbra_ssv **out)
{
    struct antumbra_mesh_view mesh = scene();
    struct antumbra_ssv_options options;
    antumbra_ssv_options_init(&options);
    options.structure = structure;
    return antumbra_ssv_create(&mesh, light, 4, light_samples, SAMPLES, &options, out);
}

static void soft_shadows(void)
{
    static uint64_t bits[2][POINTS * WORDS];
    static uint32_t counts[POINTS];
    CHECK(antumbra_ssv_generate_samples(light, 4, SAMPLES, ANTUMBRA_SSV_SAMPLES_STRATIFIED, 7, light_samples));
    for (int j = 0; j < POINTS_SIDE; j++) {
        for (int i = 0; i < POINTS_SIDE; i++) {
            float *p = ground_points + 3 * (j * POINTS_SIDE + i);
            p[0] = -1.8f + 3.6f * (float)i / (POINTS_SIDE - 1);
            p[1] = 0.01f;
            p[2] = -1.8f + 3.6f * (float)j / (POINTS_SIDE - 1);
        }
    }
    const uint32_t structures[2] = {ANTUMBRA_SSV_STRUCTURE_HIERARCHY, ANTUMBRA_SSV_STRUCTURE_BRUTE_FORCE};
    for (int s = 0; s < 2; s++) {
        struct antumbra_ssv *ssv = NULL;
        antumbra_result result = create_ssv(structures[s], &ssv);
        if (result != ANTUMBRA_RESULT_OK) {
            fail("antumbra_ssv_create", result);
            return;
        }
        CHECK(antumbra_ssv_query(ssv, ground_points, POINTS, bits[s], counts));
        unsigned long visible = 0;
        for (int k = 0; k < POINTS; k++) {
            visible += counts[k];
        }
        printf("ssv %s: %d points x %d samples, %lu visible, fnv %08lx\n", s == 0 ? "hierarchy" : "brute force",
               POINTS, SAMPLES, visible, (unsigned long)fnv(FNV_START, bits[s], sizeof bits[s]));
        antumbra_ssv_destroy(ssv);
    }
    memcpy(ssv_reference_bits, bits[0], sizeof ssv_reference_bits);
    if (memcmp(bits[0], bits[1], sizeof bits[0]) != 0) {
        printf("FAILED: the hierarchy's soft-shadow bits differ from brute force\n");
        failures++;
    }
}

#endif /* !MASKS_ONLY */

#if !defined(ANTUMBRA_HAS_STD) && !defined(MASKS_ONLY)

/* Calls `attempt` with an allocator that refuses the n-th allocation, for n = 0,
 * 1, ... until a run needs no refusal. A refused run must return OUT_OF_MEMORY
 * or, where `degrades` (soft-shadow queries, which fall back to coarser nodes),
 * succeed with the same results (the attempt checks them); a stop (the panic
 * hook) ends the program. */
static void sweep(const char *name, antumbra_result (*attempt)(void), int degrades)
{
    long refusals = 0, degraded = 0;
    for (long n = 0;; n++) {
        size_t live = firmware_heap_live();
        firmware_heap_fail_after(n);
        antumbra_result result = attempt();
        int refused = firmware_heap_refused();
        firmware_heap_fail_after(-1);
        /* A refused call keeps nothing (a call that succeeds may keep a shared
         * table for later calls). */
        if (refused && firmware_heap_live() != live) {
            printf("FAILED: out-of-memory sweep of %s: %lu bytes leaked after refusing allocation %ld\n", name,
                   (unsigned long)(firmware_heap_live() - live), n);
            failures++;
        }
        if (!refused) {
            if (result != ANTUMBRA_RESULT_OK) {
                fail(name, result);
            }
            printf("info: out of memory: %s: %ld refused allocations gave OUT_OF_MEMORY, %ld the same results "
                   "without the memory\n",
                   name, refusals - degraded, degraded);
            return;
        }
        if (result == ANTUMBRA_RESULT_OK && degrades) {
            degraded++;
        } else if (result != ANTUMBRA_RESULT_OUT_OF_MEMORY) {
            printf("FAILED: out-of-memory sweep of %s: refusing allocation %ld gave %s\n", name, n,
                   antumbra_result_str(result));
            failures++;
            return;
        }
        refusals++;
    }
}

static antumbra_result attempt_hemi_transfer(void)
{
    static float transfer[SCENE_VERTICES * 9];
    struct antumbra_mesh_view mesh = scene();
    struct antumbra_hemi_shading_options options;
    antumbra_hemi_shading_options_init(&options);
    options.bands = 2; /* a band count not used above, so its table is built here */
    return antumbra_hemi_transfer(&mesh, NULL, NULL, &options, transfer);
}

static antumbra_result attempt_hemi_shade(void)
{
    static float rgb[SCENE_VERTICES * 3];
    struct antumbra_mesh_view mesh = scene();
    struct antumbra_hemi_shading_options options;
    antumbra_hemi_shading_options_init(&options);
    options.bands = 3;
    options.method = ANTUMBRA_HEMI_METHOD_DOWNSAMPLED;
    struct antumbra_hemi_material material;
    antumbra_hemi_material_init(&material);
    material.specular[0] = material.specular[1] = material.specular[2] = 0.3f;
    material.phong_exponent = 12.0f;
    material.eye[0] = 3.0f, material.eye[1] = 4.0f, material.eye[2] = 5.0f;
    return antumbra_hemi_shade(&mesh, scene_normals, NULL, &options, sky, &material, rgb, NULL, NULL);
}

/* Loads a bake and saves it again: the bytes must come back unchanged. */
static antumbra_result attempt_save(void)
{
    static uint8_t saved[sizeof bake_mrt_pca];
    struct antumbra_transfer *set = NULL;
    antumbra_result result = antumbra_transfer_load(bake_mrt_pca, sizeof bake_mrt_pca, &set);
    if (result == ANTUMBRA_RESULT_OK) {
        size_t size = 0;
        result = antumbra_transfer_save(set, saved, sizeof saved, &size);
        if (result == ANTUMBRA_RESULT_OK && (size != sizeof saved || memcmp(saved, bake_mrt_pca, size) != 0)) {
            printf("FAILED: a loaded and saved bake differs from the file\n");
            failures++;
        }
        antumbra_transfer_destroy(set);
    }
    return result;
}

static antumbra_result attempt_bakes(void)
{
    return shade_bakes(0);
}

/* The sweep queries one row of the ground points (each attempt repeats the
 * whole construction, so a row keeps the sweep to seconds under QEMU). */
enum { SWEEP_POINTS = POINTS_SIDE };

static antumbra_result attempt_ssv(uint32_t structure)
{
    static uint64_t bits[SWEEP_POINTS * WORDS];
    struct antumbra_ssv *ssv = NULL;
    antumbra_result result = create_ssv(structure, &ssv);
    if (result == ANTUMBRA_RESULT_OK) {
        /* Queries never fail for memory: where a node of the hierarchy cannot be
         * made they use a coarser one, with the same bits. */
        result = antumbra_ssv_query(ssv, ground_points + 3 * 4 * POINTS_SIDE, SWEEP_POINTS, bits, NULL);
        if (result == ANTUMBRA_RESULT_OK &&
            memcmp(bits, ssv_reference_bits + 4 * POINTS_SIDE * WORDS, sizeof bits) != 0) {
            printf("FAILED: soft-shadow bits changed under memory pressure\n");
            failures++;
        }
        antumbra_ssv_destroy(ssv);
    }
    return result;
}

/* The hierarchy's construction makes every allocation the other structures
 * make (they share the edges, samples and caster) and more. */
static antumbra_result attempt_ssv_hierarchy(void)
{
    return attempt_ssv(ANTUMBRA_SSV_STRUCTURE_HIERARCHY);
}

static antumbra_result attempt_samples(void)
{
    static float samples[3 * SAMPLES];
    return antumbra_ssv_generate_samples(light, 4, SAMPLES, ANTUMBRA_SSV_SAMPLES_JITTERED, 11, samples);
}

static void out_of_memory(void)
{
    sweep("antumbra_hemi_transfer", attempt_hemi_transfer, 0);
    sweep("antumbra_hemi_shade (glossy)", attempt_hemi_shade, 0);
    sweep("antumbra_transfer_load and _shade", attempt_bakes, 0);
    sweep("antumbra_transfer_load and _save", attempt_save, 0);
    sweep("antumbra_ssv_generate_samples", attempt_samples, 0);
    sweep("antumbra_ssv_create and _query (hierarchy)", attempt_ssv_hierarchy, 1);
}

#endif

int main(void)
{
    if (antumbra_version() != ANTUMBRA_VERSION) {
        put("FAILED: the library's version is not the header's\n");
        return 1;
    }
    masks();
#if !defined(ANTUMBRA_HAS_STD)
    put("info: masks: heap peak ");
    put_number(firmware_heap_peak(), 10, 1);
    put(" bytes, stack ");
    put_number(firmware_stack_used(), 10, 1);
    put(" bytes\n");
#endif
#if !defined(MASKS_ONLY)
    hemi_shading();
    spherical_harmonics();
    transfer();
    soft_shadows();
#if !defined(ANTUMBRA_HAS_STD)
    printf("info: full example: heap peak %lu bytes, stack %lu bytes\n", (unsigned long)firmware_heap_peak(),
           (unsigned long)firmware_stack_used());
    out_of_memory();
#endif
#endif
    put(failures ? "FAILED: " : "done: ");
    put_number((unsigned long)failures, 10, 1);
    put(" failures\n");
    return failures ? 1 : 0;
}

//! The command line: every command, argument and help text (clap derive).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

/// Antumbra: physically-based shadows and lighting, from the command line.
///
/// Renders ray-traced ambient occlusion and environment lighting, bakes
/// per-vertex ambient occlusion, and measures and checks the ray casters of the
/// antumbra-core library. Meshes are Wavefront OBJ files with +Y up (lightmap
/// bakes also read glTF 2.0); environment maps are equirectangular OpenEXR
/// (HDR) or PNG files.
///
/// Start with `antumbra demo`: it needs no files.
#[derive(Debug, Parser)]
#[command(
    name = "antumbra",
    version,
    propagate_version = true,
    after_help = "Examples:
  antumbra demo                                     pictures into ./antumbra-demo
  antumbra render --mesh model.obj --env sky.exr    lit by an HDR sky, into model-env.png
  antumbra bake --mesh model.obj --out model.csv    per-vertex ambient occlusion
  antumbra bake --mesh model.obj --kind mrt --pca 8 -o model.xfer
                                                    matrix radiance transfer, PCA-compressed
  antumbra render --mesh model.obj --bake model.xfer --env sky.exr --rotate 90
                                                    relight the bake under a rotated sky
  antumbra bench transfer                           PRT/MRT shading cost, bake vs Embree
  antumbra bench raycast                            BVH vs brute-force rays per second
  antumbra verify --mesh model.obj                  BVH answers against brute force"
)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Render the demo pictures from built-in data (the bunny, the sunrise sky).
    ///
    /// Writes PNG files into the output folder: ray-traced ambient occlusion of
    /// the Stanford bunny on a ground plane, the bunny lit by an HDR sunrise
    /// environment map with ray-traced shadows, and a preview of that map; then,
    /// without rays, the bunny under the same sky in spherical harmonics,
    /// shadowed per vertex by hemispherical rasterization, diffuse and glossy,
    /// and a contact sheet of frames of the bunny twisting, re-shaded every frame
    /// (with per-frame timings); then the bunny over a floor under a quad light
    /// with exact soft shadows from 256 light samples (soft shadow volumes, the
    /// wedge hierarchy) and the difference image against tracing the same 256
    /// shadow rays per pixel (with the count of differing pixels); last, a glossy
    /// bunny relit by matrix radiance transfer under the sky rotating frame by
    /// frame (baked once, then shaded per frame without rays). Prints where each
    /// file went, its size and how long it took.
    Demo(DemoArgs),

    /// Render your own OBJ mesh: ambient occlusion, or lighting from an
    /// environment map with --env.
    ///
    /// The camera frames the mesh's bounding box automatically and the mesh
    /// stands on a ground plane at the bottom of its bounds (the mesh must be +Y
    /// up).
    ///
    /// With --bake FILE (made by `antumbra bake` from the same mesh): relights the
    /// bake under the map in SH (rotated by --rotate degrees about +Y), seen from
    /// the same camera, with no rays: one shading pass over the vertices, drawn
    /// with the vertex colours interpolated. No ground (the bake holds the mesh
    /// alone).
    Render(RenderArgs),

    /// Bake precomputed radiance transfer (diffuse PRT, glossy SH transfer or
    /// matrix radiance transfer) into a bake file, or per-vertex ambient occlusion
    /// into a text or CSV file (`--kind ao`, the default).
    ///
    /// Transfer (`--kind diffuse|glossy-sh|mrt`): for every vertex, `--rays`
    /// stratified rays over the hemisphere of its smooth normal (their origins
    /// moved `--ray-offset` mesh units along it) gather the transfer of every
    /// SH lighting coefficient at once, plus `--bounces` diffuse interreflections
    /// of albedo `--albedo`. MRT bakes a `--grid`² × bands² matrix per vertex for
    /// the chosen BRDF (Phong, or Ward's anisotropic one with --ward) and can be
    /// PCA-compressed to `--pca K` components, with `--clusters C` one basis per
    /// cluster of alike vertices (the error and memory per K are printed). The file is antumbra's versioned, checksummed bake format
    /// (`antumbra_core::transfer::format`); relight it with `antumbra render
    /// --bake`.
    ///
    /// Ambient occlusion (`--kind ao`): for each vertex, rays leave from the vertex
    /// (moved `--ray-offset` mesh units along its smooth normal) in
    /// cosine-weighted directions around that normal; the value is the
    /// fraction that escape. Output: with a .csv extension, a CSV table
    /// `vertex,x,y,z,nx,ny,nz,visibility` with one header row; otherwise a text
    /// file whose first line is a `#` header describing the contents, followed by
    /// one visibility value per line, line i+2 for vertex i. Visibility is in
    /// [0, 1]: 1 = unoccluded. Vertices are in the order of the loaded mesh: OBJ
    /// positions in order of first use by a face, objects one after another.
    Bake(BakeArgs),

    /// Join the part files of a bake split with `antumbra bake --shard I/N` into one
    /// bake file, byte for byte the file a single `antumbra bake` with the same
    /// arguments writes. Refuses parts that overlap, leave vertices out, or come
    /// from different meshes or settings, naming the files.
    ///
    /// Any job runner can run the parts: a Slurm array job (`--array=0-7`, each
    /// task `antumbra bake ... --shard $SLURM_ARRAY_TASK_ID/8 -o part-$SLURM_ARRAY_TASK_ID.xpart`),
    /// a Kubernetes indexed Job (`completionMode: Indexed`, `--shard
    /// $JOB_COMPLETION_INDEX/8`), or `seq 0 7 | xargs -P 8 -I{} antumbra bake ...
    /// --shard {}/8 -o part-{}.xpart`.
    Merge(MergeArgs),

    /// Measure performance and print figures next to a baseline measured in the
    /// same run.
    #[command(subcommand)]
    Bench(BenchCommand),

    /// Check Antumbra's answers against a reference: `antumbra verify` (or
    /// `verify raycast`) checks the BVH ray caster against brute force; `verify
    /// hemi` checks hemisphere masks against Embree.
    ///
    /// Without a subcommand: both ray casters use the same watertight triangle
    /// test, so closest-hit distances must be bit-identical, the triangles may
    /// differ only on exact ties (checked by re-intersecting), and occlusion answers
    /// must agree. Prints the agreement per class of rays and exits with a non-zero
    /// status on any mismatch.
    Verify(VerifyArgs),
}

/// Arguments of `antumbra demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Folder to write the pictures into (created if missing).
    #[arg(long, value_name = "DIR", default_value = "antumbra-demo")]
    pub out: PathBuf,

    /// Width of the pictures in pixels (heights follow each picture's aspect).
    #[arg(long, value_name = "N", default_value_t = 480, value_parser = clap::value_parser!(u32).range(8..=8192))]
    pub size: u32,
}

/// Arguments of `antumbra render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The mesh to render (Wavefront OBJ, +Y up; for a lightmap bake also glTF
    /// 2.0, with the UVs it was baked with).
    #[arg(long, value_name = "FILE")]
    pub mesh: PathBuf,

    /// Light the mesh with this equirectangular environment map (OpenEXR or PNG;
    /// +Y up, the image centre looks along +X). Without it, renders ambient
    /// occlusion.
    #[arg(long, value_name = "FILE.exr")]
    pub env: Option<PathBuf>,

    /// Where to write the picture [default: <mesh name>-ao.png or <mesh name>-env.png;
    /// with --bake, <bake name>-relit.png].
    #[arg(long, value_name = "FILE.png")]
    pub out: Option<PathBuf>,

    /// Width of the picture in pixels (the height is 3/4 of it).
    #[arg(long, value_name = "N", default_value_t = 640, value_parser = clap::value_parser!(u32).range(8..=8192))]
    pub size: u32,

    /// Samples per pixel: each is a primary ray plus one occlusion ray (ambient
    /// occlusion) or two shadow rays (environment lighting).
    #[arg(long, value_name = "N", default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub samples: u32,

    /// Do not add a ground plane under the mesh.
    #[arg(long)]
    pub no_ground: bool,

    /// Relight this bake file (baked from --mesh) with the environment map in SH
    /// instead of ray tracing [--env defaults to the built-in sunrise]. A
    /// lightmap (`bake --texels`) is shaded per texel into a texture, written
    /// beside the picture as `<picture stem>-lightmap.exr` (linear RGB, row 0
    /// at v = 1), and the mesh is drawn through its UVs with it.
    #[arg(long, value_name = "FILE")]
    pub bake: Option<PathBuf>,

    /// Rotate the environment map by this many degrees about +Y (with --bake).
    #[arg(long, value_name = "DEG", default_value_t = 0.0)]
    pub rotate: f32,

    /// Phong exponent of a glossy SH bake's run time (with --bake).
    #[arg(long, value_name = "S", default_value_t = 32.0)]
    pub exponent: f32,

    /// PCA components used when relighting a compressed MRT bake [default: all].
    #[arg(long, value_name = "K")]
    pub components: Option<usize>,
}

/// What `antumbra bake` computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BakeKind {
    /// Per-vertex ambient occlusion (text or CSV).
    Ao,
    /// Diffuse transfer vectors (bands² values per vertex).
    Diffuse,
    /// Glossy SH transfer matrices (bands² × bands² per vertex).
    GlossySh,
    /// Matrix radiance transfer (grid² × bands² per vertex).
    Mrt,
}

/// Arguments of `antumbra bake`.
#[derive(Debug, Args)]
pub struct BakeArgs {
    /// The mesh to bake (Wavefront OBJ; with --texels also glTF 2.0, .gltf or
    /// .glb).
    #[arg(long, value_name = "FILE")]
    pub mesh: PathBuf,

    /// What to bake.
    #[arg(long, value_enum, default_value_t = BakeKind::Ao)]
    pub kind: BakeKind,

    /// Output file: a bake file for the transfer kinds; for ao, CSV when it ends in
    /// .csv, the documented text format otherwise.
    #[arg(long, short = 'o', value_name = "FILE")]
    pub out: PathBuf,

    /// Rays per vertex (and per bounce).
    #[arg(long, value_name = "N", default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    pub rays: u32,

    /// Ignore occluders farther than this, in mesh units (ao only) [default: no limit].
    #[arg(long, value_name = "DISTANCE")]
    pub max_distance: Option<f32>,

    /// SH bands of the lighting (bands² coefficients).
    #[arg(long, value_name = "B", default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=8))]
    pub bands: u32,

    /// MRT grid side (grid² nodes over the hemisphere).
    #[arg(long, value_name = "G", default_value_t = 8, value_parser = clap::value_parser!(u32).range(2..=64))]
    pub grid: u32,

    /// Diffuse interreflection bounces.
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=64))]
    pub bounces: u32,

    /// Albedo of the scene for the bounces, in [0, 1).
    #[arg(long, value_name = "A", default_value_t = 0.5)]
    pub albedo: f32,

    /// PCA-compress an MRT bake to K components (a mean and K components; per
    /// cluster with --clusters).
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u32).range(1..))]
    pub pca: Option<u32>,

    /// With --pca: clustered PCA, C clusters of vertices each with its own mean
    /// and K components (far less error than one global basis at the same K;
    /// written as bake-file version 2 when C > 1).
    #[arg(long, value_name = "C", requires = "pca", value_parser = clap::value_parser!(u32).range(1..))]
    pub clusters: Option<u32>,

    /// Exponent of the MRT bake's Phong lobe.
    #[arg(long, value_name = "S", default_value_t = 32.0)]
    pub phong_exponent: f32,

    /// Bake Ward's anisotropic BRDF with these roughnesses instead of Phong (MRT).
    #[arg(long, value_name = "AX,AY", value_delimiter = ',')]
    pub ward: Option<Vec<f32>>,

    /// Move ray origins this far along the vertex normal, in mesh units (the C
    /// API's `ray_offset`, with its default): keeps rays off the vertex's own
    /// triangles. Scale it with the mesh: about 1e-4 of its size.
    #[arg(long, value_name = "D", default_value_t = 1e-4, value_parser = parse_ray_offset)]
    pub ray_offset: f32,

    /// Seed of the bake's random numbers.
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub seed: u64,

    /// Bake part I of N (from 0) of the vertices into a part file, for a bake split
    /// across machines; `antumbra merge` joins the N parts into the file a single
    /// bake writes, byte for byte. Transfer kinds only, without --pca (merge
    /// compresses). With bounces, every part still runs the earlier passes over
    /// every vertex.
    #[arg(long, value_name = "I/N", value_parser = crate::shard::Shard::parse)]
    pub shard: Option<crate::shard::Shard>,

    /// Bake a lightmap instead of the vertices: every texel of a W×H atlas (W
    /// alone for a square) that the mesh's UV charts (OBJ vt, glTF TEXCOORD_1
    /// or else TEXCOORD_0; non-overlapping, in [0, 1]) cover or touch, lifted
    /// out of geometry. Written as a bake file (version 3: the set and its
    /// texels; --shard and --pca as for vertices), or, for an output ending in
    /// .exr, as an OpenEXR image with a 2-texel gutter and one 32-bit channel
    /// per coefficient (`T.j` diffuse, `M.i.j` glossy SH, `R.g.j` MRT), row 0 at
    /// v = 1.
    #[arg(long, value_name = "W[xH]", value_parser = parse_texels)]
    pub texels: Option<(u32, u32)>,
}

/// Arguments of `antumbra merge`.
#[derive(Debug, Args)]
pub struct MergeArgs {
    /// The part files of `antumbra bake --shard I/N`, all N of them, in any order.
    #[arg(required = true, value_name = "PART")]
    pub parts: Vec<PathBuf>,

    /// The bake file to write; for the parts of a lightmap (`bake --texels`),
    /// an output ending in .exr gets its coefficients as OpenEXR channels (as
    /// `bake --texels -o FILE.exr` writes them).
    #[arg(long, short = 'o', value_name = "FILE")]
    pub out: PathBuf,

    /// PCA-compress the joined MRT bake to K components (as `bake --pca K`).
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u32).range(1..))]
    pub pca: Option<u32>,

    /// With --pca: C clusters (as `bake --clusters C`).
    #[arg(long, value_name = "C", requires = "pca", value_parser = clap::value_parser!(u32).range(1..))]
    pub clusters: Option<u32>,
}

/// The benchmarks.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Ray casting throughput: the BVH against the brute-force baseline; then a
    /// moving mesh: refitting its scene against rebuilding it, and the rays of each.
    ///
    /// Casts the same random rays (from outside towards the mesh, and from points
    /// on the surface in random directions) with both casters, for closest-hit and
    /// occlusion queries, on one thread and on all cores, and prints rays per
    /// second and the BVH's speed-up.
    Raycast(BenchRaycastArgs),

    /// Hemispherical rasterization: time per rasterized triangle (exact and table)
    /// and per receiver, against tracing the same cell directions with the BVH and
    /// with Embree (one thread each), printed as ratios; then frames per second
    /// shading every vertex of the deforming mesh.
    ///
    /// The frames: each twists the mesh about its vertical axis, recomputes the
    /// normals and cluster boxes, and shades every vertex (diffuse + glossy, 16 SH
    /// coefficients of the sunrise sky, Phong exponent 32), with the full mesh as
    /// the only occluder and with a far mesh (vertex clustering with cells of 1/30
    /// of the bounding-box diagonal) beyond a near radius of 1/10 of it, on one
    /// thread and on all cores. Slow frames (large meshes without the far mesh)
    /// are timed once: the armadillo takes minutes.
    Hemi(BenchHemiArgs),

    /// Soft shadows from a quad light: time per receiver of the 2006 wedge
    /// hierarchy against the 2005-style hemicube, brute force over every wedge,
    /// obvhs shadow rays and Embree shadow rays (one thread each, same receivers and
    /// samples, printed as ratios), with candidate wedges per query and memory,
    /// for N = 16, 64, 256 and 1024 light samples and three light orientations.
    ///
    /// The scene is the one of `verify ssv`: the mesh scaled to a largest extent
    /// of 1 over a floor, a 0.5 × 0.5 quad light 1.8 away (above, tilted 45°,
    /// low at the side 80°); receivers on the floor and just off the mesh. The
    /// hierarchy is lazy: its first pass over the receivers (construction
    /// included) is printed beside the timed warm passes.
    Ssv(BenchSsvArgs),
    /// Precomputed transfer: per-vertex shading cost of diffuse PRT, glossy SH
    /// transfer, MRT and MRT from PCA (as ratios); bake rays per second against
    /// obvhs and Embree casting the same rays (one thread); PCA error and memory
    /// per vertex against K.
    Transfer(BenchTransferArgs),

    /// Lightmaps: time per texel receiver of a texel bake (building the atlas,
    /// the lift out of geometry, the bake) against a vertex bake's time per
    /// vertex of the same mesh at the same rays, and the point bake at the
    /// mesh's own vertices against the vertex bake (the same sites), for
    /// diffuse and glossy SH transfer, on one thread, as ratios.
    Lightmap(BenchLightmapArgs),
}

/// Arguments of `antumbra bench lightmap`.
#[derive(Debug, Args)]
pub struct BenchLightmapArgs {
    /// Mesh with a UV atlas (OBJ vt, or glTF TEXCOORD_1 or else TEXCOORD_0)
    /// [default: the demo's two boxes on a floor].
    #[arg(long, value_name = "FILE")]
    pub mesh: Option<PathBuf>,

    /// Atlas size W or WxH.
    #[arg(long, value_name = "W[xH]", default_value = "128", value_parser = parse_texels)]
    pub texels: (u32, u32),

    /// Rays per receiver (and per vertex).
    #[arg(long, value_name = "N", default_value_t = 128, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    pub rays: u32,

    /// Timed runs of each bake; the fastest is reported.
    #[arg(long, value_name = "N", default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub repeats: u32,
}

/// Arguments of `antumbra bench transfer`.
#[derive(Debug, Args)]
pub struct BenchTransferArgs {
    /// Mesh (Wavefront OBJ) [default: the built-in bunny].
    #[arg(long, value_name = "FILE.obj")]
    pub mesh: Option<PathBuf>,

    /// SH band counts to compare at (each is a full set of figures).
    #[arg(long, value_name = "B,...", value_delimiter = ',', default_values_t = [4u32, 5])]
    pub bands: Vec<u32>,

    /// MRT grid side.
    #[arg(long, value_name = "G", default_value_t = 8, value_parser = clap::value_parser!(u32).range(2..=64))]
    pub grid: u32,

    /// Rays per vertex of the timed bakes.
    #[arg(long, value_name = "N", default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub rays: u32,

    /// Largest PCA component count of the error and memory table.
    #[arg(long, value_name = "K", default_value_t = 32)]
    pub max_components: usize,

    /// Cluster counts of the clustered-PCA table (each with every K of
    /// --cluster-components); set to 1 alone to skip the clustered fits.
    #[arg(long, value_name = "C,...", value_delimiter = ',', default_values_t = [4usize, 16, 64])]
    pub clusters: Vec<usize>,

    /// Components per cluster of the clustered-PCA table.
    #[arg(long, value_name = "K,...", value_delimiter = ',', default_values_t = [4usize, 8])]
    pub cluster_components: Vec<usize>,

    /// Time each shading figure over at least this many milliseconds.
    #[arg(long, value_name = "MS", default_value_t = 300)]
    pub min_time: u64,

    /// Skip the Embree figure (it needs the oracle's Python, see `verify hemi`).
    #[arg(long)]
    pub no_embree: bool,
}

/// Arguments of `antumbra bench raycast`.
#[derive(Debug, Args)]
pub struct BenchRaycastArgs {
    /// Mesh to cast against (Wavefront OBJ) [default: the built-in bunny].
    #[arg(long, value_name = "FILE.obj")]
    pub mesh: Option<PathBuf>,

    /// Number of distinct rays in the batch (at most 2^24, held in memory at once).
    #[arg(long, value_name = "N", default_value_t = 20_000, value_parser = clap::value_parser!(u32).range(1..=1 << 24))]
    pub rays: u32,

    /// Time each figure over at least this many milliseconds (the batch is cast
    /// again and again until then).
    #[arg(long, value_name = "MS", default_value_t = 400)]
    pub min_time: u64,
}

/// Arguments of `antumbra bench hemi`.
#[derive(Debug, Args)]
pub struct BenchHemiArgs {
    /// Mesh (Wavefront OBJ) [default: the built-in bunny]. With --scaling it may
    /// be given several times, each mesh a further row group after the built-in
    /// bunny, teapot and armadillo.
    #[arg(long, value_name = "FILE.obj")]
    pub mesh: Vec<PathBuf>,

    /// Print only the scaling table: per vertex, a deforming-mesh frame (exact,
    /// and with the library's far field at several settings) against Embree's
    /// frame on the same receivers, the ambient-occlusion error of each
    /// setting, and the triangles and hierarchy nodes tested per receiver, for
    /// the built-in bunny, teapot and armadillo and every --mesh.
    #[arg(long)]
    pub scaling: bool,

    /// Number of receivers timed (vertices spread evenly over the mesh).
    #[arg(long, value_name = "N", default_value_t = 400, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    pub receivers: u32,

    /// Time each figure over at least this many milliseconds.
    #[arg(long, value_name = "MS", default_value_t = 400)]
    pub min_time: u64,

    /// Skip the Embree figure (it needs the oracle's Python, see `verify hemi`).
    #[arg(long)]
    pub no_embree: bool,

    /// Mask quality of the frames-per-second table.
    #[arg(long, value_enum, default_value_t = QualityArg::Exact)]
    pub quality: QualityArg,

    /// Print only the frames-per-second table, with the mesh standing on the
    /// demo's ground (a polar grid reaching 30 of its diagonals, every vertex a
    /// receiver too; the far mesh is the mesh's vertex clustering plus the
    /// ground as one square), against the library's far levels made from the
    /// whole scene.
    #[arg(long, conflicts_with = "scaling")]
    pub on_ground: bool,
}

/// Arguments of `antumbra verify`: a subcommand, or the ray-caster check's options.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct VerifyArgs {
    /// What to verify [default: raycast].
    #[command(subcommand)]
    pub what: Option<VerifyCommand>,

    /// Options of the default `raycast` check.
    #[command(flatten)]
    pub raycast: VerifyRaycastArgs,
}

/// The checks of `antumbra verify`.
#[derive(Debug, Subcommand)]
pub enum VerifyCommand {
    /// The BVH ray caster against the brute-force reference (the default).
    Raycast(VerifyRaycastArgs),

    /// Hemisphere masks against Embree: for a few hundred receivers (mesh
    /// vertices with their area-weighted normals, the center of projection pushed
    /// off the surface by 1e-3 of the bounding-box diagonal), traces every valid
    /// cell direction with Embree and compares with the rasterized mask.
    ///
    /// Needs the Embree oracle's Python (`make pyenv` creates target/pyenv; or set
    /// ANTUMBRA_ORACLE_PYTHON). The last line reads `hemi <quality> agreement:
    /// <percent>% of <cells> cells, <receivers> receivers`; the exit status is
    /// non-zero below 99.99 % (exact) or 99.5 % (table).
    Hemi(VerifyHemiArgs),

    /// Soft shadow visibility bits against Embree occlusion rays: the mesh
    /// (scaled to a largest extent of 1) over a floor, a quad light in three
    /// orientations, receivers on a grid on the floor (exactly on it) and at mesh
    /// vertices lifted 1e-3 along their normals; every (receiver, sample) bit of
    /// the default hierarchy is compared with Embree's ray over the open segment.
    ///
    /// Each mismatch is decided by the exact segment–triangle test: the library
    /// must agree with it (else it is a library bug), and the segment must graze a
    /// triangle edge (Embree's f32 rounding decided). Needs the Embree oracle's
    /// Python (`make pyenv`; or set ANTUMBRA_ORACLE_PYTHON). The last line reads
    /// `ssv agreement: <percent>% of <bits> bits, <mismatches> mismatches`; the
    /// exit status is non-zero above 1e-5 of the bits or on any unexplained one.
    Ssv(VerifySsvArgs),
}

/// Arguments of `antumbra verify ssv`.
#[derive(Debug, Args)]
pub struct VerifySsvArgs {
    /// Mesh to put over the floor (Wavefront OBJ, +Y up) [default: the built-in bunny].
    #[arg(long, value_name = "FILE.obj")]
    pub mesh: Option<PathBuf>,

    /// Light samples (jittered, stratified over the quad).
    #[arg(long, value_name = "N", default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub samples: u32,

    /// Floor receivers: an N × N grid over [-1.5, 1.5]².
    #[arg(long, value_name = "N", default_value_t = 20, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub floor_grid: u32,

    /// Mesh receivers (vertices spread evenly over the vertex order).
    #[arg(long, value_name = "N", default_value_t = 400, value_parser = clap::value_parser!(u32).range(0..=1_000_000))]
    pub mesh_points: u32,
}

/// Arguments of `antumbra bench ssv`.
#[derive(Debug, Args)]
pub struct BenchSsvArgs {
    /// Mesh to put over the floor (Wavefront OBJ, +Y up); may be given more than
    /// once with --frame [default: the built-in bunny; with --frame the
    /// built-in bunny and armadillo].
    #[arg(long, value_name = "FILE.obj")]
    pub mesh: Vec<PathBuf>,

    /// Per-frame figures instead: a W × W ground of receivers reaching well
    /// beyond the mesh (not an occluder) plus receivers on the mesh, quad lights
    /// of side 1/4 and 4/5 of the mesh's extent, level, tilted 45° and at the
    /// side; per row the cold frame (creation and every query: what a scene
    /// whose light or objects move pays each frame), the warm frame (the
    /// queries again), Embree's frame (scene build and every shadow ray) and the
    /// hemicube's cold frame, all on one core, as ratios measured in the same
    /// run, with candidates per query, nodes, memory and the bits checked
    /// against Embree.
    #[arg(long)]
    pub frame: bool,

    /// With --frame: ground receivers, a W × W grid over ±1.5 mesh extents.
    #[arg(long, value_name = "W", default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=2048))]
    pub ground: u32,

    /// With --frame: time each frame this many times and keep the fastest.
    #[arg(long, value_name = "P", default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub passes: u32,

    /// With --frame: skip the hemicube's frame.
    #[arg(long)]
    pub no_hemicube: bool,

    /// Floor receivers: an N × N grid over [-1.5, 1.5]² (not with --frame).
    #[arg(long, value_name = "N", default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub floor_grid: u32,

    /// Mesh receivers (vertices spread evenly over the vertex order) [default:
    /// 100; 4096 with --frame].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=1_000_000))]
    pub mesh_points: Option<u32>,

    /// Time each warm figure over at least this many milliseconds (not with
    /// --frame).
    #[arg(long, value_name = "MS", default_value_t = 150)]
    pub min_time: u64,

    /// Skip the Embree figure (it needs the oracle's Python, see `verify ssv`).
    #[arg(long)]
    pub no_embree: bool,

    /// Hierarchy: subdivide a node holding more edges than this [default: the
    /// library's, `SsvOptions::default()`].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub leaf_edges: Option<u32>,

    /// Hierarchy: deepest level [default: the library's].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=24))]
    pub max_depth: Option<u32>,

    /// Only these sample counts (comma-separated) [default: 16,64,256,1024; with
    /// --frame the first one, default 256].
    #[arg(long, value_name = "N,N,...", value_delimiter = ',', value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub samples: Vec<u32>,
}

/// Mask quality on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum QualityArg {
    /// Per-row analytic half-space masks, exact at cell centers.
    Exact,
    /// The paper's precomputed half-space table (octant-folded, 2 MiB), with edges too
    /// short or too long for its precision rasterized exactly.
    Table,
}

/// Arguments of `antumbra verify hemi`.
#[derive(Debug, Args)]
pub struct VerifyHemiArgs {
    /// Mesh to check (Wavefront OBJ) [default: the built-in bunny].
    #[arg(long, value_name = "FILE.obj")]
    pub mesh: Option<PathBuf>,

    /// Half-space mask quality.
    #[arg(long, value_enum, default_value_t = QualityArg::Exact)]
    pub quality: QualityArg,

    /// Number of receivers (vertices spread evenly over the mesh's vertex order).
    #[arg(long, value_name = "N", default_value_t = 300, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub receivers: u32,
}

/// Arguments of `antumbra verify raycast`.
#[derive(Debug, Args)]
pub struct VerifyRaycastArgs {
    /// Mesh to check (Wavefront OBJ); repeat for several [default: the built-in
    /// bunny and teapot].
    #[arg(long, value_name = "FILE.obj")]
    pub mesh: Vec<PathBuf>,

    /// Random rays per mesh (at most 2^24, held in memory at once).
    #[arg(long, value_name = "N", default_value_t = 20_000, value_parser = clap::value_parser!(u32).range(1..=1 << 24))]
    pub rays: u32,

    /// Seed of the random rays.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,
}

/// `--texels`: `W` or `WxH`, each side 1..=16384.
fn parse_texels(text: &str) -> Result<(u32, u32), String> {
    let side = |s: &str| {
        s.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| (1..=antumbra_core::lightmap::MAX_ATLAS_SIDE).contains(n))
            .ok_or_else(|| {
                format!(
                    "{s:?} is not an atlas side in 1..={}",
                    antumbra_core::lightmap::MAX_ATLAS_SIDE
                )
            })
    };
    match text.split_once(['x', 'X']) {
        Some((w, h)) => Ok((side(w)?, side(h)?)),
        None => side(text).map(|w| (w, w)),
    }
}

/// `--ray-offset`: a finite distance of 0 or more, as the C API's `ray_offset`.
fn parse_ray_offset(text: &str) -> Result<f32, String> {
    let value: f32 = text.parse().map_err(|e| format!("{e}"))?;
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(format!("{value} is not a finite distance of 0 or more"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn command_line_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn bake_ray_offset_defaults_to_the_libraries_default() {
        let cli = Cli::try_parse_from(["antumbra", "bake", "--mesh", "m.obj", "-o", "x"]).unwrap();
        let Command::Bake(args) = cli.command else {
            panic!("not a bake");
        };
        assert_eq!(args.ray_offset, crate::prt::default_ray_offset());
        assert!(parse_ray_offset("-1").is_err());
        assert!(parse_ray_offset("nan").is_err());
    }

    #[test]
    fn bake_help_gives_the_ray_offset_one_unit() {
        let mut command = Cli::command();
        let help = command
            .find_subcommand_mut("bake")
            .expect("a bake subcommand")
            .render_long_help()
            .to_string();
        // One paragraph per idea in the rendered help, its lines joined.
        let flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
        assert!(
            flat.contains("Move ray origins this far along the vertex normal, in mesh units"),
            "the flag's own help names its unit:\n{help}"
        );
        // The description says how far rays are pushed off only through the
        // flag, never in another unit.
        for paragraph in [
            "their origins moved `--ray-offset` mesh units along it",
            "moved `--ray-offset` mesh units along its smooth normal",
        ] {
            assert!(flat.contains(paragraph), "missing {paragraph:?}:\n{help}");
        }
        assert!(
            !flat.contains("of the bounding-box diagonal"),
            "the bake's help must not give the offset relative to the diagonal:\n{help}"
        );
    }
}

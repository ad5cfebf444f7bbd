//! `antumbra demo`: renders a set of pictures from built-in data and prints where
//! each went and how long it took.
//!
//! Each picture is a module with a `PICTURE` constant; adding one to the demo is
//! a new module plus one line in [`PICTURES`]. Shared inputs (the bunny scene, the
//! sky, the hemispherical-rasterization stage of [`hemi`]) are loaded on first use
//! through [`DemoContext`].

mod ambient_occlusion;
mod environment_lighting;
mod environment_preview;
pub(super) mod hemi;
mod hemi_diffuse;
mod hemi_glossy;
mod hemi_twist;
pub(super) mod lightmap;
mod mrt_relit;
mod soft_shadows;

use std::cell::OnceCell;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::{absolute, format_duration};
use crate::bounds::Bounds;
use crate::builtin;
use crate::camera::{Camera, ViewAngles};
use crate::cli::DemoArgs;
use crate::envmap::{EnvironmentMap, EnvironmentSampler};
use crate::error::Result;
use crate::picture::save_png;
use crate::scene::Scene;

/// Every picture of the demo, in the order they are rendered.
const PICTURES: &[DemoPicture] = &[
    ambient_occlusion::PICTURE,
    environment_lighting::PICTURE,
    environment_preview::PICTURE,
    hemi_diffuse::PICTURE,
    hemi_glossy::PICTURE,
    hemi_twist::PICTURE,
    mrt_relit::PICTURE,
    lightmap::PICTURE,
    soft_shadows::PICTURE,
    soft_shadows::DIFFERENCE,
];

/// Where the bunny is seen from, in degrees around +Y (0 = from +Z): the sunrise
/// sun (azimuth about 54° in these terms) then lights it from the side, casting
/// a long shadow across the ground.
const BUNNY_VIEW_AZIMUTH_DEG: f32 = -20.0;

/// One picture of the demo.
struct DemoPicture {
    /// File name inside the output folder.
    file_name: &'static str,
    /// What the picture shows, for the summary.
    title: &'static str,
    /// Renders the finished 8-bit picture, and a short note on how (e.g. samples).
    render: fn(&DemoContext) -> Result<(image::RgbImage, String)>,
}

/// Inputs shared by the pictures, built when first asked for.
struct DemoContext {
    /// Picture width requested on the command line.
    size: u32,
    bunny: OnceCell<Scene>,
    sky: OnceCell<(EnvironmentMap, EnvironmentSampler)>,
    hemi_stage: OnceCell<hemi::HemiStage>,
    ssv_stage: OnceCell<soft_shadows::SsvStage>,
}

impl DemoContext {
    fn new(size: u32) -> Self {
        DemoContext {
            size,
            bunny: OnceCell::new(),
            sky: OnceCell::new(),
            hemi_stage: OnceCell::new(),
            ssv_stage: OnceCell::new(),
        }
    }

    /// Size of the rendered pictures: the requested width, 4:3.
    fn render_size(&self) -> (usize, usize) {
        let width = self.size as usize;
        (width, (width * 3 / 4).max(1))
    }

    /// The camera both bunny pictures share: three-quarter view from slightly
    /// above, the bunny filling most of the frame.
    fn bunny_camera(&self, scene: &Scene) -> Camera {
        self.bunny_camera_for(&scene.object_bounds())
    }

    /// The bunny pictures' view of an object with these bounds.
    fn bunny_camera_for(&self, bounds: &Bounds) -> Camera {
        let (width, height) = self.render_size();
        let view = ViewAngles {
            azimuth: BUNNY_VIEW_AZIMUTH_DEG.to_radians(),
            elevation: 22f32.to_radians(),
            vertical_fov: 35f32.to_radians(),
        };
        Camera::framing(bounds, view, width as f32 / height as f32, 0.08)
    }

    /// The built-in bunny on a ground plane, in a BVH.
    fn bunny_scene(&self) -> Result<&Scene> {
        if let Some(scene) = self.bunny.get() {
            return Ok(scene);
        }
        let scene = Scene::new(&builtin::bunny()?, true)?;
        Ok(self.bunny.get_or_init(|| scene))
    }

    /// The built-in bunny on a ground with its far mesh, the sunrise in SH and the
    /// shading tables, for the hemispherical-rasterization pictures.
    fn hemi_stage(&self) -> Result<&hemi::HemiStage> {
        if let Some(stage) = self.hemi_stage.get() {
            return Ok(stage);
        }
        let (env, _) = self.sky()?;
        let stage = hemi::HemiStage::new(builtin::bunny()?, env)?;
        Ok(self.hemi_stage.get_or_init(|| stage))
    }

    /// The built-in sunrise sky and its importance sampler.
    fn sky(&self) -> Result<&(EnvironmentMap, EnvironmentSampler)> {
        if let Some(sky) = self.sky.get() {
            return Ok(sky);
        }
        let env = builtin::sunrise()?;
        let sampler = EnvironmentSampler::new(&env);
        Ok(self.sky.get_or_init(|| (env, sampler)))
    }
}

/// What the summary prints about one written picture.
struct Written {
    path: PathBuf,
    width: u32,
    height: u32,
    elapsed: Duration,
    title: &'static str,
    note: String,
}

/// Renders every picture into `args.out` and prints the summary.
pub fn run(args: &DemoArgs) -> Result<()> {
    let started = Instant::now();
    let context = DemoContext::new(args.size);
    let out_dir = absolute(&args.out);
    let threads = rayon::current_num_threads();
    println!(
        "antumbra demo: {} pictures, {} px wide, on {threads} thread{}",
        PICTURES.len(),
        args.size,
        if threads == 1 { "" } else { "s" }
    );
    let mut written = Vec::new();
    for picture in PICTURES {
        let begun = Instant::now();
        let (image, note) = (picture.render)(&context)?;
        let path = out_dir.join(picture.file_name);
        save_png(&image, &path)?;
        written.push(Written {
            path,
            width: image.width(),
            height: image.height(),
            elapsed: begun.elapsed(),
            title: picture.title,
            note,
        });
    }
    print_summary(&written, &out_dir, started.elapsed());
    Ok(())
}

fn print_summary(written: &[Written], out_dir: &Path, total: Duration) {
    println!("wrote {} pictures to {}:", written.len(), out_dir.display());
    for item in written {
        println!(
            "  {:>9}  {:>9}  {}",
            format!("{}x{}", item.width, item.height),
            format_duration(item.elapsed),
            item.path.display()
        );
        println!("{:24}{} ({})", "", item.title, item.note);
    }
    println!("total {} (data loading included)", format_duration(total));
}

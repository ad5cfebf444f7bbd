//! Demo pictures: the bunny over a floor under a quad light, soft shadows from 256
//! light samples found by the 2006 wedge hierarchy (`antumbra_core::ssv`), and the
//! difference image against tracing the same 256 shadow rays per pixel.
//!
//! The scene is the cross-check scene of `verify ssv` ([`FloorScene`]: the bunny
//! scaled to a largest extent of 1, 0.05 above a 4 × 4 floor, a 0.5 × 0.5 light
//! tilted 45°). One primary ray per pixel; the receiver is the hit point lifted
//! 1e-4 along the geometric normal (towards the camera); its radiance is
//! `albedo · (visible / N) · cos θ · cos θ_light / d²` to the light's centroid,
//! plus a dim constant ambient term so that the umbra is not black.

use std::cell::OnceCell;
use std::time::{Duration, Instant};

use antumbra_core::raycast::BvhScene;
use antumbra_core::ssv::{LightPolygon, SamplePattern, SoftShadows, SsvOptions, Structure};
use antumbra_core::{MeshView, Ray, RayCaster};
use antumbra_tests::scenes::{FloorScene, LightOrientation};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::{DemoContext, DemoPicture};
use crate::bounds::Bounds;
use crate::builtin;
use crate::camera::{Camera, ViewAngles};
use crate::commands::format_duration;
use crate::error::{Error, Result};
use crate::picture::HdrImage;
use crate::progress;
use crate::tonemap::{luminance, to_srgb8_auto};

/// Light samples per pixel.
const SAMPLES: usize = 256;
/// Seed of the jittered samples.
const SEED: u64 = 0x5eed;
/// How far receivers are lifted off the surface they were found on.
const LIFT: f32 = 1e-4;
/// Diffuse reflectance of the bunny and of the floor.
const BUNNY_ALBEDO: Vec3 = Vec3::new(0.80, 0.78, 0.74);
const FLOOR_ALBEDO: Vec3 = Vec3::splat(0.55);
/// Constant ambient irradiance relative to the light's direct term at the floor's centre.
const AMBIENT: f32 = 0.06;
/// Radiance of pixels that see nothing.
const BACKGROUND: Vec3 = Vec3::new(0.015, 0.016, 0.02);

/// The soft-shadow picture.
pub(super) const PICTURE: DemoPicture = DemoPicture {
    file_name: "bunny-soft-shadows.png",
    title: "bunny over a floor under a tilted quad light: exact soft shadows, 256 light samples per pixel, wedge hierarchy (soft shadow volumes)",
    render: render_picture,
};

/// The difference picture.
pub(super) const DIFFERENCE: DemoPicture = DemoPicture {
    file_name: "bunny-soft-shadows-difference.png",
    title: "difference of the soft shadows against 256 traced shadow rays per pixel: red where any of the 256 bits differs",
    render: render_difference,
};

/// What both pictures are made from, computed once.
pub(super) struct SsvStage {
    width: usize,
    height: usize,
    /// Linear radiance per pixel.
    radiance: Vec<Vec3>,
    /// Per pixel: seen surface, and whether its bits differ from ray tracing.
    differs: Vec<bool>,
    /// Pixels that see a surface.
    receivers: usize,
    hierarchy_time: Duration,
    ray_time: Duration,
    nodes: usize,
    bytes: usize,
}

/// The stage, computed on first use.
pub(super) fn stage(context: &DemoContext) -> Result<&SsvStage> {
    let cell: &OnceCell<SsvStage> = &context.ssv_stage;
    if let Some(stage) = cell.get() {
        return Ok(stage);
    }
    let stage = SsvStage::new(context.render_size())?;
    Ok(cell.get_or_init(|| stage))
}

/// A pixel's receiver: where the primary ray hits, lifted, and how to shade it.
#[derive(Clone, Copy)]
struct Receiver {
    point: Vec3,
    normal: Vec3,
    albedo: Vec3,
}

impl SsvStage {
    fn new((width, height): (usize, usize)) -> Result<SsvStage> {
        let bunny = builtin::bunny()?;
        let scene = FloorScene::new(
            bunny.positions(),
            bunny.indices(),
            LightOrientation::Tilted,
            1,
            0,
        );
        let light = LightPolygon::new(&scene.light).map_err(|e| Error::msg(e.to_string()))?;
        let samples = light.samples(SAMPLES, SamplePattern::Jittered, SEED);
        let view = scene.occluders.view();
        let make = |structure| {
            let options = SsvOptions {
                structure,
                ..SsvOptions::default()
            };
            SoftShadows::new(&view, light.clone(), &samples, options)
                .map_err(|e| Error::msg(format!("cannot prepare the soft shadows: {e}")))
        };
        let hierarchy = make(Structure::Hierarchy)?;
        let rays = make(Structure::RayTrace)?;
        let receivers = primary_hits(&scene, &view, width, height)?;
        let words = hierarchy.words_per_receiver();
        let bar = progress::bar(2 * height as u64, "soft shadows", "rows");
        let (hierarchy_bits, hierarchy_time) = query_all(&hierarchy, &receivers, width, &bar)?;
        let (ray_bits, ray_time) = query_all(&rays, &receivers, width, &bar)?;
        bar.finish_and_clear();
        let centroid = light.centroid();
        let light_normal = light.normal();
        // Scale so that an unshadowed floor point under the light's centre gets 1.
        let reference = {
            let to = centroid - Vec3::ZERO;
            to.normalize().y * to.normalize().dot(light_normal).abs() / to.length_squared()
        };
        let mut differs = vec![false; width * height];
        let radiance = receivers
            .iter()
            .enumerate()
            .map(|(k, r)| {
                let Some(r) = r else { return BACKGROUND };
                let bits = &hierarchy_bits[k * words..(k + 1) * words];
                differs[k] = bits != &ray_bits[k * words..(k + 1) * words];
                let visible = bits.iter().map(|w| w.count_ones()).sum::<u32>() as f32;
                let to = centroid - r.point;
                let l = to.normalize_or_zero();
                let direct = (visible / SAMPLES as f32)
                    * r.normal.dot(l).max(0.0)
                    * l.dot(light_normal).abs()
                    / to.length_squared()
                    / reference;
                r.albedo * (direct + AMBIENT)
            })
            .collect();
        let stats = hierarchy.statistics();
        Ok(SsvStage {
            width,
            height,
            radiance,
            differs,
            receivers: receivers.iter().flatten().count(),
            hierarchy_time,
            ray_time,
            nodes: stats.nodes,
            bytes: stats.bytes,
        })
    }

    fn differing(&self) -> usize {
        self.differs.iter().filter(|&&d| d).count()
    }
}

/// The receiver seen through each pixel centre, row-major.
fn primary_hits(
    scene: &FloorScene,
    view: &MeshView<'_>,
    width: usize,
    height: usize,
) -> Result<Vec<Option<Receiver>>> {
    let bvh = BvhScene::new(view).map_err(|e| Error::msg(e.to_string()))?;
    let bounds = Bounds {
        min: Vec3::new(-1.3, 0.0, -1.3),
        max: Vec3::new(1.3, 1.05, 1.3),
    };
    let angles = ViewAngles {
        azimuth: 115f32.to_radians(),
        elevation: 38f32.to_radians(),
        vertical_fov: 35f32.to_radians(),
    };
    let camera = Camera::framing(&bounds, angles, width as f32 / height as f32, 0.0);
    let origin = camera.position();
    let triangles = scene.occluders.indices.len() / 3;
    Ok((0..width * height)
        .into_par_iter()
        .map(|k| {
            let pixel = Vec2::new(
                ((k % width) as f32 + 0.5) / width as f32,
                ((k / width) as f32 + 0.5) / height as f32,
            );
            let direction = camera.direction(pixel);
            let hit = bvh.closest_hit(&Ray::new(origin, direction, f32::INFINITY))?;
            let [a, b, c] = view.triangle(hit.triangle as usize);
            let mut normal = (b - a).cross(c - a).normalize_or_zero();
            if normal.dot(direction) > 0.0 {
                normal = -normal;
            }
            let point = a + (b - a) * hit.u + (c - a) * hit.v + normal * LIFT;
            let albedo = if (hit.triangle as usize) < triangles - 2 {
                BUNNY_ALBEDO
            } else {
                FLOOR_ALBEDO
            };
            Some(Receiver {
                point,
                normal,
                albedo,
            })
        })
        .collect())
}

/// Bits of every receiver (all zero where there is none), and the time taken.
fn query_all(
    ssv: &SoftShadows,
    receivers: &[Option<Receiver>],
    width: usize,
    bar: &indicatif::ProgressBar,
) -> Result<(Vec<u64>, Duration)> {
    let words = ssv.words_per_receiver();
    let mut bits = vec![0u64; receivers.len() * words];
    let started = Instant::now();
    bits.par_chunks_mut(width * words)
        .zip(receivers.par_chunks(width))
        .try_for_each(|(row_bits, row)| {
            for (out, r) in row_bits.chunks_mut(words).zip(row) {
                if let Some(r) = r {
                    ssv.query(r.point, out)?;
                }
            }
            bar.inc(1);
            Ok(())
        })
        .map_err(|e: antumbra_core::ssv::SsvError| Error::msg(format!("query failed: {e}")))?;
    Ok((bits, started.elapsed()))
}

fn render_picture(context: &DemoContext) -> Result<(image::RgbImage, String)> {
    let stage = stage(context)?;
    let image = HdrImage::from_pixels(stage.width, stage.height, stage.radiance.clone());
    let note = format!(
        "{SAMPLES} samples; {} receivers in {} with the hierarchy ({} nodes, {:.1} MiB), {} tracing {SAMPLES} rays each ({:.1}x)",
        stage.receivers,
        format_duration(stage.hierarchy_time),
        stage.nodes,
        stage.bytes as f64 / (1 << 20) as f64,
        format_duration(stage.ray_time),
        stage.ray_time.as_secs_f64() / stage.hierarchy_time.as_secs_f64().max(1e-9)
    );
    Ok((to_srgb8_auto(&image), note))
}

fn render_difference(context: &DemoContext) -> Result<(image::RgbImage, String)> {
    let stage = stage(context)?;
    let grey = to_srgb8_auto(&HdrImage::from_pixels(
        stage.width,
        stage.height,
        stage
            .radiance
            .iter()
            .map(|&c| Vec3::splat(luminance(c) * 0.5))
            .collect(),
    ));
    let mut image = grey;
    for (k, &differs) in stage.differs.iter().enumerate() {
        if differs {
            let (x, y) = ((k % stage.width) as u32, (k / stage.width) as u32);
            image.put_pixel(x, y, image::Rgb([255, 0, 0]));
        }
    }
    let differing = stage.differing();
    println!(
        "soft shadows against ray tracing: {differing} of {} pixels differ in any of their {SAMPLES} bits",
        stage.receivers
    );
    let note = format!(
        "{differing} of {} pixels differ in any of their {SAMPLES} visibility bits",
        stage.receivers
    );
    Ok((image, note))
}

//! Building the soft shadows of a light over a set of occluders: the welded
//! edges, the samples' angular order, the near-light band and the chosen
//! structure.

use super::*;

/// The default root box: a cube about the bounds of the occluders and the
/// light, twice their largest extent on a side.
pub(super) fn default_root(occluders: &MeshView<'_>, light: &LightPolygon) -> Aabb {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for &v in occluders.indices() {
        let p = occluders.position(v as usize).as_dvec3();
        lo = lo.min(p);
        hi = hi.max(p);
    }
    for v in light.vertices() {
        lo = lo.min(v.as_dvec3());
        hi = hi.max(v.as_dvec3());
    }
    // A cube about the bounds' centre, half again their largest extent on
    // every side: octree cells then stay cubes (a tall root over a
    // ground made tall, thin cells that the lists shrank slowly in).
    let centre = 0.5 * (lo + hi);
    let half = (hi - lo).max_element().max(1e-30);
    Aabb {
        min: centre - DVec3::splat(half),
        max: centre + DVec3::splat(half),
    }
}

/// The light's plane: a point, the normal, axes in the plane, and the light's
/// polygon in those axes with its bounding rectangle.
struct LightPlane {
    point: DVec3,
    normal: DVec3,
    u_axis: DVec3,
    v_axis: DVec3,
    /// The light's vertices in `(u, v)`.
    uv: Vec<(f64, f64)>,
    /// `(u_min, u_max, v_min, v_max)` of `uv`.
    uv_box: (f64, f64, f64, f64),
    tolerance: f64,
}

impl LightPlane {
    fn of(light: &LightPolygon) -> Result<Self, OutOfMemory> {
        let point = light.centroid().as_dvec3();
        let normal = light.normal().as_dvec3();
        let (u_axis, v_axis) = normal.any_orthonormal_pair();
        let uv: Vec<(f64, f64)> = fallible::collect(light.vertices().iter().map(|v| {
            let d = v.as_dvec3() - point;
            (d.dot(u_axis), d.dot(v_axis))
        }))?;
        let uv_box = uv.iter().fold(
            (
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ),
            |(u0, u1, v0, v1), &(u, v)| (u0.min(u), u1.max(u), v0.min(v), v1.max(v)),
        );
        Ok(LightPlane {
            point,
            normal,
            u_axis,
            v_axis,
            uv,
            uv_box,
            tolerance: f64::from(light.tolerance()),
        })
    }

    /// Half the width of the band about the plane: it holds the light's
    /// vertices (planar within the tolerance) and the samples (on the plane
    /// within the tolerance), with room to spare.
    fn band_half_width(&self) -> f64 {
        4.0 * self.tolerance
    }

    /// `d` (relative to the plane's point) in the plane's axes.
    fn uv(&self, d: DVec3) -> (f64, f64) {
        (d.dot(self.u_axis), d.dot(self.v_axis))
    }
}

/// The occluders sorted by where they lie against the light's plane.
struct SortedOccluders {
    /// Triangles clear of the band about the plane, or whose footprint misses
    /// the light's: indices into the occluders' positions.
    regular: Vec<[u32; 3]>,
    /// Triangles in the band over the light: tested against every sample.
    near_light: Vec<[Vec3; 3]>,
    /// Every triangle in the band (for receivers in it).
    band: Vec<[Vec3; 3]>,
    /// The box of the non-degenerate occluders, if any.
    bounds: Option<(DVec3, DVec3)>,
}

impl SortedOccluders {
    fn new(occluders: &MeshView<'_>, plane: &LightPlane) -> Result<Self, OutOfMemory> {
        let band_half_width = plane.band_half_width();
        let margin = 4.0 * plane.tolerance;
        let (umin, umax, vmin, vmax) = plane.uv_box;
        // (Within its capacity: pushing allocates nothing.)
        let mut regular: Vec<[u32; 3]> = fallible::with_capacity(occluders.triangle_count())?;
        let mut near_light = Vec::new();
        let mut band = Vec::new();
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for (t, tri) in occluders.triangles().enumerate() {
            if edges::degenerate(tri[0], tri[1], tri[2]) {
                continue;
            }
            for v in tri {
                lo = lo.min(v.as_dvec3());
                hi = hi.max(v.as_dvec3());
            }
            let heights = tri.map(|v| (v.as_dvec3() - plane.point).dot(plane.normal));
            let (hmin, hmax) = (
                heights[0].min(heights[1]).min(heights[2]),
                heights[0].max(heights[1]).max(heights[2]),
            );
            if hmin > band_half_width || hmax < -band_half_width {
                regular.push(occluders.triangle_indices(t));
                continue;
            }
            fallible::push(&mut band, tri)?;
            // Conservative: the triangle's footprint box in the plane against the
            // light's, both grown by the margin.
            let (mut tu0, mut tu1, mut tv0, mut tv1) = (
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            );
            for v in tri {
                let (u, w) = plane.uv(v.as_dvec3() - plane.point);
                tu0 = tu0.min(u);
                tu1 = tu1.max(u);
                tv0 = tv0.min(w);
                tv1 = tv1.max(w);
            }
            if tu0 > umax + margin
                || tu1 < umin - margin
                || tv0 > vmax + margin
                || tv1 < vmin - margin
            {
                regular.push(occluders.triangle_indices(t));
            } else {
                fallible::push(&mut near_light, tri)?;
            }
        }
        Ok(SortedOccluders {
            regular,
            near_light,
            band,
            bounds: lo.cmple(hi).all().then_some((lo, hi)),
        })
    }
}

/// The samples in their angular order about the light's centroid
/// (receiver-independent), with what the sweep reads per sample in that order.
struct SampleOrder {
    /// Sample indices: by angle, then the central ones.
    order: Vec<u32>,
    /// Position of each sample in `order`.
    rank: Vec<u32>,
    /// Pseudo-angles of the non-central samples, ascending.
    angles: Vec<f64>,
    /// Per angle bucket, the first entry of `angles` in it.
    angle_starts: Vec<u32>,
    /// Distance within which a sample counts as central.
    angle_radius: f64,
    /// Farthest sample from the plane.
    offset: f64,
    /// Each sample's inset into the light polygon, in `order`.
    insets: Vec<f64>,
    /// x, y and z of the samples in `order`.
    soa: [Vec<f64>; 3],
    /// The same in `f32`, with eight zeros after the last sample.
    soa32: [Vec<f32>; 3],
    /// The samples' bounding box.
    bounds: (DVec3, DVec3),
}

impl SampleOrder {
    fn new(
        samples: &[Vec3],
        light: &LightPolygon,
        plane: &LightPlane,
    ) -> Result<Self, OutOfMemory> {
        let angle_radius = 1e-3 * f64::from(light.diameter());
        let mut keyed: Vec<(f64, u32)> = fallible::with_capacity(samples.len())?;
        let mut central: Vec<u32> = Vec::new();
        let mut offset: f64 = 0.0;
        for (i, s) in samples.iter().enumerate() {
            let d = s.as_dvec3() - plane.point;
            offset = offset.max(d.dot(plane.normal).abs());
            let (x, y) = plane.uv(d);
            if libm::hypot(x, y) < angle_radius {
                fallible::push(&mut central, i as u32)?;
            } else {
                keyed.push((pseudo_angle(x, y), i as u32));
            }
        }
        // Unstable sort (no scratch memory): the index breaks every tie.
        keyed.sort_unstable_by(|p, q| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1)));
        let angles: Vec<f64> = fallible::collect(keyed.iter().map(|k| k.0))?;
        let angle_starts = fallible::collect(
            (0..=ANGLE_BUCKETS)
                .map(|k| angles.partition_point(|&t| t < k as f64 / ANGLE_SCALE) as u32),
        )?;
        let mut order: Vec<u32> = fallible::with_capacity(samples.len())?;
        order.extend(keyed.iter().map(|k| k.1).chain(central));
        let uv = &plane.uv;
        let twice_area: f64 = (0..uv.len())
            .map(|i| {
                let ((x0, y0), (x1, y1)) = (uv[i], uv[(i + 1) % uv.len()]);
                x0 * y1 - x1 * y0
            })
            .sum();
        let orientation = if twice_area < 0.0 { -1.0 } else { 1.0 };
        let insets = fallible::collect(order.iter().map(|&o| {
            inset(
                uv,
                orientation,
                samples[o as usize].as_dvec3() - plane.point,
                plane.u_axis,
                plane.v_axis,
            )
        }))?;
        let axis = |axis: usize| {
            fallible::collect(order.iter().map(|&o| f64::from(samples[o as usize][axis])))
        };
        let soa = [axis(0)?, axis(1)?, axis(2)?];
        // The sample pass reads eight from any sample on.
        let padded = order.len() + 8;
        let axis32 = |axis: usize| {
            fallible::collect(
                (0..padded).map(|k| order.get(k).map_or(0.0, |&o| samples[o as usize][axis])),
            )
        };
        let soa32 = [axis32(0)?, axis32(1)?, axis32(2)?];
        let bounds = samples.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), s| (lo.min(s.as_dvec3()), hi.max(s.as_dvec3())),
        );
        let mut rank = fallible::filled(0u32, order.len())?;
        for (k, &i) in order.iter().enumerate() {
            rank[i as usize] = k as u32;
        }
        Ok(SampleOrder {
            order,
            rank,
            angles,
            angle_starts,
            angle_radius,
            offset,
            insets,
            soa,
            soa32,
            bounds,
        })
    }
}

/// The structure that finds a receiver's candidate edges.
type Structures = (Option<Hierarchy>, Option<Box<Hemicube>>);

impl SoftShadows {
    /// Prepares the occluders for `light` and `samples` (validated: on the light
    /// within [`LightPolygon::tolerance`], 1 to [`MAX_SAMPLES`] of them; make them
    /// with [`LightPolygon::samples`]).
    ///
    /// With the `bvh` feature the reference caster is an owned `BvhScene`
    /// (obvhs); without it a brute-force loop over
    /// the triangles (correct, but linear per query).
    pub fn new(
        occluders: &MeshView<'_>,
        light: LightPolygon,
        samples: &[Vec3],
        options: SsvOptions,
    ) -> Result<Self, SsvError> {
        check(&light, samples, &options)?;
        Self::build(occluders, light, fallible::copied(samples)?, options, None)
    }

    /// Moves the occluders to `occluders` (the mesh moved or deformed, or
    /// another mesh altogether), keeping the light, the samples and the
    /// options: every query afterwards answers exactly as a structure made by
    /// [`SoftShadows::new`] from `occluders` would. Cheaper than that: with the
    /// `bvh` feature the reference ray's BVH is refitted to the new positions
    /// when the occluders keep their number of (welded, non-degenerate)
    /// triangles, instead of built again (the rest, which depends on where the
    /// edges are, is made anew). The statistics restart.
    ///
    /// Fails as [`SoftShadows::new`] does, leaving the structure as it was.
    pub fn update(&mut self, occluders: &MeshView<'_>) -> Result<(), SsvError> {
        let light = self.light.clone();
        let samples = fallible::copied(&self.samples)?;
        let options = self.options;
        *self = Self::build(occluders, light, samples, options, Some(&mut self.caster))?;
        Ok(())
    }

    /// [`SoftShadows::new`] with the light, samples and options checked (by
    /// [`check`]), the reference caster made from `previous` when given
    /// ([`Caster::refitted`], after every step that can fail, so that a failure
    /// leaves it untouched).
    fn build(
        occluders: &MeshView<'_>,
        light: LightPolygon,
        samples: Vec<Vec3>,
        options: SsvOptions,
        previous: Option<&mut Caster>,
    ) -> Result<Self, SsvError> {
        let plane = LightPlane::of(&light)?;
        let sorted = SortedOccluders::new(occluders, &plane)?;
        let positions: Vec<Vec3> =
            fallible::collect((0..occluders.vertex_count()).map(|v| occluders.position(v)))?;
        #[cfg_attr(not(all(target_arch = "x86_64", feature = "std")), allow(unused_mut))]
        let mut graph = EdgeGraph::from_indexed(&positions, &sorted.regular)?;
        // The set-up lanes' records, where they run.
        #[cfg(all(target_arch = "x86_64", feature = "std"))]
        if crate::simd::avx_available() {
            graph.make_lane_records()?;
        }
        let potential: Vec<u32> = fallible::collect(
            (0..graph.edges.len() as u32).filter(|&e| !graph.is_flat(&graph.edges[e as usize])),
        )?;
        let shape = LightShape {
            vertices: fallible::collect(light.vertices().iter().map(|v| v.as_dvec3()))?,
            normal: plane.normal,
            tolerance: plane.tolerance,
        };
        // A new reference caster and the structure, side by side on rayon's
        // threads with `options.parallel`; one made from `previous` comes last.
        let structure = || structures(occluders, &light, &graph, &shape, &potential, &options);
        let build_caster = || match previous {
            None => Self::build_caster(&graph).map(Some),
            Some(_) => Ok(None),
        };
        #[cfg(feature = "parallel")]
        let (caster, structures) = if options.parallel {
            rayon::join(build_caster, structure)
        } else {
            (build_caster(), structure())
        };
        #[cfg(not(feature = "parallel"))]
        let (caster, structures) = (build_caster(), structure());
        let caster = caster?;
        let (hierarchy, hemicube) = structures?;
        let sampled = SampleOrder::new(&samples, &light, &plane)?;
        let words = samples.len().div_ceil(64);
        let SortedOccluders {
            near_light,
            band,
            bounds: occluder_box,
            ..
        } = sorted;
        let near_sides = plane_sides(&near_light, &samples, words)?;
        let band_sides = plane_sides(&band, &samples, words)?;
        let near_planes = fallible::collect(near_light.iter().map(AxisPlane::of))?;
        let band_planes = fallible::collect(band.iter().map(AxisPlane::of))?;
        let band_half_width = plane.band_half_width();
        // Nothing fails after the caster: `previous` is only taken then.
        let caster = match (caster, previous) {
            (Some(caster), _) => caster,
            (None, Some(previous)) => previous.refitted(&graph)?,
            (None, None) => Self::build_caster(&graph)?,
        };
        Ok(SoftShadows {
            occluder_box,
            insets: sampled.insets,
            soa: sampled.soa,
            soa32: sampled.soa32,
            near_sides,
            band_sides,
            near_planes,
            band_planes,
            sample_lo: sampled.bounds.0,
            sample_hi: sampled.bounds.1,
            rank: sampled.rank,
            order: sampled.order,
            angles: sampled.angles,
            angle_starts: sampled.angle_starts,
            u_axis: plane.u_axis,
            v_axis: plane.v_axis,
            angle_radius: sampled.angle_radius,
            sample_offset: sampled.offset,
            shape_diameter: f64::from(light.diameter()),
            centroid: light.centroid(),
            light,
            samples,
            structure: options.structure,
            options,
            graph,
            potential,
            near_light,
            band,
            caster,
            shape,
            plane_normal: plane.normal,
            plane_point: plane.point,
            band_half_width,
            hierarchy,
            hemicube,
            queries: AtomicUsize::new(0),
            candidates: AtomicUsize::new(0),
        })
    }
}

/// The sample count and the options [`SoftShadows::new`] accepts.
fn check(light: &LightPolygon, samples: &[Vec3], options: &SsvOptions) -> Result<(), SsvError> {
    if samples.is_empty() || samples.len() > MAX_SAMPLES {
        return Err(SsvError::SampleCount {
            count: samples.len(),
        });
    }
    light.validate_samples(samples)?;
    if options.leaf_edges == 0
        || options.hemicube_resolution == 0
        || options.hemicube_resolution > 1024
        || options
            .root_bounds
            .is_some_and(|[lo, hi]| !(lo.is_finite() && hi.is_finite() && lo.cmplt(hi).all()))
    {
        return Err(SsvError::InvalidOptions);
    }
    Ok(())
}

/// The structure `options` asks for, over the potential silhouette edges.
fn structures(
    occluders: &MeshView<'_>,
    light: &LightPolygon,
    graph: &EdgeGraph,
    shape: &LightShape,
    potential: &[u32],
    options: &SsvOptions,
) -> Result<Structures, OutOfMemory> {
    Ok(match options.structure {
        Structure::Hierarchy => {
            let root = match options.root_bounds {
                Some([lo, hi]) => Aabb {
                    min: lo.as_dvec3(),
                    max: hi.as_dvec3(),
                },
                None => default_root(occluders, light),
            };
            let hierarchy = Hierarchy::new(graph, shape, potential, root, *options)?;
            (Some(hierarchy), None)
        }
        Structure::Hemicube => {
            let hemicube = Hemicube::new(
                graph,
                shape,
                potential,
                light.centroid().as_dvec3(),
                options.hemicube_resolution as usize,
            );
            (None, Some(Box::new(hemicube)))
        }
        Structure::BruteForce | Structure::RayTrace => (None, None),
    })
}

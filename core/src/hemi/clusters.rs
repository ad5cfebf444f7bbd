//! Triangle clusters of a deforming mesh: the triangles grouped once by
//! recursive splits of their centroids across the longest side of their box
//! (a k-d order), each cluster split into chunks with their
//! own vertex lists, and the boxes recomputed every frame
//! ([`TriangleClusters::update`]) with a hierarchy of boxes above them. A
//! receiver skips whole nodes below its horizon or behind the cells it has
//! already covered; the traversal that reads them is in the `lod` module.

use alloc::vec::Vec;

use glam::Vec3;

use crate::geom::MeshView;

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Smallest coordinates.
    pub min: Vec3,
    /// Largest coordinates.
    pub max: Vec3,
}

impl Aabb {
    /// The box that contains nothing (`min = +inf`, `max = -inf`).
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::INFINITY,
        max: Vec3::NEG_INFINITY,
    };

    #[inline]
    fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// Whether every point `x` of the box has `n.dot(x - o) <= 0` as evaluated in
    /// `f32` (the per-triangle horizon test): true when the corner maximising it
    /// does (see the module docs for why that is exact).
    #[inline(always)]
    pub(super) fn below_plane(&self, n: Vec3, o: Vec3) -> bool {
        let q = Vec3::select(n.cmpge(Vec3::ZERO), self.max, self.min);
        n.dot(q - o) <= 0.0
    }

    /// The squared distance from `p` to the nearest point of the box: the
    /// nearest bound of [`Aabb::distance_range_sq`].
    #[inline(always)]
    pub(super) fn distance_sq(&self, p: Vec3) -> f32 {
        (p.clamp(self.min, self.max) - p).length_squared()
    }

    /// The squared distances from `p` to the nearest and farthest point of the
    /// box, each as a lower or upper bound of `(c - p).length_squared()` in `f32`
    /// for every point `c` of the box.
    #[inline(always)]
    pub(super) fn distance_range_sq(&self, p: Vec3) -> (f32, f32) {
        let lo = self.min - p;
        let hi = self.max - p;
        let far = lo.abs().max(hi.abs());
        (self.distance_sq(p), far.length_squared())
    }
}

/// Triangles grouped into clusters of nearby triangles, with each cluster's
/// bounding box for the current frame: lets a receiver skip whole clusters below
/// its horizon (see the module docs).
///
/// The grouping (a k-d order of the triangle centroids) is computed once from
/// the positions given to [`TriangleClusters::new`] (the rest pose) and kept while
/// the mesh deforms; the boxes are recomputed every frame by
/// [`TriangleClusters::update`], which is the only way to get a
/// [`ClusteredMesh`], so boxes and positions always belong together.
#[derive(Clone, Debug)]
pub struct TriangleClusters {
    pub(super) size: usize,
    /// Triangle indices in cluster order: the triangles of ordinary size,
    /// then, from `large_start`, those far larger than their neighbours
    /// ([`LARGE_EXTENT`]), each group in its own clusters.
    pub(super) order: Vec<u32>,
    pub(super) large_start: usize,
    /// The hierarchy's boxes, finest first: `nodes[0]` has one box per
    /// cluster (runs of `size` consecutive entries of `order` from the start
    /// of each group, the group's last run shorter), and each level above
    /// one box per [`GROUP`] consecutive boxes of the level below (neighbours
    /// in the k-d order, but for the node at the seam between the two
    /// groups, which holds some of each), their union, up to a top level of at most
    /// [`GROUP`] boxes. A receiver skips a node with one test exactly when it
    /// would skip each box below it.
    pub(super) nodes: Vec<Vec<Aabb>>,
    /// Each cluster's triangles in chunks of at most [`CHUNK`], each with its
    /// own list of distinct vertices, so a receiver moves every vertex of a
    /// chunk into its frame once instead of once per corner: cluster `c`'s
    /// chunks are `chunks[cluster_chunks[c]..cluster_chunks[c + 1]]`.
    pub(super) chunks: Vec<Chunk>,
    pub(super) cluster_chunks: Vec<u32>,
    /// The chunks' vertex lists (mesh vertex indices), back to back.
    pub(super) chunk_vertices: Vec<u32>,
    /// The boxes of each chunk's runs of [`SPAN`] triangles (the last run
    /// shorter), recomputed with `nodes`: a receiver's few rays meeting a
    /// cluster skip the runs they miss, as a ray tracer's leaves of a few
    /// triangles would. Chunk `k`'s are `spans[chunks[k].spans..]`.
    pub(super) spans: Vec<Aabb>,
    /// Per entry of `order`, its corners as positions in its chunk's vertex list.
    pub(super) corners: Vec<[u8; 3]>,
    /// The index buffer the chunks were built from: a mesh whose indices
    /// changed is regrouped by [`TriangleClusters::update`].
    pub(super) indices: Vec<u32>,
}

/// Triangles per chunk: at most `3 CHUNK` distinct vertices, so a chunk's
/// corners fit in a `u8` and its vertices in a small stack buffer.
pub(super) const CHUNK: usize = 32;

/// The most distinct vertices a chunk can have.
pub(super) const CHUNK_VERTICES: usize = 3 * CHUNK;

/// Triangles per box of [`TriangleClusters::spans`]: with the runs inside a
/// cluster in k-d order, spans of 4 test a quarter fewer triangles than spans
/// of 8 on the armadillo (masks about 5 % faster) and cost the same on CGAL's
/// lion and the bunny.
pub(super) const SPAN: usize = 4;

/// Span boxes per chunk at most.
pub(super) const CHUNK_SPANS: usize = CHUNK.div_ceil(SPAN);

/// A triangle whose bounding box is more than this many times as wide as
/// the median of its cluster's (in the k-d order) is clustered apart from
/// the rest: a cluster of 32 triangles on a surface is about six of them
/// across, and one large triangle among them (a ground quad beside a
/// scanned object) stretches the cluster's box over the whole ground, so
/// that receivers far from the object open it for its small triangles. A
/// mesh whose sizes change gradually (a ground whose rings grow outwards)
/// keeps its order.
pub(super) const LARGE_EXTENT: f32 = 8.0;

/// Children per node of [`TriangleClusters::nodes`] above the clusters.
pub(super) const GROUP: usize = 16;

// `split_order` keeps groups of clusters compact only for a power of two.
const _: () = assert!(GROUP.is_power_of_two());

// The projection writes four vertices at a time.
const _: () = assert!(CHUNK_VERTICES.is_multiple_of(4));

/// A run of at most [`CHUNK`] triangles of one cluster with its vertex list.
#[derive(Clone, Copy, Debug)]
pub(super) struct Chunk {
    /// Entries `triangles.0..triangles.1` of `order` (and of `corners`).
    pub(super) triangles: (u32, u32),
    /// Entries `vertices.0..vertices.1` of `chunk_vertices`.
    pub(super) vertices: (u32, u32),
    /// The first of its boxes in `spans`.
    pub(super) spans: u32,
}

impl Chunk {
    /// Its triangles' positions in `order` (and `corners`).
    #[inline(always)]
    pub(super) fn triangle_range(&self) -> core::ops::Range<usize> {
        self.triangles.0 as usize..self.triangles.1 as usize
    }

    /// Its boxes' positions in `spans`: one per run of [`SPAN`] triangles.
    #[inline(always)]
    pub(super) fn span_range(&self) -> core::ops::Range<usize> {
        let first = self.spans as usize;
        first..first + self.triangle_range().len().div_ceil(SPAN)
    }
}

impl TriangleClusters {
    /// Triangles per cluster of the default grouping. On the bunny and the bumpy
    /// sphere 16, 32 and 64 cost about the same (`lod_receiver_*` in
    /// `core/benches/hemi.rs`); 32 needs half the boxes of 16.
    pub const DEFAULT_SIZE: usize = 32;

    /// Groups the triangles of `mesh` into clusters of `triangles_per_cluster`
    /// (at least 1) by a k-d order of their centroids in these positions
    /// (`split_order`), the runs of 4 triangles (span boxes) inside each cluster
    /// ordered the same way. The triangles far wider than the others of
    /// their cluster (more than 8 times their median, such as a ground quad
    /// of two triangles beside a detailed object) are taken out and grouped
    /// among themselves, so that they do not stretch the boxes of small
    /// triangles.
    pub fn new(mesh: &MeshView<'_>, triangles_per_cluster: usize) -> Self {
        let mut clusters = TriangleClusters {
            size: triangles_per_cluster.max(1),
            order: Vec::new(),
            large_start: 0,
            nodes: Vec::new(),
            chunks: Vec::new(),
            cluster_chunks: Vec::new(),
            chunk_vertices: Vec::new(),
            spans: Vec::new(),
            corners: Vec::new(),
            indices: Vec::new(),
        };
        clusters.reorder(mesh);
        clusters
    }

    /// Recomputes the grouping from the current positions of `mesh` (for a mesh
    /// whose shape changed so much that the rest-pose clusters are no longer
    /// compact). Allocates.
    pub fn reorder(&mut self, mesh: &MeshView<'_>) {
        let count = mesh.triangle_count();
        let keyed_of = |t: usize| {
            let [a, b, c] = mesh.triangle(t);
            ((a + b + c) * (1.0 / 3.0), t as u32)
        };
        let mut keyed: Vec<(Vec3, u32)> = (0..count).map(keyed_of).collect();
        split_order(&mut keyed, self.size);
        // Triangles far larger than their cluster's others go to clusters of
        // their own, and the rest are ordered again without them.
        let large = large_in_their_clusters(mesh, &keyed, self.size);
        let mut large: Vec<(Vec3, u32)> = if large.iter().any(|&l| l) {
            let (ordinary, large): (Vec<_>, Vec<_>) = (0..count)
                .map(keyed_of)
                .partition(|&(_, t)| !large[t as usize]);
            keyed = ordinary;
            split_order(&mut keyed, self.size);
            large
        } else {
            Vec::new()
        };
        self.large_start = keyed.len();
        split_order(&mut large, self.size);
        for group in [&mut keyed, &mut large] {
            for cluster in group.chunks_mut(self.size) {
                split_order(cluster, SPAN);
            }
        }
        keyed.append(&mut large);
        self.order.clear();
        self.order.extend(keyed.iter().map(|&(_, t)| t));
        self.nodes.clear();
        let mut boxes = self.cluster_ranges().count();
        loop {
            self.nodes.push(alloc::vec![Aabb::EMPTY; boxes]);
            if boxes <= GROUP {
                break;
            }
            boxes = boxes.div_ceil(GROUP);
        }
        self.build_chunks(mesh);
        self.compute_bounds(mesh);
    }

    /// Splits every cluster into chunks and lists each chunk's distinct vertices.
    fn build_chunks(&mut self, mesh: &MeshView<'_>) {
        self.indices.clear();
        self.indices.extend_from_slice(mesh.indices());
        self.chunks.clear();
        self.cluster_chunks.clear();
        self.chunk_vertices.clear();
        self.corners.clear();
        let mut spans = 0;
        // Position of each mesh vertex in the current chunk's list, u32::MAX
        // when absent (reset after each chunk).
        let mut slot = alloc::vec![u32::MAX; mesh.vertex_count()];
        let ranges: Vec<_> = self.cluster_ranges().collect();
        for cluster in ranges {
            self.cluster_chunks.push(self.chunks.len() as u32);
            let (mut start, cluster_end) = (cluster.start, cluster.end);
            while start < cluster_end {
                let end = (start + CHUNK).min(cluster_end);
                let first_vertex = self.chunk_vertices.len();
                for &t in &self.order[start..end] {
                    let corners = mesh.triangle_indices(t as usize).map(|v| {
                        let v = v as usize;
                        if slot[v] == u32::MAX {
                            slot[v] = (self.chunk_vertices.len() - first_vertex) as u32;
                            self.chunk_vertices.push(v as u32);
                        }
                        slot[v] as u8
                    });
                    self.corners.push(corners);
                }
                for &v in &self.chunk_vertices[first_vertex..] {
                    slot[v as usize] = u32::MAX;
                }
                self.chunks.push(Chunk {
                    triangles: (start as u32, end as u32),
                    vertices: (first_vertex as u32, self.chunk_vertices.len() as u32),
                    spans,
                });
                spans += (end - start).div_ceil(SPAN) as u32;
                start = end;
            }
        }
        self.cluster_chunks.push(self.chunks.len() as u32);
        self.spans.clear();
        self.spans.resize(spans as usize, Aabb::EMPTY);
    }

    /// Recomputes every cluster's box from the current positions of `mesh` and
    /// returns the mesh with its clusters, for one frame. One pass over the
    /// triangles, no allocation unless the index buffer changed (then the
    /// grouping is recomputed too).
    pub fn update<'a>(&'a mut self, mesh: MeshView<'a>) -> ClusteredMesh<'a> {
        if self.indices != mesh.indices() {
            self.reorder(&mesh);
        } else {
            self.compute_bounds(&mesh);
        }
        ClusteredMesh {
            mesh,
            clusters: Some(self),
        }
    }

    /// Triangles per cluster.
    #[inline]
    pub fn triangles_per_cluster(&self) -> usize {
        self.size
    }

    /// Each cluster's entries of `order`: runs of `size` from the start of
    /// each group (ordinary, then large triangles).
    pub(super) fn cluster_ranges(&self) -> impl Iterator<Item = core::ops::Range<usize>> + '_ {
        let size = self.size;
        let runs = |group: core::ops::Range<usize>| {
            group
                .clone()
                .step_by(size)
                .map(move |start| start..(start + size).min(group.end))
        };
        runs(0..self.large_start).chain(runs(self.large_start..self.order.len()))
    }

    /// Number of clusters.
    #[inline]
    pub fn cluster_count(&self) -> usize {
        self.nodes.first().map_or(0, Vec::len)
    }

    fn compute_bounds(&mut self, mesh: &MeshView<'_>) {
        let Some((clusters, upper)) = self.nodes.split_first_mut() else {
            return;
        };
        // The spans' boxes from the triangles, each cluster's the union of
        // its spans' (the same box: min and max are exact).
        for chunk in &self.chunks {
            let triangles = &self.order[chunk.triangle_range()];
            let spans = &mut self.spans[chunk.span_range()];
            for (bounds, run) in spans.iter_mut().zip(triangles.chunks(SPAN)) {
                let mut b = Aabb::EMPTY;
                for &t in run {
                    let [p, q, r] = mesh.triangle(t as usize);
                    b.grow(p);
                    b.grow(q);
                    b.grow(r);
                }
                *bounds = b;
            }
        }
        for (c, bounds) in clusters.iter_mut().enumerate() {
            let chunks = self.cluster_chunks[c] as usize..self.cluster_chunks[c + 1] as usize;
            let mut b = Aabb::EMPTY;
            for chunk in &self.chunks[chunks] {
                for span in &self.spans[chunk.span_range()] {
                    b.grow(span.min);
                    b.grow(span.max);
                }
            }
            *bounds = b;
        }
        // Refit bottom-up: each level from the one below.
        let mut below: &[Aabb] = clusters;
        for level in upper {
            for (node, children) in level.iter_mut().zip(below.chunks(GROUP)) {
                let mut b = Aabb::EMPTY;
                for child in children {
                    b.grow(child.min);
                    b.grow(child.max);
                }
                *node = b;
            }
            below = level;
        }
    }
}

/// Per triangle, whether its bounding box is more than [`LARGE_EXTENT`] times
/// as wide as the median of its cluster's (the runs of `size` of `keyed`, in
/// k-d order), leaving out those of zero width.
fn large_in_their_clusters(mesh: &MeshView<'_>, keyed: &[(Vec3, u32)], size: usize) -> Vec<bool> {
    let extent = |t: u32| {
        let [a, b, c] = mesh.triangle(t as usize);
        (a.max(b).max(c) - a.min(b).min(c)).max_element()
    };
    let mut large = alloc::vec![false; keyed.len()];
    let mut extents = Vec::with_capacity(size);
    for cluster in keyed.chunks(size) {
        // Triangles collapsed to a point do not count: a cluster of mostly
        // such would otherwise call every other triangle large.
        extents.clear();
        extents.extend(cluster.iter().map(|&(_, t)| extent(t)).filter(|&e| e > 0.0));
        if extents.is_empty() {
            continue;
        }
        let middle = extents.len() / 2;
        let typical = *extents.select_nth_unstable_by(middle, f32::total_cmp).1;
        for &(_, t) in cluster {
            large[t as usize] = extent(t) > LARGE_EXTENT * typical;
        }
    }
    large
}

/// Orders `keyed` (centroids and triangles) so that every run of `unit`
/// entries, and every run of a power of two of such runs, is the set of
/// entries on one side of a sequence of axis-aligned planes: the top split cuts
/// the centroids' box across its longest side, with the largest power of two of
/// units below the count on the low side, and each side is ordered the same
/// way. So clusters of `unit` triangles and the groups of [`GROUP`] clusters
/// above them (a power of two) are each compact, where a Morton order's runs
/// jump across the curve's seams (a third to a half fewer triangles tested
/// per receiver: docs/performance.md). Deterministic: ties are broken by
/// triangle index, and NaN centroids sort by `total_cmp`.
fn split_order(keyed: &mut [(Vec3, u32)], unit: usize) {
    let units = keyed.len().div_ceil(unit);
    if units <= 1 {
        return;
    }
    let mut bounds = Aabb::EMPTY;
    for &(centroid, _) in keyed.iter() {
        bounds.grow(centroid);
    }
    let extent = bounds.max - bounds.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    // `units >= 2`, so the low side holds at least one unit and fewer than all.
    let low = units.next_power_of_two() / 2 * unit;
    // One comparison per axis, so that none branches on the axis.
    match axis {
        0 => select_along(keyed, low - 1, |p| p.x),
        1 => select_along(keyed, low - 1, |p| p.y),
        _ => select_along(keyed, low - 1, |p| p.z),
    }
    let (low, high) = keyed.split_at_mut(low);
    split_order(low, unit);
    split_order(high, unit);
}

/// `keyed.select_nth_unstable_by` at `nth` along `key` of the centroids, ties
/// by triangle index.
#[inline(always)]
fn select_along(keyed: &mut [(Vec3, u32)], nth: usize, key: impl Fn(&Vec3) -> f32) {
    keyed.select_nth_unstable_by(nth, |(p, s), (q, t)| {
        key(p).total_cmp(&key(q)).then(s.cmp(t))
    });
}

/// A mesh for one frame, with or without cluster boxes. Copy it freely; it only
/// borrows.
#[derive(Clone, Copy, Debug)]
pub struct ClusteredMesh<'a> {
    pub(super) mesh: MeshView<'a>,
    pub(super) clusters: Option<&'a TriangleClusters>,
}

impl<'a> ClusteredMesh<'a> {
    /// The mesh without clusters: every triangle is read and culled on its own.
    #[inline]
    pub fn unclustered(mesh: MeshView<'a>) -> Self {
        ClusteredMesh {
            mesh,
            clusters: None,
        }
    }

    /// The mesh.
    #[inline]
    pub fn mesh(&self) -> &MeshView<'a> {
        &self.mesh
    }

    /// Whether cluster boxes are used.
    #[inline]
    pub fn is_clustered(&self) -> bool {
        self.clusters.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hemi::test_meshes::bumpy_sphere;

    /// The box of triangles `order[range]`, one corner at a time.
    fn bounds_of(mesh: &MeshView<'_>, triangles: &[u32]) -> Aabb {
        let mut b = Aabb::EMPTY;
        for &t in triangles {
            for p in mesh.triangle(t as usize) {
                b.grow(p);
            }
        }
        b
    }

    /// The bumpy sphere on a ground quad 400 wide, with 40 needles through
    /// it (triangles 100 long whose centroids lie among the sphere's small
    /// ones: with the quad, 42 wide triangles, each in a cluster of small
    /// ones) and 300 triangles collapsed to a point (zero width, which no
    /// median may be made of).
    fn sphere_on_ground() -> (Vec<[f32; 3]>, Vec<u32>) {
        let (mut positions, mut indices) = bumpy_sphere(23, 37, 0.3, 0.0);
        let floor = -1.5;
        let quad = positions.len() as u32;
        positions.extend([[-200.0, -200.0, floor], [200.0, -200.0, floor]]);
        positions.extend([[200.0, 200.0, floor], [-200.0, 200.0, floor]]);
        indices.extend([0, 1, 2, 0, 2, 3].map(|k| quad + k));
        for k in 0..40 {
            let [x, y, z] = positions[20 * k];
            let first = positions.len() as u32;
            positions.extend([[x, y, z - 50.0], [x, y, z + 50.0], [x + 0.01, y, z]]);
            indices.extend([first, first + 1, first + 2]);
        }
        indices.extend((0..300).flat_map(|k| [k, k, k]));
        (positions, indices)
    }

    /// The slow twin of `compute_bounds`: every span box is the box of its
    /// triangles, every cluster box the box of its `size` triangles (so the
    /// union of its spans), for cluster sizes that do and do not fill whole
    /// chunks and spans, in the rest pose and after the mesh moves.
    #[test]
    fn span_and_cluster_boxes_are_the_boxes_of_their_triangles() {
        let (rest, indices) = bumpy_sphere(23, 37, 0.3, 0.0);
        let (twisted, _) = bumpy_sphere(23, 37, 0.3, 0.9);
        let (staged, staged_indices) = sphere_on_ground();
        let cases = [
            (&rest, &indices, &twisted),
            (&staged, &staged_indices, &staged),
        ];
        for (size, (rest, indices, moved)) in [1, 5, 8, 32, 40, 100]
            .into_iter()
            .flat_map(|size| cases.map(|case| (size, case)))
        {
            let mut clusters = TriangleClusters::new(&MeshView::new(rest, indices).unwrap(), size);
            for positions in [rest, moved] {
                let mesh = MeshView::new(positions, indices).unwrap();
                let clustered = clusters.update(mesh);
                let clusters = clustered.clusters.unwrap();
                let mut spans_seen = 0;
                for chunk in &clusters.chunks {
                    let triangles = &clusters.order[chunk.triangle_range()];
                    assert!(triangles.len() <= CHUNK);
                    let spans = &clusters.spans[chunk.span_range()];
                    assert_eq!(spans.len(), triangles.chunks(SPAN).len(), "size {size}");
                    for (span, run) in spans.iter().zip(triangles.chunks(SPAN)) {
                        assert_eq!(*span, bounds_of(&mesh, run), "size {size}");
                        spans_seen += 1;
                    }
                }
                assert_eq!(spans_seen, clusters.spans.len(), "size {size}");
                for (c, range) in clusters.cluster_ranges().enumerate() {
                    assert_eq!(
                        clusters.nodes[0][c],
                        bounds_of(&mesh, &clusters.order[range]),
                        "size {size}"
                    );
                }
            }
        }
    }

    /// Whether `centroids` (in cluster order) are split as [`split_order`]
    /// promises: the first largest power of two of `unit` runs below the
    /// count lies on one side of a plane across a longest side of their box,
    /// the rest on the other, and both sides again.
    fn split_by_planes(centroids: &[Vec3], unit: usize) -> bool {
        let units = centroids.len().div_ceil(unit);
        if units <= 1 {
            return true;
        }
        let (low, high) = centroids.split_at(units.next_power_of_two() / 2 * unit);
        let (min, max) = centroids
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(min, max), &c| {
                (min.min(c), max.max(c))
            });
        let extent = max - min;
        // Across a longest side of the centroids' box, which keeps each side
        // compact (a sort along one axis would cut slabs).
        let separated = (0..3).any(|axis| {
            let top = low
                .iter()
                .map(|c| c[axis])
                .fold(f32::NEG_INFINITY, f32::max);
            extent[axis] == extent.max_element() && high.iter().all(|c| c[axis] >= top)
        });
        separated && split_by_planes(low, unit) && split_by_planes(high, unit)
    }

    /// Every triangle appears once in the order; the clusters, the groups of
    /// clusters above them and the spans inside each cluster are the sides of
    /// axis-aligned planes (so each is compact), for cluster sizes that are
    /// and are not powers of two, a mesh with many equal centroid
    /// coordinates (a grid) and an empty one.
    #[test]
    fn clusters_and_spans_are_sides_of_axis_aligned_planes() {
        let (sphere, sphere_indices) = bumpy_sphere(23, 37, 0.3, 0.0);
        // A 20 x 20 grid of quads, gently rippled (so that no axis separates
        // every split trivially), whose centroids share many coordinates.
        let grid: Vec<[f32; 3]> = (0..21 * 21)
            .map(|v| [(v % 21) as f32, (v / 21) as f32, 0.1 * ((v * 7 % 5) as f32)])
            .collect();
        let grid_indices: Vec<u32> = (0..20 * 20)
            .flat_map(|q| {
                let v = (q / 20) * 21 + q % 20;
                [v, v + 1, v + 22, v, v + 22, v + 21]
            })
            .collect();
        let (staged, staged_indices) = sphere_on_ground();
        // Each mesh with the wide triangles it must have taken out, where
        // the test checks that.
        for (positions, indices, wide) in [
            (&sphere, &sphere_indices, None),
            (&grid, &grid_indices, None),
            (&staged, &staged_indices, Some(42)),
            (&Vec::new(), &Vec::new(), None),
        ] {
            let mesh = MeshView::new(positions, indices).unwrap();
            for size in [1, 5, 8, 32, 40, 100] {
                let clusters = TriangleClusters::new(&mesh, size);
                let mut seen = alloc::vec![false; mesh.triangle_count()];
                for &t in &clusters.order {
                    assert!(!core::mem::replace(&mut seen[t as usize], true));
                }
                assert!(seen.iter().all(|&s| s), "size {size}");
                let centroids: Vec<Vec3> = clusters
                    .order
                    .iter()
                    .map(|&t| {
                        let [a, b, c] = mesh.triangle(t as usize);
                        (a + b + c) * (1.0 / 3.0)
                    })
                    .collect();
                // In clusters of a few triangles, wide ones may be the most.
                if let Some(wide) = wide.filter(|_| size >= 32) {
                    let taken_out = mesh.triangle_count() - clusters.large_start;
                    assert_eq!(taken_out, wide, "size {size}");
                }
                let (ordinary, large) = centroids.split_at(clusters.large_start);
                assert!(split_by_planes(ordinary, size), "size {size}");
                assert!(split_by_planes(large, size), "size {size}");
                for range in clusters.cluster_ranges() {
                    assert!(split_by_planes(&centroids[range], SPAN), "size {size}");
                }
            }
        }
    }

    /// A ground quad of two triangles beside a detailed object (a layout
    /// users have) is clustered apart from the object: its triangles fill a
    /// cluster of their own, so a receiver on the ground far away, none of
    /// whose cell rays comes near the object, rasterizes none of the
    /// object's triangles; its mask equals the unclustered loop's. (With the
    /// quad among the object's triangles, their cluster's box spanned the
    /// ground and that receiver rasterized them all.)
    #[test]
    fn a_ground_quad_is_clustered_apart_from_the_object() {
        use crate::hemi::{BatchOptions, HemiScene, Receiver, scene_mask_with_counts};
        let (mut positions, mut indices) = bumpy_sphere(23, 37, 0.3, 0.0);
        let ground = positions.len() as u32;
        let (half, floor) = (200.0, -1.5);
        positions.extend([
            [-half, -half, floor],
            [half, -half, floor],
            [half, half, floor],
            [-half, half, floor],
        ]);
        indices.extend([0, 1, 2, 0, 2, 3].map(|k| ground + k));
        let mesh = MeshView::new(&positions, &indices).unwrap();
        let quad = [mesh.triangle_count() - 2, mesh.triangle_count() - 1];
        let mut clusters = TriangleClusters::new(&mesh, TriangleClusters::DEFAULT_SIZE);
        let order = &clusters.order;
        assert_eq!(order.len() - clusters.large_start, 2);
        assert!(
            order[clusters.large_start..]
                .iter()
                .all(|&t| quad.contains(&(t as usize)))
        );
        let last = clusters.cluster_ranges().last().unwrap();
        assert_eq!(last, clusters.large_start..order.len());
        // On the ground 120 away, looking up: the sphere (radius at most 1.3
        // about the origin) is within 0.011 rad of its center's direction.
        let (position, normal) = (Vec3::new(120.0, 0.0, floor), Vec3::Z);
        let options = BatchOptions::default();
        let receiver = Receiver::new(position, normal, options.normal_offset);
        let toward = (Vec3::ZERO - receiver.origin).normalize();
        let nearest = crate::hemi::cell_directions()
            .filter_map(|(i, j, _)| receiver.cell_ray(i, j))
            .map(|ray| ray.direction.normalize().dot(toward))
            .fold(f32::NEG_INFINITY, f32::max);
        assert!(
            nearest < libm::cosf(0.03),
            "a cell ray passes near the sphere"
        );
        let clustered = clusters.update(mesh);
        let (mask, counts) =
            scene_mask_with_counts(&HemiScene::new(clustered), position, normal, &options);
        let (plain, _) = scene_mask_with_counts(
            &HemiScene::new(ClusteredMesh::unclustered(mesh)),
            position,
            normal,
            &options,
        );
        assert_eq!(mask, plain);
        assert_eq!(counts.rasterized, 0, "{counts:?}");
    }
}

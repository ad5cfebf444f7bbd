//! A small z-buffered triangle rasterizer for meshes shaded per vertex: the
//! vertex colours are interpolated across each triangle (perspective-correct), and
//! the nearest surface wins.
//!
//! Coverage is exact and watertight: vertices are snapped to a fixed-point grid of
//! 1/[`SUBPIXELS`] pixel and the edge functions are evaluated in integers, so a
//! pixel centre on an edge shared by two triangles is drawn by exactly one of them
//! (the "top-left" tie rule, here: the edge whose direction points down, or right
//! when horizontal, owns its centres). Pixel `(x, y)` has its centre at
//! `(x + 0.5, y + 0.5)` in pixel coordinates, `(0, 0)` the top left corner of the
//! image. Triangles are two-sided (no culling), since the depth test decides.

use glam::{Vec2, Vec3};

use crate::camera::Camera;

/// Subpixel steps per pixel of the fixed-point vertex coordinates.
pub const SUBPIXELS: i64 = 256;

/// Vertices farther than this many image sizes outside the image make a triangle
/// be skipped, which keeps the fixed-point products far from overflow.
const GUARD_BAND: f32 = 8.0;

/// A vertex in screen space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScreenVertex {
    /// Position in pixels, `(0, 0)` at the top left corner of the image.
    pub position: Vec2,
    /// Distance in front of the camera along its view axis (> 0).
    pub depth: f32,
    /// The colour to interpolate.
    pub color: Vec3,
}

/// A colour image with a depth buffer; pixels never drawn are "empty".
#[derive(Clone, Debug)]
pub struct Framebuffer {
    width: usize,
    height: usize,
    color: Vec<Vec3>,
    /// View depth of the nearest surface drawn so far; infinite where empty.
    depth: Vec<f32>,
}

impl Framebuffer {
    /// An empty `width × height` framebuffer.
    pub fn new(width: usize, height: usize) -> Self {
        Framebuffer {
            width,
            height,
            color: vec![Vec3::ZERO; width * height],
            depth: vec![f32::INFINITY; width * height],
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The colour of pixel `(x, y)`, `None` where nothing was drawn.
    pub fn get(&self, x: usize, y: usize) -> Option<Vec3> {
        let k = y * self.width + x;
        self.depth[k].is_finite().then_some(self.color[k])
    }

    /// Replaces the colour of every drawn pixel by `f` of it (a deferred
    /// pass: draw texture coordinates as colours, then look the texture up).
    pub fn map_colors(&mut self, f: impl Fn(Vec3) -> Vec3) {
        for (color, depth) in self.color.iter_mut().zip(&self.depth) {
            if depth.is_finite() {
                *color = f(*color);
            }
        }
    }

    /// Draws a triangle: every covered pixel whose centre is nearer than what it
    /// holds takes the interpolated colour.
    pub fn draw_triangle(&mut self, vertices: &[ScreenVertex; 3]) {
        let width = self.width;
        let (color, depth) = (&mut self.color, &mut self.depth);
        rasterize_triangle(vertices, self.width, self.height, |x, y, z, c| {
            let k = y * width + x;
            if z < depth[k] {
                depth[k] = z;
                color[k] = c;
            }
        });
    }

    /// Draws an indexed mesh with one colour per vertex, seen by `camera` (whose
    /// image spans this framebuffer). Triangles with a corner at or behind the
    /// camera are skipped.
    pub fn draw_mesh(
        &mut self,
        camera: &Camera,
        positions: &[[f32; 3]],
        indices: &[u32],
        colors: &[Vec3],
    ) {
        let size = Vec2::new(self.width as f32, self.height as f32);
        let projected: Vec<Option<ScreenVertex>> = positions
            .iter()
            .zip(colors)
            .map(|(&p, &color)| {
                let (uv, depth) = camera.project(Vec3::from(p))?;
                Some(ScreenVertex {
                    position: uv * size,
                    depth,
                    color,
                })
            })
            .collect();
        for corners in indices.chunks_exact(3) {
            let [Some(a), Some(b), Some(c)] = [0, 1, 2].map(|k| projected[corners[k] as usize])
            else {
                continue;
            };
            self.draw_triangle(&[a, b, c]);
        }
    }
}

/// A vertex snapped to the fixed-point grid.
#[derive(Clone, Copy)]
struct Fixed {
    x: i64,
    y: i64,
}

/// Twice the signed area of `(a, b, p)`: positive when `p` is to the right of
/// `a → b` with y pointing down (the edge function).
#[inline]
fn edge(a: Fixed, b: Fixed, px: i64, py: i64) -> i64 {
    (b.x - a.x) * (py - a.y) - (b.y - a.y) * (px - a.x)
}

/// Whether the edge `a → b` owns the pixel centres exactly on it: of the two
/// triangles sharing an edge, which traverse it in opposite directions, exactly
/// one has it pointing down (or right, when horizontal).
#[inline]
fn owns_boundary(a: Fixed, b: Fixed) -> bool {
    b.y > a.y || (b.y == a.y && b.x > a.x)
}

/// Calls `pixel(x, y, depth, colour)` for every pixel of a `width × height` image
/// whose centre the triangle covers (see the module docs for the tie rule), with
/// the perspective-correct depth and colour at that centre. Degenerate triangles,
/// triangles with a corner at or behind the camera (`depth <= 0` or not finite)
/// and triangles reaching far outside the image are skipped.
pub fn rasterize_triangle(
    vertices: &[ScreenVertex; 3],
    width: usize,
    height: usize,
    mut pixel: impl FnMut(usize, usize, f32, Vec3),
) {
    let limit = GUARD_BAND * width.max(height) as f32;
    let usable = |v: &ScreenVertex| {
        v.depth > 0.0
            && v.depth.is_finite()
            && v.position.is_finite()
            && v.position.abs().max_element() <= limit
    };
    if !vertices.iter().all(usable) {
        return;
    }
    let snap = |v: &ScreenVertex| Fixed {
        x: (v.position.x * SUBPIXELS as f32).round() as i64,
        y: (v.position.y * SUBPIXELS as f32).round() as i64,
    };
    let mut order = [0usize, 1, 2];
    let mut p = vertices.map(|v| snap(&v));
    let mut area = edge(p[0], p[1], p[2].x, p[2].y);
    if area == 0 {
        return;
    }
    if area < 0 {
        order.swap(1, 2);
        p.swap(1, 2);
        area = -area;
    }
    let v = order.map(|k| vertices[k]);
    // Pixel range of the bounding box, clamped to the image.
    let min_x = p.iter().map(|q| q.x).min().unwrap_or(0);
    let max_x = p.iter().map(|q| q.x).max().unwrap_or(0);
    let min_y = p.iter().map(|q| q.y).min().unwrap_or(0);
    let max_y = p.iter().map(|q| q.y).max().unwrap_or(0);
    // Centre of pixel k is at (k + 1/2) pixels: the first centre at or after `lo`.
    let first = |lo: i64| ((lo - SUBPIXELS / 2) as f64 / SUBPIXELS as f64).ceil() as i64;
    let last = |hi: i64| ((hi - SUBPIXELS / 2) as f64 / SUBPIXELS as f64).floor() as i64;
    let (x0, x1) = (first(min_x).max(0), last(max_x).min(width as i64 - 1));
    let (y0, y1) = (first(min_y).max(0), last(max_y).min(height as i64 - 1));
    // Edge k is opposite vertex k: its function is vertex k's barycentric weight.
    let edges = [(p[1], p[2]), (p[2], p[0]), (p[0], p[1])];
    let owned = edges.map(|(a, b)| owns_boundary(a, b));
    let inverse_depth = v.map(|q| 1.0 / q.depth);
    let inverse_area = 1.0 / area as f32;
    for y in y0..=y1 {
        let cy = y * SUBPIXELS + SUBPIXELS / 2;
        for x in x0..=x1 {
            let cx = x * SUBPIXELS + SUBPIXELS / 2;
            let w = edges.map(|(a, b)| edge(a, b, cx, cy));
            let inside = (0..3).all(|k| w[k] > 0 || (w[k] == 0 && owned[k]));
            if !inside {
                continue;
            }
            // Screen-space barycentrics, then perspective correction.
            let l = w.map(|e| e as f32 * inverse_area);
            let weights = [0, 1, 2].map(|k| l[k] * inverse_depth[k]);
            let sum = weights[0] + weights[1] + weights[2];
            if sum <= 0.0 {
                continue;
            }
            let color =
                (weights[0] * v[0].color + weights[1] * v[1].color + weights[2] * v[2].color) / sum;
            pixel(x as usize, y as usize, 1.0 / sum, color);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vertex(x: f32, y: f32, depth: f32, color: Vec3) -> ScreenVertex {
        ScreenVertex {
            position: Vec2::new(x, y),
            depth,
            color,
        }
    }

    /// How many times each pixel of a `width × height` image is drawn.
    fn coverage(triangles: &[[ScreenVertex; 3]], width: usize, height: usize) -> Vec<u32> {
        let mut counts = vec![0u32; width * height];
        for t in triangles {
            rasterize_triangle(t, width, height, |x, y, _, _| counts[y * width + x] += 1);
        }
        counts
    }

    #[test]
    fn a_quad_covers_exactly_its_pixels_once() {
        // The square [2, 6] x [1, 5] split along its diagonal, which passes through
        // pixel centres; both windings of the second triangle.
        let c = Vec3::ONE;
        let (a, b, d, e) = (
            vertex(2.0, 1.0, 1.0, c),
            vertex(6.0, 1.0, 1.0, c),
            vertex(6.0, 5.0, 1.0, c),
            vertex(2.0, 5.0, 1.0, c),
        );
        for second in [[a, d, e], [a, e, d]] {
            let counts = coverage(&[[a, b, d], second], 8, 7);
            for y in 0..7 {
                for x in 0..8 {
                    let expected = u32::from((2..6).contains(&x) && (1..5).contains(&y));
                    assert_eq!(counts[y * 8 + x], expected, "pixel ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn a_fan_around_a_pixel_centre_leaves_no_hole_and_no_overlap() {
        // Eight triangles around the centre of pixel (4, 4), with edges through
        // many pixel centres in all directions.
        let centre = vertex(4.5, 4.5, 1.0, Vec3::ONE);
        let ring: Vec<ScreenVertex> = [
            (0.0, 0.0),
            (4.5, 0.0),
            (9.0, 0.0),
            (9.0, 4.5),
            (9.0, 9.0),
            (4.5, 9.0),
            (0.0, 9.0),
            (0.0, 4.5),
        ]
        .iter()
        .map(|&(x, y)| vertex(x, y, 1.0, Vec3::ONE))
        .collect();
        let triangles: Vec<[ScreenVertex; 3]> = (0..8)
            .map(|k| [centre, ring[k], ring[(k + 1) % 8]])
            .collect();
        let counts = coverage(&triangles, 10, 10);
        // The square [0, 9]² holds the centres of pixels 0..=8; the inner edges run
        // through pixel centres in eight directions.
        for y in 0..10 {
            for x in 0..10 {
                let expected = u32::from(x < 9 && y < 9);
                assert_eq!(counts[y * 10 + x], expected, "pixel ({x}, {y})");
            }
        }
    }

    #[test]
    fn nearer_surfaces_win_and_colours_interpolate() {
        let mut frame = Framebuffer::new(4, 4);
        let far = [
            vertex(0.0, 0.0, 5.0, Vec3::X),
            vertex(4.0, 0.0, 5.0, Vec3::X),
            vertex(0.0, 4.0, 5.0, Vec3::X),
        ];
        let near = [
            vertex(0.0, 0.0, 1.0, Vec3::Y),
            vertex(4.0, 0.0, 1.0, Vec3::Y),
            vertex(0.0, 4.0, 1.0, Vec3::Y),
        ];
        frame.draw_triangle(&near);
        frame.draw_triangle(&far);
        assert_eq!(frame.get(0, 0), Some(Vec3::Y));
        assert_eq!(frame.get(3, 3), None);
        // A horizontal colour ramp at constant depth interpolates linearly.
        let mut ramp = Framebuffer::new(8, 2);
        ramp.draw_triangle(&[
            vertex(0.0, 0.0, 2.0, Vec3::ZERO),
            vertex(8.0, 0.0, 2.0, Vec3::splat(8.0)),
            vertex(0.0, 8.0, 2.0, Vec3::ZERO),
        ]);
        let value = ramp.get(2, 0).unwrap();
        assert!(
            (value - Vec3::splat(2.5)).abs().max_element() < 1e-5,
            "{value}"
        );
    }

    #[test]
    fn degenerate_and_behind_camera_triangles_draw_nothing() {
        let c = Vec3::ONE;
        let flat = [
            vertex(0.0, 0.0, 1.0, c),
            vertex(4.0, 4.0, 1.0, c),
            vertex(8.0, 8.0, 1.0, c),
        ];
        let behind = [
            vertex(0.0, 0.0, -1.0, c),
            vertex(8.0, 0.0, 1.0, c),
            vertex(0.0, 8.0, 1.0, c),
        ];
        assert!(coverage(&[flat, behind], 8, 8).iter().all(|&n| n == 0));
    }
}

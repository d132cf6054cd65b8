//! Triangle rasterisation into the same packed depth+id target as the splats (paper §4.1: voxels
//! and meshes share one depth buffer, so they occlude and shadow each other).
//!
//! Edge functions over the clamped bounding box, the top-left fill rule, near-plane clipping in
//! view space, NDC depth interpolated linearly in screen space (it is affine there for both
//! projections). Attributes are interpolated perspective-correctly at resolve time from the
//! pixel's reconstructed world position. Triangles are two-sided.

use glam::{Mat4, Vec2, Vec3};
use rayon::prelude::*;

use super::MESH_ID_FLAG;
use super::buffers::{DepthTarget, pack_key};
use super::camera::Camera;
use crate::mesh::MeshModel;

/// One triangle-mesh object to draw.
#[derive(Clone, Copy)]
pub struct MeshInstance<'a> {
    /// The mesh.
    pub model: &'a MeshModel,
    /// `world_from_object`.
    pub world_from_object: Mat4,
    /// Whether it is drawn into shadow maps.
    pub casts_shadows: bool,
    /// Reported in [`super::PixelId::object`] (1-based; 0 means background).
    pub label: u32,
}

/// A triangle in world space with the references needed to shade it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct WorldTriangle {
    pub(crate) mesh: u32,
    pub(crate) part: u32,
    pub(crate) tri: u32,
    pub(crate) world: [Vec3; 3],
}

/// [`world_triangles_into`] a new list.
#[cfg(test)]
pub(crate) fn world_triangles(meshes: &[MeshInstance<'_>]) -> Vec<WorldTriangle> {
    let mut out = Vec::new();
    world_triangles_into(meshes, &mut out);
    out
}

/// Every triangle of every mesh in world space, in a fixed order (index = id), into `out`
/// (its allocation kept).
pub(crate) fn world_triangles_into(meshes: &[MeshInstance<'_>], out: &mut Vec<WorldTriangle>) {
    out.clear();
    for (mi, m) in meshes.iter().enumerate() {
        for (pi, part) in m.model.parts.iter().enumerate() {
            let n = part.triangle_count();
            out.par_extend((0..n).into_par_iter().map(|t| {
                let [a, b, c] = part.triangle(t);
                let w = |i: usize| m.world_from_object.transform_point3(part.positions[i]);
                WorldTriangle {
                    mesh: mi as u32,
                    part: pi as u32,
                    tri: t as u32,
                    world: [w(a), w(b), w(c)],
                }
            }));
        }
    }
}

/// Rasterises the selected triangles; returns how many reached the pixel loop.
pub(crate) fn draw_triangles(
    tris: &[WorldTriangle],
    meshes: &[MeshInstance<'_>],
    cam: &Camera,
    target: &DepthTarget,
    shadow_casters_only: bool,
) -> u64 {
    tris.par_iter()
        .enumerate()
        .filter(|(_, t)| !shadow_casters_only || meshes[t.mesh as usize].casts_shadows)
        .map(|(i, t)| {
            u64::from(draw_triangle(
                t,
                cam,
                target,
                MESH_ID_FLAG | (i as u32 & !MESH_ID_FLAG),
            ))
        })
        .sum()
}

fn draw_triangle(t: &WorldTriangle, cam: &Camera, target: &DepthTarget, id: u32) -> bool {
    let v = t.world.map(|p| cam.view_from_world.transform_point3(p));
    // Clip against the near plane (perspective only: orthographic depth is affine everywhere).
    let mut poly: [Vec3; 4] = [Vec3::ZERO; 4];
    let mut n = 0usize;
    if cam.perspective {
        let inside = |p: Vec3| -p.z >= cam.near;
        for i in 0..3 {
            let (a, b) = (v[i], v[(i + 1) % 3]);
            if inside(a) {
                poly[n] = a;
                n += 1;
            }
            if inside(a) != inside(b) {
                let s = (-cam.near - a.z) / (b.z - a.z);
                poly[n] = a + (b - a) * s;
                n += 1;
            }
        }
    } else {
        poly[..3].copy_from_slice(&v);
        n = 3;
    }
    if n < 3 {
        return false;
    }
    // Screen positions with NDC depth, on the stack (a heap list per triangle cost an
    // allocation per triangle per frame).
    let mut s = [Vec3::ZERO; 4];
    for (si, &p) in s.iter_mut().zip(&poly[..n]) {
        let q = cam.project_view(p);
        *si = Vec3::new(q.x, q.y, cam.ndc_depth(q.z));
    }
    let mut any = false;
    for k in 1..n - 1 {
        any |= fill(s[0], s[k], s[k + 1], cam, target, id);
    }
    any
}

#[inline]
fn edge(a: Vec2, b: Vec2, p: Vec2) -> f32 {
    (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x)
}

/// Top-left rule for an edge `a → b` whose interior has positive edge function: the edge owns
/// its pixels when the interior lies to its right (left edge) or below a horizontal edge (top).
#[inline]
fn owns(a: Vec2, b: Vec2) -> bool {
    let nx = -(b.y - a.y);
    let ny = b.x - a.x;
    nx > 0.0 || (nx == 0.0 && ny > 0.0)
}

fn fill(a: Vec3, b: Vec3, c: Vec3, cam: &Camera, target: &DepthTarget, id: u32) -> bool {
    let (mut p0, mut p1, p2) = (a.truncate(), b.truncate(), c.truncate());
    let (mut z0, mut z1, z2) = (a.z, b.z, c.z);
    let mut area = edge(p0, p1, p2);
    if !area.is_finite() || area == 0.0 {
        return false;
    }
    if area < 0.0 {
        std::mem::swap(&mut p0, &mut p1);
        std::mem::swap(&mut z0, &mut z1);
        area = -area;
    }
    let (w, h) = (cam.width as f32, cam.height as f32);
    let lo = p0.min(p1).min(p2);
    let hi = p0.max(p1).max(p2);
    if hi.x < 0.0 || hi.y < 0.0 || lo.x > w || lo.y > h {
        return false;
    }
    let x0 = (lo.x - 0.5).ceil().max(0.0) as u32;
    let y0 = (lo.y - 0.5).ceil().max(0.0) as u32;
    let x1 = ((hi.x - 0.5).floor().min(w - 1.0)).max(-1.0);
    let y1 = ((hi.y - 0.5).floor().min(h - 1.0)).max(-1.0);
    if x1 < 0.0 || y1 < 0.0 {
        return false;
    }
    let (x1, y1) = (x1 as u32, y1 as u32);
    let own = [owns(p1, p2), owns(p2, p0), owns(p0, p1)];
    let inv_area = 1.0 / area;
    let mut wrote = false;
    for y in y0..=y1 {
        for x in x0..=x1 {
            let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let e = [edge(p1, p2, p), edge(p2, p0, p), edge(p0, p1, p)];
            if (0..3).all(|i| e[i] > 0.0 || (e[i] == 0.0 && own[i])) {
                let depth = (e[0] * z0 + e[1] * z1 + e[2] * z2) * inv_area;
                if (0.0..=1.0).contains(&depth) {
                    target.write(x, y, pack_key(depth, id));
                    wrote = true;
                }
            }
        }
    }
    wrote
}

//! An impostor of a KRS prototype: crossed quads textured with pictures of it, the coarsest
//! level of detail of an instanced forest (a tree far away covers a few pixels; two quads draw
//! it for 8 triangles instead of thousands).
//!
//! The pictures are made by the CPU reference renderer ([`crate::render`]): two orthographic
//! side views (along −Z and along −X) of the prototype alone, the G-buffer's albedo as colour
//! and its coverage as alpha, side by side in one RGBA texture. Each view becomes a square in
//! the plane through the prototype's centre facing that view, so from any side the quads show
//! the tree's silhouette at its own size. The texture is unlit albedo: the viewer lights the
//! quads. Each square is written twice, back to back with opposite windings and the same
//! upward normal (single-sided): a double-sided material would light the back side with the
//! normal reversed (pointing down, unlit), and an upward normal lights a distant crown like the
//! ground it stands on, whatever the view.

use glam::{Vec2, Vec3};

use crate::krs::KrsObject;
use crate::mesh::{Texture, linear_to_srgb_byte};
use crate::quality::Quality;
use crate::render::{View, render_document};
use crate::scene::{Document, ObjectKind, OrbitCamera};

/// Texels along each side of one view of an impostor's texture (the texture holds two views,
/// side by side).
pub const IMPOSTOR_TEXELS: u32 = 256;

/// Crossed quads and their texture (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Impostor {
    /// Vertex positions, in the prototype's (world) space.
    pub positions: Vec<Vec3>,
    /// Unit normals (all +Y).
    pub normals: Vec<Vec3>,
    /// Texture coordinates, (0, 0) = the texture's top-left.
    pub uvs: Vec<Vec2>,
    /// Three indices per triangle, counter-clockwise front faces.
    pub indices: Vec<u32>,
    /// sRGB albedo, alpha 255 where the prototype covers the texel and 0 elsewhere.
    pub texture: Texture,
}

impl Impostor {
    /// Triangles.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The impostor reflected by x → −x (for a mirrored prototype): positions mirrored,
    /// windings reversed, texture coordinates kept, so each quad shows the mirrored picture.
    #[must_use]
    pub fn mirrored_x(&self) -> Self {
        Self {
            positions: self
                .positions
                .iter()
                .map(|&p| Vec3::new(-p.x, p.y, p.z))
                .collect(),
            indices: self
                .indices
                .chunks_exact(3)
                .flat_map(|t| [t[0], t[2], t[1]])
                .collect(),
            ..self.clone()
        }
    }
}

/// Renders the impostor of `prototype`, whose mesh spans `lo..hi`, with `texels` texels along
/// each view's side.
///
/// # Errors
/// The renderer's error, as text.
pub fn krs_impostor(
    prototype: &KrsObject,
    lo: Vec3,
    hi: Vec3,
    texels: u32,
) -> Result<Impostor, String> {
    let centre = (lo + hi) * 0.5;
    let size = hi - lo;
    // A square view as large as the prototype's widest side, with a texel of margin.
    let half = 0.5 * size.max_element().max(1e-3) * (1.0 + 2.0 / texels as f32);
    let distance = 4.0 * half;
    let mut doc = Document::default();
    doc.add("impostor", ObjectKind::Krs(prototype.clone()));
    let quality = Quality {
        shadows: false,
        ao_samples: 0,
        ..Quality::default()
    };
    let width = 2 * texels;
    let mut rgba = vec![0u8; (width * texels * 4) as usize];
    let mut covered = vec![false; (width * texels) as usize];
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    let mut indices = Vec::new();
    for (view, yaw_deg) in [0.0f32, 90.0].into_iter().enumerate() {
        let camera = OrbitCamera {
            target: centre,
            yaw_deg,
            pitch_deg: 0.0,
            distance,
            fov_y_deg: 2.0 * (half / distance).atan().to_degrees(),
            near: distance - 2.0 * half,
            far: distance + 2.0 * half,
            orthographic: true,
        };
        let request = View {
            camera: Some(camera),
            quality: quality.clone(),
            ..View::new(texels, texels)
        };
        let (_, buffers, _) = render_document(&doc, &request).map_err(|e| e.to_string())?;
        for y in 0..texels {
            for x in 0..texels {
                let src = (y * texels + x) as usize;
                let dst = (y * width + view as u32 * texels + x) as usize;
                if buffers.ids[src].object == 0 {
                    continue;
                }
                let a = buffers.albedo[src];
                rgba[4 * dst..4 * dst + 4].copy_from_slice(&[
                    linear_to_srgb_byte(a.x),
                    linear_to_srgb_byte(a.y),
                    linear_to_srgb_byte(a.z),
                    255,
                ]);
                covered[dst] = true;
            }
        }
        // The image's x runs along the camera's right, its y down the world's up.
        let forward = (centre - camera.eye()).normalize_or_zero();
        let right = forward.cross(Vec3::Y).normalize_or_zero();
        let base = positions.len() as u32;
        for (s, t) in [(-1.0f32, -1.0f32), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            positions.push(centre + right * (s * half) + Vec3::Y * (t * half));
            uvs.push(Vec2::new(
                (view as f32 + 0.5 * (s + 1.0)) * 0.5,
                0.5 * (1.0 - t),
            ));
        }
        // Facing the camera (counter-clockwise seen from the eye), then the back.
        indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        indices.extend([base, base + 2, base + 1, base, base + 3, base + 2]);
    }
    dilate(&mut rgba, &mut covered, width, texels, 4);
    Ok(Impostor {
        normals: vec![Vec3::Y; positions.len()],
        positions,
        uvs,
        indices,
        texture: Texture {
            width,
            height: texels,
            rgba8: rgba,
        },
    })
}

/// Spreads the colours of covered texels into the transparent ones around them (`rounds`
/// texels deep, alpha kept 0), so filtering and mipmaps at the silhouette blend with the
/// crown's colour instead of black.
fn dilate(rgba: &mut [u8], covered: &mut [bool], width: u32, height: u32, rounds: u32) {
    let (w, h) = (width as i64, height as i64);
    for _ in 0..rounds {
        let before = covered.to_vec();
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                if before[i] {
                    continue;
                }
                let mut sum = [0u32; 3];
                let mut n = 0;
                for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < 0 || ny < 0 || nx >= w || ny >= h {
                        continue;
                    }
                    let j = (ny * w + nx) as usize;
                    if before[j] {
                        for c in 0..3 {
                            sum[c] += u32::from(rgba[4 * j + c]);
                        }
                        n += 1;
                    }
                }
                for (c, total) in sum.iter().enumerate() {
                    if let Some(mean) = total.checked_div(n) {
                        rgba[4 * i + c] = mean as u8;
                        covered[i] = true;
                    }
                }
            }
        }
    }
}

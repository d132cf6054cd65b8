//! Frame error against a reference render: colour (RMSE, PSNR), coverage (mismatch, holes,
//! bloat) and depth, computed from the images and the resolved [`FrameBuffers`] of both frames.

use serde::{Deserialize, Serialize};

use super::image::{MeasureError, psnr, rmse};
use crate::render::{Camera, FrameBuffers, RgbaImage};

/// How far a test frame is from a reference frame of the same view and size.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameError {
    /// RGB root-mean-square error in 0..=1 units.
    pub rmse: f64,
    /// Peak signal-to-noise ratio in dB (`INFINITY` for identical images; serialised as `null`).
    pub psnr_db: f64,
    /// Pixels covered (object id != background) in exactly one of the two frames.
    pub coverage_mismatch: u64,
    /// Pixels covered in the reference but not in the test frame: holes.
    pub holes: u64,
    /// Pixels covered in the test frame but not in the reference: bloat.
    pub bloat: u64,
    /// Pixels covered in both, where depth is compared.
    pub depth_compared: u64,
    /// Mean of |z_test - z_ref| / z_ref over `depth_compared` pixels, z the view-space depth
    /// (a relative error, so it means the same for a model 1 unit or 1000 units away).
    pub depth_mean_rel: f64,
    /// Largest relative view-depth error over `depth_compared` pixels.
    pub depth_max_rel: f64,
    /// Pixels in the frame.
    pub pixels: u64,
}

impl FrameError {
    /// Coverage mismatch as a fraction of all pixels.
    #[must_use]
    pub fn coverage_mismatch_fraction(&self) -> f64 {
        if self.pixels == 0 {
            0.0
        } else {
            self.coverage_mismatch as f64 / self.pixels as f64
        }
    }
}

/// One rendered frame: the shaded image and the buffers it was shaded from.
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    /// The shaded image.
    pub image: &'a RgbaImage,
    /// Depth, ids, normals and albedo.
    pub buffers: &'a FrameBuffers,
}

/// Compares `test` with `reference`; both must come from `camera` (its near/far turn NDC
/// depth back into view depth).
///
/// # Errors
/// [`MeasureError::SizeMismatch`] when the images or buffers differ in size.
pub fn compare_frames(
    reference: Frame<'_>,
    test: Frame<'_>,
    camera: &Camera,
) -> Result<FrameError, MeasureError> {
    let (r, t) = (reference.buffers, test.buffers);
    let n = r.width as usize * r.height as usize;
    let sizes_ok = r.width == t.width
        && r.height == t.height
        && [r.ids.len(), r.depth.len(), t.ids.len(), t.depth.len()]
            .iter()
            .all(|&l| l == n)
        && reference.image.width == r.width
        && reference.image.height == r.height;
    if !sizes_ok {
        return Err(MeasureError::SizeMismatch {
            a_width: r.width,
            a_height: r.height,
            b_width: t.width,
            b_height: t.height,
        });
    }
    let rmse = rmse(reference.image, test.image)?;
    let psnr_db = psnr(reference.image, test.image)?;
    let (mut holes, mut bloat, mut compared) = (0u64, 0u64, 0u64);
    let (mut sum_rel, mut max_rel) = (0.0f64, 0.0f64);
    for i in 0..n {
        match (r.ids[i].object != 0, t.ids[i].object != 0) {
            (true, false) => holes += 1,
            (false, true) => bloat += 1,
            (true, true) => {
                let zr = f64::from(camera.view_depth(r.depth[i]));
                let zt = f64::from(camera.view_depth(t.depth[i]));
                // A depth that does not convert (at the far plane) counts as fully wrong
                // rather than poisoning the mean with NaN or infinity.
                let rel = if zr.is_finite() && zt.is_finite() && zr > 0.0 {
                    ((zt - zr).abs() / zr).min(1.0)
                } else if r.depth[i] == t.depth[i] {
                    0.0
                } else {
                    1.0
                };
                sum_rel += rel;
                max_rel = max_rel.max(rel);
                compared += 1;
            }
            (false, false) => {}
        }
    }
    Ok(FrameError {
        rmse,
        psnr_db,
        coverage_mismatch: holes + bloat,
        holes,
        bloat,
        depth_compared: compared,
        depth_mean_rel: if compared == 0 {
            0.0
        } else {
            sum_rel / compared as f64
        },
        depth_max_rel: max_rel,
        pixels: n as u64,
    })
}

#[cfg(test)]
mod tests {
    use glam::{Mat4, Vec3};

    use super::*;
    use crate::render::{PixelId, Projection};

    fn buffers(w: u32, h: u32, covered: &[usize], depth: f32) -> FrameBuffers {
        let n = (w * h) as usize;
        let mut fb = FrameBuffers {
            width: w,
            height: h,
            depth: vec![1.0; n],
            ids: vec![PixelId::default(); n],
            normal: vec![Vec3::ZERO; n],
            albedo: vec![Vec3::ZERO; n],
        };
        for &i in covered {
            fb.ids[i] = PixelId { object: 1, node: 0 };
            fb.depth[i] = depth;
        }
        fb
    }

    fn camera(w: u32, h: u32) -> Camera {
        Camera::new(
            Mat4::IDENTITY,
            Projection::Perspective {
                fov_y_rad: 1.0,
                near: 0.1,
                far: 100.0,
            },
            w,
            h,
        )
    }

    #[test]
    fn holes_bloat_and_depth_on_hand_made_buffers() {
        let cam = camera(4, 1);
        let z_ref = cam.ndc_depth(10.0);
        let z_test = cam.ndc_depth(11.0);
        // Reference covers pixels 0, 1, 2; test covers 1, 2, 3 one unit further away.
        let r = buffers(4, 1, &[0, 1, 2], z_ref);
        let t = buffers(4, 1, &[1, 2, 3], z_test);
        let img = RgbaImage::new(4, 1);
        let e = compare_frames(
            Frame {
                image: &img,
                buffers: &r,
            },
            Frame {
                image: &img,
                buffers: &t,
            },
            &cam,
        )
        .unwrap();
        assert_eq!((e.holes, e.bloat, e.coverage_mismatch), (1, 1, 2));
        assert_eq!(e.depth_compared, 2);
        assert!((e.depth_mean_rel - 0.1).abs() < 1e-3, "{e:?}");
        assert!((e.depth_max_rel - 0.1).abs() < 1e-3, "{e:?}");
        assert_eq!(e.rmse, 0.0);
        assert!((e.coverage_mismatch_fraction() - 0.5).abs() < 1e-12);
        // Identical frames: no error at all.
        let same = compare_frames(
            Frame {
                image: &img,
                buffers: &r,
            },
            Frame {
                image: &img,
                buffers: &r,
            },
            &cam,
        )
        .unwrap();
        assert_eq!(same.coverage_mismatch, 0);
        assert_eq!(same.depth_max_rel, 0.0);
        // Different sizes are an error, not a panic.
        let small = buffers(2, 1, &[], 1.0);
        assert!(
            compare_frames(
                Frame {
                    image: &img,
                    buffers: &r,
                },
                Frame {
                    image: &RgbaImage::new(2, 1),
                    buffers: &small,
                },
                &cam,
            )
            .is_err()
        );
    }
}

//! Image error metrics (RMSE, PSNR, differing pixels, coverage mismatch) and the one golden-image
//! helper every test uses, so tolerances live in one place.

use std::path::{Path, PathBuf};

use crate::render::RgbaImage;

/// Why two images cannot be compared.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MeasureError {
    /// The images (or masks) have different sizes.
    #[error("cannot compare a {a_width}×{a_height} image with a {b_width}×{b_height} one")]
    SizeMismatch {
        /// First width.
        a_width: u32,
        /// First height.
        a_height: u32,
        /// Second width.
        b_width: u32,
        /// Second height.
        b_height: u32,
    },
    /// Two masks of different lengths.
    #[error("cannot compare masks of {0} and {1} pixels")]
    MaskLength(usize, usize),
}

fn same_size(a: &RgbaImage, b: &RgbaImage) -> Result<(), MeasureError> {
    if a.width != b.width || a.height != b.height || a.pixels.len() != b.pixels.len() {
        return Err(MeasureError::SizeMismatch {
            a_width: a.width,
            a_height: a.height,
            b_width: b.width,
            b_height: b.height,
        });
    }
    Ok(())
}

/// Root-mean-square error over the RGB channels, in 0..=1 units of the 8-bit range.
///
/// # Errors
/// [`MeasureError::SizeMismatch`].
pub fn rmse(a: &RgbaImage, b: &RgbaImage) -> Result<f64, MeasureError> {
    same_size(a, b)?;
    let n = a.pixels.len() / 4 * 3;
    if n == 0 {
        return Ok(0.0);
    }
    let sum: f64 = a
        .pixels
        .chunks_exact(4)
        .zip(b.pixels.chunks_exact(4))
        .map(|(p, q)| {
            (0..3)
                .map(|c| {
                    let d = (f64::from(p[c]) - f64::from(q[c])) / 255.0;
                    d * d
                })
                .sum::<f64>()
        })
        .sum();
    Ok((sum / n as f64).sqrt())
}

/// Peak signal-to-noise ratio in dB (peak 1.0); `INFINITY` for identical images.
///
/// # Errors
/// [`MeasureError::SizeMismatch`].
pub fn psnr(a: &RgbaImage, b: &RgbaImage) -> Result<f64, MeasureError> {
    let e = rmse(a, b)?;
    Ok(if e == 0.0 {
        f64::INFINITY
    } else {
        -20.0 * e.log10()
    })
}

/// Pixels where some RGBA channel differs by more than `channel_tolerance` (0..=255).
///
/// # Errors
/// [`MeasureError::SizeMismatch`].
pub fn count_differing(
    a: &RgbaImage,
    b: &RgbaImage,
    channel_tolerance: u8,
) -> Result<usize, MeasureError> {
    same_size(a, b)?;
    Ok(a.pixels
        .chunks_exact(4)
        .zip(b.pixels.chunks_exact(4))
        .filter(|(p, q)| (0..4).any(|c| p[c].abs_diff(q[c]) > channel_tolerance))
        .count())
}

/// Pixels covered in exactly one of two coverage masks (e.g. `FrameBuffers::coverage`).
///
/// # Errors
/// [`MeasureError::MaskLength`].
pub fn coverage_mismatch(a: &[bool], b: &[bool]) -> Result<usize, MeasureError> {
    if a.len() != b.len() {
        return Err(MeasureError::MaskLength(a.len(), b.len()));
    }
    Ok(a.iter().zip(b).filter(|(x, y)| x != y).count())
}

/// A visual difference: black where equal, brighter where the largest channel difference is
/// larger (amplified ×4 so small errors show), red where it exceeds `channel_tolerance`.
///
/// # Errors
/// [`MeasureError::SizeMismatch`].
pub fn difference_image(
    a: &RgbaImage,
    b: &RgbaImage,
    channel_tolerance: u8,
) -> Result<RgbaImage, MeasureError> {
    same_size(a, b)?;
    let mut out = RgbaImage::new(a.width, a.height);
    for ((o, p), q) in out
        .pixels
        .chunks_exact_mut(4)
        .zip(a.pixels.chunks_exact(4))
        .zip(b.pixels.chunks_exact(4))
    {
        let d = (0..4).map(|c| p[c].abs_diff(q[c])).max().unwrap_or(0);
        let v = d.saturating_mul(4);
        if d > channel_tolerance {
            o.copy_from_slice(&[255, v / 2, v / 2, 255]);
        } else {
            o.copy_from_slice(&[v, v, v, 255]);
        }
    }
    Ok(out)
}

/// How far a golden image may be from the render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// Largest per-channel difference (0..=255) that counts as equal.
    pub channel: u8,
    /// Fraction of pixels allowed to exceed `channel` (0 = none).
    pub max_differing_fraction: f64,
}

impl Tolerance {
    /// The default for CPU renders compared with their own goldens: rounding-level channel
    /// noise (2/255) and at most 0.1 % of pixels beyond it (float differences between machines
    /// can flip a depth tie at a silhouette).
    pub const CPU_GOLDEN: Self = Self {
        channel: 2,
        max_differing_fraction: 0.001,
    };
}

impl Tolerance {
    /// GPU renders compared with the CPU reference renderer of the same frame: the G-buffer
    /// holds 16-bit albedo and normals and the GPU evaluates `pow`/`exp` in its own precision,
    /// which moves a channel by a few steps; rasteriser fill rules and depth ties at silhouettes
    /// move a few edge pixels. At least 99 % of pixels within 3/255.
    pub const GPU_PARITY: Self = Self {
        channel: 3,
        max_differing_fraction: 0.01,
    };
}

/// How two renders of one frame compare (colour, coverage and depth), for parity tests and
/// reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Parity {
    /// Pixels in the image.
    pub total: usize,
    /// Pixels where a channel differs by more than the tolerance's `channel`.
    pub differing: usize,
    /// Pixels covered in exactly one of the two renders.
    pub coverage_mismatch: usize,
    /// Pixels covered in both whose depths differ by more than the depth tolerance.
    pub depth_mismatch: usize,
    /// Pixels covered in both.
    pub both_covered: usize,
    /// Root-mean-square colour error (0..=1).
    pub rmse: f64,
}

impl Parity {
    /// Whether colour, coverage and depth all stay within `tolerance.max_differing_fraction`
    /// of the pixels.
    #[must_use]
    pub fn within(&self, tolerance: Tolerance) -> bool {
        let allowed = (tolerance.max_differing_fraction * self.total as f64).floor() as usize;
        self.differing <= allowed
            && self.coverage_mismatch <= allowed
            && self.depth_mismatch <= allowed
    }
}

/// Compares two renders of one frame: their images (`tolerance.channel`), their coverage masks,
/// and the depths (any monotonic depth, e.g. view depth) of pixels both cover, which agree when
/// `|a − b| <= depth_tolerance · max(|a|, |b|)` (relative, so one tolerance fits near and far).
///
/// # Errors
/// [`MeasureError`] when sizes differ.
pub fn parity(
    a: &RgbaImage,
    b: &RgbaImage,
    depth_a: &[Option<f32>],
    depth_b: &[Option<f32>],
    tolerance: Tolerance,
    depth_tolerance: f32,
) -> Result<Parity, MeasureError> {
    let differing = count_differing(a, b, tolerance.channel)?;
    let n = a.width as usize * a.height as usize;
    if depth_a.len() != n || depth_b.len() != n {
        return Err(MeasureError::MaskLength(depth_a.len(), depth_b.len()));
    }
    let (mut coverage_mismatch, mut depth_mismatch, mut both_covered) = (0, 0, 0);
    for (da, db) in depth_a.iter().zip(depth_b) {
        match (da, db) {
            (Some(x), Some(y)) => {
                both_covered += 1;
                // Written as "not close" so a NaN depth counts as a mismatch.
                let close = (x - y).abs() <= depth_tolerance * x.abs().max(y.abs());
                if !close {
                    depth_mismatch += 1;
                }
            }
            (None, None) => {}
            _ => coverage_mismatch += 1,
        }
    }
    Ok(Parity {
        total: n,
        differing,
        coverage_mismatch,
        depth_mismatch,
        both_covered,
        rmse: rmse(a, b)?,
    })
}

/// Why a render does not match its golden image.
#[derive(Debug, thiserror::Error)]
pub enum GoldenError {
    /// No golden file and blessing is off.
    #[error(
        "golden image {0} is missing; run with THICKET_BLESS=1 to create it (then check it in)"
    )]
    Missing(PathBuf),
    /// The golden cannot be read or the outputs cannot be written.
    #[error(transparent)]
    Io(#[from] crate::render::ImageError),
    /// Different sizes.
    #[error(transparent)]
    Size(#[from] MeasureError),
    /// Too many pixels differ.
    #[error(
        "{differing} of {total} pixels differ by more than {channel}/255 from {expected} \
         (allowed {allowed}); see {actual_path} and {difference_path}"
    )]
    Mismatch {
        /// Golden path.
        expected: PathBuf,
        /// Differing pixels.
        differing: usize,
        /// All pixels.
        total: usize,
        /// Allowed differing pixels.
        allowed: usize,
        /// The channel tolerance.
        channel: u8,
        /// Where the render was written.
        actual_path: PathBuf,
        /// Where the difference image was written.
        difference_path: PathBuf,
    },
}

/// `dir/name.png` → `dir/name-<suffix>.png`.
fn sibling(path: &Path, suffix: &str) -> PathBuf {
    let stem = path
        .file_stem()
        .map_or_else(|| "image".into(), |s| s.to_string_lossy().into_owned());
    path.with_file_name(format!("{stem}-{suffix}.png"))
}

/// Compares `actual` with the PNG at `expected_path`. On mismatch writes `<name>-actual.png` and
/// `<name>-difference.png` next to it. A missing golden is created only when the environment
/// variable `THICKET_BLESS=1` is set (and then the comparison passes); otherwise it is an error.
/// `THICKET_BLESS=1` also rewrites an existing golden that no longer matches.
///
/// # Errors
/// [`GoldenError`] as described.
pub fn compare_with_golden(
    actual: &RgbaImage,
    expected_path: &Path,
    tolerance: Tolerance,
) -> Result<(), GoldenError> {
    let bless = std::env::var("THICKET_BLESS").is_ok_and(|v| v == "1");
    if !expected_path.exists() {
        if bless {
            if let Some(dir) = expected_path.parent() {
                // The write below reports a failure with the path.
                let _ = std::fs::create_dir_all(dir);
            }
            actual.save_png(expected_path)?;
            return Ok(());
        }
        return Err(GoldenError::Missing(expected_path.to_path_buf()));
    }
    let expected = RgbaImage::load_png(expected_path)?;
    let actual_path = sibling(expected_path, "actual");
    let difference_path = sibling(expected_path, "difference");
    let differing = match count_differing(actual, &expected, tolerance.channel) {
        Ok(d) => d,
        Err(e) => {
            actual.save_png(&actual_path)?;
            if bless {
                actual.save_png(expected_path)?;
                return Ok(());
            }
            return Err(e.into());
        }
    };
    let total = (actual.width as usize) * (actual.height as usize);
    let allowed = (tolerance.max_differing_fraction * total as f64).floor() as usize;
    if differing <= allowed {
        // Stale outputs from an earlier failure would mislead whoever looks next.
        let _ = std::fs::remove_file(&actual_path);
        let _ = std::fs::remove_file(&difference_path);
        return Ok(());
    }
    if bless {
        actual.save_png(expected_path)?;
        return Ok(());
    }
    actual.save_png(&actual_path)?;
    difference_image(actual, &expected, tolerance.channel)?.save_png(&difference_path)?;
    Err(GoldenError::Mismatch {
        expected: expected_path.to_path_buf(),
        differing,
        total,
        allowed,
        channel: tolerance.channel,
        actual_path,
        difference_path,
    })
}

/// Test helper: [`compare_with_golden`], panicking with its message on failure.
///
/// # Panics
/// When the images do not match or the golden is missing (without `THICKET_BLESS=1`).
#[track_caller]
pub fn assert_images_match(
    actual: &RgbaImage,
    expected_path: impl AsRef<Path>,
    tolerance: Tolerance,
) {
    if let Err(e) = compare_with_golden(actual, expected_path.as_ref(), tolerance) {
        panic!("{e}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn solid(w: u32, h: u32, c: [u8; 4]) -> RgbaImage {
        let mut img = RgbaImage::new(w, h);
        for p in img.pixels.chunks_exact_mut(4) {
            p.copy_from_slice(&c);
        }
        img
    }

    #[test]
    fn metrics_on_known_images() {
        let a = solid(4, 4, [0, 0, 0, 255]);
        let mut b = a.clone();
        assert_eq!(rmse(&a, &b).unwrap(), 0.0);
        assert_eq!(psnr(&a, &b).unwrap(), f64::INFINITY);
        b.pixels[0] = 255; // one channel of one pixel at full scale
        let e = rmse(&a, &b).unwrap();
        assert!((e - (1.0f64 / 48.0).sqrt()).abs() < 1e-12, "{e}");
        assert!((psnr(&a, &b).unwrap() - (-20.0 * e.log10())).abs() < 1e-9);
        assert_eq!(count_differing(&a, &b, 254).unwrap(), 1);
        assert_eq!(count_differing(&a, &b, 255).unwrap(), 0);
        assert!(matches!(
            rmse(&a, &solid(4, 5, [0; 4])),
            Err(MeasureError::SizeMismatch { .. })
        ));
        assert_eq!(
            coverage_mismatch(&[true, false, true], &[true, true, false]).unwrap(),
            2
        );
        assert!(coverage_mismatch(&[true], &[]).is_err());
        // Empty images compare as equal.
        assert_eq!(
            rmse(&RgbaImage::new(0, 0), &RgbaImage::new(0, 0)).unwrap(),
            0.0
        );
    }

    #[test]
    fn parity_counts_colour_coverage_and_depth() {
        let a = solid(4, 1, [100, 100, 100, 255]);
        let mut b = a.clone();
        b.pixels[0] = 103; // within 3
        b.pixels[4] = 110; // beyond
        let da = [Some(1.0), Some(2.0), None, Some(4.0)];
        let db = [Some(1.0005), None, None, Some(4.1)];
        let p = parity(&a, &b, &da, &db, Tolerance::GPU_PARITY, 1e-3).unwrap();
        assert_eq!(p.differing, 1);
        assert_eq!(p.coverage_mismatch, 1);
        assert_eq!(p.both_covered, 2);
        assert_eq!(p.depth_mismatch, 1);
        assert!(!p.within(Tolerance::GPU_PARITY));
        assert!(p.within(Tolerance {
            channel: 3,
            max_differing_fraction: 0.25,
        }));
        assert!(parity(&a, &b, &da[..3], &db, Tolerance::GPU_PARITY, 1e-3).is_err());
    }

    #[test]
    fn golden_helper_writes_outputs_and_refuses_missing() {
        let dir = tempfile::tempdir().unwrap();
        let golden = dir.path().join("g.png");
        let img = solid(8, 8, [10, 20, 30, 255]);
        // Missing golden without blessing is a failure (the variable is not set under test
        // unless a developer blesses, in which case this branch creates it).
        if std::env::var("THICKET_BLESS").is_err() {
            assert!(matches!(
                compare_with_golden(&img, &golden, Tolerance::CPU_GOLDEN),
                Err(GoldenError::Missing(_))
            ));
        }
        img.save_png(&golden).unwrap();
        compare_with_golden(&img, &golden, Tolerance::CPU_GOLDEN).unwrap();
        let mut other = img.clone();
        for p in other.pixels.chunks_exact_mut(4).take(3) {
            p[0] = 200;
        }
        if std::env::var("THICKET_BLESS").is_err() {
            let e = compare_with_golden(&other, &golden, Tolerance::CPU_GOLDEN).unwrap_err();
            assert!(
                matches!(e, GoldenError::Mismatch { differing: 3, .. }),
                "{e}"
            );
            assert!(dir.path().join("g-actual.png").exists());
            let diff = RgbaImage::load_png(dir.path().join("g-difference.png")).unwrap();
            assert_eq!(diff.pixel(0, 0)[0], 255);
            assert_eq!(diff.pixel(7, 7), [0, 0, 0, 255]);
            // Within tolerance: 3 of 64 pixels allowed at 5 %.
            compare_with_golden(
                &other,
                &golden,
                Tolerance {
                    channel: 2,
                    max_differing_fraction: 0.05,
                },
            )
            .unwrap();
            assert!(!dir.path().join("g-actual.png").exists());
        }
    }
}

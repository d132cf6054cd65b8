//! Visible repetition in a rendered image: how much symmetry hiding (§5: unaligned mirrors,
//! Lipschitz distortion) leaves to see.
//!
//! A KRS repeats its kernels by reflections; what an eye notices is the same motif twice in one
//! picture, shifted (two parallel mirrors compose to a translation: rows of identical trees) or
//! mirrored. The measure is the image's highest normalised correlation with a copy of itself
//! shifted by at least [`MIN_SHIFT`] of the grid, or flipped left to right and shifted, on the
//! detail of the luminance (the image minus a local mean, so the horizon and the sky gradient,
//! which match under every sideways shift, count for nothing). 1 is an exact repeat, around 0
//! none. It is a property of the image, so it compares renders of one view with and without
//! jittered mirrors or distortion, not different views.

/// Side of the luminance grid the image is averaged down to.
pub const GRID: usize = 64;
/// Smallest shift (grid cells) that counts as a repeat rather than the motif itself.
pub const MIN_SHIFT: usize = 6;
/// Half-width (grid cells) of the local mean subtracted to keep only detail.
const MEAN_RADIUS: usize = 4;
/// Shifts whose overlap is below this share of the grid are not compared (tiny overlaps
/// correlate by chance).
const MIN_OVERLAP: f32 = 0.3;

/// The visible repetition of an image.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Repetition {
    /// Highest correlation with a shifted copy (translational repeats).
    pub translation: f32,
    /// Highest correlation with a flipped, shifted copy (mirror images side by side).
    pub mirror: f32,
}

impl Repetition {
    /// The larger of the two.
    pub fn score(&self) -> f32 {
        self.translation.max(self.mirror)
    }
}

/// Measures the visible repetition of an RGBA8 image (`width × height`, rows top to bottom).
/// An image smaller than the grid or of the wrong length measures 0.
pub fn visible_repetition(rgba: &[u8], width: u32, height: u32) -> Repetition {
    let (w, h) = (width as usize, height as usize);
    if w < GRID || h < GRID || rgba.len() != w * h * 4 {
        return Repetition::default();
    }
    // Box-average the luminance onto the grid.
    let mut lum = vec![0f32; GRID * GRID];
    let mut count = vec![0u32; GRID * GRID];
    for y in 0..h {
        let gy = y * GRID / h;
        for x in 0..w {
            let gx = x * GRID / w;
            let p = &rgba[(y * w + x) * 4..(y * w + x) * 4 + 3];
            let l = 0.2126 * f32::from(p[0]) + 0.7152 * f32::from(p[1]) + 0.0722 * f32::from(p[2]);
            lum[gy * GRID + gx] += l / 255.0;
            count[gy * GRID + gx] += 1;
        }
    }
    for (l, c) in lum.iter_mut().zip(&count) {
        *l /= (*c).max(1) as f32;
    }
    let detail = minus_local_mean(&lum);
    let flipped: Vec<f32> = (0..GRID * GRID)
        .map(|i| detail[(i / GRID) * GRID + (GRID - 1 - i % GRID)])
        .collect();
    let mut out = Repetition {
        translation: f32::NEG_INFINITY,
        mirror: f32::NEG_INFINITY,
    };
    let reach = GRID as i32 - 1;
    for dy in -reach..=reach {
        for dx in -reach..=reach {
            let far =
                dx.unsigned_abs() as usize >= MIN_SHIFT || dy.unsigned_abs() as usize >= MIN_SHIFT;
            if far && let Some(c) = correlation(&detail, &detail, dx, dy) {
                out.translation = out.translation.max(c);
            }
            // A flip is never the motif itself, except at the image's own axis of symmetry,
            // which a picture of one symmetric object has and the measure should count.
            if let Some(c) = correlation(&detail, &flipped, dx, dy) {
                out.mirror = out.mirror.max(c);
            }
        }
    }
    Repetition {
        translation: out.translation.max(0.0),
        mirror: out.mirror.max(0.0),
    }
}

fn minus_local_mean(lum: &[f32]) -> Vec<f32> {
    let r = MEAN_RADIUS as i32;
    let g = GRID as i32;
    (0..GRID * GRID)
        .map(|i| {
            let (x, y) = ((i % GRID) as i32, (i / GRID) as i32);
            let (mut sum, mut n) = (0.0, 0.0);
            for yy in (y - r).max(0)..=(y + r).min(g - 1) {
                for xx in (x - r).max(0)..=(x + r).min(g - 1) {
                    sum += lum[(yy * g + xx) as usize];
                    n += 1.0;
                }
            }
            lum[i] - sum / n
        })
        .collect()
}

/// Pearson correlation of `a(x, y)` with `b(x + dx, y + dy)` over their overlap, `None` when the
/// overlap is too small or either side is flat there.
fn correlation(a: &[f32], b: &[f32], dx: i32, dy: i32) -> Option<f32> {
    let g = GRID as i32;
    let (x0, x1) = (0.max(-dx), g.min(g - dx));
    let (y0, y1) = (0.max(-dy), g.min(g - dy));
    let n = ((x1 - x0).max(0) * (y1 - y0).max(0)) as f32;
    if n < MIN_OVERLAP * (GRID * GRID) as f32 {
        return None;
    }
    let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0f64, 0f64, 0f64, 0f64, 0f64);
    for y in y0..y1 {
        for x in x0..x1 {
            let va = f64::from(a[(y * g + x) as usize]);
            let vb = f64::from(b[((y + dy) * g + x + dx) as usize]);
            sa += va;
            sb += vb;
            saa += va * va;
            sbb += vb * vb;
            sab += va * vb;
        }
    }
    let n = f64::from(n);
    let cov = sab / n - (sa / n) * (sb / n);
    let var_a = saa / n - (sa / n) * (sa / n);
    let var_b = sbb / n - (sb / n) * (sb / n);
    // Flat overlaps (sky) carry no motif.
    let floor = 1e-8;
    if var_a <= floor || var_b <= floor {
        return None;
    }
    Some((cov / (var_a * var_b).sqrt()) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> u8) -> Vec<u8> {
        let mut out = Vec::with_capacity((w * h * 4) as usize);
        for y in 0..h {
            for x in 0..w {
                let v = f(x, y);
                out.extend_from_slice(&[v, v, v, 255]);
            }
        }
        out
    }

    fn noise(x: u32, y: u32) -> u8 {
        let mut h = x.wrapping_mul(0x8da6_b343) ^ y.wrapping_mul(0xd816_3841);
        h ^= h >> 15;
        h = h.wrapping_mul(0x2c1b_3c6d);
        h ^= h >> 12;
        (h >> 24) as u8
    }

    #[test]
    fn a_tiled_image_repeats_and_noise_does_not() {
        // Noise in 2×2-pixel blocks: one value per cell of the 64-cell grid of a 128-pixel image.
        let block = |x: u32, y: u32| noise(x / 2, y / 2);
        let random = visible_repetition(&image(128, 128, block), 128, 128);
        // The same noise tiled every 40 pixels: an exact translational repeat.
        let tiled = visible_repetition(&image(128, 128, |x, y| block(x % 40, y % 40)), 128, 128);
        // Mirrored about the middle column.
        let mirrored = visible_repetition(
            &image(128, 128, |x, y| block(if x < 64 { x } else { 127 - x }, y)),
            128,
            128,
        );
        assert!(random.score() < 0.25, "{random:?}");
        assert!(tiled.translation > 0.9, "{tiled:?}");
        assert!(
            mirrored.mirror > 0.95 && mirrored.translation < 0.5,
            "{mirrored:?}"
        );
        // Too small an image measures nothing rather than failing.
        assert_eq!(visible_repetition(&[0; 16], 2, 2), Repetition::default());
    }
}

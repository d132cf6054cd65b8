//! Supersampling ([`Quality::supersample`]): a frame of k×k samples per pixel is exactly the
//! box filter of the same view drawn k times larger, and it brings sub-pixel KRS detail closer
//! to a finer reference than one sample per pixel does.

use super::scenes::sphere_document;
use super::*;
use crate::krs::presets;
use crate::measure::image::rmse;
use crate::quality::QualityPreset;

fn request(w: u32, h: u32, quality: Quality) -> View {
    View {
        width: w,
        height: h,
        camera: None,
        quality,
    }
}

/// The reference sRGB decode the box filter must agree with.
fn to_linear(b: u8) -> f32 {
    crate::mesh::srgb_to_linear(f32::from(b) / 255.0)
}

/// The box filter written out of place, the obvious way.
fn box_filter(img: &RgbaImage, k: u32) -> Vec<u8> {
    let (w, h) = (img.width / k, img.height / k);
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f32; 4];
            for j in 0..k {
                for i in 0..k {
                    let p = img.pixel(x * k + i, y * k + j);
                    for c in 0..3 {
                        sum[c] += to_linear(p[c]);
                    }
                    sum[3] += f32::from(p[3]);
                }
            }
            let n = (k * k) as f32;
            for c in sum.iter().take(3) {
                out.push(shade::linear_to_srgb8(c / n));
            }
            out.push((sum[3] / n).round() as u8);
        }
    }
    out
}

fn noise_image(w: u32, h: u32, seed: u32) -> RgbaImage {
    let mut img = RgbaImage::new(w, h);
    let mut s = seed.wrapping_mul(2_654_435_761).max(1);
    for b in &mut img.pixels {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        *b = (s >> 24) as u8;
    }
    img
}

#[test]
fn the_in_place_box_filter_equals_the_out_of_place_one() {
    for (k, w, h) in [(2, 6, 4), (3, 9, 12), (4, 16, 4), (2, 2, 2), (4, 4, 8)] {
        let img = noise_image(w, h, k * 31 + w);
        let expected = box_filter(&img, k);
        let mut small = img.clone();
        small.downsample(k);
        assert_eq!((small.width, small.height), (w / k, h / k));
        assert_eq!(small.pixels, expected, "k = {k}, {w}×{h}");
        // The allocation is kept for the next frame.
        assert!(small.pixels.capacity() >= img.pixels.len());
    }
    // Half black, half white averages to linear 0.5 (sRGB 188), not to byte 128.
    let mut img = RgbaImage::new(2, 2);
    for (i, px) in img.pixels.chunks_exact_mut(4).enumerate() {
        let v = if i % 2 == 0 { 255 } else { 0 };
        px.copy_from_slice(&[v, v, v, 255]);
    }
    img.downsample(2);
    assert_eq!(img.pixels, vec![188, 188, 188, 255]);
    // k = 1 leaves the image alone.
    let img = noise_image(5, 3, 7);
    let mut same = img.clone();
    same.downsample(1);
    assert_eq!(same.pixels, img.pixels);
}

#[test]
fn a_supersampled_frame_is_the_box_filter_of_the_frame_drawn_k_times_larger() {
    let mut doc = sphere_document(7, 0.9).unwrap();
    doc.camera.distance = 3.0;
    let quality = Quality {
        shadow_map_size: 512,
        ..Quality::default()
    };
    for (k, w, h) in [(2, 48, 40), (3, 32, 32)] {
        let big = render_document(&doc, &request(w * k, h * k, quality.clone())).unwrap();
        let ss = Quality {
            supersample: k,
            ..quality.clone()
        };
        let (img, fb, stats) = render_document(&doc, &request(w, h, ss)).unwrap();
        assert_eq!((img.width, img.height, fb.width, fb.height), (w, h, w, h));
        assert_eq!(img.pixels, box_filter(&big.0, k), "k = {k}");
        // The G-buffer keeps the sample nearest each pixel's centre.
        for y in 0..h {
            for x in 0..w {
                let (bx, by) = (x * k + k / 2, y * k + k / 2);
                assert_eq!(fb.id(x, y), big.1.id(bx, by), "k = {k} at {x},{y}");
                let (i, bi) = ((y * w + x) as usize, (by * w * k + bx) as usize);
                assert_eq!(fb.depth[i].to_bits(), big.1.depth[bi].to_bits());
                assert_eq!(fb.normal[i], big.1.normal[bi]);
            }
        }
        // The counters count samples: the work is the larger frame's.
        assert_eq!(stats.covered_pixels, big.2.covered_pixels);
        assert!(stats.covered_pixels > u64::from(w * h) / 2, "{stats:?}");
        // Edge pixels are partly covered: values between the sphere's and the background's.
        let background = img.pixel(0, 0);
        let partial = img
            .pixels
            .chunks_exact(4)
            .zip(fb.ids.iter())
            .filter(|(px, id)| id.object == 0 && px[..3] != background[..3])
            .count();
        assert!(partial > 8, "k = {k}: {partial} blended edge pixels");
    }
}

#[test]
fn supersampling_brings_sub_pixel_krs_detail_closer_to_a_finer_reference() {
    // A grass tuft seen from afar: its blades are thinner than a pixel. The reference draws
    // 4×4 samples per pixel; one sample per pixel shows each blade all or nothing.
    let mut doc = Document::default();
    doc.add("Grass", ObjectKind::Krs(presets::grass_tuft()));
    if let Some((lo, hi)) = doc.bounds() {
        doc.camera.frame(lo, hi);
    }
    doc.camera.distance *= 2.0;
    let quality = |k| Quality {
        shadow_map_size: 256,
        supersample: k,
        ..Quality::default()
    };
    let size = 48;
    let reference = render_document(&doc, &request(size, size, quality(4))).unwrap();
    let errors: Vec<f64> = [1, 2]
        .iter()
        .map(|&k| {
            let (img, ..) = render_document(&doc, &request(size, size, quality(k))).unwrap();
            rmse(&img, &reference.0).unwrap()
        })
        .collect();
    assert!(
        errors[0] > 0.01 && errors[1] < 0.7 * errors[0],
        "rmse against 4×4 at 1 and 2 samples per side: {errors:?}"
    );
}

#[test]
fn the_factor_stays_within_the_largest_image() {
    assert_eq!(supersample_factor(800, 600, 4), 4);
    assert_eq!(supersample_factor(800, 600, 1), 1);
    assert_eq!(supersample_factor(MAX_IMAGE_SIZE / 2, 10, 4), 2);
    assert_eq!(supersample_factor(MAX_IMAGE_SIZE, MAX_IMAGE_SIZE, 4), 1);
    assert_eq!(supersample_factor(3, MAX_IMAGE_SIZE / 3, 4), 3);
    // A size the renderer refuses anyway still gives a factor of at least 1.
    assert_eq!(supersample_factor(0, 0, 2), 2);
    assert_eq!(supersample_factor(u32::MAX, 1, 4), 1);
}

#[test]
fn the_knob_is_validated_and_the_estimate_counts_the_samples() {
    let mut q = Quality::default();
    assert_eq!(q.supersample, 1);
    assert!(q.set("supersample", "0").is_err());
    assert!(q.set("supersample", "5").is_err());
    assert_eq!(
        q.supersample, 1,
        "a refused value leaves the knob as it was"
    );
    q.set("supersample", "3").unwrap();
    assert_eq!(q.supersample, 3);
    assert_eq!(Quality::preset(QualityPreset::Final).supersample, 3);

    let mut doc = sphere_document(5, 0.9).unwrap();
    doc.lights.iter_mut().for_each(|l| l.casts_shadows = false);
    let one = estimate_peak_bytes(&doc, &request(200, 100, Quality::default()));
    let three = estimate_peak_bytes(&doc, &request(200, 100, q));
    // Nine times the pixels' share (the fixed part is the same).
    assert!(three > 8 * (one - FRAME_BYTES_FIXED), "{one} {three}");
}

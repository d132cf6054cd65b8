//! Frame buffers: the packed depth+id target every splat and triangle writes, its
//! hierarchical max-depth tiles (occlusion culling), the resolved G-buffer and the final image.

use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use glam::Vec3;
use rayon::prelude::*;

/// Packed `(depth bits << 32) | id`: an atomic minimum keeps the nearest fragment and, at equal
/// depth, the lowest id, whatever order threads write in (the GPU path uses the same packing
/// with a 64-bit atomic min).
pub(crate) const EMPTY_KEY: u64 = u64::MAX;

/// Packs an NDC depth (clamped to 0..=1, so its bit pattern orders like the value) and an id.
#[inline]
pub(crate) fn pack_key(ndc_depth: f32, id: u32) -> u64 {
    let d = ndc_depth.clamp(0.0, 1.0);
    (u64::from(d.to_bits()) << 32) | u64::from(id)
}

/// Depth of a packed key (`INFINITY` for an empty pixel).
#[inline]
pub(crate) fn key_depth(key: u64) -> f32 {
    if key == EMPTY_KEY {
        f32::INFINITY
    } else {
        f32::from_bits((key >> 32) as u32)
    }
}

/// Edge of the fine occlusion tiles in pixels.
pub(crate) const TILE: u32 = 4;
/// Fine tiles per coarse tile edge.
pub(crate) const SUPER: u32 = 8;

/// The depth+id target with max-depth tiles for hierarchical occlusion culling.
#[derive(Default)]
pub(crate) struct DepthTarget {
    pub(crate) width: u32,
    pub(crate) height: u32,
    pub(crate) keys: Vec<AtomicU64>,
    tiles_x: u32,
    tiles_y: u32,
    /// Max depth per fine tile (INFINITY while any pixel is empty).
    tile_max: Vec<f32>,
    tile_dirty: Vec<AtomicBool>,
    supers_x: u32,
    super_max: Vec<f32>,
    /// Depth per pixel as of the last tile update (INFINITY where empty): small nodes are
    /// tested pixel by pixel, which culls at silhouettes where a tile is partly background.
    /// Updated only with the tiles, so culling decisions do not depend on thread timing.
    pixel_depth: Vec<f32>,
    /// Scratch of [`Self::update_dirty`] and [`Self::update_all_tiles`], kept between frames.
    tile_depths: Vec<[f32; (TILE * TILE) as usize]>,
    supers: Vec<u32>,
    all_tiles: Vec<u32>,
}

impl DepthTarget {
    /// A cleared target of `width`×`height`: [`Self::reset`] of an empty one.
    #[cfg(test)]
    pub(crate) fn new(width: u32, height: u32) -> Self {
        let mut t = Self::default();
        t.reset(width, height);
        t
    }

    /// Clears the target for a frame of `width`×`height`, keeping its allocations: buffers
    /// grow only when the size needs more than they ever held, so a renderer that draws frame
    /// after frame into one target allocates nothing once it has seen its largest size (a
    /// fresh target per frame cost a small model more in page faults than in drawing).
    pub(crate) fn reset(&mut self, width: u32, height: u32) {
        let n = width as usize * height as usize;
        let tiles_x = width.div_ceil(TILE);
        let tiles_y = height.div_ceil(TILE);
        let supers_x = tiles_x.div_ceil(SUPER);
        let supers_y = tiles_y.div_ceil(SUPER);
        let nt = tiles_x as usize * tiles_y as usize;
        self.width = width;
        self.height = height;
        self.tiles_x = tiles_x;
        self.tiles_y = tiles_y;
        self.supers_x = supers_x;
        self.keys.truncate(n);
        self.keys
            .par_iter_mut()
            .for_each(|k| *k.get_mut() = EMPTY_KEY);
        self.keys.resize_with(n, || AtomicU64::new(EMPTY_KEY));
        self.pixel_depth.clear();
        self.pixel_depth
            .par_extend(rayon::iter::repeat_n(f32::INFINITY, n));
        self.tile_max.clear();
        self.tile_max.resize(nt, f32::INFINITY);
        self.tile_dirty.truncate(nt);
        for d in &mut self.tile_dirty {
            *d.get_mut() = false;
        }
        self.tile_dirty.resize_with(nt, || AtomicBool::new(false));
        self.super_max.clear();
        self.super_max
            .resize(supers_x as usize * supers_y as usize, f32::INFINITY);
    }

    /// Writes one fragment (keeps the minimum key).
    #[inline]
    pub(crate) fn write(&self, x: u32, y: u32, key: u64) {
        let k = &self.keys[y as usize * self.width as usize + x as usize];
        // A plain load first: most fragments of a front-to-back traversal lose, and a load
        // costs far less than a read-modify-write.
        if key < k.load(Ordering::Relaxed) {
            k.fetch_min(key, Ordering::Relaxed);
        }
    }

    /// Fills the inclusive pixel rectangle with `key`; appends the fine tiles it made dirty
    /// (each tile once until the next [`Self::update_dirty`]) to `dirty`.
    #[inline]
    pub(crate) fn write_rect(
        &self,
        x0: u32,
        y0: u32,
        x1: u32,
        y1: u32,
        key: u64,
        dirty: &mut Vec<u32>,
    ) {
        let w = self.width as usize;
        for y in y0..=y1 {
            let row = &self.keys[y as usize * w..y as usize * w + w];
            for k in &row[x0 as usize..=x1 as usize] {
                // A plain load first: most fragments of a front-to-back traversal lose, and a
                // load costs far less than a read-modify-write.
                if key < k.load(Ordering::Relaxed) {
                    k.fetch_min(key, Ordering::Relaxed);
                }
            }
        }
        self.mark_dirty(x0, y0, x1, y1, dirty);
    }

    /// Flags the fine tiles under the inclusive pixel rectangle as dirty, appending each not
    /// yet flagged since the last [`Self::update_dirty`] to `dirty`.
    #[inline]
    pub(crate) fn mark_dirty(&self, x0: u32, y0: u32, x1: u32, y1: u32, dirty: &mut Vec<u32>) {
        for ty in y0 / TILE..=y1 / TILE {
            for tx in x0 / TILE..=x1 / TILE {
                let t = ty * self.tiles_x + tx;
                let d = &self.tile_dirty[t as usize];
                if !d.load(Ordering::Relaxed) && !d.swap(true, Ordering::Relaxed) {
                    dirty.push(t);
                }
            }
        }
    }

    /// Recomputes every tile (after triangles were rasterised straight into the keys).
    pub(crate) fn update_all_tiles(&mut self) {
        let mut all = std::mem::take(&mut self.all_tiles);
        all.clear();
        all.extend(0..self.tile_max.len() as u32);
        for d in &self.tile_dirty {
            d.store(true, Ordering::Relaxed);
        }
        self.update_dirty(&all);
        self.all_tiles = all;
    }

    /// Clears the dirty flags of the listed tiles without recomputing them (no culling).
    pub(crate) fn clear_dirty(&self, dirty: &[u32]) {
        for &t in dirty {
            self.tile_dirty[t as usize].store(false, Ordering::Relaxed);
        }
    }

    /// Depths of fine tile `t`'s pixels, row by row (INFINITY where empty or outside).
    fn tile_depths(&self, t: u32) -> [f32; (TILE * TILE) as usize] {
        let (tx, ty) = (t % self.tiles_x, t / self.tiles_x);
        let (w, h) = (self.width, self.height);
        let mut out = [f32::INFINITY; (TILE * TILE) as usize];
        for y in ty * TILE..((ty + 1) * TILE).min(h) {
            let row = y as usize * w as usize;
            for x in tx * TILE..((tx + 1) * TILE).min(w) {
                out[((y - ty * TILE) * TILE + (x - tx * TILE)) as usize] =
                    key_depth(self.keys[row + x as usize].load(Ordering::Relaxed));
            }
        }
        out
    }

    /// Recomputes the listed fine tiles (each listed once, all flagged dirty): their pixels'
    /// depths, max depths, and their coarse tiles. Work follows the tiles written, not the
    /// image size.
    pub(crate) fn update_dirty(&mut self, dirty: &[u32]) {
        if dirty.is_empty() {
            return;
        }
        let mut depths = std::mem::take(&mut self.tile_depths);
        let mut supers = std::mem::take(&mut self.supers);
        depths.clear();
        supers.clear();
        let this = &*self;
        if dirty.len() > 1024 {
            depths.par_extend(dirty.par_iter().map(|&t| this.tile_depths(t)));
        } else {
            depths.extend(dirty.iter().map(|&t| this.tile_depths(t)));
        }
        let (w, h) = (self.width, self.height);
        for (&t, d) in dirty.iter().zip(&depths) {
            let (tx, ty) = (t % self.tiles_x, t / self.tiles_x);
            let mut max = 0.0f32;
            for y in ty * TILE..((ty + 1) * TILE).min(h) {
                for x in tx * TILE..((tx + 1) * TILE).min(w) {
                    let v = d[((y - ty * TILE) * TILE + (x - tx * TILE)) as usize];
                    self.pixel_depth[y as usize * w as usize + x as usize] = v;
                    max = max.max(v);
                }
            }
            self.tile_max[t as usize] = max;
            self.tile_dirty[t as usize].store(false, Ordering::Relaxed);
            supers.push((ty / SUPER) * self.supers_x + tx / SUPER);
        }
        supers.sort_unstable();
        supers.dedup();
        for &s in &supers {
            self.refresh_super(s);
        }
        self.tile_depths = depths;
        self.supers = supers;
    }

    /// Recomputes coarse tile `s` from its fine tiles.
    fn refresh_super(&mut self, s: u32) {
        let (tx_n, tiles_y, sx_n) = (self.tiles_x, self.tiles_y, self.supers_x);
        let (sx, sy) = (s % sx_n, s / sx_n);
        let mut max = 0.0f32;
        'tiles: for ty in sy * SUPER..((sy + 1) * SUPER).min(tiles_y) {
            for tx in sx * SUPER..((sx + 1) * SUPER).min(tx_n) {
                max = max.max(self.tile_max[(ty * tx_n + tx) as usize]);
                if max == f32::INFINITY {
                    break 'tiles;
                }
            }
        }
        self.super_max[s as usize] = max;
    }

    /// Fills the inclusive rectangles with the nearest depth there is (texels nobody reads:
    /// `render::sampled`), keys and occlusion data alike, so the occlusion test takes them as
    /// covered. Each rectangle must start on a fine tile and end on one's last texel or the
    /// image's edge.
    pub(crate) fn fill_nearest(&mut self, rects: impl Iterator<Item = [u32; 4]>) {
        let key = pack_key(0.0, 0);
        let w = self.width as usize;
        for [x0, y0, x1, y1] in rects {
            debug_assert!(x0.is_multiple_of(TILE) && y0.is_multiple_of(TILE));
            for y in y0..=y1 {
                let row = y as usize * w;
                for i in row + x0 as usize..=row + x1 as usize {
                    *self.keys[i].get_mut() = key;
                    self.pixel_depth[i] = 0.0;
                }
            }
            for ty in y0 / TILE..=y1 / TILE {
                for tx in x0 / TILE..=x1 / TILE {
                    self.tile_max[(ty * self.tiles_x + tx) as usize] = 0.0;
                }
            }
        }
        for s in 0..self.super_max.len() as u32 {
            self.refresh_super(s);
        }
    }

    /// True when every pixel of the inclusive rectangle already holds something nearer than
    /// `ndc_depth`: pixel by pixel for rectangles of up to 16 pixels, else conservatively by
    /// tile maxima (both as of the last tile update).
    #[inline]
    pub(crate) fn occluded(&self, x0: u32, y0: u32, x1: u32, y1: u32, ndc_depth: f32) -> bool {
        if (x1 - x0 + 1) * (y1 - y0 + 1) <= 16 {
            for y in y0..=y1 {
                let row = &self.pixel_depth[y as usize * self.width as usize..];
                for &d in &row[x0 as usize..=x1 as usize] {
                    if d >= ndc_depth {
                        return false;
                    }
                }
            }
            return true;
        }
        let (tx0, ty0, tx1, ty1) = (x0 / TILE, y0 / TILE, x1 / TILE, y1 / TILE);
        if (tx1 - tx0 + 1) * (ty1 - ty0 + 1) <= 64 {
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    if self.tile_max[(ty * self.tiles_x + tx) as usize] >= ndc_depth {
                        return false;
                    }
                }
            }
            return true;
        }
        let (sx0, sy0, sx1, sy1) = (tx0 / SUPER, ty0 / SUPER, tx1 / SUPER, ty1 / SUPER);
        if (sx1 - sx0 + 1) * (sy1 - sy0 + 1) > 64 {
            return false;
        }
        for sy in sy0..=sy1 {
            for sx in sx0..=sx1 {
                if self.super_max[(sy * self.supers_x + sx) as usize] >= ndc_depth {
                    return false;
                }
            }
        }
        true
    }

    /// The packed keys as plain values.
    #[cfg(test)]
    pub(crate) fn into_keys(self) -> Vec<u64> {
        self.keys.into_iter().map(AtomicU64::into_inner).collect()
    }

    /// The packed key of pixel `i` (row by row), once drawing is done.
    #[inline]
    pub(crate) fn key(&self, i: usize) -> u64 {
        self.keys[i].load(Ordering::Relaxed)
    }
}

/// Why an image could not be written or read. The detail is in words (see
/// [`crate::mesh::image_error_text`]), never the decoder's debug text.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ImageError {
    /// The PNG encoder or the file system failed.
    #[error("cannot write image {path}: {detail}")]
    Write {
        /// The target path.
        path: String,
        /// What failed.
        detail: String,
    },
    /// The PNG decoder or the file system failed.
    #[error("cannot read image {path}: {detail}")]
    Read {
        /// The source path.
        path: String,
        /// What failed.
        detail: String,
    },
}

impl ImageError {
    /// What failed, without the path (for a message that names the file its own way).
    #[must_use]
    pub fn detail(&self) -> &str {
        match self {
            Self::Write { detail, .. } | Self::Read { detail, .. } => detail,
        }
    }
}

/// An 8-bit sRGB RGBA image, rows top to bottom.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RgbaImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height * 4` bytes.
    pub pixels: Vec<u8>,
}

impl RgbaImage {
    /// Box-filters `k`×`k` blocks of samples into one pixel each, in place: colour averaged in
    /// linear light (sRGB decoded, averaged, encoded), alpha averaged. The allocation is kept.
    /// The width and height must be multiples of `k`.
    pub(crate) fn downsample(&mut self, k: u32) {
        if k <= 1 {
            return;
        }
        let lin = crate::mesh::srgb_byte_to_linear;
        let (w, h) = (self.width / k, self.height / k);
        let big_w = self.width as usize;
        let inv = 1.0 / (k * k) as f32;
        let k = k as usize;
        // As in `FrameBuffers::decimate`: output pixel o reads only input pixels ≥ o.
        for y in 0..h as usize {
            for x in 0..w as usize {
                let mut sum = [0.0f32; 4];
                for j in 0..k {
                    let row = ((y * k + j) * big_w + x * k) * 4;
                    for px in self.pixels[row..row + 4 * k].chunks_exact(4) {
                        sum[0] += lin(px[0]);
                        sum[1] += lin(px[1]);
                        sum[2] += lin(px[2]);
                        sum[3] += f32::from(px[3]);
                    }
                }
                let o = (y * w as usize + x) * 4;
                for (c, v) in sum.iter().take(3).enumerate() {
                    self.pixels[o + c] = super::shade::linear_to_srgb8(v * inv);
                }
                self.pixels[o + 3] = (sum[3] * inv).round() as u8;
            }
        }
        self.pixels.truncate(w as usize * h as usize * 4);
        self.width = w;
        self.height = h;
    }

    /// A blank (transparent black) image.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            pixels: vec![0; width as usize * height as usize * 4],
        }
    }

    /// The RGBA bytes of pixel `(x, y)`.
    #[must_use]
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let o = (y as usize * self.width as usize + x as usize) * 4;
        [
            self.pixels[o],
            self.pixels[o + 1],
            self.pixels[o + 2],
            self.pixels[o + 3],
        ]
    }

    /// As an `image` crate buffer.
    #[must_use]
    pub fn to_rgba8(&self) -> image::RgbaImage {
        image::RgbaImage::from_raw(self.width, self.height, self.pixels.clone())
            .unwrap_or_else(|| image::RgbaImage::new(self.width, self.height))
    }

    /// From an `image` crate buffer.
    #[must_use]
    pub fn from_rgba8(img: &image::RgbaImage) -> Self {
        Self {
            width: img.width(),
            height: img.height(),
            pixels: img.as_raw().clone(),
        }
    }

    /// Writes a PNG.
    ///
    /// # Errors
    /// Encoder or file-system failure, with the path.
    pub fn save_png(&self, path: impl AsRef<Path>) -> Result<(), ImageError> {
        let path = path.as_ref();
        self.to_rgba8()
            .save_with_format(path, image::ImageFormat::Png)
            .map_err(|e| ImageError::Write {
                path: path.display().to_string(),
                detail: crate::mesh::image_error_text(&e),
            })
    }

    /// Reads a PNG (any colour type, converted to RGBA8).
    ///
    /// # Errors
    /// Decoder or file-system failure, with the path.
    pub fn load_png(path: impl AsRef<Path>) -> Result<Self, ImageError> {
        let path = path.as_ref();
        let read_error = |detail| ImageError::Read {
            path: path.display().to_string(),
            detail,
        };
        let bytes = std::fs::read(path).map_err(|e| read_error(e.to_string()))?;
        crate::mesh::check_png_chunks(&bytes).map_err(read_error)?;
        let img = crate::mesh::decode_contained(|| image::load_from_memory(&bytes))
            .map_err(read_error)?;
        Ok(Self::from_rgba8(&img.to_rgba8()))
    }
}

/// What a pixel shows (object and node), for picking, coverage and GPU parity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PixelId {
    /// 1-based index of the object in the rendered scene (0 = background).
    pub object: u32,
    /// Voxels: `(level << 32) | node index in its pool`; meshes: `(part << 32) | triangle`.
    pub node: u64,
}

/// The resolved buffers of a frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrameBuffers {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// NDC depth, 0 at near, 1 at far (1 for background). See `render::camera`.
    pub depth: Vec<f32>,
    /// Object and node per pixel.
    pub ids: Vec<PixelId>,
    /// World-space unit normal (zero for background).
    pub normal: Vec<Vec3>,
    /// Linear albedo (zero for background).
    pub albedo: Vec<Vec3>,
}

impl FrameBuffers {
    /// Keeps one sample of each `k`×`k` block (the one at `(k/2, k/2)` in the block, nearest the
    /// pixel's centre) in place: the G-buffer of a supersampled frame at its image's size, for
    /// ids (picking, outlines) and coverage. The buffers keep their capacity. The width and
    /// height must be multiples of `k`.
    pub(crate) fn decimate(&mut self, k: u32) {
        if k <= 1 {
            return;
        }
        let (w, h) = (self.width / k, self.height / k);
        let (big_w, c) = (self.width as usize, (k / 2) as usize);
        let k = k as usize;
        // In raster order, output pixel o reads input pixels at indices ≥ o (k ≥ 2), so
        // nothing is overwritten before it is read.
        for y in 0..h as usize {
            for x in 0..w as usize {
                let from = (y * k + c) * big_w + x * k + c;
                let to = y * w as usize + x;
                self.depth[to] = self.depth[from];
                self.ids[to] = self.ids[from];
                self.normal[to] = self.normal[from];
                self.albedo[to] = self.albedo[from];
            }
        }
        let n = w as usize * h as usize;
        self.depth.truncate(n);
        self.ids.truncate(n);
        self.normal.truncate(n);
        self.albedo.truncate(n);
        self.width = w;
        self.height = h;
    }

    /// True where something was drawn.
    #[must_use]
    pub fn coverage(&self) -> Vec<bool> {
        self.ids.iter().map(|p| p.object != 0).collect()
    }

    /// Number of pixels showing anything.
    #[must_use]
    pub fn covered_pixels(&self) -> usize {
        // Parallel: every frame counts them (10 MB of ids at 800×800).
        self.ids.par_iter().filter(|p| p.object != 0).count()
    }

    /// The id at `(x, y)`.
    #[must_use]
    pub fn id(&self, x: u32, y: u32) -> PixelId {
        self.ids[y as usize * self.width as usize + x as usize]
    }
}

//! Splat-pass bandwidth (issue #7: "splat pass bandwidth >= 50 % of a same-device buffer
//! copy"): how many bytes the view's voxel pass moves, how long that pass alone takes, and how
//! long a `copy_buffer_to_buffer` of the same byte count takes on the same device, timed the
//! same way.
//!
//! **Bytes** ([`SplatBytes`], from the pass's own counters): every visited node reads its
//! 16-byte queue entry, and that entry was written once (by the seed for the root, by its
//! parent's split otherwise); a split node reads its 8-byte inner record (first child, child
//! mask); every pixel a splat covers is one 8-byte `atomicMin` on the key buffer (64-bit path);
//! with occlusion culling on, the occlusion-tile build before each level of each object reads
//! the 4-byte depth word of every pixel and writes one 4-byte word per tile. Not counted: the
//! uniforms (per-level node parameters, view), the indirect arguments, the workgroup counter
//! flushes and each node's reads of a few occlusion tiles (all small next to the rest, and
//! cached on a GPU). An atomic is counted once, as the 8 bytes it writes.
//!
//! **Time**: one submission holding only the voxel pass (seed, per-level indirect setup,
//! occlusion tiles and traversal/splat dispatches), after an untimed submission that restores
//! the state the frame's voxel pass starts from (counters cleared, keys cleared, meshes
//! drawn), so the pass does exactly the frame's work. The reference is one submission holding
//! only a copy of the same byte count between two fresh buffers. Each is repeated after a
//! warm-up and the median is kept. Wall clock: from `submit` to the end of a blocking
//! `device.poll`. GPU timestamps around the pass (and around the copy, by two empty compute
//! passes) are read as well where the device has them; they are the headline only on a
//! device that is not a CPU (lavapipe's timestamps do not time compute work). The ratio
//! `copy time / splat time` is the splat pass's bandwidth as a fraction of the copy's, for any
//! convention on how to count a copy's bytes, since both move the same count.

use std::time::Instant;

use serde::Serialize;

use super::gpu_data::{KEY_BYTES, OCCLUSION_TILE, QUEUE_ENTRY_BYTES};
use super::{GpuError, GpuLevelStats};

/// Bytes of one inner-node record (`vec2<u32>`: first child, child mask).
pub const INNER_RECORD_BYTES: u64 = 8;
/// Bytes of the depth word the occlusion-tile build reads per pixel.
pub const DEPTH_WORD_BYTES: u64 = 4;

/// What the view's voxel pass moves, by kind (see the module documentation).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct SplatBytes {
    /// Queue entries read: 16 bytes per visited node.
    pub queue_reads: u64,
    /// Queue entries written: 16 bytes per visited node (the seed's root, the splits' children).
    pub queue_writes: u64,
    /// Inner-node records read: 8 bytes per split node.
    pub inner_reads: u64,
    /// Key atomics: 8 bytes per pixel covered by a splat.
    pub key_atomics: u64,
    /// Occlusion tiles: per build, 4 bytes per pixel read and 4 per tile written.
    pub occlusion: u64,
}

impl SplatBytes {
    /// All of it.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.queue_reads + self.queue_writes + self.inner_reads + self.key_atomics + self.occlusion
    }
}

/// The occlusion-tile builds a voxel pass runs.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct OcclusionWork {
    /// Builds: one before each level of each object (0 with occlusion culling off).
    pub builds: u64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// The bytes of a voxel pass with these counters (`levels`, `splat_pixels` as in
/// [`super::GpuFrameStats`]) on the 64-bit splat path.
#[must_use]
pub fn splat_pass_bytes(
    levels: &[GpuLevelStats],
    splat_pixels: u64,
    occlusion: OcclusionWork,
) -> SplatBytes {
    let visited: u64 = levels.iter().map(|l| l.visited).sum();
    let split: u64 = levels.iter().map(|l| l.split).sum();
    let (w, h) = (u64::from(occlusion.width), u64::from(occlusion.height));
    let tiles = w.div_ceil(u64::from(OCCLUSION_TILE)) * h.div_ceil(u64::from(OCCLUSION_TILE));
    SplatBytes {
        queue_reads: visited * QUEUE_ENTRY_BYTES,
        queue_writes: visited * QUEUE_ENTRY_BYTES,
        inner_reads: split * INNER_RECORD_BYTES,
        key_atomics: splat_pixels * KEY_BYTES,
        occlusion: occlusion.builds * (w * h * DEPTH_WORD_BYTES + tiles * 4),
    }
}

/// One splat-bandwidth measurement.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SplatBandwidth {
    /// The bytes the pass moved, by kind (from the measured pass's own counters).
    pub bytes: SplatBytes,
    /// `bytes.total()`: also the size of the reference copy.
    pub total_bytes: u64,
    /// The occlusion-tile builds counted in `bytes.occlusion`.
    pub occlusion: OcclusionWork,
    /// Nodes the measured pass visited, per level (equal to the frame's).
    pub levels: Vec<GpuLevelStats>,
    /// Pixels the measured pass's splats covered (equal to the frame's).
    pub splat_pixels: u64,
    /// Timed submissions of each kind (after one warm-up).
    pub repeats: u32,
    /// Median wall milliseconds of a submission holding only the voxel pass.
    pub splat_wall_ms: f64,
    /// Median wall milliseconds of a submission holding only the copy.
    pub copy_wall_ms: f64,
    /// Median of the GPU timestamps around the voxel pass, where the device has them.
    pub splat_timestamp_ms: Option<f64>,
    /// Median of the GPU timestamps around the copy, where the device has them.
    pub copy_timestamp_ms: Option<f64>,
    /// Which times the figures below use: "timestamps" or "wall clock".
    pub timing: &'static str,
    /// `total_bytes` / splat time, in GB/s (10^9 bytes per second).
    pub splat_gb_per_s: f64,
    /// `total_bytes` / copy time, in GB/s.
    pub copy_gb_per_s: f64,
    /// Splat bandwidth over copy bandwidth (= copy time / splat time).
    pub ratio: f64,
}

/// What the renderer hands the measurement: encoders for the restore and the voxel pass, and
/// a read-back of the counters the last voxel pass left.
pub(super) struct ProbePasses<'a> {
    /// Restores the state the frame's voxel pass starts from.
    pub restore: &'a dyn Fn(&mut wgpu::CommandEncoder),
    /// Encodes the voxel pass, with timestamps (queries 0 and 1) into the set when given.
    pub splat: &'a dyn Fn(&mut wgpu::CommandEncoder, Option<&wgpu::QuerySet>),
    /// The view's level counters and splat pixels after the last voxel pass.
    pub read_counters: &'a dyn Fn() -> Result<(Vec<GpuLevelStats>, u64), GpuError>,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// Two timestamp queries and the buffers to read them back.
struct Queries {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    staging: wgpu::Buffer,
    period_ns: f64,
}

impl Queries {
    fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Self {
        use wgpu::BufferUsages as U;
        let buffer = |label, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16,
                usage,
                mapped_at_creation: false,
            })
        };
        Self {
            set: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("splat bandwidth timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            }),
            resolve: buffer("splat bandwidth resolve", U::QUERY_RESOLVE | U::COPY_SRC),
            staging: buffer("splat bandwidth readback", U::MAP_READ | U::COPY_DST),
            period_ns: f64::from(queue.get_timestamp_period()),
        }
    }

    /// Milliseconds between query 0 and query 1 of the last submission.
    fn read_ms(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<f64, GpuError> {
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("splat bandwidth timestamps"),
        });
        enc.resolve_query_set(&self.set, 0..2, &self.resolve, 0);
        enc.copy_buffer_to_buffer(&self.resolve, 0, &self.staging, 0, 16);
        queue.submit([enc.finish()]);
        let raw = super::renderer::map_read(device, &self.staging)?;
        let ticks: &[u64] = bytemuck::cast_slice(&raw[..16]);
        Ok(ticks[1].saturating_sub(ticks[0]) as f64 * self.period_ns * 1e-6)
    }
}

fn wait(device: &wgpu::Device) -> Result<(), GpuError> {
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map(|_| ())
        .map_err(|e| GpuError::Readback(e.to_string()))
}

/// Times `repeats` submissions of `timed` (after one warm-up), each after an untimed
/// submission of `prepare`: wall-clock milliseconds, and timestamp milliseconds when `queries`.
fn time_submissions(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    repeats: u32,
    prepare: Option<&dyn Fn(&mut wgpu::CommandEncoder)>,
    timed: &dyn Fn(&mut wgpu::CommandEncoder, Option<&wgpu::QuerySet>),
    queries: Option<&Queries>,
) -> Result<(Vec<f64>, Vec<f64>), GpuError> {
    let encoder = || {
        device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("splat bandwidth"),
        })
    };
    let (mut wall, mut stamps) = (Vec::new(), Vec::new());
    for i in 0..=repeats {
        if let Some(prepare) = prepare {
            let mut enc = encoder();
            prepare(&mut enc);
            queue.submit([enc.finish()]);
            wait(device)?;
        }
        let mut enc = encoder();
        timed(&mut enc, queries.map(|q| &q.set));
        let commands = enc.finish();
        let t0 = Instant::now();
        queue.submit([commands]);
        wait(device)?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        // Submission 0 warms caches and lazily created driver state.
        if i > 0 {
            wall.push(ms);
            if let Some(q) = queries {
                stamps.push(q.read_ms(device, queue)?);
            }
        }
    }
    Ok((wall, stamps))
}

/// Measures the voxel pass `passes` encodes against a same-size buffer copy (see the module
/// documentation). `occlusion` is what the pass builds; `timestamps`: the device has
/// timestamp queries.
pub(super) fn measure(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    passes: &ProbePasses<'_>,
    repeats: u32,
    occlusion: OcclusionWork,
    timestamps: bool,
) -> Result<SplatBandwidth, GpuError> {
    let repeats = repeats.max(1);
    let queries = timestamps.then(|| Queries::new(device, queue));
    let (mut splat_wall, mut splat_ts) = time_submissions(
        device,
        queue,
        repeats,
        Some(passes.restore),
        passes.splat,
        queries.as_ref(),
    )?;
    let (levels, splat_pixels) = (passes.read_counters)()?;
    let bytes = splat_pass_bytes(&levels, splat_pixels, occlusion);
    let total_bytes = bytes.total();
    let copy_bytes = total_bytes
        .max(wgpu::COPY_BUFFER_ALIGNMENT)
        .next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
    let limit = device.limits().max_buffer_size;
    if copy_bytes > limit {
        return Err(GpuError::TooLarge {
            what: "splat bandwidth reference copy",
            bytes: copy_bytes,
            limit,
        });
    }
    let buffer = |label, usage| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: copy_bytes,
            usage,
            mapped_at_creation: false,
        })
    };
    let src = buffer("copy source", wgpu::BufferUsages::COPY_SRC);
    let dst = buffer("copy destination", wgpu::BufferUsages::COPY_DST);
    let copy = |enc: &mut wgpu::CommandEncoder, set: Option<&wgpu::QuerySet>| {
        // Empty passes carry the timestamps: a copy has no timestamp writes of its own.
        let stamp = |enc: &mut wgpu::CommandEncoder, begin, end| {
            if let Some(set) = set {
                drop(enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("copy timestamp"),
                    timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                        query_set: set,
                        beginning_of_pass_write_index: begin,
                        end_of_pass_write_index: end,
                    }),
                }));
            }
        };
        stamp(enc, None, Some(0));
        enc.copy_buffer_to_buffer(&src, 0, &dst, 0, copy_bytes);
        stamp(enc, Some(1), None);
    };
    let (mut copy_wall, mut copy_ts) =
        time_submissions(device, queue, repeats, None, &copy, queries.as_ref())?;
    let splat_wall_ms = median(&mut splat_wall);
    let copy_wall_ms = median(&mut copy_wall);
    let splat_timestamp_ms = (!splat_ts.is_empty()).then(|| median(&mut splat_ts));
    let copy_timestamp_ms = (!copy_ts.is_empty()).then(|| median(&mut copy_ts));
    // A CPU "GPU" (lavapipe, SwiftShader) does not time compute work with its timestamps.
    let trust = device.adapter_info().device_type != wgpu::DeviceType::Cpu;
    let (timing, splat_ms, copy_ms) = match (splat_timestamp_ms, copy_timestamp_ms) {
        (Some(s), Some(c)) if trust && s > 0.0 && c > 0.0 => ("timestamps", s, c),
        _ => ("wall clock", splat_wall_ms, copy_wall_ms),
    };
    let gb_per_s = |ms: f64| {
        if ms > 0.0 {
            total_bytes as f64 / (ms * 1e-3) / 1e9
        } else {
            0.0
        }
    };
    Ok(SplatBandwidth {
        bytes,
        total_bytes,
        occlusion,
        levels,
        splat_pixels,
        repeats,
        splat_wall_ms,
        copy_wall_ms,
        splat_timestamp_ms,
        copy_timestamp_ms,
        timing,
        splat_gb_per_s: gb_per_s(splat_ms),
        copy_gb_per_s: gb_per_s(copy_ms),
        ratio: if splat_ms > 0.0 {
            copy_ms / splat_ms
        } else {
            0.0
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_follow_the_counters() {
        let level = |visited, split| GpuLevelStats {
            visited,
            split,
            splatted: visited - split,
            ..GpuLevelStats::default()
        };
        let levels = [level(1, 1), level(8, 3), level(20, 0)];
        let b = splat_pass_bytes(
            &levels,
            100,
            OcclusionWork {
                builds: 3,
                width: 16,
                height: 9,
            },
        );
        assert_eq!(b.queue_reads, 29 * 16);
        assert_eq!(b.queue_writes, 29 * 16);
        assert_eq!(b.inner_reads, 4 * 8);
        assert_eq!(b.key_atomics, 800);
        // 16 x 9 pixels in 2 x 2 tiles of 8 px.
        assert_eq!(b.occlusion, 3 * (144 * 4 + 4 * 4));
        assert_eq!(b.total(), 464 + 464 + 32 + 800 + 3 * 592);
        let none = splat_pass_bytes(&levels, 100, OcclusionWork::default());
        assert_eq!(none.occlusion, 0);
    }

    #[test]
    fn median_of_odd_and_even_counts() {
        assert!((median(&mut [3.0, 1.0, 2.0]) - 2.0).abs() < 1e-12);
        assert!((median(&mut [4.0, 1.0, 3.0, 2.0]) - 3.0).abs() < 1e-12);
    }
}

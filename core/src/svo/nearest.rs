//! Every interior voxel's nearest surface voxel at once ([`Svo::nearest_surfaces`]): what
//! [`Svo::nearest_surface`] gives each one (distance between voxel centres, ties to the smaller
//! Morton code), for exports that must write a colour into every voxel of a solid (`.vox`).
//!
//! One search per voxel costs what the shell near it costs: about 28 µs a voxel deep inside
//! Spot, a minute for a depth-8 solid. Here instead:
//! 1. an exact squared Euclidean distance transform over the octree's bounds, sites the voxels
//!    that are not interior (three separable passes, each the lower envelope of parabolas of
//!    Felzenszwalb and Huttenlocher). The distances are integers; the parabolas' crossings are
//!    f64 quotients of integers below 2^53, whose rounding cannot change which parabola is
//!    lowest at an integer position;
//! 2. each interior voxel's squared distance `N` then names its nearest voxels exactly: they
//!    are the sites at the offsets `v` with `|v|² = N`. A nearest site bounds each face
//!    neighbour's distance (`|v − e|² ≥ d(p + e)`), so only the offsets in the box
//!    `v·e ≤ (N + 1 − d(p + e)) / 2` are enumerated, usually a handful; the smallest Morton code
//!    among the sites there wins, as in the search.
//!
//! Memory: 4 bytes a cell of the bounds (the squared distance, then in place the nearest
//! site) plus two bits. Declined (the caller then searches voxel by voxel) for bounds over
//! `MAX_CELLS` cells or `MAX_SIDE` a side, and where interior voxels are under
//! 1/`MIN_INTERIOR_SHARE` of the bounds: there the transform's cost, which follows the bounds,
//! exceeds the searches'.

use glam::{IVec3, UVec3};
use rayon::prelude::*;

use super::{Svo, morton_encode};

/// The most cells of an octree's bounds the transform takes: cell indices fit 32 bits beside
/// [`NONE`] (16 GiB of distances).
pub const MAX_CELLS: u64 = (1 << 32) - 1;

/// The longest side of the bounds the transform takes: every squared distance then fits 32
/// bits (3 · 2^30).
pub const MAX_SIDE: u32 = 1 << 15;

/// Bytes [`Svo::nearest_surfaces`] holds per cell of the octree's bounds.
pub const BYTES_PER_CELL: f64 = 4.25;

/// The transform runs when at least one cell of the bounds in this many is interior: a
/// search costs about what the transform costs for 100 to 300 cells.
pub const MIN_INTERIOR_SHARE: u64 = 64;

/// No site: the octree has no voxel that is not interior.
const NONE: u32 = u32::MAX;

/// The nearest surface voxel of every interior voxel ([`Svo::nearest_surfaces`]).
#[derive(Debug, Clone)]
pub struct NearestSurfaces {
    lo: UVec3,
    dims: UVec3,
    /// Per cell of the bounds: the nearest site's cell index for interior voxels.
    site: Vec<u32>,
}

impl NearestSurfaces {
    /// The nearest voxel that is not interior to interior voxel `c`, as
    /// [`Svo::nearest_surface`] gives it; `None` for a voxel outside the bounds or when every
    /// voxel is interior. Meaningless for a voxel that is not interior.
    #[must_use]
    pub fn get(&self, c: UVec3) -> Option<UVec3> {
        let p = c.checked_sub(self.lo)?;
        if p.cmpge(self.dims).any() {
            return None;
        }
        let s = *self.site.get(index(self.dims, p))?;
        (s != NONE).then(|| self.lo + position(self.dims, s as usize))
    }
}

fn index(dims: UVec3, p: UVec3) -> usize {
    p.x as usize + dims.x as usize * (p.y as usize + dims.y as usize * p.z as usize)
}

fn position(dims: UVec3, i: usize) -> UVec3 {
    let (dx, dy) = (dims.x as usize, dims.y as usize);
    UVec3::new(
        (i % dx) as u32,
        (i / dx % dy) as u32,
        (i / (dx * dy)) as u32,
    )
}

/// Squared distance standing for "no site" during a line's transform: larger than any.
const FAR: i64 = 1 << 40;

/// "No site" as stored between passes: larger than any squared distance under `MAX_SIDE`.
const FAR32: u32 = u32::MAX;

/// The 1-D squared distance transform of `f` into `d` (Felzenszwalb and Huttenlocher): `d[q]`
/// is the minimum over `p` of `f[p] + (q − p)²`. `v` and `z` are scratch of `f`'s length and
/// one more.
fn transform_line(f: &[i64], d: &mut [i64], v: &mut [usize], z: &mut [f64]) {
    let n = f.len();
    let mut k = 0usize;
    let mut started = false;
    for q in 0..n {
        if f[q] >= FAR {
            continue;
        }
        if !started {
            v[0] = q;
            z[0] = f64::NEG_INFINITY;
            z[1] = f64::INFINITY;
            started = true;
            continue;
        }
        // Pop the parabolas q's hides; z[0] = −∞ stops at the first.
        let mut s;
        loop {
            let p = v[k];
            // Where the parabolas from p and q cross (exact in f64 below 2^52).
            s = ((f[q] + (q * q) as i64) - (f[p] + (p * p) as i64)) as f64 / (2 * (q - p)) as f64;
            if s > z[k] {
                break;
            }
            k -= 1;
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    if !started {
        d.fill(FAR);
        return;
    }
    let mut k = 0usize;
    for (q, out) in d.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        let dq = q as i64 - p as i64;
        *out = (dq * dq + f[p]).min(FAR);
    }
}

/// The integer square root: the largest `r` with `r² ≤ n`.
fn isqrt(n: i64) -> i64 {
    let mut r = (n.max(0) as f64).sqrt() as i64;
    while r * r > n {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= n {
        r += 1;
    }
    r
}

/// Calls `f` with every lattice offset `v` of squared length `n` inside the box `lo..=hi`.
fn offsets_within(n: i64, lo: IVec3, hi: IVec3, mut f: impl FnMut(IVec3)) {
    let r = isqrt(n);
    for a in i64::from(lo.x).max(-r)..=i64::from(hi.x).min(r) {
        let rest_a = n - a * a;
        let rb = isqrt(rest_a);
        for b in i64::from(lo.y).max(-rb)..=i64::from(hi.y).min(rb) {
            let rest = rest_a - b * b;
            let c = isqrt(rest);
            if c * c != rest {
                continue;
            }
            for c in if c == 0 { vec![0] } else { vec![-c, c] } {
                if (i64::from(lo.z)..=i64::from(hi.z)).contains(&c) {
                    f(IVec3::new(a as i32, b as i32, c as i32));
                }
            }
        }
    }
}

impl Svo {
    /// Bytes [`Self::nearest_surfaces`] needs, or `None` when it declines (module docs): no
    /// interior, bounds over 2^32 − 1 cells or 2^15 voxels a side, or interior voxels under
    /// 1/64 of the bounds.
    #[must_use]
    pub fn nearest_surfaces_bytes(&self) -> Option<u64> {
        let (lo, hi) = self.nearest_surfaces_bounds()?;
        let cells = (hi - lo + UVec3::ONE).as_u64vec3().element_product();
        Some((cells as f64 * BYTES_PER_CELL) as u64)
    }

    /// The bounds the transform covers, or `None` where it declines.
    fn nearest_surfaces_bounds(&self) -> Option<(UVec3, UVec3)> {
        if !self.may_have_interior() {
            return None;
        }
        let (lo, hi) = self.bounds()?;
        let cells = (hi - lo + UVec3::ONE).as_u64vec3().element_product();
        let worth_it = self.interior_voxels().saturating_mul(MIN_INTERIOR_SHARE) >= cells;
        (cells <= MAX_CELLS && (hi - lo).max_element() < MAX_SIDE && worth_it).then_some((lo, hi))
    }

    /// The nearest surface voxel of every interior voxel, computed together (module docs):
    /// `None` where [`Self::nearest_surfaces_bytes`] declines.
    #[must_use]
    pub fn nearest_surfaces(&self) -> Option<NearestSurfaces> {
        let (lo, hi) = self.nearest_surfaces_bounds()?;
        let dims = hi - lo + UVec3::ONE;
        let cells = dims.as_u64vec3().element_product() as usize;
        let words = cells.div_ceil(64);
        let (mut sites, mut interior) = (vec![0u64; words], vec![0u64; words]);
        self.for_each_run(|origin, height, v| {
            let bits = if v.is_interior() {
                &mut interior
            } else {
                &mut sites
            };
            let size = 1u32 << height;
            for z in 0..size {
                for y in 0..size {
                    for x in 0..size {
                        let i = index(dims, origin + UVec3::new(x, y, z) - lo);
                        bits[i / 64] |= 1 << (i % 64);
                    }
                }
            }
        });
        let bit = |bits: &[u64], i: usize| bits[i / 64] >> (i % 64) & 1 == 1;
        let (dx, dy, dz) = (dims.x as usize, dims.y as usize, dims.z as usize);
        // Squared distances (i64 within a line's transform; one line of scratch per thread).
        let mut dist: Vec<u32> = (0..cells)
            .into_par_iter()
            .map(|i| if bit(&sites, i) { 0 } else { FAR32 })
            .collect();
        let scratch = |n: usize| {
            (
                vec![0i64; n],
                vec![0i64; n],
                vec![0usize; n],
                vec![0f64; n + 1],
            )
        };
        let load = |d: u32| if d == FAR32 { FAR } else { i64::from(d) };
        let store = |d: i64| u32::try_from(d).unwrap_or(FAR32);
        // Along x: rows are contiguous.
        dist.par_chunks_mut(dx).for_each_init(
            || scratch(dx),
            |(f, d, v, z), row| {
                for (f, r) in f.iter_mut().zip(row.iter()) {
                    *f = load(*r);
                }
                transform_line(f, d, v, z);
                for (r, d) in row.iter_mut().zip(d.iter()) {
                    *r = store(*d);
                }
            },
        );
        // Along y: within each z slab.
        dist.par_chunks_mut(dx * dy).for_each_init(
            || scratch(dy),
            |(f, d, v, z), slab| {
                for x in 0..dx {
                    for y in 0..dy {
                        f[y] = load(slab[x + dx * y]);
                    }
                    transform_line(f, d, v, z);
                    for y in 0..dy {
                        slab[x + dx * y] = store(d[y]);
                    }
                }
            },
        );
        // Along z: lines cross every slab, so one thread walks them.
        let (mut f, mut d, mut v, mut z) = scratch(dz);
        for y in 0..dy {
            for x in 0..dx {
                for k in 0..dz {
                    f[k] = load(dist[x + dx * (y + dy * k)]);
                }
                transform_line(&f, &mut d, &mut v, &mut z);
                for k in 0..dz {
                    dist[x + dx * (y + dy * k)] = store(d[k]);
                }
            }
        }
        // Each interior cell's nearest site among the offsets of its squared distance `n`. A
        // nearest site at offset `v` bounds each face neighbour's distance, |v − e|² ≥ its
        // squared distance, so `v·e ≤ (n + 1 − d(p + e)) / 2` for each unit step `e`: only
        // the offsets in that box are enumerated (usually a handful of cells).
        let site_of = |dist: &[u32], i: usize| -> u32 {
            let n = dist[i];
            if n == FAR32 || !bit(&interior, i) {
                return NONE;
            }
            let p = position(dims, i).as_ivec3();
            let (mut lo_v, mut hi_v) = (IVec3::splat(i32::MIN), IVec3::splat(i32::MAX));
            for axis in 0..3 {
                for step in [-1i32, 1] {
                    let mut q = p;
                    q[axis] += step;
                    if q[axis] < 0 || q[axis] >= dims.as_ivec3()[axis] {
                        continue;
                    }
                    let dq = dist[index(dims, q.as_uvec3())];
                    if dq == FAR32 {
                        continue;
                    }
                    let bound = ((i64::from(n) + 1 - i64::from(dq)).div_euclid(2)) as i32;
                    if step > 0 {
                        hi_v[axis] = hi_v[axis].min(bound);
                    } else {
                        lo_v[axis] = lo_v[axis].max(-bound);
                    }
                }
            }
            // Within the bounds, too.
            lo_v = lo_v.max(-p);
            hi_v = hi_v.min(dims.as_ivec3() - IVec3::ONE - p);
            let mut best: Option<(u64, usize)> = None;
            offsets_within(i64::from(n), lo_v, hi_v, |o| {
                let q = (p + o).as_uvec3();
                let j = index(dims, q);
                if bit(&sites, j) {
                    let code = morton_encode(q + lo);
                    if best.is_none_or(|b| code < b.0) {
                        best = Some((code, j));
                    }
                }
            });
            best.map_or(NONE, |b| b.1 as u32)
        };
        // In place, a z slab at a time: a slab's sites are written once the next slab, whose
        // cells read its distances, is done.
        let slab = dx * dy;
        let mut pending: Option<(usize, Vec<u32>)> = None;
        for k in 0..dz {
            let out: Vec<u32> = (k * slab..(k + 1) * slab)
                .into_par_iter()
                .map(|i| site_of(&dist, i))
                .collect();
            if let Some((done, sites_of)) = pending.replace((k, out)) {
                dist[done * slab..(done + 1) * slab].copy_from_slice(&sites_of);
            }
        }
        if let Some((done, sites_of)) = pending {
            dist[done * slab..(done + 1) * slab].copy_from_slice(&sites_of);
        }
        let site = dist;
        Some(NearestSurfaces { lo, dims, site })
    }
}

#[cfg(test)]
mod tests {
    use glam::{IVec3, UVec3, Vec3};
    use proptest::prelude::*;

    use super::*;
    use crate::svo::Voxel;

    /// Brute force of the 1-D transform.
    fn line_by_brute_force(f: &[i64]) -> Vec<i64> {
        (0..f.len())
            .map(|q| {
                (0..f.len())
                    .filter(|&p| f[p] < FAR)
                    .map(|p| (q as i64 - p as i64).pow(2) + f[p])
                    .min()
                    .unwrap_or(FAR)
            })
            .collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// Property: the lower envelope gives the brute-force minimum on any line, sites or
        /// distances from an earlier pass, none at all, or one.
        #[test]
        fn a_line_transform_is_the_brute_force_minimum(
            f in proptest::collection::vec(prop_oneof![Just(FAR), 0i64..3000], 1..60),
        ) {
            let n = f.len();
            let (mut d, mut v, mut z) = (vec![0; n], vec![0; n], vec![0.0; n + 1]);
            transform_line(&f, &mut d, &mut v, &mut z);
            prop_assert_eq!(d, line_by_brute_force(&f));
        }
    }

    #[test]
    fn offsets_are_every_lattice_vector_of_their_length_in_the_box() {
        for n in [0i64, 1, 2, 3, 25, 50, 77, 169, 1001] {
            for (lo, hi) in [
                (IVec3::splat(-40), IVec3::splat(40)),
                (IVec3::new(-3, 0, -40), IVec3::new(5, 40, 2)),
                (IVec3::new(2, -1, 0), IVec3::new(2, 30, 0)),
            ] {
                let mut got = Vec::new();
                offsets_within(n, lo, hi, |v| got.push(v));
                got.sort_unstable_by_key(|v| v.to_array());
                let mut want = Vec::new();
                for a in lo.x..=hi.x {
                    for b in lo.y..=hi.y {
                        for c in lo.z..=hi.z {
                            if i64::from(a * a + b * b + c * c) == n {
                                want.push(IVec3::new(a, b, c));
                            }
                        }
                    }
                }
                assert_eq!(got, want, "n = {n}, {lo}..={hi}");
            }
        }
        assert_eq!(
            (isqrt(0), isqrt(15), isqrt(16), isqrt(1 << 40)),
            (0, 3, 4, 1 << 20)
        );
    }

    /// Checks every interior voxel of `svo` against the search.
    fn check(svo: &Svo) -> usize {
        let near = svo.nearest_surfaces().expect("an interior");
        let mut n = 0;
        svo.for_each_leaf(|c, v| {
            if v.is_interior() {
                assert_eq!(near.get(c), svo.nearest_surface(c).map(|s| s.0), "{c}");
                n += 1;
            }
        });
        n
    }

    /// A solid ball in a 32³ octree, its enclosed voxels interior, tiled.
    fn ball(r: f32) -> Svo {
        Svo::from_voxels(5, false, crate::svo::interior_tests::solid_ball(5, r))
            .unwrap()
            .with_tiles()
    }

    #[test]
    fn every_interior_voxel_gets_what_the_search_gives() {
        // Ties are everywhere in a ball (its symmetry): the smaller Morton code must win.
        let solid = ball(13.0);
        assert!(check(&solid) > 5_000);
        // With a box carved out (edits reveal, so the interior changes and the symmetry breaks)
        // and a box of one colour filled in (its voxels are sites, as a tile).
        let mut solid = ball(12.5);
        solid
            .edit_existing(UVec3::new(10, 10, 0), UVec3::new(31, 14, 31), |_, _| None)
            .unwrap();
        solid
            .edit_region(UVec3::new(14, 16, 14), UVec3::new(21, 23, 21), |_, _| {
                Some(Voxel::new([9, 9, 9, 255], Vec3::X))
            })
            .unwrap();
        assert!(check(&solid) > 1_000);
        // No interior: declined.
        let shell = Svo::from_voxels(
            5,
            false,
            [(UVec3::ONE, Voxel::new([1, 2, 3, 255], Vec3::Y))],
        )
        .unwrap();
        assert!(shell.nearest_surfaces().is_none());
    }

    #[test]
    fn with_no_surface_voxel_no_interior_voxel_has_a_nearest() {
        let lone = Svo::from_runs(5, false, [(UVec3::new(8, 8, 8), 3, Voxel::INTERIOR)]).unwrap();
        let near = lone.nearest_surfaces().expect("an interior");
        assert_eq!(near.get(UVec3::new(9, 10, 11)), None);
        assert_eq!(lone.nearest_surface(UVec3::new(9, 10, 11)), None);
    }

    #[test]
    fn a_few_interior_voxels_in_large_bounds_are_left_to_the_search() {
        // A 3³ block with an interior centre, and a voxel at the far corner: 1 interior voxel
        // in 32³ bounds, where the transform would cost what 30,000 searches do.
        let mut voxels = vec![(UVec3::splat(31), Voxel::new([1, 2, 3, 255], Vec3::Y))];
        for z in 1..4 {
            for y in 1..4 {
                for x in 1..4 {
                    let c = UVec3::new(x, y, z);
                    let v = if c == UVec3::splat(2) {
                        Voxel::INTERIOR
                    } else {
                        Voxel::new([9, 8, 7, 255], Vec3::X)
                    };
                    voxels.push((c, v));
                }
            }
        }
        let sparse = Svo::from_voxels(5, false, voxels).unwrap();
        assert_eq!(sparse.interior_voxels(), 1);
        assert!(sparse.nearest_surfaces_bytes().is_none());
        assert!(sparse.nearest_surfaces().is_none());
    }
}

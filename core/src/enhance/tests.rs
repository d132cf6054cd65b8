//! Tests of `enhance`: rules on hand-made neighbourhoods, the LUT, the bit-parallel kernel
//! against a dense reference, the Sierpinski law, determinism, incremental = full, extremes.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::AtomicBool;

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;

use super::grid::Window;
use super::*;

fn vox(color: [u8; 3], material: u8) -> Voxel {
    Voxel {
        color: [color[0], color[1], color[2], 255],
        normal: encode_normal(Vec3::Y),
        material,
        skin: Default::default(),
    }
}

fn map_from(n: u32, solid: impl Fn(UVec3) -> Option<Voxel>) -> Svo {
    let mut v = Vec::new();
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let p = UVec3::new(x, y, z);
                if let Some(s) = solid(p) {
                    v.push((p, s));
                }
            }
        }
    }
    Svo::from_voxels(n.trailing_zeros() as u8, false, v).unwrap()
}

fn random_map(n: u32, fill: f64, seed: u64) -> Svo {
    let mut rng = Pcg32::seed_from_u64(seed);
    let mut v = Vec::new();
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                if rng.random_bool(fill) {
                    let m = rng.random_range(1..=3u8);
                    let c = [rng.random(), rng.random(), rng.random()];
                    v.push((UVec3::new(x, y, z), vox(c, m)));
                }
            }
        }
    }
    Svo::from_voxels(n.trailing_zeros() as u8, false, v).unwrap()
}

fn subdivide(factor: u32, t: ThresholdPattern) -> EnhanceSettings {
    EnhanceSettings {
        method: Method::Subdivide,
        factor,
        subdivide: SubdivideSettings { threshold: t },
        ..EnhanceSettings::default()
    }
}

fn resample(factor: u32, count: u32, spread: f32, t: f32) -> EnhanceSettings {
    EnhanceSettings {
        method: Method::Resample,
        factor,
        resample: ResampleSettings {
            threshold: ThresholdPattern::Constant { value: t },
            probe_count: count,
            spread,
            seed: 3,
        },
        ..EnhanceSettings::default()
    }
}

fn constant(v: f32) -> ThresholdPattern {
    ThresholdPattern::Constant { value: v }
}

fn occupancy(svo: &Svo) -> HashSet<UVec3> {
    svo.leaves().into_iter().map(|(p, _)| p).collect()
}

/// Shell (solid with an empty face neighbour; outside is empty) of a dense grid.
fn dense_shell(occ: &[bool], m: usize) -> HashSet<UVec3> {
    let at = |x: i64, y: i64, z: i64| {
        x >= 0
            && y >= 0
            && z >= 0
            && (x as usize) < m
            && (y as usize) < m
            && (z as usize) < m
            && occ[(z as usize * m + y as usize) * m + x as usize]
    };
    let mut out = HashSet::new();
    for z in 0..m as i64 {
        for y in 0..m as i64 {
            for x in 0..m as i64 {
                if at(x, y, z)
                    && !(at(x - 1, y, z)
                        && at(x + 1, y, z)
                        && at(x, y - 1, z)
                        && at(x, y + 1, z)
                        && at(x, y, z - 1)
                        && at(x, y, z + 1))
                {
                    out.insert(UVec3::new(x as u32, y as u32, z as u32));
                }
            }
        }
    }
    out
}

// ---------------------------------------------------------------- rules and the LUT

#[test]
fn lut_equals_direct_rule_for_every_configuration_and_threshold() {
    for t in 1..=4u8 {
        for cfg in 0..128u8 {
            for o in 0..8u8 {
                assert_eq!(
                    LUT[usize::from(t - 1)][usize::from(cfg)] >> o & 1 == 1,
                    rule_direct(cfg, o, t),
                    "t {t} cfg {cfg:07b} octant {o}"
                );
                // And the rule is what the paper says: count of centre + 3 toward neighbours.
                let count = u8::from(cfg & 1 == 1)
                    + (cfg >> if o & 1 == 1 { 2 } else { 1 } & 1)
                    + (cfg >> if o & 2 == 2 { 4 } else { 3 } & 1)
                    + (cfg >> if o & 4 == 4 { 6 } else { 5 } & 1);
                assert_eq!(rule_direct(cfg, o, t), count >= t);
            }
        }
    }
}

#[test]
fn subdivision_rule_on_hand_made_neighbourhoods() {
    let lone = CFG_CENTRE;
    // +x, +y, +z neighbours: bits 2, 4, 6.
    let corner = CFG_CENTRE | 1 << 2 | 1 << 4 | 1 << 6;
    let empty_corner = 1 << 2 | 1 << 4 | 1 << 6;
    let plus_x = CFG_CENTRE | 1 << 2;
    let count = |cfg: u8, t: u8| LUT[usize::from(t - 1)][usize::from(cfg)].count_ones();
    // A lone voxel keeps all fragments at threshold 1 and vanishes above.
    assert_eq!([1, 2, 3, 4].map(|t| count(lone, t)), [8, 0, 0, 0]);
    // Centre + one face neighbour: the half toward it survives threshold 2.
    assert_eq!([1, 2, 3, 4].map(|t| count(plus_x, t)), [8, 4, 0, 0]);
    assert_eq!(LUT[1][usize::from(plus_x)], 0b1010_1010);
    // Centre + three neighbours of the +++ corner.
    assert_eq!([1, 2, 3, 4].map(|t| count(corner, t)), [8, 7, 4, 1]);
    assert_eq!(LUT[3][usize::from(corner)], 1 << 7);
    // An empty voxel grows toward solid neighbours (rounds inner corners).
    assert_eq!([1, 2, 3, 4].map(|t| count(empty_corner, t)), [7, 4, 1, 0]);
    assert_eq!(LUT[2][usize::from(empty_corner)], 1 << 7);
    // Full neighbourhood: always solid; empty: never.
    for t in 1..=4 {
        assert_eq!(count(127, t), 8);
        assert_eq!(count(0, t), 0);
    }
}

fn window_from(cells: &[(IVec3, bool)], r: i32) -> Window {
    let side = (2 * r + 1) as usize;
    let n = side * side * side;
    let mut w = Window {
        r,
        side,
        occ: vec![false; n],
        color: vec![[200, 200, 200, 255]; n],
        material: vec![0; n],
        interior: vec![false; n],
        solid_count: 0,
    };
    for &(d, s) in cells {
        let i = w.idx(d);
        w.occ[i] = s;
        w.solid_count += usize::from(s);
    }
    w
}

#[test]
fn resampling_rule_on_hand_made_neighbourhoods() {
    // Four probes: the fragment centre and +½ voxel along each axis. For the (1,1,1) fragment
    // of a factor-2 cell (centre at ¾) they reach the centre voxel and its +x, +y, +z
    // neighbours: the subdivision neighbourhood of octant 7. For the (0,0,0) fragment (centre
    // at ¼) all four stay in the centre voxel.
    let offsets = [
        [0.0, 0.0, 0.0],
        [0.5, 0.0, 0.0],
        [0.0, 0.5, 0.0],
        [0.0, 0.0, 0.5],
    ];
    let pattern = resample::ProbePattern::from_offsets(&offsets, 2);
    assert_eq!(pattern.r, 1);
    for (cells, hits7, hits0) in [
        (vec![(IVec3::ZERO, true)], 1u32, 4u32),
        (vec![(IVec3::ZERO, true), (IVec3::X, true)], 2, 4),
        (
            vec![
                (IVec3::ZERO, true),
                (IVec3::X, true),
                (IVec3::Y, true),
                (IVec3::Z, true),
            ],
            4,
            4,
        ),
        (
            vec![(IVec3::X, true), (IVec3::Y, true), (IVec3::Z, true)],
            3,
            0,
        ),
    ] {
        let win = window_from(&cells, 2);
        // Threshold "t of 4 probes" is the fraction (t - 1) / 4: solid when hits > t - 1.
        for t in 1..=4u32 {
            let need = t - 1;
            let needs = resample::Needs {
                even: vec![need; 257],
                odd: vec![need; 257],
                per_material: false,
                alternating: false,
            };
            let res = resample::Resampler::new(pattern.clone(), needs);
            let r = res.cell(&win, IVec3::ZERO, 0);
            assert_eq!(r.get(1, 1, 1), hits7 >= t, "cells {cells:?} t {t}");
            assert_eq!(r.get(0, 0, 0), hits0 >= t, "cells {cells:?} t {t}");
        }
    }
}

/// Direct float evaluation of the resampling rule (the paper's text) for one fine point.
fn resample_direct(map: &Svo, s: &EnhanceSettings, p: UVec3) -> bool {
    let r = &s.resample;
    let f = s.factor as usize;
    let pattern =
        resample::ProbePattern::new(r.probe_count as usize, f64::from(r.spread), r.seed, f);
    let c = p / s.factor;
    let l = p - c * s.factor;
    let mut hits = 0;
    for j in 0..pattern.count {
        let q = c.as_ivec3()
            + IVec3::new(
                pattern.cell_offset(0, j, l.x as usize),
                pattern.cell_offset(1, j, l.y as usize),
                pattern.cell_offset(2, j, l.z as usize),
            );
        if q.cmpge(IVec3::ZERO).all() && map.get(q.as_uvec3()).is_some() {
            hits += 1;
        }
    }
    let (t, _) = r.threshold.for_material(None);
    let need = ((f64::from(t) * r.probe_count as f64).floor() as u32).min(r.probe_count - 1);
    hits > need
}

#[test]
fn resampling_output_equals_the_direct_rule_everywhere() {
    let map = random_map(8, 0.45, 11);
    for (factor, count, spread, t) in [(3, 8, 1.0, 0.25), (2, 5, 0.6, 0.5), (5, 4, 1.3, 0.0)] {
        let s = resample(factor, count, spread, t);
        let e = Enhancer::new(&map, &s).unwrap();
        let m = (8 * factor) as usize;
        let mut occ = vec![false; m * m * m];
        for z in 0..m {
            for y in 0..m {
                for x in 0..m {
                    let p = UVec3::new(x as u32, y as u32, z as u32);
                    let direct = resample_direct(&map, &s, p);
                    assert_eq!(e.is_solid_fine(p), direct, "{p} factor {factor}");
                    occ[(z * m + y) * m + x] = direct;
                }
            }
        }
        assert_eq!(occupancy(e.fine()), dense_shell(&occ, m), "factor {factor}");
    }
}

#[test]
fn subdivision_kernel_equals_lut_reference_for_all_patterns() {
    let patterns = [
        constant(1.0),
        constant(2.0),
        constant(3.0),
        constant(4.0),
        ThresholdPattern::Alternating {
            even: 3.0,
            odd: 4.0,
        },
        ThresholdPattern::Alternating {
            even: 1.0,
            odd: 2.0,
        },
        ThresholdPattern::PerMaterial {
            default: 2.0,
            materials: vec![
                MaterialThreshold {
                    material: 1,
                    threshold: 1.0,
                },
                MaterialThreshold {
                    material: 2,
                    threshold: 4.0,
                },
            ],
        },
    ];
    for (seed, fill) in [(1u64, 0.3), (2, 0.55), (3, 0.8)] {
        let map = random_map(8, fill, seed);
        let n = 8usize;
        let coarse: Vec<bool> = (0..n * n * n)
            .map(|i| {
                map.get(UVec3::new(
                    (i % n) as u32,
                    (i / n % n) as u32,
                    (i / n / n) as u32,
                ))
                .is_some()
            })
            .collect();
        for pattern in &patterns {
            let mut occ = coarse.clone();
            let mut m = n;
            for k in 1..=3u32 {
                let threshold = |_src: IVec3, frag: IVec3| -> u8 {
                    let cell = frag >> k as i32;
                    let v = map.get(cell.as_uvec3());
                    let (e, o) = pattern.for_material(v.map(|v| v.material));
                    (if frag.y & 1 == 0 { e } else { o }) as u8
                };
                occ = subdivide_dense(&occ, m, &threshold);
                m *= 2;
                let e = Enhancer::new(&map, &subdivide(1 << k, pattern.clone())).unwrap();
                assert_eq!(
                    occupancy(e.fine()),
                    dense_shell(&occ, m),
                    "seed {seed} pattern {pattern:?} factor {}",
                    1 << k
                );
            }
        }
    }
}

// ---------------------------------------------------------------- Sierpinski

#[test]
fn threshold_one_grows_sierpinski_triangles_on_a_45_degree_facet() {
    // Coarse facet x + y + z <= 12 on a 8³ map (45° to every axis).
    let map = map_from(8, |p| {
        (p.x + p.y + p.z <= 12).then(|| vox([200, 200, 200], 0))
    });
    let mut top_counts = Vec::new();
    for k in 1..=4u32 {
        let f = 1 << k;
        let e = Enhancer::new(&map, &subdivide(f, constant(1.0))).unwrap();
        // Solid fragments on the fine plane x + y + z = sum over a 2×2-cell patch of the facet.
        let count = |sum: i64| -> u32 {
            let mut n = 0;
            for z in (3 * f)..(5 * f) {
                for x in (3 * f)..(5 * f) {
                    let y = sum - i64::from(x) - i64::from(z);
                    if (0..i64::from(8 * f)).contains(&y)
                        && e.is_solid_fine(UVec3::new(x, y as u32, z))
                    {
                        n += 1;
                    }
                }
            }
            n
        };
        let top = (0..i64::from(30 * f))
            .rev()
            .find(|&s| count(s) > 0)
            .unwrap();
        // The outermost plane lies a fixed number of fine layers past the coarse facet.
        assert_eq!(top, i64::from(16 * f) - 4, "factor {f}");
        top_counts.push(i64::from(count(top)));
    }
    // Self-similarity: the outer layer is a Sierpinski gasket (3 copies per doubling) plus
    // the straight cell-border lines (2 per doubling): N(k+1) - 2 N(k) - 3 = 3^k.
    for k in 0..3 {
        assert_eq!(
            top_counts[k + 1] - 2 * top_counts[k] - 3,
            3i64.pow(k as u32 + 1),
            "counts {top_counts:?}"
        );
    }
}

// ---------------------------------------------------------------- colour, normals, lighting

#[test]
fn materials_keep_crisp_edges_and_same_material_blends() {
    let red = [220, 30, 30];
    let blue = [30, 30, 220];
    // Left half material 1 red, right half material 2 blue; flat top at y = 4.
    let crisp = map_from(8, |p| {
        (p.y < 4).then(|| if p.x < 4 { vox(red, 1) } else { vox(blue, 2) })
    });
    // Same halves, one material: colours blend across the seam.
    let blend = map_from(8, |p| {
        (p.y < 4).then(|| if p.x < 4 { vox(red, 1) } else { vox(blue, 1) })
    });
    for s in [subdivide(8, constant(2.0)), resample(6, 16, 1.0, 0.3)] {
        let fine = enhance(&crisp, &s).unwrap();
        for (p, v) in fine.leaves() {
            let c = [v.color[0], v.color[1], v.color[2]];
            assert!(c == red || c == blue, "{p}: {c:?} blends across materials");
            assert_eq!(v.material, if c == red { 1 } else { 2 });
        }
        let fine = enhance(&blend, &s).unwrap();
        let mixed = fine
            .leaves()
            .iter()
            .filter(|(_, v)| v.color[0] > 40 && v.color[0] < 210 && v.color[2] > 40)
            .count();
        assert!(mixed > 0, "same material must blend");
        // Nearest mode never invents a colour.
        let near = EnhanceSettings {
            color: ColorMode::Nearest,
            ..s.clone()
        };
        for (_, v) in enhance(&blend, &near).unwrap().leaves() {
            let c = [v.color[0], v.color[1], v.color[2]];
            assert!(c == red || c == blue);
        }
    }
}

#[test]
fn normals_follow_the_surface() {
    // Flat ground: top fragments face up.
    let ground = map_from(8, |p| (p.y < 4).then(|| vox([90, 140, 60], 1)));
    let fine = enhance(&ground, &subdivide(4, constant(2.0))).unwrap();
    let mut tops = 0;
    for (p, v) in fine.leaves() {
        if p.y == 15 && (4..28).contains(&p.x) && (4..28).contains(&p.z) {
            assert!(
                v.normal_vec().dot(Vec3::Y) > 0.99,
                "{p}: {}",
                v.normal_vec()
            );
            tops += 1;
        }
    }
    assert_eq!(tops, 24 * 24);
    // A 45° ramp (y <= x): normals near (-1, 1, 0)/√2 in the middle of the facet.
    let ramp = map_from(8, |p| (p.y <= p.x).then(|| vox([90, 140, 60], 1)));
    let fine = enhance(&ramp, &subdivide(4, constant(2.0))).unwrap();
    let want = Vec3::new(-1.0, 1.0, 0.0).normalize_or_zero();
    let mut sum = Vec3::ZERO;
    for (p, v) in fine.leaves() {
        if (8..24).contains(&p.z) && (8..24).contains(&p.x) && p.y >= p.x && p.y <= p.x + 6 {
            sum += v.normal_vec();
        }
    }
    assert!(
        sum.normalize_or_zero().dot(want) > 0.98,
        "mean normal {sum} of {}",
        fine.leaf_count()
    );
}

fn lit(factor: u32) -> EnhanceSettings {
    EnhanceSettings {
        lighting: LightingSettings {
            enabled: true,
            sun_direction: [0.0, 1.0, 0.0],
            ..LightingSettings::default()
        },
        ..subdivide(factor, constant(2.0))
    }
}

#[test]
fn snowflake_lighting_darkens_under_a_roof() {
    // Ground y < 3 and a roof slab at y = 4 over x < 8 on a 16-wide map.
    let map = map_from(16, |p| {
        (p.y < 3 || (p.y == 4 && p.x < 8 && p.z >= 4 && p.z < 12)).then(|| vox([200, 200, 200], 1))
    });
    let fine = enhance(&map, &lit(4)).unwrap();
    let mut shade = [(0.0f64, 0u32); 2];
    for (p, v) in fine.leaves() {
        if p.y == 11 && (20..44).contains(&p.z) {
            let open = p.x >= 40;
            if (p.x >= 8 && p.x < 24) || (open && p.x < 56) {
                let i = usize::from(open);
                shade[i].0 += f64::from(v.color[0]);
                shade[i].1 += 1;
            }
        }
    }
    let (under, open) = (
        shade[0].0 / f64::from(shade[0].1),
        shade[1].0 / f64::from(shade[1].1),
    );
    assert!(shade[0].1 > 100 && shade[1].1 > 100);
    assert!(under + 30.0 < open, "under roof {under}, open {open}");
    // Off: the albedo itself.
    let plain = enhance(&map, &subdivide(4, constant(2.0))).unwrap();
    assert!(
        plain
            .leaves()
            .iter()
            .all(|(_, v)| v.color == [200, 200, 200, 255])
    );
}

// ---------------------------------------------------------------- determinism

#[test]
fn same_input_and_seed_give_identical_output_across_runs_and_thread_counts() {
    let terrain = sample_terrain(16, 5).unwrap();
    let mut resample_lit = resample(5, 8, 1.5, 0.3);
    resample_lit.lighting = lit(5).lighting;
    for s in [lit(4), resample_lit] {
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| enhance(&terrain, &s).unwrap())
        };
        let one = run(1);
        let two = run(2);
        let again = run(2);
        assert!(one.leaf_count() > 1000);
        assert_eq!(one, two);
        assert_eq!(two, again);
        assert_eq!(one.leaves(), two.leaves());
    }
    // Another seed changes the probe pattern and the result.
    let a = enhance(&terrain, &resample(3, 8, 1.5, 0.3)).unwrap();
    let mut s = resample(3, 8, 1.5, 0.3);
    s.resample.seed = 99;
    assert_ne!(a, enhance(&terrain, &s).unwrap());
}

// ---------------------------------------------------------------- incremental

fn random_edit(map: &mut Svo, rng: &mut Pcg32) -> EditResult {
    let n = map.extent();
    let p = UVec3::new(
        rng.random_range(0..n),
        rng.random_range(0..n),
        rng.random_range(0..n),
    );
    match rng.random_range(0..10) {
        0 => {
            // A small box of one material.
            let hi = (p + UVec3::splat(rng.random_range(0..3))).min(UVec3::splat(n - 1));
            let v = rng
                .random_bool(0.5)
                .then(|| vox([rng.random(), 90, 60], rng.random_range(1..=3)));
            map.edit_region(p, hi, |_, _| v).unwrap()
        }
        1 => map
            .edit_existing(p, p, |_, v| {
                Some(Voxel {
                    color: [10, 200, 10, 255],
                    ..v
                })
            })
            .unwrap(),
        _ => {
            let v = map
                .get(p)
                .is_none()
                .then(|| vox([rng.random(), 120, 80], rng.random_range(1..=3)));
            map.edit_region(p, p, |_, _| v).unwrap()
        }
    }
}

fn check_incremental(mut map: Svo, s: &EnhanceSettings, edits: usize, seed: u64, checks: usize) {
    let mut rng = Pcg32::seed_from_u64(seed);
    let mut e = Enhancer::new(&map, s).unwrap();
    for i in 0..edits {
        let r = random_edit(&mut map, &mut rng);
        e.update(&map, &r).unwrap();
        if checks > 0 && (i + 1) % (edits / checks).max(1) == 0 {
            assert!(*e.fine() == enhance(&map, s).unwrap(), "edit {i} of {s:?}");
        }
    }
    let full = enhance(&map, s).unwrap();
    assert_eq!(e.fine().leaves(), full.leaves());
    assert!(*e.fine() == full);
}

#[test]
fn incremental_equals_full_after_1000_random_edits() {
    let mut s = subdivide(
        4,
        ThresholdPattern::PerMaterial {
            default: 2.0,
            materials: vec![MaterialThreshold {
                material: 1,
                threshold: 1.0,
            }],
        },
    );
    s.color = ColorMode::Blend;
    check_incremental(sample_terrain(16, 2).unwrap(), &s, 1000, 1, 4);
    let mut r = resample(3, 6, 1.2, 0.3);
    r.resample.threshold = ThresholdPattern::Alternating {
        even: 0.2,
        odd: 0.5,
    };
    check_incremental(sample_terrain(16, 3).unwrap(), &r, 1000, 2, 2);
}

#[test]
fn incremental_with_lighting_equals_full() {
    let mut s = lit(4);
    s.lighting.sun_particles = 3;
    s.lighting.sky_particles = 3;
    s.lighting.steps = 6;
    check_incremental(sample_terrain(16, 4).unwrap(), &s, 60, 3, 3);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]
    #[test]
    fn prop_incremental_equals_full(
        seed in any::<u64>(),
        method in 0..2u8,
        k in 0..3u32,
        t in 1..5u8,
        fill in 0.2f64..0.7,
    ) {
        let map = random_map(8, fill, seed);
        let s = if method == 0 {
            subdivide(1 << k, constant(f32::from(t)))
        } else {
            resample(k + 2, 5, 0.3 * (k + 1) as f32, f32::from(t - 1) * 0.2)
        };
        check_incremental(map, &s, 25, seed ^ 1, 1);
    }
}

// ---------------------------------------------------------------- extremes

#[test]
fn factor_one_is_the_identity_on_the_shell() {
    let map = random_map(8, 0.5, 21);
    let grid_shell: HashMap<UVec3, Voxel> = {
        let occ: Vec<bool> = (0..512)
            .map(|i| map.get(UVec3::new(i % 8, i / 8 % 8, i / 64)).is_some())
            .collect();
        dense_shell(&occ, 8)
            .into_iter()
            .map(|p| (p, map.get(p).unwrap()))
            .collect()
    };
    for s in [subdivide(1, constant(3.0)), resample(1, 7, 0.0, 0.5)] {
        let fine = enhance(&map, &s).unwrap();
        assert_eq!(fine.depth(), map.depth());
        assert_eq!(fine.leaf_count() as usize, grid_shell.len());
        for (p, v) in fine.leaves() {
            let src = grid_shell[&p];
            assert_eq!((v.color, v.material), (src.color, src.material), "{p}");
        }
    }
}

#[test]
fn factor_64_on_a_small_map() {
    let map = map_from(4, |p| (p.y < 2 && p.x < 3).then(|| vox([100, 100, 100], 1)));
    for s in [subdivide(64, constant(2.0)), resample(64, 4, 1.0, 0.25)] {
        let e = Enhancer::new(&map, &s).unwrap();
        assert_eq!(e.fine().depth(), 8);
        let n = e.fine().leaf_count();
        let surface = coarse_surface_count(&map);
        assert!(n > 0 && n <= 6 * surface * 64 * 64, "{n} fragments");
    }
    // 65 is refused with a clear error.
    let err = Enhancer::new(&map, &resample(65, 4, 1.0, 0.25))
        .err()
        .unwrap();
    assert!(err.to_string().contains("factor"), "{err}");
}

#[test]
fn spreads_zero_and_wide_are_defined() {
    let map = random_map(8, 0.4, 5);
    // Spread 0: every probe at the fragment centre, so the result is the blocky upscaling.
    let e = Enhancer::new(&map, &resample(3, 9, 0.0, 0.5)).unwrap();
    for (p, _) in e.fine().leaves() {
        assert!(map.get(p / 3).is_some());
    }
    for i in 0..(24u32 * 24 * 24) {
        let p = UVec3::new(i % 24, i / 24 % 24, i / 576);
        assert_eq!(e.is_solid_fine(p), map.get(p / 3).is_some());
    }
    // Spread 4.5 voxels: a wide footprint; defined, bounded, and incremental still exact.
    let s = resample(2, 12, 4.5, 0.3);
    let e = Enhancer::new(&map, &s).unwrap();
    assert!(e.dependency_radius() >= 5);
    check_incremental(map, &s, 20, 9, 1);
}

#[test]
fn thresholds_zero_and_above_the_count_are_defined() {
    let map = random_map(8, 0.4, 8);
    // Subdivision: 0 acts as 1, anything above 4 as 4.
    assert_eq!(
        enhance(&map, &subdivide(4, constant(0.0))).unwrap(),
        enhance(&map, &subdivide(4, constant(1.0))).unwrap()
    );
    assert_eq!(
        enhance(&map, &subdivide(4, constant(9.0))).unwrap(),
        enhance(&map, &subdivide(4, constant(4.0))).unwrap()
    );
    // Resampling: 0 means "any probe hits"; ≥ 1 (above the probe count) means "every probe".
    let any = enhance(&map, &resample(3, 8, 1.0, 0.0)).unwrap();
    let all = enhance(&map, &resample(3, 8, 1.0, 1.0)).unwrap();
    assert_eq!(all, enhance(&map, &resample(3, 8, 1.0, 7.5)).unwrap());
    assert!(any.leaf_count() > 0 && all.leaf_count() > 0);
    let e_any = Enhancer::new(&map, &resample(3, 8, 1.0, 0.0)).unwrap();
    let e_all = Enhancer::new(&map, &resample(3, 8, 1.0, 1.0)).unwrap();
    let (mut n_any, mut n_all) = (0, 0);
    for i in 0..(24u32 * 24 * 24) {
        let p = UVec3::new(i % 24, i / 24 % 24, i / 576);
        let (a, b) = (e_any.is_solid_fine(p), e_all.is_solid_fine(p));
        assert!(a || !b, "every-probe solid implies any-probe solid");
        n_any += u32::from(a);
        n_all += u32::from(b);
    }
    assert!(n_any > n_all);
}

#[test]
fn empty_and_full_maps() {
    let empty = Svo::new(3, false).unwrap();
    let full = map_from(8, |_| Some(vox([1, 2, 3], 1)));
    let mut lit_one = lit(2);
    lit_one.subdivide.threshold = constant(1.0);
    for s in [
        subdivide(4, constant(1.0)),
        resample(3, 6, 0.0, 0.5),
        lit_one,
    ] {
        let e = Enhancer::new(&empty, &s).unwrap();
        assert!(e.fine().is_empty());
        assert_eq!(e.stats().candidate_cells, 0);
        let e = Enhancer::new(&full, &s).unwrap();
        // The shell of the fine cube: (8F)³ - (8F - 2)³.
        let m = u64::from(8 * s.factor);
        assert_eq!(
            e.fine().leaf_count(),
            m * m * m - (m - 2) * (m - 2) * (m - 2)
        );
        // Interior cells never did any work.
        assert!(e.stats().candidate_cells < 8 * 8 * 8 - 4 * 4 * 4 + 1);
        assert!(e.is_solid_fine(UVec3::splat(m as u32 / 2)));
    }
    // Eroding rules round the cube's edges (outside the map is empty): fewer fragments.
    for s in [subdivide(4, constant(3.0)), resample(4, 8, 1.0, 0.5)] {
        let m = u64::from(8 * s.factor);
        let n = enhance(&full, &s).unwrap().leaf_count();
        assert!(
            n < m * m * m - (m - 2) * (m - 2) * (m - 2) && n > 4 * m * m,
            "{n}"
        );
    }
}

#[test]
fn fragment_count_is_bounded_by_the_surface() {
    let terrain = sample_terrain(32, 1).unwrap();
    let surface = coarse_surface_count(&terrain);
    for s in [
        subdivide(4, constant(1.0)),
        subdivide(8, constant(2.0)),
        subdivide(
            8,
            ThresholdPattern::Alternating {
                even: 3.0,
                odd: 4.0,
            },
        ),
        resample(6, 16, 1.0, 0.25),
        resample(7, 4, 2.0, 0.5),
    ] {
        let e = Enhancer::new(&terrain, &s).unwrap();
        let n = e.fine().leaf_count();
        let f = u64::from(s.factor);
        // A terrain's shell is a height field: a few fragments per fine column and per
        // exposed side; 6 × surface × F² is generous and still quadratic, not cubic.
        assert!(
            n <= 6 * surface * f * f,
            "{n} fragments, surface {surface}, {s:?}"
        );
        assert!(n >= surface * f * f / 4);
        // Candidates are near the surface only.
        assert!(e.stats().candidate_cells <= 27 * surface);
    }
}

#[test]
fn resampling_cache_is_hit_on_terrain() {
    let terrain = sample_terrain(32, 1).unwrap();
    let e = Enhancer::new(&terrain, &resample(4, 16, 1.0, 0.25)).unwrap();
    let st = e.stats();
    assert!(st.cache_entries > 0);
    assert!(st.cache_hit_rate() > 0.5, "{st:?}");
}

#[test]
fn settings_are_validated_with_clear_errors() {
    let bad = |s: EnhanceSettings, field: &str| {
        let err = s.validate().err().unwrap();
        assert!(err.to_string().contains(field), "{err} lacks {field}");
    };
    bad(
        EnhanceSettings {
            factor: 0,
            ..EnhanceSettings::default()
        },
        "factor",
    );
    bad(subdivide(6, constant(2.0)), "power of two");
    bad(subdivide(4, constant(2.5)), "subdivide.threshold");
    bad(subdivide(4, constant(f32::NAN)), "subdivide.threshold");
    bad(resample(3, 0, 1.0, 0.2), "probe_count");
    bad(resample(3, 4, f32::INFINITY, 0.2), "spread");
    bad(resample(3, 4, -1.0, 0.2), "spread");
    bad(resample(3, 4, 1.0, -0.5), "resample.threshold");
    let mut s = lit(2);
    s.lighting.sun_direction = [0.0; 3];
    bad(s.clone(), "sun_direction");
    s.lighting = LightingSettings {
        enabled: true,
        step_length: 0.0,
        ..LightingSettings::default()
    };
    bad(s, "step_length");
    // Too deep: depth 20 map × 4 needs 22 levels.
    let deep = Svo::new(20, false).unwrap();
    assert!(matches!(
        Enhancer::new(&deep, &subdivide(4, constant(2.0))),
        Err(EnhanceError::TooDeep { .. })
    ));
    // Serde: defaults fill missing fields; round trip.
    let s: EnhanceSettings = serde_json::from_str(r#"{"method":"resample","factor":5}"#).unwrap();
    assert_eq!(s.method, Method::Resample);
    assert_eq!(s.resample, ResampleSettings::default());
    let json = serde_json::to_string(&s).unwrap();
    assert_eq!(serde_json::from_str::<EnhanceSettings>(&json).unwrap(), s);
}

#[test]
fn progress_and_cancel() {
    let terrain = sample_terrain(16, 1).unwrap();
    let seen = std::sync::Mutex::new(Vec::new());
    let progress = |p: f32| seen.lock().unwrap().push(p);
    let control = Control {
        progress: Some(&progress),
        cancel: None,
    };
    Enhancer::with_control(&terrain, &subdivide(2, constant(2.0)), control).unwrap();
    let seen = seen.into_inner().unwrap();
    assert!(seen.windows(2).all(|w| w[0] <= w[1]));
    assert_eq!(seen.last().copied(), Some(1.0));
    let cancel = AtomicBool::new(true);
    let control = Control {
        progress: None,
        cancel: Some(&cancel),
    };
    assert_eq!(
        Enhancer::with_control(&terrain, &subdivide(2, constant(2.0)), control).err(),
        Some(EnhanceError::Cancelled)
    );
}

#[test]
fn non_power_of_two_factor_uses_the_smallest_fitting_depth() {
    let map = sample_terrain(8, 3).unwrap();
    for (f, depth) in [(3u32, 5u8), (5, 6), (7, 6), (12, 7)] {
        let fine = enhance(&map, &resample(f, 6, 1.0, 0.3)).unwrap();
        assert_eq!(fine.depth(), depth, "factor {f}");
        let (_, hi) = fine.bounds().unwrap();
        assert!(hi.max_element() < 8 * f);
    }
}

#[test]
fn sample_terrain_has_three_materials() {
    let t = sample_terrain(64, 1).unwrap();
    assert_eq!(t.depth(), 6);
    let mut mats = [0u32; 4];
    for (_, v) in t.leaves() {
        mats[usize::from(v.material.min(3))] += 1;
    }
    assert!(
        mats[usize::from(MAT_GRASS)] > 500
            && mats[usize::from(MAT_ROCK)] > 500
            && mats[usize::from(MAT_DIRT)] > 500,
        "{mats:?}"
    );
    assert_eq!(t, sample_terrain(64, 1).unwrap());
    assert!(sample_terrain(2, 1).is_err());
}

#[test]
fn the_enhance_estimate_holds_the_measured_peak() {
    let sample = |name: &str| {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(format!("../projects/{name}.thicket.json"));
        crate::io::project::load(&path).unwrap()
    };
    for name in ["house", "terrain"] {
        let doc = sample(name);
        let crate::scene::ObjectKind::Voxels(m) = &doc.objects[0].kind else {
            panic!("{name}: the first object is a voxel model");
        };
        for method in [Method::Subdivide, Method::Resample] {
            for factor in [2u32, 8] {
                let s = EnhanceSettings {
                    factor,
                    method,
                    ..EnhanceSettings::default()
                };
                let e = estimate(&m.svo, &s).unwrap();
                let (r, peak) = crate::io::fuzz::peak_heap_bytes_on_one_thread(|| {
                    m.enhanced(&s, Control::default())
                });
                let (fine, st) = r.unwrap();
                let n = fine.svo.leaf_count();
                let case = format!("{name} {method:?} x{factor}");
                eprintln!(
                    "{case}: {n} fine voxels, predicted {} ({:.2}x); peak {peak} B, estimate {} B ({:.2}x)",
                    e.fine_voxels,
                    e.fine_voxels as f64 / n as f64,
                    e.peak_bytes,
                    e.peak_bytes as f64 / peak as f64
                );
                assert_eq!(e.coarse_surface_voxels, st.coarse_surface_voxels, "{case}");
                assert!(
                    (1.0..=2.0).contains(&(e.fine_voxels as f64 / n as f64)),
                    "{case}: predicted {} fine voxels for {n}",
                    e.fine_voxels
                );
                assert!(e.peak_bytes >= peak, "{case}: {e:?} < {peak}");
                assert!(e.peak_bytes <= 4 * peak, "{case}: {e:?} > 4 x {peak}");
            }
        }
    }
}

#[test]
fn a_map_standing_for_more_voxels_than_enhancement_lists_is_refused_before_copying() {
    // One 512³ tile and a voxel: 2^27 + 1 voxels in two records.
    let v = Voxel::new([90, 160, 60, 255], Vec3::Y);
    let map = Svo::over_listing_limit(v);
    let settings = EnhanceSettings::default();
    let want = EnhanceError::TooManyVoxels {
        voxels: crate::svo::MAX_LISTED_VOXELS + 1,
        limit: crate::svo::MAX_LISTED_VOXELS,
    };
    assert_eq!(estimate(&map, &settings).err(), Some(want.clone()));
    assert_eq!(Enhancer::new(&map, &settings).err(), Some(want));
}

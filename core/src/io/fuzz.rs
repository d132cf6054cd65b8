//! A deterministic mutation fuzzer for loaders, run by the normal test suite.
//!
//! [`run`] takes real files, applies seeded mutations (byte flips, truncations, inflated
//! numbers in text and in binary length fields, splices) and feeds each result to a loader
//! under `catch_unwind`. It reports panics with the seed and case number that reproduce them,
//! and the peak heap bytes the loader allocated for one case, measured by a counting global
//! allocator installed in the test binary. Memory is counted per thread, so loaders under test
//! must not move their allocations to other threads (none of ours do).
//!
//! Case `k` of seed `s` uses its own generator seeded from `(s, k)`, so a failure replays alone:
//! `mutate(&corpus[..], &mut case_rng(s, k))`.
//!
//! Case counts: each fuzz test reads `THICKET_FUZZ_CASES` (default 10,000 per loader) so a long
//! run is `THICKET_FUZZ_CASES=500000 cargo test --release -p thicket-core --lib io::fuzz`.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::{Duration, Instant};

use rand::{Rng, RngCore, SeedableRng};
use rand_pcg::Pcg64;

/// Counts live heap bytes per thread so a fuzz case's peak allocation can be bounded, and
/// allocation calls so a renderer's steady-state frame can be shown to make none.
struct CountingAllocator;

thread_local! {
    static LIVE_BYTES: Cell<i64> = const { Cell::new(0) };
    static PEAK_BYTES: Cell<i64> = const { Cell::new(0) };
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

/// Counts one call that obtains memory (`alloc`, `alloc_zeroed`, `realloc`).
fn count_allocation() {
    let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
}

fn track(delta: i64) {
    // `try_with` because the allocator also runs while thread-locals are being torn down.
    let _ = LIVE_BYTES.try_with(|live| {
        let now = live.get() + delta;
        live.set(now);
        let _ = PEAK_BYTES.try_with(|peak| {
            if now > peak.get() {
                peak.set(now);
            }
        });
    });
}

// The only unsafe code in the library, and test-only: `GlobalAlloc` is an unsafe trait. Every
// call is forwarded unchanged to the system allocator; only counters are added.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded with the caller's layout, which meets `alloc`'s contract.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            track(layout.size() as i64);
            count_allocation();
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as for `alloc`.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            track(layout.size() as i64);
            count_allocation();
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` with `layout` (every allocation goes there).
        unsafe { System.dealloc(ptr, layout) };
        track(-(layout.size() as i64));
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: `ptr`/`layout` come from `System`, as above; the caller upholds `new_size`.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            track(new_size as i64 - layout.size() as i64);
            count_allocation();
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// Runs `f` and returns its result with the most heap bytes it held at once on this thread.
pub fn peak_heap_bytes<T>(f: impl FnOnce() -> T) -> (T, u64) {
    let start = LIVE_BYTES.with(Cell::get);
    PEAK_BYTES.with(|p| p.set(start));
    let out = f();
    let peak = PEAK_BYTES.with(Cell::get);
    (out, u64::try_from(peak - start).unwrap_or(0))
}

/// [`peak_heap_bytes`] of `f` run on a one-thread rayon pool, so the per-thread counting
/// allocator sees every allocation of code that uses rayon (its work runs on the pool's thread).
pub fn peak_heap_bytes_on_one_thread<T: Send>(f: impl FnOnce() -> T + Send) -> (T, u64) {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool")
        .install(|| peak_heap_bytes(f))
}

/// Runs `f` and returns its result with the number of allocation calls (`alloc`,
/// `alloc_zeroed`, `realloc`) it made on this thread.
pub fn heap_allocations<T>(f: impl FnOnce() -> T) -> (T, u64) {
    let start = ALLOCATIONS.with(Cell::get);
    let out = f();
    (out, ALLOCATIONS.with(Cell::get) - start)
}

/// Number of cases per loader: `THICKET_FUZZ_CASES`, or `default`.
pub fn cases_from_env(default: u64) -> u64 {
    std::env::var("THICKET_FUZZ_CASES")
        .ok()
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or(default)
}

/// The generator for case `case` of run `seed`.
pub fn case_rng(seed: u64, case: u64) -> Pcg64 {
    Pcg64::seed_from_u64(seed ^ case.wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// Numbers that break naive size arithmetic.
const HUGE_DECIMALS: &[&str] = &[
    "4294967295",
    "4294967296",
    "2147483647",
    "2147483648",
    "18446744073709551615",
    "9223372036854775807",
    "268435457",
    "1000000000",
    "65536",
    "0",
    "-1",
    "1e308",
    "3",
];
const HUGE_U32: &[u32] = &[
    u32::MAX,
    0x7FFF_FFFF,
    0x8000_0000,
    0x1000_0001,
    0xFFFF,
    0,
    1,
    11,
    13,
];

/// One mutated copy of a corpus file: 1–3 mutations of random kinds.
pub fn mutate(corpus: &[Vec<u8>], rng: &mut Pcg64) -> Vec<u8> {
    let source = &corpus[rng.random_range(0..corpus.len())];
    let mut data = source.clone();
    let rounds = rng.random_range(1..=3);
    for _ in 0..rounds {
        match rng.random_range(0..8) {
            6 | 7 if data.starts_with(b"glTF") => mutate_glb_chunks(&mut data, rng),
            0 => flip_bytes(&mut data, rng),
            1 => {
                let keep = rng.random_range(0..=data.len());
                data.truncate(keep);
            }
            2 => inflate_decimal(&mut data, rng),
            3 => inflate_u32(&mut data, rng),
            4 => splice(&mut data, rng),
            _ => {
                // Flip one bit: keeps the structure mostly intact, so checks deep in the loader run.
                if !data.is_empty() {
                    let i = rng.random_range(0..data.len());
                    data[i] ^= 1 << rng.random_range(0..8);
                }
            }
        }
    }
    data
}

/// GLB-aware mutation: mutates the JSON or BIN chunk and rewrites the container's lengths, so
/// the mutation gets past the container checks to the JSON and accessor checks.
fn mutate_glb_chunks(data: &mut Vec<u8>, rng: &mut Pcg64) {
    let u32_at = |d: &[u8], at: usize| {
        d.get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    };
    let Some(json_len) = u32_at(data, 12) else {
        return;
    };
    let Some(json) = data.get(20..20 + json_len) else {
        return;
    };
    let mut json = json.to_vec();
    let rest_start = 20 + json_len;
    let mut bin = match u32_at(data, rest_start) {
        Some(len) => data
            .get(rest_start + 8..rest_start + 8 + len)
            .map(<[u8]>::to_vec),
        None => None,
    };
    match (rng.random_range(0..4), bin.as_mut()) {
        (3, Some(bin)) => flip_bytes(bin, rng),
        (2, _) => flip_bytes(&mut json, rng),
        _ => inflate_decimal(&mut json, rng),
    }
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut out = Vec::with_capacity(data.len() + 16);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    let total = 20 + json.len() + bin.as_ref().map_or(0, |b| 8 + b.len());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if let Some(bin) = bin {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
    }
    *data = out;
}

fn flip_bytes(data: &mut [u8], rng: &mut Pcg64) {
    if data.is_empty() {
        return;
    }
    for _ in 0..rng.random_range(1..=8) {
        let i = rng.random_range(0..data.len());
        data[i] = rng.random();
    }
}

/// Replaces one run of ASCII digits (a JSON count, offset, length, index, an OBJ index) with a
/// huge or boundary number.
fn inflate_decimal(data: &mut Vec<u8>, rng: &mut Pcg64) {
    let runs: Vec<(usize, usize)> = {
        let mut runs = Vec::new();
        let mut i = 0;
        while i < data.len() {
            if data[i].is_ascii_digit() {
                let start = i;
                while i < data.len() && data[i].is_ascii_digit() {
                    i += 1;
                }
                runs.push((start, i));
            } else {
                i += 1;
            }
        }
        runs
    };
    // Prefer whole number tokens (after ':', '[', ',' or a space) over digits inside strings
    // such as base64 data, so JSON counts, offsets and indices get inflated.
    let tokens: Vec<(usize, usize)> = runs
        .iter()
        .copied()
        .filter(|&(s, _)| s > 0 && matches!(data[s - 1], b':' | b'[' | b',' | b' '))
        .collect();
    let pool = if !tokens.is_empty() && rng.random_bool(0.75) {
        &tokens
    } else {
        &runs
    };
    if pool.is_empty() {
        return;
    }
    let (start, end) = pool[rng.random_range(0..pool.len())];
    let replacement = HUGE_DECIMALS[rng.random_range(0..HUGE_DECIMALS.len())].as_bytes();
    data.splice(start..end, replacement.iter().copied());
}

/// Overwrites a 4-byte-aligned little-endian word, preferring the first 32 bytes where GLB and
/// most binary headers keep their lengths, with a huge or boundary value.
fn inflate_u32(data: &mut [u8], rng: &mut Pcg64) {
    if data.len() < 4 {
        return;
    }
    let words = data.len() / 4;
    let word = if rng.random_bool(0.5) {
        rng.random_range(0..words.min(8))
    } else {
        rng.random_range(0..words)
    };
    let value = if rng.random_bool(0.8) {
        HUGE_U32[rng.random_range(0..HUGE_U32.len())]
    } else {
        (data.len() as u32).wrapping_add(rng.random_range(0..16))
    };
    data[word * 4..word * 4 + 4].copy_from_slice(&value.to_le_bytes());
}

/// Deletes, duplicates or inserts random bytes in a range.
fn splice(data: &mut Vec<u8>, rng: &mut Pcg64) {
    let a = rng.random_range(0..=data.len());
    let b = rng.random_range(a..=data.len().min(a + 64));
    match rng.random_range(0..3) {
        0 => {
            data.drain(a..b);
        }
        1 => {
            let copy: Vec<u8> = data[a..b].to_vec();
            data.splice(a..a, copy);
        }
        _ => {
            let mut junk = vec![0u8; rng.random_range(1..16)];
            rng.fill_bytes(&mut junk);
            data.splice(a..a, junk);
        }
    }
}

/// What a fuzz run found.
#[derive(Debug, Default)]
pub struct FuzzReport {
    /// Cases run.
    pub cases: u64,
    /// Cases the loader accepted.
    pub accepted: u64,
    /// Cases the loader refused with an error.
    pub refused: u64,
    /// `(case, panic message)` for every panic (replay with [`case_rng`]).
    pub panics: Vec<(u64, String)>,
    /// `(case, bytes)` for cases whose peak heap exceeded the budget.
    pub over_budget: Vec<(u64, u64)>,
    /// Largest peak heap of any case, in bytes.
    pub max_peak_bytes: u64,
    /// The slowest case and its wall time (a loader must not spin on a small input).
    pub slowest: (u64, Duration),
    /// Wall time.
    pub elapsed: Duration,
}

impl std::fmt::Display for FuzzReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} cases: {} accepted, {} refused, {} panics, {} over memory budget, max peak heap {} bytes, slowest case {} in {:.3} s, {:.2} s",
            self.cases,
            self.accepted,
            self.refused,
            self.panics.len(),
            self.over_budget.len(),
            self.max_peak_bytes,
            self.slowest.0,
            self.slowest.1.as_secs_f64(),
            self.elapsed.as_secs_f64()
        )
    }
}

/// Runs `cases` mutated copies of `corpus` through `load` (`Ok` = accepted). A case panics or
/// goes over `budget_bytes(input_len)` of peak heap → recorded in the report (the caller
/// asserts). The unmutated corpus files are run first as a sanity check that they load.
pub fn run<T, E>(
    corpus: &[Vec<u8>],
    cases: u64,
    seed: u64,
    budget_bytes: impl Fn(usize) -> u64,
    load: impl Fn(&[u8]) -> Result<T, E>,
) -> FuzzReport {
    let start = Instant::now();
    let mut report = FuzzReport::default();
    for case in 0..cases {
        let input = mutate(corpus, &mut case_rng(seed, case));
        let budget = budget_bytes(input.len());
        let began = Instant::now();
        let (outcome, peak) =
            peak_heap_bytes(|| catch_unwind(AssertUnwindSafe(|| load(&input).is_ok())));
        let took = began.elapsed();
        if took > report.slowest.1 {
            report.slowest = (case, took);
        }
        report.cases += 1;
        report.max_peak_bytes = report.max_peak_bytes.max(peak);
        if peak > budget {
            report.over_budget.push((case, peak));
        }
        match outcome {
            Ok(true) => report.accepted += 1,
            Ok(false) => report.refused += 1,
            Err(payload) => {
                let message = payload
                    .downcast_ref::<&str>()
                    .map(|s| (*s).to_owned())
                    .or_else(|| payload.downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                report.panics.push((case, message));
            }
        }
    }
    report.elapsed = start.elapsed();
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutations_are_deterministic_and_change_the_input() {
        let corpus = vec![b"{\"count\": 24, \"byteLength\": 648}".to_vec()];
        let a: Vec<Vec<u8>> = (0..200)
            .map(|k| mutate(&corpus, &mut case_rng(7, k)))
            .collect();
        let b: Vec<Vec<u8>> = (0..200)
            .map(|k| mutate(&corpus, &mut case_rng(7, k)))
            .collect();
        assert_eq!(a, b);
        assert!(a.iter().filter(|m| **m != corpus[0]).count() > 160);
        assert!(
            a.iter().any(|m| m.len() < corpus[0].len()),
            "some truncation"
        );
        assert!(
            a.iter().any(|m| m.windows(7).any(|w| w == b"4294967")),
            "some inflated count"
        );
    }

    #[test]
    fn the_harness_catches_panics_and_measures_memory() {
        let corpus = vec![vec![1u8; 64]];
        let report = run(
            &corpus,
            200,
            1,
            |_| 1 << 20,
            |bytes: &[u8]| -> Result<(), ()> {
                if bytes.contains(&0) {
                    panic!("zero byte");
                }
                if bytes.len() > 64 {
                    // A loader that over-allocates for long inputs.
                    let v = vec![1u8; 4 << 20];
                    std::hint::black_box(&v);
                }
                Err(())
            },
        );
        assert_eq!(report.cases, 200);
        assert!(!report.panics.is_empty(), "{report}");
        assert!(report.panics.iter().all(|(_, m)| m == "zero byte"));
        assert!(!report.over_budget.is_empty(), "{report}");
        assert!(report.max_peak_bytes >= 4 << 20);
        let (v, peak) = peak_heap_bytes(|| vec![0u8; 1000]);
        assert!(peak >= 1000 && v.len() == 1000);
    }
}

/// The loaders in this crate under the harness: ≥ 10,000 cases each by default.
#[cfg(test)]
mod loaders {
    use std::cell::{Cell, RefCell};
    use std::collections::BTreeMap;
    use std::path::Path;

    use super::{cases_from_env, run};
    use crate::io::error::{ImportLimits, IoError};
    use crate::io::{gltf_mesh, obj};

    const SEED: u64 = 0x7417_C3E7;

    fn kind(e: &IoError) -> &'static str {
        match e {
            IoError::Io { .. } => "Io",
            IoError::Truncated { .. } => "Truncated",
            IoError::Parse { .. } => "Parse",
            IoError::Invalid { .. } => "Invalid",
            IoError::TooLarge { .. } => "TooLarge",
            IoError::Unsupported { .. } => "Unsupported",
        }
    }

    /// What every loader's run must show: no panic, no case over the memory rule, and every
    /// case run (the failures print the seed and the first cases, to replay with `case_rng`).
    fn assert_clean(report: &super::FuzzReport, seed: u64, cases: u64) {
        assert!(
            report.panics.is_empty(),
            "seed {seed:#x}: panics {:?}",
            &report.panics[..report.panics.len().min(10)]
        );
        assert!(
            report.over_budget.is_empty(),
            "seed {seed:#x}: over budget {:?}",
            &report.over_budget[..report.over_budget.len().min(10)]
        );
        assert_eq!(report.cases, cases);
    }

    fn asset(relative: &str) -> Vec<u8> {
        let path =
            concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/assets/").to_owned() + relative;
        std::fs::read(path).expect("asset")
    }

    /// Peak heap allowed for one case: parsing state proportional to the input plus a constant
    /// for the texture decoder. Inputs claiming huge counts must not get anywhere near it.
    fn budget(input_len: usize) -> u64 {
        (16 << 20) + 64 * input_len as u64
    }

    #[test]
    fn gltf_survives_mutated_files() {
        let corpus = vec![
            asset("skinned/SimpleSkin.gltf"),
            asset("static/Box.glb"),
            gltf_mesh::tests::textured_glb(),
            // Instances and levels of detail, as Thicket's exporter writes a forest.
            crate::io::gltf_instancing::tests::instanced_lod_glb(),
        ];
        for file in &corpus {
            gltf_mesh::import_gltf_slice(file, None)
                .expect("every seed file loads before mutation");
        }
        let cases = cases_from_env(10_000);
        let limits = ImportLimits::default();
        let kinds: RefCell<BTreeMap<&'static str, u64>> = RefCell::default();
        let counted_too_large = Cell::new(0u64);
        let report = run(&corpus, cases, SEED, budget, |bytes| {
            let name = Path::new("fuzz.glb");
            let result = gltf_mesh::import_gltf_slice_with(bytes, None, name, &limits);
            if let Err(e) = &result {
                *kinds.borrow_mut().entry(kind(e)).or_default() += 1;
            }
            // `thicket info`'s count reads the same files: it never panics, and counts every
            // file the import builds as importable, with at least the triangles built. (Files
            // the import refuses as too large are counted where the scene, not a declared
            // size, is what is too large; the figure is printed.)
            let count = gltf_mesh::count_gltf_slice(bytes, name, &limits);
            match (&result, &count) {
                (Ok(model), count) => {
                    let count = count.as_ref().expect("an imported file is counted");
                    assert_eq!(count.refused, None, "an imported file is not refused");
                    let built: usize = model.parts.iter().map(|p| p.indices.len() / 3).sum();
                    assert!(count.triangles >= built as u64, "{count:?} < {built}");
                }
                (Err(IoError::TooLarge { .. }), Ok(c)) if c.refused.is_some() => {
                    counted_too_large.set(counted_too_large.get() + 1);
                }
                _ => {}
            }
            result
        });
        eprintln!(
            "glTF fuzz: {} too-large file(s) counted without building",
            counted_too_large.get()
        );
        let kinds = kinds.into_inner();
        eprintln!("glTF fuzz: {report}; refusals by kind {kinds:?}");
        // Every layer of checks is reached: container, JSON, accessor bounds, declared sizes.
        for k in ["Truncated", "Parse", "Invalid", "TooLarge"] {
            assert!(
                kinds.get(k).copied().unwrap_or(0) > 0,
                "no {k} refusals: {kinds:?}"
            );
        }
        assert_clean(&report, SEED, cases);
        // The mutations must not all be rejected at the door, or the deep checks go untested.
        assert!(report.accepted > cases / 50, "{report}");
    }

    #[test]
    fn obj_survives_mutated_files() {
        let mtl = obj::tests::CUBE_MTL.as_bytes();
        let files = obj::tests::cube_files(mtl);
        let corpus = vec![obj::tests::CUBE_OBJ.as_bytes().to_vec()];
        let limits = ImportLimits::default();
        let options = obj::ObjOptions::default();
        let load = |bytes: &[u8]| {
            obj::import_obj_slice_with(bytes, &files, Path::new("fuzz.obj"), &options, &limits)
        };
        load(&corpus[0]).expect("the seed file loads before mutation");
        let cases = cases_from_env(10_000);
        let report = run(&corpus, cases, SEED, budget, load);
        eprintln!("OBJ fuzz: {report}");
        assert_clean(&report, SEED, cases);
        assert!(report.accepted > cases / 50, "{report}");

        // The material library mutated, the OBJ fixed.
        let mtl_corpus = vec![mtl.to_vec()];
        let mtl_cases = (cases / 5).max(1);
        let report = run(&mtl_corpus, mtl_cases, SEED, budget, |mtl_bytes| {
            let files = obj::tests::cube_files(mtl_bytes);
            obj::import_obj_slice_with(
                obj::tests::CUBE_OBJ.as_bytes(),
                &files,
                Path::new("fuzz.obj"),
                &options,
                &limits,
            )
        });
        eprintln!("MTL fuzz: {report}");
        assert_clean(&report, SEED, mtl_cases);
    }

    #[test]
    fn skinned_gltf_survives_mutated_files() {
        let corpus = vec![
            asset("skinned/SimpleSkin.gltf"),
            asset("skinned/RiggedFigure.glb"),
        ];
        for file in &corpus {
            crate::io::import_skinned_slice(file, "seed.glb")
                .expect("every seed file imports before mutation");
        }
        // RiggedFigure is 50 kB, so its cases cost more; the count is what CI can afford in a
        // debug build (THICKET_FUZZ_CASES raises it).
        let cases = cases_from_env(10_000);
        let report = run(&corpus, cases, SEED ^ 0x5C1, budget, |bytes| {
            crate::io::import_skinned_slice(bytes, "fuzz.glb")
        });
        eprintln!("skinned glTF fuzz: {report}");
        assert_clean(&report, SEED ^ 0x5C1, cases);
        assert!(report.accepted > cases / 50, "{report}");
        assert!(report.refused > cases / 50, "{report}");
    }

    /// Encodes `img` in `format`.
    fn encoded(img: &image::DynamicImage, format: image::ImageFormat) -> Vec<u8> {
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, format).expect("encodes");
        out.into_inner()
    }

    /// PNG and JPEG textures, mutated, through every path that decodes one: the texture
    /// decoder itself, an OBJ's `map_Kd`, a GLB's embedded image and the palette loader. The
    /// seeds are an indexed PNG with a full palette (the malformed `PLTE` chunk of issue 45 is
    /// one mutation away), an RGBA PNG, a 16-bit grey-and-alpha PNG and a baseline JPEG.
    #[test]
    fn images_survive_mutated_files_on_every_decoding_path() {
        let palette: Vec<u8> = (0..=255u8).flat_map(|i| [i, 255 - i, i / 2]).collect();
        let grey16 =
            image::DynamicImage::ImageLumaA16(image::ImageBuffer::from_fn(7, 5, |x, y| {
                image::LumaA([(x * 9000 + y * 300) as u16, 60_000])
            }));
        let rgb = image::DynamicImage::ImageRgb8(image::ImageBuffer::from_fn(16, 8, |x, y| {
            image::Rgb([(x * 15) as u8, (y * 30) as u8, 128])
        }));
        let corpus = vec![
            crate::mesh::tests::indexed_png(&palette),
            obj::tests::png_2x1(),
            encoded(&grey16, image::ImageFormat::Png),
            encoded(&rgb, image::ImageFormat::Jpeg),
        ];
        // Small enough that a header claiming a huge image is refused before decoding, and
        // the budget below holds for every accepted one.
        let limits = ImportLimits {
            max_texture_bytes: 1 << 20,
            ..ImportLimits::default()
        };
        for file in &corpus {
            assert!(
                gltf_mesh::decode_texture(file, &limits).is_ok(),
                "every seed image decodes before mutation"
            );
        }
        let mtl = obj::tests::CUBE_MTL.as_bytes();
        let options = obj::ObjOptions::default();
        let paths: RefCell<[u64; 4]> = RefCell::default();
        let cases = cases_from_env(10_000);
        let report = run(&corpus, cases, SEED ^ 0x1A6E, budget, |bytes| {
            let mut accepted = paths.borrow_mut();
            let texture = gltf_mesh::decode_texture(bytes, &limits);
            accepted[0] += u64::from(texture.is_ok());
            let files = obj::tests::cube_files_with(mtl, bytes.to_vec());
            let cube = obj::tests::CUBE_OBJ.as_bytes();
            let from_obj =
                obj::import_obj_slice_with(cube, &files, Path::new("fuzz.obj"), &options, &limits);
            accepted[1] += u64::from(from_obj.is_ok());
            let glb = gltf_mesh::tests::textured_glb_with(bytes);
            let from_glb =
                gltf_mesh::import_gltf_slice_with(&glb, None, Path::new("fuzz.glb"), &limits);
            accepted[2] += u64::from(from_glb.is_ok());
            accepted[3] += u64::from(crate::sculpt::palette_from_png(bytes).is_ok());
            // One decoder behind every path: they accept the same images.
            assert_eq!(
                texture.is_ok(),
                from_glb.is_ok(),
                "GLB and decoder disagree"
            );
            texture.map(|_| ()).map_err(|_| ())
        });
        let paths = paths.into_inner();
        eprintln!("image fuzz: {report}; accepted by decoder / OBJ / GLB / palette {paths:?}");
        assert_clean(&report, SEED ^ 0x1A6E, cases);
        // Mutations reach the decoders' insides: some images still decode, most do not.
        assert!(report.accepted > cases / 50, "{report}");
        assert!(report.refused > cases / 50, "{report}");
        assert!(
            paths.iter().all(|&n| n > 0),
            "a path accepted nothing: {paths:?}"
        );
    }

    /// The palette files (`.gpl` text, PNG strips, a `.vox` palette) and the rig files of
    /// `thicket rig` / `thicket animate` (skeleton and clip specs, JSON), mutated, through the
    /// parsers and the checks that turn them into a skeleton and a clip.
    #[test]
    fn palettes_and_rig_files_survive_mutated_files() {
        use crate::sculpt::{palette_from_png, palette_from_vox, palette_to_png, parse_gpl};
        use crate::skin::{ClipSpec, SkeletonSpec};
        let colors: Vec<[u8; 4]> = (0..40u8).map(|i| [i * 6, 255 - i, i, 255]).collect();
        let gpl =
            b"GIMP Palette\nName: fuzz\nColumns: 8\n#\n255 0 0\tred\n  0 128 255 sky\n12 34 56\n"
                .to_vec();
        let skeleton = br#"{"joints": [
            {"name": "hips", "parent": null, "position": [0.0, 1.0, 0.0]},
            {"name": "spine", "parent": "hips", "position": [0.0, 1.5, 0.0]},
            {"name": "arm.L", "parent": "spine", "position": [0.5, 1.6, 0.0]},
            {"name": "arm.R", "parent": "spine", "position": [-0.5, 1.6, 0.0]}]}"#
            .to_vec();
        let clip = br#"{"name": "wave", "length": 1.0, "loop": true, "keys": [
            {"joint": "arm.L", "time": 0.0, "rotation_deg": [0, 0, 10]},
            {"joint": "arm.L", "time": 0.5, "rotation_deg": [0, 0, 80], "translation": [0, 0.1, 0]},
            {"joint": "spine", "time": 1.0, "rotation_deg": [5, 0, 0]}]}"#
            .to_vec();
        let vox = asset("vox/dot_vox/placeholder.vox");
        let corpus = vec![gpl, palette_to_png(&colors), vox, skeleton.clone(), clip];
        let bones = serde_json::from_slice::<SkeletonSpec>(&skeleton)
            .expect("the seed skeleton parses")
            .to_skeleton(None)
            .expect("the seed skeleton is valid");
        let cases = cases_from_env(10_000);
        let counts: RefCell<[u64; 5]> = RefCell::default();
        let report = run(&corpus, cases, SEED ^ 0x9A1E, budget, |bytes| {
            let mut ok = counts.borrow_mut();
            let gpl = std::str::from_utf8(bytes)
                .ok()
                .is_some_and(|t| parse_gpl(t).is_ok());
            let png = palette_from_png(bytes).is_ok();
            let vox = palette_from_vox(bytes).is_ok();
            let skeleton = serde_json::from_slice::<SkeletonSpec>(bytes)
                .ok()
                .is_some_and(|s| s.to_skeleton(None).is_ok());
            let clip = serde_json::from_slice::<ClipSpec>(bytes)
                .ok()
                .is_some_and(|c| c.to_clip(&bones).is_ok());
            for (n, accepted) in ok.iter_mut().zip([gpl, png, vox, skeleton, clip]) {
                *n += u64::from(accepted);
            }
            if gpl || png || vox || skeleton || clip {
                Ok(())
            } else {
                Err(())
            }
        });
        let counts = counts.into_inner();
        eprintln!(
            "palette and rig fuzz: {report}; accepted as gpl/png/vox/skeleton/clip {counts:?}"
        );
        assert_clean(&report, SEED ^ 0x9A1E, cases);
        assert!(report.refused > cases / 50, "{report}");
        assert!(
            counts.iter().all(|&n| n > 0),
            "a parser accepted nothing: {counts:?}"
        );
    }

    #[cfg(unix)]
    #[test]
    fn obj_references_outside_the_folder_are_never_read() {
        let dir = tempfile::tempdir().unwrap();
        let inner = dir.path().join("inner");
        std::fs::create_dir(&inner).unwrap();
        // A material library outside the folder with a colour the import would show.
        std::fs::write(dir.path().join("out.mtl"), "newmtl red\nKd 0 0.123 0\n").unwrap();
        let outside = dir.path().join("out.mtl");
        for (i, mtllib) in [
            "/dev/zero".to_owned(),
            "../out.mtl".to_owned(),
            outside.display().to_string(),
            "link.mtl".to_owned(),
        ]
        .iter()
        .enumerate()
        {
            let _ = std::os::unix::fs::symlink(&outside, inner.join("link.mtl"));
            let text = obj::tests::CUBE_OBJ.replace("mtllib cube.mtl", &format!("mtllib {mtllib}"));
            let path = inner.join(format!("m{i}.obj"));
            std::fs::write(&path, text).unwrap();
            let (model, peak) = crate::io::fuzz::peak_heap_bytes(|| obj::import_obj(&path));
            let model = model.unwrap_or_else(|e| panic!("{mtllib}: {e}"));
            assert!(peak < budget(4096), "{mtllib}: {peak} bytes");
            assert!(
                model
                    .materials
                    .iter()
                    .all(|m| (m.base_color.y - 0.123).abs() > 1e-4),
                "{mtllib}: the outside library was read: {:?}",
                model.materials
            );
        }
    }
}

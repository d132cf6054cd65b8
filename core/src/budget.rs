//! Memory budgets: a request whose estimated peak memory is over the budget is refused before
//! anything large is allocated, with the estimate, the limit and what to change in the message
//! (instead of an allocator abort minutes later).
//!
//! The default limit is the smallest of what this process may really use:
//! - half of the machine's physical memory (`MemTotal` in `/proc/meminfo`; 16 GiB is assumed
//!   where that cannot be read): one command should leave room for the editor, the desktop and
//!   a second job;
//! - the process's address-space limit (`ulimit -v`, the soft `RLIMIT_AS` that `getrlimit`
//!   returns, read from `/proc/self/limits` so no `unsafe` call is needed): past it every
//!   allocation fails, whatever the machine has;
//! - the memory limit of the process's cgroup (cgroup v2 `memory.max`, v1
//!   `memory.limit_in_bytes`, the smallest along the path from its cgroup up to the root):
//!   past it a container's processes are killed.
//!
//! Each is read defensively: a missing or unreadable file, `max`, `unlimited` or a v1
//! "no limit" value mean that limit does not apply. `--memory-limit` on the command line
//! replaces the default. Estimates live beside the work they estimate (for example
//! [`crate::render::estimate_peak_bytes`]) and are tested against the peak a counting
//! allocator measures.

use std::fmt;
use std::path::Path;

/// Used when the physical memory cannot be read.
const FALLBACK_PHYSICAL: u64 = 16 << 30;

/// A limit on the peak heap memory of one request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemoryBudget {
    /// The most bytes a request may need.
    pub limit_bytes: u64,
    /// Where the limit comes from (said in the refusal).
    pub source: BudgetSource,
}

/// Where a [`MemoryBudget`]'s limit comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BudgetSource {
    /// Half of this much physical memory.
    HalfOfPhysical(u64),
    /// The process's address-space limit (`ulimit -v`), this many bytes.
    AddressSpace(u64),
    /// The memory limit of the process's cgroup, this many bytes.
    Cgroup(u64),
    /// Given by the user (`--memory-limit`).
    Given,
}

impl fmt::Display for BudgetSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::HalfOfPhysical(p) => write!(f, "half of this machine's {}", human(*p)),
            Self::AddressSpace(a) => write!(
                f,
                "this process's address-space limit (ulimit -v) of {}",
                human(*a)
            ),
            Self::Cgroup(c) => write!(f, "this process's cgroup memory limit of {}", human(*c)),
            Self::Given => f.write_str("--memory-limit"),
        }
    }
}

/// The limits the default budget is the smallest of, as read from a machine; `None` where a
/// limit is unknown or does not apply.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MachineLimits {
    /// Physical memory (`MemTotal`).
    pub physical_bytes: Option<u64>,
    /// The soft address-space limit (`RLIMIT_AS`).
    pub address_space_bytes: Option<u64>,
    /// The cgroup memory limit.
    pub cgroup_bytes: Option<u64>,
}

impl MachineLimits {
    /// This process's limits, from `/proc/meminfo`, `/proc/self/limits`, `/proc/self/cgroup`
    /// and `/sys/fs/cgroup` (each `None` where it cannot be read: other systems, containers
    /// without those files).
    #[must_use]
    pub fn of_this_process() -> Self {
        let read = |p: &str| std::fs::read_to_string(p).ok();
        Self {
            physical_bytes: read("/proc/meminfo").as_deref().and_then(parse_meminfo),
            address_space_bytes: read("/proc/self/limits")
                .as_deref()
                .and_then(parse_address_space_limit),
            cgroup_bytes: read("/proc/self/cgroup")
                .and_then(|text| cgroup_limit(Path::new("/sys/fs/cgroup"), &text)),
        }
    }
}

/// A request over its budget.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "{what} would need about {} of memory, over the limit of {} ({limit_from}): {advice}",
    human(*estimate_bytes),
    human(*limit_bytes)
)]
pub struct OverBudget {
    /// What was asked for, e.g. "rendering 16384x16384".
    pub what: String,
    /// The estimated peak.
    pub estimate_bytes: u64,
    /// The limit.
    pub limit_bytes: u64,
    /// Where the limit comes from.
    pub limit_from: BudgetSource,
    /// What to change, e.g. "lower --size, or raise the limit with --memory-limit".
    pub advice: String,
}

impl MemoryBudget {
    /// The default for this process: the smallest of half its machine's physical memory, its
    /// address-space limit and its cgroup's memory limit (see the module docs).
    #[must_use]
    pub fn for_this_machine() -> Self {
        Self::from_limits(&MachineLimits::of_this_process())
    }

    /// The smallest of half of `limits.physical_bytes` (16 GiB assumed when unknown), the
    /// address-space limit and the cgroup limit; equal limits are credited in that order.
    #[must_use]
    pub fn from_limits(limits: &MachineLimits) -> Self {
        let physical = limits.physical_bytes.unwrap_or(FALLBACK_PHYSICAL);
        let mut budget = Self {
            limit_bytes: physical / 2,
            source: BudgetSource::HalfOfPhysical(physical),
        };
        let others = [
            limits
                .address_space_bytes
                .map(|b| (b, BudgetSource::AddressSpace(b))),
            limits.cgroup_bytes.map(|b| (b, BudgetSource::Cgroup(b))),
        ];
        for (bytes, source) in others.into_iter().flatten() {
            if bytes < budget.limit_bytes {
                budget = Self {
                    limit_bytes: bytes,
                    source,
                };
            }
        }
        budget
    }

    /// A limit given by the user.
    #[must_use]
    pub fn given(limit_bytes: u64) -> Self {
        Self {
            limit_bytes,
            source: BudgetSource::Given,
        }
    }

    /// `Ok` when `estimate_bytes` fits, else the refusal naming `what` and `advice`.
    ///
    /// # Errors
    /// [`OverBudget`] when the estimate is over the limit.
    pub fn check(&self, what: &str, estimate_bytes: u64, advice: &str) -> Result<(), OverBudget> {
        if estimate_bytes <= self.limit_bytes {
            return Ok(());
        }
        Err(OverBudget {
            what: what.to_owned(),
            estimate_bytes,
            limit_bytes: self.limit_bytes,
            limit_from: self.source,
            advice: advice.to_owned(),
        })
    }
}

/// `MemTotal` from `/proc/meminfo` text, in bytes.
fn parse_meminfo(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// The soft limit of the `Max address space` row of `/proc/self/limits` text, in bytes
/// (`None` for `unlimited` or a missing row).
fn parse_address_space_limit(text: &str) -> Option<u64> {
    let row = text
        .lines()
        .find_map(|l| l.strip_prefix("Max address space"))?;
    row.split_whitespace().next()?.parse().ok()
}

/// Values at or above this are cgroup v1's "no limit" (a page-rounded `i64::MAX`), not a
/// limit anyone set.
const CGROUP_V1_UNLIMITED: u64 = 1 << 62;

/// A cgroup memory limit file's content in bytes (`None` for `max`, v1's "no limit", or text
/// that is not a number).
fn parse_cgroup_limit(text: &str) -> Option<u64> {
    let bytes: u64 = text.trim().parse().ok()?;
    (bytes < CGROUP_V1_UNLIMITED).then_some(bytes)
}

/// The smallest memory limit on the way from the process's cgroups (the lines of
/// `/proc/self/cgroup`: `0::/path` for v2, `N:memory:/path` for v1's memory controller) up to
/// the hierarchy's root under `root` (normally `/sys/fs/cgroup`): a parent's limit binds its
/// children too. Paths that climb with `..` are ignored.
fn cgroup_limit(root: &Path, proc_self_cgroup: &str) -> Option<u64> {
    let mut smallest: Option<u64> = None;
    for line in proc_self_cgroup.lines() {
        let mut fields = line.splitn(3, ':');
        let (Some(id), Some(controllers), Some(path)) =
            (fields.next(), fields.next(), fields.next())
        else {
            continue;
        };
        let (base, file) = if id == "0" && controllers.is_empty() {
            (root.to_path_buf(), "memory.max")
        } else if controllers.split(',').any(|c| c == "memory") {
            (root.join("memory"), "memory.limit_in_bytes")
        } else {
            continue;
        };
        let relative = path.trim_start_matches('/');
        if relative.split('/').any(|part| part == "..") {
            continue;
        }
        let mut dir = base.join(relative);
        loop {
            let limit = std::fs::read_to_string(dir.join(file))
                .ok()
                .as_deref()
                .and_then(parse_cgroup_limit);
            if let Some(limit) = limit {
                smallest = Some(smallest.map_or(limit, |s| s.min(limit)));
            }
            if dir == base || !dir.pop() {
                break;
            }
        }
    }
    smallest
}

/// Parses a size such as `512M`, `1.5G`, `8GiB`, `2T` or a plain byte count (binary units:
/// K = 1024 bytes).
///
/// # Errors
/// A message saying what was expected, for text that is no positive size.
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        other => {
            return Err(format!(
                "{text:?}: unknown unit {other:?} (expected a size such as 512M, 8G or 1.5T)"
            ));
        }
    };
    let value: f64 = number
        .parse()
        .map_err(|_| format!("{text:?}: expected a size such as 512M, 8G or 1.5T"))?;
    let bytes = value * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!(
            "{text:?}: the limit must be at least 1 byte and below 16 EiB"
        ));
    }
    Ok(bytes as u64)
}

/// `1234567` → "1,234,567".
#[must_use]
pub fn thousands(n: u64) -> String {
    thousands_u128(u128::from(n))
}

/// [`thousands`] for counts beyond `u64` (KRS kernel instances).
#[must_use]
pub fn thousands_u128(n: u128) -> String {
    let digits = n.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// `1536` → "1.5 KiB".
#[must_use]
pub fn human(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_in_binary_units_and_bad_ones_say_what_was_expected() {
        assert_eq!(parse_bytes("1000"), Ok(1000));
        assert_eq!(parse_bytes("512M"), Ok(512 << 20));
        assert_eq!(parse_bytes("1.5G"), Ok(3 << 29));
        assert_eq!(parse_bytes(" 8 GiB "), Ok(8 << 30));
        assert_eq!(parse_bytes("2t"), Ok(2 << 40));
        for bad in ["", "G", "-1G", "0", "1.2.3M", "5 parsecs", "1e30T", "nan"] {
            let e = parse_bytes(bad).expect_err(bad);
            assert!(
                e.contains("expected") || e.contains("at least"),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn a_request_over_the_limit_is_refused_with_both_figures_and_the_advice() {
        let b = MemoryBudget::given(1 << 30);
        assert!(b.check("rendering 64x64", 1 << 30, "lower --size").is_ok());
        let e = b
            .check("rendering 16384x16384", 15 << 30, "lower --size")
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "rendering 16384x16384 would need about 15.0 GiB of memory, over the limit of 1.0 GiB \
             (--memory-limit): lower --size"
        );
    }

    #[test]
    fn the_default_is_within_every_limit_of_this_process() {
        let b = MemoryBudget::for_this_machine();
        let limits = MachineLimits::of_this_process();
        assert_eq!(b, MemoryBudget::from_limits(&limits));
        let physical = limits.physical_bytes.unwrap_or(FALLBACK_PHYSICAL);
        assert!(b.limit_bytes <= physical / 2, "{b:?}");
        for limit in [limits.address_space_bytes, limits.cgroup_bytes]
            .into_iter()
            .flatten()
        {
            assert!(b.limit_bytes <= limit, "{b:?} {limits:?}");
        }
        // Any machine that builds Thicket has more than 256 MiB.
        assert!(b.limit_bytes > 128 << 20, "{b:?}");
    }

    #[test]
    fn the_default_is_the_smallest_limit_and_says_which() {
        const G: u64 = 1 << 30;
        let at = |physical, address_space, cgroup| {
            MemoryBudget::from_limits(&MachineLimits {
                physical_bytes: physical,
                address_space_bytes: address_space,
                cgroup_bytes: cgroup,
            })
        };
        let b = at(Some(32 * G), None, None);
        assert_eq!(b.limit_bytes, 16 * G);
        assert_eq!(b.source, BudgetSource::HalfOfPhysical(32 * G));
        assert_eq!(b.source.to_string(), "half of this machine's 32.0 GiB");
        // Unknown physical memory: 16 GiB assumed.
        assert_eq!(at(None, None, None).limit_bytes, 8 * G);
        let b = at(Some(32 * G), Some(4 * G), Some(6 * G));
        assert_eq!(
            (b.limit_bytes, b.source),
            (4 * G, BudgetSource::AddressSpace(4 * G))
        );
        assert_eq!(
            b.source.to_string(),
            "this process's address-space limit (ulimit -v) of 4.0 GiB"
        );
        let b = at(Some(32 * G), Some(20 * G), Some(2 * G));
        assert_eq!(
            (b.limit_bytes, b.source),
            (2 * G, BudgetSource::Cgroup(2 * G))
        );
        assert_eq!(
            b.source.to_string(),
            "this process's cgroup memory limit of 2.0 GiB"
        );
        // Limits above half the memory leave the default as it was.
        let b = at(Some(8 * G), Some(100 * G), Some(5 * G));
        assert_eq!(b.source, BudgetSource::HalfOfPhysical(8 * G));
        // A refusal says where its limit comes from.
        let e = at(Some(64 * G), None, Some(G))
            .check("rendering 64x64", 2 * G, "lower --size")
            .unwrap_err();
        assert!(
            e.to_string()
                .contains("(this process's cgroup memory limit of 1.0 GiB)"),
            "{e}"
        );
    }

    #[test]
    fn limit_files_are_read_defensively() {
        assert_eq!(
            parse_meminfo("MemTotal:       16318672 kB\nMemFree: 1 kB\n"),
            Some(16_710_320_128)
        );
        assert_eq!(parse_meminfo("MemFree: 1 kB\n"), None);
        assert_eq!(parse_meminfo(""), None);
        let limits = |soft: &str| {
            format!(
                "Limit                     Soft Limit           Hard Limit           Units     \n\
                 Max cpu time              unlimited            unlimited            seconds   \n\
                 Max address space         {soft:<20} unlimited            bytes     \n"
            )
        };
        assert_eq!(parse_address_space_limit(&limits("unlimited")), None);
        assert_eq!(
            parse_address_space_limit(&limits("4294967296")),
            Some(4 << 30)
        );
        assert_eq!(
            parse_address_space_limit("Max cpu time 1 1 seconds\n"),
            None
        );
        assert_eq!(parse_cgroup_limit("max\n"), None);
        assert_eq!(parse_cgroup_limit("536870912\n"), Some(512 << 20));
        assert_eq!(
            parse_cgroup_limit("9223372036854771712\n"),
            None,
            "v1: no limit"
        );
        assert_eq!(parse_cgroup_limit(""), None);
        assert_eq!(parse_cgroup_limit("lots"), None);
    }

    #[test]
    fn the_cgroup_limit_is_the_smallest_on_the_way_to_the_root() {
        let root = tempfile::tempdir().unwrap();
        let r = root.path();
        let write = |dir: &Path, file: &str, text: &str| {
            std::fs::create_dir_all(dir).unwrap();
            std::fs::write(dir.join(file), text).unwrap();
        };
        // v2: the service allows 3 GiB, its slice 1 GiB, the root has no file.
        write(&r.join("user.slice"), "memory.max", "1073741824\n");
        write(
            &r.join("user.slice/app.service"),
            "memory.max",
            "3221225472\n",
        );
        assert_eq!(
            cgroup_limit(r, "0::/user.slice/app.service\n"),
            Some(1 << 30)
        );
        // A cgroup of its own with "max" and no limited parent: none.
        write(&r.join("free"), "memory.max", "max\n");
        assert_eq!(cgroup_limit(r, "0::/free\n"), None);
        // The process's cgroup not visible (another namespace): its root still counts.
        assert_eq!(cgroup_limit(r, "0::/elsewhere/deep\n"), None);
        write(r, "memory.max", "2147483648\n");
        assert_eq!(cgroup_limit(r, "0::/elsewhere/deep\n"), Some(2 << 30));
        // v1: the memory controller's own hierarchy, other controllers ignored.
        let v1 = tempfile::tempdir().unwrap();
        write(
            &v1.path().join("memory/docker/abc"),
            "memory.limit_in_bytes",
            "268435456\n",
        );
        write(
            &v1.path().join("memory"),
            "memory.limit_in_bytes",
            "9223372036854771712\n",
        );
        let text = "12:cpu,cpuacct:/docker/abc\n4:memory:/docker/abc\n";
        assert_eq!(cgroup_limit(v1.path(), text), Some(256 << 20));
        // Nothing readable, or a path that climbs out: no limit.
        assert_eq!(cgroup_limit(Path::new("/nonexistent"), "0::/\n"), None);
        assert_eq!(cgroup_limit(r, "0::/../etc\n"), None);
        assert_eq!(cgroup_limit(r, "garbage"), None);
    }
}

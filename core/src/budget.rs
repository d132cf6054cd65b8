//! Memory budgets: a request whose estimated peak memory is over the budget is refused before
//! anything large is allocated, with the estimate, the limit and what to change in the message
//! (instead of an allocator abort minutes later).
//!
//! The default limit is half of the machine's physical memory (`MemTotal` in `/proc/meminfo`;
//! 16 GiB of memory is assumed where that cannot be read): one command should leave room for the editor, the desktop
//! and a second job. `--memory-limit` on the command line replaces it. Estimates live beside
//! the work they estimate (for example [`crate::render::estimate_peak_bytes`]) and are tested
//! against the peak a counting allocator measures.

use std::fmt;

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
    /// Given by the user (`--memory-limit`).
    Given,
}

impl fmt::Display for BudgetSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::HalfOfPhysical(p) => write!(f, "half of this machine's {}", human(*p)),
            Self::Given => f.write_str("--memory-limit"),
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
    /// Half of this machine's physical memory.
    #[must_use]
    pub fn for_this_machine() -> Self {
        let physical = physical_memory_bytes().unwrap_or(FALLBACK_PHYSICAL);
        Self {
            limit_bytes: physical / 2,
            source: BudgetSource::HalfOfPhysical(physical),
        }
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

/// `MemTotal` from `/proc/meminfo`, in bytes.
fn physical_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
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
    fn the_default_is_half_the_physical_memory() {
        let b = MemoryBudget::for_this_machine();
        let BudgetSource::HalfOfPhysical(p) = b.source else {
            panic!("{b:?}")
        };
        assert_eq!(b.limit_bytes, p / 2);
        // Any machine that builds Thicket has more than 256 MiB.
        assert!(b.limit_bytes > 128 << 20, "{b:?}");
        assert!(b.source.to_string().starts_with("half of this machine's"));
    }
}

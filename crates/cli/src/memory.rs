//! Pre-flight estimates: every command states how much working memory and how many
//! output bytes a run will need, from the input size and its settings, before the work starts,
//! and refuses a run that exceeds the global `--max-memory` or `--max-output-size` with a
//! message naming the flag to change. The estimates are upper bounds calibrated on measured
//! peak RSS (`/usr/bin/time -v`, see `fuzz/RESULTS.md` and the issue-18 notes), not exact.
//!
//! Default memory limit: half of the physical memory (`MemTotal` in `/proc/meminfo`), lowered
//! to a cgroup `memory.max` and to three quarters of an address-space limit (`ulimit -v`) when
//! those are smaller; [`FALLBACK_MEMORY`] where none can be read.

use anyhow::{Result, bail};

/// One gibibyte.
pub(crate) const GIB: u64 = 1 << 30;

/// The default limit where the physical memory cannot be read.
pub(crate) const FALLBACK_MEMORY: u64 = 4 * GIB;

/// Default `--max-output-size`: no command writes more than this much without asking.
pub(crate) const DEFAULT_MAX_OUTPUT: u64 = 32 * GIB;

/// `--max-output-size` in bytes (default [`DEFAULT_MAX_OUTPUT`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct OutputLimit(pub(crate) u64);

impl Default for OutputLimit {
    fn default() -> Self {
        OutputLimit(DEFAULT_MAX_OUTPUT)
    }
}

/// Where the memory limit comes from (for messages).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Source {
    /// `--max-memory` on the command line.
    Flag,
    /// Half of `MemTotal` bytes of physical memory.
    Physical(u64),
    /// A cgroup `memory.max` of that many bytes (the default is half of it).
    Cgroup(u64),
    /// An address-space limit (`ulimit -v`) of that many bytes (the default: 3/4 of it).
    AddressSpace(u64),
    /// Nothing could be read: [`FALLBACK_MEMORY`].
    Fallback,
}

/// The memory limit of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Limit {
    /// Bytes.
    pub(crate) bytes: u64,
    /// Where the value comes from.
    pub(crate) source: Source,
}

impl Default for Limit {
    fn default() -> Self {
        Limit {
            bytes: FALLBACK_MEMORY,
            source: Source::Fallback,
        }
    }
}

impl std::fmt::Display for Limit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let b = human(self.bytes);
        match self.source {
            Source::Flag => write!(f, "--max-memory {b}"),
            Source::Physical(t) => write!(
                f,
                "--max-memory {b} (default: half of the {} of physical memory)",
                human(t)
            ),
            Source::Cgroup(t) => write!(
                f,
                "--max-memory {b} (default: half of the cgroup limit of {})",
                human(t)
            ),
            Source::AddressSpace(t) => write!(
                f,
                "--max-memory {b} (default: 3/4 of the address-space limit of {})",
                human(t)
            ),
            Source::Fallback => write!(
                f,
                "--max-memory {b} (default: the physical memory could not be read)"
            ),
        }
    }
}

/// A byte count for people: `1.5 GiB`, `320 MiB`, `12 KiB`, `100 B`.
pub(crate) fn human(b: u64) -> String {
    relief_pipeline::human_bytes(b)
}

/// Parses a byte size: a number with an optional unit `K`, `M`, `G`, `T` (powers of 1024,
/// `KiB`/`KB` spellings and a trailing `B` accepted), e.g. `512M`, `8G`, `1.5GiB`, `4096`.
pub(crate) fn parse_size(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let lower = t.to_ascii_lowercase();
    let body = lower.strip_suffix('b').unwrap_or(&lower);
    let body = body.strip_suffix('i').unwrap_or(body);
    let (num, mul) = match body.chars().last() {
        Some('k') => (&body[..body.len() - 1], 1u64 << 10),
        Some('m') => (&body[..body.len() - 1], 1 << 20),
        Some('g') => (&body[..body.len() - 1], 1 << 30),
        Some('t') => (&body[..body.len() - 1], 1 << 40),
        _ => (body, 1),
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a size (a number with K, M, G or T, e.g. 8G)"))?;
    let bytes = v * mul as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < 2f64.powi(63)) {
        return Err(format!(
            "`{s}`: the size must be at least 1 byte and below 8 EiB"
        ));
    }
    Ok(bytes as u64)
}

/// `--max-memory` value parser.
pub(crate) fn parse_limit(s: &str) -> std::result::Result<Limit, String> {
    let bytes = parse_size(s)?;
    if bytes < 16 << 20 {
        return Err(format!("`{s}`: at least 16M (no run fits in less)"));
    }
    Ok(Limit {
        bytes,
        source: Source::Flag,
    })
}

/// The default limit of this machine (see the module docs).
pub(crate) fn default_limit() -> Limit {
    let read = |p: &str| std::fs::read_to_string(p).ok();
    let mem_total = read("/proc/meminfo").and_then(|t| meminfo_total(&t));
    let cgroup = read("/sys/fs/cgroup/memory.max").and_then(|t| t.trim().parse::<u64>().ok());
    let address = read("/proc/self/limits").and_then(|t| address_space_limit(&t));
    choose_default(mem_total, cgroup, address)
}

/// The default from the three readings (each `None` when unknown or unlimited).
fn choose_default(mem_total: Option<u64>, cgroup: Option<u64>, address: Option<u64>) -> Limit {
    let mut best = match mem_total {
        Some(t) => Limit {
            bytes: t / 2,
            source: Source::Physical(t),
        },
        None => Limit::default(),
    };
    if let Some(c) = cgroup
        && c / 2 < best.bytes
    {
        best = Limit {
            bytes: c / 2,
            source: Source::Cgroup(c),
        };
    }
    if let Some(a) = address
        && a / 4 * 3 < best.bytes
    {
        best = Limit {
            bytes: a / 4 * 3,
            source: Source::AddressSpace(a),
        };
    }
    best
}

/// `MemTotal` of `/proc/meminfo`, in bytes.
fn meminfo_total(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let mut it = line.split_whitespace().skip(1);
    let v: u64 = it.next()?.parse().ok()?;
    let unit = it.next().unwrap_or("B");
    let mul = match unit {
        "kB" | "KB" | "kiB" => 1024,
        "mB" | "MB" => 1 << 20,
        _ => 1,
    };
    v.checked_mul(mul).filter(|&b| b > 0)
}

/// The soft `Max address space` of `/proc/self/limits`, in bytes (`None`: unlimited).
fn address_space_limit(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("Max address space"))?;
    let soft = line["Max address space".len()..]
        .split_whitespace()
        .next()?;
    soft.parse::<u64>().ok().filter(|&b| b > 0)
}

/// One part of an estimate: what it is, its bytes, and the flag that changes it.
#[derive(Debug, Clone)]
pub(crate) struct Part {
    /// What the memory is for ("the x256 intermediate raster").
    pub(crate) what: String,
    /// Bytes.
    pub(crate) bytes: u64,
    /// How to make it smaller ("a smaller --factor").
    pub(crate) change: String,
}

/// A part of an estimate (`bytes` as f64, saturating).
pub(crate) fn part(what: impl Into<String>, bytes: f64, change: impl Into<String>) -> Part {
    Part {
        what: what.into(),
        bytes: saturating_bytes(bytes),
        change: change.into(),
    }
}

/// `v` as a byte count (saturating at `u64::MAX`, negative and NaN as 0).
pub(crate) fn saturating_bytes(v: f64) -> u64 {
    if v.is_nan() || v <= 0.0 {
        0
    } else if v >= u64::MAX as f64 {
        u64::MAX
    } else {
        v as u64
    }
}

/// Refuses a run whose peak working memory (the largest of `peaks`, each the sum of the
/// memory alive at one moment) exceeds `limit`; the message names the largest part of the
/// largest peak and the flag that changes it. `command` names the run ("amplify x1024").
pub(crate) fn check_memory(command: &str, limit: Limit, peaks: &[&[Part]]) -> Result<()> {
    let total = |p: &[Part]| p.iter().fold(0u64, |a, x| a.saturating_add(x.bytes));
    let Some(peak) = peaks.iter().max_by_key(|p| total(p)) else {
        return Ok(());
    };
    let need = total(peak);
    if need <= limit.bytes {
        return Ok(());
    }
    let main = peak
        .iter()
        .max_by_key(|p| p.bytes)
        .expect("a peak over the limit has parts");
    bail!(
        "{command} would need about {} of working memory ({}: {}), more than {limit}: \
         use {} or raise --max-memory",
        human(need),
        main.what,
        human(main.bytes),
        main.change
    )
}

/// Refuses an output larger than `limit` bytes (`--max-output-size`).
pub(crate) fn check_output(what: &str, bytes: f64, limit: u64, change: &str) -> Result<()> {
    let b = saturating_bytes(bytes);
    if b > limit {
        bail!(
            "{what} would be about {}, more than --max-output-size {}: use {change} or raise \
             --max-output-size",
            human(b),
            human(limit)
        );
    }
    Ok(())
}

/// The memory a raster read may use: what a file of `file_len` bytes leaves of the limit,
/// at [`READ_BYTES_PER_CELL`] per cell, as a cell count.
pub(crate) fn readable_cells(limit: Limit, file_len: u64) -> usize {
    let left = limit.bytes.saturating_sub(file_len);
    usize::try_from(left / READ_BYTES_PER_CELL).unwrap_or(usize::MAX)
}

/// Peak bytes per cell while a raster is decoded, beyond the file itself: the decoded samples
/// in their stored type (at most 8 bytes, f64) and the f32 heightfield, plus a copy made by
/// the commands that crop or fill (4).
pub(crate) const READ_BYTES_PER_CELL: u64 = 16;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_units() {
        assert_eq!(parse_size("4096"), Ok(4096));
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("8G"), Ok(8 << 30));
        assert_eq!(parse_size("8GiB"), Ok(8 << 30));
        assert_eq!(parse_size("1.5g"), Ok(3 << 29));
        assert_eq!(parse_size("2TB"), Ok(2 << 40));
        for bad in ["", "x", "-1G", "0", "nan", "1e40", "G"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
        assert!(parse_limit("1M").is_err());
        assert_eq!(parse_limit("1G").unwrap().bytes, GIB);
    }

    #[test]
    fn default_is_the_smallest_share() {
        let meminfo = "MemTotal:       24000000 kB\nMemFree: 1 kB\n";
        let total = meminfo_total(meminfo).unwrap();
        assert_eq!(total, 24_000_000 * 1024);
        let limits = "Limit                     Soft Limit           Hard Limit           Units\n\
                      Max address space         4294967296           unlimited            bytes\n";
        assert_eq!(address_space_limit(limits), Some(4 << 30));
        let unlimited =
            "Max address space         unlimited            unlimited            bytes\n";
        assert_eq!(address_space_limit(unlimited), None);
        let l = choose_default(Some(total), None, None);
        assert_eq!(l.bytes, total / 2);
        let l = choose_default(Some(total), None, Some(4 << 30));
        assert_eq!(l.bytes, 3 << 30);
        assert_eq!(l.source, Source::AddressSpace(4 << 30));
        let l = choose_default(Some(total), Some(2 << 30), Some(4 << 30));
        assert_eq!(l.bytes, 1 << 30);
        assert_eq!(choose_default(None, None, None).bytes, FALLBACK_MEMORY);
        assert!(l.to_string().contains("cgroup"), "{l}");
    }

    #[test]
    fn the_message_names_the_largest_part_and_its_flag() {
        let limit = Limit {
            bytes: GIB,
            source: Source::Flag,
        };
        let small = [part("a", 1e6, "--a")];
        let big = [
            part("the grid", 3e9, "a smaller --resolution"),
            part("b", 1e8, "--b"),
        ];
        assert!(check_memory("volume", limit, &[&small]).is_ok());
        let e = check_memory("volume", limit, &[&small, &big])
            .unwrap_err()
            .to_string();
        assert!(e.contains("--resolution"), "{e}");
        assert!(e.contains("--max-memory 1.0 GiB"), "{e}");
        assert!(e.contains("the grid"), "{e}");
        assert!(check_memory("x", limit, &[&[part("inf", f64::INFINITY, "--x")]]).is_err());
        assert!(check_output("the mesh", 3e9, GIB, "a smaller --resolution").is_err());
        assert!(check_output("the mesh", 3e8, GIB, "x").is_ok());
        assert_eq!(human(1536 << 20), "1.5 GiB");
        assert_eq!(human(100), "100 B");
    }
}

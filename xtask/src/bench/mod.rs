//! `cargo xtask bench`: runs the criterion benches of `relief-benches` and the Python peers on
//! the same data, then writes `target/bench/dashboard.json` and `dashboard.html` with one row
//! per [`WorkItem`] (see `items.rs`): our time, the peer's time, the ratio, the goal and a
//! pass/short mark.
//!
//! Peers are either Python scripts in `xtask/peers/` or another criterion benchmark (a Rust peer
//! such as `texture-synthesis`, timed inside the same `cargo bench`). Each script is run as
//! `<venv>/bin/python xtask/peers/<script> <data dir>` and prints one JSON object
//! `{"<key>": seconds, ...}` (median of its repeats) on stdout; non-numeric values are ignored.
//! The data dir is `target/bench-data/`: the criterion benches write the inputs their peers read
//! there (`omp_*.npy`, `ksvd_patches.npy`, `volume256.npy`), and [`write_peer_data`] adds the
//! rest before the peers run. The venv `target/peers-venv` is created with the packages of
//! [`PEER_PACKAGES`] when missing.
//!
//! `cargo bench` runs with `RAYON_NUM_THREADS=2` (the issues' goals are for 2 threads); the
//! load average before and after the run is recorded in the dashboard because the machine is
//! shared and the numbers are noisy.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail};
use serde::Serialize;

mod items;

use relief_pipeline::report::esc;

/// Packages installed into the peers venv. `richdem2` is a maintained build of RichDEM (it
/// installs the `richdem` module): the `richdem` 0.3.4 sdist on PyPI bundles a pybind11 that
/// does not compile against CPython 3.11.
pub(crate) const PEER_PACKAGES: &[&str] = &[
    "spams-bin",
    "PyWavelets",
    "scikit-image",
    "scikit-learn",
    "imagecodecs",
    "richdem2",
    "pysheds",
    "fastscapelib",
    "numpy",
];

/// A dashboard row.
#[derive(Debug, Clone, Copy)]
pub(crate) struct WorkItem {
    /// What is measured (shown in the first column).
    pub(crate) name: &'static str,
    /// Criterion benchmark path under `target/criterion/` (`group/function/parameter`).
    pub(crate) criterion_id: &'static str,
    /// The side-by-side peer, if any.
    pub(crate) peer: Option<Peer>,
    /// The goal this row is judged against.
    pub(crate) goal: Goal,
    /// Work units per run (`(65536.0, "signals")`): the dashboard also shows our rate.
    pub(crate) units: Option<(f64, &'static str)>,
    /// Caveat shown with the row (different output sizes, 8-bit input, ...); may be empty.
    pub(crate) note: &'static str,
}

/// A peer measurement.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Peer {
    /// Where the peer's time comes from.
    pub(crate) source: PeerSource,
    /// Human-readable peer name.
    pub(crate) label: &'static str,
}

/// Where a peer's time comes from.
#[derive(Debug, Clone, Copy)]
pub(crate) enum PeerSource {
    /// `key` (seconds) of the JSON object printed by `script` in `xtask/peers/`.
    Script {
        /// Script file name in `xtask/peers/`.
        script: &'static str,
        /// Key of the timing in the script's JSON output.
        key: &'static str,
    },
    /// Another criterion benchmark of the same `cargo bench` run (a Rust peer).
    Criterion(&'static str),
}

impl Peer {
    /// The peer script, when the peer is a script.
    fn script(&self) -> Option<&'static str> {
        match self.source {
            PeerSource::Script { script, .. } => Some(script),
            PeerSource::Criterion(_) => None,
        }
    }
}

/// Goal of a row.
#[derive(Debug, Clone, Copy, Serialize)]
pub(crate) enum Goal {
    /// Our time / peer time must be at most this.
    #[allow(dead_code)]
    RatioAtMost(f64),
    /// We must be at least this many times faster than the peer (ratio <= 1 / x).
    SpeedupAtLeast(f64),
    /// Our time must be at most this many seconds.
    SecondsAtMost(f64),
    /// Reported only (for rows whose issue states no goal).
    #[allow(dead_code)]
    None,
}

impl Goal {
    fn describe(self) -> String {
        match self {
            Goal::RatioAtMost(r) => format!("ratio <= {r}"),
            Goal::SpeedupAtLeast(x) => format!(">= {x}x peer speed (ratio <= {:.3})", 1.0 / x),
            Goal::SecondsAtMost(s) => format!("<= {s} s"),
            Goal::None => "-".to_string(),
        }
    }

    /// `Some(true)` = pass, `Some(false)` = short, `None` = cannot judge (missing timing).
    fn judge(self, ours: Option<f64>, ratio: Option<f64>) -> Option<bool> {
        match self {
            Goal::RatioAtMost(r) => ratio.map(|x| x <= r),
            Goal::SpeedupAtLeast(x) => ratio.map(|q| q * x <= 1.0),
            Goal::SecondsAtMost(s) => ours.map(|t| t <= s),
            Goal::None => None,
        }
    }
}

/// Options of `cargo xtask bench`.
#[derive(Debug, Clone, Default)]
pub(crate) struct BenchOptions {
    pub(crate) run_cargo: bool,
    pub(crate) run_peers: bool,
    pub(crate) filter: Option<String>,
}

/// One row of `dashboard.json`.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct Row {
    pub(crate) item: String,
    pub(crate) criterion_id: String,
    pub(crate) ours_s: Option<f64>,
    pub(crate) peer: Option<String>,
    pub(crate) peer_s: Option<f64>,
    pub(crate) ratio: Option<f64>,
    /// Our rate in work units per second (`"1.23e6 signals/s"`), when the item has units.
    pub(crate) rate: Option<String>,
    pub(crate) goal: String,
    pub(crate) status: String,
    pub(crate) note: String,
}

/// Runs everything and writes the dashboard; returns the HTML path.
pub(crate) fn run(root: &Path, opts: &BenchOptions) -> Result<PathBuf> {
    let target = crate::target_dir(root);
    let out = target.join("bench");
    let data = target.join("bench-data");
    std::fs::create_dir_all(&out)?;
    std::fs::create_dir_all(&data)?;
    let selected: Vec<&WorkItem> = items::WORK_ITEMS
        .iter()
        .filter(|w| matches_filter(opts.filter.as_deref(), w))
        .collect();
    let load_before = load_average();
    let started = std::time::SystemTime::now();

    if opts.run_cargo {
        eprintln!("bench: cargo bench -p relief-benches (RAYON_NUM_THREADS=2)");
        let mut cmd = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
        cmd.current_dir(root).env("RAYON_NUM_THREADS", "2").args([
            "bench",
            "-p",
            "relief-benches",
            "--",
        ]);
        if let Some(f) = &opts.filter {
            cmd.arg(f);
        }
        let status = cmd.status().context("cannot run cargo bench")?;
        if !status.success() {
            bail!("cargo bench -p relief-benches failed ({status})");
        }
    }

    let mut notes = Vec::new();
    let mut peer_times: BTreeMap<&str, BTreeMap<String, f64>> = BTreeMap::new();
    let mut scripts: Vec<&str> = selected
        .iter()
        .filter_map(|w| w.peer.and_then(|p| p.script()))
        .collect();
    scripts.sort_unstable();
    scripts.dedup();
    if opts.run_peers && !scripts.is_empty() {
        write_peer_data(&data)?;
        match ensure_venv(&target) {
            Ok(python) => {
                for script in scripts {
                    eprintln!("bench: peer {script}");
                    match run_peer(root, &python, script, &data) {
                        Ok(t) => {
                            peer_times.insert(script, t);
                        }
                        Err(e) => notes.push(format!("peer {script} failed: {e:#}")),
                    }
                }
            }
            Err(e) => notes.push(format!("peers skipped: {e:#}")),
        }
    }
    let load_after = load_average();
    notes.push(format!(
        "load average (1, 5, 15 min) before: {}; after: {} (2-core machine shared with other \
         jobs: timings are noisy)",
        load_before.as_deref().unwrap_or("?"),
        load_after.as_deref().unwrap_or("?")
    ));

    let rows: Vec<Row> = selected
        .iter()
        .map(|w| {
            let ours = criterion_seconds(&target, w.criterion_id);
            let peer_s = w.peer.and_then(|p| match p.source {
                PeerSource::Script { script, key } => {
                    peer_times.get(script).and_then(|m| m.get(key)).copied()
                }
                PeerSource::Criterion(id) => criterion_seconds(&target, id),
            });
            let mut r = row(w, ours, peer_s);
            if let Some(PeerSource::Script { script, key }) = w.peer.map(|p| p.source)
                && let Some(m) = peer_times.get(script)
            {
                let extras = peer_extras(m, key);
                if !extras.is_empty() {
                    r.note = [r.note.as_str(), extras.as_str()]
                        .iter()
                        .filter(|s| !s.is_empty())
                        .copied()
                        .collect::<Vec<_>>()
                        .join("; ");
                }
            }
            r
        })
        .collect();

    let json = serde_json::json!({
        "rows": rows,
        "notes": notes,
        "load_average_before": load_before,
        "load_average_after": load_after,
        "started_unix_s": started
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0),
        "filter": opts.filter,
        "rayon_threads": 2,
    });
    std::fs::write(
        out.join("dashboard.json"),
        serde_json::to_string_pretty(&json)?,
    )?;
    let html_path = out.join("dashboard.html");
    std::fs::write(&html_path, dashboard_html(&rows, &notes))?;
    std::fs::write(out.join("dashboard.md"), dashboard_text(&rows))?;
    eprintln!("{}", dashboard_text(&rows));
    for n in &notes {
        eprintln!("{n}");
    }
    Ok(html_path)
}

/// Whether a work item is selected by `--filter` (criterion's filter is a regex over the
/// benchmark id; here `|`-separated alternatives are matched as substrings of the row's and
/// the Rust peer's ids, which covers the usual `omp|dwt` filters).
fn matches_filter(filter: Option<&str>, w: &WorkItem) -> bool {
    let Some(f) = filter else { return true };
    let peer_id = match w.peer.map(|p| p.source) {
        Some(PeerSource::Criterion(id)) => id,
        _ => "",
    };
    f.split('|')
        .map(|a| a.trim_matches(|c| c == '^' || c == '$'))
        .any(|a| w.criterion_id.contains(a) || (!peer_id.is_empty() && peer_id.contains(a)))
}

/// The peer's other figures about the same item: the keys sharing the timing key's stem
/// (`traindl_3ep_rmse` for `traindl_3ep_s`), as `peer key = value` (error vs time).
fn peer_extras(m: &BTreeMap<String, f64>, key: &str) -> String {
    let Some(stem) = key.strip_suffix("_s") else {
        return String::new();
    };
    let prefix = format!("{stem}_");
    m.iter()
        .filter(|(k, _)| k.starts_with(&prefix) && k.as_str() != key)
        .map(|(k, v)| format!("peer {k} = {}", relief_pipeline::report::fmt_num(*v)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// One dashboard row from our and the peer's time.
fn row(w: &WorkItem, ours: Option<f64>, peer_s: Option<f64>) -> Row {
    let ratio = match (ours, peer_s) {
        (Some(a), Some(b)) if b > 0.0 => Some(a / b),
        _ => None,
    };
    let status = match w.goal.judge(ours, ratio) {
        Some(true) => "pass",
        Some(false) => "short",
        None if ours.is_none() => "not run",
        None if matches!(w.goal, Goal::None) => "-",
        None => "no peer time",
    };
    let rate = match (w.units, ours) {
        (Some((n, unit)), Some(t)) if t > 0.0 => Some(format!("{:.3e} {unit}/s", n / t)),
        _ => None,
    };
    Row {
        item: w.name.to_string(),
        criterion_id: w.criterion_id.to_string(),
        ours_s: ours,
        peer: w.peer.map(|p| p.label.to_string()),
        peer_s,
        ratio,
        rate,
        goal: w.goal.describe(),
        status: status.to_string(),
        note: w.note.to_string(),
    }
}

/// `/proc/loadavg`'s first three fields, when readable.
fn load_average() -> Option<String> {
    let s = std::fs::read_to_string("/proc/loadavg").ok()?;
    Some(s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
}

/// Inputs the Python peers read that no criterion bench writes, as `.npy` in `dir`: the fixture
/// DEM and its holed copy (the heightfield benches' data) and the DWT bench's 4096^2 surface
/// (`relief_benches::dwt_surface`, the input of `benches/benches/dwt.rs`).
fn write_peer_data(dir: &Path) -> Result<()> {
    let dem = relief_benches::fixture_dem()?;
    let holes = relief_benches::with_holes(&dem);
    for (name, hf) in [("grandcanyon_512", &dem), ("grandcanyon_512_holes", &holes)] {
        let p = dir.join(format!("{name}.npy"));
        relief_io::write(&p, hf, &relief_io::WriteOptions::default())
            .with_context(|| format!("cannot write {}", p.display()))?;
    }
    let flow = relief_benches::flow_surface()?;
    let spl = relief_benches::spl_surface();
    for (name, hf) in [("flow_4096", &flow), ("spl_1024", &spl)] {
        let p = dir.join(format!("{name}.npy"));
        relief_io::write(&p, hf, &relief_io::WriteOptions::default())
            .with_context(|| format!("cannot write {}", p.display()))?;
    }
    let size = 4096;
    let surface = relief_benches::dwt_surface(size);
    let hf = relief_heightfield::Heightfield::new(size, size, surface, 1.0, 1.0)?;
    let p = dir.join(format!("dwt_surface_{size}.npy"));
    relief_io::write(&p, &hf, &relief_io::WriteOptions::default())
        .with_context(|| format!("cannot write {}", p.display()))?;
    Ok(())
}

/// The venv's python, creating the venv when missing.
fn ensure_venv(target: &Path) -> Result<PathBuf> {
    let venv = target.join("peers-venv");
    let python = venv.join("bin/python");
    if python.is_file() {
        return Ok(python);
    }
    eprintln!("bench: creating {}", venv.display());
    let st = Command::new("python3")
        .args(["-m", "venv"])
        .arg(&venv)
        .status()
        .context("cannot run python3 -m venv")?;
    if !st.success() {
        bail!("python3 -m venv failed ({st})");
    }
    let st = Command::new(venv.join("bin/pip"))
        .arg("install")
        .args(PEER_PACKAGES)
        .status()
        .context("cannot run pip")?;
    if !st.success() {
        bail!("pip install {} failed ({st})", PEER_PACKAGES.join(" "));
    }
    Ok(python)
}

fn run_peer(
    root: &Path,
    python: &Path,
    script: &str,
    data: &Path,
) -> Result<BTreeMap<String, f64>> {
    let out = Command::new(python)
        .arg(root.join("xtask/peers").join(script))
        .arg(data)
        .output()
        .with_context(|| format!("cannot run {}", python.display()))?;
    if !out.status.success() {
        bail!("{}", String::from_utf8_lossy(&out.stderr).trim());
    }
    let v: BTreeMap<String, serde_json::Value> = serde_json::from_slice(&out.stdout)
        .with_context(|| format!("{script} did not print a JSON object of seconds"))?;
    Ok(v.into_iter()
        .filter_map(|(k, v)| v.as_f64().map(|t| (k, t)))
        .collect())
}

/// Median time in seconds of a criterion benchmark, from its `new/estimates.json`.
fn criterion_seconds(target: &Path, id: &str) -> Option<f64> {
    let p = target.join("criterion").join(id).join("new/estimates.json");
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(p).ok()?).ok()?;
    v["median"]["point_estimate"].as_f64().map(|ns| ns * 1e-9)
}

fn fmt_s(t: Option<f64>) -> String {
    match t {
        Some(t) if t < 1e-3 => format!("{:.1} us", t * 1e6),
        Some(t) if t < 1.0 => format!("{:.2} ms", t * 1e3),
        Some(t) => format!("{t:.3} s"),
        None => "-".to_string(),
    }
}

fn cells(r: &Row) -> [String; 9] {
    [
        r.item.clone(),
        fmt_s(r.ours_s),
        r.rate.clone().unwrap_or_else(|| "-".into()),
        r.peer.clone().unwrap_or_else(|| "-".into()),
        fmt_s(r.peer_s),
        r.ratio
            .map(|x| format!("{x:.2}"))
            .unwrap_or_else(|| "-".into()),
        r.goal.clone(),
        r.status.clone(),
        r.note.clone(),
    ]
}

const COLUMNS: [&str; 9] = [
    "work item",
    "ours",
    "our rate",
    "peer",
    "peer time",
    "ratio",
    "goal",
    "status",
    "note",
];

/// The dashboard as a Markdown table (printed, and pasted into issue notes).
pub(crate) fn dashboard_text(rows: &[Row]) -> String {
    let mut s = format!(
        "| {} |\n|{}\n",
        COLUMNS.join(" | "),
        "---|".repeat(COLUMNS.len())
    );
    for r in rows {
        let c: Vec<String> = cells(r).iter().map(|c| c.replace('|', "\\|")).collect();
        let _ = writeln!(s, "| {} |", c.join(" | "));
    }
    s
}

fn dashboard_html(rows: &[Row], notes: &[String]) -> String {
    let mut h = String::from(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>relief benchmarks</title>\
         <style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}\
         td,th{border:1px solid #bbb;padding:2px 8px}th{background:#eee}\
         .pass{background:#cfc}.short{background:#fcc}</style></head><body>\
         <h1>relief benchmarks</h1><table><tr>",
    );
    for c in COLUMNS {
        let _ = write!(h, "<th>{c}</th>");
    }
    h.push_str("</tr>\n");
    for r in rows {
        let _ = write!(h, "<tr class=\"{}\">", esc(&r.status));
        for c in cells(r) {
            let _ = write!(h, "<td>{}</td>", esc(&c));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    for n in notes {
        let _ = writeln!(h, "<p>{}</p>", esc(n));
    }
    h.push_str(
        "<p>ours = criterion median (relief-benches); peer = median of repeats \
                (xtask/peers/*.py) or criterion median (Rust peers); ratio = ours / peer (below 1: we are faster); goals from the method \
                issues' speed sections, on 2 threads.</p></body></html>\n",
    );
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn work_items_are_well_formed() {
        let mut ids: Vec<&str> = items::WORK_ITEMS.iter().map(|w| w.criterion_id).collect();
        assert_eq!(ids.iter().filter(|i| i.split('/').count() < 2).count(), 0);
        ids.sort_unstable();
        ids.dedup();
        assert_eq!(
            ids.len(),
            items::WORK_ITEMS.len(),
            "duplicate criterion ids"
        );
        let root = crate::project_root();
        for w in items::WORK_ITEMS {
            match w.peer.map(|p| p.source) {
                Some(PeerSource::Script { script, key }) => {
                    assert!(root.join("xtask/peers").join(script).is_file(), "{script}");
                    assert!(key.ends_with("_s"), "{key}: peer keys are seconds, `*_s`");
                }
                Some(PeerSource::Criterion(id)) => {
                    assert!(id.split('/').count() >= 2, "{id}");
                    assert_ne!(id, w.criterion_id);
                }
                None => {}
            }
            if matches!(w.goal, Goal::RatioAtMost(_) | Goal::SpeedupAtLeast(_)) {
                assert!(w.peer.is_some(), "{}: a ratio goal needs a peer", w.name);
            }
        }
    }

    #[test]
    fn goals_judge_rows() {
        assert_eq!(
            Goal::RatioAtMost(2.0).judge(Some(1.0), Some(1.5)),
            Some(true)
        );
        assert_eq!(
            Goal::RatioAtMost(2.0).judge(Some(1.0), Some(2.5)),
            Some(false)
        );
        assert_eq!(Goal::RatioAtMost(2.0).judge(Some(1.0), None), None);
        assert_eq!(Goal::SecondsAtMost(0.5).judge(Some(0.7), None), Some(false));
        // 1.5x faster than the peer: ratio 0.6 passes, 0.7 is short.
        assert_eq!(Goal::SpeedupAtLeast(1.5).judge(None, Some(0.6)), Some(true));
        assert_eq!(
            Goal::SpeedupAtLeast(1.5).judge(None, Some(0.7)),
            Some(false)
        );
        assert_eq!(Goal::None.judge(Some(1.0), Some(1.0)), None);
    }

    const ITEM: WorkItem = WorkItem {
        name: "omp | x",
        criterion_id: "omp/batch_omp_f32/k64_n256_s1",
        peer: Some(Peer {
            source: PeerSource::Script {
                script: "spams_omp.py",
                key: "k64_n256_s1_s",
            },
            label: "SPAMS",
        }),
        goal: Goal::SpeedupAtLeast(1.5),
        units: Some((65536.0, "signals")),
        note: "",
    };

    #[test]
    fn rows_compute_ratio_rate_and_status() {
        let r = row(&ITEM, Some(0.05), Some(0.1));
        assert_eq!(r.ratio, Some(0.5));
        assert_eq!(r.status, "pass");
        assert_eq!(r.rate.as_deref(), Some("1.311e6 signals/s"));
        assert_eq!(row(&ITEM, Some(0.2), Some(0.1)).status, "short");
        assert_eq!(row(&ITEM, Some(0.2), None).status, "no peer time");
        assert_eq!(row(&ITEM, None, Some(0.1)).status, "not run");
        let md = dashboard_text(&[r]);
        assert!(
            md.contains("| omp \\| x | 50.00 ms | 1.311e6 signals/s | SPAMS | 100.00 ms | 0.50 |"),
            "{md}"
        );
        let quilt = WorkItem {
            criterion_id: "quilt/relief_patch_synth_1024_from_512_2threads",
            peer: Some(Peer {
                source: PeerSource::Criterion("quilt/texture_synthesis_512_from_512_8bit_2threads"),
                label: "texture-synthesis",
            }),
            ..ITEM
        };
        assert!(matches_filter(None, &ITEM));
        assert!(matches_filter(Some("dwt|omp"), &ITEM));
        assert!(matches_filter(Some("^omp/batch"), &ITEM));
        assert!(!matches_filter(Some("dwt"), &ITEM));
        assert!(matches_filter(Some("texture_synthesis"), &quilt));
    }

    #[test]
    fn peer_extras_share_the_timing_key_stem() {
        let m: BTreeMap<String, f64> = [
            ("traindl_3ep_s", 2.4),
            ("traindl_3ep_rmse", 3.25),
            ("traindl_1ep_rmse", 4.0),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        assert_eq!(
            peer_extras(&m, "traindl_3ep_s"),
            "peer traindl_3ep_rmse = 3.250"
        );
        assert_eq!(peer_extras(&m, "other_s"), "");
    }

    // The data helpers of `relief-benches` (its library has no test target of its own, so that
    // `cargo test --workspace` does not build criterion and the benchmark peers).

    #[test]
    fn holes_cover_about_seven_percent() {
        let hf =
            relief_heightfield::Heightfield::from_fn(512, 512, 1.0, 1.0, |x, y| (x + y) as f32);
        let holed = relief_benches::with_holes(&hf);
        let frac = holed.void_count() as f64 / holed.len() as f64;
        assert!((0.05..0.08).contains(&frac), "{frac}");
        assert_eq!(holed.get(0, 0), 0.0);
        assert!(holed.get(128, 128).is_nan());
    }

    #[test]
    fn dwt_surface_is_a_deterministic_random_walk() {
        let a = relief_benches::dwt_surface(64);
        assert_eq!(a, relief_benches::dwt_surface(64));
        // Cumulative sums in both directions: the first cell is the first normal, and the
        // surface wanders far further than one step.
        let spread = a.iter().cloned().fold(f32::NEG_INFINITY, f32::max)
            - a.iter().cloned().fold(f32::INFINITY, f32::min);
        assert!(spread > 20.0, "{spread}");
        assert!(a.iter().all(|v| v.is_finite()));
    }
}

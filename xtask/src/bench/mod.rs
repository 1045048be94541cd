//! `cargo xtask bench`: runs the criterion benches of `relief-benches` and the Python peers on
//! the same data, then writes `target/bench/dashboard.json` and `dashboard.html` with one row
//! per [`WorkItem`] (see `items.rs`): our time, the peer's time, the ratio, the goal and a
//! pass/short mark.
//!
//! Peers are Python scripts in `xtask/peers/`. Each is run as
//! `<venv>/bin/python xtask/peers/<script> <data dir>` and prints one JSON object
//! `{"<key>": seconds, ...}` (median of its repeats) on stdout. The venv
//! `target/peers-venv` is created with the packages of [`PEER_PACKAGES`] when missing.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, Result, bail};
use serde::Serialize;

mod items;

use crate::pipeline::report::esc;

/// Packages installed into the peers venv.
pub(crate) const PEER_PACKAGES: &[&str] = &[
    "spams-bin",
    "PyWavelets",
    "scikit-image",
    "scikit-learn",
    "imagecodecs",
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
}

/// A peer measurement: a key printed by a script in `xtask/peers/`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Peer {
    /// Script file name in `xtask/peers/`.
    pub(crate) script: &'static str,
    /// Key of the timing in the script's JSON output.
    pub(crate) key: &'static str,
    /// Human-readable peer name.
    pub(crate) label: &'static str,
}

/// Goal of a row.
#[derive(Debug, Clone, Copy, Serialize)]
pub(crate) enum Goal {
    /// Our time / peer time must be at most this.
    RatioAtMost(f64),
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
            Goal::SecondsAtMost(s) => format!("<= {s} s"),
            Goal::None => "-".to_string(),
        }
    }

    /// `Some(true)` = pass, `Some(false)` = short, `None` = cannot judge (missing timing).
    fn judge(self, ours: Option<f64>, ratio: Option<f64>) -> Option<bool> {
        match self {
            Goal::RatioAtMost(r) => ratio.map(|x| x <= r),
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
    pub(crate) goal: String,
    pub(crate) status: String,
}

/// Runs everything and writes the dashboard; returns the HTML path.
pub(crate) fn run(root: &Path, opts: &BenchOptions) -> Result<PathBuf> {
    let target = crate::target_dir(root);
    let out = target.join("bench");
    let data = out.join("data");
    std::fs::create_dir_all(&data)?;
    write_peer_data(&data)?;

    if opts.run_cargo {
        eprintln!("bench: cargo bench -p relief-benches");
        let mut cmd = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
        cmd.current_dir(root)
            .args(["bench", "-p", "relief-benches", "--"]);
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
    if opts.run_peers {
        match ensure_venv(&target) {
            Ok(python) => {
                let mut scripts: Vec<&str> = items::WORK_ITEMS
                    .iter()
                    .filter_map(|w| w.peer.map(|p| p.script))
                    .collect();
                scripts.sort_unstable();
                scripts.dedup();
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

    let rows: Vec<Row> = items::WORK_ITEMS
        .iter()
        .map(|w| {
            let ours = criterion_seconds(&target, w.criterion_id);
            let peer_s = w
                .peer
                .and_then(|p| peer_times.get(p.script).and_then(|m| m.get(p.key)).copied());
            let ratio = match (ours, peer_s) {
                (Some(a), Some(b)) if b > 0.0 => Some(a / b),
                _ => None,
            };
            let status = match w.goal.judge(ours, ratio) {
                Some(true) => "pass",
                Some(false) => "short",
                None if ours.is_none() => "not run",
                None => "-",
            };
            Row {
                item: w.name.to_string(),
                criterion_id: w.criterion_id.to_string(),
                ours_s: ours,
                peer: w.peer.map(|p| p.label.to_string()),
                peer_s,
                ratio,
                goal: w.goal.describe(),
                status: status.to_string(),
            }
        })
        .collect();

    let json = serde_json::json!({ "rows": rows, "notes": notes });
    std::fs::write(
        out.join("dashboard.json"),
        serde_json::to_string_pretty(&json)?,
    )?;
    let html_path = out.join("dashboard.html");
    std::fs::write(&html_path, dashboard_html(&rows, &notes))?;
    eprintln!("{}", dashboard_text(&rows));
    Ok(html_path)
}

/// Inputs the peers read (the same data the criterion benches use), as `.npy`.
fn write_peer_data(dir: &Path) -> Result<()> {
    let dem = relief_benches::fixture_dem()?;
    let holes = relief_benches::with_holes(&dem);
    for (name, hf) in [("grandcanyon_512", &dem), ("grandcanyon_512_holes", &holes)] {
        let p = dir.join(format!("{name}.npy"));
        relief_io::write(&p, hf, &relief_io::WriteOptions::default())
            .with_context(|| format!("cannot write {}", p.display()))?;
    }
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
    let v: BTreeMap<String, f64> = serde_json::from_slice(&out.stdout)
        .with_context(|| format!("{script} did not print a JSON object of seconds"))?;
    Ok(v)
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

fn cells(r: &Row) -> [String; 7] {
    [
        r.item.clone(),
        fmt_s(r.ours_s),
        r.peer.clone().unwrap_or_else(|| "-".into()),
        fmt_s(r.peer_s),
        r.ratio
            .map(|x| format!("{x:.2}"))
            .unwrap_or_else(|| "-".into()),
        r.goal.clone(),
        r.status.clone(),
    ]
}

const COLUMNS: [&str; 7] = [
    "work item",
    "ours",
    "peer",
    "peer time",
    "ratio",
    "goal",
    "status",
];

/// The dashboard as a Markdown table (printed, and pasted into issue notes).
pub(crate) fn dashboard_text(rows: &[Row]) -> String {
    let mut s = format!(
        "| {} |\n|{}\n",
        COLUMNS.join(" | "),
        "---|".repeat(COLUMNS.len())
    );
    for r in rows {
        let _ = writeln!(s, "| {} |", cells(r).join(" | "));
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
                (xtask/peers); ratio = ours / peer.</p></body></html>\n",
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
            if let Some(p) = w.peer {
                assert!(
                    root.join("xtask/peers").join(p.script).is_file(),
                    "{}",
                    p.script
                );
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
        let row = Row {
            item: "x".into(),
            criterion_id: "g/f/1".into(),
            ours_s: Some(0.002),
            peer: None,
            peer_s: None,
            ratio: None,
            goal: "-".into(),
            status: "-".into(),
        };
        assert!(dashboard_text(&[row]).contains("| x | 2.00 ms | - |"));
    }
}

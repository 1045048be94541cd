//! All-or-nothing outputs of commands that write several files (`quilt --seam-map
//! --guide-out`, `volume --mesh --render --section`, `analyze --maps --plot`): every output is
//! given a staged path in a hidden `.relief-stage-<pid>-<n>` folder beside it before any work
//! (which also checks that each folder exists and is writable), the command writes there, and
//! [`Outputs::commit`] moves them all into place at the end. An error anywhere drops the
//! [`Outputs`], which removes the staged files: no output appears.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

/// The staged outputs of one run.
#[derive(Debug)]
pub(crate) struct Outputs {
    stage: relief_io::Staging,
    /// `(target, staged path)`.
    paths: Vec<(PathBuf, PathBuf)>,
}

impl Outputs {
    /// Stages every target now (before the work starts).
    pub(crate) fn new(targets: &[&Path]) -> Result<Outputs> {
        let mut stage = relief_io::Staging::new();
        let mut paths = Vec::new();
        for t in targets {
            let staged = stage
                .path(t)
                .with_context(|| format!("cannot write {}", t.display()))?;
            paths.push((t.to_path_buf(), staged));
        }
        Ok(Outputs { stage, paths })
    }

    /// Where to write `target` (the target itself if it was not staged).
    pub(crate) fn path(&self, target: &Path) -> PathBuf {
        self.paths
            .iter()
            .find(|(t, _)| t == target)
            .map(|(_, s)| s.clone())
            .unwrap_or_else(|| target.to_path_buf())
    }

    /// Stages the paths of `outputs` (as given to `Ctx::check_outputs`) and `extra` ones.
    pub(crate) fn of(
        outputs: &[(&Path, crate::outputs::OutKind)],
        extra: Option<&Path>,
    ) -> Result<Outputs> {
        let mut targets: Vec<&Path> = outputs.iter().map(|&(p, _)| p).collect();
        targets.extend(extra);
        Outputs::new(&targets)
    }

    /// Writes an RGB image (`rgb`: `width x height` triples) as the PNG `target`.
    pub(crate) fn write_png(
        &self,
        target: &Path,
        width: usize,
        height: usize,
        rgb: &[u8],
    ) -> Result<()> {
        relief_io::write_rgb_png(&self.path(target), width, height, rgb)
            .with_context(|| format!("cannot write {}", target.display()))
    }

    /// Writes `value` as pretty JSON (one trailing newline) at `target`.
    pub(crate) fn write_json(&self, target: &Path, value: &impl serde::Serialize) -> Result<()> {
        let text = json_text(value)?;
        relief_io::write_bytes_atomic(&self.path(target), text.as_bytes())
            .with_context(|| format!("cannot write {}", target.display()))
    }

    /// Moves every staged output into place.
    pub(crate) fn commit(self) -> Result<()> {
        self.stage
            .commit()
            .context("cannot move the outputs into place")
    }
}

/// `value` as pretty JSON ending in a newline (reports, `--json` output).
pub(crate) fn json_text(value: &impl serde::Serialize) -> Result<String> {
    Ok(serde_json::to_string_pretty(value).context("cannot encode the JSON")? + "\n")
}

/// Writes `text` on stdout (an error, not a panic, when stdout is closed).
pub(crate) fn print(text: &str) -> Result<()> {
    let mut stdout = std::io::stdout().lock();
    std::io::Write::write_all(&mut stdout, text.as_bytes()).context("cannot write to stdout")
}

/// The path to show for a file written at `path`: its target when `path` is staged.
pub(crate) fn shown(path: &Path) -> PathBuf {
    let staged = path
        .parent()
        .and_then(|d| d.file_name())
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.starts_with(".relief-stage-"));
    match (
        staged,
        path.parent().and_then(Path::parent),
        path.file_name(),
    ) {
        (true, Some(dir), Some(name)) => dir.join(name),
        _ => path.to_path_buf(),
    }
}

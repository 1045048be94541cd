//! All-or-nothing outputs of commands that write a folder of files with fixed names
//! (`relief flow DEM -o DIR`, `relief masks DEM -o DIR`). When `DIR` exists, every file is
//! checked as any output is ([`Ctx::check_outputs`]: not an input, not an existing file
//! without `--force`) and staged in a hidden `.relief-stage-*` folder inside it, then moved
//! into place together. When `DIR` does not exist (its parent must), the whole folder is
//! staged beside it and renamed into place at the end: it appears with all its files or not at
//! all. An error anywhere drops the staging, so nothing is left behind.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use crate::ctx::Ctx;
use crate::outputs::OutKind;

/// The staged files of one output folder.
#[derive(Debug)]
pub(crate) struct FolderOutputs {
    stage: relief_io::Staging,
    /// Where the files are written until the commit.
    staged_dir: PathBuf,
    /// The output folder as given.
    dir: PathBuf,
}

impl FolderOutputs {
    /// Checks and stages the files `names` of `dir` (before any work). `inputs` are every
    /// file the command reads.
    pub(crate) fn new(
        dir: &Path,
        names: &[(&str, OutKind)],
        inputs: &[&Path],
        ctx: &Ctx,
    ) -> Result<FolderOutputs> {
        let mut stage = relief_io::Staging::new();
        let staged_dir = match std::fs::metadata(dir) {
            Ok(m) if m.is_dir() => {
                let targets: Vec<PathBuf> = names.iter().map(|(n, _)| dir.join(n)).collect();
                let outputs: Vec<(&Path, OutKind)> = targets
                    .iter()
                    .zip(names)
                    .map(|(t, (_, k))| (t.as_path(), *k))
                    .collect();
                ctx.check_outputs(inputs, &outputs)?;
                let mut first = None;
                for t in &targets {
                    let p = stage
                        .path(t)
                        .with_context(|| format!("cannot write {}", t.display()))?;
                    first.get_or_insert(p);
                }
                match first.as_ref().and_then(|p| p.parent()) {
                    Some(d) => d.to_path_buf(),
                    None => bail!("no output to write into {}", dir.display()),
                }
            }
            Ok(_) => bail!(
                "the output folder {} exists and is not a folder",
                dir.display()
            ),
            Err(_) => {
                let parent = crate::outputs::parent_folder(dir);
                if !parent.is_dir() {
                    bail!(
                        "cannot create the output folder {}: {} is not a folder",
                        dir.display(),
                        parent.display()
                    );
                }
                // The extension checks of the names (nothing in a new folder can exist or be
                // an input).
                let probe: Vec<PathBuf> = names.iter().map(|(n, _)| parent.join(n)).collect();
                for (p, (_, k)) in probe.iter().zip(names) {
                    crate::outputs::check_extension(p, *k)?;
                }
                let staged = stage
                    .path(dir)
                    .with_context(|| format!("cannot create {}", dir.display()))?;
                std::fs::create_dir(&staged)
                    .with_context(|| format!("cannot create {}", dir.display()))?;
                staged
            }
        };
        Ok(FolderOutputs {
            stage,
            staged_dir,
            dir: dir.to_path_buf(),
        })
    }

    /// Where to write the file `name` until the commit.
    pub(crate) fn path(&self, name: &str) -> PathBuf {
        self.staged_dir.join(name)
    }

    /// Where the file `name` appears.
    pub(crate) fn target(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Writes an RGB image (`width x height` triples) as the PNG `name`.
    pub(crate) fn write_png(
        &self,
        name: &str,
        width: usize,
        height: usize,
        rgb: &[u8],
    ) -> Result<()> {
        relief_io::write_rgb_png(&self.path(name), width, height, rgb)
            .with_context(|| format!("cannot write {}", self.target(name).display()))
    }

    /// Writes JSON text (pretty, or compact for large documents) as `name`.
    pub(crate) fn write_json(
        &self,
        name: &str,
        value: &impl serde::Serialize,
        pretty: bool,
    ) -> Result<()> {
        let text = if pretty {
            crate::staging::json_text(value)?
        } else {
            serde_json::to_string(value).context("cannot encode the JSON")? + "\n"
        };
        relief_io::write_bytes_atomic(&self.path(name), text.as_bytes())
            .with_context(|| format!("cannot write {}", self.target(name).display()))
    }

    /// Moves every file (or the new folder) into place.
    pub(crate) fn commit(self) -> Result<()> {
        self.stage
            .commit()
            .with_context(|| format!("cannot move the outputs into {}", self.dir.display()))
    }
}
